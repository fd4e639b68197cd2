!> Joint spring-dampers: tau_k += -stiffness (q_k - free_position) - damping qd_k.
module pymr_model_effect_joint_springs
  use pymr_env_kinds, only : dp
  use pymr_model_types, only : model_data, model_work
  use pymr_model_effect, only : effect_t, stage_load, energy_springs, power_damping
  implicit none
  private
  public :: joint_spring, joint_springs_effect, joint_springs_effect_of

  !> One spring-damper: its coordinate, stiffness (N/m or N m/rad), damping (N s/m or
  !> N m s/rad) and free position (m or rad).
  type :: joint_spring
    integer :: coord = 0
    real(dp) :: stiffness = 0.0_dp, damping = 0.0_dp, free_position = 0.0_dp
  end type joint_spring

  type, extends(effect_t) :: joint_springs_effect
    type(joint_spring), allocatable :: springs(:)
  contains
    procedure :: load => springs_load
    procedure :: add_energy => springs_energy
    procedure :: add_power => springs_power
  end type joint_springs_effect

contains

  function joint_springs_effect_of(springs) result(e)
    type(joint_spring), intent(in) :: springs(:)
    type(joint_springs_effect) :: e
    e%name = 'joint_springs'
    e%acts(stage_load) = .true.
    e%joint_rows_only = .true.
    e%springs = springs
  end function joint_springs_effect_of

  subroutine springs_load(self, d, wk, t, q, qd, mask)
    class(joint_springs_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: mask(:)
    integer :: i, k
    do i = 1, size(self%springs)
      associate(s => self%springs(i))
        k = s%coord
        wk%tau(k) = wk%tau(k) - s%stiffness*(q(k) - s%free_position) - s%damping*qd(k)
      end associate
    end do
  end subroutine springs_load

  !> Potential energy of the springs, 1/2 sum stiffness (q - free_position)^2 (J).
  subroutine springs_energy(self, d, wk, q, e)
    class(joint_springs_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: q(:)
    real(dp), intent(inout) :: e(:)
    integer :: i
    do i = 1, size(self%springs)
      associate(s => self%springs(i))
        e(energy_springs) = e(energy_springs) + 0.5_dp*s%stiffness*(q(s%coord) - s%free_position)**2
      end associate
    end do
  end subroutine springs_energy

  !> The dampers' loss, damping qd^2 (W).
  subroutine springs_power(self, d, wk, t, q, qd, p)
    class(joint_springs_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(inout) :: p(:)
    integer :: i
    do i = 1, size(self%springs)
      p(power_damping) = p(power_damping) + self%springs(i)%damping*qd(self%springs(i)%coord)**2
    end do
  end subroutine springs_power
end module pymr_model_effect_joint_springs
