!> Small 3-D and spatial-vector helpers.
!>
!> Spatial vectors are Pluecker vectors in inertial coordinates, ordered as in the
!> paper's state vector Yhat = [rd + r~ w; w]: motion [v_O; w] (velocity of the body
!> point at the inertial origin, angular velocity) and force [f; n_O] (force, moment
!> about the inertial origin), so that power is the plain dot product.
module pymr_model_spatial
  use pymr_env_kinds, only : dp
  implicit none
  private
  public :: cross, skew, motion_cross, rigid_inertia, unit_axes, quaternion, rotation_vector

  !> Unit vectors e_x, e_y, e_z as columns.
  real(dp), parameter :: unit_axes(3, 3) = reshape([1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp, &
    & 0.0_dp, 0.0_dp, 1.0_dp], [3, 3])

contains

  include 'vector_products.inc'

  !> Skew matrix a~ with a~ b = a x b.
  pure function skew(a) result(s)
    real(dp), intent(in) :: a(3)
    real(dp) :: s(3, 3)
    s(1, 1) = 0.0_dp; s(2, 1) = a(3); s(3, 1) = -a(2)
    s(1, 2) = -a(3); s(2, 2) = 0.0_dp; s(3, 2) = a(1)
    s(1, 3) = a(2); s(2, 3) = -a(1); s(3, 3) = 0.0_dp
  end function skew

  !> Rotation vector theta (axis times angle, angle in [0, pi]) of rotation matrix r
  !> (r = exp(theta~)), from its quaternion [w, u] (w >= 0): 2 atan2(|u|, w) u/|u|. Right
  !> up to pi, where the skew part of r, sin(angle) times the axis, vanishes and gives the
  !> axis no longer (at pi both signs are the same rotation).
  pure function rotation_vector(r) result(th)
    real(dp), intent(in) :: r(3, 3)
    real(dp) :: th(3), qt(4), s
    qt = quaternion(r)
    s = norm2(qt(2:4))
    th = 2.0_dp*qt(2:4)
    if (s > 0.0_dp) th = qt(2:4)*(2.0_dp*atan2(s, qt(1))/s)
  end function rotation_vector

  !> Spatial inertia (6x6) about the inertial origin of a rigid body of mass m with
  !> centre of mass c (inertial) and inertia ic (3x3 about the centre of mass, inertial axes).
  pure function rigid_inertia(m, c, ic) result(i6)
    real(dp), intent(in) :: m, c(3), ic(3, 3)
    real(dp) :: i6(6, 6), cx(3, 3)
    integer :: k
    cx = skew(c)
    i6 = 0.0_dp
    do k = 1, 3
      i6(k, k) = m
    end do
    i6(1:3, 4:6) = -m*cx
    i6(4:6, 1:3) = m*cx
    i6(4:6, 4:6) = ic - m*matmul(cx, cx)
  end function rigid_inertia

  !> Unit quaternion [w, x, y, z] (w >= 0) of rotation matrix r, from its largest
  !> component (Shepperd), so that no square root of a small number is taken.
  pure function quaternion(r) result(qt)
    real(dp), intent(in) :: r(3, 3)
    real(dp) :: qt(4), tr, s
    tr = r(1, 1) + r(2, 2) + r(3, 3)
    if (tr >= max(r(1, 1), r(2, 2), r(3, 3))) then
      s = 2.0_dp*sqrt(1.0_dp + tr)
      qt = [0.25_dp*s, (r(3, 2) - r(2, 3))/s, (r(1, 3) - r(3, 1))/s, (r(2, 1) - r(1, 2))/s]
    else if (r(1, 1) >= r(2, 2) .and. r(1, 1) >= r(3, 3)) then
      s = 2.0_dp*sqrt(1.0_dp + r(1, 1) - r(2, 2) - r(3, 3))
      qt = [(r(3, 2) - r(2, 3))/s, 0.25_dp*s, (r(1, 2) + r(2, 1))/s, (r(1, 3) + r(3, 1))/s]
    else if (r(2, 2) >= r(3, 3)) then
      s = 2.0_dp*sqrt(1.0_dp + r(2, 2) - r(1, 1) - r(3, 3))
      qt = [(r(1, 3) - r(3, 1))/s, (r(1, 2) + r(2, 1))/s, 0.25_dp*s, (r(2, 3) + r(3, 2))/s]
    else
      s = 2.0_dp*sqrt(1.0_dp + r(3, 3) - r(1, 1) - r(2, 2))
      qt = [(r(2, 1) - r(1, 2))/s, (r(1, 3) + r(3, 1))/s, (r(2, 3) + r(3, 2))/s, 0.25_dp*s]
    end if
    qt = qt/norm2(qt)
    if (qt(1) < 0.0_dp) qt = -qt
  end function quaternion
end module pymr_model_spatial
