!> Pre-flight stability check of fixed-step runs (issue 6, hard case 1), for any stepper.
!>
!> The model is linearised at its initial state: M, and K = -dP/dq, D = -dP/dqd by central
!> differences. Each eigenvalue lambda of [0 I; -M^-1 K  -M^-1 D] with Re lambda <= 0 is a
!> vibration the step must resolve stably: the PECE growth factor at lambda h (see
!> pymr_integrator_stability) must not exceed 1. A mode is charged to the coordinate that
!> carries most of its kinetic energy, and so to the step the stepper takes on that kind of
!> coordinate (its `pece` steps). A multirate stepper is then applied to the linearised model
!> itself: the growth of its macro step, by power iteration on its whole state, must stay
!> below `run_growth` over the run.
module pymr_driver_preflight
  use pymr_env_kinds, only : dp, pi
  use pymr_env_error, only : error_type, fatal_error, stat_input, set_fault
  use pymr_env_lapack, only : potrf, potrs, geev_real, factor_inverse
  use pymr_env_graph, only : connected_parts
  use pymr_model, only : model_t, model_counters
  use pymr_model_loops, only : independent_rows, loop_jacobian, constrain_inverse
  use pymr_integrator_stability, only : pece_growth, pece_limit, imaginary_axis_limit
  use pymr_integrator_ode, only : partitioned_system
  use pymr_integrator_stepper, only : stepper_t, pece_steps, step_counts
  use pymr_integrator_response, only : response_integrator
  use pymr_env_text, only : itoa, fmt
  use pymr_env_item_table, only : origin_t
  use pymr_model_scene, only : scene_t
  use pymr_model_types, only : model_data
  use pymr_driver_linearise, only : linear_state
  use pymr_driver_normal_modes, only : normal_modes, top_frequency, modes_bytes
  use pymr_driver_distance_watch, only : resolved, subtree_roundoff
  implicit none
  private
  public :: check_step_stability, check_mass_matrix
  !> Used from here by the binding and the stepper setup.
  public :: normal_modes, top_frequency, modes_bytes

  !> Largest growth of a linearised perturbation over a whole run that is accepted: a
  !> step whose growth factor per step is above 1 only by roundoff-sized amounts (an
  !> undamped mode on the edge) passes; a real instability multiplies it by far more.
  real(dp), parameter :: run_growth = 10.0_dp

  !> Steppers whose whole state has at most this many components get the spectral radius
  !> of their macro-step map from its matrix (LAPACK dgeev); larger ones by power iteration
  !> (at most max_iterations macro steps). A Krylov (Arnoldi) estimate was tried and
  !> dropped: on the stiff barrel its Ritz values lay outside the spectrum (non-normal map).
  !> Power iteration from 257 components was tried too, for dgeev's cost (0.11-0.15 s on
  !> the spacecraft's 'full' map of 400 components, 10-14 % of the run, against 0.08 s for
  !> 3000 macro steps), and dropped: it underestimated the growth. On that map at
  !> k = 11-24 dgeev gives growths over the run of e^0.8 to e^5.1, power iteration e^-1.9 to
  !> e^1.9, and the largest stable ratio was 24 instead of 13.
  integer, parameter :: max_exact_state = 400, max_iterations = 3000

  !> Relative resolution of the linearisation's central differences (increments 1e-6 of
  !> each coordinate: rounding of about 2e-16/1e-6 of the forces): a residual stiffness or
  !> damping below it is zero to the check.
  real(dp), parameter :: fd_resolution = 1.0e-10_dp

  !> The model linearised at a state, M qdd = -(K q + C qd), as a partitioned system: a
  !> stepper applied to it gives its linearised step map. Its accelerations are kept as
  !> products with the state: ax (n x 2n) of the whole state [q; qd], as and af (n x 2ns,
  !> n x 2nf) of the slow and fast states; the fast equation's fast accelerations fxs and fxf
  !> of the slow and fast states and fa of the slow accelerations; g = M^-1 E (the response
  !> to modal forces), the modal stiffness kf and damping df.
  type, extends(partitioned_system) :: linear_system
    integer :: ns = 0, nf = 0
    real(dp), allocatable :: ax(:, :), as(:, :), af(:, :), fxs(:, :), fxf(:, :), fa(:, :), g(:, :), kf(:), df(:)
  contains
    procedure :: eval => lin_eval
    procedure :: component_name => lin_name
    procedure :: n_slow => lin_n_slow
    procedure :: n_fast => lin_n_fast
    procedure :: sync_rhs => lin_sync
    procedure :: fast_rhs => lin_fast
    procedure :: force_response => lin_response
  end type linear_system

