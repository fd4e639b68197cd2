!> Force elements between two markers on any two bodies (&force):
!> - a spring-damper along the line from marker i to marker j, of tension
!>   k (L - L0) + c dL/dt, pulling the markers together when positive; with a
!>   force-deflection table, F(L - L0) + c dL/dt, F interpolated linearly in the table and
!>   continued by its end segments' lines, of energy the integral of F from 0 to L - L0;
!> - a bushing: in marker i's axes, forces Kt x + Ct xd on the displacement x = Ri^T (rj - ri)
!>   of marker j from marker i and its rate, and moments on the rotation vector theta of
!>   j's frame from i's (Ri^T Rj = exp(theta~)) and the relative angular velocity.
!> Each load follows from the element's potential energy: the translation acts on both
!> bodies at marker j's point (equal and opposite), the rotation as equal and opposite
!> moments Ri Jl^-T Kr theta (Jl the left Jacobian of the rotation vector), so the
!> generalised forces are minus the gradient of 1/2 x^T Kt x + 1/2 theta^T Kr theta. On a
!> flexible body the loads enter through the marker's mode shapes as well.
module pymr_model_effect_force_elements
  use pymr_env_kinds, only : dp
  use pymr_model_types, only : model_data, model_work
  use pymr_model_kinematics, only : forward_kinematics, marker_motion, marker_rotation
  use pymr_model_flexbody, only : small_rotation
  use pymr_model_spatial, only : rotation_vector
  use pymr_model_effect, only : effect_t, stage_load, energy_springs, power_damping
  use pymr_model_time_table, only : time_table, table_extended, table_extended_integral
  implicit none
  private
  public :: force_element, force_elements_effect, force_elements_effect_of, spring_damper, bushing

  integer, parameter :: spring_damper = 1, bushing = 2

  !> One element: its kind, markers i and j, stiffnesses and dampings (1 used by a
  !> spring-damper; 6 by a bushing: translations x, y, z, rotations about x, y, z) and a
  !> spring-damper's free length (m); a nonlinear spring-damper's force-deflection table
  !> (deflection L - L0 in m, tension in N), in place of k(1).
  type :: force_element
    integer :: kind = spring_damper, mi = 0, mj = 0
    real(dp) :: k(6) = 0.0_dp, c(6) = 0.0_dp, free_length = 0.0_dp
    logical :: tabulated = .false.
    type(time_table) :: table
  end type force_element

  !> A marker's state: inertial point and its velocity, frame, angular velocity, and the
  !> left Jacobian of its small rotation on a flexible body (identity on a rigid one).
  type :: marker_state
    real(dp) :: r(3), v(3), rot(3, 3), w(3), jl(3, 3)
  end type marker_state

  !> An element's loads: the force on marker j (at its point; minus it on body i at the
  !> same point) and the moment on marker j's frame (minus it on i's), inertial.
  type :: element_load
    real(dp) :: f(3) = 0.0_dp, m(3) = 0.0_dp
  end type element_load

  type, extends(effect_t) :: force_elements_effect
    type(force_element), allocatable :: elements(:)
  contains
    procedure :: load => elements_load
    procedure :: add_energy => elements_energy
    procedure :: add_power => elements_power
  end type force_elements_effect

