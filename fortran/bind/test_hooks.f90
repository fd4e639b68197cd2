!> Test hooks: entry points that expose kernel internals to the test suite only (the
!> Nordsieck operators, the step ratio, the error weights, the PECE stability limit, the
!> ODE test problems, the number formatter, the LAPACK error handler, the Adams kernel).
!> They are built into pymr._testhooks, an extension apart from the shipped pymr._core
!> (scipy's pattern for test-only extensions), so the package's binding exports none of
!> them.

!> The CSV writer's text of m reals in `digits` significant digits, as character codes
!> (text(:, i) is value i, blank padded): for round-trip tests of the formatter.
subroutine pymr_format_reals(m, x, digits, text)
  use pymr_env_real_text, only : put_real
  implicit none
  integer, intent(in) :: m, digits
  double precision, intent(in) :: x(m)
  integer(kind=1), intent(out) :: text(32, m)
  !f2py integer intent(hide), depend(x) :: m = len(x)
  character(len=32) :: buf
  integer :: i, j, pos
  do i = 1, m
    buf = ''; pos = 1
    call put_real(x(i), buf, pos, digits)
    do j = 1, 32
      text(j, i) = int(iachar(buf(j:j)), 1)
    end do
  end do
end subroutine pymr_format_reals

!> Integrate a built-in test ODE with known solution (for the integrator's tests).
!> problem 1: harmonic oscillator x'' = -x, x(0) = 1, x'(0) = 0 (state [x, x']).
!> problem 2: y' = -2 t y^2, y(0) = 1 (solution 1/(1+t^2)).
!> problem 3: Kepler orbit, eccentricity 0.5 (state [x, y, vx, vy]).
!> problem 4: x'' + 2 zeta w x' + w^2 x = w^2 [t >= 1], w = 2 pi, zeta = 0.05, at rest at 0.
!> problem 5: y' = -y, y(0) = 1.
!> order < 0: the paper's ABM4 (n_corr evaluations per step); 0-12: formula 'adams'.
!> th, hh, qh: time, step and order of the first nmax accepted steps.
subroutine pymr_ode_test(problem, t_end, h, adaptive, rtol, atol, n_corr, order, nx, nmax, x, steps, evals, &
    & rejected, th, hh, qh, stat, message)
  use pymr_env_error, only : error_type
  use pymr_bind_support, only : report
  use pymr_integrator_test_odes, only : integrate_test_ode
  implicit none
  integer, intent(in) :: problem, adaptive, n_corr, order, nx, nmax
  double precision, intent(in) :: t_end, h, rtol, atol
  double precision, intent(out) :: x(nx), th(nmax), hh(nmax)
  integer, intent(out) :: steps, evals, rejected, qh(nmax), stat
  character(len=8192), intent(out) :: message
  type(error_type), allocatable :: error
  call integrate_test_ode(problem, t_end, h, adaptive /= 0, rtol, atol, n_corr, order, x, steps, evals, rejected, &
    & th, hh, qh, error)
  call report(error, stat, message)
end subroutine pymr_ode_test

!> Nordsieck kernels for tests: predict (op 1), rescale by alpha (op 2), value at s (op 3).
subroutine pymr_nordsieck_op(op, n, z, alpha, out)
  use pymr_integrator_nordsieck, only : nordsieck_predict, nordsieck_rescale, nordsieck_value
  implicit none
  integer, intent(in) :: op, n
  double precision, intent(in) :: z(n, 4), alpha
  double precision, intent(out) :: out(n, 4)
  !f2py integer intent(hide), depend(z) :: n = shape(z, 0)
  out = 0.0d0
  select case (op)
  case (1)
    call nordsieck_predict(z, out)
  case (2)
    out = z
    call nordsieck_rescale(out, alpha)
  case (3)
    call nordsieck_value(z, alpha, out(:, 1))
  end select
end subroutine pymr_nordsieck_op

!> Nordsieck corrector for tests: z = zp + l (hf - zp(:,1)), and g = hf - zp(:,1).
subroutine pymr_nordsieck_correct(n, zp, hf, z, g)
  use pymr_integrator_nordsieck, only : nordsieck_correct
  implicit none
  integer, intent(in) :: n
  double precision, intent(in) :: zp(n, 4), hf(n)
  double precision, intent(out) :: z(n, 4), g(n)
  !f2py integer intent(hide), depend(zp) :: n = shape(zp, 0)
  call nordsieck_correct(zp, 1.0d0, hf, z, g)
