!> Variable-step, variable-order Adams-Moulton method in Nordsieck form, orders 1 to 12
!> (docs/method.md section 3.3). The derivation follows the analyses of Byrne and Hindmarsh
!> and of Jackson and Sacks-Davis ("fixed-leading-coefficient" form, as in CVODE).
!>
!> At order q the Nordsieck array z(:, 0:q) holds [y, h y', ..., h^q y^(q)/q!] at t_n. A step
!> predicts z by the Pascal matrix and corrects z = z(0) + e l, where the correction e solves
!> h f(t_n, z(0)_0 + e) = z(0)_1 + l_1 e by fixed-point iteration. The vector l makes the
!> corrected polynomial's derivative equal f at t_n and equal the old derivative at the q-1
!> earlier points, whatever the earlier steps were: l_j = m_(j-1)/(j M0), m the coefficients of
!> Lambda(x) = prod_(j<q) (1 + x/xi_j), xi_j = (t_n - t_(n-j))/h, M0 = int_(-1)^0 Lambda.
!> From the same polynomials come the local error estimates at orders q-1, q and q+1, which
!> choose the next step and order.
module pymr_integrator_adams
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver, prefix_error
  use pymr_integrator_ode, only : ode_system
  use pymr_integrator_control, only : step_control, error_weights, wrms_norm
  use pymr_integrator_stepper, only : stepper_t, step_counts, pece_steps, state_record, project_step, projection_eta, &
    & landing_ratio, step_underflow
  use pymr_integrator_abm, only : check_finite
  use pymr_env_text, only : fmt, itoa
  use pymr_env_lapack, only : lu_factor, lu_solve
  use pymr_integrator_nordsieck, only : nordsieck_predict_in_place, nordsieck_rescale, nordsieck_value
  implicit none
  private
  public :: adams_integrator, adams_coefficients, adams_lower_order, max_order, stable_omega_h

  !> Highest order.
  integer, parameter :: max_order = 12

  ! The step and order rules (their reasons in docs/method.md section 3.3).
  !> The chosen step aims at a local error of 1/bias of the tolerance: at the same order and
  !> at q-1 1/15, at q+1 1/25 (its estimate, from a difference of two corrections, is the
  !> least sure); addon keeps the ratio finite when an estimate is zero.
  real(dp), parameter :: bias_down = 15.0_dp, bias_same = 15.0_dp, bias_up = 25.0_dp, addon = 1.0e-6_dp
  !> Largest growth of the step after the first step (whose estimate is cautious), after
  !> any other step, and the least gain worth a change of step or order.
  real(dp), parameter :: grow_first = 1.0e4_dp, grow_max = 10.0_dp, gain_min = 1.5_dp
  !> Step ratio bounds after a failed error test (the second failure and later: at most
  !> shrink_repeat), and after a corrector that did not converge.
  real(dp), parameter :: shrink_min = 0.1_dp, shrink_repeat = 0.2_dp, shrink_corrector = 0.25_dp
  !> Error-test failures in one step before the order is lowered, and before the run stops;
  !> corrector failures before it stops.
  integer, parameter :: fails_to_lower = 3, max_error_fails = 7, max_corrector_fails = 10
  !> Fixed-point corrector: most iterations; the iteration error allowed, as a fraction of
  !> the local error test; memory of the convergence rate; divergence when a correction grows
  !> by this factor.
  integer, parameter :: max_iterations = 3
  !> Newton: steps a Jacobian serves at most (one that fails to converge is renewed at
  !> once); relative change of gamma that refactors I - gamma J.
  integer, parameter :: jac_max_age = 400
  real(dp), parameter :: gamma_change = 0.3_dp
  real(dp), parameter :: corrector_share = 0.1_dp, rate_memory = 0.3_dp, diverge = 2.0_dp
  !> Stability on undamped vibrations: the largest omega*h at which order q may step on
  !> the system's highest vibration frequency. Up to omega*h = 1 a mode is resolved: if it
  !> grows, the error test sees it within a few steps, and the step that then holds it is
  !> at most a few times smaller than the motion asks. Beyond, a mode the error test does
  !> not see yet (one left at roundoff) grows unseen until it fills the tolerance, and then
  !> holds a step many times smaller for the rest of the run. So beyond omega*h = 1 an order
  !> steps only while it multiplies such a mode by at most 1 + 1 % a step (the spectral
  !> radius of its amplification at z = i omega h, from z = 0 outward): orders 5, 6 and 7
  !> to 1.2607, 1.3829 and 1.0775; orders 1 and 2 (backward Euler, the trapezoidal rule,
  !> with the corrector converged) are A-stable (tests/test_adams.py recomputes these from
  !> the Adams-Moulton coefficients; docs/method.md section 3.3).
  real(dp), parameter :: stable_omega_h(max_order) = [huge(1.0_dp), huge(1.0_dp), 1.0_dp, 1.0_dp, &
    & 1.2607_dp, 1.3829_dp, 1.0775_dp, 1.0_dp, 1.0_dp, 1.0_dp, 1.0_dp, 1.0_dp]
  !> Steps at order 3 and up stay below this share of that bound at the highest frequency.
  real(dp), parameter :: stable_margin = 0.9_dp

  !> Newton (chord) iteration of the corrector: the Jacobian J by differences, the LU
  !> factors of I - gamma J, the gamma they hold, steps since J, J new in this step.
  type :: adams_newton_t
    real(dp), allocatable :: jac(:, :), lu(:, :)
    integer, allocatable :: piv(:)
    real(dp) :: gamma_lu = 0.0_dp
    integer :: jac_age = 1000
    logical :: jac_fresh = .false.
  end type adams_newton_t

  !> Counts: accepted and rejected steps, evaluations, corrector failures, steps per order.
  type :: adams_counts_t
    integer :: steps = 0, rejected = 0, evals = 0, corrector_fails = 0
    integer :: order_steps(max_order) = 0
  end type adams_counts_t

  !> Work: predicted array kept for a retry, correction, iterate, derivative, weights, new
  !> correction.
  type :: adams_work_t
    real(dp), allocatable :: z_old(:, :), e(:), y(:), f(:), w(:), e_new(:)
  end type adams_work_t

  !> The stepper's whole state.
  type, extends(stepper_t) :: adams_integrator
    integer :: n = 0
    !> Current order, and the highest the run may use (max_order when variable).
    integer :: q = 1, q_top = max_order
    !> Order fixed at q_top (reached from order 1 at the start): no lowering by choice.
    logical :: fixed = .false.
    !> Error control on; off: steps of the given size at the order held (tests that start
    !> from an exact array and measure the order).
    logical :: adaptive = .true.
    !> Time of z (s), and the step z is scaled with (the next step's).
    real(dp) :: t = 0.0_dp, h = 0.0_dp
    !> Nordsieck array z(n, 0:max_order) (columns above q are zero).
    real(dp), allocatable :: z(:, :)
    !> The previous accepted steps, latest first (s).
    real(dp) :: tau(max_order + 1) = 0.0_dp
    !> Steps to wait before the next order choice; growth bound of the next step.
    integer :: wait = 2
    real(dp) :: eta_max = grow_first
    !> Correction of the step before an order choice and its scale, for the q+1 estimate.
    real(dp), allocatable :: e_saved(:)
    real(dp) :: tq5_saved = 0.0_dp
    logical :: have_saved = .false.
    !> Measured convergence rate of the fixed-point iteration, and the h/l_1 it was measured at.
    real(dp) :: rate = 1.0_dp, gamma_rate = 0.0_dp
    type(step_control) :: ctl
    !> Highest undamped vibration frequency of the system (rad/s; 0: none known), which
    !> bounds the steps of orders 3 and up (stable_omega_h).
    real(dp) :: omega_top = 0.0_dp
    !> Newton (chord) iteration of the corrector instead of fixed-point, and its matrices.
    logical :: newton = .false.
    type(adams_newton_t) :: nt
    !> Counts.
    type(adams_counts_t) :: cnt
    !> Work: the step's coefficients, predicted array kept for a retry, correction, iterate,
    !> derivative, weights.
    real(dp) :: l(0:max_order) = 0.0_dp, tq(5) = 0.0_dp
    !> The order and steps (this one, then the earlier ones) l and tq belong to.
    integer :: q_coef = 0
    real(dp) :: s_coef(max_order + 1) = 0.0_dp
    type(adams_work_t) :: wk
  contains
    procedure :: init => adams_init
    procedure :: start => adams_start
    procedure :: advance => adams_advance
    procedure :: time => adams_time
    procedure :: value_at => adams_value_at
    procedure :: record => adams_record
    procedure :: counts => adams_counts
    procedure :: name => adams_name
    procedure :: pece => adams_steps
    procedure :: state_size => adams_state_size
    procedure :: get_state => adams_get_state
    procedure :: set_state => adams_set_state
    procedure :: order => adams_order
    procedure :: lands => adams_lands
  end type adams_integrator

contains

  !> Allocate for n components; order 0 = variable (1 to 12), 1-12 = that order; h (s): the
  !> largest first step the start takes (the pre-flight check reads it before the start).
  subroutine adams_init(self, n, order, ctl, newton, h)
    class(adams_integrator), intent(inout) :: self
    integer, intent(in) :: n, order
    type(step_control), intent(in) :: ctl
    logical, intent(in) :: newton
    real(dp), intent(in), optional :: h
    self%n = n
    if (present(h)) self%h = h
    self%fixed = order > 0
    self%q_top = merge(order, max_order, order > 0)
    self%ctl = ctl
    if (allocated(self%z)) deallocate(self%z, self%e_saved)
    self%wk = adams_work_t()
    allocate(self%z(n, 0:max_order), self%wk%z_old(n, 0:max_order), self%wk%e(n), self%e_saved(n), self%wk%y(n), &
      & self%wk%f(n), self%wk%w(n), self%wk%e_new(n))
    self%z = 0.0_dp; self%e_saved = 0.0_dp
    self%newton = newton
    if (allocated(self%nt%jac)) deallocate(self%nt%jac, self%nt%lu, self%nt%piv)
    if (newton) allocate(self%nt%jac(n, n), self%nt%lu(n, n), self%nt%piv(n))
    self%nt%jac_age = jac_max_age; self%nt%gamma_lu = 0.0_dp
    self%cnt = adams_counts_t()
  end subroutine adams_init

  !> Start at (t0, x0) at order 1 with a first step from the tolerances (at most h).
  subroutine adams_start(self, sys, t0, x0, h, error)
    class(adams_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: t0, x0(:), h
    type(error_type), allocatable, intent(out) :: error
    call sys%eval(t0, x0, self%wk%f, error); self%cnt%evals = self%cnt%evals + 1
    if (allocated(error)) return
    call check_finite(sys, t0, self%wk%f, 'derivative', error); if (allocated(error)) return
    call first_step(self, sys, t0, x0, h, error); if (allocated(error)) return
    self%z = 0.0_dp
    self%z(:, 0) = x0
    self%z(:, 1) = self%h*self%wk%f
    self%t = t0; self%q = 1; self%tau = 0.0_dp
    self%wait = 2; self%eta_max = grow_first; self%have_saved = .false.
    self%rate = 1.0_dp; self%gamma_rate = 0.0_dp
  end subroutine adams_start

  !> The first step (into self%h; f holds f(t0, x0)). Order 1's local error is
  !> h^2/2 ||y''||: the step that makes it 1 in the weighted norm is sqrt(2/||y''||), with
  !> y'' from a difference of f, refined up to four times; half of it is taken, as y'' is
  !> known at t0 only. Bounds: h_up, h_max, and no component moved by more than a tenth of
  !> its size plus its tolerance.
  subroutine first_step(self, sys, t0, x0, h_up, error)
    class(adams_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: t0, x0(:), h_up
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: hub, hlb, hg, hnew, ydd, move
    integer :: it
    call error_weights(self%ctl, x0, self%wk%w)
    hub = min(h_up, self%ctl%h_max)
    move = maxval(abs(self%wk%f)/(0.1_dp*abs(x0) + 1.0_dp/self%wk%w))
    if (move*hub > 1.0_dp) hub = 1.0_dp/move
    hlb = max(self%ctl%h_min, 100*epsilon(1.0_dp)*max(abs(t0), hub))
    if (hub <= hlb) then
      self%h = max(hub, self%ctl%h_min); return
    end if
    hg = sqrt(hlb*hub)
    hnew = hg
    do it = 1, 4
      self%wk%y = x0 + hg*self%wk%f
      call sys%eval(t0 + hg, self%wk%y, self%wk%e_new, error); self%cnt%evals = self%cnt%evals + 1
      if (allocated(error)) return
      ydd = wrms_norm((self%wk%e_new - self%wk%f)/hg, self%wk%w)
      if (ydd /= ydd .or. ydd > huge(1.0_dp)) then
        hnew = hg*0.2_dp
      else if (ydd*hub**2 > 2.0_dp) then
        hnew = sqrt(2.0_dp/ydd)
      else
        hnew = sqrt(hg*hub)
      end if
      if (hnew > 0.5_dp*hg .and. hnew < 2.0_dp*hg) exit
      hg = hnew
    end do
    self%h = min(max(0.5_dp*hnew, hlb), hub)
  end subroutine first_step

  !> One accepted step: predict, correct to convergence, test the local error; on a
  !> failure restore the array and retry smaller (and lower the order after repeated
  !> failures). The corrected state is projected onto the system's constraints; a step
  !> whose projection fails is retried smaller too (project_step). After it, choose the
  !> next step and order.
  subroutine adams_advance(self, sys, error)
    class(adams_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    type(error_type), allocatable, intent(out) :: error
    integer :: error_fails, corr_fails, projection_fails
    real(dp) :: tn, acnrm, dsm
    logical :: converged, retry
    error_fails = 0; corr_fails = 0; projection_fails = 0
    call error_weights(self%ctl, self%z(:, 0), self%wk%w)
    do
      if (self%adaptive .and. self%t + self%h > self%t_stop) call rescale(self, landing_ratio(self%t, self%h, self%t_stop))
      self%wk%z_old(:, 0:self%q) = self%z(:, 0:self%q)
      tn = self%t + self%h
      if (self%t < self%t_stop .and. tn >= self%t_stop) tn = self%t_stop
      call nordsieck_predict_in_place(self%z(:, 0:self%q))
      call set_coefficients(self)
      call correct(self, sys, tn, converged, acnrm, error); if (allocated(error)) return
      if (.not. converged .and. self%newton .and. .not. self%nt%jac_fresh) then
        ! retry the same step with a new Jacobian
        self%z(:, 0:self%q) = self%wk%z_old(:, 0:self%q)
        self%nt%jac_age = jac_max_age
        cycle
      end if
      if (.not. converged) then
        self%z(:, 0:self%q) = self%wk%z_old(:, 0:self%q)
        corr_fails = corr_fails + 1; self%cnt%corrector_fails = self%cnt%corrector_fails + 1
        if (corr_fails >= max_corrector_fails) then
          call fatal_error(error, 'at t = ' // fmt(self%t) // ' s: the corrector did not converge in ' // &
            & itoa(corr_fails) // ' tries down to the step ' // fmt(self%h) // ' s', stat_solver); return
        end if
        call shrink(self, shrink_corrector, error); if (allocated(error)) return
        cycle
      end if
      dsm = acnrm*self%tq(2)
      if (dsm <= 1.0_dp .or. .not. self%adaptive) then
        call correct_array(self, sys, tn, error); if (allocated(error)) return
        call project_step(sys, tn, self%z(:, 0), self%adaptive, projection_fails, retry, error)
        if (allocated(error)) return
        if (.not. retry) exit
        self%z(:, 0:self%q) = self%wk%z_old(:, 0:self%q)
        self%cnt%rejected = self%cnt%rejected + 1
        call shrink(self, projection_eta, error); if (allocated(error)) return
        cycle
      end if
      self%z(:, 0:self%q) = self%wk%z_old(:, 0:self%q)
      error_fails = error_fails + 1; self%cnt%rejected = self%cnt%rejected + 1
      if (error_fails >= max_error_fails) then
        call fatal_error(error, 'at t = ' // fmt(self%t) // ' s: the local error test failed ' // &
          & itoa(error_fails) // ' times in one step, down to the step ' // fmt(self%h) // ' s', stat_solver); return
      end if
      call after_error_failure(self, sys, dsm, error_fails, error); if (allocated(error)) return
    end do
    call accept(self, tn)
    if (self%adaptive) call choose_next(self, dsm)
  end subroutine adams_advance

  !> An adaptive run's steps land on t_stop.
  pure logical function adams_lands(self)
    class(adams_integrator), intent(in) :: self
    adams_lands = self%adaptive
  end function adams_lands

  !> Fixed-point iteration for the correction e of the predicted array z (not changed):
  !> e <- (h f(t_n, z_0 + e) - z_1)/l_1. Converged when the iteration error, estimated from
  !> the last change and the measured convergence rate, is below corrector_share of the
  !> error test; failed when it diverges or needs more than max_iterations. The rate is
  !> carried to the next step scaled by h/l_1 (the iteration's Lipschitz factor).
  subroutine correct(self, sys, tn, converged, acnrm, error)
    class(adams_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: tn
    logical, intent(out) :: converged
    real(dp), intent(out) :: acnrm
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: gamma, del, delp, dcon
    integer :: m
    converged = .false.; acnrm = 0.0_dp; delp = 0.0_dp
    gamma = self%h/self%l(1)
    if (.not. self%newton .and. self%gamma_rate > 0.0_dp) self%rate = min(1.0_dp, self%rate*gamma/self%gamma_rate)
    self%gamma_rate = gamma
    self%wk%e = 0.0_dp
    self%wk%y = self%z(:, 0)
    self%nt%jac_fresh = .false.
    do m = 0, max_iterations - 1
      call sys%eval(tn, self%wk%y, self%wk%f, error); self%cnt%evals = self%cnt%evals + 1
      if (allocated(error)) return
      call check_finite(sys, tn, self%wk%f, 'derivative', error); if (allocated(error)) return
      if (m == 0 .and. self%newton) then
        call newton_setup(self, sys, tn, gamma, error); if (allocated(error)) return
      end if
      self%wk%e_new = (self%h*self%wk%f - self%z(:, 1))/self%l(1)
      if (self%newton) then
        ! chord step: (I - gamma J) delta = e_new - e
        self%wk%e_new = self%wk%e_new - self%wk%e
        call lu_solve(self%nt%lu, self%nt%piv, self%wk%e_new)
        self%wk%e_new = self%wk%e + self%wk%e_new
      end if
      del = wrms_norm(self%wk%e_new - self%wk%e, self%wk%w)
      self%wk%e = self%wk%e_new
      self%wk%y = self%z(:, 0) + self%wk%e
      if (m > 0) then
        self%rate = max(rate_memory*self%rate, del/delp)
      end if
      dcon = del*min(1.0_dp, self%rate)/(corrector_share/self%tq(2))
      if (dcon <= 1.0_dp) then
        converged = .true.
        acnrm = merge(del, wrms_norm(self%wk%e, self%wk%w), m == 0)
        return
      end if
      if (m > 0 .and. del > diverge*delp) return
      delp = del
    end do
  end subroutine correct

  !> l and tq for the coming step, computed again only when its order or step history
  !> changed (a step held at its size, the usual case, keeps them).
  subroutine set_coefficients(self)
    class(adams_integrator), intent(inout) :: self
    integer :: q
    q = self%q
    if (q == self%q_coef .and. self%h == self%s_coef(1)) then
      if (all(self%tau(1:q - 1) == self%s_coef(2:q))) return
    end if
    self%s_coef(1) = self%h
    self%s_coef(2:q) = self%tau(1:q - 1)
    self%q_coef = q
    call adams_coefficients(q, self%s_coef(1:q), self%l, self%tq)
  end subroutine set_coefficients

  !> Before a Newton iteration (f holds f(tn, y) at the prediction y): a new Jacobian by
  !> forward differences when the last is jac_max_age steps old or failed to converge, new LU factors
  !> of I - gamma J when J is new or gamma changed by more than 30 %.
  subroutine newton_setup(self, sys, tn, gamma, error)
    class(adams_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: tn, gamma
    type(error_type), allocatable, intent(out) :: error
    integer :: j
    real(dp) :: sigma, yj
    self%nt%jac_age = self%nt%jac_age + 1
    if (self%nt%jac_age > jac_max_age) then
      do j = 1, self%n
        yj = self%wk%y(j)
        sigma = sqrt(epsilon(1.0_dp))*max(abs(yj), 1.0_dp/self%wk%w(j))
        self%wk%y(j) = yj + sigma
        call sys%eval(tn, self%wk%y, self%wk%e_new, error); self%cnt%evals = self%cnt%evals + 1
        self%wk%y(j) = yj
        if (allocated(error)) return
        self%nt%jac(:, j) = (self%wk%e_new - self%wk%f)/sigma
      end do
      self%nt%jac_age = 0; self%nt%jac_fresh = .true.; self%nt%gamma_lu = 0.0_dp
    end if
    if (abs(gamma/max(self%nt%gamma_lu, tiny(1.0_dp)) - 1.0_dp) <= gamma_change) return
    self%nt%lu = -gamma*self%nt%jac
    do j = 1, self%n
      self%nt%lu(j, j) = self%nt%lu(j, j) + 1.0_dp
    end do
    ! the time goes into the message only on a failure (formatting it for every factorisation
    ! took 3 % of the steps of a probe of 'adams' on the tank)
    call lu_factor(self%nt%lu, self%nt%piv, 'I - gamma J of the corrector', error)
    if (allocated(error)) call prefix_error(error, 'at t = ' // fmt(tn) // ' s')
    self%nt%gamma_lu = gamma; self%rate = 1.0_dp; self%gamma_rate = gamma
  end subroutine newton_setup

  !> The corrected array z = z(0) + e l (z holds the prediction), its state checked finite.
  subroutine correct_array(self, sys, tn, error)
    class(adams_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: tn
    type(error_type), allocatable, intent(out) :: error
    integer :: j
    do j = 0, self%q
      self%z(:, j) = self%z(:, j) + self%l(j)*self%wk%e
    end do
    call check_finite(sys, tn, self%z(:, 0), 'state', error)
  end subroutine correct_array

  !> Take the corrected step to tn: shift the step history, count, and keep the correction
  !> for the q+1 estimate one step before an order choice.
  subroutine accept(self, tn)
    class(adams_integrator), intent(inout) :: self
    real(dp), intent(in) :: tn
    self%t = tn
    self%cnt%steps = self%cnt%steps + 1
    self%cnt%order_steps(self%q) = self%cnt%order_steps(self%q) + 1
    self%tau(2:) = self%tau(:max_order)
    self%tau(1) = self%h
    self%wait = self%wait - 1
    if (self%wait == 1 .and. self%q < self%q_top) then
      self%e_saved = self%wk%e; self%tq5_saved = self%tq(5); self%have_saved = .true.
    end if
  end subroutine accept

  !> The next step and order from the error estimates at q-1, q and q+1 (every other step
  !> once q+1 steps were taken at the current order). A change must gain at least gain_min
  !> in step size; the step after a failure keeps its size.
  subroutine choose_next(self, dsm)
    class(adams_integrator), intent(inout) :: self
    real(dp), intent(in) :: dsm
    real(dp) :: eta, eta_dn, eta_up, cquot
    integer :: q_new
    if (self%eta_max <= 1.0_dp) then
      self%wait = max(self%wait, 2); self%eta_max = grow_max; return
    end if
    q_new = self%q
    eta = min(ratio(bias_same*dsm, self%q + 1), stable_step(self, self%q)/self%h)
    if (self%wait == 0) then
      self%wait = 2
      eta_dn = 0.0_dp; eta_up = 0.0_dp
      if (self%q > 1 .and. .not. self%fixed) &
        & eta_dn = min(ratio(bias_down*wrms_norm(self%z(:, self%q), self%wk%w)*self%tq(1), self%q), &
        & stable_step(self, self%q - 1)/self%h)
      if (self%q < self%q_top .and. self%have_saved) then
        cquot = self%tq(5)/self%tq5_saved*(self%h/self%tau(2))**(self%q + 1)
        eta_up = min(ratio(bias_up*wrms_norm(self%wk%e - cquot*self%e_saved, self%wk%w)*self%tq(3), self%q + 2), &
          & stable_step(self, self%q + 1)/self%h)
      end if
      if (self%fixed .and. self%q < self%q_top) then
        ! a fixed order is reached from order 1 as soon as the history allows
        q_new = self%q + 1; eta = eta_up
      else if (max(eta_up, eta_dn) > eta .and. max(eta_up, eta_dn) >= gain_min) then
        q_new = merge(self%q + 1, self%q - 1, eta_up > eta_dn)
        eta = max(eta_up, eta_dn)
      end if
    end if
    if (eta < gain_min) eta = 1.0_dp
    eta = min(eta, self%eta_max, self%ctl%h_max/self%h, stable_step(self, q_new)/self%h)
    self%eta_max = grow_max
    if (q_new < self%q) then
      call adams_lower_order(self%z, self%q, self%tau, self%h)
      self%q = q_new; self%wait = self%q + 1
    else if (q_new > self%q) then
      self%z(:, q_new) = 0.0_dp
      self%q = q_new; self%wait = self%q + 1
    end if
    if (eta /= 1.0_dp) call rescale(self, eta)
  end subroutine choose_next

  !> After a failed error test: a smaller step from the estimate; from the third failure on,
  !> the order is lowered (at order 1 the derivative column is evaluated afresh).
  subroutine after_error_failure(self, sys, dsm, fails, error)
    class(adams_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: dsm
    integer, intent(in) :: fails
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: eta
    if (fails < fails_to_lower) then
      eta = max(shrink_min, ratio(bias_same*dsm, self%q + 1))
      if (fails >= 2) eta = min(eta, shrink_repeat)
      call shrink(self, eta, error); return
    end if
    if (self%q > 1) then
      call adams_lower_order(self%z, self%q, self%tau, self%h)
      self%q = self%q - 1; self%wait = self%q + 1
      call shrink(self, shrink_min, error); return
    end if
    call shrink(self, shrink_min, error); if (allocated(error)) return
    call sys%eval(self%t, self%z(:, 0), self%wk%f, error); self%cnt%evals = self%cnt%evals + 1
    if (allocated(error)) return
    self%z(:, 1) = self%h*self%wk%f
    self%wait = 10
  end subroutine after_error_failure

  !> Retry with the step eta*h (no growth on the step after), stopping below h_min.
  subroutine shrink(self, eta, error)
    class(adams_integrator), intent(inout) :: self
    real(dp), intent(in) :: eta
    type(error_type), allocatable, intent(out) :: error
    if (eta*self%h < self%ctl%h_min) then
      call step_underflow(error, self%t, 'step', eta*self%h); return
    end if
    call rescale(self, eta)
    self%eta_max = 1.0_dp
  end subroutine shrink

  !> Largest step order k may take on the system's highest vibration: stable_margin of its
  !> bound (none at orders 1 and 2, or without a known frequency).
  pure real(dp) function stable_step(self, k)
    class(adams_integrator), intent(in) :: self
    integer, intent(in) :: k
    stable_step = huge(1.0_dp)
    if (self%omega_top > 0.0_dp .and. k >= 3) stable_step = stable_margin*stable_omega_h(k)/self%omega_top
  end function stable_step

  !> Step h -> eta h: column j of z times eta^j.
  pure subroutine rescale(self, eta)
    class(adams_integrator), intent(inout) :: self
    real(dp), intent(in) :: eta
    call nordsieck_rescale(self%z(:, 0:self%q), eta)
    self%h = eta*self%h
  end subroutine rescale

  !> Step ratio that brings an error estimate (already times its bias) to 1 for a method
  !> whose error is O(h^p).
  pure real(dp) function ratio(err, p)
    real(dp), intent(in) :: err
    integer, intent(in) :: p
    ratio = 1.0_dp/(err**(1.0_dp/p) + addon)
  end function ratio

  !> The corrector vector l(0:q) and the error constants tq of order q, for the step s(1)
  !> after the steps s(2), s(3), ... (latest first). With xi_j = (s(1) + ... + s(j))/s(1),
  !> Lambda(x) = prod_(j<q) (1 + x/xi_j) = sum m_i x^i, M0 = int_(-1)^0 Lambda,
  !> M1 = -int_(-1)^0 x Lambda:
  !>  - l_0 = 1, l_j = m_(j-1)/(j M0);
  !>  - tq(2) = M1/(M0 xi_q): local error at order q per unit correction;
  !>  - tq(1): local error at order q-1 per unit of z_q, q |int_(-1)^0 x prod_(j<q-1) (x + xi_j)|;
  !>  - tq(3): local error at order q+1 per unit difference of successive corrections,
  !>    M2/((q+1) M0), M2 = -int_(-1)^0 x Lambda(x) (1 + x/xi_q);
  !>  - tq(5) = xi_q/l_q, the scale of the correction (h^(q+1) y^(q+1) tq(5)/(q q!));
  !>  - tq(4) unused.
  pure subroutine adams_coefficients(q, s, l, tq)
    integer, intent(in) :: q
    real(dp), intent(in) :: s(:)
    real(dp), intent(out) :: l(0:), tq(5)
    real(dp) :: m(0:max_order + 1), p(0:max_order + 1), xi(max_order + 1), m0
    integer :: i, j
    do j = 1, q
      xi(j) = sum(s(1:j))/s(1)
    end do
    m = 0.0_dp; m(0) = 1.0_dp
    p = m
    do j = 1, q - 1
      if (j == q - 1) p = m
      do i = j, 1, -1
        m(i) = m(i) + m(i - 1)/xi(j)
      end do
    end do
    m0 = alt_integral(m, q - 1, 1)
    l = 0.0_dp; l(0) = 1.0_dp
    do i = 1, q
      l(i) = m(i - 1)/(i*m0)
    end do
    tq = 0.0_dp
    tq(2) = alt_integral(m, q - 1, 2)/(m0*xi(q))
    tq(5) = xi(q)/l(q)
    if (q >= 2) tq(1) = q*alt_integral(p, q - 2, 2)/p(q - 2)
    do i = q, 1, -1
      m(i) = m(i) + m(i - 1)/xi(q)
    end do
    tq(3) = alt_integral(m, q, 2)/(m0*(q + 1))
  end subroutine adams_coefficients

  !> sum_(i=0..k) (-1)^i a_i/(i+d): int_(-1)^0 of sum a_i x^i (d = 1), or minus that of
  !> x sum a_i x^i (d = 2).
  pure real(dp) function alt_integral(a, k, d)
    real(dp), intent(in) :: a(0:)
    integer, intent(in) :: k, d
    integer :: i
    alt_integral = 0.0_dp
    do i = 0, k
      alt_integral = alt_integral + (-1)**i*a(i)/(i + d)
    end do
  end function alt_integral

  !> Lower the order q of z at t_n by one: remove z_q r(x), r(x) = q int_0^x u prod_(j<q-1)
  !> (u + xi_j) du with xi_j = (tau(1) + ... + tau(j))/h, so that the derivative still equals
  !> its old values at t_n and the q-2 points before (r' vanishes there) and y_n is kept.
  pure subroutine adams_lower_order(z, q, tau, h)
    real(dp), intent(inout) :: z(:, 0:)
    integer, intent(in) :: q
    real(dp), intent(in) :: tau(:), h
    real(dp) :: c(0:max_order + 1), xi
    integer :: i, j
    if (q < 2) return
    c = 0.0_dp; c(1) = 1.0_dp
    do j = 1, q - 2
      xi = sum(tau(1:j))/h
      do i = j + 1, 1, -1
        c(i) = c(i - 1) + xi*c(i)
      end do
      c(0) = xi*c(0)
    end do
    do j = 2, q - 1
      z(:, j) = z(:, j) - q*c(j - 1)/j*z(:, q)
    end do
    z(:, q) = 0.0_dp
  end subroutine adams_lower_order

  !> The current order's polynomial inside the last step (dense output).
  pure subroutine adams_value_at(self, t, x)
    class(adams_integrator), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(out) :: x(:)
    call nordsieck_value(self%z(:, 0:self%q), (t - self%t)/self%h, x)
  end subroutine adams_value_at

  pure real(dp) function adams_time(self)
    class(adams_integrator), intent(in) :: self
    adams_time = self%t
  end function adams_time

  pure integer function adams_order(self)
    class(adams_integrator), intent(in) :: self
    adams_order = self%q
  end function adams_order

  !> What a checkpoint keeps beside the Nordsieck array: times, step and order, the step and
  !> order choice's memory, the corrector's rate, counts, and Newton's matrices.
  subroutine adams_record(self, rec)
    class(adams_integrator), intent(inout) :: self
    type(state_record), intent(inout) :: rec
    call rec%item(self%t); call rec%item(self%h); call rec%item(self%q); call rec%item(self%tau)
    call rec%item(self%wait); call rec%item(self%eta_max); call rec%item(self%e_saved)
    call rec%item(self%tq5_saved); call rec%item(self%have_saved); call rec%item(self%rate)
    call rec%item(self%gamma_rate)
    call rec%item(self%cnt%steps); call rec%item(self%cnt%rejected); call rec%item(self%cnt%evals)
    call rec%item(self%cnt%corrector_fails); call rec%item(self%cnt%order_steps)
    call rec%item(self%nt%gamma_lu); call rec%item(self%nt%jac_age)
    if (.not. self%newton) return
    call rec%item(self%nt%jac); call rec%item(self%nt%lu); call rec%item(self%nt%piv)
  end subroutine adams_record

  pure function adams_counts(self) result(c)
    class(adams_integrator), intent(in) :: self
    type(step_counts) :: c
    c%steps_slow = self%cnt%steps; c%steps_fast = self%cnt%steps
    c%rejected = self%cnt%rejected; c%h_last = self%h; c%ratio = 1
  end function adams_counts

  pure function adams_name(self) result(s)
    class(adams_integrator), intent(in) :: self
    character(len=:), allocatable :: s
    s = 'adams'
  end function adams_name

  !> Adaptive only: the pre-flight check of fixed steps never asks; its step for all.
  pure function adams_steps(self) result(s)
    class(adams_integrator), intent(in) :: self
    type(pece_steps) :: s
    s%h_joint = self%h; s%h_modal = self%h
  end function adams_steps

  pure integer function adams_state_size(self)
    class(adams_integrator), intent(in) :: self
    adams_state_size = size(self%z)
  end function adams_state_size

  !> The Nordsieck array, column by column (the state first).
  pure subroutine adams_get_state(self, v)
    class(adams_integrator), intent(in) :: self
    real(dp), intent(out) :: v(:)
    v = reshape(self%z, [size(self%z)])
  end subroutine adams_get_state

  pure subroutine adams_set_state(self, v)
    class(adams_integrator), intent(inout) :: self
    real(dp), intent(in) :: v(:)
    self%z = reshape(v, shape(self%z))
  end subroutine adams_set_state

end module pymr_integrator_adams