contains

  include 'vector_products.inc'

  function force_elements_effect_of(elements) result(e)
    type(force_element), intent(in) :: elements(:)
    type(force_elements_effect) :: e
    e%name = 'force_elements'
    e%acts(stage_load) = .true.
    e%elements = elements
  end function force_elements_effect_of

  !> The state of marker mk (after forward_kinematics).
  function marker_state_of(d, wk, mk, q, qd) result(s)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    integer, intent(in) :: mk
    real(dp), intent(in) :: q(:), qd(:)
    type(marker_state) :: s
    integer :: b, nm, k
    real(dp) :: rr(3, 3), jd(3)
    b = d%markers%body(mk)
    nm = d%nm(b)
    call marker_motion(d, wk, mk, q, qd, s%r, s%v)
    call marker_rotation(d, wk, mk, q, s%rot)
    s%w = wk%vel(4:6, b)
    s%jl = 0.0_dp
    do k = 1, 3
      s%jl(k, k) = 1.0_dp
    end do
    if (nm == 0) return
    associate(phi => d%markers%phi(:, 1:nm, mk), a => q(d%a0(b):d%a0(b) + nm - 1), &
      & ad => qd(d%a0(b):d%a0(b) + nm - 1))
      call small_rotation(matmul(phi, a), matmul(phi, ad), rr, s%jl, jd)
      s%w = s%w + matmul(wk%rot(:, :, b), matmul(s%jl, matmul(phi, ad)))
    end associate
  end function marker_state_of

  !> Jl(theta)^-T y: the moment whose work on a rotation of the frame balances y . dtheta
  !> (Jl^-T = I + theta~/2 + beta theta~^2, beta = 1/t^2 - (1 + cos t)/(2 t sin t)).
  pure function inverse_jacobian_transpose(th, y) result(m)
    real(dp), intent(in) :: th(3), y(3)
    real(dp) :: m(3), t, beta, ty(3)
    t = norm2(th)
    if (t < 1.0e-3_dp) then
      beta = 1.0_dp/12.0_dp + t**2/720.0_dp
    else
      beta = 1.0_dp/t**2 - (1.0_dp + cos(t))/(2.0_dp*t*sin(t))
    end if
    ty = cross(th, y)
    m = y + 0.5_dp*ty + beta*cross(th, ty)
  end function inverse_jacobian_transpose

  !> A spring-damper's spring tension (N) at deflection x = L - L0 (m): k x, or its table's.
  pure real(dp) function spring_tension(el, x) result(f)
    type(force_element), intent(in) :: el
    real(dp), intent(in) :: x
    if (el%tabulated) then
      f = table_extended(el%table, x)
    else
      f = el%k(1)*x
    end if
  end function spring_tension

  !> A spring-damper's spring energy (J) at deflection x: 1/2 k x^2, or the integral of
  !> its table from 0 to x (exact: the table is piecewise linear).
  pure real(dp) function spring_energy(el, x) result(e)
    type(force_element), intent(in) :: el
    real(dp), intent(in) :: x
    if (el%tabulated) then
      e = table_extended_integral(el%table, 0.0_dp, x)
    else
      e = 0.5_dp*el%k(1)*x**2
    end if
  end function spring_energy

  !> Element el's loads at marker states si, sj.
  pure function element_load_of(el, si, sj) result(ld)
    type(force_element), intent(in) :: el
    type(marker_state), intent(in) :: si, sj
    type(element_load) :: ld
    real(dp) :: dr(3), len, u(3), x(3), xd(3), th(3), wr(3)
    dr = sj%r - si%r
    if (el%kind == spring_damper) then
      len = norm2(dr)
      if (len == 0.0_dp) return
      u = dr/len
      ld%f = -(spring_tension(el, len - el%free_length) + el%c(1)*dot_product(u, sj%v - si%v))*u
      return
    end if
    x = matmul(transpose(si%rot), dr)
    xd = matmul(transpose(si%rot), sj%v - si%v - cross(si%w, dr))
    ld%f = -matmul(si%rot, el%k(1:3)*x + el%c(1:3)*xd)
    th = rotation_vector(matmul(transpose(si%rot), sj%rot))
    wr = matmul(transpose(si%rot), sj%w - si%w)
    ld%m = -matmul(si%rot, inverse_jacobian_transpose(th, el%k(4:6)*th) + el%c(4:6)*wr)
  end function element_load_of

  !> The force elements' loads (after the body terms), on the bodies in `mask`: on body j
  !> the force f at marker j's point and the moment m, on body i -f at the same point (for
  !> a spring-damper at marker i's point: the same on its line) and -m. Each enters its
  !> body's wrench and, on a flexible body, the modal forces through the marker's shapes.
  subroutine elements_load(self, d, wk, t, q, qd, mask)
    class(force_elements_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: mask(:)
    integer :: i
    type(marker_state) :: si, sj
    type(element_load) :: ld
    do i = 1, size(self%elements)
      associate(el => self%elements(i))
        if (.not. (mask(d%markers%body(el%mi)) .or. mask(d%markers%body(el%mj)))) cycle
        si = marker_state_of(d, wk, el%mi, q, qd)
        sj = marker_state_of(d, wk, el%mj, q, qd)
        ld = element_load_of(el, si, sj)
        call apply_at_marker(d, wk, mask, el%mj, sj, sj%r, ld%f, ld%m)
        if (el%kind == spring_damper) then
          call apply_at_marker(d, wk, mask, el%mi, si, si%r, -ld%f, -ld%m)
        else
          call apply_at_marker(d, wk, mask, el%mi, si, sj%r, -ld%f, -ld%m)
        end if
      end associate
    end do
  end subroutine elements_load

  !> Force f acting at inertial point p and moment m on marker mk's body (state s), when
  !> that body is in `mask`: [f; p x f + m] into the body's wrench, and on a flexible body
  !> the modal forces of the marker point's translation (f and the moment (p - r) x f about
  !> it) and of its frame's rotation.
  subroutine apply_at_marker(d, wk, mask, mk, s, p, f, m)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    logical, intent(in) :: mask(:)
    integer, intent(in) :: mk
    type(marker_state), intent(in) :: s
    real(dp), intent(in) :: p(3), f(3), m(3)
    integer :: b, k
    real(dp) :: fb(3), mb(3)
    b = d%markers%body(mk)
    if (b == 1 .or. .not. mask(b)) return
    wk%w(1:3, b) = wk%w(1:3, b) - f
    wk%w(4:6, b) = wk%w(4:6, b) - cross(p, f) - m
    if (d%nm(b) == 0) return
    fb = matmul(transpose(wk%rot(:, :, b)), f)
    mb = matmul(transpose(s%jl), matmul(transpose(wk%rot(:, :, b)), m + cross(p - s%r, f)))
    do k = 1, d%nm(b)
      wk%wam(k, b) = wk%wam(k, b) - dot_product(d%markers%psi(:, k, mk), fb) - dot_product(d%markers%phi(:, k, mk), mb)
    end do
  end subroutine apply_at_marker

  !> Potential energy of the elements (J): 1/2 k (L - L0)^2 of a spring-damper (its
  !> table's integral when tabulated),
  !> 1/2 (x^T Kt x + theta^T Kr theta) of a bushing (after the kinematics).
  subroutine elements_energy(self, d, wk, q, e)
    class(force_elements_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: q(:)
    real(dp), intent(inout) :: e(:)
    integer :: i
    real(dp) :: ri(3), rj(3), v(3), roti(3, 3), rotj(3, 3), x(3), th(3), zero(size(q))
    zero = 0.0_dp
    do i = 1, size(self%elements)
      associate(el => self%elements(i))
        call marker_motion(d, wk, el%mi, q, zero, ri, v)
        call marker_motion(d, wk, el%mj, q, zero, rj, v)
        if (el%kind == spring_damper) then
          e(energy_springs) = e(energy_springs) + spring_energy(el, norm2(rj - ri) - el%free_length)
          cycle
        end if
        call marker_rotation(d, wk, el%mi, q, roti)
        call marker_rotation(d, wk, el%mj, q, rotj)
        x = matmul(transpose(roti), rj - ri)
        th = rotation_vector(matmul(transpose(roti), rotj))
        e(energy_springs) = e(energy_springs) + 0.5_dp*(sum(el%k(1:3)*x**2) + sum(el%k(4:6)*th**2))
      end associate
    end do
  end subroutine elements_energy

  !> The dampers' loss (W): c (dL/dt)^2 of a spring-damper, xd^T Ct xd + wr^T Cr wr of a
  !> bushing (runs the kinematics at (q, qd)).
  subroutine elements_power(self, d, wk, t, q, qd, p)
    class(force_elements_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(inout) :: p(:)
    integer :: i
    real(dp) :: dr(3), xd(3), wr(3)
    type(marker_state) :: si, sj
    if (.not. any([(any(self%elements(i)%c /= 0.0_dp), i = 1, size(self%elements))])) return
    call forward_kinematics(d, wk, q, qd)
    do i = 1, size(self%elements)
      associate(el => self%elements(i))
        si = marker_state_of(d, wk, el%mi, q, qd)
        sj = marker_state_of(d, wk, el%mj, q, qd)
        dr = sj%r - si%r
        if (el%kind == spring_damper) then
          if (norm2(dr) > 0.0_dp) p(power_damping) = p(power_damping) + &
            & el%c(1)*dot_product(dr/norm2(dr), sj%v - si%v)**2
          cycle
        end if
        xd = matmul(transpose(si%rot), sj%v - si%v - cross(si%w, dr))
        wr = matmul(transpose(si%rot), sj%w - si%w)
        p(power_damping) = p(power_damping) + sum(el%c(1:3)*xd**2) + sum(el%c(4:6)*wr**2)
      end associate
    end do
  end subroutine elements_power
end module pymr_model_effect_force_elements
