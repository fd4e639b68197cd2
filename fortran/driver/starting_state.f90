!> The state a run starts from: the scene's initial coordinates and rates, its loops
!> assembled, and for &scene start = 'static' the static equilibrium.
module pymr_driver_starting_state
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type
  use pymr_model_scene, only : scene_t, unset
  use pymr_model, only : model_t
  use pymr_model_loops, only : assemble_loops
  use pymr_model_scene_rules, only : closes_loop
  use pymr_io_results_output, only : run_stats
  use pymr_driver_static_start, only : static_start
  implicit none
  private
  public :: starting_state, initial_state

contains

  !> [q0; qd0] from the joints' q0 and qd0 in model coordinate order.
  subroutine initial_state(sc, model, x)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(inout) :: model
    real(dp), intent(out) :: x(:)
    integer :: b, j, m, n
    n = model%d%n
    x = 0.0_dp
    do b = 2, model%d%nb
      do j = 1, size(sc%joints)
        if (sc%joints(j)%name /= model%d%joint_name(b)) cycle
        do m = 1, model%d%nc(b)
          x(model%d%c0(b) + m - 1) = sc%joints(j)%q0(m)
          x(n + model%d%c0(b) + m - 1) = sc%joints(j)%qd0(m)
        end do
      end do
    end do
    ! flexible bodies: their initial modal state when given (0 else)
    do b = 2, model%d%nb
      if (model%d%nm(b) == 0) cycle
      do j = 1, size(sc%bodies)
        if (sc%bodies(j)%name /= model%d%body_name(b)) cycle
        m = model%d%nm(b)
        if (sc%bodies(j)%a0(1) /= unset) x(model%d%a0(b):model%d%a0(b) + m - 1) = sc%bodies(j)%a0(1:m)
        if (sc%bodies(j)%ad0(1) /= unset) x(n + model%d%a0(b):n + model%d%a0(b) + m - 1) = sc%bodies(j)%ad0(1:m)
      end do
    end do
    ! prescribed coordinates start on their functions
    if (model%d%n_prescribed > 0) then
      call model%impose(0.0_dp, x(1:n), x(n+1:))
      x(1:n) = model%wk%qx; x(n+1:) = model%wk%qdx
    end if
  end subroutine initial_state

  !> The state a run starts from: as the scene gives it (its loops assembled), then, for
  !> &scene start = 'static', with the modal coordinates and those of the joints marked
  !> settle in static equilibrium (on the loops' constraints).
  subroutine starting_state(sc, model, x, error, stats)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(inout) :: model
    real(dp), intent(out) :: x(:)
    type(error_type), allocatable, intent(out) :: error
    !> Receives what a static start did.
    type(run_stats), intent(inout), optional :: stats
    integer :: iterations
    real(dp) :: change
    integer, allocatable :: u(:)
    logical, allocatable :: settles(:)
    character(len=64), allocatable :: names(:)
    integer :: b, j, i, n
    call initial_state(sc, model, x)
    n = model%d%n
    call assemble_loops(model%d, model%wk, x(1:n), x(n+1:), marked_coordinates(sc, model, sc%joints%hold), error)
    if (allocated(error)) then
      ! the loops' fault is no single line's: it names the first loop-closing joint
      do j = 1, size(sc%joints)
        if (closes_loop(sc, j)) exit
      end do
      error%message = sc%joints(j)%origin%where() // ': ' // error%message; return
    end if
    if (sc%scene%start /= 'static') return
    settles = marked_coordinates(sc, model, sc%joints%settle)
    allocate(u(0))
    do b = 2, model%d%nb
      u = [u, (model%d%a0(b) + i, i = 0, model%d%nm(b) - 1)]
      associate(c0 => model%d%c0(b), nc => model%d%nc(b))
        u = [u, pack([(c0 + i, i = 0, nc - 1)], settles(c0:c0 + nc - 1))]
      end associate
    end do
    allocate(names(n))
    do i = 1, n
      names(i) = model%component_name(i)
    end do
    call static_start(model, u, names, x, error, iterations, change)
    if (allocated(error)) then
      error%message = sc%scene%origin%where('start') // ': ' // error%message; return
    end if
    if (present(stats)) then
      stats%static_settled = size(u); stats%static_iterations = iterations; stats%static_change = change
    end if
    ! the equilibrium closes the loops to Newton's tolerance; the projection closes them to
    ! the run's and takes the rates' motion across them away at the settled positions
    call model%project(0.0_dp, x, error)
    model%wk%loops%closure_drift = 0.0_dp     ! the statistic is of the run's steps
  end subroutine starting_state

  !> The coordinates of the tree joints marked in `marked` (one flag per &joint: settle,
  !> hold).
  function marked_coordinates(sc, model, marked) result(mask)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    logical, intent(in) :: marked(:)
    logical :: mask(model%d%n)
    integer :: b, j
    mask = .false.
    do b = 2, model%d%nb
      do j = 1, size(sc%joints)
        if (sc%joints(j)%name == model%d%joint_name(b) .and. marked(j)) &
          & mask(model%d%c0(b):model%d%c0(b) + model%d%nc(b) - 1) = .true.
      end do
    end do
  end function marked_coordinates
end module pymr_driver_starting_state
