!> Nordsieck-form Adams-Bashforth-Moulton kernels (METHOD.md section 3; paper eqs. 19-32).
!>
!> A Nordsieck array `z(n, 0:3)` holds per component [x, h x', h^2 x''/2, h^3 x'''/6].
!> The predictor is the upper-triangular Pascal matrix (3rd-order Adams-Bashforth),
!> the corrector adds `l * (h f - z(:,1))` with l = [3/8, 1, 3/4, 1/6] (4th-order
!> Adams-Moulton). A step-size change from h to alpha*h scales column j by alpha^j.
!> Rescaling, the value of the polynomial and the in-place Pascal predictor also serve
!> arrays of any width z(n, 0:q) (formula 'adams', orders 1-12).
module pymr_integrator_nordsieck
  use pymr_env_kinds, only : dp
  implicit none
  private
  public :: nq, corrector_l, nordsieck_predict, nordsieck_correct, nordsieck_rescale
  public :: nordsieck_value, nordsieck_from_history, nordsieck_predict_in_place

  !> Highest column of the Nordsieck array (cubic history).
  integer, parameter :: nq = 3
  !> Corrector vector l = T c of the 4th-order Adams-Moulton corrector.
  real(dp), parameter :: corrector_l(0:nq) = [3.0_dp/8.0_dp, 1.0_dp, 3.0_dp/4.0_dp, 1.0_dp/6.0_dp]

contains

  !> Pascal predictor: zp = A z, A(i,j) = binomial(j, i) for j >= i.
  pure subroutine nordsieck_predict(z, zp)
    real(dp), intent(in) :: z(:, 0:)
    real(dp), intent(out) :: zp(:, 0:)
    zp(:, 0) = z(:, 0) + z(:, 1) + z(:, 2) + z(:, 3)
    zp(:, 1) = z(:, 1) + 2.0_dp*z(:, 2) + 3.0_dp*z(:, 3)
    zp(:, 2) = z(:, 2) + 3.0_dp*z(:, 3)
    zp(:, 3) = z(:, 3)
  end subroutine nordsieck_predict

  !> Corrector: z = zp + l * g with g = h f - zp(:,1); returns g for error estimates.
  pure subroutine nordsieck_correct(zp, h, f, z, g)
    !> Predicted Nordsieck array.
    real(dp), intent(in) :: zp(:, 0:)
    !> Step size, and the derivative evaluated at the latest iterate (apart: h*f passed as
    !> one argument was a heap temporary at every step).
    real(dp), intent(in) :: h, f(:)
    !> Corrected Nordsieck array.
    real(dp), intent(out) :: z(:, 0:)
    !> Correction g = h f - zp(:,1).
    real(dp), intent(out) :: g(:)
    integer :: j
    g = h*f - zp(:, 1)
    do j = 0, nq
      z(:, j) = zp(:, j) + corrector_l(j)*g
    end do
  end subroutine nordsieck_correct

  !> Pascal predictor in place, for an array of any width: z_i <- sum_(j>=i) binomial(j, i) z_j
  !> by repeated synthetic division.
  pure subroutine nordsieck_predict_in_place(z)
    real(dp), intent(inout) :: z(:, 0:)
    integer :: k, j, q
    q = ubound(z, 2)
    do k = 1, q
      do j = q, k, -1
        z(:, j - 1) = z(:, j - 1) + z(:, j)
      end do
    end do
  end subroutine nordsieck_predict_in_place

  !> Rescale for a step change h -> alpha*h: column j times alpha**j (C(alpha), eq. 38).
  pure subroutine nordsieck_rescale(z, alpha)
    real(dp), intent(inout) :: z(:, 0:)
    real(dp), intent(in) :: alpha
    integer :: j
    do j = 1, ubound(z, 2)
      z(:, j) = alpha**j*z(:, j)
    end do
  end subroutine nordsieck_rescale

  !> Value of the Nordsieck polynomial at t_n + s*h: x = sum_j z(:,j) s^j (Horner).
  pure subroutine nordsieck_value(z, s, x)
    real(dp), intent(in) :: z(:, 0:)
    real(dp), intent(in) :: s
    real(dp), intent(out) :: x(:)
    integer :: j
    x = z(:, ubound(z, 2))
    do j = ubound(z, 2) - 1, 0, -1
      x = z(:, j) + s*x
    end do
  end subroutine nordsieck_value

  !> Build a Nordsieck array from x_n and the derivatives f_n, f_{n-1}, f_{n-2} at
  !> equally spaced times h apart (transformation T, paper eq. 29).
  pure subroutine nordsieck_from_history(x, f0, f1, f2, h, z)
    real(dp), intent(in) :: x(:), f0(:), f1(:), f2(:)
    real(dp), intent(in) :: h
    real(dp), intent(out) :: z(:, 0:)
    z(:, 0) = x
    z(:, 1) = h*f0
    z(:, 2) = h*(0.75_dp*f0 - f1 + 0.25_dp*f2)
    z(:, 3) = h*(f0 - 2.0_dp*f1 + f2)/6.0_dp
  end subroutine nordsieck_from_history
end module pymr_integrator_nordsieck
