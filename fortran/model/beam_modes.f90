!> Built-in Euler-Bernoulli beam: cubic Hermite elements along the body x axis, clamped
!> at the body frame origin, bending in the x-y plane (v, rotation dv/dx about z) and the
!> x-z plane (w, rotation -dw/dx about y); line mass (no rotary inertia of the section).
!> Modes from K v = lambda M v per plane with LAPACK dsygvd, mass-normalised.
module pymr_model_beam_modes
  use pymr_kinds, only : dp, pi
  use pymr_error, only : error_type
  use pymr_lapack, only : sygvd, band_solve
  use pymr_model_flexbody, only : flex_data, flex_invariants, point_shapes
  implicit none
  private
  public :: beam_point_load_stiffness, beam_shape, build_beam, beam_point_shapes, gauss4

  !> Beams with more elements take the banded eigensolver (the dense one is kept below it,
  !> so the results of smaller beams stay as they were).
  integer, parameter :: dense_elements = 100

  !> Gauss-Legendre points and weights on [0, 1] (exact for degree 7): the nodes
  !> +-0.8611363115940526, +-0.3399810435848563 of [-1, 1] halved and shifted.
  real(dp), parameter :: gauss4(2, 4) = reshape([ &
    & 0.5_dp - 0.43056815579702629_dp, 0.17392742256872693_dp, &
    & 0.5_dp - 0.16999052179242813_dp, 0.32607257743127307_dp, &
    & 0.5_dp + 0.16999052179242813_dp, 0.32607257743127307_dp, &
    & 0.5_dp + 0.43056815579702629_dp, 0.17392742256872693_dp], [2, 4])

  !> Mode shapes of a beam at its nodes, for interpolation at attachments and markers.
  type :: beam_shape
    real(dp) :: length = 0.0_dp
    integer :: ne = 0, my = 0, mz = 0
    !> Nodal [v_0, v'_0, v_1, v'_1, ...] per mode (node 0 clamped): vy(2*(ne+1), my), vz(..., mz).
    real(dp), allocatable :: vy(:, :), vz(:, :)
  end type beam_shape

