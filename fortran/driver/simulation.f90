!> One simulation of a scene, from its file to its result files: a `simulation_t` owns the
!> scene, the model, the stepper, the results writer, the statistics and the clocks.
!>
!>     call sim%open(file, overrides, out, restarting, lines, error)   ! model, output, lock
!>     call sim%initial_state(restart, error)         ! starting state, method, stepper, output plan
!>     call sim%start(restart, error)                 ! a new run, or one from a checkpoint
!>     call sim%run_to(t, error)                      ! rows, checkpoints and steps up to t
!>     call sim%finish(error)                         ! last row, statistics, files in place
!>     call sim%close()                               ! the results file's lock released
module pymr_driver_simulation
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_text, only : itoa, fmt
  use pymr_env_clock, only : thread_cpu_time
  use pymr_env_text_file, only : acquire_lock, release_lock, commit_staged, remove_file, system_reason
  use pymr_model_scene, only : scene_t
  use pymr_model, only : model_t
  use pymr_model_sensors, only : sensors_of
  use pymr_integrator_stepper, only : stepper_t, step_counts, counts_with
  use pymr_io_namelist_input, only : text_fingerprint, checkpoint_identity, resolved_texts
  use pymr_io_results_output, only : json_path, write_json, run_stats, output_plan_of, n_work
  use pymr_io_results_file, only : results_file
  use pymr_io_results_csv, only : csv_writer
  use pymr_io_results_hdf5, only : hdf5_writer
  use pymr_io_checkpoint, only : run_progress, write_checkpoint, read_checkpoint
  use pymr_driver_stepper_setup, only : make_stepper, stepper_label, method_label, unused_adaptive_items
  use pymr_driver_output_quantities, only : write_output_row, work_at
  use pymr_driver_preflight, only : check_step_stability, check_mass_matrix
  use pymr_driver_load_model, only : load_model
  use pymr_driver_output_paths, only : default_output, check_output_path, checkpoint_default, inputs_digest, &
    & scene_files, list_inputs
  use pymr_driver_output_size, only : check_output_size, check_rows_written
  use pymr_driver_starting_state, only : starting_state
  use pymr_driver_deflection_watch, only : watch_deflection
  use pymr_driver_distance_watch, only : distance_watch
  use pymr_driver_progress, only : run_clock
  use pymr_env_interrupt, only : check_interrupt
  use pymr_driver_settings_json, only : settings_json
  use pymr_driver_summary, only : summary_text
  use pymr_driver_method_choice, only : choose_by_probe => choose_method, method_of_checkpoint, method_choice_t, &
    & probe_run
  use pymr_driver_moving_load_exits, only : note_exits, exits_json
  use pymr_driver_step_stops, only : next_stop
  implicit none
  private
  public :: simulation_t

  !> A simulation and where it is.
  type :: simulation_t
    !> The scene file as the caller named it (messages begin with it), and its overrides.
    character(len=:), allocatable :: file, overrides
    type(scene_t) :: sc
    type(model_t) :: model
    class(stepper_t), allocatable :: st
    !> Method 'auto': the choice, reviewed as the run goes, and the chosen method's probe,
    !> which the run continues when it can; the step counts of the methods that ran before
    !> the one running.
    type(method_choice_t) :: choice
    type(probe_run), allocatable :: probed
    !> The watch on how far the bodies have gone from the origin.
    type(distance_watch) :: distance
    type(step_counts) :: carried
    class(results_file), allocatable :: out
    type(run_stats) :: stats
    type(run_clock) :: clock
    !> The results file, and the lock on it once held.
    character(len=:), allocatable :: path, locked
    !> The checkpoint file, and what a checkpoint must share with the scene (only when
    !> checkpoints are written or read).
    character(len=:), allocatable :: ckpt_path, settings, fingerprint
    !> The resolved scene with absolute paths, and its fingerprint, as the results describe
    !> them (the scene does not change once the method is chosen).
    character(len=:), allocatable :: scene_text, scene_id
    !> The state [q; qd] (of the time last asked of the stepper).
    real(dp), allocatable :: x(:)
    !> The first step; the output interval (0: a row every step); times closer than eps are one.
    real(dp) :: h0 = 0.0_dp, dt_out = 0.0_dp, eps = 0.0_dp
    !> The next output row: its number and time.
    integer :: k_out = 1
    real(dp) :: t_next = 0.0_dp
    !> The works of the energy columns at t_step, the start of the stepper's last step.
    real(dp) :: t_step = 0.0_dp, work_step(n_work) = 0.0_dp
    !> The time of the row the integration starts from, and of the next checkpoint.
    real(dp) :: t_first_row = 0.0_dp, t_ckpt = huge(1.0_dp)
    !> Whether the rows and works of the time the stepper has reached are written.
    logical :: reached_written = .false.
  contains
    procedure :: open => simulation_open
    procedure :: initial_state => simulation_initial_state
    procedure :: start => simulation_start
    procedure :: step => simulation_step
    procedure :: run_to => simulation_run_to
    procedure :: finish => simulation_finish
    procedure :: summary => simulation_summary
    procedure :: close => simulation_close
    procedure, private :: choose_format, choose_method, review_method
    procedure, private :: begin_new, resume, continues_probe, continue_probe
    procedure, private :: put_row, put_rows_reached, put_last_row, checkpoint_if_due, start_again, start_stepper
    procedure :: name_file
    procedure, private :: write_results
  end type simulation_t

