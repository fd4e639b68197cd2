!> Loading the model of a scene: read the scene (with overrides), build the model, and choose
!> how its single-rate evaluations solve for the accelerations.
module pymr_driver_load_model
  use pymr_env_error, only : error_type, fatal_error
  use pymr_model_scene, only : scene_t
  use pymr_io_namelist_input, only : read_scene
  use pymr_driver_build, only : build_model
  use pymr_model, only : model_t
  implicit none
  private
  public :: load_model

  !> 'auto' dynamics with flexible bodies: the articulated-body algorithm from this many joint
  !> coordinates on.
  integer, parameter :: articulated_from = 12

contains

  !> Read and build the model of a scene (with overrides).
  subroutine load_model(file, overrides, sc, model, error, n)
    character(len=*), intent(in) :: file, overrides
    type(scene_t), intent(out) :: sc
    type(model_t), intent(out) :: model
    type(error_type), allocatable, intent(out) :: error
    !> The number of coordinates the caller's arrays hold (the binding): another is an error.
    integer, intent(in), optional :: n
    call read_scene(file, overrides, sc, error); if (allocated(error)) return
    call build_model(sc, model, error); if (allocated(error)) return
    call model%use_articulated(articulated_dynamics(sc, model))
    if (present(n)) then
      if (model%d%n /= n) call fatal_error(error, 'q has the wrong length')
    end if
  end subroutine load_model

  !> Whether single-rate evaluations take the articulated-body algorithm: as the scene says,
  !> or ('auto') where it is the faster (`pymr bench chain`, `pymr bench rhs`): always
  !> without flexible bodies, and with them from articulated_from joint coordinates on
  !> (below, condensing the modes costs more than assembling and factoring a small M).
  logical function articulated_dynamics(sc, model)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    select case (trim(sc%integrator%dynamics))
    case ('articulated'); articulated_dynamics = .true.
    case ('mass_matrix'); articulated_dynamics = .false.
    case default; articulated_dynamics = (model%d%nj >= articulated_from .or. .not. any(model%d%flexible)) &
      & .and. model%d%cuts%n_rows == 0
    end select
  end function articulated_dynamics
end module pymr_driver_load_model
