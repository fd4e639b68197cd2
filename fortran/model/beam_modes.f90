!> Built-in beam along the body x axis on one mesh of cubic Hermite elements, clamped at the
!> body frame origin. Four families of modes, each a field along the axis with nodal values
!> and slopes: bending in the x-y plane (v, rotation dv/dx about z) and the x-z plane (w,
!> rotation -dw/dx about y), Euler-Bernoulli; axial (bar) displacement u along x; torsion
!> (shaft) rotation theta about x. Line mass; with torsional modes the section's rotary
!> inertia too (see build_beam). Modes from K v = lambda M v per family with LAPACK dsygvd,
!> mass-normalised.
!>
!> Axial and torsional fields use the same C1 Hermite cubics as bending (the clamp fixes u(0)
!> or theta(0), not the slope): for these second-order problems the frequencies converge as
!> h^6, the relative error of f_n about (k_n h)^6/60480 with k_n = (2n-1) pi/(2L), from above
!> (3.8e-12 for f_1 with 20 elements; tests/test_beam_modes.py measures it).
module pymr_model_beam_modes
  use pymr_env_kinds, only : dp, pi
  use pymr_env_error, only : error_type
  use pymr_env_lapack, only : sygvd, band_solve
  use pymr_env_memory, only : check_bytes, refuse_bytes, memory_limit
  use pymr_env_text, only : itoa
  use pymr_model_flexbody, only : flex_data, flex_invariants, point_shapes
  implicit none
  private
  public :: beam_point_load_stiffness, beam_shape, beam_section, build_beam, beam_point_shapes, gauss4, axis_shapes

  !> Beams with more elements take the banded eigensolver (the dense one is kept below it,
  !> so the results of smaller beams stay as they were).
  integer, parameter, public :: dense_elements = 100
  !> The banded eigensolver's shifts come from the same beam on a dense mesh of
  !> shift_elements elements per mode kept (at least dense_elements), at most
  !> max_shift_mesh elements: so a beam with more than dense_elements elements keeps at most
  !> max_banded_modes modes per family (scene rule).
  integer, parameter :: shift_elements = 8, max_shift_mesh = 400
  integer, parameter, public :: max_banded_modes = max_shift_mesh/shift_elements

  !> Gauss-Legendre points and weights on [0, 1] (exact for degree 7): the nodes
  !> +-0.8611363115940526, +-0.3399810435848563 of [-1, 1] halved and shifted.
  real(dp), parameter :: gauss4(2, 4) = reshape([ &
    & 0.5_dp - 0.43056815579702629_dp, 0.17392742256872693_dp, &
    & 0.5_dp - 0.16999052179242813_dp, 0.32607257743127307_dp, &
    & 0.5_dp + 0.16999052179242813_dp, 0.32607257743127307_dp, &
    & 0.5_dp + 0.43056815579702629_dp, 0.17392742256872693_dp], [2, 4])

  !> Material and section of a beam (SI). g and j serve torsion only (0 without it).
  type :: beam_section
    real(dp) :: e = 0.0_dp, g = 0.0_dp, rho = 0.0_dp
    !> Area, second moments about y and z, torsion constant.
    real(dp) :: area = 0.0_dp, iy = 0.0_dp, iz = 0.0_dp, j = 0.0_dp
  end type beam_section

  !> Mode shapes of a beam at its nodes, for interpolation at attachments and markers.
  !> Modal coordinates: my x-y bending modes, mz x-z bending modes, mx axial, mt torsional.
  type :: beam_shape
    real(dp) :: length = 0.0_dp
    integer :: ne = 0, my = 0, mz = 0, mx = 0, mt = 0
    !> Nodal [f_0, f'_0, f_1, f'_1, ...] per mode (node 0 clamped) of the fields v (vy), w
    !> (vz), u (vx) and theta (vt): vy(2*(ne+1), my), ...
    real(dp), allocatable :: vy(:, :), vz(:, :), vx(:, :), vt(:, :)
  end type beam_shape

  !> One family of modes on the Hermite mesh: its element stiffness (bending: stiffness
  !> int N''N''^T, else stiffness int N'N'^T), its element mass inertia int N N^T (+ rotary
  !> int N'N'^T for the section's rotation in bending), and nfix nodal values clamped at
  !> x = 0 (bending: value and slope; axial and torsion: the value only).
  type :: mode_field
    logical :: bending = .true.
    integer :: nfix = 2
    real(dp) :: stiffness = 0.0_dp, inertia = 0.0_dp, rotary = 0.0_dp
  end type mode_field

contains

  !> Hermite shape functions and their x-derivatives at xi in [0,1], element length le.
  pure subroutine hermite(xi, le, n, dn)
    real(dp), intent(in) :: xi, le
    real(dp), intent(out) :: n(4), dn(4)
    n = [1.0_dp - 3*xi**2 + 2*xi**3, le*(xi - 2*xi**2 + xi**3), 3*xi**2 - 2*xi**3, le*(-xi**2 + xi**3)]
    dn = [(-6*xi + 6*xi**2)/le, 1.0_dp - 4*xi + 3*xi**2, (6*xi - 6*xi**2)/le, -2*xi + 3*xi**2]
  end subroutine hermite

  !> Build a beam: modes of each family, mass points at the Gauss points, invariants.
  !>
  !> Without torsional modes the mass points lie on the axis (a line mass). With them (mt > 0)
  !> each Gauss point becomes four points of a quarter of its mass at (0, +-ry, 0) and
  !> (0, 0, +-rz) off the axis, ry = sqrt(2 iz/A), rz = sqrt(2 iy/A): they carry the section's
  !> second moments of mass rho iz, rho iy and its polar moment rho (iy + iz) per length, so
  !> torsion has its kinetic energy. The points move with the section (psi = psi_axis +
  !> phi x r), so the bending modes gain the section's rotary inertia (Rayleigh beam): their
  !> eigenproblems then include it (mass rho I int N'N'^T), which keeps every mode
  !> mass-normalised over the points; the body's rigid inertia gains rho iy L, rho iz L about
  !> y and z and rho (iy + iz) L about x (the real beam's, which the line mass leaves out).
  subroutine build_beam(length, sec, ne, my, mz, mx, mt, what, fd, bs, error)
    real(dp), intent(in) :: length
    type(beam_section), intent(in) :: sec
    integer, intent(in) :: ne, my, mz, mx, mt
    !> Name of the body for messages.
    character(len=*), intent(in) :: what
    type(flex_data), intent(out) :: fd
    type(beam_shape), intent(out) :: bs
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: lam_y(:), lam_z(:), lam_x(:), lam_t(:), s(:, :), mp(:), psi(:, :, :)
    real(dp) :: le, xi, mg, off(3, 4), psi_axis(3, my + mz + mx + mt), phi(3, my + mz + mx + mt), rot_y, rot_z
    integer :: np, el, g, k, c, m, per, stat
    logical :: ring
    character(len=:), allocatable :: what_points
    bs%length = length; bs%ne = ne; bs%my = my; bs%mz = mz; bs%mx = mx; bs%mt = mt
    le = length/ne
    ring = mt > 0
    rot_y = 0.0_dp; rot_z = 0.0_dp
    if (ring) then
      rot_y = sec%rho*sec%iz; rot_z = sec%rho*sec%iy
    end if
    call field_modes(mode_field(.true., 2, sec%e*sec%iz, sec%rho*sec%area, rot_y), le, ne, my, &
      & 'the stiffness matrix of ' // what // ' (x-y plane)', bs%vy, lam_y, error)
    if (allocated(error)) return
    call field_modes(mode_field(.true., 2, sec%e*sec%iy, sec%rho*sec%area, rot_z), le, ne, mz, &
      & 'the stiffness matrix of ' // what // ' (x-z plane)', bs%vz, lam_z, error)
    if (allocated(error)) return
    call field_modes(mode_field(.false., 1, sec%e*sec%area, sec%rho*sec%area), le, ne, mx, &
      & 'the stiffness matrix of ' // what // ' (axial)', bs%vx, lam_x, error)
    if (allocated(error)) return
    call field_modes(mode_field(.false., 1, sec%g*sec%j, sec%rho*(sec%iy + sec%iz)), le, ne, mt, &
      & 'the stiffness matrix of ' // what // ' (torsion)', bs%vt, lam_t, error)
    if (allocated(error)) return
    m = my + mz + mx + mt
    per = 1
    off = 0.0_dp
    if (ring) then
      per = 4
      off(2, 1) = sqrt(2*sec%iz/sec%area); off(2, 2) = -off(2, 1)
      off(3, 3) = sqrt(2*sec%iy/sec%area); off(3, 4) = -off(3, 3)
    end if
    np = 4*ne*per
    ! the quadrature's shapes grow as elements times modes (5000 elements of 200 modes on a
    ! ring section: 0.38 GB): refused in one line, not in the compiler's runtime message
    what_points = what // ': its ' // itoa(np) // ' quadrature points of ' // itoa(m) // ' modes'
    call check_bytes(what_points, 8.0_dp*np*(3.0_dp*m + 4.0_dp), error); if (allocated(error)) return
    allocate(s(3, np), mp(np), psi(3, m, np), stat=stat)
    if (stat /= 0) then
      call refuse_bytes(what_points, 8.0_dp*np*(3.0_dp*m + 4.0_dp), memory_limit(), error); return
    end if
    s = 0.0_dp; psi = 0.0_dp
    do el = 1, ne
      do g = 1, 4
        xi = gauss4(1, g)
        mg = sec%rho*sec%area*le*gauss4(2, g)
        call section_shapes(bs, el, xi, psi_axis, phi)
        do c = 1, per
          k = per*(4*(el - 1) + g - 1) + c
          s(1, k) = (el - 1 + xi)*le
          if (.not. ring) then
            mp(k) = mg; psi(:, :, k) = psi_axis
          else
            s(2:3, k) = off(2:3, c)
            mp(k) = mg/4
            call point_shapes(psi_axis, phi, off(:, c), psi(:, :, k))
          end if
        end do
      end do
    end do
    call flex_invariants(s, mp, psi, fd)
    fd%omega2 = [lam_y, lam_z, lam_x, lam_t]
    call beam_geometric_stiffness(bs, sec%rho*sec%area, fd%kg1, fd%kg2)
  end subroutine build_beam

  !> Translational shapes psi (3 x m) of the axis point and small rotations phi (3 x m) of
  !> the section at xi in [0, 1] of element el, every mode: x-y bending (v along y, rotation
  !> v' about z), x-z bending (w along z, rotation -w' about y), axial (u along x), torsion
  !> (theta about x).
  pure subroutine section_shapes(bs, el, xi, psi, phi)
    type(beam_shape), intent(in) :: bs
    integer, intent(in) :: el
    real(dp), intent(in) :: xi
    real(dp), intent(out) :: psi(:, :), phi(:, :)
    real(dp) :: nn(4), dn(4)
    integer :: ky, kz, kx
    call hermite(xi, bs%length/bs%ne, nn, dn)
    ky = bs%my; kz = ky + bs%mz; kx = kz + bs%mx
    psi = 0.0_dp; phi = 0.0_dp
    psi(2, 1:ky) = matmul(nn, bs%vy(2*el-1:2*el+2, :))
    phi(3, 1:ky) = matmul(dn, bs%vy(2*el-1:2*el+2, :))
    psi(3, ky+1:kz) = matmul(nn, bs%vz(2*el-1:2*el+2, :))
    phi(2, ky+1:kz) = -matmul(dn, bs%vz(2*el-1:2*el+2, :))
    psi(1, kz+1:kx) = matmul(nn, bs%vx(2*el-1:2*el+2, :))
    phi(1, kx+1:kx+bs%mt) = matmul(nn, bs%vt(2*el-1:2*el+2, :))
  end subroutine section_shapes

  !> Geometric stiffness of the beam's modes per unit load factor: with the tension
  !> N(x) = c1 rho A (L - x) + c2 rho A (L^2 - x^2)/2, K_G = c1 kg1 + c2 kg2 where
  !> kg = int N_unit(x) (v_y,k' v_y,l' + v_z,k' v_z,l') dx (slopes of the modes in both
  !> planes). 4-point Gauss per element is exact: the integrand is a polynomial of degree 6.
  !> Axial and torsional modes get zero rows and columns: the tension's work on the axial
  !> strain is of higher order, and its stiffening of torsion (N Ip/A int theta'^2, the
  !> Wagner term) is left out.
  pure subroutine beam_geometric_stiffness(bs, rhoa, kg1, kg2)
    type(beam_shape), intent(in) :: bs
    real(dp), intent(in) :: rhoa
    real(dp), allocatable, intent(out) :: kg1(:, :), kg2(:, :)
    integer :: el, g, m, nb
    real(dp) :: le, xi, x, wt, sl(bs%my + bs%mz)
    m = bs%my + bs%mz + bs%mx + bs%mt
    nb = bs%my + bs%mz
    allocate(kg1(m, m), kg2(m, m))
    kg1 = 0.0_dp; kg2 = 0.0_dp
    le = bs%length/bs%ne
    do el = 1, bs%ne
      do g = 1, 4
        xi = gauss4(1, g)
        x = (el - 1 + xi)*le
        wt = le*gauss4(2, g)*rhoa
        call bending_slopes(bs, el, xi, sl)
        call add_slope_products(bs, wt*(bs%length - x), sl, kg1(1:nb, 1:nb))
        call add_slope_products(bs, wt*0.5_dp*(bs%length**2 - x**2), sl, kg2(1:nb, 1:nb))
      end do
    end do
  end subroutine beam_geometric_stiffness

  !> Geometric stiffness of the beam's modes per newton of tension carried from the root
  !> to x = xc (an axial load at a point): kg = int_0^xc (v_y,k' v_y,l' + v_z,k' v_z,l') dx.
  !> Each element, or its part below xc, by 4-point Gauss (exact for the degree-4 integrand).
  !> Axial and torsional modes: zero rows and columns, as in beam_geometric_stiffness.
  pure subroutine beam_point_load_stiffness(bs, xc, kg)
    type(beam_shape), intent(in) :: bs
    real(dp), intent(in) :: xc
    real(dp), intent(out) :: kg(:, :)
    integer :: el, g, nb
    real(dp) :: le, span, xi, wt, sl(bs%my + bs%mz)
    kg = 0.0_dp
    nb = bs%my + bs%mz
    le = bs%length/bs%ne
    do el = 1, bs%ne
      ! the part of element el below xc, as a fraction of the element
      span = min(max(xc/le - (el - 1), 0.0_dp), 1.0_dp)
      if (span <= 0.0_dp) exit
      do g = 1, 4
        xi = span*gauss4(1, g)
        wt = le*span*gauss4(2, g)
        call bending_slopes(bs, el, xi, sl)
        call add_slope_products(bs, wt, sl, kg(1:nb, 1:nb))
      end do
    end do
  end subroutine beam_point_load_stiffness

  !> Slopes sl of the bending modes (y-plane modes, then z-plane ones) at xi in [0, 1] of
  !> element el: the section rotations about z and (negated, which the products below do
  !> not see) about y.
  pure subroutine bending_slopes(bs, el, xi, sl)
    type(beam_shape), intent(in) :: bs
    integer, intent(in) :: el
    real(dp), intent(in) :: xi
    real(dp), intent(out) :: sl(:)
    real(dp) :: psi(3, bs%my + bs%mz + bs%mx + bs%mt), phi(3, bs%my + bs%mz + bs%mx + bs%mt)
    call section_shapes(bs, el, xi, psi, phi)
    sl(1:bs%my) = phi(3, 1:bs%my)
    sl(bs%my+1:) = phi(2, bs%my+1:bs%my+bs%mz)
  end subroutine bending_slopes

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

  !> Element stiffness and mass matrices of field f, element length le (4-point Gauss: exact
  !> for the degree-6 mass and degree-4 axial stiffness integrands).
  pure subroutine element_matrices(f, le, ke, me)
    type(mode_field), intent(in) :: f
    real(dp), intent(in) :: le
    real(dp), intent(out) :: ke(4, 4), me(4, 4)
    real(dp) :: nn(4), dn(4), wl
    integer :: g, j
    ke = 0.0_dp; me = 0.0_dp
    if (f%bending) ke = reshape([12.0_dp, 6*le, -12.0_dp, 6*le, 6*le, 4*le**2, -6*le, 2*le**2, &
      & -12.0_dp, -6*le, 12.0_dp, -6*le, 6*le, 2*le**2, -6*le, 4*le**2], [4, 4])*f%stiffness/le**3
    do g = 1, 4
      call hermite(gauss4(1, g), le, nn, dn)
      wl = le*gauss4(2, g)
      do j = 1, 4
        me(:, j) = me(:, j) + f%inertia*le*gauss4(2, g)*nn*nn(j)
        if (f%rotary > 0.0_dp) me(:, j) = me(:, j) + f%rotary*wl*dn*dn(j)
        if (.not. f%bending) ke(:, j) = ke(:, j) + f%stiffness*wl*dn*dn(j)
      end do
    end do
  end subroutine element_matrices

  !> Lowest `nm` modes of field f: nodal vectors (2*(ne+1) rows, the clamped values as
  !> zeros), M-normalised, signed so that the tip value is positive.
  subroutine field_modes(f, le, ne, nm, what, v, lam, error)
    type(mode_field), intent(in) :: f
    real(dp), intent(in) :: le
    integer, intent(in) :: ne, nm
    character(len=*), intent(in) :: what
    real(dp), allocatable, intent(out) :: v(:, :), lam(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp) :: ke(4, 4), me(4, 4)
    if (nm == 0) then
      allocate(v(2*ne + 2, 0), lam(0)); return
    end if
    call element_matrices(f, le, ke, me)
    if (ne > dense_elements) then
      call field_modes_banded(f, le, ke, me, ne, nm, what, v, lam, error)
    else
      call field_modes_dense(f, ke, me, ne, nm, what, v, lam, error)
    end if
  end subroutine field_modes

  !> Lowest `nm` modes of field f from the dense matrices of its ne elements (ke, me).
  subroutine field_modes_dense(f, ke, me, ne, nm, what, v, lam, error)
    type(mode_field), intent(in) :: f
    real(dp), intent(in) :: ke(4, 4), me(4, 4)
    integer, intent(in) :: ne, nm
    character(len=*), intent(in) :: what
    real(dp), allocatable, intent(out) :: v(:, :), lam(:)
    type(error_type), allocatable, intent(out) :: error
    real(dp), allocatable :: kk(:, :), mm(:, :), w(:)
    integer :: nd, el, i0, i, j, k
    nd = 2*ne + 2 - f%nfix
    allocate(kk(nd, nd), mm(nd, nd), w(nd), v(2*ne + 2, nm), lam(nm))
    kk = 0.0_dp; mm = 0.0_dp
    do el = 1, ne
      i0 = 2*(el - 1) - f%nfix        ! global index offset (clamped values removed)
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
      v(f%nfix + 1:, k) = mm(:, nd + 1 - k)/sqrt(w(nd + 1 - k))
      if (v(2*ne + 1, k) < 0.0_dp) v(f%nfix + 1:, k) = -v(f%nfix + 1:, k)
      lam(k) = 1.0_dp/w(nd + 1 - k)
    end do
  end subroutine field_modes_dense

  !> Modes of a long beam (more than dense_elements elements) from the banded matrices: each
  !> mode by inverse iteration with (K - sigma M) (LAPACK's banded LU), sigma the mode's
  !> eigenvalue on a coarse mesh, then its eigenvalue as the Rayleigh quotient summed
  !> element by element. Work and memory grow as the number of elements, not its cube and
  !> square.
  subroutine field_modes_banded(f, le, ke, me, ne, nm, what, v, lam, error)
    type(mode_field), intent(in) :: f
    real(dp), intent(in) :: le, ke(4, 4), me(4, 4)
    integer, intent(in) :: ne, nm
    character(len=*), intent(in) :: what
    real(dp), allocatable, intent(out) :: v(:, :), lam(:)
    type(error_type), allocatable, intent(out) :: error
    integer, parameter :: kd = 3
    real(dp), allocatable :: kb(:, :), mb(:, :), a(:, :), x(:), y(:)
    integer :: nd, el, i0, i, j, k, it
    real(dp) :: sigma
    nd = 2*ne + 2 - f%nfix
    allocate(kb(kd + 1, nd), mb(kd + 1, nd), x(nd), y(nd), v(2*ne + 2, nm), lam(nm))
    kb = 0.0_dp; mb = 0.0_dp
    do el = 1, ne
      i0 = 2*(el - 1) - f%nfix        ! global index offset (clamped values removed)
      do j = 1, 4
        do i = j, 4
          if (i0 + j < 1) cycle
          kb(1 + i - j, i0 + j) = kb(1 + i - j, i0 + j) + ke(i, j)
          mb(1 + i - j, i0 + j) = mb(1 + i - j, i0 + j) + me(i, j)
        end do
      end do
    end do
    v = 0.0_dp
    ! shifts: the eigenvalues of the same beam on a coarse mesh (dense, accurate to about 1e-4
    ! for the modes kept); inverse iteration then converges to the fine mesh's modes
    block
      real(dp), allocatable :: vc(:, :)
      real(dp) :: kc(4, 4), mc(4, 4)
      integer :: nc
      nc = min(max(dense_elements, shift_elements*nm), max_shift_mesh)
      call element_matrices(f, le*ne/nc, kc, mc)
      call field_modes_dense(f, kc, mc, nc, nm, what, vc, lam, error); if (allocated(error)) return
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
      if (x(2*ne + 1 - f%nfix) < 0.0_dp) x = -x
      v(f%nfix + 1:, k) = x
      ! the Rayleigh quotient of the converged mode, element by element: more accurate than
      ! the banded solver's eigenvalue, which the Cholesky of the ill-conditioned K limits
      lam(k) = element_energy(ke, v(:, k))/element_energy(me, v(:, k))
    end do
  contains
    !> sum over elements of x_e' A_e x_e, x with the clamped values as zeros.
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
  end subroutine field_modes_banded

  !> Translational and rotational mode shapes (3 x m) at point r of the body frame: the
  !> section at x = r(1) (Hermite interpolation); its small rotation carries the offset
  !> (0, r(2), r(3)).
  pure subroutine beam_point_shapes(bs, r, psi, phi)
    type(beam_shape), intent(in) :: bs
    real(dp), intent(in) :: r(3)
    real(dp), intent(out) :: psi(:, :), phi(:, :)
    real(dp) :: le, x, xi, psi_axis(3, size(psi, 2))
    integer :: el
    le = bs%length/bs%ne
    x = min(max(r(1), 0.0_dp), bs%length)
    el = min(int(x/le) + 1, bs%ne)
    xi = x/le - (el - 1)
    call section_shapes(bs, el, xi, psi_axis, phi)
    call point_shapes(psi_axis, phi, [0.0_dp, r(2), r(3)], psi)
  end subroutine beam_point_shapes
  !> Translational shapes of the axis point at x (0 <= x <= length) and their first and
  !> second derivatives along x (3 x m each), by the Hermite interpolation that
  !> section_shapes uses (the second derivative is the element's: it jumps at the nodes).
  pure subroutine axis_shapes(bs, x, psi, dpsi, ddpsi)
    type(beam_shape), intent(in) :: bs
    real(dp), intent(in) :: x
    real(dp), intent(out) :: psi(:, :), dpsi(:, :), ddpsi(:, :)
    real(dp) :: le, xc, xi, nn(4), dn(4), d2(4)
    integer :: el, ky, kz, kx
    le = bs%length/bs%ne
    xc = min(max(x, 0.0_dp), bs%length)
    el = min(int(xc/le) + 1, bs%ne)
    xi = xc/le - (el - 1)
    call hermite(xi, le, nn, dn)
    d2 = [(-6.0_dp + 12.0_dp*xi)/le**2, (-4.0_dp + 6.0_dp*xi)/le, (6.0_dp - 12.0_dp*xi)/le**2, (-2.0_dp + 6.0_dp*xi)/le]
    ky = bs%my; kz = ky + bs%mz; kx = kz + bs%mx
    psi = 0.0_dp; dpsi = 0.0_dp; ddpsi = 0.0_dp
    associate(vy => bs%vy(2*el-1:2*el+2, :), vz => bs%vz(2*el-1:2*el+2, :), vx => bs%vx(2*el-1:2*el+2, :))
      psi(2, 1:ky) = matmul(nn, vy); dpsi(2, 1:ky) = matmul(dn, vy); ddpsi(2, 1:ky) = matmul(d2, vy)
      psi(3, ky+1:kz) = matmul(nn, vz); dpsi(3, ky+1:kz) = matmul(dn, vz); ddpsi(3, ky+1:kz) = matmul(d2, vz)
      psi(1, kz+1:kx) = matmul(nn, vx); dpsi(1, kz+1:kx) = matmul(dn, vx); ddpsi(1, kz+1:kx) = matmul(d2, vx)
    end associate
  end subroutine axis_shapes
end module pymr_model_beam_modes
