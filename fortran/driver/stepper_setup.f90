!> The stepper a scene asks for: the one place that chooses between the single-rate and the
!> multirate steppers and their couplings (everything after uses the stepper interface).
module pymr_driver_stepper_setup
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_model_scene, only : scene_t
  use pymr_model, only : model_t
  use pymr_integrator_stepper, only : stepper_t
  use pymr_integrator_abm, only : abm_integrator, hinit
  use pymr_integrator_adams, only : adams_integrator
  use pymr_integrator_multirate, only : multirate_integrator
  use pymr_integrator_response, only : response_integrator
  use pymr_integrator_exponential, only : exponential_integrator
  use pymr_integrator_control, only : step_control
  use pymr_integrator_stability, only : undamped_limit
  use pymr_model, only : modal_stiffness_damping
  use pymr_driver_preflight, only : top_frequency
  use pymr_env_text, only : itoa
  implicit none
  private
  public :: make_stepper, stepper_label, method_label, unused_adaptive_items

contains

  !> Make (not start) the stepper for the scene at the initial state x, and the step h0 its
  !> start takes (the fast step; adaptive runs may start smaller). Its steps are given to
  !> its init, so that the pre-flight check can read them before the start.
  subroutine make_stepper(sc, model, x, st, h0, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:)
    class(stepper_t), allocatable, intent(out) :: st
    real(dp), intent(out) :: h0
    type(error_type), allocatable, intent(out) :: error
    type(step_control) :: ctl
    type(abm_integrator), allocatable :: abm
    type(adams_integrator), allocatable :: adams
    type(step_control) :: stable
    ctl%rtol = sc%integrator%rtol; ctl%atol = sc%integrator%atol
    if (sc%integrator%h_min > 0.0_dp) ctl%h_min = sc%integrator%h_min
    if (sc%integrator%h_max > 0.0_dp) ctl%h_max = sc%integrator%h_max
    if (sc%integrator%error_norm == 'amplitude') call modal_frequencies(model, ctl%omega)
    if (trim(sc%integrator%method) == 'auto') then
      call fatal_error(error, "method 'auto' is chosen before a stepper is made (pymr_driver_method_choice)")
      return
    end if
    if (trim(sc%integrator%method) == 'multirate') then
      call make_multirate(sc, model, x, ctl, st, h0, error); return
    end if
    ! a single-rate stepper evaluates the whole model (method 'auto' may hand it over from
    ! a multirate one, which partitioned it)
    call model%end_partition()
    if (sc%integrator%formula == 'adams') then
      allocate(adams)
      h0 = sc%integrator%h_slow
      call adams%init(size(x), sc%integrator%order, ctl, sc%integrator%corrector == 'newton', h0)
      call top_vibration(model, x, adams%omega_top, error); if (allocated(error)) return
      call move_alloc(adams, st)
    else
      allocate(abm)
      call stable_control(sc, ctl, model, x, stable, error); if (allocated(error)) return
      h0 = sc%integrator%h_slow
      call abm%init(size(x), sc%integrator%adaptive, stable, sc%integrator%n_corrector, h0)
      call move_alloc(abm, st)
    end if
  end subroutine make_stepper

  !> A note naming the &integrator items the scene (or a --set) gives that a fixed-step run
  !> does not use ("rtol, atol"), '' when none or when the steps are adaptive: the run goes
  !> on (a study sets adaptive = .false. on a scene that gives its tolerances), and says so.
  function unused_adaptive_items(sc) result(note)
    type(scene_t), intent(in) :: sc
    character(len=:), allocatable :: note
    character(len=10), parameter :: items(6) = [character(len=10) :: 'rtol', 'atol', 'h_min', 'h_max', &
      & 'error_norm', 'k_max']
    integer :: i
    note = ''
    if (sc%integrator%adaptive) return
    do i = 1, size(items)
      if (.not. sc%integrator%origin%given(trim(items(i)))) cycle
      if (len(note) > 0) note = note // ', '
      note = note // trim(items(i))
    end do
    if (len(note) > 0) note = '&integrator ' // note // ': given, but fixed steps (adaptive = .false.) do not ' // &
      & 'use them'
  end function unused_adaptive_items

  !> The angular frequency of each coordinate for error_norm = 'amplitude': a modal
  !> coordinate's from its modal stiffness (the flexible body's omega^2: its modes are
  !> mass-normalised), 0 for joint coordinates. A property of the model, not of the state:
  !> a run continued from a checkpoint weighs its errors as the run that wrote it.
  subroutine modal_frequencies(model, omega)
    type(model_t), intent(in) :: model
    real(dp), allocatable, intent(out) :: omega(:)
    real(dp), allocatable :: kf(:), df(:)
    integer :: nj
    nj = model%d%nj
    allocate(omega(model%d%n), kf(model%d%n - nj), df(model%d%n - nj))
    call modal_stiffness_damping(model%d, model%effects, kf, df)
    omega(1:nj) = 0.0_dp
    omega(nj+1:) = sqrt(max(kf, 0.0_dp))
  end subroutine modal_frequencies

  !> The step control of a stepper whose PECE formula acts with one step on every modal
  !> coordinate (single-rate, 'response', the fast steps of 'full'): adaptive steps stay
  !> below 0.9 of the PECE stability limit of the highest modal frequency. Beyond it the
  !> error estimate sees the instability only once it has grown, and the first steps of a
  !> run from rest, taken from the tolerances alone, would leave an error in the undamped
  !> stiff modes that no later step removes (stiff barrel: the error floored at 5e-10 m for
  !> every rtol below 1e-8). Closed loops stiffen the flexible bodies they pass through: with
  !> them the highest frequency is the constrained model's at the initial state x (the
  !> flexible four-bar's 669 Hz against its coupler's own 223 Hz). Fixed steps take ctl as
  !> it is (the pre-flight check judges their stability).
  subroutine stable_control(sc, ctl, model, x, c, error)
    type(scene_t), intent(in) :: sc
    type(step_control), intent(in) :: ctl
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:)
    type(step_control), intent(out) :: c
    type(error_type), allocatable, intent(out) :: error
    real(dp), parameter :: margin = 0.9_dp
    real(dp) :: omega
    c = ctl
    if (.not. sc%integrator%adaptive) return
    call top_vibration(model, x, omega, error); if (allocated(error)) return
    if (omega > 0.0_dp) c%h_max = min(c%h_max, margin*undamped_limit(omega))
  end subroutine stable_control

  !> The highest undamped vibration frequency omega (rad/s) of the flexible bodies' modes,
  !> stiffened by the closed loops they pass through (the constrained model's at x); 0
  !> without modal coordinates.
  subroutine top_vibration(model, x, omega, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:)
    real(dp), intent(out) :: omega
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: kf(model%d%n - model%d%nj), df(model%d%n - model%d%nj)
    omega = 0.0_dp
    if (size(kf) == 0) return
    call modal_stiffness_damping(model%d, model%effects, kf, df)
    omega = sqrt(maxval(kf))
    if (model%d%cuts%n_rows > 0) then
      omega = max(omega, top_frequency(model, x, error)); if (allocated(error)) return
    end if
  end subroutine top_vibration

  !> What the stepper is, for messages: "single-rate", "coupling 'response'".
  function stepper_label(sc) result(s)
    type(scene_t), intent(in) :: sc
    character(len=:), allocatable :: s
    if (trim(sc%integrator%method) == 'multirate') then
      s = "coupling '" // trim(sc%integrator%coupling) // "'"
    else
      s = 'single-rate'
    end if
  end function stepper_label

  !> The method and its steps or tolerances, for the results' header.
  function method_label(sc) result(s)
    type(scene_t), intent(in) :: sc
    character(len=:), allocatable :: s
    character(len=96) :: buf
    if (sc%integrator%adaptive) then
      write(buf, '(a,es9.2,a,es9.2)') ' rtol=', sc%integrator%rtol, ' atol=', sc%integrator%atol
      if (sc%integrator%formula == 'adams' .and. sc%integrator%order > 0) then
        buf = ' adaptive adams order ' // itoa(sc%integrator%order) // trim(buf)
      else if (trim(sc%integrator%method) == 'single') then
        buf = ' adaptive ' // trim(sc%integrator%formula) // trim(buf)
      else
        buf = ' adaptive coupling=' // trim(sc%integrator%coupling) // trim(buf)
      end if
    else if (sc%integrator%method == 'multirate') then
      write(buf, '(a,es10.3,a,es10.3,a)') ' h_slow=', sc%integrator%h_slow, ' h_fast=', sc%integrator%h_fast, &
        & ' coupling=' // trim(sc%integrator%coupling)
    else
      write(buf, '(a,es10.3)') ' fixed h=', sc%integrator%h_slow
    end if
    s = trim(sc%integrator%method) // trim(buf)
  end function method_label

  subroutine make_multirate(sc, model, x, ctl, st, h0, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: x(:)
    type(step_control), intent(in) :: ctl
    class(stepper_t), allocatable, intent(out) :: st
    real(dp), intent(out) :: h0
    type(error_type), allocatable, intent(out) :: error
    type(multirate_integrator), allocatable :: mr
    type(response_integrator), allocatable :: rs
    type(exponential_integrator), allocatable :: ex
    type(abm_integrator) :: probe
    real(dp), allocatable :: f0(:)
    type(step_control) :: stable
    integer :: k
    if (model%n_fast() == 0 .or. model%n_slow() == 0) then
      call fatal_error(error, sc%file // ": &integrator: method: 'multirate' needs slow (joint) and fast " // &
        & "(modal) coordinates; this scene has " // itoa(model%n_slow()) // ' and ' // &
        & itoa(model%n_fast()) // ": use method = 'single'"); return
    end if
    k = nint(sc%integrator%h_slow/sc%integrator%h_fast)
    h0 = sc%integrator%h_fast
    call model%init_partition()
    if (sc%integrator%coupling == 'exponential') then
      ! its fast side is the exact flow: no explicit stability bound on its steps
      allocate(ex)
      h0 = sc%integrator%h_slow
      call ex%init(model%n_slow(), model%n_fast(), sc%integrator%adaptive, ctl, h0)
      call move_alloc(ex, st)
      return
    end if
    call stable_control(sc, ctl, model, x, stable, error); if (allocated(error)) return
    if (sc%integrator%coupling == 'response') then
      allocate(rs)
      call rs%init(model%n_slow(), model%n_fast(), k, sc%integrator%adaptive, stable, &
        & sc%integrator%k_max, h0)
      call move_alloc(rs, st)
      return
    end if
    if (sc%integrator%adaptive) then
      ! start single-rate (k = 1) at h_fast, or less if the tolerances or the fast modes'
      ! stability ask for it; the controller then chooses k, the fast step within stability
      call probe%init(size(x), .true., ctl, 1)
      allocate(f0(size(x)))
      call model%eval(0.0_dp, x, f0, error); if (allocated(error)) return
      call hinit(probe, model, 0.0_dp, x, f0, h0, error); if (allocated(error)) return
      k = 1
      h0 = min(sc%integrator%h_fast, h0, stable%h_max)
    end if
    allocate(mr)
    call mr%init(model%n_slow(), model%n_fast(), k, sc%integrator%adaptive, ctl, sc%integrator%k_max, &
      & stable%h_max, h0)
    call move_alloc(mr, st)
  end subroutine make_multirate
end module pymr_driver_stepper_setup
