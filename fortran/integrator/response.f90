!> Multirate integration by fast linear response: the 'response' coupling (docs/method.md,
!> section "The response coupling").
!>
!> One Nordsieck ABM array of the whole state [q; qd] advances with the fast step h. Every
!> k-th step (a macro step H = k h) evaluates the model in full; the k - 1 steps between
!> use a cheap surrogate of the accelerations, built from the last full evaluations:
!>
!>   qdd(t, x) ~ qdd^(t) - g (kf (a - a^(t)) + df (ad - ad^(t)))
!>
!> where qdd^, a^ and ad^ are the accelerations and the fast (modal) state of the last
!> four full evaluations extrapolated to t by one cubic (the same weights for all of them),
!> and g = M^-1 E is the response of every acceleration to a unit force on each modal
!> coordinate, at the last full evaluation. The surrogate is the extrapolated acceleration
!> corrected by the linear response of all coordinates, joints included, to the elastic and
!> damping forces of the fast state's departure from its extrapolation: the fast motion the
!> joints take from the flexible bodies is integrated at the fast rate, the rest of the
!> acceleration, smooth once that response is removed, comes from the slow-rate history.
!> A step costs one product of g (n x nf) with a vector instead of a model evaluation.
!>
!> At every full evaluation the surrogate's error is measured as the difference of the full
!> and the surrogate accelerations at the same state. Grown over the macro step as the
!> cubic's extrapolation error grows, and integrated, it is the error the surrogate left in
!> the state; the macro step ends with that error taken out of its state and of its fast
!> steps' arrays (a corrected surrogate: on a flexible four-bar, whose crank keeps every
!> phase error, it ended 10-25x nearer the converged motion, at the same steps). Adaptive
!> runs control the fast step by the ABM correctors' estimates summed over the macro step
!> (the error its k fast steps leave in its end state) and the macro step by the
!> surrogate's error left after that correction: what the last macro step's error model
!> failed to predict of this one's (docs/method.md section 4.2).
module pymr_integrator_response
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_integrator_ode, only : ode_system, partitioned_system
  use pymr_integrator_stepper, only : stepper_t, step_counts, pece_steps, state_record, project_step, projection_eta, step_underflow, &
    & landing_ratio
  use pymr_integrator_nordsieck, only : nq, corrector_l, nordsieck_predict, nordsieck_correct, nordsieck_rescale, &
    & nordsieck_value
  use pymr_integrator_abm, only : abm_integrator, check_finite
  use pymr_integrator_control, only : step_control, error_weights, wrms_norm, error_envelope
  implicit none
  private
  public :: response_integrator

  !> Full evaluations the surrogate extrapolates from (a cubic).
  integer, parameter :: n_hist = 4
  !> Order in H of the macro step's error estimate: the cubic's extrapolation error d is
  !> O(H^4), and the rate error it leaves over the step O(H^5). (The exponent 1/4 of the
  !> fast steps' rule over-shot it: on the flexible four-bar 16 % of the macro steps were
  !> rejected at rtol 1e-4, 9 % with 1/5.)
  integer, parameter :: surrogate_order = 5
  !> Adaptive runs: macro steps in a row that may break down (a failed factorisation, a
  !> non-finite value) and be retried smaller before the run stops.
  integer, parameter :: max_breakdowns = 10
  !> The most a macro step's error estimate credits the correction with: at least this
  !> fraction of the error before it. The estimate after the correction is the difference
  !> of two samples of the surrogate's error and can be small by chance. On the flexible
  !> four-bar (17 tolerances, k_max = 50) floors of 0.2 / 0.3 / 0.5 / 1 took 194k / 199k /
  !> 208k / 229k full evaluations and ended at most 1.74 / 1.12 / 1.76 / 1.53 rtol away
  !> (docs/method.md section 4.2).
  real(dp), parameter :: credited_correction = 0.3_dp
  !> The most the step ratio k grows from one macro step to the next (at least by one).
  !> The surrogate is a multistep extrapolation, and a macro step longer than the
  !> history's spacing reaches where its error model holds least: on the tank, with growth
  !> up to the controller's 4x, adaptive runs ended 1.5x further from the converged motion
  !> than with 10 % at the same evaluations (81 tolerances, rtol 3e-5 to 3e-7), and their
  !> errors scattered 1.37x about the fit against 1.25x. No change on the stiff barrel
  !> (docs/method.md section 4.2). In whole per cent, so that the bound is exact.
  integer, parameter :: ratio_growth_percent = 10

  !> History of full evaluations, oldest first: nh times, accelerations (n, nh), fast
  !> states [a; ad] (2nf, nh); g of the newest, and the fast force coefficients; the full
  !> evaluation of the macro step being tried (tp, qp, yp, gp), kept until it is accepted.
  type :: response_history_t
    integer :: nh = 0
    real(dp) :: th(n_hist) = 0.0_dp
    !> The Lagrange weights' denominators, and the times they are for (history_weights).
    real(dp) :: den(n_hist) = 0.0_dp, th_den(n_hist) = -huge(1.0_dp)
    real(dp), allocatable :: hq(:, :), hy(:, :), g(:, :), kf(:), df(:)
    real(dp) :: tp = 0.0_dp
    real(dp), allocatable :: qp(:), yp(:), gp(:, :)
  end type response_history_t

  !> What a 'response' run has done: macro steps, fast steps, rejected macro steps,
  !> surrogate evaluations.
  type :: response_counts_t
    integer :: steps_slow = 0, steps_fast = 0, rejected = 0, evals_surrogate = 0
  end type response_counts_t

  !> Work arrays of a macro step.
  type :: response_work_t
    real(dp), allocatable :: zp(:, :), z0(:, :), f(:), fs(:), x(:), cor(:), w(:), e(:), dforce(:)
    !> The surrogate's error coefficient d / P(t1) of the macro step being tried.
    real(dp), allocatable :: c(:)
  end type response_work_t

  type, extends(stepper_t) :: response_integrator
    !> Coordinates (n = ns + nf), step ratio k and its adaptive bound; fast steps of the next
    !> macro step (k, but k - 2 after the start's two steps: macro steps end on multiples of
    !> k h in fixed-step runs).
    integer :: n = 0, ns = 0, nf = 0, k = 1, k_max = 1, kn = 1
    !> Time of the Nordsieck array; start and fast step of the last macro step; the run's
    !> start (fixed steps reach t0 + n h with an integer n, not a sum of steps).
    real(dp) :: t = 0.0_dp, t_macro = 0.0_dp, hb = 0.0_dp, t0 = 0.0_dp
    !> Fast step (s): set by init, changed by the stepper only.
    real(dp), private :: h = 0.0_dp
    !> Nordsieck array (2n, 0:3) scaled with h; the arrays after each fast step of the last
    !> macro step (dense output, scaled with hb), kb of them.
    real(dp), allocatable :: z(:, :), zbuf(:, :, :)
    integer :: kb = 0
    !> Whether macro steps take the surrogate's error out of their state (set before the
    !> start: the pre-flight check of a fixed-step run turns it off where the macro step is
    !> stable only without it).
    logical :: correct = .true.
    !> The correction of the last macro step (correct_surrogate_error), when it had one: the
    !> surrogate's error d_c (n) at its end t_c, the history times th_c it grew from. The
    !> arrays of its fast steps before the last are kept uncorrected; value_at adds it.
    logical :: corrected = .false.
    real(dp) :: t_c = 0.0_dp, th_c(n_hist) = 0.0_dp
    real(dp), allocatable :: d_c(:)
    !> The error model of the last accepted macro step, when it used the surrogate (k > 1):
    !> its coefficient c = d / P(t1) (the cubic's extrapolation error is c P(t)). One kept
    !> over single-step macro steps went stale: after tank_firing's recoil a c from inside
    !> the pulse refused every later try.
    logical :: c_known = .false.
    real(dp), allocatable :: c_last(:)
    !> History of full evaluations.
    type(response_history_t) :: hist
    !> Adaptive control of both steps (ctl%h_max bounds the fast step).
    logical :: adaptive = .false.
    type(step_control) :: ctl
    !> The macro step being tried ends on t_stop (land_macro_step).
    logical :: landing = .false.
    !> The last accepted macro step's surrogate error and length.
    type(error_envelope) :: last_macro
    !> Counters.
    type(response_counts_t) :: cnt
    !> Work arrays.
    type(response_work_t) :: wk
  contains
    procedure :: init => rs_init
    procedure :: start => rs_start
    procedure :: advance => rs_advance
    procedure :: time => rs_time
    procedure :: value_at => rs_value_at
    procedure :: record => rs_record
    procedure :: counts => rs_counts
    procedure :: name => rs_name
    procedure :: pece => rs_steps
    procedure :: state_size => rs_state_size
    procedure :: get_state => rs_get_state
    procedure :: set_state => rs_set_state
    procedure :: set_ratio => rs_set_ratio
    procedure :: lands => rs_lands
  end type response_integrator

contains

  !> Allocate for ns slow (joint) and nf fast (modal) coordinates, step ratio k; adaptive
  !> runs control both steps with ctl and keep k within [1, k_max]; h: the fast step the
  !> start takes (the pre-flight check reads it before the start).
  subroutine rs_init(self, ns, nf, k, adaptive, ctl, k_max, h)
    class(response_integrator), intent(inout) :: self
    integer, intent(in) :: ns, nf, k
    logical, intent(in) :: adaptive
    type(step_control), intent(in) :: ctl
    integer, intent(in) :: k_max
    real(dp), intent(in) :: h
    integer :: n
    n = ns + nf
    self%h = h
    self%n = n; self%ns = ns; self%nf = nf
    self%adaptive = adaptive; self%ctl = ctl
    self%k_max = max(1, k_max, merge(1, k, adaptive))
    self%k = min(max(1, k), self%k_max)
    allocate(self%z(2*n, 0:nq), self%wk%zp(2*n, 0:nq), self%wk%z0(2*n, 0:nq), self%zbuf(2*n, 0:nq, self%k))
    allocate(self%hist%hq(n, n_hist), self%hist%hy(2*nf, n_hist), self%hist%g(n, nf), self%hist%kf(nf), self%hist%df(nf))
    allocate(self%hist%qp(n), self%hist%yp(2*nf), self%hist%gp(n, nf))
    allocate(self%wk%f(2*n), self%wk%fs(2*n), self%wk%x(2*n), self%wk%cor(2*n), self%wk%w(2*n), self%wk%e(2*n), &
      & self%wk%dforce(nf), self%d_c(n), self%wk%c(n), self%c_last(n))
  end subroutine rs_init

  !> Start at (t0, x0) with the fast step h (adaptive: bounded by the tolerances): a full
  !> evaluation at t0 opens the history, the single-rate start (two Runge-Kutta steps)
  !> builds the Nordsieck array. Until the history holds four full evaluations every fast
  !> step evaluates in full.
  subroutine rs_start(self, sys, t0, x0, h, error)
    class(response_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: t0, x0(:), h
    type(error_type), allocatable, intent(out) :: error
    type(abm_integrator) :: boot
    type(step_counts) :: booted
    select type (sys)
    class is (partitioned_system)
      call sys%eval(t0, x0, self%wk%f, error); if (allocated(error)) return
      call check_finite(sys, t0, self%wk%f, 'derivative', error); if (allocated(error)) return
      self%hist%nh = 0                   ! a start again (past a stop) keeps no evaluation before it
      call record_evaluation(self, sys, t0, x0, self%wk%f, error); if (allocated(error)) return
      call commit_evaluation(self)
      call boot%init(2*self%n, self%adaptive, self%ctl, 1)
      call boot%stop_at(self%t_stop)
      call boot%start(sys, t0, x0, h, error); if (allocated(error)) return
      booted = boot%counts()
      self%z = boot%z; self%t = boot%t; self%h = booted%h_last; self%t0 = t0
      self%zbuf(:, :, 1) = self%z; self%kb = 1; self%corrected = .false.; self%t_macro = self%t - self%h; self%hb = self%h
      self%cnt%steps_fast = 2; self%cnt%steps_slow = 0
      call self%last_macro%forget()
      self%c_known = .false.
      self%kn = self%k
      if (self%k > 2 .and. .not. self%adaptive) self%kn = self%k - 2
    class default
      call fatal_error(error, "the 'response' coupling needs a system partitioned into slow and fast coordinates")
    end select
  end subroutine rs_start

  !> One accepted macro step. Adaptive: a step whose fast or surrogate error exceeds the
  !> tolerance is retried from its start with the steps the errors ask for; one that broke
  !> down (a step beyond the fast stability limit grows until a factorisation fails) is
  !> retried with both steps at the smallest ratio, up to max_breakdowns times in a row.
  !> The accepted state is projected onto the system's constraints; a macro step whose
  !> projection fails is retried with its fast step smaller (project_step).
  subroutine rs_advance(self, sys, error)
    class(response_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: err_f, err_s, t0, h0
    integer :: breakdowns, projection_fails
    logical :: retry, filling, refused
    select type (sys)
    class is (partitioned_system)
      t0 = self%t; h0 = self%h
      if (self%adaptive) then
        self%wk%z0 = self%z
        call error_weights(self%ctl, self%z(:, 0), self%wk%w)
      end if
      breakdowns = 0; projection_fails = 0; refused = .false.
      do
        filling = self%hist%nh < n_hist
        if (self%adaptive) call land_macro_step(self)
        call try_macro_step(self, sys, err_f, err_s, error)
        if (allocated(error)) then
          if (.not. self%adaptive .or. breakdowns == max_breakdowns) return
          breakdowns = breakdowns + 1
          deallocate(error)
          err_f = huge(1.0_dp); err_s = huge(1.0_dp)
        end if
        if (.not. err_f <= huge(1.0_dp)) err_f = huge(1.0_dp)     ! NaN: rejected, steps shrunk most
        if (.not. err_s <= huge(1.0_dp)) err_s = huge(1.0_dp)
        retry = .false.
        if (.not. self%adaptive .or. (err_f <= 1.0_dp .and. err_s <= 1.0_dp)) then
          call check_finite(sys, self%t, self%z(:, 0), 'state', error); if (allocated(error)) return
          call project_step(sys, self%t, self%z(:, 0), self%adaptive, projection_fails, retry, error)
          if (allocated(error)) return
          if (.not. retry) exit
        end if
        self%cnt%rejected = self%cnt%rejected + 1
        ! back to the start of the macro step (the array scaled with the step just tried)
        self%z = self%wk%z0; self%t = t0
        call nordsieck_rescale(self%z, self%h/h0)
        if (retry) then
          call shrink_fast_step(self, error); if (allocated(error)) return
        else
          refused = refused .or. err_s > 1.0_dp
          call resize_steps(self, err_f, err_s, filling, .false., .false., error); if (allocated(error)) return
        end if
      end do
      call commit_evaluation(self)
      self%c_known = self%corrected
      if (self%corrected) self%c_last = self%wk%c
      self%cnt%steps_slow = self%cnt%steps_slow + 1
      self%kn = self%k
      if (self%adaptive) call resize_steps(self, err_f, err_s, filling, .true., refused, error)
    class default
      call fatal_error(error, "the 'response' coupling needs a system partitioned into slow and fast coordinates")
    end select
  end subroutine rs_advance

  !> k fast steps from (t, z): surrogate evaluations, then a full one at the macro step's
  !> end (every step is a full one until the history is complete). err_f: the fast steps'
  !> weighted corrector estimates summed over the macro step (each step's error is in the
  !> state at its end, as the surrogate's is: the largest alone let the k steps' errors
  !> grow k times the tolerance, and on the stiff barrel over 0.2 s the muzzle error per
  !> unit rtol grew from 0.078 m at rtol 1e-5 to 0.93 m at 1e-8, where the sum holds it at
  !> 0.022-0.026 m: tests/test_response.py);
  !> err_s: weighted state error of the surrogate over the macro step (adaptive runs only).
  subroutine try_macro_step(self, sys, err_f, err_s, error)
    class(response_integrator), intent(inout) :: self
    class(partitioned_system), intent(inout) :: sys
    real(dp), intent(out) :: err_f, err_s
    type(error_type), allocatable, intent(out) :: error
    integer :: j, n
    real(dp) :: tn
    n = self%n
    err_f = 0.0_dp; err_s = 0.0_dp
    self%t_macro = self%t; self%corrected = .false.
    call hold_steps(self, self%kn)
    do j = 1, self%kn
      tn = self%t + self%h
      if (.not. self%adaptive) tn = self%t0 + (self%cnt%steps_fast + j)*self%h
      if (self%landing .and. j == self%kn) tn = self%t_stop
      call nordsieck_predict(self%z, self%wk%zp)
      self%wk%x = self%wk%zp(:, 0)
      if (j == self%kn .or. self%hist%nh < n_hist) then
        call sys%eval(tn, self%wk%x, self%wk%f, error); if (allocated(error)) return
        call check_finite(sys, tn, self%wk%f, 'derivative', error); if (allocated(error)) return
      else
        call surrogate(self, tn, self%wk%x, self%wk%f)
      end if
      call nordsieck_correct(self%wk%zp, self%h, self%wk%f, self%z, self%wk%cor)
      self%t = tn
      self%zbuf(:, :, j) = self%z
      ! the fast steps' own error (the full step's correction also holds the surrogate's
      ! error, which err_s measures)
      if (self%adaptive .and. (j < self%kn .or. self%kn == 1 .or. self%hist%nh < n_hist)) &
        & err_f = err_f + abs(corrector_l(0))*wrms_norm(self%wk%cor, self%wk%w)
    end do
    self%kb = self%kn; self%hb = self%h
    self%cnt%steps_fast = self%cnt%steps_fast + self%kn
    ! the macro step's full evaluation (at the predicted state x) joins the history on acceptance
    if (self%hist%nh == n_hist .and. self%kn > 1 .and. (self%adaptive .or. self%correct)) then
      call surrogate(self, tn, self%wk%x, self%wk%fs)
      call correct_surrogate_error(self, tn, err_s)
    end if
    call record_evaluation(self, sys, tn, self%wk%x, self%wk%f, error)
  end subroutine try_macro_step

  !> The surrogate's error d = f - fs at the macro step's end t1, grown over the step as the
  !> cubic's extrapolation error c P(t) grows (P the product of t - th over the history,
  !> c = d / P(t1)), and integrated: the error it left in the state, velocity wv d and
  !> position wx d at t1. err_s weighs what of it the correction leaves (adaptive runs:
  !> macro_error); the end's state and array are corrected by it (the last fast step's
  !> corrector took the full evaluation, and with it corrector_l(0) h d of the rate error),
  !> and value_at corrects the steps before.
  subroutine correct_surrogate_error(self, t1, err_s)
    class(response_integrator), intent(inout) :: self
    real(dp), intent(in) :: t1
    real(dp), intent(out) :: err_s
    real(dp) :: wv, wx, p1
    integer :: n
    n = self%n
    associate(d => self%d_c)
      d = self%wk%f(n+1:) - self%wk%fs(n+1:)
      p1 = product(t1 - self%hist%th)
      self%wk%c = d/p1
      call growth_integrals(self%hist%th, self%t_macro, t1, t1, wv, wx)
      err_s = 0.0_dp
      if (self%adaptive) err_s = macro_error(self, d, p1, wx, wv)
      if (.not. self%correct) return
      wv = wv - corrector_l(0)*self%h
      self%z(1:n, 0) = self%z(1:n, 0) + wx*d
      self%z(n+1:, 0) = self%z(n+1:, 0) + wv*d
      self%z(1:n, 1) = self%z(1:n, 1) + self%h*wv*d
      self%zbuf(:, :, self%kn) = self%z
    end associate
    self%corrected = .true.; self%t_c = t1; self%th_c = self%hist%th
  end subroutine correct_surrogate_error

  !> Weighted state error a macro step's correction leaves: the error of the part of d that
  !> the last accepted step's model c_last P(t1) did not predict, integrated as d is (on the
  !> tank d swings with the phase of the barrel's vibration and the two are alike; on the
  !> flexible four-bar it is smooth, the model predicts it and the step may grow), at
  !> least credited_correction of the error before the correction and at most that error.
  real(dp) function macro_error(self, d, p1, wx, wv) result(err)
    class(response_integrator), intent(inout) :: self
    real(dp), intent(in) :: d(:), p1, wx, wv
    integer :: n
    n = self%n
    self%wk%e(1:n) = wx*d; self%wk%e(n+1:) = wv*d
    err = wrms_norm(self%wk%e, self%wk%w)
    if (.not. (self%correct .and. self%c_known)) return
    self%wk%e(n+1:) = d - p1*self%c_last
    self%wk%e(1:n) = wx*self%wk%e(n+1:); self%wk%e(n+1:) = wv*self%wk%e(n+1:)
    err = min(max(wrms_norm(self%wk%e, self%wk%w), credited_correction*err), err)
  end function macro_error

  !> Integrals over [t0, t] of the extrapolation error's growth P(s)/P(t1), P the product of
  !> (s - th(i)): wv = int P(s)/P(t1) ds, wx = int (t - s) P(s)/P(t1) ds (3-point Gauss,
  !> exact for these degrees).
  pure subroutine growth_integrals(th, t0, t, t1, wv, wx)
    real(dp), intent(in) :: th(:), t0, t, t1
    real(dp), intent(out) :: wv, wx
    real(dp), parameter :: xg(3) = [-sqrt(0.6_dp), 0.0_dp, sqrt(0.6_dp)], wg(3) = [5.0_dp, 8.0_dp, 5.0_dp]/9.0_dp
    real(dp) :: s, p, p1, half
    integer :: i
    half = 0.5_dp*(t - t0)
    p1 = product(t1 - th)
    wv = 0.0_dp; wx = 0.0_dp
    do i = 1, 3
      s = t0 + half*(1.0_dp + xg(i))
      p = product(s - th)/p1
      wv = wv + wg(i)*half*p
      wx = wx + wg(i)*half*(t - s)*p
    end do
  end subroutine growth_integrals


  !> Surrogate derivative f = [qd; qdd^ - g (kf (a - a^) + df (ad - ad^))] at (t, x).
  subroutine surrogate(self, t, x, f)
    class(response_integrator), intent(inout) :: self
    real(dp), intent(in) :: t, x(:)
    real(dp), intent(out) :: f(:)
    real(dp) :: wt(n_hist)
    integer :: i, r, n, ns, nf
    n = self%n; ns = self%ns; nf = self%nf
    call history_weights(self%hist, t, wt)
    associate(hq => self%hist%hq, hy => self%hist%hy, g => self%hist%g, dfo => self%wk%dforce)
      do i = 1, nf
        dfo(i) = self%hist%kf(i)*(x(ns+i) - dot_product(wt, hy(i, :))) + &
          & self%hist%df(i)*(x(n+ns+i) - dot_product(wt, hy(nf+i, :)))
      end do
      do r = 1, n
        f(n+r) = dot_product(wt, hq(r, :))
      end do
      do i = 1, nf
        f(n+1:2*n) = f(n+1:2*n) - g(:, i)*dfo(i)
      end do
    end associate
    f(1:n) = x(n+1:2*n)
    self%cnt%evals_surrogate = self%cnt%evals_surrogate + 1
  end subroutine surrogate

  !> Lagrange weights of the history's cubic at t: the denominators prod_{j /= i} (th(i) -
  !> th(j)) are computed again only when the history's times changed.
  subroutine history_weights(hist, t, w)
    type(response_history_t), intent(inout) :: hist
    real(dp), intent(in) :: t
    real(dp), intent(out) :: w(n_hist)
    real(dp) :: d(n_hist)
    integer :: i, j
    if (any(hist%th /= hist%th_den)) then
      do i = 1, n_hist
        hist%den(i) = 1.0_dp
        do j = 1, n_hist
          if (j /= i) hist%den(i) = hist%den(i)*(hist%th(i) - hist%th(j))
        end do
        hist%den(i) = 1.0_dp/hist%den(i)
      end do
      hist%th_den = hist%th
    end if
    d = t - hist%th
    do i = 1, n_hist
      w(i) = hist%den(i)
      do j = 1, n_hist
        if (j /= i) w(i) = w(i)*d(j)
      end do
    end do
  end subroutine history_weights

  !> Keep the full evaluation f at (t, x) and the model's force response as pending.
  subroutine record_evaluation(self, sys, t, x, f, error)
    class(response_integrator), intent(inout) :: self
    class(partitioned_system), intent(inout) :: sys
    real(dp), intent(in) :: t, x(:), f(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: n, ns
    n = self%n; ns = self%ns
    self%hist%tp = t
    self%hist%qp = f(n+1:)
    self%hist%yp = [x(ns+1:n), x(n+ns+1:)]
    call sys%force_response(self%hist%gp, self%hist%kf, self%hist%df, error)
  end subroutine record_evaluation

  !> The pending full evaluation joins the history (the oldest leaves when it is full).
  pure subroutine commit_evaluation(self)
    class(response_integrator), intent(inout) :: self
    if (self%hist%nh == n_hist) then
      self%hist%th(1:n_hist-1) = self%hist%th(2:); self%hist%hq(:, 1:n_hist-1) = self%hist%hq(:, 2:)
      self%hist%hy(:, 1:n_hist-1) = self%hist%hy(:, 2:)
    else
      self%hist%nh = self%hist%nh + 1
    end if
    self%hist%th(self%hist%nh) = self%hist%tp; self%hist%hq(:, self%hist%nh) = self%hist%qp
    self%hist%hy(:, self%hist%nh) = self%hist%yp
    self%hist%g = self%hist%gp
  end subroutine commit_evaluation

  !> New fast step and ratio from the errors of a macro step (accepted or not): the fast
  !> step from the correctors' summed estimate (k h^5 = H h^4: the exponent 1/4 of
  !> ctl%ratio at a given macro step), the macro step from the surrogate's (after an
  !> accepted step, the envelope of its and the last one's: error_envelope), k = H/h
  !> within [1, k_max] and at most ratio_growth_percent above the last macro step's (rounded
  !> up); after an accepted step that followed a refusal for err_s (`refused`) the macro
  !> step does not grow. A macro step taken while the history was `filling` (no surrogate,
  !> no estimate of its error) keeps its ratio: grown on no estimate, the tank's start took
  !> k = 35 and the rate error of its first steps stayed in the turret's motion. The array
  !> is rescaled to the new fast step.
  subroutine resize_steps(self, err_f, err_s, filling, accepted, refused, error)
    class(response_integrator), intent(inout) :: self
    real(dp), intent(in) :: err_f, err_s
    logical, intent(in) :: filling, accepted, refused
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: h_new, hm_new, e_s
    h_new = self%h*self%ctl%ratio(err_f, accepted .or. err_f <= 1.0_dp)
    if (.not. accepted .and. err_f <= 1.0_dp) h_new = min(h_new, self%h)
    h_new = min(h_new, self%ctl%h_max)
    e_s = err_s
    if (accepted) e_s = self%last_macro%of(err_s, self%kn*self%h, surrogate_order)
    hm_new = self%kn*self%h*self%ctl%ratio(e_s, accepted .or. err_s <= 1.0_dp, surrogate_order)
    if ((.not. accepted .and. err_s <= 1.0_dp) .or. refused) hm_new = min(hm_new, self%kn*self%h)
    if (h_new < self%ctl%h_min) then
      call step_underflow(error, self%t, 'fast step', h_new); return
    end if
    self%k = min(max(1, floor(hm_new/h_new)), self%kn + (ratio_growth_percent*self%kn + 99)/100, self%k_max)
    if (filling) self%k = min(self%kn, self%k_max)
    self%kn = self%k
    if (h_new /= self%h) then
      call nordsieck_rescale(self%z, h_new/self%h)
      self%h = h_new
    end if
  end subroutine resize_steps

  !> The fast step times projection_eta, the ratio kept (a macro step whose projection
  !> failed); the array is rescaled to it.
  subroutine shrink_fast_step(self, error)
    class(response_integrator), intent(inout) :: self
    type(error_type), allocatable, intent(out) :: error
    if (projection_eta*self%h < self%ctl%h_min) then
      call step_underflow(error, self%t, 'fast step', projection_eta*self%h); return
    end if
    call nordsieck_rescale(self%z, projection_eta)
    self%h = projection_eta*self%h
  end subroutine shrink_fast_step

  pure real(dp) function rs_time(self)
    class(response_integrator), intent(in) :: self
    rs_time = self%t
  end function rs_time

  !> State at t inside the last macro step, from the Nordsieck array of its fast step.
  pure subroutine rs_value_at(self, t, x)
    class(response_integrator), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(out) :: x(:)
    integer :: j
    real(dp) :: wv, wx
    integer :: n
    j = min(max(ceiling((t - self%t_macro)/self%hb - 1.0e-9_dp), 1), self%kb)
    call nordsieck_value(self%zbuf(:, :, j), (t - (self%t_macro + j*self%hb))/self%hb, x)
    if (.not. self%corrected .or. j == self%kb) return
    n = self%n
    call growth_integrals(self%th_c, self%t_macro, t, self%t_c, wv, wx)
    x(1:n) = x(1:n) + wx*self%d_c
    x(n+1:) = x(n+1:) + wv*self%d_c
  end subroutine rs_value_at

  !> What a checkpoint keeps beside the Nordsieck array and the history's accelerations and
  !> fast states: ratios, times, steps, the last macro step's arrays, the rest of the
  !> history, counts. Loading refuses ratios outside [1, k_max].
  subroutine rs_record(self, rec)
    class(response_integrator), intent(inout) :: self
    type(state_record), intent(inout) :: rec
    call rec%item(self%k); call rec%item(self%kn); call rec%item(self%kb)
    if (rec%loading) then
      if (min(self%k, self%kn, self%kb) < 1 .or. max(self%k, self%kn, self%kb) > self%k_max) rec%ok = .false.
      if (.not. rec%ok) return
      call hold_steps(self, self%kb)
    end if
    call rec%item(self%t); call rec%item(self%h); call rec%item(self%t_macro); call rec%item(self%hb)
    call rec%item(self%t0)
    call rec%item(self%zbuf(:, :, 1:self%kb))
    call rec%item(self%correct); call rec%item(self%corrected); call rec%item(self%t_c); call rec%item(self%th_c); call rec%item(self%d_c)
    call rec%item(self%hist%nh); call rec%item(self%hist%th); call rec%item(self%hist%g)
    call rec%item(self%hist%kf); call rec%item(self%hist%df)
    call rec%item(self%cnt%steps_slow); call rec%item(self%cnt%steps_fast); call rec%item(self%cnt%rejected)
    call rec%item(self%cnt%evals_surrogate)
    call rec%item(self%last_macro%err); call rec%item(self%last_macro%h); call rec%item(self%last_macro%n)
    call rec%item(self%c_known); call rec%item(self%c_last)
  end subroutine rs_record

  pure function rs_counts(self) result(c)
    class(response_integrator), intent(in) :: self
    type(step_counts) :: c
    c%steps_slow = self%cnt%steps_slow; c%steps_fast = self%cnt%steps_fast
    c%rejected = self%cnt%rejected; c%h_last = self%k*self%h; c%ratio = self%k
    c%evals_fast = self%cnt%evals_surrogate
  end function rs_counts

  !> PECE steps of size h on every coordinate (&integrator h_fast).
  pure function rs_steps(self) result(s)
    class(response_integrator), intent(in) :: self
    type(pece_steps) :: s
    s%h_joint = self%h; s%h_modal = self%h
    s%item_joint = 'h_fast'; s%item_modal = 'h_fast'
    s%modal_surrogate = .true.
  end function rs_steps

  pure integer function rs_state_size(self)
    class(response_integrator), intent(in) :: self
    rs_state_size = size(self%z) + size(self%hist%hq) + size(self%hist%hy)
  end function rs_state_size

  !> The Nordsieck array (its value column first), then the history's accelerations and
  !> fast states.
  pure subroutine rs_get_state(self, v)
    class(response_integrator), intent(in) :: self
    real(dp), intent(out) :: v(:)
    integer :: a, b
    a = size(self%z); b = a + size(self%hist%hq)
    v(1:a) = reshape(self%z, [a])
    v(a+1:b) = reshape(self%hist%hq, [size(self%hist%hq)])
    v(b+1:) = reshape(self%hist%hy, [size(self%hist%hy)])
  end subroutine rs_get_state

  pure subroutine rs_set_state(self, v)
    class(response_integrator), intent(inout) :: self
    real(dp), intent(in) :: v(:)
    integer :: a, b
    a = size(self%z); b = a + size(self%hist%hq)
    self%z = reshape(v(1:a), shape(self%z))
    self%hist%hq = reshape(v(a+1:b), shape(self%hist%hq))
    self%hist%hy = reshape(v(b+1:), shape(self%hist%hy))
  end subroutine rs_set_state

  !> An adaptive macro step of kn fast steps that would pass t_stop: its fast step
  !> shortened (the array rescaled) so that it ends there.
  pure subroutine land_macro_step(self)
    class(response_integrator), intent(inout) :: self
    real(dp) :: eta
    eta = landing_ratio(self%t, self%kn*self%h, self%t_stop)
    self%landing = eta < 1.0_dp
    if (.not. self%landing) return
    call nordsieck_rescale(self%z, eta)
    self%h = eta*self%h
  end subroutine land_macro_step

  !> An adaptive run's steps land on t_stop.
  pure logical function rs_lands(self)
    class(response_integrator), intent(in) :: self
    rs_lands = self%adaptive
  end function rs_lands

  !> Step ratio k.
  pure subroutine rs_set_ratio(self, k)
    class(response_integrator), intent(inout) :: self
    integer, intent(in) :: k
    self%k = k; self%kn = k; self%k_max = max(self%k_max, k)
  end subroutine rs_set_ratio

  !> Room in the dense-output buffer for a macro step of k fast steps: it grows (doubling)
  !> with the ratio actually taken, not with k_max (up to 100,000).
  pure subroutine hold_steps(self, k)
    class(response_integrator), intent(inout) :: self
    integer, intent(in) :: k
    integer :: room
    if (k <= size(self%zbuf, 3)) return
    room = max(k, min(2*size(self%zbuf, 3), self%k_max))
    deallocate(self%zbuf)
    allocate(self%zbuf(2*self%n, 0:nq, room))
  end subroutine hold_steps

  pure function rs_name(self) result(s)
    class(response_integrator), intent(in) :: self
    character(len=:), allocatable :: s
    s = 'response'
  end function rs_name

end module pymr_integrator_response
