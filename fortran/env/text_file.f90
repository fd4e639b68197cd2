!> Whole files written safely: to PATH.tmp, every write and the close checked, flushed to
!> the disk (fsync), then renamed over PATH, so a complete earlier file is never lost to a
!> failed or killed write.
module pymr_env_text_file
  use, intrinsic :: iso_c_binding, only : c_char, c_int, c_long, c_null_char, c_size_t, c_ptr, c_associated
  use, intrinsic :: iso_fortran_env, only : int64
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_text, only : itoa
  implicit none
  private
  public :: write_text_file, stage_text_file, commit_staged, rename_file, sync_file, check_size, file_size, &
    & scene_relative, absolute_path, acquire_lock, release_lock, not_regular, not_replaceable, missing_folder, remove_file, &
    & read_text_file, check_header_count, same_file, write_standard_output, unwritable_folder, name_too_long, &
    & system_reason

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
    function c_lseek(fd, offset, whence) bind(c, name='lseek') result(r)
      import :: c_int, c_long
      integer(c_int), value :: fd, whence
      integer(c_long), value :: offset
      integer(c_long) :: r
    end function c_lseek
    function c_lock_take(path, holder, reason, nreason) bind(c, name='pymr_lock_take') result(r)
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int), intent(out) :: holder
      character(kind=c_char), intent(out) :: reason(*)
      integer(c_int), value :: nreason
      integer(c_int) :: r
    end function c_lock_take
    subroutine c_lock_release(path) bind(c, name='pymr_lock_release')
      import :: c_char
      character(kind=c_char), intent(in) :: path(*)
    end subroutine c_lock_release
    function c_file_kind(path) bind(c, name='pymr_file_kind') result(kind)
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: kind
    end function c_file_kind
    function c_is_link(path) bind(c, name='pymr_is_link') result(link)
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: path(*)
      integer(c_int) :: link
    end function c_is_link
    function c_write_stdout(buf, n, why, whylen) bind(c, name='pymr_write_stdout') result(r)
      import :: c_char, c_int, c_size_t
      character(kind=c_char), intent(in) :: buf(*)
      integer(c_size_t), value :: n, whylen
      character(kind=c_char), intent(out) :: why(*)
      integer(c_int) :: r
    end function c_write_stdout
    function c_unwritable_folder(dir, why, whylen) bind(c, name='pymr_unwritable_folder') result(r)
      import :: c_char, c_int, c_size_t
      character(kind=c_char), intent(in) :: dir(*)
      integer(c_size_t), value :: whylen
      character(kind=c_char), intent(out) :: why(*)
      integer(c_int) :: r
    end function c_unwritable_folder
    function c_longest_name(dir) bind(c, name='pymr_longest_name') result(n)
      import :: c_char, c_long
      character(kind=c_char), intent(in) :: dir(*)
      integer(c_long) :: n
    end function c_longest_name
    function c_same_file(a, b) bind(c, name='pymr_same_file') result(same)
      import :: c_char, c_int
      character(kind=c_char), intent(in) :: a(*), b(*)
      integer(c_int) :: same
    end function c_same_file
    function c_getcwd(buf, size) bind(c, name='getcwd') result(p)
      import :: c_char, c_size_t, c_ptr
      character(kind=c_char), intent(out) :: buf(*)
      integer(c_size_t), value :: size
      type(c_ptr) :: p
    end function c_getcwd
  end interface

