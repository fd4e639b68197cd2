!> Error handling: an allocatable error_type travels up to the caller.
!>
!> Library code never stops the program. A failing routine allocates its
!> `intent(out)` error argument with a status and a sentence, then returns;
!> callers test `allocated(error)`. Only the `mrsim` program and the Python
!> binding turn an error into an exit status or an exception.
!>
!> Beside its sentence an error carries structured fields, for callers that act on the
!> kind of fault (the Python package reads them, never the sentence): a keyword `kind`,
!> the scene `group` and `item` it is about, the fault without its place (`fault`) and,
!> for a step refused as unstable, the largest stable step or step ratio. A raise site
!> that knows them sets them with `set_fault` after `fatal_error`.
module pymr_env_error
  use pymr_env_kinds, only : dp
  implicit none
  private
  public :: error_type, fatal_error, prefix_error, set_fault, error_kind, error_list, max_errors
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
    !> A short keyword for the kind of fault: 'unstable_step' (a fixed step the pre-flight
    !> check refuses), 'unstable_ratio' (a multirate step ratio it refuses), 'bad_value' (an
    !> item's value refused); unset: 'bad_input' or 'solver' by the status (error_kind).
    character(len=:), allocatable :: kind
    !> The scene group and item the fault is about ('' when it is about none).
    character(len=:), allocatable :: group, item
    !> What is wrong, without where: the message as first raised, before its place was
    !> put in front ('' when not kept).
    character(len=:), allocatable :: fault
    !> For 'unstable_step': the largest stable step (s); 0 otherwise.
    real(dp) :: stable_step = 0.0_dp
    !> For 'unstable_ratio': the largest stable step ratio k (0 when none is); -1 otherwise.
    integer :: stable_ratio = -1
  end type error_type

  !> Most errors one check of a scene reports (it goes on after each, to show them together).
  integer, parameter :: max_errors = 10

  !> One message of an error_list, and how many more groups gave the same one.
  type :: listed_error
    character(len=:), allocatable :: message, key
    integer :: repeats = 0
  end type listed_error

  !> Errors gathered by a check that goes on after each: one message line per error. One
  !> --set can reach several groups (the six &motion of a 6-DOF joint); the same fault in
  !> each of them is one line, which counts the others.
  type :: error_list
    integer :: n = 0
    type(listed_error), allocatable :: errors(:)
  contains
    procedure :: add => list_add
    procedure :: take => list_take
  end type error_list

contains

  !> Add one error's message (the first max_errors are kept, the rest counted). A message
  !> that differs from a kept one only in its groups' numbers ("&motion #3") adds to that
  !> one's repeats.
  pure subroutine list_add(self, message)
    class(error_list), intent(inout) :: self
    character(len=*), intent(in) :: message
    character(len=:), allocatable :: key
    integer :: k
    if (.not. allocated(self%errors)) allocate(self%errors(0))
    key = without_group_numbers(message)
    do k = 1, size(self%errors)
      if (self%errors(k)%key == key) then
        self%errors(k)%repeats = self%errors(k)%repeats + 1; return
      end if
    end do
    self%n = self%n + 1
    if (self%n > max_errors) return
    self%errors = [self%errors, listed_error(message, key)]
  end subroutine list_add

  !> `message` with the digits after each '#' left out.
  pure function without_group_numbers(message) result(key)
    character(len=*), intent(in) :: message
    character(len=:), allocatable :: key
    integer :: i
    logical :: number
    key = ''
    number = .false.
    do i = 1, len(message)
      number = (number .or. message(max(i - 1, 1):max(i - 1, 1)) == '#' .and. i > 1) &
        & .and. index('0123456789', message(i:i)) > 0
      if (.not. number) key = key // message(i:i)
    end do
  end function without_group_numbers

  !> The gathered errors as one error (one line each; a last line counts those left out),
  !> or none.
  pure subroutine list_take(self, error)
    class(error_list), intent(in) :: self
    type(error_type), allocatable, intent(out) :: error
    character(len=12) :: buf
    integer :: k
    if (self%n == 0) return
    allocate(error)
    error%message = ''
    do k = 1, size(self%errors)
      if (k > 1) error%message = error%message // new_line('a')
      error%message = error%message // self%errors(k)%message
      if (self%errors(k)%repeats > 0) then
        write(buf, '(i0)') self%errors(k)%repeats
        error%message = error%message // ' (the same in ' // trim(buf) // ' more groups)'
      end if
    end do
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

  !> Set the structured fields of an existing error (those given).
  pure subroutine set_fault(error, kind, group, item, fault, stable_step, stable_ratio)
    type(error_type), intent(inout) :: error
    character(len=*), intent(in), optional :: kind, group, item, fault
    real(dp), intent(in), optional :: stable_step
    integer, intent(in), optional :: stable_ratio
    if (present(kind)) error%kind = kind
    if (present(group)) error%group = group
    if (present(item)) error%item = item
    if (present(fault)) error%fault = fault
    if (present(stable_step)) error%stable_step = stable_step
    if (present(stable_ratio)) error%stable_ratio = stable_ratio
  end subroutine set_fault

  !> The error's kind: the one its raise site set, else 'bad_input' (status 1) or 'solver'.
  pure function error_kind(error) result(kind)
    type(error_type), intent(in) :: error
    character(len=:), allocatable :: kind
    if (allocated(error%kind)) then
      kind = error%kind
    else
      kind = merge('bad_input', 'solver   ', error%stat == stat_input)
      kind = trim(kind)
    end if
  end function error_kind

  !> Put `prefix` (with ': ') in front of an existing error's message.
  pure subroutine prefix_error(error, prefix)
    type(error_type), intent(inout) :: error
    character(len=*), intent(in) :: prefix
    error%message = prefix // ': ' // error%message
  end subroutine prefix_error
end module pymr_env_error
