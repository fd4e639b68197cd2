!> Point loads at markers: a half-sine pulse of force along a direction fixed in the
!> marker's body (a follower load).
module pymr_model_effect_firing_load
  use pymr_env_kinds, only : dp, pi
  use pymr_model_types, only : model_data, model_work
  use pymr_model_kinematics, only : forward_kinematics, marker_motion
  use pymr_model_effect, only : effect_t, stage_load, power_loads
  implicit none
  private
  public :: point_load, firing_load_effect, firing_load_effect_of

  !> One load: its marker, unit direction (body frame), peak (N), start and duration (s).
  type :: point_load
    integer :: marker = 0
    real(dp) :: direction(3) = 0.0_dp, peak = 0.0_dp, start = 0.0_dp, duration = 0.0_dp
  end type point_load

  type, extends(effect_t) :: firing_load_effect
    type(point_load), allocatable :: loads(:)
  contains
    procedure :: load => firing_load
    procedure :: add_power => firing_power
  end type firing_load_effect

contains

  include 'vector_products.inc'

  function firing_load_effect_of(loads) result(e)
    type(point_load), intent(in) :: loads(:)
    type(firing_load_effect) :: e
    e%name = 'firing_load'
    e%acts(stage_load) = .true.
    e%loads = loads
  end function firing_load_effect_of

  !> Magnitude (N) of a load at time t: a half-sine pulse.
  pure real(dp) function pulse(ld, t)
    type(point_load), intent(in) :: ld
    real(dp), intent(in) :: t
    pulse = 0.0_dp
    if (t >= ld%start .and. t <= ld%start + ld%duration) pulse = ld%peak*sin(pi*(t - ld%start)/ld%duration)
  end function pulse

  !> Point loads at markers (after kinematics): the force f = R (direction F(t)) at the
  !> marker's point r enters the body's wrench as [f; r x f] and, on a flexible body, the
  !> modal forces Psi(marker)^T (direction F(t)).
  subroutine firing_load(self, d, wk, t, q, qd, mask)
    class(firing_load_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: mask(:)
    integer :: i, b, k, mk
    real(dp) :: fmag, fb(3), f(3), r(3), v(3)
    do i = 1, size(self%loads)
      mk = self%loads(i)%marker
      b = d%markers%body(mk)
      if (.not. mask(b)) cycle
      fmag = pulse(self%loads(i), t)
      if (fmag == 0.0_dp) cycle
      fb = self%loads(i)%direction*fmag
      f = matmul(wk%rot(:, :, b), fb)
      call marker_motion(d, wk, mk, q, qd, r, v)
      wk%w(1:3, b) = wk%w(1:3, b) - f
      wk%w(4:6, b) = wk%w(4:6, b) - cross(r, f)
      do k = 1, d%nm(b)
        wk%wam(k, b) = wk%wam(k, b) - dot_product(d%markers%psi(:, k, mk), fb)
      end do
    end do
  end subroutine firing_load

  !> Power of the loads: the force at each loaded marker times its velocity (runs the
  !> kinematics at (q, qd)).
  subroutine firing_power(self, d, wk, t, q, qd, p)
    class(firing_load_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(inout) :: p(:)
    integer :: i, mk
    real(dp) :: r(3), v(3), f, sum_p
    if (size(self%loads) == 0) return
    call forward_kinematics(d, wk, q, qd)
    sum_p = 0.0_dp
    do i = 1, size(self%loads)
      f = pulse(self%loads(i), t)
      if (f == 0.0_dp) cycle
      mk = self%loads(i)%marker
      call marker_motion(d, wk, mk, q, qd, r, v)
      sum_p = sum_p + f*dot_product(matmul(wk%rot(:, :, d%markers%body(mk)), self%loads(i)%direction), v)
    end do
    p(power_loads) = p(power_loads) + sum_p
  end subroutine firing_power
end module pymr_model_effect_firing_load
