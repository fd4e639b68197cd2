!> Whole files written safely: to PATH.tmp, every write and the close checked, flushed to
!> the disk (fsync), then renamed over PATH, so a complete earlier file is never lost to a
!> failed or killed write.
module pymr_io_text_file
  use, intrinsic :: iso_c_binding, only : c_char, c_int, c_null_char, c_size_t, c_ptr, c_associated
  use pymr_error, only : error_type, fatal_error
  use pymr_io_text, only : itoa
  implicit none
  private
  public :: write_text_file, rename_file, sync_file, scene_relative, absolute_path, acquire_lock, release_lock

  interface
    function c_rename(old, new) bind(c, name='rename') result(r)
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: old(*), new(*)
      integer(c_int) :: r
    end function c_rename
    function c_open(path, flags) bind(c, name='open') result(fd)
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), value :: flags
      integer(c_int) :: fd
    end function c_open
    function c_fsync(fd) bind(c, name='fsync') result(r)
      import :: c_int
      integer(c_int), value :: fd
      integer(c_int) :: r
    end function c_fsync
    function c_close(fd) bind(c, name='close') result(r)
      import :: c_int
      integer(c_int), value :: fd
      integer(c_int) :: r
    end function c_close
    function c_getpid() bind(c, name='getpid') result(pid)
      import :: c_int
      integer(c_int) :: pid
    end function c_getpid
    function c_kill(pid, sig) bind(c, name='kill') result(r)
      import :: c_int
      integer(c_int), value :: pid, sig
      integer(c_int) :: r
    end function c_kill
    function c_getcwd(buf, size) bind(c, name='getcwd') result(p)
      import :: c_char, c_size_t, c_ptr
      character(kind=c_char), intent(out) :: buf(*)
      integer(c_size_t), value :: size
      type(c_ptr) :: p
    end function c_getcwd
  end interface

contains

  !> Write `text` to `path` (through path.tmp, fsync and rename).
  subroutine write_text_file(path, text, error)
    character(len=*), intent(in) :: path, text
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios
    character(len=256) :: msg
    open(newunit=u, file=path // '.tmp', access='stream', form='unformatted', status='replace', action='write', &
      & iostat=ios, iomsg=msg)
    if (ios == 0) then
      write(u, iostat=ios, iomsg=msg) text
      if (ios /= 0) then
        close(u, status='delete', iostat=ios)
        ios = 1
      else
        close(u, iostat=ios, iomsg=msg)
      end if
    end if
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot write: ' // trim(msg)); return
    end if
    call sync_file(path // '.tmp', error); if (allocated(error)) return
    call rename_file(path // '.tmp', path, error)
  end subroutine write_text_file

  !> Make the kernel write a closed file's data to the disk (fsync).
  subroutine sync_file(path, error)
    character(len=*), intent(in) :: path
    type(error_type), allocatable, intent(out) :: error
    integer(c_int) :: fd
    integer(c_int), parameter :: o_rdonly = 0
    fd = c_open(path // c_null_char, o_rdonly)
    if (fd < 0) then
      call fatal_error(error, path // ': cannot reopen to flush it to the disk'); return
    end if
    if (c_fsync(fd) /= 0) call fatal_error(error, path // ': the disk did not take the data (fsync failed)')
    if (c_close(fd) /= 0 .and. .not. allocated(error)) call fatal_error(error, path // ': cannot close')
  end subroutine sync_file

  !> A path given in a scene, relative to the folder of the scene file `scene` (absolute
  !> paths are kept).
  pure function scene_relative(scene, path) result(p)
    character(len=*), intent(in) :: scene, path
    character(len=:), allocatable :: p
    integer :: k
    k = index(scene, '/', back=.true.)
    if (len(path) == 0) then
      p = path
    else if (path(1:1) == '/' .or. k == 0) then
      p = path
    else
      p = scene(1:k) // path
    end if
  end function scene_relative

  !> `path` made absolute from the working folder.
  function absolute_path(path) result(p)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: p
    character(kind=c_char, len=4096) :: buf
    integer :: k
    p = path
    if (len(path) > 0) then
      if (path(1:1) == '/') return
    end if
    if (.not. c_associated(c_getcwd(buf, int(len(buf), c_size_t)))) return
    k = index(buf, c_null_char) - 1
    if (k < 1) return
    p = buf(1:k) // '/' // path
    ! one spelling for one file: no './' segments
    k = index(p, '/./')
    do while (k > 0)
      p = p(1:k) // p(k+3:)
      k = index(p, '/./')
    end do
  end function absolute_path

  !> Take PATH.lock for this process: refused while another living process holds it (a
  !> lock left by a killed run is taken over).
  subroutine acquire_lock(path, error)
    character(len=*), intent(in) :: path
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios, attempt, pid
    do attempt = 1, 2
      open(newunit=u, file=path // '.lock', status='new', action='write', iostat=ios)
      if (ios == 0) then
        write(u, '(i0)', iostat=ios) c_getpid()
        close(u)
        return
      end if
      pid = 0
      open(newunit=u, file=path // '.lock', status='old', action='read', iostat=ios)
      if (ios == 0) then
        read(u, *, iostat=ios) pid
        close(u)
      end if
      if (pid > 0) then
        if (c_kill(int(pid, c_int), 0_c_int) == 0) then
          call fatal_error(error, path // ': another run (process ' // itoa(pid) // ') is writing these ' // &
            & 'results; wait for it or choose another output'); return
        end if
      end if
      call release_lock(path)          ! left by a run that no longer lives
    end do
    call fatal_error(error, path // ': cannot take the lock ' // path // '.lock')
  end subroutine acquire_lock

  !> Remove PATH.lock.
  subroutine release_lock(path)
    character(len=*), intent(in) :: path
    integer :: u, ios
    open(newunit=u, file=path // '.lock', status='old', iostat=ios)
    if (ios == 0) close(u, status='delete', iostat=ios)
  end subroutine release_lock

  !> Move `old` over `new` (atomic on one file system).
  subroutine rename_file(old, new, error)
    character(len=*), intent(in) :: old, new
    type(error_type), allocatable, intent(out) :: error
    if (c_rename(old // c_null_char, new // c_null_char) /= 0) then
      call fatal_error(error, new // ': cannot move the new file into place from ' // old)
    end if
  end subroutine rename_file
end module pymr_io_text_file
