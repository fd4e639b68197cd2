!> The memory a process may hold (the machine's, or a ulimit's), for the size checks of
!> models too large to run.
module pymr_env_memory
  use, intrinsic :: iso_c_binding, only : c_double
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_text, only : itoa, fmt
  implicit none
  private
  public :: memory_limit, check_room, refuse_room, check_bytes, refuse_bytes

  interface
    function c_memory_limit() bind(c, name='pymr_memory_limit') result(bytes)
      import :: c_double
      real(c_double) :: bytes
    end function c_memory_limit
  end interface

contains

  !> The bytes the process may still take: physical memory, or less where an address-space
  !> limit (less what the process holds) or a data limit is set; huge when the system does
  !> not say.
  real(dp) function memory_limit()
    memory_limit = real(c_memory_limit(), dp)
    if (memory_limit < 0.0_dp) memory_limit = huge(1.0_dp)
  end function memory_limit

  !> A job on a model of n coordinates whose dense matrices need `need` bytes at its peak:
  !> refused (refuse_room) when that is more than the process may still take, before the
  !> job allocates them (an allocation that fails later ends in the compiler's runtime
  !> message, or a segmentation fault, and inside Python ends the session).
  subroutine check_room(n, need, error)
    integer, intent(in) :: n
    real(dp), intent(in) :: need
    type(error_type), allocatable, intent(out) :: error
    call check_bytes(dense_matrices(n), need, error)
  end subroutine check_room

  !> The one line (exit 2) of a model too large for the memory: both figures, in GB.
  subroutine refuse_room(n, need, room, error)
    integer, intent(in) :: n
    real(dp), intent(in) :: need, room
    type(error_type), allocatable, intent(out) :: error
    call refuse_bytes(dense_matrices(n), need, room, error)
  end subroutine refuse_room

  !> What a model's dense matrices are called in the messages.
  function dense_matrices(n) result(what)
    integer, intent(in) :: n
    character(len=:), allocatable :: what
    what = 'the model has ' // itoa(n) // ' coordinates: its dense matrices'
  end function dense_matrices

  !> Arrays of `need` bytes that `what` names (a body's quadrature): refused (refuse_bytes)
  !> when that is more than the process may still take, before they are allocated.
  subroutine check_bytes(what, need, error)
    character(len=*), intent(in) :: what
    real(dp), intent(in) :: need
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: room
    room = memory_limit()
    if (need > room) call refuse_bytes(what, need, room, error)
  end subroutine check_bytes

  !> The one line (exit 2) of arrays (`what` names them) too large for the memory: both
  !> figures, in GB.
  subroutine refuse_bytes(what, need, room, error)
    character(len=*), intent(in) :: what
    real(dp), intent(in) :: need, room
    type(error_type), allocatable, intent(out) :: error
    call fatal_error(error, what // ' need about ' // fmt(need/1.0e9_dp) // ' GB, more than the ' // &
      & fmt(room/1.0e9_dp) // ' GB this process may still take (the machine''s memory, or its ulimit -v)', &
      & stat_solver)
  end subroutine refuse_bytes
end module pymr_env_memory
