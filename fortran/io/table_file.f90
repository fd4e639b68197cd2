!> Time-history files for tabulated drives and motions: two numbers per line, the time (s)
!> and the value, separated by blanks or a comma; lines starting with '#' and blank lines
!> are skipped. Times must increase strictly, and the values rise by at most 1e150 per
!> unit of time (rates beyond overflow LAPACK). A line of any other count of numbers (a
!> third column: a file written for something else) is refused, not cut to two. A spring's
!> force-deflection table is read the same way, its first column the deflection.
module pymr_io_table_file
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_env_text, only : itoa, fmt, number_text, split_words, next_text_line, below_normal, excerpt, max_shown
  use pymr_env_text_file, only : not_regular, read_text_file
  use pymr_env_lapack, only : max_entry
  implicit none
  private
  public :: read_time_table

contains

  !> Read the table at `path` into t and y. `what` starts every error message (the scene
  !> file, group and item that named the file). `limits` are the largest magnitudes of the
  !> two columns (those of the items the table stands in for). `columns` names the two
  !> columns in the messages (default 'time, value'), the first of them the one that must
  !> increase.
  subroutine read_time_table(path, what, limits, t, y, error, columns)
    character(len=*), intent(in) :: path, what
    real(dp), intent(in) :: limits(2)
    character(len=*), intent(in), optional :: columns
    real(dp), allocatable, intent(out) :: t(:), y(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: pos, line, n, nw, k
    integer, allocatable :: wa(:), wb(:)
    character(len=:), allocatable :: text, ln, why
    real(dp) :: row(2)
    real(dp), allocatable :: tt(:), yy(:)
    logical :: exists
    character(len=:), allocatable :: cols, first, first_symbol
    cols = 'time, value'
    if (present(columns)) cols = columns
    first = cols(1:index(cols, ',') - 1)
    first_symbol = first
    if (first == 'time') first_symbol = 't'
    if (len(not_regular(path)) > 0) then
      call fatal_error(error, what // ": '" // path // "' cannot be read: " // not_regular(path)); return
    end if
    inquire(file=path, exist=exists)
    if (.not. exists) then
      call fatal_error(error, what // ": '" // path // "' not found"); return
    end if
    call read_text_file(path, text, error)
    if (allocated(error)) then
      error%message = what // ': ' // error%message; return
    end if
    allocate(tt(64), yy(64))
    n = 0; line = 0; pos = 1
    do while (next_text_line(text, pos, ln))
      line = line + 1
      call split_words(ln, wa, wb, nw)
      if (nw > 0) then
        if (ln(wa(1):wa(1)) == '#') cycle
      end if
      if (empty_value(ln, wa, wb, nw)) then
        call fail('a comma with no value beside it (an empty value): ' // trim(adjustl(ln))); return
      end if
      if (nw == 0) cycle
      ln = ln(wa(1):wb(nw))
      if (nw /= 2) then
        call fail('expected two finite numbers (' // cols // '), got ' // itoa(nw) // ': ' // ln); return
      end if
      do k = 1, 2
        why = value_fault(ln(wa(k) - wa(1) + 1:wb(k) - wa(1) + 1), column_name(cols, k), limits(k), row(k))
        if (why == 'not a number') why = 'expected two finite numbers (' // cols // '), got: ' // ln
        if (len(why) > 0) then
          call fail(why); return
        end if
      end do
      if (n > 0) then
        why = step_fault(row, [tt(n), yy(n)], first, first_symbol)
        if (len(why) > 0) then
          call fail(why); return
        end if
      end if
      if (n == size(tt)) then
        tt = [tt, tt]; yy = [yy, yy]
      end if
      n = n + 1
      tt(n) = row(1); yy(n) = row(2)
    end do
    if (n < 2) then
      call fatal_error(error, what // ": '" // path // "' has " // itoa(n) // ' rows; a table needs at least 2')
      return
    end if
    t = tt(1:n); y = yy(1:n)
  contains

    subroutine fail(why)
      character(len=*), intent(in) :: why
      call fatal_error(error, what // ": '" // path // "' line " // itoa(line) // ': ' // excerpt(why, max_shown))
    end subroutine fail
  end subroutine read_time_table

  !> What is wrong with a row after the row `before` (''): its first column must increase
  !> (named `first`, `symbol` in the message), and the value rise by at most max_entry per
  !> unit of it (rows 1e-300 s apart gave a setpoint rate of 1e300, and a step-size
  !> underflow at t = 0).
  function step_fault(row, before, first, symbol) result(why)
    real(dp), intent(in) :: row(2), before(2)
    character(len=*), intent(in) :: first, symbol
    character(len=:), allocatable :: why
    why = ''
    if (.not. (row(1) > before(1))) then
      why = first // 's must increase, but ' // symbol // ' = ' // fmt(row(1)) // ' follows ' // symbol // ' = ' // &
        & fmt(before(1))
    else if (.not. abs(row(2) - before(2)) <= max_entry*(row(1) - before(1))) then
      why = 'the table rises by ' // fmt(row(2) - before(2)) // ' over ' // fmt(row(1) - before(1)) // ' from ' // &
        & 'the row before: a slope beyond ' // fmt(max_entry) // ', where LAPACK overflows; give rows farther apart'
    end if
  end function step_fault

  !> Is a comma of line `ln` (words wa(k):wb(k), k = 1..nw) not between two values: before
  !> the first, after the last, or a second one between two?
  pure logical function empty_value(ln, wa, wb, nw)
    character(len=*), intent(in) :: ln
    integer, intent(in) :: wa(:), wb(:), nw
    integer :: k, j
    if (nw == 0) then
      empty_value = index(ln, ',') > 0; return
    end if
    empty_value = index(ln(1:wa(1) - 1), ',') > 0 .or. index(ln(wb(nw) + 1:), ',') > 0
    do k = 1, nw - 1
      empty_value = empty_value .or. count([(ln(j:j) == ',', j = wb(k) + 1, wa(k + 1) - 1)]) > 1
    end do
  end function empty_value

  !> The value of `word`, in column `name` of at most `limit` in magnitude: '' and x if it
  !> is one, else what is wrong ('not a number' for no finite number).
  function value_fault(word, name, limit, x) result(why)
    character(len=*), intent(in) :: word, name
    real(dp), intent(in) :: limit
    real(dp), intent(out) :: x
    character(len=:), allocatable :: why
    logical :: ok
    why = ''
    call number_text(word, x, ok)
    if (.not. ok .or. x /= x .or. abs(x) > huge(1.0_dp)) then
      why = 'not a number'
    else if (len(below_normal(x, word)) > 0) then
      why = 'the ' // name // ' ' // word // ' ' // below_normal(x, word)
    else if (abs(x) > limit) then
      why = 'the ' // name // ' ' // fmt(x) // ' is beyond +-' // fmt(limit)
    end if
  end function value_fault

  !> Column k's name in `cols` ('time, value').
  pure function column_name(cols, k) result(c)
    character(len=*), intent(in) :: cols
    integer, intent(in) :: k
    character(len=:), allocatable :: c
    if (k == 1) then
      c = cols(1:index(cols, ',') - 1)
    else
      c = trim(adjustl(cols(index(cols, ',') + 1:)))
    end if
  end function column_name
end module pymr_io_table_file
