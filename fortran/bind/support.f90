!> Helpers of the binding layer that f2py need not see.
module pymr_bind_support
  use pymr_env_error, only : error_type
  use pymr_env_text, only : printable
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
      stat = error%stat; message = printable(error%message, len(message))
    end if
  end subroutine report
end module pymr_bind_support
