!> Pre-flight stability check of fixed-step runs (issue 6, hard case 1), for any stepper.
!>
!> The model is linearised at its initial state: M, and K = -dP/dq, D = -dP/dqd by central
!> differences. Each eigenvalue lambda of [0 I; -M^-1 K  -M^-1 D] with Re lambda <= 0 is a
!> vibration the step must resolve stably: the PECE growth factor at lambda h (see
!> pymr_integrator_stability) must not exceed 1. A mode is charged to the coordinate that
!> carries most of its kinetic energy, and so to the step the stepper takes on that kind of
!> coordinate (its `pece` steps). A multirate stepper is then applied to the linearised model
!> itself: the growth of its macro step, by power iteration on its whole state, must stay
!> below `run_growth` over the run.
module pymr_driver_preflight
  use pymr_env_kinds, only : dp, pi
  use pymr_env_error, only : error_type, fatal_error, stat_input
  use pymr_env_lapack, only : potrf, potrs, geev_real, factor_inverse, general_solve, sygvd
  use pymr_model, only : model_t, modal_stiffness_damping, model_counters
  use pymr_model_loops, only : loop_rows, independent_rows, loop_jacobian, constrain_inverse
  use pymr_integrator_stability, only : pece_growth, pece_limit
  use pymr_integrator_ode, only : partitioned_system
  use pymr_integrator_stepper, only : stepper_t, pece_steps, step_counts
  use pymr_env_text, only : itoa
  implicit none
  private
  public :: check_step_stability, check_mass_matrix, normal_modes, static_start, top_frequency

  !> Static start: most Newton iterations, and the change (relative to max(1, |q|)) below
  !> which it has converged.
  integer, parameter :: newton_max = 30
  real(dp), parameter :: newton_tol = 1.0e-13_dp

  !> Largest growth of a linearised perturbation over a whole run that is accepted: a
  !> step whose growth factor per step is above 1 only by roundoff-sized amounts (an
  !> undamped mode on the edge) passes; a real instability multiplies it by far more.
  real(dp), parameter :: run_growth = 10.0_dp

  !> Steppers whose whole state has at most this many components get the spectral radius
  !> of their macro-step map from its matrix (LAPACK dgeev); larger ones by power iteration
  !> (at most max_iterations macro steps). A Krylov (Arnoldi) estimate was tried and
  !> dropped: on the stiff barrel its Ritz values lay outside the spectrum (non-normal map).
  integer, parameter :: max_exact_state = 400, max_iterations = 3000

  !> Natural modes: an eigenvalue of the linearised model below this size (1/s) is a rigid-body
  !> motion whatever the rest of the spectrum: it changes a motion by a factor e in no less
  !> than 1e9 s, the longest run (&scene t_end). A model with no force at all (a free chain
  !> drifting) has nothing else to set the scale of its roundoff (1e-12 /s measured).
  real(dp), parameter :: lambda_floor = 1.0e-9_dp

  !> The model linearised at a state, M qdd = -(K q + C qd), as a partitioned system: a
  !> stepper applied to it gives its linearised step map.
  type, extends(partitioned_system) :: linear_system
    integer :: ns = 0, nf = 0
    real(dp), allocatable :: minv(:, :), k(:, :), c(:, :), mffinv(:, :), mfs(:, :), kf(:), df(:), tfs(:, :)
  contains
    procedure :: eval => lin_eval
    procedure :: component_name => lin_name
    procedure :: n_slow => lin_n_slow
    procedure :: n_fast => lin_n_fast
    procedure :: sync_rhs => lin_sync
    procedure :: fast_rhs => lin_fast
    procedure :: force_response => lin_response
  end type linear_system

