!> Read a scene from a namelist file, with `--set GROUP.KEY=VALUE` overrides.
!>
!> Every group is read with iostat/iomsg; unknown groups and items are found by a text
!> scan first (pymr_io_namelist_scan), so messages name the file, group, item and line.
!> Overrides are applied by reading '&group key=value /' from an internal file into the
!> same variables after the group was read from the file.
module pymr_io_namelist_input
  use pymr_kinds, only : dp, name_len
  use pymr_error, only : error_type, fatal_error
  use pymr_model_scene, only : scene_t, body_spec, joint_spec, drive_spec, marker_spec, spring_spec, motion_spec, &
    & load_spec, unset, max_modes_input
  use pymr_io_namelist_scan, only : group_scan, scan_file, check_items, itoa, lower
  implicit none
  private
  public :: read_scene

  !> One override: group[sel].text
  type :: override_t
    character(len=name_len) :: group = '', sel = ''
    character(len=:), allocatable :: text, source
    logical :: used = .false.
  end type override_t

  character(len=*), parameter :: known_groups(11) = [character(len=16) :: 'scene', 'integrator', &
    & 'effects', 'body', 'joint', 'drive', 'spring', 'motion', 'load', 'marker', 'output']
  character(len=*), parameter :: items_scene(3) = [character(len=16) :: 'title', 't_end', 'gravity']
  character(len=*), parameter :: items_integrator(12) = [character(len=16) :: 'method', 'h_fast', 'h_slow', &
    & 'adaptive', 'rtol', 'atol', 'h_min', 'h_max', 'n_corrector', 'coupling', 'k_max', 'stability_check']
  character(len=*), parameter :: items_effects(8) = [character(len=20) :: 'gravity', 'joint_drives', &
    & 'modal_damping', 'joint_springs', 'geometric_stiffening', 'base_motion', 'firing_load', 'deformation_inertia']
  character(len=*), parameter :: items_body(20) = [character(len=16) :: 'name', 'kind', 'mass', 'com', 'inertia', &
    & 'length', 'youngs_modulus', 'density', 'r_outer', 'r_inner', 'area', 'iy', 'iz', 'n_elements', 'modes_y', &
    & 'modes_z', 'modal_damping', 'rayleigh_alpha', 'rayleigh_beta', 'modal_file']
  character(len=*), parameter :: items_joint(8) = [character(len=16) :: 'name', 'kind', 'parent', 'child', &
    & 'at', 'axis', 'q0', 'qd0']
  character(len=*), parameter :: items_drive(8) = [character(len=16) :: 'joint', 'coordinate', 'form', &
    & 'offset', 'amplitude', 'frequency', 'phase', 'file']
  character(len=*), parameter :: items_spring(5) = [character(len=16) :: 'joint', 'coordinate', 'stiffness', &
    & 'damping', 'free_position']
  character(len=*), parameter :: items_motion(10) = [character(len=16) :: 'joint', 'coordinate', 'form', &
    & 'offset', 'amplitude', 'frequency', 'phase', 'rate', 'ramp_time', 'file']
  character(len=*), parameter :: items_load(6) = [character(len=16) :: 'marker', 'direction', 'form', 'peak', &
    & 'start', 'duration']
  character(len=*), parameter :: items_marker(3) = [character(len=16) :: 'name', 'body', 'at']
  character(len=*), parameter :: items_output(4) = [character(len=16) :: 'file', 'dt', 'checkpoint_dt', &
    & 'checkpoint_file']

