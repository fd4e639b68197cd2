!> Flat binding layer for f2py: plain external subroutines with explicit-shape
!> `double precision` arrays and scalars only. Each call reports `stat` (0 ok,
!> 1 bad input, 2 failed run), a one-line `message` and the error's structured fields in
!> `detail` (pymr_bind_support%report); Python raises on stat /= 0.

!> Run a scene to result files (see pymr_driver_run%run_scene); `path` returns the CSV written.
!> A non-empty `restart` continues from that checkpoint file.
subroutine pymr_run_scene(scene, overrides, out, restart, stat, message, detail, summary, path)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_driver_run, only : run_scene
  implicit none
  character(len=*), intent(in) :: scene, overrides, out, restart
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  character(len=4096), intent(out) :: summary
  character(len=1024), intent(out) :: path
  !f2py threadsafe
  type(error_type), allocatable :: error
  character(len=:), allocatable :: text, written
  call run_scene(scene, overrides, out, text, error, written, restart)
  call report(error, stat, message, detail)
  summary = ''; path = ''
  if (stat == 0) then
    summary = text; path = written
  end if
end subroutine pymr_run_scene

!> Sizes of an open model: coordinates, bodies (with ground), markers.
subroutine pymr_model_size(handle, n, nb, n_markers, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_bind_models, only : open_models, check_handle
  implicit none
  integer, intent(in) :: handle
  integer, intent(out) :: n, nb, n_markers, stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  type(error_type), allocatable :: error
  n = 0; nb = 0; n_markers = 0
  call check_handle(handle, error)
  call report(error, stat, message, detail)
  if (stat /= 0) return
  associate(d => open_models(handle)%built%d)
    n = d%n; nb = d%nb; n_markers = d%markers%n
  end associate
end subroutine pymr_model_size

!> Mass matrix mm(n,n) and right-hand side p(n) of M qdd = P at (t, q, qd) of an open model.
subroutine pymr_model_terms(handle, n, t, q, qd, mm, p, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_bind_models, only : scratch
  use pymr_model, only : model_t, check_terms_finite
  implicit none
  integer, intent(in) :: handle, n
  double precision, intent(in) :: t, q(n), qd(n)
  double precision, intent(out) :: mm(n, n), p(n)
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(q) :: n = len(q)
  type(error_type), allocatable :: error
  type(model_t) :: model
  mm = 0.0d0; p = 0.0d0
  call scratch(handle, model, error, n)
  if (.not. allocated(error)) then
    call model%terms(t, q, qd)
    call check_terms_finite(model, t, error)
  end if
  call report(error, stat, message, detail)
  if (stat /= 0) return
  mm = model%wk%mm; p = model%wk%p
end subroutine pymr_model_terms

!> The 'response' coupling's fast-force response at (t, q, qd) of an open model: after one
!> synchronised (Schur complement) evaluation, g(:, 1:nf) = M^-1 E and the fast force
!> coefficients kf(1:nf), df(1:nf) (g, kf and df are n wide; nf columns are used).
subroutine pymr_force_response(handle, n, t, q, qd, nf, g, kf, df, stat, message, detail)
  use pymr_env_error, only : error_type, fatal_error
  use pymr_bind_support, only : report
  use pymr_bind_models, only : scratch
  use pymr_model, only : model_t
  implicit none
  integer, intent(in) :: handle, n
  double precision, intent(in) :: t, q(n), qd(n)
  integer, intent(out) :: nf
  double precision, intent(out) :: g(n, n), kf(n), df(n)
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(q) :: n = len(q)
  type(error_type), allocatable :: error
  type(model_t) :: model
  double precision, allocatable :: f(:)
  g = 0.0d0; kf = 0.0d0; df = 0.0d0; nf = 0
  call scratch(handle, model, error, n)
  if (.not. allocated(error)) then
    nf = model%n_fast()
    if (nf == 0 .or. model%n_slow() == 0) call fatal_error(error, 'the scene has no slow or no fast coordinates')
  end if
  if (.not. allocated(error)) then
    call model%init_partition()
    allocate(f(2*n))
    call model%eval(t, [q, qd], f, error)
  end if
  if (.not. allocated(error)) call model%force_response(g(:, 1:nf), kf(1:nf), df(1:nf), error)
  call report(error, stat, message, detail)
end subroutine pymr_force_response

!> Natural modes of an open model linearised at (t, q, qd) (the pre-flight check's
!> linearisation; preflight%normal_modes): nm modes (at most 2n), each of a kind (1 vibration,
!> 2 rigid-body motion, 3 drift), its frequency (Hz), damping ratio, rate Re(lambda) (1/s) and
!> shape in the coordinates.
subroutine pymr_modes(handle, n, t, q, qd, nm, kind, freq, zeta, rate, shapes, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_bind_models, only : scratch
  use pymr_model, only : model_t
  use pymr_driver_preflight, only : normal_modes, modes_bytes
  use pymr_env_memory, only : check_room
  implicit none
  integer, intent(in) :: handle, n
  double precision, intent(in) :: t, q(n), qd(n)
  integer, intent(out) :: nm, kind(2*n)
  double precision, intent(out) :: freq(2*n), zeta(2*n), rate(2*n), shapes(n, 2*n)
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(q) :: n = len(q)
  type(error_type), allocatable :: error
  type(model_t) :: model
  freq = 0.0d0; zeta = 0.0d0; rate = 0.0d0; shapes = 0.0d0; kind = 0; nm = 0
  call check_room(n, modes_bytes(n), error)
  if (.not. allocated(error)) call scratch(handle, model, error, n)
  if (.not. allocated(error)) call normal_modes(model, t, [q, qd], freq, zeta, rate, shapes, kind, nm, error)
  call report(error, stat, message, detail)
end subroutine pymr_modes

!> Accelerations qdd(n, m) for m states (t(m), q(n,m), qd(n,m)) of an open model.
subroutine pymr_model_accelerations(handle, n, m, t, q, qd, qdd, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_bind_models, only : scratch
  use pymr_model, only : model_t
  implicit none
  integer, intent(in) :: handle, n, m
  double precision, intent(in) :: t(m), q(n, m), qd(n, m)
  double precision, intent(out) :: qdd(n, m)
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(q) :: n = shape(q, 0)
  !f2py integer intent(hide), depend(q) :: m = shape(q, 1)
  type(error_type), allocatable :: error
  type(model_t) :: model
  integer :: k
  qdd = 0.0d0
  call scratch(handle, model, error, n)
  do k = 1, m
    if (allocated(error)) exit
    call model%accelerations(t(k), q(:, k), qd(:, k), qdd(:, k), error)
  end do
  call report(error, stat, message, detail)
end subroutine pymr_model_accelerations

!> The loops' constraint rows of an open model at one state (t = 0; model/loops.f90
!> loop_rows): residual phi(nr), Jacobian g(nr, n) and gam(nr) = -Gdot qd of every cut
!> joint, nr of them (the arrays are nrmax long; call with nrmax = 0 to learn nr).
subroutine pymr_loop_rows(handle, n, nrmax, q, qd, nr, phi, g, gam, stat, message, detail)
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_bind_support, only : report
  use pymr_bind_models, only : scratch
  use pymr_model, only : model_t
  use pymr_model_kinematics, only : forward_kinematics
  use pymr_model_loops, only : loop_rows
  implicit none
  integer, intent(in) :: handle, n, nrmax
  double precision, intent(in) :: q(n), qd(n)
  integer, intent(out) :: nr
  double precision, intent(out) :: phi(nrmax), g(nrmax, n), gam(nrmax)
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(q) :: n = len(q)
  type(error_type), allocatable :: error
  type(model_t) :: model
  phi = 0.0d0; g = 0.0d0; gam = 0.0d0; nr = 0
  call scratch(handle, model, error, n)
  call report(error, stat, message, detail)
  if (stat /= 0) return
  nr = model%d%cuts%n_rows
  if (nrmax < nr) return
  call forward_kinematics(model%d, model%wk, q, qd)
  call loop_rows(model%d, model%wk)
  phi(1:nr) = model%wk%loops%residual; g(1:nr, :) = model%wk%loops%jac; gam(1:nr) = model%wk%loops%gamma
  ! a state too large for the loops' terms (rates of 1e200): NaN came back with no error
  if (.not. (all(abs(phi(1:nr)) <= huge(1.0d0)) .and. all(abs(g(1:nr, :)) <= huge(1.0d0)) .and. &
    & all(abs(gam(1:nr)) <= huge(1.0d0)))) then
    call fatal_error(error, 'the loops'' rows are not finite at this state: it overflows the model''s terms', &
      & stat_solver)
    call report(error, stat, message, detail)
  end if
end subroutine pymr_loop_rows

!> Kinetic and potential energy (J) for m states q(n,m), qd(n,m) of an open model.
subroutine pymr_model_energy(handle, n, m, q, qd, kinetic, potential, stat, message, detail)
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_text, only : itoa, fmt
  use pymr_bind_support, only : report
  use pymr_bind_models, only : scratch
  use pymr_model, only : model_t
  implicit none
  integer, intent(in) :: handle, n, m
  double precision, intent(in) :: q(n, m), qd(n, m)
  double precision, intent(out) :: kinetic(m), potential(m)
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(q) :: n = shape(q, 0)
  !f2py integer intent(hide), depend(q) :: m = shape(q, 1)
  type(error_type), allocatable :: error
  type(model_t) :: model
  integer :: k
  kinetic = 0.0d0; potential = 0.0d0
  call scratch(handle, model, error, n)
  call report(error, stat, message, detail)
  if (stat /= 0) return
  do k = 1, m
    call model%energy(q(:, k), qd(:, k), kinetic(k), potential(k))
    ! a state too large for the model's terms: NaN or inf came back with no error
    if (.not. (abs(kinetic(k)) <= huge(1.0d0) .and. abs(potential(k)) <= huge(1.0d0))) then
      call fatal_error(error, 'state ' // itoa(k) // ': the energy is not finite (kinetic ' // fmt(kinetic(k)) // &
        & ', potential ' // fmt(potential(k)) // '): the state overflows the model''s terms', stat_solver)
      call report(error, stat, message, detail)
      return
    end if
  end do
end subroutine pymr_model_energy

!> Timing helper: CPU seconds per model evaluation of an open model over `reps` evaluations
!> at the state (q, qd). Python takes medians over several calls.
subroutine pymr_time_evaluation(handle, n, q, qd, reps, seconds, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_bind_models, only : scratch
  use pymr_model, only : model_t
  use pymr_env_clock, only : thread_cpu_time
  implicit none
  integer, intent(in) :: handle, n, reps
  double precision, intent(in) :: q(n), qd(n)
  double precision, intent(out) :: seconds
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(q) :: n = len(q)
  type(error_type), allocatable :: error
  type(model_t) :: model
  double precision, allocatable :: qdd(:)
  double precision :: c0, c1
  integer :: k
  seconds = 0.0d0
  call scratch(handle, model, error, n)
  if (.not. allocated(error)) then
    allocate(qdd(n))
    c0 = thread_cpu_time()
    do k = 1, reps
      call model%accelerations(0.0d0, q, qd, qdd, error)
      if (allocated(error)) exit
    end do
    c1 = thread_cpu_time()
    seconds = (c1 - c0)/max(reps, 1)
  end if
  call report(error, stat, message, detail)
end subroutine pymr_time_evaluation

!> Write the modes of beam `body` of an open model to a modal data file (for kind='modal').
subroutine pymr_write_modal(handle, body, path, stat, message, detail)
  use pymr_env_error, only : error_type, fatal_error
  use pymr_bind_support, only : report
  use pymr_bind_models, only : open_models, check_handle
  use pymr_driver_run, only : scene_input
  use pymr_io_modal_file, only : write_modal_file
  implicit none
  integer, intent(in) :: handle
  character(len=*), intent(in) :: body, path
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  type(error_type), allocatable :: error
  integer :: b, k
  call check_handle(handle, error)
  if (.not. allocated(error)) then
    associate(sc => open_models(handle)%sc, d => open_models(handle)%built%d)
      k = 0
      do b = 1, d%nb
        if (d%body_name(b) == body) k = b
      end do
      if (k == 0) then
        call fatal_error(error, sc%file // ": no body named '" // body // "'")
      else if (k == 1) then
        call fatal_error(error, sc%file // ": body '" // body // "' is the ground, not a beam (kind='beam')")
      else if (d%bshape(k)%ne == 0) then
        call fatal_error(error, sc%file // ": body '" // body // "' is not a beam (kind='beam')")
      else if (len(scene_input(sc, path)) > 0) then
        call fatal_error(error, sc%file // ': ' // path // ': would overwrite ' // scene_input(sc, path) // &
          & '; choose another modal file')
      else
        call write_modal_file(path, 'modes of beam ' // body // ' from ' // sc%file, d%flex(k), d%bshape(k), error)
      end if
    end associate
  end if
  call report(error, stat, message, detail)
end subroutine pymr_write_modal

!> Build a scene's model and keep it open: `handle` for every entry point that works on a
!> built model (pymr_model_terms, pymr_model_rhs and the others), `n` its number of
!> coordinates. The one entry point that builds a model from a scene's text.
subroutine pymr_model_open(scene, overrides, handle, n, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_bind_models, only : open_models, open_flags, open_slot, close_slot
  use pymr_driver_run, only : load_model
  implicit none
  character(len=*), intent(in) :: scene, overrides
  integer, intent(out) :: handle, n, stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  type(error_type), allocatable :: error
  integer :: k
  handle = 0; n = 0
  k = open_slot()
  call load_model(scene, overrides, open_models(k)%sc, open_models(k)%built, error)
  call report(error, stat, message, detail)
  if (stat /= 0) then
    call close_slot(k)
    return
  end if
  open_flags(k) = .true.
  handle = k; n = open_models(k)%built%d%n
end subroutine pymr_model_open

!> Release an open model.
subroutine pymr_model_close(handle)
  use pymr_bind_models, only : close_slot
  implicit none
  integer, intent(in) :: handle
  call close_slot(handle)
end subroutine pymr_model_close

!> f(t, x) = [qd; qdd] of an open model for the state x = [q; qd]; `evals` counts the
!> full evaluations of this handle's pymr_model_rhs calls so far.
subroutine pymr_model_rhs(handle, nx, t, x, f, evals, stat, message, detail)
  use pymr_env_error, only : error_type, fatal_error
  use pymr_bind_support, only : report
  use pymr_bind_models, only : open_models, check_handle, live_model
  use pymr_model, only : model_t
  implicit none
  integer, intent(in) :: handle, nx
  double precision, intent(in) :: t, x(nx)
  double precision, intent(out) :: f(nx)
  integer, intent(out) :: evals, stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(x) :: nx = len(x)
  type(error_type), allocatable :: error
  type(model_t), pointer :: model
  f = 0.0d0; evals = 0
  call check_handle(handle, error)
  if (.not. allocated(error)) then
    if (2*open_models(handle)%built%d%n /= nx) then
      call fatal_error(error, 'x has the wrong length')
    else
      model => live_model(handle)
      call model%eval(t, x, f, error)
      evals = model%wk%count%evals
    end if
  end if
  call report(error, stat, message, detail)
end subroutine pymr_model_rhs

!> Position (inertial, m) of marker `marker` (1-based) of an open model at m states
!> (t(m), q(n,m), qd(n,m)); prescribed coordinates take their functions' values.
subroutine pymr_model_marker(handle, marker, n, m, t, q, qd, pos, stat, message, detail)
  use pymr_env_error, only : error_type, fatal_error
  use pymr_bind_support, only : report
  use pymr_bind_models, only : open_models, check_handle_n, live_model
  use pymr_model, only : model_t
  use pymr_model_kinematics, only : forward_kinematics, marker_motion
  implicit none
  integer, intent(in) :: handle, marker, n, m
  double precision, intent(in) :: t(m), q(n, m), qd(n, m)
  double precision, intent(out) :: pos(3, m)
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(q) :: n = shape(q, 0)
  !f2py integer intent(hide), depend(q) :: m = shape(q, 1)
  type(error_type), allocatable :: error
  type(model_t), pointer :: model
  double precision :: v(3)
  integer :: k
  pos = 0.0d0
  call check_handle_n(handle, n, error)
  if (.not. allocated(error)) then
    if (marker < 1 .or. marker > open_models(handle)%built%d%markers%n) then
      call fatal_error(error, 'no marker with this index')
    end if
  end if
  call report(error, stat, message, detail)
  if (stat /= 0) return
  model => live_model(handle)
  do k = 1, m
    call model%impose(t(k), q(:, k), qd(:, k))
    call forward_kinematics(model%d, model%wk, model%wk%qx, model%wk%qdx)
    call marker_motion(model%d, model%wk, marker, model%wk%qx, model%wk%qdx, pos(:, k), v)
  end do
end subroutine pymr_model_marker

!> Index (1-based; 0 when absent) of the marker called `name` in an open model.
subroutine pymr_model_marker_index(handle, name, k)
  use pymr_env_error, only : error_type
  use pymr_bind_models, only : open_models, check_handle
  implicit none
  integer, intent(in) :: handle
  character(len=*), intent(in) :: name
  integer, intent(out) :: k
  type(error_type), allocatable :: error
  integer :: i
  k = 0
  call check_handle(handle, error)
  if (allocated(error)) return
  do i = 1, open_models(handle)%built%d%markers%n
    if (trim(open_models(handle)%built%d%markers%name(i)) == trim(name)) k = i
  end do
end subroutine pymr_model_marker_index

!> Progress of the run going on in this process (another thread's pymr_run_scene):
!> simulated time reached, end time, and whether it is running.
subroutine pymr_progress(t, t_end, running)
  use pymr_driver_run, only : progress_t, progress_t_end, progress_running
  implicit none
  double precision, intent(out) :: t, t_end
  integer, intent(out) :: running
  t = progress_t; t_end = progress_t_end
  running = merge(1, 0, progress_running)
end subroutine pymr_progress

!> The resolved scene (what = 0: read, overrides applied and validated by building its
!> model; every item with a value, then a comment line with its fingerprint; what = 2: the
!> same with the files it names made absolute, for a copy placed elsewhere) or the schema
!> of the scene items (what = 1), written to `path`.
subroutine pymr_scene_write(scene, overrides, what, path, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_model_scene, only : scene_t
  use pymr_model, only : model_t
  use pymr_driver_run, only : load_model
  use pymr_io_namelist_input, only : resolved_texts, schema_text, text_fingerprint
  use pymr_env_text_file, only : write_text_file
  implicit none
  character(len=*), intent(in) :: scene, overrides, path
  integer, intent(in) :: what
  character(len=:), allocatable :: text, absolute
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  type(error_type), allocatable :: error
  type(scene_t), target :: sc
  type(model_t) :: model
  if (what == 1) then
    call write_text_file(path, schema_text(), error)
  else
    call load_model(scene, overrides, sc, model, error)
    if (.not. allocated(error)) then
      call resolved_texts(sc, text, absolute)
      if (what == 2) then
        call write_text_file(path, absolute // '! fingerprint ' // text_fingerprint(text) // new_line('a'), error)
      else
        call write_text_file(path, text // '! fingerprint ' // text_fingerprint(text) // new_line('a'), error)
      end if
    end if
  end if
  call report(error, stat, message, detail)
end subroutine pymr_scene_write

!> The value of one item (address GROUP.ITEM or GROUP[NAME].ITEM) of a scene read with
!> its overrides, as the resolved scene writes it ('' when it holds no value).
subroutine pymr_scene_item(scene, overrides, address, value, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_model_scene, only : scene_t
  use pymr_io_namelist_input, only : read_scene, item_value
  implicit none
  character(len=*), intent(in) :: scene, overrides, address
  character(len=4096), intent(out) :: value
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  type(error_type), allocatable :: error
  type(scene_t), target :: sc
  character(len=:), allocatable :: text
  value = ''
  call read_scene(scene, overrides, sc, error)
  if (.not. allocated(error)) call item_value(sc, address, text, error)
  if (.not. allocated(error)) value = text
  call report(error, stat, message, detail)
end subroutine pymr_scene_item

!> The one spelling of the item an override address names (canonical_address): sweeps
!> find two keys of one item by it.
subroutine pymr_override_address(address, canonical, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_io_namelist_input, only : canonical_address
  implicit none
  character(len=*), intent(in) :: address
  character(len=4096), intent(out) :: canonical
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  type(error_type), allocatable :: error
  character(len=:), allocatable :: text
  canonical = ''
  call canonical_address(address, text, error)
  if (.not. allocated(error)) canonical = text
  call report(error, stat, message, detail)
end subroutine pymr_override_address

!> A scene edited in Python (pymr.Scene.add, remove): the scene in `text`, named `file` in
!> messages and the base of its relative paths, read with `overrides` and written to `path`
!> resolved (the single groups it gives only), with its files' paths absolute and no
!> fingerprint line, without the groups the
!> address `omit` names (GROUP or GROUP[NAME]; '' none). `whole` = 1: checked as a scene
!> (read, its rules, its model built); 0: a draft, its groups and items read alone.
subroutine pymr_scene_edit(text, file, overrides, omit, whole, path, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_model_scene, only : scene_t
  use pymr_model, only : model_t
  use pymr_driver_build, only : build_model
  use pymr_io_namelist_input, only : read_scene_text, resolved_text, check_removal
  use pymr_env_text_file, only : write_text_file
  implicit none
  character(len=*), intent(in) :: text, file, overrides, omit, path
  integer, intent(in) :: whole
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  type(error_type), allocatable :: error
  type(scene_t), target :: sc
  type(model_t) :: model
  call read_scene_text(text, file, overrides, sc, error, draft=whole == 0)
  if (.not. allocated(error) .and. whole == 1) call build_model(sc, model, error)
  if (.not. allocated(error) .and. len_trim(omit) > 0) call check_removal(sc, trim(omit), error)
  if (.not. allocated(error)) then
    if (len_trim(omit) > 0) then
      call write_text_file(path, resolved_text(sc, .true., omit=trim(omit), given=.true.), error)
    else
      call write_text_file(path, resolved_text(sc, .true., given=.true.), error)
    end if
  end if
  call report(error, stat, message, detail)
end subroutine pymr_scene_edit

!> Step and order history of an open model's run (no output): time reached, step and order
!> of each accepted step (entry 1: the start), nh entries, at most nmax.
subroutine pymr_step_history(handle, nmax, t, h, q, nh, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_bind_models, only : open_models, scratch
  use pymr_model, only : model_t
  use pymr_driver_history, only : step_history
  implicit none
  integer, intent(in) :: handle, nmax
  double precision, intent(out) :: t(nmax), h(nmax)
  integer, intent(out) :: q(nmax), nh, stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  type(error_type), allocatable :: error
  type(model_t) :: model
  t = 0.0d0; h = 0.0d0; q = 0; nh = 0
  call scratch(handle, model, error)
  if (.not. allocated(error)) call step_history(open_models(handle)%sc, model, t, h, q, nh, error)
  call report(error, stat, message, detail)
end subroutine pymr_step_history

!> Every body's frame (inertial origin pos(3, b, k) and its parent's index parent(b), 0 for
!> the ground) of an open model at m states (t(m), q(n,m), qd(n,m)), for drawing.
subroutine pymr_model_frames(handle, n, m, nb, t, q, qd, pos, parent, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_bind_models, only : check_handle_count, live_model
  use pymr_model, only : model_t
  use pymr_model_kinematics, only : forward_kinematics
  implicit none
  integer, intent(in) :: handle, n, m, nb
  double precision, intent(in) :: t(m), q(n, m), qd(n, m)
  double precision, intent(out) :: pos(3, nb, m)
  integer, intent(out) :: parent(nb), stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(q) :: n = shape(q, 0)
  !f2py integer intent(hide), depend(q) :: m = shape(q, 1)
  type(error_type), allocatable :: error
  type(model_t), pointer :: model
  integer :: k
  pos = 0.0d0; parent = 0
  call check_handle_count(handle, n, 'nb', 'bodies', nb, error)
  call report(error, stat, message, detail)
  if (stat /= 0) return
  model => live_model(handle)
  parent = model%d%parent(1:nb)
  do k = 1, m
    call model%impose(t(k), q(:, k), qd(:, k))
    call forward_kinematics(model%d, model%wk, model%wk%qx, model%wk%qdx)
    pos(:, :, k) = model%wk%pos(:, 1:nb)
  end do
end subroutine pymr_model_frames

!> The body (1-based, in the model's order) marker `marker` (1-based) of an open model is on;
!> 0 for no such marker.
subroutine pymr_model_marker_body(handle, marker, body)
  use pymr_env_error, only : error_type
  use pymr_bind_models, only : open_models, check_handle
  implicit none
  integer, intent(in) :: handle, marker
  integer, intent(out) :: body
  type(error_type), allocatable :: error
  body = 0
  call check_handle(handle, error)
  if (allocated(error)) return
  if (marker < 1 .or. marker > open_models(handle)%built%d%markers%n) return
  body = open_models(handle)%built%d%markers%body(marker)
end subroutine pymr_model_marker_body

!> What of a scene's input `path` is ('the scene (FILE)', 'a modal file of the scene (FILE)',
!> ...), or '' : the kernel's rule for outputs Python writes beside a scene's files.
subroutine pymr_scene_input(scene, overrides, path, what, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_model_scene, only : scene_t
  use pymr_io_namelist_input, only : read_scene
  use pymr_driver_run, only : scene_input
  implicit none
  character(len=*), intent(in) :: scene, overrides, path
  character(len=4096), intent(out) :: what
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  type(error_type), allocatable :: error
  type(scene_t) :: sc
  what = ''
  call read_scene(scene, overrides, sc, error)
  if (.not. allocated(error)) what = scene_input(sc, path)
  call report(error, stat, message, detail)
end subroutine pymr_scene_input

!> Do `a` and `b` name one file (the kernel's same_file: the same file on the disk when both
!> are there, else the same absolute path)? 1 yes, 0 no: the rule by which an output that
!> would replace an input is refused, for the outputs Python writes.
subroutine pymr_same_file(a, b, same)
  use pymr_env_text_file, only : same_file
  implicit none
  character(len=*), intent(in) :: a, b
  integer, intent(out) :: same
  same = merge(1, 0, same_file(a, b))
end subroutine pymr_same_file

!> Why an output written whole beside `path` and renamed over it cannot be put there (the
!> kernel's not_replaceable: a directory, a FIFO or a device, a symbolic link); '' where it
!> can: the rule for the outputs Python writes.
subroutine pymr_not_replaceable(path, why)
  use pymr_env_text_file, only : not_replaceable
  implicit none
  character(len=*), intent(in) :: path
  character(len=512), intent(out) :: why
  why = not_replaceable(path)
end subroutine pymr_not_replaceable

!> The state an open model's run starts from, x = [q; qd] (n coordinates), as the run's
!> first row has it (the initial values, the loops assembled, a static start settled),
!> without running.
subroutine pymr_initial_state(handle, n, x, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_bind_models, only : open_models, scratch
  use pymr_model, only : model_t
  use pymr_driver_run, only : starting_state
  implicit none
  integer, intent(in) :: handle, n
  double precision, intent(out) :: x(2*n)
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  type(error_type), allocatable :: error
  type(model_t) :: model
  x = 0.0d0
  call scratch(handle, model, error, n)
  if (.not. allocated(error)) call starting_state(open_models(handle)%sc, model, x, error)
  call report(error, stat, message, detail)
end subroutine pymr_initial_state

!> The name of an open model's marker k (1-based; '' beyond the markers).
subroutine pymr_model_marker_name(handle, k, name)
  use pymr_env_error, only : error_type
  use pymr_bind_models, only : open_models, check_handle
  implicit none
  integer, intent(in) :: handle, k
  character(len=64), intent(out) :: name
  type(error_type), allocatable :: error
  name = ''
  call check_handle(handle, error)
  if (allocated(error)) return
  if (k >= 1 .and. k <= open_models(handle)%built%d%markers%n) name = open_models(handle)%built%d%markers%name(k)
end subroutine pymr_model_marker_name

!> The column name of an open model's coordinate k (1-based, model order; '' beyond them).
subroutine pymr_model_coordinate_name(handle, k, name)
  use pymr_env_error, only : error_type
  use pymr_bind_models, only : open_models, check_handle
  implicit none
  integer, intent(in) :: handle, k
  character(len=80), intent(out) :: name
  type(error_type), allocatable :: error
  name = ''
  call check_handle(handle, error)
  if (allocated(error)) return
  if (k >= 1 .and. k <= open_models(handle)%built%d%n) name = open_models(handle)%built%d%qname(k)
end subroutine pymr_model_coordinate_name

!> Every body's pose (inertial origin pos(3, b, k) and body-to-inertial rotation rot(3, 3, b, k))
!> of an open model at m states (t(m), q(n,m), qd(n,m)), the flexible bodies' modal
!> coordinates scaled by `exaggerate` (1: as they are), for drawing.
subroutine pymr_model_poses(handle, n, m, nb, t, q, qd, exaggerate, pos, rot, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_bind_models, only : check_handle_count, live_model
  use pymr_bind_drawing, only : scaled_kinematics
  use pymr_model, only : model_t
  implicit none
  integer, intent(in) :: handle, n, m, nb
  double precision, intent(in) :: t(m), q(n, m), qd(n, m), exaggerate
  double precision, intent(out) :: pos(3, nb, m), rot(3, 3, nb, m)
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(q) :: n = shape(q, 0)
  !f2py integer intent(hide), depend(q) :: m = shape(q, 1)
  type(error_type), allocatable :: error
  type(model_t), pointer :: model
  integer :: k
  pos = 0.0d0; rot = 0.0d0
  call check_handle_count(handle, n, 'nb', 'bodies', nb, error)
  call report(error, stat, message, detail)
  if (stat /= 0) return
  model => live_model(handle)
  do k = 1, m
    call scaled_kinematics(model, t(k), q(:, k), qd(:, k), exaggerate)
    pos(:, :, k) = model%wk%pos(:, 1:nb)
    rot(:, :, :, k) = model%wk%rot(:, :, 1:nb)
  end do
end subroutine pymr_model_poses

!> Body `body` (1-based, model order) of an open model, for drawing: its name, kind (0 the
!> ground, 1 rigid, 2 beam, 3 modal file), the number of a modal-file body's nodes, its mass
!> (kg), centre of mass (body frame, m) and inertia about it (body axes, kg m^2; a rigid
!> body's), and a beam's length and outer radius (r_outer, else that of a full circle of its
!> area; m). kind = -1 for no such body.
subroutine pymr_model_body_info(handle, body, name, kind, nodes, mass, com, inertia, length, radius)
  use pymr_env_error, only : error_type
  use pymr_bind_models, only : open_models, check_handle
  use pymr_model_scene, only : unset
  implicit none
  integer, intent(in) :: handle, body
  character(len=64), intent(out) :: name
  integer, intent(out) :: kind, nodes
  double precision, intent(out) :: mass, com(3), inertia(3, 3), length, radius
  type(error_type), allocatable :: error
  integer :: i
  name = ''; kind = -1; nodes = 0; mass = 0.0d0; com = 0.0d0; inertia = 0.0d0; length = 0.0d0; radius = 0.0d0
  call check_handle(handle, error)
  if (allocated(error)) return
  associate(d => open_models(handle)%built%d, sc => open_models(handle)%sc)
    if (body < 1 .or. body > d%nb) return
    name = d%body_name(body)
    mass = d%mass(body); com = d%com(:, body); inertia = d%inertia(:, :, body)
    kind = merge(0, 1, body == 1)
    if (d%bshape(body)%ne > 0) then
      kind = 2; length = d%bshape(body)%length
      do i = 1, size(sc%bodies)
        if (sc%bodies(i)%name /= d%body_name(body)) cycle
        if (sc%bodies(i)%r_outer /= unset) then
          radius = sc%bodies(i)%r_outer
        else if (sc%bodies(i)%area /= unset) then
          radius = sqrt(sc%bodies(i)%area/acos(-1.0d0))
        end if
      end do
    else if (d%flexible(body)) then
      kind = 3; nodes = d%mnodes(body)%np
    end if
  end associate
end subroutine pymr_model_body_info

!> Flexible body `body`'s centre line at np points (a beam: evenly along its length, np >= 2;
!> a modal-file body: its nodes, np their number) at m states of an open model: line(3, p, k)
!> the inertial place with the modal coordinates scaled by `exaggerate`, disp(3, p, k) the
!> elastic displacement at the unscaled coordinates (inertial axes of the drawn pose).
subroutine pymr_model_body_line(handle, body, n, m, np, t, q, qd, exaggerate, line, disp, stat, message, detail)
  use pymr_env_error, only : error_type, fatal_error
  use pymr_bind_support, only : report
  use pymr_bind_models, only : open_models, check_handle_n, live_model
  use pymr_bind_drawing, only : scaled_kinematics, line_points, n_line_points
  use pymr_model, only : model_t
  implicit none
  integer, intent(in) :: handle, body, n, m, np
  double precision, intent(in) :: t(m), q(n, m), qd(n, m), exaggerate
  double precision, intent(out) :: line(3, np, m), disp(3, np, m)
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(q) :: n = shape(q, 0)
  !f2py integer intent(hide), depend(q) :: m = shape(q, 1)
  type(error_type), allocatable :: error
  type(model_t), pointer :: model
  double precision, allocatable :: psi(:, :)
  double precision :: x0(3), u(3)
  integer :: k, p, nm, a0
  line = 0.0d0; disp = 0.0d0
  call check_handle_n(handle, n, error)
  if (.not. allocated(error)) then
    if (body < 2 .or. body > open_models(handle)%built%d%nb) then
      call fatal_error(error, 'no body with this index')
    else if (n_line_points(open_models(handle)%built%d, body, np) /= np .or. np < 2) then
      call fatal_error(error, 'np is not the number of points of this flexible body''s line')
    end if
  end if
  call report(error, stat, message, detail)
  if (stat /= 0) return
  model => live_model(handle)
  nm = model%d%nm(body); a0 = model%d%a0(body)
  allocate(psi(3, nm))
  do k = 1, m
    call scaled_kinematics(model, t(k), q(:, k), qd(:, k), exaggerate)
    do p = 1, np
      call line_points(model%d, body, p, np, x0, psi)
      u = matmul(psi, q(a0:a0 + nm - 1, k))
      line(:, p, k) = model%wk%pos(:, body) + matmul(model%wk%rot(:, :, body), x0 + exaggerate*u)
      disp(:, p, k) = matmul(model%wk%rot(:, :, body), u)
    end do
  end do
end subroutine pymr_model_body_line

!> Joint j (1-based: the tree joints, body 2 .. nb's inboard one, then the loops' cut
!> joints) of an open model: its name, kind (as the scene says), and its parent and child
!> bodies (1-based, model order); name '' beyond the joints.
subroutine pymr_model_joint_info(handle, j, name, kind, parent, child)
  use pymr_env_error, only : error_type
  use pymr_bind_models, only : open_models, check_handle
  implicit none
  integer, intent(in) :: handle, j
  character(len=64), intent(out) :: name
  character(len=16), intent(out) :: kind
  integer, intent(out) :: parent, child
  type(error_type), allocatable :: error
  integer :: i
  name = ''; kind = ''; parent = 0; child = 0
  call check_handle(handle, error)
  if (allocated(error)) return
  associate(d => open_models(handle)%built%d, sc => open_models(handle)%sc)
    if (j >= 1 .and. j <= d%nb - 1) then
      name = d%joint_name(j + 1); parent = d%parent(j + 1); child = j + 1
    else if (j > d%nb - 1 .and. j <= d%nb - 1 + d%cuts%n) then
      name = d%cuts%name(j - d%nb + 1); parent = d%cuts%parent(j - d%nb + 1); child = d%cuts%child(j - d%nb + 1)
    else
      return
    end if
    do i = 1, size(sc%joints)
      if (sc%joints(i)%name == name) kind = sc%joints(i)%kind
    end do
  end associate
end subroutine pymr_model_joint_info

!> Every joint's inertial place pos(3, j, k) and unit axis axis(3, j, k) (zero for a joint
!> with none; pymr_model_joint_info's order, nj of them) of an open model at m states, the
!> modal coordinates scaled by `exaggerate`.
subroutine pymr_model_joints(handle, n, m, nj, t, q, qd, exaggerate, pos, axis, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_bind_models, only : check_handle_count, live_model
  use pymr_bind_drawing, only : scaled_kinematics, joint_place
  use pymr_model, only : model_t
  implicit none
  integer, intent(in) :: handle, n, m, nj
  double precision, intent(in) :: t(m), q(n, m), qd(n, m), exaggerate
  double precision, intent(out) :: pos(3, nj, m), axis(3, nj, m)
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(q) :: n = shape(q, 0)
  !f2py integer intent(hide), depend(q) :: m = shape(q, 1)
  type(error_type), allocatable :: error
  type(model_t), pointer :: model
  integer :: k, j
  pos = 0.0d0; axis = 0.0d0
  call check_handle_count(handle, n, 'nj', 'joints', nj, error)
  call report(error, stat, message, detail)
  if (stat /= 0) return
  model => live_model(handle)
  do k = 1, m
    call scaled_kinematics(model, t(k), q(:, k), qd(:, k), exaggerate)
    do j = 1, nj
      call joint_place(model, j, pos(:, j, k), axis(:, j, k))
    end do
  end do
end subroutine pymr_model_joints

!> Every marker's inertial place pos(3, k, i) (nmk markers, the scene's order) of an open
!> model at m states, the modal coordinates scaled by `exaggerate`.
subroutine pymr_model_markers(handle, n, m, nmk, t, q, qd, exaggerate, pos, stat, message, detail)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_bind_models, only : check_handle_count, live_model
  use pymr_bind_drawing, only : scaled_kinematics
  use pymr_model, only : model_t
  use pymr_model_kinematics, only : marker_motion
  implicit none
  integer, intent(in) :: handle, n, m, nmk
  double precision, intent(in) :: t(m), q(n, m), qd(n, m), exaggerate
  double precision, intent(out) :: pos(3, nmk, m)
  integer, intent(out) :: stat
  character(len=8192), intent(out) :: message
  character(len=4096), intent(out) :: detail
  !f2py integer intent(hide), depend(q) :: n = shape(q, 0)
  !f2py integer intent(hide), depend(q) :: m = shape(q, 1)
  type(error_type), allocatable :: error
  type(model_t), pointer :: model
  double precision :: v(3)
  integer :: k, i
  pos = 0.0d0
  call check_handle_count(handle, n, 'nmk', 'markers', nmk, error)
  call report(error, stat, message, detail)
  if (stat /= 0) return
  model => live_model(handle)
  do k = 1, m
    call scaled_kinematics(model, t(k), q(:, k), qd(:, k), exaggerate)
    do i = 1, nmk
      call marker_motion(model%d, model%wk, i, model%wk%qx, model%wk%qdx, pos(:, i, k), v)
    end do
  end do
end subroutine pymr_model_markers

!> Column counts of the sparse Cholesky factor of a symmetric matrix whose whole pattern
!> (both triangles, in the order it will be factored) is (colptr, rowind), 1-based
!> compressed columns (pymr_env_sparse_cholesky). `pymr modal-import` sizes its
!> factorisation with them before making it.
subroutine pymr_cholesky_counts(n, nnz, colptr, rowind, counts)
  use pymr_env_sparse_cholesky, only : elimination_tree, column_counts
  implicit none
  integer, intent(in) :: n, nnz
  integer, intent(in) :: colptr(n + 1), rowind(nnz)
  integer, intent(out) :: counts(n)
  !f2py threadsafe
  integer, allocatable :: parent(:)
  allocate(parent(n))
  call elimination_tree(n, colptr, rowind, parent)
  call column_counts(n, colptr, rowind, parent, counts)
end subroutine pymr_cholesky_counts
