!> Text of numbers and words for messages and files: integers, reals as a person writes
!> them or in the fewest digits that read back exactly, lower case.
module pymr_env_text
  use pymr_env_kinds, only : dp
  use pymr_env_real_text, only : decimal_digits, digit_text, pow10, ipow10
  use, intrinsic :: iso_fortran_env, only : int64
  implicit none
  private
  public :: itoa, lower, fmt, decimal_text, exact_text, char_length, printable, excerpt, max_shown
  public :: number_text, count_text, split_words, next_text_line
  public :: json_escape, json_number, below_normal

  !> Most bytes of a message that quotes a line of a data file (excerpt).
  integer, parameter :: max_shown = 500

  !> Integer (default or 64-bit) to text without blanks.
  interface itoa
    module procedure itoa_default, itoa_long
  end interface itoa

contains

  !> The line of `text` that starts at `pos` (without its line break), and `pos` moved to the
  !> next one; false when `pos` is past the end. The one way the kernel walks text by lines.
  logical function next_text_line(text, pos, line) result(found)
    character(len=*), intent(in) :: text
    integer, intent(inout) :: pos
    character(len=:), allocatable, intent(out) :: line
    integer :: e
    found = pos <= len(text)
    if (.not. found) return
    e = index(text(pos:), new_line('a'))
    e = merge(len(text) + 1, pos + e - 1, e == 0)
    line = text(pos:e - 1)
    pos = e + 1
  end function next_text_line

  pure function itoa_default(i) result(s)
    integer, intent(in) :: i
    character(len=:), allocatable :: s
    s = itoa_long(int(i, 8))
  end function itoa_default

  !> Digit by digit: this runs once per item read.
  pure function itoa_long(i) result(s)
    integer(8), intent(in) :: i
    character(len=:), allocatable :: s
    character(len=21) :: buf
    integer :: k
    integer(8) :: v
    v = abs(i)
    k = len(buf) + 1
    do
      k = k - 1
      buf(k:k) = achar(iachar('0') + int(mod(v, 10_8)))
      v = v/10
      if (v == 0) exit
    end do
    if (i < 0) then
      k = k - 1; buf(k:k) = '-'
    end if
    s = buf(k:)
  end function itoa_long

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

  !> '' for 0 and a normal number; for one below the smallest normal number (subnormal, or
  !> a text such as 1e-400 whose digits are not 0 read as 0), what a reader says of it: 'is
  !> below the smallest normal number (2.22507e-308): give 0 or a larger magnitude' (no input
  !> means one: it makes a quotient overflow, or the 0 it became is not what was written).
  function below_normal(x, text) result(s)
    real(dp), intent(in) :: x
    !> The number as written.
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: s
    integer :: e
    s = ''
    e = scan(text, 'eEdD') - 1
    if (e < 0) e = len(text)
    if ((x /= 0.0_dp .and. abs(x) < tiny(x)) .or. (x == 0.0_dp .and. scan(text(1:e), '123456789') > 0)) &
      & s = 'is below the smallest normal number (' // fmt(tiny(1.0_dp)) // '): give 0 or a larger magnitude'
  end function below_normal

  !> A real for messages as a person writes it, at most 6 significant digits: 0.01, 2.5,
  !> 150000, 1.5e+8, -3e-7 (never a compiler's own form such as 0.100000E-1).
  function fmt(x) result(s)
    real(dp), intent(in) :: x
    character(len=:), allocatable :: s
    s = decimal_text(x, 6)
  end function fmt

  !> A real in at most `digits` significant digits, without trailing zeros: fixed notation
  !> from 1e-4 to 10**digits, else d.ddde+N. Non-finite values are NaN, Inf and -Inf.
  function decimal_text(x, digits) result(s)
    real(dp), intent(in) :: x
    integer, intent(in) :: digits
    character(len=:), allocatable :: s
    character(len=48) :: buf, form
    integer :: e, p
    if (x /= x) then
      s = 'NaN'; return
    else if (abs(x) > huge(x)) then
      s = 'Inf'
      if (x < 0.0_dp) s = '-Inf'
      return
    else if (x == 0.0_dp) then
      s = '0'; return
    end if
    write(form, '(a,i0,a,i0,a)') '(es', digits + 10, '.', digits - 1, 'e3)'
    write(buf, form) x
    p = index(buf, 'E')
    e = (iachar(buf(p+2:p+2)) - iachar('0'))*100 + (iachar(buf(p+3:p+3)) - iachar('0'))*10 + &
      & iachar(buf(p+4:p+4)) - iachar('0')
    if (buf(p+1:p+1) == '-') e = -e
    s = person_text(trim(adjustl(buf(:p-1))), e, digits)
  end function decimal_text

  !> decimal_text's form of the number whose scientific mantissa is m ('-d.ddd', `digits`
  !> significant digits) and decimal exponent e: fixed notation from 1e-4 to 10**digits,
  !> else d.ddde+N, without trailing zeros.
  pure function person_text(m, e, digits) result(s)
    character(len=*), intent(in) :: m
    integer, intent(in) :: e, digits
    character(len=:), allocatable :: s
    if (e >= -4 .and. e < digits) then
      s = fixed_text(m, e)
    else
      s = strip_zeros(m) // 'e' // merge('-', '+', e < 0) // itoa(abs(e))
    end if
  end function person_text

  !> exact_text without formatted I/O where that is certain (false elsewhere: zero,
  !> magnitudes beyond the exact powers of ten, digits within 1e-6 of a tie). The 15 digits
  !> read back to x exactly when their value, one correctly rounded product or quotient
  !> of two exact doubles, is x, as a correctly rounded READ of the text would be.
  logical function exact_digits_text(x, s) result(done)
    real(dp), intent(in) :: x
    character(len=:), allocatable, intent(out) :: s
    integer(int64) :: dgt
    integer :: e, nd, k
    logical :: ok, tie
    real(dp) :: y
    character(len=17) :: d
    done = .false.
    if (.not. (x /= 0.0_dp .and. abs(x) <= huge(x))) return
    do nd = 15, 17, 2
      call decimal_digits(abs(x), nd, dgt, e, ok, tie)
      if (.not. ok .or. tie) return
      if (nd == 15) then
        k = e - 14
        if (abs(k) > 22) return
        y = merge(real(dgt, dp)*pow10(max(k, 0)), real(dgt, dp)/pow10(max(-k, 0)), k >= 0)
        if (y /= abs(x)) cycle
      end if
      d = digit_text(dgt*ipow10(17 - nd))
      s = person_text(trim(merge('-', ' ', x < 0.0_dp)) // d(1:1) // '.' // d(2:nd), e, nd)
      done = .true.; return
    end do
  end function exact_digits_text

  !> The fixed notation of the number whose scientific mantissa is m ('-d.ddd', every digit
  !> significant) and decimal exponent e (-4 <= e < its digits): its digits moved past the
  !> point, without trailing zeros ('0.000123', '-25', '2.5').
  pure function fixed_text(m, e) result(s)
    character(len=*), intent(in) :: m
    integer, intent(in) :: e
    character(len=:), allocatable :: s, d, sgn
    integer :: i0
    i0 = merge(2, 1, m(1:1) == '-')
    sgn = m(1:i0-1)
    d = m(i0:i0) // m(i0+2:)
    if (e >= 0) then
      s = sgn // d(1:e+1) // '.' // d(e+2:)
    else
      s = sgn // '0.' // repeat('0', -e - 1) // d
    end if
    s = strip_zeros(s)
  end function fixed_text

  !> The shortest of 15 or 17 significant digits that reads back to x exactly.
  function exact_text(x) result(s)
    real(dp), intent(in) :: x
    character(len=:), allocatable :: s
    real(dp) :: y
    integer :: ios
    if (exact_digits_text(x, s)) return
    s = decimal_text(x, 15)
    if (x /= x .or. abs(x) > huge(x)) return
    read(s, *, iostat=ios) y
    if (ios /= 0 .or. y /= x) s = decimal_text(x, 17)
  end function exact_text

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

  !> Bytes of the character of text that starts at s(i:): 1 to 4 for a character of valid
  !> UTF-8 (as Python decodes it: no overlong forms, surrogates or code points past
  !> U+10FFFF) that prints on its line; 0 for anything else: a control character (tab and
  !> newline too), DEL, a C1 control, the line and paragraph separators U+2028 and U+2029,
  !> a byte that does not start a character, a character cut short.
  pure integer function char_length(s, i) result(n)
    character(len=*), intent(in) :: s
    integer, intent(in) :: i
    integer :: c, c2, j, k, lo, hi
    c = iachar(s(i:i))
    n = 0
    if (c < 32 .or. c == 127) return
    if (c < 128) then
      n = 1; return
    end if
    lo = 128; hi = 191
    select case (c)
    case (194:223)
      k = 1
    case (224:239)
      k = 2
      if (c == 224) lo = 160          ! overlong
      if (c == 237) hi = 159          ! surrogates
    case (240:244)
      k = 3
      if (c == 240) lo = 144          ! overlong
      if (c == 244) hi = 143          ! past U+10FFFF
    case default
      return
    end select
    if (i + k > len(s)) return
    c2 = iachar(s(i+1:i+1))
    if (c2 < lo .or. c2 > hi) return
    do j = 2, k
      c2 = iachar(s(i+j:i+j))
      if (c2 < 128 .or. c2 > 191) return
    end do
    if (c == 194 .and. iachar(s(i+1:i+1)) <= 159) return                  ! U+0080-009F
    if (s(i:i+1) == achar(226) // achar(128) .and. (iachar(s(i+2:i+2)) == 168 .or. &
      & iachar(s(i+2:i+2)) == 169)) return                                 ! U+2028, U+2029
    n = k + 1
  end function char_length

  !> A message as it may leave the kernel (on stderr, or to Python). Messages quote the
  !> text of a scene or a command line as written, so every byte of it that would not
  !> print as text on its line becomes '?' (see char_length); the newlines that separate
  !> the lines of a message stay. With `max_len`, cut to at most that many bytes, never
  !> inside a character.
  pure function printable(message, max_len) result(s)
    character(len=*), intent(in) :: message
    integer, intent(in), optional :: max_len
    character(len=:), allocatable :: s
    integer :: i, n, m
    allocate(character(len=len(message)) :: s)
    i = 1; m = 0
    do while (i <= len(message))
      n = char_length(message, i)
      if (message(i:i) == achar(10)) n = 1
      if (present(max_len)) then
        if (m + max(n, 1) > max_len) exit
      end if
      if (n > 0) then
        s(m+1:m+n) = message(i:i+n-1)
      else
        n = 1
        s(m+1:m+1) = '?'
      end if
      m = m + n
      i = i + n
    end do
    s = s(1:m)
  end function printable

  !> A message that quotes a file's text, cut to its first `most` bytes (printable) and
  !> the count of its characters when longer: a table line of 1 MB was echoed whole.
  function excerpt(message, most) result(s)
    character(len=*), intent(in) :: message
    integer, intent(in) :: most
    character(len=:), allocatable :: s
    s = message
    if (len(message) > most) s = printable(message, most) // ' ... (' // itoa(len(message)) // ' characters)'
  end function excerpt

  !> A number as pymr reads it from any text (a scene's values, modal and table files):
  !> [sign] digits [. digits] [(e|d) [sign] digits], or nan, inf, infinity (read, then
  !> refused by the caller as not finite; so is a number beyond the largest real, read as
  !> Inf). Anything else is not a number (ok false): Fortran's own reading would take
  !> '1/2' as 1, '2*3' as 3 and 'T' as an error only sometimes.
  subroutine number_text(text, x, ok)
    character(len=*), intent(in) :: text
    real(dp), intent(out) :: x
    logical, intent(out) :: ok
    character(len=:), allocatable :: t
    integer :: i, ios, nd
    x = 0.0_dp
    ok = .false.
    t = lower(text)
    i = 1
    if (len(t) == 0) return
    if (t(1:1) == '+' .or. t(1:1) == '-') i = 2
    if (any(t(i:) == [character(len=8) :: 'nan', 'inf', 'infinity'])) then
      x = huge(x); x = x*2
      if (t(i:) == 'nan') x = x - x
      ok = .true.; return
    end if
    nd = count_digits(t, i)
    if (i <= len(t)) then
      if (t(i:i) == '.') then
        i = i + 1
        nd = nd + count_digits(t, i)
      end if
    end if
    if (nd == 0) return
    if (i <= len(t)) then
      if (t(i:i) /= 'e' .and. t(i:i) /= 'd') return
      t(i:i) = 'e'
      i = i + 1
      if (i <= len(t)) then
        if (t(i:i) == '+' .or. t(i:i) == '-') i = i + 1
      end if
      if (count_digits(t, i) == 0) return
    end if
    if (i <= len(t)) return
    read(t, *, iostat=ios) x
    if (ios /= 0) then
      x = huge(x); x = 2*x
    end if
    ok = .true.
  end subroutine number_text

  !> Number of decimal digits in t from i on; i ends past them.
  integer function count_digits(t, i) result(n)
    character(len=*), intent(in) :: t
    integer, intent(inout) :: i
    n = 0
    do while (i <= len(t))
      if (t(i:i) < '0' .or. t(i:i) > '9') exit
      i = i + 1; n = n + 1
    end do
  end function count_digits

  !> A count as pymr reads it from a data file's header: [+] digits, at most huge(1)
  !> (ok false for anything else: a sign, a point, an exponent, too many digits).
  pure subroutine count_text(text, k, ok)
    character(len=*), intent(in) :: text
    integer, intent(out) :: k
    logical, intent(out) :: ok
    integer :: i, i0
    integer(8) :: v
    k = 0; v = 0
    i0 = 1
    if (len(text) > 0) then
      if (text(1:1) == '+') i0 = 2
    end if
    ok = len(text) >= i0 .and. len(text) - i0 < 18
    if (.not. ok) return
    do i = i0, len(text)
      ok = text(i:i) >= '0' .and. text(i:i) <= '9'
      if (.not. ok) return
      v = 10*v + (iachar(text(i:i)) - iachar('0'))
    end do
    ok = v <= huge(k)
    if (ok) k = int(v)
  end subroutine count_text

  !> The words of one line of a data file, separated by blanks, tabs, carriage returns or
  !> commas: word k is line(first(k):last(k)), n of them.
  pure subroutine split_words(line, first, last, n)
    character(len=*), intent(in) :: line
    integer, allocatable, intent(out) :: first(:), last(:)
    integer, intent(out) :: n
    integer :: i, pass
    logical :: inside
    character :: c
    do pass = 1, 2
      n = 0; inside = .false.
      do i = 1, len(line)
        c = line(i:i)
        ! compared one by one: index() of a 4-character set per character took a quarter of
        ! the reading of a 10^6-row table
        if (c == ' ' .or. c == ',' .or. c == achar(9) .or. c == achar(13)) then
          if (inside .and. pass == 2) last(n) = i - 1
          inside = .false.
        else if (.not. inside) then
          n = n + 1; inside = .true.
          if (pass == 2) first(n) = i
        end if
      end do
      if (pass == 2) then
        if (inside) last(n) = len(line)
      else
        allocate(first(n), last(n))
      end if
    end do
  end subroutine split_words
  !> A finite real as a JSON number in `digits` significant digits (Fortran's g0 form,
  !> which keeps the exponent's E at any width; a whole number that fills the digits,
  !> "1000000000.", gets its 0: JSON takes no bare point).
  function json_number(x, digits) result(s)
    real(dp), intent(in) :: x
    integer, intent(in) :: digits
    character(len=:), allocatable :: s
    character(len=48) :: buf
    character(len=8) :: form
    write(form, '(a,i0,a)') '(g0.', digits, ')'
    write(buf, form) x
    s = trim(buf)
    if (s(len(s):len(s)) == '.') s = s // '0'
  end function json_number

  !> A JSON string's content: backslashes and quotes escaped, control characters as \uXXXX,
  !> and a byte that is no part of a valid UTF-8 sequence (a path's Latin-1 name) as the lone
  !> surrogate \uDCXX of Python's surrogateescape, so that the JSON stays UTF-8 and Python's
  !> os.fsencode gives the byte back.
  function json_escape(s) result(r)
    character(len=*), intent(in) :: s
    character(len=:), allocatable :: r
    integer :: i, k, used, pass
    character(len=6) :: piece
    ! one pass to size the text, one to fill it: no text grown a character at a time
    k = 0
    do pass = 1, 2
      if (pass == 2) allocate(character(len=k) :: r)
      i = 1; k = 0
      do while (i <= len(s))
        call escaped_piece(s, i, piece, used)
        if (used == 0) then
          used = char_length(s, i)
          if (pass == 2) r(k+1:k+used) = s(i:i+used-1)
          k = k + used; i = i + used
        else
          if (pass == 2) r(k+1:k+used) = piece(1:used)
          k = k + used; i = i + 1
        end if
      end do
    end do
  end function json_escape

  !> The escape of s(i:i) in a JSON string, `used` characters of `piece`: 2 for a backslash
  !> or a quote, 6 for a control character (\u00XX) or a byte that starts no character
  !> char_length accepts (\uDCXX, the byte itself to os.fsencode); used = 0 where the
  !> character (its whole UTF-8 sequence) is kept.
  pure subroutine escaped_piece(s, i, piece, used)
    character(len=*), intent(in) :: s
    integer, intent(in) :: i
    character(len=6), intent(out) :: piece
    integer, intent(out) :: used
    character(len=16), parameter :: hex = '0123456789ABCDEF'
    integer :: c
    c = iachar(s(i:i)); used = 0; piece = ''
    if (s(i:i) == '\' .or. s(i:i) == '"') then
      piece = '\' // s(i:i); used = 2
    else if (c < 32 .or. c == 127) then
      piece = '\u00' // hex(c/16+1:c/16+1) // hex(mod(c, 16)+1:mod(c, 16)+1); used = 6
    else if (char_length(s, i) == 0) then
      piece = '\uDC' // hex(c/16+1:c/16+1) // hex(mod(c, 16)+1:mod(c, 16)+1); used = 6
    end if
  end subroutine escaped_piece
end module pymr_env_text
