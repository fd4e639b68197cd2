!> The model's types: its definition (the body tree in parent-before-child order, its
!> coordinates, markers and cut joints; constant after build) apart from the work of its
!> evaluations (model_work, allocated once at build).
module pymr_model_types
  use pymr_env_kinds, only : dp, name_len
  use pymr_model_flexbody, only : flex_data, flex_work, modal_nodes
  use pymr_model_beam_modes, only : beam_shape
  implicit none
  private
  public :: model_data, model_work, model_counters, marker_set, cut_set, articulated_work, loop_work
  public :: prim_revolute, prim_prismatic
  public :: cut_fixed, cut_revolute, cut_spherical, cut_prismatic, cut_free, cut_cylindrical, cut_universal, cut_planar

  !> Kinds of one-coordinate joint primitives: every joint is a chain of them.
  integer, parameter :: prim_revolute = 1, prim_prismatic = 2

  !> Kinds of loop-closing joints ('free' closes no constraint: no rows).
  integer, parameter :: cut_fixed = 1, cut_revolute = 2, cut_spherical = 3, cut_prismatic = 4, cut_free = 5, &
    & cut_cylindrical = 6, cut_universal = 7, cut_planar = 8

  !> Markers: body and point (body frame), and on flexible bodies the mode shapes there:
  !> translation and small rotation (3, mmax, n).
  type :: marker_set
    integer :: n = 0
    character(len=name_len), allocatable :: name(:)
    integer, allocatable :: body(:)
    real(dp), allocatable :: at(:, :), psi(:, :, :), phi(:, :, :)
  end type marker_set

  !> Loop-closing (cut) joints (model/loops.f90): name, parent and child body, kind
  !> (cut_fixed, cut_revolute, cut_spherical, cut_prismatic, cut_free, cut_cylindrical,
  !> cut_universal, cut_planar), joint point in the parent's and in the child's frame, and
  !> the joint's axis and two unit normals of it (parent frame; a universal cut's first
  !> normal is its axis2, child frame); their first constraint row and number of rows (3 for
  !> the point, + 3 fixed, + 2 revolute, + 1 universal; prismatic 2 + 3; cylindrical 2 + 2;
  !> planar 1 + 2; free none). Mode shapes at the points on flexible
  !> bodies (side 1 the parent's point, 2 the child's): translation and small rotation
  !> (3, mmax, 2, n). The loops' size (m): the farthest body origin or cut joint point from
  !> the origin.
  type :: cut_set
    integer :: n = 0, n_rows = 0
    character(len=name_len), allocatable :: name(:)
    integer, allocatable :: parent(:), child(:), kind(:), row0(:), nrow(:)
    real(dp), allocatable :: at(:, :), child_at(:, :), axis(:, :), normal(:, :, :)
    real(dp), allocatable :: psi(:, :, :, :), phi(:, :, :, :)
  end type cut_set

  !> A model's definition: the body tree, its coordinates and markers and cut joints, fixed
  !> at build. The evaluations' work is apart (model_work); the effects are records in the
  !> model's list (model/effect.f90).
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
    !> Invariants and (beams) mode shapes of each flexible body.
    type(flex_data), allocatable :: flex(:)
    type(beam_shape), allocatable :: bshape(:)
    type(modal_nodes), allocatable :: mnodes(:)
    !> Mode shapes of the parent at each body's joint point: translation, rotation (3, mmax, nb).
    real(dp), allocatable :: att_psi(:, :, :), att_phi(:, :, :)
    !> Per coordinate: primitive kind, axis in the frame before the primitive, owning body.
    integer, allocatable :: prim(:), cbody(:)
    real(dp), allocatable :: axis(:, :)
    !> Coordinate names for output (joint.q, joint.q1, ..., a controller's
    !> control.double_integral and control.integral).
    character(len=name_len+16), allocatable :: qname(:), qdname(:)
    type(marker_set) :: markers
    type(cut_set) :: cuts
    !> Every body (the mask of a full evaluation); bodies on or below a flexible body
    !> (whose terms the fast rows need).
    logical, allocatable :: every(:), in_fast(:)
    !> Per coordinate: prescribed by a &motion (base_motion on); how many are.
    logical, allocatable :: prescribed(:)
    integer :: n_prescribed = 0
    !> The flexible bodies' modal moments follow their deformation (deformation_inertia 'full').
    logical :: deformed_moments = .false.
  end type model_data

  !> Evaluation counters: full assemblies, fast-row assemblies, and per effect of the
  !> model's list its name, its evaluations and its CPU time measured on every 32nd evaluation
  !> (effect_cpu over effect_timed evaluations).
  type :: model_counters
    integer :: evals = 0, evals_fast_rows = 0
    character(len=24), allocatable :: effect_name(:)
    integer, allocatable :: effect_evals(:), effect_timed(:)
    real(dp), allocatable :: effect_cpu(:)
  end type model_counters

  !> The articulated-body algorithm's work (model/articulated.f90): per body the
  !> articulated inertia and bias after its joint, per joint column u/D and r/D (u = IA s,
  !> D = s . u, r = tau - s . pA), the part of the acceleration linear in qdd, and a flexible
  !> body's factored K_aa, K_Aa and b_a.
  type :: articulated_work
    real(dp), allocatable :: ia(:, :, :), pa(:, :), u(:, :, :), r(:, :), lin(:, :)
    real(dp), allocatable :: kaa(:, :, :), kam(:, :, :), ba(:, :)
  end type articulated_work

  !> The loops' work (model/loops.f90). The frames at the cut joints' points (after
  !> forward_kinematics; side 1 the parent's, 2 the child's): orientation, origin, spatial
  !> velocity and bias acceleration (inertial Pluecker), and the spatial columns of a
  !> flexible body's own modal rates there (6, mmax, 2, n_cut). The independent rows (chosen
  !> once, at assembly) and how many were redundant. Constraint residual Phi, Jacobian G
  !> (n_rows, n), gamma = -Gdot qd, the multipliers of the last evaluation (0 on redundant
  !> rows), and M^-1 G^T of the used rows. The assembly's largest change of a coordinate and
  !> of a rate, and the largest residual a projection after a step removed (m; rad). The
  !> loops' size (m), set at assembly: the farthest body origin or cut joint point from the
  !> origin.
  type :: loop_work
    real(dp), allocatable :: rot(:, :, :, :), pos(:, :, :), vel(:, :, :), acc(:, :, :), cm(:, :, :, :)
    integer :: n_used = 0, n_redundant = 0
    logical :: rows_chosen = .false.
    integer, allocatable :: row_used(:)
    real(dp), allocatable :: residual(:), jac(:, :), gamma(:), lambda(:), ymg(:, :)
    real(dp) :: assembly_dq = 0.0_dp, assembly_dqd = 0.0_dp, closure_drift = 0.0_dp, size = 1.0_dp
  end type loop_work

  !> The work of one evaluation (allocated once at build).
  type :: model_work
    !> Kinematic state (inertial frame): orientation, origin, spatial velocity and bias
    !> acceleration, joint columns.
    real(dp), allocatable :: rot(:, :, :), pos(:, :), vel(:, :), acc(:, :), s(:, :)
    !> Spatial inertia, bias wrench, composite inertia and composite wrench per body.
    real(dp), allocatable :: i6(:, :, :), w(:, :), ic(:, :, :), wc(:, :)
    !> Mass matrix, its Cholesky factor, right-hand side, generalised applied forces.
    real(dp), allocatable :: mm(:, :), lf(:, :), p(:), tau(:)
    !> Copies of q and qd with the prescribed coordinates imposed.
    real(dp), allocatable :: qx(:), qdx(:)
    !> Flexible bodies' evaluation work.
    type(flex_work), allocatable :: fwork(:)
    !> Spatial columns of the parent's modal rates at each body's joint point (6, mmax, nb).
    real(dp), allocatable :: cm(:, :, :)
    !> Flexible bodies' coupling columns (6, mmax, nb) and modal bias forces (mmax, nb).
    real(dp), allocatable :: mva(:, :, :), wam(:, :)
    !> The diagonal of the modal stiffness the state adds to omega^2 (geometric stiffening;
    !> mmax, nb): zeroed with the body terms, set in the load stages, and frozen with omega^2
    !> in the fast response (model_force_response).
    real(dp), allocatable :: kam(:, :)
    !> Modal mass that loads travelling on flexible bodies add to their constant modal mass
    !> (mmax, mmax, nb; set in the load stage; unallocated when no effect adds any).
    real(dp), allocatable :: maa(:, :, :)
    type(articulated_work) :: ab
    type(loop_work) :: loops
    type(model_counters) :: count
  end type model_work
end module pymr_model_types
