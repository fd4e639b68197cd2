!> The scene as read from a namelist file: plain data, validated, not yet a model.
module pymr_model_scene
  use pymr_kinds, only : dp, name_len
  implicit none
  private
  public :: scene_t, body_spec, joint_spec, drive_spec, marker_spec, integrator_spec, effects_spec
  public :: spring_spec, motion_spec, load_spec, max_modes_input
  public :: joint_ndof, unset

  !> Marker for "item not given" in real-valued namelist items.
  real(dp), parameter :: unset = -huge(1.0_dp)
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
    !> Refuse fixed steps that the pre-flight check finds unstable (.false.: run anyway).
    logical :: stability_check = .true.
    !> Multirate coupling of the fast substeps: 'full' (the paper's) or 'split'.
    character(len=16) :: coupling = 'split'
  end type integrator_spec

  !> Optional physics (&effects); every effect is off unless turned on. `given` records
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
    !> Fidelity of the deformation-dependent inertia of flexible bodies: 'full' or 'linear'.
    character(len=16) :: deformation_inertia = 'full'
    logical :: given_firing_load = .false.
    logical :: given_joint_drives = .false., given_modal_damping = .false., given_joint_springs = .false.
    logical :: given_base_motion = .false.
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
    !> area (m^2) and second moments iy, iz (m^4), elements, modes per plane.
    real(dp) :: length = unset, youngs_modulus = unset, density = unset
    real(dp) :: r_outer = unset, r_inner = 0.0_dp, area = unset, iy = unset, iz = unset
    integer :: n_elements = 20, modes_y = 0, modes_z = 0
    !> Modal damping (used when &effects modal_damping is on): fraction of critical, one
    !> value for every mode or one per mode; or Rayleigh damping alpha + beta omega^2 (1/s).
    real(dp) :: modal_damping(max_modes_input) = unset
    real(dp) :: rayleigh_alpha = 0.0_dp, rayleigh_beta = 0.0_dp
    !> Modal data file of a 'modal' body (relative to the scene file's folder).
    character(len=512) :: modal_file = ''
    !> Line of the group in the file (for messages).
    integer :: line = 0
  end type body_spec

  !> One &joint group.
  type :: joint_spec
    character(len=name_len) :: name = '', parent = '', child = ''
    !> 'revolute', 'prismatic', 'fixed', 'spherical', 'free'.
    character(len=16) :: kind = ''
    !> Joint point in the parent frame (m) and axis in the parent frame.
    real(dp) :: at(3) = 0.0_dp, axis(3) = [0.0_dp, 0.0_dp, 1.0_dp]
    !> Initial coordinates and rates (as many as the joint has).
    real(dp) :: q0(6) = 0.0_dp, qd0(6) = 0.0_dp
    integer :: line = 0
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
    integer :: line = 0
  end type drive_spec

  !> One &spring group: a spring-damper on a joint coordinate,
  !> force = -stiffness (q - free_position) - damping qd.
  type :: spring_spec
    character(len=name_len) :: joint = ''
    integer :: coordinate = 1
    real(dp) :: stiffness = 0.0_dp, damping = 0.0_dp, free_position = 0.0_dp
    integer :: line = 0
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
    integer :: line = 0
  end type motion_spec

  !> One &load group: a force at a marker along `direction` (body frame of the marker's
  !> body), of magnitude peak sin(pi (t - start)/duration) for start <= t <= start + duration
  !> (form 'pulse'), zero outside.
  type :: load_spec
    character(len=name_len) :: marker = ''
    real(dp) :: direction(3) = 0.0_dp
    character(len=16) :: form = 'pulse'
    real(dp) :: peak = 0.0_dp, start = 0.0_dp, duration = unset
    integer :: line = 0
  end type load_spec

  !> One &marker group: a point of a body whose motion is written out.
  type :: marker_spec
    character(len=name_len) :: name = '', body = ''
    real(dp) :: at(3) = 0.0_dp
    integer :: line = 0
  end type marker_spec

  !> The whole scene.
  type :: scene_t
    !> File the scene came from (for messages).
    character(len=:), allocatable :: file
    character(len=256) :: title = ''
    !> End time (s) and gravity (m/s^2, inertial frame).
    real(dp) :: t_end = unset, gravity(3) = [0.0_dp, -9.81_dp, 0.0_dp]
    type(integrator_spec) :: integrator
    type(effects_spec) :: effects
    type(body_spec), allocatable :: bodies(:)
    type(joint_spec), allocatable :: joints(:)
    type(drive_spec), allocatable :: drives(:)
    type(spring_spec), allocatable :: springs(:)
    type(motion_spec), allocatable :: motions(:)
    type(load_spec), allocatable :: loads(:)
    type(marker_spec), allocatable :: markers(:)
    !> CSV output file and output interval (s; 0 = every slow step).
    character(len=512) :: output_file = ''
    real(dp) :: output_dt = 0.0_dp
    !> Checkpoints every checkpoint_dt s of simulated time (0: none), to checkpoint_file
    !> (default: the CSV path with .ckpt).
    real(dp) :: checkpoint_dt = 0.0_dp
    character(len=512) :: checkpoint_file = ''
  end type scene_t

contains

  !> Number of coordinates of a joint kind (-1 for an unknown kind).
  pure function joint_ndof(kind) result(n)
    character(len=*), intent(in) :: kind
    integer :: n
    select case (trim(kind))
    case ('revolute', 'prismatic'); n = 1
    case ('fixed'); n = 0
    case ('spherical'); n = 3
    case ('free'); n = 6
    case default; n = -1
    end select
  end function joint_ndof
end module pymr_model_scene
