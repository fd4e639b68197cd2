!> Recursive assembly of M qdd = P in joint and modal coordinates (paper eqs. 16-18).
!>
!> Body terms are spatial (inertial coordinates), so composite inertias and wrenches add
!> up the tree without transformation. A coordinate's column (a joint's s_k, or a
!> flexible parent's modal column cm at its child's joint point) applies to a whole
!> subtree; M(j,k) = column_j . f_k for every column j on the path from the owner of k to
!> the base, with f_k the spatial momentum of k's motion. P_k = tau_k - column_k . Wc.
module pymr_model_assembly
  use pymr_env_kinds, only : dp
  use pymr_model_types, only : model_data, model_work
  use pymr_model_flexbody, only : flex_body_terms
  implicit none
  private
  public :: body_terms, composite_terms, assemble_mass, assemble_rhs, kinetic_energy

contains

  include 'vector_products.inc'

  !> Spatial inertia and bias wrench I a_bias + v x* I v of every body (no applied
  !> loads); flexible bodies add their modal coupling, modal bias and elastic forces.
  pure subroutine body_terms(d, wk, q, qd, only)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: q(:), qd(:)
    !> Restrict to these bodies (the fast rows).
    logical, intent(in), optional :: only(:)
    integer :: b, m
    logical :: modal_only
    real(dp) :: r(3, 3), ib(3, 3), c(3)
    do b = 2, d%nb
      modal_only = .false.
      if (present(only)) then
        if (.not. only(b)) cycle
        ! the fast rows need a body's inertia and wrench only below a flexible body
        modal_only = .not. d%in_fast(d%parent(b))
      end if
      if (d%flexible(b)) then
        m = d%nm(b)
        call flex_body_terms(d%flex(b), wk%fwork(b), wk%rot(:, :, b), wk%pos(:, b), wk%vel(:, b), wk%acc(:, b), &
          & q(d%a0(b):d%a0(b) + m - 1), qd(d%a0(b):d%a0(b) + m - 1), wk%i6(:, :, b), wk%mva(:, 1:m, b), &
          & wk%w(:, b), wk%wam(1:m, b), modal_only, d%deformed_moments)
        wk%kam(1:m, b) = 0.0_dp
        cycle
      end if
      r = wk%rot(:, :, b); ib = d%inertia(:, :, b); c = d%com(:, b)
      call rigid_body_terms(d%mass(b), wk%pos(:, b) + matmul(r, c), matmul(r, matmul(ib, transpose(r))), &
        & wk%vel(:, b), wk%acc(:, b), wk%i6(:, :, b), wk%w(:, b))
    end do
  end subroutine body_terms

  !> Spatial inertia i6 about the inertial origin of a rigid body (mass m, centre c, inertia
  !> ic about c, inertial axes) and its bias wrench w = i6 a + v x* (i6 v) at velocity
  !> v = [v_O; omega] and bias acceleration a, written out: with J = ic + m (|c|^2 - c c^T),
  !> i6 x = [m (x_O + x_w x c); m c x x_O + J x_w].
  pure subroutine rigid_body_terms(m, c, ic, v, a, i6, w)
    real(dp), intent(in) :: m, c(3), ic(3, 3), v(6), a(6)
    real(dp), intent(out) :: i6(6, 6), w(6)
    real(dp) :: j(3, 3), hl(3), ha(3), fl(3), fa(3), cc
    integer :: k
    cc = c(1)**2 + c(2)**2 + c(3)**2
    do k = 1, 3
      j(:, k) = ic(:, k) - m*c*c(k)
      j(k, k) = j(k, k) + m*cc
    end do
    i6(1:3, 1:3) = 0.0_dp
    i6(1, 1) = m; i6(2, 2) = m; i6(3, 3) = m
    ! the blocks m c~^T and m c~
    i6(1:3, 4) = [0.0_dp, -m*c(3), m*c(2)]
    i6(1:3, 5) = [m*c(3), 0.0_dp, -m*c(1)]
    i6(1:3, 6) = [-m*c(2), m*c(1), 0.0_dp]
    i6(4:6, 1:3) = transpose(i6(1:3, 4:6))
    i6(4:6, 4:6) = j
    hl = m*(v(1:3) + cross(v(4:6), c)); ha = m*cross(c, v(1:3)) + matmul(j, v(4:6))
    fl = m*(a(1:3) + cross(a(4:6), c)); fa = m*cross(c, a(1:3)) + matmul(j, a(4:6))
    w(1:3) = fl + cross(v(4:6), hl)
    w(4:6) = fa + cross(v(1:3), hl) + cross(v(4:6), ha)
  end subroutine rigid_body_terms

  !> Composite inertia and wrench of each subtree, from the leaves to the base.
  pure subroutine composite_terms(d, wk, only)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    logical, intent(in), optional :: only(:)
    integer :: b, a
    wk%ic(:, :, 2:) = wk%i6(:, :, 2:)
    wk%wc(:, 2:) = wk%w(:, 2:)
    do b = d%nb, 2, -1
      if (present(only)) then
        if (.not. only(b)) cycle
      end if
      a = d%parent(b)
      if (a > 1) then
        wk%ic(:, :, a) = wk%ic(:, :, a) + wk%ic(:, :, b)
        wk%wc(:, a) = wk%wc(:, a) + wk%wc(:, b)
      end if
    end do
  end subroutine composite_terms

  !> Mass matrix (generalised composite-rigid-body recursion; O(n * depth)).
  pure subroutine assemble_mass(d, wk, only)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    logical, intent(in), optional :: only(:)
    integer :: b, k
    do b = 2, d%nb
      if (present(only)) then
        if (.not. only(b)) cycle
        ! a joint column of a body with no flexible body above it has no fast rows
        if (.not. d%in_fast(d%parent(b))) then
          if (d%nm(b) > 0) call modal_block(d, wk, b)
          cycle
        end if
      end if
      do k = d%c0(b), d%c0(b) + d%nc(b) - 1
        call walk_up(d, wk, b, k, matmul(wk%ic(:, :, b), wk%s(:, k)))
      end do
      if (d%nm(b) > 0) call modal_block(d, wk, b)
    end do
  end subroutine assemble_mass

  !> Entries of a flexible body's modal coordinates: their own block (modal mass plus the
  !> children carried by the modes) and their coupling to every column above them.
  pure subroutine modal_block(d, wk, b)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: b
    integer :: m, k, l, i, c, ck, cl
    real(dp) :: f(6), g(6)
    m = d%nm(b)
    do k = 1, m
      ck = d%a0(b) + k - 1
      f = wk%mva(:, k, b)
      do l = 1, m
        wk%mm(d%a0(b) + l - 1, ck) = d%flex(b)%mmm(l, k)
      end do
      ! the modal mass of loads travelling on the body
      if (allocated(wk%maa)) then
        do l = 1, m
          wk%mm(d%a0(b) + l - 1, ck) = wk%mm(d%a0(b) + l - 1, ck) + wk%maa(l, k, b)
        end do
      end if
      do i = d%child_ptr(b), d%child_ptr(b + 1) - 1
        c = d%child_idx(i)
        g = matmul(wk%ic(:, :, c), wk%cm(:, k, c))
        f = f + g
        do l = 1, m
          cl = d%a0(b) + l - 1
          wk%mm(cl, ck) = wk%mm(cl, ck) + dot_product(wk%cm(:, l, c), g)
        end do
      end do
      call walk_up(d, wk, b, ck, f)
    end do
  end subroutine modal_block

  !> Fill M(j, col) = column_j . f (and its mirror) for every column on the path from
  !> body b to the base: joint columns of each body and its parent's modal columns.
  pure subroutine walk_up(d, wk, b, col, f)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: b, col
    real(dp), intent(in) :: f(6)
    integer :: a, j, l, pa
    a = b
    do while (a > 1)
      do j = d%c0(a), d%c0(a) + d%nc(a) - 1
        wk%mm(j, col) = dot_product(wk%s(:, j), f)
        wk%mm(col, j) = wk%mm(j, col)
      end do
      pa = d%parent(a)
      do l = 1, d%nm(pa)
        j = d%a0(pa) + l - 1
        wk%mm(j, col) = dot_product(wk%cm(:, l, a), f)
        wk%mm(col, j) = wk%mm(j, col)
      end do
      a = pa
    end do
  end subroutine walk_up

  !> Right-hand side P = tau - column . Wc (modal: minus the body's modal bias and the
  !> children's composite wrenches through the modal columns).
  pure subroutine assemble_rhs(d, wk, only)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    logical, intent(in), optional :: only(:)
    integer :: b, k, i, c
    do b = 2, d%nb
      if (present(only)) then
        if (.not. only(b)) cycle
      end if
      do k = d%c0(b), d%c0(b) + d%nc(b) - 1
        wk%p(k) = wk%tau(k) - dot_product(wk%s(:, k), wk%wc(:, b))
      end do
      do k = 1, d%nm(b)
        wk%p(d%a0(b) + k - 1) = wk%tau(d%a0(b) + k - 1) - wk%wam(k, b)
        do i = d%child_ptr(b), d%child_ptr(b + 1) - 1
          c = d%child_idx(i)
          wk%p(d%a0(b) + k - 1) = wk%p(d%a0(b) + k - 1) - dot_product(wk%cm(:, k, c), wk%wc(:, c))
        end do
      end do
    end do
  end subroutine assemble_rhs

  !> Kinetic energy 1/2 u^T M_b u summed over bodies (after body_terms); qd gives modal rates.
  pure function kinetic_energy(d, wk, qd) result(e)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: qd(:)
    real(dp) :: e
    integer :: b, m
    e = 0.0_dp
    do b = 2, d%nb
      e = e + 0.5_dp*dot_product(wk%vel(:, b), matmul(wk%i6(:, :, b), wk%vel(:, b)))
      m = d%nm(b)
      if (m == 0) cycle
      associate(ad => qd(d%a0(b):d%a0(b) + m - 1))
        e = e + dot_product(wk%vel(:, b), matmul(wk%mva(:, 1:m, b), ad)) + &
          & 0.5_dp*dot_product(ad, matmul(d%flex(b)%mmm, ad))
      end associate
    end do
  end function kinetic_energy
end module pymr_model_assembly
