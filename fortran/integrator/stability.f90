!> Linear stability of the Nordsieck ABM PECE step (METHOD.md section 3), computed from
!> the method itself: applied to x' = lambda x with q = lambda h, one step maps the
!> Nordsieck vector z to G(q) z, G(q) = (I + l (q e_0^T - e_1^T)) A with A the Pascal
!> predictor and l the corrector vector. The step is stable when the spectral radius of
!> G(q) is at most 1. On the imaginary axis this holds up to |q| = 0.4299, on the negative
!> real axis down to q = -0.300.
module pymr_integrator_stability
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type
  use pymr_env_lapack, only : geev_complex
  use pymr_integrator_nordsieck, only : nq, corrector_l
  implicit none
  private
  public :: pece_growth, pece_limit, undamped_limit

  !> A step counts as stable while the growth factor is at most 1 + growth_tol.
  real(dp), parameter :: growth_tol = 1.0e-12_dp
  !> |q| up to which the step is stable on the imaginary axis: pece_limit((0, 1)), which
  !> the suite checks against it (test_integrator.py); held here so that a stepper's
  !> bound on an undamped mode costs no search (70 eigenvalue problems).
  real(dp), parameter, public :: imaginary_axis_limit = 0.42998707991_dp

contains

  !> Spectral radius of the PECE amplification matrix G(q).
  function pece_growth(q) result(r)
    complex(dp), intent(in) :: q
    real(dp) :: r
    complex(dp) :: a(0:nq, 0:nq), c(0:nq, 0:nq), g(0:nq, 0:nq), w(0:nq)
    type(error_type), allocatable :: error
    integer :: i, j
    a = (0.0_dp, 0.0_dp)
    do j = 0, nq
      do i = 0, j
        a(i, j) = binomial(j, i)
      end do
    end do
    c = (0.0_dp, 0.0_dp)
    do i = 0, nq
      c(i, i) = (1.0_dp, 0.0_dp)
    end do
    c(:, 0) = c(:, 0) + corrector_l*q
    c(:, 1) = c(:, 1) - corrector_l
    g = matmul(c, a)
    call geev_complex(g, w, 'the PECE amplification matrix', error)
    r = huge(1.0_dp)
    if (.not. allocated(error)) r = maxval(abs(w))
  contains
    pure real(dp) function binomial(n, k)
      integer, intent(in) :: n, k
      integer :: m
      binomial = 1.0_dp
      do m = 1, k
        binomial = binomial*real(n - k + m, dp)/real(m, dp)
      end do
    end function binomial
  end function pece_growth

  !> Largest step h such that every step up to h is stable for the eigenvalue lambda
  !> (Re lambda <= 0): a scan outward along the ray q = lambda h, then bisection.
  function pece_limit(lambda) result(h)
    complex(dp), intent(in) :: lambda
    real(dp) :: h
    real(dp) :: lo, hi, mid
    integer :: it
    lo = 0.0_dp; hi = 0.05_dp/abs(lambda)
    do while (pece_growth(lambda*hi) <= 1.0_dp + growth_tol)
      lo = hi; hi = hi + 0.05_dp/abs(lambda)
      if (hi*abs(lambda) > 10.0_dp) exit
    end do
    do it = 1, 60
      mid = 0.5_dp*(lo + hi)
      if (pece_growth(lambda*mid) <= 1.0_dp + growth_tol) then
        lo = mid
      else
        hi = mid
      end if
    end do
    h = lo
  end function pece_limit

  !> The largest stable step on an undamped mode of angular frequency omega > 0:
  !> pece_limit((0, omega)), by the method's scaling in q = lambda h.
  pure real(dp) function undamped_limit(omega) result(h)
    real(dp), intent(in) :: omega
    h = imaginary_axis_limit/omega
  end function undamped_limit
end module pymr_integrator_stability
