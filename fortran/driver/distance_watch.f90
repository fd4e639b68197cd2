!> How far from the inertial origin a scene's bodies may be: the rule, checked at the
!> initial state by the pre-flight check (preflight.f90, check_resolved) and during the run
!> by the watch here.
!>
!> The recursive algorithms take the bodies' inertias about the inertial origin: a body of
!> mass m at distance r carries m r^2 there, and a coordinate's inertia is what is left of
!> the bodies it moves after the cancellation, with the roundoff epsilon sum m r^2
!> (subtree_roundoff). It must exceed `resolved` times that roundoff (4 digits). A block
!> pushed to 1e7 m with an arm of 0.35 kg m^2 about its hinge ran with exit 0 and its
!> accelerations off by 4e-4, then failed as 'articulated inertia 0'. Joints that slide lose
!> nothing that way (their inertia is the mass) and are not checked.
module pymr_driver_distance_watch
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_text, only : fmt
  use pymr_model, only : model_t
  use pymr_model_types, only : prim_revolute
  use pymr_model_spatial, only : cross
  use pymr_model_flexbody, only : central_inertia
  implicit none
  private
  public :: resolved, subtree_roundoff

  !> A coordinate's inertia must exceed this many times the roundoff of the inertia about
  !> the origin of the bodies it moves: 4 digits.
  real(dp), parameter :: resolved = 1.0e4_dp

  !> The watch: the distance from the origin (the farthest body origin) beyond which the
  !> turning joints are checked again. Set by each check to a tenth of the distance where
  !> the bodies of each joint, all at it, would meet the rule (sqrt(J / (resolved epsilon
  !> M)), M their mass): below, the roundoff is a hundredth of the rule's margin (a change
  !> of pose that cuts a joint's inertia a hundredfold is not seen until the next check). A
  !> check after every step cost a quarter of a tank's run, one at every row 4 %.
  type, public :: distance_watch
    real(dp) :: x_check = -1.0_dp
  contains
    procedure :: after_step
    procedure, private :: check_joints
  end type distance_watch

  !> What a joint turns (a body and the bodies after it): mass, centre of mass and inertia
  !> about it (inertial axes).
  type :: composite
    real(dp) :: m = 0.0_dp, x(3) = 0.0_dp, j(3, 3) = 0.0_dp
  end type composite

