!> The effects' registry: the model's list of effect records (model/effect.f90), built from
!> the scene's &effects switches and the groups that parametrise them. Each effect has one
!> constructor here and one line in `build_effects`; the line's place is the effect's place
!> in the list, which is the order of evaluation and of the JSON's effect statistics.
module pymr_driver_build_effects
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_model_scene, only : scene_t, moving_load_spec, unset, control_count, big_time, big_length, big_force
  use pymr_model_scene_rules, only : body_index
  use pymr_model_types, only : model_data, model_work
  use pymr_model_time_table, only : spline_setup
  use pymr_io_table_file, only : read_time_table
  use pymr_env_text_file, only : scene_relative
  use pymr_model_beam_modes, only : beam_point_load_stiffness
  use pymr_model_effect, only : effect_slot, effect_t
  use pymr_model_effect_gravity, only : gravity_effect_of
  use pymr_model_effect_joint_drives, only : joint_drive, joint_drives_effect_of
  use pymr_model_effect_modal_damping, only : modal_damping_effect_of
  use pymr_model_effect_joint_springs, only : joint_spring, joint_springs_effect_of
  use pymr_model_effect_geometric_stiffening, only : stiffening_effect_of
  use pymr_model_effect_firing_load, only : point_load, firing_load_effect_of, load_pulse, load_constant, load_sine, &
    & load_table
  use pymr_model_effect_base_motion, only : prescribed_motion, base_motion_effect_of, motion_sine, &
    & motion_spinup, motion_table
  use pymr_model_effect_deformation_inertia, only : deformation_effect_of
  use pymr_model_effect_force_elements, only : force_element, force_elements_effect_of, spring_damper, bushing
  use pymr_model_effect_controls, only : controller, controls_effect_of
  use pymr_model_effect_moving_load, only : moving_load, moving_load_effect_of, travel_exit
  use pymr_env_text, only : fmt
  implicit none
  private
  public :: build_effects

