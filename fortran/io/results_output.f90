!> Result files: OUT.csv (comment lines, header, one row per output time) and OUT.json
!> (run statistics), as fixed in ARCHITECTURE.md.
module pymr_io_results_output
  use pymr_kinds, only : dp
  use pymr_error, only : error_type, fatal_error
  use pymr_model_types, only : model_data, n_effects, effect_names
  use pymr_model_effects, only : impose_prescribed_state
  use pymr_model_kinematics, only : forward_kinematics, marker_motion
  use pymr_io_fast_format, only : put_real
  use pymr_io_text, only : itoa
  implicit none
  private
  public :: csv_writer, json_path, write_json, run_stats, pymr_version

  character(len=*), parameter :: pymr_version = '0.1.0'

  !> Statistics of one run, written to OUT.json.
  type :: run_stats
    real(dp) :: cpu_time_s = 0.0_dp, wall_time_s = 0.0_dp
    integer :: steps_slow = 0, steps_fast = 0, rhs_full = 0, rhs_fast = 0, rejected_steps = 0, rows = 0
    real(dp) :: h_last = 0.0_dp
    !> Multirate: the last step ratio H/h (1 single-rate).
    integer :: ratio_last = 1
  end type run_stats

  !> An open CSV result file.
  type :: csv_writer
    integer :: unit = 0
    logical :: opened = .false.
    character(len=:), allocatable :: path
    real(dp), allocatable :: row(:)
    character(len=:), allocatable :: line
    !> Significant digits per value (&output precision).
    integer :: digits = 17
  contains
    procedure :: open => csv_open
    procedure :: reopen => csv_reopen
    procedure :: write_row => csv_write_row
    procedure :: close => csv_close
  end type csv_writer

