!> The watch on how far the bodies go from the inertial origin during a run.
!>
!> The recursive algorithms (model/articulated.f90, model/assembly.f90) take the bodies'
!> inertias about the inertial origin: their entries grow as the sum S of m |x|^2 over the
!> bodies a joint turns (x each centre of mass), and the joint's inertia about its axis, J,
!> comes out of their differences. It then keeps epsilon S / J of itself fewer: a block
!> pushed to 1e7 m with an arm of 0.35 kg m^2 about its hinge (epsilon S / J = 0.06) ran
!> with 3 % error in its accelerations and exit 0, then failed as 'articulated inertia 0'.
!> Joints that slide lose nothing that way (their inertia is the mass).
module pymr_driver_distance_watch
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_text, only : fmt
  use pymr_model, only : model_t
  use pymr_model_types, only : prim_revolute
  use pymr_model_spatial, only : cross
  implicit none
  private

  !> The share of a joint's inertia about its axis that may be lost: a run stops before it
  !> keeps fewer than 6 significant digits.
  real(dp), parameter :: most_lost = 1.0e-6_dp

  !> The watch: the distance from the origin (the farthest body origin) beyond which the
  !> joints are checked again. Set by each check where they would lose a hundredth of
  !> most_lost, their loss growing as the distance squared (a change of pose that cuts a
  !> joint's inertia a hundredfold at the same distance is not seen). A check after every
  !> step cost a quarter of a tank's run, one at every row 4 %.
  type, public :: distance_watch
    real(dp) :: x_check = -1.0_dp
  contains
    procedure :: after_step
    procedure, private :: check_joints
  end type distance_watch

  !> What a joint turns (a body and the bodies after it): mass, centre of mass, inertia
  !> about it (inertial axes) and the sum S of m |x|^2 over the bodies.
  type :: composite
    real(dp) :: m = 0.0_dp, x(3) = 0.0_dp, j(3, 3) = 0.0_dp, s = 0.0_dp
  end type composite

contains

  !> After a step to time t: the joints checked when a body has gone beyond x_check.
  subroutine after_step(self, model, t, error)
    class(distance_watch), intent(inout) :: self
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: t
    type(error_type), allocatable, intent(out) :: error
    if (farthest(model) > self%x_check) call self%check_joints(model, t, error)
  end subroutine after_step

  !> The joints at the model's last evaluated state (its work's poses and axes) at time t:
  !> a failed run when one that turns has lost more than most_lost of its inertia; else
  !> x_check set from the most any has lost.
  subroutine check_joints(self, model, t, error)
    class(distance_watch), intent(inout) :: self
    type(model_t), intent(in) :: model
    real(dp), intent(in) :: t
    type(error_type), allocatable, intent(out) :: error
    type(composite) :: c(model%d%nb)
    real(dp) :: u(3), p0(3), jaxis, lost, most
    integer :: b, k
    most = 0.0_dp
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
        lost = epsilon(1.0_dp)*c(b)%s/jaxis
        most = max(most, lost)
        if (lost <= most_lost) cycle
        call fatal_error(error, 'at t = ' // fmt(t) // ' s: ' // trim(model%d%qname(k)) // ' turns bodies ' // &
          & fmt(sqrt(c(b)%s/c(b)%m)) // ' m from the origin, where the inertias about the origin that the ' // &
          & 'recursive algorithms sum keep fewer than 6 digits of its inertia about its axis (' // fmt(jaxis) // &
          & ' kg m^2; the sum of m |x|^2 is ' // fmt(c(b)%s) // ' kg m^2). Place the origin (the ground''s ' // &
          & 'frame) nearer the motion', stat_solver)
        return
      end do
    end do
    self%x_check = huge(1.0_dp)
    if (most > 0.0_dp) self%x_check = farthest(model)*sqrt(0.01_dp*most_lost/most)
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
    real(dp) :: com(3), jc(3, 3), tr
    integer :: i
    if (model%d%nm(b) > 0) then
      associate (fd => model%d%flex(b))
        c%m = fd%mass; com = fd%first(:, 0)/fd%mass
        jc = -(fd%w(:, :, 0, 0) - fd%mass*spread(com, 2, 3)*spread(com, 1, 3))
      end associate
      tr = -(jc(1, 1) + jc(2, 2) + jc(3, 3))
      do i = 1, 3
        jc(i, i) = jc(i, i) + tr
      end do
    else
      c%m = model%d%mass(b); com = model%d%com(:, b); jc = model%d%inertia(:, :, b)
    end if
    associate (r => model%wk%rot(:, :, b))
      c%x = model%wk%pos(:, b) + matmul(r, com)
      c%j = matmul(r, matmul(jc, transpose(r)))
    end associate
    c%s = c%m*dot_product(c%x, c%x)
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
    c%s = a%s + b%s
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
