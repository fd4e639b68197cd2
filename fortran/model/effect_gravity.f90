!> Gravity: each body's weight in its bias wrench, and the modal gravity loads of flexible
!> bodies; its potential energy.
module pymr_model_effect_gravity
  use pymr_env_kinds, only : dp
  use pymr_model_types, only : model_data, model_work
  use pymr_model_effect, only : effect_t, stage_load, energy_gravity
  implicit none
  private
  public :: gravity_effect, gravity_effect_of, body_com

  type, extends(effect_t) :: gravity_effect
    !> Gravity (m/s^2, inertial).
    real(dp) :: g(3) = 0.0_dp
  contains
    procedure :: load => gravity_load
    procedure :: add_energy => gravity_energy
  end type gravity_effect

contains

  include 'vector_products.inc'

  !> The gravity effect for gravity g.
  function gravity_effect_of(g) result(e)
    real(dp), intent(in) :: g(3)
    type(gravity_effect) :: e
    e%name = 'gravity'
    e%acts(stage_load) = .true.
    e%g = g
  end function gravity_effect_of

  !> Centre of mass of body b (inertial; deformed for flexible bodies, after body_terms).
  pure function body_com(d, wk, b) result(c)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    integer, intent(in) :: b
    real(dp) :: c(3)
    if (d%flexible(b)) then
      c = wk%pos(:, b) + matmul(wk%rot(:, :, b), wk%fwork(b)%s)/d%flex(b)%mass
    else
      c = wk%pos(:, b) + matmul(wk%rot(:, :, b), d%com(:, b))
    end if
  end function body_com

  !> Subtract the gravity wrench [m g; c x m g] of every body in `mask` from its bias
  !> wrench, and the modal gravity loads S1^T R^T g from the modal bias of flexible bodies.
  subroutine gravity_load(self, d, wk, t, q, qd, mask)
    class(gravity_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: mask(:)
    integer :: b, k
    real(dp) :: c(3), f(3), gb(3)
    do b = 2, d%nb
      if (.not. mask(b)) cycle
      c = body_com(d, wk, b)
      f = d%mass(b)*self%g
      wk%w(1:3, b) = wk%w(1:3, b) - f
      wk%w(4:6, b) = wk%w(4:6, b) - cross(c, f)
      if (d%nm(b) == 0) cycle
      gb = matmul(transpose(wk%rot(:, :, b)), self%g)
      do k = 1, d%nm(b)
        wk%wam(k, b) = wk%wam(k, b) - dot_product(d%flex(b)%first(:, k), gb)
      end do
    end do
  end subroutine gravity_load

  !> Gravitational potential energy -sum m g.c (J), after body_terms.
  subroutine gravity_energy(self, d, wk, q, e)
    class(gravity_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: q(:)
    real(dp), intent(inout) :: e(:)
    integer :: b
    do b = 2, d%nb
      e(energy_gravity) = e(energy_gravity) - d%mass(b)*dot_product(self%g, body_com(d, wk, b))
    end do
  end subroutine gravity_energy
end module pymr_model_effect_gravity
