!> The one interface of pymr's time steppers (single-rate Nordsieck ABM, multirate with the
!> 'response' or the paper's 'full' coupling): start, advance one step, the time reached,
!> dense output inside the last step, save and load of the whole state, the counts of what
!> was done, and the linear-stability data of the pre-flight check (the steps its PECE
!> formula takes per kind of coordinate; its whole state as a vector, so that the check can
!> apply the stepper itself to the linearised model). The run loop, the checkpoint and the
!> pre-flight check use nothing else; which stepper a scene gets is chosen once, when it
!> is made.
module pymr_integrator_stepper
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, prefix_error, fatal_error, stat_solver
  use pymr_env_text, only : fmt, itoa
  use pymr_integrator_ode, only : ode_system
  implicit none
  private
  public :: stepper_t, landing_ratio, step_counts, pece_steps, state_record, project_step, step_underflow
  public :: least_step, counts_with

  !> A step whose projection onto the system's constraints fails is redone with its step
  !> times projection_eta, at most max_projection_fails times in one step (adaptive steppers;
  !> fixed steps stop at the first failure): CVODE's defaults (CVodeSetMaxNumProjFails,
  !> CVodeSetProjFailEta).
  integer, parameter :: max_projection_fails = 10
  real(dp), parameter, public :: projection_eta = 0.25_dp

  !> What a stepper has done (its system counts the evaluations).
  type :: step_counts
    !> Accepted steps of the slow and the fast coordinates (equal for single-rate).
    integer :: steps_slow = 0, steps_fast = 0
    !> Rejected steps, and the last step ratio H/h (1 for single-rate).
    integer :: rejected = 0, ratio = 1
    !> The last (slow) step (s).
    real(dp) :: h_last = 0.0_dp
    !> Fast right-hand sides the stepper computed itself, without the model (the
    !> 'response' coupling's surrogate evaluations).
    integer :: evals_fast = 0
    !> Times the stepper froze its linear response anew (the 'exponential' coupling), and
    !> of those, the times it did so for accuracy rather than stability.
    integer :: renewals = 0, accuracy_renewals = 0
  end type step_counts

  !> The fixed steps a stepper's PECE formula takes on vibrations carried mostly by joint
  !> and by modal coordinates (0: none, such modes are judged by the macro-step map alone),
  !> and the &integrator items that set them.
  type :: pece_steps
    real(dp) :: h_joint = 0.0_dp, h_modal = 0.0_dp
    character(len=8) :: item_joint = 'h_slow', item_modal = 'h_slow'
    !> The modal stiffness and damping move by their exact flow (the 'exponential'
    !> coupling): only the rest of the linearised model is judged against the steps.
    logical :: exact_modal = .false.
    !> The macro step's surrogate is exact wherever the model's only stiffness and damping
    !> are the modal ones (the 'response' coupling): on such a linearised model the macro
    !> step is k fast steps of the single-rate formula, judged mode by mode.
    logical :: modal_surrogate = .false.
  end type pece_steps

  !> The part of a stepper's state that its state vector (get_state) does not hold: times,
  !> steps, ratio, counts, histories. A stepper lists these once, in its `record`, for both
  !> directions: saving appends each item to the reals r or the integers k, loading takes
  !> them back in the same order (ok false when the record runs short).
  type :: state_record
    logical :: loading = .false., ok = .true.
    real(dp), allocatable :: r(:)
    integer, allocatable :: k(:)
    integer :: nr = 0, nk = 0
  contains
    procedure, private :: real_0, real_1, real_2, real_3, int_0, int_1, logical_0
    generic :: item => real_0, real_1, real_2, real_3, int_0, int_1, logical_0
    procedure, private :: reals, ints
  end type state_record

  type, abstract :: stepper_t
    !> A time the next steps must not step over (stop_at): a stepper that lands() ends a
    !> step exactly there, so that its caller can start it again past a discontinuity.
    real(dp) :: t_stop = huge(1.0_dp)
  contains
    procedure, non_overridable :: stop_at
    !> Whether its steps land on t_stop (adaptive single-rate); the others step over it.
    procedure :: lands => no_landing
    procedure(start_iface), deferred :: start
    procedure(advance_iface), deferred :: advance
    procedure(time_iface), deferred :: time
    procedure(value_iface), deferred :: value_at
    !> Write (read) the whole state to (from) an open unformatted stream unit: the state
    !> vector and the record, built on get_state and record for every stepper.
    procedure :: save => save_stepper
    procedure :: load => load_stepper
    !> Its record (state_record): the one list of what a checkpoint keeps beside the state
    !> vector.
    procedure(record_iface), deferred :: record
    procedure(counts_iface), deferred :: counts
    procedure(name_iface), deferred :: name
    procedure(steps_iface), deferred :: pece
    procedure(state_size_iface), deferred :: state_size
    procedure(get_state_iface), deferred :: get_state
    procedure(set_state_iface), deferred :: set_state
    !> Step ratio H/h for the next steps (multirate; nothing for single-rate).
    procedure :: set_ratio => no_ratio
    !> Order of the method in the last step (4 for the paper's ABM4).
    procedure :: order => order_four
  end type stepper_t

  abstract interface
    !> Start at (t0, x0) with the (slow) step h.
    subroutine start_iface(self, sys, t0, x0, h, error)
      import :: stepper_t, ode_system, dp, error_type
      class(stepper_t), intent(inout) :: self
      class(ode_system), intent(inout) :: sys
      real(dp), intent(in) :: t0, x0(:), h
      type(error_type), allocatable, intent(out) :: error
    end subroutine start_iface
    !> One accepted (macro) step, its state projected onto the system's constraints
    !> (project_step): every caller retraces the same steps.
    subroutine advance_iface(self, sys, error)
      import :: stepper_t, ode_system, error_type
      class(stepper_t), intent(inout) :: self
      class(ode_system), intent(inout) :: sys
      type(error_type), allocatable, intent(out) :: error
    end subroutine advance_iface
    pure real(dp) function time_iface(self)
      import :: stepper_t, dp
      class(stepper_t), intent(in) :: self
    end function time_iface
    !> The state at t inside the last step.
    pure subroutine value_iface(self, t, x)
      import :: stepper_t, dp
      class(stepper_t), intent(in) :: self
      real(dp), intent(in) :: t
      real(dp), intent(out) :: x(:)
    end subroutine value_iface
    !> Pass every item of the record through rec (saving or loading).
    subroutine record_iface(self, rec)
      import :: stepper_t, state_record
      class(stepper_t), intent(inout) :: self
      type(state_record), intent(inout) :: rec
    end subroutine record_iface
    pure function counts_iface(self) result(c)
      import :: stepper_t, step_counts
      class(stepper_t), intent(in) :: self
      type(step_counts) :: c
    end function counts_iface
    !> 'single' or 'multirate' (checkpoints name the stepper they hold).
    pure function name_iface(self) result(s)
      import :: stepper_t
      class(stepper_t), intent(in) :: self
      character(len=:), allocatable :: s
    end function name_iface
    !> Its fixed steps, for the pre-flight check.
    pure function steps_iface(self) result(s)
      import :: stepper_t, pece_steps
      class(stepper_t), intent(in) :: self
      type(pece_steps) :: s
    end function steps_iface
    !> Length of its whole state as a vector.
    pure integer function state_size_iface(self)
      import :: stepper_t
      class(stepper_t), intent(in) :: self
    end function state_size_iface
    !> Its whole state as a vector v: v(1:2n) the state [q; qd] at its time, then the rest
    !> (higher Nordsieck columns, histories) in an order of its own.
    pure subroutine get_state_iface(self, v)
      import :: stepper_t, dp
      class(stepper_t), intent(in) :: self
      real(dp), intent(out) :: v(:)
    end subroutine get_state_iface
    pure subroutine set_state_iface(self, v)
      import :: stepper_t, dp
      class(stepper_t), intent(inout) :: self
      real(dp), intent(in) :: v(:)
    end subroutine set_state_iface
  end interface

contains

  !> The counts of a run whose stepper `now` took over from earlier ones (counts `before`):
  !> steps, rejections and evaluations added; the last step and ratio the stepper's now.
  pure function counts_with(before, now) result(c)
    type(step_counts), intent(in) :: before, now
    type(step_counts) :: c
    c = now
    c%steps_slow = before%steps_slow + now%steps_slow
    c%steps_fast = before%steps_fast + now%steps_fast
    c%rejected = before%rejected + now%rejected
    c%evals_fast = before%evals_fast + now%evals_fast
  end function counts_with

  !> Project the state x a step reached at t onto the system's constraints (sys%project),
  !> inside the stepper's advance once the step passed its error test. When that fails, an
  !> adaptive stepper redoes the step smaller: retry is true, fails counts the failures of
  !> this step; otherwise (fixed steps, or max_projection_fails reached) the error, which
  !> names the time.
  subroutine project_step(sys, t, x, adaptive, fails, retry, error)
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: x(:)
    logical, intent(in) :: adaptive
    integer, intent(inout) :: fails
    logical, intent(out) :: retry
    type(error_type), allocatable, intent(out) :: error
    retry = .false.
    call sys%project(t, x, error)
    if (.not. allocated(error)) return
    if (adaptive .and. fails < max_projection_fails) then
      fails = fails + 1; retry = .true.
      deallocate(error); return
    end if
    if (fails > 0) error%message = error%message // ' (the step redone ' // itoa(fails) // ' times smaller)'
    call prefix_error(error, 'at t = ' // fmt(t) // ' s')
  end subroutine project_step

  !> The least step an adaptive stepper takes at time t: h_min, and no less than the time's
  !> resolution (100 eps |t|: a smaller step leaves t where it was).
  pure real(dp) function least_step(h_min, t) result(h)
    real(dp), intent(in) :: h_min, t
    h = max(h_min, 100.0_dp*epsilon(1.0_dp)*abs(t))
  end function least_step

  !> The failure of a step (what: 'step' or 'fast step') of h below h_min at time t.
  subroutine step_underflow(error, t, what, h)
    type(error_type), allocatable, intent(out) :: error
    real(dp), intent(in) :: t, h
    character(len=*), intent(in) :: what
    call fatal_error(error, 'step size underflow at t = ' // fmt(t) // ' s (' // what // ' ' // fmt(h) // &
      & ' s below h_min)', stat_solver)
  end subroutine step_underflow

  !> The state vector's length and values, then the record's sizes and items.
  subroutine save_stepper(self, unit, ios)
    class(stepper_t), intent(inout) :: self
    integer, intent(in) :: unit
    integer, intent(out) :: ios
    real(dp) :: v(self%state_size())
    type(state_record) :: rec
    call self%get_state(v)
    allocate(rec%r(0), rec%k(0))
    call self%record(rec)
    write(unit, iostat=ios) size(v), v, rec%nr, rec%nk, rec%r(1:rec%nr), rec%k(1:rec%nk)
  end subroutine save_stepper

  !> Read what save_stepper wrote into a stepper made for the same scene; ios /= 0 when the
  !> sizes do not match it.
  subroutine load_stepper(self, unit, ios)
    class(stepper_t), intent(inout) :: self
    integer, intent(in) :: unit
    integer, intent(out) :: ios
    real(dp) :: v(self%state_size())
    type(state_record) :: rec
    integer :: nv, nr, nk
    read(unit, iostat=ios) nv
    if (ios /= 0) return
    if (nv /= size(v)) then
      ios = 1; return
    end if
    read(unit, iostat=ios) v, nr, nk
    if (ios /= 0) return
    if (nr < 0 .or. nk < 0) then
      ios = 1; return
    end if
    allocate(rec%r(nr), rec%k(nk), stat=ios)
    if (ios /= 0) return
    read(unit, iostat=ios) rec%r, rec%k
    if (ios /= 0) return
    rec%loading = .true.
    call self%record(rec)
    if (.not. rec%ok .or. rec%nr /= nr .or. rec%nk /= nk) then
      ios = 1; return
    end if
    call self%set_state(v)
  end subroutine load_stepper

  !> Append x to the reals (saving) or take them back from them (loading).
  subroutine reals(rec, x)
    class(state_record), intent(inout) :: rec
    real(dp), intent(inout) :: x(:)
    real(dp), allocatable :: grown(:)
    integer :: m
    m = size(x)
    if (rec%loading) then
      if (rec%nr + m > size(rec%r)) rec%ok = .false.
      if (rec%ok) x = rec%r(rec%nr+1:rec%nr+m)
    else
      if (rec%nr + m > size(rec%r)) then
        allocate(grown(max(2*size(rec%r), rec%nr + m, 16)))
        grown(1:rec%nr) = rec%r(1:rec%nr); call move_alloc(grown, rec%r)
      end if
      rec%r(rec%nr+1:rec%nr+m) = x
    end if
    rec%nr = rec%nr + m
  end subroutine reals

  !> Append x to the integers (saving) or take them back from them (loading).
  subroutine ints(rec, x)
    class(state_record), intent(inout) :: rec
    integer, intent(inout) :: x(:)
    integer, allocatable :: grown(:)
    integer :: m
    m = size(x)
    if (rec%loading) then
      if (rec%nk + m > size(rec%k)) rec%ok = .false.
      if (rec%ok) x = rec%k(rec%nk+1:rec%nk+m)
    else
      if (rec%nk + m > size(rec%k)) then
        allocate(grown(max(2*size(rec%k), rec%nk + m, 16)))
        grown(1:rec%nk) = rec%k(1:rec%nk); call move_alloc(grown, rec%k)
      end if
      rec%k(rec%nk+1:rec%nk+m) = x
    end if
    rec%nk = rec%nk + m
  end subroutine ints

  subroutine real_0(rec, x)
    class(state_record), intent(inout) :: rec
    real(dp), intent(inout) :: x
    real(dp) :: a(1)
    a(1) = x; call rec%reals(a); x = a(1)
  end subroutine real_0

  subroutine real_1(rec, x)
    class(state_record), intent(inout) :: rec
    real(dp), intent(inout) :: x(:)
    call rec%reals(x)
  end subroutine real_1

  subroutine real_2(rec, x)
    class(state_record), intent(inout) :: rec
    real(dp), intent(inout) :: x(:, :)
    real(dp) :: a(size(x))
    a = reshape(x, [size(x)]); call rec%reals(a); x = reshape(a, shape(x))
  end subroutine real_2

  subroutine real_3(rec, x)
    class(state_record), intent(inout) :: rec
    real(dp), intent(inout) :: x(:, :, :)
    real(dp) :: a(size(x))
    a = reshape(x, [size(x)]); call rec%reals(a); x = reshape(a, shape(x))
  end subroutine real_3

  subroutine int_0(rec, x)
    class(state_record), intent(inout) :: rec
    integer, intent(inout) :: x
    integer :: a(1)
    a(1) = x; call rec%ints(a); x = a(1)
  end subroutine int_0

  subroutine int_1(rec, x)
    class(state_record), intent(inout) :: rec
    integer, intent(inout) :: x(:)
    call rec%ints(x)
  end subroutine int_1

  subroutine logical_0(rec, x)
    class(state_record), intent(inout) :: rec
    logical, intent(inout) :: x
    integer :: a(1)
    a(1) = merge(1, 0, x); call rec%ints(a); x = a(1) /= 0
  end subroutine logical_0

  !> The next steps end at t_stop when they would pass it (huge: no stop).
  pure subroutine stop_at(self, t_stop)
    class(stepper_t), intent(inout) :: self
    real(dp), intent(in) :: t_stop
    self%t_stop = t_stop
  end subroutine stop_at

  pure logical function no_landing(self)
    class(stepper_t), intent(in) :: self
    no_landing = .false.
  end function no_landing

  !> The step h from t shortened to end on t_stop when it would pass it: the factor to
  !> rescale the step by (1: no change).
  pure real(dp) function landing_ratio(t, h, t_stop) result(eta)
    real(dp), intent(in) :: t, h, t_stop
    eta = 1.0_dp
    if (t < t_stop .and. t + h > t_stop) eta = (t_stop - t)/h
  end function landing_ratio

  pure integer function order_four(self)
    class(stepper_t), intent(in) :: self
    order_four = 4
  end function order_four

  pure subroutine no_ratio(self, k)
    class(stepper_t), intent(inout) :: self
    integer, intent(in) :: k
  end subroutine no_ratio
end module pymr_integrator_stepper
