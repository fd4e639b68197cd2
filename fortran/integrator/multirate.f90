!> Multirate Nordsieck ABM integration with the paper's coupling, 'full' (docs/method.md
!> section 4; paper eqs. 33-43): the baseline that the 'response' coupling is measured against.
!>
!> A macro step of size H = k h: the fast coordinates take k - 1 ABM steps of size h,
!> each evaluating the fast equation with the slow state and accelerations extrapolated
!> from the slow Nordsieck array (its polynomial at s = i h / H, which is C(alpha)
!> rescaling followed by the Pascal predictor, eq. 37). At the end of the macro step both
!> arrays are predicted and one full evaluation gives the slow accelerations (Schur
!> complement) and the fast ones consistent with them; both are corrected. With k = 1
!> this is the single-rate PECE method.
module pymr_integrator_multirate
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_integrator_ode, only : ode_system, partitioned_system
  use pymr_integrator_stepper, only : stepper_t, step_counts, pece_steps, state_record, project_step, projection_eta, step_underflow, &
    & least_step
  use pymr_integrator_nordsieck, only : nq, nordsieck_predict, nordsieck_correct, nordsieck_value, &
    & nordsieck_from_history, nordsieck_rescale, corrector_l
  use pymr_integrator_abm, only : rk4_step, check_finite, pece_step
  use pymr_integrator_control, only : step_control, error_weights, wrms_norm
  implicit none
  private
  public :: multirate_integrator

  !> What a multirate run has done.
  type :: mr_counts_t
    !> Macro (slow) steps, fast steps, slow, fast and starting evaluations, rejected macro steps.
    integer :: steps_slow = 0, steps_fast = 0, evals_slow = 0, evals_fast = 0, evals_start = 0, rejected = 0
  end type mr_counts_t

  !> Work arrays of a macro step.
  type :: mr_work_t
    !> Adaptive: the arrays at the start of the macro step, the error weights, the coupling
    !> error's fast derivative.
    real(dp), allocatable :: zs0(:, :), zf0(:, :), ws(:), wf(:), fx(:)
    !> Predicted and corrected slow (zp, zn) and fast (wp, wn) arrays, derivatives, corrections,
    !> the extrapolated slow state and accelerations, the fast steps' iterate.
    real(dp), allocatable :: zp(:, :), zn(:, :), wp(:, :), wn(:, :), fs(:), ff(:), gs(:), gf(:), xs(:), acc(:), &
      & xf(:)
  end type mr_work_t

  !> Dense output of the fast state inside the last macro step (or the start): its values
  !> xb(:, 0:nb) and derivatives fb(:, 0:nb) at the fast steps from tb on, nb steps of hb.
  !> The fast array's polynomial is its last step's: evaluated back over the macro step it
  !> would grow like s^3 (at k = 30 it put 13 m/s of error into the tank's muzzle velocity).
  type :: fast_steps_t
    real(dp), allocatable :: xb(:, :), fb(:, :)
    real(dp) :: tb = 0.0_dp, hb = 0.0_dp
    integer :: nb = 0
  end type fast_steps_t

  !> The fast equations as a system of their own, for the fast steps inside a macro step:
  !> the fast state's derivative with the slow state xs and accelerations acc given (their
  !> extrapolation from the slow array), as MRIStep's inner system is forced by the slow
  !> one. The fast steps are the single-rate stepper's (pece_step) on it.
  type, extends(ode_system) :: forced_fast_system
    class(partitioned_system), pointer :: full => null()
    real(dp), allocatable :: xs(:), acc(:)
    !> Positions of the fast state in the full one (for error messages).
    integer, allocatable :: fast_map(:)
  contains
    procedure :: eval => forced_eval
    procedure :: component_name => forced_name
  end type forced_fast_system

  !> Multirate integrator state.
  type, extends(stepper_t) :: multirate_integrator
    !> Slow and fast coordinates, step ratio k = H/h.
    integer :: ns = 0, nf = 0, k = 1
    !> Time of the Nordsieck arrays (s), start time (fixed steps end at t0 + n H with an
    !> integer n, not a sum of steps).
    real(dp) :: t = 0.0_dp, t0 = 0.0_dp
    !> Slow step H and fast step h (s): set by init, changed by the stepper only.
    real(dp), private :: hs = 0.0_dp, hf = 0.0_dp
    !> Slow Nordsieck array (2ns, 0:3) scaled with H, fast one (2nf, 0:3) scaled with h.
    real(dp), allocatable :: zs(:, :), zf(:, :)
    !> Counters.
    type(mr_counts_t) :: cnt
    !> Adaptive: local-error control of both steps (weighted RMS norms, as CVODE), the step
    !> ratio k chosen within [1, k_max].
    logical :: adaptive = .false.
    type(step_control) :: ctl
    integer :: k_max = 1
    !> Adaptive: the largest fast step (s), within the PECE stability limit of the fastest
    !> mode (an error estimate sees an instability only once it has grown).
    real(dp) :: hf_max = huge(1.0_dp)
    !> Work arrays.
    type(mr_work_t) :: wk
    !> Positions of the slow and fast states in the full state (for error messages).
    integer, allocatable :: slow_map(:), fast_map(:)
    !> Dense output of the fast state.
    type(fast_steps_t) :: dense
  contains
    procedure :: init => mr_init
    procedure :: start => mr_start
    procedure :: advance => mr_advance
    procedure :: time => mr_time
    procedure :: value_at => mr_value_at
    procedure :: record => mr_record
    procedure :: counts => mr_counts
    procedure :: name => mr_name
    procedure :: pece => mr_steps
    procedure :: state_size => mr_state_size
    procedure :: get_state => mr_get_state
    procedure :: set_state => mr_set_state
    procedure :: set_ratio => mr_set_ratio
  end type multirate_integrator

