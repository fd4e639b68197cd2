!> A strict parser of namelist text into groups, items and value tokens, each with its line.
!>
!> A group runs from `&name` to `/` (or `&end`); inside it, `item = values` pairs follow one
!> another, values separated by commas or blanks. A value is a quoted string ('...' or "...",
!> a doubled quote standing for one), or a bare token: a number, a logical, a repeat count
!> `n*value`, or a bare word. `!` starts a comment outside quotes. Whatever else stands outside
!> a group, an item without `=`, a subscripted item, an unclosed group or string, is an error
!> naming its line. Nothing here knows which groups or items exist: that is the item tables'.
module pymr_env_namelist_parse
  use pymr_env_kinds, only : name_len
  use pymr_env_error, only : error_type, fatal_error
  use pymr_env_text, only : itoa, lower
  implicit none
  private
  public :: token_t, item_text, group_text, parse_namelist, parse_values, group_label

  !> One value as written: its text (without quotes) and whether it was quoted.
  type :: token_t
    character(len=:), allocatable :: text
    logical :: quoted = .false.
    !> Line of the token in the file (0 for a --set value).
    integer :: line = 0
  end type token_t

  !> One `item = values` of a group.
  type :: item_text
    character(len=name_len) :: name = ''
    integer :: line = 0
    type(token_t), allocatable :: values(:)
  end type item_text

  !> One group occurrence: its name (lower case), line, running number among the groups of
  !> its name, and its items in order.
  type :: group_text
    character(len=name_len) :: name = ''
    integer :: line = 0, index = 0
    !> A repeated group (numbered in messages when it has no name).
    logical :: numbered = .false.
    type(item_text), allocatable :: items(:)
  end type group_text


