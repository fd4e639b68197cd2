!> Joint reactions by Newton-Euler on each subtree: the wrench a joint passes from its
!> parent to its child is the rate of change of the child subtree's momentum less the
!> loads applied to it. From an evaluation's body terms (spatial inertia i6, bias wrench w
!> with the applied loads subtracted, modal coupling mva) and its accelerations qdd, the
!> subtree of body b needs
!>
!>   J_b = sum over bodies i below and at b of  i6_i A_i + mva_i add_i + w_i,
!>
!> A_i the part of body i's spatial acceleration linear in qdd (w_i holds the bias part).
!> The generalised force of joint coordinate k of body b is then s_k . J_b = tau_k, the
!> row k of M qdd = P: the drive and spring load on the coordinate, or the force that
!> holds a prescribed one to its motion.
module pymr_model_reactions
  use pymr_env_kinds, only : dp
  use pymr_model_types, only : model_data, model_work
  use pymr_model_spatial, only : cross
  implicit none
  private
  public :: body_accelerations, joint_wrenches, child_frame_wrench

contains

  !> The parts of the bodies' spatial accelerations linear in qdd (6, nb; inertial Pluecker),
  !> from the base to the leaves: the parent's, its modal columns at the joint point and
  !> the joint's own columns. The whole acceleration adds wk%acc (the bias part).
  pure subroutine body_accelerations(d, wk, qdd, lin)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: qdd(:)
    real(dp), intent(out) :: lin(:, :)
    integer :: b, a, k, l
    lin(:, 1) = 0.0_dp
    do b = 2, d%nb
      a = d%parent(b)
      lin(:, b) = lin(:, a)
      do l = 1, d%nm(a)
        lin(:, b) = lin(:, b) + wk%cm(:, l, b)*qdd(d%a0(a) + l - 1)
      end do
      do k = d%c0(b), d%c0(b) + d%nc(b) - 1
        lin(:, b) = lin(:, b) + wk%s(:, k)*qdd(k)
      end do
    end do
  end subroutine body_accelerations

  !> Wrench jw(:, b) = [f; n_O] that body b's joint passes from the parent to b's subtree
  !> (inertial; moment about the inertial origin), after a full evaluation's body terms.
  !> lin: body_accelerations of qdd; ext: further loads on each body (the loop-closing
  !> joints' wrenches, 6 x nb), when there are such.
  pure subroutine joint_wrenches(d, wk, qdd, lin, jw, ext)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: qdd(:), lin(:, :)
    real(dp), intent(out) :: jw(:, :)
    real(dp), intent(in), optional :: ext(:, :)
    integer :: b, m
    jw(:, 1) = 0.0_dp
    do b = 2, d%nb
      jw(:, b) = matmul(wk%i6(:, :, b), lin(:, b)) + wk%w(:, b)
      m = d%nm(b)
      if (m > 0) jw(:, b) = jw(:, b) + matmul(wk%mva(:, 1:m, b), qdd(d%a0(b):d%a0(b) + m - 1))
      if (present(ext)) jw(:, b) = jw(:, b) - ext(:, b)
    end do
    do b = d%nb, 2, -1
      if (d%parent(b) > 1) jw(:, d%parent(b)) = jw(:, d%parent(b)) + jw(:, b)
    end do
  end subroutine joint_wrenches

  !> Body b's joint wrench in b's own axes, the moment about b's frame origin (the joint
  !> point): [R^T f; R^T (n_O - p x f)].
  pure function child_frame_wrench(d, wk, b, jw) result(r)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    integer, intent(in) :: b
    real(dp), intent(in) :: jw(6)
    real(dp) :: r(6)
    r(1:3) = matmul(transpose(wk%rot(:, :, b)), jw(1:3))
    r(4:6) = matmul(transpose(wk%rot(:, :, b)), jw(4:6) - cross(wk%pos(:, b), jw(1:3)))
  end function child_frame_wrench
end module pymr_model_reactions
