!> Modal data files for `kind='modal'` bodies (format in docs/scenes.md, "Modal data files").
!>
!>   # comment lines start with '#'
!>   pymr-modal V                    (V = 1 or 2)
!>   modes M
!>   frequencies_hz f_1 ... f_M
!>   invariants                      (optional, version 2)
!>   mass m
!>   first_moments
!>   alpha F(1:3, alpha)                                  (alpha = 0..M: M+1 lines)
!>   second_moments
!>   alpha beta W(1, 1:3) W(2, 1:3) W(3, 1:3)             (alpha = 0..M, beta = alpha..M)
!>   points P
!>   x y z mass  psi(1:3, 1) ... psi(1:3, M)  phi(1:3, 1) ... phi(1:3, M)     (P lines)
!>
!> Points are in the body frame (m); mass in kg (0 for a point that only carries a
!> joint or a marker); psi and phi are the mass-normalised translational and rotational
!> mode shapes at the point. Without an invariants block the body's inertia is the sum
!> over the point masses; with one (written by `pymr modal-import` from finite-element
!> matrices) the body's mass, first moments F = int rho Z and second moments
!> W(i,j,alpha,beta) = int rho Z(i,alpha) Z(j,beta), Z = [s, Psi], are given and the points
!> carry no mass. W(:,:,beta,alpha) = W(:,:,alpha,beta)^T gives the lower triangle.
module pymr_io_modal_file
  use, intrinsic :: iso_fortran_env, only : int64
  use, intrinsic :: ieee_arithmetic, only : ieee_is_finite
  use pymr_env_kinds, only : dp, pi
  use pymr_env_error, only : error_type, fatal_error
  use pymr_model_flexbody, only : flex_data, flex_invariants, flex_from_moments, modal_nodes, central_inertia
  use pymr_model_spatial, only : skew
  use pymr_model_beam_modes, only : beam_shape, beam_point_shapes
  use pymr_model_scene, only : big_length, big_mass, small_mass
  use pymr_model_inertia, only : eig3
  use pymr_env_lapack, only : potrf, max_entry
  use pymr_env_text, only : itoa, fmt, number_text, count_text, split_words, next_text_line, excerpt, max_shown, &
    & below_normal
  use pymr_env_text_file, only : not_regular, write_text_file, read_text_file, check_header_count
  implicit none
  private
  public :: read_modal_file, write_modal_file, normalised_tol

  !> Largest |M_ij - delta_ij| of the modal mass matrix M = sum m_p Psi_p^T Psi_p (or the
  !> traces of W's modal blocks) that a modal file's modes may have: a mode scaled by
  !> 1 + e has its frequency off by e/2. Measured: the files pymr writes reach 4e-13
  !> (modal-file, every beam of input/) and 3.2e-9 (modal-import, all 100 modes of a
  !> 20-element barrel); rounded to 6 significant digits 2.8e-6, to 4 digits 1.7e-4.
  real(dp), parameter :: normalised_tol = 1.0e-4_dp

  !> Where the reading of a modal file is: its text and current line (its words wa:wb, nw
  !> of them, its number), what the header gave, and the first error.
  type :: modal_reader
    character(len=:), allocatable :: path, text, ln
    integer, allocatable :: wa(:), wb(:)
    integer :: pos = 1, line = 0, nw = 0
    !> Format version, number of modes, the lines of 'modes', 'points' and 'invariants'.
    integer :: version = 0, m = 0, modes_line = 0, points_line = 0, invariants_line = 0
    !> Whether an invariants block is given, and the line of each pair of its second moments.
    logical :: given = .false.
    integer, allocatable :: wline(:, :)
    type(error_type), allocatable :: error
  contains
    procedure :: numbers => reader_numbers
    procedure :: word => reader_word
    procedure :: rest => reader_rest
    procedure :: count_word => reader_count_word
    procedure :: next_line => reader_next_line
    procedure :: data_line => reader_data_line
    procedure :: key_line => reader_key_line
    procedure :: next_is => reader_next_is
    procedure :: fail => reader_fail
  end type modal_reader


contains

  !> Read a modal file into invariants (fd) and nodes. The file must agree with itself:
  !> each line holds exactly the numbers its header's counts give (no more, no fewer), every
  !> number is finite, the counts fit the file's size before anything is allocated by them
  !> (check_header_count), nothing follows the points, and the modes are mass-normalised
  !> to normalised_tol.
  subroutine read_modal_file(path, fd, nodes, error)
    character(len=*), intent(in) :: path
    type(flex_data), intent(out) :: fd
    type(modal_nodes), intent(out) :: nodes
    type(error_type), allocatable, intent(out) :: error
    type(modal_reader) :: r
    real(dp), allocatable :: f(:), mp(:), first(:, :), w(:, :, :, :)
    real(dp) :: mass
    logical :: exists
    if (len(not_regular(path)) > 0) then
      call fatal_error(error, path // ': cannot open: ' // not_regular(path)); return
    end if
    inquire(file=path, exist=exists)
    if (.not. exists) then
      call fatal_error(error, path // ': modal file not found'); return
    end if
    r%path = path
    call read_text_file(path, r%text, error); if (allocated(error)) return
    call read_header(r, f)
    if (.not. allocated(r%error)) then
      r%given = r%next_is('invariants')
      if (r%given) then
        if (r%version < 2) then
          call r%fail('invariants: needs pymr-modal 2', r%line + 1)
        else
          call read_invariants(r, mass, first, w)
        end if
      end if
    end if
    if (.not. allocated(r%error)) call read_points(r, nodes, mp)
    if (.not. allocated(r%error)) call body_invariants(r, nodes, mp, mass, first, w, fd)
    if (.not. allocated(r%error)) call check_normalised(r, fd)
    if (allocated(r%error)) then
      call move_alloc(r%error, error); return
    end if
    fd%omega2 = (2.0_dp*pi*f)**2
  end subroutine read_modal_file

  !> The header: the format version, the modes' count and their frequencies f (Hz).
  subroutine read_header(r, f)
    type(modal_reader), intent(inout) :: r
    real(dp), allocatable, intent(out) :: f(:)
    integer :: p
    call r%key_line('pymr-modal'); if (allocated(r%error)) return
    if (.not. r%count_word(r%version) .or. r%version < 1 .or. r%version > 2) then
      call r%fail('pymr-modal: expected the format version 1 or 2, got ' // r%rest()); return
    end if
    call r%key_line('modes'); if (allocated(r%error)) return
    r%modes_line = r%line
    if (.not. r%count_word(r%m)) then
      call r%fail('modes: expected a count, got ' // r%rest()); return
    end if
    call check_header_count(r%path, 'line ' // itoa(r%line) // ': modes', int(r%m, int64), 2, 'frequencies', r%error)
    if (allocated(r%error)) return
    call r%key_line('frequencies_hz'); if (allocated(r%error)) return
    allocate(f(r%m))
    if (r%nw - 1 /= r%m) then
      call r%fail('frequencies_hz: expected ' // itoa(r%m) // ' positive frequencies (modes ' // itoa(r%m) // &
        & '), got ' // itoa(r%nw - 1) // ' numbers'); return
    end if
    call r%numbers(2, f, 'frequencies_hz', 'frequency'); if (allocated(r%error)) return
    do p = 1, r%m
      if (.not. (f(p) > 0.0_dp)) then
        call r%fail('frequencies_hz: frequency ' // itoa(p) // ': expected a positive frequency (Hz), got ' // &
          & r%word(p + 1)); return
      end if
      ! its stiffness (2 pi f)^2 enters the mass matrix's factorisations: 1e150 Hz was read,
      ! and the run failed at t = 0 (exit 2) where LAPACK overflows
      if (.not. (2.0_dp*pi*f(p))**2 <= max_entry) then
        call r%fail('frequencies_hz: frequency ' // itoa(p) // ': ' // r%word(p + 1) // ' Hz is too large (its ' // &
          & 'stiffness (2 pi f)^2 is beyond ' // fmt(max_entry) // ', where LAPACK overflows)'); return
      end if
      ! 1e-300 Hz passed as positive, and its stiffness (2 pi f)^2 was 0: a free mode
      if ((2.0_dp*pi*f(p))**2 < tiny(1.0_dp)) then
        call r%fail('frequencies_hz: frequency ' // itoa(p) // ': ' // r%word(p + 1) // ' Hz is too small (its ' // &
          & '(2 pi f)^2 underflows)'); return
      end if
    end do
  end subroutine read_header

  !> The invariants block: mass, first moments F(3, 0:m), second moments W (upper triangle
  !> of the pairs, the lower one by W(:,:,beta,alpha) = W(:,:,alpha,beta)^T).
  subroutine read_invariants(r, mass, first, w)
    type(modal_reader), intent(inout) :: r
    real(dp), intent(out) :: mass
    real(dp), allocatable, intent(out) :: first(:, :), w(:, :, :, :)
    real(dp) :: v1(1)
    integer :: m
    m = r%m
    call r%key_line('invariants'); if (allocated(r%error)) return
    r%invariants_line = r%line
    if (r%nw /= 1) then
      call r%fail('invariants: nothing may follow it on its line, got ' // r%rest()); return
    end if
    call r%key_line('mass'); if (allocated(r%error)) return
    if (r%nw /= 2) then
      call r%fail('mass: expected a positive mass, got ' // r%rest()); return
    end if
    call r%numbers(2, v1, 'mass', 'mass'); if (allocated(r%error)) return
    mass = v1(1)
    if (.not. (mass > 0.0_dp)) then
      call r%fail('mass: expected a positive mass'); return
    end if
    if (.not. body_mass(mass)) then
      call r%fail('mass: must be in ' // mass_range() // ', got ' // r%word(2)); return
    end if
    ! (m+1)(m+2)/2 lines of 11 numbers: checked before W's 72 (m+1)^2 bytes are allocated
    call check_header_count(r%path, 'line ' // itoa(r%modes_line) // ': modes ' // itoa(m), &
      & int(m + 1, int64)*int(m + 2, int64)/2, 22, 'second_moments lines of 11 numbers', r%error)
    if (allocated(r%error)) return
    allocate(first(3, 0:m), w(3, 3, 0:m, 0:m), r%wline(0:m, 0:m))
    call read_first_moments(r, first); if (allocated(r%error)) return
    call read_second_moments(r, w)
  end subroutine read_invariants

  !> The first moments F(1:3, alpha), alpha = 0..m: a line each after the key.
  subroutine read_first_moments(r, first)
    type(modal_reader), intent(inout) :: r
    real(dp), intent(inout) :: first(:, 0:)
    integer :: al, idx
    real(dp) :: v3(3)
    call r%key_line('first_moments'); if (allocated(r%error)) return
    do al = 0, r%m
      if (.not. r%data_line()) return
      if (.not. r%count_word(idx, 1) .or. idx /= al) then
        call r%fail('first_moments: expected the line of F(1:3, ' // itoa(al) // '), which begins with ' // &
          & itoa(al) // ', got ''' // r%word(1) // ''' first'); return
      end if
      if (r%nw /= 4) then
        call r%fail('first_moments: expected ' // itoa(al) // ' and F(1:3, ' // itoa(al) // '), 4 numbers, got ' // &
          & itoa(r%nw)); return
      end if
      call r%numbers(2, v3, 'first_moments', 'F', al); if (allocated(r%error)) return
      first(:, al) = v3
    end do
  end subroutine read_first_moments

  !> The second moments W(1:3, 1:3, alpha, beta), beta = alpha..m, row by row: a line each
  !> after the key; the line of each pair kept for messages.
  subroutine read_second_moments(r, w)
    type(modal_reader), intent(inout) :: r
    real(dp), intent(inout) :: w(:, :, 0:, 0:)
    integer :: al, be, idx(2)
    real(dp) :: v9(9)
    call r%key_line('second_moments'); if (allocated(r%error)) return
    do al = 0, r%m
      do be = al, r%m
        if (.not. r%data_line()) return
        if (.not. r%count_word(idx(1), 1) .or. .not. r%count_word(idx(2), 2) .or. idx(1) /= al .or. idx(2) /= be) &
          & then
          call r%fail('second_moments: expected the line of W(1:3, 1:3, ' // itoa(al) // ', ' // itoa(be) // &
            & '), which begins with ' // itoa(al) // ' ' // itoa(be) // ', got ''' // &
            & r%ln(r%wa(1):r%wb(min(2, r%nw))) // ''' first'); return
        end if
        if (r%nw /= 11) then
          call r%fail('second_moments: expected ' // itoa(al) // ' ' // itoa(be) // ' and the 9 numbers of W(1:3, ' // &
            & '1:3, ' // itoa(al) // ', ' // itoa(be) // ') row by row, 11 numbers, got ' // itoa(r%nw)); return
        end if
        call r%numbers(3, v9, 'second_moments', 'W', al, be); if (allocated(r%error)) return
        if (al == be) call check_symmetric_block(r, v9, al); if (allocated(r%error)) return
        w(:, :, al, be) = transpose(reshape(v9, [3, 3]))
        w(:, :, be, al) = reshape(v9, [3, 3])
        r%wline(al, be) = r%line; r%wline(be, al) = r%line
      end do
    end do
  end subroutine read_second_moments

  !> W(1:3, 1:3, al, al) (v9 row by row) is int rho Z Z^T of one column: symmetric, to 1e-9
  !> of its largest entry. A file with W(2, 1, 0, 0) alone set ran with exit 0 and another
  !> inertia than any symmetric one.
  subroutine check_symmetric_block(r, v9, al)
    type(modal_reader), intent(inout) :: r
    real(dp), intent(in) :: v9(9)
    integer, intent(in) :: al
    integer :: i, j
    do i = 1, 3
      do j = i + 1, 3
        if (abs(v9(3*(i - 1) + j) - v9(3*(j - 1) + i)) <= 1.0e-9_dp*maxval(abs(v9))) cycle
        call r%fail('second_moments: W(1:3, 1:3, ' // itoa(al) // ', ' // itoa(al) // ') is not symmetric: W(' // &
          & itoa(i) // ', ' // itoa(j) // ') = ' // r%word(2 + 3*(i - 1) + j) // ', W(' // itoa(j) // ', ' // &
          & itoa(i) // ') = ' // r%word(2 + 3*(j - 1) + i) // ' (a column''s second moment with itself is)')
        return
      end do
    end do
  end subroutine check_symmetric_block

  !> The points block: each point's position, mass mp and mode shapes; nothing may follow it.
  subroutine read_points(r, nodes, mp)
    type(modal_reader), intent(inout) :: r
    type(modal_nodes), intent(inout) :: nodes
    real(dp), allocatable, intent(out) :: mp(:)
    real(dp), allocatable :: row(:)
    integer :: np, p, m
    m = r%m
    call r%key_line('points'); if (allocated(r%error)) return
    r%points_line = r%line
    if (.not. r%count_word(np) .or. np < 1) then
      call r%fail('points: expected a positive count, got ' // r%rest()); return
    end if
    call check_header_count(r%path, 'line ' // itoa(r%line) // ': points', int(np, int64), 2*(4 + 6*m), &
      & 'lines of ' // itoa(4 + 6*m) // ' numbers', r%error)
    if (allocated(r%error)) return
    nodes%np = np
    allocate(nodes%x(3, np), nodes%psi(3, m, np), nodes%phi(3, m, np), mp(np), row(4 + 6*m))
    do p = 1, np
      if (.not. r%next_line()) then
        call r%fail('points: ' // itoa(np) // ' points, but the file ends after ' // itoa(p - 1) // ' (line ' // &
          & itoa(r%line) // ')', r%points_line); return
      end if
      if (r%nw /= 4 + 6*m) then
        call r%fail('point ' // itoa(p) // ': expected ' // itoa(4 + 6*m) // ' numbers (x y z mass, then psi and ' // &
          & 'phi of each of the ' // itoa(m) // ' modes), got ' // itoa(r%nw)); return
      end if
      call r%numbers(1, row, 'point ' // itoa(p), 'point'); if (allocated(r%error)) return
      if (row(4) < 0.0_dp) then
        call r%fail('point ' // itoa(p) // ': negative mass'); return
      end if
      if (r%given .and. row(4) /= 0.0_dp) then
        call r%fail('point ' // itoa(p) // ': mass must be 0 (the invariants block gives the body''s inertia)'); return
      end if
      call check_position(r, p, row(1:3)); if (allocated(r%error)) return
      nodes%x(:, p) = row(1:3); mp(p) = row(4)
      nodes%psi(:, :, p) = reshape(row(5:4 + 3*m), [3, m])
      nodes%phi(:, :, p) = reshape(row(5 + 3*m:4 + 6*m), [3, m])
    end do
    if (r%next_line()) call r%fail('more lines than the ' // itoa(np) // ' points of line ' // itoa(r%points_line))
  end subroutine read_points

  !> The body's invariants fd: from the invariants block when given, else from the points'
  !> masses (which must carry the body's mass, and hold at most 3 modes a point).
  subroutine body_invariants(r, nodes, mp, mass, first, w, fd)
    type(modal_reader), intent(inout) :: r
    type(modal_nodes), intent(in) :: nodes
    real(dp), intent(in) :: mp(:), mass
    real(dp), allocatable, intent(in) :: first(:, :), w(:, :, :, :)
    type(flex_data), intent(inout) :: fd
    character(len=:), allocatable :: path
    integer :: m
    if (r%given) then
      call flex_from_moments(mass, first, w, fd)
      call check_moments(r, fd); return
    end if
    path = r%path; m = r%m
    if (.not. (sum(mp) > 0.0_dp)) then
      call fatal_error(r%error, path // ': line ' // itoa(r%points_line) // ': points: the points carry no mass')
      return
    end if
    if (.not. body_mass(sum(mp))) then
      call fatal_error(r%error, path // ': line ' // itoa(r%points_line) // ': points: their masses sum to ' // &
        & fmt(sum(mp)) // ' kg; a body''s mass must be in ' // mass_range()); return
    end if
    ! sum m_p Psi_p^T Psi_p has rank 3 per point at most: more modes cannot be mass-normalised
    ! (and so the second moments W, (m+1)^2 blocks, stay within the file's size)
    if (m > 3*count(mp > 0.0_dp)) then
      call fatal_error(r%error, path // ': line ' // itoa(r%modes_line) // ': modes: ' // itoa(m) // ' modes, but ' &
        & // itoa(count(mp > 0.0_dp)) // trim(merge(' point carries', ' points carry ', count(mp > 0.0_dp) == 1)) // &
        & ' ' // 'mass: at most 3 modes a point can be mass-normalised'); return
    end if
    call flex_invariants(nodes%x, mp, nodes%psi, fd)
    if (.not. (all(ieee_is_finite(fd%w)) .and. all(ieee_is_finite(fd%first)) .and. ieee_is_finite(fd%mass))) then
      call fatal_error(r%error, path // ': line ' // itoa(r%points_line) // ': points: the inertia of the points ' // &
        & 'overflows (a mass or a position too large)')
    end if
  end subroutine body_invariants

  !> Whether `mass` (kg) is a body's: within the bounds of a rigid body's &body mass.
  elemental logical function body_mass(mass)
    real(dp), intent(in) :: mass
    body_mass = mass >= small_mass .and. mass <= big_mass
  end function body_mass

  !> Those bounds, as messages give them: '[1e-12, 1e+12] kg'.
  function mass_range() result(s)
    character(len=:), allocatable :: s
    s = '[' // fmt(small_mass) // ', ' // fmt(big_mass) // '] kg'
  end function mass_range

  !> Point p's position x (m, the body frame) within the scene's bound on lengths.
  subroutine check_position(r, p, x)
    type(modal_reader), intent(inout) :: r
    integer, intent(in) :: p
    real(dp), intent(in) :: x(3)
    integer :: i
    do i = 1, 3
      if (abs(x(i)) <= big_length) cycle
      call r%fail('point ' // itoa(p) // ': ' // 'xyz'(i:i) // ': must be in [' // fmt(-big_length) // ', ' // &
        & fmt(big_length) // '] m, got ' // r%word(i)); return
    end do
  end subroutine check_position

  !> An invariants block must hold the moments of some mass distribution (those of mass
  !> points always do): the undeformed body's mass matrix (its rigid motions and modes,
  !> mass_matrix) positive semi-definite, to what rounding the file's numbers to
  !> normalised_tol moves it. Its rigid block first: the inertia about the centre of mass.
  !> (Not the triangle inequality of that inertia: finite-element models with a torsional
  !> rotary inertia alone break it by design.)
  subroutine check_moments(r, fd)
    type(modal_reader), intent(inout) :: r
    type(flex_data), intent(in) :: fd
    real(dp), allocatable :: mb(:, :)
    real(dp) :: e(3)
    mb = mass_matrix(fd)
    if (.not. semi_definite(mb(1:6, 1:6))) then
      call eig3(central_inertia(fd), e)
      call r%fail('second_moments: W(1:3, 1:3, 0, 0), with F(1:3, 0) and the mass, gives an inertia about the ' // &
        & 'centre of mass with a negative principal moment (' // fmt(minval(e)) // ' kg m^2): no mass ' // &
        & 'distribution has it', r%wline(0, 0)); return
    end if
    if (.not. semi_definite(mb)) call r%fail('invariants: the mass matrix of the body''s rigid motions and ' // &
      & 'modes is not positive semi-definite: no mass distribution has these first and second moments (the ' // &
      & 'first moments F(1:3, 1:) or the second moments W(1:3, 1:3, 0, 1:) too large for the modes'' masses)', &
      & r%invariants_line)
  end subroutine check_moments

  !> The undeformed body's mass matrix in its frame, rows [v; w; modal rates]: the kinetic
  !> energy of the origin's velocity v, the angular velocity w and the modal rates ad.
  function mass_matrix(fd) result(mb)
    type(flex_data), intent(in) :: fd
    real(dp) :: mb(6 + fd%m, 6 + fd%m), s(3), wk(3, 3)
    integer :: i, k
    mb = 0.0_dp
    s = fd%first(:, 0)
    do i = 1, 3
      mb(i, i) = fd%mass
    end do
    mb(1:3, 4:6) = -skew(s)
    mb(4:6, 1:3) = skew(s)
    wk = fd%w(:, :, 0, 0)
    mb(4:6, 4:6) = -wk
    do i = 1, 3
      mb(3 + i, 3 + i) = mb(3 + i, 3 + i) + wk(1, 1) + wk(2, 2) + wk(3, 3)
    end do
    do k = 1, fd%m
      wk = fd%w(:, :, 0, k)
      mb(1:3, 6 + k) = fd%first(:, k)
      mb(4:6, 6 + k) = [wk(2, 3) - wk(3, 2), wk(3, 1) - wk(1, 3), wk(1, 2) - wk(2, 1)]
      mb(6 + k, 1:6) = mb(1:6, 6 + k)
    end do
    mb(7:, 7:) = fd%mmm
  end function mass_matrix

  !> Whether the symmetric a is positive semi-definite to normalised_tol per entry of its
  !> form scaled to a unit diagonal: that form plus n normalised_tol I (the most such
  !> entries' errors move its eigenvalues, Gershgorin) has a Cholesky factor. A zero
  !> diagonal keeps its row as it is.
  logical function semi_definite(a)
    real(dp), intent(in) :: a(:, :)
    real(dp) :: b(size(a, 1), size(a, 1)), d(size(a, 1))
    type(error_type), allocatable :: error
    integer :: i, n
    n = size(a, 1)
    d = 1.0_dp
    where (diag(a) > 0.0_dp) d = 1.0_dp/sqrt(diag(a))
    b = a*spread(d, 1, n)*spread(d, 2, n)
    do i = 1, n
      b(i, i) = b(i, i) + n*normalised_tol
    end do
    call potrf(b, 'the scaled mass matrix', error)
    semi_definite = .not. allocated(error)
  end function semi_definite

  pure function diag(a) result(d)
    real(dp), intent(in) :: a(:, :)
    real(dp) :: d(size(a, 1))
    integer :: i
    do i = 1, size(a, 1)
      d(i) = a(i, i)
    end do
  end function diag

  !> The modal mass matrix (the traces of W's modal blocks: sum m_p Psi_p^T Psi_p over the
  !> points, or from the invariants block) must be the identity to normalised_tol.
  subroutine check_normalised(r, fd)
    type(modal_reader), intent(inout) :: r
    type(flex_data), intent(in) :: fd
    integer :: i, j, wi, wj
    real(dp) :: d, worst
    worst = -1.0_dp; wi = 0; wj = 0
    do j = 1, r%m
      do i = 1, j
        d = abs(fd%mmm(i, j) - merge(1.0_dp, 0.0_dp, i == j))
        if (.not. (d <= worst)) then
          worst = d; wi = i; wj = j
        end if
      end do
    end do
    if (wi == 0 .or. worst <= normalised_tol) return
    if (r%given) then
      call fatal_error(r%error, r%path // ': line ' // itoa(r%wline(wi, wj)) // ': second_moments: the modes are ' // &
        & 'not mass-normalised: W11+W22+W33 of modes ' // itoa(wi) // ' and ' // itoa(wj) // ' is ' // &
        & fmt(fd%mmm(wi, wj)) // ', expected ' // merge('1', '0', wi == wj) // ' (to ' // fmt(normalised_tol) // ')')
    else
      call fatal_error(r%error, r%path // ': line ' // itoa(r%points_line) // ': points: the modes are not ' // &
        & 'mass-normalised: the sum of mass psi_' // itoa(wi) // '.psi_' // itoa(wj) // ' over the points is ' // &
        & fmt(fd%mmm(wi, wj)) // ', expected ' // merge('1', '0', wi == wj) // ' (to ' // fmt(normalised_tol) // ')')
    end if
  end subroutine check_normalised

  !> Words k0.. of the current line read as the numbers v (their count checked by the
  !> caller): each by the kernel's number rule (number_text), and finite; `what` names the
  !> line's item, `kind` the entry ('point', 'frequency', 'mass', 'F', 'W', with al, be).
  subroutine reader_numbers(r, k0, v, what, kind, al, be)
    class(modal_reader), intent(inout) :: r
    integer, intent(in) :: k0
    real(dp), intent(out) :: v(:)
    character(len=*), intent(in) :: what, kind
    integer, intent(in), optional :: al, be
    integer :: k, a, b
    logical :: ok
    character(len=:), allocatable :: entry
    a = 0; b = 0
    if (present(al)) a = al
    if (present(be)) b = be
    do k = 1, size(v)
      entry = what
      if (entry_name(kind, k, r%m, a, b) /= what) entry = what // ': ' // entry_name(kind, k, r%m, a, b)
      call number_text(r%word(k0 + k - 1), v(k), ok)
      if (.not. ok) then
        call r%fail(entry // ': ''' // r%word(k0 + k - 1) // ''' is not a number'); return
      end if
      if (.not. ieee_is_finite(v(k))) then
        call r%fail(entry // ': ' // r%word(k0 + k - 1) // ' is not a finite number'); return
      end if
      if (len(below_normal(v(k), r%word(k0 + k - 1))) > 0) then
        call r%fail(entry // ': the value ' // r%word(k0 + k - 1) // ' ' // below_normal(v(k), r%word(k0 + k - 1)))
        return
      end if
    end do
  end subroutine reader_numbers

  !> Word k of the current line.
  function reader_word(r, k) result(s)
    class(modal_reader), intent(in) :: r
    integer, intent(in) :: k
    character(len=:), allocatable :: s
    s = r%ln(r%wa(k):r%wb(k))
  end function reader_word

  !> The current line after its first word, quoted (for messages), or 'nothing'.
  function reader_rest(r) result(s)
    class(modal_reader), intent(in) :: r
    character(len=:), allocatable :: s
    if (r%nw < 2) then
      s = 'nothing'
    else
      s = '''' // r%ln(r%wa(2):r%wb(r%nw)) // ''''
    end if
  end function reader_rest

  !> Word `at` of the current line as a count; without `at`, word 2, the only word after
  !> the key.
  logical function reader_count_word(r, k, at)
    class(modal_reader), intent(in) :: r
    integer, intent(out) :: k
    integer, intent(in), optional :: at
    integer :: i
    logical :: ok
    i = 2
    if (present(at)) i = at
    k = 0
    ok = r%nw >= i
    if (.not. present(at)) ok = r%nw == 2
    if (ok) call count_text(r%word(i), k, ok)
    reader_count_word = ok
  end function reader_count_word

  !> The next line that is not blank and not a comment: ln, its words, its number `line`;
  !> false at the end of the file.
  logical function reader_next_line(r)
    class(modal_reader), intent(inout) :: r
    reader_next_line = .false.
    do while (next_text_line(r%text, r%pos, r%ln))
      r%line = r%line + 1
      call split_words(r%ln, r%wa, r%wb, r%nw)
      if (r%nw == 0) cycle
      if (r%ln(r%wa(1):r%wa(1)) == '#') cycle
      reader_next_line = .true.
      return
    end do
  end function reader_next_line

  !> next_line, with an error at the end of the file.
  logical function reader_data_line(r)
    class(modal_reader), intent(inout) :: r
    reader_data_line = r%next_line()
    if (.not. reader_data_line) call fatal_error(r%error, r%path // ': unexpected end of file after line ' // &
      & itoa(r%line))
  end function reader_data_line

  !> The next line, which must start with `expect`.
  subroutine reader_key_line(r, expect)
    class(modal_reader), intent(inout) :: r
    character(len=*), intent(in) :: expect
    if (.not. r%data_line()) return
    if (r%word(1) /= expect) call r%fail('expected ''' // expect // '''')
  end subroutine reader_key_line

  !> Does the next data line start with `expect`? (Where the reading is stays unchanged.)
  logical function reader_next_is(r, expect)
    class(modal_reader), intent(inout) :: r
    character(len=*), intent(in) :: expect
    integer :: pos0, line0
    pos0 = r%pos; line0 = r%line
    reader_next_is = r%next_line()
    if (reader_next_is) reader_next_is = r%word(1) == expect
    r%pos = pos0; r%line = line0
  end function reader_next_is

  !> The error 'PATH: line L: WHY' (L the current line, or `at`).
  subroutine reader_fail(r, why, at)
    class(modal_reader), intent(inout) :: r
    character(len=*), intent(in) :: why
    integer, intent(in), optional :: at
    integer :: l
    l = r%line
    if (present(at)) l = at
    call fatal_error(r%error, r%path // ': line ' // itoa(l) // ': ' // excerpt(why, max_shown))
  end subroutine reader_fail

  !> Entry k of a modal file's line of `kind` ('point', 'frequency', 'F', 'W' of the modes
  !> al, be; else the kind itself) for messages: 'x', 'mass', 'psi_y of mode 2', 'W(1, 3, 0, 2)'.
  pure function entry_name(kind, k, m, al, be) result(s)
    character(len=*), intent(in) :: kind
    integer, intent(in) :: k, m, al, be
    character(len=:), allocatable :: s
    character(len=3), parameter :: xyz = 'xyz'
    integer :: j
    select case (kind)
    case ('point')
      if (k <= 3) then
        s = xyz(k:k)
      else if (k == 4) then
        s = 'mass'
      else
        j = k - 5
        s = merge('psi_', 'phi_', j < 3*m) // xyz(mod(j, 3) + 1:mod(j, 3) + 1) // ' of mode ' // &
          & itoa(mod(j, 3*m)/3 + 1)
      end if
    case ('frequency')
      s = 'frequency ' // itoa(k)
    case ('F')
      s = 'F(' // itoa(k) // ', ' // itoa(al) // ')'
    case ('W')
      s = 'W(' // itoa((k - 1)/3 + 1) // ', ' // itoa(mod(k - 1, 3) + 1) // ', ' // itoa(al) // ', ' // itoa(be) // ')'
    case default
      s = kind
    end select
  end function entry_name

  !> Write a built-in beam as a modal file: its Gauss mass points and its nodes (mass 0).
  !> The file is written whole or not at all (write_text_file), so an earlier one survives
  !> a failed write.
  subroutine write_modal_file(path, title, fd, bs, error)
    character(len=*), intent(in) :: path, title
    type(flex_data), intent(in) :: fd
    type(beam_shape), intent(in) :: bs
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: text
    integer :: p, i
    real(dp) :: psi(3, fd%m), phi(3, fd%m), x(3)
    text = '# ' // trim(title) // new_line('a') // &
      & '# points: x y z mass, psi(1:3) of each mode, phi(1:3) of each mode (body frame, SI)' // new_line('a') // &
      & 'pymr-modal 1' // new_line('a') // 'modes ' // itoa(fd%m) // new_line('a') // &
      & 'frequencies_hz' // values_line(sqrt(fd%omega2)/(2.0_dp*pi), ' ') // &
      & 'points ' // itoa(size(fd%pm) + bs%ne + 1) // new_line('a')
    do p = 1, size(fd%pm)
      call beam_point_shapes(bs, fd%ps(:, p), psi, phi)
      text = text // values_line([fd%ps(:, p), fd%pm(p), reshape(fd%ppsi(:, :, p), [3*fd%m]), &
        & reshape(phi, [3*fd%m])], '')
    end do
    do i = 0, bs%ne
      x = [bs%length*i/bs%ne, 0.0_dp, 0.0_dp]
      call beam_point_shapes(bs, x, psi, phi)
      text = text // values_line([x, 0.0_dp, reshape(psi, [3*fd%m]), reshape(phi, [3*fd%m])], '')
    end do
    call write_text_file(path, text, error)
  end subroutine write_modal_file

  !> `v` as one line of numbers (es24.16e3, one blank between), after `lead`.
  function values_line(v, lead) result(line)
    real(dp), intent(in) :: v(:)
    character(len=*), intent(in) :: lead
    character(len=:), allocatable :: line
    character(len=25*size(v) + 1) :: buf
    ! below the smallest normal number as 0: the reader refuses such a value as written
    write(buf, '(*(es24.16e3,:,1x))') merge(v, 0.0_dp, abs(v) >= tiny(v))
    line = lead // trim(buf) // new_line('a')
  end function values_line
end module pymr_io_modal_file
