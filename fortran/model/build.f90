!> Validate a scene and build the model from it: bodies in parent-before-child order,
!> joints expanded into one-coordinate primitives, the effect plan, work arrays.
module pymr_model_build
  use pymr_kinds, only : dp, name_len, pi
  use pymr_error, only : error_type, fatal_error, error_list
  use pymr_model_scene, only : scene_t, body_spec, joint_spec, joint_ndof, unset, body_items
  use pymr_io_item_table, only : origin_t
  use pymr_model_types, only : model_data, prim_revolute, prim_prismatic, effect_gravity, effect_joint_drives, &
    & effect_modal_damping, effect_joint_springs, effect_geometric_stiffening, effect_base_motion, n_effects, &
    & effect_firing_load, effect_deformation_inertia, &
    & motion_sine, motion_spinup, motion_table
  use pymr_model_time_table, only : spline_setup
  use pymr_io_table_file, only : read_time_table
  use pymr_model_beam_modes, only : build_beam, beam_point_shapes, beam_point_load_stiffness
  use pymr_io_modal_file, only : read_modal_file
  use pymr_model_flexbody, only : flex_data, modal_nodes, undeformed_modal_moments
  use pymr_model_spatial, only : unit_axes
  use pymr_model_names, only : name_index
  use pymr_io_text_file, only : scene_relative
  use pymr_model, only : model_t
  use pymr_io_text, only : itoa, fmt
  implicit none
  private
  public :: build_model, check_scene

