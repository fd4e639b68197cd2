!> The multibody model as an ODE system: state x = [q; qd], f = [qd; qdd] with M qdd = P.
module pymr_model
  use pymr_env_kinds, only : dp
  use, intrinsic :: ieee_arithmetic, only : ieee_is_finite
  use pymr_env_error, only : error_type, prefix_error, fatal_error, stat_solver
  use pymr_env_lapack, only : potrf, potrs, factor_inverse
  use pymr_integrator_ode, only : partitioned_system
  use pymr_model_types, only : model_data, model_work, model_counters
  use pymr_model_kinematics, only : forward_kinematics
  use pymr_model_assembly, only : body_terms, composite_terms, assemble_mass, assemble_rhs, kinetic_energy
  use pymr_model_articulated, only : articulated_accelerations
  use pymr_model_loops, only : constrained_accelerations, project_positions, project_velocities, &
    & constrain_fast_accelerations, constrain_response
  use pymr_model_effect, only : effect_slot, stage_carried, impose_effects, deform_effects, load_effects, carried_effects, &
    & rows_effects, accelerate_effects, effect_energies, effect_fast_damping, effect_motion_energies, &
    & effects_vary_modal_mass, save_effect_states, load_effect_states
  implicit none
  private
  public :: model_t, modal_stiffness_damping, model_counters, check_terms_finite

  !> A built model: data and work arrays, and the ODE interface the integrators use.
  !> Slow coordinates are the joint coordinates (1..nj), fast ones the modal coordinates.
  type, extends(partitioned_system) :: model_t
    !> The definition, the evaluations' work, and the effects the scene turned on.
    type(model_data) :: d
    type(model_work) :: wk
    type(effect_slot), allocatable :: effects(:)
    !> Some effect acts after the composite terms (set with the list, by set_effects).
    logical :: carried_loads = .false.
    !> Single-rate evaluations solve by the articulated-body algorithm (else through M).
    logical :: articulated = .false.
    !> Multirate work: Cholesky factors of M_ff and M_e, M_fs, M_ff^-1 M_fs, M_ff^-1 Q_f and
    !> M_ff^-1 (held when M_ff is constant; the 'response' coupling's g uses it).
    real(dp), allocatable :: lff(:, :), le(:, :), mfs(:, :), xfs(:, :), yf(:), mffinv(:, :)
    !> Full coordinates and rates assembled from the slow and fast states.
    real(dp), allocatable :: qw(:), qdw(:)
    !> Once partitioned (multirate), eval solves through the Schur complement too.
    logical :: partitioned = .false.
    !> M_ff is constant (no flexible body carries children): factored once, at the first
    !> synchronised evaluation, and not again in 'full' fast steps.
    logical :: mff_fixed = .false., mff_factored = .false.
    real(dp), allocatable :: xsw(:), xfw(:), fsw(:), ffw(:)
  contains
    procedure :: eval => model_eval
    procedure :: component_name => model_component_name
    procedure :: terms => model_terms
    procedure :: accelerations => model_accelerations
    procedure :: forces => model_forces
    procedure :: energy => model_energy
    procedure :: project => model_project
    procedure :: energy_parts => model_energy_parts
    procedure :: n_slow => model_n_slow
    procedure :: n_fast => model_n_fast
    procedure :: sync_rhs => model_sync_rhs
    procedure :: fast_rhs => model_fast_rhs
    procedure :: force_response => model_force_response
    procedure :: fast_forces => model_fast_forces
    procedure :: init_partition => model_init_partition
    procedure :: end_partition => model_end_partition
    procedure :: save_run => model_save_run
    procedure :: load_run => model_load_run
    procedure :: use_articulated => model_use_articulated
    procedure :: impose => model_impose
    procedure :: set_effects => model_set_effects
    procedure :: counters => model_get_counters
    procedure :: set_counters => model_set_counters
  end type model_t

contains

  !> Mass matrix and right-hand side at (t, q, qd), left in self%wk%mm and self%wk%p.
  !> With fast_only, only the rows of the modal coordinates are assembled (the bodies
  !> on and below flexible bodies; effects on joint rows only are skipped).
  !> Prescribed coordinates (base_motion) take their functions' values before kinematics.
  subroutine model_terms(self, t, q, qd, fast_only)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in), optional :: fast_only
    logical :: fo
    fo = .false.
    if (present(fast_only)) fo = fast_only
    if (self%d%n_prescribed > 0) then
      call impose_effects(self%effects, self%wk, t, q, qd)
      call terms_at(self, t, self%wk%qx, self%wk%qdx, fo)
    else
      call terms_at(self, t, q, qd, fo)
    end if
  end subroutine model_terms

  !> model_terms at a state with the prescribed coordinates already imposed.
  subroutine terms_at(self, t, q, qd, fo)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: fo
    associate(d => self%d, wk => self%wk, fx => self%effects)
      if (fo) then
        call forward_kinematics(d, wk, q, qd)
        call deform_effects(fx, d, wk, q, d%in_fast)
        call body_terms(d, wk, q, qd, d%in_fast)
        call load_effects(fx, d, wk, t, q, qd, d%in_fast, .true.)
        call composite_terms(d, wk, d%in_fast)
        call carried_effects(fx, d, wk, q, d%in_fast)
        call assemble_mass(d, wk, d%in_fast)
        call assemble_rhs(d, wk, d%in_fast)
      else
        call composite_loads(self, t, q, qd)
        call assemble_mass(d, wk)
        call assemble_rhs(d, wk)
      end if
      call rows_effects(fx, wk, t)
      if (fo) then
        wk%count%evals_fast_rows = wk%count%evals_fast_rows + 1
      else
        wk%count%evals = wk%count%evals + 1
      end if
    end associate
  end subroutine terms_at

  !> A full evaluation's kinematics, body terms and applied loads (the bias wrenches and
  !> modal forces with the effects, and the joint loads tau).
  subroutine body_loads(self, t, q, qd)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t, q(:), qd(:)
    associate(d => self%d, wk => self%wk, fx => self%effects)
      call forward_kinematics(d, wk, q, qd)
      call deform_effects(fx, d, wk, q, d%every)
      call body_terms(d, wk, q, qd)
      wk%tau = 0.0_dp
      call load_effects(fx, d, wk, t, q, qd, d%every, .false.)
    end associate
  end subroutine body_loads

  !> body_loads and the subtrees' composite terms (with the loads that need them: the
  !> geometric stiffness of the loads beams carry), all that P needs before its assembly.
  subroutine composite_loads(self, t, q, qd)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t, q(:), qd(:)
    call body_loads(self, t, q, qd)
    call composite_terms(self%d, self%wk)
    call carried_effects(self%effects, self%d, self%wk, q, self%d%every)
  end subroutine composite_loads

  !> Accelerations by the articulated-body algorithm at a state with the prescribed
  !> coordinates imposed (loads carried by beams need the composite wrenches first).
  subroutine articulated_at(self, t, q, qd, qdd, error)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(out) :: qdd(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: k
    if (self%carried_loads) then
      call composite_loads(self, t, q, qd)
    else
      call body_loads(self, t, q, qd)
    end if
    qdd = 0.0_dp
    call accelerate_effects(self%effects, self%wk, t, qdd)
    call articulated_accelerations(self%d, self%wk, qdd, error)
    self%wk%count%evals = self%wk%count%evals + 1
    if (allocated(error)) return
    do k = 1, self%d%n
      if (.not. ieee_is_finite(qdd(k))) then
        call fatal_error(error, 'non-finite acceleration of coordinate ' // trim(self%d%qname(k)) // &
          & ' (the state or a load is out of range)', stat_solver); return
      end if
    end do
  end subroutine articulated_at

  !> Take the list of effects (moved in), and note whether one acts after the composite
  !> terms (the articulated path then assembles them).
  subroutine model_set_effects(self, list)
    class(model_t), intent(inout) :: self
    type(effect_slot), allocatable, intent(inout) :: list(:)
    integer :: i
    call move_alloc(list, self%effects)
    self%carried_loads = .false.
    do i = 1, size(self%effects)
      self%carried_loads = self%carried_loads .or. self%effects(i)%e%acts(stage_carried)
    end do
  end subroutine model_set_effects

  !> The generalised forces P at (t, q, qd) without assembling M (O(n); the pre-flight
  !> linearisation's differences), the same P as terms gives (with the rows effects replace);
  !> through terms when coordinates are prescribed (their effect on P needs M).
  subroutine model_forces(self, t, q, qd, p)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(out) :: p(:)
    if (self%d%n_prescribed > 0) then
      call self%terms(t, q, qd)
    else
      call composite_loads(self, t, q, qd)
      call assemble_rhs(self%d, self%wk)
      ! rows that other equations replace (a controller's state: no M needed)
      call rows_effects(self%effects, self%wk, t)
      self%wk%count%evals = self%wk%count%evals + 1
    end if
    p = self%wk%p
  end subroutine model_forces

  !> Copies of (q, qd) in self%wk%qx, self%wk%qdx with the prescribed coordinates on their
  !> functions of time t.
  subroutine model_impose(self, t, q, qd)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t, q(:), qd(:)
    call impose_effects(self%effects, self%wk, t, q, qd)
  end subroutine model_impose

  !> Solve single-rate evaluations by the articulated-body algorithm (on) or through M (off).
  subroutine model_use_articulated(self, on)
    class(model_t), intent(inout) :: self
    logical, intent(in) :: on
    integer :: nb, mx
    self%articulated = on
    if (.not. on .or. allocated(self%wk%ab%ia)) return
    nb = self%d%nb; mx = max(self%d%mmax, 1)
    allocate(self%wk%ab%ia(6, 6, nb), self%wk%ab%pa(6, nb), self%wk%ab%u(6, 6, nb), self%wk%ab%r(6, nb), &
      & self%wk%ab%lin(6, nb), self%wk%ab%kaa(mx, mx, nb), self%wk%ab%kam(6, mx, nb), self%wk%ab%ba(mx, nb))
  end subroutine model_use_articulated

  !> Accelerations qdd from M qdd = P (LAPACK Cholesky).
  subroutine model_accelerations(self, t, q, qd, qdd, error)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(out), contiguous :: qdd(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: minor
    if (self%articulated) then
      if (self%d%n_prescribed > 0) then
        call impose_effects(self%effects, self%wk, t, q, qd)
        call articulated_at(self, t, self%wk%qx, self%wk%qdx, qdd, error)
      else
        call articulated_at(self, t, q, qd, qdd, error)
      end if
      call add_time(error, t)
      return
    end if
    call self%terms(t, q, qd)
    associate(d => self%d, wk => self%wk)
      wk%lf = wk%mm
      call potrf(wk%lf, 'the mass matrix', error, minor)
      if (allocated(error)) then
        if (minor > 0) error%message = error%message // ' (coordinate ' // trim(d%qname(minor)) // ')'
        call prefix_error(error, 'at t = ' // time_text(t))
        return
      end if
      qdd = wk%p
      call potrs(wk%lf, qdd, 'the mass matrix', error)
      if (d%cuts%n_rows > 0 .and. .not. allocated(error)) call constrained_accelerations(d, wk, qdd, error)
      call add_time(error, t)
    end associate
  end subroutine model_accelerations

  !> Close the loops of state x = [q; qd] at time t (model/loops.f90): the prescribed
  !> coordinates put on their functions, then positions and rates projected.
  subroutine model_project(self, t, x, error)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: x(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: n
    real(dp) :: residual
    if (self%d%cuts%n_rows == 0 .or. .not. self%wk%loops%rows_chosen) return
    n = self%d%n
    if (self%d%n_prescribed > 0) then
      call impose_effects(self%effects, self%wk, t, x(1:n), x(n+1:))
      x(1:n) = self%wk%qx; x(n+1:) = self%wk%qdx
    end if
    call project_positions(self%d, self%wk, x(1:n), self%wk%loops%size, error, residual); if (allocated(error)) return
    self%wk%loops%closure_drift = max(self%wk%loops%closure_drift, residual)
    call project_velocities(self%d, self%wk, x(1:n), x(n+1:), error)
  end subroutine model_project

  !> f(t, x) for x = [q; qd].
  subroutine model_eval(self, t, x, f, error)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: x(:)
    real(dp), intent(out), contiguous :: f(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: n, ns, nf
    n = self%d%n
    if (self%partitioned) then
      ns = self%d%nj; nf = n - ns
      self%xsw = [x(1:ns), x(n+1:n+ns)]
      self%xfw = [x(ns+1:n), x(n+ns+1:)]
      call self%sync_rhs(t, self%xsw, self%xfw, self%fsw, self%ffw, error)
      f(1:ns) = self%fsw(1:ns); f(n+1:n+ns) = self%fsw(ns+1:)
      f(ns+1:n) = self%ffw(1:nf); f(n+ns+1:) = self%ffw(nf+1:)
      return
    end if
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

  !> Kinetic and potential (elastic, and gravity and springs when on) energy (J) at (q, qd).
  subroutine model_energy(self, q, qd, kinetic, potential)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: q(:), qd(:)
    real(dp), intent(out) :: kinetic, potential
    real(dp) :: e(4)
    call self%energy_parts(q, qd, e, 0.0_dp)
    kinetic = e(1)
    potential = sum(e(2:4))
  end subroutine model_energy

  !> Energies (J) at (q, qd): kinetic, gravity (0 when off), strain of the flexible bodies
  !> and the joint springs' (0 when off); with the time t, the effects' energies that
  !> depend on it and on the rates too (a moving mass's).
  subroutine model_energy_parts(self, q, qd, e, t)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: q(:), qd(:)
    real(dp), intent(out) :: e(4)
    real(dp), intent(in), optional :: t
    call forward_kinematics(self%d, self%wk, q, qd)
    call deform_effects(self%effects, self%d, self%wk, q, self%d%every)
    call body_terms(self%d, self%wk, q, qd)
    e = 0.0_dp
    e(1) = kinetic_energy(self%d, self%wk, qd)
    e(3) = elastic_potential(self%d, q)
    call effect_energies(self%effects, self%d, self%wk, q, e)
    if (present(t)) call effect_motion_energies(self%effects, self%d, self%wk, t, q, qd, e)
  end subroutine model_energy_parts

  !> Elastic energy 1/2 sum omega^2 a^2 of the flexible bodies (J).
  pure function elastic_potential(d, q) result(v)
    type(model_data), intent(in) :: d
    real(dp), intent(in) :: q(:)
    real(dp) :: v
    integer :: b, m
    v = 0.0_dp
    do b = 2, d%nb
      m = d%nm(b)
      if (m == 0) cycle
      v = v + 0.5_dp*sum(d%flex(b)%omega2*q(d%a0(b):d%a0(b) + m - 1)**2)
    end do
  end function elastic_potential

  pure integer function model_n_slow(self)
    class(model_t), intent(in) :: self
    model_n_slow = self%d%nj
  end function model_n_slow

  pure integer function model_n_fast(self)
    class(model_t), intent(in) :: self
    model_n_fast = self%d%n - self%d%nj
  end function model_n_fast

  !> Allocate the multirate work arrays.
  subroutine model_init_partition(self)
    class(model_t), intent(inout) :: self
    integer :: ns, nf, b
    ns = self%d%nj; nf = self%d%n - ns
    call self%end_partition()
    allocate(self%lff(nf, nf), self%le(ns, ns), self%mfs(nf, ns), self%xfs(nf, ns), self%yf(nf), &
      & self%qw(ns + nf), self%qdw(ns + nf), self%mffinv(nf, nf), &
      & self%xsw(2*ns), self%xfw(2*nf), self%fsw(2*ns), self%ffw(2*nf))
    self%partitioned = .true.
    ! a moving mass changes the modal block as it travels
    self%mff_fixed = .not. effects_vary_modal_mass(self%effects)
    self%mff_factored = .false.
    do b = 2, self%d%nb
      if (self%d%flexible(b) .and. self%d%child_ptr(b + 1) > self%d%child_ptr(b)) self%mff_fixed = .false.
    end do
  end subroutine model_init_partition

  !> The model whole again (a single-rate stepper taking over from a multirate one): eval
  !> solves M qdd = P at once, and the multirate terms go.
  subroutine model_end_partition(self)
    class(model_t), intent(inout) :: self
    if (allocated(self%lff)) deallocate(self%lff, self%le, self%mfs, self%xfs, self%yf, &
      & self%qw, self%qdw, self%mffinv, self%xsw, self%xfw, self%fsw, self%ffw)
    self%partitioned = .false.
    self%mff_factored = .false.
  end subroutine model_end_partition

  !> Per fast (modal) coordinate: modal stiffness omega^2 and damping (2 zeta omega + ...;
  !> 0 when modal_damping is off): the fast forces kf a + df ad linear in the fast state.
  !> With kam (model_work's, mmax x nb), kf adds the stiffness a state's tension adds on the
  !> diagonal; a compression's softening is left out (it stays with the rest of the forces:
  !> a beam loaded past buckling has modes with no stiffness to vibrate with).
  subroutine modal_stiffness_damping(d, effects, kf, df, kam)
    type(model_data), intent(in) :: d
    type(effect_slot), intent(in) :: effects(:)
    real(dp), intent(out) :: kf(:), df(:)
    real(dp), intent(in), optional :: kam(:, :)
    integer :: b, m, f0
    kf = 0.0_dp; df = 0.0_dp
    do b = 2, d%nb
      m = d%nm(b)
      if (m == 0) cycle
      f0 = d%a0(b) - d%nj
      kf(f0:f0 + m - 1) = d%flex(b)%omega2
      if (present(kam)) kf(f0:f0 + m - 1) = kf(f0:f0 + m - 1) + max(kam(1:m, b), 0.0_dp)
    end do
    call effect_fast_damping(effects, d, df)
  end subroutine modal_stiffness_damping

  !> Factor M_ff of the last assembly (Cholesky), naming time and minor on failure; once
  !> only when M_ff is constant.
  subroutine factor_ff(self, t, error)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t
    type(error_type), allocatable, intent(out) :: error
    integer :: ns, minor
    if (self%mff_fixed .and. self%mff_factored) return
    ns = self%d%nj
    self%lff = self%wk%mm(ns+1:, ns+1:)
    call potrf(self%lff, 'the fast (modal) mass matrix M_ff', error, minor)
    self%mff_factored = .not. allocated(error)
    if (allocated(error)) then
      if (minor > 0) error%message = error%message // ' (coordinate ' // trim(self%d%qname(ns + minor)) // ')'
      call prefix_error(error, 'at t = ' // time_text(t))
    end if
  end subroutine factor_ff

  !> Derivatives from one full evaluation: fs = [qd_s; qdd_s] with M_e qdd_s = Q_e,
  !> M_e = M_ss - M_sf M_ff^-1 M_fs, Q_e = Q_s - M_sf M_ff^-1 Q_f (LAPACK Cholesky of M_ff
  !> and M_e), and ff = [qd_f; qdd_f] with qdd_f = M_ff^-1 (Q_f - M_fs qdd_s). Holds the
  !> factors for force_response.
  subroutine model_sync_rhs(self, t, xs, xf, fs, ff, error)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t, xs(:), xf(:)
    real(dp), intent(out) :: fs(:), ff(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: ns, nf, minor
    ns = self%d%nj; nf = self%d%n - ns
    call gather(self, xs, xf)
    call self%terms(t, self%qw, self%qdw)
    associate(mm => self%wk%mm, p => self%wk%p)
      self%mfs = mm(ns+1:, 1:ns)
      if (self%mff_fixed .and. self%mff_factored) then
        ! constant M_ff: its inverse is held from the first synchronised evaluation
        self%xfs = matmul(self%mffinv, self%mfs)
        self%yf = matmul(self%mffinv, p(ns+1:))
      else
        call factor_ff(self, t, error); if (allocated(error)) return
        call hold_inverse(self, error); if (allocated(error)) return
        self%xfs = self%mfs
        call potrs(self%lff, self%xfs, 'M_ff', error); call add_time(error, t); if (allocated(error)) return
        self%yf = p(ns+1:)
        call potrs(self%lff, self%yf, 'M_ff', error); call add_time(error, t); if (allocated(error)) return
      end if
      self%le = mm(1:ns, 1:ns) - matmul(mm(1:ns, ns+1:), self%xfs)
      fs(ns+1:) = p(1:ns) - matmul(mm(1:ns, ns+1:), self%yf)
      call potrf(self%le, 'the effective mass matrix M_e (Schur complement of M_ff)', error, minor)
      if (allocated(error)) then
        if (minor > 0) error%message = error%message // ' (coordinate ' // trim(self%d%qname(minor)) // ')'
        call prefix_error(error, 'at t = ' // time_text(t)); return
      end if
      call potrs(self%le, fs(ns+1:), 'M_e', error); call add_time(error, t); if (allocated(error)) return
      ff(nf+1:) = self%yf - matmul(self%xfs, fs(ns+1:))
    end associate
    if (self%d%cuts%n_rows > 0) then
      call constrain_sync(self, t, fs(ns+1:), ff(nf+1:), error); if (allocated(error)) return
    end if
    fs(1:ns) = xs(ns+1:)
    ff(1:nf) = xf(nf+1:)
  end subroutine model_sync_rhs

  !> A synchronised evaluation with closed loops: the tree's accelerations (slow acc_s, fast
  !> acc_f) get the constraint forces, through the Cholesky factor of the whole M (one per
  !> macro step; the Schur factors stay the tree's, for the fast steps and the response).
  subroutine constrain_sync(self, t, acc_s, acc_f, error)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: acc_s(:), acc_f(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: qdd(self%d%n)
    integer :: ns
    ns = self%d%nj
    self%wk%lf = self%wk%mm
    call potrf(self%wk%lf, 'the mass matrix', error); call add_time(error, t); if (allocated(error)) return
    qdd(1:ns) = acc_s; qdd(ns+1:) = acc_f
    call constrained_accelerations(self%d, self%wk, qdd, error); call add_time(error, t); if (allocated(error)) return
    acc_s = qdd(1:ns); acc_f = qdd(ns+1:)
  end subroutine constrain_sync

  !> Fast derivative ff = [qd_f; qdd_f] with M_ff qdd_f = Q_f - M_fs acc_s: the modal
  !> rows assembled at (t, xs, xf) (the 'full' coupling's fast steps); with closed loops,
  !> plus the constraint forces on the modal coordinates (constrain_fast_accelerations).
  subroutine model_fast_rhs(self, t, xs, xf, acc_s, ff, error)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: t, xs(:), xf(:), acc_s(:)
    real(dp), intent(out) :: ff(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: ns, nf
    ns = self%d%nj; nf = self%d%n - ns
    call gather(self, xs, xf)
    call self%terms(t, self%qw, self%qdw, fast_only=.true.)
    call factor_ff(self, t, error); if (allocated(error)) return
    ff(nf+1:) = self%wk%p(ns+1:) - matmul(self%wk%mm(ns+1:, 1:ns), acc_s)
    call potrs(self%lff, ff(nf+1:), 'M_ff', error)
    if (self%d%cuts%n_rows > 0 .and. .not. allocated(error)) &
      & call constrain_fast_accelerations(self%d, self%wk, self%lff, acc_s, ff(nf+1:), error)
    call add_time(error, t)
    ff(1:nf) = xf(nf+1:)
  end subroutine model_fast_rhs

  !> The fast-force response g = M^-1 E of the last synchronised evaluation, from its
  !> Schur complement factors: with X = M_ff^-1 M_fs, the joint rows are
  !> g_s = -M_e^-1 X^T and the modal rows g_f = M_ff^-1 - X g_s (block inverse of M);
  !> kf, df: modal stiffness omega^2 and damping per fast coordinate.
  subroutine model_force_response(self, g, kf, df, error)
    class(model_t), intent(inout) :: self
    real(dp), intent(out) :: g(:, :), kf(:), df(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: ns
    real(dp) :: gs(self%d%nj, self%d%n - self%d%nj)
    ns = self%d%nj
    gs = transpose(self%xfs)
    call potrs(self%le, gs, 'M_e', error); if (allocated(error)) return
    g(1:ns, :) = -gs
    g(ns+1:, :) = self%mffinv + matmul(self%xfs, gs)
    if (self%d%cuts%n_rows > 0) then
      call constrain_response(self%d, self%wk, g, error); if (allocated(error)) return
    end if
    call self%fast_forces(kf, df)
  end subroutine model_force_response

  !> The stiffness kf and damping df per fast coordinate of the fast forces kf a + df ad
  !> that the fast response freezes, at the last evaluated state: omega^2 plus the diagonal
  !> of the geometric stiffness the state's tension adds (wk%kam), and the modal damping.
  subroutine model_fast_forces(self, kf, df)
    class(model_t), intent(in) :: self
    real(dp), intent(out) :: kf(:), df(:)
    call modal_stiffness_damping(self%d, self%effects, kf, df, self%wk%kam)
  end subroutine model_fast_forces

  !> After a failed call: the error names the time (for the run's message).
  subroutine add_time(error, t)
    type(error_type), allocatable, intent(inout) :: error
    real(dp), intent(in) :: t
    if (allocated(error)) call prefix_error(error, 'at t = ' // time_text(t))
  end subroutine add_time

  !> M_ff^-1 from its Cholesky factor (held when M_ff is constant, for every synchronised
  !> evaluation; force_response uses it).
  subroutine hold_inverse(self, error)
    class(model_t), intent(inout) :: self
    type(error_type), allocatable, intent(out) :: error
    call factor_inverse(self%lff, self%mffinv, 'M_ff', error)
  end subroutine hold_inverse

  !> Full coordinates and rates from the slow state [q_s; qd_s] and fast state [q_f; qd_f].
  pure subroutine gather(self, xs, xf)
    class(model_t), intent(inout) :: self
    real(dp), intent(in) :: xs(:), xf(:)
    integer :: ns, nf
    ns = self%d%nj; nf = self%d%n - ns
    self%qw(1:ns) = xs(1:ns); self%qw(ns+1:) = xf(1:nf)
    self%qdw(1:ns) = xs(ns+1:); self%qdw(ns+1:) = xf(nf+1:)
  end subroutine gather

  !> M and P as the last terms left them hold finite numbers only (a state out of range, such
  !> as velocities of 1e300, overflows them); else a solver error naming the coordinate.
  subroutine check_terms_finite(self, t, error)
    class(model_t), intent(in) :: self
    real(dp), intent(in) :: t
    type(error_type), allocatable, intent(out) :: error
    integer :: k
    do k = 1, self%d%n
      if (ieee_is_finite(self%wk%p(k)) .and. all(ieee_is_finite(self%wk%mm(:, k)))) cycle
      call fatal_error(error, 'at t = ' // time_text(t) // ': non-finite mass matrix or force term of coordinate ' &
        & // trim(self%d%qname(k)) // ' (the state or a load is out of range)', stat_solver); return
    end do
  end subroutine check_terms_finite

  !> Time as text for messages.
  function time_text(t) result(s)
    real(dp), intent(in) :: t
    character(len=:), allocatable :: s
    character(len=32) :: buf
    write(buf, '(es12.5)') t
    s = trim(adjustl(buf)) // ' s'
  end function time_text
  !> The evaluation counters.
  pure function model_get_counters(self) result(c)
    class(model_t), intent(in) :: self
    type(model_counters) :: c
    c = self%wk%count
  end function model_get_counters

  !> Put back counters saved by `counters`.
  pure subroutine model_set_counters(self, c)
    class(model_t), intent(inout) :: self
    type(model_counters), intent(in) :: c
    self%wk%count = c
  end subroutine model_set_counters

  !> Write the model's per-run state to an open unformatted stream unit: its evaluation
  !> counters and effect timings, and the held multirate terms when the run partitioned it.
  subroutine model_save_run(self, unit, ios)
    class(model_t), intent(in) :: self
    integer, intent(in) :: unit
    integer, intent(out) :: ios
    write(unit, iostat=ios) allocated(self%lff)
    if (ios == 0 .and. allocated(self%lff)) write(unit, iostat=ios) self%lff, self%le, self%mfs, self%xfs, &
      & self%yf, self%mffinv, self%mff_factored
    if (ios == 0) write(unit, iostat=ios) self%wk%count%evals, self%wk%count%evals_fast_rows, self%wk%count%effect_evals, &
      & self%wk%count%effect_timed, self%wk%count%effect_cpu, self%wk%loops%closure_drift
    if (ios == 0) call save_effect_states(self%effects, unit, ios)
  end subroutine model_save_run

  !> Read what model_save_run wrote into a model built from the same scene (partitioned
  !> the same way); ios /= 0 when it is not.
  subroutine model_load_run(self, unit, ios)
    class(model_t), intent(inout) :: self
    integer, intent(in) :: unit
    integer, intent(out) :: ios
    logical :: partitioned
    read(unit, iostat=ios) partitioned
    if (ios /= 0) return
    if (partitioned .neqv. allocated(self%lff)) then
      ios = 1; return
    end if
    if (partitioned) read(unit, iostat=ios) self%lff, self%le, self%mfs, self%xfs, self%yf, &
      & self%mffinv, self%mff_factored
    if (ios == 0) read(unit, iostat=ios) self%wk%count%evals, self%wk%count%evals_fast_rows, self%wk%count%effect_evals, &
      & self%wk%count%effect_timed, self%wk%count%effect_cpu, self%wk%loops%closure_drift
    if (ios == 0) call load_effect_states(self%effects, unit, ios)
  end subroutine model_load_run
end module pymr_model
