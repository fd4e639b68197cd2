!> What a result row holds and what describes it: the columns of &output quantities (one
!> walk states them for every format), a row's values in their order, and OUT.json (run
!> statistics and column metadata). The files of rows are results_csv and results_hdf5.
module pymr_io_results_output
  use pymr_env_kinds, only : dp
  use, intrinsic :: iso_fortran_env, only : int64
  use pymr_env_error, only : error_type
  use pymr_model_types, only : model_data, model_work, cut_free, prim_revolute
  use pymr_model_sensors, only : sensor_set, sensor_width, sensor_distance
  use pymr_env_text, only : json_escape, json_number, itoa, next_text_line
  use pymr_env_text_file, only : write_text_file, stage_text_file
  implicit none
  private
  public :: json_path, write_json, run_stats, pymr_version, output_plan, output_plan_of
  public :: energy_columns, n_energy, n_work, column_sink, walk_columns, header_line, row_width, row_values

  character(len=*), parameter :: pymr_version = '0.1.0'

  !> Statistics of one run, written to OUT.json.
  type :: run_stats
    !> CPU and wall time of the integration; CPU time of the pre-flight stability check
    !> (fixed steps), which the run's CPU time leaves out.
    real(dp) :: cpu_time_s = 0.0_dp, wall_time_s = 0.0_dp, preflight_cpu_s = 0.0_dp
    integer :: steps_slow = 0, steps_fast = 0, rhs_full = 0, rhs_fast = 0, rejected_steps = 0, rows = 0
    real(dp) :: h_last = 0.0_dp
    !> Multirate: the last step ratio H/h (1 single-rate).
    integer :: ratio_last = 1
    !> The static start: coordinates settled (-1: the run started at rest), Newton
    !> iterations, the largest change in the last one.
    integer :: static_settled = -1, static_iterations = 0
    real(dp) :: static_change = 0.0_dp
    !> Warnings of the run, one a line (a flexible body deflecting beyond its limit, a
    !> 'response' macro step run without its correction): add_warning.
    character(len=:), allocatable :: warnings
    !> JSON members the effects report (moving loads' exits), with their commas and lines.
    character(len=:), allocatable :: effects_report
    !> Method 'auto': the JSON member of its choice (with its comma and line), and the
    !> summary's line.
    character(len=:), allocatable :: choice_report, choice_line
  contains
    procedure :: add_warning
  end type run_stats

  !> The energy columns (energy.NAME): the four energies, their total, then the four works
  !> integrated over the run (held in checkpoints).
  integer, parameter :: n_energy = 9, n_work = 4
  character(len=*), parameter :: energy_columns(n_energy) = [character(len=12) :: 'kinetic', 'gravity', 'strain', &
    & 'springs', 'total', 'drive_work', 'load_work', 'motion_work', 'damping_loss']

  !> The groups of columns a run writes (&output quantities) and the number of values per
  !> row after t and the coordinates.
  type :: output_plan
    logical :: coordinates = .true., markers = .true., accelerations = .false., orientations = .false.
    logical :: reactions = .false., energy = .false.
    integer :: extra = 0
    !> The scene's sensors (&sensor): their columns come last.
    type(sensor_set) :: sensors
  end type output_plan

  !> What receives the columns of a plan, in the file's order (walk_columns): each column's
  !> name, group ('time', 'joint_coordinates', 'joint_rates', 'modal_coordinates',
  !> 'modal_rates', 'markers', 'marker_accelerations', 'marker_orientations', 'reactions',
  !> 'energy', 'sensors'), owner (the joint, flexible body, marker or sensor it belongs to;
  !> '' for t and the energies), quantity and unit. The one place that states the columns: the CSV header
  !> and the JSON's column metadata both follow from it.
  type, abstract :: column_sink
  contains
    procedure(column_add), deferred :: add
  end type column_sink

  abstract interface
    subroutine column_add(self, name, group, owner, quantity, unit)
      import :: column_sink
      class(column_sink), intent(inout) :: self
      character(len=*), intent(in) :: name, group, owner, quantity, unit
    end subroutine column_add
  end interface

  !> A text grown by appending, its buffer doubled when full (a scene may have 10^5 markers).
  type :: text_buffer
    character(len=:), allocatable :: s
    integer :: n = 0
  contains
    procedure :: add => buffer_add
  end type text_buffer

  !> The header row: the columns' names, comma-separated.
  type, extends(column_sink) :: header_sink
    type(text_buffer) :: line
  contains
    procedure :: add => header_add
  end type header_sink

  !> The column metadata of OUT.json: one JSON array (its items so far) per field.
  type, extends(column_sink) :: metadata_sink
    type(text_buffer) :: field(5)
  contains
    procedure :: add => metadata_add
  end type metadata_sink

  !> The fields of the column metadata, in metadata_sink%field's order.
  character(len=*), parameter :: metadata_fields(5) = [character(len=8) :: 'name', 'group', 'owner', 'quantity', 'unit']

contains

  !> One more line of the run's warnings.
  pure subroutine add_warning(self, line)
    class(run_stats), intent(inout) :: self
    character(len=*), intent(in) :: line
    if (.not. allocated(self%warnings)) self%warnings = ''
    self%warnings = self%warnings // line // new_line('a')
  end subroutine add_warning

  !> OUT.json beside OUT.csv (extension replaced, or appended).
  function json_path(csv) result(p)
    character(len=*), intent(in) :: csv
    character(len=:), allocatable :: p
    integer :: k
    k = index(csv, '.', back=.true.)
    if (k > index(csv, '/', back=.true.) .and. k > 1) then
      p = csv(1:k-1) // '.json'
    else
      p = csv // '.json'
    end if
  end function json_path

  !> The plan of &output quantities (blank-separated words) for model d.
  function output_plan_of(words, d, sensors) result(plan)
    character(len=*), intent(in) :: words
    type(model_data), intent(in) :: d
    !> The scene's sensors (none when absent).
    type(sensor_set), intent(in), optional :: sensors
    type(output_plan) :: plan
    plan%coordinates = has('coordinates')
    plan%markers = has('markers')
    plan%accelerations = has('marker_accelerations')
    plan%orientations = has('marker_orientations')
    plan%reactions = has('reactions')
    plan%energy = has('energy')
    plan%extra = d%markers%n*(merge(6, 0, plan%markers) + merge(3, 0, plan%accelerations) + &
      & merge(4, 0, plan%orientations)) + merge(6*(d%nb - 1 + d%cuts%n), 0, plan%reactions) + merge(n_energy, 0, plan%energy)
    if (present(sensors)) plan%sensors = sensors
    plan%extra = plan%extra + sensor_width(plan%sensors)
  contains
    logical function has(word)
      character(len=*), intent(in) :: word
      has = index(' ' // trim(words) // ' ', ' ' // word // ' ') > 0
    end function has
  end function output_plan_of

  !> Values per row: t, the coordinates and rates when written, and the plan's others.
  pure integer function row_width(plan, d)
    type(output_plan), intent(in) :: plan
    type(model_data), intent(in) :: d
    row_width = 1 + merge(2*d%n, 0, plan%coordinates) + plan%extra
  end function row_width

  !> The header row of the plan's columns.
  function header_line(plan, d) result(line)
    type(output_plan), intent(in) :: plan
    type(model_data), intent(in) :: d
    character(len=:), allocatable :: line
    type(header_sink) :: names
    call walk_columns(plan, d, names)
    line = names%line%s(1:names%line%n)
  end function header_line

  !> The row for time t in the columns' order: t, the coordinates q and rates qd (grouped by
  !> joint and body, when the plan writes them), then the plan's other values `extra`.
  pure subroutine row_values(plan, d, t, q, qd, extra, row)
    type(output_plan), intent(in) :: plan
    type(model_data), intent(in) :: d
    real(dp), intent(in) :: t, q(:), qd(:), extra(:)
    real(dp), intent(out) :: row(:)
    integer :: i, k, b0
    row(1) = t
    k = 1; b0 = 1
    do i = 1, d%n
      if (.not. plan%coordinates) exit
      k = k + 1; row(k) = q(i)
      if (i == d%n .or. d%cgrp(min(i + 1, d%n)) /= d%cgrp(i)) then
        row(k+1:k+i-b0+1) = qd(b0:i); k = k + i - b0 + 1; b0 = i + 1
      end if
    end do
    row(k+1:) = extra
  end subroutine row_values

  !> Hand every column of the plan, in the file's order, to `sink`: t, the coordinates and
  !> rates, the markers' values, the reactions, the energies.
  subroutine walk_columns(plan, d, sink)
    type(output_plan), intent(in) :: plan
    type(model_data), intent(in) :: d
    class(column_sink), intent(inout) :: sink
    integer :: i
    call sink%add('t', 'time', '', 'time', 's')
    if (plan%coordinates) call walk_coordinates(d, sink)
    do i = 1, d%markers%n
      call walk_marker(plan, trim(d%markers%name(i)), sink)
    end do
    ! the tree joints', then the loop-closing joints' reactions
    do i = 2, d%nb + d%cuts%n
      if (.not. plan%reactions) exit
      if (i <= d%nb) then
        call add_vector(sink, trim(d%joint_name(i)), 'f', 'reactions', 'force', 'N')
        call add_vector(sink, trim(d%joint_name(i)), 'm', 'reactions', 'moment', 'N m')
      else
        call add_vector(sink, trim(d%cuts%name(i - d%nb)), 'f', 'reactions', 'force', 'N')
        call add_vector(sink, trim(d%cuts%name(i - d%nb)), 'm', 'reactions', 'moment', 'N m')
      end if
    end do
    do i = 1, n_energy
      if (plan%energy) call sink%add('energy.' // trim(energy_columns(i)), 'energy', '', trim(energy_columns(i)), 'J')
    end do
    call walk_sensors(plan%sensors, sink)
  end subroutine walk_columns

  !> The sensors' columns (group 'sensors', owned by the sensor): a 'distance' NAME.d (m) and
  !> NAME.d_dot (m/s); a 'position' NAME.x, .y, .z (m) and NAME.vx, .vy, .vz (m/s).
  subroutine walk_sensors(sensors, sink)
    type(sensor_set), intent(in) :: sensors
    class(column_sink), intent(inout) :: sink
    integer :: i
    character(len=:), allocatable :: s
    do i = 1, sensors%n
      s = trim(sensors%name(i))
      if (sensors%kind(i) == sensor_distance) then
        call sink%add(s // '.d', 'sensors', s, 'distance', 'm')
        call sink%add(s // '.d_dot', 'sensors', s, 'distance_rate', 'm/s')
      else
        call add_vector(sink, s, '', 'sensors', 'position', 'm')
        call add_vector(sink, s, 'v', 'sensors', 'velocity', 'm/s')
      end if
    end do
  end subroutine walk_sensors

  !> The coordinates in model order, the rates of a joint's (or body's) coordinates after
  !> them.
  subroutine walk_coordinates(d, sink)
    type(model_data), intent(in) :: d
    class(column_sink), intent(inout) :: sink
    integer :: i, j
    do i = 1, d%n
      call add_coordinate(d, i, .false., sink)
      if (i == d%n .or. d%cgrp(min(i + 1, d%n)) /= d%cgrp(i)) then
        do j = 1, i
          if (d%cgrp(j) == d%cgrp(i)) call add_coordinate(d, j, .true., sink)
        end do
      end if
    end do
  end subroutine walk_coordinates

  !> Coordinate i's column (its rate's with `rate`): a joint's angle (rad) or displacement
  !> (m), or a flexible body's mass-normalised modal coordinate (m kg^0.5).
  subroutine add_coordinate(d, i, rate, sink)
    type(model_data), intent(in) :: d
    integer, intent(in) :: i
    logical, intent(in) :: rate
    class(column_sink), intent(inout) :: sink
    character(len=:), allocatable :: name, owner
    name = trim(merge(d%qdname(i), d%qname(i), rate))
    if (d%cbody(i) == 0) then
      call add_control_state(d, i, rate, name, sink); return
    end if
    owner = trim(d%body_name(d%cbody(i)))
    if (i > d%nj) then
      if (rate) call sink%add(name, 'modal_rates', owner, 'modal_rate', 'm kg^0.5/s')
      if (.not. rate) call sink%add(name, 'modal_coordinates', owner, 'modal_coordinate', 'm kg^0.5')
      return
    end if
    owner = trim(d%joint_name(d%cbody(i)))
    if (d%prim(i) == prim_revolute) then
      if (rate) call sink%add(name, 'joint_rates', owner, 'angular_velocity', 'rad/s')
      if (.not. rate) call sink%add(name, 'joint_coordinates', owner, 'angle', 'rad')
    else
      if (rate) call sink%add(name, 'joint_rates', owner, 'velocity', 'm/s')
      if (.not. rate) call sink%add(name, 'joint_coordinates', owner, 'displacement', 'm')
    end if
  end subroutine add_coordinate

  !> A controller's state coordinate i (model/effect_controls.f90): the integral of its error
  !> (the rate) and its double integral (the position), owned by the controller.
  subroutine add_control_state(d, i, rate, name, sink)
    type(model_data), intent(in) :: d
    integer, intent(in) :: i
    logical, intent(in) :: rate
    character(len=*), intent(in) :: name
    class(column_sink), intent(inout) :: sink
    character(len=:), allocatable :: owner, unit
    owner = d%qdname(i)(1:index(d%qdname(i), '.integral', back=.true.) - 1)
    unit = merge('rad', 'm  ', d%prim(i) == prim_revolute)
    if (rate) call sink%add(name, 'controls', owner, 'integral', trim(unit) // ' s')
    if (.not. rate) call sink%add(name, 'controls', owner, 'double_integral', trim(unit) // ' s^2')
  end subroutine add_control_state

  !> A marker's columns of the plan: position and velocity, acceleration, orientation.
  subroutine walk_marker(plan, m, sink)
    type(output_plan), intent(in) :: plan
    character(len=*), intent(in) :: m
    class(column_sink), intent(inout) :: sink
    integer :: k
    character(len=*), parameter :: wxyz = 'wxyz'
    if (plan%markers) then
      call add_vector(sink, m, '', 'markers', 'position', 'm')
      call add_vector(sink, m, 'v', 'markers', 'velocity', 'm/s')
    end if
    if (plan%accelerations) call add_vector(sink, m, 'a', 'marker_accelerations', 'acceleration', 'm/s^2')
    do k = 1, 4
      if (plan%orientations) call sink%add(m // '.q' // wxyz(k:k), 'marker_orientations', m, 'orientation', '1')
    end do
  end subroutine walk_marker

  !> The x, y and z columns OWNER.PREFIXx ... of a vector quantity.
  subroutine add_vector(sink, owner, prefix, group, quantity, unit)
    class(column_sink), intent(inout) :: sink
    character(len=*), intent(in) :: owner, prefix, group, quantity, unit
    call sink%add(owner // '.' // prefix // 'x', group, owner, quantity, unit)
    call sink%add(owner // '.' // prefix // 'y', group, owner, quantity, unit)
    call sink%add(owner // '.' // prefix // 'z', group, owner, quantity, unit)
  end subroutine add_vector

  subroutine buffer_add(self, text)
    class(text_buffer), intent(inout) :: self
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: grown
    if (.not. allocated(self%s)) allocate(character(len=max(256, 2*len(text))) :: self%s)
    if (self%n + len(text) > len(self%s)) then
      allocate(character(len=2*(self%n + len(text))) :: grown)
      grown(1:self%n) = self%s(1:self%n)
      call move_alloc(grown, self%s)
    end if
    self%s(self%n+1:self%n+len(text)) = text
    self%n = self%n + len(text)
  end subroutine buffer_add

  subroutine header_add(self, name, group, owner, quantity, unit)
    class(header_sink), intent(inout) :: self
    character(len=*), intent(in) :: name, group, owner, quantity, unit
    if (self%line%n > 0) call self%line%add(',')
    call self%line%add(name)
  end subroutine header_add

  subroutine metadata_add(self, name, group, owner, quantity, unit)
    class(metadata_sink), intent(inout) :: self
    character(len=*), intent(in) :: name, group, owner, quantity, unit
    call item(self%field(1), name); call item(self%field(2), group); call item(self%field(3), owner)
    call item(self%field(4), quantity); call item(self%field(5), unit)
  contains
    subroutine item(buffer, text)
      type(text_buffer), intent(inout) :: buffer
      character(len=*), intent(in) :: text
      if (buffer%n > 0) call buffer%add(', ')
      call buffer%add('"' // json_escape(text) // '"')
    end subroutine item
  end subroutine metadata_add

  !> The JSON member "columns": for every column of the plan, in the file's order, its
  !> name, group, owner, quantity and unit (one array per field).
  function columns_json(plan, d) result(text)
    type(output_plan), intent(in) :: plan
    type(model_data), intent(in) :: d
    character(len=:), allocatable :: text
    type(metadata_sink) :: meta
    integer :: k
    call walk_columns(plan, d, meta)
    text = '  "columns": {'
    do k = 1, size(metadata_fields)
      if (k > 1) text = text // ','
      text = text // new_line('a') // '    "' // trim(metadata_fields(k)) // '": [' // meta%field(k)%s(1:meta%field(k)%n) // ']'
    end do
    text = text // '},'
  end function columns_json

  !> Write the run statistics and settings as JSON (through path.tmp, checked, flushed,
  !> renamed): `status` 'complete' or 'failed', with the failure's message and the time
  !> reached, and the metadata of the columns of `plan`.
  subroutine write_json(path, scene_file, title, fingerprint, settings, d, wk, st, status, failure, t_reached, error, &
    & overrides, scene_text, plan, staged, text, pairing)
    !> fingerprint: 'sha256:...' of the resolved scene (pymr scene prints it).
    character(len=*), intent(in) :: path, scene_file, title, fingerprint, status, failure
    !> The run's --set overrides (one a line) and its resolved scene (every item, files
    !> absolute): what reproduces the run without the scene file as it was.
    character(len=*), intent(in) :: overrides, scene_text
    !> The columns of the results file.
    type(output_plan), intent(in) :: plan
    !> Leave the file complete in PATH.tmp for the caller's commit_staged (default: in place).
    logical, intent(in), optional :: staged
    !> The JSON text written, for a results format that keeps it with the rows.
    character(len=:), allocatable, intent(out), optional :: text
    !> Members tying the statistics to their results file (results_file%pairing).
    character(len=*), intent(in), optional :: pairing
    !> Integrator settings, already as JSON members ("\"method\": \"single\", ...").
    character(len=*), intent(in) :: settings
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    type(run_stats), intent(in) :: st
    real(dp), intent(in) :: t_reached
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: json
    json = '{' // new_line('a')
    call put('  "version": "' // pymr_version // '",')
    call put('  "status": "' // status // '",')
    if (len(failure) > 0) call put('  "error": "' // json_escape(failure) // '",')
    call put('  "t_reached": ' // json_number(t_reached, 17) // ',')
    call put('  "scene": "' // json_escape(scene_file) // '",')
    call put('  "title": "' // json_escape(trim(title)) // '",')
    call put('  "scene_fingerprint": "' // fingerprint // '",')
    if (present(pairing)) json = json // pairing
    call put('  "overrides": [' // json_lines(overrides) // '],')
    call put('  "resolved_scene": "' // json_escape(scene_text) // '",')
    json = json // counts_json(st, d, wk) // effects_json(wk)
    if (st%static_settled >= 0) then
      call put('  "static_start": {"coordinates_settled": ' // itoa(st%static_settled) // ', "newton_iterations": ' &
        & // itoa(st%static_iterations) // ', "last_change": ' // json_number(st%static_change, 6) // '},')
    end if
    if (allocated(st%effects_report)) json = json // st%effects_report
    if (allocated(st%choice_report)) json = json // st%choice_report
    if (allocated(st%warnings)) then
      call put('  "warnings": [' // json_lines(st%warnings) // '],')
    else
      call put('  "warnings": [],')
    end if
    call put(columns_json(plan, d))
    call put('  "integrator": {' // settings // '}')
    call put('}')
    call write_staged(path, json, error, staged)
    if (present(text)) text = json
    if (allocated(error)) error%message = error%message // ' (the statistics)'
  contains
    subroutine put(line)
      character(len=*), intent(in) :: line
      json = json // line // new_line('a')
    end subroutine put
  end subroutine write_json

  !> Write `text` to `path` in place, or with `staged` complete in PATH.tmp for the
  !> caller's commit_staged.
  subroutine write_staged(path, text, error, staged)
    character(len=*), intent(in) :: path, text
    type(error_type), allocatable, intent(out) :: error
    logical, intent(in), optional :: staged
    if (present(staged)) then
      if (staged) then
        call stage_text_file(path, text, error); return
      end if
    end if
    call write_text_file(path, text, error)
  end subroutine write_staged

  !> The JSON members of the run's times, steps, evaluations and sizes, and its loops'
  !> closure (one line each, with their commas).
  function counts_json(st, d, wk) result(text)
    type(run_stats), intent(in) :: st
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    character(len=:), allocatable :: text
    character(len=160) :: buf
    text = ''
    call put('  "cpu_time_s": ' // json_number(st%cpu_time_s, 10) // ',')
    call put('  "wall_time_s": ' // json_number(st%wall_time_s, 10) // ',')
    call put('  "preflight_cpu_s": ' // json_number(st%preflight_cpu_s, 10) // ',')
    write(buf, '(a,i0,a)') '  "steps_slow": ', st%steps_slow, ','; call put(trim(buf))
    write(buf, '(a,i0,a)') '  "steps_fast": ', st%steps_fast, ','; call put(trim(buf))
    write(buf, '(a,i0,a)') '  "rhs_full": ', st%rhs_full, ','; call put(trim(buf))
    write(buf, '(a,i0,a)') '  "rhs_fast": ', st%rhs_fast, ','; call put(trim(buf))
    write(buf, '(a,i0,a)') '  "rejected_steps": ', st%rejected_steps, ','; call put(trim(buf))
    call put('  "h_last": ' // json_number(st%h_last, 10) // ',')
    write(buf, '(a,i0,a)') '  "step_ratio_last": ', st%ratio_last, ','; call put(trim(buf))
    write(buf, '(a,i0,a)') '  "rows": ', st%rows, ','; call put(trim(buf))
    write(buf, '(a,i0,a)') '  "n_coordinates": ', d%n, ','; call put(trim(buf))
    if (d%cuts%n > 0) then
      write(buf, '(a,i0,a,i0,a,i0,a,i0,a)') '  "loops": {"closing_joints": ', d%cuts%n, ', "free_closing_joints": ', &
        & count(d%cuts%kind == cut_free), ', "constraint_rows": ', d%cuts%n_rows, ', "redundant_rows": ', wk%loops%n_redundant, ','
      call put(trim(buf))
      call put('    "assembly_change_q": ' // json_number(wk%loops%assembly_dq, 6) // ', "assembly_change_qd": ' // &
        & json_number(wk%loops%assembly_dqd, 6) // ', "closure_drift": ' // json_number(wk%loops%closure_drift, 6) // '},')
    end if
  contains
    subroutine put(line)
      character(len=*), intent(in) :: line
      text = text // line // new_line('a')
    end subroutine put
  end function counts_json

  !> The JSON member "effects": each effect of the model, its evaluations and CPU time.
  function effects_json(wk) result(text)
    type(model_work), intent(in) :: wk
    character(len=:), allocatable :: text
    integer :: i
    real(dp) :: cpu
    text = '  "effects": {'
    do i = 1, size(wk%count%effect_evals)
      if (text(len(text):len(text)) /= '{') text = text // ', '
      cpu = 0.0_dp
      if (wk%count%effect_timed(i) > 0) cpu = wk%count%effect_cpu(i)*real(wk%count%effect_evals(i), dp)/real(wk%count%effect_timed(i), dp)
      text = text // '"' // trim(wk%count%effect_name(i)) // '": {"evaluations": ' // itoa(wk%count%effect_evals(i)) // &
        & ', "cpu_time_s": ' // json_number(cpu, 6) // '}'
    end do
    text = text // '},' // new_line('a')
  end function effects_json

  !> Lines of text as JSON strings, comma-separated ('' for no line).
  function json_lines(lines) result(s)
    character(len=*), intent(in) :: lines
    character(len=:), allocatable :: s, one
    integer :: pos
    s = ''
    pos = 1
    do while (next_text_line(lines, pos, one))
      if (len(one) == 0) cycle
      if (len(s) > 0) s = s // ', '
      s = s // '"' // json_escape(one) // '"'
    end do
  end function json_lines

end module pymr_io_results_output
