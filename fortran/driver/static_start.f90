!> The static start (&scene start = 'static'): the coordinates to settle moved to static
!> equilibrium at t = 0 by Newton's method, with closed loops on their constraints.
module pymr_driver_static_start
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_input
  use pymr_env_lapack, only : general_solve
  use pymr_model, only : model_t, model_counters
  use pymr_model_loops, only : loop_rows, independent_rows
  use pymr_driver_linearise, only : linearise
  use pymr_env_text, only : itoa
  implicit none
  private
  public :: static_start

  !> Static start: most Newton iterations, and the change (relative to max(1, |q|)) below
  !> which it has converged.
  integer, parameter :: newton_max = 30
  real(dp), parameter :: newton_tol = 1.0e-13_dp

contains

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
        call fatal_error(error, 'no static equilibrium at t = 0: ' // why // &
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
    call fatal_error(error, "no static equilibrium found in " // itoa(newton_max) // &
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
    if (n_ind < model%wk%loops%n_used) call fatal_error(error, 'the coordinates to settle (the modal ' // &
      & 'ones and those of the joints marked settle) move only ' // itoa(n_ind) // ' of the loops'' ' // &
      & itoa(model%wk%loops%n_used) // ' independent constraints: the joints held fast hold the loops (mark settle ' // &
      & 'every joint of a loop that should settle)', stat_input)
    if (.not. allocated(error) .and. size(u) <= n_ind) call fatal_error(error, 'the loops leave ' // &
      & 'the coordinates to settle no freedom (' // itoa(size(u)) // ' coordinates, ' // itoa(n_ind) // &
      & ' independent constraints on them): with the joints held they can only stay as given (mark settle ' // &
      & 'the joints of the loop, or start from the given state)', stat_input)
  end subroutine check_settle_loops
end module pymr_driver_static_start
