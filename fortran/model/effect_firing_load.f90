!> Point loads at markers (&load): a force or a moment along a unit direction, fixed in
!> the marker's body (a follower load) or in the inertial frame, of magnitude in time
!> - 'pulse': peak sin(pi (t - start)/duration) from start to start + duration, zero outside;
!> - 'constant': offset;
!> - 'sine': offset + amplitude sin(2 pi frequency t + phase);
!> - 'table': offset + a table of (time, value) interpolated linearly.
!> A force acts at the marker's point (on a flexible body through its translation shapes
!> psi); a moment on the marker's body (on a flexible body through its rotation shapes phi).
module pymr_model_effect_firing_load
  use pymr_env_kinds, only : dp, pi
  use pymr_model_types, only : model_data, model_work
  use pymr_model_kinematics, only : forward_kinematics, marker_motion
  use pymr_model_flexbody, only : small_rotation
  use pymr_model_time_table, only : time_table, table_linear
  use pymr_model_effect, only : effect_t, stage_load, power_loads
  implicit none
  private
  public :: point_load, firing_load_effect, firing_load_effect_of
  public :: load_pulse, load_constant, load_sine, load_table

  integer, parameter :: load_pulse = 1, load_constant = 2, load_sine = 3, load_table = 4

  !> One load: its marker, form, unit direction (body or inertial frame), whether it is a
  !> moment and whether its direction is inertial, the pulse's peak (N or N m), start and
  !> duration (s), the offset, amplitude, frequency (Hz) and phase (rad) of the other forms,
  !> and its table when tabulated.
  type :: point_load
    integer :: marker = 0, form = load_pulse
    real(dp) :: direction(3) = 0.0_dp, peak = 0.0_dp, start = 0.0_dp, duration = 0.0_dp
    logical :: torque = .false., inertial = .false.
    real(dp) :: offset = 0.0_dp, amplitude = 0.0_dp, frequency = 0.0_dp, phase = 0.0_dp
    type(time_table) :: table
  end type point_load

  type, extends(effect_t) :: firing_load_effect
    type(point_load), allocatable :: loads(:)
  contains
    procedure :: load => firing_load
    procedure :: add_power => firing_power
    procedure :: next_edge => firing_next_edge
  end type firing_load_effect

