!> A body's inertia as the scene and the modal files give it: the 3x3 matrix of six items,
!> and the eigenvalues of a symmetric 3x3 matrix (its principal moments).
module pymr_model_inertia
  use pymr_env_kinds, only : dp
  implicit none
  private
  public :: inertia_matrix, eig3

contains

  !> 3x3 inertia from Ixx Iyy Izz Ixy Ixz Iyz (products enter as given: I(1,2) = Ixy).
  pure function inertia_matrix(v) result(a)
    real(dp), intent(in) :: v(6)
    real(dp) :: a(3, 3)
    a = reshape([v(1), v(4), v(5), v(4), v(2), v(6), v(5), v(6), v(3)], [3, 3])
  end function inertia_matrix

  !> Eigenvalues of a symmetric 3x3 matrix (Jacobi sweeps; enough for input checks).
  pure subroutine eig3(a0, e)
    real(dp), intent(in) :: a0(3, 3)
    real(dp), intent(out) :: e(3)
    real(dp) :: a(3, 3), th, c, s, t, g(3, 3)
    integer :: sweep, p, q, i
    a = a0
    do sweep = 1, 50
      if (abs(a(1, 2)) + abs(a(1, 3)) + abs(a(2, 3)) <= 1.0e-15_dp*sum(abs(a))) exit
      do p = 1, 2
        do q = p + 1, 3
          if (a(p, q) == 0.0_dp) cycle
          th = (a(q, q) - a(p, p))/(2*a(p, q))
          t = sign(1.0_dp, th)/(abs(th) + sqrt(th*th + 1))
          c = 1/sqrt(t*t + 1); s = t*c
          g = 0.0_dp
          do i = 1, 3
            g(i, i) = 1.0_dp
          end do
          g(p, p) = c; g(q, q) = c; g(p, q) = s; g(q, p) = -s
          a = matmul(transpose(g), matmul(a, g))
        end do
      end do
    end do
    e = [a(1, 1), a(2, 2), a(3, 3)]
  end subroutine eig3
end module pymr_model_inertia
