!> Single-rate Nordsieck Adams-Bashforth-Moulton integrator (fixed step or adaptive).
!>
!> The integrator owns its Nordsieck arrays and work vectors (allocated once in `init`)
!> and reaches the model only through `ode_system%eval`.
module pymr_integrator_abm
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_integrator_ode, only : ode_system
  use pymr_integrator_nordsieck, only : nq, corrector_l, nordsieck_predict, nordsieck_correct, &
    & nordsieck_rescale, nordsieck_value, nordsieck_from_history
  use pymr_integrator_control, only : step_control, error_weights, wrms_norm
  use pymr_integrator_stepper, only : stepper_t, step_counts, pece_steps, state_record, project_step, projection_eta, &
    & landing_ratio, step_underflow
  implicit none
  private
  public :: abm_integrator, rk4_step, check_finite, hinit, pece_step

  !> Nordsieck ABM integrator state.
  type, extends(stepper_t) :: abm_integrator
    !> Number of state components.
    integer :: n = 0
    !> Time of the Nordsieck array (s); the start time (fixed steps reach t0 + n h with an
    !> integer n, not a sum of steps).
    real(dp) :: t = 0.0_dp, t0 = 0.0_dp
    !> Current step (s): set by init, changed by the stepper only.
    real(dp), private :: h = 0.0_dp
    !> Nordsieck array z(n, 0:3) at time t, scaled with h.
    real(dp), allocatable :: z(:, :)
    !> Number of corrector evaluations per step (1 = PECE).
    integer :: n_corr = 1
    !> Adaptive step control on or off, and its settings.
    logical :: adaptive = .false.
    type(step_control) :: ctl
    !> Counters: accepted steps, rejected steps, evaluations of f.
    integer :: steps = 0, rejected = 0, evals = 0
    !> Work arrays.
    real(dp), allocatable :: zp(:, :), zn(:, :), f(:), g(:), x(:), w(:)
  contains
    procedure :: init => abm_init
    procedure :: start => abm_start
    procedure :: advance => abm_step
    procedure :: time => abm_time
    procedure :: value_at => abm_value_at
    procedure :: record => abm_record
    procedure :: counts => abm_counts
    procedure :: name => abm_name
    procedure :: pece => abm_steps
    procedure :: state_size => abm_state_size
    procedure :: get_state => abm_get_state
    procedure :: set_state => abm_set_state
    procedure :: lands => abm_lands
  end type abm_integrator

