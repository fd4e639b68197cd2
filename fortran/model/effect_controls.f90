!> Feedback drives (&control): each controller measures a joint coordinate, or the inertial
!> rotation of a marker's frame about a fixed axis (a rate gyro), and applies on its joint
!> coordinate the effort
!>   effort = kp e + ki I + kd edot,   |effort| <= max_effort,
!> with e = setpoint(t) - measured, edot = -(measured rate) (the derivative acts on the
!> measurement: a setpoint's step or a table's corner gives no kick), I the integral of e.
!>
!> The integral is part of the integrated state: each controller owns one coordinate c among
!> the slow (joint) coordinates, of no body, whose rate is I and whose acceleration is e
!> (its position, the double integral, enters nothing). Its row of M qdd = P is the unit row
!> with P_c = e (rows stage; the accelerate stage on the articulated path), so checkpoints,
!> restarts and the multirate partition carry I like any joint rate.
!>
!> The orientation sensor: marker frame R (inertial from marker axes, with a flexible body's
!> small rotation at the marker), unit inertial axis a and a fixed unit vector u normal to it;
!> angle = atan2(a . (u x R u), u . (R u)), in (-pi, pi], the rotation of R u from u about a
!> (R = I gives 0); rate = a . omega, the frame's inertial angular velocity about a (the
!> angle's time derivative when the frame turns about a only). Its error is taken the short
!> way round: e = setpoint - angle wrapped to (-pi, pi].
module pymr_model_effect_controls
  use pymr_env_kinds, only : dp, pi
  use pymr_model_types, only : model_data, model_work
  use pymr_model_effect, only : effect_t, stage_load, stage_rows, stage_accelerate, power_drives
  use pymr_model_kinematics, only : forward_kinematics, marker_rotation
  use pymr_model_flexbody, only : small_rotation
  use pymr_model_spatial, only : cross
  use pymr_model_time_table, only : time_table, table_linear
  implicit none
  private
  public :: controller, controls_effect, controls_effect_of

  !> One controller: the driven coordinate, its own state coordinate (rate: the integral),
  !> the sensor (gyro: marker, unit axis a, reference u normal to a), gains, setpoint (plus
  !> the table when tabulated) and effort limit (huge: none).
  type :: controller
    integer :: coord = 0, state = 0, marker = 0
    logical :: gyro = .false., tabulated = .false.
    real(dp) :: axis(3) = 0.0_dp, ref(3) = 0.0_dp
    real(dp) :: kp = 0.0_dp, ki = 0.0_dp, kd = 0.0_dp, setpoint = 0.0_dp, max_effort = huge(1.0_dp)
    type(time_table) :: table
  end type controller

  type, extends(effect_t) :: controls_effect
    type(controller), allocatable :: controls(:)
    !> Some controller reads a marker (its power needs the kinematics).
    logical :: gyros = .false.
  contains
    procedure :: load => controls_load
    procedure :: rows => controls_rows
    procedure :: accelerate => controls_accelerate
    procedure :: add_power => controls_power
  end type controls_effect

