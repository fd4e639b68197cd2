!> Optional physics. Each effect has its own routine; the model calls only those the
!> scene turned on (the plan in model_data%effect_on is fixed at build time).
module pymr_model_effects
  use pymr_kinds, only : dp, pi
  use pymr_model_types, only : model_data, effect_gravity, effect_joint_drives
  use pymr_model_spatial, only : cross
  implicit none
  private
  public :: add_gravity, add_joint_drives, gravity_potential

contains

  !> Subtract the gravity wrench [m g; c x m g] of every body from its bias wrench.
  pure subroutine add_gravity(d)
    type(model_data), intent(inout) :: d
    integer :: b
    real(dp) :: c(3), f(3)
    do b = 2, d%nb
      c = d%pos(:, b) + matmul(d%rot(:, :, b), d%com(:, b))
      f = d%mass(b)*d%gravity
      d%w(1:3, b) = d%w(1:3, b) - f
      d%w(4:6, b) = d%w(4:6, b) - cross(c, f)
    end do
    d%effect_evals(effect_gravity) = d%effect_evals(effect_gravity) + 1
  end subroutine add_gravity

  !> Add the drive loads offset + amplitude sin(2 pi f t + phase) to the generalised forces.
  pure subroutine add_joint_drives(d, t)
    type(model_data), intent(inout) :: d
    real(dp), intent(in) :: t
    integer :: i
    do i = 1, d%n_drives
      associate(p => d%drive_par(:, i))
        d%tau(d%drive_coord(i)) = d%tau(d%drive_coord(i)) + p(1) + p(2)*sin(2.0_dp*pi*p(3)*t + p(4))
      end associate
    end do
    d%effect_evals(effect_joint_drives) = d%effect_evals(effect_joint_drives) + 1
  end subroutine add_joint_drives

  !> Gravitational potential energy -sum m g.c (J), after forward kinematics.
  pure function gravity_potential(d) result(v)
    type(model_data), intent(in) :: d
    real(dp) :: v
    integer :: b
    v = 0.0_dp
    do b = 2, d%nb
      v = v - d%mass(b)*dot_product(d%gravity, d%pos(:, b) + matmul(d%rot(:, :, b), d%com(:, b)))
    end do
  end function gravity_potential
end module pymr_model_effects