contains

  !> Allocate the arrays for `n` components and set the options and the step h (s) the
  !> start takes (the pre-flight check reads it before the start).
  subroutine abm_init(self, n, adaptive, ctl, n_corr, h)
    class(abm_integrator), intent(inout) :: self
    integer, intent(in) :: n
    logical, intent(in) :: adaptive
    type(step_control), intent(in) :: ctl
    integer, intent(in) :: n_corr
    real(dp), intent(in), optional :: h
    self%n = n
    if (present(h)) self%h = h
    self%adaptive = adaptive
    self%ctl = ctl
    self%n_corr = max(1, n_corr)
    if (allocated(self%z)) deallocate(self%z, self%zp, self%zn, self%f, self%g, self%x, self%w)
    allocate(self%z(n, 0:nq), self%zp(n, 0:nq), self%zn(n, 0:nq), self%f(n), self%g(n), self%x(n), self%w(n))
    self%steps = 0; self%rejected = 0; self%evals = 0
  end subroutine abm_init

  !> Start at (t0, x0): two classical Runge-Kutta steps of size h (local error O(h^5),
  !> so the global order 4 is kept), then the Nordsieck array from f at the three points.
  !> An adaptive run first bounds h by a starting-step estimate from the tolerances, and
  !> by a quarter of the way to t_stop (its steps take no error estimate to land on it).
  subroutine abm_start(self, sys, t0, x0, h, error)
    class(abm_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: t0, x0(:), h
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: f0(:), f1(:), f2(:), x(:)
    real(dp) :: hs
    logical :: accepted
    allocate(f0(self%n), f1(self%n), f2(self%n), x(self%n))
    x = x0
    call sys%eval(t0, x, f0, error); self%evals = self%evals + 1
    if (allocated(error)) return
    call check_finite(sys, t0, f0, 'derivative', error); if (allocated(error)) return
    hs = h
    if (self%adaptive) then
      call hinit(self, sys, t0, x0, f0, hs, error); if (allocated(error)) return
      hs = min(h, hs)
      if (t0 < self%t_stop) hs = min(hs, 0.25_dp*(self%t_stop - t0))   ! the start's steps end before a stop
    end if
    do
      x = x0
      call rk4_step(sys, t0, hs, x, f0, self%evals, error); if (allocated(error)) return
      call sys%eval(t0 + hs, x, f1, error); self%evals = self%evals + 1
      if (allocated(error)) return
      call rk4_step(sys, t0 + hs, hs, x, f1, self%evals, error); if (allocated(error)) return
      if (.not. self%adaptive) exit
      call check_start_steps(self, sys, t0, x0, f0, x, hs, accepted, error); if (allocated(error)) return
      if (accepted) exit
    end do
    call sys%eval(t0 + 2*hs, x, f2, error); self%evals = self%evals + 1
    if (allocated(error)) return
    call check_finite(sys, t0 + 2*hs, x, 'state', error); if (allocated(error)) return
    call nordsieck_from_history(x, f2, f1, f0, hs, self%z)
    self%t0 = t0
    self%t = t0 + 2*hs
    self%h = hs
    ! a fixed-step run counts its time in steps from t0; an adaptive one started again (past
    ! a discontinuity) keeps counting
    self%steps = merge(self%steps + 2, 2, self%adaptive)
  end subroutine abm_start

  !> An adaptive start's two Runge-Kutta steps of hs from (t0, x0) that ended at x, checked
  !> against one step of 2 hs: x's error is (x - x_2hs)/15 (Richardson, order 4). Accepted
  !> within the tolerance, else hs is made smaller to be tried again: the starting-step
  !> estimate knows nothing of a load that a pulse adds past its first evaluations, nor
  !> of a vibration already going when the run starts again past a stop.
  subroutine check_start_steps(self, sys, t0, x0, f0, x, hs, accepted, error)
    class(abm_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: t0, x0(:), f0(:), x(:)
    real(dp), intent(inout) :: hs
    logical, intent(out) :: accepted
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: x2(:)
    real(dp) :: err
    x2 = x0
    call rk4_step(sys, t0, 2*hs, x2, f0, self%evals, error); if (allocated(error)) return
    call error_weights(self%ctl, x, self%w)
    err = wrms_norm((x - x2)/15.0_dp, self%w)
    accepted = err <= 1.0_dp
    if (accepted) return
    self%rejected = self%rejected + 1
    hs = hs*self%ctl%ratio(err, .false., 5)
    if (hs < self%ctl%h_min) call step_underflow(error, t0, 'step', hs)
  end subroutine check_start_steps

  !> Starting step from the tolerances (Hairer, Norsett and Wanner, order 4), capped by h_max.
  subroutine hinit(self, sys, t0, x0, f0, h, error)
    class(abm_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: t0, x0(:), f0(:)
    real(dp), intent(out) :: h
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: d0, d1, d2, h0, h1
    real(dp), allocatable :: x1(:), f1(:)
    allocate(x1(size(x0)), f1(size(x0)))
    call error_weights(self%ctl, x0, self%w)
    d0 = wrms_norm(x0, self%w); d1 = wrms_norm(f0, self%w)
    if (d0 < 1.0e-5_dp .or. d1 < 1.0e-5_dp) then
      h0 = 1.0e-6_dp
    else
      h0 = 0.01_dp*d0/d1
    end if
    h0 = min(h0, self%ctl%h_max)
    x1 = x0 + h0*f0
    call sys%eval(t0 + h0, x1, f1, error); self%evals = self%evals + 1
    if (allocated(error)) return
    d2 = wrms_norm(f1 - f0, self%w)/h0
    if (max(d1, d2) <= 1.0e-15_dp) then
      h1 = max(1.0e-6_dp, h0*1.0e-3_dp)
    else
      h1 = (0.01_dp/max(d1, d2))**0.2_dp
    end if
    h = min(100*h0, h1, self%ctl%h_max)
  end subroutine hinit

  !> One step of the classical 4th-order Runge-Kutta method; x is advanced in place.
  !> `f0` is f(t, x) on entry; `evals` counts evaluations.
  subroutine rk4_step(sys, t, h, x, f0, evals, error)
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: t, h
    real(dp), intent(inout) :: x(:)
    real(dp), intent(in) :: f0(:)
    integer, intent(inout) :: evals
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: k2(:), k3(:), k4(:)
    allocate(k2(size(x)), k3(size(x)), k4(size(x)))
    call sys%eval(t + 0.5_dp*h, x + 0.5_dp*h*f0, k2, error); if (allocated(error)) return
    call sys%eval(t + 0.5_dp*h, x + 0.5_dp*h*k2, k3, error); if (allocated(error)) return
    call sys%eval(t + h, x + h*k3, k4, error); if (allocated(error)) return
    evals = evals + 3
    x = x + h*(f0 + 2*k2 + 2*k3 + k4)/6.0_dp
  end subroutine rk4_step

  !> Advance one accepted step. Fixed step: one predictor, `n_corr` evaluations and
  !> corrections. Adaptive: the corrector-predictor difference is the local error
  !> estimate; a rejected step is retried smaller, an accepted one may change h next time.
  !> The accepted state is projected onto the system's constraints; a step whose projection
  !> fails is retried smaller too (project_step).
  subroutine abm_step(self, sys, error)
    class(abm_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: err, eta, tn
    integer :: projection_fails
    logical :: retry
    projection_fails = 0
    do
      tn = self%t + self%h
      if (.not. self%adaptive) tn = self%t0 + (self%steps + 1)*self%h
      if (self%adaptive) call land(self, tn)
      call try_step(self, sys, tn, error); if (allocated(error)) return
      err = 0.0_dp
      if (self%adaptive) then
        call error_weights(self%ctl, self%z(:, 0), self%w)
        err = abs(corrector_l(0))*wrms_norm(self%g, self%w)
      end if
      if (err <= 1.0_dp) then
        call check_finite(sys, tn, self%zn(:, 0), 'state', error); if (allocated(error)) return
        call project_step(sys, tn, self%zn(:, 0), self%adaptive, projection_fails, retry, error)
        if (allocated(error)) return
        if (.not. retry) exit
        eta = projection_eta
      else
        eta = self%ctl%ratio(err, .false.)
      end if
      self%rejected = self%rejected + 1
      if (eta*self%h < self%ctl%h_min) then
        call step_underflow(error, self%t, 'step', eta*self%h)
        return
      end if
      call nordsieck_rescale(self%z, eta)
      self%h = eta*self%h
    end do
    self%z = self%zn
    self%t = tn
    self%steps = self%steps + 1
    if (.not. self%adaptive) return
    eta = min(self%ctl%ratio(err, .true.), self%ctl%h_max/self%h)
    if (eta /= 1.0_dp) then
      call nordsieck_rescale(self%z, eta)
      self%h = eta*self%h
    end if
  end subroutine abm_step

  !> An adaptive step that would pass t_stop shortened to end on it (tn then t_stop).
  pure subroutine land(self, tn)
    class(abm_integrator), intent(inout) :: self
    real(dp), intent(inout) :: tn
    real(dp) :: eta
    eta = landing_ratio(self%t, self%h, self%t_stop)
    if (eta == 1.0_dp) return
    call nordsieck_rescale(self%z, eta)
    self%h = eta*self%h
    tn = self%t_stop
  end subroutine land

  !> An adaptive run's steps land on t_stop.
  pure logical function abm_lands(self)
    class(abm_integrator), intent(in) :: self
    abm_lands = self%adaptive
  end function abm_lands

  !> Predict from z, evaluate and correct n_corr times; result in zn and g.
  subroutine try_step(self, sys, tn, error)
    class(abm_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: tn
    type(error_type), allocatable, intent(out) :: error
    call pece_step(sys, tn, self%h, self%n_corr, self%z, self%zp, self%zn, self%x, self%f, self%g, self%evals, error)
  end subroutine try_step

  !> One step of the Nordsieck ABM formula to tn of the array z (scaled with the step h):
  !> predicted into zp, then n_corr times evaluated (f at x) and corrected into zn, with the
  !> correction g; evals counts the evaluations. The single-rate stepper's step, and the
  !> 'full' multirate coupling's fast steps (on the fast equations with the slow motion
  !> extrapolated).
  subroutine pece_step(sys, tn, h, n_corr, z, zp, zn, x, f, g, evals, error)
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: tn, h
    integer, intent(in) :: n_corr
    real(dp), intent(in) :: z(:, 0:)
    real(dp), intent(out) :: zp(:, 0:), zn(:, 0:), x(:), f(:), g(:)
    integer, intent(inout) :: evals
    type(error_type), allocatable, intent(out) :: error
    integer :: m
    call nordsieck_predict(z, zp)
    x = zp(:, 0)
    do m = 1, n_corr
      call sys%eval(tn, x, f, error); evals = evals + 1
      if (allocated(error)) return
      call check_finite(sys, tn, f, 'derivative', error); if (allocated(error)) return
      call nordsieck_correct(zp, h, f, zn, g)
      x = zn(:, 0)
    end do
  end subroutine pece_step

  !> State at time t from the Nordsieck polynomial of the last step (dense output).
  pure subroutine abm_value_at(self, t, x)
    class(abm_integrator), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(out) :: x(:)
    call nordsieck_value(self%z, (t - self%t)/self%h, x)
  end subroutine abm_value_at

  pure real(dp) function abm_time(self)
    class(abm_integrator), intent(in) :: self
    abm_time = self%t
  end function abm_time

  !> What a checkpoint keeps beside the Nordsieck array: times, step, counts.
  subroutine abm_record(self, rec)
    class(abm_integrator), intent(inout) :: self
    type(state_record), intent(inout) :: rec
    call rec%item(self%t); call rec%item(self%h); call rec%item(self%t0)
    call rec%item(self%steps); call rec%item(self%rejected); call rec%item(self%evals)
  end subroutine abm_record

  pure function abm_counts(self) result(c)
    class(abm_integrator), intent(in) :: self
    type(step_counts) :: c
    c%steps_slow = self%steps; c%steps_fast = self%steps
    c%rejected = self%rejected; c%h_last = self%h; c%ratio = 1
  end function abm_counts

  pure function abm_name(self) result(s)
    class(abm_integrator), intent(in) :: self
    character(len=:), allocatable :: s
    s = 'single'
  end function abm_name

  !> One step h for every coordinate (&integrator h_slow).
  pure function abm_steps(self) result(s)
    class(abm_integrator), intent(in) :: self
    type(pece_steps) :: s
    s%h_joint = self%h; s%h_modal = self%h
  end function abm_steps

  pure integer function abm_state_size(self)
    class(abm_integrator), intent(in) :: self
    abm_state_size = size(self%z)
  end function abm_state_size

  !> The Nordsieck array, column by column (its value column, the state, first).
  pure subroutine abm_get_state(self, v)
    class(abm_integrator), intent(in) :: self
    real(dp), intent(out) :: v(:)
    v = reshape(self%z, [size(self%z)])
  end subroutine abm_get_state

  pure subroutine abm_set_state(self, v)
    class(abm_integrator), intent(inout) :: self
    real(dp), intent(in) :: v(:)
    self%z = reshape(v, shape(self%z))
  end subroutine abm_set_state

  !> Error naming the first non-finite component of v (component map(i) of the system).
  subroutine check_finite(sys, t, v, what, error, map)
    class(ode_system), intent(in) :: sys
    real(dp), intent(in) :: t, v(:)
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    integer, intent(in), optional :: map(:)
    integer :: i, j
    character(len=40) :: buf
    do i = 1, size(v)
      if (v(i) /= v(i) .or. abs(v(i)) > huge(1.0_dp)) then
        write(buf, '(es12.5)') t
        j = i
        if (present(map)) j = map(i)
        call fatal_error(error, 'non-finite ' // what // ' of ' // sys%component_name(j) // &
          & ' at t = ' // trim(adjustl(buf)) // ' s', stat_solver)
        return
      end if
    end do
  end subroutine check_finite

end module pymr_integrator_abm
