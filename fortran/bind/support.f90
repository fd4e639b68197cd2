!> Helpers of the binding layer that f2py need not see.
module pymr_bind_support
  use pymr_error, only : error_type
  implicit none
  private
  public :: report
contains
  !> Copy an error (if any) into a status (0 ok, 1 bad input, 2 failed run) and a message.
  subroutine report(error, stat, message)
    type(error_type), allocatable, intent(in) :: error
    integer, intent(out) :: stat
    character(len=*), intent(out) :: message
    stat = 0; message = ''
    if (allocated(error)) then
      stat = error%stat; message = error%message
    end if
  end subroutine report
end module pymr_bind_support

!> Models kept open between binding calls (for integrators driven from Python, such as
!> scipy's, that call the right-hand side many times): a handle is an index here.
module pymr_bind_models
  use pymr_model, only : model_t
  implicit none
  private
  public :: open_models, open_flags

  type(model_t), allocatable, target :: open_models(:)
  logical, allocatable :: open_flags(:)
end module pymr_bind_models

