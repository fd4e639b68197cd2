!> The rules a scene must keep beyond each item's own type and range (which the item tables
!> in model/scene.f90 state): required items, items of a body's kind, names unique and
!> referring to what exists, one ground, coordinates within their joints, effects turned on
!> for the groups that need them, steps that fit together. check_scene applies them all in
!> one pass and reports up to ten faults, each naming file, line, group and item.
module pymr_model_scene_rules
  use pymr_env_kinds, only : dp, name_len
  use pymr_env_error, only : error_type, fatal_error, error_list
  use pymr_model_scene, only : scene_t, body_spec, joint_spec, force_spec, load_spec, control_spec, moving_load_spec, &
    & sensor_spec, motion_spec, sensor_items, joint_ndof, unset, body_items, beam_mode_count, &
    & closes_loop, body_index, flexible_loop
  use pymr_env_item_table, only : origin_t
  use pymr_model_names, only : name_index
  use pymr_model_beam_modes, only : dense_elements, max_banded_modes
  use pymr_integrator_control, only : step_control
  use pymr_env_text, only : itoa, fmt
  use pymr_model_inertia, only : inertia_matrix, eig3
  implicit none
  private
  public :: check_scene, body_index, closes_loop

contains

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
    call check_output(sc, errs)
    call check_static_start(sc, errs)
    call errs%take(error)
  end subroutine check_scene

  !> A static start settles the flexible bodies' modes and the joints marked settle: a
  !> scene with neither has nothing for it to do, which is no start the user meant.
  subroutine check_static_start(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    if (sc%scene%start /= 'static') return
    if (any(sc%bodies%kind == 'beam' .or. sc%bodies%kind == 'modal') .or. any(sc%joints%settle)) return
    call errs%add(sc%scene%origin%where('start') // ": 'static' settles the modes of flexible bodies and the " // &
      & "joints marked settle, and this scene has neither: nothing would settle (start = 'rest', or settle = " // &
      & '.true. on a joint)')
  end subroutine check_static_start

  !> &output quantities must write something beside the time.
  subroutine check_output(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    character(len=:), allocatable :: q
    q = ' ' // trim(sc%output%quantities) // ' '
    if (size(sc%markers) > 0 .or. index(q, ' coordinates ') > 0 .or. index(q, ' reactions ') > 0 .or. &
      & index(q, ' energy ') > 0) return
    call errs%add(sc%output%origin%where('quantities') // ': the scene has no &marker, so ' // &
      & 'these quantities write no column (add coordinates, reactions or energy)')
  end subroutine check_output

  !> Bodies, joints and markers each have names of their own.
  subroutine check_unique_names(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: i, j
    call check_name_characters(sc%bodies%name, sc%bodies%origin, errs)
    call check_name_characters(sc%joints%name, sc%joints%origin, errs)
    call check_name_characters(sc%markers%name, sc%markers%origin, errs)
    call check_name_characters(sc%forces%name, sc%forces%origin, errs)
    call check_name_characters(sc%controls%name, sc%controls%origin, errs)
    call check_name_characters(sc%moving_loads%name, sc%moving_loads%origin, errs)
    call check_name_characters(sc%sensors%name, sc%sensors%origin, errs)
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
    call first_repeat(sc%forces%name, i, j)
    if (j > 0) then
      call errs%add(sc%forces(j)%origin%where('name') // ': used by another &force too (line ' // &
        & itoa(sc%forces(i)%origin%line) // ')')
    end if
    call first_repeat(sc%controls%name, i, j)
    if (j > 0) then
      call errs%add(sc%controls(j)%origin%where('name') // ': used by another &control too (line ' // &
        & itoa(sc%controls(i)%origin%line) // ')')
    end if
    call first_repeat(sc%moving_loads%name, i, j)
    if (j > 0) then
      call errs%add(sc%moving_loads(j)%origin%where('name') // ': used by another &moving_load too (line ' // &
        & itoa(sc%moving_loads(i)%origin%line) // ')')
    end if
    call first_repeat(sc%sensors%name, i, j)
    if (j > 0) then
      call errs%add(sc%sensors(j)%origin%where('name') // ': used by another &sensor too (line ' // &
        & itoa(sc%sensors(i)%origin%line) // ')')
    end if
  end subroutine check_unique_names

  !> Names head the results' columns ("gun.a1", "muzzle.x"): no comma (it would split a CSV
  !> column), no double quote, no control character and no leading blank.
  subroutine check_name_characters(names, origins, errs)
    character(len=*), intent(in) :: names(:)
    type(origin_t), intent(in) :: origins(:)
    type(error_list), intent(inout) :: errs
    integer :: k, c
    do k = 1, size(names)
      if (len_trim(names(k)) > 0 .and. names(k)(1:1) == ' ') then
        ! a column ' lead.x' is read back as no column of the run's (names are trimmed)
        call errs%add(origins(k)%where('name') // ': may not begin with a blank (names head the results'' ' // &
          & 'columns)')
        cycle
      end if
      do c = 1, len_trim(names(k))
        if (names(k)(c:c) == ',' .or. names(k)(c:c) == '"' .or. iachar(names(k)(c:c)) < 32 .or. &
          & iachar(names(k)(c:c)) == 127) then
          call errs%add(origins(k)%where('name') // ': may not hold a comma, a double quote or a control ' // &
            & 'character (names head the results'' columns)')
          exit
        end if
      end do
    end do
  end subroutine check_name_characters

  !> The rules of a method on its steps (r = h_slow/h_fast, an integer; `where`: the step
  !> item's place for messages) and on the scenes it takes.
  subroutine check_method_steps(sc, r, where, errs)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: r
    character(len=*), intent(in) :: where
    type(error_list), intent(inout) :: errs
    associate(s => sc%integrator)
      if (trim(s%method) == 'single' .and. r /= 1) then
        call errs%add(where // ": method 'single' takes one step for all coordinates: set h_fast = " &
          & // "h_slow, or method = 'multirate'"); return
      end if
      if (trim(s%method) == 'auto' .and. r /= 1) then
        call errs%add(where // ": method 'auto' chooses the steps (its candidates start from h_slow): " &
          & // "set h_fast = h_slow or leave it out"); return
      end if
      if (trim(s%method) == 'multirate' .and. s%coupling == 'exponential' .and. flexible_loop(sc)) then
        call errs%add(s%origin%where('coupling') // ": 'exponential' does not take a closed loop through a " // &
          & "flexible body (the loop's constraint leaves the response of its modal coordinates singular, and " // &
          & "their flow cannot be diagonalised): use coupling = 'response'"); return
      end if
      if (s%error_norm == 'amplitude' .and. flexible_loop(sc)) then
        call errs%add(s%origin%where('error_norm') // ": 'amplitude' does not take a closed loop through a " // &
          & "flexible body (the loop turns its modes' rates into the joints' motion, which a rate error " // &
          & "weighed by 1/omega leaves uncontrolled): use error_norm = 'state'"); return
      end if
      if (trim(s%method) == 'multirate' .and. s%coupling == 'exponential' .and. r /= 1) then
        call errs%add(where // ": coupling 'exponential' takes no fast step (the fast coordinates move by " // &
          & "their exact flow): h_slow is its step; set h_fast = h_slow or leave it out"); return
      end if
    end associate
  end subroutine check_method_steps

  !> Items of the solver that only some runs use, refused where this run would ignore them:
  !> an order other than 4 with 'abm4', the 'adams' corrector's fixed-point iteration with
  !> another formula, fixed steps or multirate, and the articulated-body algorithm with
  !> multirate (its couplings partition M itself). Their defaults pass (a resolved scene
  !> writes every item).
  subroutine check_solver_items(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    associate(s => sc%integrator, o => sc%integrator%origin)
      if (s%formula == 'abm4' .and. o%given('order') .and. s%order /= 4) then
        call errs%add(o%where('order') // ": formula 'abm4' (the paper's) is of order 4; orders 0 (variable) " // &
          & "to 12 need formula = 'adams' with adaptive steps at one rate"); return
      end if
      if (s%corrector /= 'newton' .and. (s%formula == 'abm4' .or. .not. s%adaptive .or. trim(s%method) == 'multirate')) &
        & then
        call errs%add(o%where('corrector') // ": iterates the corrector of formula 'adams' (adaptive, " // &
          & "single-rate); this run takes n_corrector corrections a step: leave it out"); return
      end if
      if (trim(s%dynamics) == 'articulated' .and. trim(s%method) == 'multirate') then
        call errs%add(o%where('dynamics') // ": 'articulated' is how single-rate evaluations solve M qdd = P; " // &
          & "the multirate couplings partition M itself: leave it out, or method = 'single'"); return
      end if
    end associate
  end subroutine check_solver_items

  subroutine check_settings(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    real(dp) :: hf, hs, r
    integer :: n0
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
      n0 = errs%n
      call check_method_steps(sc, nint(r), w(step_item), errs)
      if (errs%n > n0) return
      if (trim(s%method) == 'multirate' .and. .not. s%adaptive .and. nint(r) > 1 .and. hs > sc%scene%t_end) then
        ! its k fast steps would all be taken (and held) far past the end
        call errs%add(w(step_item) // ': a fixed macro step h_slow = ' // fmt(hs) // ' s is longer than the run ' // &
          & '(t_end = ' // fmt(sc%scene%t_end) // ' s): take h_slow <= t_end'); return
      end if
      if (trim(s%method) == 'multirate') then
        if (s%n_corrector /= 1) then
          call errs%add(w('n_corrector') // ": multirate uses PECE (n_corrector = 1)"); return
        end if
      end if
      if (trim(s%method) == 'auto' .and. .not. s%adaptive) then
        call errs%add(w('method') // ": 'auto' chooses among adaptive methods by what a probe of each costs: " // &
          & "set adaptive = .true., or name the method of a fixed-step run ('single' or 'multirate')"); return
      end if
      if (s%formula == 'adams' .and. (.not. s%adaptive .or. trim(s%method) == 'multirate')) then
        call errs%add(w('formula') // ": 'adams' takes adaptive steps at one rate: set adaptive = .true. " // &
          & "and method = 'single', or formula = 'abm4'"); return
      end if
      call check_solver_items(sc, errs); if (errs%n > n0) return
      if (s%h_max > 0.0_dp .and. s%h_min > s%h_max) then
        call errs%add(w('h_min') // ': larger than h_max = ' // fmt(s%h_max) // ' s (got ' // fmt(s%h_min) // &
          & ' s): no step would be allowed'); return
      end if
      if (s%adaptive) then
        call check_step_bounds(sc, errs); if (errs%n > n0) return
      end if
      ! bounded work: a fixed-step run's steps are known before it starts
      if (.not. s%adaptive) call check_step_count(sc, errs, step_item, hf, ' steps of ')
    end associate
  contains
    function w(item) result(s)
      character(len=*), intent(in) :: item
      character(len=:), allocatable :: s
      s = sc%integrator%origin%where(item)
    end function w
  end subroutine check_settings

  !> An adaptive run's step bounds against its span: h_max not below the smallest step
  !> (h_min, or the controller's default), h_min below t_end, and at most max_steps steps
  !> of h_max to t_end.
  subroutine check_step_bounds(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    type(step_control) :: default_control
    real(dp) :: h_lo
    character(len=:), allocatable :: default
    associate(s => sc%integrator, t_end => sc%scene%t_end)
      h_lo = s%h_min; default = ''
      if (h_lo <= 0.0_dp) then
        h_lo = default_control%h_min; default = ' (its default)'
      end if
      if (s%h_max > 0.0_dp .and. s%h_max < h_lo) then
        call errs%add(s%origin%where('h_max') // ': below the smallest adaptive step h_min = ' // fmt(h_lo) // ' s' // default // &
          & ' (got ' // fmt(s%h_max) // ' s): no step would be allowed'); return
      end if
      if (h_lo >= t_end .and. len(default) > 0) then
        call errs%add(sc%scene%origin%where('t_end') // ': shorter than the smallest adaptive step (' // fmt(h_lo) // &
          & ' s, h_min''s default), got ' // fmt(t_end) // ' s'); return
      else if (h_lo >= t_end) then
        call errs%add(s%origin%where('h_min') // ': the smallest adaptive step (' // fmt(h_lo) // &
          & ' s) must be below t_end = ' // fmt(t_end) // ' s'); return
      end if
      if (s%h_max > 0.0_dp) call check_step_count(sc, errs, 'h_max', s%h_max, ' steps of at most ')
    end associate
  end subroutine check_step_bounds

  !> Bounded work: t_end/h steps (h the step `item` sets; `steps` says how they relate, as
  !> ' steps of at most ') at most max_steps (else the error is added).
  subroutine check_step_count(sc, errs, item, h, steps)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    character(len=*), intent(in) :: item, steps
    real(dp), intent(in) :: h
    character(len=:), allocatable :: least
    if (sc%scene%t_end/h <= real(sc%integrator%max_steps, dp)) return
    least = ''
    if (index(steps, 'most') > 0) least = 'at least '
    call errs%add(sc%integrator%origin%where(item) // ': the run would take ' // least // &
      & fmt(sc%scene%t_end/h) // steps // fmt(h) // ' s to t_end = ' // &
      & fmt(sc%scene%t_end) // ' s, more than max_steps = ' // itoa(sc%integrator%max_steps) // &
      & ' (raise it in &integrator if you mean it)')
  end subroutine check_step_count

  subroutine check_bodies(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    type(error_type), allocatable :: error
    integer :: i, ng
    real(dp) :: a(3, 3), e(3)
    ng = 0
    each_bodies: do i = 1, size(sc%bodies)
      associate(b => sc%bodies(i))
        ! counted first: a ground with another fault is still the scene's ground
        if (trim(b%kind) == 'ground') ng = ng + 1
        if (len_trim(b%name) == 0) then
          call errs%add(b%origin%where('name') // ': missing'); cycle each_bodies
        end if
        call check_kind_items(b, error)
        if (allocated(error)) then
          call errs%add(error%message); cycle each_bodies
        end if
        select case (trim(b%kind))
        case ('ground')
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
    if (ng == 0 .and. all(len_trim(sc%bodies%kind) > 0)) then    ! else a kind missing may be the ground's
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
      ! the free nodal values of each field: bending 2 per element (value and slope clamped at
      ! the root), axial and torsion one more (only the value clamped)
      call within('modes_y', b%modes_y, 2*b%n_elements, '2*n_elements'); if (allocated(error)) return
      call within('modes_z', b%modes_z, 2*b%n_elements, '2*n_elements'); if (allocated(error)) return
      call within('modes_x', b%modes_x, 2*b%n_elements + 1, '2*n_elements + 1'); if (allocated(error)) return
      call within('modes_t', b%modes_t, 2*b%n_elements + 1, '2*n_elements + 1'); if (allocated(error)) return
      if (b%n_elements > dense_elements) then
        call banded_within('modes_y', b%modes_y); if (allocated(error)) return
        call banded_within('modes_z', b%modes_z); if (allocated(error)) return
        call banded_within('modes_x', b%modes_x); if (allocated(error)) return
        call banded_within('modes_t', b%modes_t); if (allocated(error)) return
      end if
      if (b%r_outer /= unset .and. b%torsion_constant /= unset) then
        call fatal_error(error, b%origin%where('torsion_constant') // ': a tube has pi/2 (r_outer^4 - r_inner^4); ' // &
          & 'give torsion_constant only with area, iy and iz'); return
      end if
      if (b%modes_t > 0) then
        if (b%shear_modulus == unset) then
          call fatal_error(error, b%origin%where('shear_modulus') // ': missing (Pa): torsional modes (modes_t = ' // &
            & itoa(b%modes_t) // ') need the shear modulus'); return
        end if
        if (b%r_outer == unset .and. b%torsion_constant == unset) then
          call fatal_error(error, b%origin%where('torsion_constant') // ': missing (m^4): torsional modes (modes_t = ' // &
            & itoa(b%modes_t) // ') of a section given by area, iy and iz need its torsion constant'); return
        end if
      end if
      call check_damping(sc, i, error); if (allocated(error)) return
    end associate
  contains
    subroutine positive(x, item, unit)
      real(dp), intent(in) :: x
      character(len=*), intent(in) :: item, unit
      if (x == unset) call fatal_error(error, sc%bodies(i)%origin%where(item) // ': missing ' // unit)
    end subroutine positive
    !> A count of modes of at most `most` (`says` how the bound is formed).
    subroutine within(item, count, most, says)
      character(len=*), intent(in) :: item, says
      integer, intent(in) :: count, most
      if (count > most) call fatal_error(error, sc%bodies(i)%origin%where(item) // ': must be 0 to ' // says // &
        & ' = ' // itoa(most) // ', got ' // itoa(count))
    end subroutine within

    !> A beam of more than dense_elements elements: its modes by the banded eigensolver.
    subroutine banded_within(item, count)
      character(len=*), intent(in) :: item
      integer, intent(in) :: count
      if (count > max_banded_modes) call fatal_error(error, sc%bodies(i)%origin%where(item) // ': at most ' // &
        & itoa(max_banded_modes) // ' modes per family on a beam of more than ' // itoa(dense_elements) // &
        & ' elements (n_elements = ' // itoa(sc%bodies(i)%n_elements) // '), got ' // itoa(count))
    end subroutine banded_within
  end subroutine check_beam

  subroutine check_joints(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    type(error_type), allocatable :: error
    integer :: i, ip, ic, k
    logical :: said
    said = .false.
    each_joints: do i = 1, size(sc%joints)
      associate(jt => sc%joints(i))
        if (len_trim(jt%name) == 0) then
          call errs%add(jt%origin%where('name') // ': missing'); cycle each_joints
        end if
        if (joint_ndof(jt%kind) < 0) then
          call errs%add(jt%origin%where('kind') // ": missing ('revolute', 'prismatic', 'fixed', " // &
            & "'spherical', 'free', 'cylindrical', 'universal' or 'planar')"); cycle each_joints
        end if
        call check_coordinate_count(jt, 'q0', error)
        if (allocated(error)) then
          call errs%add(error%message); cycle each_joints
        end if
        call check_coordinate_count(jt, 'qd0', error)
        if (allocated(error)) then
          call errs%add(error%message); cycle each_joints
        end if
        if (jt%settle .and. joint_ndof(jt%kind) == 0) then
          call errs%add(jt%origin%where('settle') // ": a 'fixed' joint has no coordinates to settle"); cycle each_joints
        end if
        if (jt%hold .and. jt%settle) then
          call errs%add(jt%origin%where('hold') // ': a joint either holds its q0 (hold) or finds its ' // &
            & 'equilibrium in a static start (settle), not both'); cycle each_joints
        end if
        if (jt%hold .and. joint_ndof(jt%kind) == 0) then
          call errs%add(jt%origin%where('hold') // ": a 'fixed' joint has no coordinates to hold"); cycle each_joints
        end if
        if (jt%hold .and. .not. any([(closes_loop(sc, k), k = 1, size(sc%joints))])) then
          call errs%add(jt%origin%where('hold') // ': only the assembly of closed loops holds coordinates, and ' // &
            & 'this scene has no joint that closes a loop'); cycle each_joints
        end if
        if (jt%settle .and. sc%scene%start /= 'static') then
          ! said once, at the first such joint: the start is the one fault
          if (.not. said) call errs%add(jt%origin%where('settle') // ": joints settle only in a static start " // &
            & "(&scene start = 'static')")
          said = .true.; cycle each_joints
        end if
        ip = body_index(sc, jt%parent); ic = body_index(sc, jt%child)
        if (ip == 0) then
          call add_unknown_name(errs, sc%bodies%name, &
            & sc%joints(i)%origin%where('parent') // ": no &body named '" // trim(jt%parent) // "'")
          cycle each_joints
        end if
        if (ic == 0) then
          call add_unknown_name(errs, sc%bodies%name, &
            & sc%joints(i)%origin%where('child') // ": no &body named '" // trim(jt%child) // "'")
          cycle each_joints
        end if
        if (ip == ic) then
          ! the item a --set changed, when one did: the other is as the file gave it
          call errs%add(sc%joints(i)%origin%where(trim(merge('parent', 'child ', &
            & sc%joints(i)%origin%line_of('parent') < 0 .and. sc%joints(i)%origin%line_of('child') >= 0))) // &
            & ": the joint joins body '" // trim(jt%child) // "' to itself (a cycle)"); cycle each_joints
        end if
        if (sc%bodies(ic)%kind == 'ground') then
          call errs%add(sc%joints(i)%origin%where('child') // ": '" // trim(jt%child) // &
            & "' is the ground; the ground can only be a parent"); cycle each_joints
        end if
        call check_joint_axes(jt, error)
        if (allocated(error)) call errs%add(error%message)
      end associate
    end do each_joints
    call check_loops(sc, errs)
  end subroutine check_joints

  !> A joint's axes: axis of nonzero length for the kinds that use it; axis2 only on a
  !> universal joint, of nonzero length and normal to axis (cosine below 1e-9).
  subroutine check_joint_axes(jt, error)
    type(joint_spec), intent(in) :: jt
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: cosine
    select case (trim(jt%kind))
    case ('revolute', 'prismatic', 'cylindrical', 'universal', 'planar')
      if (norm2(jt%axis) < 1.0e-12_dp) then
        call fatal_error(error, jt%origin%where('axis') // ': zero length; give a direction in the parent frame')
        return
      end if
    end select
    if (jt%kind /= 'universal') then
      if (jt%origin%given('axis2')) call fatal_error(error, jt%origin%where('axis2') // ": only a 'universal' " // &
        & "joint takes axis2 (this joint is '" // trim(jt%kind) // "')")
      return
    end if
    if (all(jt%axis2 == unset)) return
    if (norm2(jt%axis2) < 1.0e-12_dp) then
      call fatal_error(error, jt%origin%where('axis2') // ': zero length; give a direction normal to axis'); return
    end if
    cosine = dot_product(jt%axis, jt%axis2)/(norm2(jt%axis)*norm2(jt%axis2))
    if (abs(cosine) > 1.0e-9_dp) call fatal_error(error, jt%origin%where('axis2') // ': not normal to axis ' // &
      & '(the cosine of the angle between them is ' // fmt(cosine) // '); give a direction normal to axis')
  end subroutine check_joint_axes

  !> Loop-closing joints (closes_loop): any kind ('free' closes no constraint), at rigid
  !> bodies or at points of flexible ones (the points a flexible body allows are checked,
  !> with its modes, where the model is built: driver/build.f90 flexible_point), no coordinates of
  !> their own (no q0, qd0, settle, hold, drive, spring or motion), not at a beam whose geometric
  !> stiffness is on (the cut's load would not stiffen it), only through the mass matrix
  !> (loop_refusal); child_at only on them, and given on each of them.
  subroutine check_loops(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: j
    character(len=:), allocatable :: refused
    do j = 1, size(sc%joints)
      associate(jt => sc%joints(j), o => sc%joints(j)%origin)
        ! a joint to a missing body is reported once, by check_joints
        if (body_index(sc, jt%parent) == 0 .or. body_index(sc, jt%child) == 0) cycle
        if (.not. closes_loop(sc, j)) then
          if (any(jt%child_at /= 0.0_dp)) call errs%add(o%where('child_at') // ": only a joint that closes a loop (its " // &
            & "child already has a parent joint) takes child_at; this joint's point is the child's origin")
          cycle
        end if
        ! a second parent joint is a loop only when the scene says so: a repeated child
        ! written by mistake would otherwise run as a constraint nobody meant
        if (.not. o%given('child_at')) then
          call errs%add(o%where('child') // ": body '" // trim(jt%child) // "' already has a parent joint ('" // &
            & trim(first_parent(jt%child)) // "'); a second joint to it closes a loop, which it says by giving " // &
            & "child_at (its point on the child; 0, 0, 0 for the child's origin)"); cycle
        end if
        if (nonzero(jt%q0) .or. nonzero(jt%qd0) .or. jt%settle .or. jt%hold) then
          call errs%add(o%where(trim(first_given([character(len=6) :: 'q0', 'qd0', 'settle', 'hold'], &
            & [nonzero(jt%q0), nonzero(jt%qd0), jt%settle, jt%hold]))) // &
            & ': a joint that closes a loop has no coordinates of its own (its state follows from the tree)'); cycle
        end if
        ! a 'free' cut constrains nothing: nothing more to refuse
        if (jt%kind == 'free') cycle
        if (sc%effects%geometric_stiffening .and. (kind_of(jt%parent) == 'beam' .or. kind_of(jt%child) == 'beam')) then
          call errs%add(o%where(trim(merge('parent', 'child ', kind_of(jt%parent) == 'beam'))) // ': a joint ' // &
            & "that closes a loop at a beam does not stiffen it (geometric_stiffening counts the loads of tree " // &
            & "joints only): turn geometric_stiffening off in &effects"); cycle
        end if
        refused = loop_refusal(sc)
        if (len(refused) > 0) call errs%add(o%where('child') // ': closes a loop, and loops are not ' // refused)
      end associate
    end do
  contains
    function kind_of(name) result(k)
      character(len=*), intent(in) :: name
      character(len=:), allocatable :: k
      k = trim(sc%bodies(body_index(sc, name))%kind)
    end function kind_of
    function first_parent(child) result(name)
      character(len=*), intent(in) :: child
      character(len=:), allocatable :: name
      name = trim(sc%joints(findloc(sc%joints%child, child, dim=1))%name)
    end function first_parent
    pure function first_given(items, given) result(item)
      character(len=*), intent(in) :: items(:)
      logical, intent(in) :: given(:)
      character(len=len(items)) :: item
      item = items(findloc(given, .true., dim=1))
    end function first_given
    pure logical function nonzero(x)
      real(dp), intent(in) :: x(:)
      nonzero = any(x /= 0.0_dp .and. x /= unset)
    end function nonzero
  end subroutine check_loops

  !> Why a scene's run cannot take loops ('' if it can).
  function loop_refusal(sc) result(s)
    type(scene_t), intent(in) :: sc
    character(len=:), allocatable :: s
    s = ''
    if (trim(sc%integrator%dynamics) == 'articulated') s = "supported by dynamics = 'articulated' (use 'mass_matrix')"
  end function loop_refusal

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

  !> The groups that act on joints, bodies and markers: drives, springs, prescribed motion,
  !> damping, loads and markers, each referring to what exists, with its effect turned on.
  subroutine check_loads_markers(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    call check_drives(sc, errs)
    call check_springs(sc, errs)
    call check_motions(sc, errs)
    call check_damping_effect(sc, errs)
    call check_loads(sc, errs)
    call check_stiffening(sc, errs)
    call check_markers(sc, errs)
    call check_forces(sc, errs)
    call check_controls(sc, errs)
    call check_moving_loads(sc, errs)
    call check_sensors(sc, errs)
  end subroutine check_loads_markers

  !> &sensor: a name of its own (its columns are named after it), a kind, the items of its
  !> kind only, an existing marker, and another marker ('distance') or a body ('position').
  subroutine check_sensors(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: i
    do i = 1, size(sc%sensors)
      associate(se => sc%sensors(i), o => sc%sensors(i)%origin)
        if (len_trim(se%name) == 0) then
          call errs%add(o%where('name') // ': missing'); cycle
        end if
        if (any(sc%markers%name == se%name)) then
          call errs%add(o%where('name') // ": a &marker's name too (the sensor's columns would take its " // &
            & "column names: give the sensor a name of its own)"); cycle
        end if
        if (len_trim(se%kind) == 0) then
          call errs%add(o%where('kind') // ": missing ('distance' or 'position')"); cycle
        end if
        if (.not. sensor_kind_items(errs, se)) cycle
        if (.not. named_marker(sc, errs, o, 'marker', se%marker)) cycle
        if (se%kind == 'distance') then
          if (.not. named_marker(sc, errs, o, 'to', se%to)) cycle
          if (se%to == se%marker) call errs%add(o%where('to') // ": the same marker as marker ('" // &
            & trim(se%marker) // "'): a distance is measured between two markers")
        else if (len_trim(se%frame) == 0) then
          call errs%add(o%where('frame') // ": missing (the body in whose frame 'position' measures)")
        else if (body_index(sc, se%frame) == 0) then
          call add_unknown_name(errs, sc%bodies%name, &
            & o%where('frame') // ": no &body named '" // trim(se%frame) // "'")
        end if
      end associate
    end do
  end subroutine check_sensors

  !> A sensor takes the items of its kind only (else the error is added).
  logical function sensor_kind_items(errs, se) result(ok)
    type(error_list), intent(inout) :: errs
    type(sensor_spec), intent(in) :: se
    character(len=:), allocatable :: takes
    integer :: k
    takes = sensor_items(se%kind)
    ok = .true.
    do k = 1, se%origin%n
      if (index(' ' // takes // ' ', ' ' // trim(se%origin%items(k)) // ' ') > 0) cycle
      call errs%add(se%origin%where(trim(se%origin%items(k))) // ": not an item of a '" // trim(se%kind) // &
        & "' sensor (it takes " // takes // ')')
      ok = .false.; return
    end do
  end function sensor_kind_items

  !> &moving_load: a name, a beam to travel on, the items of its travel, and &effects
  !> moving_loads on.
  subroutine check_moving_loads(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: i
    logical :: said
    said = .false.
    do i = 1, size(sc%moving_loads)
      associate(ml => sc%moving_loads(i), o => sc%moving_loads(i)%origin)
        if (len_trim(ml%name) == 0) then
          call errs%add(o%where('name') // ': missing'); cycle
        end if
        if (.not. travel_body(sc, errs, ml)) cycle
        if (.not. travel_items(sc, errs, ml)) cycle
        call say_forgotten(errs, sc, sc%effects%moving_loads, 'moving_loads', o, 'the scene gives moving loads', said)
      end associate
    end do
  end subroutine check_moving_loads

  !> A moving load's body exists and is a built-in beam (else the error is added). A
  !> modal-file body is refused: its shapes between its nodes are not known.
  logical function travel_body(sc, errs, ml) result(ok)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    type(moving_load_spec), intent(in) :: ml
    integer :: b
    ok = .false.
    associate(o => ml%origin)
      if (len_trim(ml%body) == 0) then
        call errs%add(o%where('body') // ': missing (the beam the load travels along)'); return
      end if
      b = body_index(sc, ml%body)
      if (b == 0) then
        call add_unknown_name(errs, sc%bodies%name, &
          & o%where('body') // ": no &body named '" // trim(ml%body) // "'"); return
      end if
      if (sc%bodies(b)%kind == 'modal') then
        call errs%add(o%where('body') // ": '" // trim(ml%body) // "' is a modal-file body, whose shapes " // &
          & "between its nodes are not known: a moving load travels along a body of kind 'beam'"); return
      end if
      if (len_trim(sc%bodies(b)%kind) == 0) return     ! its missing kind is the body's own error
      if (sc%bodies(b)%kind /= 'beam') then
        call errs%add(o%where('body') // ": '" // trim(ml%body) // "' is not a flexible body (kind '" // &
          & trim(sc%bodies(b)%kind) // "'): a moving load travels along a body of kind 'beam'"); return
      end if
    end associate
    ok = .true.
  end function travel_body

  !> A moving load's travel items agree with its form: 'constant_speed' a speed not 0 and
  !> s0 on the beam (0 to its length), no file; 'table' a file and none of start, s0,
  !> speed (else the error is added).
  logical function travel_items(sc, errs, ml) result(ok)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    type(moving_load_spec), intent(in) :: ml
    character(len=*), parameter :: names(3) = [character(len=5) :: 'start', 's0', 'speed']
    real(dp) :: length
    integer :: k
    ok = .false.
    length = sc%bodies(body_index(sc, ml%body))%length
    associate(o => ml%origin)
      if (ml%form == 'table') then
        k = findloc([ml%start /= 0.0_dp, ml%s0 /= 0.0_dp, ml%speed /= 0.0_dp], .true., 1)
        if (k > 0) then
          call errs%add(o%where(trim(names(k))) // ": only form 'constant_speed' uses it (form 'table' reads " // &
            & 'the travel from file)'); return
        end if
      else
        if (ml%speed == 0.0_dp) then
          call errs%add(o%where('speed') // ": missing or 0 (form 'constant_speed' travels at speed, m/s)"); return
        end if
        if (length /= unset .and. (ml%s0 < 0.0_dp .or. ml%s0 > length)) then
          call errs%add(o%where('s0') // ': ' // fmt(ml%s0) // " m is off the beam '" // trim(ml%body) // &
            & "' (0 to its length, " // fmt(length) // ' m)'); return
        end if
      end if
    end associate
    ok = table_form(errs, ml%origin, ml%form, ml%file, [0.0_dp, 0.0_dp, 0.0_dp])
  end function travel_items

  !> &drive: a joint coordinate, its form, and &effects joint_drives on.
  subroutine check_drives(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: i
    logical :: said
    said = .false.
    do i = 1, size(sc%drives)
      associate(dr => sc%drives(i))
        if (.not. joint_coordinate(sc, errs, dr%origin, dr%joint, dr%coordinate)) cycle
        if (.not. table_form(errs, dr%origin, dr%form, dr%file, [dr%amplitude, dr%frequency, dr%phase])) cycle
        call say_forgotten(errs, sc, sc%effects%joint_drives, 'joint_drives', &
          & dr%origin, 'the scene gives drives', said)
      end associate
    end do
  end subroutine check_drives

  !> &spring: a joint coordinate and &effects joint_springs on.
  subroutine check_springs(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: i
    logical :: said
    said = .false.
    do i = 1, size(sc%springs)
      associate(sp => sc%springs(i))
        if (.not. joint_coordinate(sc, errs, sp%origin, sp%joint, sp%coordinate)) cycle
        call say_forgotten(errs, sc, sc%effects%joint_springs, 'joint_springs', &
          & sp%origin, 'the scene gives springs', said)
      end associate
    end do
  end subroutine check_springs

  !> &motion: a joint coordinate prescribed once, its form (a spin-up needs its ramp time),
  !> and &effects base_motion on.
  subroutine check_motions(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: i, j
    logical :: said
    said = .false.
    each_motions: do i = 1, size(sc%motions)
      associate(mo => sc%motions(i))
        if (.not. joint_coordinate(sc, errs, mo%origin, mo%joint, mo%coordinate)) cycle each_motions
        do j = 1, i - 1
          if (sc%motions(j)%joint == mo%joint .and. sc%motions(j)%coordinate == mo%coordinate) then
            call errs%add(mo%origin%where('coordinate') // ': ' // itoa(mo%coordinate) // " of joint '" // &
              & trim(mo%joint) // "' is already prescribed by &motion #" // itoa(j)); cycle each_motions
          end if
        end do
        if (.not. table_form(errs, mo%origin, mo%form, mo%file, [mo%amplitude, mo%frequency, mo%phase])) &
          & cycle each_motions
        if (.not. motion_form_items(errs, mo)) cycle each_motions
        if (mo%form == 'spinup' .and. mo%ramp_time == unset) then
          call errs%add(mo%origin%where('ramp_time') // ": missing (form 'spinup' needs the ramp time, s)")
          cycle each_motions
        end if
        call say_forgotten(errs, sc, sc%effects%base_motion, 'base_motion', &
          & mo%origin, 'the scene prescribes motion', said)
      end associate
    end do each_motions
  end subroutine check_motions

  !> A motion's items are its form's: 'spinup' takes no sine items, the other forms no
  !> spin-up items (else the error is added).
  logical function motion_form_items(errs, mo) result(ok)
    type(error_list), intent(inout) :: errs
    type(motion_spec), intent(in) :: mo
    character(len=*), parameter :: sine_items(3) = [character(len=9) :: 'amplitude', 'frequency', 'phase']
    character(len=*), parameter :: spinup_items(2) = [character(len=9) :: 'rate', 'ramp_time']
    integer :: k
    ok = .false.
    if (mo%form == 'spinup') then
      k = findloc([mo%amplitude /= 0.0_dp, mo%frequency /= 0.0_dp, mo%phase /= 0.0_dp], .true., 1)
      if (k > 0) then
        call errs%add(mo%origin%where(trim(sine_items(k))) // ": not used by form 'spinup' (offset, rate " // &
          & 'and ramp_time give the motion)'); return
      end if
    else
      k = findloc([mo%rate /= 0.0_dp, mo%ramp_time /= unset], .true., 1)
      if (k > 0) then
        call errs%add(mo%origin%where(trim(spinup_items(k))) // ": only form 'spinup' uses it (form is '" // &
          & trim(mo%form) // "')"); return
      end if
    end if
    ok = .true.
  end function motion_form_items

  !> A flexible body that gives modal damping needs &effects modal_damping on.
  subroutine check_damping_effect(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: i
    do i = 1, size(sc%bodies)
      associate(b => sc%bodies(i))
        if (b%kind /= 'beam' .and. b%kind /= 'modal') cycle
        if (any(b%modal_damping /= unset .and. b%modal_damping /= 0.0_dp) .or. b%rayleigh_alpha /= 0.0_dp .or. &
          & b%rayleigh_beta /= 0.0_dp) then
          if (forgotten(sc, sc%effects%modal_damping, 'modal_damping')) then
            call errs%add(b%origin%where(damping_item(b)) // effect_not_on('the body gives modal damping', &
              & 'modal_damping'))
            exit        ! said once, at the first such body
          end if
        end if
      end associate
    end do
  end subroutine check_damping_effect

  !> &load: an existing marker, a direction, the items of its form, and &effects
  !> firing_load on.
  subroutine check_loads(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: i
    logical :: said
    said = .false.
    do i = 1, size(sc%loads)
      associate(ld => sc%loads(i))
        if (.not. any(sc%markers%name == ld%marker)) then
          call add_unknown_name(errs, sc%markers%name, &
            & ld%origin%where('marker') // ": no &marker named '" // trim(ld%marker) // "'"); cycle
        end if
        if (norm2(ld%direction) < 1.0e-12_dp) then
          call errs%add(ld%origin%where('direction') // ': missing or zero (a direction in the frame given by ' // &
            & 'frame)'); cycle
        end if
        if (.not. load_form_items(errs, ld)) cycle
        if (.not. pulse_within_steps(errs, sc, ld)) cycle
        call say_forgotten(errs, sc, sc%effects%firing_load, 'firing_load', ld%origin, 'the scene gives loads', said)
      end associate
    end do
  end subroutine check_loads

  !> A fixed-step run's pulse lasts at least one step (h_slow, the full evaluations' step
  !> of a multirate run): a shorter one can pass between two evaluations, and the run would
  !> never feel it (else the error is added). Adaptive runs end steps on its start, peak
  !> and end (driver/step_stops.f90).
  logical function pulse_within_steps(errs, sc, ld) result(ok)
    type(error_list), intent(inout) :: errs
    type(scene_t), intent(in) :: sc
    type(load_spec), intent(in) :: ld
    real(dp) :: h
    ok = .true.
    if (ld%form /= 'pulse' .or. sc%integrator%adaptive) return
    h = sc%integrator%h_slow
    if (h == unset) h = sc%integrator%h_fast
    if (h == unset .or. ld%duration >= h) return
    if (ld%start + ld%duration <= 0.0_dp .or. (sc%scene%t_end /= unset .and. ld%start >= sc%scene%t_end)) return
    ok = .false.
    call errs%add(ld%origin%where('duration') // ': a pulse of ' // fmt(ld%duration) // ' s is shorter than ' // &
      & 'the fixed step h_slow = ' // fmt(h) // ' s, which can pass it between two evaluations unfelt: take ' // &
      & "h_slow <= duration, or adaptive = .true. (its steps end on the pulse's start, peak and end)")
  end function pulse_within_steps

  !> A load's form and its items agree: a pulse needs its duration and takes no offset,
  !> sine or file; the other forms take no pulse items; 'constant' no sine items; 'sine'
  !> and 'table' as a drive's (else the error is added).
  logical function load_form_items(errs, ld) result(ok)
    type(error_list), intent(inout) :: errs
    type(load_spec), intent(in) :: ld
    character(len=*), parameter :: pulse_items(3) = [character(len=8) :: 'peak', 'start', 'duration']
    character(len=*), parameter :: sine_items(4) = [character(len=9) :: 'offset', 'amplitude', 'frequency', 'phase']
    logical :: given_pulse(3), given_sine(4)
    integer :: k
    given_pulse = [ld%peak /= 0.0_dp, ld%start /= 0.0_dp, ld%duration /= unset]
    given_sine = [ld%offset /= 0.0_dp, ld%amplitude /= 0.0_dp, ld%frequency /= 0.0_dp, ld%phase /= 0.0_dp]
    ok = .false.
    if (ld%form == 'pulse') then
      if (ld%duration == unset) then
        call errs%add(ld%origin%where('duration') // ': missing (the pulse length, s)'); return
      end if
      k = findloc(given_sine, .true., 1)
      if (k > 0) then
        call errs%add(ld%origin%where(trim(sine_items(k))) // ": not used by form 'pulse' (peak, start and " // &
          & 'duration give the pulse)'); return
      end if
    else
      k = findloc(given_pulse, .true., 1)
      if (k > 0) then
        call errs%add(ld%origin%where(trim(pulse_items(k))) // ": only form 'pulse' uses it (form is '" // &
          & trim(ld%form) // "')"); return
      end if
      k = findloc(given_sine(2:4), .true., 1)
      if (ld%form == 'constant' .and. k > 0) then
        call errs%add(ld%origin%where(trim(sine_items(k + 1))) // ": not used by form 'constant' (offset " // &
          & 'gives the load)'); return
      end if
    end if
    ok = table_form(errs, ld%origin, ld%form, ld%file, [ld%amplitude, ld%frequency, ld%phase])
  end function load_form_items

  !> &effects geometric_stiffening needs a built-in beam to act on.
  subroutine check_stiffening(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    ! a body whose kind is missing (its own error) may be the beam
    if (sc%effects%geometric_stiffening .and. .not. any(sc%bodies%kind == 'beam') .and. &
      & all(len_trim(sc%bodies%kind) > 0)) &
      & call errs%add(sc%effects%origin%where('geometric_stiffening') // ': the scene has no beam (only built-in ' // &
      & "beams, kind = 'beam', carry a geometric stiffness)")
  end subroutine check_stiffening

  !> &marker: a name and an existing body.
  subroutine check_markers(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: i
    do i = 1, size(sc%markers)
      if (len_trim(sc%markers(i)%name) == 0) then
        call errs%add(sc%markers(i)%origin%where('name') // ': missing'); cycle
      end if
      if (body_index(sc, sc%markers(i)%body) == 0) &
        & call add_unknown_name(errs, sc%bodies%name, &
          & sc%markers(i)%origin%where('body') // ": no &body named '" // trim(sc%markers(i)%body) // "'")
    end do
  end subroutine check_markers

  !> &force: a name and kind, two different existing markers, the kind's count of stiffnesses
  !> (and of dampings when given), a spring-damper's free length, and &effects force_elements on.
  subroutine check_forces(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: i
    logical :: said
    said = .false.
    do i = 1, size(sc%forces)
      associate(fe => sc%forces(i), o => sc%forces(i)%origin)
        if (len_trim(fe%name) == 0) then
          call errs%add(o%where('name') // ': missing'); cycle
        end if
        if (len_trim(fe%kind) == 0) then
          call errs%add(o%where('kind') // ": missing ('spring_damper' or 'bushing')"); cycle
        end if
        if (.not. force_markers(sc, errs, fe%origin, fe%marker_i, fe%marker_j)) cycle
        if (.not. force_values(errs, fe)) cycle
        call say_forgotten(errs, sc, sc%effects%force_elements, 'force_elements', &
          & o, 'the scene gives force elements', said)
      end associate
    end do
  end subroutine check_forces

  !> &control: a name, a tree joint's coordinate that no &motion prescribes, its sensor's
  !> items, some gain, and &effects controls on.
  subroutine check_controls(sc, errs)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    integer :: i
    logical :: said
    said = .false.
    do i = 1, size(sc%controls)
      associate(ct => sc%controls(i), o => sc%controls(i)%origin)
        if (len_trim(ct%name) == 0) then
          call errs%add(o%where('name') // ': missing'); cycle
        end if
        if (.not. joint_coordinate(sc, errs, o, ct%joint, ct%coordinate)) cycle
        if (.not. free_tree_coordinate(sc, errs, o, ct%joint, ct%coordinate)) cycle
        if (.not. control_sensor(sc, errs, ct)) cycle
        if (ct%kp == 0.0_dp .and. ct%ki == 0.0_dp .and. ct%kd == 0.0_dp) then
          call errs%add(o%where('kp') // ': kp, ki and kd are all 0 (give the gains of the controller)'); cycle
        end if
        call say_forgotten(errs, sc, sc%effects%controls, 'controls', o, 'the scene gives controllers', said)
      end associate
    end do
  end subroutine check_controls

  !> No &motion prescribes the coordinate (else the error is added): a controller drives a
  !> coordinate of the tree (joint_coordinate) that moves freely.
  logical function free_tree_coordinate(sc, errs, o, joint, coordinate) result(ok)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    type(origin_t), intent(in) :: o
    character(len=*), intent(in) :: joint
    integer, intent(in) :: coordinate
    integer :: j
    ok = .false.
    do j = 1, size(sc%motions)
      if (sc%motions(j)%joint /= joint .or. sc%motions(j)%coordinate /= coordinate) cycle
      call errs%add(o%where('coordinate') // ': ' // itoa(coordinate) // " of joint '" // trim(joint) // &
        & "' is prescribed by the &motion on line " // itoa(sc%motions(j)%origin%line) // &
        & ': a controller drives a coordinate that is free to move'); return
    end do
    ok = .true.
  end function free_tree_coordinate

  !> A controller's sensor items: 'orientation' needs a marker and a nonzero axis,
  !> 'coordinate' takes neither (else the error is added).
  logical function control_sensor(sc, errs, ct) result(ok)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    type(control_spec), intent(in) :: ct
    ok = .false.
    associate(o => ct%origin)
      if (ct%sensor == 'orientation') then
        if (.not. named_marker(sc, errs, o, 'marker', ct%marker)) return
        if (norm2(ct%axis) < 1.0e-12_dp) then
          call errs%add(o%where('axis') // ": missing or zero (sensor 'orientation' measures the rotation " // &
            & 'about this inertial axis)'); return
        end if
      else
        if (len_trim(ct%marker) > 0) then
          call errs%add(o%where('marker') // ": only sensor 'orientation' reads a marker (sensor is 'coordinate')")
          return
        end if
        if (any(ct%axis /= 0.0_dp)) then
          call errs%add(o%where('axis') // ": only sensor 'orientation' takes an axis (sensor is 'coordinate')")
          return
        end if
      end if
    end associate
    ok = .true.
  end function control_sensor

  !> A force element's two markers exist and differ (else the error is added).
  logical function force_markers(sc, errs, o, marker_i, marker_j) result(ok)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    type(origin_t), intent(in) :: o
    character(len=*), intent(in) :: marker_i, marker_j
    ok = .false.
    if (.not. named_marker(sc, errs, o, 'marker_i', marker_i)) return
    if (.not. named_marker(sc, errs, o, 'marker_j', marker_j)) return
    if (marker_i == marker_j) then
      call errs%add(o%where('marker_j') // ": the same marker as marker_i ('" // trim(marker_i) // &
        & "'): a force element joins two markers"); return
    end if
    ok = .true.
  end function force_markers

  !> Add `message`, that a reference names no group of a kind whose `names` are given,
  !> unless one of those groups has no name: its own error says so, and the reference is
  !> most likely to it (one fault, one line).
  subroutine add_unknown_name(errs, names, message)
    type(error_list), intent(inout) :: errs
    character(len=*), intent(in) :: names(:), message
    if (any(len_trim(names) == 0)) return
    call errs%add(message)
  end subroutine add_unknown_name

  !> Marker item `item` names an existing marker (else the error is added).
  logical function named_marker(sc, errs, o, item, marker) result(ok)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    type(origin_t), intent(in) :: o
    character(len=*), intent(in) :: item, marker
    ok = .false.
    if (len_trim(marker) == 0) then
      call errs%add(o%where(item) // ': missing (a marker name)'); return
    end if
    if (.not. any(sc%markers%name == marker)) then
      call add_unknown_name(errs, sc%markers%name, &
        & o%where(item) // ": no &marker named '" // trim(marker) // "'"); return
    end if
    ok = .true.
  end function named_marker

  !> A force element gives its kind's count of stiffnesses (1 or 6), as many dampings or
  !> none, and a spring-damper its free length, a bushing none (else the error is added).
  !> The values given are those set (a repeat such as 6*10.0 counts as its six).
  logical function force_values(errs, fe) result(ok)
    type(error_list), intent(inout) :: errs
    type(force_spec), intent(in) :: fe
    integer :: n, nk, nc
    character(len=:), allocatable :: what
    ok = .false.
    nk = count(fe%stiffness /= unset); nc = count(fe%damping /= unset)
    associate(o => fe%origin, kind => fe%kind, free_length => fe%free_length)
      if (.not. table_spring(errs, fe, nk)) return
      if (len_trim(fe%file) > 0) nk = 1
      if (kind == 'spring_damper') then
        n = 1; what = "a 'spring_damper' takes 1 value"
      else
        n = 6; what = "a 'bushing' takes 6 (translations x, y, z, rotations about x, y, z)"
      end if
      if (nk == 0) then
        call errs%add(o%where('stiffness') // ': missing (' // what // ')'); return
      end if
      if (nk /= n) then
        call errs%add(o%where('stiffness') // ': ' // what // ', got ' // itoa(nk)); return
      end if
      if (nc /= 0 .and. nc /= n) then
        call errs%add(o%where('damping') // ': ' // what // ' (as stiffness), got ' // itoa(nc)); return
      end if
      if (kind == 'spring_damper' .and. free_length == unset) then
        call errs%add(o%where('free_length') // ": missing (the length at which the spring is relaxed, m)"); return
      end if
      if (kind == 'bushing' .and. free_length /= unset) then
        call errs%add(o%where('free_length') // ": a 'bushing' has none (it is relaxed where marker j's frame " // &
          & "meets marker i's)"); return
      end if
    end associate
    ok = .true.
  end function force_values

  !> A force element's table `file`: only a 'spring_damper' has one, and then no stiffness
  !> (the table gives the spring's force; else the error is added).
  logical function table_spring(errs, fe, nk) result(ok)
    type(error_list), intent(inout) :: errs
    type(force_spec), intent(in) :: fe
    integer, intent(in) :: nk
    ok = .false.
    if (len_trim(fe%file) > 0 .and. fe%kind /= 'spring_damper') then
      call errs%add(fe%origin%where('file') // ": only a 'spring_damper' takes a force-deflection table"); return
    end if
    if (len_trim(fe%file) > 0 .and. nk > 0) then
      call errs%add(fe%origin%where('stiffness') // ': not with a file (the force-deflection table gives ' // &
        & "the spring's force; give one or the other)"); return
    end if
    ok = .true.
  end function table_spring

  !> The error that an effect whose data the scene gives (`what`, at group origin `o`) is off
  !> without being turned off on purpose: said once per kind of group, at the first group that
  !> reaches the check (`said` keeps that it was; one fault, one line).
  subroutine say_forgotten(errs, sc, on, effect, o, what, said)
    type(error_list), intent(inout) :: errs
    type(scene_t), intent(in) :: sc
    logical, intent(in) :: on
    character(len=*), intent(in) :: effect, what
    type(origin_t), intent(in) :: o
    logical, intent(inout) :: said
    if (said .or. .not. forgotten(sc, on, effect)) return
    call errs%add(o%where() // effect_not_on(what, effect))
    said = .true.
  end subroutine say_forgotten

  !> An effect whose data the scene gives is off without being turned off on purpose.
  logical function forgotten(sc, on, effect)
    type(scene_t), intent(in) :: sc
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

  !> The named joint exists, is a joint of the tree (a loop-closing joint has no coordinates
  !> of its own) and has the coordinate (else the error is added).
  logical function joint_coordinate(sc, errs, o, joint, coordinate) result(ok)
    type(scene_t), intent(in) :: sc
    type(error_list), intent(inout) :: errs
    type(origin_t), intent(in) :: o
    character(len=*), intent(in) :: joint
    integer, intent(in) :: coordinate
    integer :: j, k, ndof
    ok = .false.
    if (len_trim(joint) == 0) then
      call errs%add(o%where('joint') // ': missing (the joint it acts on)'); return
    end if
    k = 0
    do j = 1, size(sc%joints)
      if (sc%joints(j)%name == joint) k = j
    end do
    if (k == 0) then
      call add_unknown_name(errs, sc%joints%name, &
        & o%where('joint') // ": no &joint named '" // trim(joint) // "'"); return
    end if
    if (closes_loop(sc, k)) then
      call errs%add(o%where('joint') // ": '" // trim(joint) // "' closes a loop: it has no coordinate of its own " // &
        & 'to act on (its state follows from the tree; act on a joint of the tree)'); return
    end if
    ndof = joint_ndof(sc%joints(k)%kind)
    if (ndof < 0) return    ! the joint's kind is missing or unknown: its own error says so
    if (coordinate < 1 .or. coordinate > ndof) then
      call errs%add(o%where('coordinate') // ': joint ''' // trim(joint) // ''' has ' // itoa(ndof) // &
        & trim(merge(' coordinate ', ' coordinates', ndof == 1)) // ', got ' // itoa(coordinate)); return
    end if
    ok = .true.
  end function joint_coordinate

  !> A group's form and file agree (else the error is added).
  logical function table_form(errs, o, form, file, sine_items) result(ok)
    type(error_list), intent(inout) :: errs
    type(origin_t), intent(in) :: o
    character(len=*), intent(in) :: form, file
    real(dp), intent(in) :: sine_items(3)
    type(error_type), allocatable :: error
    call check_table_form(o, form, file, sine_items, error)
    ok = .not. allocated(error)
    if (.not. ok) call errs%add(error%message)
  end function table_form

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

  !> Modal damping of beam i: one value or one per mode; its initial modal state: one value
  !> per mode (every mode counted: bending, axial, torsional). A modal file's mode count is
  !> known only when the model reads it (driver/build.f90 checks those bodies).
  subroutine check_damping(sc, i, error)
    type(scene_t), intent(in) :: sc
    integer, intent(in) :: i
    type(error_type), allocatable, intent(out) :: error
    integer :: ng, m
    associate(b => sc%bodies(i))
      if (b%kind /= 'beam') return
      m = beam_mode_count(b)
      ng = count(b%modal_damping /= unset)
      if (ng > 1 .and. ng /= m) then
        call fatal_error(error, b%origin%where('modal_damping') // ': give one value or one per mode (' // &
          & itoa(m) // ' modes), got ' // itoa(ng)); return
      end if
      if (count(b%a0 /= unset) > 0 .and. count(b%a0 /= unset) /= m) then
        call fatal_error(error, b%origin%where('a0') // ': give one value per mode (' // &
          & itoa(m) // ' modes), got ' // itoa(count(b%a0 /= unset))); return
      end if
      if (count(b%ad0 /= unset) > 0 .and. count(b%ad0 /= unset) /= m) then
        call fatal_error(error, b%origin%where('ad0') // ': give one value per mode (' // &
          & itoa(m) // ' modes), got ' // itoa(count(b%ad0 /= unset))); return
      end if
    end associate
  end subroutine check_damping
end module pymr_model_scene_rules
