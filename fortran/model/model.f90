!> The multibody model as an ODE system: state x = [q; qd], f = [qd; qdd] with M qdd = P.
module pymr_model
  use pymr_kinds, only : dp
  use pymr_error, only : error_type, prefix_error
  use pymr_lapack, only : potrf, potrs
  use pymr_integrator_ode, only : ode_system
  use pymr_model_types, only : model_data, effect_gravity, effect_joint_drives, effect_modal_damping
  use pymr_model_kinematics, only : forward_kinematics
  use pymr_model_assembly, only : body_terms, composite_terms, assemble_mass, assemble_rhs, kinetic_energy
  use pymr_model_effects, only : add_gravity, add_joint_drives, add_modal_damping, gravity_potential, &
    & elastic_potential
  implicit none
  private
  public :: model_t

  !> A built model: data and work arrays, and the ODE interface the integrators use.
  type, extends(ode_system) :: model_t
    type(model_data) :: d
  contains
    procedure :: eval => model_eval
    procedure :: component_name => model_component_name
    procedure :: terms => model_terms
    procedure :: accelerations => model_accelerations
    procedure :: energy => model_energy
  end type model_t

contains

  !> Mass matrix and right-hand side at (t, q, qd), left in self%d%mm and self%d%p.
  subroutine model_terms(self, t, q, qd)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t, q(:), qd(:)
    associate(d => self%d)
      call forward_kinematics(d, q, qd)
      call body_terms(d, q, qd)
      if (d%effect_on(effect_gravity)) call add_gravity(d)
      if (d%effect_on(effect_modal_damping)) call add_modal_damping(d, qd)
      d%tau = 0.0_dp
      if (d%effect_on(effect_joint_drives)) call add_joint_drives(d, t)
      call composite_terms(d)
      call assemble_mass(d)
      call assemble_rhs(d)
      d%evals = d%evals + 1
    end associate
  end subroutine model_terms

  !> Accelerations qdd from M qdd = P (LAPACK Cholesky).
  subroutine model_accelerations(self, t, q, qd, qdd, error)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(out), contiguous :: qdd(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: minor
    character(len=32) :: buf
    call self%terms(t, q, qd)
    associate(d => self%d)
      d%lf = d%mm
      call potrf(d%lf, 'the mass matrix', error, minor)
      if (allocated(error)) then
        write(buf, '(es12.5)') t
        if (minor > 0) error%message = error%message // ' (coordinate ' // trim(d%qname(minor)) // ')'
        call prefix_error(error, 'at t = ' // trim(adjustl(buf)) // ' s')
        return
      end if
      qdd = d%p
      call potrs(d%lf, qdd, 'the mass matrix', error)
    end associate
  end subroutine model_accelerations

  !> f(t, x) for x = [q; qd].
  subroutine model_eval(self, t, x, f, error)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: x(:)
    real(dp), intent(out), contiguous :: f(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: n
    n = self%d%n
    f(1:n) = x(n+1:2*n)
    call self%accelerations(t, x(1:n), x(n+1:2*n), f(n+1:2*n), error)
  end subroutine model_eval

  !> Name of state component i: joint.q... for i <= n, joint.qd... after.
  function model_component_name(self, i) result(name)
    class(model_t), intent(in) :: self
    integer, intent(in) :: i
    character(len=:), allocatable :: name
    if (i <= self%d%n) then
      name = trim(self%d%qname(i))
    else
      name = trim(self%d%qdname(i - self%d%n))
    end if
  end function model_component_name

  !> Kinetic and potential (elastic, and gravity when on) energy (J) at (q, qd).
  subroutine model_energy(self, q, qd, kinetic, potential)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: q(:), qd(:)
    real(dp), intent(out) :: kinetic, potential
    call forward_kinematics(self%d, q, qd)
    call body_terms(self%d, q, qd)
    kinetic = kinetic_energy(self%d, qd)
    potential = elastic_potential(self%d, q)
    if (self%d%effect_on(effect_gravity)) potential = potential + gravity_potential(self%d)
  end subroutine model_energy
end module pymr_model
