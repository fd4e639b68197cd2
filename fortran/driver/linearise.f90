!> The model linearised at a state, shared by the pre-flight check, the static start and the
!> natural modes: M, K = -dP/dq and C = -dP/dqd by central differences, the (with loops,
!> constrained) inverse of M, and the first-order state matrix built from them.
module pymr_driver_linearise
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type
  use pymr_env_lapack, only : potrf, factor_inverse
  use pymr_model, only : model_t, model_counters
  use pymr_model_loops, only : loop_jacobian, constrain_inverse
  implicit none
  private
  public :: linearise, linear_state, state_matrix, mass_inverse

contains

  !> The model linearised at (t, x = [q; qd]): M (symmetrised), K = -dP/dq and C = -dP/dqd
  !> by central differences with increments 1e-6 max(1, |x_j|); the model is left evaluated
  !> at x. Its evaluations do not count as the run's.
  subroutine linearise(model, t, x, m, k, c, n_columns)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, x(:)
    real(dp), allocatable, intent(out) :: m(:, :), k(:, :), c(:, :)
    !> Differentiate by the first n_columns coordinates only (the others' columns are zero).
    integer, intent(in), optional :: n_columns
    type(model_counters) :: counters
    real(dp), allocatable :: q(:), qd(:), pp(:), pm(:)
    real(dp) :: del
    integer :: n, j, nc
    n = model%d%n
    nc = n
    if (present(n_columns)) nc = n_columns
    counters = model%counters()
    q = x(1:n); qd = x(n+1:2*n)
    allocate(k(n, n), c(n, n), pp(n), pm(n))
    k = 0.0_dp; c = 0.0_dp
    do j = 1, nc
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
    ! last, so that the model is left evaluated at x (model%fast_forces reads it)
    call model%terms(t, q, qd)
    m = 0.5_dp*(model%wk%mm + transpose(model%wk%mm))
    call model%set_counters(counters)
  end subroutine linearise

  !> The model linearised at (t, x): M, its (with loops, constrained) inverse, K, C, and the
  !> state matrix a built from them.
  subroutine linear_state(model, t, x, m, minv, k, c, a, error, n_columns)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, x(:)
    real(dp), allocatable, intent(out) :: m(:, :), minv(:, :), k(:, :), c(:, :), a(:, :)
    type(error_type), allocatable, intent(out) :: error
    !> As for linearise.
    integer, intent(in), optional :: n_columns
    call linearise(model, t, x, m, k, c, n_columns)
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
end module pymr_driver_linearise
