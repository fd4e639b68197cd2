!> The abstract first-order system x' = f(t, x) that the integrators advance.
!> Models extend `ode_system`; one integrator serves every model.
module pymr_integrator_ode
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type
  implicit none
  private
  public :: ode_system, partitioned_system

  !> A first-order system of `n` equations.
  type, abstract :: ode_system
  contains
    !> Evaluate f(t, x).
    procedure(eval_iface), deferred :: eval
    !> Name of state component i for messages ("elevation.qd").
    procedure(name_iface), deferred :: component_name
    !> Bring a state back onto the system's invariant manifold after an accepted step
    !> (a model with closed loops: its constraints); nothing for most systems.
    procedure :: project => no_projection
  end type ode_system

  !> A second-order system split into slow and fast coordinates for multirate
  !> integration. The full state is x = [q_s; q_f; qd_s; qd_f]; the slow state is
  !> xs = [q_s; qd_s], the fast state xf = [q_f; qd_f].
  type, abstract, extends(ode_system) :: partitioned_system
  contains
    !> Numbers of slow and fast coordinates.
    procedure(count_iface), deferred :: n_slow, n_fast
    !> Both derivatives from one full evaluation: qdd_s from the Schur complement equation
    !> M_e qdd_s = Q_e, then qdd_f from M_ff qdd_f = Q_f - M_fs qdd_s.
    procedure(sync_iface), deferred :: sync_rhs
    !> Fast derivative [qd_f; qdd_f] from M_ff qdd_f = Q_f - M_fs acc_s with given slow
    !> accelerations (the fast rows assembled at the full state).
    procedure(fast_iface), deferred :: fast_rhs
    !> After a synchronised evaluation: g = M^-1 E (n x nf, rows in the order of q), the
    !> accelerations of all coordinates per unit generalised force on each fast coordinate,
    !> and the coefficients of the fast forces that are linear in the fast state: the
    !> elastic and damping forces kf a + df ad (the 'response' coupling).
    procedure(response_iface), deferred :: force_response
  end type partitioned_system
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
    pure integer function count_iface(self)
      import :: partitioned_system
      class(partitioned_system), intent(in) :: self
    end function count_iface
    subroutine sync_iface(self, t, xs, xf, fs, ff, error)
      import :: partitioned_system, dp, error_type
      class(partitioned_system), intent(inout) :: self
      real(dp), intent(in) :: t, xs(:), xf(:)
      real(dp), intent(out) :: fs(:), ff(:)
      type(error_type), allocatable, intent(out) :: error
    end subroutine sync_iface
    subroutine fast_iface(self, t, xs, xf, acc_s, ff, error)
      import :: partitioned_system, dp, error_type
      class(partitioned_system), intent(inout) :: self
      real(dp), intent(in) :: t, xs(:), xf(:), acc_s(:)
      real(dp), intent(out) :: ff(:)
      type(error_type), allocatable, intent(out) :: error
    end subroutine fast_iface
    subroutine response_iface(self, g, kf, df, error)
      import :: partitioned_system, dp, error_type
      class(partitioned_system), intent(inout) :: self
      real(dp), intent(out) :: g(:, :), kf(:), df(:)
      type(error_type), allocatable, intent(out) :: error
    end subroutine response_iface
    function name_iface(self, i) result(name)
      import :: ode_system
      class(ode_system), intent(in) :: self
      integer, intent(in) :: i
      character(len=:), allocatable :: name
    end function name_iface
  end interface

contains

  subroutine no_projection(self, t, x, error)
    class(ode_system), intent(inout) :: self
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: x(:)
    type(error_type), allocatable, intent(out) :: error
  end subroutine no_projection
end module pymr_integrator_ode