contains

  function controls_effect_of(controls) result(e)
    type(controller), intent(in) :: controls(:)
    type(controls_effect) :: e
    e%name = 'controls'
    e%acts([stage_load, stage_rows, stage_accelerate]) = .true.
    e%joint_rows_only = .true.
    e%controls = controls
    e%gyros = any(controls%gyro)
  end function controls_effect_of

  !> The setpoint at time t.
  pure real(dp) function setpoint_at(c, t) result(s)
    type(controller), intent(in) :: c
    real(dp), intent(in) :: t
    s = c%setpoint
    if (c%tabulated) s = s + table_linear(c%table, t)
  end function setpoint_at

  !> The measured value and rate (after forward_kinematics when the sensor is a gyro).
  pure subroutine measure(c, d, wk, q, qd, y, yd)
    type(controller), intent(in) :: c
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: q(:), qd(:)
    real(dp), intent(out) :: y, yd
    real(dp) :: rm(3, 3), v(3), w(3)
    if (.not. c%gyro) then
      y = q(c%coord); yd = qd(c%coord); return
    end if
    call marker_rotation(d, wk, c%marker, q, rm)
    v = matmul(rm, c%ref)
    y = atan2(dot_product(c%axis, cross(c%ref, v)), dot_product(c%ref, v))
    w = marker_angular_velocity(d, wk, c%marker, q, qd)
    yd = dot_product(c%axis, w)
  end subroutine measure

  !> Inertial angular velocity of marker m's frame: its body's, plus on a flexible body the
  !> rate of the small rotation at the marker (body frame, turned to inertial).
  pure function marker_angular_velocity(d, wk, m, q, qd) result(w)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    integer, intent(in) :: m
    real(dp), intent(in) :: q(:), qd(:)
    real(dp) :: w(3), rr(3, 3), jl(3, 3), jd(3)
    integer :: b, nm
    b = d%markers%body(m)
    nm = d%nm(b)
    w = wk%vel(4:6, b)
    if (nm == 0) return
    associate(phi => d%markers%phi(:, 1:nm, m), a => q(d%a0(b):d%a0(b) + nm - 1), &
      & ad => qd(d%a0(b):d%a0(b) + nm - 1))
      call small_rotation(matmul(phi, a), matmul(phi, ad), rr, jl, jd)
      w = w + matmul(wk%rot(:, :, b), matmul(jl, matmul(phi, ad)))
    end associate
  end function marker_angular_velocity

  !> The error e and the limited effort of controller c at (t, q, qd).
  pure subroutine error_effort(c, d, wk, t, q, qd, e, effort)
    type(controller), intent(in) :: c
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(out) :: e, effort
    real(dp) :: y, yd
    call measure(c, d, wk, q, qd, y, yd)
    e = setpoint_at(c, t) - y
    if (c%gyro) e = e - 2.0_dp*pi*ceiling((e - pi)/(2.0_dp*pi))
    effort = c%kp*e + c%ki*qd(c%state) - c%kd*yd
    effort = max(-c%max_effort, min(c%max_effort, effort))
  end subroutine error_effort

  !> The efforts added to the driven coordinates' generalised forces; each controller's
  !> error put in its state coordinate's entry of tau (the rows and accelerate stages read it).
  subroutine controls_load(self, d, wk, t, q, qd, mask)
    class(controls_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: mask(:)
    integer :: i
    real(dp) :: e, effort
    do i = 1, size(self%controls)
      associate(c => self%controls(i))
        call error_effort(c, d, wk, t, q, qd, e, effort)
        wk%tau(c%coord) = wk%tau(c%coord) + effort
        wk%tau(c%state) = e
      end associate
    end do
  end subroutine controls_load

  !> After assembly: each state coordinate's row becomes qdd_c = e (its row and column of M
  !> the unit ones: it carries no inertia and couples to nothing).
  subroutine controls_rows(self, wk, t)
    class(controls_effect), intent(in) :: self
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t
    integer :: i, j
    do i = 1, size(self%controls)
      j = self%controls(i)%state
      wk%mm(:, j) = 0.0_dp
      wk%mm(j, :) = 0.0_dp
      wk%mm(j, j) = 1.0_dp
      wk%p(j) = wk%tau(j)
    end do
  end subroutine controls_rows

  !> The state coordinates' accelerations, the errors (the articulated path).
  subroutine controls_accelerate(self, wk, t, qdd)
    class(controls_effect), intent(in) :: self
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: qdd(:)
    integer :: i
    do i = 1, size(self%controls)
      qdd(self%controls(i)%state) = wk%tau(self%controls(i)%state)
    end do
  end subroutine controls_accelerate

  !> Power of the efforts: effort times the driven coordinate's rate (the drives' power).
  subroutine controls_power(self, d, wk, t, q, qd, p)
    class(controls_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(inout) :: p(:)
    integer :: i
    real(dp) :: e, effort
    if (self%gyros) call forward_kinematics(d, wk, q, qd)
    do i = 1, size(self%controls)
      call error_effort(self%controls(i), d, wk, t, q, qd, e, effort)
      p(power_drives) = p(power_drives) + effort*qd(self%controls(i)%coord)
    end do
  end subroutine controls_power
end module pymr_model_effect_controls
