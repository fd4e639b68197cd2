!> Closed loops. The tree stays the backbone; each loop-closing (cut) joint adds constraint
!> rows Phi(q) = 0 between a point of its parent (at, parent frame) and a point of its child
!> (child_at, child frame), written with the frames at the two points (p_p, R_p and p_c,
!> R_c): a rigid body's frame moved to its point, or on a flexible body the frame at the
!> deformed point (moved by Psi a, turned by exp((Phi a)~): kinematics.f90 flexible_frame,
!> the rule a child's tree joint follows too):
!>
!>   point     p_c - p_p = 0                              (3 rows, every kind but free)
!>   fixed     1/2 sum_j (R_p e_j) x (R_c e_j) = 0        (3 rows: the frames agree)
!>   revolute  (R_p n_i) . (R_c u) = 0, i = 1, 2          (2 rows: the axis u agrees)
!>   prismatic (R_p n_i) . (p_c - p_p) = 0, i = 1, 2       (2 rows instead of the point's 3:
!>             the child point slides along the axis), and the 3 rows of 'fixed'
!>   free      no rows (it closes no constraint and carries no force)
!>
!> The point and frame rows are taken along the parent's axes (the three rows turned by
!> R_p^T), as the axis and sliding rows already are: the rows chosen once stay independent
!> when the whole loop turns (a planar loop on a traversing turret keeps its plane's rows),
!> and their multipliers are the cut's force and moment in the parent's axes. With every
!> row used this is the same constraint (rows turned by an orthogonal matrix).
!>
!> Their Jacobian G comes from the recursive kinematics: the columns s_k on the path of a
!> body, and on a flexible body its own modal columns at the point (wk%loops%cm), give the
!> point frame's velocity v_O + w x p and angular velocity w, so G qd is the relative
!> velocity of the two points (and the relative angular velocity across the rotation rows),
!> and gamma = -Gdot qd follows from the frames' bias accelerations (wk%loops%acc, with the
!> modal velocity-product terms of a flexible point). The accelerations solve
!> M qdd = P + G^T lambda, G qdd = gamma through M's Cholesky factor. Dependent rows (a
!> planar loop of 3-D joints) are found once, at assembly, by a pivoted (rank-revealing)
!> Gram-Schmidt factorisation of G^T and dropped. A loop may pass through flexible bodies
!> (their modal columns at each child's joint enter G) and be cut at a point of one. The
!> cut's force acts at the deformed point; its modal share is G^T lambda in the modal rows.
module pymr_model_loops
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver, stat_input
  use pymr_env_lapack, only : potrf, potrs
  use pymr_model_types, only : model_data, model_work, cut_fixed, cut_revolute, cut_prismatic, cut_spherical, cut_free, &
    & cut_cylindrical, cut_universal, cut_planar
  use pymr_model_kinematics, only : forward_kinematics
  use pymr_model_spatial, only : cross, unit_axes
  use pymr_env_text, only : itoa, fmt
  implicit none
  private
  public :: assemble_loops, loop_rows, choose_rows, independent_rows, constrained_accelerations, project_positions
  public :: project_velocities, cut_wrench, cut_body_wrenches, constrain_fast_accelerations, constrain_response
  public :: constrain_inverse, loop_jacobian

  !> A row is dependent when its part independent of the rows chosen before is below this
  !> fraction of the largest row.
  real(dp), parameter :: rank_tol = 1.0e-8_dp
  !> Position projection: closure tolerance per metre of loop size, and most iterations.
  real(dp), parameter :: closure_tol = 1.0e-13_dp
  integer, parameter :: max_iterations = 30
  !> Assembly: the given state may miss closure by this fraction of the loops' size.
  real(dp), parameter :: assembly_tol = 1.0e-3_dp
  !> The sides of a cut joint (wk%loops%rot(:, :, side, c) and the like).
  integer, parameter :: parent = 1, child = 2

contains

  !> Assemble the initial state: choose the independent rows, then project the given q and
  !> qd onto the constraints (least change, recorded in wk%loops%assembly_dq, wk%loops%assembly_dqd),
  !> keeping the coordinates marked held. A state further than assembly_tol of the loops'
  !> size (m; rad) from closure is an error, and so are held coordinates that leave the
  !> loops too few others to close them.
  subroutine assemble_loops(d, wk, q, qd, held, error)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(inout) :: q(:), qd(:)
    logical, intent(in) :: held(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: q0(size(q)), qd0(size(qd))
    integer :: used(d%cuts%n_rows), n_free
    if (d%cuts%n_rows == 0) return
    call forward_kinematics(d, wk, q, 0.0_dp*q)
    call loop_rows(d, wk)
    call choose_rows(d, wk, error); if (allocated(error)) return
    call independent_rows(held_columns(free_columns(d, wk%loops%jac(wk%loops%row_used(1:wk%loops%n_used), :)), held), used, n_free)
    if (n_free < wk%loops%n_used) then
      call fatal_error(error, 'the joints held (hold = .true.) leave the loops ' // itoa(n_free) // ' of the ' // &
        & itoa(wk%loops%n_used) // ' independent constraints to close by the other coordinates', stat_input); return
    end if
    wk%loops%size = max(maxval(norm2(wk%pos, dim=1)), maxval(norm2(d%cuts%at, dim=1)), &
      & maxval(norm2(d%cuts%child_at, dim=1)), tiny(1.0_dp))
    if (maxval(abs(wk%loops%residual)) > assembly_tol*wk%loops%size) then
      call fatal_error(error, 'the initial state does not close the loops: residual ' // fmt(maxval(abs(wk%loops%residual))) // &
        & ' exceeds ' // fmt(assembly_tol) // ' of the loops'' size ' // fmt(wk%loops%size) // ' m (give consistent q0)')
      return
    end if
    q0 = q; qd0 = qd
    call project_positions(d, wk, q, wk%loops%size, error, held=held)
    if (.not. allocated(error)) call project_velocities(d, wk, q, qd, error, held)
    if (allocated(error)) then
      ! a state that cannot be assembled is the scene's fault, not the run's
      error%stat = stat_input; error%message = 'cannot assemble the initial state: ' // error%message; return
    end if
    wk%loops%assembly_dq = maxval(abs(q - q0)); wk%loops%assembly_dqd = maxval(abs(qd - qd0))
  end subroutine assemble_loops

  !> Residual wk%loops%residual, Jacobian wk%loops%jac and wk%loops%gamma = -Gdot qd of every cut joint, after
  !> forward_kinematics at (q, qd), from the frames at the cut's two points (wk%loops%rot,
  !> wk%loops%pos, wk%loops%vel, wk%loops%acc: a rigid body's frame, or the deformed frame at a point
  !> of a flexible body).
  pure subroutine loop_rows(d, wk)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer :: c, r, rr, i, j
    real(dp) :: pp(3), pc(3), vp(3), vc(3), ap(3), ac(3), wp(3), wc(3), alp(3), alc(3), uc(3), ci(3)
    wk%loops%jac = 0.0_dp
    do c = 1, d%cuts%n
      if (d%cuts%kind(c) == cut_free) cycle
      r = d%cuts%row0(c)
      pp = wk%loops%pos(:, 1, c); pc = wk%loops%pos(:, 2, c)
      wp = wk%loops%vel(4:6, 1, c); wc = wk%loops%vel(4:6, 2, c)
      alp = wk%loops%acc(4:6, 1, c); alc = wk%loops%acc(4:6, 2, c)
      vp = wk%loops%vel(1:3, 1, c) + cross(wp, pp); vc = wk%loops%vel(1:3, 2, c) + cross(wc, pc)
      ap = wk%loops%acc(1:3, 1, c) + cross(alp, pp) + cross(wp, vp)
      ac = wk%loops%acc(1:3, 2, c) + cross(alc, pc) + cross(wc, vc)
      if (d%cuts%kind(c) == cut_prismatic .or. d%cuts%kind(c) == cut_cylindrical) then
        call sliding_rows(d, wk, c, r, d%cuts%normal(:, :, c), pp, pc, vp, vc, ap, ac, wp, alp)
      else if (d%cuts%kind(c) == cut_planar) then
        call sliding_rows(d, wk, c, r, d%cuts%axis(:, c:c), pp, pc, vp, vc, ap, ac, wp, alp)
      else
        wk%loops%residual(r:r + 2) = pc - pp
        wk%loops%gamma(r:r + 2) = ap - ac
        do i = 1, 3
          call add_point_columns(d, wk, c, child, pc, unit_axes(:, i), 1.0_dp, r + i - 1)
          call add_point_columns(d, wk, c, parent, pp, unit_axes(:, i), -1.0_dp, r + i - 1)
        end do
        call to_parent_axes(d, wk, r, wk%loops%rot(:, :, parent, c))
      end if
      select case (d%cuts%kind(c))
      case (cut_fixed, cut_prismatic)
        ! the frames agree: rows rr .. rr + 2 after the 3 point rows (fixed) or the 2 sliding ones
        rr = r + merge(2, 3, d%cuts%kind(c) == cut_prismatic)
        wk%loops%residual(rr:rr + 2) = 0.0_dp
        do j = 1, 3
          wk%loops%residual(rr:rr + 2) = wk%loops%residual(rr:rr + 2) + 0.5_dp*cross(wk%loops%rot(:, j, parent, c), wk%loops%rot(:, j, child, c))
        end do
        wk%loops%gamma(rr:rr + 2) = alp - alc
        do i = 1, 3
          call add_turn_columns(d, wk, c, child, unit_axes(:, i), 1.0_dp, rr + i - 1)
          call add_turn_columns(d, wk, c, parent, unit_axes(:, i), -1.0_dp, rr + i - 1)
        end do
        call to_parent_axes(d, wk, rr, wk%loops%rot(:, :, parent, c))
      case (cut_revolute, cut_cylindrical, cut_planar)
        ! the axes stay aligned: two rows after the 3 point rows, 2 or 1 sliding rows
        rr = r + axis_row0(d%cuts%kind(c))
        uc = matmul(wk%loops%rot(:, :, child, c), d%cuts%axis(:, c))
        do i = 1, 2
          ci = matmul(wk%loops%rot(:, :, parent, c), d%cuts%normal(:, i, c))
          call normal_row(d, wk, c, rr + i - 1, ci, uc, wp, wc, alp, alc)
        end do
      case (cut_universal)
        ! the child's second axis stays normal to the parent's axis: one row after the point rows
        ci = matmul(wk%loops%rot(:, :, parent, c), d%cuts%axis(:, c))
        uc = matmul(wk%loops%rot(:, :, child, c), d%cuts%normal(:, 1, c))
        call normal_row(d, wk, c, r + 3, ci, uc, wp, wc, alp, alc)
      end select
    end do
  end subroutine loop_rows

  !> The first axis row of a revolute (after 3 point rows), cylindrical (2 sliding rows) or
  !> planar cut (1 sliding row), as an offset from its first row.
  pure integer function axis_row0(kind)
    integer, intent(in) :: kind
    select case (kind)
    case (cut_cylindrical); axis_row0 = 2
    case (cut_planar); axis_row0 = 1
    case default; axis_row0 = 3
    end select
  end function axis_row0

  !> Row `row`: the parent's vector ci (inertial, turning with the parent's frame) stays
  !> normal to the child's vector uc (turning with the child's), ci . uc = 0. Its rate is
  !> (wc - wp) . n with n = uc x ci; gamma = -(alpha_c - alpha_p) . n - (wc - wp) . dn/dt.
  pure subroutine normal_row(d, wk, c, row, ci, uc, wp, wc, alp, alc)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: c, row
    real(dp), intent(in) :: ci(3), uc(3), wp(3), wc(3), alp(3), alc(3)
    real(dp) :: ni(3), nd(3)
    ni = cross(uc, ci)
    nd = cross(cross(wc, uc), ci) + cross(uc, cross(wp, ci))
    wk%loops%residual(row) = dot_product(ci, uc)
    wk%loops%gamma(row) = -dot_product(alc - alp, ni) - dot_product(wc - wp, nd)
    call add_turn_columns(d, wk, c, child, ni, 1.0_dp, row)
    call add_turn_columns(d, wk, c, parent, ni, -1.0_dp, row)
  end subroutine normal_row

  !> Turn rows r .. r + 2 (inertial components of a vector constraint: residual, Jacobian,
  !> gamma) into the components along the axes rp of the parent's frame at the cut point. The
  !> Jacobian is that of the turned residual at closure (the parent's turning times the
  !> residual is dropped, as for the frame rows' own Jacobian), so every loop's motion is
  !> unchanged.
  pure subroutine to_parent_axes(d, wk, r, rp)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: r
    real(dp), intent(in) :: rp(3, 3)
    real(dp) :: rt(3, 3)
    rt = transpose(rp)
    wk%loops%residual(r:r + 2) = matmul(rt, wk%loops%residual(r:r + 2))
    wk%loops%gamma(r:r + 2) = matmul(rt, wk%loops%gamma(r:r + 2))
    wk%loops%jac(r:r + 2, :) = matmul(rt, wk%loops%jac(r:r + 2, :))
  end subroutine to_parent_axes

  !> A prismatic (or cylindrical) cut's two sliding rows r, r + 1: the child point stays on the line
  !> through the parent point along the axis, n_i . (pc - pp) = 0 for the axis' normals n_i, which
  !> turn with the parent's frame at its point. Their rate is n_i . (vc - vp) + wp . (n_i x (pc - pp)), and
  !> gamma = -[n_i . (ac - ap) + 2 (wp x n_i) . (vc - vp) + (alpha_p x n_i + wp x (wp x n_i)) . (pc - pp)]
  !> with the bias (qdd = 0) point accelerations ap, ac and angular acceleration alpha_p.
  pure subroutine sliding_rows(d, wk, c, r, dirs, pp, pc, vp, vc, ap, ac, wp, alp)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: c, r
    !> The rows' directions n_i in the parent's frame (a prismatic or cylindrical cut: the
    !> axis' two normals; a planar one: the axis, the child point staying in the plane).
    real(dp), intent(in) :: dirs(:, :)
    real(dp), intent(in) :: pp(3), pc(3), vp(3), vc(3), ap(3), ac(3), wp(3), alp(3)
    integer :: i
    real(dp) :: n(3), dl(3)
    dl = pc - pp
    do i = 1, size(dirs, 2)
      n = matmul(wk%loops%rot(:, :, parent, c), dirs(:, i))
      wk%loops%residual(r + i - 1) = dot_product(n, dl)
      wk%loops%gamma(r + i - 1) = -(dot_product(n, ac - ap) + 2.0_dp*dot_product(cross(wp, n), vc - vp) + &
        & dot_product(cross(alp, n) + cross(wp, cross(wp, n)), dl))
      call add_point_columns(d, wk, c, child, pc, n, 1.0_dp, r + i - 1)
      call add_point_columns(d, wk, c, parent, pp, n, -1.0_dp, r + i - 1)
      call add_turn_columns(d, wk, c, parent, cross(n, dl), 1.0_dp, r + i - 1)
    end do
  end subroutine sliding_rows

  !> Row `row` of G += sgn * (direction e . velocity of the inertial point p of side s of cut
  !> c) per unit rate of each coordinate that moves it: e . (s_v + s_w x p) =
  !> e . s_v + (p x e) . s_w.
  pure subroutine add_point_columns(d, wk, c, s, p, e, sgn, row)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: c, s, row
    real(dp), intent(in) :: p(3), e(3), sgn
    call add_frame_columns(d, wk, c, s, sgn*e, sgn*cross(p, e), row)
  end subroutine add_point_columns

  !> Row `row` of G += sgn * (direction e . angular velocity of side s's frame of cut c) per
  !> unit rate.
  pure subroutine add_turn_columns(d, wk, c, s, e, sgn, row)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: c, s, row
    real(dp), intent(in) :: e(3), sgn
    call add_frame_columns(d, wk, c, s, [0.0_dp, 0.0_dp, 0.0_dp], sgn*e, row)
  end subroutine add_turn_columns

  !> Row `row` of G += ev . s_v + ew . s_w for every spatial column s that moves the frame
  !> at side s of cut c: the columns on its body's path (add_path_columns) and, on a
  !> flexible body, the body's own modal columns at the point (wk%loops%cm).
  pure subroutine add_frame_columns(d, wk, c, s, ev, ew, row)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: c, s, row
    real(dp), intent(in) :: ev(3), ew(3)
    integer :: b, l, k
    b = merge(d%cuts%parent(c), d%cuts%child(c), s == parent)
    call add_path_columns(d, wk, b, ev, ew, row)
    do l = 1, d%nm(b)
      k = d%a0(b) + l - 1
      wk%loops%jac(row, k) = wk%loops%jac(row, k) + dot_product(ev, wk%loops%cm(1:3, l, s, c)) + dot_product(ew, wk%loops%cm(4:6, l, s, c))
    end do
  end subroutine add_frame_columns

  !> Row `row` of G += ev . s_v + ew . s_w for every spatial column s on body b's path: the
  !> joint columns, and the modal columns (wk%cm) of each flexible body the path crosses.
  pure subroutine add_path_columns(d, wk, b, ev, ew, row)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: b, row
    real(dp), intent(in) :: ev(3), ew(3)
    integer :: a, k, l, pa
    a = b
    do while (a > 1)
      do k = d%c0(a), d%c0(a) + d%nc(a) - 1
        wk%loops%jac(row, k) = wk%loops%jac(row, k) + dot_product(ev, wk%s(1:3, k)) + dot_product(ew, wk%s(4:6, k))
      end do
      pa = d%parent(a)
      do l = 1, d%nm(pa)
        k = d%a0(pa) + l - 1
        wk%loops%jac(row, k) = wk%loops%jac(row, k) + dot_product(ev, wk%cm(1:3, l, a)) + dot_product(ew, wk%cm(4:6, l, a))
      end do
      a = pa
    end do
  end subroutine add_path_columns

  !> The independent rows of G (wk%loops%jac, after loop_rows): independent_rows of its free
  !> columns; the others are redundant. Chosen once, at the first evaluation or at assembly.
  !> A loop that leaves no motion is an error.
  subroutine choose_rows(d, wk, error)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    type(error_type), allocatable, intent(out) :: error
    call independent_rows(free_columns(d, wk%loops%jac), wk%loops%row_used, wk%loops%n_used)
    wk%loops%n_redundant = d%cuts%n_rows - wk%loops%n_used
    wk%loops%rows_chosen = .true.
    ! with prescribed coordinates the loops may take every other coordinate (a driven mechanism)
    if (d%n_prescribed == 0 .and. wk%loops%n_used >= d%n) call fatal_error(error, &
      & 'the loops lock the mechanism: ' // itoa(wk%loops%n_used) // ' independent constraints on ' // itoa(d%n) // &
      & ' coordinates leave no motion')
  end subroutine choose_rows

  !> The independent rows of a: pivoted Gram-Schmidt on the rows (the column-pivoted QR of
  !> a^T); a row is dependent when its part independent of the rows chosen before is below
  !> rank_tol of the largest row. used(1:n_used) are their indices, in the order chosen.
  pure subroutine independent_rows(a, used, n_used)
    real(dp), intent(in) :: a(:, :)
    integer, intent(out) :: used(:), n_used
    real(dp) :: rows(size(a, 1), size(a, 2)), norms(size(a, 1)), scale
    logical :: free(size(a, 1))
    integer :: k, i, j
    rows = a
    free = .true.
    n_used = 0
    scale = maxval(norm2(rows, dim=2))
    do k = 1, size(a, 1)
      norms = norm2(rows, dim=2)
      i = maxloc(norms, dim=1, mask=free)
      if (norms(i) <= rank_tol*scale) exit
      free(i) = .false.
      n_used = n_used + 1; used(n_used) = i
      rows(i, :) = rows(i, :)/norms(i)
      do j = 1, size(a, 1)
        if (free(j)) rows(j, :) = rows(j, :) - dot_product(rows(j, :), rows(i, :))*rows(i, :)
      end do
    end do
  end subroutine independent_rows

  !> Add the constraint forces to qdd = M^-1 P (M's Cholesky factor in wk%lf), after an
  !> evaluation's kinematics (the rows chosen at the first).
  subroutine constrained_accelerations(d, wk, qdd, error)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(inout) :: qdd(:)
    type(error_type), allocatable, intent(out) :: error
    call loop_rows(d, wk)
    if (.not. wk%loops%rows_chosen) then
      call choose_rows(d, wk, error); if (allocated(error)) return
    end if
    call add_multipliers(d, wk, qdd, error)
  end subroutine constrained_accelerations

  !> lambda from (G M^-1 G^T) lambda = gamma - G qdd on the used rows, then
  !> qdd += M^-1 G^T lambda; wk%loops%lambda keeps them (0 on redundant rows).
  subroutine add_multipliers(d, wk, qdd, error)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(inout) :: qdd(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: lam(wk%loops%n_used), gu(wk%loops%n_used, d%n), gf(wk%loops%n_used, d%n)
    gu = wk%loops%jac(wk%loops%row_used(1:wk%loops%n_used), :)
    gf = free_columns(d, gu)
    lam = wk%loops%gamma(wk%loops%row_used(1:wk%loops%n_used)) - matmul(gu, qdd)
    call add_row_forces(wk%lf, 'the mass matrix', gf, wk%loops%ymg(:, 1:wk%loops%n_used), lam, qdd, error)
    if (allocated(error)) return
    wk%loops%lambda = 0.0_dp
    wk%loops%lambda(wk%loops%row_used(1:wk%loops%n_used)) = lam
  end subroutine add_multipliers

  !> The forces g^T lambda along independent rows g that bring the accelerations qdd = M^-1 P
  !> onto the rows: with M's Cholesky factor l (named `mass` in messages), y = M^-1 g^T,
  !> (g y) lambda = r (r: the rows' acceleration residual on entry, lambda on return) and
  !> qdd += y lambda.
  subroutine add_row_forces(l, mass, g, y, r, qdd, error)
    real(dp), intent(in) :: l(:, :), g(:, :)
    character(len=*), intent(in) :: mass
    real(dp), intent(out) :: y(:, :)
    real(dp), intent(inout) :: r(:), qdd(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: a(size(g, 1), size(g, 1))
    y = transpose(g)
    call potrs(l, y, mass, error); if (allocated(error)) return
    a = matmul(g, y)
    call solve_rows(a, r, error); if (allocated(error)) return
    qdd = qdd + matmul(y, r)
  end subroutine add_row_forces

  !> Rows of G without the prescribed coordinates' columns: the loops' forces and
  !> projections move only the free coordinates (a prescribed one follows its function, and
  !> its known motion stays in the right-hand sides).
  pure function free_columns(d, g) result(gf)
    type(model_data), intent(in) :: d
    real(dp), intent(in) :: g(:, :)
    real(dp) :: gf(size(g, 1), size(g, 2))
    integer :: k
    gf = g
    do k = 1, d%n
      if (d%prescribed(k)) gf(:, k) = 0.0_dp
    end do
  end function free_columns

  !> Rows g without the columns of the coordinates marked held.
  pure function held_columns(g, held) result(gh)
    real(dp), intent(in) :: g(:, :)
    logical, intent(in) :: held(:)
    real(dp) :: gh(size(g, 1), size(g, 2))
    gh = g
    where (spread(held, 1, size(g, 1))) gh = 0.0_dp
  end function held_columns

  !> Solve the (symmetric positive definite) system of the used rows in place.
  subroutine solve_rows(a, x, error)
    real(dp), intent(inout) :: a(:, :), x(:)
    type(error_type), allocatable, intent(out) :: error
    call potrf(a, 'the loop constraints (a singular position of a loop)', error); if (allocated(error)) return
    call potrs(a, x, 'the loop constraints', error)
  end subroutine solve_rows

  !> Close the loops from q by the least change: q <- q - G^T (G G^T)^-1 Phi, iterated until
  !> |Phi| <= closure_tol * max(scale, 1 m) (m; rad for rotation rows); an error if that fails.
  subroutine project_positions(d, wk, q, scale, error, residual, held)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(inout) :: q(:)
    real(dp), intent(in) :: scale
    type(error_type), allocatable, intent(out) :: error
    !> The largest residual |Phi| of the given q.
    real(dp), intent(out), optional :: residual
    !> Coordinates the projection keeps (the assembly's held ones).
    logical, intent(in), optional :: held(:)
    real(dp) :: gu(wk%loops%n_used, d%n), y(wk%loops%n_used), a(wk%loops%n_used, wk%loops%n_used)
    integer :: it
    do it = 1, max_iterations
      call forward_kinematics(d, wk, q, 0.0_dp*q)
      call loop_rows(d, wk)
      if (it == 1 .and. present(residual)) residual = maxval(abs(wk%loops%residual))
      if (maxval(abs(wk%loops%residual)) <= closure_tol*max(scale, 1.0_dp)) return
      gu = free_columns(d, wk%loops%jac(wk%loops%row_used(1:wk%loops%n_used), :))
      if (present(held)) gu = held_columns(gu, held)
      a = matmul(gu, transpose(gu))
      y = wk%loops%residual(wk%loops%row_used(1:wk%loops%n_used))
      call solve_rows(a, y, error); if (allocated(error)) return
      q = q - matmul(y, gu)
    end do
    call fatal_error(error, 'the loops cannot be closed (constraint residual ' // fmt(maxval(abs(wk%loops%residual))) // &
      & ' after ' // itoa(max_iterations) // ' projections)', stat_solver)
  end subroutine project_positions

  !> Remove the rates' motion across the loops: qd <- qd - G^T (G G^T)^-1 G qd (G at q).
  subroutine project_velocities(d, wk, q, qd, error, held)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: q(:)
    real(dp), intent(inout) :: qd(:)
    type(error_type), allocatable, intent(out) :: error
    !> Coordinates whose rates the projection keeps (the assembly's held ones).
    logical, intent(in), optional :: held(:)
    real(dp) :: gu(wk%loops%n_used, d%n), y(wk%loops%n_used), a(wk%loops%n_used, wk%loops%n_used)
    call forward_kinematics(d, wk, q, qd)
    call loop_rows(d, wk)
    gu = wk%loops%jac(wk%loops%row_used(1:wk%loops%n_used), :)
    y = matmul(gu, qd)
    gu = free_columns(d, gu)
    if (present(held)) gu = held_columns(gu, held)
    a = matmul(gu, transpose(gu))
    call solve_rows(a, y, error); if (allocated(error)) return
    qd = qd - matmul(y, gu)
  end subroutine project_velocities

  !> The force f and torque cut joint c puts on its child at its child point pc (inertial;
  !> from wk%loops%lambda, after forward_kinematics). A 'free' cut puts none.
  pure subroutine cut_force(d, wk, c, f, torque, pc)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    integer, intent(in) :: c
    real(dp), intent(out) :: f(3), torque(3), pc(3)
    real(dp) :: uc(3), ci(3)
    integer :: r, i
    r = d%cuts%row0(c)
    pc = wk%loops%pos(:, child, c)
    f = 0.0_dp; torque = 0.0_dp
    ! the point and frame rows are along the axes of the parent's frame at its point
    associate(rp => wk%loops%rot(:, :, parent, c))
      select case (d%cuts%kind(c))
      case (cut_free)
        pc = wk%pos(:, d%cuts%child(c)) + matmul(wk%rot(:, :, d%cuts%child(c)), d%cuts%child_at(:, c))
      case (cut_spherical)
        f = matmul(rp, wk%loops%lambda(r:r + 2))
      case (cut_fixed)
        f = matmul(rp, wk%loops%lambda(r:r + 2))
        torque = matmul(rp, wk%loops%lambda(r + 3:r + 5))
      case (cut_prismatic, cut_cylindrical)
        ! the sliding rows push along the normals, the frame rows or the axis rows turn
        do i = 1, 2
          f = f + wk%loops%lambda(r + i - 1)*matmul(rp, d%cuts%normal(:, i, c))
        end do
        if (d%cuts%kind(c) == cut_prismatic) torque = matmul(rp, wk%loops%lambda(r + 2:r + 4))
      case (cut_revolute, cut_universal)
        f = matmul(rp, wk%loops%lambda(r:r + 2))
      case (cut_planar)
        f = wk%loops%lambda(r)*matmul(rp, d%cuts%axis(:, c))
      end select
      select case (d%cuts%kind(c))
      case (cut_revolute, cut_cylindrical, cut_planar)
        uc = matmul(wk%loops%rot(:, :, child, c), d%cuts%axis(:, c))
        do i = 1, 2
          ci = matmul(wk%loops%rot(:, :, parent, c), d%cuts%normal(:, i, c))
          torque = torque + wk%loops%lambda(r + axis_row0(d%cuts%kind(c)) + i - 1)*cross(uc, ci)
        end do
      case (cut_universal)
        ci = matmul(rp, d%cuts%axis(:, c))
        uc = matmul(wk%loops%rot(:, :, child, c), d%cuts%normal(:, 1, c))
        torque = wk%loops%lambda(r + 3)*cross(uc, ci)
      end select
    end associate
  end subroutine cut_force

  !> Cut joint c's force and moment on its child in the child's frame, the moment about
  !> the child point (a &output 'reactions' column group).
  pure function cut_wrench(d, wk, c) result(w)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    integer, intent(in) :: c
    real(dp) :: w(6), f(3), torque(3), pc(3)
    call cut_force(d, wk, c, f, torque, pc)
    w(1:3) = matmul(f, wk%rot(:, :, d%cuts%child(c)))
    w(4:6) = matmul(torque, wk%rot(:, :, d%cuts%child(c)))
  end function cut_wrench

  !> The cut joints' wrenches [f; n_O] (inertial, moment about the origin) on each body
  !> (6, nb): + on the child, - on the parent.
  pure subroutine cut_body_wrenches(d, wk, ext)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(out) :: ext(:, :)
    real(dp) :: f(3), torque(3), pc(3), w(6)
    integer :: c
    ext = 0.0_dp
    do c = 1, d%cuts%n
      call cut_force(d, wk, c, f, torque, pc)
      w(1:3) = f; w(4:6) = cross(pc, f) + torque
      ext(:, d%cuts%child(c)) = ext(:, d%cuts%child(c)) + w
      ext(:, d%cuts%parent(c)) = ext(:, d%cuts%parent(c)) - w
    end do
  end subroutine cut_body_wrenches

  !> A multirate fast step's modal accelerations with the loops. Given the slow
  !> accelerations acc_s, qdd_f = M_ff^-1 (Q_f - M_fs acc_s) (on entry) takes the constraint
  !> forces G_f^T mu that make G_f qdd_f = gamma - G_s acc_s hold on the rows independent in
  !> G_f (the others constrain only the slow motion, given here). With exact acc_s this is
  !> the fast part of the constrained accelerations. lff: M_ff's Cholesky factor; after
  !> forward_kinematics at the step's state.
  subroutine constrain_fast_accelerations(d, wk, lff, acc_s, qdd_f, error)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: lff(:, :), acc_s(:)
    real(dp), intent(inout) :: qdd_f(:)
    type(error_type), allocatable, intent(out) :: error
    integer, allocatable :: r(:), fast_used(:)
    real(dp), allocatable :: gf(:, :), y(:, :), mu(:)
    integer :: ns, n_fast
    ns = d%nj
    call loop_rows(d, wk)
    if (.not. wk%loops%rows_chosen) then
      call choose_rows(d, wk, error); if (allocated(error)) return
    end if
    r = wk%loops%row_used(1:wk%loops%n_used)
    allocate(fast_used(wk%loops%n_used))
    call independent_rows(wk%loops%jac(r, ns+1:), fast_used, n_fast)
    if (n_fast == 0) return
    r = r(fast_used(1:n_fast))
    gf = wk%loops%jac(r, ns+1:)
    mu = wk%loops%gamma(r) - matmul(wk%loops%jac(r, 1:ns), acc_s) - matmul(gf, qdd_f)
    allocate(y(size(qdd_f), n_fast))
    call add_row_forces(lff, 'M_ff', gf, y, mu, qdd_f, error)
  end subroutine constrain_fast_accelerations

  !> The response g = M^-1 E of the last constrained evaluation (add_multipliers: its rows
  !> G and Y = M^-1 G^T) made the loops' response: a force f moves the accelerations by
  !> M^-1 f + Y lambda with (G Y) lambda = -G M^-1 f, so g <- g - Y (G Y)^-1 G g.
  subroutine constrain_response(d, wk, g, error)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(inout) :: g(:, :)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: a(wk%loops%n_used, wk%loops%n_used), b(wk%loops%n_used, size(g, 2))
    associate(y => wk%loops%ymg(:, 1:wk%loops%n_used), gu => wk%loops%jac(wk%loops%row_used(1:wk%loops%n_used), :))
      a = matmul(free_columns(d, gu), y)
      b = matmul(gu, g)
      call potrf(a, 'the loop constraints (a singular position of a loop)', error); if (allocated(error)) return
      call potrs(a, b, 'the loop constraints', error); if (allocated(error)) return
      g = g - matmul(y, b)
    end associate
  end subroutine constrain_response

  !> The loops' used rows of G at positions q (the kinematics at rest), without the
  !> prescribed coordinates' columns (the pre-flight linearisation's constraints); the rows
  !> are chosen here if no evaluation has yet.
  subroutine loop_jacobian(d, wk, q, g, error)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: q(:)
    real(dp), allocatable, intent(out) :: g(:, :)
    type(error_type), allocatable, intent(out) :: error
    call forward_kinematics(d, wk, q, 0.0_dp*q)
    call loop_rows(d, wk)
    if (.not. wk%loops%rows_chosen) then
      call choose_rows(d, wk, error); if (allocated(error)) return
    end if
    g = free_columns(d, wk%loops%jac(wk%loops%row_used(1:wk%loops%n_used), :))
  end subroutine loop_jacobian

  !> For independent rows g of constraints on coordinates whose inverse mass matrix is
  !> minv: minv becomes the constrained inverse minv - Y (g Y)^-1 Y^T, Y = minv g^T (qdd =
  !> minv f are then the accelerations the constraints allow under forces f), and kg =
  !> Y (g Y)^-1, the accelerations that meet a constraint acceleration of one, if asked.
  subroutine constrain_inverse(minv, g, error, kg)
    real(dp), intent(inout) :: minv(:, :)
    real(dp), intent(in) :: g(:, :)
    type(error_type), allocatable, intent(out) :: error
    real(dp), intent(out), optional :: kg(:, :)
    real(dp) :: y(size(minv, 1), size(g, 1)), a(size(g, 1), size(g, 1)), yt(size(g, 1), size(minv, 1))
    y = matmul(minv, transpose(g))
    a = matmul(g, y)
    yt = transpose(y)
    call potrf(a, 'the loop constraints (a singular position of a loop)', error); if (allocated(error)) return
    call potrs(a, yt, 'the loop constraints', error); if (allocated(error)) return
    minv = minv - matmul(y, yt)
    if (present(kg)) kg = transpose(yt)
  end subroutine constrain_inverse
end module pymr_model_loops
