!> `&integrator method = 'auto'`: the kernel chooses the method of an adaptive run.
!>
!> The candidates are single-rate (the scene's formula, 'adams' by default) and, when the
!> scene has slow (joint) and fast (modal) coordinates, the multirate couplings
!> 'exponential' (not with a closed loop through a flexible body, which it refuses) and
!> 'response'. Each candidate runs on a copy of the model from the initial state over the
!> first `probe_share` of the run, at the scene's tolerances, with the dense output of the
!> run's rows (its cost differs between the methods: the exponential flow's closed form
!> against a polynomial). Its CPU over the probe's second half (past the start's small
!> steps), scaled to the rest of the run, plus its CPU up to there, predicts its run; the
!> least prediction runs the scene. A probe that has taken `race_margin` times the CPU of
!> the fastest finished probe is stopped: its candidate is slower; so is one whose CPU so
!> far, scaled to the whole run, is `far_margin` times the least prediction (after
!> `far_steps` steps: a method several times slower is seen early). A scene without both
!> kinds of coordinates runs single-rate with no probe. A run continued from a checkpoint
!> keeps the method that wrote it.
module pymr_driver_method_choice
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_env_clock, only : thread_cpu_time
  use pymr_env_text, only : fmt, itoa, json_escape
  use pymr_model_scene, only : scene_t, flexible_loop
  use pymr_model, only : model_t
  use pymr_integrator_stepper, only : stepper_t, step_counts
  use pymr_io_checkpoint, only : checkpoint_stepper
  use pymr_driver_stepper_setup, only : make_stepper
  implicit none
  private
  public :: choose_method, method_of_checkpoint, method_choice_t, probe_run

  !> Share of the run (from its start) each candidate is probed over; CPU beyond the fastest
  !> finished probe's at which a probe stops.
  real(dp), parameter :: probe_share = 0.03_dp, race_margin = 1.5_dp, far_margin = 10.0_dp
  integer, parameter :: far_steps = 10
  integer, parameter :: max_candidates = 3
  !> Rows of dense output a probe keeps at most (beyond, its run starts again from 0).
  integer, parameter :: max_probe_rows = 20000

  !> A finished probe, kept until the choice: its stepper and model where it stopped, and
  !> the states of the rows it passed (every dt of &output), so that the chosen method's
  !> run can go on from there instead of starting again (nr = -1: too many rows kept).
  type :: probe_run
    class(stepper_t), allocatable :: st
    type(model_t), allocatable :: model
    real(dp), allocatable :: rows(:, :)
    integer :: nr = 0
  end type probe_run

  !> What 'auto' chose and why: the candidates' labels and methods (set_method's numbers),
  !> probe CPU and predicted run CPU (s; huge when the probe failed or stopped) and why it
  !> did, the probe's end time.
  type :: method_choice_t
    integer :: n = 0, chosen = 0
    character(len=40) :: label(max_candidates) = ''
    integer :: method(max_candidates) = 0
    real(dp) :: cpu(max_candidates) = huge(1.0_dp), predicted(max_candidates) = huge(1.0_dp)
    character(len=200) :: failure(max_candidates) = ''
    real(dp) :: t_probe = 0.0_dp
    character(len=:), allocatable :: reason
    !> The candidates' finished probes.
    type(probe_run) :: runs(max_candidates)
  contains
    procedure :: summary => choice_summary
    procedure :: json => choice_json
    procedure :: take_chosen
  end type method_choice_t

