!> Results as HDF5 (&output format = 'hdf5'): one dataset per group of columns ('time',
!> 'joint_coordinates', 'markers', 'energy', ...: the groups of walk_columns), rows by
!> columns, chunked, shuffled and deflated (&output compression), appended block by block as
!> the run goes. Each
!> dataset carries its columns' names, owners, quantities and units; the file carries the
!> run's title, method, scene fingerprint, resolved scene, settings and the column order,
!> and at the end its statistics (OUT.json's text).
!>
!> Kills: the file is written in HDF5's single-writer/multiple-reader mode, whose ordered
!> metadata writes leave a file that can be read at any moment; rows are flushed to it
!> whenever the run checkpoints, so a killed run's partial file holds every row the last
!> checkpoint counts, and a restart copies them into a new partial file.
module pymr_io_results_hdf5
  use, intrinsic :: iso_c_binding, only : c_int, c_char, c_null_char
  use, intrinsic :: ieee_arithmetic, only : ieee_is_finite
  use hdf5
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_text, only : itoa
  use pymr_env_text_file, only : sync_file, rename_file, remove_file
  use pymr_model_types, only : model_data
  use pymr_io_results_output, only : pymr_version, output_plan, column_sink, walk_columns, header_line, row_width, row_values
  use pymr_io_results_file, only : results_file, check_kept_values, check_kept_times, check_kept_last
  implicit none
  private
  public :: hdf5_writer

  !> Bytes of a chunk (a block of rows of one dataset), and the fewest rows a chunk holds.
  integer, parameter :: chunk_bytes = 65536, min_chunk_rows = 16

  type :: text_item
    character(len=:), allocatable :: s
  end type text_item

  !> Texts grown by appending, their storage doubled when full.
  type :: text_list
    type(text_item), allocatable :: item(:)
    integer :: n = 0
  contains
    procedure :: add => list_add
  end type text_list


  !> The columns of one group: their places in the row, what they are, the dataset and the
  !> rows waiting to be written.
  type :: column_group
    character(len=:), allocatable :: name
    integer :: n = 0
    integer, allocatable :: place(:)
    type(text_list) :: names, owners, quantities, units
    integer(hid_t) :: dataset = -1
    real(dp), allocatable :: block(:, :)
  end type column_group

  !> walk_columns' sink: each column into its group, groups in order of first appearance.
  type, extends(column_sink) :: group_sink
    type(column_group), allocatable :: group(:)
    integer :: n_groups = 0, n_columns = 0
  contains
    procedure :: add => group_add
  end type group_sink

  type, extends(results_file) :: hdf5_writer
    integer(hid_t) :: file = -1
    !> Deflate level, after the shuffle filter (&output compression; 0: neither).
    integer :: compression = 1
    type(group_sink) :: groups
    !> Rows in the file, rows waiting in the blocks, and rows a block holds.
    integer :: rows_written = 0, rows_waiting = 0, block_rows = 0
  contains
    procedure :: open => h5_open
    procedure :: reopen => h5_reopen
    procedure :: write_row => h5_write_row
    procedure :: flush_rows => h5_flush_rows
    procedure :: close => h5_close
    procedure :: discard => h5_discard
    procedure :: finish => h5_finish
    procedure, private :: create, write_blocks, write_kept, failed
  end type hdf5_writer

  !> H5F_ACC_* flags of the C library (its Fortran interface lacks SWMR in HDF5 1.10).
  integer(c_int), parameter :: acc_rdonly = 0, acc_rdwr = 1, acc_swmr_read = 64

  interface
    integer(c_int) function h5f_start_swmr_write(file) bind(C, name='H5Fstart_swmr_write')
      import :: c_int, hid_t
      integer(hid_t), value :: file
    end function h5f_start_swmr_write
    integer(hid_t) function h5f_open(name, flags, fapl) bind(C, name='H5Fopen')
      import :: c_int, c_char, hid_t
      character(kind=c_char), intent(in) :: name(*)
      integer(c_int), value :: flags
      integer(hid_t), value :: fapl
    end function h5f_open
  end interface

contains

  !> Create PATH.partial with its datasets (no rows yet) and start writing it.
  subroutine h5_open(self, path, d, error)
    class(hdf5_writer), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(model_data), intent(in) :: d
    type(error_type), allocatable, intent(out) :: error
    self%path = path
    self%partial = path // '.partial'
    call self%create(self%partial, d, error)
  end subroutine h5_open

  !> A new file at `name`: the groups of the plan's columns, a dataset for each, the run's
  !> description, then single-writer mode and the blocks that collect rows.
  subroutine create(self, name, d, error)
    class(hdf5_writer), intent(inout) :: self
    character(len=*), intent(in) :: name
    type(model_data), intent(in) :: d
    type(error_type), allocatable, intent(out) :: error
    integer(hid_t) :: fapl
    integer :: err, k
    call start_library(error); if (allocated(error)) return
    call h5pcreate_f(H5P_FILE_ACCESS_F, fapl, err)
    if (err == 0) call h5pset_libver_bounds_f(fapl, H5F_LIBVER_LATEST_F, H5F_LIBVER_LATEST_F, err)
    if (err == 0) call h5fcreate_f(name, H5F_ACC_TRUNC_F, self%file, err, access_prp=fapl)
    call h5pclose_f(fapl, k)
    if (err /= 0) then
      call fatal_error(error, name // ': cannot write the results (HDF5 could not create the file)'); return
    end if
    self%opened = .true.
    self%groups = group_sink()
    call walk_columns(self%plan, d, self%groups)
    self%block_rows = max(min_chunk_rows, chunk_bytes/(8*maxval(self%groups%group(1:self%groups%n_groups)%n)))
    do k = 1, self%groups%n_groups
      call make_dataset(self, self%groups%group(k), err); if (err /= 0) exit
      allocate(self%groups%group(k)%block(self%groups%group(k)%n, self%block_rows))
    end do
    if (err == 0) call write_description(self, d, err)
    if (err == 0) err = int(h5f_start_swmr_write(self%file))
    if (err /= 0) call fatal_error(error, name // ': cannot write the results (HDF5 could not make its datasets)')
    allocate(self%row(row_width(self%plan, d)))
    self%rows_written = 0; self%rows_waiting = 0
  end subroutine create

  !> The HDF5 library started, its error printing off (pymr reports failures itself), and
  !> without its clean-up at exit: every file is closed by then, except after a failed
  !> write, where the clean-up would write to the failing file again (and, with HDF5 1.10's
  !> single-writer mode, crash).
  subroutine start_library(error)
    type(error_type), allocatable, intent(out) :: error
    integer :: err
    call h5dont_atexit_f(err)
    call h5open_f(err)
    if (err == 0) call h5eset_auto_f(0, err)
    if (err /= 0) call fatal_error(error, 'the HDF5 library could not start')
  end subroutine start_library

  !> The dataset of group g: rows unlimited, chunked by the writer's block, shuffled and
  !> deflated (unless compression is 0), with its columns' names, owners, quantities and units. 'time' is one column,
  !> so its dataset has one dimension.
  subroutine make_dataset(self, g, err)
    class(hdf5_writer), intent(inout) :: self
    type(column_group), intent(inout) :: g
    integer, intent(out) :: err
    integer(hid_t) :: space, dcpl
    integer(hsize_t) :: dims(2), maxdims(2), chunk(2)
    integer :: rank, e
    rank = merge(1, 2, g%name == 'time')
    dims = [int(g%n, hsize_t), 0_hsize_t]; maxdims = [int(g%n, hsize_t), H5S_UNLIMITED_F]
    chunk = [int(g%n, hsize_t), int(self%block_rows, hsize_t)]
    if (rank == 1) then
      dims(1) = 0; maxdims(1) = H5S_UNLIMITED_F; chunk(1) = chunk(2)
    end if
    call h5screate_simple_f(rank, dims(1:rank), space, err, maxdims(1:rank))
    if (err /= 0) return
    call h5pcreate_f(H5P_DATASET_CREATE_F, dcpl, err)
    if (err == 0) call h5pset_chunk_f(dcpl, rank, chunk(1:rank), err)
    if (err == 0 .and. self%compression > 0) call h5pset_shuffle_f(dcpl, err)
    if (err == 0 .and. self%compression > 0) call h5pset_deflate_f(dcpl, self%compression, err)
    if (err == 0) call h5dcreate_f(self%file, g%name, H5T_NATIVE_DOUBLE, space, g%dataset, err, dcpl)
    call h5pclose_f(dcpl, e); call h5sclose_f(space, e)
    if (err /= 0) return
    call put_texts(g%dataset, 'columns', g%names, err)
    if (err == 0) call put_texts(g%dataset, 'owners', g%owners, err)
    if (err == 0) call put_texts(g%dataset, 'quantities', g%quantities, err)
    if (err == 0) call put_texts(g%dataset, 'units', g%units, err)
  end subroutine make_dataset

  !> The file's attributes that say what the run is.
  subroutine write_description(self, d, err)
    class(hdf5_writer), intent(inout) :: self
    type(model_data), intent(in) :: d
    integer, intent(out) :: err
    call put_text(self%file, 'pymr_version', pymr_version, err)
    if (err == 0) call put_text(self%file, 'title', self%title, err)
    if (err == 0) call put_text(self%file, 'method', self%method, err)
    if (err == 0) call put_text(self%file, 'scene_fingerprint', self%fingerprint, err)
    if (err == 0) call put_text(self%file, 'resolved_scene', self%scene_text, err)
    if (err == 0) call put_text(self%file, 'integrator', '{' // self%settings // '}', err)
    if (err == 0) call put_text(self%file, 'column_order', header_line(self%plan, d), err)
    if (err == 0) call put_text(self%file, 'status', 'partial', err)
  end subroutine write_description

  !> A text attribute `name` of object `owner` (one fixed-length string).
  subroutine put_text(owner, name, text, err)
    integer(hid_t), intent(in) :: owner
    character(len=*), intent(in) :: name, text
    integer, intent(out) :: err
    integer(hid_t) :: stype, space, attr
    integer :: e
    call h5tcopy_f(H5T_FORTRAN_S1, stype, err); if (err /= 0) return
    call h5tset_size_f(stype, int(max(len(text), 1), size_t), err)
    if (err == 0) call h5screate_f(H5S_SCALAR_F, space, err)
    if (err == 0) then
      call h5acreate_f(owner, name, stype, space, attr, err)
      if (err == 0) call h5awrite_f(attr, stype, text // repeat(' ', merge(1, 0, len(text) == 0)), &
        & [1_hsize_t], err)
      if (err == 0) call h5aclose_f(attr, err)
      call h5sclose_f(space, e)
    end if
    call h5tclose_f(stype, e)
  end subroutine put_text

  !> An attribute `name` of object `owner`: the texts of `list`, as fixed-length strings
  !> padded to the longest.
  subroutine put_texts(owner, name, list, err)
    integer(hid_t), intent(in) :: owner
    character(len=*), intent(in) :: name
    type(text_list), intent(in) :: list
    integer, intent(out) :: err
    integer(hid_t) :: stype, space, attr
    character(len=:), allocatable :: texts(:)
    integer :: k, width, e
    width = 1
    do k = 1, list%n
      width = max(width, len(list%item(k)%s))
    end do
    allocate(character(len=width) :: texts(list%n))
    do k = 1, list%n
      texts(k) = list%item(k)%s // repeat(c_null_char, width - len(list%item(k)%s))
    end do
    call h5tcopy_f(H5T_FORTRAN_S1, stype, err); if (err /= 0) return
    call h5tset_size_f(stype, int(width, size_t), err)
    if (err == 0) call h5tset_strpad_f(stype, H5T_STR_NULLPAD_F, err)
    if (err == 0) call h5screate_simple_f(1, [int(list%n, hsize_t)], space, err)
    if (err == 0) then
      call h5acreate_f(owner, name, stype, space, attr, err)
      if (err == 0) call h5awrite_f(attr, stype, texts, [int(list%n, hsize_t)], err)
      if (err == 0) call h5aclose_f(attr, err)
      call h5sclose_f(space, e)
    end if
    call h5tclose_f(stype, e)
  end subroutine put_texts

  !> The row for time t, into its groups' blocks; a full block is written.
  subroutine h5_write_row(self, d, t, q, qd, extra)
    class(hdf5_writer), intent(inout) :: self
    type(model_data), intent(in) :: d
    real(dp), intent(in) :: t, q(:), qd(:), extra(:)
    integer :: k
    if (self%ios /= 0) return
    call row_values(self%plan, d, t, q, qd, extra, self%row)
    self%rows_waiting = self%rows_waiting + 1
    do k = 1, self%groups%n_groups
      associate (g => self%groups%group(k))
        g%block(:, self%rows_waiting) = self%row(g%place(1:g%n))
      end associate
    end do
    if (self%rows_waiting == self%block_rows) call self%write_blocks()
  end subroutine h5_write_row

  !> The rows waiting, appended to every dataset.
  subroutine write_blocks(self)
    class(hdf5_writer), intent(inout) :: self
    integer :: k, err
    if (self%rows_waiting == 0 .or. self%ios /= 0) return
    do k = 1, self%groups%n_groups
      call append_rows(self%groups%group(k), self%rows_written, self%rows_waiting, err)
      if (err /= 0) then
        call self%failed('append rows to ' // self%groups%group(k)%name); return
      end if
    end do
    self%rows_written = self%rows_written + self%rows_waiting
    self%rows_waiting = 0
  end subroutine write_blocks

  !> Rows first+1 .. first+m of group g's dataset from its block.
  subroutine append_rows(g, first, m, err)
    type(column_group), intent(inout) :: g
    integer, intent(in) :: first, m
    integer, intent(out) :: err
    integer(hid_t) :: file_space, memory_space
    integer(hsize_t) :: extent(2), start(2), count(2)
    integer :: rank, e
    rank = merge(1, 2, g%name == 'time')
    extent = [int(g%n, hsize_t), int(first + m, hsize_t)]
    start = [0_hsize_t, int(first, hsize_t)]
    count = [int(g%n, hsize_t), int(m, hsize_t)]
    if (rank == 1) then
      extent(1) = extent(2); start(1) = start(2); count(1) = count(2)
    end if
    call h5dset_extent_f(g%dataset, extent(1:rank), err); if (err /= 0) return
    call h5dget_space_f(g%dataset, file_space, err); if (err /= 0) return
    call h5sselect_hyperslab_f(file_space, H5S_SELECT_SET_F, start(1:rank), count(1:rank), err)
    if (err == 0) call h5screate_simple_f(rank, count(1:rank), memory_space, err)
    if (err == 0) then
      call h5dwrite_f(g%dataset, H5T_NATIVE_DOUBLE, g%block(:, 1:m), count(1:rank), err, memory_space, file_space)
      call h5sclose_f(memory_space, e)
    end if
    call h5sclose_f(file_space, e)
  end subroutine append_rows

  !> The rows so far written and flushed to the file (a checkpoint's rows are then in it).
  subroutine h5_flush_rows(self)
    class(hdf5_writer), intent(inout) :: self
    integer :: err
    if (self%ios /= 0 .or. .not. self%opened) return
    call self%write_blocks()
    if (self%ios /= 0) return
    call h5fflush_f(self%file, H5F_SCOPE_GLOBAL_F, err)
    if (err /= 0) call self%failed('flush the file')
  end subroutine h5_flush_rows

  !> Record the first failure (the run reports it with its time).
  subroutine failed(self, what)
    class(hdf5_writer), intent(inout) :: self
    character(len=*), intent(in) :: what
    if (self%ios /= 0) return
    self%ios = -1
    self%io_message = 'HDF5 could not ' // what // ' (the file system may be full, or a file-size limit reached)'
  end subroutine failed

  !> The rows waiting written, the datasets and the file closed (checked).
  subroutine close_file(self)
    class(hdf5_writer), intent(inout) :: self
    integer :: k, err
    if (.not. self%opened) return
    call self%write_blocks()
    do k = 1, self%groups%n_groups
      if (self%groups%group(k)%dataset < 0) cycle
      call h5dclose_f(self%groups%group(k)%dataset, err)
      if (err /= 0) call self%failed('close ' // self%groups%group(k)%name)
      self%groups%group(k)%dataset = -1
    end do
    call h5fclose_f(self%file, err)
    if (err /= 0) call self%failed('close the file')
    self%opened = .false.
  end subroutine close_file

  !> A failed run: its rows stay in the partial file.
  subroutine h5_close(self)
    class(hdf5_writer), intent(inout) :: self
    call close_file(self)
  end subroutine h5_close

  !> A refused run: the partial file removed.
  subroutine h5_discard(self)
    class(hdf5_writer), intent(inout) :: self
    call close_file(self)
    call remove_file(self%partial)
  end subroutine h5_discard

  !> The run ended well: the last rows, the statistics and status 'complete' written, the
  !> file closed, flushed to the disk and put in place.
  subroutine h5_finish(self, statistics, error)
    class(hdf5_writer), intent(inout) :: self
    character(len=*), intent(in) :: statistics
    type(error_type), allocatable, intent(out) :: error
    integer(hid_t) :: file
    integer :: err, e
    call close_file(self)
    if (self%ios == 0) then
      call h5fopen_f(self%partial, H5F_ACC_RDWR_F, file, err)
      if (err == 0) then
        call h5adelete_f(file, 'status', err)
        if (err == 0) call put_text(file, 'status', 'complete', err)
        if (err == 0) call put_text(file, 'statistics', statistics, err)
        call h5fclose_f(file, e)
        err = max(abs(err), abs(e))
      end if
      if (err /= 0) call self%failed('write the statistics')
    end if
    if (self%ios /= 0) then
      call fatal_error(error, self%partial // ': cannot write the results: ' // trim(self%io_message), stat_solver)
      return
    end if
    call sync_file(self%partial, error); if (allocated(error)) return
    call rename_file(self%partial, self%path, error)
  end subroutine h5_finish

  !> Restart: the first `rows` rows of the checkpointed run's file (its partial file if it
  !> was stopped, else its complete file) copied into a new file, which replaces the partial
  !> file once on disk; rows are then appended to it.
  subroutine h5_reopen(self, path, d, rows, last, error)
    class(hdf5_writer), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(model_data), intent(in) :: d
    integer, intent(in) :: rows
    real(dp), intent(in) :: last(:)
    type(error_type), allocatable, intent(out) :: error
    type(group_sink) :: kept
    character(len=:), allocatable :: source
    real(dp), allocatable :: values(:)
    integer :: k
    self%path = path
    self%partial = path // '.partial'
    source = self%partial
    if (.not. exists(source)) source = path
    if (.not. exists(source)) then
      call fatal_error(error, path // ': the results of the checkpointed run are missing (restart needs them)')
      return
    end if
    call start_library(error); if (allocated(error)) return
    call read_kept_rows(source, self%plan, d, rows, kept, error); if (allocated(error)) return
    allocate(values(row_width(self%plan, d)))
    do k = 1, kept%n_groups
      values(kept%group(k)%place(1:kept%group(k)%n)) = kept%group(k)%block(:, rows)
    end do
    call check_kept_last(source, rows, values, last, self%digits, header_line(self%plan, d), error)
    if (allocated(error)) return
    call self%create(self%partial // '.tmp', d, error); if (allocated(error)) return
    self%row = values
    call self%write_kept(kept, rows)
    call self%flush_rows()
    if (self%ios /= 0) then
      call fatal_error(error, self%partial // '.tmp: cannot write the results: ' // trim(self%io_message)); return
    end if
    call sync_file(self%partial // '.tmp', error); if (allocated(error)) return
    call rename_file(self%partial // '.tmp', self%partial, error)
  end subroutine h5_reopen

  logical function exists(path)
    character(len=*), intent(in) :: path
    inquire(file=path, exist=exists)
  end function exists

  !> The kept rows, as the blocks of the new file's groups, written.
  subroutine write_kept(self, kept, rows)
    class(hdf5_writer), intent(inout) :: self
    type(group_sink), intent(inout) :: kept
    integer, intent(in) :: rows
    integer :: k, err
    if (rows == 0) return
    do k = 1, self%groups%n_groups
      call move_alloc(kept%group(k)%block, self%groups%group(k)%block)
    end do
    self%rows_waiting = rows
    self%block_rows = rows
    call self%write_blocks()
    do k = 1, self%groups%n_groups
      deallocate(self%groups%group(k)%block)
      allocate(self%groups%group(k)%block(self%groups%group(k)%n, self%block_rows))
    end do
    err = 0
  end subroutine write_kept

  !> The first `rows` rows of every group of the plan's columns in file `source`, checked to
  !> be the columns this run writes.
  subroutine read_kept_rows(source, plan, d, rows, kept, error)
    character(len=*), intent(in) :: source
    type(output_plan), intent(in) :: plan
    type(model_data), intent(in) :: d
    integer, intent(in) :: rows
    type(group_sink), intent(out) :: kept
    type(error_type), allocatable, intent(out) :: error
    integer(hid_t) :: file
    integer :: k, err, have, width
    character(len=:), allocatable :: columns
    file = h5f_open(source // c_null_char, ior(acc_rdonly, acc_swmr_read), H5P_DEFAULT_F)
    if (file < 0) then
      call fatal_error(error, source // ': cannot read the results (not an HDF5 file, or damaged)'); return
    end if
    call walk_columns(plan, d, kept)
    columns = header_line(plan, d)
    if (get_text(file, 'column_order') /= columns) then
      call fatal_error(error, source // ': its columns are not the ones this run writes (&output quantities, or ' // &
        & 'the markers, differ from the checkpointed run''s): restart with the same ones')
    end if
    do k = 1, kept%n_groups
      if (allocated(error)) exit
      allocate(kept%group(k)%block(kept%group(k)%n, rows))
      call read_rows(file, kept%group(k), rows, have, width, err)
      if (err == 0 .and. width /= kept%group(k)%n) then
        call fatal_error(error, source // ': its dataset ' // kept%group(k)%name // ' holds ' // itoa(width) // &
          & ' columns, the run writes ' // itoa(kept%group(k)%n) // ' (the file was changed after the run): ' // &
          & 'restart from the results the run wrote'); exit
      end if
      if (err /= 0) call fatal_error(error, source // ': cannot read the results (' // kept%group(k)%name // ')')
      if (err == 0 .and. have < rows) call fatal_error(error, source // ': has ' // itoa(have) // &
        & ' result rows, the checkpoint expects ' // itoa(rows) // ': the file belongs to another run')
      if (.not. allocated(error)) call check_kept_group(source, kept, k, rows, columns, error)
      if (.not. allocated(error) .and. kept%group(k)%name == 'time') &
        & call check_kept_times(source, kept%group(k)%block(1, :), error)
    end do
    call h5fclose_f(file, err)
  end subroutine read_kept_rows

  !> The kept rows of group k hold only finite numbers (check_kept_values; `columns`: the
  !> row's column names, which g%place indexes).
  subroutine check_kept_group(source, kept, k, rows, columns, error)
    character(len=*), intent(in) :: source, columns
    type(group_sink), intent(in) :: kept
    integer, intent(in) :: k, rows
    type(error_type), allocatable, intent(out) :: error
    integer :: r, j
    associate(g => kept%group(k))
      do r = 1, rows
        do j = 1, g%n
          if (ieee_is_finite(g%block(j, r))) cycle
          call check_kept_values(source, r, g%block(j:j, r), columns, g%place(j), error); return
        end do
      end do
    end associate
  end subroutine check_kept_group

  !> The first `rows` rows of group g's dataset in `file` into g%block (`have`: the rows
  !> the dataset holds, `width` its columns; none are read unless it has g%n).
  subroutine read_rows(file, g, rows, have, width, err)
    integer(hid_t), intent(in) :: file
    type(column_group), intent(inout) :: g
    integer, intent(in) :: rows
    integer, intent(out) :: have, width, err
    integer(hid_t) :: dataset, file_space, memory_space
    integer(hsize_t) :: dims(2), maxdims(2), start(2), count(2)
    integer :: rank, e
    have = 0; width = 0
    rank = merge(1, 2, g%name == 'time')
    call h5dopen_f(file, g%name, dataset, err); if (err /= 0) return
    call h5dget_space_f(dataset, file_space, err)
    if (err == 0) call h5sget_simple_extent_dims_f(file_space, dims(1:rank), maxdims(1:rank), e)
    have = int(dims(rank))
    width = 1
    if (rank == 2) width = int(dims(1))
    if (err == 0 .and. have >= rows .and. rows > 0 .and. width == g%n) then
      start = 0; count = [int(g%n, hsize_t), int(rows, hsize_t)]
      if (rank == 1) count(1) = count(2)
      call h5sselect_hyperslab_f(file_space, H5S_SELECT_SET_F, start(1:rank), count(1:rank), err)
      if (err == 0) call h5screate_simple_f(rank, count(1:rank), memory_space, err)
      if (err == 0) then
        call h5dread_f(dataset, H5T_NATIVE_DOUBLE, g%block, count(1:rank), err, memory_space, file_space)
        call h5sclose_f(memory_space, e)
      end if
    end if
    call h5sclose_f(file_space, e)
    call h5dclose_f(dataset, e)
  end subroutine read_rows

  !> The text attribute `name` of object `owner` ('' if it cannot be read).
  function get_text(owner, name) result(text)
    integer(hid_t), intent(in) :: owner
    character(len=*), intent(in) :: name
    character(len=:), allocatable :: text
    integer(hid_t) :: attr, stype
    integer(size_t) :: width
    integer :: err, e
    text = ''
    call h5aopen_f(owner, name, attr, err); if (err /= 0) return
    call h5aget_type_f(attr, stype, err)
    if (err == 0) call h5tget_size_f(stype, width, err)
    if (err == 0) then
      text = repeat(' ', width)
      call h5aread_f(attr, stype, text, [1_hsize_t], err)
      if (err /= 0) text = ''
    end if
    call h5tclose_f(stype, e)
    call h5aclose_f(attr, e)
  end function get_text

  !> Column `name` of `group` into its group (a new one at its first column).
  subroutine group_add(self, name, group, owner, quantity, unit)
    class(group_sink), intent(inout) :: self
    character(len=*), intent(in) :: name, group, owner, quantity, unit
    type(column_group), allocatable :: grown(:)
    integer :: k
    self%n_columns = self%n_columns + 1
    if (.not. allocated(self%group)) allocate(self%group(16))
    k = 1
    do while (k <= self%n_groups)
      if (self%group(k)%name == group) exit
      k = k + 1
    end do
    if (k > self%n_groups) then
      if (k > size(self%group)) then
        allocate(grown(2*size(self%group)))
        grown(1:self%n_groups) = self%group(1:self%n_groups)
        call move_alloc(grown, self%group)
      end if
      self%n_groups = k
      self%group(k)%name = group
      allocate(self%group(k)%place(16))
    end if
    call add_column(self%group(k), self%n_columns, name, owner, quantity, unit)
  end subroutine group_add

  !> Column `place` of the row, and what it is, into group g.
  subroutine add_column(g, place, name, owner, quantity, unit)
    type(column_group), intent(inout) :: g
    integer, intent(in) :: place
    character(len=*), intent(in) :: name, owner, quantity, unit
    integer, allocatable :: grown(:)
    g%n = g%n + 1
    if (g%n > size(g%place)) then
      allocate(grown(2*size(g%place)))
      grown(1:g%n-1) = g%place(1:g%n-1)
      call move_alloc(grown, g%place)
    end if
    g%place(g%n) = place
    call g%names%add(name); call g%owners%add(owner)
    call g%quantities%add(quantity); call g%units%add(unit)
  end subroutine add_column

  subroutine list_add(self, text)
    class(text_list), intent(inout) :: self
    character(len=*), intent(in) :: text
    type(text_item), allocatable :: grown(:)
    if (.not. allocated(self%item)) allocate(self%item(16))
    if (self%n == size(self%item)) then
      allocate(grown(2*self%n))
      grown(1:self%n) = self%item(1:self%n)
      call move_alloc(grown, self%item)
    end if
    self%n = self%n + 1
    self%item(self%n)%s = text
  end subroutine list_add

end module pymr_io_results_hdf5
