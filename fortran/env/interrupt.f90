!> SIGINT (Ctrl-C) and SIGTERM during a run: the run polls for them after each step and
!> stops as a failed run does, its partial results kept and its lock released, in one line
!> (exit 2). Without this a run in Python went on to its end, replaced the earlier results
!> and only then raised KeyboardInterrupt; mrsim died with no line, its lock left behind.
module pymr_env_interrupt
  use, intrinsic :: iso_c_binding, only : c_int
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_text, only : fmt
  implicit none
  private
  public :: catch_interrupts, release_interrupts, check_interrupt

  interface
    !> From now on SIGINT and SIGTERM set a flag (those the caller ignores stay ignored).
    subroutine catch_interrupts() bind(c, name='pymr_catch_interrupts')
    end subroutine catch_interrupts
    !> The dispositions before catch_interrupts again.
    subroutine release_interrupts() bind(c, name='pymr_release_interrupts')
    end subroutine release_interrupts
    function interrupt_caught() bind(c, name='pymr_interrupt_caught') result(sig)
      import :: c_int
      integer(c_int) :: sig
    end function interrupt_caught
  end interface

contains

  !> The run's error when a signal came since catch_interrupts: the time reached and the
  !> signal.
  subroutine check_interrupt(t, error)
    real(dp), intent(in) :: t
    type(error_type), allocatable, intent(out) :: error
    integer :: sig
    character(len=:), allocatable :: name
    sig = interrupt_caught()
    if (sig == 0) return
    name = 'SIGTERM'
    if (sig == 2) name = 'SIGINT'
    call fatal_error(error, 'at t = ' // fmt(t) // ' s: stopped by ' // name // &
      & ' (the rows so far are kept in the partial results file)', stat_solver)
  end subroutine check_interrupt
end module pymr_env_interrupt
