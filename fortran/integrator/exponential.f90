!> Multirate integration with the fast side by its exact flow: the 'exponential' coupling
!> (docs/method.md section 4.3).
!>
!> The model is evaluated in full once per (macro) step H. Between evaluations the
!> accelerations are qdd = rho(t) - g0 (kf0 a + df0 ad): the elastic and damping forces of
!> the fast (modal) coordinates act through their linear response g0 = M^-1 E, frozen at
!> one full evaluation, and everything else, rho, is the polynomial through the last full
!> evaluations (rho_i = qdd_i + g0 (kf0 a_i + df0 ad_i)). That system is solved exactly
!> (pymr_integrator_modal_flow): every modal vibration, however stiff, moves by its own
!> flow, and the step is bound only by how well a cubic follows rho.
!>
!> A step predicts with the cubic through the last four evaluations (an exponential
!> Adams-Bashforth step), evaluates the model at the predicted state, and corrects with the
!> cubic through the last three and the new one (exponential Adams-Moulton, PEC); the
!> difference of the two states gives the local error estimate of adaptive runs. The first
!> steps take H/8, H/8, H/4, H/2 with the evaluations there are. The frozen response is
!> renewed when the evaluations' own has moved from it by what the explicit extrapolation
!> of the difference could no longer carry stably (drift_limit), and in adaptive runs also
!> when the vibration that difference carries would cost accuracy (vibration_drift).
module pymr_integrator_exponential
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_integrator_ode, only : ode_system, partitioned_system
  use pymr_integrator_stepper, only : stepper_t, step_counts, pece_steps, state_record, project_step, step_underflow, &
    & least_step
  use pymr_integrator_abm, only : check_finite
  use pymr_integrator_control, only : step_control, error_weights, wrms_norm, error_envelope
  use pymr_integrator_modal_flow, only : modal_flow_t, flow_rows_t, taylor_weights, n_coef, n_phi
  implicit none
  private
  public :: exponential_integrator

  !> Full evaluations the predictor's polynomial passes through.
  integer, parameter :: n_hist = n_coef
  !> Local error of the corrected step, from the difference of corrector and predictor
  !> (Milne's estimate for the order-4 Adams pair, |C_AM|/(C_AB - C_AM) = 19/270).
  real(dp), parameter :: milne = 19.0_dp/270.0_dp
  !> Order in h of that local error (the order-4 pair's: h^5).
  integer, parameter :: local_order = 5
  !> The response is frozen again when h^2 |Delta(g K)| + h |Delta(g D)| exceeds this.
  real(dp), parameter :: drift_limit = 0.5_dp
  !> Adaptive runs: steps in a row that may break down and be retried smaller.
  integer, parameter :: max_breakdowns = 10
  !> Adaptive runs: the response is also frozen anew when its drift's vibration
  !> (vibration_drift) has exceeded the tolerance at this many accepted steps in a row, the
  !> evaluations the cubic spans; and such renewals stop for the run when the drift is back
  !> within as many steps (it then follows the motion's own pace, which a freeze cannot).
  !> On the tank with its elevation driven by a cylinder (a closed loop moving the joints'
  !> response), the stability bound alone left the response frozen all run while the step
  !> fell from 1.1 to 0.5 ms (docs/method.md section 4.3).
  integer, parameter :: drift_steps = n_hist

  !> History of full evaluations, oldest first: times, accelerations (n, nh), fast states
  !> [a; ad] (2nf, nh), remainders rho (n, nh) and their modal forcing (nm, nh).
  type :: flow_history_t
    integer :: nh = 0
    real(dp) :: th(n_hist) = 0.0_dp
    real(dp), allocatable :: hq(:, :), hy(:, :), hr(:, :)
    complex(dp), allocatable :: hp(:, :)
  end type flow_history_t

  !> The last accepted step, for dense output: start, length, state, modal state, forcing,
  !> and its flow in the form rows take.
  type :: flow_step_t
    real(dp) :: t = 0.0_dp, h = 0.0_dp
    real(dp), allocatable :: x(:), cs(:, :)
    complex(dp), allocatable :: eta(:), beta(:, :)
    type(flow_rows_t) :: rows
  end type flow_step_t

  !> Work arrays of a step.
  type :: flow_work_t
    real(dp), allocatable :: w(:), xp(:), xc(:), f(:), g(:, :), kf(:), df(:), y(:), rnew(:), cs(:, :)
    complex(dp), allocatable :: eta0(:), pnew(:), beta(:, :)
  end type flow_work_t

  type, extends(stepper_t) :: exponential_integrator
    integer :: n = 0, ns = 0, nf = 0
    !> Time and state reached; the run's start; the next step (adaptive) or H (fixed).
    real(dp) :: t = 0.0_dp, t0 = 0.0_dp
    real(dp), private :: h = 0.0_dp
    real(dp), allocatable :: x(:)
    logical :: adaptive = .false.
    type(step_control) :: ctl
    type(modal_flow_t) :: flow
    type(flow_history_t) :: hist
    type(flow_step_t) :: last
    !> The last accepted step's error estimate and step (adaptive).
    type(error_envelope) :: last_error
    !> Accepted and rejected steps, renewals of the frozen response (those for accuracy
    !> among them).
    integer :: steps = 0, rejected = 0, renewals = 0, accuracy_renewals = 0
    !> Accepted steps in a row whose drift's vibration exceeded the tolerance; accepted
    !> steps since the last renewal for accuracy (-1: none since the start); whether such
    !> renewals are still made.
    integer :: drifted = 0, since_accuracy = -1
    logical :: renew_for_accuracy = .true.
    !> The flow's coefficients for a step of tau_phi (kept while steps and flow stay).
    complex(dp), allocatable :: tp(:, :)
    real(dp) :: tau_phi = -1.0_dp
    type(flow_work_t) :: wk
  contains
    procedure :: init => ex_init
    procedure :: start => ex_start
    procedure :: advance => ex_advance
    procedure :: time => ex_time
    procedure :: value_at => ex_value_at
    procedure :: record => ex_record
    procedure :: counts => ex_counts
    procedure :: name => ex_name
    procedure :: pece => ex_steps
    procedure :: state_size => ex_state_size
    procedure :: get_state => ex_get_state
    procedure :: set_state => ex_set_state
    procedure :: lands => ex_lands
  end type exponential_integrator

contains

  !> Allocate for ns slow and nf fast coordinates; h: the (first) step.
  subroutine ex_init(self, ns, nf, adaptive, ctl, h)
    class(exponential_integrator), intent(inout) :: self
    integer, intent(in) :: ns, nf
    logical, intent(in) :: adaptive
    type(step_control), intent(in) :: ctl
    real(dp), intent(in) :: h
    integer :: n
    n = ns + nf
    self%n = n; self%ns = ns; self%nf = nf
    self%adaptive = adaptive; self%ctl = ctl; self%h = h
    allocate(self%x(2*n), self%hist%hq(n, n_hist), self%hist%hy(2*nf, n_hist), self%hist%hr(n, n_hist))
    allocate(self%flow%g0(n, nf), self%flow%kf0(nf), self%flow%df0(nf), self%last%x(2*n), self%last%cs(ns, n_coef))
    allocate(self%wk%w(2*n), self%wk%xp(2*n), self%wk%xc(2*n), self%wk%f(2*n), self%wk%g(n, nf), self%wk%kf(nf), &
      & self%wk%df(nf), self%wk%y(2*nf), self%wk%rnew(n), self%wk%cs(ns, n_coef))
    self%hist%hq = 0.0_dp; self%hist%hy = 0.0_dp; self%hist%hr = 0.0_dp
  end subroutine ex_init

  !> Start at (t0, x0): a full evaluation opens the history and freezes the response.
  subroutine ex_start(self, sys, t0, x0, h, error)
    class(exponential_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: t0, x0(:), h
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: f(:), g(:, :), kf(:), df(:)
    if (h > 0.0_dp) self%h = h
    select type (sys)
    class is (partitioned_system)
      allocate(f(2*self%n), g(self%n, self%nf), kf(self%nf), df(self%nf))
      call sys%eval(t0, x0, f, error); if (allocated(error)) return
      call check_finite(sys, t0, f, 'derivative', error); if (allocated(error)) return
      call sys%force_response(g, kf, df, error); if (allocated(error)) return
      call self%flow%build(self%ns, g, kf, df, error); if (allocated(error)) return
      call size_modal(self)
      self%hist%nh = 0
      self%wk%y = fast_state(self, x0)
      self%wk%rnew = self%flow%remainder(f(self%n+1:), self%wk%y); self%wk%pnew = self%flow%project(self%wk%rnew)
      call push_evaluation(self, t0, f(self%n+1:), self%wk%y, self%wk%rnew, self%wk%pnew)
      self%t = t0; self%t0 = t0; self%x = x0
      self%drifted = 0; self%since_accuracy = -1; self%renew_for_accuracy = .true.
      call self%last_error%forget()
      self%last%t = t0; self%last%h = 0.0_dp; self%last%x = x0
      self%last%eta = self%flow%modal_state(x0)
      self%last%beta = (0.0_dp, 0.0_dp); self%last%cs = 0.0_dp
      call self%flow%rows_form(self%last%eta, self%last%beta, 0.0_dp, self%last%rows)
    class default
      call fatal_error(error, "the 'exponential' coupling needs a system partitioned into slow and fast coordinates")
    end select
  end subroutine ex_start

  !> [a; ad] of the state x = [q_s; a; qd_s; ad].
  pure function fast_state(self, x) result(y)
    class(exponential_integrator), intent(in) :: self
    real(dp), intent(in) :: x(:)
    real(dp) :: y(2*self%nf)
    y = [x(self%ns+1:self%n), x(self%n+self%ns+1:)]
  end function fast_state

  !> A full evaluation (accelerations qdd at the fast state y) joins the history; the oldest
  !> leaves when it is full.
  subroutine push_evaluation(self, t, qdd, y, r, p)
    class(exponential_integrator), intent(inout) :: self
    real(dp), intent(in) :: t, qdd(:), y(:)
    !> Its remainder (flow%remainder) and modal forcing (flow%project).
    real(dp), intent(in) :: r(:)
    complex(dp), intent(in) :: p(:)
    integer :: m
    associate(h => self%hist)
      if (h%nh == n_hist) then
        h%th(1:n_hist-1) = h%th(2:); h%hq(:, 1:n_hist-1) = h%hq(:, 2:); h%hy(:, 1:n_hist-1) = h%hy(:, 2:)
        h%hr(:, 1:n_hist-1) = h%hr(:, 2:); h%hp(:, 1:n_hist-1) = h%hp(:, 2:)
      else
        h%nh = h%nh + 1
      end if
      m = h%nh
      h%th(m) = t; h%hq(:, m) = qdd; h%hy(:, m) = y
      h%hr(:, m) = r; h%hp(:, m) = p
    end associate
  end subroutine push_evaluation

  !> The remainders of the history again, after the response was frozen anew.
  pure subroutine refresh_history(self)
    class(exponential_integrator), intent(inout) :: self
    integer :: i
    associate(h => self%hist)
      do i = 1, h%nh
        h%hr(:, i) = self%flow%remainder(h%hq(:, i), h%hy(:, i)); h%hp(:, i) = self%flow%project(h%hr(:, i))
      end do
    end associate
  end subroutine refresh_history

  !> The end of fixed step m: the start takes H/2^(n_hist-1), the same again, then steps
  !> doubling up to H/2, so that the run is back on the multiples of H after n_hist steps.
  pure real(dp) function fixed_end(self, m) result(t)
    class(exponential_integrator), intent(in) :: self
    integer, intent(in) :: m
    if (m <= n_hist) then
      t = self%t0 + self%h/2.0_dp**(n_hist - m)
    else
      t = self%t0 + (m - n_hist + 1)*self%h
    end if
  end function fixed_end

  !> The nominal length of fixed step m (the start's fractions of H, then H).
  pure real(dp) function fixed_length(self, m) result(h)
    class(exponential_integrator), intent(in) :: self
    integer, intent(in) :: m
    h = self%h
    if (m <= n_hist) h = self%h/2.0_dp**(n_hist - max(m, 2) + 1)
  end function fixed_length

  !> The next step from t0 to try, its length hs and end tn: adaptive, the controller's (at
  !> most twice the last while the history fills), shortened to land on t_stop; fixed, the
  !> start's fractions of H, then H.
  pure subroutine step_to_try(self, t0, hs, tn)
    class(exponential_integrator), intent(in) :: self
    real(dp), intent(in) :: t0
    real(dp), intent(out) :: hs, tn
    if (.not. self%adaptive) then
      tn = fixed_end(self, self%steps + 1); hs = fixed_length(self, self%steps + 1); return
    end if
    hs = self%h
    if (self%hist%nh < n_hist) hs = min(hs, 2.0_dp*max(self%last%h, self%h/2.0_dp**(n_hist - 1)))
    tn = t0 + hs
    if (t0 < self%t_stop .and. tn > self%t_stop) then
      hs = self%t_stop - t0; tn = self%t_stop
    end if
  end subroutine step_to_try

  !> One accepted step: predict, evaluate, correct; adaptive steps retried smaller when the
  !> estimate exceeds the tolerance or the evaluation broke down.
  subroutine ex_advance(self, sys, error)
    class(exponential_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: t0, tn, hs, err
    integer :: breakdowns, fails
    logical :: retry, full, unstable
    select type (sys)
    class is (partitioned_system)
    associate(wk => self%wk, n => self%n)
      t0 = self%t
      if (self%adaptive) call error_weights(self%ctl, self%x, wk%w)
      breakdowns = 0; fails = 0
      do
        call step_to_try(self, t0, hs, tn)
        wk%eta0 = self%flow%modal_state(self%x)
        ! predict: the polynomial through the history
        call forcing(self, t0, self%hist%nh, .false., tn)
        call step_phis(self, hs)
        call self%flow%state_at(self%x, wk%eta0, wk%beta, wk%cs, hs, self%tp, wk%xp)
        call sys%eval(tn, wk%xp, wk%f, error)
        if (.not. allocated(error)) call check_finite(sys, tn, wk%f, 'derivative', error)
        if (.not. allocated(error)) call sys%force_response(wk%g, wk%kf, wk%df, error)
        if (allocated(error)) then
          if (.not. self%adaptive .or. breakdowns == max_breakdowns) return
          breakdowns = breakdowns + 1; deallocate(error)
          self%h = hs*self%ctl%shrink_min; self%rejected = self%rejected + 1
          cycle
        end if
        wk%y = fast_state(self, wk%xp)
        unstable = self%flow%drift(wk%g, wk%kf, wk%df, hs) > drift_limit
        if (unstable .or. self%drifted >= drift_steps) then
          if (.not. unstable) call note_accuracy_renewal(self)
          call renew_flow(self, wk%g, wk%kf, wk%df, error); if (allocated(error)) return
          wk%eta0 = self%flow%modal_state(self%x)
          call step_phis(self, hs)
        end if
        ! correct: the polynomial through the last three and the new evaluation
        wk%rnew = self%flow%remainder(wk%f(n+1:), wk%y); wk%pnew = self%flow%project(wk%rnew)
        call forcing(self, t0, min(self%hist%nh, n_hist - 1), .true., tn)
        call self%flow%state_at(self%x, wk%eta0, wk%beta, wk%cs, hs, self%tp, wk%xc)
        err = 0.0_dp
        if (self%adaptive) then
          err = wrms_norm(milne*(wk%xc - wk%xp), wk%w)
          if (.not. err <= huge(1.0_dp)) err = huge(1.0_dp)
          if (err > 1.0_dp) then
            self%h = hs*self%ctl%ratio(err, .false.); self%rejected = self%rejected + 1
            if (self%h < least_step(self%ctl%h_min, t0)) then
              call step_underflow(error, t0, 'step', self%h); return
            end if
            cycle
          end if
        end if
        call check_finite(sys, tn, wk%xc, 'state', error); if (allocated(error)) return
        call project_step(sys, tn, wk%xc, self%adaptive, fails, retry, error); if (allocated(error)) return
        if (.not. retry) exit
        self%h = 0.25_dp*hs; self%rejected = self%rejected + 1
      end do
      self%last%t = t0; self%last%h = hs; self%last%x = self%x; self%last%eta = wk%eta0
      self%last%beta = wk%beta; self%last%cs = wk%cs
      call self%flow%rows_form(wk%eta0, wk%beta, hs, self%last%rows)
      self%x = wk%xc; self%t = tn; self%steps = self%steps + 1
      if (self%adaptive .and. self%renew_for_accuracy) &
        & call watch_drift(self, vibration_drift(self, wk%g, wk%kf, wk%df, wk%y, hs))
      full = self%hist%nh == n_hist
      call push_evaluation(self, tn, wk%f(n+1:), wk%y, wk%rnew, wk%pnew)
      ! an accepted step's successor no less than the least step (its error test fails there)
      if (self%adaptive) self%h = max(min(hs*self%ctl%ratio(self%last_error%of(err, hs, local_order, keep=full), &
        & .true.), self%ctl%h_max), least_step(self%ctl%h_min, tn))
    end associate
    class default
      call fatal_error(error, "the 'exponential' coupling needs a system partitioned into slow and fast coordinates")
    end select
  end subroutine ex_advance

  !> Freeze the response anew at (g, kf, df): the flow, the history's remainders, the work
  !> arrays' modal sizes.
  subroutine renew_flow(self, g, kf, df, error)
    class(exponential_integrator), intent(inout) :: self
    real(dp), intent(in) :: g(:, :), kf(:), df(:)
    type(error_type), allocatable, intent(out) :: error
    call self%flow%build(self%ns, g, kf, df, error); if (allocated(error)) return
    call size_modal(self)
    call refresh_history(self)
    self%renewals = self%renewals + 1
  end subroutine renew_flow

  !> A renewal for accuracy is made: counted, and its drift watched afresh.
  pure subroutine note_accuracy_renewal(self)
    class(exponential_integrator), intent(inout) :: self
    self%accuracy_renewals = self%accuracy_renewals + 1
    self%drifted = 0; self%since_accuracy = 0
  end subroutine note_accuracy_renewal

  !> After an accepted step whose drift's vibration was e (in tolerances): the steps in a
  !> row over the tolerance, and renewals for accuracy stopped when the drift came back
  !> within drift_steps steps of the last one.
  pure subroutine watch_drift(self, e)
    class(exponential_integrator), intent(inout) :: self
    real(dp), intent(in) :: e
    if (self%since_accuracy >= 0) self%since_accuracy = self%since_accuracy + 1
    if (e <= 1.0_dp) then
      self%drifted = 0; return
    end if
    if (self%since_accuracy >= 0 .and. self%since_accuracy <= drift_steps) self%renew_for_accuracy = .false.
    self%drifted = merge(self%drifted + 1, 0, self%renew_for_accuracy)
  end subroutine watch_drift

  !> What the drift of the response from the frozen one moves the state by over a step of
  !> h, in tolerances (the error weights' norm), through the vibration it carries: the
  !> remainder holds (g0 K0 - g K) a + (g0 D0 - g D) ad, and the cubic through its last four
  !> values misses a vibration of amplitude A and frequency omega by about A (omega h)^4/4
  !> over the step (at most A). The amplitude of fast coordinate i is taken from its rate,
  !> ad_i/omega_i (omega_i^2 = g0_ii K0_i, frozen): a static deflection moves as the motion
  !> does, which the cubic follows. y = [a; ad] at the evaluation of (g, kf, df).
  pure real(dp) function vibration_drift(self, g, kf, df, y, h) result(e)
    class(exponential_integrator), intent(in) :: self
    real(dp), intent(in) :: g(:, :), kf(:), df(:), y(:), h
    real(dp) :: d(self%n), omega, v
    integer :: i
    d = 0.0_dp
    associate(nf => self%nf, f => self%flow)
      do i = 1, nf
        omega = sqrt(max(f%g0(self%ns + i, i)*f%kf0(i), tiny(1.0_dp)))
        v = min(1.0_dp, (omega*h)**4/4.0_dp)*y(nf + i)
        d = d + g(:, i)*((kf(i)/omega + df(i))*v) - f%g0(:, i)*((f%kf0(i)/omega + f%df0(i))*v)
      end do
    end associate
    e = wrms_norm([h**2*d, h*d], self%wk%w)
  end function vibration_drift

  !> The arrays sized by the number of kept eigenvalues (which a renewal may change: a
  !> vibration becoming two real decays), and the flow's coefficients to compute again.
  pure subroutine size_modal(self)
    class(exponential_integrator), intent(inout) :: self
    integer :: nm
    nm = self%flow%nm
    self%tau_phi = -1.0_dp
    if (allocated(self%wk%eta0)) then
      if (size(self%wk%eta0) == nm) return
      deallocate(self%wk%eta0, self%wk%pnew, self%wk%beta, self%hist%hp, self%last%eta, self%last%beta)
    end if
    allocate(self%wk%eta0(nm), self%wk%pnew(nm), self%wk%beta(nm, n_coef), self%hist%hp(nm, n_hist), &
      & self%last%eta(nm), self%last%beta(nm, n_coef))
    self%hist%hp = (0.0_dp, 0.0_dp); self%last%eta = (0.0_dp, 0.0_dp); self%last%beta = (0.0_dp, 0.0_dp)
    call self%flow%rows_form(self%last%eta, self%last%beta, 0.0_dp, self%last%rows)
  end subroutine size_modal

  !> The flow's coefficients for a step of tau (computed again only when it changes).
  pure subroutine step_phis(self, tau)
    class(exponential_integrator), intent(inout) :: self
    real(dp), intent(in) :: tau
    if (tau == self%tau_phi .and. allocated(self%tp)) then
      if (size(self%tp, 2) == self%flow%nm) return
    end if
    if (allocated(self%tp)) deallocate(self%tp)
    allocate(self%tp(0:n_phi-1, self%flow%nm))
    call self%flow%phis(tau, self%tp)
    self%tau_phi = tau
  end subroutine step_phis

  !> Taylor coefficients at t0 (wk%cs: slow rows, wk%beta: modal) of the polynomial
  !> through the history's last m remainders and, with `with_new`, the pending one (wk%rnew,
  !> wk%pnew at tn). The weights come from the history's own times each step (a few hundred
  !> operations), so that a run continued from a checkpoint repeats the uninterrupted one.
  pure subroutine forcing(self, t0, m, with_new, tn)
    class(exponential_integrator), intent(inout) :: self
    real(dp), intent(in) :: t0, tn
    integer, intent(in) :: m
    logical, intent(in) :: with_new
    real(dp) :: th(n_hist), tw(n_hist, n_coef)
    integer :: i, j, j0, np
    associate(h => self%hist, wk => self%wk, ns => self%ns)
      j0 = h%nh - m
      th(1:m) = h%th(j0+1:h%nh) - t0; np = m
      if (with_new) then
        np = m + 1; th(np) = tn - t0
      end if
      call taylor_weights(th(1:np), 0.0_dp, tw(1:np, :))
      wk%cs = 0.0_dp; wk%beta = (0.0_dp, 0.0_dp)
      do j = 1, n_coef
        do i = 1, m
          wk%cs(:, j) = wk%cs(:, j) + tw(i, j)*h%hr(1:ns, j0+i)
          wk%beta(:, j) = wk%beta(:, j) + tw(i, j)*h%hp(:, j0+i)
        end do
        if (with_new) then
          wk%cs(:, j) = wk%cs(:, j) + tw(np, j)*wk%rnew(1:ns)
          wk%beta(:, j) = wk%beta(:, j) + tw(np, j)*wk%pnew
        end if
      end do
    end associate
  end subroutine forcing

  !> An adaptive run's steps land on t_stop.
  pure logical function ex_lands(self)
    class(exponential_integrator), intent(in) :: self
    ex_lands = self%adaptive
  end function ex_lands

  pure real(dp) function ex_time(self)
    class(exponential_integrator), intent(in) :: self
    ex_time = self%t
  end function ex_time

  !> The state at t inside the last step, by the same closed form.
  pure subroutine ex_value_at(self, t, x)
    class(exponential_integrator), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(out) :: x(:)
    if (t >= self%t) then
      x = self%x
    else
      call self%flow%row_at(self%last%rows, self%last%x, self%last%eta, self%last%beta, self%last%cs, &
        & t - self%last%t, x)
    end if
  end subroutine ex_value_at

  !> What a checkpoint keeps beside the state and the history's accelerations and fast
  !> states: times, steps, the frozen response (the flow is built again from it on
  !> loading), the last step, counts.
  subroutine ex_record(self, rec)
    class(exponential_integrator), intent(inout) :: self
    type(state_record), intent(inout) :: rec
    type(error_type), allocatable :: error
    real(dp), allocatable :: br(:, :), bi(:, :), er(:), ei(:), g0(:, :), kf0(:), df0(:)
    call rec%item(self%t); call rec%item(self%t0); call rec%item(self%h)
    call rec%item(self%hist%nh); call rec%item(self%hist%th)
    call rec%item(self%flow%g0); call rec%item(self%flow%kf0); call rec%item(self%flow%df0)
    if (rec%loading) then
      if (self%hist%nh < 1 .or. self%hist%nh > n_hist) rec%ok = .false.
      if (.not. rec%ok) return
      g0 = self%flow%g0; kf0 = self%flow%kf0; df0 = self%flow%df0
      call self%flow%build(self%ns, g0, kf0, df0, error)
      if (allocated(error)) then
        rec%ok = .false.; return
      end if
      call size_modal(self)
    end if
    call rec%item(self%last%t); call rec%item(self%last%h); call rec%item(self%last%x); call rec%item(self%last%cs)
    br = real(self%last%beta); bi = aimag(self%last%beta); er = real(self%last%eta); ei = aimag(self%last%eta)
    call rec%item(br); call rec%item(bi); call rec%item(er); call rec%item(ei)
    if (rec%loading) then
      self%last%beta = cmplx(br, bi, dp); self%last%eta = cmplx(er, ei, dp)
      call self%flow%rows_form(self%last%eta, self%last%beta, self%last%h, self%last%rows)
    end if
    call rec%item(self%steps); call rec%item(self%rejected); call rec%item(self%renewals)
    call rec%item(self%last_error%err); call rec%item(self%last_error%h); call rec%item(self%last_error%n)
    call rec%item(self%accuracy_renewals); call rec%item(self%drifted); call rec%item(self%since_accuracy)
    call rec%item(self%renew_for_accuracy)
  end subroutine ex_record

  pure function ex_counts(self) result(c)
    class(exponential_integrator), intent(in) :: self
    type(step_counts) :: c
    c%steps_slow = self%steps; c%steps_fast = self%steps; c%renewals = self%renewals
    c%accuracy_renewals = self%accuracy_renewals
    c%rejected = self%rejected; c%h_last = self%last%h; c%ratio = 1
  end function ex_counts

  !> The modal stiffness and damping (with a tension's stiffening on the diagonal) move by
  !> their exact flow; the rest of the model (its joints' vibrations, the rest of the
  !> stiffness the motion adds) is carried by the polynomial over
  !> the step H, whose stability the pre-flight check judges by the ABM formula's.
  pure function ex_steps(self) result(s)
    class(exponential_integrator), intent(in) :: self
    type(pece_steps) :: s
    s%h_joint = self%h; s%h_modal = self%h
    s%item_joint = 'h_slow'; s%item_modal = 'h_slow'
    s%exact_modal = .true.
  end function ex_steps

  pure integer function ex_state_size(self)
    class(exponential_integrator), intent(in) :: self
    ex_state_size = size(self%x) + size(self%hist%hq) + size(self%hist%hy)
  end function ex_state_size

  !> The state, then the history's accelerations and fast states.
  pure subroutine ex_get_state(self, v)
    class(exponential_integrator), intent(in) :: self
    real(dp), intent(out) :: v(:)
    integer :: a, b
    a = size(self%x); b = a + size(self%hist%hq)
    v(1:a) = self%x
    v(a+1:b) = reshape(self%hist%hq, [size(self%hist%hq)])
    v(b+1:) = reshape(self%hist%hy, [size(self%hist%hy)])
  end subroutine ex_get_state

  pure subroutine ex_set_state(self, v)
    class(exponential_integrator), intent(inout) :: self
    real(dp), intent(in) :: v(:)
    integer :: a, b
    a = size(self%x); b = a + size(self%hist%hq)
    self%x = v(1:a)
    self%hist%hq = reshape(v(a+1:b), shape(self%hist%hq))
    self%hist%hy = reshape(v(b+1:), shape(self%hist%hy))
    call refresh_history(self)
  end subroutine ex_set_state

  pure function ex_name(self) result(s)
    class(exponential_integrator), intent(in) :: self
    character(len=:), allocatable :: s
    s = 'exponential'
  end function ex_name

end module pymr_integrator_exponential
