!> Error handling: an allocatable error_type travels up to the caller.
!>
!> Library code never stops the program. A failing routine allocates its
!> `intent(out)` error argument with a status and a sentence, then returns;
!> callers test `allocated(error)`. Only the `mrsim` program and the Python
!> binding turn an error into an exit status or an exception.
module pymr_error
  implicit none
  private
  public :: error_type, fatal_error, prefix_error
  public :: stat_input, stat_solver

  !> Status of an error caused by the scene or the command line (bad input).
  integer, parameter :: stat_input = 1
  !> Status of an error raised while running (singular matrix, step underflow, non-finite state).
  integer, parameter :: stat_solver = 2

  !> A failure with its status and a one-line message.
  type :: error_type
    !> stat_input or stat_solver
    integer :: stat = stat_input
    !> What went wrong, in words.
    character(len=:), allocatable :: message
  end type error_type

contains

  !> Allocate `error` with a message and a status (default stat_input).
  pure subroutine fatal_error(error, message, stat)
    type(error_type), allocatable, intent(out) :: error
    character(len=*), intent(in) :: message
    integer, intent(in), optional :: stat
    allocate(error)
    error%message = message
    if (present(stat)) error%stat = stat
  end subroutine fatal_error

  !> Put `prefix` (with ': ') in front of an existing error's message.
  pure subroutine prefix_error(error, prefix)
    type(error_type), intent(inout) :: error
    character(len=*), intent(in) :: prefix
    error%message = prefix // ': ' // error%message
  end subroutine prefix_error
end module pymr_error