contains

  include 'vector_products.inc'

  function firing_load_effect_of(loads) result(e)
    type(point_load), intent(in) :: loads(:)
    type(firing_load_effect) :: e
    e%name = 'firing_load'
    e%acts(stage_load) = .true.
    e%loads = loads
  end function firing_load_effect_of

  !> The first time after t at which a pulse starts, peaks or ends (huge: none): an
  !> adaptive run's steps end there, so that a pulse shorter than a step is not stepped
  !> over unseen (the load is 0 at both ends), and its slope's jumps are not stepped across.
  pure real(dp) function firing_next_edge(self, t) result(te)
    class(firing_load_effect), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp) :: edges(3)
    integer :: k, j
    te = huge(1.0_dp)
    do k = 1, size(self%loads)
      if (self%loads(k)%form /= load_pulse) cycle
      associate(ld => self%loads(k))
        edges = [ld%start, ld%start + 0.5_dp*ld%duration, ld%start + ld%duration]
      end associate
      do j = 1, 3
        if (edges(j) > t) te = min(te, edges(j))
      end do
    end do
  end function firing_next_edge

  !> Magnitude (N or N m) of a load at time t.
  pure real(dp) function magnitude(ld, t)
    type(point_load), intent(in) :: ld
    real(dp), intent(in) :: t
    select case (ld%form)
    case (load_constant)
      magnitude = ld%offset
    case (load_sine)
      magnitude = ld%offset + ld%amplitude*sin(2.0_dp*pi*ld%frequency*t + ld%phase)
    case (load_table)
      magnitude = ld%offset + table_linear(ld%table, t)
    case default
      magnitude = 0.0_dp
      if (t >= ld%start .and. t <= ld%start + ld%duration) magnitude = ld%peak*sin(pi*(t - ld%start)/ld%duration)
    end select
  end function magnitude

  !> The load's vector in the inertial frame (fi) and in its body's frame (fb), of
  !> magnitude fmag (after kinematics).
  pure subroutine load_vectors(ld, rot, fmag, fi, fb)
    type(point_load), intent(in) :: ld
    real(dp), intent(in) :: rot(3, 3), fmag
    real(dp), intent(out) :: fi(3), fb(3)
    if (ld%inertial) then
      fi = ld%direction*fmag
      fb = matmul(transpose(rot), fi)
    else
      fb = ld%direction*fmag
      fi = matmul(rot, fb)
    end if
  end subroutine load_vectors

  !> The left Jacobian of marker mk's small rotation on a flexible body and the rotation
  !> rate of its frame relative to the body (body frame), from the modal coordinates.
  subroutine marker_rotation_rate(d, mk, q, qd, jl, wrel)
    type(model_data), intent(in) :: d
    integer, intent(in) :: mk
    real(dp), intent(in) :: q(:), qd(:)
    real(dp), intent(out) :: jl(3, 3), wrel(3)
    integer :: b, nm
    real(dp) :: rr(3, 3), jd(3)
    b = d%markers%body(mk)
    nm = d%nm(b)
    associate(phi => d%markers%phi(:, 1:nm, mk), a => q(d%a0(b):d%a0(b) + nm - 1), &
      & ad => qd(d%a0(b):d%a0(b) + nm - 1))
      call small_rotation(matmul(phi, a), matmul(phi, ad), rr, jl, jd)
      wrel = matmul(jl, matmul(phi, ad))
    end associate
  end subroutine marker_rotation_rate

  !> Point loads at markers (after kinematics): a force fi at the marker's point r enters
  !> the body's wrench as [fi; r x fi] and, on a flexible body, the modal forces
  !> Psi(marker)^T fb; a moment mi enters it as [0; mi] and the modal forces
  !> Phi(marker)^T Jl^T mb (fb, mb: the body-frame components).
  subroutine firing_load(self, d, wk, t, q, qd, mask)
    class(firing_load_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: mask(:)
    integer :: i, b, k, mk
    real(dp) :: fmag, fb(3), f(3), r(3), v(3), jl(3, 3), wrel(3)
    do i = 1, size(self%loads)
      mk = self%loads(i)%marker
      b = d%markers%body(mk)
      if (.not. mask(b)) cycle
      fmag = magnitude(self%loads(i), t)
      if (fmag == 0.0_dp) cycle
      call load_vectors(self%loads(i), wk%rot(:, :, b), fmag, f, fb)
      if (self%loads(i)%torque) then
        wk%w(4:6, b) = wk%w(4:6, b) - f
        if (d%nm(b) == 0) cycle
        call marker_rotation_rate(d, mk, q, qd, jl, wrel)
        fb = matmul(transpose(jl), fb)
        do k = 1, d%nm(b)
          wk%wam(k, b) = wk%wam(k, b) - dot_product(d%markers%phi(:, k, mk), fb)
        end do
        cycle
      end if
      call marker_motion(d, wk, mk, q, qd, r, v)
      wk%w(1:3, b) = wk%w(1:3, b) - f
      wk%w(4:6, b) = wk%w(4:6, b) - cross(r, f)
      do k = 1, d%nm(b)
        wk%wam(k, b) = wk%wam(k, b) - dot_product(d%markers%psi(:, k, mk), fb)
      end do
    end do
  end subroutine firing_load

  !> Power of the loads (runs the kinematics at (q, qd)): a force times its marker's
  !> velocity, a moment times the angular velocity of its marker's frame.
  subroutine firing_power(self, d, wk, t, q, qd, p)
    class(firing_load_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(inout) :: p(:)
    integer :: i, mk, b
    real(dp) :: r(3), v(3), f, sum_p, di(3), jl(3, 3), wrel(3)
    if (size(self%loads) == 0) return
    call forward_kinematics(d, wk, q, qd)
    sum_p = 0.0_dp
    do i = 1, size(self%loads)
      f = magnitude(self%loads(i), t)
      if (f == 0.0_dp) cycle
      mk = self%loads(i)%marker
      b = d%markers%body(mk)
      di = self%loads(i)%direction
      if (.not. self%loads(i)%inertial) di = matmul(wk%rot(:, :, b), di)
      if (self%loads(i)%torque) then
        v = wk%vel(4:6, b)
        if (d%nm(b) > 0) then
          call marker_rotation_rate(d, mk, q, qd, jl, wrel)
          v = v + matmul(wk%rot(:, :, b), wrel)
        end if
      else
        call marker_motion(d, wk, mk, q, qd, r, v)
      end if
      sum_p = sum_p + f*dot_product(di, v)
    end do
    p(power_loads) = p(power_loads) + sum_p
  end subroutine firing_power
end module pymr_model_effect_firing_load
