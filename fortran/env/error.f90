!> Error handling: an allocatable error_type travels up to the caller.
!>
!> Library code never stops the program. A failing routine allocates its
!> `intent(out)` error argument with a status and a sentence, then returns;
!> callers test `allocated(error)`. Only the `mrsim` program and the Python
!> binding turn an error into an exit status or an exception.
module pymr_env_error
  implicit none
  private
  public :: error_type, fatal_error, prefix_error, error_list, max_errors
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

  !> Most errors one check of a scene reports (it goes on after each, to show them together).
  integer, parameter :: max_errors = 10

  !> Errors gathered by a check that goes on after each: one message line per error.
  type :: error_list
    integer :: n = 0
    character(len=:), allocatable :: text
  contains
    procedure :: add => list_add
    procedure :: take => list_take
  end type error_list

contains

  !> Add one error's message (the first max_errors are kept, the rest counted).
  pure subroutine list_add(self, message)
    class(error_list), intent(inout) :: self
    character(len=*), intent(in) :: message
    self%n = self%n + 1
    if (self%n > max_errors) return
    if (allocated(self%text)) then
      self%text = self%text // new_line('a') // message
    else
      self%text = message
    end if
  end subroutine list_add

  !> The gathered errors as one error (one line each; a last line counts those left out),
  !> or none.
  pure subroutine list_take(self, error)
    class(error_list), intent(in) :: self
    type(error_type), allocatable, intent(out) :: error
    character(len=12) :: buf
    if (self%n == 0) return
    allocate(error)
    error%message = self%text
    if (self%n > max_errors) then
      write(buf, '(i0)') self%n - max_errors
      error%message = error%message // new_line('a') // '(and ' // trim(buf) // ' more errors)'
    end if
  end subroutine list_take

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
end module pymr_env_error