contains

  !> Read `file` into `sc`, applying `overrides` (entries "group.key=value" or
  !> "group[name].key=value", separated by newlines or ';').
  subroutine read_scene(file, overrides, sc, error)
    character(len=*), intent(in) :: file, overrides
    type(scene_t), intent(out) :: sc
    type(error_type), allocatable, intent(out) :: error
    type(group_scan), allocatable :: groups(:)
    type(override_t), allocatable :: ovs(:)
    integer :: u, ios, i
    character(len=256) :: msg

    sc%file = file
    call scan_file(file, groups, error); if (allocated(error)) return
    call check_groups(file, groups, error); if (allocated(error)) return
    call parse_overrides(overrides, ovs, error)
    if (allocated(error)) then
      error%message = file // ': ' // error%message; return
    end if
    open(newunit=u, file=file, status='old', action='read', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, file // ': cannot open: ' // trim(msg)); return
    end if
    call read_scene_group(file, u, groups, ovs, sc, error)
    if (.not. allocated(error)) call read_integrator(file, u, groups, ovs, sc, error)
    if (.not. allocated(error)) call read_effects(file, u, groups, ovs, sc, error)
    if (.not. allocated(error)) call read_output(file, u, groups, ovs, sc, error)
    if (.not. allocated(error)) call read_bodies(file, u, groups, ovs, sc, error)
    if (.not. allocated(error)) call read_joints(file, u, groups, ovs, sc, error)
    if (.not. allocated(error)) call read_drives(file, u, groups, ovs, sc, error)
    if (.not. allocated(error)) call read_springs(file, u, groups, ovs, sc, error)
    if (.not. allocated(error)) call read_motions(file, u, groups, ovs, sc, error)
    if (.not. allocated(error)) call read_loads(file, u, groups, ovs, sc, error)
    if (.not. allocated(error)) call read_markers(file, u, groups, ovs, sc, error)
    close(u)
    if (allocated(error)) then
      if (index(error%message, '--set ') == 1) error%message = file // ': ' // error%message
      return
    end if
    ! one step given: it serves both rates
    if (sc%integrator%h_fast == unset) sc%integrator%h_fast = sc%integrator%h_slow
    if (sc%integrator%h_slow == unset) sc%integrator%h_slow = sc%integrator%h_fast
    do i = 1, size(ovs)
      if (.not. ovs(i)%used) then
        call fatal_error(error, file // ': --set ' // ovs(i)%source // ': no &' // trim(ovs(i)%group) // &
          & ' group named ''' // trim(ovs(i)%sel) // ''''); return
      end if
    end do
  end subroutine read_scene

  !> Unknown groups, unknown items, single groups given twice, required groups missing.
  subroutine check_groups(file, groups, error)
    character(len=*), intent(in) :: file
    type(group_scan), intent(in) :: groups(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: i
    character(len=:), allocatable :: list
    do i = 1, size(groups)
      if (.not. any(known_groups == groups(i)%name)) then
        list = 'scene, integrator, effects, body, joint, drive, spring, motion, load, marker, output'
        call fatal_error(error, file // ': &' // trim(groups(i)%name) // ' (line ' // itoa(groups(i)%line) // &
          & '): unknown group (known: ' // list // ')'); return
      end if
      select case (trim(groups(i)%name))
      case ('scene'); call check_items(file, groups(i), items_scene, error)
      case ('integrator'); call check_items(file, groups(i), items_integrator, error)
      case ('effects'); call check_items(file, groups(i), items_effects, error)
      case ('body'); call check_items(file, groups(i), items_body, error)
      case ('joint'); call check_items(file, groups(i), items_joint, error)
      case ('drive'); call check_items(file, groups(i), items_drive, error)
      case ('spring'); call check_items(file, groups(i), items_spring, error)
      case ('motion'); call check_items(file, groups(i), items_motion, error)
      case ('load'); call check_items(file, groups(i), items_load, error)
      case ('marker'); call check_items(file, groups(i), items_marker, error)
      case ('output'); call check_items(file, groups(i), items_output, error)
      end select
      if (allocated(error)) return
      select case (trim(groups(i)%name))
      case ('scene', 'integrator', 'effects', 'output')
        if (groups(i)%index > 1) then
          call fatal_error(error, file // ': &' // trim(groups(i)%name) // ' (line ' // itoa(groups(i)%line) &
            & // '): group given twice (only one is allowed)'); return
        end if
      end select
    end do
    if (.not. any(groups%name == 'scene')) then
      call fatal_error(error, file // ': &scene: missing group (it holds title, t_end, gravity)'); return
    end if
    if (.not. any(groups%name == 'integrator')) then
      call fatal_error(error, file // ': &integrator: missing group (it holds method, h_fast, h_slow, ...)')
      return
    end if
    if (.not. any(groups%name == 'body')) then
      call fatal_error(error, file // ': &body: missing group (a scene needs a ground body and at least one more)')
      return
    end if
  end subroutine check_groups

  !> Split "a.b=1; c[x].d=2" into overrides and check their item names.
  subroutine parse_overrides(text, ovs, error)
    character(len=*), intent(in) :: text
    type(override_t), allocatable, intent(out) :: ovs(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: i0, i, n
    character(len=:), allocatable :: entry
    allocate(ovs(0))
    i0 = 1; n = len(text)
    do i = 1, n + 1
      if (i <= n) then
        if (text(i:i) /= ';' .and. text(i:i) /= achar(10)) cycle
      end if
      entry = trim(adjustl(text(i0:i-1)))
      i0 = i + 1
      if (len(entry) == 0) cycle
      call parse_one(entry, ovs, error); if (allocated(error)) return
    end do
  end subroutine parse_overrides

  subroutine parse_one(entry, ovs, error)
    character(len=*), intent(in) :: entry
    type(override_t), allocatable, intent(inout) :: ovs(:)
    type(error_type), allocatable, intent(out) :: error
    type(override_t) :: ov
    integer :: dot, eq, lb, rb
    character(len=:), allocatable :: key
    eq = index(entry, '=')
    dot = index(entry(1:max(eq-1, 0)), '.')
    if (eq == 0 .or. dot == 0) then
      call fatal_error(error, '--set ' // entry // ': expected GROUP.KEY=VALUE or GROUP[NAME].KEY=VALUE')
      return
    end if
    lb = index(entry(1:dot), '['); rb = index(entry(1:dot), ']')
    if (lb > 0 .and. rb > lb) then
      ov%group = lower(entry(1:lb-1)); ov%sel = entry(lb+1:rb-1)
    else
      ov%group = lower(entry(1:dot-1))
    end if
    key = lower(trim(adjustl(entry(dot+1:eq-1))))
    ov%source = entry
    if (.not. any(known_groups == ov%group)) then
      call fatal_error(error, '--set ' // entry // ': unknown group ''' // trim(ov%group) // ''''); return
    end if
    if (.not. key_known(ov%group, key)) then
      call fatal_error(error, '--set ' // entry // ': &' // trim(ov%group) // ': unknown item ''' // key // '''')
      return
    end if
    select case (trim(ov%group))
    case ('body', 'joint', 'drive', 'spring', 'motion', 'load', 'marker')
      if (len_trim(ov%sel) == 0) then
        call fatal_error(error, '--set ' // entry // ': &' // trim(ov%group) // ' is a repeated group: name one as ' &
          & // trim(ov%group) // '[NAME].' // key); return
      end if
    case default
      if (len_trim(ov%sel) > 0) then
        call fatal_error(error, '--set ' // entry // ': &' // trim(ov%group) // ' is not repeated: write ' // &
          & trim(ov%group) // '.' // key); return
      end if
    end select
    ov%text = '&' // trim(ov%group) // ' ' // entry(dot+1:) // ' /'
    ovs = [ovs, ov]
  end subroutine parse_one

  logical function key_known(group, key)
    character(len=*), intent(in) :: group, key
    integer :: p
    character(len=name_len) :: base
    p = index(key, '(')
    base = key
    if (p > 0) base = key(1:p-1)
    select case (trim(group))
    case ('scene'); key_known = any(items_scene == base)
    case ('integrator'); key_known = any(items_integrator == base)
    case ('effects'); key_known = any(items_effects == base)
    case ('body'); key_known = any(items_body == base)
    case ('joint'); key_known = any(items_joint == base)
    case ('drive'); key_known = any(items_drive == base)
    case ('spring'); key_known = any(items_spring == base)
    case ('motion'); key_known = any(items_motion == base)
    case ('load'); key_known = any(items_load == base)
    case ('marker'); key_known = any(items_marker == base)
    case ('output'); key_known = any(items_output == base)
    case default; key_known = .false.
    end select
  end function key_known

  !> Message for a failed namelist read of group occurrence `idx`. gfortran names the
  !> token it could not read; the item whose value holds that token is named.
  subroutine read_failed(file, group, groups, idx, msg, error)
    character(len=*), intent(in) :: file, group, msg
    type(group_scan), intent(in) :: groups(:)
    integer, intent(in) :: idx
    type(error_type), allocatable, intent(out) :: error
    integer :: i, k, hit, nhit
    character(len=:), allocatable :: token, where
    where = file // ': &' // group // ' #' // itoa(idx) // ' (line ' // itoa(group_line(groups, group, idx)) // ')'
    k = index(msg, 'object name ', back=.true.)
    token = ''
    if (k > 0) token = trim(adjustl(msg(k + 12:)))
    if (len(token) > 1) then
      if (token(1:1) == "'" .or. token(1:1) == '"') token = token(2:len(token) - 1)
    end if
    nhit = 0; hit = 0
    do i = 1, size(groups)
      if (groups(i)%name /= group .or. groups(i)%index /= idx) cycle
      do k = 1, size(groups(i)%items)
        if (len(token) > 0 .and. index(groups(i)%values(k), token) > 0) then
          nhit = nhit + 1
          if (nhit == 1) hit = k
        end if
      end do
      if (nhit >= 1 .and. hit > 0) then
        call fatal_error(error, where // ': ' // trim(groups(i)%items(hit)) // ': cannot read the value ' // &
          & trim(groups(i)%values(hit)) // ' (wrong type, or more values than the item holds)'); return
      end if
    end do
    call fatal_error(error, where // ': cannot read a value (wrong type or too many values): ' // trim(msg))
  end subroutine read_failed

  !> Message for a failed override read.
  subroutine override_failed(ov, error)
    type(override_t), intent(in) :: ov
    type(error_type), allocatable, intent(out) :: error
    call fatal_error(error, '--set ' // ov%source // ': cannot read the value (wrong type, or more values ' // &
      & 'than the item holds)')
  end subroutine override_failed

  !> Line of occurrence idx of group.
  integer function group_line(groups, group, idx)
    type(group_scan), intent(in) :: groups(:)
    character(len=*), intent(in) :: group
    integer, intent(in) :: idx
    integer :: i
    group_line = 0
    do i = 1, size(groups)
      if (groups(i)%name == group .and. groups(i)%index == idx) group_line = groups(i)%line
    end do
  end function group_line

  subroutine read_scene_group(file, u, groups, ovs, sc, error)
    character(len=*), intent(in) :: file
    integer, intent(in) :: u
    type(group_scan), intent(in) :: groups(:)
    type(override_t), intent(inout) :: ovs(:)
    type(scene_t), intent(inout) :: sc
    type(error_type), allocatable, intent(out) :: error
    character(len=256) :: title
    real(dp) :: t_end, gravity(3)
    integer :: ios, i
    character(len=256) :: msg
    namelist /scene/ title, t_end, gravity
    title = sc%title; t_end = sc%t_end; gravity = sc%gravity
    rewind(u)
    read(u, nml=scene, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call read_failed(file, 'scene', groups, 1, msg, error); return
    end if
    do i = 1, size(ovs)
      if (ovs(i)%group /= 'scene') cycle
      read(ovs(i)%text, nml=scene, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call override_failed(ovs(i), error); return
      end if
      ovs(i)%used = .true.
    end do
    sc%title = title; sc%t_end = t_end; sc%gravity = gravity
  end subroutine read_scene_group

  subroutine read_integrator(file, u, groups, ovs, sc, error)
    character(len=*), intent(in) :: file
    integer, intent(in) :: u
    type(group_scan), intent(in) :: groups(:)
    type(override_t), intent(inout) :: ovs(:)
    type(scene_t), intent(inout) :: sc
    type(error_type), allocatable, intent(out) :: error
    character(len=16) :: method, coupling
    real(dp) :: h_fast, h_slow, rtol, atol, h_min, h_max
    logical :: adaptive
    integer :: n_corrector, k_max, ios, i
    logical :: stability_check
    character(len=256) :: msg
    namelist /integrator/ method, h_fast, h_slow, adaptive, rtol, atol, h_min, h_max, n_corrector, coupling, k_max, &
      & stability_check
    associate(s => sc%integrator)
      coupling = s%coupling
      method = s%method; h_fast = s%h_fast; h_slow = s%h_slow; adaptive = s%adaptive
      rtol = s%rtol; atol = s%atol; h_min = s%h_min; h_max = s%h_max; n_corrector = s%n_corrector
      k_max = s%k_max; stability_check = s%stability_check
    end associate
    rewind(u)
    read(u, nml=integrator, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call read_failed(file, 'integrator', groups, 1, msg, error); return
    end if
    do i = 1, size(ovs)
      if (ovs(i)%group /= 'integrator') cycle
      read(ovs(i)%text, nml=integrator, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call override_failed(ovs(i), error); return
      end if
      ovs(i)%used = .true.
    end do
    associate(s => sc%integrator)
      s%coupling = lower(coupling)
      s%method = lower(method); s%h_fast = h_fast; s%h_slow = h_slow; s%adaptive = adaptive
      s%rtol = rtol; s%atol = atol; s%h_min = h_min; s%h_max = h_max; s%n_corrector = n_corrector
      s%k_max = k_max; s%stability_check = stability_check
    end associate
  end subroutine read_integrator

  subroutine read_effects(file, u, groups, ovs, sc, error)
    character(len=*), intent(in) :: file
    integer, intent(in) :: u
    type(group_scan), intent(in) :: groups(:)
    type(override_t), intent(inout) :: ovs(:)
    type(scene_t), intent(inout) :: sc
    type(error_type), allocatable, intent(out) :: error
    logical :: gravity, joint_drives, modal_damping, joint_springs, geometric_stiffening, base_motion, firing_load
    character(len=16) :: deformation_inertia
    integer :: ios, i
    character(len=256) :: msg
    namelist /effects/ gravity, joint_drives, modal_damping, joint_springs, geometric_stiffening, base_motion, &
      & firing_load, deformation_inertia
    deformation_inertia = sc%effects%deformation_inertia
    gravity = sc%effects%gravity; joint_drives = sc%effects%joint_drives
    modal_damping = sc%effects%modal_damping; joint_springs = sc%effects%joint_springs
    geometric_stiffening = sc%effects%geometric_stiffening; base_motion = sc%effects%base_motion
    firing_load = sc%effects%firing_load
    if (any(groups%name == 'effects')) then
      rewind(u)
      read(u, nml=effects, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call read_failed(file, 'effects', groups, 1, msg, error); return
      end if
    end if
    do i = 1, size(ovs)
      if (ovs(i)%group /= 'effects') cycle
      read(ovs(i)%text, nml=effects, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call override_failed(ovs(i), error); return
      end if
      ovs(i)%used = .true.
    end do
    sc%effects%gravity = gravity; sc%effects%joint_drives = joint_drives
    sc%effects%modal_damping = modal_damping; sc%effects%joint_springs = joint_springs
    sc%effects%geometric_stiffening = geometric_stiffening; sc%effects%base_motion = base_motion
    sc%effects%firing_load = firing_load
    sc%effects%deformation_inertia = lower(deformation_inertia)
    sc%effects%given_firing_load = effect_given('firing_load')
    sc%effects%given_joint_drives = effect_given('joint_drives')
    sc%effects%given_modal_damping = effect_given('modal_damping')
    sc%effects%given_joint_springs = effect_given('joint_springs')
    sc%effects%given_base_motion = effect_given('base_motion')
  contains
    !> The item was written in &effects or by a --set effects.ITEM=...
    logical function effect_given(item)
      character(len=*), intent(in) :: item
      integer :: g, j
      effect_given = .false.
      do g = 1, size(groups)
        if (groups(g)%name /= 'effects') cycle
        effect_given = effect_given .or. any(groups(g)%items == item)
      end do
      do j = 1, size(ovs)
        if (ovs(j)%group /= 'effects') cycle
        effect_given = effect_given .or. index(lower(ovs(j)%text), '&effects ' // item) == 1
      end do
    end function effect_given
  end subroutine read_effects

  subroutine read_output(path, u, groups, ovs, sc, error)
    character(len=*), intent(in) :: path
    integer, intent(in) :: u
    type(group_scan), intent(in) :: groups(:)
    type(override_t), intent(inout) :: ovs(:)
    type(scene_t), intent(inout) :: sc
    type(error_type), allocatable, intent(out) :: error
    character(len=512) :: file, checkpoint_file
    real(dp) :: dt, checkpoint_dt
    integer :: ios, i
    character(len=256) :: msg
    namelist /output/ file, dt, checkpoint_dt, checkpoint_file
    file = sc%output_file; dt = sc%output_dt
    checkpoint_dt = sc%checkpoint_dt; checkpoint_file = sc%checkpoint_file
    if (any(groups%name == 'output')) then
      rewind(u)
      read(u, nml=output, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call read_failed(path, 'output', groups, 1, msg, error); return
      end if
    end if
    do i = 1, size(ovs)
      if (ovs(i)%group /= 'output') cycle
      read(ovs(i)%text, nml=output, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call override_failed(ovs(i), error); return
      end if
      ovs(i)%used = .true.
    end do
    sc%output_file = file; sc%output_dt = dt
    sc%checkpoint_dt = checkpoint_dt; sc%checkpoint_file = checkpoint_file
  end subroutine read_output

  subroutine read_bodies(file, u, groups, ovs, sc, error)
    character(len=*), intent(in) :: file
    integer, intent(in) :: u
    type(group_scan), intent(in) :: groups(:)
    type(override_t), intent(inout) :: ovs(:)
    type(scene_t), intent(inout) :: sc
    type(error_type), allocatable, intent(out) :: error
    character(len=name_len) :: name
    character(len=16) :: kind
    real(dp) :: mass, com(3), inertia(6), length, youngs_modulus, density, r_outer, r_inner, area, iy, iz
    real(dp) :: modal_damping(max_modes_input), rayleigh_alpha, rayleigh_beta
    integer :: n_elements, modes_y, modes_z
    character(len=512) :: modal_file
    integer :: ios, i, k, n
    character(len=256) :: msg
    type(body_spec) :: d
    namelist /body/ name, kind, mass, com, inertia, length, youngs_modulus, density, r_outer, r_inner, area, &
      & iy, iz, n_elements, modes_y, modes_z, modal_damping, rayleigh_alpha, rayleigh_beta, modal_file
    n = count(groups%name == 'body')
    allocate(sc%bodies(n))
    rewind(u)
    do k = 1, n
      name = d%name; kind = d%kind; mass = d%mass; com = d%com; inertia = d%inertia
      length = d%length; youngs_modulus = d%youngs_modulus; density = d%density; r_outer = d%r_outer
      r_inner = d%r_inner; area = d%area; iy = d%iy; iz = d%iz; n_elements = d%n_elements
      modes_y = d%modes_y; modes_z = d%modes_z; modal_damping = d%modal_damping; modal_file = d%modal_file
      rayleigh_alpha = d%rayleigh_alpha; rayleigh_beta = d%rayleigh_beta
      read(u, nml=body, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call read_failed(file, 'body', groups, k, msg, error); return
      end if
      do i = 1, size(ovs)
        if (ovs(i)%group /= 'body' .or. ovs(i)%sel /= name) cycle
        read(ovs(i)%text, nml=body, iostat=ios, iomsg=msg)
        if (ios /= 0) then
          call override_failed(ovs(i), error); return
        end if
        ovs(i)%used = .true.
      end do
      sc%bodies(k) = body_spec(name=name, kind=lower(kind), mass=mass, com=com, inertia=inertia, length=length, &
        & youngs_modulus=youngs_modulus, density=density, r_outer=r_outer, r_inner=r_inner, area=area, iy=iy, &
        & iz=iz, n_elements=n_elements, modes_y=modes_y, modes_z=modes_z, modal_damping=modal_damping, &
        & rayleigh_alpha=rayleigh_alpha, rayleigh_beta=rayleigh_beta, modal_file=modal_file, &
        & line=group_line(groups, 'body', k))
    end do
  end subroutine read_bodies

  subroutine read_joints(file, u, groups, ovs, sc, error)
    character(len=*), intent(in) :: file
    integer, intent(in) :: u
    type(group_scan), intent(in) :: groups(:)
    type(override_t), intent(inout) :: ovs(:)
    type(scene_t), intent(inout) :: sc
    type(error_type), allocatable, intent(out) :: error
    character(len=name_len) :: name, parent, child
    character(len=16) :: kind
    real(dp) :: at(3), axis(3), q0(6), qd0(6)
    integer :: ios, i, k, n
    character(len=256) :: msg
    type(joint_spec) :: d
    namelist /joint/ name, kind, parent, child, at, axis, q0, qd0
    n = count(groups%name == 'joint')
    allocate(sc%joints(n))
    rewind(u)
    do k = 1, n
      name = d%name; kind = d%kind; parent = d%parent; child = d%child
      at = d%at; axis = d%axis; q0 = d%q0; qd0 = d%qd0
      read(u, nml=joint, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call read_failed(file, 'joint', groups, k, msg, error); return
      end if
      do i = 1, size(ovs)
        if (ovs(i)%group /= 'joint' .or. ovs(i)%sel /= name) cycle
        read(ovs(i)%text, nml=joint, iostat=ios, iomsg=msg)
        if (ios /= 0) then
          call override_failed(ovs(i), error); return
        end if
        ovs(i)%used = .true.
      end do
      sc%joints(k) = joint_spec(name=name, kind=lower(kind), parent=parent, child=child, at=at, axis=axis, &
        & q0=q0, qd0=qd0, line=group_line(groups, 'joint', k))
    end do
  end subroutine read_joints

  subroutine read_drives(path, u, groups, ovs, sc, error)
    character(len=*), intent(in) :: path
    integer, intent(in) :: u
    type(group_scan), intent(in) :: groups(:)
    type(override_t), intent(inout) :: ovs(:)
    type(scene_t), intent(inout) :: sc
    type(error_type), allocatable, intent(out) :: error
    character(len=name_len) :: joint
    character(len=16) :: form
    character(len=512) :: file
    integer :: coordinate
    real(dp) :: offset, amplitude, frequency, phase
    integer :: ios, i, k, n
    character(len=256) :: msg
    type(drive_spec) :: d
    namelist /drive/ joint, coordinate, form, offset, amplitude, frequency, phase, file
    n = count(groups%name == 'drive')
    allocate(sc%drives(n))
    rewind(u)
    do k = 1, n
      joint = d%joint; coordinate = d%coordinate; form = d%form; offset = d%offset; amplitude = d%amplitude
      frequency = d%frequency; phase = d%phase; file = d%file
      read(u, nml=drive, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call read_failed(path, 'drive', groups, k, msg, error); return
      end if
      do i = 1, size(ovs)
        if (ovs(i)%group /= 'drive' .or. ovs(i)%sel /= joint) cycle
        read(ovs(i)%text, nml=drive, iostat=ios, iomsg=msg)
        if (ios /= 0) then
          call override_failed(ovs(i), error); return
        end if
        ovs(i)%used = .true.
      end do
      sc%drives(k) = drive_spec(joint=joint, coordinate=coordinate, form=lower(form), offset=offset, &
        & amplitude=amplitude, frequency=frequency, phase=phase, file=file, line=group_line(groups, 'drive', k))
    end do
  end subroutine read_drives

  subroutine read_springs(file, u, groups, ovs, sc, error)
    character(len=*), intent(in) :: file
    integer, intent(in) :: u
    type(group_scan), intent(in) :: groups(:)
    type(override_t), intent(inout) :: ovs(:)
    type(scene_t), intent(inout) :: sc
    type(error_type), allocatable, intent(out) :: error
    character(len=name_len) :: joint
    integer :: coordinate
    real(dp) :: stiffness, damping, free_position
    integer :: ios, i, k, n
    character(len=256) :: msg
    type(spring_spec) :: d
    namelist /spring/ joint, coordinate, stiffness, damping, free_position
    n = count(groups%name == 'spring')
    allocate(sc%springs(n))
    rewind(u)
    do k = 1, n
      joint = d%joint; coordinate = d%coordinate; stiffness = d%stiffness; damping = d%damping
      free_position = d%free_position
      read(u, nml=spring, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call read_failed(file, 'spring', groups, k, msg, error); return
      end if
      do i = 1, size(ovs)
        if (ovs(i)%group /= 'spring' .or. ovs(i)%sel /= joint) cycle
        read(ovs(i)%text, nml=spring, iostat=ios, iomsg=msg)
        if (ios /= 0) then
          call override_failed(ovs(i), error); return
        end if
        ovs(i)%used = .true.
      end do
      sc%springs(k) = spring_spec(joint=joint, coordinate=coordinate, stiffness=stiffness, damping=damping, &
        & free_position=free_position, line=group_line(groups, 'spring', k))
    end do
  end subroutine read_springs

  subroutine read_motions(path, u, groups, ovs, sc, error)
    character(len=*), intent(in) :: path
    integer, intent(in) :: u
    type(group_scan), intent(in) :: groups(:)
    type(override_t), intent(inout) :: ovs(:)
    type(scene_t), intent(inout) :: sc
    type(error_type), allocatable, intent(out) :: error
    character(len=name_len) :: joint
    character(len=16) :: form
    character(len=512) :: file
    integer :: coordinate
    real(dp) :: offset, amplitude, frequency, phase, rate, ramp_time
    integer :: ios, i, k, n
    character(len=256) :: msg
    type(motion_spec) :: d
    namelist /motion/ joint, coordinate, form, offset, amplitude, frequency, phase, rate, ramp_time, file
    n = count(groups%name == 'motion')
    allocate(sc%motions(n))
    rewind(u)
    do k = 1, n
      joint = d%joint; coordinate = d%coordinate; form = d%form; offset = d%offset; amplitude = d%amplitude
      frequency = d%frequency; phase = d%phase; rate = d%rate; ramp_time = d%ramp_time; file = d%file
      read(u, nml=motion, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call read_failed(path, 'motion', groups, k, msg, error); return
      end if
      do i = 1, size(ovs)
        if (ovs(i)%group /= 'motion' .or. ovs(i)%sel /= joint) cycle
        read(ovs(i)%text, nml=motion, iostat=ios, iomsg=msg)
        if (ios /= 0) then
          call override_failed(ovs(i), error); return
        end if
        ovs(i)%used = .true.
      end do
      sc%motions(k) = motion_spec(joint=joint, coordinate=coordinate, form=lower(form), offset=offset, &
        & amplitude=amplitude, frequency=frequency, phase=phase, rate=rate, ramp_time=ramp_time, file=file, &
        & line=group_line(groups, 'motion', k))
    end do
  end subroutine read_motions

  subroutine read_loads(file, u, groups, ovs, sc, error)
    character(len=*), intent(in) :: file
    integer, intent(in) :: u
    type(group_scan), intent(in) :: groups(:)
    type(override_t), intent(inout) :: ovs(:)
    type(scene_t), intent(inout) :: sc
    type(error_type), allocatable, intent(out) :: error
    character(len=name_len) :: marker
    character(len=16) :: form
    real(dp) :: direction(3), peak, start, duration
    integer :: ios, i, k, n
    character(len=256) :: msg
    type(load_spec) :: d
    namelist /load/ marker, direction, form, peak, start, duration
    n = count(groups%name == 'load')
    allocate(sc%loads(n))
    rewind(u)
    do k = 1, n
      marker = d%marker; direction = d%direction; form = d%form; peak = d%peak; start = d%start
      duration = d%duration
      read(u, nml=load, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call read_failed(file, 'load', groups, k, msg, error); return
      end if
      do i = 1, size(ovs)
        if (ovs(i)%group /= 'load' .or. ovs(i)%sel /= marker) cycle
        read(ovs(i)%text, nml=load, iostat=ios, iomsg=msg)
        if (ios /= 0) then
          call override_failed(ovs(i), error); return
        end if
        ovs(i)%used = .true.
      end do
      sc%loads(k) = load_spec(marker=marker, direction=direction, form=lower(form), peak=peak, start=start, &
        & duration=duration, line=group_line(groups, 'load', k))
    end do
  end subroutine read_loads

  subroutine read_markers(file, u, groups, ovs, sc, error)
    character(len=*), intent(in) :: file
    integer, intent(in) :: u
    type(group_scan), intent(in) :: groups(:)
    type(override_t), intent(inout) :: ovs(:)
    type(scene_t), intent(inout) :: sc
    type(error_type), allocatable, intent(out) :: error
    character(len=name_len) :: name, body
    real(dp) :: at(3)
    integer :: ios, i, k, n
    character(len=256) :: msg
    type(marker_spec) :: d
    namelist /marker/ name, body, at
    n = count(groups%name == 'marker')
    allocate(sc%markers(n))
    rewind(u)
    do k = 1, n
      name = d%name; body = d%body; at = d%at
      read(u, nml=marker, iostat=ios, iomsg=msg)
      if (ios /= 0) then
        call read_failed(file, 'marker', groups, k, msg, error); return
      end if
      do i = 1, size(ovs)
        if (ovs(i)%group /= 'marker' .or. ovs(i)%sel /= name) cycle
        read(ovs(i)%text, nml=marker, iostat=ios, iomsg=msg)
        if (ios /= 0) then
          call override_failed(ovs(i), error); return
        end if
        ovs(i)%used = .true.
      end do
      sc%markers(k) = marker_spec(name=name, body=body, at=at, line=group_line(groups, 'marker', k))
    end do
  end subroutine read_markers
end module pymr_io_namelist_input