contains

  !> Roundoff of the inertia about the inertial origin of each body and those beyond it
  !> (kg m^2), at the model's last evaluated poses: a body of mass m whose origin is at
  !> distance r carries m r^2 there, and its own inertia is what is left after the
  !> cancellation, epsilon of the sum of those m r^2.
  function subtree_roundoff(model) result(e)
    type(model_t), intent(in) :: model
    real(dp) :: e(model%d%nb)
    integer :: b
    e = 0.0_dp
    do b = 2, model%d%nb
      e(b) = model%d%mass(b)*sum(model%wk%pos(:, b)**2)
    end do
    do b = model%d%nb, 2, -1
      if (model%d%parent(b) > 1) e(model%d%parent(b)) = e(model%d%parent(b)) + e(b)
    end do
    e = epsilon(1.0_dp)*e
  end function subtree_roundoff

  !> After a step to time t: the joints checked when a body has gone beyond x_check.
  subroutine after_step(self, model, t, error)
    class(distance_watch), intent(inout) :: self
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: t
    type(error_type), allocatable, intent(out) :: error
    if (farthest(model) > self%x_check) call self%check_joints(model, t, error)
  end subroutine after_step

  !> The turning joints at the model's last evaluated state (its work's poses and axes) at
  !> time t: a failed run when one's inertia about its axis is within `resolved` times the
  !> roundoff of the bodies it moves; else x_check set.
  subroutine check_joints(self, model, t, error)
    class(distance_watch), intent(inout) :: self
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: t
    type(error_type), allocatable, intent(out) :: error
    type(composite) :: c(model%d%nb)
    real(dp) :: e(model%d%nb), u(3), p0(3), jaxis
    integer :: b, k
    e = subtree_roundoff(model)
    self%x_check = huge(1.0_dp)
    do b = model%d%nb, 2, -1
      c(b) = combined(c(b), own(model, b))
      if (model%d%parent(b) > 1) c(model%d%parent(b)) = combined(c(model%d%parent(b)), c(b))
    end do
    do b = 2, model%d%nb
      do k = model%d%c0(b), model%d%c0(b) + model%d%nc(b) - 1
        if (model%d%prim(k) /= prim_revolute) cycle
        u = model%wk%s(4:6, k)
        p0 = cross(u, model%wk%s(1:3, k))              ! the axis's point nearest the origin
        jaxis = dot_product(u, matmul(c(b)%j, u)) + c(b)%m*sum(cross(u, c(b)%x - p0)**2)
        if (.not. (jaxis > 0.0_dp)) cycle
        self%x_check = min(self%x_check, 0.1_dp*sqrt(jaxis/(resolved*epsilon(1.0_dp)*c(b)%m)))
        if (jaxis > resolved*e(b)) cycle
        call fatal_error(error, 'at t = ' // fmt(t) // ' s: coordinate ' // trim(model%d%qname(k)) // &
          & ' moves an inertia of ' // fmt(jaxis) // ' kg m^2, within ' // fmt(resolved) // ' times the ' // &
          & 'roundoff (' // fmt(e(b)) // ') of the inertia about the inertial origin of the bodies it moves, ' // &
          & 'which pymr assembles about (their m r^2 up to ' // fmt(e(b)/epsilon(1.0_dp)) // ' kg m^2): the ' // &
          & 'motion has gone too far from the origin (place the origin nearer)', stat_solver)
        return
      end do
    end do
  end subroutine check_joints

  !> The farthest body origin from the inertial origin at the last evaluated state (m).
  pure real(dp) function farthest(model)
    type(model_t), intent(in) :: model
    integer :: b
    farthest = 0.0_dp
    do b = 2, model%d%nb
      farthest = max(farthest, norm2(model%wk%pos(:, b)))
    end do
  end function farthest

  !> Body b alone at its last evaluated pose (a flexible body undeformed).
  function own(model, b) result(c)
    type(model_t), intent(in) :: model
    integer, intent(in) :: b
    type(composite) :: c
    real(dp) :: com(3), jc(3, 3)
    if (model%d%nm(b) > 0) then
      c%m = model%d%flex(b)%mass; com = model%d%flex(b)%first(:, 0)/c%m
      jc = central_inertia(model%d%flex(b))
    else
      c%m = model%d%mass(b); com = model%d%com(:, b); jc = model%d%inertia(:, :, b)
    end if
    associate (r => model%wk%rot(:, :, b))
      c%x = model%wk%pos(:, b) + matmul(r, com)
      c%j = matmul(r, matmul(jc, transpose(r)))
    end associate
  end function own

  !> Two composites as one: the inertias moved to the common centre of mass (parallel axes;
  !> the offsets are differences of nearby points, exact to their rounding).
  pure function combined(a, b) result(c)
    type(composite), intent(in) :: a, b
    type(composite) :: c
    if (a%m <= 0.0_dp) then
      c = b; return
    end if
    c%m = a%m + b%m
    c%x = a%x + (b%m/c%m)*(b%x - a%x)
    c%j = a%j + shifted(a%m, a%x - c%x) + b%j + shifted(b%m, b%x - c%x)
  end function combined

  !> The inertia of a point mass m at offset d: m (|d|^2 I - d d^T).
  pure function shifted(m, d) result(j)
    real(dp), intent(in) :: m, d(3)
    real(dp) :: j(3, 3)
    integer :: i
    j = -m*spread(d, 2, 3)*spread(d, 1, 3)
    do i = 1, 3
      j(i, i) = j(i, i) + m*dot_product(d, d)
    end do
  end function shifted
end module pymr_driver_distance_watch