contains

  !> Parse the whole text of a namelist file (`where` prefixes messages: the file name).
  !> The groups are groups(1:n_groups).
  !> `repeated` lists the groups that may appear more than once (blank-separated): their
  !> occurrences are numbered in messages.
  subroutine parse_namelist(text, where, repeated, groups, n_groups, error)
    character(len=*), intent(in) :: text, where, repeated
    type(group_text), allocatable, intent(out) :: groups(:)
    integer, intent(out) :: n_groups
    type(error_type), allocatable, intent(out) :: error
    integer :: i, line, k, n_names
    character(len=name_len) :: names(64)
    integer :: counts(64)
    ! at most one group per '&' or '$': one allocation, no copies of parsed groups
    allocate(groups(max(1, count_groups_bound(text))))
    n_groups = 0; i = 1; line = 1; n_names = 0
    do
      call skip_space(text, i, line, .true.)
      if (i > len(text)) exit
      if (text(i:i) /= '&' .and. text(i:i) /= '$') then
        call fatal_error(error, where // ':' // itoa(line) // ': text outside a group: ''' // &
          & snippet(text, i) // ''' (a group starts with &NAME and ends with /)'); return
      end if
      n_groups = n_groups + 1
      associate(g => groups(n_groups))
        g%name = lower(text(i+1:ident_end(text, i+1)))
        ! running number among the groups of its name (few distinct names: a short list)
        k = findloc(names(1:n_names), g%name, 1)
        if (k == 0 .and. n_names < size(names)) then
          n_names = n_names + 1; k = n_names
          names(k) = g%name; counts(k) = 0
        end if
        if (k > 0) then
          counts(k) = counts(k) + 1
          g%index = counts(k)
        end if
        g%numbered = index(' ' // repeated // ' ', ' ' // trim(g%name) // ' ') > 0
        call parse_group(text, i, line, where, g, error); if (allocated(error)) return
      end associate
    end do
  end subroutine parse_namelist

  !> Number of '=' outside quotes from text(i:) to the next '/' or group start ('&' or '$'
  !> after a separator) outside quotes: a bound on the number of items of the group there.
  pure integer function count_equals(text, i) result(n)
    character(len=*), intent(in) :: text
    integer, intent(in) :: i
    integer :: j
    character(len=1) :: q
    n = 0; q = ' '; j = i
    do while (j <= len(text))
      if (q /= ' ') then
        if (text(j:j) == q .or. text(j:j) == achar(10)) q = ' '
      else
        select case (text(j:j))
        case ('''', '"'); q = text(j:j)
        case ('='); n = n + 1
        case ('/'); exit
        case ('&', '$')
          ! a group starts only where a value could (R&D is one bare word, as the reader has it)
          if (j == i) exit
          if (index(' ,' // achar(9) // achar(10) // achar(13), text(j-1:j-1)) > 0) exit
        case ('!')
          do while (j < len(text))
            if (text(j+1:j+1) == achar(10)) exit
            j = j + 1
          end do
        end select
      end if
      j = j + 1
    end do
  end function count_equals

  !> Number of '&' and '$' in text: a bound on the number of groups.
  pure integer function count_groups_bound(text) result(n)
    character(len=*), intent(in) :: text
    integer :: i
    n = 0
    do i = 1, len(text)
      if (text(i:i) == '&' .or. text(i:i) == '$') n = n + 1
    end do
  end function count_groups_bound

  !> Parse a list of values (the text after `=` of a --set entry): tokens only, no groups.
  subroutine parse_values(text, where, values, error)
    character(len=*), intent(in) :: text, where
    type(token_t), allocatable, intent(out) :: values(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: i, line, n
    allocate(values(4)); n = 0
    i = 1; line = 0   ! a --set value has no line in a file
    do
      call skip_separators(text, i, line)
      if (i > len(text)) exit
      if (n == size(values)) call grow_tokens(values)
      n = n + 1
      call read_token(text, i, line, .false., values(n), error)
      if (allocated(error)) then
        error%message = where // ': ' // error%message; return
      end if
    end do
    values = values(1:n)
    if (n == 0) call fatal_error(error, where // ': no value given')
  end subroutine parse_values

  !> One group from its '&' at text(i:); on return i is past its closing '/'.
  subroutine parse_group(text, i, line, where, g, error)
    character(len=*), intent(in) :: text, where
    integer, intent(inout) :: i, line
    type(group_text), intent(inout) :: g
    type(error_type), allocatable, intent(out) :: error
    integer :: j, n_items, name_start, name_end
    j = ident_end(text, i + 1) + 1
    if (j == i + 1) then
      call fatal_error(error, where // ':' // itoa(line) // ': a group name must follow ''' // text(i:i) // ''''); return
    end if
    g%line = line
    ! one item per '=' at most: sized once
    allocate(g%items(max(1, count_equals(text, j)))); n_items = 0
    i = j
    do
      call skip_separators(text, i, line)
      if (i > len(text)) then
        call fatal_error(error, where // ':' // itoa(g%line) // ': ' // group_label(g, n_items) // ': the group ' // &
          & 'is not closed (a / must end it)'); return
      end if
      if (text(i:i) == '/') then
        i = i + 1; exit
      end if
      if (group_end(text, i)) then
        i = i + 4; exit
      end if
      if (text(i:i) == '&' .or. text(i:i) == '$') then
        call fatal_error(error, where // ':' // itoa(g%line) // ': ' // group_label(g, n_items) // ': the group ' // &
          & 'is not closed: a / must end it before the ' // snippet(text, i) // ' on line ' // itoa(line)); return
      end if
      call read_name(text, i, name_start, name_end, error)
      if (allocated(error)) then
        error%message = where // ':' // itoa(line) // ': ' // group_label(g, n_items) // ': ' // error%message; return
      end if
      if (n_items == size(g%items)) then
        call fatal_error(error, where // ':' // itoa(line) // ': ' // group_label(g, n_items) // ': more items ' // &
          & 'than the group has ''='' signs'); return
      end if
      n_items = n_items + 1
      g%items(n_items)%name = lower(text(name_start:name_end))
      g%items(n_items)%line = line
      call read_item_values(text, i, line, g%items(n_items), error)
      if (allocated(error)) then
        error%message = where // ':' // itoa(line) // ': ' // group_label(g, n_items - 1) // ': ' // &
          & trim(g%items(n_items)%name) // ': ' // error%message; return
      end if
    end do
    g%items = g%items(1:n_items)
  end subroutine parse_group

  !> An item name followed by '=' at text(i:); on return name_start:name_end is the name
  !> in text and i is past the '='. Messages name no place (the caller prefixes it).
  subroutine read_name(text, i, name_start, name_end, error)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: i
    integer, intent(out) :: name_start, name_end
    type(error_type), allocatable, intent(out) :: error
    name_start = i
    name_end = ident_end(text, i)
    if (name_end < i) then
      if (text(i:i) == '=') then
        call fatal_error(error, 'expected an item name before ''' // snippet(text, i) // ''''); return
      end if
      call fatal_error(error, 'expected an item name, found ''' // snippet(text, i) // ''''); return
    end if
    i = name_end + 1
    call skip_blanks(text, i)
    if (i <= len(text)) then
      if (text(i:i) == '(') then
        call fatal_error(error, lower(text(name_start:name_end)) // ': subscripts are not read: give all the ' // &
          & 'values of the item'); return
      end if
      if (text(i:i) == '=') then
        i = i + 1; return
      end if
    end if
    call fatal_error(error, lower(text(name_start:name_end)) // ': expected ''='' after the item name, found ''' // &
      & snippet(text, i) // '''')
  end subroutine read_name

  !> The values of one item: tokens up to the next `name =`, the group's '/' or its end,
  !> or a '&' or '=' that the group's loop reports.
  subroutine read_item_values(text, i, line, item, error)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: i, line
    type(item_text), intent(inout) :: item
    type(error_type), allocatable, intent(out) :: error
    integer :: n
    allocate(item%values(4)); n = 0
    do
      call skip_separators(text, i, line)
      if (i > len(text)) exit
      if (text(i:i) == '/' .or. group_end(text, i)) exit
      if (starts_item(text, i)) exit
      if (text(i:i) == '&' .or. text(i:i) == '$' .or. text(i:i) == '=') exit
      if (n == size(item%values)) call grow_tokens(item%values)
      n = n + 1
      call read_token(text, i, line, .true., item%values(n), error)
      if (allocated(error)) return
    end do
    item%values = item%values(1:n)
  end subroutine read_item_values

  !> "&body 'gun'" when the items so far name the group with a quoted name, "&drive #2"
  !> for another repeated group, "&scene" for a single one.
  function group_label(g, n_items) result(s)
    type(group_text), intent(in) :: g
    integer, intent(in) :: n_items
    character(len=:), allocatable :: s
    integer :: k
    s = '&' // trim(g%name)
    do k = 1, min(n_items, size(g%items))
      if (g%items(k)%name /= 'name' .or. .not. allocated(g%items(k)%values)) cycle
      if (size(g%items(k)%values) /= 1) cycle
      if (g%items(k)%values(1)%quoted .and. len_trim(g%items(k)%values(1)%text) > 0) then
        s = s // ' ''' // g%items(k)%values(1)%text // ''''; return
      end if
    end do
    if (g%numbered) s = s // ' #' // itoa(g%index)
  end function group_label

  !> Last position of the identifier starting at text(i:) (i - 1 if none).
  pure integer function ident_end(text, i) result(j)
    character(len=*), intent(in) :: text
    integer, intent(in) :: i
    j = i
    do while (j <= len(text))
      if (.not. is_ident(text(j:j))) exit
      j = j + 1
    end do
    j = j - 1
  end function ident_end

  !> One value token at text(i:): a quoted string (on one line) or a bare token. In a file
  !> (`in_file`) a bare token ends at '/', which closes the group; in a --set value it does not.
  subroutine read_token(text, i, line, in_file, tok, error)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: i, line
    logical, intent(in) :: in_file
    type(token_t), intent(out) :: tok
    type(error_type), allocatable, intent(out) :: error
    character(len=1) :: q
    integer :: j, n_quotes
    tok%line = line
    if (text(i:i) == '''' .or. text(i:i) == '"') then
      q = text(i:i)
      tok%quoted = .true.
      j = i + 1; n_quotes = 0
      do
        if (j > len(text)) then
          call fatal_error(error, 'the string is not closed (a string ends on its own line)'); return
        end if
        if (text(j:j) == achar(10)) then
          call fatal_error(error, 'the string is not closed on its line'); return
        end if
        if (text(j:j) == q) then
          if (j == len(text)) exit
          if (text(j+1:j+1) /= q) exit
          n_quotes = n_quotes + 1; j = j + 1
        end if
        j = j + 1
      end do
      tok%text = text(i+1:j-1)
      if (n_quotes > 0) call undouble(tok%text, q)
      i = j + 1
    else
      j = i
      do while (j <= len(text))
        if (ends_token(text(j:j), in_file)) exit
        j = j + 1
      end do
      tok%text = text(i:j-1)
      i = j
    end if
  end subroutine read_token

  !> Replace each doubled quote q in s by one.
  pure subroutine undouble(s, q)
    character(len=:), allocatable, intent(inout) :: s
    character(len=1), intent(in) :: q
    character(len=len(s)) :: buf
    integer :: j, k
    j = 1; k = 0
    do while (j <= len(s))
      k = k + 1
      buf(k:k) = s(j:j)
      if (s(j:j) == q) j = j + 1
      j = j + 1
    end do
    s = buf(1:k)
  end subroutine undouble

  !> Does text(i:) start `name =` (the next item)?
  logical function starts_item(text, i)
    character(len=*), intent(in) :: text
    integer, intent(in) :: i
    integer :: j
    starts_item = .false.
    if (.not. is_ident(text(i:i)) .or. index('0123456789', text(i:i)) > 0) return
    j = i
    do while (j <= len(text))
      if (.not. is_ident(text(j:j))) exit
      j = j + 1
    end do
    call skip_blanks(text, j)
    if (j > len(text)) return
    starts_item = text(j:j) == '=' .or. text(j:j) == '('
  end function starts_item

  !> Does text(i:) hold the old-style group end '&end' (or '$end')?
  logical function group_end(text, i)
    character(len=*), intent(in) :: text
    integer, intent(in) :: i
    group_end = .false.
    if (i + 3 > len(text)) return
    if (text(i:i) /= '&' .and. text(i:i) /= '$') return
    group_end = lower(text(i+1:i+3)) == 'end'
    if (group_end .and. i + 4 <= len(text)) group_end = .not. is_ident(text(i+4:i+4))
  end function group_end

  !> Skip blanks, newlines and comments (outside groups: comments to the end of line).
  subroutine skip_space(text, i, line, comments)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: i, line
    logical, intent(in) :: comments
    do while (i <= len(text))
      if (text(i:i) == achar(10)) then
        line = line + 1
      else if (comments .and. text(i:i) == '!') then
        do while (i < len(text))
          if (text(i+1:i+1) == achar(10)) exit
          i = i + 1
        end do
      else if (.not. is_blank(text(i:i))) then
        exit
      end if
      i = i + 1
    end do
  end subroutine skip_space

  !> Skip blanks, newlines, comments and value-separating commas.
  subroutine skip_separators(text, i, line)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: i, line
    do
      call skip_space(text, i, line, .true.)
      if (i > len(text)) return
      if (text(i:i) /= ',') return
      i = i + 1
    end do
  end subroutine skip_separators

  !> Skip blanks on the same line.
  subroutine skip_blanks(text, i)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: i
    do while (i <= len(text))
      if (.not. is_blank(text(i:i))) exit
      i = i + 1
    end do
  end subroutine skip_blanks

  !> Blank, tab or carriage return.
  pure logical function is_blank(c)
    character(len=1), intent(in) :: c
    is_blank = c == ' ' .or. c == achar(9) .or. c == achar(13)
  end function is_blank

  !> Does c end a bare token? Blanks, commas, line ends and comments do; in a file '/' and
  !> '=' too.
  pure logical function ends_token(c, in_file)
    character(len=1), intent(in) :: c
    logical, intent(in) :: in_file
    select case (c)
    case (' ', ',', '!', achar(9), achar(10), achar(13))
      ends_token = .true.
    case ('/', '=')
      ends_token = in_file
    case default
      ends_token = .false.
    end select
  end function ends_token

  !> Up to 20 characters of text from i, on one line, for messages; bytes that are not
  !> printable ASCII show as '?'.
  function snippet(text, i) result(s)
    character(len=*), intent(in) :: text
    integer, intent(in) :: i
    character(len=:), allocatable :: s
    integer :: j, k
    j = i
    do while (j <= len(text) .and. j < i + 20)
      if (text(j:j) == achar(10) .or. text(j:j) == achar(13)) exit
      j = j + 1
    end do
    s = text(i:j-1)
    do k = 1, len(s)
      if (iachar(s(k:k)) < 32 .or. iachar(s(k:k)) > 126) s(k:k) = '?'
    end do
  end function snippet

  pure logical function is_ident(c)
    character(len=1), intent(in) :: c
    is_ident = (c >= 'a' .and. c <= 'z') .or. (c >= 'A' .and. c <= 'Z') .or. (c >= '0' .and. c <= '9') &
      & .or. c == '_'
  end function is_ident

  subroutine grow_tokens(a)
    type(token_t), allocatable, intent(inout) :: a(:)
    type(token_t), allocatable :: b(:)
    allocate(b(2*size(a)))
    b(1:size(a)) = a
    call move_alloc(b, a)
  end subroutine grow_tokens
end module pymr_env_namelist_parse