contains

  !> Read and build the scene's model (with overrides), choose the results file (`out`, or
  !> the default) and check it, and take its lock. `restarting`: the run continues from a
  !> checkpoint; `lines`: progress lines on stderr.
  subroutine simulation_open(self, file, overrides, out, restarting, lines, error)
    class(simulation_t), intent(inout) :: self
    character(len=*), intent(in) :: file, overrides, out
    logical, intent(in) :: restarting, lines
    type(error_type), allocatable, intent(out) :: error
    type(scene_files) :: inputs
    character(len=:), allocatable :: digest
    self%file = file; self%overrides = overrides
    self%clock%lines = lines
    call load_model(file, overrides, self%sc, self%model, error); if (allocated(error)) return
    self%path = default_output(self%sc, out)
    inputs = list_inputs(self%sc)
    call check_output_path(self%sc, self%path, inputs, error); if (allocated(error)) return
    call acquire_lock(self%path, error); if (allocated(error)) return
    self%locked = self%path
    if (restarting .or. self%sc%output%checkpoint_dt > 0.0_dp) then
      digest = inputs_digest(inputs, error); if (allocated(error)) return
      call checkpoint_identity(self%sc, digest, self%settings, self%fingerprint)
    end if
    self%ckpt_path = trim(self%sc%output%checkpoint_file)
    if (len(self%ckpt_path) == 0) self%ckpt_path = checkpoint_default(self%path)
  end subroutine simulation_open

  !> The clocks started, the state the run starts from, the method ('auto': chosen, or that
  !> of the checkpoint `restart` when not ''), the output plan and the stepper (made, not
  !> started; none when the run goes on from the chosen method's probe).
  subroutine simulation_initial_state(self, restart, error)
    class(simulation_t), intent(inout) :: self
    character(len=*), intent(in) :: restart
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: h
    call self%clock%start()
    h = self%sc%integrator%h_slow
    allocate(self%x(2*self%model%d%n))
    call starting_state(self%sc, self%model, self%x, error, self%stats)
    if (allocated(error)) then
      call self%name_file(error); return
    end if
    if (self%sc%integrator%method == 'auto') then
      call self%choose_method(restart, error); if (allocated(error)) return
    end if
    self%dt_out = self%sc%output%dt
    if (self%dt_out <= 0.0_dp .and. .not. self%sc%integrator%adaptive) self%dt_out = h
    self%eps = 1.0e-9_dp*h
    self%k_out = 1
    self%t_next = self%dt_out
    call self%choose_format()
    self%work_step = 0.0_dp; self%t_step = 0.0_dp
    ! a run that goes on from the chosen method's probe takes its stepper (begin_new)
    if (self%continues_probe()) return
    call make_stepper(self%sc, self%model, self%x, self%st, self%h0, error)
    if (allocated(error)) call self%name_file(error)
  end subroutine simulation_initial_state

  !> Method 'auto': the method chosen by probes from the initial state (or the one the
  !> checkpoint `restart` was written with) set in the scene, and the choice reported.
  subroutine choose_method(self, restart, error)
    class(simulation_t), intent(inout) :: self
    character(len=*), intent(in) :: restart
    type(error_type), allocatable, intent(out) :: error
    if (len_trim(restart) > 0) then
      call method_of_checkpoint(self%sc, restart, self%choice, error)
      if (allocated(error)) then
        call self%name_file(error); return
      end if
    else
      call choose_by_probe(self%sc, self%model, self%x, self%choice)
      call self%choice%take_chosen(self%probed)
    end if
    self%stats%choice_line = self%choice%summary()
    self%stats%choice_report = self%choice%json()
  end subroutine choose_method

  !> Method 'auto' at the end of a review window: the choice reviewed (method_choice.f90);
  !> when another method takes over, its stepper starts where the run stands (the rows up
  !> to there are written), and the counts of the one that stops are carried. The report
  !> is written again only after a review (every window's, 25 on a tank's run, took 7 % of
  !> its instructions in formatted writes).
  subroutine review_method(self, error)
    class(simulation_t), intent(inout) :: self
    type(error_type), allocatable, intent(out) :: error
    logical :: switched
    real(dp) :: t
    integer :: reviews
    reviews = self%choice%reviews
    call self%choice%review(self%sc, self%model, self%st, switched)
    if (self%choice%reviews /= reviews) then
      self%stats%choice_line = self%choice%summary()
      self%stats%choice_report = self%choice%json()
    end if
    if (.not. switched) return
    self%carried = counts_with(self%carried, self%st%counts())
    t = self%st%time()
    call self%st%value_at(t, self%x)
    deallocate(self%st)
    call make_stepper(self%sc, self%model, self%x, self%st, self%h0, error); if (allocated(error)) return
    call self%start_stepper(t, self%h0, error)
  end subroutine review_method

  !> The results file of &output format, what it writes (the plan of &output quantities)
  !> and what the run is.
  subroutine choose_format(self)
    class(simulation_t), intent(inout) :: self
    character(len=:), allocatable :: text
    if (self%sc%output%format == 'hdf5') then
      allocate(hdf5_writer :: self%out)
      select type (out => self%out)
      type is (hdf5_writer)
        out%compression = self%sc%output%compression
      end select
    else
      allocate(csv_writer :: self%out)
    end if
    self%out%digits = self%sc%output%precision
    self%out%plan = output_plan_of(self%sc%output%quantities, self%model%d, sensors_of(self%sc, self%model%d))
    call resolved_texts(self%sc, text, self%scene_text)
    self%scene_id = text_fingerprint(text)
    call self%out%describe(self%sc%scene%title, method_label(self%sc), self%scene_id, self%scene_text, &
      & settings_json(self%sc))
  end subroutine choose_format

  !> Start the integration: from the checkpoint file `restart` (its results file keeps the
  !> rows written up to it), or ('') a new run from the initial state.
  subroutine simulation_start(self, restart, error)
    class(simulation_t), intent(inout) :: self
    character(len=*), intent(in) :: restart
    type(error_type), allocatable, intent(out) :: error
    if (len_trim(restart) > 0) then
      call self%resume(restart, error)
    else
      call self%begin_new(error)
    end if
    if (allocated(error)) return
    self%t_first_row = self%st%time()
    self%reached_written = .false.
    call self%clock%run_begins(self%st%time(), self%sc%scene%t_end)
    self%t_ckpt = huge(1.0_dp)
    if (self%sc%output%checkpoint_dt > 0.0_dp) self%t_ckpt = next_checkpoint(self%sc, self%st%time())
  end subroutine simulation_start

  !> A new run: the results file opened and its first row written, the pre-flight checks,
  !> the stepper started.
  subroutine begin_new(self, error)
    class(simulation_t), intent(inout) :: self
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: note, unused
    call check_output_size(self%sc, self%model, self%out, self%dt_out, error); if (allocated(error)) return
    call self%out%open(self%path, self%model%d, error)
    if (allocated(error)) return
    ! an earlier failed run's statistics describe the partial file this run replaces
    call remove_file(json_path(self%path) // '.partial')
    call check_mass_matrix(self%sc, self%model, self%x, error)
    if (.not. allocated(error)) call self%put_row(0.0_dp, self%work_step, error)
    if (allocated(error)) then
      call self%out%discard(); return
    end if
    unused = unused_adaptive_items(self%sc)
    if (len(unused) > 0) call self%stats%add_warning(unused)
    if (.not. self%sc%integrator%adaptive .and. self%sc%integrator%stability_check) then
      self%stats%preflight_cpu_s = thread_cpu_time()
      call check_step_stability(self%model, self%x, self%st, stepper_label(self%sc), self%sc%scene%t_end, &
        & self%sc%integrator%origin, error, note)
      if (allocated(error)) then
        call self%out%discard(); return
      end if
      if (allocated(note)) call self%stats%add_warning(note)
      self%stats%preflight_cpu_s = thread_cpu_time() - self%stats%preflight_cpu_s
      self%clock%cpu0 = self%clock%cpu0 + self%stats%preflight_cpu_s
    end if
    if (self%continues_probe()) then
      call self%continue_probe(error)
      deallocate(self%probed)
    else
      ! the probe's copy of the model and its stepper go before this run's stepper starts
      if (allocated(self%probed)) deallocate(self%probed)
      call self%start_stepper(0.0_dp, self%h0, error)
    end if
    if (allocated(error)) then
      call self%name_file(error)
      if (error%stat /= stat_solver) then
        call self%out%discard(); return
      end if
      ! the start's steps failed: a failed run, whose rows so far its partial files keep
      call self%finish(error)
    end if
  end subroutine begin_new

  !> Whether the run goes on from the probe of the method 'auto' chose: the probe's rows are
  !> the run's (every &output dt, no energy columns, whose works integrate over the steps),
  !> and nothing the run does between steps falls inside it (a stop of its steps, such as a
  !> moving load's exit, or a checkpoint).
  logical function continues_probe(self)
    class(simulation_t), intent(in) :: self
    continues_probe = .false.
    if (.not. allocated(self%probed)) return
    if (self%probed%nr < 0 .or. self%dt_out <= 0.0_dp .or. self%out%plan%energy) return
    if (next_stop(self%model, 0.0_dp) < huge(1.0_dp)) return
    if (self%sc%output%checkpoint_dt > 0.0_dp .and. self%sc%output%checkpoint_dt <= self%probed%st%time()) return
    continues_probe = self%probed%st%time() < self%sc%scene%t_end - self%eps
  end function continues_probe

  !> The run continued from the chosen method's probe: its stepper and model taken, the
  !> rows it passed written. The run is the one a start from 0 gives, step for step.
  subroutine continue_probe(self, error)
    class(simulation_t), intent(inout) :: self
    type(error_type), allocatable, intent(out) :: error
    integer :: k
    call move_alloc(self%probed%st, self%st)
    self%model = self%probed%model
    do k = 1, self%probed%nr
      self%x = self%probed%rows(:, k)
      call self%put_row(k*self%dt_out, self%work_step, error); if (allocated(error)) return
      self%k_out = self%k_out + 1; self%t_next = self%k_out*self%dt_out
    end do
  end subroutine continue_probe

  !> A run continued from the checkpoint file `restart`: the stepper and the model as they
  !> were, the results file reopened at the rows the checkpoint counts.
  subroutine resume(self, restart, error)
    class(simulation_t), intent(inout) :: self
    character(len=*), intent(in) :: restart
    type(error_type), allocatable, intent(out) :: error
    type(run_progress) :: prog
    call check_output_size(self%sc, self%model, self%out, self%dt_out, error); if (allocated(error)) return
    call read_checkpoint(restart, self%st, self%model, prog, self%settings, self%fingerprint, &
      & self%sc%scene%t_end, error)
    if (.not. allocated(error)) call self%out%reopen(self%path, self%model%d, prog%rows, prog%last_row, error)
    if (allocated(error)) then
      call self%out%close()
      call self%name_file(error)
      return
    end if
    self%stats%rows = prog%rows; self%k_out = prog%k_out; self%t_next = prog%t_next; self%work_step = prog%work
    if (len(prog%warnings) > 0) self%stats%warnings = prog%warnings
    self%carried = prog%carried
    self%t_step = self%st%time()
    ! another &output dt: the rows after the checkpoint follow the new interval (the next row
    ! numbered on the old one was timed k dt_new, before the rows kept)
    if (self%dt_out > 0.0_dp .and. abs(self%t_next - self%k_out*self%dt_out) > self%eps) then
      self%k_out = floor((self%t_step + self%eps)/self%dt_out) + 1
      self%t_next = self%k_out*self%dt_out
    end if
    self%clock%cpu0 = self%clock%cpu0 - prog%cpu_s
  end subroutine resume

  !> One step: advance (the stepper closes the loops again inside it), and the step count
  !> checked. A stepper that lands() ends a step on each of the run's stops (step_stops.f90:
  !> a moving load's exit, a pulse's start, peak and end) and is started again there.
  subroutine simulation_step(self, error)
    class(simulation_t), intent(inout) :: self
    type(error_type), allocatable, intent(out) :: error
    type(step_counts) :: done
    real(dp) :: t_stop
    t_stop = next_stop(self%model, self%st%time())
    call self%st%stop_at(t_stop)
    call self%st%advance(self%model, error); if (allocated(error)) return
    call check_interrupt(self%st%time(), error); if (allocated(error)) return
    done = counts_with(self%carried, self%st%counts())
    if (done%steps_fast > self%sc%integrator%max_steps) then
      call fatal_error(error, 'at t = ' // fmt(self%st%time()) // ' s: the run took more than max_steps = ' // &
        & itoa(self%sc%integrator%max_steps) // ' steps (&integrator max_steps lifts the limit)', stat_solver)
      return
    end if
    self%reached_written = .false.
    if (self%st%lands() .and. self%st%time() == t_stop .and. t_stop < self%sc%scene%t_end) &
      & call self%start_again(error)
  end subroutine simulation_step

  !> Start the stepper again where it stands (after the rows up to there are written from
  !> its steps so far): its history is of the motion before a discontinuity. Its start's
  !> (fast) step is at most the one it was taking: a start's first steps take no error
  !> estimate, and the step from the scene's h_slow can be far too long for a vibration
  !> that a pulse has set going.
  subroutine start_again(self, error)
    class(simulation_t), intent(inout) :: self
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: t, h
    type(step_counts) :: last
    call self%put_rows_reached(error); if (allocated(error)) return
    self%reached_written = .true.
    t = self%st%time()
    call self%st%value_at(t, self%x)
    last = self%st%counts()
    h = self%h0
    if (last%h_last > 0.0_dp) h = min(h, last%h_last/max(1, last%ratio))
    call self%start_stepper(t, h, error)
  end subroutine start_again

  !> Start the stepper at (t, x) with the (first) step h, told the run's next stop first
  !> (its start's steps take no error estimate to land on one, and stay short of it).
  subroutine start_stepper(self, t, h, error)
    class(simulation_t), intent(inout) :: self
    real(dp), intent(in) :: t, h
    type(error_type), allocatable, intent(out) :: error
    call self%st%stop_at(next_stop(self%model, t))
    call self%st%start(self%model, t, self%x, h, error)
  end subroutine start_stepper

  !> Integrate until the stepper has reached t: the rows of every output time passed, the
  !> checkpoints due, and the steps.
  subroutine simulation_run_to(self, t, error)
    class(simulation_t), intent(inout) :: self
    real(dp), intent(in) :: t
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: t0
    logical :: timed
    do
      if (.not. self%reached_written) then
        ! method 'auto' reviews its choice by the CPU its steps take, the output's left out
        ! (method_choice.f90)
        timed = .false.
        if (self%choice%reviewing()) timed = self%choice%times_output()
        if (timed) t0 = thread_cpu_time()
        call self%put_rows_reached(error); if (allocated(error)) return
        if (timed) self%choice%output = self%choice%output + (thread_cpu_time() - t0)
        self%reached_written = .true.
      end if
      if (self%st%time() >= t - self%eps) return
      if (self%choice%review_due(self%st%time(), self%sc%scene%t_end)) then
        call self%review_method(error); if (allocated(error)) return
      end if
      call self%checkpoint_if_due(error); if (allocated(error)) return
      if (self%out%ios /= 0) then
        call fatal_error(error, 'at t = ' // fmt(self%st%time()) // ' s: ' // self%out%partial // ': cannot ' // &
          & 'write the results: ' // system_reason(self%out%io_message), stat_solver); return
      end if
      call self%step(error); if (allocated(error)) return
      call self%clock%reached(self%st%time())
    end do
  end subroutine simulation_run_to

  !> The rows of the output times up to the time the stepper has reached (every step's
  !> row with dt = 0, but not again the row of the state the integration starts from, nor
  !> the last, written at the end), and the works there; then the moving loads' exits in
  !> the step (their rows and works taken with the loads still on).
  subroutine put_rows_reached(self, error)
    class(simulation_t), intent(inout) :: self
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: work(n_work), t_end, t, t0
    t_end = self%sc%scene%t_end
    if (self%dt_out > 0.0_dp) then
      do while (self%t_next <= min(self%st%time(), t_end) + self%eps)
        call self%st%value_at(self%t_next, self%x)
        call work_at(self%out%plan, self%st, self%model, self%t_step, self%work_step, self%t_next, work, error)
        if (allocated(error)) return
        call self%put_row(self%t_next, work, error); if (allocated(error)) return
        self%k_out = self%k_out + 1; self%t_next = self%k_out*self%dt_out
      end do
    end if
    ! the works at the time reached (for its row, the checkpoint, and the start of the next step)
    t = self%st%time()
    call work_at(self%out%plan, self%st, self%model, self%t_step, self%work_step, t, work, error)
    if (allocated(error)) return
    t0 = self%t_step
    self%work_step = work; self%t_step = t
    if (self%dt_out <= 0.0_dp .and. t > self%t_first_row + self%eps .and. t < t_end - self%eps) then
      call self%st%value_at(t, self%x)
      call self%put_row(t, self%work_step, error); if (allocated(error)) return
      call check_rows_written(self%sc, self%model, self%out, self%stats%rows, t, error); if (allocated(error)) return
    end if
    call note_exits(self%model, self%st, t0, t, t_end)
    call self%distance%after_step(self%model, t, error)
  end subroutine put_rows_reached

  !> Write the row of the state x at time t (counted once written: a deflection that stops
  !> the run there leaves it in the partial file), and watch the flexible bodies' deflection.
  subroutine put_row(self, t, row_work, error)
    class(simulation_t), intent(inout) :: self
    real(dp), intent(in) :: t, row_work(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: n
    n = self%model%d%n
    call write_output_row(self%out, self%model, t, self%x(1:n), self%x(n+1:), row_work, error)
    if (allocated(error)) return
    self%stats%rows = self%stats%rows + 1
    call watch_deflection(self%sc, self%model, t, self%x(1:n), self%stats, error)
  end subroutine put_row

  !> A checkpoint when its time has come: the rows up to now are on disk (checked) before
  !> the checkpoint that counts them.
  subroutine checkpoint_if_due(self, error)
    class(simulation_t), intent(inout) :: self
    type(error_type), allocatable, intent(out) :: error
    type(run_progress) :: prog
    if (self%st%time() < self%t_ckpt - self%eps) return
    call self%out%flush_rows()
    if (self%out%ios /= 0) return
    prog = run_progress(rows=self%stats%rows, k_out=self%k_out, t_next=self%t_next, cpu_s=self%clock%cpu_s(), &
      & t_checkpoint=self%st%time(), work=self%work_step, last_row=self%out%row, warnings='', &
      & carried=self%carried)
    if (allocated(self%stats%warnings)) prog%warnings = self%stats%warnings
    call write_checkpoint(self%ckpt_path, self%st, self%model, prog, self%settings, self%fingerprint, error)
    if (allocated(error)) return
    self%t_ckpt = next_checkpoint(self%sc, self%st%time())
  end subroutine checkpoint_if_due

  !> The first checkpoint time after t.
  real(dp) function next_checkpoint(sc, t)
    type(scene_t), intent(in) :: sc
    real(dp), intent(in) :: t
    next_checkpoint = (floor(t/sc%output%checkpoint_dt + 1.0e-9_dp) + 1)*sc%output%checkpoint_dt
  end function next_checkpoint

  !> End the run: with no `error` from the integration, the last row (at t_end) and the
  !> result files put in place; with one, the rows so far kept in PATH.partial and described
  !> by PATH.json.partial, and `error` named after the scene file.
  subroutine simulation_finish(self, error)
    class(simulation_t), intent(inout) :: self
    type(error_type), allocatable, intent(inout) :: error
    call self%clock%run_ends(.not. allocated(error), self%eps)
    if (.not. allocated(error)) call self%put_last_row(error)
    call self%clock%stop(self%stats%cpu_time_s, self%stats%wall_time_s)
    call fill_stats(counts_with(self%carried, self%st%counts()), self%model, self%stats)
    self%stats%effects_report = exits_json(self%model)
    call self%write_results(error)
  end subroutine simulation_finish

  !> The row at t_end, unless the last output row was already there.
  subroutine put_last_row(self, error)
    class(simulation_t), intent(inout) :: self
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: work(n_work), t_end
    t_end = self%sc%scene%t_end
    call self%st%value_at(t_end, self%x)
    if (self%dt_out <= 0.0_dp .or. abs(self%t_next - self%dt_out - t_end) > self%eps) then
      call work_at(self%out%plan, self%st, self%model, self%t_step, self%work_step, t_end, work, error)
      if (.not. allocated(error)) call self%put_row(t_end, work, error)
    end if
  end subroutine put_last_row

  !> The statistics and the rows in place. The new results replace the earlier ones only
  !> once both files are complete: the statistics wait in PATH.json.tmp while the rows are
  !> put in place. A run that failed (error given, or here) leaves PATH.partial and
  !> PATH.json.partial.
  subroutine write_results(self, error)
    class(simulation_t), intent(inout) :: self
    type(error_type), allocatable, intent(inout) :: error
    type(error_type), allocatable :: json_error
    character(len=:), allocatable :: statistics
    if (.not. allocated(error)) call write_json(json_path(self%path), self%file, self%sc%scene%title, &
      & self%scene_id, settings_json(self%sc), self%model%d, self%model%wk, self%stats, 'complete', '', &
      & self%sc%scene%t_end, error, self%overrides, self%scene_text, self%out%plan, staged=.true., text=statistics, &
      & pairing=self%out%pairing())
    if (.not. allocated(error)) then
      call self%out%finish(statistics, error)
      if (allocated(error)) call remove_file(json_path(self%path) // '.tmp')
    end if
    if (allocated(error)) then
      call self%out%close()
      call self%name_file(error)
      call write_json(json_path(self%path) // '.partial', self%file, self%sc%scene%title, self%scene_id, &
        & settings_json(self%sc), self%model%d, self%model%wk, self%stats, 'failed', error%message, self%st%time(), json_error, &
        & self%overrides, self%scene_text, self%out%plan)
      return
    end if
    call commit_staged(json_path(self%path), error)
    if (allocated(error)) error%message = self%file // ': ' // error%message // ' (the statistics; ' // &
      & self%path // ' is the new results)'
  end subroutine write_results

  !> Step and evaluation counts of a run: steps c from its steppers, evaluations from the model.
  subroutine fill_stats(c, model, stats)
    type(step_counts), intent(in) :: c
    type(model_t), intent(in) :: model
    type(run_stats), intent(inout) :: stats
    stats%steps_slow = c%steps_slow; stats%steps_fast = c%steps_fast
    stats%rejected_steps = c%rejected; stats%h_last = c%h_last; stats%ratio_last = c%ratio
    stats%rhs_full = model%wk%count%evals
    stats%rhs_fast = model%wk%count%evals_fast_rows + c%evals_fast
  end subroutine fill_stats

  !> The run's summary: a few human-readable lines.
  function simulation_summary(self) result(s)
    class(simulation_t), intent(inout) :: self
    character(len=:), allocatable :: s
    s = summary_text(self%sc, self%model, self%stats, self%path, self%x)
  end function simulation_summary

  !> Release the results file's lock, if held.
  subroutine simulation_close(self)
    class(simulation_t), intent(inout) :: self
    if (allocated(self%locked)) call release_lock(self%locked)
    if (allocated(self%locked)) deallocate(self%locked)
  end subroutine simulation_close

  !> An error message begins with the scene file's name (as the caller gave it), and a
  !> failed run's (stat_solver) names the time it failed at: "FILE: at t = T s: ..." (the
  !> time the stepper had reached, 0 before it started), whichever of the two it did not say.
  subroutine name_file(self, error)
    class(simulation_t), intent(in) :: self
    type(error_type), intent(inout) :: error
    character(len=:), allocatable :: msg
    real(dp) :: t
    msg = error%message
    if (index(msg, self%file // ': ') == 1) then
      msg = msg(len(self%file) + 3:)
    else if (index(msg, self%file) == 1) then
      return                                 ! "FILE:LINE: ..." of the scene reader
    end if
    if (error%stat == stat_solver .and. index(msg, 'at t = ') == 0) then
      t = 0.0_dp
      if (allocated(self%st)) t = self%st%time()
      msg = 'at t = ' // fmt(t) // ' s: ' // msg
    end if
    error%message = self%file // ': ' // msg
  end subroutine name_file
end module pymr_driver_simulation
