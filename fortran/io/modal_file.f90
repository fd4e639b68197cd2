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
  use pymr_kinds, only : dp, pi
  use pymr_error, only : error_type, fatal_error
  use pymr_model_flexbody, only : flex_data, flex_invariants, flex_from_moments, modal_nodes
  use pymr_model_beam_modes, only : beam_shape, beam_point_shapes
  use pymr_io_text, only : itoa
  use pymr_io_text_file, only : not_regular, write_text_file
  implicit none
  private
  public :: read_modal_file, write_modal_file

contains

  !> Read a modal file into invariants (fd) and nodes.
  subroutine read_modal_file(path, fd, nodes, error)
    character(len=*), intent(in) :: path
    type(flex_data), intent(out) :: fd
    type(modal_nodes), intent(out) :: nodes
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios, m, np, p, line, version
    character(len=256) :: msg
    character(len=64) :: key
    real(dp), allocatable :: f(:), row(:), mp(:), first(:, :), w(:, :, :, :)
    real(dp) :: mass
    logical :: exists, given
    inquire(file=path, exist=exists)
    if (.not. exists) then
      call fatal_error(error, path // ': modal file not found'); return
    end if
    if (len(not_regular(path)) > 0) then
      call fatal_error(error, path // ': cannot open: ' // not_regular(path)); return
    end if
    open(newunit=u, file=path, status='old', action='read', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot open: ' // trim(msg)); return
    end if
    line = 0
    call next_key('pymr-modal'); if (allocated(error)) goto 90
    backspace(u); read(u, *, iostat=ios) key, version
    if (ios /= 0 .or. version < 1 .or. version > 2) then
      call fatal_error(error, path // ': line ' // itoa(line) // ': pymr-modal: expected the format version 1 or 2')
      goto 90
    end if
    call next_key('modes'); if (allocated(error)) goto 90
    backspace(u); read(u, *, iostat=ios, iomsg=msg) key, m
    if (ios /= 0 .or. m < 0) then
      call fatal_error(error, path // ': line ' // itoa(line) // ': modes: expected a count'); goto 90
    end if
    allocate(f(m))
    call next_key('frequencies_hz'); if (allocated(error)) goto 90
    backspace(u); read(u, *, iostat=ios, iomsg=msg) key, f
    if (ios /= 0 .or. any(f <= 0.0_dp)) then
      call fatal_error(error, path // ': line ' // itoa(line) // ': frequencies_hz: expected ' // itoa(m) // &
        & ' positive frequencies'); goto 90
    end if
    call skip_comments(); if (allocated(error)) goto 90
    read(u, *, iostat=ios) key
    backspace(u); line = line - 1
    given = ios == 0 .and. key == 'invariants'
    if (given) then
      if (version < 2) then
        call fatal_error(error, path // ': line ' // itoa(line + 1) // ': invariants: needs pymr-modal 2'); goto 90
      end if
      call read_invariants(); if (allocated(error)) goto 90
    end if
    call next_key('points'); if (allocated(error)) goto 90
    backspace(u); read(u, *, iostat=ios, iomsg=msg) key, np
    if (ios /= 0 .or. np < 1) then
      call fatal_error(error, path // ': line ' // itoa(line) // ': points: expected a positive count'); goto 90
    end if
    nodes%np = np
    allocate(nodes%x(3, np), nodes%psi(3, m, np), nodes%phi(3, m, np), mp(np), row(4 + 6*m))
    do p = 1, np
      call skip_comments(); if (allocated(error)) goto 90
      read(u, *, iostat=ios, iomsg=msg) row
      if (ios /= 0) then
        call fatal_error(error, path // ': line ' // itoa(line) // ': point ' // itoa(p) // ': expected ' // &
          & itoa(4 + 6*m) // ' numbers (x y z mass, then psi and phi of each mode)'); goto 90
      end if
      if (row(4) < 0.0_dp) then
        call fatal_error(error, path // ': line ' // itoa(line) // ': point ' // itoa(p) // ': negative mass')
        goto 90
      end if
      if (given .and. row(4) /= 0.0_dp) then
        call fatal_error(error, path // ': line ' // itoa(line) // ': point ' // itoa(p) // &
          & ': mass must be 0 (the invariants block gives the body''s inertia)'); goto 90
      end if
      nodes%x(:, p) = row(1:3); mp(p) = row(4)
      nodes%psi(:, :, p) = reshape(row(5:4 + 3*m), [3, m])
      nodes%phi(:, :, p) = reshape(row(5 + 3*m:4 + 6*m), [3, m])
    end do
    if (given) then
      call flex_from_moments(mass, first, w, fd)
    else
      if (.not. (sum(mp) > 0.0_dp)) then
        call fatal_error(error, path // ': the points carry no mass'); goto 90
      end if
      call flex_invariants(nodes%x, mp, nodes%psi, fd)
    end if
    fd%omega2 = (2.0_dp*pi*f)**2
90  close(u)
  contains
    !> The invariants block: mass, first moments F(3, 0:m), second moments W (upper triangle
    !> of the pairs, the lower one by W(:,:,beta,alpha) = W(:,:,alpha,beta)^T).
    subroutine read_invariants()
      integer :: al, be, idx(2)
      real(dp) :: v3(3), v9(9)
      call next_key('invariants'); if (allocated(error)) return
      call next_key('mass'); if (allocated(error)) return
      backspace(u); read(u, *, iostat=ios) key, mass
      if (ios /= 0 .or. .not. (mass > 0.0_dp)) then
        call fatal_error(error, path // ': line ' // itoa(line) // ': mass: expected a positive mass'); return
      end if
      allocate(first(3, 0:m), w(3, 3, 0:m, 0:m))
      call next_key('first_moments'); if (allocated(error)) return
      do al = 0, m
        call skip_comments(); if (allocated(error)) return
        read(u, *, iostat=ios) idx(1), v3
        if (ios /= 0 .or. idx(1) /= al) then
          call fatal_error(error, path // ': line ' // itoa(line) // ': first_moments: expected ' // itoa(al) // &
            & ' and F(1:3, ' // itoa(al) // ')'); return
        end if
        first(:, al) = v3
      end do
      call next_key('second_moments'); if (allocated(error)) return
      do al = 0, m
        do be = al, m
          call skip_comments(); if (allocated(error)) return
          read(u, *, iostat=ios) idx, v9
          if (ios /= 0 .or. idx(1) /= al .or. idx(2) /= be) then
            call fatal_error(error, path // ': line ' // itoa(line) // ': second_moments: expected ' // itoa(al) // &
              & ' ' // itoa(be) // ' and the 9 numbers of W(1:3, 1:3, ' // itoa(al) // ', ' // itoa(be) // &
              & ') row by row'); return
          end if
          w(:, :, al, be) = transpose(reshape(v9, [3, 3]))
          w(:, :, be, al) = reshape(v9, [3, 3])
        end do
      end do
    end subroutine read_invariants
    subroutine skip_comments()
      character(len=1024) :: buf
      do
        read(u, '(a)', iostat=ios) buf
        line = line + 1
        if (ios /= 0) then
          call fatal_error(error, path // ': unexpected end of file after line ' // itoa(line - 1)); return
        end if
        if (len_trim(buf) == 0) cycle
        if (buf(verify(buf, ' '):verify(buf, ' ')) == '#') cycle
        backspace(u); line = line - 1
        exit
      end do
      line = line + 1
    end subroutine skip_comments
    subroutine next_key(expect)
      character(len=*), intent(in) :: expect
      character(len=64) :: word
      call skip_comments(); if (allocated(error)) return
      read(u, *, iostat=ios) word
      if (ios /= 0 .or. trim(word) /= expect) then
        call fatal_error(error, path // ': line ' // itoa(line) // ": expected '" // expect // "'")
      end if
    end subroutine next_key
  end subroutine read_modal_file

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
    write(buf, '(*(es24.16e3,:,1x))') v
    line = lead // trim(buf) // new_line('a')
  end function values_line
end module pymr_io_modal_file
