!> One run from a scene file to result files: read, build, integrate, write. Shared by the
!> `mrsim` program and the Python binding; the jobs are the simulation's
!> (pymr_driver_simulation) and the modules it uses, each named for its job.
module pymr_driver_run
  use pymr_env_error, only : error_type
  use pymr_env_interrupt, only : catch_interrupts, release_interrupts
  use pymr_driver_simulation, only : simulation_t
  use pymr_driver_load_model, only : load_model
  use pymr_driver_output_paths, only : scene_input, default_output
  use pymr_driver_starting_state, only : starting_state
  use pymr_driver_progress, only : progress_t, progress_t_end, progress_running
  implicit none
  private
  public :: run_scene
  !> Used from here by the binding and the step history.
  public :: load_model, scene_input, starting_state, default_output, progress_t, progress_t_end, progress_running

contains

  !> Run a scene: results to `out` (or the default), statistics beside it; `summary`
  !> receives a few human-readable lines. With `restart`, continue the run from that
  !> checkpoint file: the results file keeps the rows written up to the checkpoint. The run
  !> holds OUT.lock from the moment its output is known, so that two runs never write the
  !> same results.
  subroutine run_scene(file, overrides, out, summary, error, written, restart, progress_lines)
    character(len=*), intent(in) :: file, overrides, out
    character(len=:), allocatable, intent(out) :: summary
    type(error_type), allocatable, intent(out) :: error
    !> The CSV file written (a required argument: gfortran 12 gave an optional deferred-length
    !> one, passed on, a garbage length when the output path was the default).
    character(len=:), allocatable, intent(out) :: written
    !> Checkpoint to continue from ('' or absent: a new run).
    character(len=*), intent(in), optional :: restart
    !> Print a progress line to stderr about every second (mrsim --progress).
    logical, intent(in), optional :: progress_lines
    type(simulation_t) :: sim
    character(len=:), allocatable :: from
    logical :: lines
    from = ''
    if (present(restart)) from = restart
    lines = .false.
    if (present(progress_lines)) lines = progress_lines
    call catch_interrupts()                     ! SIGINT, SIGTERM: the run stops after its step
    call sim%open(file, overrides, out, len_trim(from) > 0, lines, error)
    if (.not. allocated(error)) call sim%initial_state(from, error)
    if (.not. allocated(error)) call sim%start(from, error)
    if (allocated(error)) call sim%name_file(error)
    if (.not. allocated(error)) then
      call sim%run_to(sim%sc%scene%t_end, error)
      if (allocated(error)) call sim%name_file(error)
      call sim%finish(error)
    end if
    if (.not. allocated(error)) then
      summary = sim%summary()
      written = sim%path
    end if
    call sim%close()
    call release_interrupts()
  end subroutine run_scene
end module pymr_driver_run
