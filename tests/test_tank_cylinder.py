"""The tank's elevation driven by a hydraulic cylinder (input/tank_elevation_cylinder.nml): a
cylinder hinged to the turret, a rod sliding in it, the rod's eye pinned to the cradle (a
loop-closing revolute). Checked against independent expectations: the loop's kinematics by
the law of cosines in the triangle trunnion T, hinge H, rod pin P; the static loads by a hand
moment balance; the energy balance of the run; the muzzle's convergence.

Every test runs for each method in METHODS (the overrides that select it): single-rate
fixed steps, adaptive Adams, and multirate ('response' coupling) at k = 10. (The paper's
'full' coupling at k = 10 misses the muzzle by 4.4e-3 m here, as on the tank without the
cylinder: its own coupling error, docs/method.md section 4.)"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pymr

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "input" / "tank_elevation_cylinder.nml"
G = 9.81

# how each method runs the scene; refine(method, k) makes it k times finer
METHODS = {
    "single": {"integrator.method": "single"},
    "adams": {"integrator.method": "single", "integrator.adaptive": True, "integrator.formula": "adams",
              "integrator.rtol": 1e-9, "integrator.atol": 1e-11},
    "response": {"integrator.method": "multirate", "integrator.coupling": "response",
                 "integrator.h_slow": 1e-3, "integrator.h_fast": 1e-4},
}


def refine(method: str, k: int) -> dict:
    """The method's overrides with steps 2^k times smaller (fixed steps; h = 1e-4 s at k = 0,
    multirate at its step ratio) or a tolerance 10^(2k) times tighter (adaptive)."""
    over = dict(METHODS[method])
    if over.get("integrator.adaptive"):
        over["integrator.rtol"] *= 10.0 ** (-2 * k); over["integrator.atol"] *= 10.0 ** (-2 * k)
    else:
        ratio = over.get("integrator.h_slow", 1e-4) / over.get("integrator.h_fast", 1e-4)
        over["integrator.h_fast"] = 1e-4 / 2**k
        over["integrator.h_slow"] = ratio * over["integrator.h_fast"]
    return over


# the geometry of the scene's comment, in the turret's plane (x forward, y up), from the trunnion T
TH = np.array([-0.8, -0.3])           # hinge H - T
TP0 = np.array([0.0, -0.4])           # rod pin P - T at elevation 0 (mount frame (0, -0.4, 0))
GAMMA0 = np.arccos(TH @ TP0 / (np.hypot(*TH) * 0.4))     # angle HTP at elevation 0
M_CYL, C_CYL, M_ROD, C_ROD = 40.0, 0.25, 15.0, -0.3      # masses, centres along the cylinder from H, P
M_MOUNT, X_MOUNT = 1000.0, 0.1324
M_GUN = 7850.0 * np.pi * (0.11**2 - 0.06**2) * 5.3       # the beam's mass, centre 0.3 + 5.3/2 ahead of T
X_GUN = 0.3 + 5.3 / 2


def pin(q):
    """P - T at elevation q (about -Z: positive lowers the muzzle)."""
    return 0.4 * np.array([-np.sin(q), -np.cos(q)])


def elevation_of_stroke(s):
    """The elevation angle for pin-to-pin length s: the angle HTP = GAMMA0 - q by the law of
    cosines, s^2 = |TH|^2 + |TP|^2 - 2 |TH| |TP| cos(HTP)."""
    th = np.hypot(*TH)
    return GAMMA0 - np.arccos((th**2 + 0.4**2 - s**2) / (2 * th * 0.4))


def cross(a, b):
    return a[0] * b[1] - a[1] * b[0]


def run(method: str, k: int = 0, text: str | None = None, tmp_path: Path | None = None, **over):
    scene = SCENE
    if text is not None:
        scene = tmp_path / "scene.nml"
        scene.write_text(text)
    return pymr.run(scene, None, overrides={**refine(method, k), **over})


@pytest.mark.parametrize("method", METHODS)
def test_the_stroke_sets_the_elevation_by_the_law_of_cosines(method, tmp_path):
    """The rod's extension prescribed (&motion: s0 - 0.04 sin 2 pi t m, 80 mm of stroke): the
    elevation angle follows the triangle T H P by the law of cosines, and the cylinder's angle
    the direction H to P, to 1e-8 rad over 1 s; the loop stays closed to 1e-8 m. Measured:
    6.6e-15 rad, 3.3e-15 rad, 2.7e-15 m."""
    text = SCENE.read_text().replace("  joint_drives = .true.\n", "  joint_drives = .true.\n  base_motion = .true.\n")
    drive = "&drive joint = 'stroke', offset = 84278.0, amplitude = -44342.0, frequency = 1.0 /\n"
    assert drive in text
    text = text.replace(drive, "&motion joint = 'stroke', offset = 0.806225774829855, amplitude = -0.04, frequency = 1.0 /\n")
    res = run(method, text=text, tmp_path=tmp_path)
    s = res["stroke.q"]
    assert np.abs(s - (np.sqrt(0.65) - 0.04 * np.sin(2 * np.pi * res.t))).max() < 1e-12
    q = elevation_of_stroke(s)
    assert np.ptp(q) > 0.19                             # the muzzle swings 0.20 rad
    assert np.abs(res["elevation.q"] - q).max() < 1e-8
    hp = np.array([pin(x) for x in q]) - TH             # H to P
    assert np.abs(res["cyl_hinge.q"] - np.arctan2(-hp[:, 1], hp[:, 0])).max() < 1e-8
    assert max(np.abs(res[f"rod_eye.{x}"] - res[f"cradle_pin.{x}"]).max() for x in "xyz") < 1e-8


def static_balance():
    """The hand calculation at elevation 0, at rest: the force F of the cradle on the rod's
    eye (turret axes) and the cylinder force f along the rod that hold gun and cradle.

    - Cradle and gun about the trunnion (the elevation joint takes no moment):
      (P - T) x (-F) + sum_i (c_i - T) x m_i g = 0;
    - cylinder and rod about the hinge (the cylinder force is internal to them):
      (P - H) x F + (c_cyl - H) x m_cyl g + (c_rod - H) x m_rod g = 0;
    - the rod along its axis u: f + F . u + m_rod g . u = 0.
    Two equations for F, then f. Without the cylinder's and rod's weights f is the weight
    moment over the lever arm, 33449 N m / 0.39691 m."""
    g = np.array([0.0, -G])
    p = TP0; u = (p - TH) / np.hypot(*(p - TH))
    weight_moment = cross([X_MOUNT, 0.0], M_MOUNT * g) + cross([X_GUN, 0.0], M_GUN * g)
    actuator = cross(TH + C_CYL * u - TH, M_CYL * g) + cross(p + C_ROD * u - TH, M_ROD * g)
    # (P - T) x F = weight_moment, (P - H) x F = -actuator: a x F = a[0] F[1] - a[1] F[0]
    a = np.array([[-p[1], p[0]], [-(p - TH)[1], (p - TH)[0]]])
    f_pin = np.linalg.solve(a, [weight_moment, -actuator])
    f = -(f_pin @ u) - M_ROD * g @ u
    return f_pin, f, u, weight_moment


def gun_static_sag():
    """The barrel's modal coordinates in static equilibrium under gravity on a horizontal
    cradle (the tree scene's static start, joints held), to start the loop scene at rest."""
    res = pymr.run(ROOT / "input" / "tank_gun_turret.nml", None,
                   overrides={"scene.start": "static", "scene.t_end": 1e-3, "effects.joint_drives": False})
    return [float(res[f"gun.a{i}"][0]) for i in range(1, 5)]


@pytest.mark.parametrize("method", METHODS)
def test_the_cylinder_holds_the_gun_by_the_hand_moment_balance(method):
    """At rest at elevation 0 (the barrel at its static sag, no traverse torque) with the
    cylinder force f of the hand balance (static_balance: 84,285.7 N; the weight moment over
    the lever arm alone would be 84,277.4 N): nothing moves (1e-9 rad over 0.2 s; measured
    3e-15), and the reactions are the hand calculation's, to 1e-9 of f (measured 3e-10 N of
    84 kN): the cut pin's force on the rod (its frame: x along the rod, y across it) is F
    (-84,304 N along, 212 N across), the prismatic joint carries f along the rod, and the
    trunnion's force on the cradle is F plus the weight of cradle and gun."""
    f_pin, f, u, weight_moment = static_balance()
    assert weight_moment == pytest.approx(-33451, abs=1.0)     # the original scene's elevation offset
    assert f == pytest.approx(84285.7, abs=0.1)
    v = np.array([-u[1], u[0]])                         # the rod's y axis (its frame turned about -Z)
    over = {"scene.t_end": 0.2, "drive[traverse].amplitude": 0.0, "drive[stroke].offset": float(f),
            "drive[stroke].amplitude": 0.0, "body[gun].a0": gun_static_sag()}
    res = run(method, **over)
    for c in ("elevation.q", "cyl_hinge.q", "traverse.q"):
        assert np.abs(res[c] - res[c][0]).max() < 1e-9, c
    tol = 1e-9 * f
    assert np.abs(res["rod_pin.fx"] - f_pin @ u).max() < tol
    assert np.abs(res["rod_pin.fy"] - f_pin @ v).max() < tol
    assert np.abs(res["stroke.fx"] - f).max() < tol
    assert np.abs(res["stroke.fy"] + (f_pin + M_ROD * np.array([0.0, -G])) @ v).max() < tol
    assert np.abs(res["elevation.fx"] - f_pin[0]).max() < tol
    assert np.abs(res["elevation.fy"] - f_pin[1] - (M_MOUNT + M_GUN) * G).max() < tol
    for c in ("fz", "mx", "my", "mz"):
        assert np.abs(res[f"rod_pin.{c}"]).max() < tol, c


@pytest.mark.parametrize("method", METHODS)
def test_the_driven_scene_balances_its_energy_and_stays_closed(method):
    """The shipped run (traverse torque, cylinder force): E(t) - E(0) equals the drives' work
    (with the loads', the prescribed motions' and the damping's, all 0 here) to 1e-7 of the
    work done (measured 8.7e-9 of 6847 J at h = 1e-4 s, 2.5e-10 adaptive), the rod's eye stays
    on the cradle's pin to 1e-8 m (2e-13), and the muzzle goes down by about the original
    scene's 0.21 rad (0.2066; the original 0.2099)."""
    res = run(method)
    e = res["energy.total"]
    work = res["energy.drive_work"] + res["energy.load_work"] + res["energy.motion_work"] - res["energy.damping_loss"]
    assert np.abs(work).max() > 5000.0
    assert np.abs(e - e[0] - work).max() < 1e-7 * np.abs(work).max()
    assert max(np.abs(res[f"rod_eye.{x}"] - res[f"cradle_pin.{x}"]).max() for x in "xyz") < 1e-8
    assert 0.19 < res["elevation.q"].max() < 0.23


@pytest.mark.parametrize("method", METHODS)
def test_the_muzzle_motion_converges(method):
    """The muzzle's path against a run 4 times finer (fixed steps) or 10^4 times tighter
    (adaptive): within 1e-6 m, and refining once cuts the difference by more than 8. Measured:
    5.7e-8 m and 17.0 at h = 1e-4 s (order 4); 9.0e-11 m and 82 for 'adams' at rtol 1e-9."""
    runs = [run(method, k) for k in range(3)]
    ref = runs[2]
    err = []
    for r in runs[:2]:
        tt = np.searchsorted(ref.t, r.t)
        assert np.allclose(ref.t[tt], r.t, atol=1e-12, rtol=0)
        err.append(max(np.abs(r[f"muzzle.{x}"] - ref[f"muzzle.{x}"][tt]).max() for x in "xyz"))
    assert err[0] < 1e-6 and err[0] / err[1] > 8, err
