!> Descriptions of namelist items, and the one generic way to set, check and write them.
!>
!> A group's table is built by its record's `describe` routine: each entry names an item,
!> its type, how many values it takes, its range or choices, its unit and its meaning, and
!> points at the record field that holds it. The reader sets fields through these pointers
!> from parsed tokens (checking count, type, finiteness, range and choices); the writer
!> prints them back; the schema prints the tables. The field's initial value is the default.
module pymr_env_item_table
  use, intrinsic :: iso_c_binding, only : c_f_pointer, c_loc
  use, intrinsic :: iso_fortran_env, only : int64
  use pymr_env_kinds, only : dp, name_len
  use pymr_env_error, only : error_type, fatal_error
  use pymr_env_namelist_parse, only : token_t
  use pymr_env_text, only : itoa, lower, fmt, exact_text, char_length, number_text, below_normal
  use pymr_env_text_file, only : scene_relative, absolute_path
  implicit none
  private
  public :: item_t, item_table, origin_t, unset, t_real, t_integer, t_logical, t_string
  public :: suggestion, value_text, is_unset, set_item, given_values, schema_line, comma_list

  !> Marker for "not given, no default" in real items.
  real(dp), parameter :: unset = -huge(1.0_dp)

  integer, parameter :: t_real = 1, t_integer = 2, t_logical = 3, t_string = 4
  character(len=*), parameter :: type_names(4) = [character(len=7) :: 'real', 'integer', 'logical', 'string']

  !> One item: its description and the field it sets.
  type :: item_t
    character(len=name_len) :: name = ''
    integer :: type = t_real
    !> Number of values; with `variable`, the most (1 to count may be given).
    integer :: count = 1
    logical :: variable = .false.
    !> Allowed range of numbers (open or closed at each end).
    real(dp) :: lo = -huge(1.0_dp), hi = huge(1.0_dp)
    logical :: lo_open = .false., hi_open = .false.
    !> Allowed words of a string item, blank-separated ('' = any text).
    character(len=:), allocatable :: choices
    !> A file path that the scene gives relative to its own folder.
    logical :: scene_file = .false.
    character(len=:), allocatable :: unit, meaning
    real(dp), pointer :: r(:) => null()
    integer, pointer :: i => null()
    logical, pointer :: l => null()
    character(len=:), pointer :: s => null()
  end type item_t

  !> The table of one group.
  type :: item_table
    type(item_t), allocatable :: items(:)
    integer :: n = 0
    !> When set, the table keeps only this item (a cheap lookup of one item of a record).
    character(len=name_len) :: only = ''
  contains
    procedure, private :: add_real, add_reals, add_integer, add_logical, add_string, add_words
    generic :: add => add_real, add_reals, add_integer, add_logical, add_string, add_words
    procedure :: find => table_find
  end type item_table

  !> Text of one --set entry.
  type :: text_t
    character(len=:), allocatable :: s
  end type text_t

  !> Where a record's values came from: the group's line and index, its label for messages
  !> ("&body 'gun'", "&drive #2"), and for each item given its line in the file (or -k for
  !> the k-th --set entry that set it) and how many values.
  type :: origin_t
    integer :: line = 0, index = 0
    character(len=:), allocatable :: file, label
    integer :: n = 0
    character(len=name_len), allocatable :: items(:)
    integer, allocatable :: lines(:), counts(:)
    type(text_t), allocatable :: sets(:)
  contains
    procedure :: given => origin_given
    procedure :: count_of => origin_count
    procedure :: line_of => origin_line
    procedure :: where => origin_where
    procedure :: note => origin_note
    procedure :: note_set => origin_note_set
  end type origin_t

