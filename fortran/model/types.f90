!> The model's data: the body tree in parent-before-child order, its coordinates, the
!> effect plan and the work arrays of one evaluation (allocated once at build).
module pymr_model_types
  use pymr_env_kinds, only : dp, name_len
  use pymr_model_flexbody, only : flex_data, flex_work, modal_nodes
  use pymr_model_beam_modes, only : beam_shape
  use pymr_model_time_table, only : time_table
  implicit none
  private
  public :: model_data, prim_revolute, prim_prismatic
  public :: effect_gravity, effect_joint_drives, effect_modal_damping, effect_joint_springs
  public :: effect_geometric_stiffening, effect_base_motion, effect_firing_load, effect_deformation_inertia
  public :: n_effects, effect_names
  public :: motion_sine, motion_spinup, motion_table
  public :: cut_fixed, cut_revolute, cut_spherical, cut_prismatic, cut_free

  !> Kinds of one-coordinate joint primitives: every joint is a chain of them.
  integer, parameter :: prim_revolute = 1, prim_prismatic = 2

  !> Effect identifiers (index into counters and names).
  integer, parameter :: effect_gravity = 1, effect_joint_drives = 2, effect_modal_damping = 3, &
    & effect_joint_springs = 4, effect_geometric_stiffening = 5, effect_firing_load = 6, effect_base_motion = 7, &
    & effect_deformation_inertia = 8, n_effects = 8
  character(len=*), parameter :: effect_names(n_effects) = [character(len=20) :: 'gravity', 'joint_drives', &
    & 'modal_damping', 'joint_springs', 'geometric_stiffening', 'firing_load', 'base_motion', 'deformation_inertia']

  !> Kinds of loop-closing joints ('free' closes no constraint: no rows).
  integer, parameter :: cut_fixed = 1, cut_revolute = 2, cut_spherical = 3, cut_prismatic = 4, cut_free = 5

  !> Forms of a prescribed coordinate's time function.
  integer, parameter :: motion_sine = 1, motion_spinup = 2, motion_table = 3

  !> Everything one model evaluation needs.
  type :: model_data
    !> Bodies (1 = ground), coordinates (joint coordinates 1..nj first, then modal ones),
    !> the largest number of modes of one body.
    integer :: nb = 0, n = 0, nj = 0, mmax = 0
    character(len=name_len), allocatable :: body_name(:), joint_name(:)
    !> Parent body, first coordinate and number of coordinates of each body's inboard joint.
    integer, allocatable :: parent(:), c0(:), nc(:)
    !> Mass (kg), centre of mass (body frame, m), inertia about the centre of mass (body axes).
    real(dp), allocatable :: mass(:), com(:, :), inertia(:, :, :)
    !> Joint point (parent frame, m).
    real(dp), allocatable :: at(:, :)
    !> Flexible bodies: flag, modes of each body and index of its first modal coordinate.
    logical, allocatable :: flexible(:)
    integer, allocatable :: nm(:), a0(:)
    !> Children of each body: child_idx(child_ptr(b):child_ptr(b+1)-1).
    integer, allocatable :: child_ptr(:), child_idx(:)
    !> Output group of each coordinate (the joint's body, or nb + body for modal ones).
    integer, allocatable :: cgrp(:)
    !> Invariants, evaluation work and (beams) mode shapes of each flexible body.
    type(flex_data), allocatable :: flex(:)
    type(flex_work), allocatable :: fwork(:)
    type(beam_shape), allocatable :: bshape(:)
    type(modal_nodes), allocatable :: mnodes(:)
    !> Mode shapes of the parent at each body's joint point: translation, rotation (3, mmax, nb).
    real(dp), allocatable :: att_psi(:, :, :), att_phi(:, :, :)
    !> Spatial columns of the parent's modal rates at each body's joint point (6, mmax, nb).
    real(dp), allocatable :: cm(:, :, :)
    !> Flexible bodies' coupling columns (6, mmax, nb) and modal bias forces (mmax, nb).
    real(dp), allocatable :: mva(:, :, :), wam(:, :)
    !> Per coordinate: primitive kind, axis in the frame before the primitive, owning body.
    integer, allocatable :: prim(:), cbody(:)
    real(dp), allocatable :: axis(:, :)
    !> Coordinate names for output (joint.q, joint.q1, ...).
    character(len=name_len+4), allocatable :: qname(:), qdname(:)
    !> Markers: body and point (body frame).
    integer :: n_markers = 0
    character(len=name_len), allocatable :: marker_name(:)
    integer, allocatable :: marker_body(:)
    real(dp), allocatable :: marker_at(:, :)
    !> Mode shapes at markers on flexible bodies: translation and small rotation (3, mmax, n_markers).
    real(dp), allocatable :: marker_psi(:, :, :), marker_phi(:, :, :)
    !> Effect plan: which effects are on, the active ones in evaluation order, their
    !> evaluation counters, and their CPU time measured on every 32nd evaluation
    !> (effect_cpu over effect_timed evaluations).
    logical :: effect_on(n_effects) = .false.
    integer :: n_plan = 0, plan(n_effects) = 0
    integer :: effect_evals(n_effects) = 0, effect_timed(n_effects) = 0
    real(dp) :: effect_cpu(n_effects) = 0.0_dp
    !> Every body (the mask of a full evaluation).
    logical, allocatable :: every(:)
    !> Joint springs: coordinate, stiffness, damping, free position.
    integer :: n_springs = 0
    integer, allocatable :: spring_coord(:)
    real(dp), allocatable :: spring_par(:, :)
    !> Point loads: marker, direction (body frame, unit), peak (N), start and duration (s).
    integer :: n_loads = 0
    integer, allocatable :: load_marker(:)
    real(dp), allocatable :: load_dir(:, :), load_par(:, :)
    !> Prescribed coordinates: coordinate, form and parameters (offset, amplitude,
    !> frequency, phase, rate, ramp time); work copies of q and qd with them imposed.
    integer :: n_prescribed = 0
    integer, allocatable :: pres_coord(:), pres_form(:)
    real(dp), allocatable :: pres_par(:, :), qx(:), qdx(:)
    !> Tabulated histories, and the table of each drive and prescribed coordinate (0: none).
    type(time_table), allocatable :: tables(:)
    integer, allocatable :: drive_table(:), pres_table(:)
    !> Bodies jointed to a beam with geometric stiffness, and the beam's geometric stiffness
    !> per newton of the axial load such a body puts on it (mmax, mmax, nb).
    logical, allocatable :: child_kg(:)
    real(dp), allocatable :: kgc(:, :, :)
    !> Gravity (m/s^2, inertial).
    real(dp) :: gravity(3) = 0.0_dp
    !> Drives: coordinate and offset, amplitude, frequency (Hz), phase (rad).
    integer :: n_drives = 0
    integer, allocatable :: drive_coord(:)
    real(dp), allocatable :: drive_par(:, :)
    !> Kinematic state of one evaluation (inertial frame).
    real(dp), allocatable :: rot(:, :, :), pos(:, :), vel(:, :), acc(:, :), s(:, :)
    !> Spatial inertia, bias wrench, composite inertia and composite wrench per body.
    real(dp), allocatable :: i6(:, :, :), w(:, :), ic(:, :, :), wc(:, :)
    !> Mass matrix, its Cholesky factor, right-hand side, generalised applied forces.
    real(dp), allocatable :: mm(:, :), lf(:, :), p(:), tau(:)
    !> Per coordinate: prescribed by a &motion (base_motion on).
    logical, allocatable :: prescribed(:)
    !> Forward dynamics by the articulated-body algorithm (model/articulated.f90) instead of
    !> assembling and factoring M, and its work: per body the articulated inertia and bias
    !> after its joint, per joint column u/D and r/D (u = IA s, D = s . u, r = tau - s . pA),
    !> the part of the acceleration linear in qdd, and a flexible body's factored K_aa, K_Aa
    !> and b_a.
    logical :: articulated = .false.
    real(dp), allocatable :: ab_ia(:, :, :), ab_pa(:, :), ab_u(:, :, :), ab_r(:, :), ab_lin(:, :)
    real(dp), allocatable :: ab_kaa(:, :, :), ab_kam(:, :, :), ab_ba(:, :)
    !> Bodies on or below a flexible body (whose terms the fast rows need).
    logical, allocatable :: in_fast(:)
    !> Loop-closing (cut) joints (model/loops.f90): name, parent and child body, kind
    !> (cut_fixed, cut_revolute, cut_spherical, cut_prismatic, cut_free), joint point in the
    !> parent's and in the child's frame, and a revolute joint's axis and two unit normals of
    !> it (parent frame); their first constraint row and number of rows (3 for the point, + 3
    !> fixed, + 2 revolute; prismatic 2 + 3; free none).
    integer :: n_cut = 0, n_rows = 0
    character(len=name_len), allocatable :: cut_name(:)
    integer, allocatable :: cut_parent(:), cut_child(:), cut_kind(:), cut_row0(:), cut_nrow(:)
    real(dp), allocatable :: cut_at(:, :), cut_child_at(:, :), cut_axis(:, :), cut_normal(:, :, :)
    !> Mode shapes at a cut joint's points on flexible bodies (side 1 the parent's point, 2 the
    !> child's): translation and small rotation (3, mmax, 2, n_cut).
    real(dp), allocatable :: cut_psi(:, :, :, :), cut_phi(:, :, :, :)
    !> The frames at the cut joints' points (after forward_kinematics; side 1 the parent's, 2
    !> the child's): orientation, origin, spatial velocity and bias acceleration (inertial
    !> Pluecker), and the spatial columns of a flexible body's own modal rates there (6, mmax,
    !> 2, n_cut). On a rigid body the frame is the body's, moved to the point; on a flexible
    !> one it moves and turns with the deflection there, as a child's joint frame does.
    real(dp), allocatable :: cut_rot(:, :, :, :), cut_pos(:, :, :), cut_vel(:, :, :), cut_acc(:, :, :)
    real(dp), allocatable :: cut_cm(:, :, :, :)
    !> The independent rows (chosen once, at assembly) and how many were redundant.
    integer :: n_used = 0, n_redundant = 0
    logical :: rows_chosen = .false.
    integer, allocatable :: row_used(:)
    !> Constraint residual Phi, Jacobian G (n_rows, n), gamma = -Gdot qd, the multipliers
    !> of the last evaluation (0 on redundant rows), and M^-1 G^T of the used rows.
    real(dp), allocatable :: phi(:), gj(:, :), gam(:), lambda(:), ymg(:, :)
    !> Assembly of the initial state: the largest change of a coordinate and of a rate.
    real(dp) :: assembly_dq = 0.0_dp, assembly_dqd = 0.0_dp
    !> The largest constraint residual a projection after a step removed (m; rad for rotation rows).
    real(dp) :: closure_drift = 0.0_dp
    !> The loops' size (m): the farthest body origin or cut joint point from the origin.
    real(dp) :: loop_size = 1.0_dp
    !> Evaluation counters: full assemblies, fast-row assemblies.
    integer :: evals = 0, evals_fast_rows = 0
  end type model_data
end module pymr_model_types