contains

  !> Check the scene, then build `model`; errors name file, group and item.
  subroutine build_model(sc, model, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(out) :: model
    type(error_type), allocatable, intent(out) :: error
    integer, allocatable :: order(:), inboard(:)
    call check_scene(sc, error); if (allocated(error)) return
    call tree_order(sc, order, inboard, error); if (allocated(error)) return
    call fill_model(sc, order, inboard, model%d, error)
  end subroutine build_model


  !> Index of the body called `name`, 0 if none.
  integer function body_index(sc, name)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: name
    integer :: i
    body_index = 0
    do i = 1, size(sc%bodies)
      if (sc%bodies(i)%name == name) then
        body_index = i; return
      end if
    end do
  end function body_index

  !> Every check that needs no tree: values, names, kinds, integrator and output settings.
  subroutine check_scene(sc, error)
    type(scene_t), intent(in) :: sc
    type(error_type), allocatable, intent(out) :: error
    type(error_list) :: errs
    integer :: n0
    call check_settings(sc, errs)
    n0 = errs%n
    call check_unique_names(sc, errs)
    ! names given twice make every reference to them ambiguous: nothing more to check
    if (errs%n > n0) then
      call errs%take(error); return
    end if
    call check_bodies(sc, errs)
    call check_joints(sc, errs)
    call check_loads_markers(sc, errs)
    call errs%take(error)
  end subroutine check_scene

  !> Bodies, joints and markers each have names of their own.
  subroutine check_unique_names(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: i, j
    call first_repeat(sc%bodies%name, i, j)
    if (j > 0) then
      call errs%add(sc%bodies(j)%origin%where('name') // ': used by another &body too (line ' // &
        & itoa(sc%bodies(i)%origin%line) // ')')
    end if
    call first_repeat(sc%joints%name, i, j)
    if (j > 0) then
      call errs%add(sc%joints(j)%origin%where('name') // ': used by another &joint too (line ' // &
        & itoa(sc%joints(i)%origin%line) // ')')
    end if
    call first_repeat(sc%markers%name, i, j)
    if (j > 0) then
      call errs%add(sc%markers(j)%origin%where('name') // ': used by another &marker too (line ' // &
        & itoa(sc%markers(i)%origin%line) // ')')
    end if
  end subroutine check_unique_names

  subroutine check_settings(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    real(dp) :: hf, hs, r
    character(len=:), allocatable :: step_item
    ! a rule on both steps names the one the scene (or a --set) gave last
    step_item = 'h_slow'
    associate(o => sc%integrator%origin)
      if (o%given('h_fast') .and. (.not. o%given('h_slow') .or. (o%line_of('h_fast') < 0 .and. &
        & o%line_of('h_slow') >= 0))) step_item = 'h_fast'
    end associate
    if (sc%scene%t_end == unset) then
      call errs%add(sc%scene%origin%where('t_end') // ': missing (the end time of the run in s)'); return
    end if
    associate(s => sc%integrator)
      hf = s%h_fast; hs = s%h_slow
      if (hf == unset .and. hs == unset) then
        call errs%add(w('h_slow') // ': missing (the step in s; h_fast for the modal coordinates)'); return
      end if
      if (hf == unset) hf = hs
      if (hs == unset) hs = hf
      r = hs/hf
      if (r < 1.0_dp - 1.0e-9_dp .or. abs(r - nint(r)) > 1.0e-9_dp*r) then
        if (step_item == 'h_slow') then
          call errs%add(w(step_item) // ': must be an integer multiple of h_fast, got h_slow/h_fast = ' // fmt(r))
        else
          call errs%add(w(step_item) // ': h_slow must be an integer multiple of h_fast, got h_slow/h_fast = ' // &
            & fmt(r))
        end if
        return
      end if
      if (trim(s%method) == 'single' .and. nint(r) /= 1) then
        call errs%add(w(step_item) // ": method 'single' takes one step for all coordinates: set h_fast = " &
          & // "h_slow, or method = 'multirate'"); return
      end if
      if (trim(s%method) == 'multirate') then
        if (s%n_corrector /= 1) then
          call errs%add(w('n_corrector') // ": multirate uses PECE (n_corrector = 1)"); return
        end if
      end if
      if (.not. s%adaptive .and. sc%output%dt > 0.0_dp) then
        r = sc%output%dt/hs
        if (abs(r - nint(r)) > 1.0e-9_dp*r .or. nint(r) < 1) then
          call errs%add(sc%output%origin%where('dt') // ': must be a multiple of the step h_slow = ' // fmt(hs) &
            & // ' s, got ' // fmt(sc%output%dt)); return
        end if
      end if
    end associate
  contains
    function w(item) result(s)
      character(len=*), intent(in) :: item
      character(len=:), allocatable :: s
      s = sc%integrator%origin%where(item)
    end function w
  end subroutine check_settings

  subroutine check_bodies(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    type(error_type), allocatable :: error
    integer :: i, ng
    real(dp) :: a(3, 3), e(3)
    ng = 0
    each_bodies: do i = 1, size(sc%bodies)
      associate(b => sc%bodies(i))
        if (len_trim(b%name) == 0) then
          call errs%add(b%origin%where('name') // ': missing'); cycle each_bodies
        end if
        call check_kind_items(b, error)
        if (allocated(error)) then
          call errs%add(error%message); cycle each_bodies
        end if
        select case (trim(b%kind))
        case ('ground')
          ng = ng + 1
          if (ng == 2) call errs%add(b%origin%where('kind') // ": a second ground (the tree has one fixed base): " // &
            & 'join this body to the first ground with a fixed joint')
        case ('rigid')
          if (b%mass == unset) then
            call errs%add(sc%bodies(i)%origin%where('mass') // ': missing (kg)'); cycle each_bodies
          end if
          if (any(b%inertia == unset)) then
            call errs%add(sc%bodies(i)%origin%where('inertia') // ': missing (6 values: Ixx Iyy Izz Ixy Ixz Iyz)')
            cycle each_bodies
          end if
          a = inertia_matrix(b%inertia)
          call eig3(a, e)
          if (minval(e) <= 0.0_dp) then
            call errs%add(sc%bodies(i)%origin%where('inertia') // ': not positive definite (smallest principal ' // &
              & 'moment ' // fmt(minval(e)) // ' kg m^2)'); cycle each_bodies
          end if
          if (2*maxval(e) > sum(e)*(1.0_dp + 1.0e-12_dp)) then
            call errs%add(sc%bodies(i)%origin%where('inertia') // ': principal moments ' // fmt(e(1)) // ', ' // &
              & fmt(e(2)) // ', ' // fmt(e(3)) // ' break the triangle inequality (no real body has them)'); cycle each_bodies
          end if
        case ('beam')
          call check_beam(sc, i, error)
          if (allocated(error)) then
            call errs%add(error%message); cycle each_bodies
          end if
        case ('modal')
          if (len_trim(b%modal_file) == 0) then
            call errs%add(sc%bodies(i)%origin%where('modal_file') // ': missing (the file with the mode data)')
            cycle each_bodies
          end if
          call check_damping(sc, i, error)
          if (allocated(error)) then
            call errs%add(error%message); cycle each_bodies
          end if
        case default
          call errs%add(sc%bodies(i)%origin%where('kind') // ": missing ('ground', 'rigid', 'beam' or 'modal')")
          cycle each_bodies
        end select
      end associate
    end do each_bodies
    if (ng == 0) then
      call errs%add(sc%file // ": &body: no body has kind = 'ground' (the fixed base of the tree)"); return
    end if
    if (size(sc%bodies) < 2) then
      call errs%add(sc%file // ': &body: the scene has only the ground: add a moving body'); return
    end if
  end subroutine check_bodies

  !> Items of a built-in beam.
  subroutine check_beam(sc, i, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: i
    type(error_type), allocatable, intent(out) :: error
    associate(b => sc%bodies(i))
      call positive(b%length, 'length', '(m)'); if (allocated(error)) return
      call positive(b%youngs_modulus, 'youngs_modulus', '(Pa)'); if (allocated(error)) return
      call positive(b%density, 'density', '(kg/m^3)'); if (allocated(error)) return
      if (b%r_outer /= unset) then
        call positive(b%r_outer, 'r_outer', '(m)'); if (allocated(error)) return
        if (b%r_inner >= b%r_outer) then
          call fatal_error(error, b%origin%where('r_inner') // ': must be below r_outer = ' // fmt(b%r_outer) // &
            & ', got ' // fmt(b%r_inner)); return
        end if
        if (b%area /= unset .or. b%iy /= unset .or. b%iz /= unset) then
          call fatal_error(error, b%origin%where('r_outer') // ': give either r_outer (and r_inner) or area, iy ' // &
            & 'and iz'); return
        end if
      else
        if (b%area == unset .and. b%iy == unset .and. b%iz == unset) then
          call fatal_error(error, b%origin%where('r_outer') // ': missing (or give area, iy and iz for the section)')
          return
        end if
        call positive(b%area, 'area', '(m^2)'); if (allocated(error)) return
        call positive(b%iy, 'iy', '(m^4)'); if (allocated(error)) return
        call positive(b%iz, 'iz', '(m^4)'); if (allocated(error)) return
      end if
      if (b%modes_y > 2*b%n_elements) then
        call fatal_error(error, b%origin%where('modes_y') // ': must be 0 to 2*n_elements = ' // itoa(2*b%n_elements) // &
          & ', got ' // itoa(b%modes_y)); return
      end if
      if (b%modes_z > 2*b%n_elements) then
        call fatal_error(error, b%origin%where('modes_z') // ': must be 0 to 2*n_elements = ' // itoa(2*b%n_elements) // &
          & ', got ' // itoa(b%modes_z)); return
      end if
      call check_damping(sc, i, error); if (allocated(error)) return
    end associate
  contains
    subroutine positive(x, item, unit)
      real(dp), intent(in) :: x
      character(len=*), intent(in) :: item, unit
      if (x == unset) call fatal_error(error, sc%bodies(i)%origin%where(item) // ': missing ' // unit)
    end subroutine positive
  end subroutine check_beam

  subroutine check_joints(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    type(error_type), allocatable :: error
    integer :: i, j, ip, ic
    character(len=name_len) :: children(size(sc%joints))
    each_joints: do i = 1, size(sc%joints)
      associate(jt => sc%joints(i))
        if (len_trim(jt%name) == 0) then
          call errs%add(jt%origin%where('name') // ': missing'); cycle each_joints
        end if
        if (joint_ndof(jt%kind) < 0) then
          call errs%add(jt%origin%where('kind') // ": missing ('revolute', 'prismatic', 'fixed', " // &
            & "'spherical' or 'free')"); cycle each_joints
        end if
        call check_coordinate_count(jt, 'q0', error)
        if (allocated(error)) then
          call errs%add(error%message); cycle each_joints
        end if
        call check_coordinate_count(jt, 'qd0', error)
        if (allocated(error)) then
          call errs%add(error%message); cycle each_joints
        end if
        ip = body_index(sc, jt%parent); ic = body_index(sc, jt%child)
        if (ip == 0) then
          call errs%add(sc%joints(i)%origin%where('parent') // ": no &body named '" // trim(jt%parent) // "'")
          cycle each_joints
        end if
        if (ic == 0) then
          call errs%add(sc%joints(i)%origin%where('child') // ": no &body named '" // trim(jt%child) // "'")
          cycle each_joints
        end if
        if (ip == ic) then
          call errs%add(sc%joints(i)%origin%where('child') // ": the joint joins body '" // trim(jt%child) // &
            & "' to itself (a cycle)"); cycle each_joints
        end if
        if (sc%bodies(ic)%kind == 'ground') then
          call errs%add(sc%joints(i)%origin%where('child') // ": '" // trim(jt%child) // &
            & "' is the ground; the ground can only be a parent"); cycle each_joints
        end if
        if (jt%kind == 'revolute' .or. jt%kind == 'prismatic') then
          if (norm2(jt%axis) < 1.0e-12_dp) then
            call errs%add(sc%joints(i)%origin%where('axis') // ': zero length; give a direction in the parent frame')
            cycle each_joints
          end if
        end if
      end associate
    end do each_joints
    ! a joint from a body to itself is reported above, not again as a second parent
    children = sc%joints%child
    where (sc%joints%parent == sc%joints%child) children = ''
    call first_repeat(children, i, j)
    if (j > 0) then
      call errs%add(sc%joints(j)%origin%where('child') // ": body '" // trim(sc%joints(j)%child) // &
        & "' has two parents (also joint '" // trim(sc%joints(i)%name) // "'); a tree allows one"); return
    end if
  end subroutine check_joints

  !> The first repeated non-blank name: i < j, names(i) == names(j), j the smallest such
  !> (sorted once, so O(n log n)); j = 0 if every name is distinct.
  subroutine first_repeat(names, i, j)
    character(len=*), intent(in) :: names(:)
    integer, intent(out) :: i, j
    type(name_index) :: idx
    call idx%build(names)
    call idx%duplicate(i, j)
  end subroutine first_repeat

  !> The item by which a body gives its damping (for messages).
  pure function damping_item(b) result(item)
    type(body_spec), intent(in) :: b
    character(len=:), allocatable :: item
    item = 'modal_damping'
    if (b%origin%given('modal_damping')) return
    if (b%origin%given('rayleigh_alpha')) item = 'rayleigh_alpha'
    if (b%origin%given('rayleigh_beta')) item = 'rayleigh_beta'
  end function damping_item

  !> A body takes the items of its kind only: a beam's mass follows from its density and
  !> section, a rigid body has no elastic items, and so on.
  subroutine check_kind_items(b, error)
    type(body_spec), intent(in) :: b
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: takes
    integer :: k
    takes = body_items(b%kind)
    if (len(takes) == 0) return
    do k = 1, b%origin%n
      if (index(' ' // takes // ' ', ' ' // trim(b%origin%items(k)) // ' ') > 0) cycle
      call fatal_error(error, b%origin%where(trim(b%origin%items(k))) // ': not an item of a ' // trim(b%kind) // &
        & ' body (it takes ' // takes // ')'); return
    end do
  end subroutine check_kind_items

  !> A joint's q0 or qd0, when given, has one value per coordinate of the joint.
  subroutine check_coordinate_count(jt, item, error)
    type(joint_spec), intent(in) :: jt
    character(len=*), intent(in) :: item
    type(error_type), allocatable, intent(out) :: error
    integer :: n
    n = jt%origin%count_of(item)
    if (n > 0 .and. n /= joint_ndof(jt%kind)) then
      call fatal_error(error, jt%origin%where(item) // ': a ' // trim(jt%kind) // ' joint has ' // &
        & itoa(joint_ndof(jt%kind)) // trim(merge(' coordinate ', ' coordinates', joint_ndof(jt%kind) == 1)) // &
        & ', got ' // itoa(n) // ' values')
    end if
  end subroutine check_coordinate_count

  subroutine check_loads_markers(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: i, j, k
    each_drives: do i = 1, size(sc%drives)
      associate(dr => sc%drives(i))
        if (.not. joint_coordinate(dr%origin, dr%joint, dr%coordinate)) cycle each_drives
        if (.not. table_form(dr%origin, dr%form, dr%file, [dr%amplitude, dr%frequency, dr%phase])) cycle each_drives
        if (forgotten(sc%effects%joint_drives, 'joint_drives')) &
          & call errs%add(dr%origin%where() // effect_not_on('the scene gives drives', 'joint_drives'))
      end associate
    end do each_drives
    each_springs: do i = 1, size(sc%springs)
      associate(sp => sc%springs(i))
        if (.not. joint_coordinate(sp%origin, sp%joint, sp%coordinate)) cycle each_springs
        if (forgotten(sc%effects%joint_springs, 'joint_springs')) &
          & call errs%add(sp%origin%where() // effect_not_on('the scene gives springs', 'joint_springs'))
      end associate
    end do each_springs
    each_motions: do i = 1, size(sc%motions)
      associate(mo => sc%motions(i))
        if (.not. joint_coordinate(mo%origin, mo%joint, mo%coordinate)) cycle each_motions
        do j = 1, i - 1
          if (sc%motions(j)%joint == mo%joint .and. sc%motions(j)%coordinate == mo%coordinate) then
            call errs%add(mo%origin%where('coordinate') // ': ' // itoa(mo%coordinate) // " of joint '" // &
              & trim(mo%joint) // "' is already prescribed by &motion #" // itoa(j)); cycle each_motions
          end if
        end do
        if (.not. table_form(mo%origin, mo%form, mo%file, [mo%amplitude, mo%frequency, mo%phase])) cycle each_motions
      end associate
      if (sc%motions(i)%form == 'spinup' .and. sc%motions(i)%ramp_time == unset) then
        call errs%add(sc%motions(i)%origin%where('ramp_time') // ": missing (form 'spinup' needs the ramp time, s)"); cycle each_motions
      end if
      if (forgotten(sc%effects%base_motion, 'base_motion')) &
        & call errs%add(sc%motions(i)%origin%where() // effect_not_on('the scene prescribes motion', 'base_motion'))
    end do each_motions
    each_bodies: do i = 1, size(sc%bodies)
      associate(b => sc%bodies(i))
        if (b%kind /= 'beam' .and. b%kind /= 'modal') cycle
        if (any(b%modal_damping /= unset .and. b%modal_damping /= 0.0_dp) .or. b%rayleigh_alpha /= 0.0_dp .or. &
          & b%rayleigh_beta /= 0.0_dp) then
          if (forgotten(sc%effects%modal_damping, 'modal_damping')) &
            & call errs%add(b%origin%where(damping_item(b)) // effect_not_on('the body gives modal damping', &
            & 'modal_damping'))
        end if
      end associate
    end do each_bodies
    each_loads: do i = 1, size(sc%loads)
      associate(ld => sc%loads(i))
        k = 0
        do j = 1, size(sc%markers)
          if (sc%markers(j)%name == ld%marker) k = j
        end do
        if (k == 0) then
          call errs%add(ld%origin%where('marker') // ": no &marker named '" // trim(ld%marker) // "'"); cycle each_loads
        end if
        if (norm2(ld%direction) < 1.0e-12_dp) then
          call errs%add(ld%origin%where('direction') // ': missing or zero (a direction in the body frame of the ' // &
            & "marker's body)"); cycle each_loads
        end if
        if (ld%duration == unset) then
          call errs%add(ld%origin%where('duration') // ': missing (the pulse length, s)'); cycle each_loads
        end if
        if (forgotten(sc%effects%firing_load, 'firing_load')) &
          & call errs%add(ld%origin%where() // effect_not_on('the scene gives loads', 'firing_load'))
      end associate
    end do each_loads
    if (sc%effects%geometric_stiffening .and. .not. any(sc%bodies%kind == 'beam')) then
      call errs%add(sc%effects%origin%where('geometric_stiffening') // ': the scene has no beam (only built-in ' // &
        & "beams, kind = 'beam', carry a geometric stiffness)"); return
    end if
    each_markers: do i = 1, size(sc%markers)
      if (len_trim(sc%markers(i)%name) == 0) then
        call errs%add(sc%markers(i)%origin%where('name') // ': missing'); cycle each_markers
      end if
      if (body_index(sc, sc%markers(i)%body) == 0) then
        call errs%add(sc%markers(i)%origin%where('body') // ": no &body named '" // trim(sc%markers(i)%body) // "'"); cycle each_markers
      end if
    end do each_markers
  contains
    !> An effect whose data the scene gives is off without being turned off on purpose.
    logical function forgotten(on, effect)
      logical, intent(in) :: on
      character(len=*), intent(in) :: effect
      forgotten = .not. on .and. .not. sc%effects%origin%given(effect)
    end function forgotten

    !> ": the scene gives X but &effects E is not on: ..." for a forgotten effect.
    function effect_not_on(what, effect) result(s)
      character(len=*), intent(in) :: what, effect
      character(len=:), allocatable :: s
      s = ': ' // what // ' but &effects ' // effect // ' is not on: set ' // effect // ' = .true. in &effects ' // &
        & '(or .false. to leave it out on purpose)'
    end function effect_not_on

    !> The named joint exists and has the coordinate (else the error is added).
    logical function joint_coordinate(o, joint, coordinate) result(ok)
      type(origin_t), intent(in) :: o
      character(len=*), intent(in) :: joint
      integer, intent(in) :: coordinate
      integer :: jj, kk, ndof
      ok = .false.
      if (len_trim(joint) == 0) then
        call errs%add(o%where('joint') // ': missing (the joint it acts on)'); return
      end if
      kk = 0
      do jj = 1, size(sc%joints)
        if (sc%joints(jj)%name == joint) kk = jj
      end do
      if (kk == 0) then
        call errs%add(o%where('joint') // ": no &joint named '" // trim(joint) // "'"); return
      end if
      ndof = joint_ndof(sc%joints(kk)%kind)
      if (coordinate < 1 .or. coordinate > ndof) then
        call errs%add(o%where('coordinate') // ': joint ''' // trim(joint) // ''' has ' // itoa(ndof) // &
          & trim(merge(' coordinate ', ' coordinates', ndof == 1)) // ', got ' // itoa(coordinate)); return
      end if
      ok = .true.
    end function joint_coordinate

    !> A group's form and file agree (else the error is added).
    logical function table_form(o, form, file, sine_items) result(ok)
      type(origin_t), intent(in) :: o
      character(len=*), intent(in) :: form, file
      real(dp), intent(in) :: sine_items(3)
      type(error_type), allocatable :: error
      call check_table_form(o, form, file, sine_items, error)
      ok = .not. allocated(error)
      if (.not. ok) call errs%add(error%message)
    end function table_form
  end subroutine check_loads_markers

  !> A group's form 'table' needs a file and no sine items; other forms take no file.
  !> `o` is the group's origin; `sine_items` are its amplitude, frequency and phase.
  subroutine check_table_form(o, form, file, sine_items, error)
    type(origin_t), intent(in) :: o
    character(len=*), intent(in) :: form, file
    real(dp), intent(in) :: sine_items(3)
    type(error_type), allocatable, intent(out) :: error
    character(len=*), parameter :: names(3) = [character(len=9) :: 'amplitude', 'frequency', 'phase']
    integer :: k
    if (trim(form) == 'table') then
      if (len_trim(file) == 0) then
        call fatal_error(error, o%where('file') // ": missing (form 'table' reads the history from a file of " // &
          & "'time value' lines)"); return
      end if
      do k = 1, 3
        if (sine_items(k) /= 0.0_dp) then
          call fatal_error(error, o%where(trim(names(k))) // ": not used by form 'table' (the file gives " // &
            & 'the history; offset adds a constant)'); return
        end if
      end do
    else if (len_trim(file) > 0) then
      call fatal_error(error, o%where('file') // ": only form 'table' reads a file (form is '" // trim(form) // &
        & "')"); return
    end if
  end subroutine check_table_form

  !> Modal damping of body i: fractions in [0, 1) given contiguously from the first mode;
  !> Rayleigh coefficients >= 0.
  subroutine check_damping(sc, i, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: i
    type(error_type), allocatable, intent(out) :: error
    integer :: ng
    associate(b => sc%bodies(i))
      ng = count(b%modal_damping /= unset)
      if (b%kind == 'beam' .and. ng > 1 .and. ng /= b%modes_y + b%modes_z) then
        call fatal_error(error, b%origin%where('modal_damping') // ': give one value or one per mode (' // &
          & itoa(b%modes_y + b%modes_z) // ' modes), got ' // itoa(ng)); return
      end if
    end associate
  end subroutine check_damping

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
  subroutine fill_model(sc, order, inboard, d, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: order(:), inboard(:)
    type(model_data), intent(out) :: d
    type(error_type), allocatable, intent(out) :: error
    integer :: nb, b, i, j, k, m, nmod, nmb, pos_in(size(order))
    type(flex_data), allocatable :: mfd(:)
    type(modal_nodes), allocatable :: mnd(:)
    nb = size(order)
    do b = 1, nb
      pos_in(order(b)) = b
    end do
    d%nb = nb
    d%nj = 0; nmod = 0; d%mmax = 0
    allocate(mfd(nb), mnd(nb))
    do b = 2, nb
      d%nj = d%nj + joint_ndof(sc%joints(inboard(order(b)))%kind)
      associate(bs => sc%bodies(order(b)))
        nmb = 0
        if (bs%kind == 'beam') nmb = bs%modes_y + bs%modes_z
        if (bs%kind == 'modal') then
          call read_modal_file(scene_relative(sc%file, trim(bs%modal_file)), mfd(b), mnd(b), error)
          if (allocated(error)) then
            error%message = sc%bodies(order(b))%origin%where() // ': modal_file: ' // error%message; return
          end if
          nmb = mfd(b)%m
        end if
        nmod = nmod + nmb
        d%mmax = max(d%mmax, nmb)
      end associate
    end do
    d%n = d%nj + nmod
    associate(n => d%n, mx => d%mmax)
      allocate(d%body_name(nb), d%joint_name(nb), d%parent(nb), d%c0(nb), d%nc(nb), d%mass(nb), d%com(3, nb), &
        & d%inertia(3, 3, nb), d%at(3, nb), d%prim(n), d%cbody(n), d%cgrp(n), d%axis(3, n), d%qname(n), &
        & d%qdname(n), d%flexible(nb), d%nm(nb), d%a0(nb), d%flex(nb), d%fwork(nb), d%bshape(nb), d%mnodes(nb), &
        & d%att_psi(3, mx, nb), d%att_phi(3, mx, nb), d%cm(6, mx, nb), d%mva(6, mx, nb), d%wam(mx, nb))
    end associate
    d%parent = 0; d%c0 = 1; d%nc = 0; d%mass = 0.0_dp; d%com = 0.0_dp; d%inertia = 0.0_dp; d%at = 0.0_dp
    d%joint_name = ''; d%flexible = .false.; d%nm = 0; d%a0 = d%n + 1
    d%att_psi = 0.0_dp; d%att_phi = 0.0_dp; d%cm = 0.0_dp; d%mva = 0.0_dp; d%wam = 0.0_dp
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
        call add_beam(sc, i, b, m, d, error); if (allocated(error)) return
      else if (sc%bodies(i)%kind == 'modal') then
        d%flex(b) = mfd(b); d%mnodes(b) = mnd(b)
        call add_flexible(sc%bodies(i)%name, b, m, d)
      else
        d%mass(b) = sc%bodies(i)%mass
        d%com(:, b) = sc%bodies(i)%com
        d%inertia(:, :, b) = inertia_matrix(sc%bodies(i)%inertia)
      end if
      if (d%nm(b) > 0) then
        call set_damping(sc, i, d%flex(b), error); if (allocated(error)) return
      end if
    end do
    call fill_children(d)
    allocate(d%in_fast(nb))
    d%in_fast(1) = .false.
    do b = 2, nb
      d%in_fast(b) = d%flexible(b) .or. d%in_fast(d%parent(b))
    end do
    do b = 2, nb
      if (d%nm(d%parent(b)) > 0) then
        call flexible_point(sc, d, d%parent(b), d%at(:, b), "joint '" // trim(d%joint_name(b)) // "'", &
          & d%att_psi(:, :, b), d%att_phi(:, :, b), error); if (allocated(error)) return
      end if
    end do
    call fill_loads_markers(sc, pos_in, d, error); if (allocated(error)) return
    allocate(d%rot(3, 3, nb), d%pos(3, nb), d%vel(6, nb), d%acc(6, nb), d%s(6, d%n), d%i6(6, 6, nb), &
      & d%w(6, nb), d%ic(6, 6, nb), d%wc(6, nb), d%mm(d%n, d%n), d%lf(d%n, d%n), d%p(d%n), d%tau(d%n))
    d%i6 = 0.0_dp; d%w = 0.0_dp; d%ic = 0.0_dp; d%wc = 0.0_dp; d%mm = 0.0_dp; d%tau = 0.0_dp; d%s = 0.0_dp
  end subroutine fill_model

  !> Expand joint jt of body b into primitives, coordinates k+1 ... (k is advanced).
  subroutine add_joint(jt, b, k, d)
    type(joint_spec), intent(in) :: jt
    integer, intent(in) :: b
    integer, intent(inout) :: k
    type(model_data), intent(inout) :: d
    integer :: m
    d%c0(b) = k + 1
    d%nc(b) = joint_ndof(jt%kind)
    select case (trim(jt%kind))
    case ('revolute', 'prismatic')
      d%axis(:, k + 1) = jt%axis/norm2(jt%axis)
      d%prim(k + 1) = merge(prim_revolute, prim_prismatic, jt%kind == 'revolute')
    case ('spherical')
      do m = 1, 3
        d%axis(:, k + m) = unit_axes(:, m); d%prim(k + m) = prim_revolute
      end do
    case ('free')
      do m = 1, 3
        d%axis(:, k + m) = unit_axes(:, m); d%prim(k + m) = prim_prismatic
        d%axis(:, k + 3 + m) = unit_axes(:, m); d%prim(k + 3 + m) = prim_revolute
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
  end subroutine add_joint

  !> Build beam i of the scene as model body b; its modal coordinates follow index m.
  subroutine add_beam(sc, i, b, m, d, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: i, b
    integer, intent(inout) :: m
    type(model_data), intent(inout) :: d
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: area, iy, iz
    associate(bs => sc%bodies(i))
      if (bs%r_outer /= unset) then
        area = pi*(bs%r_outer**2 - bs%r_inner**2)
        iy = pi/4.0_dp*(bs%r_outer**4 - bs%r_inner**4); iz = iy
      else
        area = bs%area; iy = bs%iy; iz = bs%iz
      end if
      call build_beam(bs%length, bs%youngs_modulus, bs%density, area, iy, iz, bs%n_elements, bs%modes_y, &
        & bs%modes_z, "beam '" // trim(bs%name) // "'", d%flex(b), d%bshape(b), error)
      if (allocated(error)) then
        error%message = sc%bodies(i)%origin%where() // ': ' // error%message; return
      end if
      call add_flexible(bs%name, b, m, d)
    end associate
  end subroutine add_beam

  !> Register flexible body b (its flex data already set): modal coordinates after m.
  subroutine add_flexible(name, b, m, d)
    character(len=*), intent(in) :: name
    integer, intent(in) :: b
    integer, intent(inout) :: m
    type(model_data), intent(inout) :: d
    integer :: k, nmb
    nmb = d%flex(b)%m
    d%flexible(b) = .true.
    d%nm(b) = nmb
    d%a0(b) = m + 1
    d%mass(b) = d%flex(b)%mass
    allocate(d%fwork(b)%wa(3, 3, 0:nmb), d%fwork(b)%cr(3, nmb))
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

  !> Mode shapes at point r (body frame) of flexible body b; the point must lie on the beam.
  subroutine flexible_point(sc, d, b, r, what, psi, phi, error)
    type(scene_t), intent(in) :: sc
    type(model_data), intent(in) :: d
    integer, intent(in) :: b
    real(dp), intent(in) :: r(3)
    character(len=*), intent(in) :: what
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
      call fatal_error(error, sc%file // ': ' // what // ': at: (' // fmt(r(1)) // ', ' // fmt(r(2)) // ', ' // &
        & fmt(r(3)) // ") is not a point of modal body '" // trim(d%body_name(b)) // "' (joints and markers " // &
        & 'on a modal body must sit on one of its file''s points)'); return
    end if
    len_b = d%bshape(b)%length
    if (r(1) < -1.0e-9_dp*len_b .or. r(1) > len_b*(1.0_dp + 1.0e-9_dp)) then
      call fatal_error(error, sc%file // ': ' // what // ': at: x = ' // fmt(r(1)) // " lies outside beam '" // &
        & trim(d%body_name(b)) // "' (0 to " // fmt(len_b) // ' m along its x axis)'); return
    end if
    psi = 0.0_dp; phi = 0.0_dp
    call beam_point_shapes(d%bshape(b), r, psi(:, 1:d%nm(b)), phi(:, 1:d%nm(b)))
  end subroutine flexible_point

  subroutine fill_loads_markers(sc, pos_in, d, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: pos_in(:)
    type(model_data), intent(inout) :: d
    type(error_type), allocatable, intent(out) :: error
    integer :: i, j, b
    real(dp), allocatable :: phi(:, :)
    character(len=:), allocatable :: where_file
    d%effect_on(effect_gravity) = sc%effects%gravity
    d%effect_on(effect_joint_drives) = sc%effects%joint_drives .and. size(sc%drives) > 0
    d%effect_on(effect_modal_damping) = sc%effects%modal_damping .and. any(d%nm > 0)
    d%effect_on(effect_joint_springs) = sc%effects%joint_springs .and. size(sc%springs) > 0
    d%effect_on(effect_geometric_stiffening) = sc%effects%geometric_stiffening
    d%effect_on(effect_base_motion) = sc%effects%base_motion .and. size(sc%motions) > 0
    d%effect_on(effect_firing_load) = sc%effects%firing_load .and. size(sc%loads) > 0
    d%effect_on(effect_deformation_inertia) = sc%effects%deformation_inertia == 'full' .and. any(d%nm > 0)
    if (.not. d%effect_on(effect_deformation_inertia)) then
      do b = 2, d%nb
        if (d%nm(b) > 0) call undeformed_modal_moments(d%flex(b), d%fwork(b))
      end do
    end if
    ! the plan: active effects in evaluation order (loads first; base motion last)
    d%n_plan = 0
    do i = 1, n_effects
      if (.not. d%effect_on(i)) cycle
      d%n_plan = d%n_plan + 1
      d%plan(d%n_plan) = i
    end do
    allocate(d%every(d%nb))
    d%every = .true.
    d%gravity = sc%scene%gravity
    d%n_springs = 0
    if (d%effect_on(effect_joint_springs)) d%n_springs = size(sc%springs)
    allocate(d%spring_coord(d%n_springs), d%spring_par(3, d%n_springs))
    do i = 1, d%n_springs
      d%spring_coord(i) = coordinate_index(sc%springs(i)%joint, sc%springs(i)%coordinate)
      d%spring_par(:, i) = [sc%springs(i)%stiffness, sc%springs(i)%damping, sc%springs(i)%free_position]
    end do
    d%n_prescribed = 0
    if (d%effect_on(effect_base_motion)) d%n_prescribed = size(sc%motions)
    allocate(d%pres_coord(d%n_prescribed), d%pres_form(d%n_prescribed), d%pres_par(6, d%n_prescribed), &
      & d%qx(d%n), d%qdx(d%n))
    ! tables: one per tabulated drive or motion, read and (motions) splined once
    allocate(d%tables(count(sc%drives%form == 'table') + count(sc%motions%form == 'table')), &
      & d%drive_table(size(sc%drives)), d%pres_table(d%n_prescribed))
    d%drive_table = 0; d%pres_table = 0
    j = 0
    do i = 1, size(sc%drives)
      if (sc%drives(i)%form /= 'table' .or. .not. d%effect_on(effect_joint_drives)) cycle
      j = j + 1
      d%drive_table(i) = j
      call read_time_table(scene_relative(sc%file, trim(sc%drives(i)%file)), sc%drives(i)%origin%where('file'), &
        & d%tables(j)%t, d%tables(j)%y, error)
      if (allocated(error)) return
    end do
    do i = 1, d%n_prescribed
      if (sc%motions(i)%form /= 'table') cycle
      j = j + 1
      d%pres_table(i) = j
      where_file = sc%motions(i)%origin%where('file')
      call read_time_table(scene_relative(sc%file, trim(sc%motions(i)%file)), where_file, d%tables(j)%t, &
        & d%tables(j)%y, error)
      if (allocated(error)) return
      call spline_setup(d%tables(j), where_file, error); if (allocated(error)) return
    end do
    do i = 1, d%n_prescribed
      associate(mo => sc%motions(i))
        d%pres_coord(i) = coordinate_index(mo%joint, mo%coordinate)
        d%pres_form(i) = motion_sine
        if (mo%form == 'spinup') d%pres_form(i) = motion_spinup
        if (mo%form == 'table') d%pres_form(i) = motion_table
        d%pres_par(:, i) = [mo%offset, mo%amplitude, mo%frequency, mo%phase, mo%rate, mo%ramp_time]
      end associate
    end do
    if (.not. d%effect_on(effect_geometric_stiffening)) then
      do b = 2, d%nb
        if (allocated(d%flex(b)%kg1)) deallocate(d%flex(b)%kg1, d%flex(b)%kg2)
      end do
    end if
    ! bodies whose joint sits on a stiffened beam: the beam carries their axial load to its root
    allocate(d%child_kg(d%nb), d%kgc(d%mmax, d%mmax, d%nb))
    d%child_kg = .false.
    do b = 2, d%nb
      if (.not. allocated(d%flex(d%parent(b))%kg1)) cycle
      d%child_kg(b) = .true.
      call beam_point_load_stiffness(d%bshape(d%parent(b)), d%at(1, b), &
        & d%kgc(1:d%nm(d%parent(b)), 1:d%nm(d%parent(b)), b))
    end do
    d%n_drives = size(sc%drives)
    allocate(d%drive_coord(d%n_drives), d%drive_par(4, d%n_drives))
    do i = 1, d%n_drives
      d%drive_coord(i) = coordinate_index(sc%drives(i)%joint, sc%drives(i)%coordinate)
      d%drive_par(:, i) = [sc%drives(i)%offset, sc%drives(i)%amplitude, sc%drives(i)%frequency, sc%drives(i)%phase]
    end do
    d%n_markers = size(sc%markers)
    allocate(d%marker_name(d%n_markers), d%marker_body(d%n_markers), d%marker_at(3, d%n_markers), &
      & d%marker_psi(3, d%mmax, d%n_markers), phi(3, d%mmax))
    d%marker_psi = 0.0_dp
    do i = 1, d%n_markers
      d%marker_name(i) = sc%markers(i)%name
      b = pos_in(body_index(sc, sc%markers(i)%body))
      d%marker_body(i) = b
      d%marker_at(:, i) = sc%markers(i)%at
      if (d%nm(b) > 0) then
        call flexible_point(sc, d, b, sc%markers(i)%at, "marker '" // trim(sc%markers(i)%name) // "'", &
          & d%marker_psi(:, :, i), phi, error); if (allocated(error)) return
      end if
    end do
    d%n_loads = 0
    if (d%effect_on(effect_firing_load)) d%n_loads = size(sc%loads)
    allocate(d%load_marker(d%n_loads), d%load_dir(3, d%n_loads), d%load_par(3, d%n_loads))
    do i = 1, d%n_loads
      do j = 1, d%n_markers
        if (d%marker_name(j) == sc%loads(i)%marker) d%load_marker(i) = j
      end do
      d%load_dir(:, i) = sc%loads(i)%direction/norm2(sc%loads(i)%direction)
      d%load_par(:, i) = [sc%loads(i)%peak, sc%loads(i)%start, sc%loads(i)%duration]
    end do
  contains
    !> Model coordinate of a joint's coordinate.
    integer function coordinate_index(joint, coordinate)
      character(len=*), intent(in) :: joint
      integer, intent(in) :: coordinate
      integer :: jj
      coordinate_index = 0
      do jj = 1, size(sc%joints)
        if (sc%joints(jj)%name /= joint) cycle
        coordinate_index = d%c0(pos_in(body_index(sc, sc%joints(jj)%child))) + coordinate - 1
      end do
    end function coordinate_index
  end subroutine fill_loads_markers

  !> 3x3 inertia from Ixx Iyy Izz Ixy Ixz Iyz (products enter as given: I(1,2) = Ixy).
  pure function inertia_matrix(v) result(a)
    real(dp), intent(in) :: v(6)
    real(dp) :: a(3, 3)
    a = reshape([v(1), v(4), v(5), v(4), v(2), v(6), v(5), v(6), v(3)], [3, 3])
  end function inertia_matrix

  !> Eigenvalues of a symmetric 3x3 matrix (Jacobi sweeps; enough for input checks).
  pure subroutine eig3(a0, e)
    real(dp), intent(in) :: a0(3, 3)
    real(dp), intent(out) :: e(3)
    real(dp) :: a(3, 3), th, c, s, t, g(3, 3)
    integer :: sweep, p, q, i
    a = a0
    do sweep = 1, 50
      if (abs(a(1, 2)) + abs(a(1, 3)) + abs(a(2, 3)) <= 1.0e-15_dp*sum(abs(a))) exit
      do p = 1, 2
        do q = p + 1, 3
          if (a(p, q) == 0.0_dp) cycle
          th = (a(q, q) - a(p, p))/(2*a(p, q))
          t = sign(1.0_dp, th)/(abs(th) + sqrt(th*th + 1))
          c = 1/sqrt(t*t + 1); s = t*c
          g = 0.0_dp
          do i = 1, 3
            g(i, i) = 1.0_dp
          end do
          g(p, p) = c; g(q, q) = c; g(p, q) = s; g(q, p) = -s
          a = matmul(transpose(g), matmul(a, g))
        end do
      end do
    end do
    e = [a(1, 1), a(2, 2), a(3, 3)]
  end subroutine eig3
end module pymr_model_build
