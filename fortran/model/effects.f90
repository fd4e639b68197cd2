!> Optional physics. Each effect has its own routine; the model calls only those the
!> scene turned on (the plan in model_data%effect_on is fixed at build time).
module pymr_model_effects
  use pymr_env_kinds, only : dp, pi
  use pymr_model_types, only : model_data, model_work, effect_gravity, effect_joint_drives, effect_modal_damping, &
    & effect_joint_springs, effect_geometric_stiffening, effect_base_motion, effect_firing_load, motion_spinup, &
    & motion_table
  use pymr_model_time_table, only : table_linear, table_spline
  use pymr_model_kinematics, only : marker_motion
  implicit none
  private
  public :: add_gravity, add_joint_drives, add_modal_damping, gravity_potential, elastic_potential
  public :: add_joint_springs, spring_potential, add_geometric_stiffening, add_firing_load, load_force, drive_force
  public :: add_carried_load_stiffening
  public :: prescribed_motion, impose_prescribed_state, prescribe_rows

contains

  include 'vector_products.inc'

  !> Centre of mass of body b (inertial; deformed for flexible bodies, after body_terms).
  pure function body_com(d, wk, b) result(c)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    integer, intent(in) :: b
    real(dp) :: c(3)
    if (d%flexible(b)) then
      c = wk%pos(:, b) + matmul(wk%rot(:, :, b), wk%fwork(b)%s)/d%flex(b)%mass
    else
      c = wk%pos(:, b) + matmul(wk%rot(:, :, b), d%com(:, b))
    end if
  end function body_com

  !> Subtract the gravity wrench [m g; c x m g] of every body from its bias wrench, and
  !> the modal gravity loads S1^T R^T g from the modal bias of flexible bodies.
  pure subroutine add_gravity(d, wk, only)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    !> The bodies to load (all, or those of the fast rows).
    logical, intent(in) :: only(:)
    integer :: b, k
    real(dp) :: c(3), f(3), gb(3)
    do b = 2, d%nb
      if (.not. only(b)) cycle
      c = body_com(d, wk, b)
      f = d%mass(b)*d%gravity
      wk%w(1:3, b) = wk%w(1:3, b) - f
      wk%w(4:6, b) = wk%w(4:6, b) - cross(c, f)
      if (d%nm(b) == 0) cycle
      gb = matmul(transpose(wk%rot(:, :, b)), d%gravity)
      do k = 1, d%nm(b)
        wk%wam(k, b) = wk%wam(k, b) - dot_product(d%flex(b)%first(:, k), gb)
      end do
    end do
    wk%count%effect_evals(effect_gravity) = wk%count%effect_evals(effect_gravity) + 1
  end subroutine add_gravity

  !> Add the drive loads to the generalised forces.
  pure subroutine add_joint_drives(d, wk, t)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t
    integer :: i
    do i = 1, d%n_drives
      wk%tau(d%drive_coord(i)) = wk%tau(d%drive_coord(i)) + drive_force(d, i, t)
    end do
    wk%count%effect_evals(effect_joint_drives) = wk%count%effect_evals(effect_joint_drives) + 1
  end subroutine add_joint_drives

  !> Generalised force of drive i at time t: offset + amplitude sin(2 pi f t + phase), or
  !> offset + the drive's table interpolated linearly at t.
  pure real(dp) function drive_force(d, i, t) result(f)
    type(model_data), intent(in) :: d
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    associate(p => d%drive_par(:, i))
      if (d%drive_table(i) > 0) then
        f = p(1) + table_linear(d%tables(d%drive_table(i)), t)
      else
        f = p(1) + p(2)*sin(2.0_dp*pi*p(3)*t + p(4))
      end if
    end associate
  end function drive_force

  !> Modal damping forces (2 zeta omega + alpha + beta omega^2) ad added to the modal bias
  !> of flexible bodies.
  pure subroutine add_modal_damping(d, wk, qd, only)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: qd(:)
    logical, intent(in) :: only(:)
    integer :: b, m
    do b = 2, d%nb
      m = d%nm(b)
      if (m == 0 .or. .not. only(b)) cycle
      wk%wam(1:m, b) = wk%wam(1:m, b) + d%flex(b)%damp*qd(d%a0(b):d%a0(b) + m - 1)
    end do
    wk%count%effect_evals(effect_modal_damping) = wk%count%effect_evals(effect_modal_damping) + 1
  end subroutine add_modal_damping

  !> Gravitational potential energy -sum m g.c (J), after body_terms.
  pure function gravity_potential(d, wk) result(v)
    type(model_data), intent(in) :: d
    type(model_work), intent(in) :: wk
    real(dp) :: v
    integer :: b
    v = 0.0_dp
    do b = 2, d%nb
      v = v - d%mass(b)*dot_product(d%gravity, body_com(d, wk, b))
    end do
  end function gravity_potential

  !> Elastic energy 1/2 sum omega^2 a^2 of the flexible bodies (J).
  pure function elastic_potential(d, q) result(v)
    type(model_data), intent(in) :: d
    real(dp), intent(in) :: q(:)
    real(dp) :: v
    integer :: b, m
    v = 0.0_dp
    do b = 2, d%nb
      m = d%nm(b)
      if (m == 0) cycle
      v = v + 0.5_dp*sum(d%flex(b)%omega2*q(d%a0(b):d%a0(b) + m - 1)**2)
    end do
  end function elastic_potential

  !> Joint spring-dampers: tau_k += -stiffness (q_k - free_position) - damping qd_k.
  pure subroutine add_joint_springs(d, wk, q, qd)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: q(:), qd(:)
    integer :: i, k
    do i = 1, d%n_springs
      k = d%spring_coord(i)
      associate(p => d%spring_par(:, i))
        wk%tau(k) = wk%tau(k) - p(1)*(q(k) - p(3)) - p(2)*qd(k)
      end associate
    end do
    wk%count%effect_evals(effect_joint_springs) = wk%count%effect_evals(effect_joint_springs) + 1
  end subroutine add_joint_springs

  !> Potential energy of the joint springs, 1/2 sum stiffness (q - free_position)^2 (J).
  pure function spring_potential(d, q) result(v)
    type(model_data), intent(in) :: d
    real(dp), intent(in) :: q(:)
    real(dp) :: v
    integer :: i
    v = 0.0_dp
    do i = 1, d%n_springs
      v = v + 0.5_dp*d%spring_par(1, i)*(q(d%spring_coord(i)) - d%spring_par(3, i))**2
    end do
  end function spring_potential

  !> Geometric stiffening of beams by their axial load (after body_terms). A beam along its
  !> x axis carries the tension N(x) = rho A [(g_x - a0_x)(L - x) + (w_y^2 + w_z^2)(L^2 - x^2)/2]
  !> from gravity, the axial acceleration a0_x of its frame origin (velocity terms only: the
  !> part proportional to the accelerations is not known before the solve) and the
  !> centrifugal load of its rotation (body-frame components). Its modal stiffness
  !> K_G = (g_x - a0_x) kg1 + (w_y^2 + w_z^2) kg2 adds K_G a to the modal bias.
  pure subroutine add_geometric_stiffening(d, wk, q, only)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: q(:)
    logical, intent(in) :: only(:)
    integer :: b, m, k
    real(dp) :: wb(3), pd(3), alv(3), gb(3), g(3), c1, c2
    g = 0.0_dp
    if (d%effect_on(effect_gravity)) g = d%gravity
    do b = 2, d%nb
      if (.not. allocated(d%flex(b)%kg1) .or. .not. only(b)) cycle
      m = d%nm(b)
      associate(rot => wk%rot(:, :, b), pos => wk%pos(:, b), vel => wk%vel(:, b), acc => wk%acc(:, b))
        wb = matmul(transpose(rot), vel(4:6))
        pd = vel(1:3) + cross(vel(4:6), pos)
        alv = matmul(transpose(rot), acc(1:3) + cross(acc(4:6), pos) + cross(vel(4:6), pd))
        gb = matmul(transpose(rot), g)
      end associate
      c1 = gb(1) - alv(1)
      c2 = wb(2)**2 + wb(3)**2
      associate(a => q(d%a0(b):d%a0(b) + m - 1))
        do k = 1, m
          wk%wam(k, b) = wk%wam(k, b) + c1*dot_product(d%flex(b)%kg1(:, k), a) + c2*dot_product(d%flex(b)%kg2(:, k), a)
        end do
      end associate
    end do
    wk%count%effect_evals(effect_geometric_stiffening) = wk%count%effect_evals(effect_geometric_stiffening) + 1
  end subroutine add_geometric_stiffening

  !> Geometric stiffening of beams by the bodies they carry (after composite_terms): a body
  !> c jointed to beam b at x_c pulls on it with the force -f_c, f_c the composite bias
  !> wrench's force of c's subtree (its weight, applied loads and velocity-term inertia;
  !> the part proportional to the accelerations is not known before the solve). Its
  !> component along the beam axis is a tension N_c = -x_b . f_c on [0, x_c], adding
  !> N_c kgc_c a to the beam's modal bias.
  pure subroutine add_carried_load_stiffening(d, wk, q, only)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: q(:)
    logical, intent(in) :: only(:)
    integer :: c, b, m, k
    real(dp) :: tension
    do c = 2, d%nb
      if (.not. d%child_kg(c) .or. .not. only(c)) cycle
      b = d%parent(c)
      m = d%nm(b)
      tension = -dot_product(wk%rot(:, 1, b), wk%wc(1:3, c))
      associate(a => q(d%a0(b):d%a0(b) + m - 1))
        do k = 1, m
          wk%wam(k, b) = wk%wam(k, b) + tension*dot_product(d%kgc(k, 1:m, c), a)
        end do
      end associate
    end do
  end subroutine add_carried_load_stiffening

  !> Magnitude (N) of load i at time t: a half-sine pulse.
  pure real(dp) function load_force(d, i, t)
    type(model_data), intent(in) :: d
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    associate(p => d%load_par(:, i))
      load_force = 0.0_dp
      if (t >= p(2) .and. t <= p(2) + p(3)) load_force = p(1)*sin(pi*(t - p(2))/p(3))
    end associate
  end function load_force

  !> Point loads at markers (after kinematics): the force f = R (direction F(t)) at the
  !> marker's point r enters the body's wrench as [f; r x f] and, on a flexible body, the
  !> modal forces Psi(marker)^T (direction F(t)).
  pure subroutine add_firing_load(d, wk, t, q, qd, only)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    logical, intent(in) :: only(:)
    integer :: i, b, k, mk
    real(dp) :: fmag, fb(3), f(3), r(3), v(3)
    do i = 1, d%n_loads
      mk = d%load_marker(i)
      b = d%markers%body(mk)
      if (.not. only(b)) cycle
      fmag = load_force(d, i, t)
      if (fmag == 0.0_dp) cycle
      fb = d%load_dir(:, i)*fmag
      f = matmul(wk%rot(:, :, b), fb)
      call marker_motion(d, wk, mk, q, qd, r, v)
      wk%w(1:3, b) = wk%w(1:3, b) - f
      wk%w(4:6, b) = wk%w(4:6, b) - cross(r, f)
      do k = 1, d%nm(b)
        wk%wam(k, b) = wk%wam(k, b) - dot_product(d%markers%psi(:, k, mk), fb)
      end do
    end do
    wk%count%effect_evals(effect_firing_load) = wk%count%effect_evals(effect_firing_load) + 1
  end subroutine add_firing_load

  !> Value, rate and acceleration at time t of prescribed coordinate i.
  pure subroutine prescribed_motion(d, i, t, f, fd, fdd)
    type(model_data), intent(in) :: d
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    real(dp), intent(out) :: f, fd, fdd
    real(dp) :: w, rate, tr, c
    associate(p => d%pres_par(:, i))
      if (d%pres_form(i) == motion_table) then
        call table_spline(d%tables(d%pres_table(i)), t, f, fd, fdd)
        f = f + p(1)
      else if (d%pres_form(i) == motion_spinup) then
        ! theta = (rate/T)[t^2/2 + (T/2 pi)^2 (cos(2 pi t/T) - 1)] up to T, then constant rate
        rate = p(5); tr = p(6)
        if (t <= tr) then
          w = 2.0_dp*pi/tr
          c = rate/tr
          f = p(1) + c*(0.5_dp*t**2 + (cos(w*t) - 1.0_dp)/w**2)
          fd = c*(t - sin(w*t)/w)
          fdd = c*(1.0_dp - cos(w*t))
        else
          f = p(1) + rate*(t - 0.5_dp*tr)
          fd = rate
          fdd = 0.0_dp
        end if
      else
        w = 2.0_dp*pi*p(3)
        f = p(1) + p(2)*sin(w*t + p(4))
        fd = p(2)*w*cos(w*t + p(4))
        fdd = -p(2)*w**2*sin(w*t + p(4))
      end if
    end associate
  end subroutine prescribed_motion

  !> Copies of (q, qd) in wk%qx, wk%qdx with the prescribed coordinates set to their functions.
  pure subroutine impose_prescribed_state(d, wk, t, q, qd)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t, q(:), qd(:)
    integer :: i
    real(dp) :: fdd
    wk%qx = q; wk%qdx = qd
    do i = 1, d%n_prescribed
      call prescribed_motion(d, i, t, wk%qx(d%pres_coord(i)), wk%qdx(d%pres_coord(i)), fdd)
    end do
  end subroutine impose_prescribed_state

  !> After assembly: each prescribed coordinate j gets the equation qdd_j = f''(t). Its known
  !> acceleration moves to the right-hand side of the other rows and its row and column
  !> are cleared (M stays symmetric positive definite).
  pure subroutine prescribe_rows(d, wk, t)
    type(model_data), intent(in) :: d
    type(model_work), intent(inout) :: wk
    real(dp), intent(in) :: t
    integer :: i, j
    real(dp) :: f, fd, fdd
    do i = 1, d%n_prescribed
      j = d%pres_coord(i)
      call prescribed_motion(d, i, t, f, fd, fdd)
      wk%p = wk%p - wk%mm(:, j)*fdd
      wk%mm(:, j) = 0.0_dp
      wk%mm(j, :) = 0.0_dp
      wk%mm(j, j) = 1.0_dp
      wk%p(j) = fdd
    end do
    wk%count%effect_evals(effect_base_motion) = wk%count%effect_evals(effect_base_motion) + 1
  end subroutine prescribe_rows
end module pymr_model_effects
