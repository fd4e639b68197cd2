!> Moving loads (&moving_load): a point mass m and a force F (body axes) travelling along
!> the x axis of a built-in beam, at s(t) by a travel law ('constant_speed': s0 until start,
!> then s0 + speed (t - start); 'table': the natural cubic spline through a history of
!> positions, so that its acceleration, which the mass's inertia along the path needs, is
!> continuous; at its first position before its first time, continued at its last rate
!> after its last). The load acts while
!> 0 <= s <= L (L the beam's length); it leaves the body when s passes either end: L (shot
!> exit) or 0 (its root).
!>
!> The point in the body frame is c = s e_x + Psi(s) a (Psi the 3 x m translational shapes
!> of the axis at x = s, by Hermite interpolation). With the tangent tg = e_x + Psi' a its
!> velocity relative to the body frame is c' = Psi ad + sd tg, and its relative
!> acceleration at zero modal accelerations cb = sdd tg + 2 sd Psi' ad + sd^2 Psi'' a. The
!> point mass adds, as the distributed body's terms do (model/flexbody.f90), to the body's
!> spatial inertia (a point mass at r = p + R c), its coupling columns [m R Psi; r x m R Psi],
!> its modal mass m Psi^T Psi (wk%maa) and its bias terms: with the inertial force
!> f = m (a_O + alpha x r + w x (v_O + w x r) + 2 w x R c' + R cb) - R F - m g at the bias
!> accelerations, the wrench [f; r x f] and the modal forces Psi^T R^T f (method.md).
module pymr_model_effect_moving_load
  use pymr_env_kinds, only : dp, name_len
  use pymr_model_types, only : model_data, model_work
  use pymr_model_spatial, only : rigid_inertia, rotation_vector
  use pymr_model_flexbody, only : small_rotation
  use pymr_model_beam_modes, only : axis_shapes
  use pymr_model_kinematics, only : forward_kinematics, marker_motion, marker_rotation
  use pymr_model_reactions, only : body_accelerations
  use pymr_model_time_table, only : time_table, table_spline
  use pymr_model_effect, only : effect_t, stage_load, energy_kinetic, energy_gravity, power_loads, power_motion
  implicit none
  private
  public :: moving_load, moving_load_effect, moving_load_effect_of, load_exit, travel_exit, record_exit

  !> One moving load: its name, body (model index) and the body's length (m), mass (kg),
  !> force (N, body axes), and its travel: start (s), s0 (m) and speed (m/s), or a table of
  !> positions (m) in time.
  type :: moving_load
    character(len=name_len) :: name = ''
    integer :: body = 0
    real(dp) :: length = 0.0_dp, mass = 0.0_dp, force(3) = 0.0_dp
    real(dp) :: start = 0.0_dp, s0 = 0.0_dp, speed = 0.0_dp
    logical :: tabulated = .false.
    type(time_table) :: table
    !> Its exit time (travel_exit): it acts up to it, and leaves when the run passes it; and
    !> whether it leaves through the root (s = 0) rather than the end s = L.
    real(dp) :: t_exit = huge(1.0_dp)
    logical :: exit_at_root = .false.
  end type moving_load

  !> A load's exit: whether it has left the body in the run, when (s), and the states then
  !> of its body's markers (model indices): position and velocity (inertial, m and m/s),
  !> rotation vector of the marker frame (rad, inertial) and its angular velocity (rad/s).
  type :: load_exit
    logical :: exited = .false.
    real(dp) :: t = 0.0_dp
    integer, allocatable :: markers(:)
    real(dp), allocatable :: r(:, :), v(:, :), angle(:, :), rate(:, :)
  end type load_exit

  type, extends(effect_t) :: moving_load_effect
    type(moving_load), allocatable :: loads(:)
    !> Gravity (m/s^2; zero when its effect is off).
    real(dp) :: g(3) = 0.0_dp
    type(load_exit), allocatable :: exits(:)
  contains
    procedure :: load => moving_terms
    procedure :: add_motion_energy => moving_energy
    procedure :: add_power_qdd => moving_power
    procedure :: save_state => save_exits
    procedure :: load_state => load_exits
  end type moving_load_effect

contains

  include 'vector_products.inc'

  !> The effect of loads on a model with data d, under gravity g (zero when off).
  function moving_load_effect_of(loads, g, d) result(e)
    type(moving_load), intent(in) :: loads(:)
    real(dp), intent(in) :: g(3)
    type(model_data), intent(in) :: d
    type(moving_load_effect) :: e
    integer :: i, k
    e%name = 'moving_loads'
    e%acts(stage_load) = .true.
    e%modal_mass_varies = .true.
    e%power_needs_accelerations = .true.
    e%loads = loads
    e%g = g
    do i = 1, size(loads)
      call travel_exit(loads(i), e%loads(i)%t_exit, e%loads(i)%exit_at_root)
    end do
    allocate(e%exits(size(loads)))
    do i = 1, size(loads)
      associate(x => e%exits(i))
        x%markers = pack([(k, k = 1, d%markers%n)], d%markers%body(1:d%markers%n) == loads(i)%body)
        k = size(x%markers)
        allocate(x%r(3, k), x%v(3, k), x%angle(3, k), x%rate(3, k))
        x%r = 0.0_dp; x%v = 0.0_dp; x%angle = 0.0_dp; x%rate = 0.0_dp
      end associate
    end do
  end function moving_load_effect_of

  !> Position s (m), rate sd and acceleration sdd of a load's travel at time t.
  pure subroutine travel(ld, t, s, sd, sdd)
    type(moving_load), intent(in) :: ld
    real(dp), intent(in) :: t
    real(dp), intent(out) :: s, sd, sdd
    sdd = 0.0_dp
    if (ld%tabulated) then
      if (t <= ld%table%t(1)) then
        s = ld%table%y(1); sd = 0.0_dp
      else
        call table_spline(ld%table, t, s, sd, sdd)
      end if
    else if (t < ld%start) then
      s = ld%s0; sd = 0.0_dp
    else
      s = ld%s0 + ld%speed*(t - ld%start); sd = ld%speed
    end if
  end subroutine travel

  !> When a load leaves its body (te, huge when it never does) and whether through its root
  !> (s = 0; else through its end s = L): for a constant speed at start + (L - s0)/speed
  !> (speed > 0) or start - s0/speed (speed < 0); for a table, in the first interval whose
  !> end position is off the beam, where its spline leaves it (bisection to rounding), else
  !> on the line that continues it.
  pure subroutine travel_exit(ld, te, root)
    type(moving_load), intent(in) :: ld
    real(dp), intent(out) :: te
    logical, intent(out) :: root
    integer :: i, n
    real(dp) :: sd, sdd, s_end
    te = huge(1.0_dp); root = .false.
    if (.not. ld%tabulated) then
      root = ld%speed < 0.0_dp
      if (ld%speed /= 0.0_dp) te = ld%start + (merge(0.0_dp, ld%length, root) - ld%s0)/ld%speed
      return
    end if
    if (.not. allocated(ld%table%t)) return
    n = size(ld%table%t)
    if (n < 2) return
    associate(t => ld%table%t, y => ld%table%y)
      do i = 1, n - 1
        if (off_beam(ld, y(i + 1))) then
          root = y(i + 1) < 0.0_dp
          te = spline_crossing(ld, t(i), t(i + 1)); return
        end if
      end do
      call table_spline(ld%table, t(n), s_end, sd, sdd)
      root = sd < 0.0_dp
      if (sd /= 0.0_dp) te = t(n) + (merge(0.0_dp, ld%length, root) - y(n))/sd
    end associate
  end subroutine travel_exit

  !> Is the place s off the load's beam (s < 0 or s > L)?
  pure logical function off_beam(ld, s)
    type(moving_load), intent(in) :: ld
    real(dp), intent(in) :: s
    off_beam = s < 0.0_dp .or. s > ld%length
  end function off_beam

  !> The time in [ta, tb] where a table's spline, on the beam at ta and off it at tb, leaves it.
  pure real(dp) function spline_crossing(ld, ta, tb) result(tc)
    type(moving_load), intent(in) :: ld
    real(dp), intent(in) :: ta, tb
    real(dp) :: lo, hi, s, sd, sdd
    integer :: k
    lo = ta; hi = tb
    do k = 1, 200
      tc = 0.5_dp*(lo + hi)
      if (tc <= lo .or. tc >= hi) exit
      call table_spline(ld%table, tc, s, sd, sdd)
      if (off_beam(ld, s)) then
        hi = tc
      else
        lo = tc
      end if
    end do
    tc = hi
  end function spline_crossing

  !> The load's point on its body at time t: shapes psi (3 x m) at s, the body-frame place
  !> c, the tangent tg = e_x + Psi' a, the relative velocity cv = Psi ad + sd tg and the
  !> relative acceleration at zero modal accelerations cb; `on` when s >= 0, up to its exit
  !> time and until the run has noted its exit (`gone`): a step that ends on the exit time
  !> sees the load throughout, and the run started again there sees none.
  pure subroutine point_on_body(ld, gone, d, t, q, qd, psi, c, tg, cv, cb, sd, on)
    type(moving_load), intent(in) :: ld
    logical, intent(in) :: gone
    type(model_data), intent(in) :: d
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(out) :: psi(:, :), c(3), tg(3), cv(3), cb(3), sd
    logical, intent(out) :: on
    real(dp) :: s, sdd, dpsi(3, size(psi, 2)), ddpsi(3, size(psi, 2))
    integer :: b, m
    b = ld%body; m = d%nm(b)
    call travel(ld, t, s, sd, sdd)
    on = s >= 0.0_dp .and. t <= ld%t_exit .and. .not. gone
    if (.not. on) return
    call axis_shapes(d%bshape(b), s, psi, dpsi, ddpsi)
    associate(a => q(d%a0(b):d%a0(b) + m - 1), ad => qd(d%a0(b):d%a0(b) + m - 1))
      c = matmul(psi, a); c(1) = c(1) + s
      tg = matmul(dpsi, a); tg(1) = tg(1) + 1.0_dp
      cv = matmul(psi, ad) + sd*tg
      cb = sdd*tg + 2.0_dp*sd*matmul(dpsi, ad) + sd**2*matmul(ddpsi, a)
    end associate
  end subroutine point_on_body

  !> The load stage: each load's inertia, coupling, modal mass and bias terms added to its
  !> body's (after the body terms). In fast-row evaluations a body whose parent is outside
  !> them gets its modal rows' terms only, as body_terms does.
  subroutine moving_terms(self, d, wk, t, q, qd, mask)
    class(moving_load_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: mask(:)
    integer :: i, b, k, m
    logical :: on
    real(dp) :: psi(3, d%mmax), c(3), tg(3), cv(3), cb(3), sd, r(3), u(3), f(3), fl(3), rp(3)
    real(dp), parameter :: point(3, 3) = 0.0_dp
    if (.not. allocated(wk%maa)) then
      allocate(wk%maa(d%mmax, d%mmax, d%nb)); wk%maa = 0.0_dp
    end if
    do i = 1, size(self%loads)
      if (mask(self%loads(i)%body)) wk%maa(:, :, self%loads(i)%body) = 0.0_dp
    end do
    do i = 1, size(self%loads)
      associate(ld => self%loads(i))
        b = ld%body; m = d%nm(b)
        if (.not. mask(b)) cycle
        call point_on_body(ld, self%exits(i)%exited, d, t, q, qd, psi(:, 1:m), c, tg, cv, cb, sd, on)
        if (.not. on) cycle
        associate(rot => wk%rot(:, :, b), w => wk%vel(4:6, b), acc => wk%acc(:, b))
          r = wk%pos(:, b) + matmul(rot, c)
          u = wk%vel(1:3, b) + cross(w, r)
          f = ld%mass*(acc(1:3) + cross(acc(4:6), r) + cross(w, u) + 2.0_dp*cross(w, matmul(rot, cv)) + &
            & matmul(rot, cb)) - matmul(rot, ld%force) - ld%mass*self%g
          if (mask(d%parent(b))) then
            wk%i6(:, :, b) = wk%i6(:, :, b) + rigid_inertia(ld%mass, r, point)
            wk%w(1:3, b) = wk%w(1:3, b) + f
            wk%w(4:6, b) = wk%w(4:6, b) + cross(r, f)
          end if
          fl = matmul(transpose(rot), f)
          do k = 1, m
            rp = ld%mass*matmul(rot, psi(:, k))
            wk%mva(1:3, k, b) = wk%mva(1:3, k, b) + rp
            wk%mva(4:6, k, b) = wk%mva(4:6, k, b) + cross(r, rp)
            wk%wam(k, b) = wk%wam(k, b) + dot_product(psi(:, k), fl)
          end do
          wk%maa(1:m, 1:m, b) = wk%maa(1:m, 1:m, b) + ld%mass*matmul(transpose(psi(:, 1:m)), psi(:, 1:m))
        end associate
      end associate
    end do
  end subroutine moving_terms

  !> Inertial place r and velocity v of a load's point (after forward_kinematics), with its
  !> tangent tg (body frame) and travel rate sd; `on` as point_on_body.
  subroutine point_motion(ld, gone, d, wk, t, q, qd, r, v, tg, sd, on, cb, psi)
    type(moving_load), intent(in) :: ld
    logical, intent(in) :: gone
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(out) :: r(3), v(3), tg(3), sd, cb(3), psi(:, :)
    logical, intent(out) :: on
    real(dp) :: c(3), cv(3)
    integer :: b
    b = ld%body
    call point_on_body(ld, gone, d, t, q, qd, psi, c, tg, cv, cb, sd, on)
    if (.not. on) return
    r = wk%pos(:, b) + matmul(wk%rot(:, :, b), c)
    v = wk%vel(1:3, b) + cross(wk%vel(4:6, b), r) + matmul(wk%rot(:, :, b), cv)
  end subroutine point_motion

  !> The loads' kinetic energy 1/2 m |v|^2 (with the travel's velocity) and, under
  !> gravity, their potential -m g . r (after forward_kinematics at (q, qd)).
  subroutine moving_energy(self, d, wk, t, q, qd, e)
    class(moving_load_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    real(dp), intent(inout) :: e(:)
    integer :: i
    logical :: on
    real(dp) :: r(3), v(3), tg(3), sd, cb(3), psi(3, d%mmax)
    do i = 1, size(self%loads)
      associate(ld => self%loads(i))
        call point_motion(ld, self%exits(i)%exited, d, wk, t, q, qd, r, v, tg, sd, on, cb, psi(:, 1:d%nm(ld%body)))
        if (.not. on) cycle
        e(energy_kinetic) = e(energy_kinetic) + 0.5_dp*ld%mass*dot_product(v, v)
        e(energy_gravity) = e(energy_gravity) - ld%mass*dot_product(self%g, r)
      end associate
    end do
  end subroutine moving_energy

  !> Powers at the accelerations qdd (after an evaluation at (t, q, qd)): the force's,
  !> F . v (loads), and the travel law's, (m a - F - m g) . (R tg) sd (prescribed motion):
  !> the force along the path that keeps the mass on its travel, times the travel's velocity.
  subroutine moving_power(self, d, wk, t, q, qd, qdd, p)
    class(moving_load_effect), intent(in) :: self
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:), qdd(:)
    real(dp), intent(inout) :: p(:)
    integer :: i, b, m
    logical :: on
    real(dp) :: r(3), v(3), tg(3), sd, cb(3), psi(3, d%mmax), lin(6, d%nb), ab(6), a(3), fi(3), vrel(3)
    call body_accelerations(d, wk, qdd, lin)
    do i = 1, size(self%loads)
      associate(ld => self%loads(i))
        b = ld%body; m = d%nm(b)
        call point_motion(ld, self%exits(i)%exited, d, wk, t, q, qd, r, v, tg, sd, on, cb, psi(:, 1:m))
        if (.not. on) cycle
        associate(rot => wk%rot(:, :, b), w => wk%vel(4:6, b))
          ab = wk%acc(:, b) + lin(:, b)
          ! v - (v_O + w x r) = R c', the velocity relative to the body frame
          vrel = v - wk%vel(1:3, b) - cross(w, r)
          a = ab(1:3) + cross(ab(4:6), r) + cross(w, wk%vel(1:3, b) + cross(w, r)) + 2.0_dp*cross(w, vrel) + &
            & matmul(rot, cb + matmul(psi(:, 1:m), qdd(d%a0(b):d%a0(b) + m - 1)))
          fi = matmul(rot, ld%force)
          p(power_loads) = p(power_loads) + dot_product(fi, v)
          p(power_motion) = p(power_motion) + dot_product(ld%mass*(a - self%g) - fi, matmul(rot, tg))*sd
        end associate
      end associate
    end do
  end subroutine moving_power

  !> Note load i's exit at time t with the state (q, qd): the states of its body's markers
  !> (runs the kinematics).
  subroutine record_exit(self, i, d, wk, t, q, qd)
    class(moving_load_effect), intent(inout) :: self
    integer, intent(in) :: i
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    integer :: k, mk, b, nm
    real(dp) :: rm(3, 3), th(3), rr(3, 3), jl(3, 3), jd(3)
    call forward_kinematics(d, wk, q, qd)
    associate(x => self%exits(i))
      x%exited = .true.; x%t = t
      do k = 1, size(x%markers)
        mk = x%markers(k); b = d%markers%body(mk); nm = d%nm(b)
        call marker_motion(d, wk, mk, q, qd, x%r(:, k), x%v(:, k))
        call marker_rotation(d, wk, mk, q, rm)
        x%angle(:, k) = rotation_vector(rm)
        th = matmul(d%markers%phi(:, 1:nm, mk), q(d%a0(b):d%a0(b) + nm - 1))
        call small_rotation(th, [0.0_dp, 0.0_dp, 0.0_dp], rr, jl, jd)
        x%rate(:, k) = wk%vel(4:6, b) + matmul(wk%rot(:, :, b), &
          & matmul(jl, matmul(d%markers%phi(:, 1:nm, mk), qd(d%a0(b):d%a0(b) + nm - 1))))
      end do
    end associate
  end subroutine record_exit

  !> The exits so far, for a checkpoint.
  subroutine save_exits(self, unit, ios)
    class(moving_load_effect), intent(in) :: self
    integer, intent(in) :: unit
    integer, intent(out) :: ios
    integer :: i
    ios = 0
    do i = 1, size(self%exits)
      associate(x => self%exits(i))
        if (ios == 0) write(unit, iostat=ios) x%exited, x%t, x%r, x%v, x%angle, x%rate
      end associate
    end do
  end subroutine save_exits

  subroutine load_exits(self, unit, ios)
    class(moving_load_effect), intent(inout) :: self
    integer, intent(in) :: unit
    integer, intent(out) :: ios
    integer :: i
    ios = 0
    do i = 1, size(self%exits)
      associate(x => self%exits(i))
        if (ios == 0) read(unit, iostat=ios) x%exited, x%t, x%r, x%v, x%angle, x%rate
      end associate
    end do
  end subroutine load_exits
end module pymr_model_effect_moving_load
