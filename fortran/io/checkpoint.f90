!> Checkpoint files: the full state of a run at a step boundary, so that a run stopped
!> by a wall-time limit continues from its last checkpoint exactly as if uninterrupted.
!>
!> Unformatted stream layout: a tag and version, the model's size and the stepper's name, the
!> run's output bookkeeping (rows written, next output time, CPU time so far), the stepper's
!> state (its own save), and the model's per-run state (held multirate terms, evaluation and
!> effect counters). Written to PATH.tmp, checked, flushed and renamed, so a run killed while
!> writing keeps the previous checkpoint.
module pymr_io_checkpoint
  use pymr_io_text_file, only : rename_file, sync_file
  use pymr_kinds, only : dp
  use pymr_error, only : error_type, fatal_error
  use pymr_integrator_stepper, only : stepper_t
  use pymr_model, only : model_t
  use pymr_io_text, only : itoa
  implicit none
  private
  public :: run_progress, write_checkpoint, read_checkpoint

  character(len=8), parameter :: tag = 'PYMRCKPT'
  integer, parameter :: version = 2

  !> Output bookkeeping of a run at a checkpoint.
  type :: run_progress
    integer :: rows = 0, k_out = 1
    real(dp) :: t_next = 0.0_dp, cpu_s = 0.0_dp, t_checkpoint = 0.0_dp
  end type run_progress

contains

  !> Write the state of the run (any stepper) and model to `path`: every write and the close
  !> checked, flushed to the disk, then renamed over the previous checkpoint.
  subroutine write_checkpoint(path, st, model, prog, error)
    character(len=*), intent(in) :: path
    class(stepper_t), intent(in) :: st
    type(model_t), intent(in) :: model
    type(run_progress), intent(in) :: prog
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios
    character(len=256) :: msg
    character(len=16) :: name
    open(newunit=u, file=path // '.tmp', access='stream', form='unformatted', status='replace', action='write', &
      & iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot write the checkpoint: ' // trim(msg)); return
    end if
    name = st%name()
    write(u, iostat=ios) tag, version, model%d%n, model%d%nj, name
    if (ios == 0) write(u, iostat=ios) prog%rows, prog%k_out, prog%t_next, prog%cpu_s, prog%t_checkpoint
    if (ios == 0) call st%save(u, ios)
    if (ios == 0) call model%save_run(u, ios)
    if (ios /= 0) then
      close(u, status='delete', iostat=ios)
      call fatal_error(error, path // ': cannot write the checkpoint (disk full?)'); return
    end if
    close(u, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot write the checkpoint: ' // trim(msg)); return
    end if
    call sync_file(path // '.tmp', error); if (allocated(error)) return
    call rename_file(path // '.tmp', path, error)
  end subroutine write_checkpoint

  !> Read a checkpoint into a stepper set up for the same scene (not started) and its model.
  subroutine read_checkpoint(path, st, model, prog, error)
    character(len=*), intent(in) :: path
    class(stepper_t), intent(inout) :: st
    type(model_t), intent(inout) :: model
    type(run_progress), intent(out) :: prog
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios, ver, n, nj
    logical :: exists
    character(len=8) :: got
    character(len=16) :: name
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
    read(u, iostat=ios) got, ver, n, nj, name
    if (ios /= 0 .or. got /= tag) then
      close(u); call fatal_error(error, path // ': not a pymr checkpoint'); return
    end if
    if (ver /= version) then
      close(u); call fatal_error(error, path // ': checkpoint version ' // itoa(ver) // ', this pymr reads ' // &
        & itoa(version)); return
    end if
    if (n /= model%d%n .or. nj /= model%d%nj .or. name /= st%name()) then
      close(u)
      call fatal_error(error, path // ': the checkpoint is of another model (' // itoa(n) // ' coordinates, ' // &
        & trim(name) // '); the scene has ' // itoa(model%d%n) // ' coordinates, ' // st%name())
      return
    end if
    read(u, iostat=ios) prog%rows, prog%k_out, prog%t_next, prog%cpu_s, prog%t_checkpoint
    if (ios == 0) call st%load(u, ios)
    if (ios == 0) call model%load_run(u, ios)
    close(u)
    if (ios /= 0) call fatal_error(error, path // ': the checkpoint is truncated or damaged')
  end subroutine read_checkpoint
end module pymr_io_checkpoint
