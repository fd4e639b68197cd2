!> Modal damping of the flexible bodies: forces (2 zeta omega + alpha + beta omega^2) ad
!> added to their modal bias.
module pymr_model_effect_modal_damping
  use pymr_env_kinds, only : dp
  use pymr_model_types, only : model_data, model_work
  use pymr_model_effect, only : effect_t, stage_load, power_damping
  implicit none
  private
  public :: modal_damping_effect, modal_damping_effect_of

  type, extends(effect_t) :: modal_damping_effect
  contains
    procedure :: load => damping_load
    procedure :: add_power => damping_power
    procedure :: fast_damping => damping_fast
  end type modal_damping_effect

contains

  function modal_damping_effect_of() result(e)
    type(modal_damping_effect) :: e
    e%name = 'modal_damping'
    e%acts(stage_load) = .true.
  end function modal_damping_effect_of

  subroutine damping_load(self, d, wk, t, q, qd, mask)
    class(modal_damping_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: mask(:)
    integer :: b, m
    do b = 2, d%nb
      m = d%nm(b)
      if (m == 0 .or. .not. mask(b)) cycle
      wk%wam(1:m, b) = wk%wam(1:m, b) + d%flex(b)%damp*qd(d%a0(b):d%a0(b) + m - 1)
    end do
  end subroutine damping_load

  !> The damping's loss, sum damp ad^2 (W).
  subroutine damping_power(self, d, wk, t, q, qd, p)
    class(modal_damping_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(inout) :: p(:)
    integer :: b, m
    do b = 2, d%nb
      m = d%nm(b)
      if (m > 0) p(power_damping) = p(power_damping) + sum(d%flex(b)%damp*qd(d%a0(b):d%a0(b) + m - 1)**2)
    end do
  end subroutine damping_power

  !> The damping per fast (modal) coordinate.
  subroutine damping_fast(self, d, df)
    class(modal_damping_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    real(dp), intent(inout) :: df(:)
    integer :: b, m, f0
    do b = 2, d%nb
      m = d%nm(b)
      if (m == 0) cycle
      f0 = d%a0(b) - d%nj
      df(f0:f0 + m - 1) = d%flex(b)%damp
    end do
  end subroutine damping_fast
end module pymr_model_effect_modal_damping
