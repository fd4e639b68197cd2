"""Integrator rules that the rest of the suite left loosely pinned (issue 29, mutation
testing): each test here checks one rule against an expectation that does not come from the
kernel, and states the figures measured with the rule as shipped and with a single-line
slip in it.

- The 'response' coupling's macro-step error estimate: an error control built from
  quantities of consistent units takes the same steps whatever the unit of time.
- The surrogate's damping term: with heavily damped modes the 'response' coupling still
  follows a converged single-rate run, and the pre-flight check still passes the ratio.
- The adaptive 'full' coupling's step ratio: the nearest integer to the wanted macro step
  over the wanted fast step, on a scene where both are pinned by known bounds.
- Formula 'adams' lowering its order: the order follows the one whose Adams-Moulton local
  error allows the longest step, as a damped oscillation decays below the tolerance.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import pymr
from test_adams import AM_ERROR
from test_hard_cases import imaginary_limit
from test_response import marker_dev, response

ROOT = Path(__file__).resolve().parent.parent
TANK = ROOT / "input" / "tank_gun_turret.nml"
STIFF = ROOT / "input" / "hard" / "stiff_barrel.nml"


# ------------------------------------------------- 1. 'response': the macro-step estimate

def time_unit(scene: Path, c: float) -> dict:
    """Overrides that run `scene` (the tank) in a time unit c times longer: every mass and
    inertia times c^2 (the beam's density too) with the elastic stiffness kept, so every
    frequency is divided by c; gravity divided by c^2 and the drives' torques kept, so every
    force keeps its ratio to the inertia; drive frequencies divided by c. The motion is
    the same function of t/c: positions as they were, rates divided by c, modal coordinates
    (m kg^0.5) times c (fixed steps of 1e-4 c s: muzzle paths alike to 1.6e-14 m for c = 0.01,
    1 and 10)."""
    s = pymr.Scene(scene)
    m = c * c
    over = {"scene.t_end": s["scene.t_end"] * c, "output.dt": 1e-2 * c,
            "scene.gravity": [g / m for g in s["scene.gravity"]],
            "body[gun].density": s["body[gun].density"] * m}
    for body in ("turret", "mount"):
        over[f"body[{body}].mass"] = s[f"body[{body}].mass"] * m
        over[f"body[{body}].inertia"] = [float(i) * m for i in s[f"body[{body}].inertia"]]
    for joint in ("traverse", "elevation"):
        over[f"drive[{joint}].frequency"] = s[f"drive[{joint}].frequency"] / c
    return over


def test_adaptive_response_steps_do_not_depend_on_the_time_unit():
    """Adaptive 'response' on the tank, rtol 1e-4 with atol 1e-6 rtol (a relative error
    control), run in time units 0.01, 1 and 10 times the second (time_unit). A change of
    unit changes no dimensionless quantity: an error estimate whose terms have the units of
    the state they are weighed against (a position error is an acceleration error times
    H^2, a rate error an acceleration error times H) takes the same steps measured in t/c,
    so the counts agree and the muzzle follows the same path. Measured: 776, 781, 785
    macro steps and 1134, 1162, 1109 full evaluations (spread 1.012 and 1.048), the muzzle
    paths within 2.9e-6 m. With the surrogate's position error scaled by H instead of H^2
    (a length per time), the estimate grows as the unit shrinks: 2350, 1065, 829 macro
    steps and 4202, 1484, 1145 full evaluations (spread 2.8 and 3.7)."""
    rtol = 1e-4
    steps, fulls, paths = [], [], []
    for c in (0.01, 1.0, 10.0):
        over = {"integrator.method": "multirate", "integrator.coupling": "response", "integrator.adaptive": True,
                "integrator.rtol": rtol, "integrator.atol": rtol * 1e-6, "integrator.h_slow": 1e-3 * c,
                "integrator.h_fast": 1e-4 * c, **time_unit(TANK, c)}
        res = pymr.run(TANK, overrides=over)
        assert res.t[-1] == pytest.approx(c) and res.t.size == 101
        steps.append(res.stats["steps_slow"])
        fulls.append(res.stats["rhs_full"])
        paths.append(res.marker("muzzle")[0])
    assert max(steps) / min(steps) < 1.15, f"macro steps {steps} in time units 0.01, 1, 10 s"
    assert max(fulls) / min(fulls) < 1.15, f"full evaluations {fulls} in time units 0.01, 1, 10 s"
    for p in paths[1:]:
        assert np.linalg.norm(p - paths[0], axis=1).max() < 1e-4


# ------------------------------------------------- 2. 'response': the surrogate's damping

@pytest.mark.parametrize("zeta", [0.2, 0.5])
def test_response_coupling_follows_heavily_damped_modes(zeta):
    """The tank with 20 % and 50 % modal damping on the barrel's modes, 0-0.3 s, against
    single-rate h = 1e-5 s (within 2.2e-13 m of h = 2e-5 s: converged). Damping a mode moves
    its eigenvalues into the left half-plane, so the Table 1 ratio k = 10 at h_fast = 1e-4 s,
    stable undamped, stays stable, and the surrogate, which moves every coordinate by its
    linear response to the fast elastic and damping forces, keeps the muzzle as close to
    the converged motion as without damping. Measured 1.4e-10 and 1.2e-10 m at h_fast
    1e-4 s, 1.7e-11 and 7.5e-12 m at 5e-5 s (20 % and 50 %). With the damping term left out
    of the surrogate's fast force, the runs go ahead (the pre-flight check trusts the
    surrogate's form; test_spacecraft checks that form), and at 5e-5 s the muzzle is
    4.1e-8 m off at 20 % while the run at 50 % breaks down at 0.0475 s."""
    damped = {"effects.modal_damping": True, "body[gun].modal_damping": zeta, "scene.t_end": 0.3,
              "output.dt": 1e-3}
    ref = pymr.run(TANK, overrides={**damped, "integrator.h_slow": 1e-5, "integrator.h_fast": 1e-5})
    for h, bound in ((5e-5, 1e-10), (1e-4, 1e-9)):
        try:
            res = pymr.run(TANK, overrides={**damped, **response(10, h)})
        except pymr.SceneError as exc:
            pytest.fail(f"k = 10, h_fast = {h} s with {zeta:.0%} damping refused: {exc}")
        assert marker_dev(res, ref, "muzzle") < bound


# ------------------------------------------------- 3. adaptive 'full': the step ratio

@pytest.mark.parametrize("wanted", [2.6, 3.6])
def test_adaptive_multirate_ratio_is_the_nearest_integer_to_the_wanted_steps(wanted):
    """Adaptive 'full' coupling on the stiff barrel at rtol 1e-2, 0-0.3 s: the motion asks
    for steps far longer than two bounds allow, so the fast step wants the stability bound,
    0.9 of the PECE imaginary-axis limit (computed here from the method's amplification
    matrix) over the top modal frequency (sqrt of the largest modal stiffness,
    pymr.force_response), and the macro step wants h_max, set to 2.6 and 3.6 times that. The
    ratio k = H/h is the nearest integer to 2.6 or 3.6, 3 or 4: H stays h_max and the fast
    step shrinks to H/k, below its bound; steps_fast = k steps_slow after the single-rate
    start. Measured k = 3 and 4, H = h_max to 1e-10, steps_fast/steps_slow 2.9968 and
    3.9920, no rejected step. With k truncated instead (int for nint), k = 2 and 3, H = 0.77
    and 0.83 h_max, steps_fast/steps_slow 1.9988 and 2.9964."""
    n = pymr.model_size(STIFF)[0]
    _, kf, _ = pymr.force_response(STIFF, np.zeros(n), np.zeros(n))
    h_fast_max = 0.9 * imaginary_limit() / math.sqrt(kf.max())
    h_max = wanted * h_fast_max
    k = round(wanted)
    res = pymr.run(STIFF, overrides={"integrator.method": "multirate", "integrator.coupling": "full",
                                     "integrator.adaptive": True, "integrator.rtol": 1e-2, "integrator.atol": 1e-4,
                                     "integrator.h_slow": 1e-3, "integrator.h_fast": 1e-4,
                                     "integrator.h_max": h_max, "scene.t_end": 0.3, "output.dt": 1e-2})
    s = res.stats
    assert s["step_ratio_last"] == k
    assert s["h_last"] == pytest.approx(h_max, rel=1e-8)
    assert s["h_last"] / s["step_ratio_last"] <= h_fast_max * (1 + 1e-9)
    assert s["steps_fast"] / s["steps_slow"] == pytest.approx(k, abs=0.05)


# ------------------------------------------------- 4. formula 'adams': lowering the order

OSCILLATOR = """
&scene title = 'damped oscillator: 1 Hz, 10 % of critical, from 1 m at rest', t_end = 40.0 /
&integrator method = 'single', adaptive = .true., formula = 'adams', rtol = 1e-10, atol = {atol},
            h_slow = 1e-3, h_max = {h_max} /
&effects joint_springs = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'slider', kind = 'rigid', mass = 1.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /
&joint name = 'x', kind = 'prismatic', parent = 'ground', child = 'slider', axis = 1.0, 0.0, 0.0, q0 = 1.0 /
&spring joint = 'x', stiffness = {k!r}, damping = {c!r} /
"""


def longest_step_order(allowed: float) -> int:
    """The Adams-Moulton order whose local error C_(q+1) (omega h)^(q+1) (published constants,
    test_adams.AM_ERROR) reaches a fifteenth of `allowed` (the allowed error over the
    motion's amplitude) at the longest step: the order a variable-order method should use."""
    q = np.arange(1, 13)
    consts = np.array([float(c) for c in AM_ERROR])
    return int(q[np.argmax((allowed / (15.0 * consts)) ** (1.0 / (q + 1)))])


def test_adams_order_falls_as_a_damped_oscillation_decays_below_the_tolerance(tmp_path):
    """A 1 Hz oscillator damped at 10 % of critical, from 1 m at rest, for 40 s (the motion
    decays as exp(-0.63 t) to 1e-11 m), formula 'adams' with a pure absolute tolerance
    (atol 1e-6, rtol 1e-10) and the step held at h_max (omega h = 0.05), so only the order
    is chosen: the one whose error estimate allows the longest step. Its error is
    C_(q+1) (omega h)^(q+1) times the amplitude A(t), so the best order falls as the
    allowed error over the amplitude, X = atol / (A sqrt((1 + omega^2)/2)), grows
    (longest_step_order): 12 below X = 0.39, 5 at X = 1.5-2.2, 2 from X = 10, 1 from
    X = 272. Order q is left for q - 1 when the q - 1 estimate, which is O(h^q), allows a
    longer step: its step ratio is err^(-1/q), as in LSODE and CVODE. Measured: orders 8-11
    while X < 1e-3, 2-4 at X = 1-10, 1-3 at X = 10-1000, 1-2 beyond, order 1 at the end;
    never more than one above the best order once X >= 1 (asserted: two, from X = 10).
    With the q - 1 ratio taken as err^(-1/(q+1)) the order is lowered only when the lower
    order's error is the smaller at the same step, which it never is here: orders 10-11 to
    the end, 8 to 10 above the best."""
    w, zeta = 2 * math.pi, 0.1
    scene = tmp_path / "oscillator.nml"
    scene.write_text(OSCILLATOR.format(atol=1e-6, h_max=0.05 / w, k=w * w, c=2 * zeta * w))
    t, h, q = pymr.step_history(scene)
    assert 40.0 <= t[-1] < 40.0 + 0.05 / w and np.all(h[2:] <= 0.05 / w * (1 + 1e-12))
    sigma, wd = zeta * w, w * math.sqrt(1 - zeta * zeta)
    amplitude = np.exp(-sigma * t) * w / wd
    allowed = 1e-6 / (amplitude * math.sqrt((1 + w * w) / 2))
    best = np.array([longest_step_order(x) for x in allowed])
    early = (t > 2.0) & (allowed < 1e-3)
    assert q[early].min() >= 8, f"orders {np.unique(q[early])} while the motion is far above the tolerance"
    late = allowed >= 10
    too_high = late & (q > best + 2)
    assert not too_high.any(), (f"order {q[too_high][0]} at t = {t[too_high][0]:.2f} s where the longest step "
                                f"is order {best[too_high][0]} (X = {allowed[too_high][0]:.3g})")
    assert q[-1] <= 2
