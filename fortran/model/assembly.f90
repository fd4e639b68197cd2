!> Recursive assembly of M qdd = P in joint coordinates (paper eqs. 16-18).
!>
!> Body terms are spatial (inertial coordinates), so composite inertias and wrenches add
!> up the tree without transformation. M(j,k) = s_j . (Ic_b s_k) for every coordinate j
!> on the path from body b (owner of k) to the base; P_k = tau_k - s_k . Wc_b.
module pymr_model_assembly
  use pymr_kinds, only : dp
  use pymr_model_types, only : model_data
  use pymr_model_spatial, only : force_cross, rigid_inertia
  implicit none
  private
  public :: body_terms, composite_terms, assemble_mass, assemble_rhs, kinetic_energy

contains

  !> Spatial inertia and bias wrench I a_bias + v x* I v of every body (no applied loads).
  pure subroutine body_terms(d)
    type(model_data), intent(inout) :: d
    integer :: b
    real(dp) :: c(3), icw(3, 3)
    do b = 2, d%nb
      c = d%pos(:, b) + matmul(d%rot(:, :, b), d%com(:, b))
      icw = matmul(d%rot(:, :, b), matmul(d%inertia(:, :, b), transpose(d%rot(:, :, b))))
      d%i6(:, :, b) = rigid_inertia(d%mass(b), c, icw)
      d%w(:, b) = matmul(d%i6(:, :, b), d%acc(:, b)) + &
        & force_cross(d%vel(:, b), matmul(d%i6(:, :, b), d%vel(:, b)))
    end do
  end subroutine body_terms

  !> Composite inertia and wrench of each subtree, from the leaves to the base.
  pure subroutine composite_terms(d)
    type(model_data), intent(inout) :: d
    integer :: b, a
    d%ic(:, :, 2:) = d%i6(:, :, 2:)
    d%wc(:, 2:) = d%w(:, 2:)
    do b = d%nb, 2, -1
      a = d%parent(b)
      if (a > 1) then
        d%ic(:, :, a) = d%ic(:, :, a) + d%ic(:, :, b)
        d%wc(:, a) = d%wc(:, a) + d%wc(:, b)
      end if
    end do
  end subroutine composite_terms

  !> Mass matrix (composite-rigid-body recursion; O(n * depth)).
  pure subroutine assemble_mass(d)
    type(model_data), intent(inout) :: d
    integer :: b, a, k, j
    real(dp) :: f(6)
    do b = 2, d%nb
      do k = d%c0(b), d%c0(b) + d%nc(b) - 1
        f = matmul(d%ic(:, :, b), d%s(:, k))
        a = b
        do while (a > 1)
          do j = d%c0(a), d%c0(a) + d%nc(a) - 1
            d%mm(j, k) = dot_product(d%s(:, j), f)
            d%mm(k, j) = d%mm(j, k)
          end do
          a = d%parent(a)
        end do
      end do
    end do
  end subroutine assemble_mass

  !> Right-hand side P = tau - s_k . Wc_b.
  pure subroutine assemble_rhs(d)
    type(model_data), intent(inout) :: d
    integer :: b, k
    do b = 2, d%nb
      do k = d%c0(b), d%c0(b) + d%nc(b) - 1
        d%p(k) = d%tau(k) - dot_product(d%s(:, k), d%wc(:, b))
      end do
    end do
  end subroutine assemble_rhs

  !> Kinetic energy 1/2 sum v^T I v (after body_terms).
  pure function kinetic_energy(d) result(e)
    type(model_data), intent(in) :: d
    real(dp) :: e
    integer :: b
    e = 0.0_dp
    do b = 2, d%nb
      e = e + 0.5_dp*dot_product(d%vel(:, b), matmul(d%i6(:, :, b), d%vel(:, b)))
    end do
  end function kinetic_energy
end module pymr_model_assembly
