!> Step-size control: error weights and norms as in CVODE, and the step ratio rule.
module pymr_integrator_control
  use pymr_env_kinds, only : dp
  implicit none
  private
  public :: step_control, error_weights, wrms_norm

  !> Settings of the adaptive step-size controller.
  type :: step_control
    !> Relative and absolute tolerances of the local error.
    real(dp) :: rtol = 1.0e-6_dp, atol = 1.0e-8_dp
    !> Smallest and largest step (s).
    real(dp) :: h_min = 1.0e-12_dp, h_max = huge(1.0_dp)
    !> Safety factor and bounds of the step ratio after an accepted step.
    real(dp) :: safety = 0.85_dp, grow_max = 4.0_dp, shrink_min = 0.2_dp
    !> Ratios in [1, hold_band) keep the step (no rescale for tiny gains).
    real(dp) :: hold_band = 1.25_dp
    !> &integrator error_norm = 'amplitude': the angular frequency of each coordinate of
    !> the state [q; qd] (rad/s; 0 where none: joint coordinates). Not allocated: 'state'.
    real(dp), allocatable :: omega(:)
  contains
    procedure :: ratio => control_ratio
  end type step_control

contains

  !> Error weights w_i = 1 / (rtol |x_i| + atol) of a state x = [q; qd]. With ctl%omega
  !> (error_norm = 'amplitude') a coordinate of frequency omega > 0 is weighted by its
  !> amplitude A = sqrt(q^2 + (qd/omega)^2): 1 / (rtol A + atol) for q, and omega times
  !> less for qd, whose error moves the amplitude by its 1/omega. `first`: the coordinate of
  !> x(1) among ctl%omega's (default 1; a stepper that weights a part of the state apart).
  pure subroutine error_weights(ctl, x, w, first)
    type(step_control), intent(in) :: ctl
    real(dp), intent(in) :: x(:)
    real(dp), intent(out) :: w(:)
    integer, intent(in), optional :: first
    integer :: m, i0, i
    real(dp) :: om, tol
    w = 1.0_dp/(ctl%rtol*abs(x) + ctl%atol)
    if (.not. allocated(ctl%omega)) return
    m = size(x)/2
    i0 = 0
    if (present(first)) i0 = first - 1
    if (i0 + m > size(ctl%omega)) return
    do i = 1, m
      om = ctl%omega(i0 + i)
      if (om <= 0.0_dp) cycle
      tol = ctl%rtol*hypot(x(i), x(m + i)/om) + ctl%atol
      w(i) = 1.0_dp/tol
      w(m + i) = 1.0_dp/(om*tol)
    end do
  end subroutine error_weights

  !> Weighted root-mean-square norm sqrt(mean((v w)^2)).
  pure function wrms_norm(v, w) result(r)
    real(dp), intent(in) :: v(:), w(:)
    real(dp) :: r
    if (size(v) == 0) then
      r = 0.0_dp
    else
      r = sqrt(sum((v*w)**2)/size(v))
    end if
  end function wrms_norm

  !> Step ratio for a normalised error estimate `err` that is O(h^order) (default 4).
  pure function control_ratio(self, err, accepted, order) result(eta)
    class(step_control), intent(in) :: self
    real(dp), intent(in) :: err
    logical, intent(in) :: accepted
    integer, intent(in), optional :: order
    real(dp) :: eta
    integer :: p
    p = 4
    if (present(order)) p = order
    if (err <= 0.0_dp) then
      eta = self%grow_max
    else
      eta = self%safety*err**(-1.0_dp/p)
    end if
    if (accepted) then
      eta = min(max(eta, 0.5_dp), self%grow_max)
      if (eta >= 1.0_dp .and. eta < self%hold_band) eta = 1.0_dp
    else
      eta = min(max(eta, self%shrink_min), 0.9_dp)
    end if
  end function control_ratio
end module pymr_integrator_control
