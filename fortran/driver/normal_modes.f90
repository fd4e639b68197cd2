!> Natural modes of the model linearised at a state (`pymr modes`), and its highest natural
!> frequency (which bounds the largest step of adaptive runs whose closed loops pass
!> through flexible bodies).
module pymr_driver_normal_modes
  use pymr_env_kinds, only : dp, pi
  use pymr_env_error, only : error_type
  use pymr_env_lapack, only : geev_real, sygvd
  use pymr_model, only : model_t, model_counters
  use pymr_model_loops, only : loop_jacobian
  use pymr_driver_linearise, only : linear_state, state_matrix
  implicit none
  private
  public :: normal_modes, top_frequency, modes_bytes

  !> Natural modes: an eigenvalue of the linearised model below this size (1/s) is a rigid-body
  !> motion whatever the rest of the spectrum: it changes a motion by a factor e in no less
  !> than 1e9 s, the longest run (&scene t_end). A model with no force at all (a free chain
  !> drifting) has nothing else to set the scale of its roundoff (1e-12 /s measured).
  real(dp), parameter :: lambda_floor = 1.0e-9_dp

  !> The modes found so far, in the order found: kind (1 vibration, 2 rigid, 3 drift),
  !> frequency (Hz), damping ratio, rate (1/s), shape, and the key each kind is sorted by.
  type :: mode_list
    integer :: nm = 0
    integer, allocatable :: kd(:)
    real(dp), allocatable :: f(:), z(:), r(:), s(:, :), key(:)
  end type mode_list

  !> The rigid-body motions found so far: an orthonormal basis of nr of them.
  type :: rigid_basis
    integer :: nr = 0
    real(dp), allocatable :: u(:, :)
  end type rigid_basis

