!> The progress of a run: the simulated time reached, for the Python binding to read from
!> another thread while the run goes on, a progress line on stderr about every second
!> (mrsim --progress), and the run's CPU and wall clocks.
module pymr_driver_progress
  use, intrinsic :: iso_fortran_env, only : error_unit
  use pymr_env_kinds, only : dp
  use pymr_env_clock, only : thread_cpu_time
  implicit none
  private
  public :: progress_t, progress_t_end, progress_running, run_clock

  !> Progress of the run in this process, read by the Python binding from another thread
  !> while the run goes on (no call back into Python per step): simulated time reached,
  !> end time, and whether a run is going.
  real(dp), volatile :: progress_t = 0.0_dp, progress_t_end = 0.0_dp
  logical, volatile :: progress_running = .false.

  !> The clocks of a run, and its progress lines when asked for.
  type :: run_clock
    !> Print a progress line to stderr about every second.
    logical :: lines = .false.
    !> CPU time at the start (moved back by a checkpoint's CPU time, on by the pre-flight check's).
    real(dp) :: cpu0 = 0.0_dp
    !> The run's end time, and the simulated time of the last progress line.
    real(dp) :: t_end = 0.0_dp, t_line = 0.0_dp
    !> Wall clock at the start and at the last progress line, and its rate.
    integer(8) :: c0 = 0, c_line = 0, rate = 1
  contains
    procedure :: start => clock_start
    procedure :: cpu_s => clock_cpu_s
    procedure :: run_begins => clock_run_begins
    procedure :: reached => clock_reached
    procedure :: run_ends => clock_run_ends
    procedure :: stop => clock_stop
  end type run_clock

contains

  !> Start the CPU and wall clocks.
  subroutine clock_start(self)
    class(run_clock), intent(inout) :: self
    self%cpu0 = thread_cpu_time(); call system_clock(self%c0, self%rate)
  end subroutine clock_start

  !> CPU time of the run so far (s).
  real(dp) function clock_cpu_s(self)
    class(run_clock), intent(in) :: self
    clock_cpu_s = thread_cpu_time() - self%cpu0
  end function clock_cpu_s

  !> The integration begins at time t of a run to t_end: the progress goes from there.
  subroutine clock_run_begins(self, t, t_end)
    class(run_clock), intent(inout) :: self
    real(dp), intent(in) :: t, t_end
    self%t_end = t_end
    progress_t_end = t_end; progress_t = t; progress_running = .true.
    self%c_line = self%c0
    if (self%lines) call progress_line(t, t_end, self%c0, self%rate)
    self%t_line = t
  end subroutine clock_run_begins

  !> The run has reached time t: the progress, and a line when a second has passed since the last.
  subroutine clock_reached(self, t)
    class(run_clock), intent(inout) :: self
    real(dp), intent(in) :: t
    integer(8) :: c1
    progress_t = t
    if (self%lines) then
      call system_clock(c1)
      if (c1 - self%c_line >= self%rate) then
        call progress_line(t, self%t_end, self%c0, self%rate); self%c_line = c1; self%t_line = t
      end if
    end if
  end subroutine clock_reached

  !> The integration has ended (`ok`: at t_end): no run goes on; the last line, unless the
  !> last one was already at t_end (within eps).
  subroutine clock_run_ends(self, ok, eps)
    class(run_clock), intent(inout) :: self
    logical, intent(in) :: ok
    real(dp), intent(in) :: eps
    progress_running = .false.
    if (self%lines .and. ok .and. self%t_line < self%t_end - eps) &
      & call progress_line(self%t_end, self%t_end, self%c0, self%rate)
  end subroutine clock_run_ends

  !> Stop the clocks: the run's CPU and wall times (s).
  subroutine clock_stop(self, cpu_s, wall_s)
    class(run_clock), intent(in) :: self
    real(dp), intent(out) :: cpu_s, wall_s
    real(dp) :: cpu1
    integer(8) :: c1
    cpu1 = thread_cpu_time(); call system_clock(c1)
    cpu_s = cpu1 - self%cpu0; wall_s = real(c1 - self%c0, dp)/real(self%rate, dp)
  end subroutine clock_stop

  !> One progress line on stderr: simulated time, percent, wall time and its estimate to go.
  subroutine progress_line(t, t_end, c0, rate)
    real(dp), intent(in) :: t, t_end
    integer(8), intent(in) :: c0, rate
    integer(8) :: c
    real(dp) :: wall, eta
    character(len=160) :: buf
    call system_clock(c)
    wall = real(c - c0, dp)/real(rate, dp)
    write(buf, '(a,es11.4,a,es11.4,a,f6.1,a,f9.1,a)') 'mrsim: t = ', t, ' s of ', t_end, ' s (', &
      & 100.0_dp*min(t/t_end, 1.0_dp), ' %), ', wall, ' s elapsed'
    ! the time to go, from the pace so far: none before 1 % of the run or 1 s of it (the
    ! start-up's pace says nothing of the rest), none at the end
    if (t >= 0.01_dp*t_end .and. wall >= 1.0_dp .and. t < t_end) then
      eta = wall*(t_end - t)/t
      write(buf, '(a,a,f9.1,a)') trim(buf), ', ETA ', eta, ' s'
    end if
    write(error_unit, '(a)') trim(buf)
    flush(error_unit)
  end subroutine progress_line
end module pymr_driver_progress
