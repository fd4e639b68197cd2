!> The step and order history of a scene's run, for studies and tests: the run's own
!> stepper from the initial state to t_end, without output, recording each accepted step.
!> The projection of closed loops runs inside the stepper's advance, so these are the run's
!> steps on scenes with loops too.
module pymr_driver_history
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_model_scene, only : scene_t
  use pymr_model, only : model_t
  use pymr_integrator_stepper, only : stepper_t
  use pymr_driver_stepper_setup, only : make_stepper
  use pymr_driver_run, only : starting_state
  use pymr_env_text, only : itoa
  implicit none
  private
  public :: step_history

contains

  !> Time reached, step taken and order of every accepted step (t(1) the start, h(1) and
  !> q(1) the first step's), nh of them, of the run of scene `sc` on `model` (built from it
  !> and not yet evaluated); more than size(t) is an error.
  subroutine step_history(sc, model, t, h, q, nh, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(inout) :: model
    real(dp), intent(out) :: t(:), h(:)
    integer, intent(out) :: q(:), nh
    type(error_type), allocatable, intent(out) :: error
    class(stepper_t), allocatable :: st
    real(dp), allocatable :: x(:)
    real(dp) :: h0, t_prev
    nh = 0; t = 0.0_dp; h = 0.0_dp; q = 0
    if (sc%integrator%method == 'auto') then
      call fatal_error(error, sc%file // ": &integrator: method: 'auto' chooses by timing probes at the run's " // &
        & "start, so its steps are not known before: name the method ('single' or 'multirate') for a step " // &
        & "history"); return
    end if
    allocate(x(2*model%d%n))
    call starting_state(sc, model, x, error); if (allocated(error)) return
    call make_stepper(sc, model, x, st, h0, error); if (allocated(error)) return
    call st%start(model, 0.0_dp, x, h0, error); if (allocated(error)) return
    nh = 1; t(1) = st%time(); q(1) = st%order()
    do while (st%time() < sc%scene%t_end*(1.0_dp - 1.0e-12_dp))
      if (nh >= size(t)) then
        call fatal_error(error, 'the run takes more than ' // itoa(size(t) - 1) // ' steps'); return
      end if
      t_prev = st%time()
      call st%advance(model, error); if (allocated(error)) return
      nh = nh + 1
      t(nh) = st%time(); h(nh) = t(nh) - t_prev; q(nh) = st%order()
    end do
  end subroutine step_history
end module pymr_driver_history