contains

  !> Bytes the modes of a model of n coordinates take beside the model and the caller's
  !> arrays: a working copy of the model, the linearised mass, its inverse, stiffness and
  !> damping, the 2n x 2n state matrix and its eigenvectors, the modes found and the
  !> rigid-body basis: 22 n^2 words. `pymr.modes` measured 24 in all (the address-space
  !> limit below which it cannot finish, n = 525 and 1025; the model's two and the shapes'
  !> two among them), rounded up by about a tenth.
  pure real(dp) function modes_bytes(n)
    integer, intent(in) :: n
    modes_bytes = 8.0_dp*22.0_dp*real(n, dp)**2
  end function modes_bytes

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
    type(mode_list) :: modes
    type(rigid_basis) :: rigid
    real(dp) :: noise2, tol
    integer :: n, j
    n = model%d%n
    nm = 0; freq = 0.0_dp; zeta = 0.0_dp; rate = 0.0_dp; shapes = 0.0_dp; kind = 0
    call linear_state(model, t, x, m, minv, k, c, a, error); if (allocated(error)) return
    call accelerating_stiffness(model, t, x, minv, k, noise2, error); if (allocated(error)) return
    call state_matrix(minv, k, c, a)
    allocate(wr(2*n), wi(2*n), vr(2*n, 2*n))
    call geev_real(a, wr, wi, 'the linearised model', error, vr); if (allocated(error)) return
    tol = max(1.0e-6_dp*maxval(hypot(wr, wi)), sqrt(noise2), lambda_floor)
    call sort_eigenvalues(wr, wi, vr, n, tol, modes, rigid)
    if (rigid%nr > 0) then
      call held_by_nothing(model, x, minv, k, tol, rigid, error); if (allocated(error)) return
    end if
    do j = 1, rigid%nr
      call add_mode(modes, 2, 0.0_dp, 0.0_dp, 0.0_dp, rigid%u(:, j)/rigid%u(maxloc(abs(rigid%u(:, j)), 1), j), &
        & real(j, dp))
    end do
    nm = modes%nm
    call put_in_order(modes, freq, zeta, rate, kind, shapes)
  end subroutine normal_modes

  !> Each eigenvalue lambda = wr + i wi (eigenvectors vr, n coordinates) to its kind: below
  !> tol a rigid-body motion (the real and imaginary parts of its position part, into the
  !> basis), a complex pair a vibration (its shape scaled to 1 at its largest component), a
  !> real one a drift.
  subroutine sort_eigenvalues(wr, wi, vr, n, tol, modes, rigid)
    real(dp), intent(in) :: wr(:), wi(:), vr(:, :), tol
    integer, intent(in) :: n
    type(mode_list), intent(inout) :: modes
    type(rigid_basis), intent(inout) :: rigid
    complex(dp) :: v(n)
    real(dp) :: lam
    integer :: i, top
    allocate(modes%kd(2*n), modes%f(2*n), modes%z(2*n), modes%r(2*n), modes%s(n, 2*n), modes%key(2*n))
    allocate(rigid%u(n, n))
    do i = 1, 2*n
      lam = hypot(wr(i), wi(i))
      if (lam <= tol) then
        ! rigid: each of the real and imaginary parts of the position part, kept on the loops
        call add_rigid(rigid, vr(1:n, i))
        if (wi(i) > 0.0_dp .and. i < 2*n) call add_rigid(rigid, vr(1:n, i + 1))
      else if (wi(i) > 0.0_dp .and. i < 2*n) then
        v = cmplx(vr(1:n, i), vr(1:n, i + 1), dp)
        top = maxloc(abs(v), 1)
        v = v/v(top)
        call add_mode(modes, 1, lam/(2.0_dp*pi), -wr(i)/lam, wr(i), real(v, dp), lam/(2.0_dp*pi))
      else if (wi(i) == 0.0_dp) then
        call add_mode(modes, 3, 0.0_dp, -sign(1.0_dp, wr(i)), wr(i), vr(1:n, i)/vr(maxloc(abs(vr(1:n, i)), 1), i), &
          & -wr(i))
      end if
    end do
  end subroutine sort_eigenvalues

  !> One more mode of kind kd: frequency f, damping ratio z, rate r, shape s, sort key.
  subroutine add_mode(modes, kd, f, z, r, s, key)
    type(mode_list), intent(inout) :: modes
    integer, intent(in) :: kd
    real(dp), intent(in) :: f, z, r, s(:), key
    integer :: i
    modes%nm = modes%nm + 1
    i = modes%nm
    modes%kd(i) = kd; modes%f(i) = f; modes%z(i) = z; modes%r(i) = r; modes%s(:, i) = s; modes%key(i) = key
  end subroutine add_mode

  !> The modes into the caller's arrays: rigid-body motions, drifts, vibrations; each kind
  !> by its key.
  subroutine put_in_order(modes, freq, zeta, rate, kind, shapes)
    type(mode_list), intent(in) :: modes
    real(dp), intent(inout) :: freq(:), zeta(:), rate(:), shapes(:, :)
    integer, intent(inout) :: kind(:)
    integer, allocatable :: order(:)
    integer :: i, j, top
    i = 0
    do top = 2, 4
      order = pack([(j, j = 1, modes%nm)], modes%kd(1:modes%nm) == merge(1, top, top == 4))
      order = order(sort_index(modes%key(order)))
      do j = 1, size(order)
        i = i + 1
        freq(i) = modes%f(order(j)); zeta(i) = modes%z(order(j)); rate(i) = modes%r(order(j))
        kind(i) = modes%kd(order(j)); shapes(:, i) = modes%s(:, order(j))
      end do
    end do
  end subroutine put_in_order

  !> The unresolved eigenvalues' eigenvectors span the rigid-body motions and, where the
  !> zero eigenvalue is defective, motions chained to them; with loops also motions that
  !> would open a loop (the constrained inverse leaves them without stiffness) and the
  !> motions these lead into. The rigid-body motions are those u of the basis's span that
  !> nothing holds, -M^-1 K u = 0 to the threshold tol^2, and that keep the loops closed,
  !> G u = 0 to 1e-5 of |G|: the null space of B^T B, B = [G Q / (1e-5 |G|); M^-1 K Q / tol^2]
  !> for the basis Q (eigenvalues at most 1).
  subroutine held_by_nothing(model, x, minv, k, tol, rigid, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:), minv(:, :), k(:, :), tol
    type(rigid_basis), intent(inout) :: rigid
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: g(:, :), b(:, :), e(:, :), mu(:), kept(:, :), eye(:, :)
    integer :: l, nk, n, nr
    n = model%d%n; nr = rigid%nr
    associate(basis => rigid%u)
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
      rigid%nr = nk
      basis(:, 1:nk) = kept(:, 1:nk)
    end associate
  end subroutine held_by_nothing

  !> Add the motion u to the rigid-body basis unless the basis already holds it
  !> (Gram-Schmidt: what is left is below 1e-3 of it).
  subroutine add_rigid(rigid, u)
    type(rigid_basis), intent(inout) :: rigid
    real(dp), intent(in) :: u(:)
    real(dp) :: phi(size(u)), size_u
    integer :: l
    if (rigid%nr == size(u)) return
    phi = u
    size_u = norm2(phi)
    if (size_u == 0.0_dp) return
    do l = 1, rigid%nr
      phi = phi - dot_product(rigid%u(:, l), phi)*rigid%u(:, l)
    end do
    if (norm2(phi) <= 1.0e-3_dp*size_u) return
    rigid%nr = rigid%nr + 1
    rigid%u(:, rigid%nr) = phi/norm2(phi)
  end subroutine add_rigid

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
end module pymr_driver_normal_modes
