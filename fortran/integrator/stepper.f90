!> The one interface of pymr's time steppers (single-rate Nordsieck ABM, multirate with the
!> 'response' or the paper's 'full' coupling): start, advance one step, the time reached,
!> dense output inside the last step, save and load of the whole state, the counts of what
!> was done, and the linear-stability data of the pre-flight check (the steps its PECE
!> formula takes per kind of coordinate; its whole state as a vector, so that the check can
!> apply the stepper itself to the linearised model). The run loop, the checkpoint and the
!> pre-flight check use nothing else; which stepper a scene gets is chosen once, when it
!> is made.
module pymr_integrator_stepper
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type
  use pymr_integrator_ode, only : ode_system
  implicit none
  private
  public :: stepper_t, step_counts, pece_steps

  !> What a stepper has done (its system counts the evaluations).
  type :: step_counts
    !> Accepted steps of the slow and the fast coordinates (equal for single-rate).
    integer :: steps_slow = 0, steps_fast = 0
    !> Rejected steps, and the last step ratio H/h (1 for single-rate).
    integer :: rejected = 0, ratio = 1
    !> The last (slow) step (s).
    real(dp) :: h_last = 0.0_dp
    !> Fast right-hand sides the stepper computed itself, without the model (the
    !> 'response' coupling's surrogate evaluations).
    integer :: evals_fast = 0
  end type step_counts

  !> The fixed steps a stepper's PECE formula takes on vibrations carried mostly by joint
  !> and by modal coordinates (0: none, such modes are judged by the macro-step map alone),
  !> and the &integrator items that set them.
  type :: pece_steps
    real(dp) :: h_joint = 0.0_dp, h_modal = 0.0_dp
    character(len=8) :: item_joint = 'h_slow', item_modal = 'h_slow'
  end type pece_steps

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
    procedure(steps_iface), deferred :: pece
    procedure(state_size_iface), deferred :: state_size
    procedure(get_state_iface), deferred :: get_state
    procedure(set_state_iface), deferred :: set_state
    !> Step ratio H/h for the next steps (multirate; nothing for single-rate).
    procedure :: set_ratio => no_ratio
    !> Order of the method in the last step (4 for the paper's ABM4).
    procedure :: order => order_four
    !> Project the state reached (the Nordsieck array's value column) onto the system's
    !> constraints after an accepted step (sys%project).
    procedure(project_iface), deferred :: project
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
    !> Its fixed steps, for the pre-flight check.
    pure function steps_iface(self) result(s)
      import :: stepper_t, pece_steps
      class(stepper_t), intent(in) :: self
      type(pece_steps) :: s
    end function steps_iface
    subroutine project_iface(self, sys, error)
      import :: stepper_t, ode_system, error_type
      class(stepper_t), intent(inout) :: self
      class(ode_system), intent(inout) :: sys
      type(error_type), allocatable, intent(out) :: error
    end subroutine project_iface
    !> Length of its whole state as a vector.
    pure integer function state_size_iface(self)
      import :: stepper_t
      class(stepper_t), intent(in) :: self
    end function state_size_iface
    !> Its whole state as a vector v: v(1:2n) the state [q; qd] at its time, then the rest
    !> (higher Nordsieck columns, histories) in an order of its own.
    pure subroutine get_state_iface(self, v)
      import :: stepper_t, dp
      class(stepper_t), intent(in) :: self
      real(dp), intent(out) :: v(:)
    end subroutine get_state_iface
    pure subroutine set_state_iface(self, v)
      import :: stepper_t, dp
      class(stepper_t), intent(inout) :: self
      real(dp), intent(in) :: v(:)
    end subroutine set_state_iface
  end interface

contains

  pure integer function order_four(self)
    class(stepper_t), intent(in) :: self
    order_four = 4
  end function order_four

  pure subroutine no_ratio(self, k)
    class(stepper_t), intent(inout) :: self
    integer, intent(in) :: k
  end subroutine no_ratio
end module pymr_integrator_stepper
