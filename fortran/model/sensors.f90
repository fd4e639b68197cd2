!> Sensors (&sensor): output quantities measured on markers after the kinematics. A
!> 'distance' sensor gives the distance between two markers and its rate; a 'position'
!> sensor gives a marker's position from a body's frame origin and its velocity relative to
!> that frame, both in the frame's axes (the time derivative of that position).
module pymr_model_sensors
  use pymr_env_kinds, only : dp, name_len
  use pymr_model_types, only : model_data, model_work
  use pymr_model_kinematics, only : marker_motion
  use pymr_model_spatial, only : cross
  use pymr_model_scene, only : scene_t
  implicit none
  private
  public :: sensor_set, sensors_of, sensor_width, sensor_values

  !> Kinds of sensors.
  integer, parameter, public :: sensor_distance = 1, sensor_position = 2

  !> The sensors of a scene, resolved on its model: name, kind, the marker measured and the
  !> other marker ('distance') or the model's body whose frame is used ('position').
  type :: sensor_set
    integer :: n = 0
    character(len=name_len), allocatable :: name(:)
    integer, allocatable :: kind(:), marker(:), other(:)
  end type sensor_set

contains

  !> The scene's sensors on model d (the scene's rules have checked the names).
  function sensors_of(sc, d) result(set)
    type(scene_t), intent(in) :: sc
    type(model_data), intent(in) :: d
    type(sensor_set) :: set
    integer :: i
    set%n = size(sc%sensors)
    allocate(set%name(set%n), set%kind(set%n), set%marker(set%n), set%other(set%n))
    do i = 1, set%n
      associate(se => sc%sensors(i))
        set%name(i) = se%name
        set%marker(i) = findloc(d%markers%name, se%marker, dim=1)
        if (se%kind == 'distance') then
          set%kind(i) = sensor_distance
          set%other(i) = findloc(d%markers%name, se%to, dim=1)
        else
          set%kind(i) = sensor_position
          set%other(i) = findloc(d%body_name, se%frame, dim=1)
        end if
      end associate
    end do
  end function sensors_of

  !> Values per row of the sensors: 2 a 'distance', 6 a 'position'.
  pure integer function sensor_width(set)
    type(sensor_set), intent(in) :: set
    sensor_width = 0
    if (set%n > 0) sensor_width = 2*count(set%kind == sensor_distance) + 6*count(set%kind == sensor_position)
  end function sensor_width

  !> The sensors' values in order (after forward_kinematics at q, qd): a 'distance' d = |ri - rj|
  !> (m) and its rate (ri - rj).(vi - vj)/d (m/s; 0 where d = 0); a 'position' p = R^T (r - o)
  !> (m) and R^T (v - vo - w x (r - o)) = dp/dt (m/s), R, o, vo and w the body frame's
  !> orientation, origin, origin velocity and angular velocity (inertial).
  pure subroutine sensor_values(set, d, wk, q, qd, v)
    type(sensor_set), intent(in) :: set
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: q(:), qd(:)
    real(dp), intent(out) :: v(:)
    integer :: i, k, b
    real(dp) :: ri(3), vi(3), rj(3), vj(3), x(3), dist, rot(3, 3)
    k = 0
    do i = 1, set%n
      call marker_motion(d, wk, set%marker(i), q, qd, ri, vi)
      if (set%kind(i) == sensor_distance) then
        call marker_motion(d, wk, set%other(i), q, qd, rj, vj)
        x = ri - rj
        dist = norm2(x)
        v(k+1) = dist
        v(k+2) = 0.0_dp
        if (dist > 0.0_dp) v(k+2) = dot_product(x, vi - vj)/dist
        k = k + 2
      else
        b = set%other(i)
        rot = transpose(wk%rot(:, :, b))
        ! the body's spatial velocity [vel(1:3); w]: its point at r moves at vel(1:3) + w x r
        v(k+1:k+3) = matmul(rot, ri - wk%pos(:, b))
        v(k+4:k+6) = matmul(rot, vi - wk%vel(1:3, b) - cross(wk%vel(4:6, b), ri))
        k = k + 6
      end if
    end do
  end subroutine sensor_values
end module pymr_model_sensors
