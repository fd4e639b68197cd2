!> Checkpoint files: the full state of a run at a step boundary, so that a run stopped
!> by a wall-time limit continues from its last checkpoint exactly as if uninterrupted.
!>
!> Unformatted stream layout: a tag and version, the model's size and method, the run's
!> output bookkeeping (rows written, next output time, CPU time so far), the integrator's
!> Nordsieck arrays, steps and counters, the multirate terms the model holds between
!> evaluations, and the model's evaluation and effect counters. Written to PATH.tmp and
!> renamed, so a run killed while writing keeps the previous checkpoint.
module pymr_io_checkpoint
  use pymr_io_text_file, only : rename_file
  use pymr_kinds, only : dp
  use pymr_error, only : error_type, fatal_error
  use pymr_integrator_abm, only : abm_integrator
  use pymr_integrator_multirate, only : multirate_integrator
  use pymr_model, only : model_t
  use pymr_io_text, only : itoa
  implicit none
  private
  public :: run_progress, write_checkpoint, read_checkpoint

  character(len=8), parameter :: tag = 'PYMRCKPT'
  integer, parameter :: version = 1

  !> Output bookkeeping of a run at a checkpoint.
  type :: run_progress
    integer :: rows = 0, k_out = 1
    real(dp) :: t_next = 0.0_dp, cpu_s = 0.0_dp, t_checkpoint = 0.0_dp
  end type run_progress

contains

  !> Write the state of the run (single-rate `abm` or `mr`) and model to `path`.
  subroutine write_checkpoint(path, multirate, abm, mr, model, prog, error)
    character(len=*), intent(in) :: path
    logical, intent(in) :: multirate
    type(abm_integrator), intent(in) :: abm
    type(multirate_integrator), intent(in) :: mr
    type(model_t), intent(in) :: model
    type(run_progress), intent(in) :: prog
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios
    character(len=256) :: msg
    open(newunit=u, file=path // '.tmp', access='stream', form='unformatted', status='replace', action='write', &
      & iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot write the checkpoint: ' // trim(msg)); return
    end if
    write(u) tag, version, model%d%n, model%d%nj, multirate
    write(u) prog%rows, prog%k_out, prog%t_next, prog%cpu_s, prog%t_checkpoint
    if (multirate) then
      write(u) mr%k, mr%t, mr%hs, mr%hf, mr%zs, mr%zf, mr%steps_slow, mr%steps_fast, mr%evals_slow, &
        & mr%evals_fast, mr%evals_start, mr%rejected
      write(u) model%lff, model%le, model%mfs, model%xfs, model%qrest, model%yf, model%mffinv, model%yrest, &
        & model%mff_factored, model%evals_split
    else
      write(u) abm%t, abm%h, abm%z, abm%steps, abm%rejected, abm%evals
    end if
    write(u) model%d%evals, model%d%evals_fast_rows, model%d%effect_evals, model%d%effect_timed, model%d%effect_cpu
    close(u)
    call rename_file(path // '.tmp', path, error)
  end subroutine write_checkpoint

  !> Read a checkpoint into an initialised stepper (abm or mr) and model; the model must
  !> be the one the checkpoint was written for.
  subroutine read_checkpoint(path, multirate, abm, mr, model, prog, error)
    character(len=*), intent(in) :: path
    logical, intent(in) :: multirate
    type(abm_integrator), intent(inout) :: abm
    type(multirate_integrator), intent(inout) :: mr
    type(model_t), intent(inout) :: model
    type(run_progress), intent(out) :: prog
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios, ver, n, nj
    logical :: was_multirate, exists
    character(len=8) :: got
    character(len=256) :: msg
    inquire(file=path, exist=exists)
    if (.not. exists) then
      call fatal_error(error, path // ': checkpoint not found'); return
    end if
    open(newunit=u, file=path, access='stream', form='unformatted', status='old', action='read', iostat=ios, &
      & iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot read the checkpoint: ' // trim(msg)); return
    end if
    read(u, iostat=ios) got, ver, n, nj, was_multirate
    if (ios /= 0 .or. got /= tag) then
      close(u); call fatal_error(error, path // ': not a pymr checkpoint'); return
    end if
    if (ver /= version) then
      close(u); call fatal_error(error, path // ': checkpoint version ' // itoa(ver) // ', this pymr reads ' // &
        & itoa(version)); return
    end if
    if (n /= model%d%n .or. nj /= model%d%nj .or. (was_multirate .neqv. multirate)) then
      close(u)
      call fatal_error(error, path // ': the checkpoint is of another model (' // itoa(n) // ' coordinates, ' // &
        & trim(merge('multirate', 'single   ', was_multirate)) // '); the scene has ' // itoa(model%d%n) // &
        & ' coordinates, ' // trim(merge('multirate', 'single   ', multirate)))
      return
    end if
    read(u, iostat=ios) prog%rows, prog%k_out, prog%t_next, prog%cpu_s, prog%t_checkpoint
    if (multirate .and. ios == 0) then
      read(u, iostat=ios) mr%k, mr%t, mr%hs, mr%hf, mr%zs, mr%zf, mr%steps_slow, mr%steps_fast, mr%evals_slow, &
        & mr%evals_fast, mr%evals_start, mr%rejected
      if (ios == 0) read(u, iostat=ios) model%lff, model%le, model%mfs, model%xfs, model%qrest, model%yf, &
        & model%mffinv, model%yrest, model%mff_factored, model%evals_split
    else if (ios == 0) then
      read(u, iostat=ios) abm%t, abm%h, abm%z, abm%steps, abm%rejected, abm%evals
    end if
    if (ios == 0) read(u, iostat=ios) model%d%evals, model%d%evals_fast_rows, model%d%effect_evals, &
      & model%d%effect_timed, model%d%effect_cpu
    close(u)
    if (ios /= 0) call fatal_error(error, path // ': the checkpoint is truncated or damaged')
  end subroutine read_checkpoint
end module pymr_io_checkpoint
