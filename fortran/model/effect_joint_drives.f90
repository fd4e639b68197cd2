!> Joint drives: a generalised force on a joint coordinate, offset + amplitude
!> sin(2 pi frequency t + phase), or offset + a table interpolated linearly in time.
module pymr_model_effect_joint_drives
  use pymr_env_kinds, only : dp, pi
  use pymr_model_types, only : model_data, model_work
  use pymr_model_time_table, only : time_table, table_linear
  use pymr_model_effect, only : effect_t, stage_load, power_drives
  implicit none
  private
  public :: joint_drive, joint_drives_effect, joint_drives_effect_of

  !> One drive: its coordinate, offset, amplitude (N or N m), frequency (Hz), phase (rad),
  !> and its table when tabulated.
  type :: joint_drive
    integer :: coord = 0
    real(dp) :: offset = 0.0_dp, amplitude = 0.0_dp, frequency = 0.0_dp, phase = 0.0_dp
    logical :: tabulated = .false.
    type(time_table) :: table
  end type joint_drive

  type, extends(effect_t) :: joint_drives_effect
    type(joint_drive), allocatable :: drives(:)
  contains
    procedure :: load => drives_load
    procedure :: add_power => drives_power
  end type joint_drives_effect

contains

  function joint_drives_effect_of(drives) result(e)
    type(joint_drive), intent(in) :: drives(:)
    type(joint_drives_effect) :: e
    e%name = 'joint_drives'
    e%acts(stage_load) = .true.
    e%joint_rows_only = .true.
    e%drives = drives
  end function joint_drives_effect_of

  !> Generalised force of a drive at time t.
  pure real(dp) function drive_force(dr, t) result(f)
    type(joint_drive), intent(in) :: dr
    real(dp), intent(in) :: t
    if (dr%tabulated) then
      f = dr%offset + table_linear(dr%table, t)
    else
      f = dr%offset + dr%amplitude*sin(2.0_dp*pi*dr%frequency*t + dr%phase)
    end if
  end function drive_force

  !> Add the drive loads to the generalised forces.
  subroutine drives_load(self, d, wk, t, q, qd, mask)
    class(joint_drives_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: mask(:)
    integer :: i
    do i = 1, size(self%drives)
      wk%tau(self%drives(i)%coord) = wk%tau(self%drives(i)%coord) + drive_force(self%drives(i), t)
    end do
  end subroutine drives_load

  !> Power of the drives: force times the coordinate's rate.
  subroutine drives_power(self, d, wk, t, q, qd, p)
    class(joint_drives_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(inout) :: p(:)
    integer :: i
    do i = 1, size(self%drives)
      p(power_drives) = p(power_drives) + drive_force(self%drives(i), t)*qd(self%drives(i)%coord)
    end do
  end subroutine drives_power
end module pymr_model_effect_joint_drives
