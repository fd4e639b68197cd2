!> A light scan of a namelist file's text: where each group starts, which items it
!> names and on which line. It lets the reader report unknown groups and unknown items
!> by name and line before gfortran's namelist read sees them.
module pymr_io_namelist_scan
  use pymr_kinds, only : dp, name_len
  use pymr_error, only : error_type, fatal_error
  implicit none
  private
  public :: group_scan, scan_file, scan_text, check_items, itoa, lower, fmt

  !> One group occurrence in the file.
  type :: group_scan
    !> Group name in lower case, without '&'.
    character(len=name_len) :: name = ''
    !> Line of the '&' and running number of this group name (1 = first &body).
    integer :: line = 0, index = 0
    !> Item names (lower case), the line of each, and the text of its value.
    character(len=name_len), allocatable :: items(:)
    integer, allocatable :: item_lines(:)
    character(len=256), allocatable :: values(:)
  end type group_scan

contains

  !> Read a whole file and scan it; errors for a missing or unreadable file.
  subroutine scan_file(file, groups, error)
    character(len=*), intent(in) :: file
    type(group_scan), allocatable, intent(out) :: groups(:)
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: text
    integer :: u, ios, sz
    character(len=256) :: msg
    logical :: exists
    inquire(file=file, exist=exists)
    if (.not. exists) then
      call fatal_error(error, file // ': file not found'); return
    end if
    open(newunit=u, file=file, access='stream', form='unformatted', status='old', action='read', &
      & iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, file // ': cannot open: ' // trim(msg)); return
    end if
    inquire(unit=u, size=sz)
    allocate(character(len=max(sz, 0)) :: text)
    if (sz > 0) read(u, iostat=ios, iomsg=msg) text
    close(u)
    if (ios /= 0) then
      call fatal_error(error, file // ': cannot read: ' // trim(msg)); return
    end if
    call scan_text(text, groups)
  end subroutine scan_file

  !> Scan namelist text: groups start with '&name' and end with '/' outside quotes;
  !> an item is the identifier before an '=' (a subscript such as com(2) is allowed).
  subroutine scan_text(text, groups)
    character(len=*), intent(in) :: text
    type(group_scan), allocatable, intent(out) :: groups(:)
    integer :: i, n, line, j, k
    character(len=1) :: c, quote
    logical :: in_group
    type(group_scan) :: g
    integer, allocatable :: vstart(:), istart(:)
    allocate(groups(0))
    line = 1; i = 1; n = len(text); in_group = .false.; quote = ' '
    do while (i <= n)
      c = text(i:i)
      if (quote /= ' ') then
        if (c == quote) quote = ' '
        if (c == achar(10)) line = line + 1
        i = i + 1; cycle
      end if
      select case (c)
      case (achar(10))
        line = line + 1
      case ('!')
        do while (i < n .and. text(min(i+1, n):min(i+1, n)) /= achar(10))
          i = i + 1
        end do
      case ("'", '"')
        if (in_group) quote = c
      case ('&', '$')
        if (.not. in_group) then
          j = i + 1
          do while (j <= n .and. is_ident(text(j:j)))
            j = j + 1
          end do
          if (j > i + 1) then
            g%name = lower(text(i+1:j-1)); g%line = line; g%index = 0
            if (allocated(g%items)) deallocate(g%items, g%item_lines)
            allocate(g%items(0), g%item_lines(0))
            vstart = [integer ::]; istart = [integer ::]
            in_group = .true.; i = j; cycle
          end if
        else if (c == '&' .or. c == '$') then
          ! '&end' or '$end' closes a group in the old style
          j = i + 1
          do while (j <= n .and. is_ident(text(j:j)))
            j = j + 1
          end do
          if (lower(text(i+1:max(i+1, j-1))) == 'end') then
            call close_group(i); i = j; cycle
          end if
        end if
      case ('/')
        if (in_group) call close_group(i)
      case ('=')
        if (in_group) then
          k = i - 1
          do while (k >= 1 .and. text(k:k) == ' ')
            k = k - 1
          end do
          if (k >= 1 .and. text(k:k) == ')') then
            do while (k >= 1 .and. text(k:k) /= '(')
              k = k - 1
            end do
            k = k - 1
          end if
          j = k
          do while (j >= 1 .and. is_ident(text(max(j, 1):max(j, 1))))
            j = j - 1
          end do
          if (k > j) then
            g%items = [character(len=name_len) :: g%items, lower(text(j+1:k))]
            g%item_lines = [g%item_lines, line]
            vstart = [vstart, i + 1]; istart = [istart, j + 1]
          end if
        end if
      end select
      i = i + 1
    end do
    if (in_group) call close_group(n + 1)
    do i = 1, size(groups)
      groups(i)%index = count(groups(1:i)%name == groups(i)%name)
    end do
  contains
    !> Close the group at position iend; each item's value runs to the next item.
    subroutine close_group(iend)
      integer, intent(in) :: iend
      integer :: m, e
      allocate(g%values(size(g%items)))
      do m = 1, size(g%items)
        e = iend - 1
        if (m < size(g%items)) e = istart(m + 1) - 1
        g%values(m) = adjustl(text(vstart(m):max(e, vstart(m) - 1)))
        do while (len_trim(g%values(m)) > 0)
          e = len_trim(g%values(m))
          if (g%values(m)(e:e) /= ',' .and. g%values(m)(e:e) /= achar(10) .and. g%values(m)(e:e) /= achar(13)) exit
          g%values(m)(e:e) = ' '
        end do
      end do
      groups = [groups, g]
      deallocate(g%values)
      in_group = .false.
    end subroutine close_group
  end subroutine scan_text

  !> Error if a group names an item that is not in `known`.
  subroutine check_items(where, g, known, error)
    !> Prefix for messages (file name).
    character(len=*), intent(in) :: where
    type(group_scan), intent(in) :: g
    character(len=*), intent(in) :: known(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: i, j
    character(len=:), allocatable :: list
    do i = 1, size(g%items)
      if (any(known == g%items(i))) cycle
      list = trim(known(1))
      do j = 2, size(known)
        list = list // ', ' // trim(known(j))
      end do
      call fatal_error(error, where // ': &' // trim(g%name) // ' #' // itoa(g%index) // ' (line ' // &
        & itoa(g%item_lines(i)) // '): unknown item ''' // trim(g%items(i)) // ''' (known: ' // list // ')')
      return
    end do
  end subroutine check_items

  pure logical function is_ident(c)
    character(len=1), intent(in) :: c
    is_ident = (c >= 'a' .and. c <= 'z') .or. (c >= 'A' .and. c <= 'Z') .or. (c >= '0' .and. c <= '9') &
      & .or. c == '_'
  end function is_ident

  !> Integer to text without blanks.
  pure function itoa(i) result(s)
    integer, intent(in) :: i
    character(len=:), allocatable :: s
    character(len=24) :: buf
    write(buf, '(i0)') i
    s = trim(buf)
  end function itoa

  !> Lower-case copy of a string.
  pure function lower(s) result(r)
    character(len=*), intent(in) :: s
    character(len=len(s)) :: r
    integer :: i, c
    r = s
    do i = 1, len(s)
      c = iachar(s(i:i))
      if (c >= iachar('A') .and. c <= iachar('Z')) r(i:i) = achar(c + 32)
    end do
  end function lower

  !> A real for messages as a person writes it, at most 6 significant digits: 0.01, 2.5,
  !> 150000, 1.5e+8, -3e-7 (never a compiler's own form such as 0.100000E-1).
  function fmt(x) result(s)
    real(dp), intent(in) :: x
    character(len=:), allocatable :: s
    character(len=40) :: buf, form
    integer :: e, p
    if (x /= x) then
      s = 'NaN'; return
    else if (abs(x) > huge(x)) then
      s = merge('-Inf', 'Inf ', x < 0.0_dp); s = trim(s); return
    else if (x == 0.0_dp) then
      s = '0'; return
    end if
    write(buf, '(es14.5e3)') x
    p = index(buf, 'E')
    read(buf(p+1:), *) e
    if (e >= -4 .and. e < 6) then
      write(form, '(a,i0,a)') '(f0.', max(0, 5 - e), ')'
      write(buf, form) x
      s = strip_zeros(trim(adjustl(buf)))
      if (s(1:1) == '.') s = '0' // s
      if (s(1:min(2, len(s))) == '-.') s = '-0' // s(2:)
    else
      s = strip_zeros(trim(adjustl(buf(:p-1)))) // 'e' // merge('-', '+', e < 0) // itoa(abs(e))
    end if
  end function fmt

  !> A decimal number's text without trailing zeros after its point (and without the point).
  pure function strip_zeros(t) result(s)
    character(len=*), intent(in) :: t
    character(len=:), allocatable :: s
    integer :: n
    s = t
    if (index(s, '.') == 0) return
    n = len(s)
    do while (s(n:n) == '0')
      n = n - 1
    end do
    if (s(n:n) == '.') n = n - 1
    s = s(:n)
  end function strip_zeros
end module pymr_io_namelist_scan
