!> Modal flexible bodies in the floating frame of reference (METHOD.md section 1).
!>
!> A flexible body is described by mass points: position s_p (body frame), mass m_p and
!> translational mode shapes Psi_p (3 x m). For a built-in beam the points are the Gauss
!> points of its Hermite elements (with torsional modes, rings of four points around them:
!> model/beam_modes.f90), so sums over them reproduce the consistent finite-element mass
!> matrix exactly. With Z_p = [s_p, Psi_p] (3 x (1+m)) all inertia
!> invariants follow from the first moment F = sum m_p Z_p and the second-moment tensor
!> W(i,j,alpha,beta) = sum m_p Z_p(i,alpha) Z_p(j,beta), computed once. The deformed
!> point is c_p = Z_p [1; a].
module pymr_model_flexbody
  use pymr_env_kinds, only : dp
  use pymr_model_spatial, only : skew, rigid_inertia
  implicit none
  private
  public :: flex_data, flex_invariants, flex_from_moments, flex_body_terms, flex_work, small_rotation, point_shapes, modal_nodes
  public :: deformed_modal_moments, undeformed_modal_moments, point_deflection, central_inertia

  !> Invariants and modal properties of one flexible body.
  type :: flex_data
    !> Number of modes.
    integer :: m = 0
    !> Total mass (kg).
    real(dp) :: mass = 0.0_dp
    !> First moments F(3, 0:m) and second moments W(3, 3, 0:m, 0:m) (a contiguous 3 x 3
    !> block per pair of columns of Z).
    real(dp), allocatable :: first(:, :), w(:, :, :, :)
    !> Gyroscopic vectors G(:,l,k) = sum m_p Psi_l x Psi_k (so that summed over the points,
    !> Psi_k . (w x Psi_l) = w . G(:,l,k)).
    real(dp), allocatable :: gyro(:, :, :)
    !> Modal mass matrix sum m_p Psi_p^T Psi_p (identity for mass-normalised modes).
    real(dp), allocatable :: mmm(:, :)
    !> Squared circular frequencies (rad^2/s^2) and modal damping 2 zeta omega (1/s).
    real(dp), allocatable :: omega2(:), damp(:)
    !> Geometric stiffness of a beam per unit axial load factor (m x m): kg1 for a uniform
    !> axial acceleration, kg2 for the centrifugal load (see beam_geometric_stiffness);
    !> unallocated when the body has none.
    real(dp), allocatable :: kg1(:, :), kg2(:, :)
    !> Mode data at the mass points (kept for the modal file writer): s(3,np), mp(np), psi(3,m,np)
    real(dp), allocatable :: ps(:, :), pm(:), ppsi(:, :, :)
    !> The body's size (its farthest mass point from its origin, m) and the largest
    !> Frobenius norm of a mass point's shapes psi(:,:,p): |psi_p a| <= shape_bound |a|.
    real(dp) :: size_m = 0.0_dp, shape_bound = 0.0_dp
  end type flex_data

  !> Points of a modal-file body with their shapes, where joints and markers attach.
  type :: modal_nodes
    integer :: np = 0
    real(dp), allocatable :: x(:, :), psi(:, :, :), phi(:, :, :)
  end type modal_nodes

  !> Work arrays of one evaluation of a flexible body.
  type :: flex_work
    !> Wa(i,j,beta) = sum m_p c_p(i) Z_p(j,beta).
    real(dp), allocatable :: wa(:, :, :)
    !> Deformed first moment S (3), rotational-modal coupling Cr(3,m), inertia J about the origin.
    real(dp), allocatable :: cr(:, :)
    real(dp) :: s(3) = 0.0_dp, j(3, 3) = 0.0_dp
  end type flex_work

