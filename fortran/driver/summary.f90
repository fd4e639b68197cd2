!> The summary of a run: a few human-readable lines (mrsim prints them, `res.summary` holds
!> them): the scene and method, the counts and times, the loops and the static start, the
!> warnings and the markers' final motion.
module pymr_driver_summary
  use pymr_env_kinds, only : dp
  use pymr_env_text, only : itoa, fmt, next_text_line
  use pymr_model_scene, only : scene_t
  use pymr_model, only : model_t
  use pymr_model_types, only : cut_free
  use pymr_model_kinematics, only : forward_kinematics, marker_motion
  use pymr_io_results_output, only : run_stats, json_path
  use pymr_driver_stepper_setup, only : method_label
  use pymr_driver_moving_load_exits, only : exits_text
  use pymr_driver_output_quantities, only : imposed_state
  implicit none
  private
  public :: summary_text

  !> Markers whose final motion the summary prints (the results hold them all).
  integer, parameter :: max_summary_markers = 10

contains

  !> The summary of the run of `sc` that ended in state x with statistics st, its results in `path`.
  function summary_text(sc, model, st, path, x) result(s)
    type(scene_t), intent(in) :: sc
    type(model_t), intent(inout) :: model
    type(run_stats), intent(in) :: st
    character(len=*), intent(in) :: path
    real(dp), intent(in) :: x(:)
    character(len=:), allocatable :: s
    character(len=256) :: buf
    character(len=:), allocatable :: warning
    integer :: j
    s = 'scene: ' // trim(sc%scene%title) // new_line('a') // 'method: ' // method_label(sc) // new_line('a')
    if (allocated(st%choice_line)) s = s // st%choice_line // new_line('a')
    if (st%steps_fast /= st%steps_slow) then
      write(buf, '(a,i0,a,i0,a,i0,a,i0,a)') 'simulated 0 to ' // fmt(sc%scene%t_end) // ' s: ', st%steps_slow, &
        & ' steps (', st%steps_fast, ' fast), ', st%rejected_steps, ' rejected, ', st%rhs_full, ' full evaluations'
    else
      write(buf, '(a,i0,a,i0,a,i0,a)') 'simulated 0 to ' // fmt(sc%scene%t_end) // ' s: ', st%steps_slow, &
        & ' steps, ', st%rejected_steps, ' rejected, ', st%rhs_full, ' full evaluations'
    end if
    if (st%rhs_fast > 0) write(buf, '(a,a,i0,a)') trim(buf), ', ', st%rhs_fast, ' fast-only'
    s = s // trim(buf) // new_line('a')
    write(buf, '(a,f10.4,a,f10.4,a)') 'cpu time ', st%cpu_time_s, ' s, wall time ', st%wall_time_s, ' s'
    s = s // trim(buf)
    if (st%preflight_cpu_s > 0.0_dp) s = s // ' (pre-flight stability check: ' // fmt(st%preflight_cpu_s) // ' s CPU)'
    s = s // loops_text(model)
    if (st%static_settled >= 0) then
      write(buf, '(a,i0,a,i0,a,es9.2)') 'static start: ', st%static_settled, ' coordinates settled in ', &
        & st%static_iterations, ' Newton iterations (last change ', st%static_change
      s = s // new_line('a') // trim(buf) // ')'
    end if
    if (allocated(st%warnings)) then
      j = 1
      do while (next_text_line(st%warnings, j, warning))
        if (len(warning) > 0) s = s // new_line('a') // 'warning: ' // warning
      end do
    end if
    s = s // new_line('a') // exits_text(model, sc%scene%t_end) // markers_text(model, sc%scene%t_end, x)
    s = s // 'results: ' // path // ', ' // json_path(path)
  end function summary_text

  !> The loops' lines (each after a new line; '' without loops): closing joints, rows, the
  !> initial assembly, and the largest closure error a step left.
  function loops_text(model) result(s)
    type(model_t), intent(in) :: model
    character(len=:), allocatable :: s
    character(len=256) :: buf
    s = ''
    if (model%d%cuts%n == 0) return
    write(buf, '(a,i0,a)') 'loops: ', model%d%cuts%n, ' closing joints'
    if (any(model%d%cuts%kind == cut_free)) write(buf, '(a,i0,a)') trim(buf) // ' (', &
      & count(model%d%cuts%kind == cut_free), " 'free': no constraint)"
    write(buf, '(a,i0,a,i0,a,es9.2,a,es9.2,a)') trim(buf) // ', ', &
      & model%d%cuts%n_rows, ' constraint rows, ', model%wk%loops%n_redundant, ' redundant (dropped); the initial ' // &
      & 'state assembled with largest changes ', model%wk%loops%assembly_dq, ' (q), ', model%wk%loops%assembly_dqd, ' (qd)'
    s = s // new_line('a') // trim(buf)
    if (model%d%cuts%n_rows > 0) then
      write(buf, '(a,es9.2,a)') 'loops: the largest closure error a step left (removed by projection): ', &
        & model%wk%loops%closure_drift, ' (m; rad for rotation rows)'
      s = s // new_line('a') // trim(buf)
    end if
  end function loops_text

  !> The final position and velocity of the first max_summary_markers markers at state x
  !> at time t (prescribed coordinates on their functions, as the results' rows), a line each.
  function markers_text(model, t, x) result(s)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, x(:)
    character(len=:), allocatable :: s
    character(len=256) :: buf
    real(dp) :: r(3), v(3), q(model%d%n), qd(model%d%n)
    integer :: i, n
    n = model%d%n
    s = ''
    call imposed_state(model, t, x(1:n), x(n+1:), q, qd)
    call forward_kinematics(model%d, model%wk, q, qd)
    do i = 1, min(model%d%markers%n, max_summary_markers)
      call marker_motion(model%d, model%wk, i, q, qd, r, v)
      ! fixed digits for ordinary values (f12.6 keeps a blank before -999.999999); exponents of
      ! three digits, with their E, for a scene far out or a run gone far off
      if (maxval(abs([r, v])) < 1.0e3_dp) then
        write(buf, '(a,3f12.6,a,3f12.6,a)') 'final ' // trim(model%d%markers%name(i)) // ': position', r, &
          & ' m, velocity', v, ' m/s'
      else
        write(buf, '(a,3(1x,es12.4e3),a,3(1x,es12.4e3),a)') 'final ' // trim(model%d%markers%name(i)) // &
          & ': position', r, ' m, velocity', v, ' m/s'
      end if
      s = s // trim(buf) // new_line('a')
    end do
    if (model%d%markers%n > max_summary_markers) s = s // '(and ' // itoa(model%d%markers%n - max_summary_markers) &
      & // ' more markers in the results)' // new_line('a')
  end function markers_text
end module pymr_driver_summary
