!> Deformation inertia 'full': the flexible bodies' modal moments follow their deformation
!> (before the body terms).
module pymr_model_effect_deformation_inertia
  use pymr_env_kinds, only : dp
  use pymr_model_types, only : model_data, model_work
  use pymr_model_flexbody, only : deformed_modal_moments
  use pymr_model_effect, only : effect_t, stage_deform
  implicit none
  private
  public :: deformation_effect, deformation_effect_of, deform_moments

  type, extends(effect_t) :: deformation_effect
  contains
    procedure :: deform => deformation_deform
  end type deformation_effect

contains

  function deformation_effect_of() result(e)
    type(deformation_effect) :: e
    e%name = 'deformation_inertia'
    e%acts(stage_deform) = .true.
  end function deformation_effect_of

  subroutine deformation_deform(self, d, wk, q, mask)
    class(deformation_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: q(:)
    logical, intent(in) :: mask(:)
    call deform_moments(d, wk, q, mask)
  end subroutine deformation_deform

  !> The deformed modal moments of the flexible bodies in `mask`.
  pure subroutine deform_moments(d, wk, q, mask)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: q(:)
    logical, intent(in) :: mask(:)
    integer :: b
    do b = 2, d%nb
      if (d%nm(b) == 0 .or. .not. mask(b)) cycle
      call deformed_modal_moments(d%flex(b), wk%fwork(b), q(d%a0(b):d%a0(b) + d%nm(b) - 1))
    end do
  end subroutine deform_moments
end module pymr_model_effect_deformation_inertia