contains

  ! ------------------------------------------------------------------ building a table

  subroutine push(self, it)
    class(item_table), intent(inout) :: self
    type(item_t), intent(in) :: it
    type(item_t), allocatable :: tmp(:)
    if (.not. allocated(self%items)) allocate(self%items(merge(1, 24, len_trim(self%only) > 0)))
    if (self%n == size(self%items)) then
      allocate(tmp(2*self%n)); tmp(1:self%n) = self%items
      call move_alloc(tmp, self%items)
    end if
    self%n = self%n + 1
    self%items(self%n) = it
  end subroutine push

  !> Range of a number item from gt/ge/lt/le.
  subroutine set_range(it, gt, ge, lt, le)
    type(item_t), intent(inout) :: it
    real(dp), intent(in), optional :: gt, ge, lt, le
    if (present(gt)) then
      it%lo = gt; it%lo_open = .true.
    end if
    if (present(ge)) it%lo = ge
    if (present(lt)) then
      it%hi = lt; it%hi_open = .true.
    end if
    if (present(le)) it%hi = le
  end subroutine set_range

  subroutine add_real(self, name, x, unit, meaning, gt, ge, lt, le)
    class(item_table), intent(inout) :: self
    character(len=*), intent(in) :: name, unit, meaning
    real(dp), target, intent(inout) :: x
    real(dp), intent(in), optional :: gt, ge, lt, le
    type(item_t) :: it
    if (len_trim(self%only) > 0 .and. self%only /= name) return
    it%name = name; it%type = t_real; it%unit = unit; it%meaning = meaning; it%choices = ''
    call c_f_pointer(c_loc(x), it%r, [1])
    call set_range(it, gt, ge, lt, le)
    call push(self, it)
  end subroutine add_real

  !> An array item: exactly size(x) values, or 1 to size(x) with `variable`.
  subroutine add_reals(self, name, x, unit, meaning, gt, ge, lt, le, variable)
    class(item_table), intent(inout) :: self
    character(len=*), intent(in) :: name, unit, meaning
    real(dp), target, contiguous, intent(inout) :: x(:)
    real(dp), intent(in), optional :: gt, ge, lt, le
    logical, intent(in), optional :: variable
    type(item_t) :: it
    if (len_trim(self%only) > 0 .and. self%only /= name) return
    it%name = name; it%type = t_real; it%unit = unit; it%meaning = meaning; it%choices = ''
    it%r => x
    it%count = size(x)
    if (present(variable)) it%variable = variable
    call set_range(it, gt, ge, lt, le)
    call push(self, it)
  end subroutine add_reals

  subroutine add_integer(self, name, x, unit, meaning, ge, le)
    class(item_table), intent(inout) :: self
    character(len=*), intent(in) :: name, unit, meaning
    integer, target, intent(inout) :: x
    integer, intent(in), optional :: ge, le
    type(item_t) :: it
    if (len_trim(self%only) > 0 .and. self%only /= name) return
    it%name = name; it%type = t_integer; it%unit = unit; it%meaning = meaning; it%choices = ''
    it%i => x
    it%lo = -huge(1); it%hi = huge(1)
    if (present(ge)) it%lo = ge
    if (present(le)) it%hi = le
    call push(self, it)
  end subroutine add_integer

  subroutine add_logical(self, name, x, meaning)
    class(item_table), intent(inout) :: self
    character(len=*), intent(in) :: name, meaning
    logical, target, intent(inout) :: x
    type(item_t) :: it
    if (len_trim(self%only) > 0 .and. self%only /= name) return
    it%name = name; it%type = t_logical; it%unit = ''; it%meaning = meaning; it%choices = ''
    it%l => x
    call push(self, it)
  end subroutine add_logical

  subroutine add_string(self, name, x, meaning, choices, scene_file)
    class(item_table), intent(inout) :: self
    character(len=*), intent(in) :: name, meaning
    character(len=*), target, intent(inout) :: x
    character(len=*), intent(in), optional :: choices
    logical, intent(in), optional :: scene_file
    type(item_t) :: it
    if (len_trim(self%only) > 0 .and. self%only /= name) return
    it%name = name; it%type = t_string; it%unit = ''; it%meaning = meaning
    it%s => x
    it%choices = ''
    if (present(choices)) it%choices = choices
    if (present(scene_file)) it%scene_file = scene_file
    call push(self, it)
  end subroutine add_string

  !> A list of 1 to `most` different words, each one of `choices`, held blank-separated in x.
  subroutine add_words(self, name, x, meaning, choices, most)
    class(item_table), intent(inout) :: self
    character(len=*), intent(in) :: name, meaning, choices
    character(len=*), target, intent(inout) :: x
    integer, intent(in) :: most
    type(item_t) :: it
    if (len_trim(self%only) > 0 .and. self%only /= name) return
    it%name = name; it%type = t_string; it%unit = ''; it%meaning = meaning
    it%s => x
    it%choices = choices
    it%count = most; it%variable = .true.
    call push(self, it)
  end subroutine add_words

  !> Index of the item `name` in the table (0 if none).
  pure integer function table_find(self, name) result(k)
    class(item_table), intent(in) :: self
    character(len=*), intent(in) :: name
    do k = 1, self%n
      if (self%items(k)%name == name) return
    end do
    k = 0
  end function table_find

  ! ------------------------------------------------------------------- setting values

  !> Set item `it` from its tokens; the caller puts where ("file:12: &body 'gun': mass") in
  !> front of an error's message.
  subroutine set_item(it, values, error)
    type(item_t), intent(inout) :: it
    type(token_t), intent(in) :: values(:)
    type(error_type), allocatable, intent(out) :: error
    type(token_t), allocatable :: flat(:)
    integer :: k, n
    call expand_repeats(values, it%count, flat, n, error); if (allocated(error)) return
    call check_count(it, n, error); if (allocated(error)) return
    ! the values given replace the whole item: none of an earlier, longer list stays behind
    if (it%type == t_real .and. it%variable) it%r = unset
    do k = 1, n
      select case (it%type)
      case (t_real); call set_real(it, k, flat(k), error)
      case (t_integer); call set_integer(it, flat(k), error)
      case (t_logical); call set_logical(it, flat(k), error)
      case (t_string); call set_string(it, k, flat(k), error)
      end select
      if (allocated(error)) return
    end do
  end subroutine set_item

  !> Repeat counts: `3*0.0` stands for three values 0.0. `n` is the number of values; `flat`
  !> holds them when they are at most `most` (what an item takes at most; beyond, `n` alone
  !> makes the message), built once: a repeat of up to 100000 values costs that much, not
  !> its square.
  subroutine expand_repeats(values, most, flat, n, error)
    type(token_t), intent(in) :: values(:)
    integer, intent(in) :: most
    type(token_t), allocatable, intent(out) :: flat(:)
    integer, intent(out) :: n
    type(error_type), allocatable, intent(out) :: error
    integer :: k, star, ios, j, m
    integer :: reps(size(values))
    integer(int64) :: total
    n = size(values)
    if (all(values%quoted .or. [(index(values(k)%text, '*') == 0, k = 1, size(values))])) then
      if (n <= most) flat = values
      return
    end if
    total = 0
    do k = 1, size(values)
      reps(k) = 0                     ! 0: the token itself
      star = 0
      if (.not. values(k)%quoted) star = index(values(k)%text, '*')
      if (star > 1) then
        read(values(k)%text(1:star-1), '(i20)', iostat=ios) reps(k)
        if (ios /= 0 .or. reps(k) < 1 .or. reps(k) > 100000 .or. verify(values(k)%text(1:star-1), '0123456789') /= 0 &
          & .or. star == len(values(k)%text)) then
          call fatal_error(error, 'cannot read ''' // values(k)%text // ''' (a repeat is N*VALUE)'); return
        end if
        if (scan(values(k)%text(star+1:star+1), '''"') > 0) then
          call fatal_error(error, 'cannot read ' // values(k)%text // ' (a repeat N*VALUE is of numbers or ' // &
            & 'logicals: give text once)'); return
        end if
      end if
      total = total + max(reps(k), 1)
    end do
    n = int(min(total, int(huge(n), int64)))
    if (n > most) return
    allocate(flat(n))
    j = 0
    do k = 1, size(values)
      if (reps(k) == 0) then
        j = j + 1; flat(j) = values(k); cycle
      end if
      star = index(values(k)%text, '*')
      do m = 1, reps(k)
        j = j + 1; flat(j) = token_t(values(k)%text(star+1:), .false., values(k)%line)
      end do
    end do
  end subroutine expand_repeats

  !> How many values the tokens stand for (a repeat N*VALUE counts N; tokens that are no
  !> repeat count one each).
  integer function given_values(values) result(n)
    type(token_t), intent(in) :: values(:)
    type(token_t), allocatable :: flat(:)
    type(error_type), allocatable :: error
    call expand_repeats(values, 0, flat, n, error)
    if (allocated(error)) n = size(values)
  end function given_values

  subroutine check_count(it, n, error)
    type(item_t), intent(in) :: it
    integer, intent(in) :: n
    type(error_type), allocatable, intent(out) :: error
    if (n == 0) then
      call fatal_error(error, 'no value given'); return
    end if
    if (it%variable) then
      if (n > it%count) call fatal_error(error, 'takes at most ' // itoa(it%count) // &
        & ' values, got ' // itoa(n))
    else if (n /= it%count) then
      call fatal_error(error, 'takes ' // plural(it%count, 'value') // ', got ' // itoa(n))
    end if
  end subroutine check_count

  subroutine set_real(it, k, tok, error)
    type(item_t), intent(inout) :: it
    integer, intent(in) :: k
    type(token_t), intent(in) :: tok
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: x
    logical :: ok
    call read_real(tok, x, ok)
    if (.not. ok) then
      call fatal_error(error, '''' // tok%text // ''' is not a number'); return
    end if
    if (x /= x .or. abs(x) > huge(x)) then
      call fatal_error(error, '''' // tok%text // ''' is not a finite number'); return
    end if
    if (len(below_normal(x, tok%text)) > 0) then
      call fatal_error(error, '''' // tok%text // ''' ' // below_normal(x, tok%text)); return
    end if
    call check_range(it, x, error); if (allocated(error)) return
    it%r(k) = x
  end subroutine set_real

  subroutine set_integer(it, tok, error)
    type(item_t), intent(inout) :: it
    type(token_t), intent(in) :: tok
    type(error_type), allocatable, intent(out) :: error
    integer :: ios, start
    integer(8) :: v
    start = 1
    if (len(tok%text) > 0) then
      if (tok%text(1:1) == '+' .or. tok%text(1:1) == '-') start = 2
    end if
    if (tok%quoted .or. len(tok%text) < start .or. len(tok%text) > 18 .or. &
      & verify(tok%text(start:), '0123456789') /= 0) then
      call fatal_error(error, '''' // tok%text // ''' is not a whole number'); return
    end if
    read(tok%text, '(i20)', iostat=ios) v
    if (ios /= 0 .or. abs(v) > huge(1)) then
      call fatal_error(error, '''' // tok%text // ''' is out of the range of whole numbers'); return
    end if
    call check_range(it, real(v, dp), error); if (allocated(error)) return
    it%i = int(v)
  end subroutine set_integer

  subroutine set_logical(it, tok, error)
    type(item_t), intent(inout) :: it
    type(token_t), intent(in) :: tok
    type(error_type), allocatable, intent(out) :: error
    select case (lower(tok%text))
    case ('.true.', '.t.', 't', 'true')
      it%l = .true.
    case ('.false.', '.f.', 'f', 'false')
      it%l = .false.
    case default
      call fatal_error(error, '''' // tok%text // ''' is not a logical (.true. or .false.)')
    end select
    if (tok%quoted .and. .not. allocated(error)) &
      & call fatal_error(error, '''' // tok%text // ''' is quoted: write .true. or .false.')
  end subroutine set_logical

  !> The k-th value of a string item (a word list's k-th word).
  subroutine set_string(it, k, tok, error)
    type(item_t), intent(inout) :: it
    integer, intent(in) :: k
    type(token_t), intent(in) :: tok
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: v
    integer :: j
    v = tok%text
    if (len(it%choices) > 0) then
      v = lower(v)
      if (index(' ' // it%choices // ' ', ' ' // v // ' ') == 0 .or. len(v) == 0) then
        call fatal_error(error, '''' // tok%text // ''' is not one of: ' // &
          & comma_list(it%choices) // suggestion(v, it%choices)); return
      end if
    end if
    if (k > 1) then
      if (index(' ' // trim(it%s) // ' ', ' ' // v // ' ') > 0) then
        call fatal_error(error, '''' // tok%text // ''' is given twice'); return
      end if
      v = trim(it%s) // ' ' // v
    end if
    if (len(v) > len(it%s)) then
      ! the limit is in bytes: a letter beyond ASCII takes 2 to 4 of them in UTF-8
      if (all([(iachar(v(j:j)) < 128, j = 1, len(v))])) then
        call fatal_error(error, 'the text is longer than ' // itoa(len(it%s)) // ' characters'); return
      end if
      call fatal_error(error, 'the text is longer than ' // itoa(len(it%s)) // ' bytes of UTF-8 (' // itoa(len(v)) // &
        & ' bytes: a letter beyond ASCII takes 2 to 4)'); return
    end if
    if (index(v, achar(10)) > 0 .or. index(v, achar(13)) > 0) then
      call fatal_error(error, 'the text spans lines'); return
    end if
    if (.not. clean_text(v)) then
      call fatal_error(error, 'the text holds control characters or bytes that are not UTF-8'); return
    end if
    it%s = v
  end subroutine set_string

  !> Is t valid UTF-8 text without control characters (tab aside)?
  pure logical function clean_text(t)
    character(len=*), intent(in) :: t
    integer :: i, n
    clean_text = .false.
    i = 1
    do while (i <= len(t))
      n = char_length(t, i)
      if (t(i:i) == achar(9)) n = 1
      if (n == 0) return
      i = i + n
    end do
    clean_text = .true.
  end function clean_text

  !> A number token: the kernel's one rule for numbers in text (pymr_env_text's
  !> number_text). A quoted token is not a number.
  subroutine read_real(tok, x, ok)
    type(token_t), intent(in) :: tok
    real(dp), intent(out) :: x
    logical, intent(out) :: ok
    x = 0.0_dp
    ok = .false.
    if (tok%quoted) return
    call number_text(tok%text, x, ok)
  end subroutine read_real

  subroutine check_range(it, x, error)
    type(item_t), intent(in) :: it
    real(dp), intent(in) :: x
    type(error_type), allocatable, intent(out) :: error
    logical :: low, high
    low = x < it%lo .or. (it%lo_open .and. x == it%lo)
    high = x > it%hi .or. (it%hi_open .and. x == it%hi)
    if (low .or. high) call fatal_error(error, 'must be ' // range_text(it) // ', got ' // fmt(x))
  end subroutine check_range

  !> "> 0", "in [0, 1)", "<= 1e+12", "" for an item without a range.
  function range_text(it) result(s)
    type(item_t), intent(in) :: it
    character(len=:), allocatable :: s
    logical :: has_lo, has_hi
    has_lo = it%lo > -huge(1.0_dp) .and. .not. (it%type == t_integer .and. it%lo <= -huge(1))
    has_hi = it%hi < huge(1.0_dp) .and. .not. (it%type == t_integer .and. it%hi >= huge(1))
    if (has_lo .and. has_hi) then
      s = 'in ' // merge('(', '[', it%lo_open) // fmt(it%lo) // ', ' // fmt(it%hi) // merge(')', ']', it%hi_open)
    else if (has_lo) then
      s = merge('> ', '>=', it%lo_open) // ' ' // fmt(it%lo)
    else if (has_hi) then
      s = merge('< ', '<=', it%hi_open) // ' ' // fmt(it%hi)
    else
      s = ''
    end if
    s = trim(s)
  end function range_text

  ! ------------------------------------------------------------------ writing values

  !> Is x the "not given" marker?
  elemental logical function is_unset(x)
    real(dp), intent(in) :: x
    is_unset = x == unset
  end function is_unset

  !> The item's current values as namelist text ('' when it holds no value: unset reals).
  !> With `scene`, a path item given relative to the scene's folder is written absolute.
  function value_text(it, scene) result(s)
    type(item_t), intent(in) :: it
    character(len=*), intent(in), optional :: scene
    character(len=:), allocatable :: s
    integer :: k, n
    select case (it%type)
    case (t_real)
      n = size(it%r)
      if (it%variable) then
        n = 0
        do while (n < size(it%r))
          if (is_unset(it%r(n + 1))) exit
          n = n + 1
        end do
      end if
      s = ''
      if (any(is_unset(it%r(1:n))) .or. n == 0) return
      do k = 1, n
        s = s // merge(', ', '  ', k > 1) // exact_text(it%r(k))
      end do
      s = s(3:)
    case (t_integer)
      s = itoa(it%i)
    case (t_logical)
      s = merge('.true. ', '.false.', it%l)
      s = trim(s)
    case (t_string)
      if (it%variable) then
        s = quoted_words(trim(it%s)); return
      end if
      s = quoted(trim(it%s))
      if (present(scene) .and. it%scene_file .and. len_trim(it%s) > 0) &
        & s = quoted(absolute_path(scene_relative(scene, trim(it%s))))
    end select
  end function value_text

  !> "a b" -> "'a', 'b'" (a word list's values).
  function quoted_words(words) result(s)
    character(len=*), intent(in) :: words
    character(len=:), allocatable :: s
    integer :: i, j
    s = ''
    i = 1
    do
      call next_word(words, i, j); if (i > len(words)) exit
      s = s // merge(', ', '  ', len(s) > 0) // '''' // words(i:j) // ''''
      i = j + 1
    end do
    if (len(s) > 0) s = s(3:)
  end function quoted_words

  !> The next blank-separated word of `text` from position i on: text(i:j); i > len(text)
  !> when there is none.
  pure subroutine next_word(text, i, j)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: i
    integer, intent(out) :: j
    do while (i <= len(text))
      if (text(i:i) /= ' ') exit
      i = i + 1
    end do
    j = i - 1
    if (i <= len(text)) j = index(text(i:) // ' ', ' ') + i - 2
  end subroutine next_word

  !> Text in single quotes, inner quotes doubled.
  function quoted(t) result(s)
    character(len=*), intent(in) :: t
    character(len=:), allocatable :: s
    integer :: k
    s = ''''
    do k = 1, len(t)
      s = s // t(k:k)
      if (t(k:k) == '''') s = s // ''''
    end do
    s = s // ''''
  end function quoted

  !> One line of the schema: name, type (with its count), default, range or choices, unit
  !> and meaning, tab-separated. The default is the value the field holds before reading.
  function schema_line(it) result(s)
    type(item_t), intent(in) :: it
    character(len=:), allocatable :: s, kind, dflt, allowed
    character(len=1), parameter :: tab = achar(9)
    kind = trim(type_names(it%type))
    if (it%variable) then
      kind = kind // '(1..' // itoa(it%count) // ')'
    else if (it%count > 1) then
      kind = kind // '(' // itoa(it%count) // ')'
    end if
    dflt = value_text(it)
    if (len(dflt) == 0) dflt = '-'
    if (it%type == t_string .and. len(it%choices) > 0) then
      allowed = comma_list(it%choices)
    else
      allowed = range_text(it)
    end if
    s = trim(it%name) // tab // kind // tab // dflt // tab // allowed // tab // it%unit // tab // it%meaning
  end function schema_line

  ! ------------------------------------------------------------------------- origins

  !> Record that `item` was given on `line` of the file with n values (`room`: how many
  !> items the group gives, to size the record once).
  subroutine origin_note(self, item, line, n, room)
    class(origin_t), intent(inout) :: self
    character(len=*), intent(in) :: item
    integer, intent(in) :: line, n
    integer, intent(in), optional :: room
    integer :: k
    character(len=name_len), allocatable :: items(:)
    integer, allocatable :: lines(:), counts(:)
    if (.not. allocated(self%items)) then
      k = 4
      if (present(room)) k = max(room, 1)
      allocate(self%items(k), self%lines(k), self%counts(k))
    end if
    do k = 1, self%n
      if (self%items(k) == item) then
        self%lines(k) = line; self%counts(k) = n; return
      end if
    end do
    if (self%n == size(self%items)) then
      allocate(items(2*self%n), lines(2*self%n), counts(2*self%n))
      items(1:self%n) = self%items; lines(1:self%n) = self%lines; counts(1:self%n) = self%counts
      call move_alloc(items, self%items); call move_alloc(lines, self%lines); call move_alloc(counts, self%counts)
    end if
    self%n = self%n + 1
    self%items(self%n) = item; self%lines(self%n) = line; self%counts(self%n) = n
  end subroutine origin_note

  !> Record that `item` was set by the --set entry `source` with n values.
  subroutine origin_note_set(self, item, source, n)
    class(origin_t), intent(inout) :: self
    character(len=*), intent(in) :: item, source
    integer, intent(in) :: n
    if (.not. allocated(self%sets)) allocate(self%sets(0))
    self%sets = [self%sets, text_t(source)]
    call self%note(item, -size(self%sets), n)
  end subroutine origin_note_set

  pure logical function origin_given(self, item)
    class(origin_t), intent(in) :: self
    character(len=*), intent(in) :: item
    origin_given = self%count_of(item) > 0
  end function origin_given

  !> Number of values given for `item` (0 if not given).
  pure integer function origin_count(self, item) result(n)
    class(origin_t), intent(in) :: self
    character(len=*), intent(in) :: item
    integer :: k
    n = 0
    do k = 1, self%n
      if (self%items(k) == item) n = self%counts(k)
    end do
  end function origin_count

  !> Line of the file that gave `item` (-k: the k-th --set that touched the group; 0: not
  !> given).
  pure integer function origin_line(self, item) result(line)
    class(origin_t), intent(in) :: self
    character(len=*), intent(in) :: item
    integer :: k
    line = 0
    do k = 1, self%n
      if (self%items(k) == item) line = self%lines(k)
    end do
  end function origin_line

  !> Prefix for a message about `item` of this group: "file:12: &body 'gun': mass", the
  !> item's own line if it was given, "file: --set ...: &body 'gun': mass" if a --set gave it,
  !> else the group's line.
  function origin_where(self, item) result(s)
    class(origin_t), intent(in) :: self
    character(len=*), intent(in), optional :: item
    character(len=:), allocatable :: s
    integer :: k, line
    line = self%line
    s = ''
    if (present(item)) then
      s = ': ' // item
      do k = 1, self%n
        if (self%items(k) == item) line = self%lines(k)
      end do
    end if
    if (line < 0) then
      s = self%file // ': ' // self%sets(-line)%s // ': ' // self%label // s
    else if (line == 0) then
      s = self%file // ': ' // self%label // s
    else
      s = self%file // ':' // itoa(line) // ': ' // self%label // s
    end if
  end function origin_where

  ! ------------------------------------------------------------------------- helpers

  !> "; did you mean 'x'?" for the closest of `names` (blank-separated) to `word`, or ''.
  !> With `group`, the name is written as a group: "; did you mean &x?".
  function suggestion(word, names, group) result(s)
    character(len=*), intent(in) :: word, names
    logical, intent(in), optional :: group
    character(len=:), allocatable :: s
    character(len=:), allocatable :: best
    best = nearest_name(word, names)
    s = ''
    if (len(best) == 0) return
    s = '; did you mean ''' // best // '''?'
    if (present(group)) then
      if (group) s = '; did you mean &' // best // '?'
    end if
  end function suggestion

  !> The name of `names` (blank-separated) nearest to `word` by edit distance, if within
  !> a third of its length (at least 2 edits); '' when none is near.
  function nearest_name(word, names) result(best)
    character(len=*), intent(in) :: word, names
    character(len=:), allocatable :: best
    integer :: i, j, d, dbest
    best = ''; dbest = huge(1)
    i = 1
    do
      call next_word(names, i, j); if (i > len(names)) exit
      d = edit_distance(lower(word), names(i:j))
      if (d < dbest) then
        dbest = d; best = names(i:j)
      end if
      i = j + 1
    end do
    if (dbest > max(2, len_trim(word)/3)) best = ''
  end function nearest_name

  !> Levenshtein distance.
  pure integer function edit_distance(a, b) result(d)
    character(len=*), intent(in) :: a, b
    integer :: prev(0:len(b)), cur(0:len(b)), i, j
    prev = [(j, j = 0, len(b))]
    do i = 1, len(a)
      cur(0) = i
      do j = 1, len(b)
        cur(j) = min(prev(j) + 1, cur(j-1) + 1, prev(j-1) + merge(0, 1, a(i:i) == b(j:j)))
      end do
      prev = cur
    end do
    d = prev(len(b))
  end function edit_distance

  !> "a b c" -> "a, b, c".
  function comma_list(words) result(s)
    character(len=*), intent(in) :: words
    character(len=:), allocatable :: s
    integer :: i
    s = ''
    do i = 1, len(words)
      if (words(i:i) == ' ') then
        if (len(s) > 0) then
          if (s(len(s):len(s)) /= ' ') s = s // ', '
        end if
      else
        s = s // words(i:i)
      end if
    end do
  end function comma_list

  function plural(n, word) result(s)
    integer, intent(in) :: n
    character(len=*), intent(in) :: word
    character(len=:), allocatable :: s
    s = itoa(n) // ' ' // word
    if (n /= 1) s = s // 's'
  end function plural
end module pymr_env_item_table
