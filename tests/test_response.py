"""The 'response' multirate coupling (the default of method = 'multirate'): its force
response against the mass matrix and a finite-difference Jacobian, its convergence order
at fixed step ratio, the paper's Table 1 case against a converged reference, stability of
the stiff barrel at every ratio, error control, and reduction to single-rate at k = 1."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pymr

ROOT = Path(__file__).resolve().parent.parent
TANK = ROOT / "input" / "tank_gun_turret.nml"
CHAIN = ROOT / "input" / "flexible_chain.nml"
STIFF = ROOT / "input" / "hard" / "stiff_barrel.nml"


def response(k: int, h: float, **extra) -> dict:
    return {"integrator.method": "multirate", "integrator.coupling": "response", "integrator.h_fast": h,
            "integrator.h_slow": k * h, **extra}


def marker_dev(a: pymr.Results, b: pymr.Results, marker: str) -> float:
    idx = np.searchsorted(b.t, a.t - 1e-12)
    assert np.allclose(b.t[idx], a.t, rtol=0, atol=1e-12)
    return float(np.linalg.norm(a.marker(marker)[0] - b.marker(marker)[0][idx], axis=1).max())


@pytest.fixture(scope="module")
def tank_reference(tmp_path_factory) -> pymr.Results:
    """Single-rate h = 2.5e-5 s: within 1e-9 m of the converged muzzle motion."""
    out = tmp_path_factory.mktemp("ref") / "ref.csv"
    return pymr.run(TANK, out, overrides={"integrator.h_slow": 2.5e-5, "integrator.h_fast": 2.5e-5,
                                          "output.dt": 1e-3})


@pytest.mark.parametrize("scene, nj", [(TANK, 2), (CHAIN, 3)])
def test_force_response_is_m_inverse_e_and_the_elastic_jacobian(scene, nj):
    """At a moving, deflected state: g equals the modal columns of M^-1 from the mass matrix
    (numpy's solve; the kernel goes through the Schur complement) to 1e-12, and kf, df are
    the modal stiffness and damping: -g kf and -g df are the central-difference Jacobians of
    the accelerations with respect to a and ad where the elastic forces dominate them (the
    tank: measured 4.9e-4 relative; the chain's lowest modes carry large inertial terms,
    its damping Jacobian agrees to 3.2e-2)."""
    n = pymr.model_size(scene)[0]
    rng = np.random.default_rng(3)
    q = 0.3 * rng.standard_normal(n)
    q[nj:] *= 1e-2
    qd = 0.5 * rng.standard_normal(n)
    qd[nj:] *= 1e-1
    g, kf, df = pymr.force_response(scene, q, qd)
    mm, _ = pymr.model_terms(scene, q, qd)
    e = np.zeros((n, n - nj))
    e[nj:] = np.eye(n - nj)
    exact = np.linalg.solve(mm, e)
    assert np.abs(g - exact).max() < 1e-12 * np.abs(exact).max()
    jac_a, jac_ad = np.zeros_like(g), np.zeros_like(g)
    for j in range(n - nj):
        for jac, x, d in ((jac_a, q, 1e-7), (jac_ad, qd, 1e-6)):
            xp, xm = x.copy(), x.copy()
            xp[nj + j] += d
            xm[nj + j] -= d
            args_p = (xp, qd) if x is q else (q, xp)
            args_m = (xm, qd) if x is q else (q, xm)
            jac[:, j] = (pymr.model_accelerations(scene, 0.0, *args_p) -
                         pymr.model_accelerations(scene, 0.0, *args_m)) / (2 * d)
    if scene == TANK:
        assert np.all(df == 0.0)            # no modal damping: ad enters through inertia only
        assert np.abs(jac_a + g * kf).max() < 2e-3 * np.abs(g * kf).max()
    else:
        assert np.all(df > 0.0)
        assert np.abs(jac_ad + g * df).max() < 0.1 * np.abs(g * df).max()


def test_ratio_one_is_single_rate_pece(tmp_path):
    """k = 1: every step is a full evaluation, the single-rate method (to 1e-12 relative:
    the Schur complement solve against the full Cholesky solve)."""
    single = pymr.run(TANK, tmp_path / "s.csv")
    multi = pymr.run(TANK, tmp_path / "m.csv", overrides=response(1, 1e-4))
    scale = np.maximum(np.abs(single.data).max(axis=0), 1e-300)
    assert (np.abs(multi.data - single.data).max(axis=0) / scale).max() < 1e-12
    assert multi.stats["rhs_fast"] == 0 and multi.stats["steps_fast"] == 10000


def test_table1_ratio_ten_is_within_a_micrometre_of_the_converged_muzzle(tmp_path, tank_reference):
    """The paper's Table 1 case k = 10, h_fast = 1e-4 s: the muzzle within 1e-6 m of the
    converged motion over 0-1 s (measured 5.8e-8 m, 1.0e-7 m before the surrogate's
    correction; the paper's coupling: 4.4e-3 m). One full evaluation per macro step after
    the first three, whose steps are all full (the surrogate needs four full evaluations),
    and one surrogate evaluation more at each macro step's end (its difference from the full
    one is the error the correction takes out): 1000 macro steps, 10000 fast steps."""
    res = pymr.run(TANK, tmp_path / "k10.csv", overrides=response(10, 1e-4, **{"output.dt": 1e-3}))
    assert marker_dev(res, tank_reference, "muzzle") < 1e-6
    assert res.stats["steps_fast"] == 10000 and res.stats["steps_slow"] == 1000
    assert res.stats["rhs_fast"] + res.stats["rhs_full"] < 11040
    assert res.stats["rhs_full"] < 1040


def test_tank_converges_at_order_four_at_fixed_ratio(tmp_path):
    """k = 10, h_fast halved from 2e-4 to 5e-5 s over 0.5 s against single-rate h = 1e-5 s:
    the muzzle's deviation falls at order 4 (measured 3.58 and 3.96 over 1 s; the cubic
    extrapolation of the surrogate keeps the ABM method's order)."""
    over = {"scene.t_end": 0.5, "output.dt": 1e-2}
    fine = pymr.run(TANK, tmp_path / "f.csv", overrides={**over, "integrator.h_slow": 1e-5, "integrator.h_fast": 1e-5})
    devs = [marker_dev(pymr.run(TANK, tmp_path / "m.csv", overrides={**response(10, h), **over}), fine, "muzzle")
            for h in (2e-4, 1e-4, 5e-5)]
    orders = np.log2(np.array(devs[:-1]) / np.array(devs[1:]))
    assert orders[-1] == pytest.approx(4.0, abs=0.3) and orders[0] > 3.3


def test_flexible_chain_converges_at_order_four_at_fixed_ratio(tmp_path):
    """Flexible links carrying flexible links (M_ff and g change with the state), k = 4 over
    0.1 s: the tip's deviation from single-rate h = 2e-6 s falls at order 4 once the macro
    step resolves the chain's coupled modes (measured 3.75, 4.23, 4.25 for h_fast 2.5e-5 to
    3.1e-6 s)."""
    over = {"scene.t_end": 0.1, "output.dt": 1e-2}
    fine = pymr.run(CHAIN, tmp_path / "f.csv", overrides={**over, "integrator.h_slow": 2e-6, "integrator.h_fast": 2e-6})
    devs = [marker_dev(pymr.run(CHAIN, tmp_path / "m.csv", overrides={**response(4, h), **over}), fine, "tip")
            for h in (1.25e-5, 6.25e-6)]
    assert np.log2(devs[0] / devs[1]) == pytest.approx(4.2, abs=0.35)


def test_stiff_barrel_takes_every_ratio_at_the_fast_stability_limit(tmp_path):
    """The stiff barrel's top mode (1015 Hz) bounds only the fast step: at h_fast = 6.5e-5 s
    (omega h = 0.415 < 0.430) the pre-flight check passes k = 2, 10 and 50 (the 'full'
    coupling is refused from k = 10 on), and each run's muzzle stays within 1e-5 m of the
    adaptive rtol 1e-9 reference (measured 2.5e-6 to 4.7e-6 m; the fast step's own error)."""
    ref = pymr.run(STIFF, tmp_path / "ref.csv", overrides={"integrator.adaptive": True, "integrator.rtol": 1e-9,
                                                          "integrator.atol": 1e-11, "output.dt": 1e-2})
    h = 6.5e-5
    for k in (2, 10, 50):
        res = pymr.run(STIFF, tmp_path / f"k{k}.csv", overrides=response(k, h, **{"output.dt": 1e-2,
                                                                                   "scene.t_end": 0.52}))
        assert marker_dev(res, ref, "muzzle") < 1e-5
    with pytest.raises(pymr.SceneError, match=r"coupling 'full'\) is not stable"):
        pymr.run(STIFF, tmp_path / "full.csv", overrides={**response(10, h), "integrator.coupling": "full"})


def test_adaptive_error_follows_the_tolerance(tmp_path, tank_reference):
    """Adaptive 'response' on the tank, rtol 1e-3 to 1e-8 (atol = rtol / 100): the muzzle
    error stays below 10 rtol and falls with it (measured 2.8e-5, 1.7e-6, 1.4e-8, 2.3e-10 m
    at rtol 1e-3, 1e-4, 1e-6, 1e-8), with the step ratio above 1."""
    errs = []
    for rtol in (1e-3, 1e-4, 1e-6, 1e-8):
        res = pymr.run(TANK, tmp_path / f"a{rtol}.csv", overrides={
            "integrator.method": "multirate", "integrator.adaptive": True, "integrator.rtol": rtol,
            "integrator.atol": rtol * 1e-2, "output.dt": 1e-3})
        err = marker_dev(res, tank_reference, "muzzle")
        assert err < 10 * rtol
        assert res.stats["rhs_fast"] > res.stats["rhs_full"]
        errs.append(err)
    assert all(a > b for a, b in zip(errs, errs[1:]))
    assert errs[0] / errs[-1] > 1e3


def test_adaptive_error_is_proportional_to_the_tolerance_on_the_stiff_barrel(stiff_barrel_reference):
    """Adaptive 'response' ('amplitude') on the stiff barrel over 0.2 s, rtol 1e-5 to 1e-8
    (atol = rtol / 100), against DOP853 at rtol 1e-13: the muzzle error falls as rtol does
    (tolerance proportionality, slope 1 in log-log; measured 1.04, 0.025-0.035 m per unit
    rtol; 0.98 and 0.022-0.026 before the step ratio's growth was bounded, b548008). Each
    macro step's fast steps are held to the tolerance together, their corrector estimates
    summed: with the largest alone their k errors outgrew the surrogate's as rtol
    tightened, and the error fell as rtol^0.66 (0.078 to 0.93 m per unit rtol)."""
    scene, ref = stiff_barrel_reference
    rtols = np.array([1e-5, 1e-6, 1e-7, 1e-8])
    errs = []
    for rtol in rtols:
        res = pymr.run(scene, overrides={
            "scene.t_end": 0.2, "output.dt": 1e-3, "integrator.method": "multirate", "integrator.coupling": "response",
            "integrator.adaptive": True, "integrator.error_norm": "amplitude", "integrator.rtol": rtol,
            "integrator.atol": rtol * 1e-2})
        errs.append(np.linalg.norm(res.marker("muzzle")[0] - ref, axis=1).max())
    assert np.polyfit(np.log(rtols), np.log(errs), 1)[0] == pytest.approx(1.0, abs=0.1)


def test_adaptive_ratio_recovers_after_the_recoil(tmp_path):
    """Adaptive 'response' through tank_firing.nml's 1 MN, 10 ms recoil pulse at rtol 1e-6:
    the muzzle stays within 10 rtol of a single-rate run at h = 2.5e-5 s (measured 1.4e-7 m),
    and the macro step recovers once the pulse has passed: fewer than one
    step in four rejected and over three fast-only evaluations per full one (measured 0.08
    and 10.0). When the error model of a macro step taken inside the pulse was kept over
    the single-step macro steps that followed it, every later try was refused on an
    estimate of 1e6: 0.90 of the steps rejected, 2.3 fast-only evaluations per full one."""
    scene = ROOT / "input" / "tank_firing.nml"
    ref = pymr.run(scene, tmp_path / "ref.csv", overrides={"integrator.h_slow": 2.5e-5, "integrator.h_fast": 2.5e-5})
    res = pymr.run(scene, tmp_path / "a.csv", overrides={
        "integrator.method": "multirate", "integrator.coupling": "response", "integrator.adaptive": True,
        "integrator.rtol": 1e-6, "integrator.atol": 1e-8})
    assert marker_dev(res, ref, "muzzle") < 10 * 1e-6
    assert res.stats["rejected_steps"] < 0.25 * res.stats["steps_slow"]
    assert res.stats["rhs_fast"] > 3 * res.stats["rhs_full"]


def test_adaptive_ratio_grows_by_at_most_a_tenth_per_macro_step(tmp_path):
    """Adaptive 'response' on the tank from k = 1 (h_slow = h_fast): after n macro steps the
    step ratio is at most the rule's bound, k + ceil(k / 10) per step from 1 (the history's
    first macro steps keep k, so the bound is not reached), and it has grown. Free to grow
    4x per macro step, k reached 39 in 6 macro steps and 2 of them were refused; bounded,
    7 in 9, 11 in 13 and 21 in 18, none refused (rtol 1e-6)."""
    for t_end in (0.002, 0.005, 0.01):
        res = pymr.run(TANK, tmp_path / "a.csv", overrides={
            "scene.t_end": t_end, "output.dt": t_end / 4, "integrator.method": "multirate",
            "integrator.coupling": "response", "integrator.adaptive": True, "integrator.h_slow": 1e-4,
            "integrator.h_fast": 1e-4, "integrator.rtol": 1e-6, "integrator.atol": 1e-8})
        bound = 1
        for _ in range(res.stats["steps_slow"]):
            bound += -(-bound // 10)
        assert 1 < res.stats["step_ratio_last"] <= bound