contains

  !> Write `text` to `path` (through path.tmp, fsync and rename). The file's size is checked
  !> against the text: the Fortran runtime does not report a write the disk refused.
  subroutine write_text_file(path, text, error)
    character(len=*), intent(in) :: path, text
    type(error_type), allocatable, intent(out) :: error
    call stage_text_file(path, text, error); if (allocated(error)) return
    call commit_staged(path, error)
  end subroutine write_text_file

  !> Put `path` in place of its earlier version: rename the complete path.tmp that
  !> stage_text_file left (removed if the rename fails).
  subroutine commit_staged(path, error)
    character(len=*), intent(in) :: path
    type(error_type), allocatable, intent(out) :: error
    call rename_file(path // '.tmp', path, error)
    if (allocated(error)) call remove_file(path // '.tmp')
  end subroutine commit_staged

  !> The first half of write_text_file: `text` whole and on the disk in path.tmp (written,
  !> size-checked, fsynced), path itself untouched, for a caller that puts several files in
  !> place only once all of them are complete. A failed write leaves no path.tmp.
  subroutine stage_text_file(path, text, error)
    character(len=*), intent(in) :: path, text
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios
    character(len=256) :: msg
    if (len(not_replaceable(path)) > 0) then
      call fatal_error(error, path // ': cannot write: ' // not_replaceable(path)); return
    end if
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
      call fatal_error(error, path // ': cannot write: ' // system_reason(msg)); return
    end if
    call check_size(path // '.tmp', int(len(text), int64), error); if (allocated(error)) return
    call sync_file(path // '.tmp', error)
    if (allocated(error)) call remove_file(path // '.tmp')
  end subroutine stage_text_file

  !> The folder `path` would be written in, when it is not there as a folder ('' when it is).
  function missing_folder(path) result(folder)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: folder
    folder = folder_of(path)
    if (c_file_kind(folder // c_null_char) == 2) folder = ''
  end function missing_folder

  !> Why no file can be made beside `path` ("cannot make files in its folder 'F' (Permission
  !> denied)"; its folder is there), or '' when one can.
  function unwritable_folder(path) result(why)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: why
    character(kind=c_char) :: buf(256)
    integer :: k
    why = ''
    if (c_unwritable_folder(folder_of(path) // c_null_char, buf, size(buf, kind=c_size_t)) == 0) return
    why = "cannot make files in its folder '" // folder_of(path) // "' ("
    do k = 1, size(buf)
      if (buf(k) == c_null_char) exit
      why = why // buf(k)
    end do
    why = why // ')'
  end function unwritable_folder

  !> The name of `path` (its last component) when it is longer than its folder's file system
  !> takes, with that length ('... is 304 bytes long, longer than the 255 ...'), else ''.
  function name_too_long(path) result(why)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: why
    integer :: n
    integer(c_long) :: most
    why = ''
    n = len_trim(path) - index(trim(path), '/', back=.true.)
    if (n <= 14) return                ! every file system takes 14 bytes (POSIX)
    most = c_longest_name(folder_of(path) // c_null_char)
    if (n <= most) return
    why = 'its name is ' // itoa(n) // ' bytes long, longer than the ' // itoa(int(most)) // &
      & ' its file system takes'
  end function name_too_long

  !> The whole file as text; a UTF-8 byte-order mark, which some editors write at the start,
  !> reads as blanks (lines and columns stay those of the file).
  subroutine read_text_file(file, text, error)
    character(len=*), intent(in) :: file
    character(len=:), allocatable, intent(out) :: text
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios
    integer(int64) :: sz
    character(len=256) :: msg
    logical :: exists
    if (len_trim(file) == 0) then
      call fatal_error(error, 'no scene file given (its path is empty)'); return
    end if
    if (len(not_regular(file)) > 0) then
      call fatal_error(error, file // ': cannot read: ' // not_regular(file)); return
    end if
    inquire(file=file, exist=exists)
    if (.not. exists) then
      call fatal_error(error, file // ': file not found'); return
    end if
    open(newunit=u, file=file, access='stream', form='unformatted', status='old', action='read', &
      & iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, file // ': cannot read: ' // system_reason(msg)); return
    end if
    inquire(unit=u, size=sz)
    if (sz < 0) then
      close(u)
      call fatal_error(error, file // ': cannot read: not a regular file'); return
    end if
    ! its size in a default integer wrapped past 4 GiB: a table read as its first
    ! (size mod 2^32) bytes, exit 0; between 2 and 4 GiB 'not a regular file'
    if (sz > huge(1)) then
      close(u)
      call fatal_error(error, file // ': cannot read: it holds ' // itoa(sz) // ' bytes, more than the ' // &
        & itoa(huge(1)) // ' a text file pymr reads may hold'); return
    end if
    allocate(character(len=sz) :: text)
    if (sz > 0) read(u, iostat=ios, iomsg=msg) text
    close(u)
    if (ios /= 0) then
      call fatal_error(error, file // ': cannot read: ' // system_reason(msg)); return
    end if
    if (sz >= 3) then
      if (text(1:3) == achar(239) // achar(187) // achar(191)) text(1:3) = ' '
    end if
    call lone_returns_as_breaks(text)
  end subroutine read_text_file

  !> Old Mac line ends: a carriage return not followed by a line feed ends a line (one
  !> followed by a line feed, as Windows writes them, is left to the readers, which take it
  !> for a blank).
  pure subroutine lone_returns_as_breaks(text)
    character(len=*), intent(inout) :: text
    integer :: i
    do i = 1, len(text)
      if (text(i:i) /= achar(13)) cycle
      if (i < len(text)) then
        if (text(i+1:i+1) == achar(10)) cycle
      end if
      text(i:i) = achar(10)
    end do
  end subroutine lone_returns_as_breaks

  !> A count read from a file (a header's number of points, modes, entries) must fit the
  !> file before anything is allocated by it: `count` items of at least `least` bytes each
  !> cannot be in a file of fewer bytes. Else the error 'PATH: WHERE: COUNT WHAT cannot be
  !> in this file (SIZE bytes)'. ('points 2000000000' in a modal file of 70 kB asked for
  !> 48 GB, and the Fortran runtime stopped the program.)
  subroutine check_header_count(path, where, count, least, what, error)
    character(len=*), intent(in) :: path, where, what
    integer(int64), intent(in) :: count
    integer, intent(in) :: least
    type(error_type), allocatable, intent(out) :: error
    integer(int64) :: sz
    sz = max(file_size(path), 0_int64)
    if (real(count, dp)*real(least, dp) <= real(sz, dp)) return
    call fatal_error(error, path // ': ' // where // ': ' // itoa(count) // ' ' // what // &
      & ' cannot be in this file (' // itoa(sz) // ' bytes)')
  end subroutine check_header_count

  !> Do `a` and `b` name one file? When both are there, whether they are the same file on
  !> the disk (links followed; any spelling: './', '..', a link); else whether their
  !> absolute paths are equal. The one rule by which an output is refused that would
  !> replace an input.
  function same_file(a, b) result(same)
    character(len=*), intent(in) :: a, b
    logical :: same
    select case (c_same_file(a // c_null_char, b // c_null_char))
    case (0)
      same = .false.
    case (1)
      same = .true.
    case default
      same = absolute_path(a) == absolute_path(b)
    end select
  end function same_file

  !> Remove a file if it is there (a temporary one left by a failed write).
  subroutine remove_file(path)
    character(len=*), intent(in) :: path
    integer :: u, ios
    open(newunit=u, file=path, status='old', iostat=ios)
    if (ios == 0) close(u, status='delete', iostat=ios)
  end subroutine remove_file

  !> The size of a file on the disk, from the system (-1 when it cannot be opened): what the
  !> Fortran runtime reports for a file it has open is what it believes it wrote.
  function file_size(path) result(sz)
    character(len=*), intent(in) :: path
    integer(int64) :: sz
    integer(c_int) :: fd
    integer(c_int), parameter :: o_rdonly = 0, seek_end = 2
    sz = -1
    fd = c_open(path // c_null_char, o_rdonly)
    if (fd < 0) return
    sz = int(c_lseek(fd, 0_c_long, seek_end), int64)
    if (c_close(fd) /= 0) sz = -1
  end function file_size

  !> A closed file must hold the `expected` bytes written to it; if not, it is removed and
  !> the error says how much the disk took.
  subroutine check_size(path, expected, error)
    character(len=*), intent(in) :: path
    integer(int64), intent(in) :: expected
    type(error_type), allocatable, intent(out) :: error
    integer(int64) :: got
    integer :: u, ios
    got = file_size(path)
    if (got == expected) return
    open(newunit=u, file=path, status='old', iostat=ios)
    if (ios == 0) close(u, status='delete', iostat=ios)
    call fatal_error(error, path // ': cannot write: the disk took ' // itoa(got) // ' of ' // itoa(expected) // &
      & ' bytes (the file system is full, or a file-size limit is reached)', stat_solver)
  end subroutine check_size

  !> Why `path` is no file to read or to replace, for messages: 'it is a directory', 'it is
  !> not a regular file (...)'; '' for a regular file, or for no file at all (the caller
  !> tells a missing file in its own words). A FIFO would hold a read until something
  !> writes to it, and a renamed results file would replace a device.
  function not_regular(path) result(why)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: why
    select case (c_file_kind(path // c_null_char))
    case (2)
      why = 'it is a directory'
    case (3)
      why = 'it is not a regular file (a FIFO, a socket or a device)'
    case (4)
      why = 'it is a loop of symbolic links'
    case (5)
      why = 'it is a symbolic link to nothing'
    case (6)
      why = 'a folder on its path may not be searched (permission denied)'
    case default
      why = ''
    end select
  end function not_regular

  !> Why an output written whole beside `path` and renamed over it cannot be put there:
  !> not_regular's reasons, and a symbolic link, which the rename would replace (its target
  !> left as it was); '' where it can.
  function not_replaceable(path) result(why)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: why
    if (c_is_link(path // c_null_char) == 1) then
      why = 'it is a symbolic link, which the finished file, renamed into place, would replace (not the file ' // &
        & 'it points to)'
    else
      why = not_regular(path)
    end if
  end function not_replaceable

  !> `text` and a line end on the standard output, every byte of it checked: an error (stat 1)
  !> naming the reason when the output does not take it (a full disk, a closed output).
  !> Nothing may be pending on the Fortran unit of the standard output.
  subroutine write_standard_output(text, error)
    character(len=*), intent(in) :: text
    type(error_type), allocatable, intent(out) :: error
    character(kind=c_char) :: why(256)
    character(len=256) :: reason
    integer :: i
    why = c_null_char
    if (c_write_stdout(text // new_line('a'), int(len(text) + 1, c_size_t), why, int(size(why), c_size_t)) == 0) return
    reason = ''
    do i = 1, size(why)
      if (why(i) == c_null_char) exit
      reason(i:i) = why(i)
    end do
    call fatal_error(error, 'the standard output: ' // trim(reason))
  end subroutine write_standard_output

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

  !> The system's reason in a run-time library's message ("Cannot open file 'x': Permission
  !> denied" -> "Permission denied"): the file it names may be one of pymr's own.
  function system_reason(msg) result(r)
    character(len=*), intent(in) :: msg
    character(len=:), allocatable :: r
    integer :: k
    k = index(msg, ': ', back=.true.)
    r = trim(msg(k + 1:))
    r = trim(adjustl(r))
    if (len(r) == 0) r = trim(msg)
  end function system_reason

  !> Take PATH.lock for this process (env/lock.c: an flock the system releases when the
  !> process ends): refused while another process holds it; a lock left by a killed run is
  !> free.
  subroutine acquire_lock(path, error)
    character(len=*), intent(in) :: path
    type(error_type), allocatable, intent(out) :: error
    integer(c_int) :: holder, r
    character(kind=c_char, len=256) :: reason
    r = c_lock_take(path // '.lock' // c_null_char, holder, reason, int(len(reason), c_int))
    select case (r)
    case (0)
      return
    case (1)
      call fatal_error(error, path // ': another run (process ' // itoa(int(holder)) // ') is writing these ' // &
        & 'results; wait for it or choose another output')
    case default
      ! no lock can be made: the folder is missing or not writable
      call fatal_error(error, path // ': cannot write in its folder ' // folder_of(path) // ' (' // &
        & reason(1:max(index(reason, c_null_char) - 1, 0)) // '): the results could not be written')
    end select
  end subroutine acquire_lock

  !> The folder part of a path ('.' for a bare file name).
  function folder_of(path) result(s)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: s
    integer :: k
    k = index(path, '/', back=.true.)
    if (k == 0) then
      s = '.'
    else if (k == 1) then
      s = '/'
    else
      s = path(1:k-1)
    end if
  end function folder_of

  !> Release PATH.lock, if this process holds it (the file removed).
  subroutine release_lock(path)
    character(len=*), intent(in) :: path
    call c_lock_release(path // '.lock' // c_null_char)
  end subroutine release_lock

  !> Move `old` over `new` (atomic on one file system).
  subroutine rename_file(old, new, error)
    character(len=*), intent(in) :: old, new
    type(error_type), allocatable, intent(out) :: error
    if (c_rename(old // c_null_char, new // c_null_char) /= 0) then
      call fatal_error(error, new // ': cannot move the new file into place from ' // old)
    end if
  end subroutine rename_file
end module pymr_env_text_file
