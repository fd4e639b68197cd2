!> The stepper a scene asks for, made and started: the one place that chooses between the
!> single-rate and the multirate stepper (everything after uses the stepper interface).
module pymr_stepper_setup
  use pymr_kinds, only : dp
  use pymr_error, only : error_type, fatal_error
  use pymr_model_scene, only : scene_t
  use pymr_model, only : model_t
  use pymr_integrator_stepper, only : stepper_t
  use pymr_integrator_abm, only : abm_integrator, hinit
  use pymr_integrator_multirate, only : multirate_integrator, coupling_full, coupling_split
  use pymr_integrator_control, only : step_control
  use pymr_io_text, only : itoa
  implicit none
  private
  public :: start_stepper

contains

  !> Make the stepper for the scene and start it at (0, x); with `restarting`, only set it
  !> up (its state comes from a checkpoint).
  subroutine start_stepper(sc, model, x, st, restarting, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:)
    class(stepper_t), allocatable, intent(out) :: st
    logical, intent(in) :: restarting
    type(error_type), allocatable, intent(out) :: error
    type(step_control) :: ctl
    ctl%rtol = sc%integrator%rtol; ctl%atol = sc%integrator%atol
    if (sc%integrator%h_min > 0.0_dp) ctl%h_min = sc%integrator%h_min
    if (sc%integrator%h_max > 0.0_dp) ctl%h_max = sc%integrator%h_max
    if (trim(sc%integrator%method) == 'multirate') then
      call start_multirate(sc, model, x, ctl, st, restarting, error)
    else
      call start_single(sc, model, x, ctl, st, restarting, error)
    end if
  end subroutine start_stepper

  subroutine start_single(sc, model, x, ctl, st, restarting, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:)
    type(step_control), intent(in) :: ctl
    class(stepper_t), allocatable, intent(out) :: st
    logical, intent(in) :: restarting
    type(error_type), allocatable, intent(out) :: error
    type(abm_integrator), allocatable :: abm
    allocate(abm)
    call abm%init(size(x), sc%integrator%adaptive, ctl, sc%integrator%n_corrector)
    if (.not. restarting) call abm%start(model, 0.0_dp, x, sc%integrator%h_slow, error)
    call move_alloc(abm, st)
  end subroutine start_single

  subroutine start_multirate(sc, model, x, ctl, st, restarting, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:)
    type(step_control), intent(in) :: ctl
    class(stepper_t), allocatable, intent(out) :: st
    logical, intent(in) :: restarting
    type(error_type), allocatable, intent(out) :: error
    type(multirate_integrator), allocatable :: mr
    type(abm_integrator) :: probe
    real(dp), allocatable :: f0(:)
    real(dp) :: hs, h0
    integer :: k
    if (model%n_fast() == 0 .or. model%n_slow() == 0) then
      call fatal_error(error, sc%file // ": &integrator: method: 'multirate' needs slow (joint) and fast " // &
        & "(modal) coordinates; this scene has " // itoa(model%n_slow()) // ' and ' // &
        & itoa(model%n_fast()) // ": use method = 'single'"); return
    end if
    k = nint(sc%integrator%h_slow/sc%integrator%h_fast)
    hs = sc%integrator%h_slow
    if (sc%integrator%adaptive .and. .not. restarting) then
      ! start single-rate (k = 1) at h_fast, or less if the tolerances ask for it; the
      ! controller then chooses k
      call probe%init(size(x), .true., ctl, 1)
      allocate(f0(size(x)))
      call model%eval(0.0_dp, x, f0, error); if (allocated(error)) return
      call hinit(probe, model, 0.0_dp, x, f0, h0, error); if (allocated(error)) return
      k = 1
      hs = min(sc%integrator%h_fast, h0)
    end if
    call model%init_partition()
    allocate(mr)
    call mr%init(model%n_slow(), model%n_fast(), k, merge(coupling_split, coupling_full, &
      & sc%integrator%coupling == 'split'), sc%integrator%adaptive, ctl, sc%integrator%k_max)
    if (.not. restarting) call mr%start(model, 0.0_dp, x, hs, error)
    call move_alloc(mr, st)
  end subroutine start_multirate
end module pymr_stepper_setup
