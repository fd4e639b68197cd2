!> SHA-256 digests (FIPS 180-4) of strings, as 64 lower-case hex digits.
!>
!> The 32-bit words are held in 64-bit integers and masked to 32 bits after every
!> addition, so no arithmetic overflows. Whole 64-byte blocks are hashed straight from
!> the text; only the last one or two (with the padding and length) are copied.
module pymr_io_sha256
  use, intrinsic :: iso_fortran_env, only : int64
  implicit none
  private
  public :: sha256_hex

  !> The low 32 bits of a 64-bit integer.
  integer(int64), parameter :: m32 = int(z'FFFFFFFF', int64)

  !> Round constants: the first 32 bits of the fractional parts of the cube roots of
  !> the first 64 primes.
  integer(int64), parameter :: k(0:63) = [ &
    & int(z'428a2f98', int64), int(z'71374491', int64), int(z'b5c0fbcf', int64), int(z'e9b5dba5', int64), &
    & int(z'3956c25b', int64), int(z'59f111f1', int64), int(z'923f82a4', int64), int(z'ab1c5ed5', int64), &
    & int(z'd807aa98', int64), int(z'12835b01', int64), int(z'243185be', int64), int(z'550c7dc3', int64), &
    & int(z'72be5d74', int64), int(z'80deb1fe', int64), int(z'9bdc06a7', int64), int(z'c19bf174', int64), &
    & int(z'e49b69c1', int64), int(z'efbe4786', int64), int(z'0fc19dc6', int64), int(z'240ca1cc', int64), &
    & int(z'2de92c6f', int64), int(z'4a7484aa', int64), int(z'5cb0a9dc', int64), int(z'76f988da', int64), &
    & int(z'983e5152', int64), int(z'a831c66d', int64), int(z'b00327c8', int64), int(z'bf597fc7', int64), &
    & int(z'c6e00bf3', int64), int(z'd5a79147', int64), int(z'06ca6351', int64), int(z'14292967', int64), &
    & int(z'27b70a85', int64), int(z'2e1b2138', int64), int(z'4d2c6dfc', int64), int(z'53380d13', int64), &
    & int(z'650a7354', int64), int(z'766a0abb', int64), int(z'81c2c92e', int64), int(z'92722c85', int64), &
    & int(z'a2bfe8a1', int64), int(z'a81a664b', int64), int(z'c24b8b70', int64), int(z'c76c51a3', int64), &
    & int(z'd192e819', int64), int(z'd6990624', int64), int(z'f40e3585', int64), int(z'106aa070', int64), &
    & int(z'19a4c116', int64), int(z'1e376c08', int64), int(z'2748774c', int64), int(z'34b0bcb5', int64), &
    & int(z'391c0cb3', int64), int(z'4ed8aa4a', int64), int(z'5b9cca4f', int64), int(z'682e6ff3', int64), &
    & int(z'748f82ee', int64), int(z'78a5636f', int64), int(z'84c87814', int64), int(z'8cc70208', int64), &
    & int(z'90befffa', int64), int(z'a4506ceb', int64), int(z'bef9a3f7', int64), int(z'c67178f2', int64)]

  !> Initial hash value: the first 32 bits of the fractional parts of the square roots
  !> of the first 8 primes.
  integer(int64), parameter :: h0(0:7) = [ &
    & int(z'6a09e667', int64), int(z'bb67ae85', int64), int(z'3c6ef372', int64), int(z'a54ff53a', int64), &
    & int(z'510e527f', int64), int(z'9b05688c', int64), int(z'1f83d9ab', int64), int(z'5be0cd19', int64)]

