!> Prescribed (base) motion: joint coordinates that follow functions of time, a sine, a
!> smooth spin-up to a constant rate, or a table (cubic spline). They take their
!> functions' values before the kinematics, and their rows of M qdd = P become qdd = f''(t).
module pymr_model_effect_base_motion
  use pymr_env_kinds, only : dp, pi
  use pymr_model_types, only : model_work
  use pymr_model_time_table, only : time_table, table_spline
  use pymr_model_effect, only : effect_t, stage_impose, stage_rows, stage_accelerate
  implicit none
  private
  public :: prescribed_motion, base_motion_effect, base_motion_effect_of
  public :: motion_sine, motion_spinup, motion_table

  !> Forms of a prescribed coordinate's time function.
  integer, parameter :: motion_sine = 1, motion_spinup = 2, motion_table = 3

  !> One prescribed coordinate: its coordinate, form, offset (m or rad), and for a sine its
  !> amplitude, frequency (Hz) and phase (rad), for a spin-up its rate and ramp time (s),
  !> for a table the table.
  type :: prescribed_motion
    integer :: coord = 0, form = motion_sine
    real(dp) :: offset = 0.0_dp, amplitude = 0.0_dp, frequency = 0.0_dp, phase = 0.0_dp
    real(dp) :: rate = 0.0_dp, ramp_time = 0.0_dp
    type(time_table) :: table
  end type prescribed_motion

  type, extends(effect_t) :: base_motion_effect
    type(prescribed_motion), allocatable :: motions(:)
  contains
    procedure :: impose => motion_impose
    procedure :: rows => motion_rows
    procedure :: accelerate => motion_accelerate
  end type base_motion_effect

contains

  function base_motion_effect_of(motions) result(e)
    type(prescribed_motion), intent(in) :: motions(:)
    type(base_motion_effect) :: e
    e%name = 'base_motion'
    e%acts([stage_impose, stage_rows, stage_accelerate]) = .true.
    e%motions = motions
  end function base_motion_effect_of

  !> Value, rate and acceleration at time t of a prescribed coordinate.
  pure subroutine motion_at(mo, t, f, fd, fdd)
    type(prescribed_motion), intent(in) :: mo
    real(dp), intent(in) :: t
    real(dp), intent(out) :: f, fd, fdd
    real(dp) :: w
    select case (mo%form)
    case (motion_table)
      call table_spline(mo%table, t, f, fd, fdd)
      f = f + mo%offset
    case (motion_spinup)
      call spinup_at(mo, t, f, fd, fdd)
    case default
      w = 2.0_dp*pi*mo%frequency
      f = mo%offset + mo%amplitude*sin(w*t + mo%phase)
      fd = mo%amplitude*w*cos(w*t + mo%phase)
      fdd = -mo%amplitude*w**2*sin(w*t + mo%phase)
    end select
  end subroutine motion_at

  !> theta = (rate/T)[t^2/2 + (T/2 pi)^2 (cos(2 pi t/T) - 1)] up to the ramp time T, then
  !> a constant rate. Written in the ramp's fraction s = t/T, so that no T, however short,
  !> overflows a frequency 2 pi/T.
  pure subroutine spinup_at(mo, t, f, fd, fdd)
    type(prescribed_motion), intent(in) :: mo
    real(dp), intent(in) :: t
    real(dp), intent(out) :: f, fd, fdd
    real(dp) :: s, a
    if (t <= mo%ramp_time) then
      s = t/mo%ramp_time
      a = 2.0_dp*pi*s
      f = mo%offset + mo%rate*mo%ramp_time*(0.5_dp*s**2 + (cos(a) - 1.0_dp)/(2.0_dp*pi)**2)
      fd = mo%rate*(s - sin(a)/(2.0_dp*pi))
      fdd = 0.0_dp
      if (mo%rate /= 0.0_dp .and. cos(a) < 1.0_dp) fdd = (mo%rate/mo%ramp_time)*(1.0_dp - cos(a))
    else
      f = mo%offset + mo%rate*(t - 0.5_dp*mo%ramp_time)
      fd = mo%rate
      fdd = 0.0_dp
    end if
  end subroutine spinup_at

  !> The prescribed coordinates of (q, qd) set to their functions at t.
  subroutine motion_impose(self, t, q, qd)
    class(base_motion_effect), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: q(:), qd(:)
    integer :: i
    real(dp) :: fdd
    do i = 1, size(self%motions)
      associate(k => self%motions(i)%coord)
        call motion_at(self%motions(i), t, q(k), qd(k), fdd)
      end associate
    end do
  end subroutine motion_impose

  !> After assembly: each prescribed coordinate j gets the equation qdd_j = f''(t). Its known
  !> acceleration moves to the right-hand side of the other rows and its row and column
  !> are cleared (M stays symmetric positive definite).
  subroutine motion_rows(self, wk, t)
    class(base_motion_effect), intent(in) :: self
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t
    integer :: i, j
    real(dp) :: f, fd, fdd
    do i = 1, size(self%motions)
      j = self%motions(i)%coord
      call motion_at(self%motions(i), t, f, fd, fdd)
      wk%p = wk%p - wk%mm(:, j)*fdd
      wk%mm(:, j) = 0.0_dp
      wk%mm(j, :) = 0.0_dp
      wk%mm(j, j) = 1.0_dp
      wk%p(j) = fdd
    end do
  end subroutine motion_rows

  !> The prescribed coordinates' accelerations (their functions' second derivatives).
  subroutine motion_accelerate(self, wk, t, qdd)
    class(base_motion_effect), intent(in) :: self
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: qdd(:)
    integer :: i
    real(dp) :: f, fd
    do i = 1, size(self%motions)
      call motion_at(self%motions(i), t, f, fd, qdd(self%motions(i)%coord))
    end do
  end subroutine motion_accelerate
end module pymr_model_effect_base_motion
