!> The one interface of pymr's time steppers (single-rate Nordsieck ABM, multirate): start,
!> advance one step, the time reached, dense output inside the last step, save and load of
!> the whole state, and the counts of what was done. The run loop and the checkpoint use
!> nothing else; which stepper a scene gets is chosen once, when it is made.
module pymr_integrator_stepper
  use pymr_kinds, only : dp
  use pymr_error, only : error_type
  use pymr_integrator_ode, only : ode_system
  implicit none
  private
  public :: stepper_t, step_counts

  !> What a stepper has done (its system counts the evaluations).
  type :: step_counts
    !> Accepted steps of the slow and the fast coordinates (equal for single-rate).
    integer :: steps_slow = 0, steps_fast = 0
    !> Rejected steps, and the last step ratio H/h (1 for single-rate).
    integer :: rejected = 0, ratio = 1
    !> The last (slow) step (s).
    real(dp) :: h_last = 0.0_dp
  end type step_counts

  type, abstract :: stepper_t
  contains
    procedure(start_iface), deferred :: start
    procedure(advance_iface), deferred :: advance
    procedure(time_iface), deferred :: time
    procedure(value_iface), deferred :: value_at
    procedure(save_iface), deferred :: save
    procedure(load_iface), deferred :: load
    procedure(counts_iface), deferred :: counts
    procedure(name_iface), deferred :: name
  end type stepper_t

  abstract interface
    !> Start at (t0, x0) with the (slow) step h.
    subroutine start_iface(self, sys, t0, x0, h, error)
      import :: stepper_t, ode_system, dp, error_type
      class(stepper_t), intent(inout) :: self
      class(ode_system), intent(inout) :: sys
      real(dp), intent(in) :: t0, x0(:), h
      type(error_type), allocatable, intent(out) :: error
    end subroutine start_iface
    !> One accepted (macro) step.
    subroutine advance_iface(self, sys, error)
      import :: stepper_t, ode_system, error_type
      class(stepper_t), intent(inout) :: self
      class(ode_system), intent(inout) :: sys
      type(error_type), allocatable, intent(out) :: error
    end subroutine advance_iface
    pure real(dp) function time_iface(self)
      import :: stepper_t, dp
      class(stepper_t), intent(in) :: self
    end function time_iface
    !> The state at t inside the last step.
    pure subroutine value_iface(self, t, x)
      import :: stepper_t, dp
      class(stepper_t), intent(in) :: self
      real(dp), intent(in) :: t
      real(dp), intent(out) :: x(:)
    end subroutine value_iface
    !> Write (read) the whole state to (from) an open unformatted stream unit.
    subroutine save_iface(self, unit, ios)
      import :: stepper_t
      class(stepper_t), intent(in) :: self
      integer, intent(in) :: unit
      integer, intent(out) :: ios
    end subroutine save_iface
    subroutine load_iface(self, unit, ios)
      import :: stepper_t
      class(stepper_t), intent(inout) :: self
      integer, intent(in) :: unit
      integer, intent(out) :: ios
    end subroutine load_iface
    pure function counts_iface(self) result(c)
      import :: stepper_t, step_counts
      class(stepper_t), intent(in) :: self
      type(step_counts) :: c
    end function counts_iface
    !> 'single' or 'multirate' (checkpoints name the stepper they hold).
    pure function name_iface(self) result(s)
      import :: stepper_t
      class(stepper_t), intent(in) :: self
      character(len=:), allocatable :: s
    end function name_iface
  end interface
end module pymr_integrator_stepper
