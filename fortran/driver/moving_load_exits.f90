!> Exits of moving loads: after each step, a load whose travel passes either end of its beam
!> (the tip s = L, a shot exit, or the root s = 0) within the step has the state there taken
!> from the stepper's dense output (value_at at the exit time the travel law gives), and its
!> body's markers' states noted (model/effect_moving_load.f90 record_exit). The summary and
!> the JSON report them.
module pymr_driver_moving_load_exits
  use pymr_env_kinds, only : dp
  use pymr_env_text, only : fmt, json_escape, exact_text
  use pymr_model, only : model_t
  use pymr_model_effect_moving_load, only : moving_load_effect, record_exit
  use pymr_integrator_stepper, only : stepper_t
  implicit none
  private
  public :: note_exits, next_exit, exits_text, exits_json

contains

  !> The exits in (t0, min(t1, t_end)], the stepper's last step up to the run's end.
  subroutine note_exits(model, st, t0, t1, t_end)
    type(model_t), intent(inout) :: model
    class(stepper_t), intent(in) :: st
    real(dp), intent(in) :: t0, t1, t_end
    integer :: i, k, n
    real(dp) :: te, x(2*model%d%n)
    n = model%d%n
    do i = 1, size(model%effects)
      select type (e => model%effects(i)%e)
      type is (moving_load_effect)
        do k = 1, size(e%loads)
          if (e%exits(k)%exited) cycle
          te = e%loads(k)%t_exit
          if (.not. (te > t0 .and. te <= min(t1, t_end))) cycle
          call st%value_at(te, x)
          if (model%d%n_prescribed > 0) then
            call model%impose(te, x(1:n), x(n+1:))
            x(1:n) = model%wk%qx; x(n+1:) = model%wk%qdx
          end if
          call record_exit(e, k, model%d, model%wk, te, x(1:n), x(n+1:))
        end do
      end select
    end do
  end subroutine note_exits

  !> The first exit time after t of a load still on its body (huge: none).
  real(dp) function next_exit(model, t) result(te)
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: t
    integer :: i, k
    te = huge(1.0_dp)
    do i = 1, size(model%effects)
      select type (e => model%effects(i)%e)
      type is (moving_load_effect)
        do k = 1, size(e%loads)
          if (.not. e%exits(k)%exited .and. e%loads(k)%t_exit > t) te = min(te, e%loads(k)%t_exit)
        end do
      end select
    end do
  end function next_exit

  !> Summary lines: per moving load its exit time (through the tip, a shot exit, or the
  !> root) and its body's markers' states there, or that it did not leave the body by t_end.
  function exits_text(model, t_end) result(s)
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: t_end
    character(len=:), allocatable :: s
    integer :: i, k, j
    s = ''
    do i = 1, size(model%effects)
      select type (e => model%effects(i)%e)
      type is (moving_load_effect)
        do k = 1, size(e%loads)
          associate(x => e%exits(k))
            if (.not. x%exited) then
              s = s // "moving load '" // trim(e%loads(k)%name) // "': did not leave its body by t = " // &
                & fmt(t_end) // ' s' // new_line('a'); cycle
            end if
            if (e%loads(k)%exit_at_root) then
              s = s // "moving load '" // trim(e%loads(k)%name) // "': left its body through its root (s = 0) " // &
                & 'at t = ' // fmt(x%t) // ' s' // new_line('a')
            else
              s = s // "moving load '" // trim(e%loads(k)%name) // "': shot exit at t = " // fmt(x%t) // ' s' // &
                & new_line('a')
            end if
            do j = 1, size(x%markers)
              s = s // "  marker '" // trim(model%d%markers%name(x%markers(j))) // "' at exit: position " // &
                & vec(x%r(:, j)) // ' m, velocity ' // vec(x%v(:, j)) // ' m/s, angle ' // vec(x%angle(:, j)) // &
                & ' rad, angular rate ' // vec(x%rate(:, j)) // ' rad/s' // new_line('a')
            end do
          end associate
        end do
      end select
    end do
  end function exits_text

  !> The JSON member "moving_loads" (with its comma; empty without moving loads): per load
  !> its name, "exited", "t_exit" and "exit_end" ('tip' or 'root'; null when it did not
  !> leave) and "markers_at_exit".
  function exits_json(model) result(s)
    type(model_t), intent(in) :: model
    character(len=:), allocatable :: s, items
    integer :: i, k, j
    s = ''; items = ''
    do i = 1, size(model%effects)
      select type (e => model%effects(i)%e)
      type is (moving_load_effect)
        do k = 1, size(e%loads)
          associate(x => e%exits(k))
            if (len(items) > 0) items = items // ', '
            items = items // '{"name": "' // json_escape(trim(e%loads(k)%name)) // '", "exited": ' // &
              & merge('true ', 'false', x%exited)
            if (.not. x%exited) then
              items = items // ', "t_exit": null, "exit_end": null, "markers_at_exit": {}}'; cycle
            end if
            items = trim(items) // ', "t_exit": ' // num(x%t) // ', "exit_end": "' // &
              & trim(merge('root', 'tip ', e%loads(k)%exit_at_root)) // '", "markers_at_exit": {'
            do j = 1, size(x%markers)
              if (j > 1) items = items // ', '
              items = items // '"' // json_escape(trim(model%d%markers%name(x%markers(j)))) // '": {"position": ' // &
                & arr(x%r(:, j)) // ', "velocity": ' // arr(x%v(:, j)) // ', "angle": ' // arr(x%angle(:, j)) // &
                & ', "angular_rate": ' // arr(x%rate(:, j)) // '}'
            end do
            items = items // '}}'
          end associate
        end do
      end select
    end do
    if (len(items) > 0) s = '  "moving_loads": [' // items // '],' // new_line('a')
  end function exits_json

  !> A number as JSON, exactly (es25.17 dropped the E of a three-digit exponent: 6.7-204,
  !> which no JSON reader takes).
  function num(v) result(s)
    real(dp), intent(in) :: v
    character(len=:), allocatable :: s
    s = exact_text(v)
  end function num

  !> A 3-vector as a JSON array.
  function arr(v) result(s)
    real(dp), intent(in) :: v(3)
    character(len=:), allocatable :: s
    s = '[' // num(v(1)) // ', ' // num(v(2)) // ', ' // num(v(3)) // ']'
  end function arr

  !> A 3-vector for the summary.
  function vec(v) result(s)
    real(dp), intent(in) :: v(3)
    character(len=:), allocatable :: s
    character(len=48) :: buf
    write(buf, '(3es13.5e3)') v
    s = '(' // trim(adjustl(buf)) // ')'
  end function vec
end module pymr_driver_moving_load_exits