contains

  !> Lower-case hex SHA-256 digest of the bytes of text.
  pure function sha256_hex(text) result(hex)
    character(len=*), intent(in) :: text
    character(len=64) :: hex
    character(len=*), parameter :: digits = '0123456789abcdef'
    character(len=128) :: tail
    integer(int64) :: h(0:7), nbits
    integer :: n, nfull, rem, ntail, b, i, j, d
    n = len(text)
    nfull = n/64
    h = h0
    do b = 0, nfull - 1
      call compress(h, text(64*b+1:64*b+64))
    end do
    ! the rest of the text, a 1 bit, zeros, and the length in bits (64-bit big-endian)
    rem = n - 64*nfull
    ntail = merge(64, 128, rem < 56)
    tail = repeat(achar(0), 128)
    tail(1:rem) = text(64*nfull+1:n)
    tail(rem+1:rem+1) = char(128)
    nbits = 8_int64*n
    do i = 0, 7
      tail(ntail-i:ntail-i) = char(int(iand(shiftr(nbits, 8*i), 255_int64)))
    end do
    do b = 0, ntail/64 - 1
      call compress(h, tail(64*b+1:64*b+64))
    end do
    do i = 0, 7
      do j = 0, 7
        d = int(iand(shiftr(h(i), 28-4*j), 15_int64)) + 1
        hex(8*i+j+1:8*i+j+1) = digits(d:d)
      end do
    end do
  end function sha256_hex

  !> Update the hash value h with one 64-byte block.
  pure subroutine compress(h, block)
    integer(int64), intent(inout) :: h(0:7)
    character(len=64), intent(in) :: block
    integer(int64) :: w(0:63), s(0:7), t1, t2
    integer :: i
    do i = 0, 15
      w(i) = ior(ior(shiftl(byte(block, 4*i+1), 24), shiftl(byte(block, 4*i+2), 16)), &
        & ior(shiftl(byte(block, 4*i+3), 8), byte(block, 4*i+4)))
    end do
    do i = 16, 63
      w(i) = iand(small_sigma1(w(i-2)) + w(i-7) + small_sigma0(w(i-15)) + w(i-16), m32)
    end do
    s = h
    do i = 0, 63
      t1 = s(7) + big_sigma1(s(4)) + choose(s(4), s(5), s(6)) + k(i) + w(i)
      t2 = big_sigma0(s(0)) + majority(s(0), s(1), s(2))
      s(1:7) = s(0:6)
      s(4) = iand(s(4) + t1, m32)
      s(0) = iand(t1 + t2, m32)
    end do
    h = iand(h + s, m32)
  end subroutine compress

  !> Byte i of str as an integer 0 ... 255.
  pure integer(int64) function byte(str, i)
    character(len=*), intent(in) :: str
    integer, intent(in) :: i
    byte = iand(int(ichar(str(i:i)), int64), 255_int64)
  end function byte

  !> Rotate the 32-bit word x right by n bits.
  pure integer(int64) function rotr(x, n)
    integer(int64), intent(in) :: x
    integer, intent(in) :: n
    rotr = ior(shiftr(x, n), iand(shiftl(x, 32-n), m32))
  end function rotr

  !> Bits of y where x is set, of z where it is not.
  pure integer(int64) function choose(x, y, z)
    integer(int64), intent(in) :: x, y, z
    choose = ieor(iand(x, y), iand(ieor(x, m32), z))
  end function choose

  !> Majority vote of the bits of x, y and z.
  pure integer(int64) function majority(x, y, z)
    integer(int64), intent(in) :: x, y, z
    majority = ieor(ieor(iand(x, y), iand(x, z)), iand(y, z))
  end function majority

  !> FIPS 180-4 (4.4): the upper-case sigma 0 of x.
  pure integer(int64) function big_sigma0(x)
    integer(int64), intent(in) :: x
    big_sigma0 = ieor(ieor(rotr(x, 2), rotr(x, 13)), rotr(x, 22))
  end function big_sigma0

  !> FIPS 180-4 (4.5): the upper-case sigma 1 of x.
  pure integer(int64) function big_sigma1(x)
    integer(int64), intent(in) :: x
    big_sigma1 = ieor(ieor(rotr(x, 6), rotr(x, 11)), rotr(x, 25))
  end function big_sigma1

  !> FIPS 180-4 (4.6): the lower-case sigma 0 of x.
  pure integer(int64) function small_sigma0(x)
    integer(int64), intent(in) :: x
    small_sigma0 = ieor(ieor(rotr(x, 7), rotr(x, 18)), shiftr(x, 3))
  end function small_sigma0

  !> FIPS 180-4 (4.7): the lower-case sigma 1 of x.
  pure integer(int64) function small_sigma1(x)
    integer(int64), intent(in) :: x
    small_sigma1 = ieor(ieor(rotr(x, 17), rotr(x, 19)), shiftr(x, 10))
  end function small_sigma1

end module pymr_io_sha256
