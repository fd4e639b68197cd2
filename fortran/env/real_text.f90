!> Reals as text without formatted I/O: correctly rounded decimal digits (decimal_digits),
!> and put_real, the CSV writer's numbers: 17 significant digits in E notation
!> ("-1.2345678901234567e+002"), about ten times faster than a formatted WRITE, and read
!> back to the same double. pymr_env_text's exact_text takes its digits from here too.
!>
!> For magnitudes 1e-21 to 1e22 the digits come from x 10^-e carried in double-double
!> arithmetic (error-free products and quotients by exact powers of ten, Dekker's
!> splitting): they are correctly rounded, except where x lies within 1e-6 of the last
!> digit of a tie (exact_text then leaves it to a formatted WRITE; put_real's 17 digits
!> read back to x either way). Beyond that range (subnormal numbers included) put_real
!> writes by a formatted WRITE.
module pymr_env_real_text
  use pymr_env_kinds, only : dp
  use, intrinsic :: iso_fortran_env, only : int64
  implicit none
  private
  public :: decimal_digits, digit_text, pow10, ipow10, put_real

  integer :: k_, j_
  !> The powers of ten exact in double precision, and as 64-bit integers.
  real(dp), parameter :: pow10(0:22) = [(10.0_dp**k_, k_ = 0, 22)]
  integer(int64), parameter :: ipow10(0:18) = [(10_int64**k_, k_ = 0, 18)]
  !> The hundred two-digit strings '00' ... '99'.
  character(len=2), parameter :: pairs(0:99) = [((achar(iachar('0') + k_) // achar(iachar('0') + j_), j_ = 0, 9), &
    & k_ = 0, 9)]
  !> The ten thousand four-digit strings '0000' ... '9999'.
  character(len=4), parameter :: quads(0:9999) = [((pairs(k_) // pairs(j_), j_ = 0, 99), k_ = 0, 99)]

contains

  !> Append the text of x to buf at position pos (advanced past the text), in `digits`
  !> significant digits (17, the default, reads back to x; fewer are rounded).
  pure subroutine put_real(x, buf, pos, digits)
    real(dp), intent(in) :: x
    character(len=*), intent(inout) :: buf
    integer, intent(inout) :: pos
    integer, intent(in), optional :: digits
    integer :: e, nd
    integer(int64) :: dgt
    logical :: ok
    real(dp) :: r
    character(len=17) :: dstr
    if (x /= x) then
      call put_word('nan', buf, pos); return
    else if (abs(x) > huge(x)) then
      call put_word(trim(merge('inf ', '-inf', x > 0.0_dp)), buf, pos); return
    else if (x == 0.0_dp) then
      call put_word(trim(merge('-0.0', '0.0 ', sign(1.0_dp, x) < 0.0_dp)), buf, pos); return
    end if
    if (x < 0.0_dp) then
      buf(pos:pos) = '-'; pos = pos + 1
    end if
    nd = 17
    if (present(digits)) nd = digits
    call rounded_digits(abs(x), nd, dgt, e, ok, r)
    if (.not. ok) then
      call put_real_exact(abs(x), nd, buf, pos); return
    end if
    if (nd == 17) then
      ! straight into buf, then the first digit before the point: a copy through a
      ! 17-character temporary read 16 bytes over its four-byte stores, which stalled
      call write_digits(dgt, buf(pos+1:pos+17))
      buf(pos:pos) = buf(pos+1:pos+1)
    else
      dstr = digit_text(dgt*ipow10(17 - nd))
      buf(pos:pos) = dstr(1:1); buf(pos+2:pos+nd) = dstr(2:nd)
    end if
    buf(pos+1:pos+1) = '.'
    pos = pos + nd + 1
    buf(pos:pos+1) = merge('e-', 'e+', e < 0); buf(pos+2:pos+2) = '0'
    buf(pos+3:pos+4) = pairs(abs(e))                      ! |e| <= 23 here
    pos = pos + 5
  end subroutine put_real

  !> Append the word w to buf at pos (advanced past it).
  pure subroutine put_word(w, buf, pos)
    character(len=*), intent(in) :: w
    character(len=*), intent(inout) :: buf
    integer, intent(inout) :: pos
    buf(pos:pos+len(w)-1) = w
    pos = pos + len(w)
  end subroutine put_word

  !> The 17 decimal digits of 0 <= dgt < 10^17 (leading zeros kept), four at a time in two
  !> 32-bit halves (9 + 8): five divisions by constants.
  pure function digit_text(dgt) result(d)
    integer(int64), intent(in) :: dgt
    character(len=17) :: d
    call write_digits(dgt, d)
  end function digit_text

  !> digit_text's work, written into d (put_real's buffer itself).
  pure subroutine write_digits(dgt, d)
    integer(int64), intent(in) :: dgt
    character(len=17), intent(out) :: d
    integer :: hi, lo
    hi = int(dgt/100000000_int64)
    lo = int(dgt - 100000000_int64*hi)
    d(14:17) = quads(mod(lo, 10000)); d(10:13) = quads(lo/10000)
    d(6:9) = quads(mod(hi, 10000)); hi = hi/10000
    d(2:5) = quads(mod(hi, 10000)); d(1:1) = achar(iachar('0') + hi/10000)
  end subroutine write_digits

  !> Append the text of x > 0 by a formatted WRITE, correctly rounded to `digits` digits: the path
  !> for magnitudes beyond 1e+-21, where a power of ten is not exact in double precision
  !> (subnormal numbers included).
  pure subroutine put_real_exact(x, digits, buf, pos)
    real(dp), intent(in) :: x
    integer, intent(in) :: digits
    character(len=*), intent(inout) :: buf
    integer, intent(inout) :: pos
    character(len=24) :: text, form
    integer :: p
    write(form, '(a,i0,a)') '(es24.', digits - 1, 'e3)'
    write(text, form) x
    text = adjustl(text)
    p = index(text, 'E')
    text(p:p) = 'e'
    buf(pos:pos+len_trim(text)-1) = trim(text)
    pos = pos + len_trim(text)
  end subroutine put_real_exact

  !> The nd significant digits (nd <= 17) of x > 0 (finite) as the integer dgt,
  !> 10^(nd-1) <= dgt < 10^nd, and its decimal exponent e: x ~ dgt 10^(e - nd + 1).
  !> ok is false beyond 1e+-21 (dgt, e undefined); near_tie is true when x lies within
  !> 1e-6 of a last digit from halfway between two roundings.
  pure subroutine decimal_digits(x, nd, dgt, e, ok, near_tie)
    real(dp), intent(in) :: x
    integer, intent(in) :: nd
    integer(int64), intent(out) :: dgt
    integer, intent(out) :: e
    logical, intent(out) :: ok, near_tie
    real(dp) :: r
    call rounded_digits(x, nd, dgt, e, ok, r)
    near_tie = abs(abs(r - real(nearest_integer(r), dp)) - 0.5_dp) < 1.0e-6_dp
  end subroutine decimal_digits

  !> decimal_digits' work; r: the part of x 10^(nd-1-e) beyond its nearest integer.
  pure subroutine rounded_digits(x, nd, dgt, e, ok, r)
    real(dp), intent(in) :: x
    integer, intent(in) :: nd
    integer(int64), intent(out) :: dgt
    integer, intent(out) :: e
    logical, intent(out) :: ok
    real(dp), intent(out) :: r
    real(dp) :: m, ml, th, tl
    ! decimal exponent from the binary one (log10(2) = 0.30103...); the checks of m
    ! below correct the estimate by one either way
    dgt = 0; r = 0.0_dp
    e = floor((binary_exponent(x) - 1)*0.30102999566398120_dp)
    ok = abs(e) <= 21
    if (.not. ok) return
    call scale_by_pow10(x, -e, m, ml)
    ! compared as the double-double: x just below a power of ten can have m = 10 or 1
    ! exactly with ml < 0
    if (m > 10.0_dp .or. (m == 10.0_dp .and. ml >= 0.0_dp)) then
      e = e + 1
      call scale_by_pow10(x, -e, m, ml)
    else if (m < 1.0_dp .or. (m == 1.0_dp .and. ml < 0.0_dp)) then
      e = e - 1
      call scale_by_pow10(x, -e, m, ml)
    end if
    ! m + ml times 10^(nd-1) < 1e17: its high part is a double in [1e16, 1e17) when nd = 17,
    ! an integer; the low part carries the rest
    call two_product(m, pow10(nd - 1), th, tl)
    tl = tl + ml*pow10(nd - 1)
    dgt = nearest_integer(th)
    r = tl + (th - real(dgt, dp))
    dgt = dgt + nearest_integer(r)
    if (dgt >= ipow10(nd)) then
      dgt = dgt/10; e = e + 1
    end if
  end subroutine rounded_digits

  !> The integer nearest v, |v| < 2^63 (halves away from zero, as nint): inline, where
  !> gfortran's nint and anint call the C library's lround and round.
  elemental integer(int64) function nearest_integer(v) result(k)
    real(dp), intent(in) :: v
    real(dp) :: f
    k = int(v, int64)
    f = v - real(k, dp)                   ! exact: k and v share their leading bits
    if (f >= 0.5_dp) then
      k = k + 1
    else if (f <= -0.5_dp) then
      k = k - 1
    end if
  end function nearest_integer

  !> exponent(x) of a finite x /= 0 (x = f 2^e, 0.5 <= |f| < 1) from its bits; a
  !> subnormal x gives -1022, beyond decimal_digits' range as it should be.
  elemental integer function binary_exponent(x) result(e)
    real(dp), intent(in) :: x
    e = int(ibits(transfer(x, 0_int64), 52, 11)) - 1022
  end function binary_exponent

  !> x 10^k as the double-double m + ml, for |k| <= 22 (10^|k| exact): a product by the
  !> power (error-free), or a quotient with its remainder (exact by Sterbenz's lemma).
  pure subroutine scale_by_pow10(x, k, m, ml)
    real(dp), intent(in) :: x
    integer, intent(in) :: k
    real(dp), intent(out) :: m, ml
    real(dp) :: p, ph, pl
    p = pow10(abs(k))
    if (k >= 0) then
      call two_product(x, p, m, ml)
    else
      m = x/p
      call two_product(m, p, ph, pl)
      ml = ((x - ph) - pl)/p
    end if
  end subroutine scale_by_pow10

  !> a b = p + e exactly (Dekker: both factors split into 26-bit halves).
  pure subroutine two_product(a, b, p, e)
    real(dp), intent(in) :: a, b
    real(dp), intent(out) :: p, e
    real(dp), parameter :: splitter = 134217729.0_dp      ! 2^27 + 1
    real(dp) :: c, ah, al, bh, bl
    p = a*b
    c = splitter*a; ah = c - (c - a); al = a - ah
    c = splitter*b; bh = c - (c - b); bl = b - bh
    e = ((ah*bh - p) + ah*bl + al*bh) + al*bl
  end subroutine two_product
end module pymr_env_real_text
