!> Results as CSV: comment lines (pymr's version, the title, the method), the header row of
!> the columns' names, then one row per output time at &output precision digits.
module pymr_io_results_csv
  use pymr_env_kinds, only : dp
  use, intrinsic :: iso_fortran_env, only : int64
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_model_types, only : model_data
  use pymr_env_real_text, only : put_real
  use pymr_env_text, only : itoa
  use pymr_env_text_file, only : sync_file, rename_file, file_size, check_size, system_reason
  use pymr_io_results_output, only : pymr_version, header_line, row_width, row_values
  use pymr_io_results_file, only : results_file, check_kept_values, check_kept_times, check_kept_last
  implicit none
  private
  public :: csv_writer

  !> A line of text read back.
  type :: line_t
    character(len=:), allocatable :: s
  end type line_t

  !> A CSV results file being written (comment lines, the header row, one row per output
  !> time), its rows streamed to PATH.partial.
  type, extends(results_file) :: csv_writer
    integer :: unit = 0
    !> Bytes written to the file so far, and rows since the file's size was last checked
    !> against them: the Fortran runtime does not report a write that the disk refused
    !> (gfortran 12 drops the data of a full disk or a file-size limit with status 0), so the
    !> size on disk is compared with what was written, every `check_rows` rows and at the end.
    integer(int64) :: written = 0
    integer :: unchecked = 0
    character(len=:), allocatable :: line
    !> Rows formatted and not yet handed to the runtime: pending(1:n_pending), each ended
    !> by a newline, written in one WRITE when the next would not fit (a formatted WRITE
    !> per row cost as much as formatting half its numbers).
    character(len=:), allocatable :: pending
    integer :: n_pending = 0
  contains
    procedure :: open => csv_open
    procedure :: reopen => csv_reopen
    procedure :: write_row => csv_write_row
    procedure :: close => csv_close
    procedure :: finish => csv_finish
    procedure :: discard => csv_discard
    procedure :: flush_rows => csv_flush_rows
    procedure :: pairing => csv_pairing
  end type csv_writer

  !> Rows between checks of the file's size against the bytes written.
  integer, parameter :: check_rows = 256
  !> Bytes of rows held before they are written: the size of the runtime's own buffer
  !> (gfortran's for formatted files), so that a killed run loses at most that much more.
  integer, parameter :: pending_bytes = 8192

contains

  !> Open the CSV file and write the comment lines and the header row (self%plan's columns).
  subroutine csv_open(self, path, d, error)
    class(csv_writer), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(model_data), intent(in) :: d
    type(error_type), allocatable, intent(out) :: error
    integer :: ios
    character(len=256) :: msg
    self%path = path
    self%partial = path // '.partial'
    open(newunit=self%unit, file=self%partial, status='replace', action='write', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, self%partial // ': cannot write the results: ' // system_reason(msg)); return
    end if
    self%opened = .true.
    call put('# pymr ' // pymr_version // ' results')
    call put('# title: ' // self%title)
    call put('# method: ' // self%method)
    call put(header_line(self%plan, d))
    if (self%ios /= 0) then
      call fatal_error(error, self%partial // ': cannot write the results: ' // system_reason(self%io_message)); return
    end if
    call allocate_row(self, d)
  contains
    !> One line, its bytes counted.
    subroutine put(text)
      character(len=*), intent(in) :: text
      if (self%ios /= 0) return
      write(self%unit, '(a)', iostat=self%ios, iomsg=self%io_message) text
      self%written = self%written + len(text) + 1
    end subroutine put
  end subroutine csv_open

  !> Restart: the comment lines, the header and the first `rows` rows of the results the
  !> checkpointed run wrote (its partial file if it was stopped, else its complete file),
  !> written whole to a new partial file that then replaces the old one, and append. The
  !> source stays intact until its replacement is complete.
  subroutine csv_reopen(self, path, d, rows, last, error)
    class(csv_writer), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(model_data), intent(in) :: d
    integer, intent(in) :: rows
    real(dp), intent(in) :: last(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios, k, keep
    character(len=256) :: msg
    character(len=:), allocatable :: buf, source
    type(line_t), allocatable :: lines(:)
    real(dp), allocatable :: times(:), values(:)
    logical :: exists
    keep = rows + 4
    self%path = path
    self%partial = path // '.partial'
    source = self%partial
    inquire(file=source, exist=exists)
    if (.not. exists) then
      source = path
      inquire(file=source, exist=exists)
    end if
    if (.not. exists) then
      call fatal_error(error, path // ': the results of the checkpointed run are missing (restart needs them)')
      return
    end if
    allocate(character(len=max(25*row_width(self%plan, d), len(header_line(self%plan, d))) + 1024) :: buf)
    allocate(lines(keep))
    open(newunit=u, file=source, status='old', action='read', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, source // ': cannot read the results: ' // system_reason(msg)); return
    end if
    do k = 1, keep
      read(u, '(a)', iostat=ios) buf
      if (ios /= 0) exit
      lines(k)%s = trim(buf)
    end do
    close(u)
    if (k <= keep) then
      call fatal_error(error, source // ': has ' // itoa(max(k - 5, 0)) // ' result rows, the checkpoint expects ' // &
        & itoa(rows) // ': the file belongs to another run'); return
    end if
    if (lines(4)%s /= header_line(self%plan, d)) then
      call fatal_error(error, source // ': its columns are not the ones this run writes (&output quantities, or ' // &
        & 'the markers, differ from the checkpointed run''s): restart with the same ones'); return
    end if
    allocate(times(rows), values(row_width(self%plan, d)))
    do k = 5, keep
      call check_kept_line(source, k - 4, lines(k)%s, lines(4)%s, values, error)
      if (allocated(error)) return
      times(k - 4) = values(1)
    end do
    call check_kept_times(source, times, error); if (allocated(error)) return
    call check_kept_last(source, rows, values, last, self%digits, lines(4)%s, error); if (allocated(error)) return
    open(newunit=u, file=self%partial // '.tmp', status='replace', action='write', iostat=ios, iomsg=msg)
    do k = 1, keep
      if (ios == 0) write(u, '(a)', iostat=ios, iomsg=msg) lines(k)%s
    end do
    if (ios == 0) close(u, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, self%partial // ': cannot write the results: ' // system_reason(msg)); return
    end if
    call check_size(self%partial // '.tmp', sum([(int(len(lines(k)%s) + 1, int64), k = 1, keep)]), error)
    if (allocated(error)) return
    call sync_file(self%partial // '.tmp', error); if (allocated(error)) return
    call rename_file(self%partial // '.tmp', self%partial, error); if (allocated(error)) return
    open(newunit=self%unit, file=self%partial, status='old', action='write', position='append', iostat=ios, &
      & iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, self%partial // ': cannot write the results: ' // system_reason(msg)); return
    end if
    self%opened = .true.
    self%written = file_size(self%partial)
    call allocate_row(self, d)
    self%row = values
  end subroutine csv_reopen

  !> Row `row` of the results in `source`, kept by a restart, is what a run writes:
  !> size(values) finite numbers (the columns named in `header`), comma-separated, none empty
  !> (the list-directed READ also takes blanks, '/', 'r*v' and empty fields); else the error
  !> names file and row. `values`: the row's numbers.
  subroutine check_kept_line(source, row, line, header, values, error)
    character(len=*), intent(in) :: source, line, header
    integer, intent(in) :: row
    real(dp), intent(out) :: values(:)
    type(error_type), allocatable, intent(out) :: error
    !> What a number's text may hold (nan and inf are read, then refused as not finite).
    character(len=*), parameter :: number_text = '0123456789.eE+-,nNaAiIfFtTyY'
    integer :: ios, fields, i, width
    width = size(values)
    fields = count([(line(i:i) == ',', i = 1, len(line))]) + 1
    ios = 1
    values = 0.0_dp
    if (fields == width .and. verify(line, number_text) == 0 .and. index(',' // line // ',', ',,') == 0) &
      & read(line, *, iostat=ios) values
    if (ios /= 0) then
      call fatal_error(error, source // ': row ' // itoa(row) // ' is not a row of ' // itoa(width) // &
        & ' numbers (a run writes no other: the file was changed after the run): restart from the results the ' // &
        & 'run wrote'); return
    end if
    call check_kept_values(source, row, values, header, 1, error)
  end subroutine check_kept_line

  !> The row's values and text, and the pending rows' buffer (at least one row).
  subroutine allocate_row(self, d)
    class(csv_writer), intent(inout) :: self
    type(model_data), intent(in) :: d
    allocate(self%row(row_width(self%plan, d)))
    allocate(character(len=25*size(self%row) + 1) :: self%line)
    allocate(character(len=max(pending_bytes, len(self%line))) :: self%pending)
    self%n_pending = 0
  end subroutine allocate_row

  !> Write the row for time t: the coordinates q and rates qd (grouped by joint and body,
  !> when the plan writes them), then the plan's other values `extra`.
  subroutine csv_write_row(self, d, t, q, qd, extra)
    class(csv_writer), intent(inout) :: self
    type(model_data), intent(in) :: d
    real(dp), intent(in) :: t, q(:), qd(:), extra(:)
    integer :: i, pos
    call row_values(self%plan, d, t, q, qd, extra, self%row)
    pos = 1
    do i = 1, size(self%row)
      if (i > 1) then
        self%line(pos:pos) = ','; pos = pos + 1
      end if
      call put_real(self%row(i), self%line, pos, self%digits)
    end do
    self%line(pos:pos) = new_line('a')
    if (self%ios /= 0) return
    if (self%n_pending + pos > len(self%pending)) call write_pending(self)
    self%pending(self%n_pending+1:self%n_pending+pos) = self%line(1:pos)
    self%n_pending = self%n_pending + pos
    self%written = self%written + pos
    self%unchecked = self%unchecked + 1
    if (self%unchecked >= check_rows) call self%flush_rows()
  end subroutine csv_write_row

  !> Hand the pending rows to the runtime (their newlines are in the text: the WRITE adds
  !> the last one's).
  subroutine write_pending(self)
    class(csv_writer), intent(inout) :: self
    if (self%n_pending > 0 .and. self%ios == 0) write(self%unit, '(a)', iostat=self%ios, iomsg=self%io_message) &
      & self%pending(1:self%n_pending-1)
    self%n_pending = 0
  end subroutine write_pending

  !> Hand the rows written so far to the system and check that the file holds them all
  !> (a refused write sets ios and io_message, which the run reports with its time).
  subroutine csv_flush_rows(self)
    class(csv_writer), intent(inout) :: self
    integer(int64) :: size_now
    self%unchecked = 0
    if (self%ios /= 0 .or. .not. self%opened) return
    call write_pending(self)
    if (self%ios /= 0) return
    flush(self%unit, iostat=self%ios, iomsg=self%io_message)
    if (self%ios /= 0) return
    size_now = file_size(self%partial)
    if (size_now /= self%written) then
      self%ios = -1
      self%io_message = 'the disk took ' // itoa(size_now) // ' of ' // itoa(self%written) // &
        & ' bytes (the file system is full, or a file-size limit is reached)'
    end if
  end subroutine csv_flush_rows

  !> Close the partial file, leaving it in place (a failed run's rows).
  subroutine csv_close(self)
    class(csv_writer), intent(inout) :: self
    if (self%opened) then
      call write_pending(self)
      close(self%unit, iostat=self%ios)
    end if
    self%opened = .false.
  end subroutine csv_close

  !> Close, remove the partial file (a run refused before its first step).
  subroutine csv_discard(self)
    class(csv_writer), intent(inout) :: self
    integer :: ios
    if (self%opened) close(self%unit, status='delete', iostat=ios)
    self%opened = .false.
  end subroutine csv_discard

  !> The complete file's size and its last row, for the statistics: a kill between the
  !> renames of the results and of their statistics left new results beside old statistics
  !> (or the reverse), which loaded as one run when their row counts agreed. A reader
  !> compares both with the file.
  function csv_pairing(self) result(members)
    class(csv_writer), intent(in) :: self
    character(len=:), allocatable :: members
    integer :: k
    members = '  "results_bytes": ' // itoa(self%written) // ',' // new_line('a')
    if (.not. allocated(self%line)) return
    k = index(self%line, new_line('a'))
    if (k > 1) members = members // '  "last_row": "' // self%line(1:k-1) // '",' // new_line('a')
  end function csv_pairing

  !> The run ended well: close (checked), flush to the disk, and put the complete file in place.
  subroutine csv_finish(self, statistics, error)
    class(csv_writer), intent(inout) :: self
    character(len=*), intent(in) :: statistics
    type(error_type), allocatable, intent(out) :: error
    integer :: ios
    character(len=256) :: msg
    call self%flush_rows()
    if (self%ios /= 0) then
      call fatal_error(error, self%partial // ': cannot write the results: ' // system_reason(self%io_message), stat_solver)
      return
    end if
    close(self%unit, iostat=ios, iomsg=msg)
    self%opened = .false.
    if (ios /= 0) then
      call fatal_error(error, self%partial // ': cannot write the results: ' // system_reason(msg), stat_solver); return
    end if
    call sync_file(self%partial, error); if (allocated(error)) return
    call rename_file(self%partial, self%path, error)
  end subroutine csv_finish

end module pymr_io_results_csv