contains

  !> Choose the method of the scene sc (method 'auto') at the initial state x of the model,
  !> and set it in sc (method, coupling, formula).
  subroutine choose_method(sc, model, x, choice)
    type(scene_t), intent(inout) :: sc
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: x(:)
    type(method_choice_t), intent(out) :: choice
    integer :: i
    ! the multirate couplings first: where they pay, their probes are short and stop the rest
    if (model%n_fast() > 0 .and. model%n_slow() > 0) then
      if (.not. flexible_loop(sc)) call add_candidate(choice, sc, 2)
      call add_candidate(choice, sc, 3)
    end if
    call add_candidate(choice, sc, 1)
    if (choice%n == 1) then
      choice%chosen = 1
      choice%reason = 'the scene has no ' // trim(merge('fast (modal)', 'slow (joint)', model%n_fast() == 0)) // &
        & ' coordinates: nothing to run at two rates'
    else
      choice%t_probe = probe_share*sc%scene%t_end
      do i = 1, choice%n
        call probe(sc, model, x, i, choice)
      end do
      choice%chosen = minloc(choice%predicted(1:choice%n), 1)
      choice%reason = 'least predicted CPU'
      if (all(choice%predicted(1:choice%n) == huge(1.0_dp))) then
        choice%chosen = choice%n
        choice%reason = 'every probe failed: single-rate, whose run reports why'
      end if
    end if
    call set_method(sc, choice%method(choice%chosen))
  end subroutine choose_method

  !> Method `method` of the scene sc (set_method's numbers) as the next candidate, with its
  !> label ("single-rate 'adams'", "multirate 'exponential'").
  subroutine add_candidate(choice, sc, method)
    type(method_choice_t), intent(inout) :: choice
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: method
    choice%n = choice%n + 1
    choice%method(choice%n) = method
    select case (method)
    case (1)
      choice%label(choice%n) = "single-rate '" // trim(sc%integrator%formula) // "'"
    case (2)
      choice%label(choice%n) = "multirate 'exponential'"
    case default
      choice%label(choice%n) = "multirate 'response'"
    end select
  end subroutine add_candidate

  !> Set method i (1 single-rate, 2 'exponential', 3 'response') in sc.
  subroutine set_method(sc, i)
    type(scene_t), intent(inout) :: sc
    integer, intent(in) :: i
    if (i == 1) then
      sc%integrator%method = 'single'; return
    end if
    sc%integrator%method = 'multirate'
    sc%integrator%formula = 'abm4'; sc%integrator%order = 4
    sc%integrator%coupling = trim(merge('exponential', 'response   ', i == 2))
  end subroutine set_method

  !> Candidate i from the initial state over [0, t_probe] on a copy of the model: its CPU
  !> (the stepper's making included) and its predicted run; the probe is kept (runs(i))
  !> when it finished.
  subroutine probe(sc, model, x, i, choice)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: x(:)
    integer, intent(in) :: i
    type(method_choice_t), intent(inout), target :: choice
    type(probe_run), pointer :: run
    type(scene_t) :: trial
    type(error_type), allocatable :: error
    real(dp) :: cpu0, cpu_half, t_half, cap, h0, best
    integer :: k_row, steps
    type(step_counts) :: done
    trial = sc
    call set_method(trial, choice%method(i))
    cap = huge(1.0_dp)
    if (i > 1) cap = minval(choice%cpu(1:i-1))
    if (cap < huge(1.0_dp)) cap = race_margin*cap
    best = huge(1.0_dp)
    if (i > 1) best = minval(choice%predicted(1:i-1))
    run => choice%runs(i)
    cpu0 = thread_cpu_time(); cpu_half = -1.0_dp; t_half = 0.0_dp
    allocate(run%model, source=model)
    allocate(run%rows(size(x), 16))
    call make_stepper(trial, run%model, x, run%st, h0, error)
    if (.not. allocated(error)) call run%st%start(run%model, 0.0_dp, x, h0, error)
    k_row = 1; steps = 0
    do while (.not. allocated(error))
      call dense_rows(sc%output%dt, min(run%st%time(), sc%scene%t_end) + 1.0e-9_dp*sc%integrator%h_slow, run, k_row)
      if (cpu_half < 0.0_dp .and. run%st%time() >= 0.5_dp*choice%t_probe) then
        cpu_half = thread_cpu_time(); t_half = run%st%time()
      end if
      if (run%st%time() >= choice%t_probe) exit
      if (thread_cpu_time() - cpu0 > cap .or. (steps >= far_steps .and. best < huge(1.0_dp) .and. &
        & (thread_cpu_time() - cpu0)*sc%scene%t_end > far_margin*best*run%st%time())) then
        choice%failure(i) = 'stopped at t = ' // fmt(run%st%time()) // ' s: slower than the fastest probe'
        call forget(run); return
      end if
      call run%st%advance(run%model, error)
      steps = steps + 1
      done = run%st%counts()
      if (.not. allocated(error) .and. done%steps_fast > sc%integrator%max_steps) &
        & call fatal_error(error, 'at t = ' // fmt(run%st%time()) // ' s: the probe took more than max_steps = ' // &
        & itoa(sc%integrator%max_steps) // ' steps')
    end do
    if (allocated(error)) then
      choice%failure(i) = error%message
      call forget(run); return
    end if
    choice%cpu(i) = thread_cpu_time() - cpu0
    choice%predicted(i) = predicted_run(choice%cpu(i), thread_cpu_time() - cpu_half, run%st%time(), t_half, &
      & cpu_half >= 0.0_dp, choice%t_probe, sc%scene%t_end)
    call keep_least(choice, i)
  end subroutine probe

  !> Of the finished probes 1..i only the one of least predicted CPU is kept (each holds a
  !> copy of the model and a stepper: the memory check, build.f90 run_bytes, counts one
  !> besides the probe running).
  subroutine keep_least(choice, i)
    type(method_choice_t), intent(inout) :: choice
    integer, intent(in) :: i
    integer :: j, least
    least = minloc(choice%predicted(1:i), 1)
    do j = 1, i
      if (j /= least) call forget(choice%runs(j))
    end do
  end subroutine keep_least

  !> A probe's predicted run: its CPU, and its CPU over its second half (from t_half to
  !> t, cpu_2) scaled to the rest of the run to t_end; a probe of one or two steps (no
  !> second half to speak of): its CPU scaled.
  pure real(dp) function predicted_run(cpu, cpu_2, t, t_half, halved, t_probe, t_end) result(p)
    real(dp), intent(in) :: cpu, cpu_2, t, t_half, t_probe, t_end
    logical, intent(in) :: halved
    if (.not. halved .or. t - t_half < 0.25_dp*t_probe) then
      p = cpu*t_end/t
    else
      p = cpu + cpu_2*(t_end - t)/(t - t_half)
    end if
  end function predicted_run

  !> The chosen candidate's probe moved to `run` (not allocated when the probe was not kept).
  subroutine take_chosen(self, run)
    class(method_choice_t), intent(inout) :: self
    type(probe_run), allocatable, intent(out) :: run
    if (self%chosen == 0) return
    if (.not. allocated(self%runs(self%chosen)%st)) return
    allocate(run)
    call move_alloc(self%runs(self%chosen)%st, run%st)
    call move_alloc(self%runs(self%chosen)%model, run%model)
    call move_alloc(self%runs(self%chosen)%rows, run%rows)
    run%nr = self%runs(self%chosen)%nr
  end subroutine take_chosen

  !> A probe that failed or stopped is not kept.
  subroutine forget(run)
    type(probe_run), intent(inout) :: run
    if (allocated(run%st)) deallocate(run%st)
    if (allocated(run%model)) deallocate(run%model)
    if (allocated(run%rows)) deallocate(run%rows)
  end subroutine forget

  !> The dense output of the rows every dt (every step when dt is 0: not kept) up to the
  !> time t_last (the time the probe's stepper has reached, within the run, plus the run's
  !> tolerance on output times), from row k on (k advanced past them), kept in the probe's
  !> rows up to max_probe_rows; beyond, the rows are neither evaluated nor kept (nr = -1).
  subroutine dense_rows(dt, t_last, run, k)
    real(dp), intent(in) :: dt, t_last
    type(probe_run), intent(inout) :: run
    integer, intent(inout) :: k
    real(dp), allocatable :: grown(:, :)
    integer :: stat
    if (dt <= 0.0_dp) then
      call run%st%value_at(run%st%time(), run%rows(:, 1)); run%nr = -1; return
    end if
    do while (k*dt <= t_last .and. run%nr >= 0)
      if (k > size(run%rows, 2)) then
        allocate(grown(size(run%rows, 1), min(2*size(run%rows, 2), max_probe_rows)), stat=stat)
        if (k > max_probe_rows .or. stat /= 0) then
          run%nr = -1; exit
        end if
        grown(:, 1:k-1) = run%rows(:, 1:k-1)
        call move_alloc(grown, run%rows)
      end if
      call run%st%value_at(k*dt, run%rows(:, k))
      run%nr = k
      k = k + 1
    end do
  end subroutine dense_rows

  !> The method of a run of method 'auto' continued from the checkpoint `path`: the one
  !> whose stepper wrote it, set in sc (a file read_checkpoint refuses is refused here).
  subroutine method_of_checkpoint(sc, path, choice, error)
    type(scene_t), intent(inout) :: sc
    character(len=*), intent(in) :: path
    type(method_choice_t), intent(out) :: choice
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: name
    name = checkpoint_stepper(path, error); if (allocated(error)) return
    select case (name)
    case ('exponential')
      call add_candidate(choice, sc, 2)
    case ('response')
      call add_candidate(choice, sc, 3)
    case ('adams', 'single')
      call add_candidate(choice, sc, 1)
    case default
      call fatal_error(error, path // ": the checkpoint was written by the '" // name // "' stepper, which " // &
        & "method 'auto' never chooses: continue it with the scene's method set as it ran")
      return
    end select
    choice%chosen = 1
    call set_method(sc, choice%method(1))
    choice%reason = 'the method the checkpoint was written with'
  end subroutine method_of_checkpoint

  !> One line for the run's summary: "auto: multirate 'exponential' (least CPU over the
  !> probe, 0 to 0.05 s: single-rate 'adams' 4.1 ms, ...)".
  function choice_summary(self) result(s)
    class(method_choice_t), intent(in) :: self
    character(len=:), allocatable :: s
    integer :: i
    s = 'auto: ' // trim(self%label(self%chosen)) // ' (' // self%reason
    if (self%t_probe > 0.0_dp) then
      s = s // '; probes from 0 to ' // fmt(self%t_probe) // ' s:'
      do i = 1, self%n
        s = s // ' ' // trim(self%label(i)) // ' ' // probe_text(self, i) // trim(merge(',', ' ', i < self%n))
      end do
    end if
    s = s // ')'
  end function choice_summary

  function probe_text(self, i) result(s)
    class(method_choice_t), intent(in) :: self
    integer, intent(in) :: i
    character(len=:), allocatable :: s
    if (len_trim(self%failure(i)) > 0) then
      s = merge('stopped', 'failed ', self%failure(i)(1:7) == 'stopped')
      s = trim(s)
    else
      s = milliseconds(self%cpu(i)) // ', run ' // milliseconds(self%predicted(i))
    end if
  end function probe_text

  !> A CPU time t (s) in ms, to 0.01 ms ("12.34 ms").
  function milliseconds(t) result(s)
    real(dp), intent(in) :: t
    character(len=:), allocatable :: s
    character(len=32) :: buf
    write(buf, '(f0.2)') min(1.0e3_dp*t, 1.0e12_dp)
    if (buf(1:1) == '.') buf = '0' // buf(1:len(buf) - 1)
    s = trim(buf) // ' ms'
  end function milliseconds

  !> The JSON member "method_choice": {...}, with its comma and line.
  function choice_json(self) result(s)
    class(method_choice_t), intent(in) :: self
    character(len=:), allocatable :: s
    integer :: i
    s = '  "method_choice": {"chosen": "' // json_escape(trim(self%label(self%chosen))) // '", "reason": "' // &
      & json_escape(self%reason) // '", "probe_t_end": ' // fmt(self%t_probe) // ', "candidates": ['
    do i = 1, self%n
      s = s // '{"method": "' // json_escape(trim(self%label(i))) // '", "probe_cpu_s": '
      if (len_trim(self%failure(i)) > 0 .or. self%t_probe == 0.0_dp) then
        s = s // 'null, "predicted_cpu_s": null'
      else
        s = s // fmt(self%cpu(i)) // ', "predicted_cpu_s": ' // fmt(self%predicted(i))
      end if
      s = s // ', "failure": "' // json_escape(trim(self%failure(i))) // '"}' // trim(merge(', ', '  ', i < self%n))
    end do
    s = s // ']},' // new_line('a')
  end function choice_json
end module pymr_driver_method_choice