contains

  !> Refuse (error naming the body and mode, its frequency and the largest stable step)
  !> fixed steps of the stepper `st` (made, not started) that cannot be stable at the
  !> initial state x = [q; qd]; label: what the stepper is, for messages ("coupling
  !> 'response'"); t_end: the run's length (a step is refused when the linearised growth
  !> over the whole run would exceed `run_growth`). A 'response' stepper whose macro step is
  !> stable only without its surrogate correction has it turned off, and `note` says so.
  subroutine check_step_stability(model, x, st, label, t_end, o, error, note)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:)
    class(stepper_t), intent(inout) :: st
    character(len=*), intent(in) :: label
    real(dp), intent(in) :: t_end
    type(origin_t), intent(in) :: o       ! &integrator's: messages name its item and line
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable, intent(out) :: note
    integer :: n, i, dom, worst
    real(dp), allocatable :: m(:, :), minv(:, :), k(:, :), c(:, :), a(:, :), ev(:, :), wr(:), wi(:), vr(:, :), wgt(:)
    real(dp) :: h, ratio, worst_ratio, stable
    complex(dp) :: lam, worst_lam
    character(len=32) :: b1, b2, b3, b4, b5
    type(pece_steps) :: steps
    n = model%d%n
    if (n == 0) return
    steps = st%pece()
    allocate(wgt(n))
    call linearised_for(model, x, steps, m, minv, k, c, a, error); if (allocated(error)) return
    if (steps%exact_modal) then
      if (joints_stable(a, model%d%nj, steps%h_joint, t_end, error)) return
      if (allocated(error)) return
    end if
    allocate(wr(2*n), wi(2*n), vr(2*n, 2*n))
    if (steps%h_modal == steps%h_joint) then
      ! one step for every coordinate: the eigenvalues alone decide; the vectors are needed
      ! only to name the coordinate of a mode that fails
      ev = a
      call geev_real(ev, wr, wi, 'the linearised model', error); if (allocated(error)) return
      if (all_stable(wr, wi, steps%h_joint, t_end)) then
        call check_coupling(model, x, m, minv, k, c, max(maxval(wr), 0.0_dp), st, label, t_end, o, error, note)
        return
      end if
    end if
    call geev_real(a, wr, wi, 'the linearised model', error, vr); if (allocated(error)) return
    worst = 0; worst_ratio = 1.0_dp; worst_lam = (0.0_dp, 0.0_dp)
    i = 1
    do while (i <= 2*n)
      lam = cmplx(wr(i), wi(i), dp)
      ! each coordinate's share of the mode's kinetic energy, |v_j (M v)_j| (complex pairs
      ! packed): with the coupling terms of M, a joint that a fast modal vibration barely
      ! moves takes no share for its large inertia M_jj alone
      wgt = abs(vr(1:n, i)*matmul(m, vr(1:n, i)))
      if (wi(i) /= 0.0_dp .and. i < 2*n) wgt = wgt + abs(vr(1:n, i + 1)*matmul(m, vr(1:n, i + 1)))
      dom = maxloc(wgt, 1)
      h = merge(steps%h_modal, steps%h_joint, dom > model%d%nj)
      if (grows(lam, h, t_end)) then
        ratio = h/pece_limit(lam)
        if (ratio > worst_ratio) then
          worst_ratio = ratio; worst = dom; worst_lam = lam
        end if
      end if
      if (wi(i) /= 0.0_dp) i = i + 1
      i = i + 1
    end do
    if (worst == 0) then
      call check_coupling(model, x, m, minv, k, c, max(maxval(wr), 0.0_dp), st, label, t_end, o, error, note)
      return
    end if
    h = merge(steps%h_modal, steps%h_joint, worst > model%d%nj)
    write(b1, '(es9.2)') h
    write(b2, '(f0.1)') abs(worst_lam)/(2.0_dp*pi)
    if (abs(worst_lam)*h < 9.9995_dp) then         ! rounds to 10.000, six characters, at 9.9995
      write(b3, '(f5.3)') abs(worst_lam)*h
    else
      write(b3, '(es9.2)') abs(worst_lam)*h
    end if
    stable = pece_limit(worst_lam); write(b4, '(es9.2)') stable
    write(b5, '(f5.3)') imaginary_axis_limit
    call fatal_error(error, o%where(trim(merge(steps%item_modal, steps%item_joint, worst > model%d%nj))) // &
      & ': a fixed step of ' // trim(adjustl(b1)) // ' s is not stable for ' // coordinate_name(model, worst) // ' (' // &
      & trim(b2) // ' Hz, omega*h = ' // trim(adjustl(b3)) // '); the largest stable step is ' // trim(adjustl(b4)) // &
      & ' s (the ABM PECE method is stable up to omega*h = ' // trim(b5) // ' on an undamped mode): take a smaller step, ' // &
      & 'or adaptive = .true.')
    call set_fault(error, kind='unstable_step', group='integrator', stable_step=stable, &
      & item=trim(merge(steps%item_modal, steps%item_joint, worst > model%d%nj)))
  end subroutine check_step_stability

  !> Does the eigenvalue lam (a vibration or decay: growing modes are physical, not
  !> numerical) grow by more than run_growth over a run to t_end in fixed steps h? A step of 0
  !> leaves it to the macro-step map of multirate runs.
  logical function grows(lam, h, t_end)
    complex(dp), intent(in) :: lam
    real(dp), intent(in) :: h, t_end
    grows = .false.
    if (abs(lam) == 0.0_dp .or. real(lam) > 1.0e-9_dp*abs(lam) .or. h <= 0.0_dp) return
    grows = log(pece_growth(lam*h))*steps_in_run(t_end, h) > log(run_growth)
  end function grows

  !> Steps of length h a run to t_end takes: at least one, however short the run (a step
  !> past t_end is taken whole, and its rows are interpolated back).
  pure real(dp) function steps_in_run(t_end, h) result(n)
    real(dp), intent(in) :: t_end, h
    n = max(1.0_dp, t_end/h)
  end function steps_in_run

  !> The model linearised at x for a stepper's steps: with steps%exact_modal the modal
  !> columns hold the stiffness and damping the flow carries exactly, so the joint columns
  !> alone are linearised (the state matrix is then block triangular, its joints' block
  !> deciding).
  subroutine linearised_for(model, x, steps, m, minv, k, c, a, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:)
    type(pece_steps), intent(in) :: steps
    real(dp), allocatable, intent(out) :: m(:, :), minv(:, :), k(:, :), c(:, :), a(:, :)
    type(error_type), allocatable, intent(out) :: error
    if (steps%exact_modal) then
      call linear_state(model, 0.0_dp, x, m, minv, k, c, a, error, model%d%nj)
    else
      call linear_state(model, 0.0_dp, x, m, minv, k, c, a, error)
    end if
  end subroutine linearised_for

  !> Multirate runs whose fixed steps are stable mode by mode: the coupling's own stability
  !> (sigma: the linearised model's growth rate), unless its surrogate is exact on the
  !> linearised model.
  subroutine check_coupling(model, x, m, minv, k, c, sigma, st, label, t_end, o, error, note)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:), m(:, :), minv(:, :), k(:, :), c(:, :), sigma, t_end
    class(stepper_t), intent(inout) :: st
    character(len=*), intent(in) :: label
    type(origin_t), intent(in) :: o
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable, intent(out) :: note
    type(step_counts) :: counts
    type(pece_steps) :: steps
    counts = st%counts(); steps = st%pece()
    if (counts%ratio == 1) return
    if (steps%modal_surrogate) then
      if (modal_forces_only(model, m, k, c)) return
    end if
    call check_macro_step(model, x, m, minv, k, c, sigma, st, label, t_end, o, error, note)
  end subroutine check_coupling

  !> Are the linearised model's stiffness k and damping c the modal ones alone (the modal
  !> stiffness and damping on the modal diagonal, nothing else), within the resolution of
  !> the central differences? Then a surrogate built on them (steps%modal_surrogate) is
  !> exact on the linearised model. Entries are compared scaled by the mass matrix's
  !> diagonal, against the largest scaled stiffness (omega_max^2) and omega_max.
  logical function modal_forces_only(model, m, k, c)
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: m(:, :), k(:, :), c(:, :)
    real(dp), allocatable :: kf(:), df(:), rk(:, :), rc(:, :), s(:)
    real(dp) :: kmax
    integer :: n, ns, i
    n = size(m, 1); ns = model%d%nj
    allocate(kf(n - ns), df(n - ns))
    call model%fast_forces(kf, df)
    rk = k; rc = c
    do i = ns + 1, n
      rk(i, i) = rk(i, i) - kf(i - ns)
      rc(i, i) = rc(i, i) - df(i - ns)
    end do
    s = [(1.0_dp/sqrt(m(i, i)), i = 1, n)]
    do i = 1, n
      rk(:, i) = rk(:, i)*s*s(i)
      rc(:, i) = rc(:, i)*s*s(i)
    end do
    kmax = maxval([(k(i, i)*s(i)**2, i = 1, n)])
    modal_forces_only = kmax > 0.0_dp .and. maxval(abs(rk)) <= fd_resolution*kmax .and. &
      & maxval(abs(rc)) <= fd_resolution*sqrt(kmax)
  end function modal_forces_only

  !> No vibration of the joints' block of the state matrix a (its rows and columns of the
  !> nj joint coordinates and rates) grows in fixed steps h over the run.
  logical function joints_stable(a, nj, h, t_end, error)
    real(dp), intent(in) :: a(:, :), h, t_end
    integer, intent(in) :: nj
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: b(:, :), wr(:), wi(:)
    integer :: n, i
    integer, allocatable :: idx(:)
    n = size(a, 1)/2
    joints_stable = .true.
    if (nj == 0) return
    idx = [(i, i = 1, nj), (n + i, i = 1, nj)]
    b = a(idx, idx)
    allocate(wr(2*nj), wi(2*nj))
    call geev_real(b, wr, wi, "the joints' block of the linearised model", error); if (allocated(error)) return
    joints_stable = all_stable(wr, wi, h, t_end)
  end function joints_stable

  !> No eigenvalue wr + i wi grows in fixed steps h over the run.
  logical function all_stable(wr, wi, h, t_end)
    real(dp), intent(in) :: wr(:), wi(:), h, t_end
    integer :: i
    all_stable = .true.
    do i = 1, size(wr)
      if (grows(cmplx(wr(i), wi(i), dp), h, t_end)) then
        all_stable = .false.; return
      end if
    end do
  end function all_stable


  !> The mass matrix at the initial state must be positive definite: a body without mass
  !> or inertia at the end of a chain, or joint axes that leave a motion without inertia,
  !> make it singular. The error names the first such coordinate.
  subroutine check_mass_matrix(sc, model, x, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: n, minor
    real(dp), allocatable :: l(:, :)
    type(model_counters) :: counters
    n = model%d%n
    if (n == 0) return
    counters = model%counters()
    call model%terms(0.0_dp, x(1:n), x(n+1:2*n))
    call model%set_counters(counters)
    call check_resolved(sc, model, error); if (allocated(error)) return
    l = model%wk%mm
    call potrf(l, 'the mass matrix', error, minor)
    if (.not. allocated(error)) then
      ! nearly singular: a pivot that keeps less than 1e-10 of its diagonal entry
      do minor = 1, n
        if (l(minor, minor)**2 < 1.0e-10_dp*model%wk%mm(minor, minor)) exit
      end do
      if (minor > n) return
      call fatal_error(error, '')
    end if
    if (minor > 0) then
      error%message = coordinate_place(sc, model%d, minor) // 'the mass matrix is singular at the initial ' // &
        & 'state: coordinate ' // &
        & trim(model%d%qname(minor)) // ' (leading minor ' // itoa(minor) // ') moves no inertia that the ' // &
        & 'coordinates before it do not already move (or almost none): check the masses and inertias of the ' // &
        & 'bodies it moves, the axes of its joint, and the singular angles of spherical and free joints'
      error%stat = stat_input
    else
      error%message = sc%file // ': ' // error%message
    end if
  end subroutine check_mass_matrix

  !> Prefix of a message about coordinate i: the line and group of the &joint that gives it
  !> ("file:12: &joint 'elevation': "), of the flexible &body that gives a modal one, else the
  !> scene file's name (a controller's state).
  function coordinate_place(sc, d, i) result(s)
    type(scene_t), intent(in) :: sc
    type(model_data), intent(in) :: d
    integer, intent(in) :: i
    character(len=:), allocatable :: s
    integer :: b, k
    s = sc%file // ': '
    b = d%cbody(i)
    if (b == 0) return
    if (i > d%nj) then
      do k = 1, size(sc%bodies)
        if (sc%bodies(k)%name == d%body_name(b)) s = sc%bodies(k)%origin%where() // ': '
      end do
    else
      do k = 1, size(sc%joints)
        if (sc%joints(k)%name == d%joint_name(b)) s = sc%joints(k)%origin%where() // ': '
      end do
    end if
  end function coordinate_place

  !> Every coordinate moves an inertia that the assembly resolves: at least `resolved` times
  !> the roundoff that the inertia about the inertial origin of the bodies it moves leaves
  !> (subtree_roundoff; the rule of distance_watch.f90, which holds it during the run), so
  !> that its diagonal entry holds 4 leading digits. A scene far from
  !> the origin fails here, not as a singular mass matrix or with its inertias silently off.
  !> A sliding (prismatic) column moves no inertia about the origin (its entry is a mass) and
  !> is not checked; nor are the controllers' states, which belong to no body.
  subroutine check_resolved(sc, model, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: e(model%d%nb)
    integer :: b, i
    e = subtree_roundoff(model)
    do b = 2, model%d%nb
      if (e(b) == 0.0_dp) cycle         ! nothing away from the origin: the factorisation judges
      do i = model%d%c0(b), model%d%c0(b) + model%d%nc(b) - 1
        if (all(model%wk%s(4:6, i) == 0.0_dp)) cycle
        if (unresolved(model, i, e(b), coordinate_place(sc, model%d, i), error)) return
      end do
      do i = model%d%a0(b), model%d%a0(b) + model%d%nm(b) - 1
        if (unresolved(model, i, e(b), coordinate_place(sc, model%d, i), error)) return
      end do
    end do
  end subroutine check_resolved

  !> Whether coordinate i's diagonal entry is within `resolved` times the roundoff e of the
  !> bodies it moves (then the error says so, with both causes it can have).
  logical function unresolved(model, i, e, where, error)
    type(model_t), intent(in) :: model
    integer, intent(in) :: i
    real(dp), intent(in) :: e
    character(len=*), intent(in) :: where
    type(error_type), allocatable, intent(inout) :: error
    unresolved = abs(model%wk%mm(i, i)) <= resolved*e
    if (.not. unresolved) return
    call fatal_error(error, where // 'the mass matrix cannot be resolved at the initial state: coordinate ' // &
      & trim(model%d%qname(i)) // ' moves an inertia of ' // fmt(model%wk%mm(i, i)) // ', within ' // &
      & fmt(resolved) // ' times the roundoff (' // fmt(e) // ') of the inertia about the inertial origin of ' // &
      & 'the bodies it moves, which pymr assembles about (their m r^2 up to ' // fmt(e/epsilon(1.0_dp)) // &
      & ' kg m^2): either it moves (almost) no inertia (check the masses and inertias of the bodies it moves ' // &
      & 'and the axes of its joint), or the scene lies too far from the origin (place it nearer)')
  end function unresolved

  !> Multirate runs: the growth per macro step of the stepper itself applied to the model
  !> linearised at the initial state (power iteration on its whole state). When its growth
  !> beyond the linearised model's own (a motion that grows physically, or the drift of a
  !> closed loop's coordinates that the projection removes) would exceed run_growth over the
  !> run, a 'response' stepper is tried without its surrogate correction (which halves the
  !> stable range of forces outside its linear response: docs/integrators.md); if neither
  !> is stable the run is refused, naming the coordinate that carries the growing motion and
  !> the largest stable step ratio at this fast step.
  subroutine check_macro_step(model, x, m, minv, k, c, sigma, st, label, t_end, o, error, note)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:), m(:, :), minv(:, :), k(:, :), c(:, :), t_end
    !> The linearised model's own growth rate (1/s; its largest real eigenvalue part, or 0):
    !> only the growth beyond it is the stepper's.
    real(dp), intent(in) :: sigma
    class(stepper_t), intent(inout) :: st
    character(len=*), intent(in) :: label
    type(origin_t), intent(in) :: o
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable, intent(out) :: note
    type(linear_system) :: sys
    integer :: kr, ks, dom, k_run
    real(dp) :: rho, hf
    character(len=32) :: b1, b2, b3
    type(step_counts) :: counts
    type(pece_steps) :: steps
    logical :: ok, has
    call linear_model(model, x, m, minv, k, c, sys, error); if (allocated(error)) return
    counts = st%counts(); steps = st%pece()
    k_run = counts%ratio; kr = k_run
    hf = steps%h_modal
    call macro_stable(sys, m, st, kr, hf, t_end, sigma, ok, rho, error); if (allocated(error)) return
    if (ok) return
    if (set_correction(st, .false.)) then
      call macro_stable(sys, m, st, kr, hf, t_end, sigma, ok, rho, error); if (allocated(error)) return
      if (ok) then
        note = 'the macro step of k = ' // itoa(kr) // ' (' // label // ') is stable only without the ' // &
          & 'surrogate''s correction: the run goes without it (its error is larger; adaptive = .true. keeps it)'
        return
      end if
      has = set_correction(st, .true.)
    end if
    ! refused: the growing motion's coordinate, and the largest stable ratio below kr, with
    ! or without the correction (stability need not be monotone in k: scan all)
    call macro_growth(sys, m, st, kr, hf, t_end, rho, error, dom); if (allocated(error)) return
    ks = 0
    do kr = 1, k_run - 1
      call stable_either(sys, m, st, kr, hf, t_end, sigma, ok, error); if (allocated(error)) return
      if (ok) ks = kr
    end do
    kr = k_run
    write(b1, '(es9.2)') kr*hf
    write(b2, '(f0.4)') rho
    write(b3, '(es9.2)') hf
    call fatal_error(error, o%where('h_slow') // ': the multirate macro step of ' // trim(adjustl(b1)) // ' s (k = ' // &
      & itoa(kr) // ', ' // label // ') is not stable: linearised at the initial state, one macro step multiplies ' // &
      & 'the motion of ' // coordinate_name(model, dom) // ' by ' // trim(b2) // '; at h_fast = ' // &
      & trim(adjustl(b3)) // ' s the largest stable ratio is k = ' // itoa(ks) // ' (growth below 10 over the ' // &
      & 'run; or use adaptive = .true.)')
    call set_fault(error, kind='unstable_ratio', group='integrator', item='h_slow', stable_ratio=ks)
  end subroutine check_macro_step

  !> Is the macro step of ratio kr stable with the stepper's surrogate correction or without
  !> it (the stepper is left with it)?
  subroutine stable_either(sys, m, st, kr, hf, t_end, sigma, ok, error)
    type(linear_system), intent(inout) :: sys
    real(dp), intent(in) :: m(:, :), hf, t_end, sigma
    class(stepper_t), intent(inout) :: st
    integer, intent(in) :: kr
    logical, intent(out) :: ok
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: rho
    logical :: has
    call macro_stable(sys, m, st, kr, hf, t_end, sigma, ok, rho, error)
    if (ok .or. allocated(error)) return
    if (.not. set_correction(st, .false.)) return
    call macro_stable(sys, m, st, kr, hf, t_end, sigma, ok, rho, error)
    has = set_correction(st, .true.)
  end subroutine stable_either

  !> Is the macro step of ratio kr stable over the run (growth rho per macro step beyond the
  !> linearised model's own rate sigma within run_growth)?
  subroutine macro_stable(sys, m, st, kr, hf, t_end, sigma, ok, rho, error)
    type(linear_system), intent(inout) :: sys
    real(dp), intent(in) :: m(:, :), hf, t_end, sigma
    class(stepper_t), intent(in) :: st
    integer, intent(in) :: kr
    logical, intent(out) :: ok
    real(dp), intent(out) :: rho
    type(error_type), allocatable, intent(out) :: error
    ok = .false.
    call macro_growth(sys, m, st, kr, hf, t_end, rho, error); if (allocated(error)) return
    ok = (log(rho) - sigma*kr*hf)*steps_in_run(t_end, kr*hf) <= log(run_growth)
  end subroutine macro_stable

  !> Turn a 'response' stepper's surrogate correction on or off: whether it has one.
  logical function set_correction(st, on)
    class(stepper_t), intent(inout) :: st
    logical, intent(in) :: on
    set_correction = .false.
    select type (st)
    class is (response_integrator)
      st%correct = on; set_correction = .true.
    end select
  end function set_correction

  !> The linearised model as a partitioned system (slow = joint coordinates), with its
  !> (constrained) inverse mass matrix minv. With closed loops its fast steps keep the loops
  !> closed as the model's do (constrain_fast_accelerations): the constrained inverse of
  !> M_ff on the rows independent in G_f, and the fast accelerations tfs acc_s that the
  !> slow accelerations impose through them.
  subroutine linear_model(model, x, m, minv, k, c, sys, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:), m(:, :), minv(:, :), k(:, :), c(:, :)
    type(linear_system), intent(out) :: sys
    type(error_type), allocatable, intent(out) :: error
    integer :: n, ns, nf
    integer, allocatable :: used(:)
    integer :: n_fast
    real(dp), allocatable :: l(:, :), g(:, :), kg(:, :), mffinv(:, :), tfs(:, :), kc(:, :)
    n = size(m, 1); ns = model%d%nj; nf = n - ns
    sys%ns = ns; sys%nf = nf
    allocate(mffinv(nf, nf), tfs(nf, ns), sys%kf(nf), sys%df(nf))
    l = m(ns+1:, ns+1:)
    call potrf(l, 'M_ff at the initial state', error); if (allocated(error)) return
    call factor_inverse(l, mffinv, 'M_ff', error); if (allocated(error)) return
    call model%fast_forces(sys%kf, sys%df)
    tfs = 0.0_dp
    if (model%d%cuts%n_rows > 0) then
      call loop_jacobian(model%d, model%wk, x(1:n), g, error); if (allocated(error)) return
      allocate(used(size(g, 1)))
      call independent_rows(g(:, ns+1:), used, n_fast)
      if (n_fast > 0) then
        allocate(kg(nf, n_fast))
        call constrain_inverse(mffinv, g(used(1:n_fast), ns+1:), error, kg); if (allocated(error)) return
        tfs = matmul(kg, g(used(1:n_fast), 1:ns))
      end if
    end if
    ! the columns of [K C] in the order of the slow and the fast states
    kc = reshape([k(:, 1:ns), c(:, 1:ns), k(:, ns+1:), c(:, ns+1:)], [n, 2*n])
    sys%ax = -matmul(minv, reshape([k, c], [n, 2*n]))
    sys%as = -matmul(minv, kc(:, 1:2*ns))
    sys%af = -matmul(minv, kc(:, 2*ns+1:))
    sys%fxs = -matmul(mffinv, kc(ns+1:, 1:2*ns))
    sys%fxf = -matmul(mffinv, kc(ns+1:, 2*ns+1:))
    sys%fa = -matmul(mffinv, m(ns+1:, 1:ns)) - tfs
    sys%g = minv(:, ns+1:)
  end subroutine linear_model

  !> Growth rho per macro step (ratio kr, fast step hf) of the stepper `proto` applied to
  !> the linear system, and (if asked) the coordinate `dom` whose kinetic energy dominates
  !> the growing motion. The stepper is started at rest and taken past its start-up phase;
  !> then its macro step is a linear map of its whole state vector.
  subroutine macro_growth(sys, m, proto, kr, hf, t_end, rho, error, dom)
    type(linear_system), intent(inout) :: sys
    real(dp), intent(in) :: m(:, :)
    class(stepper_t), intent(in) :: proto
    integer, intent(in) :: kr
    real(dp), intent(in) :: hf, t_end
    real(dp), intent(out) :: rho
    type(error_type), allocatable, intent(out) :: error
    integer, intent(out), optional :: dom
    class(stepper_t), allocatable :: st
    real(dp), allocatable :: v(:), x0(:)
    integer :: n, i
    n = sys%ns + sys%nf
    allocate(st, source=proto)
    call st%set_ratio(kr)
    allocate(x0(2*n))
    x0 = 0.0_dp
    call st%start(sys, 0.0_dp, x0, hf, error); if (allocated(error)) return
    do i = 1, 4
      call st%advance(sys, error); if (allocated(error)) return
    end do
    allocate(v(st%state_size()))
    if (size(v) <= max_exact_state) then
      call map_radius(sys, st, v, rho, error, present(dom))
    else
      call power_radius(sys, st, v, min(max_iterations, max(300, 4*nint(t_end/(kr*hf)))), rho, error)
    end if
    if (allocated(error) .or. .not. present(dom)) return
    dom = maxloc([(m(i, i)*(v(i)**2 + v(n + i)**2), i = 1, n)], 1)
  end subroutine macro_growth

  !> Spectral radius of the macro-step map from its matrix (one macro step per column);
  !> with_vector: v, the dominant eigenvector (its real part; the eigenvalues alone cost a
  !> third of the work).
  subroutine map_radius(sys, st, v, rho, error, with_vector)
    type(linear_system), intent(inout) :: sys
    class(stepper_t), intent(inout) :: st
    real(dp), intent(out) :: v(:), rho
    type(error_type), allocatable, intent(out) :: error
    logical, intent(in) :: with_vector
    real(dp), allocatable :: g(:, :), wr(:), wi(:), vr(:, :)
    integer :: j, nz, top
    nz = size(v)
    allocate(g(nz, nz), wr(nz), wi(nz))
    do j = 1, nz
      v = 0.0_dp; v(j) = 1.0_dp
      call st%set_state(v)
      call st%advance(sys, error); if (allocated(error)) return
      call st%get_state(g(:, j))
    end do
    if (.not. with_vector) then
      rho = block_radius(g, error); return
    end if
    allocate(vr(nz, nz))
    call geev_real(g, wr, wi, 'the linearised macro step', error, vr); if (allocated(error)) return
    top = maxloc(hypot(wr, wi), 1)
    rho = hypot(wr(top), wi(top))
    if (wi(top) < 0.0_dp .and. top > 1) top = top - 1
    v = vr(:, top)
  end subroutine map_radius

  !> Spectral radius of g from the eigenvalues of its diagonal blocks: the state components
  !> that do not act on each other (connected_parts) are taken apart, so that each dgeev is
  !> of one block. The spacecraft's 'full' map of 400 components has blocks of 200, 96, 96
  !> and 8 (the booms' bending out of the slew's plane apart): a sixth of the work.
  function block_radius(g, error) result(rho)
    real(dp), intent(in) :: g(:, :)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: rho
    integer, allocatable :: part(:), idx(:)
    real(dp), allocatable :: b(:, :), wr(:), wi(:)
    integer :: c, i
    part = connected_parts(g)
    rho = 0.0_dp
    do c = 1, maxval(part)
      idx = pack([(i, i = 1, size(part))], part == c)
      b = g(idx, idx)
      allocate(wr(size(idx)), wi(size(idx)))
      call geev_real(b, wr, wi, 'the linearised macro step', error); if (allocated(error)) return
      rho = max(rho, maxval(hypot(wr, wi)))
      deallocate(wr, wi)
    end do
  end function block_radius

  !> Growth per macro step by power iteration from a fixed start with every component
  !> present (the geometric mean over the second half of `iters` steps). The norm leaves
  !> out the positions' values: a joint without stiffness drifts at constant rate, which is
  !> motion, not growth.
  subroutine power_radius(sys, st, v, iters, rho, error)
    type(linear_system), intent(inout) :: sys
    class(stepper_t), intent(inout) :: st
    real(dp), intent(out) :: v(:), rho
    integer, intent(in) :: iters
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: g, logsum
    integer :: n, i, it
    n = sys%ns + sys%nf
    do i = 1, size(v)
      v(i) = sin(12.9898_dp*i)
    end do
    logsum = 0.0_dp
    rho = huge(1.0_dp)
    do it = 1, iters
      v = v/norm2(v(n+1:))
      call st%set_state(v)
      call st%advance(sys, error); if (allocated(error)) return
      call st%get_state(v)
      g = norm2(v(n+1:))
      if (.not. (g > 0.0_dp .and. g <= huge(g))) return
      if (2*it > iters) logsum = logsum + log(g)
    end do
    rho = exp(logsum/(iters - iters/2))
  end subroutine power_radius

  !> "body 'gun', mode 8" for a modal coordinate, "joint coordinate 'elevation.q'" else.
  function coordinate_name(model, ic) result(s)
    type(model_t), intent(in) :: model
    integer, intent(in) :: ic
    character(len=:), allocatable :: s
    integer :: b
    b = model%d%cbody(ic)
    if (b == 0) then
      s = "controller state '" // trim(model%d%qdname(ic)) // "'"
    else if (ic > model%d%nj) then
      s = "body '" // trim(model%d%body_name(b)) // "', mode " // itoa(ic - model%d%a0(b) + 1)
    else
      s = "joint coordinate '" // trim(model%d%qname(ic)) // "'"
    end if
  end function coordinate_name

  subroutine lin_eval(self, t, x, f, error)
    class(linear_system), intent(inout) :: self
    real(dp), intent(in) :: t
    real(dp), intent(in), contiguous :: x(:)
    real(dp), intent(out), contiguous :: f(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: n
    n = self%ns + self%nf
    f(1:n) = x(n+1:)
    f(n+1:) = matmul(self%ax, x)
  end subroutine lin_eval

  function lin_name(self, i) result(name)
    class(linear_system), intent(in) :: self
    integer, intent(in) :: i
    character(len=:), allocatable :: name
    name = 'coordinate ' // itoa(i) // ' of ' // itoa(2*(self%ns + self%nf))
  end function lin_name

  pure integer function lin_n_slow(self)
    class(linear_system), intent(in) :: self
    lin_n_slow = self%ns
  end function lin_n_slow

  pure integer function lin_n_fast(self)
    class(linear_system), intent(in) :: self
    lin_n_fast = self%nf
  end function lin_n_fast

  subroutine lin_sync(self, t, xs, xf, fs, ff, error)
    class(linear_system), intent(inout) :: self
    real(dp), intent(in) :: t, xs(:), xf(:)
    real(dp), intent(out) :: fs(:), ff(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: a(self%ns + self%nf)
    integer :: ns, nf
    ns = self%ns; nf = self%nf
    a = matmul(self%as, xs) + matmul(self%af, xf)
    fs = [xs(ns+1:), a(1:ns)]
    ff = [xf(nf+1:), a(ns+1:)]
  end subroutine lin_sync

  subroutine lin_response(self, g, kf, df, error)
    class(linear_system), intent(inout) :: self
    real(dp), intent(out) :: g(:, :), kf(:), df(:)
    type(error_type), allocatable, intent(out) :: error
    g = self%g
    kf = self%kf; df = self%df
  end subroutine lin_response

  subroutine lin_fast(self, t, xs, xf, acc_s, ff, error)
    class(linear_system), intent(inout) :: self
    real(dp), intent(in) :: t, xs(:), xf(:), acc_s(:)
    real(dp), intent(out) :: ff(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: nf
    nf = self%nf
    ff(nf+1:) = matmul(self%fxs, xs) + matmul(self%fxf, xf) + matmul(self%fa, acc_s)
    ff(1:nf) = xf(nf+1:)
  end subroutine lin_fast
end module pymr_driver_preflight