end subroutine pymr_nordsieck_correct

!> Step ratio of the default adaptive controller for a normalised error estimate `err`
!> after an accepted (accepted /= 0) or a rejected step.
subroutine pymr_step_ratio(err, accepted, eta)
  use pymr_integrator_control, only : step_control
  implicit none
  double precision, intent(in) :: err
  integer, intent(in) :: accepted
  double precision, intent(out) :: eta
  type(step_control) :: ctl
  eta = ctl%ratio(err, accepted /= 0)
end subroutine pymr_step_ratio

!> Error weights of the state x = [q; qd] (m coordinates) at rtol and atol, with the
!> angular frequencies omega of its coordinates (error_norm 'amplitude') when amplitude /= 0.
subroutine pymr_error_weights(m, x, omega, rtol, atol, amplitude, w)
  use pymr_integrator_control, only : step_control, error_weights
  implicit none
  integer, intent(in) :: m, amplitude
  double precision, intent(in) :: x(2*m), omega(m), rtol, atol
  double precision, intent(out) :: w(2*m)
  !f2py integer intent(hide), depend(omega) :: m = len(omega)
  type(step_control) :: ctl
  ctl%rtol = rtol; ctl%atol = atol
  if (amplitude /= 0) ctl%omega = omega
  call error_weights(ctl, x, w)
end subroutine pymr_error_weights

!> Method 'auto''s review rules: the running method's lead over the n candidates' CPU rates
!> (rates, huge for a failed probe; stopped(i) /= 0 for a stopped one; run the running
!> method, 1-based), and the baseline after a review that kept it (base_rate, the
!> window's rate).
subroutine pymr_review_rule(n, rates, run, stopped, base_rate, rate, lead, baseline)
  use pymr_driver_method_choice, only : lead_of, baseline_after_review
  implicit none
  integer, intent(in) :: n, run
  double precision, intent(in) :: rates(n), base_rate, rate
  integer, intent(in) :: stopped(n)
  double precision, intent(out) :: lead, baseline
  !f2py integer intent(hide), depend(rates) :: n = len(rates)
  lead = lead_of(rates, run, stopped /= 0)
  baseline = baseline_after_review(base_rate, rate, lead)
end subroutine pymr_review_rule

!> LAPACK called with an illegal argument: info and the routine pymr's XERBLA recorded
!> (the process goes on; the reference XERBLA would have stopped it).
subroutine pymr_xerbla_probe(info, routine, argument)
  use pymr_env_lapack, only : illegal_argument_probe, xerbla_routine, xerbla_argument
  implicit none
  integer, intent(out) :: info, argument
  character(len=32), intent(out) :: routine
  xerbla_routine = ''; xerbla_argument = 0
  call illegal_argument_probe(info)
  routine = xerbla_routine
  argument = xerbla_argument
end subroutine pymr_xerbla_probe

!> Formula 'adams' for tests: the corrector vector l(0:q) and error constants tq(1:5) of
!> order q for the step s(1) after the steps s(2:) (op 1); or z(n, 0:q) lowered to order
!> q-1 with the past steps s(1:) and the step h = s(1) it is scaled with (op 2, into zout);
!> or order q's stability bound omega*h on undamped vibrations (op 3, into tq(1)).
subroutine pymr_adams_kernel(op, q, m, s, n, z, l, tq, zout)
  use pymr_integrator_adams, only : adams_coefficients, adams_lower_order, stable_omega_h
  implicit none
  integer, intent(in) :: op, q, m, n
  double precision, intent(in) :: s(m), z(n, 0:q)
  double precision, intent(out) :: l(0:12), tq(5), zout(n, 0:q)
  l = 0.0d0; tq = 0.0d0; zout = z
  if (op == 1) call adams_coefficients(q, s, l, tq)
  if (op == 2) call adams_lower_order(zout, q, s, s(1))
  if (op == 3) tq(1) = stable_omega_h(q)
end subroutine pymr_adams_kernel

!> The PECE step's stability limit along the ray of lambda = (re, im) (the search
!> pece_limit), and the imaginary-axis limit the steppers take as a constant.
subroutine pymr_pece_limit(re, im, h, axis_limit)
  use pymr_integrator_stability, only : pece_limit, imaginary_axis_limit
  implicit none
  double precision, intent(in) :: re, im
  double precision, intent(out) :: h, axis_limit
  h = pece_limit(cmplx(re, im, kind(1.0d0)))
  axis_limit = imaginary_axis_limit
end subroutine pymr_pece_limit
