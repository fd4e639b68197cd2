!> The size check of a run's results, before it starts.
module pymr_driver_output_size
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_text, only : fmt, itoa
  use pymr_model_scene, only : scene_t
  use pymr_model, only : model_t
  use pymr_io_results_output, only : row_width
  use pymr_io_results_file, only : results_file
  implicit none
  private
  public :: check_output_size, check_rows_written

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
    if (dt_out <= 0.0_dp) return          ! adaptive, every step: check_rows_written watches it
    rows = sc%scene%t_end/dt_out + 2
    bytes = rows*row_bytes(sc, model, out)
    if (bytes > sc%output%max_bytes) call fatal_error(error, sc%output%origin%where('dt') // ': the results would ' // &
      & 'take about ' // fmt(bytes) // ' bytes (' // fmt(rows) // ' rows), more than max_bytes = ' // &
      & fmt(sc%output%max_bytes) // ' (a larger dt, or raise max_bytes in &output)')
  end subroutine check_output_size

  !> The bytes of a row: 25 a value as text, 8 as HDF5 (uncompressed).
  real(dp) function row_bytes(sc, model, out)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    class(results_file), intent(in) :: out
    row_bytes = merge(8.0_dp, 25.0_dp, sc%output%format == 'hdf5')*row_width(out%plan, model%d)
  end function row_bytes

  !> An adaptive run writing a row every step, whose row count no check before it knows: it
  !> fails at the time t its `rows` reach max_bytes.
  subroutine check_rows_written(sc, model, out, rows, t, error)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(in) :: model
    class(results_file), intent(in) :: out
    integer, intent(in) :: rows
    real(dp), intent(in) :: t
    type(error_type), allocatable, intent(out) :: error
    if (rows*row_bytes(sc, model, out) <= sc%output%max_bytes) return
    call fatal_error(error, 'at t = ' // fmt(t) // ' s: the results reach max_bytes = ' // fmt(sc%output%max_bytes) // &
      & ' (' // itoa(rows) // ' rows, one every step): give &output dt, or raise max_bytes', stat_solver)
  end subroutine check_rows_written
end module pymr_driver_output_size
