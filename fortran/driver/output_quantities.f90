!> The values of a result row beyond the coordinates (&output quantities), and the works
!> that the energy columns integrate over the run. Only the groups the plan asks for are
!> computed. Evaluations made for the output are not counted as the integrator's.
module pymr_driver_output_quantities
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_text, only : fmt
  use pymr_model, only : model_t, model_counters
  use pymr_model_types, only : model_data, model_work
  use pymr_model_kinematics, only : forward_kinematics, marker_motion, marker_acceleration, marker_rotation
  use pymr_model_sensors, only : sensor_values, sensor_width
  use pymr_model_reactions, only : body_accelerations, joint_wrenches, child_frame_wrench
  use pymr_model_loops, only : cut_wrench, cut_body_wrenches
  use pymr_model_effect, only : effect_powers, effect_powers_qdd, effects_need_qdd, power_motion
  use pymr_model_spatial, only : quaternion
  use pymr_integrator_stepper, only : stepper_t
  use pymr_io_results_output, only : output_plan, n_energy, n_work, row_width, row_values, header_line
  use pymr_io_results_file, only : results_file, column_name
  implicit none
  private
  public :: write_output_row, work_at, imposed_state

  !> Gauss-Legendre nodes (on [-1, 1]) and weights of the work integrals over a step:
  !> exact for polynomials of degree 5, beyond the dense output's order.
  real(dp), parameter :: gauss_x(3) = [-0.7745966692414834_dp, 0.0_dp, 0.7745966692414834_dp]
  real(dp), parameter :: gauss_w(3) = [5.0_dp/9.0_dp, 8.0_dp/9.0_dp, 5.0_dp/9.0_dp]

