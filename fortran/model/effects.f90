!> Optional physics. Each effect has its own routine; the model calls only those the
!> scene turned on (the plan in model_data%effect_on is fixed at build time).
module pymr_model_effects
  use pymr_kinds, only : dp, pi
  use pymr_model_types, only : model_data, effect_gravity, effect_joint_drives, effect_modal_damping
  use pymr_model_spatial, only : cross
  implicit none
  private
  public :: add_gravity, add_joint_drives, add_modal_damping, gravity_potential, elastic_potential

contains

  !> Centre of mass of body b (inertial; deformed for flexible bodies, after body_terms).
  pure function body_com(d, b) result(c)
    type(model_data), intent(in) :: d
    integer, intent(in) :: b
    real(dp) :: c(3)
    if (d%flexible(b)) then
      c = d%pos(:, b) + matmul(d%rot(:, :, b), d%fwork(b)%s)/d%flex(b)%mass
    else
      c = d%pos(:, b) + matmul(d%rot(:, :, b), d%com(:, b))
    end if
  end function body_com

  !> Subtract the gravity wrench [m g; c x m g] of every body from its bias wrench, and
  !> the modal gravity loads S1^T R^T g from the modal bias of flexible bodies.
  pure subroutine add_gravity(d, only)
    type(model_data), intent(inout) :: d
    !> Restrict to these bodies (the fast rows).
    logical, intent(in), optional :: only(:)
    integer :: b, k
    real(dp) :: c(3), f(3), gb(3)
    do b = 2, d%nb
      if (present(only)) then
        if (.not. only(b)) cycle
      end if
      c = body_com(d, b)
      f = d%mass(b)*d%gravity
      d%w(1:3, b) = d%w(1:3, b) - f
      d%w(4:6, b) = d%w(4:6, b) - cross(c, f)
      if (d%nm(b) == 0) cycle
      gb = matmul(transpose(d%rot(:, :, b)), d%gravity)
      do k = 1, d%nm(b)
        d%wam(k, b) = d%wam(k, b) - dot_product(d%flex(b)%first(:, k), gb)
      end do
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

  !> Modal damping forces 2 zeta omega ad added to the modal bias of flexible bodies.
  pure subroutine add_modal_damping(d, qd)
    type(model_data), intent(inout) :: d
    real(dp), intent(in) :: qd(:)
    integer :: b, m
    do b = 2, d%nb
      m = d%nm(b)
      if (m == 0) cycle
      d%wam(1:m, b) = d%wam(1:m, b) + d%flex(b)%damp*qd(d%a0(b):d%a0(b) + m - 1)
    end do
    d%effect_evals(effect_modal_damping) = d%effect_evals(effect_modal_damping) + 1
  end subroutine add_modal_damping

  !> Gravitational potential energy -sum m g.c (J), after body_terms.
  pure function gravity_potential(d) result(v)
    type(model_data), intent(in) :: d
    real(dp) :: v
    integer :: b
    v = 0.0_dp
    do b = 2, d%nb
      v = v - d%mass(b)*dot_product(d%gravity, body_com(d, b))
    end do
  end function gravity_potential

  !> Elastic energy 1/2 sum omega^2 a^2 of the flexible bodies (J).
  pure function elastic_potential(d, q) result(v)
    type(model_data), intent(in) :: d
    real(dp), intent(in) :: q(:)
    real(dp) :: v
    integer :: b, m
    v = 0.0_dp
    do b = 2, d%nb
      m = d%nm(b)
      if (m == 0) cycle
      v = v + 0.5_dp*sum(d%flex(b)%omega2*q(d%a0(b):d%a0(b) + m - 1)**2)
    end do
  end function elastic_potential
end module pymr_model_effects