contains

  !> Allocate for ns slow and nf fast coordinates, step ratio k; adaptive runs control
  !> both steps with `ctl`, the fast one at most hf_max, and keep the ratio within [1, k_max].
  !> h: the fast step the start takes (its macro step k h), which the pre-flight check reads
  !> before the start.
  subroutine mr_init(self, ns, nf, k, adaptive, ctl, k_max, hf_max, h)
    class(multirate_integrator), intent(inout) :: self
    integer, intent(in) :: ns, nf, k
    logical, intent(in), optional :: adaptive
    type(step_control), intent(in), optional :: ctl
    integer, intent(in), optional :: k_max
    real(dp), intent(in), optional :: hf_max, h
    self%ns = ns; self%nf = nf; self%k = k
    if (present(h)) then
      self%hf = h; self%hs = k*h
    end if
    if (present(hf_max)) self%hf_max = hf_max
    if (present(adaptive)) self%adaptive = adaptive
    if (present(ctl)) self%ctl = ctl
    self%k_max = max(k, 1)
    if (present(k_max)) self%k_max = max(k_max, 1)
    allocate(self%wk%zs0(2*ns, 0:nq), self%wk%zf0(2*nf, 0:nq), self%wk%ws(2*ns), self%wk%wf(2*nf), self%wk%fx(2*nf))
    allocate(self%zs(2*ns, 0:nq), self%zf(2*nf, 0:nq), self%wk%zp(2*ns, 0:nq), self%wk%zn(2*ns, 0:nq), &
      & self%wk%wp(2*nf, 0:nq), self%wk%wn(2*nf, 0:nq), self%wk%fs(2*ns), self%wk%ff(2*nf), self%wk%gs(2*ns), &
      & self%wk%gf(2*nf), &
      & self%wk%xs(2*ns), self%wk%acc(ns), self%wk%xf(2*nf))
    self%slow_map = slow_index(ns, nf)
    self%fast_map = fast_index(ns, nf)
    allocate(self%dense%xb(2*nf, 0:2*k), self%dense%fb(2*nf, 0:2*k))
  end subroutine mr_init

  !> Start at (t0, x0), x0 = [q_s; q_f; qd_s; qd_f]: classical RK4 steps of size h on the
  !> coupled system up to t0 + 2H (local error O(h^5)), recording the derivatives that
  !> build the slow array (at t0, t0 + H, t0 + 2H) and the fast one (last three fast points).
  !> Start at (t0, x0) with the fast step h, macro step k h (the stepper interface: the
  !> system must be partitioned into slow and fast coordinates).
  subroutine mr_start(self, sys, t0, x0, h, error)
    class(multirate_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    real(dp), intent(in) :: t0, x0(:), h
    type(error_type), allocatable, intent(out) :: error
    select type (sys)
    class is (partitioned_system)
      call start_partitioned(self, sys, t0, x0, self%k*h, error)
    class default
      call fatal_error(error, 'multirate integration needs a system partitioned into slow and fast coordinates')
    end select
  end subroutine mr_start

  !> One macro step (the stepper interface).
  subroutine mr_advance(self, sys, error)
    class(multirate_integrator), intent(inout) :: self
    class(ode_system), intent(inout) :: sys
    type(error_type), allocatable, intent(out) :: error
    select type (sys)
    class is (partitioned_system)
      call mr_step(self, sys, error)
    class default
      call fatal_error(error, 'multirate integration needs a system partitioned into slow and fast coordinates')
    end select
  end subroutine mr_advance

  pure real(dp) function mr_time(self)
    class(multirate_integrator), intent(in) :: self
    mr_time = self%t
  end function mr_time

  !> What a checkpoint keeps beside the Nordsieck arrays: ratio, times, steps, counts.
  subroutine mr_record(self, rec)
    class(multirate_integrator), intent(inout) :: self
    type(state_record), intent(inout) :: rec
    call rec%item(self%k); call rec%item(self%t); call rec%item(self%hs); call rec%item(self%hf)
    call rec%item(self%t0)
    call rec%item(self%cnt%steps_slow); call rec%item(self%cnt%steps_fast); call rec%item(self%cnt%evals_slow)
    call rec%item(self%cnt%evals_fast); call rec%item(self%cnt%evals_start); call rec%item(self%cnt%rejected)
  end subroutine mr_record

  pure function mr_counts(self) result(c)
    class(multirate_integrator), intent(in) :: self
    type(step_counts) :: c
    c%steps_slow = self%cnt%steps_slow; c%steps_fast = self%cnt%steps_fast
    c%rejected = self%cnt%rejected; c%h_last = self%hs; c%ratio = self%k
  end function mr_counts

  pure function mr_name(self) result(s)
    class(multirate_integrator), intent(in) :: self
    character(len=:), allocatable :: s
    s = 'multirate'
  end function mr_name

  !> PECE steps of size h on the modal coordinates only: the joints' vibrations are
  !> judged by the macro-step map.
  pure function mr_steps(self) result(s)
    class(multirate_integrator), intent(in) :: self
    type(pece_steps) :: s
    s%h_modal = self%hf; s%item_modal = 'h_fast'
  end function mr_steps

  pure integer function mr_state_size(self)
    class(multirate_integrator), intent(in) :: self
    mr_state_size = size(self%zs) + size(self%zf)
  end function mr_state_size

  !> [q; qd] from both arrays' value columns, then their higher columns.
  pure subroutine mr_get_state(self, v)
    class(multirate_integrator), intent(in) :: self
    real(dp), intent(out) :: v(:)
    integer :: ns, nf, n, m
    ns = self%ns; nf = self%nf; n = ns + nf
    v(1:ns) = self%zs(1:ns, 0); v(ns+1:n) = self%zf(1:nf, 0)
    v(n+1:n+ns) = self%zs(ns+1:, 0); v(n+ns+1:2*n) = self%zf(nf+1:, 0)
    m = 2*ns*nq
    v(2*n+1:2*n+m) = reshape(self%zs(:, 1:), [m])
    v(2*n+m+1:) = reshape(self%zf(:, 1:), [2*nf*nq])
  end subroutine mr_get_state

  pure subroutine mr_set_state(self, v)
    class(multirate_integrator), intent(inout) :: self
    real(dp), intent(in) :: v(:)
    integer :: ns, nf, n, m
    ns = self%ns; nf = self%nf; n = ns + nf
    self%zs(1:ns, 0) = v(1:ns); self%zf(1:nf, 0) = v(ns+1:n)
    self%zs(ns+1:, 0) = v(n+1:n+ns); self%zf(nf+1:, 0) = v(n+ns+1:2*n)
    m = 2*ns*nq
    self%zs(:, 1:) = reshape(v(2*n+1:2*n+m), [2*ns, nq])
    self%zf(:, 1:) = reshape(v(2*n+m+1:), [2*nf, nq])
  end subroutine mr_set_state

  pure subroutine mr_set_ratio(self, k)
    class(multirate_integrator), intent(inout) :: self
    integer, intent(in) :: k
    self%k = k
  end subroutine mr_set_ratio

  subroutine start_partitioned(self, sys, t0, x0, hs, error)
    class(multirate_integrator), intent(inout) :: self
    class(partitioned_system), intent(inout) :: sys
    real(dp), intent(in) :: t0, x0(:), hs
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: x(:), f(:), fsl(:, :), ffa(:, :)
    integer :: i, ns, nf, n, nsteps
    real(dp) :: t
    ns = self%ns; nf = self%nf; n = ns + nf
    self%hs = hs; self%hf = hs/self%k
    nsteps = 2*self%k
    allocate(x(2*n), f(2*n), fsl(2*ns, 0:2), ffa(2*nf, 0:nsteps))
    x = x0; t = t0
    do i = 0, nsteps
      call sys%eval(t, x, f, error); self%cnt%evals_start = self%cnt%evals_start + 1
      if (allocated(error)) return
      call check_finite(sys, t, f, 'derivative', error); if (allocated(error)) return
      if (mod(i, self%k) == 0) fsl(:, i/self%k) = slow_part(f)
      ffa(:, i) = fast_part(f)
      call keep_fast_point(self, i, fast_part(x), ffa(:, i))
      if (i == nsteps) exit
      call rk4_step(sys, t, self%hf, x, f, self%cnt%evals_start, error); if (allocated(error)) return
      t = t0 + (i + 1)*self%hf
    end do
    call nordsieck_from_history(slow_part(x), fsl(:, 2), fsl(:, 1), fsl(:, 0), self%hs, self%zs)
    call nordsieck_from_history(fast_part(x), ffa(:, nsteps), ffa(:, nsteps - 1), ffa(:, nsteps - 2), self%hf, self%zf)
    self%t0 = t0
    self%t = t0 + 2*hs
    self%cnt%steps_slow = 2; self%cnt%steps_fast = nsteps
    self%dense%tb = t0; self%dense%hb = self%hf; self%dense%nb = nsteps
  contains
    pure function slow_part(v) result(r)
      real(dp), intent(in) :: v(:)
      real(dp) :: r(2*ns)
      r = [v(1:ns), v(n+1:n+ns)]
    end function slow_part
    pure function fast_part(v) result(r)
      real(dp), intent(in) :: v(:)
      real(dp) :: r(2*nf)
      r = [v(ns+1:n), v(n+ns+1:2*n)]
    end function fast_part
  end subroutine start_partitioned

  !> One macro step. Fixed steps: `try_macro_step` once. Adaptive: the slow corrector's
  !> error estimate sets the next macro step H, the largest fast one sets the fast step h,
  !> and k = H/h is rounded into [1, k_max] (H shrinks when k would exceed k_max). A
  !> rejected macro step is retried from its start with both steps rescaled, and so is one
  !> whose state the system's projection does not bring onto its constraints.
  subroutine mr_step(self, sys, error)
    class(multirate_integrator), intent(inout) :: self
    class(partitioned_system), intent(inout) :: sys
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: err_s, err_f, hs_new, hf_new, hs0, hf0
    integer :: k_new, projection_fails
    logical :: retry
    projection_fails = 0
    if (.not. self%adaptive) then
      call try_macro_step(self, sys, err_s, err_f, error); if (allocated(error)) return
      call close_macro_step(self, sys, projection_fails, retry, error); if (allocated(error)) return
      call finish_macro_step(self)
      return
    end if
    self%wk%zs0 = self%zs; self%wk%zf0 = self%zf
    hs0 = self%hs; hf0 = self%hf
    call error_weights(self%ctl, self%zs(:, 0), self%wk%ws)
    call error_weights(self%ctl, self%zf(:, 0), self%wk%wf, self%ns + 1)
    do
      call try_macro_step(self, sys, err_s, err_f, error); if (allocated(error)) return
      if (err_s <= 1.0_dp .and. err_f <= 1.0_dp) then
        call close_macro_step(self, sys, projection_fails, retry, error); if (allocated(error)) return
        if (.not. retry) exit
        hs_new = projection_eta*self%hs; hf_new = projection_eta*self%hf
      else
        hs_new = self%hs*min(self%ctl%ratio(err_s, err_s <= 1.0_dp), 1.0_dp)
        hf_new = self%hf*min(self%ctl%ratio(err_f, err_f <= 1.0_dp), 1.0_dp)
      end if
      self%cnt%rejected = self%cnt%rejected + 1
      call choose_ratio(self, hs_new, hf_new, k_new)
      if (hf_new < least_step(self%ctl%h_min, self%t)) then
        call step_underflow(error, self%t, 'fast step', hf_new); return
      end if
      ! back to the start of the macro step, with the arrays' own scaling
      self%zs = self%wk%zs0; self%zf = self%wk%zf0
      self%hs = hs0; self%hf = hf0
      call rescale_steps(self, hs_new, hf_new, k_new)
    end do
    call finish_macro_step(self)
    ! an accepted step's successor no less than the least step (its error test fails there)
    hf_new = max(min(self%hf*self%ctl%ratio(err_f, .true.), self%hf_max), least_step(self%ctl%h_min, self%t))
    hs_new = max(min(self%hs*self%ctl%ratio(err_s, .true.), self%ctl%h_max), hf_new)
    call choose_ratio(self, hs_new, hf_new, k_new)
    if (hs_new /= self%hs .or. k_new /= self%k) call rescale_steps(self, hs_new, hf_new, k_new)
  end subroutine mr_step

  !> Step ratio k for the wanted slow and fast steps: nint(H/h) within [1, k_max]; on
  !> return H = k h with h no larger than wanted (H shrinks when k is capped).
  pure subroutine choose_ratio(self, hs, hf, k)
    class(multirate_integrator), intent(in) :: self
    real(dp), intent(inout) :: hs, hf
    integer, intent(out) :: k
    k = min(max(nint(hs/hf), 1), self%k_max)
    if (hs/k > hf) hs = k*hf
    hf = hs/k
  end subroutine choose_ratio

  !> Rescale both Nordsieck arrays to the macro step hs and fast step hf = hs/k.
  pure subroutine rescale_steps(self, hs, hf, k)
    class(multirate_integrator), intent(inout) :: self
    real(dp), intent(in) :: hs, hf
    integer, intent(in) :: k
    call nordsieck_rescale(self%zs, hs/self%hs)
    call nordsieck_rescale(self%zf, hf/self%hf)
    self%hs = hs; self%hf = hf; self%k = k
  end subroutine rescale_steps

  !> Accept the macro step computed by try_macro_step and closed by close_macro_step.
  subroutine finish_macro_step(self)
    class(multirate_integrator), intent(inout) :: self
    self%zs = self%wk%zn
    self%zf = self%wk%wn
    self%cnt%steps_fast = self%cnt%steps_fast + 1
    self%t = macro_end(self)
    self%cnt%steps_slow = self%cnt%steps_slow + 1
  end subroutine finish_macro_step

  !> k - 1 fast ABM steps with the extrapolated slow state, then the predicted slow and
  !> fast arrays corrected with one synchronised evaluation; results in zn (slow) and wn
  !> (fast), zs unchanged. err_s, err_f: weighted RMS local error estimates l0 |g| of the
  !> slow corrector and the largest of the fast ones (adaptive runs only).
  subroutine try_macro_step(self, sys, err_s, err_f, error)
    class(multirate_integrator), intent(inout) :: self
    class(partitioned_system), intent(inout) :: sys
    real(dp), intent(out) :: err_s, err_f
    type(error_type), allocatable, intent(out) :: error
    integer :: nf
    err_s = 0.0_dp
    call fast_steps(self, sys, err_f, error); if (allocated(error)) return
    call nordsieck_predict(self%zs, self%wk%zp)
    call nordsieck_predict(self%zf, self%wk%wp)
    call sys%sync_rhs(macro_end(self), self%wk%zp(:, 0), self%wk%wp(:, 0), self%wk%fs, self%wk%ff, error)
    self%cnt%evals_slow = self%cnt%evals_slow + 1
    if (allocated(error)) return
    call nordsieck_correct(self%wk%zp, self%hs, self%wk%fs, self%wk%zn, self%wk%gs)
    call nordsieck_correct(self%wk%wp, self%hf, self%wk%ff, self%wk%wn, self%wk%gf)
    call keep_fast_point(self, self%k, self%wk%wn(:, 0), self%wk%wn(:, 1)/self%hf)
    self%dense%tb = self%t; self%dense%hb = self%hf; self%dense%nb = self%k
    if (.not. self%adaptive) return
    err_s = abs(corrector_l(0))*wrms_norm(self%wk%gs, self%wk%ws)
    err_f = max(err_f, abs(corrector_l(0))*wrms_norm(self%wk%gf, self%wk%wf))
    if (self%k == 1) return
    ! Coupling error: the fast substeps used slow accelerations extrapolated from the slow
    ! array. Their error at the end of the macro step shows in the fast accelerations with
    ! the extrapolated and the synchronised slow accelerations, d = ff - f_x. Grown like
    ! the quadratic extrapolation's error s(s+1)(s+2)/6 over the step, it displaces the
    ! fast state by 0.106 H^2 d and its rates by 0.375 H d; this error bounds H.
    call slow_extrapolation(self%zs, self%hs, 1.0_dp, self%wk%xs, self%wk%acc)
    call sys%fast_rhs(self%t + self%hs, self%wk%xs, self%wk%wp(:, 0), self%wk%acc, self%wk%fx, error)
    self%cnt%evals_fast = self%cnt%evals_fast + 1
    if (allocated(error)) return
    nf = self%nf
    self%wk%fx(1:nf) = 0.10556_dp*self%hs**2*(self%wk%ff(nf+1:) - self%wk%fx(nf+1:))
    self%wk%fx(nf+1:) = 0.375_dp*self%hs*(self%wk%ff(nf+1:) - self%wk%fx(nf+1:))
    err_s = max(err_s, wrms_norm(self%wk%fx, self%wk%wf))
  end subroutine try_macro_step

  !> End of the macro step being taken: t + H, or with fixed steps t0 + n H.
  pure real(dp) function macro_end(self)
    class(multirate_integrator), intent(in) :: self
    if (self%adaptive) then
      macro_end = self%t + self%hs
    else
      macro_end = self%t0 + (self%cnt%steps_slow + 1)*self%hs
    end if
  end function macro_end

  !> Positions of the slow state [q_s; qd_s] in the full state [q_s; q_f; qd_s; qd_f].
  pure function slow_index(ns, nf) result(idx)
    integer, intent(in) :: ns, nf
    integer :: idx(2*ns), i
    idx = [(i, i = 1, ns), (ns + nf + i, i = 1, ns)]
  end function slow_index

  !> Positions of the fast state [q_f; qd_f] in the full state.
  pure function fast_index(ns, nf) result(idx)
    integer, intent(in) :: ns, nf
    integer :: idx(2*nf), i
    idx = [(ns + i, i = 1, nf), (2*ns + nf + i, i = 1, nf)]
  end function fast_index

  !> Slow state xs and accelerations acc at t + s H from the slow Nordsieck array zs
  !> (scaled with H = hs).
  pure subroutine slow_extrapolation(zs, hs, s, xs, acc)
    real(dp), intent(in) :: zs(:, 0:), hs, s
    real(dp), intent(out) :: xs(:), acc(:)
    integer :: ns
    ns = size(acc)
    call nordsieck_value(zs, s, xs)
    acc = (zs(ns+1:, 1) + s*(2.0_dp*zs(ns+1:, 2) + 3.0_dp*s*zs(ns+1:, 3)))/hs
  end subroutine slow_extrapolation

  !> The k - 1 fast steps of the macro step from (t, zf): the single-rate ABM step
  !> (pece_step) on the fast equations forced by the slow motion extrapolated to each step.
  !> err_f: the largest weighted corrector estimate of them (adaptive runs).
  subroutine fast_steps(self, sys, err_f, error)
    class(multirate_integrator), intent(inout) :: self
    class(partitioned_system), intent(inout), target :: sys
    real(dp), intent(out) :: err_f
    type(error_type), allocatable, intent(out) :: error
    type(forced_fast_system) :: fast
    integer :: i
    err_f = 0.0_dp
    fast%full => sys
    allocate(fast%xs(2*self%ns), fast%acc(self%ns))
    fast%fast_map = self%fast_map
    call keep_fast_point(self, 0, self%zf(:, 0), self%zf(:, 1)/self%hf)
    do i = 1, self%k - 1
      call slow_extrapolation(self%zs, self%hs, real(i, dp)/self%k, fast%xs, fast%acc)
      call pece_step(fast, self%t + i*self%hf, self%hf, 1, self%zf, self%wk%wp, self%wk%wn, self%wk%xf, self%wk%ff, &
        & self%wk%gf, self%cnt%evals_fast, error); if (allocated(error)) return
      if (self%adaptive) err_f = max(err_f, abs(corrector_l(0))*wrms_norm(self%wk%gf, self%wk%wf))
      call keep_fast_point(self, i, self%wk%wn(:, 0), self%wk%wn(:, 1)/self%hf)
      self%zf = self%wk%wn
      self%cnt%steps_fast = self%cnt%steps_fast + 1
    end do
  end subroutine fast_steps

  !> The fast derivative [qd_f; qdd_f] at (t, x) with the slow state and accelerations held.
  subroutine forced_eval(self, t, x, f, error)
    class(forced_fast_system), intent(inout) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: x(:)
    real(dp), intent(out), contiguous :: f(:)
    type(error_type), allocatable, intent(out) :: error
    call self%full%fast_rhs(t, self%xs, x, self%acc, f, error)
  end subroutine forced_eval

  !> The name of fast state component i: the full system's.
  function forced_name(self, i) result(name)
    class(forced_fast_system), intent(in) :: self
    integer, intent(in) :: i
    character(len=:), allocatable :: name
    name = self%full%component_name(self%fast_map(i))
  end function forced_name

  !> Full state [q_s; q_f; qd_s; qd_f] at time t (t within the last macro step).
  pure subroutine mr_value_at(self, t, x)
    class(multirate_integrator), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(out) :: x(:)
    real(dp) :: xs(2*self%ns), xf(2*self%nf)
    integer :: ns, nf, n
    ns = self%ns; nf = self%nf; n = ns + nf
    call nordsieck_value(self%zs, (t - self%t)/self%hs, xs)
    if (self%dense%nb > 0) then
      call fast_dense(self, t, xf)
    else
      call nordsieck_value(self%zf, (t - self%t)/self%hf, xf)
    end if
    x(1:ns) = xs(1:ns); x(n+1:n+ns) = xs(ns+1:)
    x(ns+1:n) = xf(1:nf); x(n+ns+1:) = xf(nf+1:)
  end subroutine mr_value_at

  !> The fast state x and its derivative f at fast step i of the dense output's steps.
  subroutine keep_fast_point(self, i, x, f)
    class(multirate_integrator), intent(inout) :: self
    integer, intent(in) :: i
    real(dp), intent(in) :: x(:), f(:)
    real(dp), allocatable :: grown(:, :)
    if (size(self%dense%xb, 2) <= i) then
      allocate(grown(size(x), 0:2*i + 1))
      grown(:, 0:size(self%dense%xb, 2) - 1) = self%dense%xb; call move_alloc(grown, self%dense%xb)
      allocate(grown(size(x), 0:2*i + 1))
      grown(:, 0:size(self%dense%fb, 2) - 1) = self%dense%fb; call move_alloc(grown, self%dense%fb)
    end if
    self%dense%xb(:, i) = x; self%dense%fb(:, i) = f
  end subroutine keep_fast_point

  !> Fast state at t from the cubic Hermite interpolant of the kept fast steps (the order
  !> of the steps themselves, O(h^4)); t is within them.
  pure subroutine fast_dense(self, t, xf)
    class(multirate_integrator), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(out) :: xf(:)
    real(dp) :: th
    integer :: i
    associate (d => self%dense)
      i = min(max(ceiling((t - d%tb)/d%hb - 1.0e-9_dp), 1), d%nb)
      th = (t - (d%tb + (i - 1)*d%hb))/d%hb
      xf = (2*th**3 - 3*th**2 + 1)*d%xb(:, i - 1) + (th**3 - 2*th**2 + th)*d%hb*d%fb(:, i - 1) + &
        & (3*th**2 - 2*th**3)*d%xb(:, i) + (th**3 - th**2)*d%hb*d%fb(:, i)
    end associate
  end subroutine fast_dense

  !> The macro step computed by try_macro_step (zn, wn) checked finite and its state, the
  !> value columns of both arrays joined into [q_s; q_f; qd_s; qd_f], projected onto the
  !> system's constraints (project_step: retry when an adaptive step is to be redone
  !> smaller); the dense output's last fast point follows.
  subroutine close_macro_step(self, sys, fails, retry, error)
    class(multirate_integrator), intent(inout) :: self
    class(partitioned_system), intent(inout) :: sys
    integer, intent(inout) :: fails
    logical, intent(out) :: retry
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: x(2*(self%ns + self%nf)), t
    integer :: ns, nf
    ns = self%ns; nf = self%nf
    retry = .false.
    t = macro_end(self)
    call check_finite(sys, t, self%wk%zn(:, 0), 'state', error, self%slow_map); if (allocated(error)) return
    call check_finite(sys, t, self%wk%wn(:, 0), 'state', error, self%fast_map); if (allocated(error)) return
    x = [self%wk%zn(1:ns, 0), self%wk%wn(1:nf, 0), self%wk%zn(ns+1:, 0), self%wk%wn(nf+1:, 0)]
    call project_step(sys, t, x, self%adaptive, fails, retry, error)
    if (allocated(error) .or. retry) return
    self%wk%zn(:, 0) = [x(1:ns), x(ns+nf+1:2*ns+nf)]
    self%wk%wn(:, 0) = [x(ns+1:ns+nf), x(2*ns+nf+1:)]
    if (self%dense%nb > 0) self%dense%xb(:, self%dense%nb) = self%wk%wn(:, 0)
  end subroutine close_macro_step

end module pymr_integrator_multirate