contains

  !> Write the row of time t and state (q, qd): prescribed coordinates are written (and
  !> move the bodies) exactly as their functions; `work` holds the works of the energy columns.
  subroutine write_output_row(out, model, t, q, qd, work, error)
    class(results_file), intent(inout) :: out
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, q(:), qd(:), work(n_work)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: qe(size(q)), qde(size(qd)), extra(out%plan%extra)
    call imposed_state(model, t, q, qd, qe, qde)
    call output_values(out%plan, model, t, qe, qde, work, extra, error)
    if (allocated(error)) return
    call check_row_finite(out%plan, model%d, t, qe, qde, extra, error); if (allocated(error)) return
    call out%write_row(model%d, t, qe, qde, extra)
  end subroutine write_output_row

  !> A run writes finite numbers only: a value that overflowed (an energy column of a motion
  !> that grows beyond bounds while its state is still finite) fails the run at its row's
  !> time, naming the column, before the row is written.
  subroutine check_row_finite(plan, d, t, q, qd, extra, error)
    type(output_plan), intent(in) :: plan
    type(model_data), intent(in) :: d
    real(dp), intent(in) :: t, q(:), qd(:), extra(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: row(:)
    integer :: k
    if (all(abs(extra) <= huge(1.0_dp)) .and. (.not. plan%coordinates .or. &
      & (all(abs(q) <= huge(1.0_dp)) .and. all(abs(qd) <= huge(1.0_dp))))) return
    allocate(row(row_width(plan, d)))
    call row_values(plan, d, t, q, qd, extra, row)
    k = findloc(abs(row) <= huge(1.0_dp), .false., 1)
    call fatal_error(error, 'at t = ' // fmt(t) // ' s: the results'' column ' // &
      & column_name(header_line(plan, d), k) // ' is ' // fmt(row(k)) // ', not a finite number: the motion ' // &
      & 'has grown beyond what can be written (an unstable step, or a force that grows without bound)', stat_solver)
  end subroutine check_row_finite

  !> The state with the prescribed coordinates on their functions.
  subroutine imposed_state(model, t, q, qd, qe, qde)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(out) :: qe(:), qde(:)
    if (model%d%n_prescribed > 0) then
      call model%impose(t, q, qd)
      qe = model%wk%qx; qde = model%wk%qdx
    else
      qe = q; qde = qd
    end if
  end subroutine imposed_state

  !> The plan's values after the coordinates: per marker its position and velocity,
  !> acceleration and orientation; per joint its reaction; the energies and works.
  subroutine output_values(plan, model, t, q, qd, work, v, error)
    type(output_plan), intent(in) :: plan
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, q(:), qd(:), work(n_work)
    real(dp), intent(out) :: v(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: qdd(size(q)), lin(6, model%d%nb), jw(6, model%d%nb), e(4), r(3), vel(3), a(3), rm(3, 3)
    integer :: k, i, b
    if (plan%accelerations .or. plan%reactions) then
      call output_accelerations(model, t, q, qd, qdd, error); if (allocated(error)) return
      call body_accelerations(model%d, model%wk, qdd, lin)
      if (plan%reactions) call tree_joint_wrenches(model%d, model%wk, qdd, lin, jw)
    else if (plan%markers .or. plan%orientations) then
      call forward_kinematics(model%d, model%wk, q, qd)
    end if
    k = 0
    associate(d => model%d, wk => model%wk)
      do i = 1, d%markers%n
        if (.not. (plan%markers .or. plan%accelerations .or. plan%orientations)) exit
        call marker_motion(d, wk, i, q, qd, r, vel)
        if (plan%markers) call put([r, vel])
        if (plan%accelerations) then
          b = d%markers%body(i)
          call marker_acceleration(d, wk, i, qd, qdd, wk%acc(:, b) + lin(:, b), r, vel, a)
          call put(a)
        end if
        if (plan%orientations) then
          call marker_rotation(d, wk, i, q, rm)
          call put(quaternion(rm))
        end if
      end do
      do b = 2, d%nb
        if (plan%reactions) call put(child_frame_wrench(d, wk, b, jw(:, b)))
      end do
      do i = 1, d%cuts%n
        if (plan%reactions) call put(cut_wrench(d, wk, i))
      end do
    end associate
    if (plan%energy) then
      call model%energy_parts(q, qd, e, t)
      call put([e, sum(e), work])
    end if
    if (plan%sensors%n > 0) then
      call forward_kinematics(model%d, model%wk, q, qd)
      call sensor_values(plan%sensors, model%d, model%wk, q, qd, v(k+1:k+sensor_width(plan%sensors)))
    end if
  contains
    subroutine put(x)
      real(dp), intent(in) :: x(:)
      v(k+1:k+size(x)) = x
      k = k + size(x)
    end subroutine put
  end subroutine output_values

  !> The tree joints' wrenches (reactions.f90) after an evaluation at accelerations qdd, the
  !> loop-closing joints' forces counted as loads on their bodies.
  subroutine tree_joint_wrenches(d, wk, qdd, lin, jw)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: qdd(:), lin(:, :)
    real(dp), intent(out) :: jw(:, :)
    real(dp) :: ext(6, d%nb)
    if (d%cuts%n == 0) then
      call joint_wrenches(d, wk, qdd, lin, jw); return
    end if
    call cut_body_wrenches(d, wk, ext)
    call joint_wrenches(d, wk, qdd, lin, jw, ext)
  end subroutine tree_joint_wrenches

  !> Accelerations at (t, q, qd) for the output, leaving the model's counters as they were.
  subroutine output_accelerations(model, t, q, qd, qdd, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(out) :: qdd(:)
    type(error_type), allocatable, intent(out) :: error
    type(model_counters) :: c
    c = model%counters()
    call model%accelerations(t, q, qd, qdd, error)
    call model%set_counters(c)
  end subroutine output_accelerations

  !> The works at time t (in the stepper's last step, which t0 is in too) from those at t0:
  !> work = work0 plus the integrals from t0 to t of the powers of the drives, the loads and
  !> the prescribed motions and of the damping's loss, by 3-point Gauss quadrature of the
  !> stepper's dense output. Nothing without energy output.
  subroutine work_at(plan, st, model, t0, work0, t, work, error)
    type(output_plan), intent(in) :: plan
    class(stepper_t), intent(in) :: st
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t0, work0(n_work), t
    real(dp), intent(out) :: work(n_work)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: x(2*model%d%n), tn, p(n_work)
    integer :: i, n
    work = work0
    if (.not. plan%energy .or. t == t0) return
    n = model%d%n
    do i = 1, 3
      tn = 0.5_dp*(t0 + t) + 0.5_dp*(t - t0)*gauss_x(i)
      call st%value_at(tn, x)
      call powers(model, tn, x(1:n), x(n+1:), p, error); if (allocated(error)) return
      work = work + 0.5_dp*(t - t0)*gauss_w(i)*p
    end do
  end subroutine work_at

  !> Powers at (t, q, qd) (W): of the drives, of the loads, of the prescribed motions (and
  !> the travel of moving loads), and the damping's loss (joint dampers and modal damping).
  subroutine powers(model, t, q, qd, p, error)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(out) :: p(n_work)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: qe(size(q)), qde(size(qd)), qdd(size(q))
    call imposed_state(model, t, q, qd, qe, qde)
    p = 0.0_dp
    call effect_powers(model%effects, model%d, model%wk, t, qe, qde, p)
    if (model%d%n_prescribed > 0) then
      p(power_motion) = p(power_motion) + motion_power(model, t, qe, qde, error); if (allocated(error)) return
    end if
    if (effects_need_qdd(model%effects)) then
      call output_accelerations(model, t, qe, qde, qdd, error); if (allocated(error)) return
      call effect_powers_qdd(model%effects, model%d, model%wk, t, qe, qde, qdd, p)
    end if
  end subroutine powers

  !> Power of the prescribed motions: each prescribed coordinate's generalised force beyond
  !> the drive and spring on it (s_k . J_b - tau_k) times its rate.
  real(dp) function motion_power(model, t, q, qd, error) result(p)
    type(model_t), intent(inout) :: model
    real(dp), intent(in) :: t, q(:), qd(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: qdd(size(q)), lin(6, model%d%nb), jw(6, model%d%nb)
    integer :: k
    p = 0.0_dp
    call output_accelerations(model, t, q, qd, qdd, error); if (allocated(error)) return
    call body_accelerations(model%d, model%wk, qdd, lin)
    call tree_joint_wrenches(model%d, model%wk, qdd, lin, jw)
    associate(d => model%d, wk => model%wk)
      do k = 1, d%n
        if (.not. d%prescribed(k)) cycle
        p = p + (dot_product(wk%s(:, k), jw(:, d%cbody(k))) - wk%tau(k))*qd(k)
      end do
    end associate
  end function motion_power
end module pymr_driver_output_quantities
