!> Geometric stiffening of beams: by their own axial load (gravity, the axial acceleration
!> of their frame and their rotation's centrifugal load), and by the bodies they carry.
module pymr_model_effect_geometric_stiffening
  use pymr_env_kinds, only : dp
  use pymr_model_types, only : model_data, model_work
  use pymr_model_effect, only : effect_t, stage_load, stage_carried
  implicit none
  private
  public :: stiffening_effect, stiffening_effect_of

  type, extends(effect_t) :: stiffening_effect
    !> Gravity (m/s^2, inertial; 0 when the gravity effect is off).
    real(dp) :: g(3) = 0.0_dp
    !> Bodies jointed to a beam with geometric stiffness, and the beam's geometric stiffness
    !> per newton of the axial load such a body puts on it (mmax, mmax, nb).
    logical, allocatable :: child_kg(:)
    real(dp), allocatable :: kgc(:, :, :)
  contains
    procedure :: load => own_load_stiffening
    procedure :: carried => carried_load_stiffening
  end type stiffening_effect

contains

  include 'vector_products.inc'

  function stiffening_effect_of(g, child_kg, kgc) result(e)
    real(dp), intent(in) :: g(3), kgc(:, :, :)
    logical, intent(in) :: child_kg(:)
    type(stiffening_effect) :: e
    e%name = 'geometric_stiffening'
    e%acts([stage_load, stage_carried]) = .true.
    e%g = g
    e%child_kg = child_kg
    e%kgc = kgc
  end function stiffening_effect_of

  !> Geometric stiffening of beams by their axial load (after body_terms). A beam along its
  !> x axis carries the tension N(x) = rho A [(g_x - a0_x)(L - x) + (w_y^2 + w_z^2)(L^2 - x^2)/2]
  !> from gravity, the axial acceleration a0_x of its frame origin (velocity terms only: the
  !> part proportional to the accelerations is not known before the solve) and the
  !> centrifugal load of its rotation (body-frame components). Its modal stiffness
  !> K_G = (g_x - a0_x) kg1 + (w_y^2 + w_z^2) kg2 adds K_G a to the modal bias.
  subroutine own_load_stiffening(self, d, wk, t, q, qd, mask)
    class(stiffening_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: mask(:)
    integer :: b, m, k
    real(dp) :: wb(3), pd(3), alv(3), gb(3), c1, c2
    do b = 2, d%nb
      if (.not. allocated(d%flex(b)%kg1) .or. .not. mask(b)) cycle
      m = d%nm(b)
      associate(rot => wk%rot(:, :, b), pos => wk%pos(:, b), vel => wk%vel(:, b), acc => wk%acc(:, b))
        wb = matmul(transpose(rot), vel(4:6))
        pd = vel(1:3) + cross(vel(4:6), pos)
        alv = matmul(transpose(rot), acc(1:3) + cross(acc(4:6), pos) + cross(vel(4:6), pd))
        gb = matmul(transpose(rot), self%g)
      end associate
      c1 = gb(1) - alv(1)
      c2 = wb(2)**2 + wb(3)**2
      associate(a => q(d%a0(b):d%a0(b) + m - 1))
        do k = 1, m
          wk%wam(k, b) = wk%wam(k, b) + c1*dot_product(d%flex(b)%kg1(:, k), a) + c2*dot_product(d%flex(b)%kg2(:, k), a)
          wk%kam(k, b) = wk%kam(k, b) + c1*d%flex(b)%kg1(k, k) + c2*d%flex(b)%kg2(k, k)
        end do
      end associate
    end do
  end subroutine own_load_stiffening

  !> Geometric stiffening of beams by the bodies they carry (after composite_terms): a body
  !> c jointed to beam b at x_c pulls on it with the force -f_c, f_c the composite bias
  !> wrench's force of c's subtree (its weight, applied loads and velocity-term inertia;
  !> the part proportional to the accelerations is not known before the solve). Its
  !> component along the beam axis is a tension N_c = -x_b . f_c on [0, x_c], adding
  !> N_c kgc_c a to the beam's modal bias.
  subroutine carried_load_stiffening(self, d, wk, q, mask)
    class(stiffening_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: q(:)
    logical, intent(in) :: mask(:)
    integer :: c, b, m, k
    real(dp) :: tension
    do c = 2, d%nb
      if (.not. self%child_kg(c) .or. .not. mask(c)) cycle
      b = d%parent(c)
      m = d%nm(b)
      tension = -dot_product(wk%rot(:, 1, b), wk%wc(1:3, c))
      associate(a => q(d%a0(b):d%a0(b) + m - 1))
        do k = 1, m
          wk%wam(k, b) = wk%wam(k, b) + tension*dot_product(self%kgc(k, 1:m, c), a)
          wk%kam(k, b) = wk%kam(k, b) + tension*self%kgc(k, k, c)
        end do
      end associate
    end do
  end subroutine carried_load_stiffening
end module pymr_model_effect_geometric_stiffening
