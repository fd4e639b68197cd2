!> Effects: the optional physics a scene turns on, each a record type extending effect_t
!> with its own named parameters, kept in the model's list (built once, in the order of
!> driver/build_effects.f90's registry). An evaluation runs the list stage by stage; an
!> effect implements the stages it acts in and says so in `acts`:
!> - impose: prescribed coordinates put on their functions (before kinematics);
!> - deform: flexible bodies' terms that follow the deformation (after kinematics);
!> - load: bias wrenches, modal forces and joint loads (after the body terms);
!> - carried: loads that need the subtrees' composite wrenches (after composite terms);
!> - rows: equations that replace rows of M qdd = P (after assembly);
!> - accelerate: known accelerations (the articulated-body path's form of `rows`).
!> Each counts one evaluation in the deform, load, rows or accelerate stage it acts in,
!> and every 32nd evaluation is timed (thread CPU time); the JSON reports both.
module pymr_model_effect
  use pymr_env_kinds, only : dp
  use pymr_env_clock, only : thread_cpu_time
  use pymr_model_types, only : model_data, model_work
  implicit none
  private
  public :: effect_t, effect_slot, effect_names
  public :: stage_impose, stage_deform, stage_load, stage_carried, stage_rows, stage_accelerate, n_stages
  public :: impose_effects, deform_effects, load_effects, carried_effects, rows_effects, accelerate_effects
  public :: effect_energies, effect_powers, effect_fast_damping, start_effect_counters
  public :: effect_motion_energies, effect_powers_qdd, effects_need_qdd, effects_vary_modal_mass
  public :: save_effect_states, load_effect_states
  public :: energy_kinetic, energy_gravity, energy_springs, power_drives, power_loads, power_motion, power_damping

  integer, parameter :: stage_impose = 1, stage_deform = 2, stage_load = 3, stage_carried = 4, &
    & stage_rows = 5, stage_accelerate = 6, n_stages = 6
  !> Energy parts (kinetic 1, gravity 2, strain 3, springs 4) and powers (drives 1, loads 2,
  !> prescribed motion 3, damping loss 4) an effect adds to.
  integer, parameter :: energy_kinetic = 1, energy_gravity = 2, energy_springs = 4
  integer, parameter :: power_drives = 1, power_loads = 2, power_motion = 3, power_damping = 4
  !> One evaluation in this many times its effects.
  integer, parameter :: timing_interval = 32

  !> An effect. Extensions override the stages they act in and set `acts` for them.
  type, abstract :: effect_t
    !> Its name in the scene's &effects group and in the JSON.
    character(len=24) :: name = ''
    logical :: acts(n_stages) = .false.
    !> It acts on joint rows only: skipped in fast-row evaluations.
    logical :: joint_rows_only = .false.
    !> It adds to the modal mass (wk%maa): the modal block of M is not constant.
    logical :: modal_mass_varies = .false.
    !> Its add_power_qdd needs the accelerations (the output computes them for it).
    logical :: power_needs_accelerations = .false.
  contains
    procedure :: impose => no_impose
    procedure :: deform => no_deform
    procedure :: load => no_load
    procedure :: carried => no_carried
    procedure :: rows => no_rows
    procedure :: accelerate => no_accelerate
    procedure :: add_energy => no_energy
    procedure :: add_power => no_power
    procedure :: fast_damping => no_fast_damping
    procedure :: add_motion_energy => no_motion_energy
    procedure :: add_power_qdd => no_power_qdd
    procedure :: save_state => no_save_state
    procedure :: load_state => no_load_state
  end type effect_t

  !> One entry of the model's list.
  type :: effect_slot
    class(effect_t), allocatable :: e
  end type effect_slot

contains

  subroutine no_impose(self, t, q, qd)
    class(effect_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: q(:), qd(:)
  end subroutine no_impose

  subroutine no_deform(self, d, wk, q, mask)
    class(effect_t), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: q(:)
    logical, intent(in) :: mask(:)
  end subroutine no_deform

  subroutine no_load(self, d, wk, t, q, qd, mask)
    class(effect_t), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: mask(:)
  end subroutine no_load

  subroutine no_carried(self, d, wk, q, mask)
    class(effect_t), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: q(:)
    logical, intent(in) :: mask(:)
  end subroutine no_carried

  subroutine no_rows(self, wk, t)
    class(effect_t), intent(in) :: self
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t
  end subroutine no_rows

  subroutine no_accelerate(self, wk, t, qdd)
    class(effect_t), intent(in) :: self
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: qdd(:)
  end subroutine no_accelerate

  subroutine no_energy(self, d, wk, q, e)
    class(effect_t), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: q(:)
    real(dp), intent(inout) :: e(:)
  end subroutine no_energy

  subroutine no_power(self, d, wk, t, q, qd, p)
    class(effect_t), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(inout) :: p(:)
  end subroutine no_power

  !> Damping per fast (modal) coordinate that the effect adds linearly in the modal rates
  !> (the multirate couplings' fast forces).
  subroutine no_fast_damping(self, d, df)
    class(effect_t), intent(in) :: self
    type(model_data), intent(in) :: d
    real(dp), intent(inout) :: df(:)
  end subroutine no_fast_damping

  !> Energies that depend on time and rates beyond the body terms (a moving mass's).
  subroutine no_motion_energy(self, d, wk, t, q, qd, e)
    class(effect_t), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(inout) :: e(:)
  end subroutine no_motion_energy

  !> Powers that need the accelerations qdd at (t, q, qd) (after an evaluation there).
  subroutine no_power_qdd(self, d, wk, t, q, qd, qdd, p)
    class(effect_t), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:), qdd(:)
    real(dp), intent(inout) :: p(:)
  end subroutine no_power_qdd

  !> Write (save_state) or read (load_state) the effect's run state on an open unformatted
  !> stream unit (checkpoints); nothing for effects without one.
  subroutine no_save_state(self, unit, ios)
    class(effect_t), intent(in) :: self
    integer, intent(in) :: unit
    integer, intent(out) :: ios
    ios = 0
  end subroutine no_save_state

  subroutine no_load_state(self, unit, ios)
    class(effect_t), intent(inout) :: self
    integer, intent(in) :: unit
    integer, intent(out) :: ios
    ios = 0
  end subroutine no_load_state

  !> Counters for the list's effects, named and zero.
  subroutine start_effect_counters(list, wk)
    type(effect_slot), intent(in) :: list(:)
    type(model_work), intent(inout) :: wk
    wk%count%effect_name = effect_names(list)
    allocate(wk%count%effect_evals(size(list)), wk%count%effect_timed(size(list)), wk%count%effect_cpu(size(list)))
    wk%count%effect_evals = 0; wk%count%effect_timed = 0; wk%count%effect_cpu = 0.0_dp
  end subroutine start_effect_counters

  !> The names of the list's effects, in list order.
  function effect_names(list) result(names)
    type(effect_slot), intent(in) :: list(:)
    character(len=24) :: names(size(list))
    integer :: i
    do i = 1, size(list)
      names(i) = list(i)%e%name
    end do
  end function effect_names

  !> This evaluation is one of those timed.
  pure logical function timed_evaluation(wk)
    type(model_work), intent(in) :: wk
    timed_evaluation = mod(wk%count%evals + wk%count%evals_fast_rows, timing_interval) == 0
  end function timed_evaluation

  !> The CPU clock at an effect stage's start (0 when this evaluation is not timed).
  real(dp) function clock_start(wk)
    type(model_work), intent(in) :: wk
    clock_start = 0.0_dp
    if (timed_evaluation(wk)) clock_start = thread_cpu_time()
  end function clock_start

  !> After effect i's stage: its CPU time when timed, and one evaluation when the stage counts.
  subroutine clock_stop(wk, i, c0, counts)
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: i
    real(dp), intent(in) :: c0
    logical, intent(in) :: counts
    if (timed_evaluation(wk)) then
      wk%count%effect_cpu(i) = wk%count%effect_cpu(i) + (thread_cpu_time() - c0)
      if (counts) wk%count%effect_timed(i) = wk%count%effect_timed(i) + 1
    end if
    if (counts) wk%count%effect_evals(i) = wk%count%effect_evals(i) + 1
  end subroutine clock_stop

  !> Copies of (q, qd) in wk%qx, wk%qdx with the prescribed coordinates on their functions.
  subroutine impose_effects(list, wk, t, q, qd)
    type(effect_slot), intent(in) :: list(:)
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    integer :: i
    wk%qx = q; wk%qdx = qd
    do i = 1, size(list)
      if (list(i)%e%acts(stage_impose)) call list(i)%e%impose(t, wk%qx, wk%qdx)
    end do
  end subroutine impose_effects

  !> The deform stage on the bodies in `mask`.
  subroutine deform_effects(list, d, wk, q, mask)
    type(effect_slot), intent(in) :: list(:)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: q(:)
    logical, intent(in) :: mask(:)
    integer :: i
    real(dp) :: c0
    do i = 1, size(list)
      if (.not. list(i)%e%acts(stage_deform)) cycle
      c0 = clock_start(wk)
      call list(i)%e%deform(d, wk, q, mask)
      call clock_stop(wk, i, c0, .true.)
    end do
  end subroutine deform_effects

  !> The load stage on the bodies in `mask`; joint loads only in full evaluations.
  subroutine load_effects(list, d, wk, t, q, qd, mask, fast_only)
    type(effect_slot), intent(in) :: list(:)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: mask(:), fast_only
    integer :: i
    real(dp) :: c0
    do i = 1, size(list)
      if (.not. list(i)%e%acts(stage_load)) cycle
      if (fast_only .and. list(i)%e%joint_rows_only) cycle
      c0 = clock_start(wk)
      call list(i)%e%load(d, wk, t, q, qd, mask)
      call clock_stop(wk, i, c0, .true.)
    end do
  end subroutine load_effects

  !> The carried stage on the bodies in `mask` (after the composite terms).
  subroutine carried_effects(list, d, wk, q, mask)
    type(effect_slot), intent(in) :: list(:)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: q(:)
    logical, intent(in) :: mask(:)
    integer :: i
    real(dp) :: c0
    do i = 1, size(list)
      if (.not. list(i)%e%acts(stage_carried)) cycle
      c0 = clock_start(wk)
      call list(i)%e%carried(d, wk, q, mask)
      call clock_stop(wk, i, c0, .false.)
    end do
  end subroutine carried_effects

  !> The rows stage (after assembly of M and P in wk).
  subroutine rows_effects(list, wk, t)
    type(effect_slot), intent(in) :: list(:)
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t
    integer :: i
    real(dp) :: c0
    do i = 1, size(list)
      if (.not. list(i)%e%acts(stage_rows)) cycle
      c0 = clock_start(wk)
      call list(i)%e%rows(wk, t)
      call clock_stop(wk, i, c0, .true.)
    end do
  end subroutine rows_effects

  !> The accelerate stage: known accelerations put in qdd (the articulated-body path; after
  !> the load stage, whose results in wk they may use).
  subroutine accelerate_effects(list, wk, t, qdd)
    type(effect_slot), intent(in) :: list(:)
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: qdd(:)
    integer :: i
    real(dp) :: c0
    do i = 1, size(list)
      if (.not. list(i)%e%acts(stage_accelerate)) cycle
      c0 = clock_start(wk)
      call list(i)%e%accelerate(wk, t, qdd)
      call clock_stop(wk, i, c0, .true.)
    end do
  end subroutine accelerate_effects

  !> The effects' potential energies added to the energy parts e (after the body terms).
  subroutine effect_energies(list, d, wk, q, e)
    type(effect_slot), intent(in) :: list(:)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: q(:)
    real(dp), intent(inout) :: e(:)
    integer :: i
    do i = 1, size(list)
      call list(i)%e%add_energy(d, wk, q, e)
    end do
  end subroutine effect_energies

  !> The effects' powers added to p (W) at a state with the prescribed coordinates imposed.
  subroutine effect_powers(list, d, wk, t, q, qd, p)
    type(effect_slot), intent(in) :: list(:)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(inout) :: p(:)
    integer :: i
    do i = 1, size(list)
      call list(i)%e%add_power(d, wk, t, q, qd, p)
    end do
  end subroutine effect_powers

  !> The effects' time- and rate-dependent energies added to e (after the kinematics).
  subroutine effect_motion_energies(list, d, wk, t, q, qd, e)
    type(effect_slot), intent(in) :: list(:)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(inout) :: e(:)
    integer :: i
    do i = 1, size(list)
      call list(i)%e%add_motion_energy(d, wk, t, q, qd, e)
    end do
  end subroutine effect_motion_energies

  !> The effects' powers that need the accelerations qdd, added to p (W).
  subroutine effect_powers_qdd(list, d, wk, t, q, qd, qdd, p)
    type(effect_slot), intent(in) :: list(:)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:), qdd(:)
    real(dp), intent(inout) :: p(:)
    integer :: i
    do i = 1, size(list)
      if (list(i)%e%power_needs_accelerations) call list(i)%e%add_power_qdd(d, wk, t, q, qd, qdd, p)
    end do
  end subroutine effect_powers_qdd

  !> Some effect's power needs the accelerations.
  pure logical function effects_need_qdd(list)
    type(effect_slot), intent(in) :: list(:)
    integer :: i
    effects_need_qdd = .false.
    do i = 1, size(list)
      effects_need_qdd = effects_need_qdd .or. list(i)%e%power_needs_accelerations
    end do
  end function effects_need_qdd

  !> Some effect adds to the modal mass (the modal block of M then varies).
  pure logical function effects_vary_modal_mass(list)
    type(effect_slot), intent(in) :: list(:)
    integer :: i
    effects_vary_modal_mass = .false.
    do i = 1, size(list)
      effects_vary_modal_mass = effects_vary_modal_mass .or. list(i)%e%modal_mass_varies
    end do
  end function effects_vary_modal_mass

  !> The effects' run states written to (save) or read from (load) a checkpoint's unit.
  subroutine save_effect_states(list, unit, ios)
    type(effect_slot), intent(in) :: list(:)
    integer, intent(in) :: unit
    integer, intent(out) :: ios
    integer :: i
    ios = 0
    do i = 1, size(list)
      if (ios == 0) call list(i)%e%save_state(unit, ios)
    end do
  end subroutine save_effect_states

  subroutine load_effect_states(list, unit, ios)
    type(effect_slot), intent(inout) :: list(:)
    integer, intent(in) :: unit
    integer, intent(out) :: ios
    integer :: i
    ios = 0
    do i = 1, size(list)
      if (ios == 0) call list(i)%e%load_state(unit, ios)
    end do
  end subroutine load_effect_states

  !> Damping per fast coordinate, linear in the modal rates, of all the effects.
  subroutine effect_fast_damping(list, d, df)
    type(effect_slot), intent(in) :: list(:)
    type(model_data), intent(in) :: d
    real(dp), intent(inout) :: df(:)
    integer :: i
    do i = 1, size(list)
      call list(i)%e%fast_damping(d, df)
    end do
  end subroutine effect_fast_damping
end module pymr_model_effect
