!> The mechanism's geometry for drawing (pymr.geometry: pymr export, animate, view): the
!> kinematics at a state whose modal coordinates are scaled (deflections magnified), the
!> points of a flexible body's centre line and their mode shapes, and the joints' places
!> and axes. The kinematics are the model's own (forward_kinematics); nothing here states
!> another rule of motion.
module pymr_bind_drawing
  use pymr_env_kinds, only : dp
  use pymr_model, only : model_t
  use pymr_model_types, only : model_data, prim_revolute, cut_free
  use pymr_model_kinematics, only : forward_kinematics
  use pymr_model_beam_modes, only : beam_point_shapes
  implicit none
  private
  public :: scaled_kinematics, line_points, joint_place, n_line_points

contains

  !> Forward kinematics at (t, q, qd) with every flexible body's modal coordinates (and
  !> rates) multiplied by `exaggerate` (1: the state as it is).
  subroutine scaled_kinematics(model, t, q, qd, exaggerate)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, q(:), qd(:), exaggerate
    real(dp) :: qs(size(q)), qds(size(qd))
    integer :: b
    qs = q; qds = qd
    do b = 2, model%d%nb
      if (model%d%nm(b) == 0) cycle
      associate(i0 => model%d%a0(b), i1 => model%d%a0(b) + model%d%nm(b) - 1)
        qs(i0:i1) = exaggerate*q(i0:i1); qds(i0:i1) = exaggerate*qd(i0:i1)
      end associate
    end do
    call model%impose(t, qs, qds)
    call forward_kinematics(model%d, model%wk, model%wk%qx, model%wk%qdx)
  end subroutine scaled_kinematics

  !> Number of points of body b's centre line: a modal-file body's nodes; a beam's `np`
  !> asked for (at least 2); 0 for a rigid body or the ground.
  integer function n_line_points(d, b, np) result(k)
    type(model_data), intent(in) :: d
    integer, intent(in) :: b, np
    k = 0
    if (d%nm(b) == 0 .and. .not. d%flexible(b)) return
    if (d%bshape(b)%ne > 0) then
      k = max(np, 2)
    else
      k = d%mnodes(b)%np
    end if
  end function n_line_points

  !> Point p (1..np) of flexible body b's centre line: its undeformed place x0 (body frame)
  !> and its translational mode shapes psi (3 x nm): a beam's axis at x = L (p-1)/(np-1), a
  !> modal-file body's node p.
  subroutine line_points(d, b, p, np, x0, psi)
    type(model_data), intent(in) :: d
    integer, intent(in) :: b, p, np
    real(dp), intent(out) :: x0(3), psi(:, :)
    real(dp) :: phi(3, size(psi, 2))
    if (d%bshape(b)%ne > 0) then
      x0 = [d%bshape(b)%length*real(p - 1, dp)/real(np - 1, dp), 0.0_dp, 0.0_dp]
      call beam_point_shapes(d%bshape(b), x0, psi, phi)
    else
      x0 = d%mnodes(b)%x(:, p)
      psi = d%mnodes(b)%psi(:, :, p)
    end if
  end subroutine line_points

  !> Place and unit axis (inertial; after forward_kinematics) of joint j: j = 1 .. nb-1 the
  !> tree joint of body j+1 (at the child's origin; the axis its coordinates share, as a
  !> revolute, prismatic or cylindrical joint's, else zero: fixed, spherical, universal,
  !> planar, free), then the loops' cut joints (at the parent's point; its axis,
  !> zero for a free cut).
  subroutine joint_place(model, j, pos, axis)
    type(model_t), intent(in) :: model
    integer, intent(in) :: j
    real(dp), intent(out) :: pos(3), axis(3)
    integer :: b, k, c
    axis = 0.0_dp
    associate(d => model%d, wk => model%wk)
      if (j <= d%nb - 1) then
        b = j + 1
        pos = wk%pos(:, b)
        if (d%nc(b) == 0) return
        k = d%c0(b)
        if (any(abs(d%axis(:, k:k + d%nc(b) - 1) - spread(d%axis(:, k), 2, d%nc(b))) > 1.0e-12_dp)) return
        if (d%prim(k) == prim_revolute) then
          axis = wk%s(4:6, k)
        else
          axis = wk%s(1:3, k)
        end if
      else
        c = j - (d%nb - 1)
        if (d%cuts%kind(c) == cut_free) then
          pos = wk%pos(:, d%cuts%parent(c)) + matmul(wk%rot(:, :, d%cuts%parent(c)), d%cuts%at(:, c))
          return
        end if
        pos = wk%loops%pos(:, 1, c)
        axis = matmul(wk%loops%rot(:, :, 1, c), d%cuts%axis(:, c))
      end if
    end associate
    if (norm2(axis) > 0.0_dp) axis = axis/norm2(axis)
  end subroutine joint_place
end module pymr_bind_drawing
