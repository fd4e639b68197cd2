!> The exact flow of the fast (modal) subsystem, linear with frozen coefficients, under a
!> polynomial forcing: the fast side of the 'exponential' coupling (docs/method.md section
!> 4.3).
!>
!> With the accelerations written as qdd = rho(t) - g0 (kf0 a + df0 ad), where g0 = M^-1 E
!> (n x nf) and the modal stiffness and damping kf0, df0 are frozen at one state and rho(t)
!> is a polynomial in time (the rest of the accelerations, extrapolated from full
!> evaluations), the fast state z = [a; ad] obeys z' = F z + [0; rho_f(t)] with
!> F = [0 I; -G K  -G D] (G = g0's fast rows, K = diag(kf0), D = diag(df0)), and the slow
!> rates qd_s' = rho_s(t) - C z. F is diagonalised once per freeze:
!> - G = L L^T (Cholesky), and L^T K L = Psi Omega^2 Psi^T (symmetric eigenproblem), so that
!>   a = Phi u with Phi = L Psi turns the undamped part into u'' = -Omega^2 u;
!> - the damping Psi^T L^T D L Psi couples the u; in the scaled coordinates [Omega u; u'] the
!>   first-order matrix is skew-symmetric plus the damping, nearly normal, and LAPACK dgeev
!>   gives its eigenvalues lambda and well-conditioned eigenvectors (an undamped group's
!>   are known in closed form: lambda = +-i omega, no eigenproblem);
!> - eta = W z (W = V^-1) are then independent: eta' = lambda eta + W [0; rho_f], solved in
!>   closed form with the phi functions phi_k(lambda tau), and the slow coordinates by
!>   integrating the same closed form once and twice.
!> Of each complex conjugate pair of eigenvalues one is kept (weight 2): z = Re(V (wgt eta)).
module pymr_integrator_modal_flow
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_lapack, only : potrf, syevd, geev_real, complex_inverse
  use pymr_env_graph, only : connected_parts
  implicit none
  private
  public :: modal_flow_t, flow_rows_t, taylor_weights, n_coef, n_phi

  !> Taylor coefficients of the forcing polynomial (degree 3).
  integer, parameter :: n_coef = 4
  !> phi_0 .. phi_kmax are needed: the forcing's degree plus the two integrations.
  integer, parameter :: kmax = n_coef + 2
  !> Columns of flow_phis' tp: phi_0 .. phi_kmax.
  integer, parameter :: n_phi = kmax + 1
  integer :: k_
  !> 1/k for the terms of phi_kmax's series (at most 30 past kmax): a product, where
  !> a complex quotient by an integer costs a division of complex numbers.
  real(dp), parameter :: reciprocal(kmax + 30) = [(1.0_dp/k_, k_ = 1, kmax + 30)]

  !> A group's right vectors as one real block, so that the state is one product: rows
  !> [a; ad] of the group's fast coordinates, columns [Re V | -Im V] of its kept modes.
  type :: group_vectors
    real(dp), allocatable :: b(:, :)
  end type group_vectors

  !> One step's flow in the form its rows take (flow_rows_form): for each kept mode, whether
  !> it moves (active), from which time into the step a row takes the particular solution
  !> (tau_poly = 1/|lambda|; huge for a mode that never does), d = eta0 - p(0) and p's
  !> Taylor coefficients c (n_coef x nm).
  type :: flow_rows_t
    logical, allocatable :: active(:)
    complex(dp), allocatable :: d(:), c(:, :)
    real(dp), allocatable :: tau_poly(:)
  end type flow_rows_t

  type :: modal_flow_t
    integer :: ns = 0, nf = 0, nm = 0
    !> The frozen response g0 (n x nf) and modal stiffness and damping (nf).
    real(dp), allocatable :: g0(:, :), kf0(:), df0(:)
    !> Eigenvalues kept (nm), their weights (2 for a complex pair, 1 for a real one), and
    !> the rows of V^-1 (nm x 2nf).
    complex(dp), allocatable :: lam(:), w(:, :)
    real(dp), allocatable :: wgt(:)
    !> The right vectors V of each group (group_vectors), and C V as [Re C V | -Im C V]
    !> transposed (2nm x ns: a slow row is one contiguous dot product).
    type(group_vectors), allocatable :: vg(:)
    real(dp), allocatable :: cvt(:, :)
    !> The groups of fast coordinates diagonalised apart: group c has the kept eigenvalues
    !> mode_start(c) .. mode_start(c+1) - 1 and the fast coordinates rows(row_start(c) ..
    !> row_start(c+1) - 1); V and W are zero outside those blocks.
    integer :: ng = 0
    integer, allocatable :: mode_start(:), row_start(:), rows(:)
  contains
    procedure :: build => flow_build
    procedure :: remainder => flow_remainder
    procedure :: project => flow_project
    procedure :: modal_state => flow_modal_state
    procedure :: phis => flow_phis
    procedure :: state_at => flow_state_at
    procedure :: rows_form => flow_rows_form
    procedure :: row_at => flow_row_at
    procedure :: drift => flow_drift
  end type modal_flow_t

contains

  !> Freeze the flow at g (n x nf, rows in the order of q: ns slow rows first), kf, df.
  !> Fast coordinates that do not act on each other (G_ij = 0 between the groups, as the
  !> two bending planes of a beam that no joint couples) are diagonalised group by group:
  !> a vibration that nothing excites then stays exactly zero, as in the other steppers.
  !> An error when a fast coordinate has no stiffness (its flow is not diagonalisable).
  subroutine flow_build(self, ns, g, kf, df, error)
    class(modal_flow_t), intent(inout) :: self
    integer, intent(in) :: ns
    real(dp), intent(in) :: g(:, :), kf(:), df(:)
    type(error_type), allocatable, intent(out) :: error
    integer, allocatable :: group(:), idx(:)
    integer :: nf, c, m, i, ng
    complex(dp), allocatable :: v(:, :), cv(:, :)
    nf = size(kf)
    self%ns = ns; self%nf = nf
    self%g0 = g; self%kf0 = kf; self%df0 = df
    group = connected_parts(g(ns+1:, :))        ! fast coordinates that act on each other
    ng = maxval([0, group])
    if (allocated(self%lam)) deallocate(self%lam, self%w, self%wgt, self%mode_start, self%row_start, self%rows)
    allocate(self%lam(2*nf), v(2*nf, 2*nf), self%w(2*nf, 2*nf), self%wgt(2*nf))
    allocate(self%mode_start(ng + 1), self%row_start(ng + 1), self%rows(nf))
    v = (0.0_dp, 0.0_dp); self%w = (0.0_dp, 0.0_dp)
    m = 0; self%row_start(1) = 1
    do c = 1, ng
      idx = pack([(i, i = 1, nf)], group == c)
      self%mode_start(c) = m + 1
      self%rows(self%row_start(c):self%row_start(c) + size(idx) - 1) = idx
      self%row_start(c+1) = self%row_start(c) + size(idx)
      call build_group(self, idx, g(ns+idx, idx), kf(idx), df(idx), v, m, error); if (allocated(error)) return
    end do
    self%mode_start(ng + 1) = m + 1
    self%ng = ng; self%nm = m
    self%lam = self%lam(1:m); v = v(:, 1:m); self%w = self%w(1:m, :); self%wgt = self%wgt(1:m)
    ! C V: the slow accelerations' response to the fast state, g_s [K | D] V
    cv = matmul(cmplx(g(1:ns, :)*spread(kf, 1, ns), 0.0_dp, dp), v(1:nf, :)) + &
      & matmul(cmplx(g(1:ns, :)*spread(df, 1, ns), 0.0_dp, dp), v(nf+1:, :))
    self%cvt = transpose(reshape([real(cv), -aimag(cv)], [ns, 2*m]))
    call keep_group_vectors(self, v)
  end subroutine flow_build

  !> Each group's block of V (its fast coordinates' rows, its modes' columns; V is zero
  !> outside the blocks) as [Re V | -Im V].
  pure subroutine keep_group_vectors(self, v)
    class(modal_flow_t), intent(inout) :: self
    complex(dp), intent(in) :: v(:, :)
    integer :: c
    integer, allocatable :: r(:), modes(:)
    if (allocated(self%vg)) deallocate(self%vg)
    allocate(self%vg(self%ng))
    do c = 1, self%ng
      r = self%rows(self%row_start(c):self%row_start(c+1) - 1)
      r = [r, self%nf + r]
      modes = group_modes(self, c)
      self%vg(c)%b = reshape([real(v(r, modes)), -aimag(v(r, modes))], [size(r), 2*size(modes)])
    end do
  end subroutine keep_group_vectors

  !> The kept modes of group c.
  pure function group_modes(self, c) result(modes)
    class(modal_flow_t), intent(in) :: self
    integer, intent(in) :: c
    integer, allocatable :: modes(:)
    integer :: i
    modes = [(i, i = self%mode_start(c), self%mode_start(c+1) - 1)]
  end function group_modes

  !> The flow of one group of fast coordinates idx (its G, kf, df): its eigenvalues kept
  !> from position m + 1 on (m advanced past them), their vectors in V's rows and W's
  !> columns of the group.
  subroutine build_group(self, idx, gf, kf, df, v, m, error)
    class(modal_flow_t), intent(inout) :: self
    integer, intent(in) :: idx(:)
    !> The right vectors V (2nf x 2nf), filled in the group's rows and its modes' columns.
    complex(dp), intent(inout) :: v(:, :)
    real(dp), intent(in) :: gf(:, :), kf(:), df(:)
    integer, intent(inout) :: m
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: l(:, :), b(:, :), om2(:), om(:), phi(:, :), pinv(:, :)
    integer :: ng, j
    ng = size(idx)
    ! G = L L^T; L^T K L = Psi Omega^2 Psi^T
    l = gf
    call potrf(l, "the fast coordinates' response G", error); if (allocated(error)) return
    do j = 2, ng
      l(1:j-1, j) = 0.0_dp
    end do
    b = matmul(transpose(l), spread(kf, 2, ng)*l)
    allocate(om2(ng))
    call syevd(b, om2, "the fast coordinates' stiffness", error); if (allocated(error)) return
    if (any(.not. om2 > 0.0_dp)) then
      call fatal_error(error, "coupling 'exponential': a fast (modal) coordinate has no stiffness, so its flow " // &
        & "cannot be diagonalised: use coupling = 'response'", stat_solver); return
    end if
    om = sqrt(om2)
    phi = matmul(l, b)                                     ! a = Phi u
    pinv = phi_inverse(l, b)
    if (all(df == 0.0_dp)) then
      call keep_undamped(self, idx, om, phi, pinv, v, m)
    else
      call keep_damped(self, idx, om, phi, pinv, matmul(transpose(phi), spread(df, 2, ng)*phi), v, m, error)
    end if
  end subroutine build_group

  !> An undamped group's modes: in [Omega u; u'] the first-order matrix [0 Omega; -Omega 0]
  !> has the eigenvalues +-i omega_k and the unitary eigenvectors [e_k; +-i e_k]/sqrt(2)
  !> (W = V^H), so no general eigenproblem is solved: on the stiff barrel (16 modes) that
  !> is most of a renewal's CPU.
  pure subroutine keep_undamped(self, idx, om, phi, pinv, v, m)
    class(modal_flow_t), intent(inout) :: self
    integer, intent(in) :: idx(:)
    real(dp), intent(in) :: om(:), phi(:, :), pinv(:, :)
    complex(dp), intent(inout) :: v(:, :)
    integer, intent(inout) :: m
    real(dp), parameter :: r2 = sqrt(0.5_dp)
    complex(dp), parameter :: i1 = (0.0_dp, 1.0_dp)
    integer :: k, nf
    nf = self%nf
    do k = 1, size(om)
      m = m + 1
      self%lam(m) = cmplx(0.0_dp, om(k), dp); self%wgt(m) = 2.0_dp
      v(idx, m) = cmplx(phi(:, k)*(r2/om(k)), 0.0_dp, dp)
      v(nf+idx, m) = i1*(r2*phi(:, k))
      self%w(m, idx) = cmplx(r2*om(k)*pinv(k, :), 0.0_dp, dp)
      self%w(m, nf+idx) = -i1*(r2*pinv(k, :))
    end do
  end subroutine keep_undamped

  !> A damped group's modes (damping cu in u): in the scaled coordinates [Omega u; u'] the
  !> first-order matrix is skew-symmetric plus the damping, nearly normal, and LAPACK dgeev
  !> gives its eigenvalues and well-conditioned eigenvectors.
  subroutine keep_damped(self, idx, om, phi, pinv, cu, v, m, error)
    class(modal_flow_t), intent(inout) :: self
    integer, intent(in) :: idx(:)
    real(dp), intent(in) :: om(:), phi(:, :), pinv(:, :), cu(:, :)
    complex(dp), intent(inout) :: v(:, :)
    integer, intent(inout) :: m
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: a(:, :), wr(:), wi(:), vr(:, :)
    complex(dp), allocatable :: vy(:, :), wy(:, :), tmp(:, :)
    integer :: nf, ng, i, j
    nf = self%nf; ng = size(idx)
    allocate(a(2*ng, 2*ng)); a = 0.0_dp
    do i = 1, ng
      a(i, ng+i) = om(i); a(ng+i, i) = -om(i)
    end do
    a(ng+1:, ng+1:) = -cu
    allocate(wr(2*ng), wi(2*ng), vr(2*ng, 2*ng))
    call geev_real(a, wr, wi, "the fast coordinates' flow", error, vr); if (allocated(error)) return
    allocate(vy(2*ng, 2*ng))
    j = 1
    do while (j <= 2*ng)
      if (wi(j) /= 0.0_dp .and. j < 2*ng) then
        vy(:, j) = cmplx(vr(:, j), vr(:, j+1), dp); vy(:, j+1) = conjg(vy(:, j))
        j = j + 2
      else
        vy(:, j) = cmplx(vr(:, j), 0.0_dp, dp); j = j + 1
      end if
    end do
    allocate(wy(2*ng, 2*ng))
    tmp = vy
    call complex_inverse(tmp, wy, "the fast coordinates' eigenvectors", error); if (allocated(error)) return
    ! the kept eigenvalues: one of each pair (positive imaginary part), every real one
    do j = 1, 2*ng
      if (wi(j) < 0.0_dp) cycle
      m = m + 1
      self%lam(m) = cmplx(wr(j), wi(j), dp)
      self%wgt(m) = merge(2.0_dp, 1.0_dp, wi(j) > 0.0_dp)
      ! z = [a; ad] = [Phi Omega^-1 Y1; Phi Y2]
      v(idx, m) = matmul(phi, vy(1:ng, j)/om)
      v(nf+idx, m) = matmul(phi, vy(ng+1:, j))
      ! eta = W_y [Omega Phi^-1 a; Phi^-1 ad], Phi^-1 = Psi^T L^-1
      self%w(m, idx) = matmul(wy(j, 1:ng)*om, pinv)
      self%w(m, nf+idx) = matmul(wy(j, ng+1:), pinv)
    end do
  end subroutine keep_damped

  !> Phi^-1 = Psi^T L^-1 (L lower triangular, Psi orthogonal).
  pure function phi_inverse(l, psi) result(p)
    real(dp), intent(in) :: l(:, :), psi(:, :)
    real(dp) :: p(size(l, 1), size(l, 1))
    real(dp) :: linv(size(l, 1), size(l, 1))
    integer :: i, j, n
    n = size(l, 1)
    linv = 0.0_dp
    do j = 1, n
      linv(j, j) = 1.0_dp/l(j, j)
      do i = j + 1, n
        linv(i, j) = -dot_product(l(i, j:i-1), linv(j:i-1, j))/l(i, i)
      end do
    end do
    p = matmul(transpose(psi), linv)
  end function phi_inverse

  !> The rest of the accelerations at a full evaluation: rho = qdd + g0 (kf0 a + df0 ad),
  !> y = [a; ad].
  pure function flow_remainder(self, qdd, y) result(r)
    class(modal_flow_t), intent(in) :: self
    real(dp), intent(in) :: qdd(:), y(:)
    real(dp) :: r(size(qdd))
    integer :: j
    r = qdd
    do j = 1, self%nf
      r = r + self%g0(:, j)*(self%kf0(j)*y(j) + self%df0(j)*y(self%nf+j))
    end do
  end function flow_remainder

  !> The modal forcing of a remainder: W [0; rho_f].
  pure function flow_project(self, r) result(p)
    class(modal_flow_t), intent(in) :: self
    real(dp), intent(in) :: r(:)
    complex(dp) :: p(self%nm)
    integer :: i, c, j, k
    do c = 1, self%ng
      do i = self%mode_start(c), self%mode_start(c+1) - 1
        p(i) = (0.0_dp, 0.0_dp)
        do k = self%row_start(c), self%row_start(c+1) - 1
          j = self%rows(k)
          p(i) = p(i) + self%w(i, self%nf+j)*r(self%ns+j)
        end do
      end do
    end do
  end function flow_project

  !> Modal state eta = W z of the fast state of x = [q_s; a; qd_s; ad].
  pure function flow_modal_state(self, x) result(eta)
    class(modal_flow_t), intent(in) :: self
    real(dp), intent(in) :: x(:)
    complex(dp) :: eta(self%nm)
    integer :: n, i, c, j, k
    n = self%ns + self%nf
    do c = 1, self%ng
      do i = self%mode_start(c), self%mode_start(c+1) - 1
        eta(i) = (0.0_dp, 0.0_dp)
        do k = self%row_start(c), self%row_start(c+1) - 1
          j = self%rows(k)
          eta(i) = eta(i) + self%w(i, j)*x(self%ns+j) + self%w(i, self%nf+j)*x(n+self%ns+j)
        end do
      end do
    end do
  end function flow_modal_state

  !> tau^k phi_k(lambda tau), k = 0 .. n_coef + 2, of every kept eigenvalue (the flow's
  !> coefficients for a step of tau; pass them to state_at).
  pure subroutine flow_phis(self, tau, tp)
    class(modal_flow_t), intent(in) :: self
    real(dp), intent(in) :: tau
    complex(dp), intent(out) :: tp(0:, :)
    real(dp) :: tr(0:kmax)
    integer :: i, j
    tr(0) = 1.0_dp
    do j = 1, kmax
      tr(j) = tr(j-1)*tau
    end do
    do i = 1, self%nm
      call phi_functions(self%lam(i)*tau, tp(:, i))
      tp(:, i) = tr*tp(:, i)
    end do
  end subroutine flow_phis

  !> The state at tau after x0 (modal state eta0) under the forcing whose Taylor
  !> coefficients at the start are beta (modal, nm x n_coef) and cs (slow rows, ns x n_coef);
  !> tp from flow_phis for the same tau.
  pure subroutine flow_state_at(self, x0, eta0, beta, cs, tau, tp, x)
    class(modal_flow_t), intent(in) :: self
    real(dp), intent(in) :: x0(:), cs(:, :), tau
    complex(dp), intent(in) :: eta0(:), beta(:, :), tp(0:, :)
    real(dp), intent(out) :: x(:)
    real(dp) :: e(2*self%nm, 0:2)
    integer :: i
    do i = 1, self%nm
      call put_amplitudes(self, i, phi_sums(tp(:, i), eta0(i), beta(i, :)), e)
    end do
    call state_from_amplitudes(self, x0, cs, tau, e, x)
  end subroutine flow_state_at

  !> The modal state and its first and second integrals over tau, from the step's phi
  !> functions tp (tau^k phi_k) of one mode: [eta, int eta, int int eta].
  pure function phi_sums(tp, eta0, beta) result(s)
    complex(dp), intent(in) :: tp(0:), eta0, beta(:)
    complex(dp) :: s(0:2)
    integer :: j
    s = tp(0:2)*eta0
    do j = 1, n_coef
      s = s + tp(j:j+2)*beta(j)
    end do
  end function phi_sums

  !> Mode i's amplitudes s (eta and its two integrals), weighted, into e: real parts in
  !> rows 1 .. nm, imaginary parts in rows nm + 1 .. 2 nm.
  pure subroutine put_amplitudes(self, i, s, e)
    class(modal_flow_t), intent(in) :: self
    integer, intent(in) :: i
    complex(dp), intent(in) :: s(0:2)
    real(dp), intent(inout) :: e(:, 0:)
    e(i, :) = self%wgt(i)*real(s); e(self%nm+i, :) = self%wgt(i)*aimag(s)
  end subroutine put_amplitudes

  !> The state x at tau after x0 from the modal amplitudes e (put_amplitudes) and the slow
  !> rows' forcing cs: the real parts of V e and C V e, by the real and imaginary parts of
  !> both; a group whose modes are all zero is zero with no product.
  pure subroutine state_from_amplitudes(self, x0, cs, tau, e, x)
    class(modal_flow_t), intent(in) :: self
    real(dp), intent(in) :: x0(:), cs(:, :), tau, e(:, 0:)
    real(dp), intent(out) :: x(:)
    real(dp) :: y(2*self%nf), fact, tr
    integer :: i, j, c, n, ns, nm, m1, m2, nc, r1, r2, nr
    n = self%ns + self%nf; ns = self%ns; nm = self%nm
    do c = 1, self%ng
      m1 = self%mode_start(c); m2 = self%mode_start(c+1) - 1; nc = m2 - m1 + 1
      r1 = self%row_start(c); r2 = self%row_start(c+1) - 1; nr = r2 - r1 + 1
      if (all(e(m1:m2, 0) == 0.0_dp .and. e(nm+m1:nm+m2, 0) == 0.0_dp)) then
        do i = r1, r2
          x(ns+self%rows(i)) = 0.0_dp; x(n+ns+self%rows(i)) = 0.0_dp
        end do
        cycle
      end if
      y(1:2*nr) = 0.0_dp
      call add_product(self%vg(c)%b(:, 1:nc), e(m1:m2, 0), y(1:2*nr))
      call add_product(self%vg(c)%b(:, nc+1:), e(nm+m1:nm+m2, 0), y(1:2*nr))
      do i = 1, nr                                        ! a loop: no vector-subscript temporaries
        x(ns+self%rows(r1+i-1)) = y(i); x(n+ns+self%rows(r1+i-1)) = y(nr+i)
      end do
    end do
    do i = 1, ns
      x(n+i) = x0(n+i) - dot_product(self%cvt(:, i), e(:, 1))
      x(i) = x0(i) + tau*x0(n+i) - dot_product(self%cvt(:, i), e(:, 2))
    end do
    fact = 1.0_dp; tr = 1.0_dp
    do j = 1, n_coef
      fact = fact*j; tr = tr*tau                            ! j!, tau^j
      x(n+1:n+ns) = x(n+1:n+ns) + tr/fact*cs(:, j)
      x(1:ns) = x(1:ns) + tr*tau/(fact*(j+1))*cs(:, j)
    end do
  end subroutine state_from_amplitudes

  !> One step's flow in the form its rows take (row_at): for a mode with |lambda| h >= 1,
  !> the particular solution. With p the cubic that solves p' = lambda p + (the mode's
  !> forcing) and d = eta0 - p(0), eta(tau) = e^(lambda tau) d + p(tau), and its integrals
  !> tau phi_1 d + P1(tau), tau^2 phi_2 d + P2(tau). A row then needs phi_0 .. phi_2, not
  !> phi_0 .. phi_6, and the polynomials share their powers of tau over the modes. Where
  !> e^(lambda tau) d and p(tau) would cancel (a mode slow against the step, or a row with
  !> |lambda| tau < 1 near the step's start) the step's form is kept; a mode at rest and
  !> unforced stays at rest.
  pure subroutine flow_rows_form(self, eta0, beta, h, rows)
    class(modal_flow_t), intent(in) :: self
    complex(dp), intent(in) :: eta0(:), beta(:, :)
    real(dp), intent(in) :: h
    type(flow_rows_t), intent(inout) :: rows
    integer :: i, m
    real(dp) :: fact(0:n_coef-1)
    fact(0) = 1.0_dp
    do m = 1, n_coef - 1
      fact(m) = fact(m-1)*m
    end do
    if (allocated(rows%c)) then
      if (size(rows%c, 2) /= self%nm) deallocate(rows%active, rows%d, rows%c, rows%tau_poly)
    end if
    if (.not. allocated(rows%c)) allocate(rows%active(self%nm), rows%d(self%nm), rows%c(0:n_coef-1, self%nm), &
      & rows%tau_poly(self%nm))
    do i = 1, self%nm
      rows%active(i) = eta0(i) /= (0.0_dp, 0.0_dp) .or. any(beta(i, :) /= (0.0_dp, 0.0_dp))
      rows%c(:, i) = (0.0_dp, 0.0_dp); rows%d(i) = (0.0_dp, 0.0_dp)
      rows%tau_poly(i) = huge(1.0_dp)
      if (.not. (rows%active(i) .and. abs(self%lam(i))*h >= 1.0_dp)) cycle
      rows%tau_poly(i) = 1.0_dp/abs(self%lam(i))
      ! forcing sum_m a_m s^m with a_m = beta_(m+1)/m!: lambda c_m = (m + 1) c_(m+1) - a_m
      rows%c(n_coef-1, i) = -beta(i, n_coef)/(fact(n_coef-1)*self%lam(i))
      do m = n_coef - 2, 0, -1
        rows%c(m, i) = ((m + 1)*rows%c(m+1, i) - beta(i, m+1)/fact(m))/self%lam(i)
      end do
      rows%d(i) = eta0(i) - rows%c(0, i)
    end do
  end subroutine flow_rows_form

  !> The state at tau inside the step whose flow_rows_form is `rows` (the same state as
  !> state_at's, for a row of the output).
  pure subroutine flow_row_at(self, rows, x0, eta0, beta, cs, tau, x)
    class(modal_flow_t), intent(in) :: self
    type(flow_rows_t), intent(in) :: rows
    real(dp), intent(in) :: x0(:), cs(:, :), tau
    complex(dp), intent(in) :: eta0(:), beta(:, :)
    real(dp), intent(out) :: x(:)
    real(dp) :: e(2*self%nm, 0:2), pw(0:n_coef-1, 0:2), tr(0:kmax)
    complex(dp) :: tp(0:kmax), s(0:2), acc
    integer :: i, m, k
    tr(0) = 1.0_dp
    do m = 1, kmax
      tr(m) = tr(m-1)*tau
    end do
    do m = 0, n_coef - 1                   ! tau^m, tau^(m+1)/(m+1), tau^(m+2)/((m+1)(m+2))
      pw(m, :) = [tr(m), tr(m+1)/(m+1), tr(m+2)/((m+1)*(m+2))]
    end do
    do i = 1, self%nm
      if (.not. rows%active(i)) then
        s = (0.0_dp, 0.0_dp)
      else if (tau >= rows%tau_poly(i)) then
        call phi_functions(self%lam(i)*tau, tp(0:2))
        do k = 0, 2                                       ! scalar sums: no array temporaries
          acc = tr(k)*tp(k)*rows%d(i)
          do m = 0, n_coef - 1
            acc = acc + rows%c(m, i)*pw(m, k)
          end do
          s(k) = acc
        end do
      else
        call phi_functions(self%lam(i)*tau, tp)
        s = phi_sums(tr*tp, eta0(i), beta(i, :))
      end if
      call put_amplitudes(self, i, s, e)
    end do
    call state_from_amplitudes(self, x0, cs, tau, e, x)
  end subroutine flow_row_at

  !> y = y + a v, column by column (contiguous, so that the compiler vectorises it; the
  !> intrinsic matmul's inlined loop did not, on the spacecraft's dense output).
  pure subroutine add_product(a, v, y)
    real(dp), intent(in) :: a(:, :), v(:)
    real(dp), intent(inout) :: y(:)
    integer :: k
    do k = 1, size(v)
      y = y + a(:, k)*v(k)
    end do
  end subroutine add_product

  !> How far the response g with coefficients kf, df has moved from the frozen one, as the
  !> explicit step's stability sees it: h^2 |Delta(g K)| + h |Delta(g D)| (row sums, largest).
  pure real(dp) function flow_drift(self, g, kf, df, h) result(d)
    class(modal_flow_t), intent(in) :: self
    real(dp), intent(in) :: g(:, :), kf(:), df(:), h
    integer :: i
    d = 0.0_dp
    do i = 1, size(g, 1)
      d = max(d, h**2*sum(abs(g(i, :)*kf - self%g0(i, :)*self%kf0)) + h*sum(abs(g(i, :)*df - self%g0(i, :)*self%df0)))
    end do
  end function flow_drift

  !> phi_0(z) = e^z and phi_{k+1}(z) = (phi_k(z) - 1/k!)/z, k = 0 .. size - 1: by that
  !> recurrence where |z| >= 2, and below it by the Taylor series of the last one and the
  !> recurrence run backwards (phi_k = 1/k! + z phi_{k+1}), each stable where it is used.
  pure subroutine phi_functions(z, p)
    complex(dp), intent(in) :: z
    complex(dp), intent(out) :: p(0:)
    integer :: k, m, kt
    real(dp) :: fk
    complex(dp) :: term, zi
    kt = ubound(p, 1)
    if (real(z)**2 + aimag(z)**2 >= 4.0_dp) then
      p(0) = exp(z)
      zi = 1.0_dp/z
      fk = 1.0_dp
      do k = 0, kt - 1
        if (k > 0) fk = fk*k
        p(k+1) = (p(k) - 1.0_dp/fk)*zi
      end do
      return
    end if
    ! phi_kt by its series sum z^m/(m + kt)!
    fk = 1.0_dp
    do k = 2, kt
      fk = fk*k
    end do
    term = cmplx(1.0_dp/fk, 0.0_dp, dp); p(kt) = term
    do m = 1, 30
      term = term*(z*reciprocal(m + kt))
      p(kt) = p(kt) + term
      if (abs(real(term)) + abs(aimag(term)) <= 1.0e-18_dp*(abs(real(p(kt))) + abs(aimag(p(kt))))) exit
    end do
    do k = kt - 1, 0, -1
      fk = fk/max(k + 1, 1)
      p(k) = 1.0_dp/fk + z*p(k+1)
    end do
  end subroutine phi_functions

  !> Weights tw(i, j) of the Taylor coefficients at t0 (the j-th derivative, j = 0 ..
  !> n_coef - 1) of the polynomial through the values at the times th(i): c_j = sum_i
  !> tw(i, j + 1) v_i. Through m < n_coef points the polynomial is of degree m - 1.
  pure subroutine taylor_weights(th, t0, tw)
    real(dp), intent(in) :: th(:), t0
    real(dp), intent(out) :: tw(:, :)
    real(dp) :: c(n_coef), den, r, fact
    integer :: i, k, j, deg
    tw = 0.0_dp
    do i = 1, size(th)
      ! l_i(t0 + tau) = prod_{k /= i} (tau - (th_k - t0)) / (th_i - th_k), coefficients in tau
      c = 0.0_dp; c(1) = 1.0_dp; deg = 0; den = 1.0_dp
      do k = 1, size(th)
        if (k == i) cycle
        r = th(k) - t0
        deg = deg + 1
        do j = deg + 1, 2, -1
          c(j) = c(j-1) - r*c(j)
        end do
        c(1) = -r*c(1)
        den = den*(th(i) - th(k))
      end do
      fact = 1.0_dp
      do j = 1, n_coef
        if (j > 1) fact = fact*(j - 1)
        tw(i, j) = fact*c(j)/den
      end do
    end do
  end subroutine taylor_weights

end module pymr_integrator_modal_flow
