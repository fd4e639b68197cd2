!> Recursive kinematics from the base to the leaves (paper eqs. 8-11, 14): body
!> orientation and origin, spatial velocity, spatial bias acceleration (the acceleration
!> with all qdd = 0) and the spatial column of every coordinate. Cost O(n).
!>
!> A child of a flexible body is attached to a point of it: the joint frame moves with
!> the point's deflection Psi a and turns with its small rotation exp((Phi a)~) (paper
!> eqs. 8-9); the parent's modal rates enter the child's velocity through the columns cm.
!> The points of the loop-closing joints (model/loops.f90) get their frames by the same
!> rule (flexible_frame), after the tree.
module pymr_model_kinematics
  use pymr_env_kinds, only : dp
  use pymr_model_types, only : model_data, model_work, prim_revolute, cut_free
  use pymr_model_flexbody, only : small_rotation
  implicit none
  private
  public :: forward_kinematics, marker_motion, marker_acceleration, marker_rotation

contains

  include 'vector_products.inc'

  !> Positions, velocities, bias accelerations and coordinate columns for state (q, qd).
  pure subroutine forward_kinematics(d, wk, q, qd)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    !> Coordinates and rates (joint coordinates, then modal coordinates).
    real(dp), intent(in) :: q(:), qd(:)
    integer :: b, a, k, m, c
    real(dp) :: rf(3, 3), pf(3), vf(6), af(6), u(3), sk(6)
    wk%rot(:, :, 1) = 0.0_dp
    do k = 1, 3
      wk%rot(k, k, 1) = 1.0_dp
    end do
    wk%pos(:, 1) = 0.0_dp; wk%vel(:, 1) = 0.0_dp; wk%acc(:, 1) = 0.0_dp
    do b = 2, d%nb
      a = d%parent(b)
      vf = wk%vel(:, a); af = wk%acc(:, a)
      if (d%nm(a) > 0) then
        m = d%nm(a)
        call flexible_frame(wk%rot(:, :, a), wk%pos(:, a), wk%vel(:, a), d%at(:, b), d%att_psi(:, 1:m, b), &
          & d%att_phi(:, 1:m, b), q(d%a0(a):d%a0(a) + m - 1), qd(d%a0(a):d%a0(a) + m - 1), rf, pf, &
          & wk%cm(:, 1:m, b), vf, af)
      else
        rf = wk%rot(:, :, a)
        pf = wk%pos(:, a) + matmul(rf, d%at(:, b))
      end if
      do k = d%c0(b), d%c0(b) + d%nc(b) - 1
        u = matmul(rf, d%axis(:, k))
        if (d%prim(k) == prim_revolute) then
          sk(1:3) = cross(pf, u); sk(4:6) = u
          call turn_frame(rf, u, q(k))
        else
          sk(1:3) = u; sk(4:6) = 0.0_dp
          pf = pf + u*q(k)
        end if
        vf = vf + sk*qd(k)
        af = af + motion_cross(vf, sk)*qd(k)
        wk%s(:, k) = sk
      end do
      wk%rot(:, :, b) = rf; wk%pos(:, b) = pf; wk%vel(:, b) = vf; wk%acc(:, b) = af
    end do
    do c = 1, d%cuts%n
      if (d%cuts%kind(c) == cut_free) cycle
      call cut_frame(d, wk, c, 1, d%cuts%parent(c), d%cuts%at(:, c), q, qd)
      call cut_frame(d, wk, c, 2, d%cuts%child(c), d%cuts%child_at(:, c), q, qd)
    end do
  end subroutine forward_kinematics

  !> The frame at point r (body frame) of body b, side s of cut joint c (1 its parent's,
  !> 2 its child's), after the tree's kinematics: on a rigid body b's frame moved to the
  !> point; on a flexible one the deformed frame there (flexible_frame, with the shapes
  !> d%cuts%psi, d%cuts%phi) and the columns of b's modal rates at it.
  pure subroutine cut_frame(d, wk, c, s, b, r, q, qd)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: c, s, b
    real(dp), intent(in) :: r(3), q(:), qd(:)
    integer :: m
    real(dp) :: rf(3, 3), pf(3), vf(6), af(6)
    m = d%nm(b)
    vf = wk%vel(:, b); af = wk%acc(:, b)
    if (m == 0) then
      rf = wk%rot(:, :, b)
      pf = wk%pos(:, b) + matmul(rf, r)
    else
      call flexible_frame(wk%rot(:, :, b), wk%pos(:, b), wk%vel(:, b), r, d%cuts%psi(:, 1:m, s, c), &
        & d%cuts%phi(:, 1:m, s, c), q(d%a0(b):d%a0(b) + m - 1), qd(d%a0(b):d%a0(b) + m - 1), rf, pf, &
        & wk%loops%cm(:, 1:m, s, c), vf, af)
    end if
    wk%loops%rot(:, :, s, c) = rf; wk%loops%pos(:, s, c) = pf; wk%loops%vel(:, s, c) = vf; wk%loops%acc(:, s, c) = af
  end subroutine cut_frame

  !> Turn the frame rf (its columns, inertial) by angle about the inertial unit axis u
  !> (Rodrigues: c cos + (u x c) sin + u (u . c)(1 - cos) for each column c).
  pure subroutine turn_frame(rf, u, angle)
    real(dp), intent(inout) :: rf(3, 3)
    real(dp), intent(in) :: u(3), angle
    real(dp) :: c, s, uc, col(3)
    integer :: j
    c = cos(angle); s = sin(angle)
    do j = 1, 3
      col = rf(:, j)
      uc = (u(1)*col(1) + u(2)*col(2) + u(3)*col(3))*(1.0_dp - c)
      rf(1, j) = col(1)*c + (u(2)*col(3) - u(3)*col(2))*s + u(1)*uc
      rf(2, j) = col(2)*c + (u(3)*col(1) - u(1)*col(3))*s + u(2)*uc
      rf(3, j) = col(3)*c + (u(1)*col(2) - u(2)*col(1))*s + u(3)*uc
    end do
  end subroutine turn_frame

  !> The frame at a point of flexible body a (pose ra, pa, spatial velocity va) whose
  !> undeformed place is r (body frame) and whose translational and rotational mode shapes
  !> are psi, phi (3 x m), at modal coordinates aa and rates ad: it moves with the deflection
  !> psi aa and turns with the small rotation exp((phi aa)~). Gives its pose (rf, pf), the
  !> spatial columns cm (6 x m) of the modal rates there, and adds their parts to the spatial
  !> velocity vf and bias acceleration af (which hold the body's on entry).
  pure subroutine flexible_frame(ra, pa, va, r, psi, phi, aa, ad, rf, pf, cm, vf, af)
    real(dp), intent(in) :: ra(3, 3), pa(3), va(6), r(3), psi(:, :), phi(:, :), aa(:), ad(:)
    real(dp), intent(out) :: rf(3, 3), pf(3), cm(:, :)
    real(dp), intent(inout) :: vf(6), af(6)
    integer :: k, m
    real(dp) :: th(3), thd(3), rr(3, 3), jl(3, 3), jd(3), ob(3), obd(3), wk(3), cad(6), lv(3), lw(3)
    m = size(aa)
    th = matmul(phi, aa); thd = matmul(phi, ad)
    call small_rotation(th, thd, rr, jl, jd)
    ob = r + matmul(psi, aa)
    obd = matmul(psi, ad)
    pf = pa + matmul(ra, ob)
    rf = matmul(ra, rr)
    do k = 1, m
      wk = matmul(ra, matmul(jl, phi(:, k)))
      cm(1:3, k) = matmul(ra, psi(:, k)) + cross(pf, wk)
      cm(4:6, k) = wk
    end do
    cad = matmul(cm, ad)
    ! rate of the columns: frame rotation (V_a x) plus their change with the deflection
    lw = jd
    lv = cross(obd, matmul(jl, thd)) + cross(ob, jd)
    af = af + motion_cross(va, cad)
    af(1:3) = af(1:3) + matmul(ra, lv) + cross(pa, matmul(ra, lw))
    af(4:6) = af(4:6) + matmul(ra, lw)
    vf = vf + cad
  end subroutine flexible_frame

  !> Inertial position and velocity of marker m (after forward_kinematics); q, qd give the
  !> deflection of a marker on a flexible body.
  pure subroutine marker_motion(d, wk, m, q, qd, r, v)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    integer, intent(in) :: m
    real(dp), intent(in) :: q(:), qd(:)
    real(dp), intent(out) :: r(3), v(3)
    integer :: b
    b = d%markers%body(m)
    r = wk%pos(:, b) + matmul(wk%rot(:, :, b), d%markers%at(:, m) + marker_deflection(d, m, q))
    v = wk%vel(1:3, b) + cross(wk%vel(4:6, b), r)
    if (d%nm(b) > 0) v = v + matmul(wk%rot(:, :, b), marker_deflection(d, m, qd))
  end subroutine marker_motion

  !> Inertial acceleration of marker m from its body's spatial acceleration acc_b = [a_O; alpha]
  !> (after forward_kinematics; r, v from marker_motion): a = a_O + alpha x r + w x v, and on
  !> a flexible body + w x (R Psi ad) + R Psi add.
  pure subroutine marker_acceleration(d, wk, m, qd, qdd, acc_b, r, v, a)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    integer, intent(in) :: m
    real(dp), intent(in) :: qd(:), qdd(:), acc_b(6), r(3), v(3)
    real(dp), intent(out) :: a(3)
    integer :: b
    real(dp) :: vd(3)
    b = d%markers%body(m)
    a = acc_b(1:3) + cross(acc_b(4:6), r) + cross(wk%vel(4:6, b), v)
    if (d%nm(b) == 0) return
    vd = matmul(wk%rot(:, :, b), marker_deflection(d, m, qd))
    a = a + cross(wk%vel(4:6, b), vd) + matmul(wk%rot(:, :, b), marker_deflection(d, m, qdd))
  end subroutine marker_acceleration

  !> Psi v at marker m: the deflection (or its rate, or acceleration) in its body's frame
  !> from the body's modal coordinates in v (q, qd or qdd), summed by columns (a matmul of
  !> array sections made heap temporaries per call); zero on a rigid body.
  pure function marker_deflection(d, m, v) result(u)
    type(model_data), intent(in) :: d
    integer, intent(in) :: m
    real(dp), intent(in) :: v(:)
    real(dp) :: u(3)
    integer :: b, k
    b = d%markers%body(m)
    u = 0.0_dp
    do k = 1, d%nm(b)
      u = u + d%markers%psi(:, k, m)*v(d%a0(b)+k-1)
    end do
  end function marker_deflection

  !> Orientation of marker m's frame (inertial from marker axes; after forward_kinematics):
  !> its body's, turned on a flexible body by the small rotation exp((Phi a)~) of the point.
  pure subroutine marker_rotation(d, wk, m, q, rm)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    integer, intent(in) :: m
    real(dp), intent(in) :: q(:)
    real(dp), intent(out) :: rm(3, 3)
    integer :: b, nm
    real(dp) :: th(3), rr(3, 3), jl(3, 3), jd(3)
    b = d%markers%body(m)
    nm = d%nm(b)
    rm = wk%rot(:, :, b)
    if (nm == 0) return
    th = matmul(d%markers%phi(:, 1:nm, m), q(d%a0(b):d%a0(b) + nm - 1))
    call small_rotation(th, [0.0_dp, 0.0_dp, 0.0_dp], rr, jl, jd)
    rm = matmul(rm, rr)
  end subroutine marker_rotation
end module pymr_model_kinematics
