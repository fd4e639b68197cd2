!> The scene as read from a namelist file: plain data, validated, not yet a model.
!>
!> Each namelist group is a record type here, and beside it the one table that describes
!> its items (`describe_*`: name, type, count, range or choices, unit, meaning, and the field
!> that holds it). A field's initial value is the item's default; `unset` marks an item
!> without one. The reader, the writer of the resolved scene and the schema all go through
!> these tables.
module pymr_model_scene
  use pymr_env_kinds, only : dp, name_len
  use pymr_env_item_table, only : item_table, origin_t, unset
  implicit none
  private
  public :: scene_t, body_spec, joint_spec, drive_spec, marker_spec, integrator_spec, effects_spec
  public :: spring_spec, motion_spec, load_spec, force_spec, control_spec, moving_load_spec, output_spec, scene_spec
  public :: sensor_spec, sensor_items
  public :: max_modes_input, big_length, big_force, big_time, big_mass, small_mass
  public :: joint_ndof, unset, group_names, single_groups, repeated_groups, describe_group, group_origin, group_count
  public :: naming_item, complete_scene, body_items, item_applies, output_quantities, beam_mode_count
  public :: closes_loop, flexible_loop, body_index, control_count

  !> The groups of a scene file, in the order the resolved scene is written.
  character(len=*), parameter :: group_names = &
    & 'scene integrator effects output body joint drive spring motion load marker force control moving_load sensor'
  !> The groups that may appear at most once, and those that may repeat.
  character(len=*), parameter :: single_groups = 'scene integrator effects output'
  character(len=*), parameter :: repeated_groups = &
    & 'body joint drive spring motion load marker force control moving_load sensor'
  !> The groups of output columns (&output quantities).
  character(len=*), parameter :: output_quantities = &
    & 'coordinates markers marker_accelerations marker_orientations reactions energy'

  !> Bounds that keep every physical value far from overflow in the model's arithmetic; the
  !> least mass of a body (kg).
  real(dp), parameter :: big_length = 1.0e6_dp, big_force = 1.0e12_dp, big_mass = 1.0e12_dp
  real(dp), parameter :: small_mass = 1.0e-12_dp
  !> Largest time (s) an item or a table's time column may give.
  real(dp), parameter :: big_time = 1.0e9_dp
  !> Most per-mode values an item such as modal_damping can hold.
  integer, parameter :: max_modes_input = 64

  !> Settings of the time integrator (&integrator).
  type :: integrator_spec
    !> 'single' or 'multirate'.
    character(len=16) :: method = 'single'
    !> Fast (modal) and slow (joint) steps (s); single-rate uses one step.
    real(dp) :: h_fast = unset, h_slow = unset
    !> Adaptive step control and its tolerances.
    logical :: adaptive = .false.
    real(dp) :: rtol = 1.0e-6_dp, atol = 1.0e-8_dp
    !> Smallest and largest adaptive step (s); 0 = automatic.
    real(dp) :: h_min = 0.0_dp, h_max = 0.0_dp
    !> Corrector evaluations per step (1 = PECE).
    integer :: n_corrector = 1
    !> Adaptive multirate: the largest step ratio H/h the controller may choose.
    integer :: k_max = 50
    !> How adaptive steps weigh a modal coordinate's error: 'state' (its position and rate
    !> apart) or 'amplitude' (both as the mode's amplitude).
    character(len=16) :: error_norm = 'state'
    !> Refuse fixed steps that the pre-flight check finds unstable (.false.: run anyway).
    logical :: stability_check = .true.
    !> Most (fast) steps a run may take.
    integer :: max_steps = 100000000
    !> Multirate coupling of the fast steps: 'response' (linear response of all
    !> coordinates to the fast forces) or 'full' (the paper's).
    character(len=16) :: coupling = 'response'
    !> The Adams formula: 'adams' (variable step and order, iterated corrector) or 'abm4'
    !> (the paper's PECE of order 4); '' until the scene is complete: 'adams' for adaptive
    !> single-rate runs, else 'abm4'.
    character(len=8) :: formula = ''
    !> Order of 'adams': 0 = variable (1 to 12), 1-12 = that order ('abm4': 4).
    integer :: order = 0
    !> Iteration of the 'adams' corrector: 'newton' or 'fixed-point'.
    character(len=12) :: corrector = 'newton'
    !> Forward dynamics of single-rate evaluations: 'auto', 'articulated' (O(n)) or
    !> 'mass_matrix' (assemble and factor M).
    character(len=12) :: dynamics = 'auto'
    type(origin_t) :: origin
  end type integrator_spec

  !> &scene: the run's title, end time and gravity.
  type :: scene_spec
    character(len=256) :: title = ''
    !> End time (s) and gravity (m/s^2, inertial frame).
    real(dp) :: t_end = unset, gravity(3) = [0.0_dp, -9.81_dp, 0.0_dp]
    !> The initial state: 'rest' (as given) or 'static' (modal coordinates, and the joints
    !> marked settle, in static equilibrium under the forces at t = 0).
    character(len=8) :: start = 'rest'
    !> Largest deflection of a flexible body, as a fraction of its size, before the run
    !> warns (linear modal theory holds for small deflections; 0: no check), and whether
    !> passing it stops the run instead.
    real(dp) :: deflection_limit = 0.1_dp
    logical :: deflection_stop = .false.
    type(origin_t) :: origin
  end type scene_spec

  !> &output: the CSV file, its interval and the checkpoints.
  type :: output_spec
    !> CSV output file and output interval (s; 0 = every slow step).
    character(len=512) :: file = ''
    real(dp) :: dt = 0.0_dp
    !> Checkpoints every checkpoint_dt s of simulated time (0: none), to checkpoint_file
    !> (default: the CSV path with .ckpt).
    real(dp) :: checkpoint_dt = 0.0_dp
    character(len=512) :: checkpoint_file = ''
    !> Significant digits written per value.
    integer :: precision = 17
    !> Largest results file a run may write (bytes).
    real(dp) :: max_bytes = 1.0e10_dp
    !> The groups of columns written (blank-separated words of output_quantities).
    character(len=128) :: quantities = 'coordinates markers'
    !> The results file's format: 'csv' or 'hdf5', and HDF5's deflate level (0: none).
    character(len=8) :: format = 'csv'
    integer :: compression = 1
    type(origin_t) :: origin
  end type output_spec

  !> Optional physics (&effects); every effect is off unless turned on. Its origin records
  !> the items the scene (or a --set) wrote, so that an effect turned off on purpose is
  !> told apart from one forgotten.
  type :: effects_spec
    logical :: gravity = .false.
    logical :: joint_drives = .false.
    logical :: modal_damping = .false.
    logical :: joint_springs = .false.
    logical :: geometric_stiffening = .false.
    logical :: base_motion = .false.
    logical :: firing_load = .false.
    logical :: force_elements = .false.
    logical :: controls = .false.
    logical :: moving_loads = .false.
    !> Fidelity of the deformation-dependent inertia of flexible bodies: 'full' or 'linear'.
    character(len=16) :: deformation_inertia = 'full'
    type(origin_t) :: origin
  end type effects_spec

  !> One &body group.
  type :: body_spec
    character(len=name_len) :: name = ''
    !> 'ground', 'rigid', 'beam', 'modal'.
    character(len=16) :: kind = ''
    !> Mass (kg), centre of mass in the body frame (m), inertia about the centre of
    !> mass in body axes: Ixx Iyy Izz Ixy Ixz Iyz (kg m^2).
    real(dp) :: mass = unset, com(3) = 0.0_dp, inertia(6) = unset
    !> Beam: length (m), Young's modulus (Pa), density (kg/m^3), tube radii (m) or section
    !> area (m^2) and second moments iy, iz (m^4), elements, bending modes per plane, axial
    !> and torsional modes; shear modulus (Pa) and (without tube radii) torsion constant
    !> (m^4) for the torsional ones.
    real(dp) :: length = unset, youngs_modulus = unset, density = unset
    real(dp) :: r_outer = unset, r_inner = 0.0_dp, area = unset, iy = unset, iz = unset
    real(dp) :: shear_modulus = unset, torsion_constant = unset
    integer :: n_elements = 20, modes_y = 0, modes_z = 0, modes_x = 0, modes_t = 0
    !> Modal damping (used when &effects modal_damping is on): fraction of critical, one
    !> value for every mode or one per mode; or Rayleigh damping alpha + beta omega^2 (1/s).
    real(dp) :: modal_damping(max_modes_input) = unset
    real(dp) :: rayleigh_alpha = 0.0_dp, rayleigh_beta = 0.0_dp
    !> Initial modal coordinates and rates of a flexible body, one per mode (0 when not given).
    real(dp) :: a0(max_modes_input) = unset, ad0(max_modes_input) = unset
    !> Modal data file of a 'modal' body (relative to the scene file's folder).
    character(len=512) :: modal_file = ''
    type(origin_t) :: origin
  end type body_spec

  !> One &joint group.
  type :: joint_spec
    character(len=name_len) :: name = '', parent = '', child = ''
    !> 'revolute', 'prismatic', 'fixed', 'spherical', 'free', 'cylindrical', 'universal', 'planar'.
    character(len=16) :: kind = ''
    !> Joint point in the parent frame (m) and axis in the parent frame.
    real(dp) :: at(3) = 0.0_dp, axis(3) = [0.0_dp, 0.0_dp, 1.0_dp]
    !> A universal joint's second axis, normal to axis (unset: joint_axis2 chooses one).
    real(dp) :: axis2(3) = unset
    !> A loop-closing joint's point in the child's frame (m).
    real(dp) :: child_at(3) = 0.0_dp
    !> Initial coordinates and rates, one per coordinate of the joint (0 when not given:
    !> see complete_joint); the rest stay unset.
    real(dp) :: q0(6) = unset, qd0(6) = unset
    !> Free to settle in a static start (its coordinates solved with the modal ones).
    logical :: settle = .false.
    !> Held by the assembly of closed loops (its q0 and qd0 kept, the others closing the loops).
    logical :: hold = .false.
    type(origin_t) :: origin
  end type joint_spec

  !> One &drive group: a generalised force offset + amplitude*sin(2 pi frequency t + phase).
  type :: drive_spec
    character(len=name_len) :: joint = ''
    !> Which coordinate of the joint (1 for one-coordinate joints).
    integer :: coordinate = 1
    !> 'sine': offset + amplitude sin(2 pi frequency t + phase); 'table': offset + the
    !> history in `file` (time, value lines), interpolated linearly.
    character(len=16) :: form = 'sine'
    real(dp) :: offset = 0.0_dp, amplitude = 0.0_dp, frequency = 0.0_dp, phase = 0.0_dp
    character(len=512) :: file = ''
    type(origin_t) :: origin
  end type drive_spec

  !> One &spring group: a spring-damper on a joint coordinate,
  !> force = -stiffness (q - free_position) - damping qd.
  type :: spring_spec
    character(len=name_len) :: joint = ''
    integer :: coordinate = 1
    real(dp) :: stiffness = 0.0_dp, damping = 0.0_dp, free_position = 0.0_dp
    type(origin_t) :: origin
  end type spring_spec

  !> One &motion group: a joint coordinate that follows a function of time.
  !> form 'sine': offset + amplitude sin(2 pi frequency t + phase); 'spinup': the smooth
  !> ramp to the rate `rate` over `ramp_time` (Kane, Ryan and Banerjee 1987), then constant rate;
  !> 'table': a tabulated history (see `file`).
  type :: motion_spec
    character(len=name_len) :: joint = ''
    integer :: coordinate = 1
    character(len=16) :: form = 'sine'
    real(dp) :: offset = 0.0_dp, amplitude = 0.0_dp, frequency = 0.0_dp, phase = 0.0_dp
    real(dp) :: rate = 0.0_dp, ramp_time = unset
    !> form 'table': offset + the natural cubic spline through the history in `file`.
    character(len=512) :: file = ''
    type(origin_t) :: origin
  end type motion_spec

  !> One &load group: a force or moment at a marker along `direction` (in the frame of the
  !> marker's body, a follower load, or inertial), of magnitude peak sin(pi (t - start)/duration)
  !> for start <= t <= start + duration, zero outside (form 'pulse'); offset (form 'constant');
  !> offset + amplitude sin(2 pi frequency t + phase) (form 'sine'); offset + the history in
  !> `file` interpolated linearly (form 'table').
  type :: load_spec
    character(len=name_len) :: marker = ''
    real(dp) :: direction(3) = 0.0_dp
    character(len=16) :: form = 'pulse', kind = 'force', frame = 'body'
    real(dp) :: peak = 0.0_dp, start = 0.0_dp, duration = unset
    real(dp) :: offset = 0.0_dp, amplitude = 0.0_dp, frequency = 0.0_dp, phase = 0.0_dp
    character(len=512) :: file = ''
    type(origin_t) :: origin
  end type load_spec

  !> One &marker group: a point of a body whose motion is written out.
  type :: marker_spec
    character(len=name_len) :: name = '', body = ''
    real(dp) :: at(3) = 0.0_dp
    type(origin_t) :: origin
  end type marker_spec

  !> One &sensor group: output columns measured on markers. 'distance': the distance between
  !> marker and marker `to` and its rate; 'position': marker's position and velocity in the
  !> frame of body `frame` (its axes, relative to it).
  type :: sensor_spec
    character(len=name_len) :: name = '', marker = '', to = '', frame = ''
    character(len=16) :: kind = ''
    type(origin_t) :: origin
  end type sensor_spec

  !> One &force group: a force element between two markers. 'spring_damper': one
  !> stiffness and damping along the line between the markers, relaxed at free_length;
  !> 'bushing': six of each (translations x, y, z, rotations about x, y, z) in marker i's
  !> axes on the displacement and rotation of marker j from marker i. A 'spring_damper'
  !> may give a force-deflection table `file` in place of its stiffness.
  type :: force_spec
    character(len=name_len) :: name = '', marker_i = '', marker_j = ''
    character(len=16) :: kind = ''
    real(dp) :: stiffness(6) = unset, damping(6) = unset, free_length = unset
    character(len=512) :: file = ''
    type(origin_t) :: origin
  end type force_spec

  !> One &control group: a feedback drive on a joint coordinate. The effort
  !> kp e + ki (integral of e) + kd edot, limited to |effort| <= max_effort, acts on the
  !> joint coordinate; e = setpoint - measured, edot = -(measured rate). The sensor measures
  !> the coordinate itself ('coordinate') or the inertial rotation of a marker's frame about
  !> `axis` ('orientation').
  type :: control_spec
    character(len=name_len) :: name = '', joint = '', marker = ''
    integer :: coordinate = 1
    character(len=16) :: sensor = 'coordinate'
    real(dp) :: axis(3) = 0.0_dp
    real(dp) :: kp = 0.0_dp, ki = 0.0_dp, kd = 0.0_dp, setpoint = 0.0_dp, max_effort = unset
    character(len=512) :: file = ''
    type(origin_t) :: origin
  end type control_spec
  !> One &moving_load group: a point mass and a force (body axes) travelling along the x
  !> axis of a beam: 'constant_speed' (at s0 until start, then s0 + speed (t - start)) or
  !> 'table' (the natural cubic spline through the positions in `file`).
  type :: moving_load_spec
    character(len=name_len) :: name = '', body = ''
    real(dp) :: mass = 0.0_dp, force(3) = 0.0_dp
    character(len=16) :: form = 'constant_speed'
    real(dp) :: start = 0.0_dp, s0 = 0.0_dp, speed = 0.0_dp
    character(len=512) :: file = ''
    type(origin_t) :: origin
  end type moving_load_spec

  !> The whole scene.
  type :: scene_t
    !> File the scene came from (for messages).
    character(len=:), allocatable :: file
    type(scene_spec) :: scene
    type(integrator_spec) :: integrator
    type(effects_spec) :: effects
    type(body_spec), allocatable :: bodies(:)
    type(joint_spec), allocatable :: joints(:)
    type(drive_spec), allocatable :: drives(:)
    type(spring_spec), allocatable :: springs(:)
    type(motion_spec), allocatable :: motions(:)
    type(load_spec), allocatable :: loads(:)
    type(marker_spec), allocatable :: markers(:)
    type(force_spec), allocatable :: forces(:)
    type(control_spec), allocatable :: controls(:)
    type(moving_load_spec), allocatable :: moving_loads(:)
    type(sensor_spec), allocatable :: sensors(:)
    type(output_spec) :: output
  end type scene_t

contains

  ! ----------------------------------------------------------------- the item tables

  subroutine describe_scene(g, t)
    type(scene_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('title', g%title, 'title of the run, written into the results')
    call t%add('t_end', g%t_end, 's', 'end time of the run (required)', gt=0.0_dp, le=1.0e9_dp)
    call t%add('gravity', g%gravity, 'm/s^2', 'gravity in the inertial frame (used with &effects gravity)', &
      & ge=-1.0e6_dp, le=1.0e6_dp)
    call t%add('start', g%start, "initial state: 'rest' (as given by q0, qd0, a0, ad0) or 'static' (the modal " // &
      & 'coordinates, and the coordinates of joints marked settle, in static equilibrium under the forces at ' // &
      & 't = 0, solved by Newton before the run)', choices='rest static')
    call t%add('deflection_limit', g%deflection_limit, '-', "largest deflection of a flexible body's points, " // &
      & 'as a fraction of its size (its farthest point from its origin), before the run warns at an output ' // &
      & 'time: linear modal theory holds for small deflections (0: no check)', ge=0.0_dp, le=1.0e3_dp)
    call t%add('deflection_stop', g%deflection_stop, 'a deflection beyond deflection_limit stops the run ' // &
      & '(exit 2) instead of a warning in the summary and the JSON')
  end subroutine describe_scene

  subroutine describe_integrator(g, t)
    type(integrator_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('method', g%method, "single-rate or multirate integration; 'auto' (adaptive runs): the kernel " // &
      & "chooses between single-rate (the scene's formula) and the multirate couplings 'exponential' and " // &
      & "'response' by a measured probe over the first part of the run (docs/integrators.md)", &
      & choices='single multirate auto')
    call t%add('h_fast', g%h_fast, 's', 'step of the fast (modal) coordinates; default h_slow', &
      & ge=1.0e-12_dp, le=1.0e3_dp)
    call t%add('h_slow', g%h_slow, 's', 'step of the slow (joint) coordinates, the step of a single-rate run; ' // &
      & 'default h_fast', ge=1.0e-12_dp, le=1.0e3_dp)
    call t%add('adaptive', g%adaptive, 'adaptive steps from the local error estimate')
    call t%add('rtol', g%rtol, '-', 'relative tolerance of the local error (adaptive)', ge=100*epsilon(1.0_dp), &
      & le=1.0_dp)
    call t%add('atol', g%atol, 'state units', 'absolute tolerance of the local error (adaptive)', &
      & ge=1.0e-20_dp, le=1.0e6_dp)
    call t%add('h_min', g%h_min, 's', 'smallest adaptive step; 0 = 1e-12 s', ge=0.0_dp, le=1.0e3_dp)
    call t%add('h_max', g%h_max, 's', 'largest adaptive step; 0 = no limit', ge=0.0_dp, le=1.0e9_dp)
    call t%add('n_corrector', g%n_corrector, '-', 'corrector evaluations per step (1 = PECE)', ge=1, le=10)
    call t%add('coupling', g%coupling, "multirate coupling of the fast steps: 'response' moves every " // &
      & "coordinate by its linear response to the fast forces, 'full' re-evaluates the modal rows (the paper's), " // &
      & "'exponential' moves the fast coordinates by the exact flow of their linear part (no fast step: h_slow " // &
      & "is the step)", choices='response full exponential')
    call t%add('formula', g%formula, "the Adams formula: 'adams' (variable step and order 1-12, corrector " // &
      & "iterated to convergence; the default of adaptive single-rate runs) or 'abm4' (the paper's order-4 " // &
      & "predictor-corrector; the default, and the formula, of fixed-step and multirate runs)", choices='adams abm4')
    call t%add('order', g%order, '-', "order of formula 'adams': 0 = variable (1 to 12, from the error " // &
      & "estimates), 1-12 = that order; formula 'abm4' is of order 4", ge=0, le=12)
    call t%add('corrector', g%corrector, "iteration of the 'adams' corrector to convergence: 'newton' (chord " // &
      & "iteration with a difference Jacobian, renewed when it is 400 steps old or an iteration fails) or " // &
      & "'fixed-point' (no Jacobian)", &
      & choices='newton fixed-point')
    call t%add('dynamics', g%dynamics, "how single-rate evaluations solve M qdd = P: 'articulated' (the " // &
      & "articulated-body algorithm, O(n), flexible bodies included), 'mass_matrix' (assemble M and P and " // &
      & "factor M, O(n^3)) or 'auto' (articulated without flexible bodies, and with them from 12 " // &
      & "joint coordinates on: where it is the faster; " // &
      & "multirate and the pre-flight check always use M)", choices='auto articulated mass_matrix')
    call t%add('k_max', g%k_max, '-', "largest step ratio H/h of adaptive multirate", ge=1, le=100000)
    call t%add('error_norm', g%error_norm, "how adaptive steps weigh the local error of a modal coordinate: " // &
      & "'state' its position and rate apart (each against rtol |x| + atol), 'amplitude' both as the mode's " // &
      & "amplitude A = sqrt(a^2 + (ad/omega)^2) (the position against rtol A + atol, the rate against omega " // &
      & "times that; omega the flexible body's own, from its mass-normalised modes); method 'auto' runs its " // &
      & "candidates with 'amplitude' when none is given, unless a loop closes through a flexible body", &
      & choices='state amplitude')
    call t%add('stability_check', g%stability_check, 'refuse fixed steps that the pre-flight check finds unstable')
    call t%add('max_steps', g%max_steps, '-', 'most (fast) steps a run may take: a fixed-step run needing more is ' // &
      & 'refused, an adaptive one stops', ge=1, le=2000000000)
  end subroutine describe_integrator

  subroutine describe_effects(g, t)
    type(effects_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('gravity', g%gravity, 'gravity (&scene gravity) on every body')
    call t%add('joint_drives', g%joint_drives, 'the &drive forces and torques')
    call t%add('modal_damping', g%modal_damping, "the flexible bodies' modal damping")
    call t%add('joint_springs', g%joint_springs, 'the &spring spring-dampers')
    call t%add('geometric_stiffening', g%geometric_stiffening, 'geometric stiffness of beams from their axial load')
    call t%add('base_motion', g%base_motion, 'the &motion prescribed joint coordinates')
    call t%add('firing_load', g%firing_load, 'the &load pulses')
    call t%add('force_elements', g%force_elements, 'the &force elements between markers')
    call t%add('controls', g%controls, 'the &control feedback drives')
    call t%add('moving_loads', g%moving_loads, 'the &moving_load masses and forces travelling along beams')
    call t%add('deformation_inertia', g%deformation_inertia, "inertia of deformed flexible bodies: 'full' or " // &
      & "'linear' (without the second-order deformation terms)", choices='full linear')
  end subroutine describe_effects

  subroutine describe_output(g, t)
    type(output_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('file', g%file, 'results file (relative to the working folder; default: the scene file ' // &
      & 'with .csv, or .h5 for format = ''hdf5'')')
    call t%add('format', g%format, "results file format: 'csv' (text, one row a line) or 'hdf5' (binary, " // &
      & "compressed, one dataset per group of columns, with units and the run's description; a .h5 or " // &
      & ".hdf5 file)", choices='csv hdf5')
    call t%add('compression', g%compression, '-', "hdf5 only: deflate level of the datasets (after the " // &
      & "shuffle filter); 1 costs the least CPU, 9 writes the smallest file, 0 writes them uncompressed", ge=0, le=9)
    call t%add('dt', g%dt, 's', 'output interval; 0 = every step', ge=0.0_dp, le=1.0e9_dp)
    call t%add('checkpoint_dt', g%checkpoint_dt, 's', 'checkpoint interval of simulated time; 0 = none', &
      & ge=0.0_dp, le=1.0e9_dp)
    call t%add('checkpoint_file', g%checkpoint_file, 'checkpoint file (default: the CSV file with .ckpt)')
    call t%add('precision', g%precision, '-', 'significant digits written per value (17 read back exactly; ' // &
      & 'csv only: hdf5 keeps every bit)', &
      & ge=6, le=17)
    call t%add('max_bytes', g%max_bytes, 'bytes', 'largest results file a run may write: a run whose output ' // &
      & 'would exceed it is refused (a restart too); an adaptive run writing a row every step fails when its ' // &
      & 'rows reach it', ge=1.0e3_dp, le=1.0e15_dp)
    call t%add('quantities', g%quantities, "the groups of columns written: 'coordinates' (joint and modal " // &
      & "coordinates and rates), 'markers' (position and velocity of each marker), 'marker_accelerations', " // &
      & "'marker_orientations' (quaternion w, x, y, z of each marker's frame), 'reactions' (each joint's force " // &
      & "and moment on its child, in the child's frame, about the joint point), 'energy' (kinetic, gravity, " // &
      & "strain and spring energy, their total, and the work of drives, loads and prescribed motion and the " // &
      & "energy lost in damping)", choices=output_quantities, most=6)
  end subroutine describe_output

  subroutine describe_body(g, t)
    type(body_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('name', g%name, 'name of the body, unique among the bodies (required)')
    call t%add('kind', g%kind, "'ground' (the fixed base), 'rigid', 'beam' (built-in Euler-Bernoulli beam " // &
      & "along x) or 'modal' (modes from a file) (required)", choices='ground rigid beam modal')
    call t%add('mass', g%mass, 'kg', 'mass of a rigid body (required for rigid)', ge=small_mass, le=big_mass)
    call t%add('com', g%com, 'm', 'centre of mass of a rigid body in its frame', ge=-big_length, le=big_length)
    call t%add('inertia', g%inertia, 'kg m^2', 'inertia about the centre of mass in body axes: Ixx Iyy Izz ' // &
      & 'Ixy Ixz Iyz (required for rigid)', ge=-1.0e15_dp, le=1.0e15_dp)
    call t%add('length', g%length, 'm', 'beam length along its x axis', ge=1.0e-6_dp, le=1.0e4_dp)
    call t%add('youngs_modulus', g%youngs_modulus, 'Pa', "beam Young's modulus", ge=1.0e-3_dp, le=1.0e13_dp)
    call t%add('density', g%density, 'kg/m^3', 'beam density', ge=1.0e-6_dp, le=1.0e6_dp)
    call t%add('r_outer', g%r_outer, 'm', 'outer radius of a tube section', ge=1.0e-9_dp, le=1.0e3_dp)
    call t%add('r_inner', g%r_inner, 'm', 'inner radius of a tube section', ge=0.0_dp, le=1.0e3_dp)
    call t%add('area', g%area, 'm^2', 'section area (instead of r_outer)', ge=1.0e-18_dp, le=1.0e6_dp)
    call t%add('iy', g%iy, 'm^4', 'second moment of the section for bending in the x-z plane (modes_z)', &
      & ge=1.0e-36_dp, le=1.0e12_dp)
    call t%add('iz', g%iz, 'm^4', 'second moment of the section for bending in the x-y plane (modes_y)', &
      & ge=1.0e-36_dp, le=1.0e12_dp)
    call t%add('n_elements', g%n_elements, '-', 'finite elements of a beam', ge=1, le=5000)
    call t%add('modes_y', g%modes_y, '-', 'bending modes kept in the x-y plane (deflection along y)', ge=0, le=10000)
    call t%add('modes_z', g%modes_z, '-', 'bending modes kept in the x-z plane (deflection along z)', ge=0, le=10000)
    call t%add('modes_x', g%modes_x, '-', 'axial (bar) modes kept (displacement along x), after the bending modes', &
      & ge=0, le=10000)
    call t%add('modes_t', g%modes_t, '-', 'torsional (shaft) modes kept (rotation about x), after the axial ' // &
      & 'modes; with them the mass points carry the rotary inertia of the section', ge=0, le=10000)
    call t%add('shear_modulus', g%shear_modulus, 'Pa', 'shear modulus G for torsion (required when modes_t > 0)', &
      & ge=1.0e-3_dp, le=1.0e13_dp)
    call t%add('torsion_constant', g%torsion_constant, 'm^4', 'torsion constant J of a section given by area, ' // &
      & 'iy and iz (required when modes_t > 0; a tube has pi/2 (r_outer^4 - r_inner^4))', &
      & ge=1.0e-36_dp, le=1.0e12_dp)
    call t%add('modal_damping', g%modal_damping, '-', 'damping as a fraction of critical: one value for ' // &
      & 'every mode, or one per mode', ge=0.0_dp, lt=1.0_dp, variable=.true.)
    call t%add('rayleigh_alpha', g%rayleigh_alpha, '1/s', 'Rayleigh damping: alpha + beta omega^2', &
      & ge=0.0_dp, le=1.0e6_dp)
    call t%add('rayleigh_beta', g%rayleigh_beta, 's', 'Rayleigh damping: alpha + beta omega^2', &
      & ge=0.0_dp, le=1.0e3_dp)
    call t%add('modal_file', g%modal_file, "modal data file of a 'modal' body (relative to the scene's folder)", &
      & scene_file=.true.)
    call t%add('a0', g%a0, 'm kg^0.5', 'initial modal coordinates of a flexible body, one per mode (default 0)', &
      & ge=-big_length, le=big_length, variable=.true.)
    call t%add('ad0', g%ad0, 'm kg^0.5/s', 'initial modal rates of a flexible body, one per mode (default 0)', &
      & ge=-big_length, le=big_length, variable=.true.)
  end subroutine describe_body

  subroutine describe_joint(g, t)
    type(joint_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('name', g%name, 'name of the joint, unique among the joints (required)')
    call t%add('kind', g%kind, "'revolute', 'prismatic' (one coordinate about or along axis), 'fixed', " // &
      & "'spherical' (rotations x, y, z), 'free' (translations x, y, z, then rotations), 'cylindrical' " // &
      & "(translation along axis, then rotation about it), 'universal' (rotation about axis, then about axis2) " // &
      & "or 'planar' (translations along two normals of axis, then rotation about it) (required)", &
      & choices='revolute prismatic fixed spherical free cylindrical universal planar')
    call t%add('parent', g%parent, 'the body the joint hangs from (required)')
    call t%add('child', g%child, 'the body the joint moves (required)')
    call t%add('at', g%at, 'm', "joint point in the parent's frame", ge=-big_length, le=big_length)
    call t%add('child_at', g%child_at, 'm', "joint point in the child's frame, for a joint that closes a loop " // &
      & "(its child already has a parent joint), which must give it (0, 0, 0: the child's origin)", &
      & ge=-big_length, le=big_length)
    call t%add('axis', g%axis, '-', "axis of a revolute, prismatic, cylindrical, universal or planar joint " // &
      & "in the parent's frame", ge=-big_length, le=big_length)
    call t%add('axis2', g%axis2, '-', "a universal joint's second axis, normal to axis, in the parent's " // &
      & "frame at zero first angle (it turns with the first rotation; a loop-closing joint's: in the " // &
      & "child's frame); default: the coordinate axis least " // &
      & "aligned with axis (the first on a tie) made normal to it, x for axis z", ge=-big_length, le=big_length)
    call t%add('q0', g%q0, 'rad or m', 'initial coordinates, one per coordinate of the joint', &
      & ge=-big_length, le=big_length, variable=.true.)
    call t%add('qd0', g%qd0, 'rad/s or m/s', 'initial rates, one per coordinate of the joint', &
      & ge=-big_length, le=big_length, variable=.true.)
    call t%add('settle', g%settle, "free to settle in a static start (&scene start = 'static'): its coordinates " // &
      & 'are solved for equilibrium with the modal coordinates, q0 is the first guess')
    call t%add('hold', g%hold, 'kept by the assembly of closed loops: its q0 and qd0 stay as given and the ' // &
      & 'other coordinates take the least change that closes the loops')
  end subroutine describe_joint

  subroutine describe_drive(g, t)
    type(drive_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('joint', g%joint, 'the joint driven (required)')
    call t%add('coordinate', g%coordinate, '-', 'which coordinate of the joint', ge=1, le=6)
    call t%add('form', g%form, "'sine': offset + amplitude sin(2 pi frequency t + phase); 'table': offset + " // &
      & 'the history in file', choices='sine table')
    call t%add('offset', g%offset, 'N or N m', 'constant force or torque', ge=-big_force, le=big_force)
    call t%add('amplitude', g%amplitude, 'N or N m', 'amplitude of the sine', ge=-big_force, le=big_force)
    call t%add('frequency', g%frequency, 'Hz', 'frequency of the sine', ge=0.0_dp, le=1.0e6_dp)
    call t%add('phase', g%phase, 'rad', 'phase of the sine', ge=-1.0e3_dp, le=1.0e3_dp)
    call t%add('file', g%file, "file of 'time value' lines (form 'table'; relative to the scene's folder)", &
      & scene_file=.true.)
  end subroutine describe_drive

  subroutine describe_spring(g, t)
    type(spring_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('joint', g%joint, 'the joint whose coordinate the spring-damper acts on (required)')
    call t%add('coordinate', g%coordinate, '-', 'which coordinate of the joint', ge=1, le=6)
    call t%add('stiffness', g%stiffness, 'N/m or N m/rad', 'spring stiffness', ge=0.0_dp, le=big_force)
    call t%add('damping', g%damping, 'N s/m or N m s/rad', 'damper coefficient', ge=0.0_dp, le=big_force)
    call t%add('free_position', g%free_position, 'm or rad', 'coordinate at which the spring is relaxed', &
      & ge=-big_length, le=big_length)
  end subroutine describe_spring

  subroutine describe_motion(g, t)
    type(motion_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('joint', g%joint, 'the joint whose coordinate is prescribed (required)')
    call t%add('coordinate', g%coordinate, '-', 'which coordinate of the joint', ge=1, le=6)
    call t%add('form', g%form, "'sine': offset + amplitude sin(2 pi frequency t + phase); 'spinup': a " // &
      & "smooth ramp to rate over ramp_time; 'table': offset + the spline through file", &
      & choices='sine spinup table')
    call t%add('offset', g%offset, 'm or rad', 'constant part', ge=-big_length, le=big_length)
    call t%add('amplitude', g%amplitude, 'm or rad', 'amplitude of the sine', ge=-big_length, le=big_length)
    call t%add('frequency', g%frequency, 'Hz', 'frequency of the sine', ge=0.0_dp, le=1.0e6_dp)
    call t%add('phase', g%phase, 'rad', 'phase of the sine', ge=-1.0e3_dp, le=1.0e3_dp)
    call t%add('rate', g%rate, 'm/s or rad/s', "final rate of form 'spinup'", ge=-big_length, le=big_length)
    call t%add('ramp_time', g%ramp_time, 's', "ramp time of form 'spinup'", gt=0.0_dp, le=1.0e9_dp)
    call t%add('file', g%file, "file of 'time value' lines (form 'table'; relative to the scene's folder)", &
      & scene_file=.true.)
  end subroutine describe_motion

  subroutine describe_load(g, t)
    type(load_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('marker', g%marker, 'the marker the load acts at (required)')
    call t%add('direction', g%direction, '-', "direction of the load, in the frame given by frame " // &
      & '(required; made unit)', ge=-big_length, le=big_length)
    call t%add('kind', g%kind, "'force': a force at the marker's point; 'torque': a moment on the marker's " // &
      & "body (on a flexible body through the rotation of the marker's frame)", choices='force torque')
    call t%add('frame', g%frame, "'body': direction fixed in the marker's body (a follower load); 'inertial': " // &
      & 'direction fixed in the inertial frame', choices='body inertial')
    call t%add('form', g%form, "'pulse': peak sin(pi (t - start)/duration) from start to start + duration; " // &
      & "'constant': offset; 'sine': offset + amplitude sin(2 pi frequency t + phase); 'table': offset + " // &
      & 'the history in file, interpolated linearly', choices='pulse constant sine table')
    call t%add('peak', g%peak, 'N or N m', "peak of the pulse (form 'pulse')", ge=-big_force, le=big_force)
    call t%add('start', g%start, 's', "start time of the pulse (form 'pulse')", ge=-1.0e9_dp, le=1.0e9_dp)
    call t%add('duration', g%duration, 's', "length of the pulse (form 'pulse': required)", gt=0.0_dp, le=1.0e9_dp)
    call t%add('offset', g%offset, 'N or N m', "the constant load (forms 'constant', 'sine' and 'table')", &
      & ge=-big_force, le=big_force)
    call t%add('amplitude', g%amplitude, 'N or N m', 'amplitude of the sine', ge=-big_force, le=big_force)
    call t%add('frequency', g%frequency, 'Hz', 'frequency of the sine', ge=0.0_dp, le=1.0e6_dp)
    call t%add('phase', g%phase, 'rad', 'phase of the sine', ge=-1.0e3_dp, le=1.0e3_dp)
    call t%add('file', g%file, "file of 'time value' lines (form 'table'; relative to the scene's folder)", &
      & scene_file=.true.)
  end subroutine describe_load

  subroutine describe_marker(g, t)
    type(marker_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('name', g%name, 'name of the marker, unique among the markers (required)')
    call t%add('body', g%body, 'the body the marker is fixed to (required)')
    call t%add('at', g%at, 'm', "the point in the body's frame", ge=-big_length, le=big_length)
  end subroutine describe_marker

  subroutine describe_sensor(g, t)
    type(sensor_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('name', g%name, "name of the sensor, unique among the sensors and the markers: its columns are " // &
      & "NAME.d, NAME.d_dot ('distance') or NAME.x, .y, .z, .vx, .vy, .vz ('position') (required)")
    call t%add('kind', g%kind, "'distance': the distance from marker to marker to (m) and its rate (m/s); " // &
      & "'position': marker's position from the origin of body frame and its velocity relative to that body, " // &
      & "both in the body's axes (m, m/s) (required)", choices='distance position')
    call t%add('marker', g%marker, 'the marker measured (required)')
    call t%add('to', g%to, "kind 'distance': the other marker, another than marker (required for it)")
    call t%add('frame', g%frame, "kind 'position': the body in whose frame the marker is measured (its " // &
      & 'reference frame, for a flexible body) (required for it)')
  end subroutine describe_sensor

  subroutine describe_force(g, t)
    type(force_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('name', g%name, 'name of the force element, unique among them (required)')
    call t%add('kind', g%kind, "'spring_damper' (a force along the line from marker i to marker j: " // &
      & "stiffness (length - free_length) + damping d(length)/dt, pulling them together when positive) or " // &
      & "'bushing' (forces and moments on the displacement of marker j from marker i in marker i's axes and " // &
      & "on the rotation vector of j's frame from i's, and on their rates) (required)", &
      & choices='spring_damper bushing')
    call t%add('marker_i', g%marker_i, 'the first marker (a bushing acts in its axes) (required)')
    call t%add('marker_j', g%marker_j, 'the second marker, another than marker_i (required)')
    call t%add('stiffness', g%stiffness, 'N/m, N m/rad', "'spring_damper': one value (N/m); 'bushing': six, " // &
      & "translations x, y, z (N/m) then rotations about x, y, z (N m/rad) (required, but for a 'spring_damper' " // &
      & 'with a file)', ge=0.0_dp, le=big_force, variable=.true.)
    call t%add('damping', g%damping, 'N s/m, N m s/rad', "as many values as stiffness, on the rates " // &
      & '(default 0)', ge=0.0_dp, le=big_force, variable=.true.)
    call t%add('free_length', g%free_length, 'm', "length at which a 'spring_damper' is relaxed (required " // &
      & 'for it)', ge=0.0_dp, le=big_length)
    call t%add('file', g%file, "a nonlinear 'spring_damper': file of 'deflection force' lines (m, length - " // &
      & 'free_length, negative in compression; N, positive in tension), interpolated linearly and continued by ' // &
      & "its end segments' lines; in place of stiffness (relative to the scene's folder)", scene_file=.true.)
  end subroutine describe_force

  subroutine describe_control(g, t)
    type(control_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('name', g%name, 'name of the controller, unique among them (required)')
    call t%add('joint', g%joint, 'the joint whose coordinate the controller drives (required)')
    call t%add('coordinate', g%coordinate, '-', 'which coordinate of the joint', ge=1, le=6)
    call t%add('sensor', g%sensor, "'coordinate': the driven coordinate and its rate; 'orientation': the " // &
      & "inertial rotation of marker's frame about axis and its rate (a rate gyro)", choices='coordinate orientation')
    call t%add('marker', g%marker, "the marker whose frame sensor 'orientation' measures")
    call t%add('axis', g%axis, '-', "inertial axis of sensor 'orientation' (made unit)", ge=-big_length, le=big_length)
    call t%add('kp', g%kp, 'N/m or N m/rad', 'proportional gain (effort per unit error)', ge=0.0_dp, le=big_force)
    call t%add('ki', g%ki, 'N/(m s) or N m/(rad s)', 'integral gain (effort per unit integral of the error)', &
      & ge=0.0_dp, le=big_force)
    call t%add('kd', g%kd, 'N s/m or N m s/rad', 'derivative gain (effort per unit rate, on the measured rate)', &
      & ge=0.0_dp, le=big_force)
    call t%add('setpoint', g%setpoint, 'm or rad', 'the setpoint (with file: added to the history)', &
      & ge=-big_length, le=big_length)
    call t%add('file', g%file, "file of 'time value' lines: the setpoint's history, interpolated linearly " // &
      & "(relative to the scene's folder)", scene_file=.true.)
    call t%add('max_effort', g%max_effort, 'N or N m', 'the largest |effort| (default: no limit)', &
      & gt=0.0_dp, le=big_force)
  end subroutine describe_control

  subroutine describe_moving_load(g, t)
    type(moving_load_spec), target, intent(inout) :: g
    type(item_table), intent(inout) :: t
    call t%add('name', g%name, 'name of the moving load, unique among them (required)')
    call t%add('body', g%body, "the beam it travels along, on its x axis (a body of kind 'beam') (required)")
    call t%add('mass', g%mass, 'kg', 'the travelling point mass (its inertia, Coriolis and centripetal terms ' // &
      & 'and its weight under gravity)', ge=0.0_dp, le=big_mass)
    call t%add('force', g%force, 'N', "a force at the travelling point, in the beam's body axes", &
      & ge=-big_force, le=big_force)
    call t%add('form', g%form, "the travel: 'constant_speed' (at s0 until start, then s0 + speed (t - start)) " // &
      & "or 'table' (the natural cubic spline through the positions in file; the first before its first time, " // &
      & 'the last rate after its last)', choices='constant_speed table')
    call t%add('start', g%start, 's', "time the travel starts (form 'constant_speed')", ge=-1.0e9_dp, le=1.0e9_dp)
    call t%add('s0', g%s0, 'm', "position on the axis before and at start (form 'constant_speed'; " // &
      & '0 <= s0 <= the length)', ge=-big_length, le=big_length)
    call t%add('speed', g%speed, 'm/s', "speed along the axis after start (form 'constant_speed'; not 0)", &
      & ge=-1.0e6_dp, le=1.0e6_dp)
    call t%add('file', g%file, "file of 'time position' lines (form 'table'; relative to the scene's folder)", &
      & scene_file=.true.)
  end subroutine describe_moving_load

  !> Defaults that depend on other items, set once the scene is read: a joint's q0 and qd0
  !> default to 0 for each of its coordinates; one step serves both rates, and at one rate a
  !> --set of h_slow alone sets the step.
  subroutine complete_scene(sc)
    type(scene_t), intent(inout) :: sc
    integer :: j, n
    do j = 1, size(sc%joints)
      n = max(joint_ndof(sc%joints(j)%kind), 0)
      where (sc%joints(j)%q0(1:n) == unset) sc%joints(j)%q0(1:n) = 0.0_dp
      where (sc%joints(j)%qd0(1:n) == unset) sc%joints(j)%qd0(1:n) = 0.0_dp
    end do
    ! one step given: it serves both rates
    if (sc%integrator%h_fast == unset) sc%integrator%h_fast = sc%integrator%h_slow
    ! at one rate h_slow is the step: a --set of it alone sets both
    associate(o => sc%integrator%origin)
      if (sc%integrator%method /= 'multirate' .and. o%given('h_slow') .and. o%line_of('h_slow') < 0 .and. &
        & .not. (o%given('h_fast') .and. o%line_of('h_fast') < 0)) sc%integrator%h_fast = sc%integrator%h_slow
    end associate
    if (sc%integrator%h_slow == unset) sc%integrator%h_slow = sc%integrator%h_fast
    if (len_trim(sc%integrator%formula) == 0) then
      sc%integrator%formula = merge('adams', 'abm4 ', sc%integrator%adaptive .and. sc%integrator%method /= 'multirate')
    end if
    ! the paper's formula is of order 4 (a scene written back states it)
    if (sc%integrator%formula == 'abm4' .and. .not. sc%integrator%origin%given('order')) sc%integrator%order = 4
  end subroutine complete_scene

  !> Index of the body called `name`, 0 if none.
  pure integer function body_index(sc, name)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: name
    body_index = findloc(sc%bodies%name, name, dim=1)
  end function body_index

  !> Joint j closes a loop: an earlier joint already gives its child a parent (the first
  !> joint naming a body as child is its tree joint; the later ones are cut joints).
  pure logical function closes_loop(sc, j)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: j
    closes_loop = any(sc%joints(1:j - 1)%child == sc%joints(j)%child) .and. sc%joints(j)%child /= sc%joints(j)%parent
  end function closes_loop

  !> A closed loop passes through a flexible body: one of the bodies on the tree paths from
  !> a cut joint's two bodies up to their common ancestor (that one included) is a beam or
  !> a modal body. Paths stop at a body without a tree joint, or after as many steps as
  !> there are bodies (the scene's rules judge a malformed tree).
  pure logical function flexible_loop(sc)
    type(scene_t), intent(in) :: sc
    character(len=name_len) :: up_a(size(sc%bodies) + 1), up_b(size(sc%bodies) + 1)
    integer :: j, na, nb, i
    flexible_loop = .false.
    do j = 1, size(sc%joints)
      if (.not. closes_loop(sc, j)) cycle
      call path_up(sc%joints(j)%parent, up_a, na)
      call path_up(sc%joints(j)%child, up_b, nb)
      do i = 1, na
        if (flexible(up_a(i))) flexible_loop = .true.
        if (any(up_b(1:nb) == up_a(i))) exit
      end do
      do i = 1, nb
        if (any(up_a(1:na) == up_b(i))) exit
        if (flexible(up_b(i))) flexible_loop = .true.
      end do
      if (flexible_loop) return
    end do
  contains
    !> The body and its tree ancestors, nearest first.
    pure subroutine path_up(body, up, n)
      character(len=*), intent(in) :: body
      character(len=name_len), intent(out) :: up(:)
      integer, intent(out) :: n
      integer :: k
      n = 1; up(1) = body
      do while (n < size(up))
        k = findloc(sc%joints%child, up(n), dim=1)
        if (k == 0) exit
        n = n + 1; up(n) = sc%joints(k)%parent
      end do
    end subroutine path_up
    pure logical function flexible(body)
      character(len=*), intent(in) :: body
      integer :: k
      k = body_index(sc, body)
      flexible = .false.
      if (k > 0) flexible = sc%bodies(k)%kind == 'beam' .or. sc%bodies(k)%kind == 'modal'
    end function flexible
  end function flexible_loop

  !> The items a body of each kind takes ('' for an unknown kind: no rule).
  pure function body_items(kind) result(s)
    character(len=*), intent(in) :: kind
    character(len=:), allocatable :: s
    select case (trim(kind))
    case ('ground'); s = 'name kind'
    case ('rigid'); s = 'name kind mass com inertia'
    case ('beam')
      s = 'name kind length youngs_modulus density r_outer r_inner area iy iz n_elements modes_y modes_z ' // &
        & 'modes_x modes_t shear_modulus torsion_constant modal_damping rayleigh_alpha rayleigh_beta a0 ad0'
    case ('modal'); s = 'name kind modal_file modal_damping rayleigh_alpha rayleigh_beta a0 ad0'
    case default; s = ''
    end select
  end function body_items

  !> Modal coordinates of a beam: its bending, axial and torsional modes.
  pure integer function beam_mode_count(b) result(m)
    type(body_spec), intent(in) :: b
    m = b%modes_y + b%modes_z + b%modes_x + b%modes_t
  end function beam_mode_count

  !> The items a sensor of each kind takes ('' for an unknown kind: no rule).
  pure function sensor_items(kind) result(s)
    character(len=*), intent(in) :: kind
    character(len=:), allocatable :: s
    select case (trim(kind))
    case ('distance'); s = 'name kind marker to'
    case ('position'); s = 'name kind marker frame'
    case default; s = ''
    end select
  end function sensor_items

  !> Does `item` apply to occurrence k of group `name`? (A body takes its kind's items, and
  !> so does a sensor.)
  logical function item_applies(sc, name, k, item)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: name, item
    integer, intent(in) :: k
    character(len=:), allocatable :: takes
    item_applies = .true.
    if (name == 'sensor') then
      takes = sensor_items(sc%sensors(k)%kind)
    else if (name == 'body') then
      takes = body_items(sc%bodies(k)%kind)
    else
      return
    end if
    if (len(takes) > 0) item_applies = index(' ' // takes // ' ', ' ' // trim(item) // ' ') > 0
  end function item_applies

  ! ------------------------------------------------------------ groups by their names

  !> The table of occurrence k of group `name` in `sc` (the records must exist); with
  !> `only`, the table of that one item (empty if the group has no such item).
  subroutine describe_group(sc, name, k, t, only)
    type(scene_t), target, intent(inout) :: sc
    character(len=*), intent(in) :: name
    integer, intent(in) :: k
    type(item_table), intent(out) :: t
    character(len=*), intent(in), optional :: only
    if (present(only)) t%only = only
    select case (name)
    case ('scene'); call describe_scene(sc%scene, t)
    case ('integrator'); call describe_integrator(sc%integrator, t)
    case ('effects'); call describe_effects(sc%effects, t)
    case ('output'); call describe_output(sc%output, t)
    case ('body'); call describe_body(sc%bodies(k), t)
    case ('joint'); call describe_joint(sc%joints(k), t)
    case ('drive'); call describe_drive(sc%drives(k), t)
    case ('spring'); call describe_spring(sc%springs(k), t)
    case ('motion'); call describe_motion(sc%motions(k), t)
    case ('load'); call describe_load(sc%loads(k), t)
    case ('marker'); call describe_marker(sc%markers(k), t)
    case ('force'); call describe_force(sc%forces(k), t)
    case ('control'); call describe_control(sc%controls(k), t)
    case ('moving_load'); call describe_moving_load(sc%moving_loads(k), t)
    case ('sensor'); call describe_sensor(sc%sensors(k), t)
    end select
  end subroutine describe_group

  !> The origin record of occurrence k of group `name`.
  function group_origin(sc, name, k) result(o)
    type(scene_t), target, intent(inout) :: sc
    character(len=*), intent(in) :: name
    integer, intent(in) :: k
    type(origin_t), pointer :: o
    o => null()
    select case (name)
    case ('scene'); o => sc%scene%origin
    case ('integrator'); o => sc%integrator%origin
    case ('effects'); o => sc%effects%origin
    case ('output'); o => sc%output%origin
    case ('body'); o => sc%bodies(k)%origin
    case ('joint'); o => sc%joints(k)%origin
    case ('drive'); o => sc%drives(k)%origin
    case ('spring'); o => sc%springs(k)%origin
    case ('motion'); o => sc%motions(k)%origin
    case ('load'); o => sc%loads(k)%origin
    case ('marker'); o => sc%markers(k)%origin
    case ('force'); o => sc%forces(k)%origin
    case ('control'); o => sc%controls(k)%origin
    case ('moving_load'); o => sc%moving_loads(k)%origin
    case ('sensor'); o => sc%sensors(k)%origin
    end select
  end function group_origin

  !> How many occurrences of group `name` the scene holds.
  integer function group_count(sc, name) result(n)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: name
    select case (name)
    case ('body'); n = size(sc%bodies)
    case ('joint'); n = size(sc%joints)
    case ('drive'); n = size(sc%drives)
    case ('spring'); n = size(sc%springs)
    case ('motion'); n = size(sc%motions)
    case ('load'); n = size(sc%loads)
    case ('marker'); n = size(sc%markers)
    case ('force'); n = size(sc%forces)
    case ('control'); n = size(sc%controls)
    case ('moving_load'); n = size(sc%moving_loads)
    case ('sensor'); n = size(sc%sensors)
    case default; n = 1
    end select
  end function group_count

  !> The item that names an occurrence of a repeated group (and selects it in --set
  !> GROUP[NAME].ITEM=...): 'name', or for groups that act on something, that thing.
  pure function naming_item(name) result(item)
    character(len=*), intent(in) :: name
    character(len=:), allocatable :: item
    select case (name)
    case ('drive', 'spring', 'motion'); item = 'joint'
    case ('load'); item = 'marker'
    case ('body', 'joint', 'marker', 'force', 'control', 'moving_load', 'sensor'); item = 'name'
    case default; item = ''
    end select
  end function naming_item

  !> The controllers the model builds: each &control when &effects controls is on (each
  !> owns a state coordinate, after the joint coordinates).
  pure integer function control_count(sc)
    type(scene_t), intent(in) :: sc
    control_count = 0
    if (sc%effects%controls) control_count = size(sc%controls)
  end function control_count

  !> Number of coordinates of a joint kind (-1 for an unknown kind).
  pure function joint_ndof(kind) result(n)
    character(len=*), intent(in) :: kind
    integer :: n
    select case (trim(kind))
    case ('revolute', 'prismatic'); n = 1
    case ('fixed'); n = 0
    case ('cylindrical', 'universal'); n = 2
    case ('spherical', 'planar'); n = 3
    case ('free'); n = 6
    case default; n = -1
    end select
  end function joint_ndof
end module pymr_model_scene
