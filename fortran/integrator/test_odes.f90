!> ODEs with known solutions, used by the tests of the integrators.
module pymr_integrator_test_odes
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_integrator_ode, only : ode_system
  use pymr_integrator_abm, only : abm_integrator
  use pymr_integrator_adams, only : adams_integrator
  use pymr_integrator_stepper, only : stepper_t, step_counts
  use pymr_integrator_control, only : step_control
  implicit none
  private
  public :: test_ode, integrate_test_ode

  !> Problem 4's angular frequency (rad/s) and damping ratio.
  real(dp), parameter :: w4 = 8*atan(1.0_dp), zeta4 = 0.05_dp
  !> Problem 6's projection fails on a state further than this from its unit circle (a
  !> Newton projection that does not converge from far off its manifold).
  real(dp), parameter :: reach6 = 1.0e-9_dp

  !> Problem 1: oscillator; 2: y' = -2 t y^2; 3: Kepler orbit (e = 0.5); 4: a lightly damped
  !> oscillator (1 Hz, damping ratio 0.05) at rest until a constant force turns on at t = 1
  !> (static deflection 1); 5: y' = -y; 6: problem 1 with its invariant |x| = 1 as a
  !> constraint: the projection scales x onto the unit circle, and fails further than reach6
  !> from it.
  type, extends(ode_system) :: test_ode
    integer :: problem = 1
  contains
    procedure :: eval => test_eval
    procedure :: component_name => test_name
    procedure :: project => test_project
  end type test_ode

