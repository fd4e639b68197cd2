!> Recursive kinematics from the base to the leaves (paper eqs. 8-11, 14): body
!> orientation and origin, spatial velocity, spatial bias acceleration (the acceleration
!> with all qdd = 0) and the spatial column of every coordinate. Cost O(n).
module pymr_model_kinematics
  use pymr_kinds, only : dp
  use pymr_model_types, only : model_data, prim_revolute
  use pymr_model_spatial, only : cross, rot_axis, motion_cross
  implicit none
  private
  public :: forward_kinematics, marker_motion

contains

  !> Positions, velocities, bias accelerations and coordinate columns for state (q, qd).
  pure subroutine forward_kinematics(d, q, qd)
    type(model_data), intent(inout) :: d
    !> Joint coordinates and rates.
    real(dp), intent(in) :: q(:), qd(:)
    integer :: b, a, k
    real(dp) :: rf(3, 3), pf(3), vf(6), af(6), u(3), sk(6)
    d%rot(:, :, 1) = 0.0_dp
    do k = 1, 3
      d%rot(k, k, 1) = 1.0_dp
    end do
    d%pos(:, 1) = 0.0_dp; d%vel(:, 1) = 0.0_dp; d%acc(:, 1) = 0.0_dp
    do b = 2, d%nb
      a = d%parent(b)
      rf = d%rot(:, :, a)
      pf = d%pos(:, a) + matmul(rf, d%at(:, b))
      vf = d%vel(:, a); af = d%acc(:, a)
      do k = d%c0(b), d%c0(b) + d%nc(b) - 1
        u = matmul(rf, d%axis(:, k))
        if (d%prim(k) == prim_revolute) then
          sk(1:3) = cross(pf, u); sk(4:6) = u
          rf = matmul(rf, rot_axis(d%axis(:, k), q(k)))
        else
          sk(1:3) = u; sk(4:6) = 0.0_dp
          pf = pf + u*q(k)
        end if
        vf = vf + sk*qd(k)
        af = af + motion_cross(vf, sk)*qd(k)
        d%s(:, k) = sk
      end do
      d%rot(:, :, b) = rf; d%pos(:, b) = pf; d%vel(:, b) = vf; d%acc(:, b) = af
    end do
  end subroutine forward_kinematics

  !> Inertial position and velocity of marker m (after forward_kinematics).
  pure subroutine marker_motion(d, m, r, v)
    type(model_data), intent(in) :: d
    integer, intent(in) :: m
    real(dp), intent(out) :: r(3), v(3)
    integer :: b
    b = d%marker_body(m)
    r = d%pos(:, b) + matmul(d%rot(:, :, b), d%marker_at(:, m))
    v = d%vel(1:3, b) + cross(d%vel(4:6, b), r)
  end subroutine marker_motion
end module pymr_model_kinematics
