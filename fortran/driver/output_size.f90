!> The size check of a run's results, before it starts.
module pymr_driver_output_size
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error
  use pymr_env_text, only : fmt
  use pymr_model_scene, only : scene_t
  use pymr_model, only : model_t
  use pymr_io_results_output, only : row_width
  use pymr_io_results_file, only : results_file
  implicit none
  private
  public :: check_output_size

contains

  !> The results file the run would write, refused above &output max_bytes: rows from t_end
  !> and the output interval (every step of a fixed-step run when dt is 0), 25 bytes a value
  !> as text, 8 as HDF5 (uncompressed).
  subroutine check_output_size(sc, model, out, dt_out, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    class(results_file), intent(in) :: out
    real(dp), intent(in) :: dt_out
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: rows, bytes
    if (dt_out <= 0.0_dp) return          ! adaptive, every step: bounded by max_steps
    rows = sc%scene%t_end/dt_out + 2
    bytes = rows*merge(8.0_dp, 25.0_dp, sc%output%format == 'hdf5')*row_width(out%plan, model%d)
    if (bytes > sc%output%max_bytes) call fatal_error(error, sc%output%origin%where('dt') // ': the results would ' // &
      & 'take about ' // fmt(bytes) // ' bytes (' // fmt(rows) // ' rows), more than max_bytes = ' // &
      & fmt(sc%output%max_bytes) // ' (a larger dt, or raise max_bytes in &output)')
  end subroutine check_output_size
end module pymr_driver_output_size
