!> Time-history files for tabulated drives and motions: two numbers per line, the time (s)
!> and the value, separated by blanks or a comma; lines starting with '#' and blank lines
!> are skipped. Times must increase strictly.
module pymr_io_table_file
  use pymr_kinds, only : dp
  use pymr_error, only : error_type, fatal_error
  use pymr_io_text, only : itoa, fmt
  use pymr_io_text_file, only : not_regular
  implicit none
  private
  public :: read_time_table

contains

  !> Read the table at `path` into t and y. `what` starts every error message (the scene
  !> file, group and item that named the file).
  subroutine read_time_table(path, what, t, y, error)
    character(len=*), intent(in) :: path, what
    real(dp), allocatable, intent(out) :: t(:), y(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios, line, n, k
    character(len=1024) :: text
    character(len=256) :: msg
    real(dp) :: row(2)
    real(dp), allocatable :: tt(:), yy(:)
    logical :: exists
    inquire(file=path, exist=exists)
    if (.not. exists) then
      call fatal_error(error, what // ": '" // path // "' not found"); return
    end if
    if (len(not_regular(path)) > 0) then
      call fatal_error(error, what // ": '" // path // "' cannot be read: " // not_regular(path)); return
    end if
    open(newunit=u, file=path, status='old', action='read', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, what // ": '" // path // "' cannot be read: " // trim(msg)); return
    end if
    allocate(tt(64), yy(64))
    n = 0; line = 0
    do
      read(u, '(a)', iostat=ios) text
      if (ios /= 0) exit
      line = line + 1
      text = adjustl(text)
      if (len_trim(text) == 0 .or. text(1:1) == '#') cycle
      do k = 1, len_trim(text)
        if (text(k:k) == ',') text(k:k) = ' '
      end do
      read(text, *, iostat=ios) row
      if (ios /= 0 .or. any(row /= row) .or. any(abs(row) > huge(1.0_dp))) then
        call fail('expected two finite numbers (time, value), got: ' // trim(text)); return
      end if
      if (n > 0) then
        if (.not. (row(1) > tt(n))) then
          call fail('times must increase, but t = ' // fmt(row(1)) // ' follows t = ' // fmt(tt(n))); return
        end if
      end if
      if (n == size(tt)) then
        tt = [tt, tt]; yy = [yy, yy]
      end if
      n = n + 1
      tt(n) = row(1); yy(n) = row(2)
    end do
    close(u)
    if (n < 2) then
      call fatal_error(error, what // ": '" // path // "' has " // itoa(n) // ' rows; a table needs at least 2')
      return
    end if
    t = tt(1:n); y = yy(1:n)
  contains
    subroutine fail(why)
      character(len=*), intent(in) :: why
      close(u)
      call fatal_error(error, what // ": '" // path // "' line " // itoa(line) // ': ' // why)
    end subroutine fail
  end subroutine read_time_table
end module pymr_io_table_file
