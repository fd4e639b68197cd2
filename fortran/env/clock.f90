!> CPU time of the calling thread (Linux clock_gettime(CLOCK_THREAD_CPUTIME_ID)). A run
!> happens in one thread; the process-wide cpu_time would also count other threads of a
!> host process (numpy's BLAS threads when called from Python).
module pymr_env_clock
  use, intrinsic :: iso_c_binding, only : c_int, c_long
  use pymr_env_kinds, only : dp
  implicit none
  private
  public :: thread_cpu_time

  integer(c_int), parameter :: clock_thread_cputime_id = 3

  type, bind(c) :: timespec
    integer(c_long) :: tv_sec, tv_nsec
  end type timespec

  interface
    function clock_gettime(clk, ts) bind(c, name='clock_gettime') result(r)
      import :: c_int, timespec
      integer(c_int), value :: clk
      type(timespec), intent(out) :: ts
      integer(c_int) :: r
    end function clock_gettime
  end interface

contains

  !> Seconds of CPU used by this thread (falls back to cpu_time if the clock fails).
  function thread_cpu_time() result(t)
    real(dp) :: t
    type(timespec) :: ts
    if (clock_gettime(clock_thread_cputime_id, ts) == 0) then
      t = real(ts%tv_sec, dp) + 1.0e-9_dp*real(ts%tv_nsec, dp)
    else
      call cpu_time(t)
    end if
  end function thread_cpu_time
end module pymr_env_clock
