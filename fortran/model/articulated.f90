!> Forward dynamics in O(n): the articulated-body algorithm (Featherstone) in inertial
!> Pluecker coordinates, extended to flexible bodies, as an alternative to assembling M and
!> P and factoring M (model/assembly.f90). It solves the same equations, M qdd = P, after
!> the same body terms.
!>
!> Every spatial quantity is inertial, as in the assembly, so no transform is needed between
!> bodies. With lin_b the part of body b's spatial acceleration linear in qdd (its bias part
!> is inside the bias wrench w_b), the wrench that b's joint passes to b's subtree is
!> J_b = IA_b lin_b + pA_b, with the articulated inertia IA_b and bias pA_b of the subtree:
!>
!> - Backward (leaves to base): a rigid body starts from its i6 and w and adds, for every
!>   child c, the child's articulated terms after c's joint, ia_c and pa_c. A flexible body
!>   with modal accelerations add and modal columns Cm_c at its children's joint points has
!>     [K_AA K_Aa; K_Aa^T K_aa] [lin; add] + [b_A; b_a] = [J_b; 0],
!>   K_AA = i6 + sum ia_c, K_Aa = mva + sum ia_c Cm_c, K_aa = mmm + sum Cm_c^T ia_c Cm_c,
!>   b_A = w + sum pa_c, b_a = wam - tau_modal + sum Cm_c^T pa_c;
!>   its modal accelerations are condensed out: IA = K_AA - K_Aa K_aa^-1 K_Aa^T,
!>   pA = b_A - K_Aa K_aa^-1 b_a. Then b's joint, of columns S = [S_P S_F] (prescribed,
!>   free): pA' = pA + IA S_P qdd_P, U = IA S_F, D = S_F^T U, u = tau_F - S_F^T pA', and
!>   ia_b = IA - U D^-1 U^T, pa_b = pA' + U D^-1 u.
!> - Forward (base to leaves): lin at b's joint point = lin of the parent (plus its modal
!>   columns times its modal accelerations), qdd_F = D^-1 (u - U^T lin), lin_b = lin + S
!>   qdd, and a flexible body's add = -K_aa^-1 (K_Aa^T lin_b + b_a).
!>
!> A joint of several coordinates is condensed one column at a time (its primitives are
!> joined by massless frames); the flexible bodies' K_aa are factored by potrf.
module pymr_model_articulated
  use pymr_env_kinds, only : dp
  use pymr_env_error, only : error_type, fatal_error, stat_solver
  use pymr_env_text, only : fmt
  use pymr_env_lapack, only : potrf, potrs
  use pymr_model_types, only : model_data, model_work
  use pymr_model_scene, only : big_length
  implicit none
  private
  public :: articulated_accelerations