contains

  !> Hermite shape functions and their x-derivatives at xi in [0,1], element length le.
  pure subroutine hermite(xi, le, n, dn)
    real(dp), intent(in) :: xi, le
    real(dp), intent(out) :: n(4), dn(4)
    n = [1.0_dp - 3*xi**2 + 2*xi**3, le*(xi - 2*xi**2 + xi**3), 3*xi**2 - 2*xi**3, le*(-xi**2 + xi**3)]
    dn = [(-6*xi + 6*xi**2)/le, 1.0_dp - 4*xi + 3*xi**2, (6*xi - 6*xi**2)/le, -2*xi + 3*xi**2]
  end subroutine hermite

  !> Build a beam: modes of each plane, mass points at the Gauss points, invariants.
  subroutine build_beam(length, e, rho, area, iy, iz, ne, my, mz, what, fd, bs, error)
    real(dp), intent(in) :: length, e, rho, area, iy, iz
    integer, intent(in) :: ne, my, mz
    !> Name of the body for messages.
    character(len=*), intent(in) :: what
    type(flex_data), intent(out) :: fd
    type(beam_shape), intent(out) :: bs
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: lam_y(:), lam_z(:), s(:, :), mp(:), psi(:, :, :)
    integer :: np, el, g, k, m
    real(dp) :: le, xi, nn(4), dn(4)
    bs%length = length; bs%ne = ne; bs%my = my; bs%mz = mz
    le = length/ne
    call plane_modes(e*iz, rho*area, le, ne, my, 'the stiffness matrix of ' // what // ' (x-y plane)', bs%vy, &
      & lam_y, error)
    if (allocated(error)) return
    call plane_modes(e*iy, rho*area, le, ne, mz, 'the stiffness matrix of ' // what // ' (x-z plane)', bs%vz, &
      & lam_z, error)
    if (allocated(error)) return
    m = my + mz
    np = 4*ne
    allocate(s(3, np), mp(np), psi(3, m, np))
    s = 0.0_dp; psi = 0.0_dp
    do el = 1, ne
      do g = 1, 4
        xi = gauss4(1, g)
        k = 4*(el - 1) + g
        s(1, k) = (el - 1 + xi)*le
        mp(k) = rho*area*le*gauss4(2, g)
        call hermite(xi, le, nn, dn)
        psi(2, 1:my, k) = matmul(nn, bs%vy(2*el-1:2*el+2, :))
        psi(3, my+1:m, k) = matmul(nn, bs%vz(2*el-1:2*el+2, :))
      end do
    end do
    call flex_invariants(s, mp, psi, fd)
    fd%omega2 = [lam_y, lam_z]
    call beam_geometric_stiffness(bs, rho*area, fd%kg1, fd%kg2)
  end subroutine build_beam

  !> Geometric stiffness of the beam's modes per unit load factor: with the tension
  !> N(x) = c1 rho A (L - x) + c2 rho A (L^2 - x^2)/2, K_G = c1 kg1 + c2 kg2 where
  !> kg = int N_unit(x) (v_y,k' v_y,l' + v_z,k' v_z,l') dx (slopes of the modes in both
  !> planes). 4-point Gauss per element is exact: the integrand is a polynomial of degree 6.
  pure subroutine beam_geometric_stiffness(bs, rhoa, kg1, kg2)
    type(beam_shape), intent(in) :: bs
    real(dp), intent(in) :: rhoa
    real(dp), allocatable, intent(out) :: kg1(:, :), kg2(:, :)
    integer :: el, g, m
    real(dp) :: le, xi, x, wt, sl(bs%my + bs%mz)
    m = bs%my + bs%mz
    allocate(kg1(m, m), kg2(m, m))
    kg1 = 0.0_dp; kg2 = 0.0_dp
    le = bs%length/bs%ne
    do el = 1, bs%ne
      do g = 1, 4
        xi = gauss4(1, g)
        x = (el - 1 + xi)*le
        wt = le*gauss4(2, g)*rhoa
        call mode_slopes(bs, el, xi, le, sl)
        call add_slope_products(bs, wt*(bs%length - x), sl, kg1)
        call add_slope_products(bs, wt*0.5_dp*(bs%length**2 - x**2), sl, kg2)
      end do
    end do
  end subroutine beam_geometric_stiffness

  !> Geometric stiffness of the beam's modes per newton of tension carried from the root
  !> to x = xc (an axial load at a point): kg = int_0^xc (v_y,k' v_y,l' + v_z,k' v_z,l') dx.
  !> Each element, or its part below xc, by 4-point Gauss (exact for the degree-4 integrand).
  pure subroutine beam_point_load_stiffness(bs, xc, kg)
    type(beam_shape), intent(in) :: bs
    real(dp), intent(in) :: xc
    real(dp), intent(out) :: kg(:, :)
    integer :: el, g
    real(dp) :: le, span, xi, wt, sl(bs%my + bs%mz)
    kg = 0.0_dp
    le = bs%length/bs%ne
    do el = 1, bs%ne
      ! the part of element el below xc, as a fraction of the element
      span = min(max(xc/le - (el - 1), 0.0_dp), 1.0_dp)
      if (span <= 0.0_dp) exit
      do g = 1, 4
        xi = span*gauss4(1, g)
        wt = le*span*gauss4(2, g)
        call mode_slopes(bs, el, xi, le, sl)
        call add_slope_products(bs, wt, sl, kg)
      end do
    end do
  end subroutine beam_point_load_stiffness

  !> Slopes sl (y-plane modes, then z-plane ones) of the modes at xi in [0, 1] of element el.
  pure subroutine mode_slopes(bs, el, xi, le, sl)
    type(beam_shape), intent(in) :: bs
    integer, intent(in) :: el
    real(dp), intent(in) :: xi, le
    real(dp), intent(out) :: sl(:)
    real(dp) :: nn(4), dn(4)
    integer :: k
    call hermite(xi, le, nn, dn)
    do k = 1, bs%my
      sl(k) = dot_product(dn, bs%vy(2*el-1:2*el+2, k))
    end do
    do k = 1, bs%mz
      sl(bs%my + k) = dot_product(dn, bs%vz(2*el-1:2*el+2, k))
    end do
  end subroutine mode_slopes

  !> kg(k, l) += w sl(k) sl(l) for modes of the same plane (slopes of modes in different
  !> planes are orthogonal components).
  pure subroutine add_slope_products(bs, w, sl, kg)
    type(beam_shape), intent(in) :: bs
    real(dp), intent(in) :: w, sl(:)
    real(dp), intent(inout) :: kg(:, :)
    integer :: k, l
    do l = 1, size(sl)
      do k = 1, size(sl)
        if ((k <= bs%my) .neqv. (l <= bs%my)) cycle
        kg(k, l) = kg(k, l) + w*sl(k)*sl(l)
      end do
    end do
  end subroutine add_slope_products

  !> Lowest `nm` modes of one bending plane: nodal vectors (with the clamped node 0 as zeros),
  !> M-normalised, signed so that the tip displacement is positive.
  recursive subroutine plane_modes(ei, rhoa, le, ne, nm, what, v, lam, error)
    real(dp), intent(in) :: ei, rhoa, le
    integer, intent(in) :: ne, nm
    character(len=*), intent(in) :: what
    real(dp), allocatable, intent(out) :: v(:, :), lam(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: kk(:, :), mm(:, :), w(:)
    real(dp) :: ke(4, 4), me(4, 4), nn(4), dn(4)
    integer :: nd, el, g, i0, i, j, k
    nd = 2*ne
    ke = reshape([12.0_dp, 6*le, -12.0_dp, 6*le, 6*le, 4*le**2, -6*le, 2*le**2, &
      & -12.0_dp, -6*le, 12.0_dp, -6*le, 6*le, 2*le**2, -6*le, 4*le**2], [4, 4])*ei/le**3
    me = 0.0_dp
    do g = 1, 4
      call hermite(gauss4(1, g), le, nn, dn)
      do j = 1, 4
        me(:, j) = me(:, j) + rhoa*le*gauss4(2, g)*nn*nn(j)
      end do
    end do
    if (ne > dense_elements) then
      call plane_modes_banded(ei, rhoa, le, ke, me, ne, nm, what, v, lam, error); return
    end if
    allocate(kk(nd, nd), mm(nd, nd), w(nd), v(nd + 2, nm), lam(nm))
    kk = 0.0_dp; mm = 0.0_dp
    do el = 1, ne
      i0 = 2*(el - 1) - 2        ! global index offset (node 0 removed)
      do j = 1, 4
        if (i0 + j < 1) cycle
        do i = 1, 4
          if (i0 + i < 1) cycle
          kk(i0 + i, i0 + j) = kk(i0 + i, i0 + j) + ke(i, j)
          mm(i0 + i, i0 + j) = mm(i0 + i, i0 + j) + me(i, j)
        end do
      end do
    end do
    ! flexibility form M v = mu K v (mu = 1/lambda): the lowest modes are the largest mu and
    ! come out more accurately than from K v = lambda M v; v^T K v = 1, so v/sqrt(mu) is
    ! mass-normalised.
    call sygvd(mm, kk, w, what, error); if (allocated(error)) return
    v = 0.0_dp
    do k = 1, nm
      v(3:, k) = mm(:, nd + 1 - k)/sqrt(w(nd + 1 - k))
      if (v(nd + 1, k) < 0.0_dp) v(3:, k) = -v(3:, k)
      lam(k) = 1.0_dp/w(nd + 1 - k)
    end do
  end subroutine plane_modes

  !> Modes of a long beam (more than dense_elements elements) from the banded matrices: each
  !> mode by inverse iteration with (K - sigma M) (LAPACK's banded LU), sigma the mode's
  !> eigenvalue on a coarse mesh, then its eigenvalue as the Rayleigh quotient summed
  !> element by element. Work and memory grow as the number of elements, not its cube and
  !> square.
  recursive subroutine plane_modes_banded(ei, rhoa, le, ke, me, ne, nm, what, v, lam, error)
    real(dp), intent(in) :: ei, rhoa, le, ke(4, 4), me(4, 4)
    integer, intent(in) :: ne, nm
    character(len=*), intent(in) :: what
    real(dp), allocatable, intent(out) :: v(:, :), lam(:)
    type(error_type), allocatable, intent(out) :: error
    integer, parameter :: kd = 3
    real(dp), allocatable :: kb(:, :), mb(:, :), a(:, :), x(:), y(:)
    integer :: nd, el, i0, i, j, k, it
    real(dp) :: sigma
    nd = 2*ne
    allocate(kb(kd + 1, nd), mb(kd + 1, nd), x(nd), y(nd), v(nd + 2, nm), lam(nm))
    kb = 0.0_dp; mb = 0.0_dp
    do el = 1, ne
      i0 = 2*(el - 1) - 2        ! global index offset (node 0 removed)
      do j = 1, 4
        do i = j, 4
          if (i0 + j < 1) cycle
          kb(1 + i - j, i0 + j) = kb(1 + i - j, i0 + j) + ke(i, j)
          mb(1 + i - j, i0 + j) = mb(1 + i - j, i0 + j) + me(i, j)
        end do
      end do
    end do
    v = 0.0_dp
    if (nm == 0) return
    ! shifts: the eigenvalues of the same beam on a coarse mesh (dense, accurate to about 1e-4
    ! for the modes kept); inverse iteration then converges to the fine mesh's modes
    block
      real(dp), allocatable :: vc(:, :)
      integer :: nc
      nc = max(dense_elements, 8*nm)
      call plane_modes(ei, rhoa, le*ne/nc, nc, nm, what, vc, lam, error); if (allocated(error)) return
    end block
    do k = 1, nm
      sigma = lam(k)
      a = kb - sigma*mb
      x = [(1.0_dp + 0.1_dp*sin(real(i, dp)), i = 1, nd)]
      do it = 1, 6
        y = band_product(mb, x)
        call band_solve(a, y, what, error); if (allocated(error)) return
        x = y/norm2(y)
      end do
      x = x/sqrt(dot_product(x, band_product(mb, x)))
      if (x(nd - 1) < 0.0_dp) x = -x
      v(3:, k) = x
      ! the Rayleigh quotient of the converged mode, element by element: more accurate than
      ! the banded solver's eigenvalue, which the Cholesky of the ill-conditioned K limits
      lam(k) = element_energy(ke, v(:, k))/element_energy(me, v(:, k))
    end do
  contains
    !> sum over elements of x_e' A_e x_e, x with the clamped node's two zeros in front.
    pure real(dp) function element_energy(ae, x) result(e)
      real(dp), intent(in) :: ae(4, 4), x(:)
      integer :: el
      e = 0.0_dp
      do el = 1, ne
        e = e + dot_product(x(2*el-1:2*el+2), matmul(ae, x(2*el-1:2*el+2)))
      end do
    end function element_energy

    !> y = B x for the symmetric banded B (lower band).
    pure function band_product(b, x) result(y)
      real(dp), intent(in) :: b(:, :), x(:)
      real(dp) :: y(size(x))
      integer :: i, j
      y = 0.0_dp
      do j = 1, size(x)
        y(j) = y(j) + b(1, j)*x(j)
        do i = j + 1, min(size(x), j + kd)
          y(i) = y(i) + b(1 + i - j, j)*x(j)
          y(j) = y(j) + b(1 + i - j, j)*x(i)
        end do
      end do
    end function band_product
  end subroutine plane_modes_banded

  !> Translational and rotational mode shapes (3 x m) at point r of the body frame:
  !> Hermite interpolation at x = r(1); the section's small rotation carries the offset
  !> (0, r(2), r(3)).
  pure subroutine beam_point_shapes(bs, r, psi, phi)
    type(beam_shape), intent(in) :: bs
    real(dp), intent(in) :: r(3)
    real(dp), intent(out) :: psi(:, :), phi(:, :)
    real(dp) :: le, x, xi, nn(4), dn(4), psi_axis(3, size(psi, 2))
    integer :: el, k
    le = bs%length/bs%ne
    x = min(max(r(1), 0.0_dp), bs%length)
    el = min(int(x/le) + 1, bs%ne)
    xi = x/le - (el - 1)
    call hermite(xi, le, nn, dn)
    psi_axis = 0.0_dp; phi = 0.0_dp
    do k = 1, bs%my
      psi_axis(2, k) = dot_product(nn, bs%vy(2*el-1:2*el+2, k))
      phi(3, k) = dot_product(dn, bs%vy(2*el-1:2*el+2, k))
    end do
    do k = 1, bs%mz
      psi_axis(3, bs%my + k) = dot_product(nn, bs%vz(2*el-1:2*el+2, k))
      phi(2, bs%my + k) = -dot_product(dn, bs%vz(2*el-1:2*el+2, k))
    end do
    call point_shapes(psi_axis, phi, [0.0_dp, r(2), r(3)], psi)
  end subroutine beam_point_shapes
end module pymr_model_beam_modes
