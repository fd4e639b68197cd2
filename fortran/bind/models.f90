!> Models kept open between binding calls (for integrators driven from Python, such as
!> scipy's, that call the right-hand side many times): a handle is an index here.
module pymr_bind_models
  use pymr_env_error, only : error_type, fatal_error
  use pymr_model, only : model_t
  implicit none
  private
  public :: open_models, open_flags, check_handle

  type(model_t), allocatable, target :: open_models(:)
  logical, allocatable :: open_flags(:)
contains
  !> An error unless `handle` names an open model.
  subroutine check_handle(handle, error)
    integer, intent(in) :: handle
    type(error_type), allocatable, intent(out) :: error
    if (.not. allocated(open_flags)) then
      call fatal_error(error, 'no open model')
    else if (handle < 1 .or. handle > size(open_flags)) then
      call fatal_error(error, 'no open model with this handle')
    else if (.not. open_flags(handle)) then
      call fatal_error(error, 'the model of this handle is closed')
    end if
  end subroutine check_handle
end module pymr_bind_models

