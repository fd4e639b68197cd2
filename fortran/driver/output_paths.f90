!> Where a run writes: the results file (the command line's, &output file, or the scene's
!> name), its statistics and checkpoint files beside it, and the checks that none of them
!> replaces what the run reads or what is no regular file.
module pymr_driver_output_paths
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_model_scene, only : scene_t
  use pymr_io_results_output, only : json_path
  use pymr_env_text_file, only : absolute_path, scene_relative, not_regular, missing_folder, same_file
  implicit none
  private
  public :: default_output, check_output_path, scene_input, checkpoint_default

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

  !> The output must not overwrite what the run reads (the scene, its modal and table files)
  !> nor collide with its own statistics file.
  subroutine check_output_path(sc, path, error)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    type(error_type), allocatable, intent(out) :: error
    character(len=:), allocatable :: what
    if (wrong_extension(sc, path, error)) return
    if (absolute_path(json_path(path)) == absolute_path(path)) then
      call fatal_error(error, sc%file // ': output ' // path // ': the results and their statistics would both ' // &
        & 'be ' // json_path(path) // ' (give a .csv file)'); return
    end if
    ! the run writes each file whole beside it and renames it over the old one
    if (replaces(path, 'output ' // path, 'another results file')) return
    if (replaces(json_path(path), 'output ' // path // ': its statistics ' // json_path(path), &
      & 'another results file')) return
    if (sc%output%checkpoint_dt > 0.0_dp) then
      if (len_trim(sc%output%checkpoint_file) > 0) then
        if (replaces(trim(sc%output%checkpoint_file), sc%output%origin%where('checkpoint_file'), &
          & 'another checkpoint file')) return
        if (no_folder(trim(sc%output%checkpoint_file), sc%output%origin%where('checkpoint_file'))) return
      else
        if (replaces(checkpoint_default(path), 'output ' // path // ': its checkpoint ' // checkpoint_default(path), &
          & 'another results file, or a checkpoint_file in &output')) return
      end if
    end if
    what = scene_input(sc, path)
    if (len(what) > 0) then
      call fatal_error(error, sc%file // ': output ' // path // ': would overwrite ' // what // &
        & '; choose another results file'); return
    end if
    what = scene_input(sc, json_path(path))
    if (len(what) > 0) call fatal_error(error, sc%file // ': output ' // path // ': its statistics ' // &
      & json_path(path) // ' would overwrite ' // what // '; choose another results file')
  contains
    !> Is `file` there and no regular file, that the run's file would replace? `label` names
    !> it in the message (after the scene's name unless it is an item's place), `advice` what to choose.
    logical function replaces(file, label, advice)
      character(len=*), intent(in) :: file, label, advice
      replaces = len(not_regular(file)) > 0
      if (.not. replaces) return
      if (index(label, sc%file) == 1) then
        call fatal_error(error, label // ': ' // not_regular(file) // '; choose ' // advice)
      else
        call fatal_error(error, sc%file // ': ' // label // ': ' // not_regular(file) // '; choose ' // advice)
      end if
    end function replaces

    !> Is the folder that `file` would be written in missing? Found before the run starts.
    logical function no_folder(file, label)
      character(len=*), intent(in) :: file, label
      no_folder = len(missing_folder(file)) > 0
      if (no_folder) call fatal_error(error, label // ": the folder '" // missing_folder(file) // &
        & "' does not exist (make it, or choose a checkpoint_file in a folder that does)")
    end function no_folder
  end subroutine check_output_path

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

  !> What of the scene's input `path` is: 'the scene (FILE)', 'a modal file of the scene
  !> (FILE)', 'a table file of the scene (FILE)', or '' when the run reads no such file. An
  !> output written there would destroy the input of the next run.
  function scene_input(sc, path) result(what)
    type(scene_t), intent(in) :: sc
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: what
    integer :: i
    what = ''
    if (is(sc%file, 'the scene')) return
    do i = 1, size(sc%bodies)
      if (len_trim(sc%bodies(i)%modal_file) == 0) cycle
      if (is(scene_relative(sc%file, trim(sc%bodies(i)%modal_file)), 'a modal file of the scene')) return
    end do
    do i = 1, size(sc%drives)
      if (len_trim(sc%drives(i)%file) == 0) cycle
      if (is(scene_relative(sc%file, trim(sc%drives(i)%file)), 'a table file of the scene')) return
    end do
    do i = 1, size(sc%motions)
      if (len_trim(sc%motions(i)%file) == 0) cycle
      if (is(scene_relative(sc%file, trim(sc%motions(i)%file)), 'a table file of the scene')) return
    end do
  contains
    logical function is(file, label)
      character(len=*), intent(in) :: file, label
      is = same_file(file, path)
      if (is) what = label // ' (' // file // ')'
    end function is
  end function scene_input

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