contains

  !> OUT.json beside OUT.csv (extension replaced, or appended).
  function json_path(csv) result(p)
    character(len=*), intent(in) :: csv
    character(len=:), allocatable :: p
    integer :: k
    k = index(csv, '.', back=.true.)
    if (k > index(csv, '/', back=.true.) .and. k > 1) then
      p = csv(1:k-1) // '.json'
    else
      p = csv // '.json'
    end if
  end function json_path

  !> Open the CSV file and write the comment lines and the header row.
  subroutine csv_open(self, path, d, title, method, error)
    class(csv_writer), intent(inout) :: self
    character(len=*), intent(in) :: path, title, method
    type(model_data), intent(in) :: d
    type(error_type), allocatable, intent(out) :: error
    integer :: ios, i
    character(len=256) :: msg
    character(len=:), allocatable :: m
    open(newunit=self%unit, file=path, status='replace', action='write', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot write the results: ' // trim(msg)); return
    end if
    self%path = path
    self%opened = .true.
    write(self%unit, '(a)') '# pymr ' // pymr_version // ' results'
    write(self%unit, '(a)') '# title: ' // trim(title)
    write(self%unit, '(a)') '# method: ' // trim(method)
    ! the header piece by piece (a scene may have 10^5 markers)
    write(self%unit, '(a)', advance='no') 't'
    do i = 1, d%n
      write(self%unit, '(a)', advance='no') ',' // trim(d%qname(i))
      if (i == d%n .or. d%cgrp(min(i + 1, d%n)) /= d%cgrp(i)) call add_rates(i)
    end do
    do i = 1, d%n_markers
      m = trim(d%marker_name(i))
      write(self%unit, '(a)', advance='no') ',' // m // '.x,' // m // '.y,' // m // '.z,' // m // '.vx,' // m // &
        & '.vy,' // m // '.vz'
    end do
    write(self%unit, '(a)') ''
    allocate(self%row(1 + 2*d%n + 6*d%n_markers))
    allocate(character(len=25*size(self%row)) :: self%line)
  contains
    subroutine add_rates(last)
      integer, intent(in) :: last
      integer :: j
      do j = 1, last
        if (d%cgrp(j) == d%cgrp(last)) write(self%unit, '(a)', advance='no') ',' // trim(d%qdname(j))
      end do
    end subroutine add_rates
  end subroutine csv_open

  !> Restart: keep the comment lines, the header and the first `rows` rows of the CSV file a
  !> checkpointed run wrote (dropping rows it wrote after its checkpoint), and append.
  subroutine csv_reopen(self, path, d, rows, error)
    class(csv_writer), intent(inout) :: self
    character(len=*), intent(in) :: path
    type(model_data), intent(in) :: d
    integer, intent(in) :: rows
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios, k, keep
    character(len=256) :: msg
    character(len=:), allocatable :: buf
    type :: line_t
      character(len=:), allocatable :: s
    end type line_t
    type(line_t), allocatable :: lines(:)
    logical :: exists
    keep = rows + 4
    inquire(file=path, exist=exists)
    if (.not. exists) then
      call fatal_error(error, path // ': the results of the checkpointed run are missing (restart needs them)')
      return
    end if
    allocate(character(len=25*(1 + 2*d%n + 6*d%n_markers) + 64*d%n + 1024) :: buf)
    allocate(lines(keep))
    open(newunit=u, file=path, status='old', action='read', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot read the results: ' // trim(msg)); return
    end if
    do k = 1, keep
      read(u, '(a)', iostat=ios) buf
      if (ios /= 0) exit
      lines(k)%s = trim(buf)
    end do
    close(u)
    if (k <= keep) then
      call fatal_error(error, path // ': has ' // itoa(max(k - 5, 0)) // ' result rows, the checkpoint expects ' // &
        & itoa(rows) // ': the file belongs to another run'); return
    end if
    open(newunit=self%unit, file=path, status='replace', action='write', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot write the results: ' // trim(msg)); return
    end if
    do k = 1, keep
      write(self%unit, '(a)') lines(k)%s
    end do
    self%path = path
    self%opened = .true.
    allocate(self%row(1 + 2*d%n + 6*d%n_markers))
    allocate(character(len=25*size(self%row)) :: self%line)
  end subroutine csv_reopen

  !> Write the row for time t and state (q, qd); runs kinematics for the markers.
  subroutine csv_write_row(self, d, t, q, qd)
    class(csv_writer), intent(inout) :: self
    type(model_data), intent(inout) :: d
    real(dp), intent(in) :: t, q(:), qd(:)
    if (d%n_prescribed > 0) then
      ! prescribed coordinates are written (and move the markers) exactly as their functions
      call impose_prescribed_state(d, t, q, qd)
      call write_values(self, d, t, d%qx, d%qdx)
    else
      call write_values(self, d, t, q, qd)
    end if
  end subroutine csv_write_row

  subroutine write_values(self, d, t, q, qd)
    class(csv_writer), intent(inout) :: self
    type(model_data), intent(inout) :: d
    real(dp), intent(in) :: t, q(:), qd(:)
    integer :: i, k, b0, pos
    real(dp) :: r(3), v(3)
    self%row(1) = t
    k = 1; b0 = 1
    do i = 1, d%n
      k = k + 1; self%row(k) = q(i)
      if (i == d%n .or. d%cgrp(min(i + 1, d%n)) /= d%cgrp(i)) then
        self%row(k+1:k+i-b0+1) = qd(b0:i); k = k + i - b0 + 1; b0 = i + 1
      end if
    end do
    if (d%n_markers > 0) call forward_kinematics(d, q, qd)
    do i = 1, d%n_markers
      call marker_motion(d, i, q, qd, r, v)
      self%row(k+1:k+3) = r; self%row(k+4:k+6) = v; k = k + 6
    end do
    pos = 1
    do i = 1, size(self%row)
      if (i > 1) then
        self%line(pos:pos) = ','; pos = pos + 1
      end if
      call put_real(self%row(i), self%line, pos, self%digits)
    end do
    write(self%unit, '(a)') self%line(1:pos-1)
  end subroutine write_values

  subroutine csv_close(self)
    class(csv_writer), intent(inout) :: self
    if (self%opened) close(self%unit)
    self%opened = .false.
  end subroutine csv_close

  !> Write the run statistics and settings as JSON.
  subroutine write_json(path, scene_file, title, fingerprint, settings, d, st, error)
    !> fingerprint: 'sha256:...' of the resolved scene (pymr scene prints it).
    character(len=*), intent(in) :: path, scene_file, title, fingerprint
    !> Integrator settings, already as JSON members ("\"method\": \"single\", ...").
    character(len=*), intent(in) :: settings
    type(model_data), intent(in) :: d
    type(run_stats), intent(in) :: st
    type(error_type), allocatable, intent(out) :: error
    integer :: u, ios, i
    real(dp) :: cpu
    character(len=256) :: msg
    logical :: first
    open(newunit=u, file=path, status='replace', action='write', iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call fatal_error(error, path // ': cannot write the statistics: ' // trim(msg)); return
    end if
    write(u, '(a)') '{'
    write(u, '(a)') '  "version": "' // pymr_version // '",'
    write(u, '(a)') '  "scene": "' // escape(scene_file) // '",'
    write(u, '(a)') '  "title": "' // escape(trim(title)) // '",'
    write(u, '(a)') '  "scene_fingerprint": "' // fingerprint // '",'
    write(u, '(a,g0.10,a)') '  "cpu_time_s": ', st%cpu_time_s, ','
    write(u, '(a,g0.10,a)') '  "wall_time_s": ', st%wall_time_s, ','
    write(u, '(a,i0,a)') '  "steps_slow": ', st%steps_slow, ','
    write(u, '(a,i0,a)') '  "steps_fast": ', st%steps_fast, ','
    write(u, '(a,i0,a)') '  "rhs_full": ', st%rhs_full, ','
    write(u, '(a,i0,a)') '  "rhs_fast": ', st%rhs_fast, ','
    write(u, '(a,i0,a)') '  "rejected_steps": ', st%rejected_steps, ','
    write(u, '(a,g0.10,a)') '  "h_last": ', st%h_last, ','
    write(u, '(a,i0,a)') '  "step_ratio_last": ', st%ratio_last, ','
    write(u, '(a,i0,a)') '  "rows": ', st%rows, ','
    write(u, '(a,i0,a)') '  "n_coordinates": ', d%n, ','
    write(u, '(a)', advance='no') '  "effects": {'
    first = .true.
    do i = 1, n_effects
      if (.not. d%effect_on(i)) cycle
      if (.not. first) write(u, '(a)', advance='no') ', '
      cpu = 0.0_dp
      if (d%effect_timed(i) > 0) cpu = d%effect_cpu(i)*real(d%effect_evals(i), dp)/real(d%effect_timed(i), dp)
      write(u, '(a,i0,a,es12.5,a)', advance='no') '"' // trim(effect_names(i)) // '": {"evaluations": ', &
        & d%effect_evals(i), ', "cpu_time_s": ', cpu, '}'
      first = .false.
    end do
    write(u, '(a)') '},'
    write(u, '(a)') '  "integrator": {' // settings // '}'
    write(u, '(a)') '}'
    close(u)
  end subroutine write_json

  !> A JSON string's content: backslashes and quotes escaped, control characters as \uXXXX.
  function escape(s) result(r)
    character(len=*), intent(in) :: s
    character(len=:), allocatable :: r
    character(len=6) :: u
    integer :: i
    r = ''
    do i = 1, len(s)
      select case (s(i:i))
      case ('\', '"')
        r = r // '\' // s(i:i)
      case (achar(0):achar(31), achar(127))
        write(u, '(a,z4.4)') '\u', iachar(s(i:i))
        r = r // u
      case default
        r = r // s(i:i)
      end select
    end do
  end function escape
end module pymr_io_results_output