contains

  !> The largest displacement (m) of a flexible body's mass points at modal coordinates a
  !> (0 for a body that keeps no mass points), when it may exceed `limit` (m): below
  !> fd%shape_bound |a| <= limit it is not sought point by point, and 0 is returned.
  pure real(dp) function point_deflection(fd, a, limit) result(deflection)
    type(flex_data), intent(in) :: fd
    real(dp), intent(in) :: a(:), limit
    integer :: p
    deflection = 0.0_dp
    if (.not. allocated(fd%ppsi)) return
    if (fd%shape_bound*norm2(a) <= limit) return
    do p = 1, size(fd%pm)
      deflection = max(deflection, norm2(matmul(fd%ppsi(:, :, p), a)))
    end do
  end function point_deflection

  include 'vector_products.inc'

  !> Invariants from mass points: s(3,np) positions, mp(np) masses, psi(3,m,np) mode shapes.
  subroutine flex_invariants(s, mp, psi, fd)
    real(dp), intent(in) :: s(:, :), mp(:), psi(:, :, :)
    type(flex_data), intent(inout) :: fd
    integer :: p, m, i, j, al, be
    real(dp) :: z(3, 0:size(psi, 2))
    real(dp), allocatable :: first(:, :), w(:, :, :, :)
    m = size(psi, 2)
    allocate(first(3, 0:m), w(3, 3, 0:m, 0:m))
    first = 0.0_dp; w = 0.0_dp
    do p = 1, size(mp)
      z(:, 0) = s(:, p)
      z(:, 1:m) = psi(:, :, p)
      first = first + mp(p)*z
      do be = 0, m
        do al = 0, m
          do j = 1, 3
            do i = 1, 3
              w(i, j, al, be) = w(i, j, al, be) + mp(p)*z(i, al)*z(j, be)
            end do
          end do
        end do
      end do
    end do
    call flex_from_moments(sum(mp), first, w, fd)
    fd%ps = s; fd%pm = mp; fd%ppsi = psi
    fd%size_m = 0.0_dp; fd%shape_bound = 0.0_dp
    do p = 1, size(mp)
      fd%size_m = max(fd%size_m, norm2(s(:, p)))
      fd%shape_bound = max(fd%shape_bound, norm2(psi(:, :, p)))
    end do
  end subroutine flex_invariants

  !> Invariants from the body's moments: mass, first moments F(3, 0:m) and second moments
  !> W(3, 3, 0:m, 0:m) (from mass points, or given by a modal file's invariants block); the
  !> modal mass matrix is the trace of W's modal blocks, the gyroscopic vectors their axial
  !> vectors.
  subroutine flex_from_moments(mass, first, w, fd)
    real(dp), intent(in) :: mass, first(:, 0:), w(:, :, 0:, 0:)
    type(flex_data), intent(inout) :: fd
    integer :: m, al, be
    m = ubound(first, 2)
    fd%m = m
    fd%mass = mass
    allocate(fd%first(3, 0:m), fd%w(3, 3, 0:m, 0:m))
    fd%first = first; fd%w = w
    allocate(fd%mmm(m, m), fd%gyro(3, m, m))
    do al = 1, m
      do be = 1, m
        fd%mmm(al, be) = w(1, 1, al, be) + w(2, 2, al, be) + w(3, 3, al, be)
        fd%gyro(:, al, be) = [w(2, 3, al, be) - w(3, 2, al, be), w(3, 1, al, be) - w(1, 3, al, be), &
          & w(1, 2, al, be) - w(2, 1, al, be)]
      end do
    end do
  end subroutine flex_from_moments

  !> The undeformed body's inertia about its centre of mass (body axes, kg m^2): tr(C) I - C
  !> with C = W(:,:,0,0) - m c c^T its second moment there, c = F(:,0)/m.
  pure function central_inertia(fd) result(jc)
    type(flex_data), intent(in) :: fd
    real(dp) :: jc(3, 3), c(3), tr
    integer :: i
    c = fd%first(:, 0)/fd%mass
    jc = -(fd%w(:, :, 0, 0) - fd%mass*spread(c, 2, 3)*spread(c, 1, 3))
    tr = -(jc(1, 1) + jc(2, 2) + jc(3, 3))
    do i = 1, 3
      jc(i, i) = jc(i, i) + tr
    end do
  end function central_inertia

  !> Mode shapes of a point at `x` of the body frame: translation psi = psi0 + phi0 x r
  !> for a point offset r from a node with shapes psi0, phi0 (small rotation of the section).
  pure subroutine point_shapes(psi0, phi0, r, psi)
    real(dp), intent(in) :: psi0(:, :), phi0(:, :), r(3)
    real(dp), intent(out) :: psi(:, :)
    integer :: k
    do k = 1, size(psi0, 2)
      psi(:, k) = psi0(:, k) + cross(phi0(:, k), r)
    end do
  end subroutine point_shapes

  !> Spatial mass matrix blocks and bias of a flexible body.
  !>
  !> Inputs: pose (rot, pos), spatial velocity vel = [v_O; w] and bias acceleration acc
  !> (inertial Pluecker), modal coordinates a and rates ad.
  !> Outputs: i6 (6x6, the deformed body's spatial inertia about the origin),
  !> mva (6 x m, coupling of frame motion and modal rates), and the bias terms
  !> wv (6, spatial wrench) and wam (m): inertia forces at zero joint and modal
  !> accelerations plus the elastic forces omega^2 a. Gravity and damping are effects.
  pure subroutine flex_body_terms(fd, wk, rot, pos, vel, acc, a, ad, i6, mva, wv, wam, modal_only, full_inertia)
    type(flex_data), intent(in) :: fd
    type(flex_work), intent(inout) :: wk
    real(dp), intent(in) :: rot(3, 3), pos(3), vel(6), acc(6), a(:), ad(:)
    real(dp), intent(inout) :: i6(6, 6), wv(6)
    real(dp), intent(out) :: mva(:, :), wam(:)
    !> Only the modal rows' terms (mva, wam): i6 and wv are left as they were.
    logical, intent(in) :: modal_only
    !> deformation_inertia 'full': the modal gyroscopic forces of Cr's deformed part
    !> (dropped with 'linear', whose Cr is constant).
    logical, intent(in) :: full_inertia
    integer :: m, k, l, al, be
    real(dp) :: ah(0:size(a)), d(3), jc(3, 3), cm(3, 3), pd(3), wb(3), alv(3), alw(3)
    real(dp) :: f(3), n(3), psiad(3), tr, tmp(3)
    m = fd%m
    ah(0) = 1.0_dp; ah(1:m) = a
    ! Wa(:,:,0) = sum m c s^T and S = F ah (Wa(:,:,1:m) and Cr come from the
    ! deformation_inertia routines: deformed, or fixed at their undeformed values)
    wk%wa(:, :, 0) = fd%w(:, :, 0, 0)
    do al = 1, m
      wk%wa(:, :, 0) = wk%wa(:, :, 0) + ah(al)*fd%w(:, :, al, 0)
    end do
    wk%s = fd%first(:, 0)
    do al = 1, m
      wk%s = wk%s + ah(al)*fd%first(:, al)
    end do
    if (.not. modal_only) then
      cm = 0.0_dp
      do be = 0, m
        cm = cm + ah(be)*wk%wa(:, :, be)
      end do
      tr = cm(1, 1) + cm(2, 2) + cm(3, 3)
      wk%j = -cm
      do k = 1, 3
        wk%j(k, k) = wk%j(k, k) + tr
      end do
      ! spatial inertia of the deformed body about the inertial origin
      d = wk%s/fd%mass
      jc = wk%j + fd%mass*matmul(skew(d), skew(d))
      i6 = rigid_inertia(fd%mass, pos + matmul(rot, d), matmul(rot, matmul(jc, transpose(rot))))
    end if
    ! coupling columns [R S1; p x R S1 + R Cr]
    do k = 1, m
      tmp = matmul(rot, fd%first(:, k))
      mva(1:3, k) = tmp
      mva(4:6, k) = cross(pos, tmp) + matmul(rot, wk%cr(:, k))
    end do
    ! body-frame velocities and accelerations of the body origin
    pd = vel(1:3) + cross(vel(4:6), pos)
    wb = matmul(transpose(rot), vel(4:6))
    alv = matmul(transpose(rot), acc(1:3) + cross(acc(4:6), pos) + cross(vel(4:6), pd))
    alw = matmul(transpose(rot), acc(4:6))
    ! inertia forces M_bb [alv; alw; 0] + quadratic velocity terms (body frame)
    if (.not. modal_only) then
      psiad = matmul(fd%first(:, 1:m), ad)
      f = fd%mass*alv + cross(alw, wk%s) + cross(wb, cross(wb, wk%s)) + 2.0_dp*cross(wb, psiad)
      n = cross(wk%s, alv) + matmul(wk%j, alw) + cross(wb, matmul(wk%j, wb))
      do l = 1, m
        tr = wk%wa(1, 1, l) + wk%wa(2, 2, l) + wk%wa(3, 3, l)
        n = n + 2.0_dp*ad(l)*(wb*tr - matmul(transpose(wk%wa(:, :, l)), wb))
      end do
      ! to inertial Pluecker: [R f; R n + p x R f]
      wv(1:3) = matmul(rot, f)
      wv(4:6) = matmul(rot, n) + cross(pos, wv(1:3))
    end if
    call modal_bias(fd, wk, a, ad, wb, alv, alw, full_inertia, wam)
  end subroutine flex_body_terms

  !> The modal rows' bias forces: the modal inertia of the body-frame motion of the origin
  !> (alv, alw, wb), the deformed body's gyroscopic forces (full_inertia) and the stiffness.
  pure subroutine modal_bias(fd, wk, a, ad, wb, alv, alw, full_inertia, wam)
    type(flex_data), intent(in) :: fd
    type(flex_work), intent(in) :: wk
    real(dp), intent(in) :: a(:), ad(:), wb(3), alv(3), alw(3)
    logical, intent(in) :: full_inertia
    real(dp), intent(out) :: wam(:)
    integer :: k, l
    real(dp) :: tr
    do k = 1, fd%m
      tr = wk%wa(1, 1, k) + wk%wa(2, 2, k) + wk%wa(3, 3, k)
      wam(k) = dot_product(fd%first(:, k), alv) + dot_product(wk%cr(:, k), alw) &
        & + quad_form(wk%wa(:, :, k), wb) - dot_product(wb, wb)*tr
      if (full_inertia) then
        do l = 1, fd%m
          ! 2 sum_p m_p Psi_k . (w x Psi_l) ad_l
          wam(k) = wam(k) + 2.0_dp*ad(l)*dot_product(wb, fd%gyro(:, l, k))
        end do
      end if
      wam(k) = wam(k) + fd%omega2(k)*a(k)
    end do
  end subroutine modal_bias

  !> v . (A v) for a 3 x 3 matrix A.
  pure real(dp) function quad_form(a3, v)
    real(dp), intent(in) :: a3(3, 3), v(3)
    quad_form = v(1)*(a3(1, 1)*v(1) + a3(1, 2)*v(2) + a3(1, 3)*v(3)) &
      & + v(2)*(a3(2, 1)*v(1) + a3(2, 2)*v(2) + a3(2, 3)*v(3)) &
      & + v(3)*(a3(3, 1)*v(1) + a3(3, 2)*v(2) + a3(3, 3)*v(3))
  end function quad_form

  !> deformation_inertia 'full': the deformed parts of the second moments,
  !> Wa(:,:,k) = sum_p m_p c_p Psi_p(:,k)^T (k = 1..m) with c_p = s_p + Psi_p a, and the
  !> rotational-modal coupling Cr(:,k) = sum_p m_p c_p x Psi_p(:,k). With them the body's
  !> inertia J(a) is exact (quadratic in a) and Cr(a) linear in a.
  pure subroutine deformed_modal_moments(fd, wk, a)
    type(flex_data), intent(in) :: fd
    type(flex_work), intent(inout) :: wk
    real(dp), intent(in) :: a(:)
    integer :: al, be
    do be = 1, fd%m
      wk%wa(:, :, be) = fd%w(:, :, 0, be)
      do al = 1, fd%m
        wk%wa(:, :, be) = wk%wa(:, :, be) + a(al)*fd%w(:, :, al, be)
      end do
    end do
    call coupling_from_moments(fd%m, wk)
  end subroutine deformed_modal_moments

  !> deformation_inertia 'linear': Wa(:,:,k) = sum_p m_p s_p Psi_p(:,k)^T and Cr = Cr(0),
  !> set once. The inertia J(a) keeps its terms of first order in a; the dropped ones
  !> (sum m |w x Psi a|^2 / 2 + sum m (w x Psi a) . Psi ad in the kinetic energy) are of
  !> second order in the deformation, so the equations stay those of a kinetic energy.
  pure subroutine undeformed_modal_moments(fd, wk)
    type(flex_data), intent(in) :: fd
    type(flex_work), intent(inout) :: wk
    wk%wa(:, :, 1:fd%m) = fd%w(:, :, 0, 1:fd%m)
    call coupling_from_moments(fd%m, wk)
  end subroutine undeformed_modal_moments

  !> Cr(:,k) = axial vector of Wa(:,:,k) - Wa(:,:,k)^T = sum m_p c_p x Psi_p(:,k).
  pure subroutine coupling_from_moments(m, wk)
    integer, intent(in) :: m
    type(flex_work), intent(inout) :: wk
    integer :: k
    do k = 1, m
      wk%cr(:, k) = [wk%wa(2, 3, k) - wk%wa(3, 2, k), wk%wa(3, 1, k) - wk%wa(1, 3, k), &
        & wk%wa(1, 2, k) - wk%wa(2, 1, k)]
    end do
  end subroutine coupling_from_moments

  !> Small rotation of an attachment: R = exp(theta~) (Rodrigues), the left Jacobian
  !> jl (angular velocity = jl theta_dot) and jd = d(jl)/dt theta_dot.
  pure subroutine small_rotation(th, thd, r, jl, jd)
    real(dp), intent(in) :: th(3), thd(3)
    real(dp), intent(out) :: r(3, 3), jl(3, 3), jd(3)
    real(dp) :: t, t2, al, be, a1, b1, s(3, 3), c1(3), c2(3), sn, cs, tt
    integer :: i
    t2 = dot_product(th, th); t = sqrt(t2)
    if (t < 0.1_dp) then
      al = 0.5_dp - t2/24.0_dp + t2**2/720.0_dp - t2**3/40320.0_dp + t2**4/3628800.0_dp
      be = 1.0_dp/6.0_dp - t2/120.0_dp + t2**2/5040.0_dp - t2**3/362880.0_dp + t2**4/39916800.0_dp
      a1 = -1.0_dp/12.0_dp + t2/180.0_dp - t2**2/6720.0_dp + t2**3/453600.0_dp - t2**4/47900160.0_dp
      b1 = -1.0_dp/60.0_dp + t2/1260.0_dp - t2**2/60480.0_dp + t2**3/4989600.0_dp - t2**4/622702080.0_dp
      sn = t*(1.0_dp - t2/6.0_dp*(1.0_dp - t2/20.0_dp*(1.0_dp - t2/42.0_dp*(1.0_dp - t2/72.0_dp))))
    else
      sn = sin(t); cs = cos(t)
      al = (1.0_dp - cs)/t2
      be = (t - sn)/(t2*t)
      a1 = (t*sn - 2.0_dp*(1.0_dp - cs))/(t2*t2)
      b1 = (1.0_dp - cs)/(t2*t2) - 3.0_dp*(t - sn)/(t2*t2*t)
    end if
    s = skew(th)
    ! R = I + sin(t)/t th~ + (1-cos t)/t^2 th~^2 ; sin(t)/t = 1 - t^2 be
    tt = 1.0_dp - t2*be
    r = tt*s + al*matmul(s, s)
    jl = al*s + be*matmul(s, s)
    do i = 1, 3
      r(i, i) = r(i, i) + 1.0_dp
      jl(i, i) = jl(i, i) + 1.0_dp
    end do
    ! d/dt(jl) thd = (a1 th.thd) th x thd + (b1 th.thd) th x (th x thd) + be thd x (th x thd)
    c1 = cross(th, thd); c2 = cross(th, c1)
    jd = a1*dot_product(th, thd)*c1 + b1*dot_product(th, thd)*c2 + be*cross(thd, c1)
  end subroutine small_rotation
end module pymr_model_flexbody
