!> mrsim: run a pymr scene from a namelist file.
!>
!>   mrsim SCENE.nml [-o OUT.csv] [--set GROUP.ITEM=VALUE ...] [--restart CKPT] [--progress] [--quiet]
!>
!> Exit status 0 on success; otherwise one line on stderr,
!> "mrsim: error: <message>", and status 1 (bad input) or 2 (failed run).
program mrsim
  use, intrinsic :: iso_fortran_env, only : error_unit, output_unit
  use, intrinsic :: iso_c_binding, only : c_int, c_funptr, c_intptr_t
  use pymr_env_error, only : error_type
  use pymr_env_text, only : printable
  use pymr_env_text_file, only : write_standard_output
  use pymr_driver_run, only : run_scene
  use pymr_io_results_output, only : pymr_version
  implicit none
  interface
    function c_signal(sig, handler) bind(c, name='signal') result(old)
      import :: c_int, c_funptr
      integer(c_int), value :: sig
      type(c_funptr), value :: handler
      type(c_funptr) :: old
    end function c_signal
  end interface
  !> SIGXFSZ (Linux): a write past the file-size limit (ulimit -f) then fails with EFBIG,
  !> which the run reports as a failed write (exit 2), instead of a signal that the
  !> compiler's runtime turns into a backtrace. SIG_IGN is the handler value 1.
  integer(c_int), parameter :: sigxfsz = 25
  type(c_funptr) :: previous
  character(len=:), allocatable :: scene, out, overrides, summary, restart, written
  type(error_type), allocatable :: error
  logical :: quiet, progress

  previous = c_signal(sigxfsz, transfer(1_c_intptr_t, previous))
  call read_arguments()
  if (len(scene) == 0) call usage_error('no scene file (usage: mrsim SCENE.nml [-o OUT.csv] [--set G.I=V ...])')

  call run_scene(scene, overrides, out, summary, error, written, restart=restart, progress_lines=progress)
  if (allocated(error)) then
    call print_error_lines(printable(error%message))
    if (error%stat == 1) stop 1, quiet=.true.
    stop 2, quiet=.true.
  end if
  if (.not. quiet) call print_summary(summary)

contains

  !> The summary on the standard output, checked: one that cannot take it (a full disk,
  !> `> /dev/full`, a closed output) is an error (exit 1, as `pymr run`), not a success with
  !> the summary lost. The results are complete on the disk by then.
  subroutine print_summary(text)
    character(len=*), intent(in) :: text
    type(error_type), allocatable :: error
    call write_standard_output(text, error)
    if (.not. allocated(error)) return
    call print_error_lines(error%message // ': the summary is lost; the results are complete')
    stop 1, quiet=.true.
  end subroutine print_summary

  !> The command line: the scene, -o, --set, --restart, --progress, --quiet (--version and
  !> --help answer and stop; a bad argument stops with status 1).
  subroutine read_arguments()
    integer :: i, nargs
    character(len=:), allocatable :: arg
    scene = ''; out = ''; overrides = ''; restart = ''; quiet = .false.; progress = .false.
    nargs = command_argument_count()
    i = 1
    do while (i <= nargs)
      arg = get_arg(i)
      select case (arg)
      case ('--version')
        write(output_unit, '(a)') 'mrsim (pymr) ' // pymr_version
        stop
      case ('-h', '--help')
        write(output_unit, '(a)') 'usage: mrsim SCENE.nml [-o OUT.csv] [--set GROUP.ITEM=VALUE ...] [--restart CKPT] ' &
          & // '[--progress] [--quiet] | --version'
        stop
      case ('-o', '--output')
        if (len(out) > 0) call usage_error(arg // ': the results file is given twice (' // out // ' before)')
        out = option_value(i, nargs, arg, 'a file name')
        if (len(out) == 0) call usage_error(arg // ' needs a file name (got an empty one)')
      case ('--set')
        arg = option_value(i, nargs, arg, 'GROUP.ITEM=VALUE')
        if (len_trim(arg) == 0) call usage_error('--set needs GROUP.ITEM=VALUE (got an empty one)')
        ! the kernel reads one override a line: a line break would make two of one
        if (scan(arg, achar(10) // achar(13)) > 0) call usage_error('--set ' // escaped_breaks(arg) // &
          & ': a line break in an override (one GROUP.ITEM=VALUE, on one line)')
        overrides = overrides // arg // achar(10)
      case ('--restart')
        if (len(restart) > 0) call usage_error(arg // ': the checkpoint is given twice (' // restart // ' before)')
        restart = option_value(i, nargs, arg, 'a checkpoint file')
        ! an empty name (an unset shell variable) would run from the start instead
        if (len(restart) == 0) call usage_error('--restart needs a checkpoint file (got an empty name)')
      case ('--progress')
        progress = .true.
      case ('-q', '--quiet')
        quiet = .true.
      case default
        if (arg(1:1) == '-') call usage_error('unknown option ' // arg)
        if (len(scene) > 0) call usage_error('one scene file at a time (got ' // scene // ' and ' // arg // ')')
        scene = arg
      end select
      i = i + 1
    end do
  end subroutine read_arguments

  !> The value of the option at argument i (the next argument, i advanced to it); none, or
  !> one of mrsim's own options in its place (the value left out: `-o --quiet` would write
  !> the results to a file named --quiet), stops with status 1 saying the option needs `what`.
  function option_value(i, nargs, option, what) result(v)
    integer, intent(inout) :: i
    integer, intent(in) :: nargs
    character(len=*), intent(in) :: option, what
    character(len=:), allocatable :: v
    character(len=*), parameter :: options(10) = [character(len=9) :: '-o', '--output', '--set', '--restart', &
      & '--progress', '-q', '--quiet', '--version', '-h', '--help']
    if (i == nargs) call usage_error(option // ' needs ' // what)
    i = i + 1; v = get_arg(i)
    if (len(v) > 0 .and. len(v) <= len(options)) then
      if (any(options == v)) call usage_error(option // ' needs ' // what // ' (got the option ' // v // ')')
    end if
  end function option_value

  function get_arg(k) result(a)
    integer, intent(in) :: k
    character(len=:), allocatable :: a
    integer :: l
    call get_command_argument(k, length=l)
    allocate(character(len=l) :: a)
    call get_command_argument(k, a)
  end function get_arg

  !> Each line of a message as 'mrsim: error: LINE' (a scene check reports up to ten).
  subroutine print_error_lines(msg)
    character(len=*), intent(in) :: msg
    integer :: i0, i
    i0 = 1
    do i = 1, len(msg) + 1
      if (i <= len(msg)) then
        if (msg(i:i) /= new_line('a')) cycle
      end if
      write(error_unit, '(a)') 'mrsim: error: ' // msg(i0:i-1)
      i0 = i + 1
    end do
  end subroutine print_error_lines

  !> `text` with its line breaks written as \n and \r, to show on one line.
  function escaped_breaks(text) result(s)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: s
    integer :: i
    s = ''
    do i = 1, len(text)
      select case (iachar(text(i:i)))
      case (10); s = s // '\n'
      case (13); s = s // '\r'
      case default; s = s // text(i:i)
      end select
    end do
  end function escaped_breaks

  subroutine usage_error(msg)
    character(len=*), intent(in) :: msg
    write(error_unit, '(a)') 'mrsim: error: ' // printable(msg)
    stop 1, quiet=.true.
  end subroutine usage_error
end program mrsim
