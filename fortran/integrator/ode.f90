!> The abstract first-order system x' = f(t, x) that the integrators advance.
!> Models extend `ode_system`; one integrator serves every model.
module pymr_integrator_ode
  use pymr_kinds, only : dp
  use pymr_error, only : error_type
  implicit none
  private
  public :: ode_system

  !> A first-order system of `n` equations.
  type, abstract :: ode_system
  contains
    !> Evaluate f(t, x).
    procedure(eval_iface), deferred :: eval
    !> Name of state component i for messages ("elevation.qd").
    procedure(name_iface), deferred :: component_name
  end type ode_system

  abstract interface
    subroutine eval_iface(self, t, x, f, error)
      import :: ode_system, dp, error_type
      class(ode_system), intent(inout) :: self
      !> Time (s).
      real(dp), intent(in) :: t
      !> State.
      real(dp), intent(in), contiguous :: x(:)
      !> Derivative of the state.
      real(dp), intent(out), contiguous :: f(:)
      type(error_type), allocatable, intent(out) :: error
    end subroutine eval_iface
    function name_iface(self, i) result(name)
      import :: ode_system
      class(ode_system), intent(in) :: self
      integer, intent(in) :: i
      character(len=:), allocatable :: name
    end function name_iface
  end interface
end module pymr_integrator_ode
