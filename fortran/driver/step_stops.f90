!> The times a run's steps end on (adaptive single-rate, 'response' and 'exponential'
!> steppers land there; the run starts its stepper again past each): a moving load's start
!> at constant speed and its exit (discontinuities of the motion's equations), and a
!> pulse's start, peak and end (a load that a step could pass between two evaluations
!> unseen, with its slope's jumps at the ends).
module pymr_driver_step_stops
  use pymr_env_kinds, only : dp
  use pymr_model, only : model_t
  use pymr_model_effect_firing_load, only : firing_load_effect
  use pymr_model_effect_moving_load, only : moving_load_effect
  use pymr_driver_moving_load_exits, only : next_exit
  implicit none
  private
  public :: next_stop

contains

  !> The first such time after t (huge: none).
  real(dp) function next_stop(model, t) result(ts)
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: t
    integer :: i, k
    ts = next_exit(model, t)
    do i = 1, size(model%effects)
      select type (e => model%effects(i)%e)
      type is (firing_load_effect)
        ts = min(ts, e%next_edge(t))
      type is (moving_load_effect)
        do k = 1, size(e%loads)
          if (.not. e%loads(k)%tabulated .and. e%loads(k)%start > t) ts = min(ts, e%loads(k)%start)
        end do
      end select
    end do
  end function next_stop

end module pymr_driver_step_stops
