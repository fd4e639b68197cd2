!> Pre-flight stability check of fixed-step runs (issue 6, hard case 1).
!>
!> The model is linearised at its initial state: M, and K = -dP/dq, D = -dP/dqd by central
!> differences. Each eigenvalue lambda of [0 I; -M^-1 K  -M^-1 D] with Re lambda <= 0 is a
!> vibration the step must resolve stably: the PECE growth factor at lambda h (see
!> pymr_integrator_stability) must not exceed 1. A mode is charged to the coordinate that
!> carries most of its kinetic energy, and so to the step of that coordinate's partition
!> (h_fast for modal coordinates in multirate runs, h_slow otherwise).
module pymr_preflight
  use pymr_kinds, only : dp, pi
  use pymr_error, only : error_type, fatal_error, stat_input
  use pymr_lapack, only : potrf, potrs, geev_real, factor_inverse
  use pymr_model, only : model_t, modal_stiffness_damping
  use pymr_model_types, only : model_data
  use pymr_integrator_stability, only : pece_growth, pece_limit
  use pymr_integrator_ode, only : partitioned_system
  use pymr_integrator_multirate, only : multirate_integrator, coupling_split
  use pymr_integrator_nordsieck, only : nq
  use pymr_io_text, only : itoa
  implicit none
  private
  public :: check_step_stability, check_mass_matrix

  !> Largest growth of a linearised perturbation over a whole run that is accepted: a
  !> step whose growth factor per step is above 1 only by roundoff-sized amounts (an
  !> undamped mode on the edge) passes; a real instability multiplies it by far more.
  real(dp), parameter :: run_growth = 10.0_dp

  !> The model linearised at a state, M qdd = -(K q + C qd), as a partitioned system
  !> whose fast right-hand sides copy the model's two couplings: the multirate integrator
  !> applied to it gives the linearised macro-step map.
  type, extends(partitioned_system) :: linear_system
    integer :: ns = 0, nf = 0
    real(dp), allocatable :: minv(:, :), k(:, :), c(:, :), mffinv(:, :), mfs(:, :), kf(:), df(:), yrest(:)
  contains
    procedure :: eval => lin_eval
    procedure :: component_name => lin_name
    procedure :: n_slow => lin_n_slow
    procedure :: n_fast => lin_n_fast
    procedure :: sync_rhs => lin_sync
    procedure :: fast_rhs => lin_fast
  end type linear_system

