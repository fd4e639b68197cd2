!> LAPACK wrappers: each routine is called once here, sizes come from the
!> arrays, and a non-zero `info` becomes a sentence naming the matrix. LAPACK's own error
!> handler XERBLA, which prints and stops the process (with status 0), is replaced at the end
!> of this file by one that records the fault and returns: the routine then returns a
!> negative `info`, which the wrappers turn into an error. Before each call the input is
!> checked: a non-finite entry, or one beyond 1e150 where LAPACK's products and norms
!> overflow, is an error naming the matrix instead of a call.
module pymr_env_lapack
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_text, only : itoa, fmt
  implicit none
  private
  public :: potrf, potrs, sygvd, syevd, ptsv, geev_complex, geev_real, factor_inverse, band_solve
  public :: lu_factor, lu_solve, general_solve, complex_inverse
  public :: illegal_argument_probe

  !> The last fault LAPACK reported to XERBLA: routine and argument number.
  character(len=32), public :: xerbla_routine = ''
  integer, public :: xerbla_argument = 0

  !> Largest entry (in size) handed to LAPACK.
  real(dp), parameter, public :: max_entry = 1.0e150_dp
  !> Cholesky factors and solves of matrices up to this order are computed here, not by
  !> LAPACK: for the few coordinates of most scenes the call costs more than the arithmetic
  !> (the tank's 6 x 6 mass matrix: 0.5 us of a 2.7 us evaluation through dpotrf/dpotrs).
  integer, parameter :: small_order = 16

  !> Cholesky solve for one (vector) or several (matrix) right-hand sides.
  interface potrs
    module procedure potrs_mat, potrs_vec
  end interface potrs

  interface
    subroutine dgetrf(m, n, a, lda, ipiv, info)
      import :: dp
      integer, intent(in) :: m, n, lda
      real(dp), intent(inout) :: a(lda, *)
      integer, intent(out) :: ipiv(*), info
    end subroutine dgetrf
    subroutine dgbsv(n, kl, ku, nrhs, ab, ldab, ipiv, b, ldb, info)
      import :: dp
      integer, intent(in) :: n, kl, ku, nrhs, ldab, ldb
      real(dp), intent(inout) :: ab(ldab, *), b(ldb, *)
      integer, intent(out) :: ipiv(*), info
    end subroutine dgbsv
    subroutine dpotrf(uplo, n, a, lda, info)
      import :: dp
      character(len=1), intent(in) :: uplo
      integer, intent(in) :: n, lda
      real(dp), intent(inout) :: a(lda, *)
      integer, intent(out) :: info
    end subroutine dpotrf
    subroutine dpotrs(uplo, n, nrhs, a, lda, b, ldb, info)
      import :: dp
      character(len=1), intent(in) :: uplo
      integer, intent(in) :: n, nrhs, lda, ldb
      real(dp), intent(in) :: a(lda, *)
      real(dp), intent(inout) :: b(*)
      integer, intent(out) :: info
    end subroutine dpotrs
    subroutine dsygvd(itype, jobz, uplo, n, a, lda, b, ldb, w, work, lwork, iwork, liwork, info)
      import :: dp
      integer, intent(in) :: itype, n, lda, ldb, lwork, liwork
      character(len=1), intent(in) :: jobz, uplo
      real(dp), intent(inout) :: a(lda, *), b(ldb, *)
      real(dp), intent(out) :: w(*), work(*)
      integer, intent(out) :: iwork(*), info
    end subroutine dsygvd
    subroutine dsyevd(jobz, uplo, n, a, lda, w, work, lwork, iwork, liwork, info)
      import :: dp
      integer, intent(in) :: n, lda, lwork, liwork
      character(len=1), intent(in) :: jobz, uplo
      real(dp), intent(inout) :: a(lda, *)
      real(dp), intent(out) :: w(*), work(*)
      integer, intent(out) :: iwork(*), info
    end subroutine dsyevd
    subroutine zgeev(jobvl, jobvr, n, a, lda, w, vl, ldvl, vr, ldvr, work, lwork, rwork, info)
      import :: dp
      character(len=1), intent(in) :: jobvl, jobvr
      integer, intent(in) :: n, lda, ldvl, ldvr, lwork
      complex(dp), intent(inout) :: a(lda, *)
      complex(dp), intent(out) :: w(*), vl(ldvl, *), vr(ldvr, *), work(*)
      real(dp), intent(out) :: rwork(*)
      integer, intent(out) :: info
    end subroutine zgeev
    subroutine dgeev(jobvl, jobvr, n, a, lda, wr, wi, vl, ldvl, vr, ldvr, work, lwork, info)
      import :: dp
      character(len=1), intent(in) :: jobvl, jobvr
      integer, intent(in) :: n, lda, ldvl, ldvr, lwork
      real(dp), intent(inout) :: a(lda, *)
      real(dp), intent(out) :: wr(*), wi(*), vl(ldvl, *), vr(ldvr, *), work(*)
      integer, intent(out) :: info
    end subroutine dgeev
    subroutine zgesv(n, nrhs, a, lda, ipiv, b, ldb, info)
      import :: dp
      integer, intent(in) :: n, nrhs, lda, ldb
      complex(dp), intent(inout) :: a(lda, *), b(ldb, *)
      integer, intent(out) :: ipiv(*), info
    end subroutine zgesv
    subroutine dptsv(n, nrhs, d, e, b, ldb, info)
      import :: dp
      integer, intent(in) :: n, nrhs, ldb
      real(dp), intent(inout) :: d(*), e(*), b(ldb, *)
      integer, intent(out) :: info
    end subroutine dptsv
  end interface

contains

  !> Solve A x = b in place for a general square A (LU with partial pivoting; A is
  !> overwritten by its factors).
  subroutine general_solve(a, b, what, error)
    real(dp), intent(inout) :: a(:, :)
    real(dp), intent(inout), contiguous :: b(:)
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    integer, allocatable :: piv(:)
    allocate(piv(size(a, 1)))
    call check_vector(b, 'dgetrf', 'the right-hand side for ' // what, error); if (allocated(error)) return
    call lu_factor(a, piv, what, error); if (allocated(error)) return
    call lu_solve(a, piv, b)
  end subroutine general_solve

  !> Solve A x = b in place with the factors of `lu_factor` (row interchanges, then the unit
  !> lower and the upper triangle). Written out, not LAPACK's dgetrs: for the small systems
  !> of the 'adams' corrector (12 on the tank, every step) a LAPACK call's own overhead
  !> would cost as much as the solve.
  pure subroutine lu_solve(lu, piv, b)
    real(dp), intent(in) :: lu(:, :)
    integer, intent(in) :: piv(:)
    real(dp), intent(inout) :: b(:)
    integer :: i, n
    real(dp) :: tmp
    n = size(b)
    do i = 1, n
      if (piv(i) /= i) then
        tmp = b(i); b(i) = b(piv(i)); b(piv(i)) = tmp
      end if
    end do
    do i = 2, n
      b(i) = b(i) - dot_product(lu(i, 1:i - 1), b(1:i - 1))
    end do
    do i = n, 1, -1
      b(i) = (b(i) - dot_product(lu(i, i + 1:n), b(i + 1:n)))/lu(i, i)
    end do
  end subroutine lu_solve

  !> LU factorisation with partial pivoting of the square `a` (in place, pivots in piv).
  subroutine lu_factor(a, piv, what, error)
    real(dp), intent(inout) :: a(:, :)
    integer, intent(out) :: piv(:)
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    integer :: info
    if (size(a, 1) == 0) return
    call check_matrix(a, 'dgetrf', what, error); if (allocated(error)) return
    call dgetrf(size(a, 1), size(a, 2), a, size(a, 1), piv, info)
    if (info > 0) then
      call fatal_error(error, what // ' is singular (LU dgetrf: zero pivot ' // itoa(info) // ')', stat_solver)
    else if (info < 0) then
      call fatal_error(error, 'dgetrf: argument ' // itoa(-info) // ' had an illegal value for ' // what, stat_solver)
    end if
  end subroutine lu_factor

  !> Solve T x = b in place for the symmetric positive definite tridiagonal T with
  !> diagonal `dg` and off-diagonal `e` (both overwritten by its factor).
  subroutine ptsv(dg, e, b, what, error)
    real(dp), intent(inout) :: dg(:), e(:)
    real(dp), intent(inout), contiguous :: b(:)
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    integer :: info
    character(len=24) :: buf
    if (size(dg) == 0) return
    call check_vector([dg, e, b], 'dptsv', what, error); if (allocated(error)) return
    call dptsv(size(dg), 1, dg, e, b, size(b), info)
    if (info == 0) return
    write(buf, '(i0)') info
    call fatal_error(error, 'dptsv failed for ' // what // ' (info ' // trim(buf) // ')', stat_solver)
  end subroutine ptsv

  !> Cholesky factorisation (lower triangle) of the symmetric positive definite `a`.
  !> `what` names the matrix in the error message ("the mass matrix at t = 0.5 s").
  subroutine potrf(a, what, error, minor)
    !> Matrix to factor; on return its lower triangle holds L with A = L L^T.
    real(dp), intent(inout) :: a(:, :)
    !> Name of the matrix for messages.
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    !> Leading minor that is not positive definite (0 on success).
    integer, intent(out), optional :: minor
    integer :: info
    character(len=24) :: buf
    if (present(minor)) minor = 0
    if (size(a, 1) == 0) return
    call check_matrix(a, 'dpotrf', what, error); if (allocated(error)) return
    if (size(a, 1) <= small_order) then
      call small_cholesky(a, info)
    else
      call dpotrf('L', size(a, 1), a, size(a, 1), info)
    end if
    if (info == 0) return
    if (present(minor)) minor = max(info, 0)
    write(buf, '(i0)') abs(info)
    if (info > 0) then
      call fatal_error(error, 'leading minor ' // trim(buf) // ' of ' // what // &
        & ' is not positive definite (Cholesky failed)', stat_solver)
    else
      call fatal_error(error, 'dpotrf: argument ' // trim(buf) // ' had an illegal value for ' &
        & // what, stat_solver)
    end if
  end subroutine potrf

  !> Solve A x = b in place with the Cholesky factor from `potrf` (one right-hand side).
  subroutine potrs_vec(a, b, what, error)
    real(dp), intent(in) :: a(:, :)
    real(dp), intent(inout), contiguous :: b(:)
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    integer :: info
    character(len=24) :: buf
    if (size(a, 1) == 0) return
    call check_vector(b, 'dpotrs', 'the right-hand side for ' // what, error); if (allocated(error)) return
    if (size(a, 1) <= small_order) then
      call small_solve(a, b); return
    end if
    call dpotrs('L', size(a, 1), 1, a, size(a, 1), b, size(b), info)
    if (info /= 0) then
      write(buf, '(i0)') -info
      call fatal_error(error, 'dpotrs: argument ' // trim(buf) // ' had an illegal value for ' &
        & // what, stat_solver)
    end if
  end subroutine potrs_vec

  !> Solve A X = B in place with the Cholesky factor from `potrf`.
  subroutine potrs_mat(a, b, what, error)
    !> Factor from potrf (lower triangle).
    real(dp), intent(in) :: a(:, :)
    !> Right-hand sides on entry, solutions on return.
    real(dp), intent(inout), contiguous :: b(:, :)
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    integer :: info
    character(len=24) :: buf
    if (size(a, 1) == 0) return
    call check_matrix(b, 'dpotrs', 'the right-hand sides for ' // what, error)
    if (allocated(error)) return
    if (size(a, 1) <= small_order) then
      call small_solve(a, b); return
    end if
    call dpotrs('L', size(a, 1), size(b, 2), a, size(a, 1), b, size(b, 1), info)
    if (info /= 0) then
      write(buf, '(i0)') -info
      call fatal_error(error, 'dpotrs: argument ' // trim(buf) // ' had an illegal value for ' &
        & // what, stat_solver)
    end if
  end subroutine potrs_mat

  !> The inverse of A from its Cholesky factor (from `potrf`): the identity solved in place.
  subroutine factor_inverse(l, ainv, what, error)
    real(dp), intent(in) :: l(:, :)
    real(dp), intent(out), contiguous :: ainv(:, :)
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    integer :: i
    ainv = 0.0_dp
    do i = 1, size(ainv, 1)
      ainv(i, i) = 1.0_dp
    end do
    call potrs(l, ainv, what, error)
  end subroutine factor_inverse

  !> The inverse of the complex square matrix a (overwritten by its LU factors): LAPACK
  !> zgesv on the identity.
  subroutine complex_inverse(a, ainv, what, error)
    complex(dp), intent(inout) :: a(:, :)
    complex(dp), intent(out) :: ainv(:, :)
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    integer :: i, n, info
    integer, allocatable :: piv(:)
    n = size(a, 1)
    if (n == 0) return
    call check_matrix(real(a), 'zgesv', what, error)
    if (.not. allocated(error)) call check_matrix(aimag(a), 'zgesv', what, error); if (allocated(error)) return
    allocate(piv(n))
    ainv = (0.0_dp, 0.0_dp)
    do i = 1, n
      ainv(i, i) = (1.0_dp, 0.0_dp)
    end do
    call zgesv(n, n, a, n, piv, ainv, n, info)
    if (info > 0) then
      call fatal_error(error, what // ' is singular (LU zgesv: zero pivot ' // itoa(info) // ')', stat_solver)
    else if (info < 0) then
      call fatal_error(error, 'zgesv: argument ' // itoa(-info) // ' had an illegal value for ' // what, stat_solver)
    end if
  end subroutine complex_inverse

  !> Generalised symmetric-definite eigenproblem A v = lambda B v, B positive definite
  !> (all eigenpairs, ascending). On return `k` (A) holds the B-normalised eigenvectors
  !> in its columns. `what` names B in messages.
  subroutine sygvd(k, m, lambda, what, error)
    real(dp), intent(inout) :: k(:, :)
    real(dp), intent(inout) :: m(:, :)
    real(dp), intent(out) :: lambda(:)
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    integer :: n, info, lwork, liwork, iwq(1)
    real(dp) :: wq(1)
    real(dp), allocatable :: work(:)
    integer, allocatable :: iwork(:)
    character(len=24) :: buf
    n = size(k, 1)
    if (n == 0) return
    call check_matrix(k, 'dsygvd', 'the stiffness matrix for ' // what, error)
    if (allocated(error)) return
    call check_matrix(m, 'dsygvd', what, error); if (allocated(error)) return
    call dsygvd(1, 'V', 'L', n, k, n, m, n, lambda, wq, -1, iwq, -1, info)
    lwork = int(wq(1)); liwork = iwq(1)
    allocate(work(lwork), iwork(liwork))
    call dsygvd(1, 'V', 'L', n, k, n, m, n, lambda, work, lwork, iwork, liwork, info)
    if (info == 0) return
    write(buf, '(i0)') info
    if (info > n) then
      call fatal_error(error, 'leading minor ' // itoa(info - n) // ' of ' &
        & // what // ' is not positive definite (dsygvd)', stat_solver)
    else
      call fatal_error(error, 'eigenvalue solver dsygvd failed for ' // what // ' (info ' // trim(buf) // ')', &
        & stat_solver)
    end if
  end subroutine sygvd

  !> Symmetric eigenproblem A v = lambda v (all eigenpairs, ascending), LAPACK dsyevd. On
  !> return `a` holds the orthonormal eigenvectors in its columns. `what` names A in
  !> messages.
  subroutine syevd(a, lambda, what, error)
    real(dp), intent(inout) :: a(:, :)
    real(dp), intent(out) :: lambda(:)
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    integer :: n, info, iwq(1)
    real(dp) :: wq(1)
    real(dp), allocatable :: work(:)
    integer, allocatable :: iwork(:)
    n = size(a, 1)
    if (n == 0) return
    call check_matrix(a, 'dsyevd', what, error); if (allocated(error)) return
    call dsyevd('V', 'L', n, a, n, lambda, wq, -1, iwq, -1, info)
    allocate(work(int(wq(1))), iwork(iwq(1)))
    call dsyevd('V', 'L', n, a, n, lambda, work, size(work), iwork, size(iwork), info)
    if (info /= 0) call fatal_error(error, 'eigenvalue solver dsyevd failed for ' // what // ' (info ' // &
      & itoa(info) // ')', stat_solver)
  end subroutine syevd

  !> Eigenvalues w of the complex square matrix a (overwritten), LAPACK zgeev.
  subroutine geev_complex(a, w, what, error)
    complex(dp), intent(inout) :: a(:, :)
    complex(dp), intent(out) :: w(:)
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    integer :: n, info
    complex(dp) :: vl(1, 1), vr(1, 1), wq(1)
    complex(dp), allocatable :: work(:)
    real(dp) :: rwork(2*size(a, 1))
    n = size(a, 1)
    if (n == 0) return
    call check_matrix(real(a), 'zgeev', what, error)
    if (.not. allocated(error)) call check_matrix(aimag(a), 'zgeev', what, error); if (allocated(error)) return
    call zgeev('N', 'N', n, a, n, w, vl, 1, vr, 1, wq, -1, rwork, info)
    allocate(work(max(1, int(real(wq(1))))))
    call zgeev('N', 'N', n, a, n, w, vl, 1, vr, 1, work, size(work), rwork, info)
    if (info /= 0) call fatal_error(error, 'eigenvalue solver zgeev failed for ' // what, stat_solver)
  end subroutine geev_complex

  !> Eigenvalues wr + i wi and right eigenvectors vr (dgeev's packed real form) of the
  !> real square matrix a (overwritten), LAPACK dgeev.
  subroutine geev_real(a, wr, wi, what, error, vr)
    real(dp), intent(inout) :: a(:, :)
    real(dp), intent(out) :: wr(:), wi(:)
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    !> The right eigenvectors (packed as dgeev packs them); without it, the eigenvalues only
    !> (about a third of the work).
    real(dp), intent(out), optional, target :: vr(:, :)
    integer :: n, info, ldv
    real(dp), target :: dum(1, 1)
    real(dp) :: wq(1)
    real(dp), pointer :: v(:, :)
    character :: jobv
    real(dp), allocatable :: work(:)
    n = size(a, 1)
    if (n == 0) return
    call check_matrix(a, 'dgeev', what, error); if (allocated(error)) return
    jobv = 'N'; v => dum; ldv = 1
    if (present(vr)) then
      jobv = 'V'; v => vr; ldv = n
    end if
    call dgeev('N', jobv, n, a, n, wr, wi, dum, 1, v, ldv, wq, -1, info)
    allocate(work(max(1, int(wq(1)))))
    call dgeev('N', jobv, n, a, n, wr, wi, dum, 1, v, ldv, work, size(work), info)
    if (info /= 0) call fatal_error(error, 'eigenvalue solver dgeev failed for ' // what, stat_solver)
  end subroutine geev_real

  !> Solve A x = b for a symmetric banded A given by its lower band a (a(1 + i - j, j) = A(i, j)),
  !> not necessarily definite: LAPACK dgbsv with partial pivoting; b becomes x.
  subroutine band_solve(a, b, what, error)
    real(dp), intent(in) :: a(:, :)
    real(dp), intent(inout) :: b(:)
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: ab(:, :)
    integer, allocatable :: ipiv(:)
    integer :: n, kd, i, j, info
    n = size(a, 2); kd = size(a, 1) - 1
    call check_matrix(a, 'dgbsv', what, error)
    if (.not. allocated(error)) call check_vector(b, 'dgbsv', what, error); if (allocated(error)) return
    allocate(ab(3*kd + 1, n), ipiv(n))
    ab = 0.0_dp
    do j = 1, n
      do i = j, min(n, j + kd)
        ab(2*kd + 1 + i - j, j) = a(1 + i - j, j)       ! A(i, j), below the diagonal
        ab(2*kd + 1 + j - i, i) = a(1 + i - j, j)       ! A(j, i), above it
      end do
    end do
    call dgbsv(n, kd, kd, 1, ab, 3*kd + 1, ipiv, b, n, info)
    if (info /= 0) call fatal_error(error, 'banded solver dgbsv failed for ' // what // ' (info ' // &
      & itoa(info) // ')', stat_solver)
  end subroutine band_solve


  !> Before a LAPACK call: every entry of its input finite, and below `max_entry` in size
  !> (larger ones overflow in LAPACK's products and norms), else an error naming the matrix.
  subroutine check_vector(a, routine, what, error)
    real(dp), intent(in) :: a(:)
    character(len=*), intent(in) :: routine, what
    type(error_type), allocatable, intent(out) :: error
    integer :: i
    do i = 1, size(a)
      if (.not. abs(a(i)) <= max_entry) then
        call entry_error(a(i), routine, what, error); return
      end if
    end do
  end subroutine check_vector

  subroutine check_matrix(a, routine, what, error)
    real(dp), intent(in) :: a(:, :)
    character(len=*), intent(in) :: routine, what
    type(error_type), allocatable, intent(out) :: error
    integer :: i, j
    do j = 1, size(a, 2)
      do i = 1, size(a, 1)
        if (.not. abs(a(i, j)) <= max_entry) then
          call entry_error(a(i, j), routine, what, error); return
        end if
      end do
    end do
  end subroutine check_matrix

  subroutine entry_error(x, routine, what, error)
    real(dp), intent(in) :: x
    character(len=*), intent(in) :: routine, what
    type(error_type), allocatable, intent(out) :: error
    if (x /= x .or. abs(x) > huge(x)) then
      call fatal_error(error, routine // ': ' // what // ' has a non-finite entry (' // fmt(x) // '); not solved', &
        & stat_solver)
    else
      call fatal_error(error, routine // ': ' // what // ' has an entry of ' // fmt(x) // ', beyond ' // &
        & fmt(max_entry) // ' where LAPACK overflows; not solved', stat_solver)
    end if
  end subroutine entry_error

  !> Cholesky factor (lower) of a small symmetric matrix in place; bad = 0, or the first
  !> leading minor that is not positive definite.
  pure subroutine small_cholesky(a, bad)
    real(dp), intent(inout) :: a(:, :)
    integer, intent(out) :: bad
    integer :: i, j, n
    n = size(a, 1)
    bad = 0
    do j = 1, n
      a(j, j) = a(j, j) - dot_product(a(j, 1:j-1), a(j, 1:j-1))
      if (.not. a(j, j) > 0.0_dp) then
        bad = j; return
      end if
      a(j, j) = sqrt(a(j, j))
      do i = j + 1, n
        a(i, j) = (a(i, j) - dot_product(a(i, 1:j-1), a(j, 1:j-1)))/a(j, j)
      end do
    end do
  end subroutine small_cholesky

  !> Solve L L^T x = b in place for the columns of b (the factor of small_cholesky).
  pure subroutine small_solve(l, b)
    real(dp), intent(in) :: l(:, :)
    real(dp), intent(inout) :: b(..)
    select rank (b)
    rank (1)
      call solve_one(b)
    rank (2)
      block
        integer :: k
        do k = 1, size(b, 2)
          call solve_one(b(:, k))
        end do
      end block
    end select
  contains
    pure subroutine solve_one(x)
      real(dp), intent(inout) :: x(:)
      integer :: i, n
      n = size(x)
      do i = 1, n
        x(i) = (x(i) - dot_product(l(i, 1:i-1), x(1:i-1)))/l(i, i)
      end do
      do i = n, 1, -1
        x(i) = (x(i) - dot_product(l(i+1:n, i), x(i+1:n)))/l(i, i)
      end do
    end subroutine solve_one
  end subroutine small_solve

  !> A call with an illegal argument (dpotrf with uplo 'X'): for the test that XERBLA
  !> returns. Gives LAPACK's info.
  subroutine illegal_argument_probe(info)
    integer, intent(out) :: info
    real(dp) :: a(1, 1)
    a = 1.0_dp
    call dpotrf('X', 1, a, 1, info)
  end subroutine illegal_argument_probe
end module pymr_env_lapack

!> LAPACK's error handler, called with the routine's name and the number of the argument
!> found illegal. Reference LAPACK prints and stops the process; pymr's records the fault
!> and returns, so the routine returns info < 0 and the caller reports it as an error.
subroutine xerbla(srname, info)
  use pymr_env_lapack, only : xerbla_routine, xerbla_argument
  implicit none
  character(len=*), intent(in) :: srname
  integer, intent(in) :: info
  xerbla_routine = srname
  xerbla_argument = info
end subroutine xerbla