contains

  !> Refuse (error naming the body and mode, its frequency and the largest stable step)
  !> fixed steps of the stepper `st` (made, not started) that cannot be stable at the
  !> initial state x = [q; qd].
  subroutine check_step_stability(model, x, st, label, t_end, where, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:)
    class(stepper_t), intent(in) :: st
    !> What the stepper is, for messages ("coupling 'response'").
    character(len=*), intent(in) :: label
    !> Length of the run (s): a step is refused when the linearised growth over the whole
    !> run would exceed `run_growth`.
    real(dp), intent(in) :: t_end
    character(len=*), intent(in) :: where
    type(error_type), allocatable, intent(out) :: error
    integer :: n, i, j, dom, worst
    real(dp), allocatable :: m(:, :), minv(:, :), k(:, :), c(:, :), a(:, :), ev(:, :), wr(:), wi(:), vr(:, :), wgt(:)
    real(dp) :: h, ratio, worst_ratio
    complex(dp) :: lam, worst_lam
    character(len=32) :: b1, b2, b3, b4
    type(pece_steps) :: steps
    type(step_counts) :: counts
    n = model%d%n
    if (n == 0) return
    steps = st%pece(); counts = st%counts()
    allocate(wgt(n))
    call linear_state(model, 0.0_dp, x, m, minv, k, c, a, error); if (allocated(error)) return
    allocate(wr(2*n), wi(2*n), vr(2*n, 2*n))
    if (steps%h_modal == steps%h_joint .and. counts%ratio == 1) then
      ! one step for every coordinate: the eigenvalues alone decide; the vectors are needed
      ! only to name the coordinate of a mode that fails
      ev = a
      call geev_real(ev, wr, wi, 'the linearised model', error); if (allocated(error)) return
      if (all_stable(wr, wi, steps%h_joint, t_end)) return
    end if
    call geev_real(a, wr, wi, 'the linearised model', error, vr); if (allocated(error)) return
    worst = 0; worst_ratio = 1.0_dp; worst_lam = (0.0_dp, 0.0_dp)
    i = 1
    do while (i <= 2*n)
      lam = cmplx(wr(i), wi(i), dp)
      ! each coordinate's share of the mode's kinetic energy, |v_j (M v)_j| (complex pairs
      ! packed): with the coupling terms of M, a joint that a fast modal vibration barely
      ! moves takes no share for its large inertia M_jj alone
      wgt = abs(vr(1:n, i)*matmul(m, vr(1:n, i)))
      if (wi(i) /= 0.0_dp .and. i < 2*n) wgt = wgt + abs(vr(1:n, i + 1)*matmul(m, vr(1:n, i + 1)))
      dom = maxloc(wgt, 1)
      h = merge(steps%h_modal, steps%h_joint, dom > model%d%nj)
      if (grows(lam, h, t_end)) then
        ratio = h/pece_limit(lam)
        if (ratio > worst_ratio) then
          worst_ratio = ratio; worst = dom; worst_lam = lam
        end if
      end if
      if (wi(i) /= 0.0_dp) i = i + 1
      i = i + 1
    end do
    if (worst == 0) then
      if (counts%ratio > 1) call check_macro_step(model, x, m, minv, k, c, max(maxval(wr), 0.0_dp), st, label, t_end, where, error)
      return
    end if
    h = merge(steps%h_modal, steps%h_joint, worst > model%d%nj)
    write(b1, '(es9.2)') h
    write(b2, '(f0.1)') abs(worst_lam)/(2.0_dp*pi)
    if (abs(worst_lam)*h < 10.0_dp) then
      write(b3, '(f5.3)') abs(worst_lam)*h
    else
      write(b3, '(es9.2)') abs(worst_lam)*h
    end if
    write(b4, '(es9.2)') pece_limit(worst_lam)
    call fatal_error(error, where // trim(merge(steps%item_modal, steps%item_joint, worst > model%d%nj)) // &
      & ': a fixed step of ' // trim(adjustl(b1)) // ' s is not stable for ' // coordinate_name(model, worst) // ' (' // &
      & trim(b2) // ' Hz, omega*h = ' // trim(adjustl(b3)) // '); the largest stable step is ' // trim(adjustl(b4)) // &
      & ' s (the ABM PECE method is stable up to omega*h = 0.430 on an undamped mode): take a smaller step, ' // &
      & 'or adaptive = .true.')
  end subroutine check_step_stability

  !> Does the eigenvalue lam (a vibration or decay: growing modes are physical, not
  !> numerical) grow by more than run_growth over a run to t_end in fixed steps h? A step of 0
  !> leaves it to the macro-step map of multirate runs.
  logical function grows(lam, h, t_end)
    complex(dp), intent(in) :: lam
    real(dp), intent(in) :: h, t_end
    grows = .false.
    if (abs(lam) == 0.0_dp .or. real(lam) > 1.0e-9_dp*abs(lam) .or. h <= 0.0_dp) return
    grows = log(pece_growth(lam*h))*t_end/h > log(run_growth)
  end function grows

  !> No eigenvalue wr + i wi grows in fixed steps h over the run.
  logical function all_stable(wr, wi, h, t_end)
    real(dp), intent(in) :: wr(:), wi(:), h, t_end
    integer :: i
    all_stable = .true.
    do i = 1, size(wr)
      if (grows(cmplx(wr(i), wi(i), dp), h, t_end)) then
        all_stable = .false.; return
      end if
    end do
  end function all_stable

  !> The model linearised at (t, x = [q; qd]): M (symmetrised), K = -dP/dq and C = -dP/dqd
  !> by central differences with increments 1e-6 max(1, |x_j|). Its evaluations do not count
  !> as the run's.
  subroutine linearise(model, t, x, m, k, c)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, x(:)
    real(dp), allocatable, intent(out) :: m(:, :), k(:, :), c(:, :)
    type(model_counters) :: counters
    real(dp), allocatable :: q(:), qd(:), pp(:), pm(:)
    real(dp) :: del
    integer :: n, j
    n = model%d%n
    counters = model%counters()
    q = x(1:n); qd = x(n+1:2*n)
    allocate(k(n, n), c(n, n), pp(n), pm(n))
    call model%terms(t, q, qd)
    m = 0.5_dp*(model%wk%mm + transpose(model%wk%mm))
    do j = 1, n
      del = 1.0e-6_dp*max(1.0_dp, abs(q(j)))
      q(j) = x(j) + del; call model%forces(t, q, qd, pp)
      q(j) = x(j) - del; call model%forces(t, q, qd, pm)
      q(j) = x(j)
      k(:, j) = -(pp - pm)/(2.0_dp*del)
      del = 1.0e-6_dp*max(1.0_dp, abs(qd(j)))
      qd(j) = x(n + j) + del; call model%forces(t, q, qd, pp)
      qd(j) = x(n + j) - del; call model%forces(t, q, qd, pm)
      qd(j) = x(n + j)
      c(:, j) = -(pp - pm)/(2.0_dp*del)
    end do
    call model%set_counters(counters)
  end subroutine linearise

  !> Static equilibrium at t = 0 of the coordinates u (the others held as given): the
  !> generalised forces P_u(q, qd) vanish. Newton: q_u <- q_u + K_uu^-1 P_u with K = -dP/dq
  !> of the pre-flight linearisation. With loops, the equilibrium on their constraints
  !> (loop_newton_step). `names(i)` names coordinate i for messages. Its evaluations do not
  !> count as the run's.
  subroutine static_start(model, u, names, x, error, iterations, last_change)
    type(model_t), intent(inout) :: model
    integer, intent(in) :: u(:)
    character(len=*), intent(in) :: names(:)
    real(dp), intent(inout) :: x(:)
    type(error_type), allocatable, intent(out) :: error
    !> Newton iterations taken, and the largest change of a coordinate in the last one.
    integer, intent(out) :: iterations
    real(dp), intent(out) :: last_change
    type(model_counters) :: counters
    real(dp), allocatable :: du(:), lam(:)
    character(len=:), allocatable :: why
    integer :: it, worst
    logical :: loops
    iterations = 0; last_change = 0.0_dp
    if (size(u) == 0) return
    counters = model%counters()
    loops = model%wk%loops%n_used > 0
    if (loops) then
      call check_settle_loops(model, u, x, error); if (allocated(error)) return
      allocate(lam(model%wk%loops%n_used))
      lam = 0.0_dp
    end if
    do it = 1, newton_max
      if (loops) then
        call loop_newton_step(model, u, x, lam, du, error)
      else
        call newton_step(model, u, x, du, error)
      end if
      if (allocated(error)) then
        call model%set_counters(counters)
        why = error%message
        call fatal_error(error, '&scene: start: no static equilibrium at t = 0: ' // why // &
          & ' (a joint marked settle that no spring or stiffness holds has none)', stat_input); return
      end if
      x(u) = x(u) + du
      iterations = it; last_change = maxval(abs(du))
      if (all(abs(du) <= newton_tol*max(1.0_dp, abs(x(u))))) then
        call model%set_counters(counters); return
      end if
    end do
    call model%set_counters(counters)
    worst = maxloc(abs(du)/max(1.0_dp, abs(x(u))), 1)
    call fatal_error(error, "&scene: start: no static equilibrium found in " // itoa(newton_max) // &
      & ' Newton iterations (the last change of ' // trim(names(u(worst))) // ' was ' // fmt_es(du(worst)) // &
      & '): the loads may have none', stat_input)
  contains
    function fmt_es(v) result(s)
      real(dp), intent(in) :: v
      character(len=:), allocatable :: s
      character(len=16) :: buf
      write(buf, '(es10.3)') v
      s = trim(adjustl(buf))
    end function fmt_es
  end subroutine static_start

  !> One Newton step du = K_uu^-1 P_u of the static start without loops.
  subroutine newton_step(model, u, x, du, error)
    type(model_t), intent(inout) :: model
    integer, intent(in) :: u(:)
    real(dp), intent(in) :: x(:)
    real(dp), allocatable, intent(out) :: du(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: m(:, :), k(:, :), c(:, :), ku(:, :)
    integer :: n
    n = model%d%n
    call model%terms(0.0_dp, x(1:n), x(n+1:))
    du = model%wk%p(u)
    call linearise(model, 0.0_dp, x, m, k, c)
    ku = k(u, u)
    call general_solve(ku, du, 'the stiffness of the coordinates to settle', error)
  end subroutine newton_step

  !> With loops the coordinates u settle on their constraints: the equilibrium of
  !> M qdd = P + G^T lambda at rest, r = P_u(q) + G_u^T lambda = 0 with Phi(q) = 0 on the
  !> loops' used rows, for q_u and lambda (the other coordinates held). One Newton step on
  !> [dr/dq_u  G_u^T; G_u  0] [du; dlambda] = -[r; Phi], dr/dq_u by central differences
  !> (increments 1e-6 max(1, |q_j|)) at the given lambda, which is updated.
  subroutine loop_newton_step(model, u, x, lam, du, error)
    type(model_t), intent(inout) :: model
    integer, intent(in) :: u(:)
    real(dp), intent(in) :: x(:)
    real(dp), intent(inout) :: lam(:)
    real(dp), allocatable, intent(out) :: du(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: q(:), a(:, :), b(:), rp(:), rm(:), gu(:, :), phi(:)
    real(dp) :: del
    integer :: n, nu, nr, j
    n = model%d%n; nu = size(u); nr = size(lam)
    q = x(1:n)
    allocate(a(nu + nr, nu + nr), b(nu + nr), rp(nu), rm(nu))
    call settle_residual(model, q, x(n+1:), u, lam, b(1:nu), gu, phi)
    b(nu+1:) = phi
    a = 0.0_dp
    a(1:nu, nu+1:) = transpose(gu)
    a(nu+1:, 1:nu) = gu
    do j = 1, nu
      del = 1.0e-6_dp*max(1.0_dp, abs(x(u(j))))
      q(u(j)) = x(u(j)) + del; call settle_residual(model, q, x(n+1:), u, lam, rp)
      q(u(j)) = x(u(j)) - del; call settle_residual(model, q, x(n+1:), u, lam, rm)
      q(u(j)) = x(u(j))
      a(1:nu, j) = (rp - rm)/(2.0_dp*del)
    end do
    b = -b
    call general_solve(a, b, 'the stiffness of the coordinates to settle on the loops', error)
    if (allocated(error)) return
    du = b(1:nu)
    lam = lam + b(nu+1:)
  end subroutine loop_newton_step

  !> r = P_u(q) + G_u^T lambda at (q, qd) and t = 0 (the loops' used rows); optionally G_u
  !> and Phi of those rows.
  subroutine settle_residual(model, q, qd, u, lam, r, gu, phi)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: q(:), qd(:), lam(:)
    integer, intent(in) :: u(:)
    real(dp), intent(out) :: r(:)
    real(dp), allocatable, intent(out), optional :: gu(:, :), phi(:)
    real(dp) :: p(size(q))
    associate(d => model%d, wk => model%wk)
      call model%forces(0.0_dp, q, qd, p)
      call loop_rows(d, wk)
      r = p(u) + matmul(lam, wk%loops%jac(wk%loops%row_used(1:wk%loops%n_used), u))
      if (present(gu)) gu = wk%loops%jac(wk%loops%row_used(1:wk%loops%n_used), u)
      if (present(phi)) phi = wk%loops%residual(wk%loops%row_used(1:wk%loops%n_used))
    end associate
  end subroutine settle_residual

  !> The coordinates to settle must be able to move the loops' independent rows: else the
  !> loops hold them (a loop through joints that are held, not marked settle); and they must
  !> keep some freedom on them, else the start has nothing to settle.
  subroutine check_settle_loops(model, u, x, error)
    type(model_t), intent(inout) :: model
    integer, intent(in) :: u(:)
    real(dp), intent(in) :: x(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: r(size(u))
    real(dp), allocatable :: gu(:, :), phi(:)
    integer :: used(model%wk%loops%n_used), n_ind
    call settle_residual(model, x(1:model%d%n), x(model%d%n+1:), u, [(0.0_dp, n_ind = 1, model%wk%loops%n_used)], &
      & r, gu, phi)
    call independent_rows(gu, used, n_ind)
    if (n_ind < model%wk%loops%n_used) call fatal_error(error, '&scene: start: the coordinates to settle (the modal ' // &
      & 'ones and those of the joints marked settle) move only ' // itoa(n_ind) // ' of the loops'' ' // &
      & itoa(model%wk%loops%n_used) // ' independent constraints: the joints held fast hold the loops (mark settle ' // &
      & 'every joint of a loop that should settle)', stat_input)
    if (.not. allocated(error) .and. size(u) <= n_ind) call fatal_error(error, '&scene: start: the loops leave ' // &
      & 'the coordinates to settle no freedom (' // itoa(size(u)) // ' coordinates, ' // itoa(n_ind) // &
      & ' independent constraints on them): with the joints held they can only stay as given (mark settle ' // &
      & 'the joints of the loop, or start from the given state)', stat_input)
  end subroutine check_settle_loops

  !> The model linearised at (t, x): M, its (with loops, constrained) inverse, K, C, and the
  !> state matrix a built from them.
  subroutine linear_state(model, t, x, m, minv, k, c, a, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, x(:)
    real(dp), allocatable, intent(out) :: m(:, :), minv(:, :), k(:, :), c(:, :), a(:, :)
    type(error_type), allocatable, intent(out) :: error
    call linearise(model, t, x, m, k, c)
    call mass_inverse(model, x, m, minv, error); if (allocated(error)) return
    call state_matrix(minv, k, c, a)
  end subroutine linear_state

  !> The first-order state matrix [0 I; -M^-1 K  -M^-1 C] of the linearised model, from
  !> its (constrained) inverse mass matrix minv.
  pure subroutine state_matrix(minv, k, c, a)
    real(dp), intent(in) :: minv(:, :), k(:, :), c(:, :)
    real(dp), allocatable, intent(out) :: a(:, :)
    integer :: n, i
    n = size(minv, 1)
    allocate(a(2*n, 2*n))
    a = 0.0_dp
    do i = 1, n
      a(i, n + i) = 1.0_dp
    end do
    a(n+1:, 1:n) = -matmul(minv, k)
    a(n+1:, n+1:) = -matmul(minv, c)
  end subroutine state_matrix

  !> M^-1 of the linearisation at x (m from linearise); with closed loops the constrained
  !> inverse, whose accelerations keep the loops closed (to first order: the constraint
  !> rows at x, without their curvature).
  subroutine mass_inverse(model, x, m, minv, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:), m(:, :)
    real(dp), allocatable, intent(out) :: minv(:, :)
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: l(:, :), g(:, :)
    l = m
    allocate(minv(size(m, 1), size(m, 1)))
    call potrf(l, 'the mass matrix at the linearisation state', error); if (allocated(error)) return
    call factor_inverse(l, minv, 'the mass matrix', error); if (allocated(error)) return
    if (model%d%cuts%n_rows == 0) return
    call loop_jacobian(model%d, model%wk, x(1:model%d%n), g, error); if (allocated(error)) return
    call constrain_inverse(minv, g, error)
  end subroutine mass_inverse

  !> Natural modes of the model linearised at (t, x), each of one kind (the eigenvalues
  !> lambda of the state matrix [0 I; -M^-1 K  -M^-1 C]):
  !> - kind 1, a vibration: a complex pair of lambda (one taken): the undamped natural
  !>   frequency |lambda|/(2 pi) (Hz), the damping ratio -Re(lambda)/|lambda|;
  !> - kind 2, a rigid-body motion: |lambda| not resolved by the linearisation (at most the
  !>   largest of 1e-6 of the largest |lambda|, the square root of the size of the
  !>   difference error of M^-1 K, and lambda_floor): nothing holds the motion (a free joint, a free body in a
  !>   uniform field); frequency, damping ratio and rate 0: the motions u of the unresolved
  !>   eigenvectors' span with M^-1 K u = 0 and, with loops, G u = 0 (held_by_nothing): a
  !>   motion that would open a loop is none;
  !> - kind 3, a drift: a real lambda that is resolved: the motion grows (rate lambda > 0,
  !>   a divergence, as of an inverted pendulum) or decays (lambda < 0, overdamped) without
  !>   oscillating; frequency 0, damping ratio -sign(lambda).
  !> rate(j) is Re(lambda) (1/s). The mode shape is the coordinates' motion (the eigenvector's
  !> position part, real part), scaled so that its largest component is 1; the rigid-body
  !> motions are an orthogonal basis of theirs. Sorted: rigid-body motions, drifts (by rate,
  !> growing first), vibrations (by frequency); nm of them (at most 2n). At a state that
  !> accelerates the stiffness includes the change of M with q (accelerating_stiffness):
  !> without it a free body falling under gravity showed a 'vibration' (0.3 to 80 Hz).
  subroutine normal_modes(model, t, x, freq, zeta, rate, shapes, kind, nm, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, x(:)
    real(dp), intent(out) :: freq(:), zeta(:), rate(:), shapes(:, :)
    integer, intent(out) :: kind(:), nm
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: m(:, :), minv(:, :), k(:, :), c(:, :), a(:, :), wr(:), wi(:), vr(:, :)
    real(dp), allocatable :: f(:), z(:), r(:), s(:, :), key(:), basis(:, :), phi(:)
    integer, allocatable :: kd(:), order(:)
    complex(dp), allocatable :: v(:)
    real(dp) :: noise2, tol, lam
    integer :: n, i, j, nr, top
    n = model%d%n
    nm = 0; freq = 0.0_dp; zeta = 0.0_dp; rate = 0.0_dp; shapes = 0.0_dp; kind = 0
    call linear_state(model, t, x, m, minv, k, c, a, error); if (allocated(error)) return
    call accelerating_stiffness(model, t, x, minv, k, noise2, error); if (allocated(error)) return
    call state_matrix(minv, k, c, a)
    allocate(wr(2*n), wi(2*n), vr(2*n, 2*n), f(2*n), z(2*n), r(2*n), s(n, 2*n), kd(2*n), key(2*n), v(n))
    allocate(basis(n, n), phi(n))
    call geev_real(a, wr, wi, 'the linearised model', error, vr); if (allocated(error)) return
    tol = max(1.0e-6_dp*maxval(hypot(wr, wi)), sqrt(noise2), lambda_floor)
    nr = 0
    do i = 1, 2*n
      lam = hypot(wr(i), wi(i))
      if (lam <= tol) then
        ! rigid: each of the real and imaginary parts of the position part, kept on the loops
        call add_rigid(vr(1:n, i))
        if (wi(i) > 0.0_dp .and. i < 2*n) call add_rigid(vr(1:n, i + 1))
      else if (wi(i) > 0.0_dp .and. i < 2*n) then
        v = cmplx(vr(1:n, i), vr(1:n, i + 1), dp)
        top = maxloc(abs(v), 1)
        v = v/v(top)
        nm = nm + 1
        kd(nm) = 1; f(nm) = lam/(2.0_dp*pi); z(nm) = -wr(i)/lam; r(nm) = wr(i); s(:, nm) = real(v, dp)
        key(nm) = f(nm)
      else if (wi(i) == 0.0_dp) then
        nm = nm + 1
        kd(nm) = 3; f(nm) = 0.0_dp; z(nm) = -sign(1.0_dp, wr(i)); r(nm) = wr(i)
        s(:, nm) = vr(1:n, i)/vr(maxloc(abs(vr(1:n, i)), 1), i)
        key(nm) = -wr(i)
      end if
    end do
    if (nr > 0) then
      call held_by_nothing(error); if (allocated(error)) return
    end if
    do j = 1, nr
      nm = nm + 1
      kd(nm) = 2; f(nm) = 0.0_dp; z(nm) = 0.0_dp; r(nm) = 0.0_dp
      s(:, nm) = basis(:, j)/basis(maxloc(abs(basis(:, j)), 1), j)
      key(nm) = j
    end do
    ! rigid-body motions, drifts, vibrations; each kind by its key
    i = 0
    do top = 2, 4
      order = pack([(j, j = 1, nm)], kd(1:nm) == merge(1, top, top == 4))
      order = order(sort_index(key(order)))
      do j = 1, size(order)
        i = i + 1
        freq(i) = f(order(j)); zeta(i) = z(order(j)); rate(i) = r(order(j)); kind(i) = kd(order(j))
        shapes(:, i) = s(:, order(j))
      end do
    end do
  contains
    !> The unresolved eigenvalues' eigenvectors span the rigid-body motions and, where the
    !> zero eigenvalue is defective, motions chained to them; with loops also motions that
    !> would open a loop (the constrained inverse leaves them without stiffness) and the
    !> motions these lead into. The rigid-body motions are those u of the basis's span that
    !> nothing holds, -M^-1 K u = 0 to the threshold tol^2, and that keep the loops closed,
    !> G u = 0 to 1e-5 of |G|: the null space of B^T B, B = [G Q / (1e-5 |G|); M^-1 K Q / tol^2]
    !> for the basis Q (eigenvalues at most 1).
    subroutine held_by_nothing(error)
      type(error_type), allocatable, intent(out) :: error
      real(dp), allocatable :: g(:, :), b(:, :), e(:, :), mu(:), kept(:, :), eye(:, :)
      integer :: l, nk
      b = matmul(matmul(minv, k), basis(:, 1:nr))/max(tol**2, tiny(1.0_dp))
      if (model%d%cuts%n_rows > 0) then
        call loop_jacobian(model%d, model%wk, x(1:n), g, error); if (allocated(error)) return
        b = reshape([transpose(b), transpose(matmul(g, basis(:, 1:nr)))/max(1.0e-5_dp*norm2(g), tiny(1.0_dp))], &
          & [nr, n + size(g, 1)])
        b = transpose(b)
      end if
      e = matmul(transpose(b), b)
      allocate(mu(nr), kept(n, nr), eye(nr, nr))
      eye = 0.0_dp
      do l = 1, nr
        eye(l, l) = 1.0_dp
      end do
      call sygvd(e, eye, mu, 'the rigid-body motions', error); if (allocated(error)) return
      nk = 0
      do l = 1, nr
        if (mu(l) > 1.0_dp) cycle
        nk = nk + 1
        kept(:, nk) = matmul(basis(:, 1:nr), e(:, l))
      end do
      nr = nk
      basis(:, 1:nr) = kept(:, 1:nr)
    end subroutine held_by_nothing

    !> Add the motion u to the rigid-body basis unless the basis already holds it
    !> (Gram-Schmidt: what is left is below 1e-3 of it).
    subroutine add_rigid(u)
      real(dp), intent(in) :: u(:)
      integer :: l
      if (nr == n) return
      phi = u
      lam = norm2(phi)
      if (lam == 0.0_dp) return
      do l = 1, nr
        phi = phi - dot_product(basis(:, l), phi)*basis(:, l)
      end do
      if (norm2(phi) <= 1.0e-3_dp*lam) return
      nr = nr + 1
      basis(:, nr) = phi/norm2(phi)
    end subroutine add_rigid
  end subroutine normal_modes

  !> The stiffness of a state that accelerates: linearise's K = -dP/dq holds M at the state,
  !> which makes -M^-1 K the accelerations' own derivative only where they vanish. With
  !> qdd0 /= 0 the derivative of qdd = M^-1 P is -M^-1 (K + (dM/dq_j) qdd0) (column j): the
  !> term is added here (central differences, linearise's increments). noise2 (1/s^2) is the
  !> size of the difference error in M^-1 K: 1e-8 |M^-1| (|P| + |M| |qdd0|) (roundoff
  !> 2.2e-16/1e-6 of the forces, with a margin of 45), under which a stiffness is not resolved.
  subroutine accelerating_stiffness(model, t, x, minv, k, noise2, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, x(:), minv(:, :)
    real(dp), intent(inout) :: k(:, :)
    real(dp), intent(out) :: noise2
    type(error_type), allocatable, intent(out) :: error
    type(model_counters) :: counters
    real(dp), allocatable :: q(:), qd(:), a0(:), mp(:, :)
    real(dp) :: del, forces
    integer :: n, j
    n = model%d%n
    noise2 = 0.0_dp
    counters = model%counters()
    q = x(1:n); qd = x(n+1:2*n)
    allocate(a0(n))
    call model%accelerations(t, q, qd, a0, error)
    if (.not. allocated(error)) then
      call model%terms(t, q, qd)
      forces = maxval(abs(model%wk%p)) + maxval(sum(abs(model%wk%mm), 2))*maxval(abs(a0))
      noise2 = 1.0e-8_dp*maxval(sum(abs(minv), 2))*forces
      if (any(a0 /= 0.0_dp)) then
        do j = 1, n
          del = 1.0e-6_dp*max(1.0_dp, abs(q(j)))
          q(j) = x(j) + del; call model%terms(t, q, qd); mp = model%wk%mm
          q(j) = x(j) - del; call model%terms(t, q, qd)
          q(j) = x(j)
          k(:, j) = k(:, j) + matmul(mp - model%wk%mm, a0)/(2.0_dp*del)
        end do
        call model%terms(t, q, qd)
      end if
    end if
    call model%set_counters(counters)
  end subroutine accelerating_stiffness

  !> The highest natural frequency (rad/s: the largest |lambda| of the state matrix) of the
  !> model linearised at x, its loops closed (the constrained inverse mass matrix).
  function top_frequency(model, x, error) result(omega)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: omega
    real(dp), allocatable :: m(:, :), minv(:, :), k(:, :), c(:, :), a(:, :), wr(:), wi(:)
    omega = 0.0_dp
    call linear_state(model, 0.0_dp, x, m, minv, k, c, a, error); if (allocated(error)) return
    allocate(wr(size(a, 1)), wi(size(a, 1)))
    call geev_real(a, wr, wi, 'the linearised model', error); if (allocated(error)) return
    omega = maxval(hypot(wr, wi))
  end function top_frequency

  !> Indices that sort v ascending (insertion sort: a model has few modes).
  pure function sort_index(v) result(idx)
    real(dp), intent(in) :: v(:)
    integer :: idx(size(v)), i, j, tmp
    idx = [(i, i = 1, size(v))]
    do i = 2, size(v)
      tmp = idx(i); j = i - 1
      do while (j >= 1)
        if (v(idx(j)) <= v(tmp)) exit
        idx(j + 1) = idx(j); j = j - 1
      end do
      idx(j + 1) = tmp
    end do
  end function sort_index

  !> The mass matrix at the initial state must be positive definite: a body without mass
  !> or inertia at the end of a chain, or joint axes that leave a motion without inertia,
  !> make it singular. The error names the first such coordinate.
  subroutine check_mass_matrix(model, x, where, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:)
    character(len=*), intent(in) :: where
    type(error_type), allocatable, intent(out) :: error
    integer :: n, minor
    real(dp), allocatable :: l(:, :)
    type(model_counters) :: counters
    n = model%d%n
    if (n == 0) return
    counters = model%counters()
    call model%terms(0.0_dp, x(1:n), x(n+1:2*n))
    call model%set_counters(counters)
    l = model%wk%mm
    call potrf(l, 'the mass matrix', error, minor)
    if (.not. allocated(error)) then
      ! nearly singular: a pivot that keeps less than 1e-10 of its diagonal entry
      do minor = 1, n
        if (l(minor, minor)**2 < 1.0e-10_dp*model%wk%mm(minor, minor)) exit
      end do
      if (minor > n) return
      call fatal_error(error, '')
    end if
    if (minor > 0) then
      error%message = where // 'the mass matrix is singular at the initial state: coordinate ' // &
        & trim(model%d%qname(minor)) // ' (leading minor ' // itoa(minor) // ') moves no inertia that the ' // &
        & 'coordinates before it do not already move (or almost none): check the masses and inertias of the ' // &
        & 'bodies it moves, the axes of its joint, and the singular angles of spherical and free joints'
      error%stat = stat_input
    else
      error%message = where // error%message
    end if
  end subroutine check_mass_matrix

  !> Multirate runs: the growth per macro step of the stepper itself applied to the model
  !> linearised at the initial state (power iteration on its whole state). When its growth
  !> beyond the linearised model's own (a motion that grows physically, or the drift of a
  !> closed loop's coordinates that the projection removes) would exceed run_growth over the
  !> run, the run is refused, naming the coordinate that
  !> carries the growing motion and the largest stable step ratio at this fast step.
  subroutine check_macro_step(model, x, m, minv, k, c, sigma, st, label, t_end, where, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:), m(:, :), minv(:, :), k(:, :), c(:, :), t_end
    !> The linearised model's own growth rate (1/s; its largest real eigenvalue part, or 0):
    !> only the growth beyond it is the stepper's.
    real(dp), intent(in) :: sigma
    class(stepper_t), intent(in) :: st
    character(len=*), intent(in) :: label, where
    type(error_type), allocatable, intent(out) :: error
    type(linear_system) :: sys
    integer :: kr, ks, dom, d2, k_run
    real(dp) :: rho, r2, hf
    character(len=32) :: b1, b2, b3
    type(step_counts) :: counts
    type(pece_steps) :: steps
    call linear_model(model, x, m, minv, k, c, sys, error); if (allocated(error)) return
    counts = st%counts(); steps = st%pece()
    k_run = counts%ratio; kr = k_run
    hf = steps%h_modal
    call macro_growth(sys, m, st, kr, hf, t_end, rho, dom, error); if (allocated(error)) return
    if ((log(rho) - sigma*kr*hf)*t_end/(kr*hf) <= log(run_growth)) return
    ! the largest stable ratio below kr (stability need not be monotone in k: scan all)
    ks = 0
    do kr = 1, k_run - 1
      call macro_growth(sys, m, st, kr, hf, t_end, r2, d2, error); if (allocated(error)) return
      if ((log(r2) - sigma*kr*hf)*t_end/(kr*hf) <= log(run_growth)) ks = kr
    end do
    kr = k_run
    write(b1, '(es9.2)') kr*hf
    write(b2, '(f0.4)') rho
    write(b3, '(es9.2)') hf
    call fatal_error(error, where // 'h_slow: the multirate macro step of ' // trim(adjustl(b1)) // ' s (k = ' // &
      & itoa(kr) // ', ' // label // ') is not stable: linearised at the initial state, one macro step multiplies ' // &
      & 'the motion of ' // coordinate_name(model, dom) // ' by ' // trim(b2) // '; at h_fast = ' // &
      & trim(adjustl(b3)) // ' s the largest stable ratio is k = ' // itoa(ks) // ' (growth below 10 over the ' // &
      & 'run; or use adaptive = .true.)')
  end subroutine check_macro_step

  !> The linearised model as a partitioned system (slow = joint coordinates), with its
  !> (constrained) inverse mass matrix minv. With closed loops its fast steps keep the loops
  !> closed as the model's do (constrain_fast_accelerations): the constrained inverse of
  !> M_ff on the rows independent in G_f, and the fast accelerations tfs acc_s that the
  !> slow accelerations impose through them.
  subroutine linear_model(model, x, m, minv, k, c, sys, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:), m(:, :), minv(:, :), k(:, :), c(:, :)
    type(linear_system), intent(out) :: sys
    type(error_type), allocatable, intent(out) :: error
    integer :: n, ns, nf
    integer, allocatable :: used(:)
    integer :: n_fast
    real(dp), allocatable :: l(:, :), g(:, :), kg(:, :)
    n = size(m, 1); ns = model%d%nj; nf = n - ns
    sys%ns = ns; sys%nf = nf
    sys%k = k; sys%c = c
    sys%minv = minv
    allocate(sys%mffinv(nf, nf), sys%kf(nf), sys%df(nf))
    l = m(ns+1:, ns+1:)
    call potrf(l, 'M_ff at the initial state', error); if (allocated(error)) return
    call factor_inverse(l, sys%mffinv, 'M_ff', error); if (allocated(error)) return
    sys%mfs = m(ns+1:, 1:ns)
    call modal_stiffness_damping(model%d, model%effects, sys%kf, sys%df)
    if (model%d%cuts%n_rows == 0) return
    call loop_jacobian(model%d, model%wk, x(1:n), g, error); if (allocated(error)) return
    allocate(used(size(g, 1)), sys%tfs(nf, ns))
    call independent_rows(g(:, ns+1:), used, n_fast)
    sys%tfs = 0.0_dp
    if (n_fast == 0) return
    allocate(kg(nf, n_fast))
    call constrain_inverse(sys%mffinv, g(used(1:n_fast), ns+1:), error, kg); if (allocated(error)) return
    sys%tfs = matmul(kg, g(used(1:n_fast), 1:ns))
  end subroutine linear_model

  !> Growth rho per macro step (ratio kr, fast step hf) of the stepper `proto` applied to
  !> the linear system, and the coordinate `dom` whose kinetic energy dominates the growing
  !> motion. The stepper is started at rest and taken past its start-up phase; then its
  !> macro step is a linear map of its whole state vector.
  subroutine macro_growth(sys, m, proto, kr, hf, t_end, rho, dom, error)
    type(linear_system), intent(inout) :: sys
    real(dp), intent(in) :: m(:, :)
    class(stepper_t), intent(in) :: proto
    integer, intent(in) :: kr
    real(dp), intent(in) :: hf, t_end
    real(dp), intent(out) :: rho
    integer, intent(out) :: dom
    type(error_type), allocatable, intent(out) :: error
    class(stepper_t), allocatable :: st
    real(dp), allocatable :: v(:), x0(:)
    integer :: n, i
    n = sys%ns + sys%nf
    allocate(st, source=proto)
    call st%set_ratio(kr)
    allocate(x0(2*n))
    x0 = 0.0_dp
    call st%start(sys, 0.0_dp, x0, hf, error); if (allocated(error)) return
    do i = 1, 4
      call st%advance(sys, error); if (allocated(error)) return
    end do
    allocate(v(st%state_size()))
    if (size(v) <= max_exact_state) then
      call map_radius(sys, st, v, rho, error)
    else
      call power_radius(sys, st, v, min(max_iterations, max(300, 4*nint(t_end/(kr*hf)))), rho, error)
    end if
    if (allocated(error)) return
    dom = maxloc([(m(i, i)*(v(i)**2 + v(n + i)**2), i = 1, n)], 1)
  end subroutine macro_growth

  !> Spectral radius of the macro-step map from its matrix (one macro step per column);
  !> v: the dominant eigenvector (its real part).
  subroutine map_radius(sys, st, v, rho, error)
    type(linear_system), intent(inout) :: sys
    class(stepper_t), intent(inout) :: st
    real(dp), intent(out) :: v(:), rho
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: g(:, :), wr(:), wi(:), vr(:, :)
    integer :: j, nz, top
    nz = size(v)
    allocate(g(nz, nz), wr(nz), wi(nz), vr(nz, nz))
    do j = 1, nz
      v = 0.0_dp; v(j) = 1.0_dp
      call st%set_state(v)
      call st%advance(sys, error); if (allocated(error)) return
      call st%get_state(g(:, j))
    end do
    call geev_real(g, wr, wi, 'the linearised macro step', error, vr); if (allocated(error)) return
    top = maxloc(hypot(wr, wi), 1)
    rho = hypot(wr(top), wi(top))
    if (wi(top) < 0.0_dp .and. top > 1) top = top - 1
    v = vr(:, top)
  end subroutine map_radius

  !> Growth per macro step by power iteration from a fixed start with every component
  !> present (the geometric mean over the second half of `iters` steps). The norm leaves
  !> out the positions' values: a joint without stiffness drifts at constant rate, which is
  !> motion, not growth.
  subroutine power_radius(sys, st, v, iters, rho, error)
    type(linear_system), intent(inout) :: sys
    class(stepper_t), intent(inout) :: st
    real(dp), intent(out) :: v(:), rho
    integer, intent(in) :: iters
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: g, logsum
    integer :: n, i, it
    n = sys%ns + sys%nf
    do i = 1, size(v)
      v(i) = sin(12.9898_dp*i)
    end do
    logsum = 0.0_dp
    rho = huge(1.0_dp)
    do it = 1, iters
      v = v/norm2(v(n+1:))
      call st%set_state(v)
      call st%advance(sys, error); if (allocated(error)) return
      call st%get_state(v)
      g = norm2(v(n+1:))
      if (.not. (g > 0.0_dp .and. g <= huge(g))) return
      if (2*it > iters) logsum = logsum + log(g)
    end do
    rho = exp(logsum/(iters - iters/2))
  end subroutine power_radius

  !> "body 'gun', mode 8" for a modal coordinate, "joint coordinate 'elevation.q'" else.
  function coordinate_name(model, ic) result(s)
    type(model_t), intent(in) :: model
    integer, intent(in) :: ic
    character(len=:), allocatable :: s
    integer :: b
    b = model%d%cbody(ic)
    if (ic > model%d%nj) then
      s = "body '" // trim(model%d%body_name(b)) // "', mode " // itoa(ic - model%d%a0(b) + 1)
    else
      s = "joint coordinate '" // trim(model%d%qname(ic)) // "'"
    end if
  end function coordinate_name

  subroutine lin_eval(self, t, x, f, error)
    class(linear_system), intent(inout) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: x(:)
    real(dp), intent(out), contiguous :: f(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: n
    n = self%ns + self%nf
    f(1:n) = x(n+1:)
    f(n+1:) = -matmul(self%minv, matmul(self%k, x(1:n)) + matmul(self%c, x(n+1:)))
  end subroutine lin_eval

  function lin_name(self, i) result(name)
    class(linear_system), intent(in) :: self
    integer, intent(in) :: i
    character(len=:), allocatable :: name
    name = 'coordinate ' // itoa(i) // ' of ' // itoa(2*(self%ns + self%nf))
  end function lin_name

  pure integer function lin_n_slow(self)
    class(linear_system), intent(in) :: self
    lin_n_slow = self%ns
  end function lin_n_slow

  pure integer function lin_n_fast(self)
    class(linear_system), intent(in) :: self
    lin_n_fast = self%nf
  end function lin_n_fast

  !> Generalised forces -(K q + C qd) at the full state gathered from xs and xf.
  pure function forces(self, xs, xf) result(p)
    class(linear_system), intent(in) :: self
    real(dp), intent(in) :: xs(:), xf(:)
    real(dp) :: p(self%ns + self%nf)
    p = -matmul(self%k, [xs(1:self%ns), xf(1:self%nf)]) - matmul(self%c, [xs(self%ns+1:), xf(self%nf+1:)])
  end function forces

  subroutine lin_sync(self, t, xs, xf, fs, ff, error)
    class(linear_system), intent(inout) :: self
    real(dp), intent(in) :: t, xs(:), xf(:)
    real(dp), intent(out) :: fs(:), ff(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: p(self%ns + self%nf), a(self%ns + self%nf)
    integer :: ns, nf
    ns = self%ns; nf = self%nf
    p = forces(self, xs, xf)
    a = matmul(self%minv, p)
    fs = [xs(ns+1:), a(1:ns)]
    ff = [xf(nf+1:), a(ns+1:)]
  end subroutine lin_sync

  subroutine lin_response(self, g, kf, df, error)
    class(linear_system), intent(inout) :: self
    real(dp), intent(out) :: g(:, :), kf(:), df(:)
    type(error_type), allocatable, intent(out) :: error
    g = self%minv(:, self%ns+1:)
    kf = self%kf; df = self%df
  end subroutine lin_response

  subroutine lin_fast(self, t, xs, xf, acc_s, ff, error)
    class(linear_system), intent(inout) :: self
    real(dp), intent(in) :: t, xs(:), xf(:), acc_s(:)
    real(dp), intent(out) :: ff(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: p(self%ns + self%nf)
    integer :: ns, nf
    ns = self%ns; nf = self%nf
    p = forces(self, xs, xf)
    ff(nf+1:) = matmul(self%mffinv, p(ns+1:) - matmul(self%mfs, acc_s))
    if (allocated(self%tfs)) ff(nf+1:) = ff(nf+1:) - matmul(self%tfs, acc_s)
    ff(1:nf) = xf(nf+1:)
  end subroutine lin_fast
end module pymr_driver_preflight