contains

  !> Refuse (error naming the body and mode, its frequency and the largest stable step)
  !> a fixed step that cannot be stable at the initial state x = [q; qd].
  !> `h_slow`, `h_fast`: the steps of the joint and modal coordinates (equal single-rate).
  subroutine check_step_stability(model, x, h_slow, h_fast, multirate, coupling, t_end, where, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:), h_slow, h_fast
    !> Length of the run (s): a step is refused when the linearised growth over the whole
    !> run would exceed `run_growth`.
    real(dp), intent(in) :: t_end
    logical, intent(in) :: multirate
    !> Multirate coupling (coupling_full or coupling_split).
    integer, intent(in) :: coupling
    character(len=*), intent(in) :: where
    type(error_type), allocatable, intent(out) :: error
    integer :: n, i, j, dom, worst
    type(model_data) :: counters
    real(dp), allocatable :: q(:), qd(:), m(:, :), lm(:, :), k(:, :), c(:, :), a(:, :), wr(:), wi(:), vr(:, :)
    real(dp), allocatable :: p0(:), pp(:), pm(:), wgt(:)
    real(dp) :: del, h, ratio, worst_ratio
    complex(dp) :: lam, worst_lam
    character(len=32) :: b1, b2, b3, b4
    n = model%d%n
    if (n == 0) return
    ! the linearisation must not count as the run's evaluations
    call save_counters(model, counters)
    q = x(1:n); qd = x(n+1:2*n)
    allocate(k(n, n), c(n, n), a(2*n, 2*n), wr(2*n), wi(2*n), vr(2*n, 2*n), wgt(n))
    call model%terms(0.0_dp, q, qd)
    m = 0.5_dp*(model%d%mm + transpose(model%d%mm))
    p0 = model%d%p
    do j = 1, n
      del = 1.0e-6_dp*max(1.0_dp, abs(q(j)))
      q(j) = x(j) + del; call model%terms(0.0_dp, q, qd); pp = model%d%p
      q(j) = x(j) - del; call model%terms(0.0_dp, q, qd); pm = model%d%p
      q(j) = x(j)
      k(:, j) = -(pp - pm)/(2.0_dp*del)
      del = 1.0e-6_dp*max(1.0_dp, abs(qd(j)))
      qd(j) = x(n + j) + del; call model%terms(0.0_dp, q, qd); pp = model%d%p
      qd(j) = x(n + j) - del; call model%terms(0.0_dp, q, qd); pm = model%d%p
      qd(j) = x(n + j)
      c(:, j) = -(pp - pm)/(2.0_dp*del)
    end do
    call restore_counters(model, counters)
    lm = m
    call potrf(lm, 'the mass matrix at the initial state', error); if (allocated(error)) return
    a = 0.0_dp
    do i = 1, n
      a(i, n + i) = 1.0_dp
    end do
    a(n+1:, 1:n) = -k
    a(n+1:, n+1:) = -c
    call potrs(lm, a(n+1:, :), 'the mass matrix', error); if (allocated(error)) return
    call geev_real(a, wr, wi, vr, 'the linearised model', error); if (allocated(error)) return
    worst = 0; worst_ratio = 1.0_dp; worst_lam = (0.0_dp, 0.0_dp)
    i = 1
    do while (i <= 2*n)
      lam = cmplx(wr(i), wi(i), dp)
      ! kinetic-energy weight of each coordinate in the eigenvector (complex pairs packed)
      if (wi(i) /= 0.0_dp .and. i < 2*n) then
        wgt = (vr(1:n, i)**2 + vr(1:n, i + 1)**2)
      else
        wgt = vr(1:n, i)**2
      end if
      do j = 1, n
        wgt(j) = wgt(j)*m(j, j)
      end do
      dom = maxloc(wgt, 1)
      ! only vibrations and decays: growing modes are physical, not numerical
      if (abs(lam) > 0.0_dp .and. wr(i) <= 1.0e-9_dp*abs(lam)) then
        ! multirate: modes of the joint coordinates are judged by the macro-step map below
        h = h_slow
        if (multirate) h = merge(h_fast, 0.0_dp, dom > model%d%nj)
        if (h > 0.0_dp .and. log(pece_growth(lam*h))*t_end/h > log(run_growth)) then
          ratio = h/pece_limit(lam)
          if (ratio > worst_ratio) then
            worst_ratio = ratio; worst = dom; worst_lam = lam
          end if
        end if
      end if
      if (wi(i) /= 0.0_dp) i = i + 1
      i = i + 1
    end do
    if (worst == 0) then
      if (multirate) call check_macro_step(model, m, k, c, h_slow, h_fast, coupling, t_end, where, error)
      return
    end if
    h = h_slow
    if (multirate .and. worst > model%d%nj) h = h_fast
    write(b1, '(es9.2)') h
    write(b2, '(f0.1)') abs(worst_lam)/(2.0_dp*pi)
    write(b3, '(f5.3)') abs(worst_lam)*h
    write(b4, '(es9.2)') pece_limit(worst_lam)
    call fatal_error(error, where // merge('h_fast', 'h_slow', multirate .and. worst > model%d%nj) // &
      & ': a fixed step of ' // trim(adjustl(b1)) // ' s is not stable for ' // coordinate_name(model, worst) // ' (' // &
      & trim(b2) // ' Hz, omega*h = ' // trim(b3) // '); the largest stable step is ' // trim(adjustl(b4)) // &
      & ' s (the ABM PECE method is stable up to omega*h = 0.430 on an undamped mode): take a smaller step, ' // &
      & 'or adaptive = .true.')
  end subroutine check_step_stability

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
    type(model_data) :: counters
    n = model%d%n
    if (n == 0) return
    call save_counters(model, counters)
    call model%terms(0.0_dp, x(1:n), x(n+1:2*n))
    call restore_counters(model, counters)
    l = model%d%mm
    call potrf(l, 'the mass matrix', error, minor)
    if (.not. allocated(error)) then
      ! nearly singular: a pivot that keeps less than 1e-10 of its diagonal entry
      do minor = 1, n
        if (l(minor, minor)**2 < 1.0e-10_dp*model%d%mm(minor, minor)) exit
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

  !> The evaluation counters of the model (kept in a model_data's counter fields), so that
  !> pre-flight evaluations do not count as the run's.
  subroutine save_counters(model, c)
    type(model_t), intent(in) :: model
    type(model_data), intent(out) :: c
    c%evals = model%d%evals; c%evals_fast_rows = model%d%evals_fast_rows
    c%effect_evals = model%d%effect_evals; c%effect_timed = model%d%effect_timed
    c%effect_cpu = model%d%effect_cpu
  end subroutine save_counters

  subroutine restore_counters(model, c)
    type(model_t), intent(inout) :: model
    type(model_data), intent(in) :: c
    model%d%evals = c%evals; model%d%evals_fast_rows = c%evals_fast_rows
    model%d%effect_evals = c%effect_evals; model%d%effect_timed = c%effect_timed
    model%d%effect_cpu = c%effect_cpu
  end subroutine restore_counters

  !> Multirate runs: the spectral radius of the linearised macro-step map, computed by
  !> applying the multirate integrator itself to the linearised model from each unit
  !> Nordsieck array. Above 1 the run is refused, naming the coordinate that carries the
  !> growing motion and the largest stable step ratio at this h_fast.
  subroutine check_macro_step(model, m, k, c, h_slow, h_fast, coupling, t_end, where, error)
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: m(:, :), k(:, :), c(:, :), h_slow, h_fast, t_end
    integer, intent(in) :: coupling
    character(len=*), intent(in) :: where
    type(error_type), allocatable, intent(out) :: error
    type(linear_system) :: sys
    integer :: kr, ks, dom, d2
    real(dp) :: rho, r2
    character(len=32) :: b1, b2, b3
    call linear_model(model, m, k, c, sys, error); if (allocated(error)) return
    kr = max(1, nint(h_slow/h_fast))
    call macro_growth(sys, kr, h_fast, coupling, rho, dom, error); if (allocated(error)) return
    if (log(rho)*t_end/(kr*h_fast) <= log(run_growth)) return
    ! the largest stable ratio below kr (stability need not be monotone in k: scan all)
    ks = 0
    do kr = 1, max(1, nint(h_slow/h_fast)) - 1
      call macro_growth(sys, kr, h_fast, coupling, r2, d2, error); if (allocated(error)) return
      if (log(r2)*t_end/(kr*h_fast) <= log(run_growth)) ks = kr
    end do
    kr = max(1, nint(h_slow/h_fast))
    write(b1, '(es9.2)') h_slow
    write(b2, '(f0.4)') rho
    write(b3, '(es9.2)') h_fast
    call fatal_error(error, where // 'h_slow: the multirate macro step of ' // trim(adjustl(b1)) // ' s (k = ' // &
      & itoa(kr) // ", coupling '" // trim(merge('split', 'full ', coupling == coupling_split)) // &
      & "') is not stable: linearised at the initial state, one macro step multiplies the motion of " // &
      & coordinate_name(model, dom) // ' by ' // trim(b2) // '; at h_fast = ' // trim(adjustl(b3)) // &
      & ' s the largest stable ratio is k = ' // itoa(ks) // ' (growth below 10 over the run; or use ' // &
      & 'adaptive = .true.)')
  end subroutine check_macro_step

  !> The linearised model as a partitioned system (slow = joint coordinates).
  subroutine linear_model(model, m, k, c, sys, error)
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: m(:, :), k(:, :), c(:, :)
    type(linear_system), intent(out) :: sys
    type(error_type), allocatable, intent(out) :: error
    integer :: n, ns, nf
    real(dp), allocatable :: l(:, :)
    n = size(m, 1); ns = model%d%nj; nf = n - ns
    sys%ns = ns; sys%nf = nf
    sys%k = k; sys%c = c
    l = m
    call potrf(l, 'the mass matrix at the initial state', error); if (allocated(error)) return
    allocate(sys%minv(n, n), sys%mffinv(nf, nf), sys%kf(nf), sys%df(nf), sys%yrest(nf))
    call factor_inverse(l, sys%minv, 'the mass matrix', error); if (allocated(error)) return
    l = m(ns+1:, ns+1:)
    call potrf(l, 'M_ff at the initial state', error); if (allocated(error)) return
    call factor_inverse(l, sys%mffinv, 'M_ff', error); if (allocated(error)) return
    sys%mfs = m(ns+1:, 1:ns)
    call modal_stiffness_damping(model%d, sys%kf, sys%df)
    sys%yrest = 0.0_dp
  end subroutine linear_model

  !> Spectral radius rho of one multirate macro step (ratio kr, fast step hf) on the linear
  !> system, and the coordinate `dom` carrying most of its dominant eigenvector.
  subroutine macro_growth(sys, kr, hf, coupling, rho, dom, error)
    type(linear_system), intent(inout) :: sys
    integer, intent(in) :: kr, coupling
    real(dp), intent(in) :: hf
    real(dp), intent(out) :: rho
    integer, intent(out) :: dom
    type(error_type), allocatable, intent(out) :: error
    type(multirate_integrator) :: mr
    integer :: ns, nf, nz, j, top, i
    real(dp), allocatable :: g(:, :), z(:), wr(:), wi(:), vr(:, :), wgt(:)
    ns = sys%ns; nf = sys%nf
    nz = 2*(ns + nf)*(nq + 1)
    allocate(g(nz, nz), z(nz), wr(nz), wi(nz), vr(nz, nz))
    call mr%init(ns, nf, kr, coupling)
    do j = 1, nz
      z = 0.0_dp; z(j) = 1.0_dp
      mr%zs = reshape(z(1:2*ns*(nq + 1)), [2*ns, nq + 1])
      mr%zf = reshape(z(2*ns*(nq + 1) + 1:), [2*nf, nq + 1])
      mr%t = 0.0_dp; mr%hs = kr*hf; mr%hf = hf
      if (coupling == coupling_split) then
        call sys%sync_rhs(0.0_dp, mr%zs(:, 0), mr%zf(:, 0), mr%fs, mr%ff, error); if (allocated(error)) return
      end if
      call mr%advance(sys, error); if (allocated(error)) return
      g(:, j) = [reshape(mr%zs, [2*ns*(nq + 1)]), reshape(mr%zf, [2*nf*(nq + 1)])]
    end do
    call geev_real(g, wr, wi, vr, 'the linearised macro step', error); if (allocated(error)) return
    top = maxloc(hypot(wr, wi), 1)
    rho = hypot(wr(top), wi(top))
    ! coordinate weights from the value columns z(:, 0) of the slow and fast arrays
    allocate(wgt(ns + nf))
    if (wi(top) < 0.0_dp .and. top > 1) top = top - 1
    do i = 1, ns
      wgt(i) = abs(vr(i, top))
    end do
    do i = 1, nf
      wgt(ns + i) = abs(vr(2*ns*(nq + 1) + i, top))
    end do
    dom = maxloc(wgt, 1)
  end subroutine macro_growth

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
    ! held for 'split': M_ff^-1 times the fast forces without their modal stiffness and damping
    self%yrest = matmul(self%mffinv, p(ns+1:) + self%kf*xf(1:nf) + self%df*xf(nf+1:))
  end subroutine lin_sync

  subroutine lin_fast(self, t, xs, xf, acc_s, split, ff, error)
    class(linear_system), intent(inout) :: self
    real(dp), intent(in) :: t, xs(:), xf(:), acc_s(:)
    logical, intent(in) :: split
    real(dp), intent(out) :: ff(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: p(self%ns + self%nf)
    integer :: ns, nf
    ns = self%ns; nf = self%nf
    if (split) then
      ff(nf+1:) = self%yrest - matmul(self%mffinv, self%kf*xf(1:nf) + self%df*xf(nf+1:) + matmul(self%mfs, acc_s))
    else
      p = forces(self, xs, xf)
      ff(nf+1:) = matmul(self%mffinv, p(ns+1:) - matmul(self%mfs, acc_s))
    end if
    ff(1:nf) = xf(nf+1:)
  end subroutine lin_fast
end module pymr_preflight
