!> Build the model from a checked scene (model/scene_rules.f90): bodies in parent-before-child
!> order, joints expanded into one-coordinate primitives, markers, cut joints, work arrays;
!> then the effects' list (driver/build_effects.f90).
module pymr_driver_build
  use pymr_env_kinds, only : dp, name_len, pi
  use pymr_env_error, only : error_type, fatal_error
  use pymr_model_scene, only : scene_t, integrator_spec, body_spec, joint_spec, joint_ndof, unset, beam_mode_count, control_count
  use pymr_model_scene_rules, only : check_scene, body_index, closes_loop
  use pymr_model_inertia, only : inertia_matrix
  use pymr_model_types, only : model_data, model_work, prim_revolute, prim_prismatic, &
    & cut_fixed, cut_revolute, cut_spherical, cut_prismatic, cut_free, cut_cylindrical, cut_universal, cut_planar
  use pymr_model_beam_modes, only : build_beam, beam_section, beam_point_shapes
  use pymr_model_effect, only : effect_slot, start_effect_counters
  use pymr_driver_build_effects, only : build_effects
  use pymr_io_modal_file, only : read_modal_file
  use pymr_model_flexbody, only : flex_data, modal_nodes, undeformed_modal_moments
  use pymr_model_spatial, only : unit_axes, cross
  use pymr_env_text_file, only : scene_relative
  use pymr_model, only : model_t
  use pymr_env_text, only : itoa, fmt
  use pymr_env_memory, only : memory_limit, check_room, refuse_room
  implicit none
  private
  public :: build_model

