!> Recursive kinematics from the base to the leaves (paper eqs. 8-11, 14): body
!> orientation and origin, spatial velocity, spatial bias acceleration (the acceleration
!> with all qdd = 0) and the spatial column of every coordinate. Cost O(n).
!>
!> A child of a flexible body is attached to a point of it: the joint frame moves with
!> the point's deflection Psi a and turns with its small rotation exp((Phi a)~) (paper
!> eqs. 8-9); the parent's modal rates enter the child's velocity through the columns cm.
module pymr_model_kinematics
  use pymr_kinds, only : dp
  use pymr_model_types, only : model_data, prim_revolute
  use pymr_model_flexbody, only : small_rotation
  implicit none
  private
  public :: forward_kinematics, marker_motion, marker_acceleration, marker_rotation

contains

  include 'vector_products.inc'

  !> Positions, velocities, bias accelerations and coordinate columns for state (q, qd).
  pure subroutine forward_kinematics(d, q, qd)
    type(model_data), intent(inout) :: d
    !> Coordinates and rates (joint coordinates, then modal coordinates).
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
      vf = d%vel(:, a); af = d%acc(:, a)
      if (d%nm(a) > 0) then
        call attach_flexible(d, b, a, q(d%a0(a):d%a0(a) + d%nm(a) - 1), qd(d%a0(a):d%a0(a) + d%nm(a) - 1), &
          & rf, pf, vf, af)
      else
        rf = d%rot(:, :, a)
        pf = d%pos(:, a) + matmul(rf, d%at(:, b))
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
        d%s(:, k) = sk
      end do
      d%rot(:, :, b) = rf; d%pos(:, b) = pf; d%vel(:, b) = vf; d%acc(:, b) = af
    end do
  end subroutine forward_kinematics

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

  !> Joint frame of body b on flexible parent a with modal coordinates aa and rates ad:
  !> pose (rf, pf), and the modal contributions to velocity vf and bias acceleration af.
  pure subroutine attach_flexible(d, b, a, aa, ad, rf, pf, vf, af)
    type(model_data), intent(inout) :: d
    integer, intent(in) :: b, a
    real(dp), intent(in) :: aa(:), ad(:)
    real(dp), intent(out) :: rf(3, 3), pf(3)
    real(dp), intent(inout) :: vf(6), af(6)
    integer :: k, m
    real(dp) :: th(3), thd(3), rr(3, 3), jl(3, 3), jd(3), ob(3), obd(3), wk(3), cad(6), lv(3), lw(3)
    m = d%nm(a)
    th = matmul(d%att_phi(:, 1:m, b), aa); thd = matmul(d%att_phi(:, 1:m, b), ad)
    call small_rotation(th, thd, rr, jl, jd)
    ob = d%at(:, b) + matmul(d%att_psi(:, 1:m, b), aa)
    obd = matmul(d%att_psi(:, 1:m, b), ad)
    associate(ra => d%rot(:, :, a), pa => d%pos(:, a))
      pf = pa + matmul(ra, ob)
      rf = matmul(ra, rr)
      do k = 1, m
        wk = matmul(ra, matmul(jl, d%att_phi(:, k, b)))
        d%cm(1:3, k, b) = matmul(ra, d%att_psi(:, k, b)) + cross(pf, wk)
        d%cm(4:6, k, b) = wk
      end do
      cad = matmul(d%cm(:, 1:m, b), ad)
      ! rate of the columns: frame rotation (V_a x) plus their change with the deflection
      lw = jd
      lv = cross(obd, matmul(jl, thd)) + cross(ob, jd)
      af = af + motion_cross(d%vel(:, a), cad)
      af(1:3) = af(1:3) + matmul(ra, lv) + cross(pa, matmul(ra, lw))
      af(4:6) = af(4:6) + matmul(ra, lw)
    end associate
    vf = vf + cad
  end subroutine attach_flexible

  !> Inertial position and velocity of marker m (after forward_kinematics); q, qd give the
  !> deflection of a marker on a flexible body.
  pure subroutine marker_motion(d, m, q, qd, r, v)
    type(model_data), intent(in) :: d
    integer, intent(in) :: m
    real(dp), intent(in) :: q(:), qd(:)
    real(dp), intent(out) :: r(3), v(3)
    integer :: b, nm
    real(dp) :: loc(3)
    b = d%marker_body(m)
    nm = d%nm(b)
    loc = d%marker_at(:, m)
    if (nm > 0) loc = loc + matmul(d%marker_psi(:, 1:nm, m), q(d%a0(b):d%a0(b) + nm - 1))
    r = d%pos(:, b) + matmul(d%rot(:, :, b), loc)
    v = d%vel(1:3, b) + cross(d%vel(4:6, b), r)
    if (nm > 0) v = v + matmul(d%rot(:, :, b), matmul(d%marker_psi(:, 1:nm, m), qd(d%a0(b):d%a0(b) + nm - 1)))
  end subroutine marker_motion

  !> Inertial acceleration of marker m from its body's spatial acceleration acc_b = [a_O; alpha]
  !> (after forward_kinematics; r, v from marker_motion): a = a_O + alpha x r + w x v, and on
  !> a flexible body + w x (R Psi ad) + R Psi add.
  pure subroutine marker_acceleration(d, m, qd, qdd, acc_b, r, v, a)
    type(model_data), intent(in) :: d
    integer, intent(in) :: m
    real(dp), intent(in) :: qd(:), qdd(:), acc_b(6), r(3), v(3)
    real(dp), intent(out) :: a(3)
    integer :: b, nm
    real(dp) :: vd(3)
    b = d%marker_body(m)
    nm = d%nm(b)
    a = acc_b(1:3) + cross(acc_b(4:6), r) + cross(d%vel(4:6, b), v)
    if (nm == 0) return
    associate(psi => d%marker_psi(:, 1:nm, m), rot => d%rot(:, :, b))
      vd = matmul(rot, matmul(psi, qd(d%a0(b):d%a0(b) + nm - 1)))
      a = a + cross(d%vel(4:6, b), vd) + matmul(rot, matmul(psi, qdd(d%a0(b):d%a0(b) + nm - 1)))
    end associate
  end subroutine marker_acceleration

  !> Orientation of marker m's frame (inertial from marker axes; after forward_kinematics):
  !> its body's, turned on a flexible body by the small rotation exp((Phi a)~) of the point.
  pure subroutine marker_rotation(d, m, q, rm)
    type(model_data), intent(in) :: d
    integer, intent(in) :: m
    real(dp), intent(in) :: q(:)
    real(dp), intent(out) :: rm(3, 3)
    integer :: b, nm
    real(dp) :: th(3), rr(3, 3), jl(3, 3), jd(3)
    b = d%marker_body(m)
    nm = d%nm(b)
    rm = d%rot(:, :, b)
    if (nm == 0) return
    th = matmul(d%marker_phi(:, 1:nm, m), q(d%a0(b):d%a0(b) + nm - 1))
    call small_rotation(th, [0.0_dp, 0.0_dp, 0.0_dp], rr, jl, jd)
    rm = matmul(rm, rr)
  end subroutine marker_rotation
end module pymr_model_kinematics
