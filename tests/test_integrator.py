"""Nordsieck Adams-Bashforth-Moulton integrator (METHOD.md section 3).

Every test compares the kernel against an independent expectation: analytic ODE solutions
(measured convergence order, tolerance proportionality) and exact polynomial identities of the
Nordsieck representation (Pascal predictor, step rescaling C(alpha)).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr import _testhooks

# ---------------------------------------------------------------------------------------------
# Built-in test problems of pymr_ode_test and their exact solutions at t_end
# ---------------------------------------------------------------------------------------------
KEPLER_X0 = np.array([0.5, 0.0, 0.0, math.sqrt(3.0)])


def exact(problem: int, t: float) -> np.ndarray:
    if problem == 1:  # x'' = -x, x(0) = 1, x'(0) = 0
        return np.array([math.cos(t), -math.sin(t)])
    if problem == 2:  # y' = -2 t y^2, y(0) = 1
        return np.array([1.0 / (1.0 + t * t)])
    if problem == 3:  # Kepler, e = 0.5, a = 1, GM = 1: period 2 pi, only t = k 2 pi is used
        k = t / (2.0 * math.pi)
        assert abs(k - round(k)) < 1e-12
        return KEPLER_X0.copy()
    if problem == 5:  # y' = -y, y(0) = 1
        return np.array([math.exp(-t)])
    raise ValueError(problem)


NX = {1: 2, 2: 1, 3: 4, 4: 2, 5: 1}


def run_ode(problem, t_end, h, adaptive=False, rtol=1e-6, atol=1e-8, n_corr=1, order=-1, nmax=1):
    """pymr_ode_test: order -1 is the paper's ABM4, 0-12 formula 'adams' (adaptive). Returns
    the final state, counts and the (time, step, order) of the first nmax accepted steps."""
    x, steps, evals, rejected, th, hh, qh, stat, message = _testhooks.pymr_ode_test(
        problem, t_end, h, 1 if adaptive else 0, rtol, atol, n_corr, order, NX[problem], nmax)
    assert stat == 0, message.decode(errors="replace").strip() if isinstance(message, bytes) else message
    k = min(int(steps), nmax)
    return (np.array(x, dtype=float), int(steps), int(evals), int(rejected),
            (th[:k].copy(), hh[:k].copy(), qh[:k].copy()))


def integrate(problem, t_end, h, adaptive=False, rtol=1e-6, atol=1e-8, n_corr=1, order=-1):
    return run_ode(problem, t_end, h, adaptive, rtol, atol, n_corr, order)[:4]


def global_error(problem, t_end, **kw):
    x, steps, evals, rejected = integrate(problem, t_end, **kw)
    return float(np.max(np.abs(x - exact(problem, t_end)))), steps, evals, rejected


# ---------------------------------------------------------------------------------------------
# 1. Measured global order of the fixed-step PECE and PE(CE)^2 schemes
# ---------------------------------------------------------------------------------------------
# (problem, t_end, coarsest h, n_corr). The coarsest h is chosen in the asymptotic range
# (above it the order is still pre-asymptotic, e.g. problem 2 with n_corr=2 shows an error
# cancellation near h=0.05); the finest error stays >= ~1e-12, well above roundoff.
ORDER_CASES = [
    (1, 10.0, 0.1, 1),
    (1, 10.0, 0.1, 2),
    (2, 1.0, 0.05, 1),
    (2, 1.0, 0.0125, 2),
    (3, 2.0 * math.pi, 2.0 * math.pi / 400, 1),
    (3, 2.0 * math.pi, 2.0 * math.pi / 400, 2),
]


@pytest.mark.parametrize("problem,t_end,h0,n_corr", ORDER_CASES,
                         ids=[f"p{c[0]}-ncorr{c[3]}" for c in ORDER_CASES])
def test_fixed_step_global_order_is_four(problem, t_end, h0, n_corr):
    hs = [h0 / 2**k for k in range(4)]
    errs = []
    for h in hs:
        err, steps, evals, rejected = global_error(problem, t_end, h=h, n_corr=n_corr)
        # fixed step: exactly t_end/h steps, no rejections, n_corr evaluations per step
        # plus a bounded start-up
        assert steps == round(t_end / h)
        assert rejected == 0
        assert n_corr * steps <= evals <= n_corr * steps + 20
        errs.append(err)
    errs = np.array(errs)
    orders = np.log2(errs[:-1] / errs[1:])
    assert np.all(np.abs(orders - 4.0) < 0.3), f"errors {errs}, orders {orders}"


def test_second_corrector_iteration_reduces_the_error():
    # PE(CE)^2 has the same order but a smaller error constant than PECE on the oscillator
    # (the corrector is iterated towards the implicit Adams-Moulton solution).
    e1, *_ = global_error(1, 10.0, h=0.05, n_corr=1)
    e2, *_ = global_error(1, 10.0, h=0.05, n_corr=2)
    assert e2 < 0.5 * e1


# ---------------------------------------------------------------------------------------------
# 2. Adaptive step: error proportional to the tolerance
# ---------------------------------------------------------------------------------------------
RTOLS = 10.0 ** -np.arange(5, 11)  # 1e-5 ... 1e-10
ADAPTIVE_CASES = [(p, nc) for p in (1, 2, 3) for nc in (1, 2)]
ADAPTIVE_T_END = {1: 10.0, 2: 3.0, 3: 2.0 * math.pi}


@pytest.mark.parametrize("problem,n_corr", ADAPTIVE_CASES,
                         ids=[f"p{p}-ncorr{nc}" for p, nc in ADAPTIVE_CASES])
def test_adaptive_error_is_proportional_to_tolerance(problem, n_corr):
    t_end = ADAPTIVE_T_END[problem]
    scale = max(1.0, float(np.max(np.abs(exact(problem, t_end)))))
    errs, steps = [], []
    for rtol in RTOLS:
        err, n, _, _ = global_error(problem, t_end, h=0.1, adaptive=True, rtol=rtol,
                                    atol=rtol * 1e-2, n_corr=n_corr)
        errs.append(err)
        steps.append(n)
    errs = np.array(errs)
    # over 5 decades of rtol the error falls by well over 1e3, every decade by at least 3x
    assert errs[0] / errs[-1] > 1e3, errs
    assert np.all(errs[:-1] / errs[1:] > 3.0), errs
    # tolerance proportionality: slope of log(err) against log(rtol)
    slope = np.polyfit(np.log10(RTOLS), np.log10(errs), 1)[0]
    assert 0.7 < slope < 1.3, (slope, errs)
    # and the global error stays within a modest factor of the requested tolerance
    assert np.all(errs < 100.0 * RTOLS * scale), errs / RTOLS
    # a 4th-order method needs ~10^(1/4) = 1.78x more steps per decade of rtol
    step_ratio = (steps[-1] / steps[0]) ** (1.0 / (len(RTOLS) - 1))
    assert 1.5 < step_ratio < 2.1, steps


# ---------------------------------------------------------------------------------------------
# 3. Nordsieck array operations: Pascal predictor and C(alpha) rescaling
# ---------------------------------------------------------------------------------------------
PASCAL, RESCALE, VALUE = 1, 2, 3


def nordsieck_op(op, z, alpha=1.0):
    z = np.asfortranarray(z, dtype=float)
    return np.array(_testhooks.pymr_nordsieck_op(op, z, float(alpha)))


def poly(z, s):
    """Nordsieck polynomial p(s) = sum_j z_j s^j, s = (t - t_n) / h, per row of z."""
    return z @ (s ** np.arange(4))


def dpoly(z, s):
    """h dp/dt = dp/ds."""
    return z[:, 1:] @ (np.arange(1, 4) * s ** np.arange(3))


@pytest.fixture
def zrand():
    return np.random.default_rng(12345).standard_normal((7, 4))


def test_rescale_is_column_power_and_round_trips(zrand):
    for alpha in (0.5, 2.0, 0.3, 1.7, 1e-2):
        zs = nordsieck_op(RESCALE, zrand, alpha)
        np.testing.assert_allclose(zs, zrand * alpha ** np.arange(4), rtol=1e-15, atol=0)
        back = nordsieck_op(RESCALE, zs, 1.0 / alpha)
        assert np.max(np.abs(back - zrand) / np.abs(zrand)) < 1e-15


def test_value_is_the_nordsieck_polynomial(zrand):
    for s in (0.0, 1.0, -1.0, 0.37, 2.5):
        out = nordsieck_op(VALUE, zrand, s)
        np.testing.assert_allclose(out[:, 0], poly(zrand, s), rtol=1e-14, atol=1e-14)


def test_rescaled_polynomial_describes_the_same_physical_time(zrand):
    # The array for step h evaluated at s equals the array rescaled to alpha*h at s/alpha.
    for alpha in (0.5, 2.0, 0.3):
        zs = nordsieck_op(RESCALE, zrand, alpha)
        for s in (-1.0, 0.4, 1.0, 1.6):
            a = nordsieck_op(VALUE, zrand, s)[:, 0]
            b = nordsieck_op(VALUE, zs, s / alpha)[:, 0]
            np.testing.assert_allclose(b, a, rtol=1e-13, atol=1e-13)


def test_pascal_predictor_shifts_the_polynomial_by_one_step(zrand):
    zp = nordsieck_op(PASCAL, zrand)
    pascal = np.array([[1, 1, 1, 1], [0, 1, 2, 3], [0, 0, 1, 3], [0, 0, 0, 1]], float)
    np.testing.assert_allclose(zp, zrand @ pascal.T, rtol=1e-14, atol=1e-14)
    # column 0: value at s = 1; column 1: h x' at s = 1; column 2: h^2 x''/2; column 3: h^3 x'''/6
    np.testing.assert_allclose(zp[:, 0], poly(zrand, 1.0), rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(zp[:, 1], dpoly(zrand, 1.0), rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(zp[:, 2], zrand[:, 2] + 3 * zrand[:, 3], rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(zp[:, 3], zrand[:, 3], rtol=1e-14, atol=1e-14)
    # the shifted polynomial at s equals the old one at s + 1
    for s in (-2.0, -0.5, 0.0, 0.8):
        np.testing.assert_allclose(poly(zp, s), poly(zrand, s + 1.0), rtol=1e-13, atol=1e-13)


# ---------------------------------------------------------------------------------------------
# 4. Cubic solutions are reproduced exactly; the predictor error for a quartic is h^4 c4
# ---------------------------------------------------------------------------------------------
def nordsieck_of(coeffs, t, h):
    """Exact Nordsieck array [x, h x', h^2 x''/2, h^3 x'''/6] of x(t) = sum_k c_k t^k."""
    p = np.polynomial.Polynomial(coeffs)
    return np.array([p(t), h * p.deriv(1)(t), h**2 * p.deriv(2)(t) / 2, h**3 * p.deriv(3)(t) / 6])


def test_cubic_is_propagated_exactly_with_step_changes():
    c = np.array([[0.7, -1.3, 0.4, 2.1], [-2.0, 0.5, 3.0, -0.25], [1.0, 0.0, 0.0, 0.0]])
    t, h = 0.3, 0.05
    z = np.stack([nordsieck_of(ci, t, h) for ci in c])
    rng = np.random.default_rng(7)
    for _ in range(200):
        z = nordsieck_op(PASCAL, z)
        t += h
        alpha = rng.uniform(0.5, 2.0)
        z = nordsieck_op(RESCALE, z, alpha)
        h *= alpha
    ref = np.stack([nordsieck_of(ci, t, h) for ci in c])
    np.testing.assert_allclose(z, ref, rtol=1e-11, atol=1e-11 * np.max(np.abs(ref)))


def test_predictor_local_error_for_a_quartic_is_binomial_h4():
    # x = t^4: the cubic Nordsieck predictor misses exactly h^4 * [1, 4, 6, 4] (Pascal row 4)
    h, t = 0.1, 0.6
    z = nordsieck_of([0, 0, 0, 0, 1.0], t, h)[None, :]
    zp = nordsieck_op(PASCAL, z)
    ref = nordsieck_of([0, 0, 0, 0, 1.0], t + h, h)
    np.testing.assert_allclose(ref - zp[0], h**4 * np.array([1.0, 4.0, 6.0, 4.0]), rtol=1e-10)


# ---------------------------------------------------------------------------------------------
# 5. The corrector is the 3-step Adams-Moulton formula; its local error constant is -19/720
# ---------------------------------------------------------------------------------------------
def correct(zp, hf):
    z, g = _testhooks.pymr_nordsieck_correct(np.asfortranarray(zp, dtype=float), np.asarray(hf, dtype=float))
    return np.array(z), np.array(g)


def history(x, f0, f1, f2, h):
    """Nordsieck array of x_n and the derivatives f_n, f_{n-1}, f_{n-2} at t_n, t_n - h, t_n - 2h:
    the derivative is the quadratic p(s) = f0 + b s + c s^2 through them (s = (t - t_n)/h), and
    x(s) = x_n + h (f0 s + b s^2/2 + c s^3/3), so z = [x_n, h f0, h b/2, h c/3]."""
    c = (f2 - 2 * f1 + f0) / 2
    b = f0 - f1 + c
    return np.stack([x, h * f0, h * b / 2, h * c / 3], axis=-1)


PASCAL_T = np.array([[1, 1, 1, 1], [0, 1, 2, 3], [0, 0, 1, 3], [0, 0, 0, 1]], float).T


def test_corrector_is_the_three_step_adams_moulton_formula():
    """Predict, evaluate f_{n+1}, correct: x_{n+1} = x_n + h/24 (9 f_{n+1} + 19 f_n - 5 f_{n-1}
    + f_{n-2}) (Adams-Moulton, order 4), and the corrected array is the Nordsieck array of the
    shifted history (f_{n+1}, f_n, f_{n-1}). The four columns pin the corrector vector l."""
    rng = np.random.default_rng(2026)
    h = 0.1
    x = rng.standard_normal(6)
    f_new, f0, f1, f2 = rng.standard_normal((4, 6))
    zp = history(x, f0, f1, f2, h) @ PASCAL_T
    z, g = correct(zp, h * f_new)
    np.testing.assert_allclose(g, h * f_new - zp[:, 1], rtol=0, atol=1e-15)
    am = x + h / 24 * (9 * f_new + 19 * f0 - 5 * f1 + f2)
    np.testing.assert_allclose(z[:, 0], am, rtol=0, atol=2e-15 * np.abs(am).max())
    np.testing.assert_allclose(z, history(am, f_new, f0, f1, h), rtol=0, atol=2e-15)


def test_corrector_local_error_constant_is_minus_19_over_720():
    """On x' = t^4 from an exact history the corrector misses x(t_n + h) by exactly
    -(-19/720) h^5 x^(5) = 19/30 h^5 (x^(5) = 24; no higher derivative), at any t_n and h."""
    for tn in (0.0, 0.3, -1.1):
        for h in (0.2, 0.1, 0.05):
            x0 = np.array([tn**5 / 5])
            fs = [np.array([(tn - k * h)**4]) for k in (0, 1, 2)]
            zp = history(x0, *fs, h)[None, 0] @ PASCAL_T
            z, _ = correct(zp, h * np.array([(tn + h)**4]))
            miss = z[0, 0] - (tn + h)**5 / 5
            assert miss == pytest.approx(19 / 30 * h**5, rel=1e-9, abs=0)


def test_step_ratio_exponent_matches_the_order_of_the_error_estimate():
    """The estimate l0 (h f - zp') is measured to scale as h^p on x' = t^3 (where it is exact:
    the quadratic extrapolation of f misses 6 h^3); the controller's ratio eta then puts the
    next estimate at safety^p of the tolerance: err eta^p = 0.85^p for every ratio that no bound
    clips (accepted: 0.5 <= eta <= 4 outside the hold band [1, 1.25); rejected: eta >= 0.2)."""
    est = []
    for h in (0.1, 0.05, 0.025):
        fs = [np.array([(0.7 - k * h)**3]) for k in (0, 1, 2)]
        zp = history(np.array([0.7**4 / 4]), *fs, h)[None, 0] @ PASCAL_T
        _, g = correct(zp, h * np.array([(0.7 + h)**3]))
        est.append(abs(g[0]))
        assert g[0] == pytest.approx(6 * h**4, rel=1e-9)
    p = np.log2(est[0] / est[1])
    assert p == pytest.approx(4.0, abs=1e-9) and np.log2(est[1] / est[2]) == pytest.approx(p, abs=1e-9)
    for err, accepted in [(0.01, 1), (0.05, 1), (0.1, 1), (1.01, 0), (2.0, 0), (5.0, 0), (20.0, 0)]:
        eta = _testhooks.pymr_step_ratio(err, accepted)
        assert err * eta**p == pytest.approx(0.85**p, rel=1e-12), (err, accepted, eta)
    # the bounds: growth at most 4x, a rejected step at least 0.2x
    assert _testhooks.pymr_step_ratio(1e-9, 1) == 4.0
    assert _testhooks.pymr_step_ratio(1e9, 0) == pytest.approx(0.2)


@pytest.mark.parametrize("over, steps", [({}, 70000),
                                         ({"integrator.method": "multirate", "integrator.h_slow": 1e-3}, 70000),
                                         ({"integrator.method": "multirate", "integrator.coupling": "full",
                                           "integrator.h_slow": 5e-4}, 70000)])
def test_fixed_steps_reach_t_end_in_the_counted_number_of_steps(tmp_path, over, steps):
    """Fixed steps of 1e-4 s to t_end = 7 s: exactly 70,000 fast steps, every stepper (the time
    is t0 + n h, not a sum of steps: summed, 7 s took 70,001 steps, one past t_end), and the
    last row is at t_end."""
    tank = Path(__file__).resolve().parent.parent / "input" / "tank_gun_turret.nml"
    res = pymr.run(tank, tmp_path / "x.csv", overrides={"scene.t_end": 7.0, "output.dt": 0.5, **over})
    assert res.stats["steps_fast"] == steps
    assert res.t[-1] == 7.0 and len(res.t) == 15


def _pece_growth(q: complex) -> float:
    """Spectral radius of the ABM4 PECE step's amplification matrix G(q) = (I + l (q e_0^T
    - e_1^T)) A on x' = lambda x, q = lambda h, written out here from the method (Nordsieck
    order 3, Pascal predictor A, corrector vector l = [3/8, 1, 3/4, 1/6])."""
    l = np.array([3 / 8, 1, 3 / 4, 1 / 6])
    a = np.array([[math.comb(j, i) for j in range(4)] for i in range(4)], dtype=complex)
    c = np.eye(4, dtype=complex)
    c[:, 0] += l * q
    c[:, 1] -= l
    return float(np.abs(np.linalg.eigvals(c @ a)).max())


def test_undamped_stability_limit_is_the_methods_own():
    """The steppers bound a step on an undamped mode of omega by imaginary_axis_limit/omega,
    a constant: it is the kernel's search along the imaginary axis to 1e-9, and the
    amplification matrix built here from the method grows past 1 just beyond it and not
    below it. The search scales as 1/|lambda| (q = lambda h), which the constant relies on."""
    h, axis = _testhooks.pymr_pece_limit(0.0, 1.0)
    assert h == pytest.approx(axis, rel=1e-9)
    assert _pece_growth(1j * axis * (1 - 1e-6)) <= 1 + 1e-12 < _pece_growth(1j * axis * (1 + 1e-6))
    for omega in (3.7, 6.4e3):
        assert _testhooks.pymr_pece_limit(0.0, omega)[0] * omega == pytest.approx(axis, rel=1e-9)


def test_amplitude_error_norm_weighs_a_mode_by_its_amplitude_at_every_phase():
    """error_norm = 'amplitude': over a period of a free vibration q = A cos(omega t),
    qd = -A omega sin(omega t), the weights stay those of the amplitude A, 1/(rtol A + atol)
    for q and omega times less for qd; a coordinate without frequency (a joint) keeps
    1/(rtol |x| + atol) for each of q and qd, and 'state' keeps it for every coordinate."""
    rtol, atol, amp, omega = 1e-5, 1e-9, 3e-3, 2 * math.pi * 240.0
    freq = np.array([0.0, omega])
    for phase in np.linspace(0.0, 2 * math.pi, 17):
        q = np.array([1.3, amp * math.cos(phase)])
        qd = np.array([-0.4, -amp * omega * math.sin(phase)])
        x = np.concatenate([q, qd])
        w = _testhooks.pymr_error_weights(x, freq, rtol, atol, 1)
        assert w[1] == pytest.approx(1 / (rtol * amp + atol), rel=1e-12)
        assert w[3] == pytest.approx(1 / (omega * (rtol * amp + atol)), rel=1e-12)
        assert w[[0, 2]] == pytest.approx(1 / (rtol * np.abs(x[[0, 2]]) + atol), rel=1e-15)
        assert _testhooks.pymr_error_weights(x, freq, rtol, atol, 0) == pytest.approx(1 / (rtol * np.abs(x) + atol),
                                                                                       rel=1e-15)
