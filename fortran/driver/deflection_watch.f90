!> The watch on flexible bodies' deflection during a run (&scene deflection_limit).
module pymr_driver_deflection_watch
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_text, only : fmt
  use pymr_model_scene, only : scene_t
  use pymr_model, only : model_t
  use pymr_model_flexbody, only : point_deflection
  use pymr_io_results_output, only : run_stats
  implicit none
  private
  public :: watch_deflection

contains

  !> A flexible body whose points deflect beyond &scene deflection_limit of its size at time
  !> t: a warning (once a body) in the run's statistics, or with deflection_stop a failed run.
  subroutine watch_deflection(sc, model, t, q, stats, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: t, q(:)
    type(run_stats), intent(inout) :: stats
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: deflection, size_m
    integer :: b
    character(len=:), allocatable :: said
    if (sc%scene%deflection_limit <= 0.0_dp) return
    do b = 2, model%d%nb
      if (model%d%nm(b) == 0) cycle
      ! a body is warned about once: not measured again after that
      if (allocated(stats%warnings)) then
        if (index(stats%warnings, "body '" // trim(model%d%body_name(b)) // "' deflects") > 0) cycle
      end if
      size_m = model%d%flex(b)%size_m
      deflection = point_deflection(model%d%flex(b), q(model%d%a0(b):model%d%a0(b) + model%d%nm(b) - 1), &
        & sc%scene%deflection_limit*size_m)
      if (deflection <= sc%scene%deflection_limit*size_m) cycle
      said = "body '" // trim(model%d%body_name(b)) // "' deflects " // fmt(deflection) // ' m, ' // &
        & fmt(deflection/size_m) // ' of its size ' // fmt(size_m) // ' m (&scene deflection_limit = ' // &
        & fmt(sc%scene%deflection_limit) // '): linear modal theory holds for small deflections only'
      if (sc%scene%deflection_stop) then
        call fatal_error(error, 'at t = ' // fmt(t) // ' s: ' // said // ' (deflection_stop)', stat_solver); return
      end if
      call stats%add_warning('at t = ' // fmt(t) // ' s: ' // said)
    end do
  end subroutine watch_deflection
end module pymr_driver_deflection_watch
