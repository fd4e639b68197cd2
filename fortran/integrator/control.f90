!> Step-size control: error weights and norms as in CVODE, and the step ratio rule.
module pymr_integrator_control
  use pymr_env_kinds, only : dp
  implicit none
  private
  public :: step_control, error_weights, wrms_norm, error_envelope

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

  !> Accepted steps whose error estimates size the next step (error_envelope).
  integer, parameter, public :: envelope_steps = 8

  !> The last envelope_steps accepted steps' error estimates and steps, for the next step's
  !> size. An estimate measured at one point of the step (the end of a multirate macro step,
  !> the difference of an exponential step's predictor and corrector) swings with the phase
  !> of the vibrations there: on the tank the 'response' macro step's went from 0.01 to 0.8
  !> in consecutive steps of one length. A step grown on a low sample was rejected, or
  !> accepted with more error than asked: on the flexible four-bar ('response', k_max 50,
  !> 17 tolerances from 1e-4 to 1e-8) the crank ended up to 1.4-2.2 rtol away with the last
  !> step's estimate alone, 1.03 with the last four, 0.81 with the last eight; on the tank
  !> ('exponential', rtol 1e-6) the muzzle ended 5.5e-7 m away with the last one, 7e-8 m
  !> with the last four (docs/method.md sections 4.2 and 4.3).
  type :: error_envelope
    real(dp) :: err(envelope_steps) = 0.0_dp, h(envelope_steps) = 0.0_dp
    !> How many are known (0 after a start).
    integer :: n = 0
  contains
    procedure :: of => envelope_of
    procedure :: forget => envelope_forget
  end type error_envelope

contains

  !> The error an accepted step of h (estimate err, O(h^order)) sizes its successor by: the
  !> largest of err and the last envelope_steps accepted steps', each scaled to h as
  !> h^order. err and h are kept for the next, unless `keep` is false: a start's step,
  !> whose estimate is of a lower order (the exponential flow's, through fewer evaluations),
  !> scaled as h^order held the spacecraft's start at 1.3e-5 s for 8 steps.
  function envelope_of(self, err, h, order, keep) result(e)
    class(error_envelope), intent(inout) :: self
    real(dp), intent(in) :: err, h
    integer, intent(in) :: order
    logical, intent(in), optional :: keep
    real(dp) :: e
    integer :: i
    e = err
    do i = 1, self%n
      e = max(e, self%err(i)*(h/self%h(i))**order)
    end do
    if (present(keep)) then
      if (.not. keep) return
    end if
    self%err(2:) = self%err(:envelope_steps - 1); self%h(2:) = self%h(:envelope_steps - 1)
    self%err(1) = err; self%h(1) = h
    self%n = min(self%n + 1, envelope_steps)
  end function envelope_of

  !> No step is known (a start).
  pure subroutine envelope_forget(self)
    class(error_envelope), intent(inout) :: self
    self%err = 0.0_dp; self%h = 0.0_dp; self%n = 0
  end subroutine envelope_forget

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
