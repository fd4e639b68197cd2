!> One run from a scene file to result files: read, build, integrate, write.
!> Shared by the `mrsim` program and the Python binding.
module pymr_driver_run
  use, intrinsic :: iso_fortran_env, only : error_unit
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver, prefix_error
  use pymr_model_scene, only : scene_t, unset
  use pymr_io_namelist_input, only : read_scene, scene_fingerprint, checkpoint_identity, resolved_text
  use pymr_driver_build, only : build_model
  use pymr_model, only : model_t
  use pymr_integrator_stepper, only : stepper_t, step_counts
  use pymr_driver_stepper_setup, only : make_stepper, stepper_label, method_label
  use pymr_io_results_output, only : csv_writer, json_path, write_json, run_stats, output_plan_of, n_work
  use pymr_driver_output_quantities, only : write_output_row, work_at
  use pymr_model_kinematics, only : forward_kinematics, marker_motion
  use pymr_model_loops, only : assemble_loops
  use pymr_model_scene_rules, only : closes_loop
  use pymr_model_types, only : cut_free
  use pymr_env_clock, only : thread_cpu_time
  use pymr_model_effects, only : prescribed_motion
  use pymr_env_text, only : itoa, fmt, next_text_line
  use pymr_model_flexbody, only : point_deflection
  use pymr_env_text_file, only : absolute_path, scene_relative, acquire_lock, release_lock, not_regular, missing_folder, &
    & commit_staged, remove_file, same_file
  use pymr_driver_preflight, only : check_step_stability, check_mass_matrix, static_start
  use pymr_io_checkpoint, only : run_progress, write_checkpoint, read_checkpoint
  implicit none
  private
  public :: run_scene, load_model, scene_input, starting_state, default_output, progress_t, progress_t_end, progress_running

  !> 'auto' dynamics with flexible bodies: the articulated-body algorithm from this many joint
  !> coordinates on.
  integer, parameter :: articulated_from = 12

  !> Markers whose final motion the summary prints (the results hold them all).
  integer, parameter :: max_summary_markers = 10

  !> Progress of the run in this process, read by the Python binding from another thread
  !> while the run goes on (no call back into Python per step): simulated time reached,
  !> end time, and whether a run is going.
  real(dp), volatile :: progress_t = 0.0_dp, progress_t_end = 0.0_dp
  logical, volatile :: progress_running = .false.

