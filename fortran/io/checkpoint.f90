!> Checkpoint files: the full state of a run at a step boundary, so that a run stopped
!> by a wall-time limit continues from its last checkpoint exactly as if uninterrupted.
!>
!> Unformatted stream layout: a tag and version, pymr's version, the model's size, the
!> stepper's name, the time, the integrator settings and the model's fingerprint (what a
!> restart must match), the run's output bookkeeping (rows written, next output time, CPU
!> time so far), the stepper's state (its state vector and its record, written by
!> stepper_t's save), and the model's per-run state (held multirate terms, evaluation and
!> effect counters), and last a sha256 checksum of everything before it. Written to PATH.tmp,
!> checked, flushed and renamed, so a run killed while writing keeps the previous checkpoint.
module pymr_io_checkpoint
  use, intrinsic :: iso_fortran_env, only : int64
  use pymr_env_text_file, only : rename_file, sync_file, check_size, not_regular, check_header_count, system_reason
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_integrator_stepper, only : stepper_t, step_counts
  use pymr_model, only : model_t
  use pymr_env_text, only : itoa, fmt
  use pymr_io_sha256, only : sha256_hex
  use pymr_io_results_output, only : pymr_version, n_work
  implicit none
  private
  public :: run_progress, write_checkpoint, read_checkpoint, checkpoint_stepper

  character(len=8), parameter :: tag = 'PYMRCKPT'
  !> 6: the stepper's state written as its state vector and its record (state_record);
  !> 7: the 'response' and 'exponential' steppers named apart (a run of method 'auto'
  !> continues with the one that wrote it); 8: the 'response' macro step's surrogate
  !> correction kept for its dense output; 9: the results' last row (a restart checks the
  !> kept file against it) and the run's warnings; 10: the step counts of the methods
  !> that ran before the stepper written (method 'auto' reviewed); 11: the last accepted
  !> step's error estimate and length of adaptive 'response' and 'exponential' (their
  !> error envelope); 12: the error model of the last accepted 'response' macro step; 13: the
  !> error envelope of the last eight accepted steps; 14: the 'exponential' stepper's watch
  !> of its response's drift (its renewals for accuracy).
  integer, parameter :: version = 14

  !> What a checkpoint's header says: pymr's version, the model's size, the stepper's name,
  !> the time, the integrator settings and the model's fingerprint.
  type :: checkpoint_header
    character(len=16) :: pv = '', name = ''
    integer :: n = 0, nj = 0
    real(dp) :: t = 0.0_dp
    character(len=:), allocatable :: settings
    character(len=71) :: fp = ''
  end type checkpoint_header

  !> Output bookkeeping of a run at a checkpoint.
  type :: run_progress
    integer :: rows = 0, k_out = 1
    real(dp) :: t_next = 0.0_dp, cpu_s = 0.0_dp, t_checkpoint = 0.0_dp
    !> The works of the energy columns integrated so far (J).
    real(dp) :: work(n_work) = 0.0_dp
    !> The accepted slow and fast steps, rejections and stepper-made fast evaluations of the
    !> methods that ran before the stepper written (method 'auto' switches, method_choice.f90).
    type(step_counts) :: carried
    !> The last row the results hold (a restart checks the kept file's against it).
    real(dp), allocatable :: last_row(:)
    !> The run's warnings so far (a restart keeps them: each is said once, at its time).
    character(len=:), allocatable :: warnings
  end type run_progress

contains

  !> Write the state of the run (any stepper) and model to `path`: a header that names the
  !> scene (its integrator settings and model fingerprint), pymr's version and the time,
  !> then the states, then a sha256 checksum of all of it. Every write and the close are
  !> checked; the file is flushed to the disk and renamed over the previous checkpoint.
  subroutine write_checkpoint(path, st, model, prog, settings, fingerprint, error)
    character(len=*), intent(in) :: path, settings, fingerprint
    class(stepper_t), intent(inout) :: st
    type(model_t), intent(in) :: model
    type(run_progress), intent(in) :: prog
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios
    integer(int64) :: pos
    character(len=256) :: msg
    character(len=16) :: name, ver
    character(len=:), allocatable :: body
    open(newunit=u, file=path // '.tmp', access='stream', form='unformatted', status='replace', action='write', &
      & iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot write the checkpoint (' // system_reason(msg) // ')', stat_solver); return
    end if
    name = st%name(); ver = pymr_version
    write(u, iostat=ios) tag, version, ver, model%d%n, model%d%nj, name, st%time(), len(settings), settings, &
      & fingerprint_field(fingerprint)
    if (ios == 0) write(u, iostat=ios) prog%rows, prog%k_out, prog%t_next, prog%cpu_s, prog%t_checkpoint, prog%work, &
      & prog%carried%steps_slow, prog%carried%steps_fast, prog%carried%rejected, prog%carried%evals_fast, &
      & size(prog%last_row), prog%last_row, len(prog%warnings), prog%warnings
    if (ios == 0) call st%save(u, ios)
    if (ios == 0) call model%save_run(u, ios)
    if (ios /= 0) then
      close(u, status='delete', iostat=ios)
      call fatal_error(error, path // ': cannot write the checkpoint (disk full?)', stat_solver); return
    end if
    ! what the runtime wrote: the file's size must match it (a refused write is not reported)
    inquire(unit=u, pos=pos)
    close(u, iostat=ios, iomsg=msg)
    if (ios == 0) call check_size(path // '.tmp', pos - 1, error)
    if (allocated(error)) then
      error%message = error%message // ' (the checkpoint)'; return
    end if
    if (ios == 0) call read_bytes(path // '.tmp', body, ios)
    if (ios == 0) then
      open(newunit=u, file=path // '.tmp', access='stream', form='unformatted', status='old', action='write', &
        & position='append', iostat=ios, iomsg=msg)
      if (ios == 0) write(u, iostat=ios) sha256_hex(body)
      if (ios == 0) close(u, iostat=ios, iomsg=msg)
    end if
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot write the checkpoint (' // system_reason(msg) // ')', stat_solver); return
    end if
    call check_size(path // '.tmp', int(len(body) + 64, int64), error)
    if (allocated(error)) then
      error%message = error%message // ' (the checkpoint)'; return
    end if
    call sync_file(path // '.tmp', error); if (allocated(error)) return
    call rename_file(path // '.tmp', path, error)
  end subroutine write_checkpoint

  !> Read a checkpoint into a stepper set up for the same scene (not started) and its model.
  !> Refused, saying what differs: a damaged file (checksum), another checkpoint version or
  !> pymr version, another stepper or model size, other integrator settings, another model,
  !> a t_end not after it.
  subroutine read_checkpoint(path, st, model, prog, settings, fingerprint, t_end, error)
    character(len=*), intent(in) :: path, settings, fingerprint
    class(stepper_t), intent(inout) :: st
    type(model_t), intent(inout) :: model
    type(run_progress), intent(out) :: prog
    real(dp), intent(in) :: t_end
    type(error_type), allocatable, intent(out) :: error
    type(checkpoint_header) :: hd
    integer :: u, ios, n_last
    character(len=256) :: msg
    call verify_file(path, error); if (allocated(error)) return
    open(newunit=u, file=path, access='stream', form='unformatted', status='old', action='read', iostat=ios, &
      & iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot read the checkpoint: ' // system_reason(msg)); return
    end if
    call read_header(u, path, hd, error)
    if (.not. allocated(error)) call compare_identity(path, hd, st, model, settings, fingerprint, t_end, error)
    if (allocated(error)) then
      close(u); return
    end if
    read(u, iostat=ios) prog%rows, prog%k_out, prog%t_next, prog%cpu_s, prog%t_checkpoint, prog%work, &
      & prog%carried%steps_slow, prog%carried%steps_fast, prog%carried%rejected, prog%carried%evals_fast, n_last
    if (ios == 0 .and. (n_last < 0 .or. n_last > huge(1)/8)) ios = 1
    if (ios == 0) then
      allocate(prog%last_row(n_last))
      read(u, iostat=ios) prog%last_row, n_last
    end if
    if (ios == 0 .and. (n_last < 0 .or. n_last > 100000000)) ios = 1
    if (ios == 0) then
      allocate(character(len=n_last) :: prog%warnings)
      read(u, iostat=ios) prog%warnings
    end if
    if (ios == 0) call st%load(u, ios)
    if (ios == 0) call model%load_run(u, ios)
    close(u)
    if (ios /= 0) call fatal_error(error, path // ': the checkpoint is truncated or damaged')
  end subroutine read_checkpoint

  !> The name of the stepper that wrote the checkpoint `path` (a run of method 'auto'
  !> continues with the method it chose), with read_checkpoint's refusals of the file.
  function checkpoint_stepper(path, error) result(name)
    character(len=*), intent(in) :: path
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: name
    type(checkpoint_header) :: hd
    integer :: u, ios
    name = ''
    call verify_file(path, error); if (allocated(error)) return
    open(newunit=u, file=path, access='stream', form='unformatted', status='old', action='read', iostat=ios)
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot read the checkpoint'); return
    end if
    call read_header(u, path, hd, error)
    close(u)
    if (.not. allocated(error)) name = trim(hd%name)
  end function checkpoint_stepper

  !> A regular file that begins with the tag and ends with the sha256 of all before it.
  subroutine verify_file(path, error)
    character(len=*), intent(in) :: path
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: bytes
    logical :: exists
    integer :: ios
    if (len(not_regular(path)) > 0) then
      call fatal_error(error, path // ': cannot read the checkpoint: ' // not_regular(path)); return
    end if
    inquire(file=path, exist=exists)
    if (.not. exists) then
      call fatal_error(error, path // ': checkpoint not found'); return
    end if
    call read_bytes(path, bytes, ios)
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot read the checkpoint'); return
    end if
    if (len(bytes) < 8 + 64) then
      call fatal_error(error, path // ': not a pymr checkpoint'); return
    end if
    if (bytes(1:8) /= tag) then
      call fatal_error(error, path // ': not a pymr checkpoint'); return
    end if
    if (sha256_hex(bytes(1:len(bytes) - 64)) /= bytes(len(bytes) - 63:)) then
      call fatal_error(error, path // ': the checkpoint is damaged or truncated (its checksum does not match)')
    end if
  end subroutine verify_file

  !> The header of the checkpoint open on unit u, up to the model's fingerprint; a file of
  !> another checkpoint version is refused at once (its layout after the version is not
  !> this one's).
  subroutine read_header(u, path, hd, error)
    integer, intent(in) :: u
    character(len=*), intent(in) :: path
    type(checkpoint_header), intent(out) :: hd
    type(error_type), allocatable, intent(out) :: error
    character(len=8) :: got
    integer :: ios, ver, ls
    read(u, iostat=ios) got, ver
    if (ios == 0 .and. ver /= version) then
      call fatal_error(error, path // ': checkpoint version ' // itoa(ver) // ', this pymr reads ' // &
        & itoa(version) // ' (write it again with this pymr: run the scene from the start)'); return
    end if
    if (ios == 0) read(u, iostat=ios) hd%pv, hd%n, hd%nj, hd%name, hd%t, ls
    if (ios == 0) then
      call check_header_count(path, 'its integrator settings', int(max(ls, 0), int64), 1, 'bytes', error)
      if (allocated(error)) return
      allocate(character(len=ls) :: hd%settings)
      read(u, iostat=ios) hd%settings, hd%fp
    end if
    if (ios /= 0) call fatal_error(error, path // ': the checkpoint is truncated or damaged')
  end subroutine read_header

  !> Refuse a checkpoint whose header does not match the scene: another pymr, model size or
  !> stepper, other settings, another model, or a t_end not after its time.
  subroutine compare_identity(path, hd, st, model, settings, fingerprint, t_end, error)
    character(len=*), intent(in) :: path, settings, fingerprint
    type(checkpoint_header), intent(in) :: hd
    class(stepper_t), intent(in) :: st
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: t_end
    type(error_type), allocatable, intent(out) :: error
    if (hd%pv /= pymr_version) then
      call fatal_error(error, path // ': the checkpoint was written by pymr ' // trim(hd%pv) // '; this is pymr ' // &
        & pymr_version); return
    end if
    if (hd%n /= model%d%n .or. hd%nj /= model%d%nj .or. hd%name /= st%name()) then
      call fatal_error(error, path // ': the checkpoint is of another model (' // itoa(hd%n) // ' coordinates, ' // &
        & trim(hd%name) // '); the scene has ' // itoa(model%d%n) // ' coordinates, ' // st%name()); return
    end if
    if (hd%settings /= settings) then
      call fatal_error(error, path // ': the checkpoint was written with other integrator settings: ' // &
        & first_difference(hd%settings, settings)); return
    end if
    if (hd%fp /= fingerprint_field(fingerprint)) then
      call fatal_error(error, path // ': the checkpoint is of another scene (a group other than &integrator ' // &
        & 'and &output, or a file the scene reads, differs: model fingerprint ' // hd%fp(8:19) // &
        & '..., the scene''s ' // fingerprint(8:19) // '...)')
      return
    end if
    if (.not. (t_end > hd%t)) then
      call fatal_error(error, path // ': t_end = ' // fmt(t_end) // ' s is not after the checkpoint''s time ' // &
        & fmt(hd%t) // ' s'); return
    end if
  end subroutine compare_identity

  !> A fingerprint in the fixed width of the checkpoint header.
  pure function fingerprint_field(fp) result(s)
    character(len=*), intent(in) :: fp
    character(len=71) :: s
    s = fp
  end function fingerprint_field

  !> "h_slow = 0.0001 then, h_slow = 5e-05 now": the first line where two texts differ.
  function first_difference(a, b) result(s)
    character(len=*), intent(in) :: a, b
    character(len=:), allocatable :: s
    integer :: ia, ib, ea, eb
    ia = 1; ib = 1
    do
      ea = index(a(ia:) // new_line('a'), new_line('a')) + ia - 2
      eb = index(b(ib:) // new_line('a'), new_line('a')) + ib - 2
      if (a(ia:ea) /= b(ib:eb) .or. ea >= len(a) .or. eb >= len(b)) exit
      ia = ea + 2; ib = eb + 2
    end do
    s = trim(adjustl(a(ia:min(ea, len(a))))) // ' then, ' // trim(adjustl(b(ib:min(eb, len(b))))) // ' now'
  end function first_difference

  !> A whole file's bytes.
  subroutine read_bytes(path, bytes, ios)
    character(len=*), intent(in) :: path
    character(len=:), allocatable, intent(out) :: bytes
    integer, intent(out) :: ios
    integer :: u, sz
    open(newunit=u, file=path, access='stream', form='unformatted', status='old', action='read', iostat=ios)
    if (ios /= 0) return
    inquire(unit=u, size=sz)
    allocate(character(len=max(sz, 0)) :: bytes)
    if (sz > 0) read(u, iostat=ios) bytes
    close(u)
  end subroutine read_bytes
end module pymr_io_checkpoint