contains

  !> qdd of the state whose body terms, applied loads (w, wam, tau) and kinematics wk holds;
  !> the prescribed coordinates' accelerations are given in qdd.
  subroutine articulated_accelerations(d, wk, qdd, error)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(inout) :: qdd(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: b
    do b = d%nb, 2, -1
      call subtree_terms(d, wk, b, error); if (allocated(error)) return
      call through_joint(d, wk, b, qdd, error); if (allocated(error)) return
    end do
    wk%ab%lin(:, 1) = 0.0_dp
    do b = 2, d%nb
      call body_acceleration(d, wk, b, qdd)
    end do
  end subroutine articulated_accelerations

  !> Articulated inertia and bias of body b's subtree at b's frame (before b's joint), in
  !> wk%ab%ia(:, :, b), wk%ab%pa(:, b); a flexible body's modal accelerations condensed out.
  subroutine subtree_terms(d, wk, b, error)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: b
    type(error_type), allocatable, intent(out) :: error
    integer :: i, c, m
    associate(ia => wk%ab%ia(:, :, b), pa => wk%ab%pa(:, b))
      ia = wk%i6(:, :, b); pa = wk%w(:, b)
      m = d%nm(b)
      do i = d%child_ptr(b), d%child_ptr(b + 1) - 1
        c = d%child_idx(i)
        ia = ia + wk%ab%ia(:, :, c); pa = pa + wk%ab%pa(:, c)
      end do
      if (m == 0) return
      call condense_modes(d, wk, b, m, ia, pa, error)
    end associate
  end subroutine subtree_terms

  !> A flexible body's modal accelerations condensed out of its subtree's terms (ia, pa on
  !> entry: K_AA and b_A), keeping the factored K_aa, K_Aa and b_a for the forward pass.
  subroutine condense_modes(d, wk, b, m, ia, pa, error)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: b, m
    real(dp), intent(inout) :: ia(6, 6), pa(6)
    type(error_type), allocatable, intent(out) :: error
    integer :: i, c, l
    real(dp) :: x(m, 6), y(m), g(6)
    associate(kaa => wk%ab%kaa(1:m, 1:m, b), kam => wk%ab%kam(:, 1:m, b), ba => wk%ab%ba(1:m, b))
      kam = wk%mva(:, 1:m, b)
      kaa = d%flex(b)%mmm
      if (allocated(wk%maa)) kaa = kaa + wk%maa(1:m, 1:m, b)
      ba = wk%wam(1:m, b) - wk%tau(d%a0(b):d%a0(b) + m - 1)
      do i = d%child_ptr(b), d%child_ptr(b + 1) - 1
        c = d%child_idx(i)
        do l = 1, m
          g = matmul(wk%ab%ia(:, :, c), wk%cm(:, l, c))
          kam(:, l) = kam(:, l) + g
          kaa(:, l) = kaa(:, l) + matmul(transpose(wk%cm(:, 1:m, c)), g)
          ba(l) = ba(l) + dot_product(wk%cm(:, l, c), wk%ab%pa(:, c))
        end do
      end do
      call potrf(kaa, "the modal mass of body '" // trim(d%body_name(b)) // "' with what it carries", error)
      if (allocated(error)) return
      ! IA = K_AA - K_Aa K_aa^-1 K_Aa^T, pA = b_A - K_Aa K_aa^-1 b_a
      x(1:m, :) = transpose(kam)
      call potrs(kaa, x(1:m, :), 'K_aa', error); if (allocated(error)) return
      ia = ia - matmul(kam, x(1:m, :))
      y(1:m) = ba
      call potrs(kaa, y(1:m), 'K_aa', error); if (allocated(error)) return
      pa = pa - matmul(kam, y(1:m))
    end associate
  end subroutine condense_modes

  !> Body b's joint: its columns, from the child's side to the parent's, condensed out of
  !> the subtree's terms one at a time (the joint is a chain of one-coordinate primitives
  !> with massless frames between them), leaving the articulated terms the parent sees in
  !> wk%ab%ia(:, :, b), wk%ab%pa(:, b). A prescribed column's known acceleration moves into
  !> the bias; a free column k keeps u_k / D_k and r_k / D_k (u_k = IA s_k, D_k = s_k . u_k,
  !> r_k = tau_k - s_k . pA) for the forward pass: qdd_k = (r_k - u_k . lin) / D_k.
  subroutine through_joint(d, wk, b, qdd, error)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: b
    real(dp), intent(in) :: qdd(:)
    type(error_type), allocatable, intent(out) :: error
    integer :: k, i, j
    real(dp) :: u(6), v(6), dd, r
    associate(ia => wk%ab%ia(:, :, b), pa => wk%ab%pa(:, b))
      do k = d%c0(b) + d%nc(b) - 1, d%c0(b), -1
        do i = 1, 6
          u(i) = ia(i, 1)*wk%s(1, k) + ia(i, 2)*wk%s(2, k) + ia(i, 3)*wk%s(3, k) + ia(i, 4)*wk%s(4, k) + &
            & ia(i, 5)*wk%s(5, k) + ia(i, 6)*wk%s(6, k)
        end do
        if (d%prescribed(k)) then
          pa = pa + u*qdd(k)
          cycle
        end if
        dd = dot_product(u, wk%s(:, k))
        if (dd /= dd) then
          ! NaN: the state (a position, a rate) overflowed before the inertia was formed
          call fatal_error(error, 'the motion has grown beyond the numbers: the articulated inertia of coordinate ' // &
            & trim(d%qname(k)) // ' is NaN (an unstable step, or a force that grows without bound)', stat_solver)
          return
        else if (lost_in_rounding(dd, wk%s(:, k), ia)) then
          call fatal_error(error, 'the motion has grown beyond the numbers: coordinate ' // trim(d%qname(k)) // &
            & ' moves bodies ' // fmt(norm2(wk%s(1:3, k))) // ' m from the origin, where its articulated inertia (' // &
            & fmt(dd) // ') is lost in rounding (an unstable step, or a force that grows without bound)', stat_solver)
          return
        else if (.not. dd > 0.0_dp) then
          call fatal_error(error, 'the mass matrix is not positive definite: the articulated inertia of ' // &
            & 'coordinate ' // trim(d%qname(k)) // ' is ' // fmt(dd), stat_solver); return
        end if
        r = wk%tau(k) - dot_product(wk%s(:, k), pa)
        v = u/dd
        j = k - d%c0(b) + 1
        wk%ab%u(:, j, b) = v; wk%ab%r(j, b) = r/dd
        do j = 1, 6
          do i = 1, 6
            ia(i, j) = ia(i, j) - u(i)*v(j)
          end do
        end do
        pa = pa + u*(r/dd)
      end do
    end associate
  end subroutine through_joint

  !> Whether the articulated inertia dd = s . IA s of a turning joint whose axis is beyond the
  !> bound on lengths from the origin is within the rounding of its terms
  !> (100 times epsilon the sum of |IA_ij s_i s_j|): the state has grown so far (a body at
  !> 1e20 m after an unstable step) that the inertia is lost, which read as 'not positive
  !> definite: ... is 0'. Nearer the origin a zero is the mass matrix's own fault (an axis
  !> with no inertia about it).
  pure logical function lost_in_rounding(dd, s, ia) result(lost)
    real(dp), intent(in) :: dd, s(6), ia(6, 6)
    ! every joint at every evaluation asks: the distance first, the terms only beyond it
    lost = abs(s(1)) + abs(s(2)) + abs(s(3)) > big_length
    if (.not. lost) return
    lost = norm2(s(1:3)) > big_length .and. abs(dd) <= 100.0_dp*epsilon(1.0_dp)*dot_product(abs(s), &
      & matmul(abs(ia), abs(s)))
  end function lost_in_rounding

  !> Forward pass at body b: its coordinates' accelerations, from the parent's side, the
  !> part of its spatial acceleration linear in qdd, and (flexible) its modal accelerations.
  subroutine body_acceleration(d, wk, b, qdd)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    integer, intent(in) :: b
    real(dp), intent(inout) :: qdd(:)
    integer :: a, l, k, j, m
    real(dp) :: lin(6)
    type(error_type), allocatable :: e
    a = d%parent(b)
    lin = wk%ab%lin(:, a)
    do l = 1, d%nm(a)
      lin = lin + wk%cm(:, l, b)*qdd(d%a0(a) + l - 1)
    end do
    do k = d%c0(b), d%c0(b) + d%nc(b) - 1
      if (.not. d%prescribed(k)) then
        j = k - d%c0(b) + 1
        qdd(k) = wk%ab%r(j, b) - dot_product(wk%ab%u(:, j, b), lin)
      end if
      lin = lin + wk%s(:, k)*qdd(k)
    end do
    wk%ab%lin(:, b) = lin
    m = d%nm(b)
    if (m == 0) return
    associate(add => qdd(d%a0(b):d%a0(b) + m - 1))
      add = -(matmul(transpose(wk%ab%kam(:, 1:m, b)), lin) + wk%ab%ba(1:m, b))
      call potrs(wk%ab%kaa(1:m, 1:m, b), add, 'K_aa', e)
    end associate
  end subroutine body_acceleration

end module pymr_model_articulated