contains

  !> Read and build the model of a scene (with overrides).
  subroutine load_model(file, overrides, sc, model, error, n)
    character(len=*), intent(in) :: file, overrides
    type(scene_t), intent(out) :: sc
    type(model_t), intent(out) :: model
    type(error_type), allocatable, intent(out) :: error
    !> The number of coordinates the caller's arrays hold (the binding): another is an error.
    integer, intent(in), optional :: n
    call read_scene(file, overrides, sc, error); if (allocated(error)) return
    call build_model(sc, model, error); if (allocated(error)) return
    call model%use_articulated(articulated_dynamics(sc, model))
    if (present(n)) then
      if (model%d%n /= n) call fatal_error(error, 'q has the wrong length')
    end if
  end subroutine load_model

  !> Whether single-rate evaluations take the articulated-body algorithm: as the scene says,
  !> or ('auto') where it is the faster (`pymr bench chain`, `pymr bench rhs`): always
  !> without flexible bodies, and with them from articulated_from joint coordinates on
  !> (below, condensing the modes costs more than assembling and factoring a small M).
  logical function articulated_dynamics(sc, model)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    select case (trim(sc%integrator%dynamics))
    case ('articulated'); articulated_dynamics = .true.
    case ('mass_matrix'); articulated_dynamics = .false.
    case default; articulated_dynamics = (model%d%nj >= articulated_from .or. .not. any(model%d%flexible)) &
      & .and. model%d%n_rows == 0
    end select
  end function articulated_dynamics

  !> The output must not overwrite what the run reads (the scene, its modal and table files)
  !> nor collide with its own statistics file.
  subroutine check_output_path(sc, path, error)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: what
    if (absolute_path(json_path(path)) == absolute_path(path)) then
      call fatal_error(error, sc%file // ': output ' // path // ': the results and their statistics would both ' // &
        & 'be ' // json_path(path) // ' (give a .csv file)'); return
    end if
    ! the run writes each file whole beside it and renames it over the old one
    if (replaces(path, 'output ' // path, 'another results file')) return
    if (replaces(json_path(path), 'output ' // path // ': its statistics ' // json_path(path), &
      & 'another results file')) return
    if (sc%output%checkpoint_dt > 0.0_dp) then
      if (len_trim(sc%output%checkpoint_file) > 0) then
        if (replaces(trim(sc%output%checkpoint_file), sc%output%origin%where('checkpoint_file'), &
          & 'another checkpoint file')) return
        if (no_folder(trim(sc%output%checkpoint_file), sc%output%origin%where('checkpoint_file'))) return
      else
        if (replaces(checkpoint_default(path), 'output ' // path // ': its checkpoint ' // checkpoint_default(path), &
          & 'another results file, or a checkpoint_file in &output')) return
      end if
    end if
    what = scene_input(sc, path)
    if (len(what) > 0) then
      call fatal_error(error, sc%file // ': output ' // path // ': would overwrite ' // what // &
        & '; choose another results file'); return
    end if
    what = scene_input(sc, json_path(path))
    if (len(what) > 0) call fatal_error(error, sc%file // ': output ' // path // ': its statistics ' // &
      & json_path(path) // ' would overwrite ' // what // '; choose another results file')
  contains
    !> Is `file` there and no regular file, that the run's file would replace? `label` names
    !> it in the message (after the scene's name unless it is an item's place), `advice` what to choose.
    logical function replaces(file, label, advice)
      character(len=*), intent(in) :: file, label, advice
      replaces = len(not_regular(file)) > 0
      if (.not. replaces) return
      if (index(label, sc%file) == 1) then
        call fatal_error(error, label // ': ' // not_regular(file) // '; choose ' // advice)
      else
        call fatal_error(error, sc%file // ': ' // label // ': ' // not_regular(file) // '; choose ' // advice)
      end if
    end function replaces

    !> Is the folder that `file` would be written in missing? Found before the run starts.
    logical function no_folder(file, label)
      character(len=*), intent(in) :: file, label
      no_folder = len(missing_folder(file)) > 0
      if (no_folder) call fatal_error(error, label // ": the folder '" // missing_folder(file) // &
        & "' does not exist (make it, or choose a checkpoint_file in a folder that does)")
    end function no_folder
  end subroutine check_output_path

  !> What of the scene's input `path` is: 'the scene (FILE)', 'a modal file of the scene
  !> (FILE)', 'a table file of the scene (FILE)', or '' when the run reads no such file. An
  !> output written there would destroy the input of the next run.
  function scene_input(sc, path) result(what)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: what
    integer :: i
    what = ''
    if (is(sc%file, 'the scene')) return
    do i = 1, size(sc%bodies)
      if (len_trim(sc%bodies(i)%modal_file) == 0) cycle
      if (is(scene_relative(sc%file, trim(sc%bodies(i)%modal_file)), 'a modal file of the scene')) return
    end do
    do i = 1, size(sc%drives)
      if (len_trim(sc%drives(i)%file) == 0) cycle
      if (is(scene_relative(sc%file, trim(sc%drives(i)%file)), 'a table file of the scene')) return
    end do
    do i = 1, size(sc%motions)
      if (len_trim(sc%motions(i)%file) == 0) cycle
      if (is(scene_relative(sc%file, trim(sc%motions(i)%file)), 'a table file of the scene')) return
    end do
  contains
    logical function is(file, label)
      character(len=*), intent(in) :: file, label
      is = same_file(file, path)
      if (is) what = label // ' (' // file // ')'
    end function is
  end function scene_input

  !> The results file the run would write, refused above &output max_bytes: rows from t_end
  !> and the output interval (every step of a fixed-step run when dt is 0), 25 bytes a value.
  subroutine check_output_size(sc, model, csv, dt_out, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    type(csv_writer), intent(in) :: csv
    real(dp), intent(in) :: dt_out
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: rows, bytes
    if (dt_out <= 0.0_dp) return          ! adaptive, every step: bounded by max_steps
    rows = sc%scene%t_end/dt_out + 2
    bytes = rows*25.0_dp*(1 + merge(2*model%d%n, 0, csv%plan%coordinates) + csv%plan%extra)
    if (bytes > sc%output%max_bytes) call fatal_error(error, sc%output%origin%where('dt') // ': the results would ' // &
      & 'take about ' // fmt(bytes) // ' bytes (' // fmt(rows) // ' rows), more than max_bytes = ' // &
      & fmt(sc%output%max_bytes) // ' (a larger dt, or raise max_bytes in &output)')
  end subroutine check_output_size

  !> Output path: the command line's, else &output file, else the scene's name with .csv.
  function default_output(sc, out) result(path)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: out
    character(len=:), allocatable :: path
    integer :: k, s
    if (len_trim(out) > 0) then
      path = trim(out)
    else if (len_trim(sc%output%file) > 0) then
      path = trim(sc%output%file)
    else
      s = index(sc%file, '/', back=.true.)
      k = index(sc%file, '.', back=.true.)
      if (k <= s) k = len(sc%file) + 1
      path = sc%file(s+1:k-1) // '.csv'
    end if
  end function default_output

  !> Run a scene: results to `out` (or the default), statistics beside it; `summary`
  !> receives a few human-readable lines. With `restart`, continue the run from that
  !> checkpoint file: the results file keeps the rows written up to the checkpoint.
  subroutine run_scene(file, overrides, out, summary, error, written, restart, progress_lines)
    character(len=*), intent(in) :: file, overrides, out
    character(len=:), allocatable, intent(out) :: summary
    type(error_type), allocatable, intent(out) :: error
    !> The CSV file written (a required argument: gfortran 12 gave an optional deferred-length
    !> one, passed on to run_locked, a garbage length when the output path was the default).
    character(len=:), allocatable, intent(out) :: written
    !> Checkpoint to continue from ('' or absent: a new run).
    character(len=*), intent(in), optional :: restart
    !> Print a progress line to stderr about every second (mrsim --progress).
    logical, intent(in), optional :: progress_lines
    character(len=:), allocatable :: locked
    call run_locked(file, overrides, out, summary, error, locked, written, restart, progress_lines)
    if (allocated(locked)) call release_lock(locked)
  end subroutine run_scene

  !> The run, holding OUT.lock from the moment its output is known (`locked` names it for
  !> the caller to release), so that two runs never write the same results.
  subroutine run_locked(file, overrides, out, summary, error, locked, written, restart, progress_lines)
    character(len=*), intent(in) :: file, overrides, out
    character(len=:), allocatable, intent(out) :: summary
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable, intent(out) :: locked
    character(len=:), allocatable, intent(out) :: written
    character(len=*), intent(in), optional :: restart
    logical, intent(in), optional :: progress_lines
    type(scene_t), target :: sc
    type(model_t) :: model
    class(stepper_t), allocatable :: st
    type(csv_writer) :: csv
    type(run_stats) :: stats
    type(run_progress) :: prog
    real(dp), allocatable :: x(:)
    real(dp) :: h, h0, dt_out, t_next, eps, cpu0, cpu1, t_ckpt, t_step, t_first_row, t_line, work(n_work), work_step(n_work)
    integer :: n, k_out
    integer(8) :: c0, c1, rate, c_line
    logical :: restarting, lines
    character(len=:), allocatable :: path, ckpt_path, settings, fingerprint, scene_text
    type(error_type), allocatable :: json_error
    type(step_counts) :: done

    restarting = .false.
    if (present(restart)) restarting = len_trim(restart) > 0
    lines = .false.
    if (present(progress_lines)) lines = progress_lines
    call load_model(file, overrides, sc, model, error); if (allocated(error)) return
    n = model%d%n
    path = default_output(sc, out)
    call check_output_path(sc, path, error); if (allocated(error)) return
    call acquire_lock(path, error); if (allocated(error)) return
    locked = path
    ! what a checkpoint must share with its scene (only needed when there are checkpoints)
    if (restarting .or. sc%output%checkpoint_dt > 0.0_dp) call checkpoint_identity(sc, settings, fingerprint)
    ckpt_path = trim(sc%output%checkpoint_file)
    if (len(ckpt_path) == 0) ckpt_path = checkpoint_default(path)
    cpu0 = thread_cpu_time(); call system_clock(c0, rate)
    h = sc%integrator%h_slow
    allocate(x(2*n))
    call starting_state(sc, model, x, error, stats)
    if (allocated(error)) then
      if (index(error%message, file) /= 1) error%message = file // ': ' // error%message
      return
    end if
    dt_out = sc%output%dt
    if (dt_out <= 0.0_dp .and. .not. sc%integrator%adaptive) dt_out = h
    eps = 1.0e-9_dp*h
    k_out = 1
    t_next = dt_out
    csv%digits = sc%output%precision
    csv%plan = output_plan_of(sc%output%quantities, model%d)
    ! the works of the energy columns at t_step, the start of the stepper's last step
    work_step = 0.0_dp; t_step = 0.0_dp
    call make_stepper(sc, model, x, st, h0, error)
    if (allocated(error)) then
      if (index(error%message, file) /= 1) error%message = file // ': ' // error%message
      return
    end if
    if (restarting) then
      call read_checkpoint(restart, st, model, prog, settings, fingerprint, &
        & sc%scene%t_end, error)
      if (.not. allocated(error)) call csv%reopen(path, model%d, prog%rows, error)
      if (allocated(error)) then
        call csv%close()
        if (index(error%message, file) /= 1) error%message = file // ': ' // error%message
        return
      end if
      stats%rows = prog%rows; k_out = prog%k_out; t_next = prog%t_next; work_step = prog%work; t_step = st%time()
      cpu0 = cpu0 - prog%cpu_s
    else
      call check_output_size(sc, model, csv, dt_out, error); if (allocated(error)) return
      call csv%open(path, model%d, sc%scene%title, method_label(sc), error); if (allocated(error)) return
      call check_mass_matrix(model, x, file // ': ', error)
      if (.not. allocated(error)) call put_row(0.0_dp, work_step)
      stats%rows = 1
      if (allocated(error)) then
        call csv%discard(); return
      end if
      if (.not. sc%integrator%adaptive .and. sc%integrator%stability_check) then
        stats%preflight_cpu_s = thread_cpu_time()
        call check_step_stability(model, x, st, stepper_label(sc), sc%scene%t_end, file // ': &integrator: ', error)
        if (allocated(error)) then
          call csv%discard(); return
        end if
        stats%preflight_cpu_s = thread_cpu_time() - stats%preflight_cpu_s
        cpu0 = cpu0 + stats%preflight_cpu_s
      end if
      call st%start(model, 0.0_dp, x, h0, error)
      if (allocated(error)) then
        call csv%discard()
        if (index(error%message, file) /= 1) error%message = file // ': ' // error%message
        return
      end if
    end if
    t_first_row = st%time()
    progress_t_end = sc%scene%t_end; progress_t = st%time(); progress_running = .true.
    c_line = c0
    if (lines) call progress_line(st%time(), sc%scene%t_end, c0, rate)
    t_line = st%time()
    t_ckpt = huge(1.0_dp)
    if (sc%output%checkpoint_dt > 0.0_dp) t_ckpt = (floor(st%time()/sc%output%checkpoint_dt + 1.0e-9_dp) + 1)*sc%output%checkpoint_dt
    do
      if (dt_out > 0.0_dp) then
        do while (t_next <= min(st%time(), sc%scene%t_end) + eps)
          call st%value_at(t_next, x)
          call work_at(csv%plan, st, model, t_step, work_step, t_next, work, error); if (allocated(error)) exit
          call put_row(t_next, work); if (allocated(error)) exit
          stats%rows = stats%rows + 1
          k_out = k_out + 1; t_next = k_out*dt_out
        end do
      end if
      if (allocated(error)) exit
      ! the works at the time reached (for its row, the checkpoint, and the start of the next step)
      call work_at(csv%plan, st, model, t_step, work_step, st%time(), work, error); if (allocated(error)) exit
      work_step = work; t_step = st%time()
      ! every step's row, but not again the row of the state the loop starts from (t = 0, or
      ! a checkpoint's time, whose row is written)
      if (dt_out <= 0.0_dp .and. st%time() > t_first_row + eps .and. st%time() < sc%scene%t_end - eps) then
        call st%value_at(st%time(), x)
        call put_row(st%time(), work_step)
        stats%rows = stats%rows + 1
        if (allocated(error)) exit
      end if
      if (st%time() >= sc%scene%t_end - eps) exit
      if (st%time() >= t_ckpt - eps) then
        ! the rows up to now are on disk (checked) before the checkpoint that counts them
        call csv%flush_rows()
        if (csv%ios == 0) then
          prog = run_progress(rows=stats%rows, k_out=k_out, t_next=t_next, cpu_s=thread_cpu_time() - cpu0, &
            & t_checkpoint=st%time(), work=work_step)
          call write_checkpoint(ckpt_path, st, model, prog, settings, fingerprint, error); if (allocated(error)) exit
          t_ckpt = (floor(st%time()/sc%output%checkpoint_dt + 1.0e-9_dp) + 1)*sc%output%checkpoint_dt
        end if
      end if
      if (csv%ios /= 0) then
        call fatal_error(error, 'at t = ' // fmt(st%time()) // ' s: ' // csv%partial // ': cannot write the ' // &
          & 'results: ' // trim(csv%io_message), stat_solver); exit
      end if
      call st%advance(model, error); if (allocated(error)) exit
      done = st%counts()
      if (done%steps_fast > sc%integrator%max_steps) then
        call fatal_error(error, 'at t = ' // fmt(st%time()) // ' s: the run took more than max_steps = ' // &
          & itoa(sc%integrator%max_steps) // ' steps (&integrator max_steps lifts the limit)', stat_solver); exit
      end if
      progress_t = st%time()
      if (lines) then
        call system_clock(c1)
        if (c1 - c_line >= rate) then
          call progress_line(st%time(), sc%scene%t_end, c0, rate); c_line = c1; t_line = st%time()
        end if
      end if
    end do
    progress_running = .false.
    ! the last line, unless the loop's last one was already at t_end
    if (lines .and. .not. allocated(error) .and. t_line < sc%scene%t_end - eps) &
      & call progress_line(sc%scene%t_end, sc%scene%t_end, c0, rate)
    if (.not. allocated(error)) then
      call st%value_at(sc%scene%t_end, x)
      if (dt_out <= 0.0_dp .or. abs(t_next - dt_out - sc%scene%t_end) > eps) then
        call work_at(csv%plan, st, model, t_step, work_step, sc%scene%t_end, work, error)
        if (.not. allocated(error)) call put_row(sc%scene%t_end, work)
        stats%rows = stats%rows + 1
      end if
    end if
    cpu1 = thread_cpu_time(); call system_clock(c1)
    stats%cpu_time_s = cpu1 - cpu0; stats%wall_time_s = real(c1 - c0, dp)/real(rate, dp)
    call fill_stats(st, model, stats)
    scene_text = resolved_text(sc, absolute_paths=.true.)
    ! the new results replace the earlier ones only once both files are complete: the
    ! statistics wait in PATH.json.tmp while the rows are put in place
    if (.not. allocated(error)) call write_json(json_path(path), file, sc%scene%title, scene_fingerprint(sc), &
      & settings_json(sc), model%d, stats, 'complete', '', sc%scene%t_end, error, overrides, scene_text, staged=.true.)
    if (.not. allocated(error)) then
      call csv%finish(error)
      if (allocated(error)) call remove_file(json_path(path) // '.tmp')
    end if
    if (allocated(error)) then
      ! the rows written so far stay in PATH.partial, described by PATH.json.partial
      call csv%close()
      error%message = file // ': ' // error%message
      call write_json(json_path(path) // '.partial', file, sc%scene%title, scene_fingerprint(sc), &
        & settings_json(sc), model%d, stats, 'failed', error%message, st%time(), json_error, overrides, scene_text)
      return
    end if
    call commit_staged(json_path(path), error)
    if (allocated(error)) then
      error%message = file // ': ' // error%message // ' (the statistics; ' // path // ' is the new results)'; return
    end if
    summary = summary_text(sc, model, stats, path, x)
    written = path
  contains
    !> Write the row of state x at time t, and watch the flexible bodies' deflection there.
    subroutine put_row(t, row_work)
      real(dp), intent(in) :: t, row_work(:)
      call write_output_row(csv, model, t, x(1:n), x(n+1:), row_work, error); if (allocated(error)) return
      call watch_deflection(sc, model, t, x(1:n), stats, error)
    end subroutine put_row
  end subroutine run_locked

  !> A flexible body whose points deflect beyond &scene deflection_limit of its size at time
  !> t: a warning (once a body) in the run's statistics, or with deflection_stop a failed run.
  subroutine watch_deflection(sc, model, t, q, stats, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: t, q(:)
    type(run_stats), intent(inout) :: stats
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: deflection, size_m
    integer :: b
    character(len=:), allocatable :: said
    if (sc%scene%deflection_limit <= 0.0_dp) return
    if (.not. allocated(stats%warnings)) stats%warnings = ''
    do b = 2, model%d%nb
      if (model%d%nm(b) == 0) cycle
      ! a body is warned about once: not measured again after that
      if (index(stats%warnings, "body '" // trim(model%d%body_name(b)) // "' deflects") > 0) cycle
      call point_deflection(model%d%flex(b), q(model%d%a0(b):model%d%a0(b) + model%d%nm(b) - 1), deflection, size_m)
      if (deflection <= sc%scene%deflection_limit*size_m) cycle
      said = "body '" // trim(model%d%body_name(b)) // "' deflects " // fmt(deflection) // ' m, ' // &
        & fmt(deflection/size_m) // ' of its size ' // fmt(size_m) // ' m (&scene deflection_limit = ' // &
        & fmt(sc%scene%deflection_limit) // '): linear modal theory holds for small deflections only'
      if (sc%scene%deflection_stop) then
        call fatal_error(error, 'at t = ' // fmt(t) // ' s: ' // said // ' (deflection_stop)', stat_solver); return
      end if
      stats%warnings = stats%warnings // 'at t = ' // fmt(t) // ' s: ' // said // new_line('a')
    end do
  end subroutine watch_deflection

  !> One progress line on stderr: simulated time, percent, wall time and its estimate to go.
  subroutine progress_line(t, t_end, c0, rate)
    real(dp), intent(in) :: t, t_end
    integer(8), intent(in) :: c0, rate
    integer(8) :: c
    real(dp) :: wall, eta
    character(len=160) :: buf
    call system_clock(c)
    wall = real(c - c0, dp)/real(rate, dp)
    write(buf, '(a,es11.4,a,es11.4,a,f6.1,a,f9.1,a)') 'mrsim: t = ', t, ' s of ', t_end, ' s (', &
      & 100.0_dp*min(t/t_end, 1.0_dp), ' %), ', wall, ' s elapsed'
    ! the time to go, from the pace so far: none before 1 % of the run or 1 s of it (the
    ! start-up's pace says nothing of the rest), none at the end
    if (t >= 0.01_dp*t_end .and. wall >= 1.0_dp .and. t < t_end) then
      eta = wall*(t_end - t)/t
      write(buf, '(a,a,f9.1,a)') trim(buf), ', ETA ', eta, ' s'
    end if
    write(error_unit, '(a)') trim(buf)
    flush(error_unit)
  end subroutine progress_line

  !> The checkpoint file beside the CSV: extension replaced by .ckpt (or appended).
  function checkpoint_default(csv) result(p)
    character(len=*), intent(in) :: csv
    character(len=:), allocatable :: p
    integer :: k
    k = index(csv, '.', back=.true.)
    if (k > index(csv, '/', back=.true.) .and. k > 1) then
      p = csv(1:k-1) // '.ckpt'
    else
      p = csv // '.ckpt'
    end if
  end function checkpoint_default

  !> Step and evaluation counts of a run: steps from the stepper, evaluations from the model.
  subroutine fill_stats(st, model, stats)
    class(stepper_t), intent(in) :: st
    type(model_t), intent(in) :: model
    type(run_stats), intent(inout) :: stats
    type(step_counts) :: c
    c = st%counts()
    stats%steps_slow = c%steps_slow; stats%steps_fast = c%steps_fast
    stats%rejected_steps = c%rejected; stats%h_last = c%h_last; stats%ratio_last = c%ratio
    stats%rhs_full = model%d%evals
    stats%rhs_fast = model%d%evals_fast_rows + c%evals_fast
  end subroutine fill_stats

  !> [q0; qd0] from the joints' q0 and qd0 in model coordinate order.
  subroutine initial_state(sc, model, x)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    real(dp), intent(out) :: x(:)
    integer :: b, j, m, n, i
    real(dp) :: fdd
    n = model%d%n
    x = 0.0_dp
    do b = 2, model%d%nb
      do j = 1, size(sc%joints)
        if (sc%joints(j)%name /= model%d%joint_name(b)) cycle
        do m = 1, model%d%nc(b)
          x(model%d%c0(b) + m - 1) = sc%joints(j)%q0(m)
          x(n + model%d%c0(b) + m - 1) = sc%joints(j)%qd0(m)
        end do
      end do
    end do
    ! flexible bodies: their initial modal state when given (0 else)
    do b = 2, model%d%nb
      if (model%d%nm(b) == 0) cycle
      do j = 1, size(sc%bodies)
        if (sc%bodies(j)%name /= model%d%body_name(b)) cycle
        m = model%d%nm(b)
        if (sc%bodies(j)%a0(1) /= unset) x(model%d%a0(b):model%d%a0(b) + m - 1) = sc%bodies(j)%a0(1:m)
        if (sc%bodies(j)%ad0(1) /= unset) x(n + model%d%a0(b):n + model%d%a0(b) + m - 1) = sc%bodies(j)%ad0(1:m)
      end do
    end do
    ! prescribed coordinates start on their functions
    do i = 1, model%d%n_prescribed
      call prescribed_motion(model%d, i, 0.0_dp, x(model%d%pres_coord(i)), x(n + model%d%pres_coord(i)), fdd)
    end do
  end subroutine initial_state

  !> The state a run starts from: as the scene gives it (its loops assembled), then, for
  !> &scene start = 'static', with the modal coordinates and those of the joints marked
  !> settle in static equilibrium (on the loops' constraints).
  subroutine starting_state(sc, model, x, error, stats)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(inout) :: model
    real(dp), intent(out) :: x(:)
    type(error_type), allocatable, intent(out) :: error
    !> Receives what a static start did.
    type(run_stats), intent(inout), optional :: stats
    integer :: iterations
    real(dp) :: change
    integer, allocatable :: u(:)
    logical, allocatable :: settles(:)
    character(len=64), allocatable :: names(:)
    integer :: b, j, i, n
    call initial_state(sc, model, x)
    n = model%d%n
    call assemble_loops(model%d, x(1:n), x(n+1:), marked_coordinates(sc, model, sc%joints%hold), error)
    if (allocated(error)) then
      ! the loops' fault is no single line's: it names the first loop-closing joint
      do j = 1, size(sc%joints)
        if (closes_loop(sc, j)) exit
      end do
      error%message = sc%joints(j)%origin%where() // ': ' // error%message; return
    end if
    if (sc%scene%start /= 'static') return
    settles = marked_coordinates(sc, model, sc%joints%settle)
    allocate(u(0))
    do b = 2, model%d%nb
      u = [u, (model%d%a0(b) + i, i = 0, model%d%nm(b) - 1)]
      associate(c0 => model%d%c0(b), nc => model%d%nc(b))
        u = [u, pack([(c0 + i, i = 0, nc - 1)], settles(c0:c0 + nc - 1))]
      end associate
    end do
    allocate(names(n))
    do i = 1, n
      names(i) = model%component_name(i)
    end do
    call static_start(model, u, names, x, error, iterations, change); if (allocated(error)) return
    if (present(stats)) then
      stats%static_settled = size(u); stats%static_iterations = iterations; stats%static_change = change
    end if
    ! the equilibrium closes the loops to Newton's tolerance; the projection closes them to
    ! the run's and takes the rates' motion across them away at the settled positions
    call model%project(0.0_dp, x, error)
    model%d%closure_drift = 0.0_dp     ! the statistic is of the run's steps
  end subroutine starting_state

  !> The coordinates of the tree joints marked in `marked` (one flag per &joint: settle,
  !> hold).
  function marked_coordinates(sc, model, marked) result(mask)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    logical, intent(in) :: marked(:)
    logical :: mask(model%d%n)
    integer :: b, j
    mask = .false.
    do b = 2, model%d%nb
      do j = 1, size(sc%joints)
        if (sc%joints(j)%name == model%d%joint_name(b) .and. marked(j)) &
          & mask(model%d%c0(b):model%d%c0(b) + model%d%nc(b) - 1) = .true.
      end do
    end do
  end function marked_coordinates

  !> Integrator settings as JSON members.
  function settings_json(sc) result(s)
    type(scene_t), intent(in) :: sc
    character(len=:), allocatable :: s
    character(len=512) :: buf
    associate(g => sc%integrator)
      write(buf, '(a,g0.10,a,g0.10,a,g0.10,a,g0.10,a,g0.10,a,g0.10,a,i0,a,g0.10)') &
        & '", "h_fast": ', g%h_fast, ', "h_slow": ', g%h_slow, ', "rtol": ', g%rtol, ', "atol": ', g%atol, &
        & ', "h_min": ', g%h_min, ', "h_max": ', g%h_max, ', "n_corrector": ', g%n_corrector, ', "t_end": ', sc%scene%t_end
      s = '"method": "' // trim(g%method) // trim(buf) // ', "adaptive": ' // trim(merge('true ', 'false', g%adaptive)) &
        & // ', "coupling": "' // trim(g%coupling) // '", "formula": "' // trim(g%formula) // '", "order": ' // &
        & itoa(g%order) // ', "corrector": "' // trim(g%corrector) // '", "dynamics": "' // trim(g%dynamics) // &
        & '", "k_max": ' // itoa(g%k_max)
    end associate
  end function settings_json

  function summary_text(sc, model, st, path, x) result(s)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(inout) :: model
    type(run_stats), intent(in) :: st
    character(len=*), intent(in) :: path
    real(dp), intent(in) :: x(:)
    character(len=:), allocatable :: s
    character(len=256) :: buf
    character(len=:), allocatable :: warning
    real(dp) :: r(3), v(3)
    integer :: i, j, n
    n = model%d%n
    s = 'scene: ' // trim(sc%scene%title) // new_line('a') // 'method: ' // method_label(sc) // new_line('a')
    if (st%steps_fast /= st%steps_slow) then
      write(buf, '(a,i0,a,i0,a,i0,a,i0,a)') 'simulated 0 to ' // fmt(sc%scene%t_end) // ' s: ', st%steps_slow, &
        & ' steps (', st%steps_fast, ' fast), ', st%rejected_steps, ' rejected, ', st%rhs_full, ' full evaluations'
    else
      write(buf, '(a,i0,a,i0,a,i0,a)') 'simulated 0 to ' // fmt(sc%scene%t_end) // ' s: ', st%steps_slow, &
        & ' steps, ', st%rejected_steps, ' rejected, ', st%rhs_full, ' full evaluations'
    end if
    if (st%rhs_fast > 0) write(buf, '(a,a,i0,a)') trim(buf), ', ', st%rhs_fast, ' fast-only'
    s = s // trim(buf) // new_line('a')
    write(buf, '(a,f10.4,a,f10.4,a)') 'cpu time ', st%cpu_time_s, ' s, wall time ', st%wall_time_s, ' s'
    s = s // trim(buf)
    if (st%preflight_cpu_s > 0.0_dp) s = s // ' (pre-flight stability check: ' // fmt(st%preflight_cpu_s) // ' s CPU)'
    if (model%d%n_cut > 0) then
      write(buf, '(a,i0,a)') 'loops: ', model%d%n_cut, ' closing joints'
      if (any(model%d%cut_kind == cut_free)) write(buf, '(a,i0,a)') trim(buf) // ' (', &
        & count(model%d%cut_kind == cut_free), " 'free': no constraint)"
      write(buf, '(a,i0,a,i0,a,es9.2,a,es9.2,a)') trim(buf) // ', ', &
        & model%d%n_rows, ' constraint rows, ', model%d%n_redundant, ' redundant (dropped); the initial ' // &
        & 'state assembled with largest changes ', model%d%assembly_dq, ' (q), ', model%d%assembly_dqd, ' (qd)'
      s = s // new_line('a') // trim(buf)
      if (model%d%n_rows > 0) then
        write(buf, '(a,es9.2,a)') 'loops: the largest closure error a step left (removed by projection): ', &
          & model%d%closure_drift, ' (m; rad for rotation rows)'
        s = s // new_line('a') // trim(buf)
      end if
    end if
    if (st%static_settled >= 0) then
      write(buf, '(a,i0,a,i0,a,es9.2)') 'static start: ', st%static_settled, ' coordinates settled in ', &
        & st%static_iterations, ' Newton iterations (last change ', st%static_change
      s = s // new_line('a') // trim(buf) // ')'
    end if
    if (allocated(st%warnings)) then
      j = 1
      do while (next_text_line(st%warnings, j, warning))
        if (len(warning) > 0) s = s // new_line('a') // 'warning: ' // warning
      end do
    end if
    s = s // new_line('a')
    call forward_kinematics(model%d, x(1:n), x(n+1:))
    do i = 1, min(model%d%n_markers, max_summary_markers)
      call marker_motion(model%d, i, x(1:n), x(n+1:), r, v)
      ! fixed digits for ordinary values; exponents when a run went far off (a diverging model)
      if (maxval(abs([r, v])) < 1.0e5_dp) then
        write(buf, '(a,3f12.6,a,3f12.6,a)') 'final ' // trim(model%d%marker_name(i)) // ': position', r, &
          & ' m, velocity', v, ' m/s'
      else
        write(buf, '(a,3es12.4,a,3es12.4,a)') 'final ' // trim(model%d%marker_name(i)) // ': position', r, &
          & ' m, velocity', v, ' m/s'
      end if
      s = s // trim(buf) // new_line('a')
    end do
    if (model%d%n_markers > max_summary_markers) s = s // '(and ' // itoa(model%d%n_markers - max_summary_markers) &
      & // ' more markers in the results)' // new_line('a')
    s = s // 'results: ' // path // ', ' // json_path(path)
  end function summary_text
end module pymr_driver_run
