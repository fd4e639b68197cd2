!> Time histories given as tables (t_i, y_i): drives interpolate them linearly; prescribed
!> motions through a natural cubic spline, whose value, rate and acceleration are
!> continuous (a prescribed coordinate needs all three). A spring's force-deflection table
!> (&force file) is a table too, its first column the deflection: interpolated linearly and
!> continued by its end segments' lines, with the exact integral of that line for its energy.
module pymr_model_time_table
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_input
  use pymr_env_text, only : fmt
  use pymr_env_lapack, only : ptsv
  implicit none
  private
  public :: time_table, table_linear, spline_setup, table_spline, table_extended, table_extended_integral

  !> Strictly increasing times t (s), values y and, for a spline, the second derivatives y2.
  type :: time_table
    real(dp), allocatable :: t(:), y(:), y2(:)
  end type time_table

contains

  !> Index i of the interval [t(i), t(i+1)] holding x (1 or n-1 outside the table).
  pure integer function interval(t, x)
    real(dp), intent(in) :: t(:), x
    integer :: lo, hi, mid
    lo = 1; hi = size(t)
    do while (hi - lo > 1)
      mid = (lo + hi)/2
      if (x < t(mid)) then
        hi = mid
      else
        lo = mid
      end if
    end do
    interval = lo
  end function interval

  !> Linear interpolation at x; the end values hold before and after the table.
  pure real(dp) function table_linear(tb, x) result(f)
    type(time_table), intent(in) :: tb
    real(dp), intent(in) :: x
    integer :: i, n
    n = size(tb%t)
    if (x <= tb%t(1)) then
      f = tb%y(1)
    else if (x >= tb%t(n)) then
      f = tb%y(n)
    else
      i = interval(tb%t, x)
      f = tb%y(i) + (tb%y(i + 1) - tb%y(i))*(x - tb%t(i))/(tb%t(i + 1) - tb%t(i))
    end if
  end function table_linear

  !> Linear interpolation at x, continued outside the table by the lines of its first and
  !> last segments.
  pure real(dp) function table_extended(tb, x) result(f)
    type(time_table), intent(in) :: tb
    real(dp), intent(in) :: x
    integer :: i
    i = interval(tb%t, x)
    f = tb%y(i) + (tb%y(i + 1) - tb%y(i))*(x - tb%t(i))/(tb%t(i + 1) - tb%t(i))
  end function table_extended

  !> The integral of table_extended from a to b: exact (trapezoids over the segments, the
  !> function being linear on each).
  pure real(dp) function table_extended_integral(tb, a, b) result(s)
    type(time_table), intent(in) :: tb
    real(dp), intent(in) :: a, b
    s = from_start(b) - from_start(a)
  contains
    !> The integral from the table's first abscissa to x.
    pure real(dp) function from_start(x) result(v)
      real(dp), intent(in) :: x
      integer :: i, k
      i = interval(tb%t, x)
      v = 0.0_dp
      do k = 1, i - 1
        v = v + 0.5_dp*(tb%t(k + 1) - tb%t(k))*(tb%y(k) + tb%y(k + 1))
      end do
      v = v + 0.5_dp*(x - tb%t(i))*(tb%y(i) + table_extended(tb, x))
    end function from_start
  end function table_extended_integral

  !> Second derivatives of the natural cubic spline through the table (y2 = 0 at both
  !> ends): the tridiagonal system h(i-1) y2(i-1) + 2 (h(i-1) + h(i)) y2(i) + h(i) y2(i+1)
  !> = 6 (slope(i) - slope(i-1)), solved with LAPACK dptsv.
  subroutine spline_setup(tb, what, error)
    type(time_table), intent(inout) :: tb
    character(len=*), intent(in) :: what
    type(error_type), allocatable, intent(out) :: error
    integer :: n, i
    real(dp), allocatable :: h(:), dg(:), e(:), r(:)
    n = size(tb%t)
    allocate(tb%y2(n))
    tb%y2 = 0.0_dp
    if (n < 3) return
    h = tb%t(2:n) - tb%t(1:n - 1)
    dg = 2.0_dp*(h(1:n - 2) + h(2:n - 1))
    e = h(2:n - 2)
    allocate(r(n - 2))
    do i = 2, n - 1
      r(i - 1) = 6.0_dp*((tb%y(i + 1) - tb%y(i))/h(i) - (tb%y(i) - tb%y(i - 1))/h(i - 1))
    end do
    ! times so close that the slopes beside them overflow LAPACK: the table's fault
    i = maxloc(abs(r), 1) + 1
    if (.not. abs(r(i - 1)) <= 1.0e150_dp) then
      call fatal_error(error, what // ': the spline through the table cannot be formed: its slope changes by ' // &
        & fmt(r(i - 1)/6.0_dp) // ' at the time ' // fmt(tb%t(i)) // ' (the rows there are ' // fmt(h(i - 1)) // &
        & ' and ' // fmt(h(i)) // ' apart): give rows farther apart in time', stat_input); return
    end if
    call ptsv(dg, e, r, 'the spline of ' // what, error)
    if (allocated(error)) return
    tb%y2(2:n - 1) = r
  end subroutine spline_setup

  !> Value f, rate fd and acceleration fdd of the spline at x. Outside the table the
  !> spline continues as the straight line of its end value and slope (its curvature is
  !> zero there, so f, fd and fdd stay continuous).
  pure subroutine table_spline(tb, x, f, fd, fdd)
    type(time_table), intent(in) :: tb
    real(dp), intent(in) :: x
    real(dp), intent(out) :: f, fd, fdd
    integer :: i, n
    real(dp) :: h, a, b, xe
    n = size(tb%t)
    xe = min(max(x, tb%t(1)), tb%t(n))
    i = interval(tb%t, xe)
    h = tb%t(i + 1) - tb%t(i)
    a = (tb%t(i + 1) - xe)/h
    b = 1.0_dp - a
    f = a*tb%y(i) + b*tb%y(i + 1) + ((a**3 - a)*tb%y2(i) + (b**3 - b)*tb%y2(i + 1))*h**2/6.0_dp
    fd = (tb%y(i + 1) - tb%y(i))/h - (3.0_dp*a**2 - 1.0_dp)*h/6.0_dp*tb%y2(i) &
      & + (3.0_dp*b**2 - 1.0_dp)*h/6.0_dp*tb%y2(i + 1)
    fdd = a*tb%y2(i) + b*tb%y2(i + 1)
    if (x /= xe) then
      f = f + fd*(x - xe)
    end if
  end subroutine table_spline
end module pymr_model_time_table
