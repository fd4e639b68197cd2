!> A file of result rows being written, whatever its format (results_csv, results_hdf5):
!> rows go to PATH.partial, which replaces PATH only when the run ends well (finish); a
!> failed run leaves it as it is (close), a refused one removes it (discard), so an earlier
!> complete PATH is never lost. A restart (reopen) keeps the rows a checkpoint counts.
module pymr_io_results_file
  use, intrinsic :: ieee_arithmetic, only : ieee_is_finite
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_env_text, only : itoa, fmt
  use pymr_model_types, only : model_data
  use pymr_io_results_output, only : output_plan
  implicit none
  private
  public :: results_file, check_kept_values, check_kept_times, check_kept_last, column_name

  type, abstract :: results_file
    !> The results file, and the partial file written until the run is complete.
    character(len=:), allocatable :: path, partial
    logical :: opened = .false.
    !> The status and message of the first write that failed (0: none): the run reports it
    !> with its time.
    integer :: ios = 0
    character(len=256) :: io_message = ''
    !> The groups of columns written.
    type(output_plan) :: plan
    !> Significant digits per value (&output precision; a text format's).
    integer :: digits = 17
    !> The last row written (after reopen: the last row kept), which a checkpoint records
    !> so that a restart can tell the checkpointed run's results from another run's file.
    real(dp), allocatable :: row(:)
    !> What the run is: its title and method, the scene's fingerprint, the resolved scene
    !> and the integrator settings as JSON members (a format that holds them writes them).
    character(len=:), allocatable :: title, method, fingerprint, scene_text, settings
  contains
    procedure :: describe => file_describe
    procedure :: pairing => file_pairing
    procedure(file_open), deferred :: open
    procedure(file_reopen), deferred :: reopen
    procedure(file_write_row), deferred :: write_row
    procedure(file_action), deferred :: flush_rows
    procedure(file_action), deferred :: close
    procedure(file_action), deferred :: discard
    procedure(file_finish), deferred :: finish
  end type results_file

  abstract interface
    !> Open PATH.partial and write what precedes the rows.
    subroutine file_open(self, path, d, error)
      import :: results_file, model_data, error_type
      class(results_file), intent(inout) :: self
      character(len=*), intent(in) :: path
      type(model_data), intent(in) :: d
      type(error_type), allocatable, intent(out) :: error
    end subroutine file_open

    !> Restart: a new PATH.partial holding the first `rows` rows of the checkpointed run's
    !> (its partial file if it was stopped, else its complete file), then append. `last`:
    !> row `rows` as that run wrote it (check_kept_last).
    subroutine file_reopen(self, path, d, rows, last, error)
      import :: results_file, model_data, error_type, dp
      class(results_file), intent(inout) :: self
      character(len=*), intent(in) :: path
      type(model_data), intent(in) :: d
      integer, intent(in) :: rows
      real(dp), intent(in) :: last(:)
      type(error_type), allocatable, intent(out) :: error
    end subroutine file_reopen

    !> The row for time t of the coordinates q, rates qd and the plan's other values.
    subroutine file_write_row(self, d, t, q, qd, extra)
      import :: results_file, model_data, dp
      class(results_file), intent(inout) :: self
      type(model_data), intent(in) :: d
      real(dp), intent(in) :: t, q(:), qd(:), extra(:)
    end subroutine file_write_row

    !> flush_rows: the rows so far handed to the system and checked; close: the partial
    !> file closed and left (a failed run's rows); discard: closed and removed.
    subroutine file_action(self)
      import :: results_file
      class(results_file), intent(inout) :: self
    end subroutine file_action

    !> The run ended well: `statistics` (OUT.json's text) kept with the rows where the format
    !> can, the file closed (checked), flushed to the disk and put in place.
    subroutine file_finish(self, statistics, error)
      import :: results_file, error_type
      class(results_file), intent(inout) :: self
      character(len=*), intent(in) :: statistics
      type(error_type), allocatable, intent(out) :: error
    end subroutine file_finish
  end interface

contains

  !> Record what the run is, before open.
  subroutine file_describe(self, title, method, fingerprint, scene_text, settings)
    class(results_file), intent(inout) :: self
    character(len=*), intent(in) :: title, method, fingerprint, scene_text, settings
    self%title = trim(title); self%method = trim(method); self%fingerprint = fingerprint
    self%scene_text = scene_text; self%settings = settings
  end subroutine file_describe

  !> JSON members (each a line, with its comma) that tie the statistics to the results file
  !> they were written with ('': a format that keeps them inside the file).
  function file_pairing(self) result(members)
    class(results_file), intent(in) :: self
    character(len=:), allocatable :: members
    members = ''
  end function file_pairing

  !> Values a restart keeps (row `row` of `source`, the columns named by `column` from its
  !> first, comma-separated) are finite: a run writes no other, so a row that holds one was
  !> changed after the run (else the error names file, row and column).
  subroutine check_kept_values(source, row, values, columns, first, error)
    character(len=*), intent(in) :: source, columns
    integer, intent(in) :: row, first
    real(dp), intent(in) :: values(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: k
    k = findloc(ieee_is_finite(values), .false., 1)
    if (k == 0) return
    call fatal_error(error, source // ': row ' // itoa(row) // ', column ' // column_name(columns, first + k - 1) // &
      & ': not a finite number (a run writes none: the file was changed after the run): restart from the ' // &
      & 'results the run wrote')
  end subroutine check_kept_values

  !> The times of the rows a restart keeps (from `source`) are in order, as a run writes
  !> them (else the error names file and row).
  subroutine check_kept_times(source, times, error)
    character(len=*), intent(in) :: source
    real(dp), intent(in) :: times(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: k
    if (size(times) < 2) return
    k = findloc(times(2:) >= times(:size(times)-1), .false., 1)
    if (k == 0) return
    call fatal_error(error, source // ': row ' // itoa(k + 1) // ', column t: ' // fmt(times(k+1)) // ' is before ' // &
      & 'the row before it (' // fmt(times(k)) // '; a run writes its rows in time: the file was changed after ' // &
      & 'the run): restart from the results the run wrote')
  end subroutine check_kept_times

  !> Row `row` of `source`, the last a restart keeps (`values`, read at `digits` significant
  !> digits), is the row the checkpointed run wrote there (`last`): a results file of another
  !> run (another output interval, other physics, an older complete file where the partial
  !> one was lost) would be continued as this run's. The error names file, row and column.
  subroutine check_kept_last(source, row, values, last, digits, columns, error)
    character(len=*), intent(in) :: source, columns
    integer, intent(in) :: row, digits
    real(dp), intent(in) :: values(:), last(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: k
    real(dp) :: tol
    tol = 10.0_dp**(1 - min(max(digits, 1), 17))
    do k = 1, min(size(values), size(last))
      if (abs(values(k) - last(k)) <= tol*max(abs(values(k)), abs(last(k)))) cycle
      call fatal_error(error, source // ': row ' // itoa(row) // ', column ' // column_name(columns, k) // ' is ' // &
        & fmt(values(k)) // ', where the checkpointed run wrote ' // fmt(last(k)) // ': the file is another ' // &
        & 'run''s results; restart from the results the checkpointed run wrote'); return
    end do
  end subroutine check_kept_last

  !> The k-th name of the comma-separated list `columns`.
  pure function column_name(columns, k) result(name)
    character(len=*), intent(in) :: columns
    integer, intent(in) :: k
    character(len=:), allocatable :: name
    integer :: i, start, found
    start = 1; found = 1
    do i = 1, len(columns)
      if (columns(i:i) /= ',') cycle
      if (found == k) exit
      found = found + 1; start = i + 1
    end do
    name = columns(start:i-1)
  end function column_name
end module pymr_io_results_file