contains

  !> Check the scene, then build `model`; errors name file, group and item.
  subroutine build_model(sc, model, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(out) :: model
    type(error_type), allocatable, intent(out) :: error
    integer, allocatable :: order(:), inboard(:)
    type(effect_slot), allocatable :: effects(:)
    call check_scene(sc, error); if (allocated(error)) return
    call tree_order(sc, order, inboard, error); if (allocated(error)) return
    call fill_model(sc, order, inboard, model%d, model%wk, error); if (allocated(error)) return
    call build_effects(sc, order, model%d, effects, error); if (allocated(error)) return
    call model%set_effects(effects)
    call start_effect_counters(model%effects, model%wk)
  end subroutine build_model


  !> The initial modal state of body i, when given, holds one value per mode (m of them: a
  !> modal file's count is known only now).
  subroutine check_modal_state(sc, i, m, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: i, m
    type(error_type), allocatable, intent(out) :: error
    associate(b => sc%bodies(i))
      if (count(b%a0 /= unset) > 0 .and. count(b%a0 /= unset) /= m) then
        call fatal_error(error, b%origin%where('a0') // ': give one value per mode (' // itoa(m) // ' modes), got ' // &
          & itoa(count(b%a0 /= unset))); return
      end if
      if (count(b%ad0 /= unset) > 0 .and. count(b%ad0 /= unset) /= m) then
        call fatal_error(error, b%origin%where('ad0') // ': give one value per mode (' // itoa(m) // ' modes), ' // &
          & 'got ' // itoa(count(b%ad0 /= unset)))
      end if
    end associate
  end subroutine check_modal_state

  !> Modal damping forces per unit modal rate of flexible body i: 2 zeta_k omega_k +
  !> alpha + beta omega_k^2.
  subroutine set_damping(sc, i, fd, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: i
    type(flex_data), intent(inout) :: fd
    type(error_type), allocatable, intent(out) :: error
    integer :: ng, k
    real(dp) :: zeta
    associate(b => sc%bodies(i))
      ng = count(b%modal_damping /= unset)
      if (ng > 1 .and. ng /= fd%m) then
        call fatal_error(error, sc%bodies(i)%origin%where() // ': modal_damping: give one value or one per mode (' // &
          & itoa(fd%m) // ' modes), got ' // itoa(ng)); return
      end if
      if (allocated(fd%damp)) deallocate(fd%damp)
      allocate(fd%damp(fd%m))
      do k = 1, fd%m
        zeta = 0.0_dp
        if (ng == 1) zeta = b%modal_damping(1)
        if (ng > 1) zeta = b%modal_damping(k)
        fd%damp(k) = 2.0_dp*zeta*sqrt(max(fd%omega2(k), 0.0_dp)) + b%rayleigh_alpha + b%rayleigh_beta*fd%omega2(k)
      end do
    end associate
  end subroutine set_damping

  !> Bodies in parent-before-child order (order(1) = ground) and each body's inboard joint.
  subroutine tree_order(sc, order, inboard, error)
    type(scene_t), intent(in) :: sc
    integer, allocatable, intent(out) :: order(:), inboard(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: nb, i, j, k, a, steps
    integer, allocatable :: parent(:)
    logical, allocatable :: placed(:)
    nb = size(sc%bodies)
    allocate(parent(nb), inboard(nb), placed(nb), order(0))
    parent = 0; inboard = 0
    do j = 1, size(sc%joints)
      if (closes_loop(sc, j)) cycle
      i = body_index(sc, sc%joints(j)%child)
      parent(i) = body_index(sc, sc%joints(j)%parent); inboard(i) = j
    end do
    do i = 1, nb
      if (sc%bodies(i)%kind == 'ground') cycle
      a = i; steps = 0
      do while (a /= 0 .and. sc%bodies(max(a, 1))%kind /= 'ground')
        a = parent(a); steps = steps + 1
        if (steps > nb) then
          call fatal_error(error, sc%bodies(i)%origin%where() // ': the joints form a cycle through this body; ' // &
            & 'a tree needs every body to reach the ground'); return
        end if
      end do
      if (a == 0) then
        call fatal_error(error, sc%bodies(i)%origin%where() // ': not connected to the ground by joints (add a &joint ' // &
          & 'with this body as child)'); return
      end if
    end do
    placed = .false.
    do i = 1, nb
      if (sc%bodies(i)%kind == 'ground') then
        order = [order, i]; placed(i) = .true.
      end if
    end do
    do k = 1, nb
      do i = 1, nb
        if (.not. placed(i) .and. parent(i) > 0) then
          if (placed(parent(i))) then
            order = [order, i]; placed(i) = .true.
          end if
        end if
      end do
    end do
  end subroutine tree_order

  !> Fill model data from a checked scene in tree order.
  subroutine fill_model(sc, order, inboard, d, wk, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: order(:), inboard(:)
    type(model_data), intent(out) :: d
    type(model_work), intent(inout) :: wk
    type(error_type), allocatable, intent(out) :: error
    integer :: nb, b, i, j, k, m, pos_in(size(order))
    type(flex_data), allocatable :: mfd(:)
    type(modal_nodes), allocatable :: mnd(:)
    nb = size(order)
    do b = 1, nb
      pos_in(order(b)) = b
    end do
    call count_coordinates(sc, order, inboard, d, mfd, mnd, error); if (allocated(error)) return
    call allocate_tree(d, wk)
    d%body_name(1) = sc%bodies(order(1))%name
    k = 0; m = d%nj
    do b = 2, nb
      i = order(b); j = inboard(i)
      d%body_name(b) = sc%bodies(i)%name
      d%joint_name(b) = sc%joints(j)%name
      d%parent(b) = pos_in(body_index(sc, sc%joints(j)%parent))
      d%at(:, b) = sc%joints(j)%at
      call add_joint(sc%joints(j), b, k, d)
      if (sc%bodies(i)%kind == 'beam') then
        call add_beam(sc, i, b, m, d, wk, error); if (allocated(error)) return
      else if (sc%bodies(i)%kind == 'modal') then
        d%flex(b) = mfd(b); d%mnodes(b) = mnd(b)
        call add_flexible(sc%bodies(i)%name, b, m, d, wk)
      else
        d%mass(b) = sc%bodies(i)%mass
        d%com(:, b) = sc%bodies(i)%com
        d%inertia(:, :, b) = inertia_matrix(sc%bodies(i)%inertia)
      end if
      if (d%nm(b) > 0) then
        call set_damping(sc, i, d%flex(b), error); if (allocated(error)) return
        call check_modal_state(sc, i, d%flex(b)%m, error); if (allocated(error)) return
      end if
    end do
    call add_control_states(sc, pos_in, k, d)
    call fill_children(d)
    call fill_joint_shapes(sc, order, inboard, d, error); if (allocated(error)) return
    call fill_markers_moments(sc, pos_in, d, wk, error); if (allocated(error)) return
    call fill_cuts(sc, pos_in, d, wk, error); if (allocated(error)) return
    call allocate_work(d, wk, run_bytes(sc%integrator, d%n, d%n - d%nj), error)
  end subroutine fill_model

  !> The coordinates: joint coordinates, then each flexible body's modes (a modal body's
  !> file read here, into mfd and mnd); the largest number of modes of one body.
  subroutine count_coordinates(sc, order, inboard, d, mfd, mnd, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: order(:), inboard(:)
    type(model_data), intent(inout) :: d
    type(flex_data), allocatable, intent(out) :: mfd(:)
    type(modal_nodes), allocatable, intent(out) :: mnd(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: b, nmb, nmod
    d%nb = size(order)
    d%nj = 0; nmod = 0; d%mmax = 0
    allocate(mfd(d%nb), mnd(d%nb))
    do b = 2, d%nb
      d%nj = d%nj + joint_ndof(sc%joints(inboard(order(b)))%kind)
      associate(bs => sc%bodies(order(b)))
        nmb = 0
        if (bs%kind == 'beam') nmb = beam_mode_count(bs)
        if (bs%kind == 'modal') then
          call read_modal_file(scene_relative(sc%file, trim(bs%modal_file)), mfd(b), mnd(b), error)
          if (allocated(error)) then
            error%message = sc%bodies(order(b))%origin%where('modal_file') // ': ' // error%message; return
          end if
          nmb = mfd(b)%m
        end if
        nmod = nmod + nmb
        d%mmax = max(d%mmax, nmb)
      end associate
    end do
    d%nj = d%nj + control_count(sc)
    d%n = d%nj + nmod
  end subroutine count_coordinates

  !> The controllers' state coordinates, after the k joint coordinates (model/effect_controls.f90):
  !> of no body, each its own output group; position control.double_integral, rate
  !> control.integral (the integral of the error), of the driven coordinate's kind.
  subroutine add_control_states(sc, pos_in, k, d)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: pos_in(:), k
    type(model_data), intent(inout) :: d
    integer :: i, j, c
    do i = 1, control_count(sc)
      associate(ct => sc%controls(i))
        c = k + i
        d%cbody(c) = 0; d%cgrp(c) = 2*d%nb + i; d%axis(:, c) = 0.0_dp
        do j = 1, size(sc%joints)
          if (sc%joints(j)%name == ct%joint .and. .not. closes_loop(sc, j)) &
            & d%prim(c) = d%prim(d%c0(pos_in(body_index(sc, sc%joints(j)%child))) + ct%coordinate - 1)
        end do
        d%qname(c) = trim(ct%name) // '.double_integral'
        d%qdname(c) = trim(ct%name) // '.integral'
      end associate
    end do
  end subroutine add_control_states

  !> The tree's arrays, sized and cleared.
  subroutine allocate_tree(d, wk)
    type(model_data), intent(inout) :: d
    type(model_work), intent(inout) :: wk
    associate(n => d%n, mx => d%mmax, nb => d%nb)
      allocate(d%body_name(nb), d%joint_name(nb), d%parent(nb), d%c0(nb), d%nc(nb), d%mass(nb), d%com(3, nb), &
        & d%inertia(3, 3, nb), d%at(3, nb), d%prim(n), d%cbody(n), d%cgrp(n), d%axis(3, n), d%qname(n), &
        & d%qdname(n), d%flexible(nb), d%nm(nb), d%a0(nb), d%flex(nb), wk%fwork(nb), d%bshape(nb), d%mnodes(nb), &
        & d%att_psi(3, mx, nb), d%att_phi(3, mx, nb), wk%cm(6, mx, nb), wk%mva(6, mx, nb), wk%wam(mx, nb), &
        & wk%kam(mx, nb))
    end associate
    d%parent = 0; d%c0 = 1; d%nc = 0; d%mass = 0.0_dp; d%com = 0.0_dp; d%inertia = 0.0_dp; d%at = 0.0_dp
    d%joint_name = ''; d%flexible = .false.; d%nm = 0; d%a0 = d%n + 1
    d%att_psi = 0.0_dp; d%att_phi = 0.0_dp; wk%cm = 0.0_dp; wk%mva = 0.0_dp; wk%wam = 0.0_dp; wk%kam = 0.0_dp
  end subroutine allocate_tree

  !> The bodies on or below a flexible body, and the parent's mode shapes at each joint
  !> point on a flexible body.
  subroutine fill_joint_shapes(sc, order, inboard, d, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: order(:), inboard(:)
    type(model_data), intent(inout) :: d
    type(error_type), allocatable, intent(out) :: error
    integer :: b
    allocate(d%in_fast(d%nb))
    d%in_fast(1) = .false.
    do b = 2, d%nb
      d%in_fast(b) = d%flexible(b) .or. d%in_fast(d%parent(b))
    end do
    do b = 2, d%nb
      if (d%nm(d%parent(b)) > 0) then
        call flexible_point(d, d%parent(b), d%at(:, b), sc%joints(inboard(order(b)))%origin%where('at'), &
          & d%att_psi(:, :, b), d%att_phi(:, :, b), error); if (allocated(error)) return
      end if
    end do
  end subroutine fill_joint_shapes

  !> The evaluations' kinematics and terms, sized and cleared. A model too large for the
  !> memory the process may hold (`need` bytes at the run's peak: run_bytes) fails here in
  !> one line, not in the compiler's runtime at some later allocation (which would also end
  !> a Python session).
  subroutine allocate_work(d, wk, need, error)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: need
    type(error_type), allocatable, intent(out) :: error
    integer :: nb, stat
    nb = d%nb
    call check_room(d%n, need, error); if (allocated(error)) return
    allocate(wk%mm(d%n, d%n), wk%lf(d%n, d%n), stat=stat)
    if (stat /= 0) then
      call refuse_room(d%n, need, memory_limit(), error); return
    end if
    allocate(wk%rot(3, 3, nb), wk%pos(3, nb), wk%vel(6, nb), wk%acc(6, nb), wk%s(6, d%n), wk%i6(6, 6, nb), &
      & wk%w(6, nb), wk%ic(6, 6, nb), wk%wc(6, nb), wk%p(d%n), wk%tau(d%n))
    wk%i6 = 0.0_dp; wk%w = 0.0_dp; wk%ic = 0.0_dp; wk%wc = 0.0_dp; wk%mm = 0.0_dp; wk%tau = 0.0_dp; wk%s = 0.0_dp
  end subroutine allocate_work

  !> Bytes of the dense matrices (n x n and larger) a run of n coordinates holds at its
  !> peak, by its method: n^2 times the words measured for each (the address-space limit
  !> below which the run cannot start or finish, bisected at two sizes;
  !> docs/performance.md), rounded up by about a tenth. Every run holds the mass matrix, its
  !> factor and the start's working copies (5 n^2 words). Beside them: single-rate 'adams'
  !> with Newton, its Jacobian and factor ((2n)^2 each); 'response' and 'full', the fast
  !> force response and partition; 'exponential', the modal flow's complex eigenvectors
  !> and their inverse ((2 nf)^2 complex each) while it is made; the pre-flight check of
  !> fixed steps, the linearised model (2n x 2n, its eigenvectors, and for multirate the
  !> macro step's own linearisation); 'auto', a copy of the model per probe, the probe kept
  !> and the one running (single-rate alone, with no probe, without both joint and modal
  !> coordinates). The modal flow's words go with the nf modal coordinates' nf^2. A fixed
  !> multirate step ('response', 'full') also holds its k fast steps' dense output.
  pure real(dp) function run_bytes(integ, n, nf)
    type(integrator_spec), intent(in) :: integ
    integer, intent(in) :: n, nf
    real(dp) :: words, r2
    logical :: checked
    checked = .not. integ%adaptive .and. integ%stability_check
    r2 = (real(nf, dp)/max(n, 1))**2
    select case (trim(integ%method))
    case ('auto')
      words = merge(13.0_dp + 29.0_dp*r2, 13.0_dp, nf > 0 .and. nf < n)
    case ('multirate')
      select case (trim(integ%coupling))
      case ('exponential')
        words = 5.0_dp + 33.0_dp*r2
      case ('full')
        words = merge(34.0_dp, 7.0_dp, checked)
      case default
        words = merge(28.0_dp, 9.0_dp, checked)
      end select
    case default
      words = 5.0_dp
      if (integ%adaptive .and. integ%formula /= 'abm4' .and. integ%corrector == 'newton') words = 13.0_dp
      if (checked) words = 22.0_dp
    end select
    run_bytes = 8.0_dp*words*real(n, dp)**2
    ! a fixed macro step's dense output holds its k fast steps' arrays (10 n words each)
    if (trim(integ%method) == 'multirate' .and. integ%coupling /= 'exponential' .and. .not. integ%adaptive) &
      & run_bytes = run_bytes + 80.0_dp*real(n, dp)*fixed_ratio(integ)
  end function run_bytes

  !> k = h_slow/h_fast of a fixed-step multirate run (1 where a step is unset).
  pure real(dp) function fixed_ratio(integ)
    type(integrator_spec), intent(in) :: integ
    fixed_ratio = 1.0_dp
    if (integ%h_fast > 0.0_dp .and. integ%h_slow > 0.0_dp) fixed_ratio = max(1.0_dp, integ%h_slow/integ%h_fast)
  end function fixed_ratio

  !> The loop-closing joints (closes_loop) and their constraint rows (model/loops.f90); a
  !> cut joint's point on a flexible body takes the body's mode shapes there (flexible_point).
  subroutine fill_cuts(sc, pos_in, d, wk, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: pos_in(:)
    type(model_data), intent(inout) :: d
    type(model_work), intent(inout) :: wk
    type(error_type), allocatable, intent(out) :: error
    integer :: j, c, mx
    d%cuts%n = count([(closes_loop(sc, j), j = 1, size(sc%joints))])
    mx = d%mmax
    allocate(d%cuts%name(d%cuts%n), d%cuts%parent(d%cuts%n), d%cuts%child(d%cuts%n), d%cuts%kind(d%cuts%n), &
      & d%cuts%row0(d%cuts%n), d%cuts%nrow(d%cuts%n), d%cuts%at(3, d%cuts%n), d%cuts%child_at(3, d%cuts%n), &
      & d%cuts%axis(3, d%cuts%n), d%cuts%normal(3, 2, d%cuts%n), d%cuts%psi(3, mx, 2, d%cuts%n), &
      & d%cuts%phi(3, mx, 2, d%cuts%n), wk%loops%rot(3, 3, 2, d%cuts%n), wk%loops%pos(3, 2, d%cuts%n), &
      & wk%loops%vel(6, 2, d%cuts%n), wk%loops%acc(6, 2, d%cuts%n), wk%loops%cm(6, mx, 2, d%cuts%n))
    d%cuts%psi = 0.0_dp; d%cuts%phi = 0.0_dp; wk%loops%cm = 0.0_dp
    c = 0; d%cuts%n_rows = 0
    do j = 1, size(sc%joints)
      if (.not. closes_loop(sc, j)) cycle
      c = c + 1
      associate(jt => sc%joints(j))
        d%cuts%name(c) = jt%name
        d%cuts%parent(c) = pos_in(body_index(sc, jt%parent)); d%cuts%child(c) = pos_in(body_index(sc, jt%child))
        d%cuts%at(:, c) = jt%at; d%cuts%child_at(:, c) = jt%child_at
        d%cuts%axis(:, c) = jt%axis/norm2(jt%axis); d%cuts%normal(:, :, c) = axis_normals(jt%axis)
        select case (trim(jt%kind))
        case ('fixed'); d%cuts%kind(c) = cut_fixed; d%cuts%nrow(c) = 6
        case ('revolute'); d%cuts%kind(c) = cut_revolute; d%cuts%nrow(c) = 5
        case ('prismatic'); d%cuts%kind(c) = cut_prismatic; d%cuts%nrow(c) = 5
        case ('free'); d%cuts%kind(c) = cut_free; d%cuts%nrow(c) = 0
        case ('cylindrical'); d%cuts%kind(c) = cut_cylindrical; d%cuts%nrow(c) = 4
        case ('planar'); d%cuts%kind(c) = cut_planar; d%cuts%nrow(c) = 3
        case ('universal')
          d%cuts%kind(c) = cut_universal; d%cuts%nrow(c) = 4
          ! the child's second axis: normal(:, 1), as the tree joint's axis2
          if (any(jt%axis2 /= unset)) then
            d%cuts%normal(:, 1, c) = jt%axis2/norm2(jt%axis2)
            d%cuts%normal(:, 2, c) = cross(d%cuts%axis(:, c), d%cuts%normal(:, 1, c))
          end if
        case default; d%cuts%kind(c) = cut_spherical; d%cuts%nrow(c) = 3
        end select
        if (d%cuts%kind(c) /= cut_free .and. d%nm(d%cuts%parent(c)) > 0) then
          call flexible_point(d, d%cuts%parent(c), jt%at, jt%origin%where('at'), d%cuts%psi(:, :, 1, c), &
            & d%cuts%phi(:, :, 1, c), error); if (allocated(error)) return
        end if
        if (d%cuts%kind(c) /= cut_free .and. d%nm(d%cuts%child(c)) > 0) then
          call flexible_point(d, d%cuts%child(c), jt%child_at, jt%origin%where('child_at'), &
            & d%cuts%psi(:, :, 2, c), d%cuts%phi(:, :, 2, c), error); if (allocated(error)) return
        end if
      end associate
      d%cuts%row0(c) = d%cuts%n_rows + 1; d%cuts%n_rows = d%cuts%n_rows + d%cuts%nrow(c)
    end do
    allocate(wk%loops%row_used(d%cuts%n_rows), wk%loops%residual(d%cuts%n_rows), wk%loops%jac(d%cuts%n_rows, d%n), wk%loops%gamma(d%cuts%n_rows), wk%loops%lambda(d%cuts%n_rows), &
      & wk%loops%ymg(d%n, d%cuts%n_rows))
    wk%loops%lambda = 0.0_dp
  end subroutine fill_cuts

  !> Expand joint jt of body b into primitives, coordinates k+1 ... (k is advanced). Axes
  !> are in the frame before each primitive: a universal joint's axis2 turns with its first
  !> rotation; a planar joint translates along axis_normals(axis) and then turns about axis.
  subroutine add_joint(jt, b, k, d)
    type(joint_spec), intent(in) :: jt
    integer, intent(in) :: b
    integer, intent(inout) :: k
    type(model_data), intent(inout) :: d
    integer :: m
    real(dp) :: u(3), e(3, 2)
    d%c0(b) = k + 1
    d%nc(b) = joint_ndof(jt%kind)
    u = jt%axis/norm2(jt%axis); e = axis_normals(jt%axis)
    select case (trim(jt%kind))
    case ('revolute'); call put(1, prim_revolute, u)
    case ('prismatic'); call put(1, prim_prismatic, u)
    case ('cylindrical'); call put(1, prim_prismatic, u); call put(2, prim_revolute, u)
    case ('universal')
      call put(1, prim_revolute, u)
      if (any(jt%axis2 /= unset)) then
        call put(2, prim_revolute, jt%axis2/norm2(jt%axis2))
      else
        call put(2, prim_revolute, e(:, 1))
      end if
    case ('planar')
      call put(1, prim_prismatic, e(:, 1)); call put(2, prim_prismatic, e(:, 2)); call put(3, prim_revolute, u)
    case ('spherical')
      do m = 1, 3
        call put(m, prim_revolute, unit_axes(:, m))
      end do
    case ('free')
      do m = 1, 3
        call put(m, prim_prismatic, unit_axes(:, m)); call put(3 + m, prim_revolute, unit_axes(:, m))
      end do
    end select
    do m = 1, d%nc(b)
      d%cbody(k + m) = b; d%cgrp(k + m) = b
      if (d%nc(b) == 1) then
        d%qname(k + m) = trim(jt%name) // '.q'
        d%qdname(k + m) = trim(jt%name) // '.qd'
      else
        d%qname(k + m) = trim(jt%name) // '.q' // itoa(m)
        d%qdname(k + m) = trim(jt%name) // '.qd' // itoa(m)
      end if
    end do
    k = k + d%nc(b)
  contains
    subroutine put(i, prim, axis)
      integer, intent(in) :: i, prim
      real(dp), intent(in) :: axis(3)
      d%axis(:, k + i) = axis; d%prim(k + i) = prim
    end subroutine put
  end subroutine add_joint

  !> Two unit normals of an axis, the one rule for a joint's in-plane directions: the
  !> coordinate axis least aligned with it (the first on a tie) made normal to it, then the
  !> unit axis crossed with that (axis z: x, then y).
  pure function axis_normals(axis) result(e)
    real(dp), intent(in) :: axis(3)
    real(dp) :: e(3, 2), u(3)
    u = axis/norm2(axis)
    e(:, 1) = unit_axes(:, minloc(abs(u), dim=1))
    e(:, 1) = e(:, 1) - dot_product(e(:, 1), u)*u; e(:, 1) = e(:, 1)/norm2(e(:, 1))
    e(:, 2) = cross(u, e(:, 1))
  end function axis_normals

  !> Build beam i of the scene as model body b; its modal coordinates follow index m.
  subroutine add_beam(sc, i, b, m, d, wk, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: i, b
    integer, intent(inout) :: m
    type(model_data), intent(inout) :: d
    type(model_work), intent(inout) :: wk
    type(error_type), allocatable, intent(out) :: error
    type(beam_section) :: sec
    associate(bs => sc%bodies(i))
      sec%e = bs%youngs_modulus; sec%rho = bs%density
      if (bs%shear_modulus /= unset) sec%g = bs%shear_modulus
      if (bs%r_outer /= unset) then
        sec%area = pi*(bs%r_outer**2 - bs%r_inner**2)
        sec%iy = pi/4.0_dp*(bs%r_outer**4 - bs%r_inner**4); sec%iz = sec%iy
        sec%j = pi/2.0_dp*(bs%r_outer**4 - bs%r_inner**4)
      else
        sec%area = bs%area; sec%iy = bs%iy; sec%iz = bs%iz
        if (bs%torsion_constant /= unset) sec%j = bs%torsion_constant
      end if
      call build_beam(bs%length, sec, bs%n_elements, bs%modes_y, bs%modes_z, bs%modes_x, bs%modes_t, &
        & "beam '" // trim(bs%name) // "'", d%flex(b), d%bshape(b), error)
      if (allocated(error)) then
        error%message = sc%bodies(i)%origin%where() // ': ' // error%message; return
      end if
      call add_flexible(bs%name, b, m, d, wk)
    end associate
  end subroutine add_beam

  !> Register flexible body b (its flex data already set): modal coordinates after m.
  subroutine add_flexible(name, b, m, d, wk)
    character(len=*), intent(in) :: name
    integer, intent(in) :: b
    integer, intent(inout) :: m
    type(model_data), intent(inout) :: d
    type(model_work), intent(inout) :: wk
    integer :: k, nmb
    nmb = d%flex(b)%m
    d%flexible(b) = .true.
    d%nm(b) = nmb
    d%a0(b) = m + 1
    d%mass(b) = d%flex(b)%mass
    allocate(wk%fwork(b)%wa(3, 3, 0:nmb), wk%fwork(b)%cr(3, nmb))
    do k = 1, nmb
      d%cbody(m + k) = b; d%cgrp(m + k) = d%nb + b
      d%qname(m + k) = trim(name) // '.a' // itoa(k)
      d%qdname(m + k) = trim(name) // '.ad' // itoa(k)
      d%prim(m + k) = 0; d%axis(:, m + k) = 0.0_dp
    end do
    m = m + nmb
  end subroutine add_flexible

  !> Children lists of every body.
  subroutine fill_children(d)
    type(model_data), intent(inout) :: d
    integer :: b, k, c
    allocate(d%child_ptr(d%nb + 1), d%child_idx(max(d%nb - 1, 1)))
    k = 0
    do b = 1, d%nb
      d%child_ptr(b) = k + 1
      do c = 2, d%nb
        if (d%parent(c) == b) then
          k = k + 1; d%child_idx(k) = c
        end if
      end do
    end do
    d%child_ptr(d%nb + 1) = k + 1
  end subroutine fill_children

  !> Mode shapes at point r (body frame) of flexible body b, where a joint, a marker or a
  !> loop-closing joint's point sits: the one rule for points of flexible bodies. On a beam
  !> the point lies within its length (0 to L along x); on a modal body it is one of the
  !> file's points. `where` names file, line, group and item for the message.
  subroutine flexible_point(d, b, r, where, psi, phi, error)
    type(model_data), intent(in) :: d
    integer, intent(in) :: b
    real(dp), intent(in) :: r(3)
    character(len=*), intent(in) :: where
    real(dp), intent(out) :: psi(:, :), phi(:, :)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: len_b
    integer :: p
    if (d%bshape(b)%ne == 0) then
      do p = 1, d%mnodes(b)%np
        if (norm2(d%mnodes(b)%x(:, p) - r) <= 1.0e-9_dp*max(1.0_dp, norm2(r))) then
          psi = 0.0_dp; phi = 0.0_dp
          psi(:, 1:d%nm(b)) = d%mnodes(b)%psi(:, :, p); phi(:, 1:d%nm(b)) = d%mnodes(b)%phi(:, :, p)
          return
        end if
      end do
      call fatal_error(error, where // ': (' // fmt(r(1)) // ', ' // fmt(r(2)) // ', ' // &
        & fmt(r(3)) // ") is not a point of modal body '" // trim(d%body_name(b)) // "' (joints and markers " // &
        & 'on a modal body must sit on one of its file''s points)'); return
    end if
    len_b = d%bshape(b)%length
    if (r(1) < -1.0e-9_dp*len_b .or. r(1) > len_b*(1.0_dp + 1.0e-9_dp)) then
      call fatal_error(error, where // ': x = ' // fmt(r(1)) // " lies outside beam '" // &
        & trim(d%body_name(b)) // "' (0 to " // fmt(len_b) // ' m along its x axis)'); return
    end if
    psi = 0.0_dp; phi = 0.0_dp
    call beam_point_shapes(d%bshape(b), r, psi(:, 1:d%nm(b)), phi(:, 1:d%nm(b)))
  end subroutine flexible_point

  !> The markers, the prescribed coordinates' mask (set by the base motion's effect), the
  !> modal moments (the undeformed ones when they do not follow the deformation) and the
  !> geometric stiffness (dropped when its effect is off).
  subroutine fill_markers_moments(sc, pos_in, d, wk, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: pos_in(:)
    type(model_data), intent(inout) :: d
    type(model_work), intent(inout) :: wk
    type(error_type), allocatable, intent(out) :: error
    integer :: b
    allocate(d%every(d%nb), d%prescribed(d%n), wk%qx(d%n), wk%qdx(d%n))
    d%every = .true.; d%prescribed = .false.; d%n_prescribed = 0
    d%deformed_moments = sc%effects%deformation_inertia == 'full' .and. any(d%nm > 0)
    do b = 2, d%nb
      if (d%nm(b) > 0 .and. .not. d%deformed_moments) call undeformed_modal_moments(d%flex(b), wk%fwork(b))
      if (allocated(d%flex(b)%kg1) .and. .not. sc%effects%geometric_stiffening) deallocate(d%flex(b)%kg1, d%flex(b)%kg2)
    end do
    call fill_markers(sc, pos_in, d, error)
  end subroutine fill_markers_moments

  !> The markers: body, point, and on a flexible body the point's mode shapes.
  subroutine fill_markers(sc, pos_in, d, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: pos_in(:)
    type(model_data), intent(inout) :: d
    type(error_type), allocatable, intent(out) :: error
    integer :: i, b
    d%markers%n = size(sc%markers)
    allocate(d%markers%name(d%markers%n), d%markers%body(d%markers%n), d%markers%at(3, d%markers%n), &
      & d%markers%psi(3, d%mmax, d%markers%n), d%markers%phi(3, d%mmax, d%markers%n))
    d%markers%psi = 0.0_dp; d%markers%phi = 0.0_dp
    do i = 1, d%markers%n
      d%markers%name(i) = sc%markers(i)%name
      b = pos_in(body_index(sc, sc%markers(i)%body))
      d%markers%body(i) = b
      d%markers%at(:, i) = sc%markers(i)%at
      if (d%nm(b) > 0) then
        call flexible_point(d, b, sc%markers(i)%at, sc%markers(i)%origin%where('at'), &
          & d%markers%psi(:, :, i), d%markers%phi(:, :, i), error); if (allocated(error)) return
      end if
    end do
  end subroutine fill_markers


end module pymr_driver_build