contains

  subroutine test_eval(self, t, x, f, error)
    class(test_ode), intent(inout) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: x(:)
    real(dp), intent(out), contiguous :: f(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: r3
    select case (self%problem)
    case (1, 6)
      f = [x(2), -x(1)]
    case (2)
      f(1) = -2.0_dp*t*x(1)**2
    case (3)
      r3 = norm2(x(1:2))**3
      f = [x(3), x(4), -x(1)/r3, -x(2)/r3]
    case (4)
      f = [x(2), w4**2*(merge(1.0_dp, 0.0_dp, t >= 1.0_dp) - x(1)) - 2*zeta4*w4*x(2)]
    case (5)
      f = -x
    end select
  end subroutine test_eval

  !> Problem 6: x onto the unit circle, an error when it is further than reach6 from it.
  subroutine test_project(self, t, x, error)
    class(test_ode), intent(inout) :: self
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: x(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: r
    if (self%problem /= 6) return
    r = norm2(x)
    if (abs(r - 1.0_dp) > reach6) then
      call fatal_error(error, 'the projection onto |x| = 1 did not converge'); return
    end if
    x = x/r
  end subroutine test_project

  function test_name(self, i) result(name)
    class(test_ode), intent(in) :: self
    integer, intent(in) :: i
    character(len=:), allocatable :: name
    character(len=8) :: buf
    write(buf, '(a,i0)') 'x', i
    name = trim(buf)
  end function test_name

  !> Integrate problem from 0 to t_end (exactly, fixed step h must divide t_end; adaptive
  !> runs end by interpolation) and return the final state. order < 0: the paper's ABM4
  !> (fixed or adaptive); 0-12: formula 'adams' (adaptive) of variable or that order.
  !> th, hh, qh: time, step and order of each accepted step (as many as they hold).
  subroutine integrate_test_ode(problem, t_end, h, adaptive, rtol, atol, n_corr, order, x, steps, evals, rejected, &
      & th, hh, qh, error)
    integer, intent(in) :: problem, n_corr, order
    real(dp), intent(out) :: th(:), hh(:)
    integer, intent(out) :: qh(:)
    real(dp), intent(in) :: t_end, h, rtol, atol
    logical, intent(in) :: adaptive
    real(dp), intent(out) :: x(:)
    integer, intent(out) :: steps, evals, rejected
    type(error_type), allocatable, intent(out) :: error
    type(test_ode) :: sys
    class(stepper_t), allocatable :: integ
    type(abm_integrator), allocatable :: abm
    type(adams_integrator), allocatable :: adams
    type(step_control) :: ctl
    real(dp), allocatable :: x0(:)
    real(dp) :: t_prev
    integer :: nx, k
    type(step_counts) :: c
    steps = 0; evals = 0; rejected = 0; x = 0.0_dp; th = 0.0_dp; hh = 0.0_dp; qh = 0
    nx = merge(1, merge(4, 2, problem == 3), problem == 2 .or. problem == 5)
    if (problem < 1 .or. problem > 6 .or. size(x) /= nx) then
      call fatal_error(error, 'unknown test problem or wrong state size'); return
    end if
    sys%problem = problem
    select case (problem)
    case (1, 6); x0 = [1.0_dp, 0.0_dp]
    case (2); x0 = [1.0_dp]
    case (3); x0 = [0.5_dp, 0.0_dp, 0.0_dp, sqrt(3.0_dp)]
    case (4); x0 = [0.0_dp, 0.0_dp]
    case (5); x0 = [1.0_dp]
    end select
    ctl%rtol = rtol; ctl%atol = atol
    if (order < 0) then
      allocate(abm)
      call abm%init(nx, adaptive, ctl, n_corr)
      call move_alloc(abm, integ)
    else
      allocate(adams)
      call adams%init(nx, order, ctl, n_corr == 0)
      call move_alloc(adams, integ)
    end if
    select type (integ)
    type is (adams_integrator)
      if (.not. adaptive) then
        call exact_start(integ, problem, order, h, error); if (allocated(error)) return
      end if
    end select
    if (.not. (order > 0 .and. .not. adaptive)) then
      call integ%start(sys, 0.0_dp, x0, h, error); if (allocated(error)) return
    end if
    k = 0
    do
      c = integ%counts()
      if (integ%time() >= t_end - 1.0e-9_dp*c%h_last) exit
      t_prev = integ%time()
      call integ%advance(sys, error); if (allocated(error)) return
      k = k + 1
      if (k <= size(th)) then
        th(k) = integ%time(); hh(k) = integ%time() - t_prev; qh(k) = integ%order()
      end if
    end do
    call integ%value_at(t_end, x)
    select type (integ)
    type is (abm_integrator)
      steps = integ%steps; evals = integ%evals; rejected = integ%rejected
    type is (adams_integrator)
      steps = integ%cnt%steps; evals = integ%cnt%evals; rejected = integ%cnt%rejected
    end select
  end subroutine integrate_test_ode

  !> Fixed steps h of formula 'adams' at the order `order` from the exact Nordsieck array,
  !> so that the measured order is the method's own: problem 1 (x = cos t: its j-th
  !> derivative at 0 is cos(j pi/2), that of x' = -sin t is -sin(j pi/2)) or problem 2
  !> (y = 1/(1 + t^2) = sum (-1)^k t^(2k): h^j y^(j)(0)/j! = h^j (-1)^(j/2) for even j) or
  !> problem 5 (y = exp(-t): (-h)^j/j!).
  subroutine exact_start(st, problem, order, h, error)
    type(adams_integrator), intent(inout) :: st
    integer, intent(in) :: problem, order
    real(dp), intent(in) :: h
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: half_pi, fact
    integer :: j
    if (problem > 2 .and. problem /= 5 .or. order < 1) then
      call fatal_error(error, "fixed steps of formula 'adams' need problem 1, 2 or 5 and an order 1-12"); return
    end if
    half_pi = 2*atan(1.0_dp)
    st%adaptive = .false.
    st%z = 0.0_dp
    fact = 1.0_dp
    do j = 0, order
      if (j > 0) fact = fact*j
      if (problem == 5) then
        st%z(:, j) = (-h)**j/fact
      else if (problem == 1) then
        st%z(:, j) = h**j/fact*[cos(j*half_pi), -sin(j*half_pi)]
      else if (mod(j, 2) == 0) then
        st%z(:, j) = h**j*(-1)**(j/2)
      end if
    end do
    st%q = order; st%h = h; st%t = 0.0_dp; st%tau = h
  end subroutine exact_start
end module pymr_integrator_test_odes
