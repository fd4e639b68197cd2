!> The memory a process may hold (the machine's, or a ulimit's), for the size checks of
!> models too large to run.
module pymr_env_memory
  use, intrinsic :: iso_c_binding, only : c_double
  use pymr_env_kinds, only : dp
  implicit none
  private
  public :: memory_limit

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
end module pymr_env_memory