contains

  !> The effects the scene turns on, in evaluation order; `d` gets the prescribed
  !> coordinates' mask.
  subroutine build_effects(sc, order, d, list, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: order(:)
    type(model_data), intent(inout) :: d
    type(effect_slot), allocatable, intent(out) :: list(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: pos_in(size(order)), b
    do b = 1, size(order)
      pos_in(order(b)) = b
    end do
    allocate(list(0))
    if (sc%effects%gravity) call append(list, gravity_effect_of(sc%scene%gravity))
    if (sc%effects%joint_drives .and. size(sc%drives) > 0) then
      call append(list, joint_drives_effect_of(drives_of(sc, pos_in, d, error))); if (allocated(error)) return
    end if
    if (sc%effects%modal_damping .and. any(d%nm > 0)) call append(list, modal_damping_effect_of())
    if (sc%effects%joint_springs .and. size(sc%springs) > 0) call append(list, joint_springs_effect_of(springs_of(sc, pos_in, d)))
    if (sc%effects%geometric_stiffening) call append(list, stiffening_of(sc, d))
    if (sc%effects%firing_load .and. size(sc%loads) > 0) then
      call append(list, firing_load_effect_of(loads_of(sc, d, error))); if (allocated(error)) return
    end if
    if (sc%effects%force_elements .and. size(sc%forces) > 0) then
      call append(list, force_elements_effect_of(force_elements_of(sc, d, error))); if (allocated(error)) return
    end if
    if (control_count(sc) > 0) then
      call append(list, controls_effect_of(controls_of(sc, pos_in, d, error))); if (allocated(error)) return
    end if
    if (sc%effects%moving_loads .and. size(sc%moving_loads) > 0) then
      call append(list, moving_load_effect_of(moving_loads_of(sc, d, error), gravity_of(sc), d))
      if (allocated(error)) return
    end if
    if (sc%effects%base_motion .and. size(sc%motions) > 0) then
      call append(list, base_motion_effect_of(motions_of(sc, pos_in, d, error))); if (allocated(error)) return
    end if
    if (d%deformed_moments) call append(list, deformation_effect_of())
  end subroutine build_effects

  !> Put effect e at the list's end.
  subroutine append(list, e)
    type(effect_slot), allocatable, intent(inout) :: list(:)
    class(effect_t), intent(in) :: e
    type(effect_slot), allocatable :: longer(:)
    integer :: i
    allocate(longer(size(list) + 1))
    do i = 1, size(list)
      call move_alloc(list(i)%e, longer(i)%e)
    end do
    allocate(longer(size(list) + 1)%e, source=e)
    call move_alloc(longer, list)
  end subroutine append

  !> The joint drives, each with its table read when tabulated.
  function drives_of(sc, pos_in, d, error) result(drives)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: pos_in(:)
    type(model_data), intent(in) :: d
    type(error_type), allocatable, intent(out) :: error
    type(joint_drive) :: drives(size(sc%drives))
    integer :: i
    do i = 1, size(sc%drives)
      associate(dr => sc%drives(i))
        drives(i)%coord = coordinate_index(sc, pos_in, d, dr%joint, dr%coordinate)
        drives(i)%offset = dr%offset; drives(i)%amplitude = dr%amplitude
        drives(i)%frequency = dr%frequency; drives(i)%phase = dr%phase
        drives(i)%tabulated = dr%form == 'table'
        if (.not. drives(i)%tabulated) cycle
        call read_time_table(scene_relative(sc%file, trim(dr%file)), dr%origin%where('file'), [big_time, big_force], &
          & drives(i)%table%t, drives(i)%table%y, error)
        if (allocated(error)) return
      end associate
    end do
  end function drives_of

  !> The joint spring-dampers.
  function springs_of(sc, pos_in, d) result(springs)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: pos_in(:)
    type(model_data), intent(in) :: d
    type(joint_spring) :: springs(size(sc%springs))
    integer :: i
    do i = 1, size(sc%springs)
      associate(sp => sc%springs(i))
        springs(i) = joint_spring(coordinate_index(sc, pos_in, d, sp%joint, sp%coordinate), sp%stiffness, &
          & sp%damping, sp%free_position)
      end associate
    end do
  end function springs_of

  !> Geometric stiffness: bodies whose joint sits on a stiffened beam get the stiffness of
  !> their axial load carried to the beam's root; gravity counts when its effect is on.
  function stiffening_of(sc, d) result(e)
    use pymr_model_effect_geometric_stiffening, only : stiffening_effect
    type(scene_t), intent(in) :: sc
    type(model_data), intent(in) :: d
    type(stiffening_effect) :: e
    logical :: child_kg(d%nb)
    real(dp) :: kgc(d%mmax, d%mmax, d%nb), g(3)
    integer :: b
    child_kg = .false.; kgc = 0.0_dp
    do b = 2, d%nb
      if (.not. allocated(d%flex(d%parent(b))%kg1)) cycle
      child_kg(b) = .true.
      call beam_point_load_stiffness(d%bshape(d%parent(b)), d%at(1, b), &
        & kgc(1:d%nm(d%parent(b)), 1:d%nm(d%parent(b)), b))
    end do
    g = 0.0_dp
    if (sc%effects%gravity) g = sc%scene%gravity
    e = stiffening_effect_of(g, child_kg, kgc)
  end function stiffening_of

  !> The point loads: marker, form, kind, frame, unit direction, the items of the form, and
  !> the table read when tabulated.
  function loads_of(sc, d, error) result(loads)
    type(scene_t), intent(in) :: sc
    type(model_data), intent(in) :: d
    type(error_type), allocatable, intent(out) :: error
    type(point_load) :: loads(size(sc%loads))
    integer :: i, j
    do i = 1, size(sc%loads)
      associate(ld => sc%loads(i))
        do j = 1, d%markers%n
          if (d%markers%name(j) == ld%marker) loads(i)%marker = j
        end do
        loads(i)%direction = ld%direction/norm2(ld%direction)
        loads(i)%peak = ld%peak; loads(i)%start = ld%start; loads(i)%duration = ld%duration
        loads(i)%offset = ld%offset; loads(i)%amplitude = ld%amplitude
        loads(i)%frequency = ld%frequency; loads(i)%phase = ld%phase
        loads(i)%torque = ld%kind == 'torque'
        loads(i)%inertial = ld%frame == 'inertial'
        select case (ld%form)
        case ('constant'); loads(i)%form = load_constant
        case ('sine'); loads(i)%form = load_sine
        case ('table'); loads(i)%form = load_table
        case default; loads(i)%form = load_pulse
        end select
        if (loads(i)%form /= load_table) cycle
        call read_time_table(scene_relative(sc%file, trim(ld%file)), ld%origin%where('file'), [big_time, big_force], &
          & loads(i)%table%t, loads(i)%table%y, error)
        if (allocated(error)) return
      end associate
    end do
  end function loads_of

  !> The force elements: kind, marker indices, stiffnesses and dampings (those not given 0)
  !> and free length; a spring-damper's force-deflection table read when it gives one.
  function force_elements_of(sc, d, error) result(elements)
    type(scene_t), intent(in) :: sc
    type(model_data), intent(in) :: d
    type(error_type), allocatable, intent(out) :: error
    type(force_element) :: elements(size(sc%forces))
    integer :: i
    do i = 1, size(sc%forces)
      associate(fs => sc%forces(i), el => elements(i))
        el%kind = merge(spring_damper, bushing, fs%kind == 'spring_damper')
        el%mi = marker_index(d, fs%marker_i)
        el%mj = marker_index(d, fs%marker_j)
        el%k = merge(fs%stiffness, 0.0_dp, fs%stiffness /= unset)
        el%c = merge(fs%damping, 0.0_dp, fs%damping /= unset)
        if (fs%free_length /= unset) el%free_length = fs%free_length
        el%tabulated = len_trim(fs%file) > 0
        if (.not. el%tabulated) cycle
        call read_time_table(scene_relative(sc%file, trim(fs%file)), fs%origin%where('file'), &
          & [big_length, big_force], el%table%t, el%table%y, error, 'deflection, force')
        if (allocated(error)) return
      end associate
    end do
  end function force_elements_of

  !> The controllers: driven coordinate, state coordinate (after the joint coordinates, in
  !> scene order), sensor (a gyro's unit axis and a unit reference normal to it, the rule of
  !> the joints' in-plane directions: the inertial axis least aligned with it), gains, effort
  !> limit and the setpoint's table when given.
  function controls_of(sc, pos_in, d, error) result(controls)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: pos_in(:)
    type(model_data), intent(in) :: d
    type(error_type), allocatable, intent(out) :: error
    type(controller) :: controls(control_count(sc))
    integer :: i
    real(dp) :: u(3)
    do i = 1, size(controls)
      associate(ct => sc%controls(i), c => controls(i))
        c = controller()
        c%coord = coordinate_index(sc, pos_in, d, ct%joint, ct%coordinate)
        c%state = d%nj - size(controls) + i
        c%gyro = ct%sensor == 'orientation'
        if (c%gyro) then
          c%marker = marker_index(d, ct%marker)
          c%axis = ct%axis/norm2(ct%axis)
          u = 0.0_dp; u(minloc(abs(c%axis), dim=1)) = 1.0_dp
          u = u - dot_product(u, c%axis)*c%axis
          c%ref = u/norm2(u)
        end if
        c%kp = ct%kp; c%ki = ct%ki; c%kd = ct%kd; c%setpoint = ct%setpoint
        if (ct%max_effort /= unset) c%max_effort = ct%max_effort
        c%tabulated = len_trim(ct%file) > 0
        if (.not. c%tabulated) cycle
        call read_time_table(scene_relative(sc%file, trim(ct%file)), ct%origin%where('file'), [big_time, big_length], &
          & c%table%t, c%table%y, error)
        if (allocated(error)) return
      end associate
    end do
  end function controls_of
  !> Gravity when its effect is on, else zero.
  pure function gravity_of(sc) result(g)
    type(scene_t), intent(in) :: sc
    real(dp) :: g(3)
    g = 0.0_dp
    if (sc%effects%gravity) g = sc%scene%gravity
  end function gravity_of

  !> The moving loads: body, its length, mass, force and travel, the table read and splined
  !> when tabulated (its first position on the beam, else an error naming the file).
  function moving_loads_of(sc, d, error) result(loads)
    type(scene_t), intent(in) :: sc
    type(model_data), intent(in) :: d
    type(error_type), allocatable, intent(out) :: error
    type(moving_load) :: loads(size(sc%moving_loads))
    integer :: i
    do i = 1, size(sc%moving_loads)
      associate(ml => sc%moving_loads(i), ld => loads(i))
        ld%name = ml%name
        ld%body = findloc(d%body_name, ml%body, 1)
        ld%length = d%bshape(ld%body)%length
        ld%mass = ml%mass; ld%force = ml%force
        ld%start = ml%start; ld%s0 = ml%s0; ld%speed = ml%speed
        ld%tabulated = ml%form == 'table'
        if (ld%tabulated) then
          call read_time_table(scene_relative(sc%file, trim(ml%file)), ml%origin%where('file'), &
            & [big_time, big_length], ld%table%t, ld%table%y, error)
          if (allocated(error)) return
          call spline_setup(ld%table, ml%origin%where('file'), error); if (allocated(error)) return
          if (ld%table%y(1) < 0.0_dp .or. ld%table%y(1) > ld%length) then
            call fatal_error(error, ml%origin%where('file') // ': the first position, ' // fmt(ld%table%y(1)) // &
              & " m, is off the beam '" // trim(ml%body) // "' (0 to its length, " // fmt(ld%length) // ' m)'); return
          end if
        end if
        call check_exit_after_start(ml, ld, error); if (allocated(error)) return
      end associate
    end do
  end function moving_loads_of

  !> A load that leaves its beam (through either end) by the run's start never acts, and no
  !> step could note its exit (it was reported as not having left its body): refused,
  !> naming the item of its travel (start, or the table's file) and the end.
  subroutine check_exit_after_start(ml, ld, error)
    type(moving_load_spec), intent(in) :: ml
    type(moving_load), intent(in) :: ld
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: through
    real(dp) :: te
    logical :: root
    call travel_exit(ld, te, root)
    if (te > 0.0_dp) return
    through = 'its end at ' // fmt(ld%length) // ' m'
    if (root) through = 'its root at 0 m'
    call fatal_error(error, ml%origin%where(trim(merge('file ', 'start', ld%tabulated))) // &
      & ": the load leaves the beam '" // trim(ml%body) // "' (" // through // ') at t = ' // fmt(te) // &
      & ' s, not after the run starts (t = 0): it would never act')
  end subroutine check_exit_after_start

  !> Index of the marker called `name` (0 if none).
  pure integer function marker_index(d, name)
    type(model_data), intent(in) :: d
    character(len=*), intent(in) :: name
    integer :: j
    marker_index = 0
    do j = 1, d%markers%n
      if (d%markers%name(j) == name) marker_index = j
    end do
  end function marker_index

  !> The prescribed coordinates (marked in d), each with its table read and splined when
  !> tabulated.
  function motions_of(sc, pos_in, d, error) result(motions)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: pos_in(:)
    type(model_data), intent(inout) :: d
    type(error_type), allocatable, intent(out) :: error
    type(prescribed_motion) :: motions(size(sc%motions))
    integer :: i
    character(len=:), allocatable :: where_file
    d%n_prescribed = size(sc%motions)
    do i = 1, size(sc%motions)
      associate(mo => sc%motions(i), pm => motions(i))
        pm%coord = coordinate_index(sc, pos_in, d, mo%joint, mo%coordinate)
        d%prescribed(pm%coord) = .true.
        pm%form = motion_sine
        if (mo%form == 'spinup') pm%form = motion_spinup
        if (mo%form == 'table') pm%form = motion_table
        pm%offset = mo%offset; pm%amplitude = mo%amplitude; pm%frequency = mo%frequency; pm%phase = mo%phase
        pm%rate = mo%rate; pm%ramp_time = mo%ramp_time
        if (pm%form /= motion_table) cycle
        where_file = mo%origin%where('file')
        call read_time_table(scene_relative(sc%file, trim(mo%file)), where_file, [big_time, big_length], pm%table%t, &
          & pm%table%y, error)
        if (allocated(error)) return
        call spline_setup(pm%table, where_file, error); if (allocated(error)) return
      end associate
    end do
  end function motions_of

  !> Model coordinate of a joint's coordinate.
  integer function coordinate_index(sc, pos_in, d, joint, coordinate)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: pos_in(:)
    type(model_data), intent(in) :: d
    character(len=*), intent(in) :: joint
    integer, intent(in) :: coordinate
    integer :: j
    coordinate_index = 0
    do j = 1, size(sc%joints)
      if (sc%joints(j)%name /= joint) cycle
      coordinate_index = d%c0(pos_in(body_index(sc, sc%joints(j)%child))) + coordinate - 1
    end do
  end function coordinate_index
end module pymr_driver_build_effects
