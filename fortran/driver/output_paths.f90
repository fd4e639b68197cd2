!> Where a run writes: the results file (the command line's, &output file, or the scene's
!> name), its statistics and checkpoint files beside it, and the checks that none of them
!> replaces what the run reads or what is no regular file.
module pymr_driver_output_paths
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_model_scene, only : scene_t, group_names, group_count, describe_group, item_applies, group_origin
  use pymr_env_item_table, only : item_table, origin_t
  use pymr_io_results_output, only : json_path
  use pymr_env_text_file, only : absolute_path, scene_relative, not_replaceable, missing_folder, same_file, read_text_file, &
    & unwritable_folder, name_too_long
  use pymr_io_sha256, only : sha256_hex
  implicit none
  private
  public :: default_output, check_output_path, scene_input, checkpoint_default, inputs_digest, scene_files, &
    & list_inputs
  !> Longest path of a file the run writes.
  integer, parameter :: path_len = 4096

  !> The files a scene reads and what each is (list_inputs), listed once for the checks
  !> and the checkpoint's digest.
  type :: scene_files
    character(len=path_len), allocatable :: files(:), labels(:)
  end type scene_files

contains

  !> Output path: the command line's, else &output file, else the scene's name with .csv
  !> (.h5 for &output format 'hdf5').
  function default_output(sc, out) result(path)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: out
    character(len=:), allocatable :: path
    integer :: k, s
    if (len_trim(out) > 0) then
      path = trim(out)
    else if (len_trim(sc%output%file) > 0) then
      path = trim(sc%output%file)
    else
      s = index(sc%file, '/', back=.true.)
      k = index(sc%file, '.', back=.true.)
      if (k <= s) k = len(sc%file) + 1
      path = sc%file(s+1:k-1) // merge('.h5 ', '.csv', sc%output%format == 'hdf5')
      path = trim(path)
    end if
  end function default_output

  !> The output must not overwrite what the run reads (the scene, its modal and table files),
  !> nor collide with its own statistics or checkpoint, nor be written where no folder is.
  subroutine check_output_path(sc, path, inputs, error)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    !> The scene's inputs (list_inputs).
    type(scene_files), intent(in) :: inputs
    type(error_type), allocatable, intent(out) :: error
    if (standard_output(sc, path, error)) return
    if (wrong_extension(sc, path, error)) return
    if (absolute_path(json_path(path)) == absolute_path(path)) then
      call fatal_error(error, sc%file // ': output ' // path // ': the results and their statistics would both ' // &
        & 'be ' // json_path(path) // ' (give a .csv file)'); return
    end if
    ! the run writes each file whole beside it and renames it over the old one
    if (replaces(sc, path, 'output ' // path, 'another results file', error)) return
    if (len_trim(sc%output%file) > 0 .and. path == trim(sc%output%file)) then
      if (no_folder(path, sc%output%origin%where('file'), 'a file', error)) return
      if (cannot_make(results_files(path), sc%output%origin%where('file'), 'another file', error)) return
    else
      if (no_folder(path, sc%file // ': output ' // path, 'an output', error)) return
      if (cannot_make(results_files(path), sc%file // ': output ' // path, 'another output', error)) return
    end if
    if (replaces(sc, json_path(path), 'output ' // path // ': its statistics ' // json_path(path), &
      & 'another results file', error)) return
    if (shares_statistics(sc, path, error)) return
    call check_checkpoint_path(sc, path, inputs, error); if (allocated(error)) return
    call check_inputs_kept(sc, path, inputs, error)
  end subroutine check_output_path

  !> OUT.csv and OUT.h5 (.hdf5) keep their statistics in the same OUT.json: a run to one of
  !> them while the other is there with its statistics would replace those, and the other,
  !> intact, would no longer load. Refused, naming both.
  logical function shares_statistics(sc, path, error)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    type(error_type), allocatable, intent(inout) :: error
    character(len=*), parameter :: suffixes(3) = [character(len=5) :: '.csv', '.h5', '.hdf5']
    character(len=:), allocatable :: json, stem, other
    logical :: there
    integer :: i
    shares_statistics = .false.
    json = json_path(path)
    inquire(file=json, exist=there)
    if (.not. there) return
    stem = json(1:len(json) - len('.json'))
    do i = 1, size(suffixes)
      other = stem // trim(suffixes(i))
      if (absolute_path(other) == absolute_path(path)) cycle
      inquire(file=other, exist=there)
      if (.not. there) cycle
      call fatal_error(error, sc%file // ': output ' // path // ': its statistics ' // json // ' are those of ' // &
        & other // ', which would no longer load: give another name, or remove ' // other)
      shares_statistics = .true.; return
    end do
  end function shares_statistics

  !> The checkpoint file (&output checkpoint_file, else beside the results) of a run that
  !> writes checkpoints: a regular file or none, in a folder, over no input (`inputs`) nor
  !> the run's files.
  subroutine check_checkpoint_path(sc, path, inputs, error)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    type(scene_files), intent(in) :: inputs
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: file, label
    character(len=path_len) :: staged(2)
    if (sc%output%checkpoint_dt <= 0.0_dp) return
    if (len_trim(sc%output%checkpoint_file) == 0) then
      if (replaces(sc, checkpoint_default(path), 'output ' // path // ': its checkpoint ' // checkpoint_default(path), &
        & 'another results file, or a checkpoint_file in &output', error)) return
      if (replaces(sc, checkpoint_default(path) // '.tmp', 'output ' // path // ': the run''s file ' // &
        & checkpoint_default(path) // '.tmp', 'another results file, or a checkpoint_file in &output', error)) return
      ! -o run.ckpt: the checkpoint beside the results is the results file itself
      if (collides(path, checkpoint_default(path), sc%file // ': output ' // path // ': its checkpoint ' // &
        & checkpoint_default(path), inputs, error, 'another results file, or a checkpoint_file in &output')) return
      return
    end if
    file = trim(sc%output%checkpoint_file); label = sc%output%origin%where('checkpoint_file')
    if (replaces(sc, file, label, 'another checkpoint file', error)) return
    ! a directory where it is staged failed at the first checkpoint (exit 2)
    if (replaces(sc, file // '.tmp', label // ': the run''s file ' // file // '.tmp', 'another checkpoint file', &
      & error)) return
    if (no_folder(file, label, 'a checkpoint_file', error)) return
    staged(1) = file; staged(2) = file // '.tmp'
    if (cannot_make(staged, label, 'another checkpoint_file', error)) return
    if (collides(path, file, label, inputs, error, 'another checkpoint file')) return
  end subroutine check_checkpoint_path

  !> Neither the results nor any file the run writes through (results_files, and the default
  !> checkpoint's) may be a file the scene reads (`inputs`).
  subroutine check_inputs_kept(sc, path, inputs, error)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    type(scene_files), intent(in) :: inputs
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: what
    character(len=path_len), allocatable :: files(:)
    integer :: k
    what = input_at(inputs, path)
    if (len(what) > 0) then
      call fatal_error(error, sc%file // ': output ' // path // ': would overwrite ' // what // &
        & '; choose another results file'); return
    end if
    files = results_files(path)
    if (sc%output%checkpoint_dt > 0.0_dp .and. len_trim(sc%output%checkpoint_file) == 0) &
      & files = [character(len=path_len) :: files, checkpoint_default(path), checkpoint_default(path) // '.tmp']
    do k = 2, size(files)
      what = input_at(inputs, trim(files(k)))
      if (len(what) == 0) cycle
      call fatal_error(error, sc%file // ': output ' // path // ': the run''s file ' // trim(files(k)) // &
        & ' would overwrite ' // what // '; choose another results file'); return
    end do
  end subroutine check_inputs_kept

  !> Is `file` there and no regular file (or a link), that the run's file would replace? `label` names
  !> it in the message (after the scene's name unless it is an item's place), `advice` what to choose.
  logical function replaces(sc, file, label, advice, error)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: file, label, advice
    type(error_type), allocatable, intent(inout) :: error
    replaces = len(not_replaceable(file)) > 0
    if (.not. replaces) return
    if (index(label, sc%file) == 1) then
      call fatal_error(error, label // ': ' // not_replaceable(file) // '; choose ' // advice)
    else
      call fatal_error(error, sc%file // ': ' // label // ': ' // not_replaceable(file) // '; choose ' // advice)
    end if
  end function replaces

  !> Would the checkpoint `file` (or its staging file) replace what the run reads (`inputs`),
  !> or a file the run to `path` writes? `label` is the item's place.
  logical function collides(path, file, label, inputs, error, advice)
    character(len=*), intent(in) :: path, file, label
    type(scene_files), intent(in) :: inputs
    type(error_type), allocatable, intent(inout) :: error
    !> What to choose instead ('another checkpoint file').
    character(len=*), intent(in) :: advice
    character(len=:), allocatable :: what
    character(len=path_len), allocatable :: files(:)
    character(len=path_len) :: mine(2)
    integer :: i, j
    what = input_at(inputs, file)
    if (len(what) == 0) what = input_at(inputs, file // '.tmp')
    files = results_files(path)
    mine = [character(len=path_len) :: file, file // '.tmp']
    do i = 1, size(files)
      do j = 1, 2
        if (len(what) > 0 .or. .not. same_file(trim(mine(j)), trim(files(i)))) cycle
        select case (i)
        case (1); what = 'the results (' // trim(files(i)) // ')'
        case (2); what = 'their statistics (' // trim(files(i)) // ')'
        case default; what = 'the run''s file ' // trim(files(i))
        end select
      end do
    end do
    collides = len(what) > 0
    if (collides) call fatal_error(error, label // ': would overwrite ' // what // '; choose ' // advice)
  end function collides

  !> Is the folder that `file` would be written in missing? Found before the run starts;
  !> `choice` names what to choose instead ('a checkpoint_file').
  logical function no_folder(file, label, choice, error)
    character(len=*), intent(in) :: file, label, choice
    type(error_type), allocatable, intent(inout) :: error
    logical :: there
    no_folder = len(missing_folder(file)) > 0
    if (.not. no_folder) return
    inquire(file=missing_folder(file), exist=there)
    if (there) then
      call fatal_error(error, label // ": '" // missing_folder(file) // "' is not a folder (choose " // choice // &
        & ' in a folder)')
    else
      call fatal_error(error, label // ": the folder '" // missing_folder(file) // "' does not exist (make it, " // &
        & 'or choose ' // choice // ' in a folder that does)')
    end if
  end function no_folder

  !> Can the run make `files` (a file, then the files it writes it through) in their
  !> folder, which is there? Found before the run starts: a checkpoint folder without write
  !> permission failed at the first checkpoint (exit 2), and a results name longer than the
  !> file system takes was blamed on its folder. `label` is the place of the item, `choice`
  !> what to choose instead.
  logical function cannot_make(files, label, choice, error)
    character(len=*), intent(in) :: files(:), label, choice
    type(error_type), allocatable, intent(inout) :: error
    character(len=:), allocatable :: why
    integer :: k
    cannot_make = .true.
    why = unwritable_folder(trim(files(1)))
    if (len(why) > 0) then
      call fatal_error(error, label // ': ' // why // '; choose ' // choice // ' or a folder it can write'); return
    end if
    do k = 1, size(files)
      why = name_too_long(trim(files(k)))
      if (len(why) == 0) cycle
      if (k > 1) why = 'the run''s file ' // trim(files(k)) // ': ' // why
      call fatal_error(error, label // ': ' // why // '; choose a shorter name'); return
    end do
    cannot_make = .false.
  end function cannot_make

  !> The files a run to `path` writes: the results, their statistics, and the files it
  !> writes them through (the partial results and statistics, their staging files, the lock).
  function results_files(path) result(files)
    character(len=*), intent(in) :: path
    character(len=path_len), allocatable :: files(:)
    files = [character(len=path_len) :: path, json_path(path), path // '.partial', path // '.partial.tmp', &
      & path // '.tmp', path // '.lock', json_path(path) // '.tmp', json_path(path) // '.partial']
  end function results_files

  !> Is `path` '-', standard output in most tools? The run writes its results to a file
  !> (staged and renamed, with its statistics beside it), so '-' would be a file named '-'.
  logical function standard_output(sc, path, error)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    type(error_type), allocatable, intent(inout) :: error
    standard_output = path == '-'
    if (.not. standard_output) return
    if (len_trim(sc%output%file) > 0 .and. path == trim(sc%output%file)) then
      call fatal_error(error, sc%output%origin%where('file') // ": '-': the results go to a file (with their " // &
        & 'statistics beside it), not to standard output; name a file')
    else
      call fatal_error(error, sc%file // ": output '-': the results go to a file (with their statistics " // &
        & 'beside it), not to standard output; name a file')
    end if
  end function standard_output

  !> Does the results file's extension contradict &output format (a .h5 or .hdf5 file is
  !> HDF5, any other text)? Then the error says what to change.
  logical function wrong_extension(sc, path, error)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    type(error_type), allocatable, intent(inout) :: error
    logical :: h5
    integer :: k
    k = index(path, '.', back=.true.)
    h5 = .false.
    if (k > index(path, '/', back=.true.)) h5 = path(k:) == '.h5' .or. path(k:) == '.hdf5'
    wrong_extension = h5 .neqv. sc%output%format == 'hdf5'
    if (.not. wrong_extension) return
    if (h5) then
      call fatal_error(error, sc%file // ': output ' // path // ': an HDF5 file, but &output format is ''' // &
        & trim(sc%output%format) // ''' (set format = ''hdf5'', or give a .csv file)')
    else
      call fatal_error(error, sc%output%origin%where('format') // ': ''hdf5'' writes a .h5 or .hdf5 file, not ' // &
        & path // ' (give a .h5 file, or format = ''csv'')')
    end if
  end function wrong_extension

  !> What of the scene's input `path` is: 'the scene (FILE)', or the file item that names it,
  !> as "an input of the scene, &load 'shot' file (FILE)" (list_inputs), or '' when the run
  !> reads no such file. An output written there would destroy the input of the next run.
  function scene_input(sc, path) result(what)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: what
    what = input_at(list_inputs(sc), path)
  end function scene_input

  !> The label of the input among `inputs` that `path` is ('' if none).
  function input_at(inputs, path) result(what)
    type(scene_files), intent(in) :: inputs
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: what
    integer :: k
    what = ''
    do k = 1, size(inputs%files)
      if (.not. same_file(trim(inputs%files(k)), path)) cycle
      what = trim(inputs%labels(k)); return
    end do
  end function input_at

  !> The sha256 of each file the scene reads besides itself (its modal and table files, from
  !> list_inputs), a line each in the scene's order, for the fingerprint of the model a
  !> checkpoint belongs to: the model is built from their contents, which a restart must
  !> find unchanged.
  function inputs_digest(inputs, error) result(s)
    type(scene_files), intent(in) :: inputs
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: s, text
    integer :: i
    s = ''
    do i = 2, size(inputs%files)
      call read_text_file(trim(inputs%files(i)), text, error); if (allocated(error)) return
      s = s // 'file ' // sha256_hex(text) // new_line('a')
    end do
  end function inputs_digest

  !> Every file the scene reads, with what it is: the scene, and each item its tables mark as
  !> a file of the scene (modal files, the tables of drives, motions, loads, forces, controls
  !> and moving loads) as "an input of the scene, &load 'shot' file (FILE)".
  function list_inputs(sc) result(inputs)
    type(scene_t), intent(in) :: sc
    type(scene_files) :: inputs
    character(len=:), allocatable :: name, file
    type(scene_t), target :: copy
    type(item_table) :: t
    type(origin_t), pointer :: o
    integer :: i, j, k, m
    inputs%files = [character(len=path_len) :: sc%file]
    inputs%labels = [character(len=path_len) :: 'the scene (' // sc%file // ')']
    copy = sc
    i = 1
    do while (i <= len(group_names))
      j = index(group_names(i:) // ' ', ' ') + i - 2
      name = group_names(i:j); i = j + 2
      if (group_count(copy, name) == 0) cycle
      ! a group whose table has no file item (markers, joints, ...) reads no file
      call describe_group(copy, name, 1, t)
      if (.not. any([(t%items(m)%scene_file, m = 1, t%n)])) cycle
      do k = 1, group_count(copy, name)
        call describe_group(copy, name, k, t)
        do m = 1, t%n
          if (.not. t%items(m)%scene_file) cycle      ! only a file item holds a string to look at
          if (len_trim(t%items(m)%s) == 0) cycle
          if (.not. item_applies(copy, name, k, t%items(m)%name)) cycle
          file = scene_relative(sc%file, trim(t%items(m)%s))
          o => group_origin(copy, name, k)
          inputs%files = [character(len=path_len) :: inputs%files, file]
          inputs%labels = [character(len=path_len) :: inputs%labels, 'an input of the scene, ' // o%label // ' ' // &
            & trim(t%items(m)%name) // ' (' // file // ')']
        end do
      end do
    end do
  end function list_inputs

  !> The checkpoint file beside the CSV: extension replaced by .ckpt (or appended).
  function checkpoint_default(csv) result(p)
    character(len=*), intent(in) :: csv
    character(len=:), allocatable :: p
    integer :: k
    k = index(csv, '.', back=.true.)
    if (k > index(csv, '/', back=.true.) .and. k > 1) then
      p = csv(1:k-1) // '.ckpt'
    else
      p = csv // '.ckpt'
    end if
  end function checkpoint_default
end module pymr_driver_output_paths
