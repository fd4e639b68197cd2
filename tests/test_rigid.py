"""Rigid multibody scenes against analytic solutions and conservation laws.

- pendulum: the exact large-amplitude period (complete elliptic integral);
- spatial chain (floating base, no loads): energy, linear and angular momentum conserved, the
  momenta computed independently from marker kinematics and the scene's mass properties;
- double pendulum: energy conserved, the energy computed by hand from the planar kinematics;
- constant gravity on a prismatic joint and constant/sinusoidal drive torques on a revolute
  joint: closed-form q(t).
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
from scipy.special import ellipk

import pymr

ROOT = Path(__file__).resolve().parents[1]
INPUT = ROOT / "input"
PENDULUM = INPUT / "pendulum.nml"
CHAIN = INPUT / "spatial_chain.nml"
DOUBLE = INPUT / "double_pendulum.nml"
G = 9.81


def run(scene, tmp_path, name="out", overrides=None):
    return pymr.run(scene, output=str(tmp_path / f"{name}.csv"), overrides=overrides or {})


def total_energy(scene, r):
    q, qd = r.coordinates()
    ke, pe = pymr.model_energy(scene, q, qd)
    return np.asarray(ke), np.asarray(pe)


# ---------------------------------------------------------------------------------------------
# 1. Large-amplitude pendulum: exact period
# ---------------------------------------------------------------------------------------------
def upward_zero_crossings(t, q, half=4, degree=5):
    """Times of the upward zero crossings of q(t), each located by a local polynomial fit
    over 2*half samples around the sign change."""
    idx = np.nonzero((q[:-1] < 0.0) & (q[1:] >= 0.0))[0]
    idx = idx[(idx >= half - 1) & (idx + half < len(t))]
    out = []
    for i in idx:
        sl = slice(i - half + 1, i + half + 1)
        tt = t[sl] - t[i]
        roots = np.roots(np.polyfit(tt, q[sl], degree))
        roots = roots[np.abs(roots.imag) < 1e-12].real
        roots = roots[(roots >= -1e-12) & (roots <= t[i + 1] - t[i] + 1e-12)]
        assert len(roots) == 1
        out.append(t[i] + roots[0])
    return np.array(out)


def mean_period(t, q):
    tc = upward_zero_crossings(t, q)
    assert len(tc) >= 2
    return (tc[-1] - tc[0]) / (len(tc) - 1), len(tc) - 1


def test_zero_crossing_period_estimator_is_precise():
    # the estimator itself: a sampled sine of known period and phase, dt = 1e-3
    t = np.arange(0.0, 10.0 + 5e-4, 1e-3)
    period = 2.0 * math.pi / 2.987654321
    q = 0.7 * np.sin(2.0 * math.pi * t / period + 0.4)
    est, n = mean_period(t, q)
    assert n == 3  # 4 upward crossings in 10 s, the first at t = 1.97 s
    assert abs(est / period - 1.0) < 1e-12


def pendulum_exact_period():
    m, L, ic, q0 = 1.0, 1.0, 4.0e-5, 1.0  # input/pendulum.nml
    w0 = math.sqrt(m * G * L / (ic + m * L * L))
    return 4.0 / w0 * ellipk(math.sin(q0 / 2.0) ** 2)  # ellipk takes the parameter m = k^2


@pytest.mark.parametrize("overrides", [
    {},  # the file's fixed step h = 1e-3
    {"integrator.adaptive": True, "integrator.rtol": 1e-11, "integrator.atol": 1e-13},
], ids=["fixed-h1e-3", "adaptive-rtol1e-11"])
def test_pendulum_period_is_exact(tmp_path, overrides):
    r = run(PENDULUM, tmp_path, overrides={"output.dt": 1e-3, **overrides})
    assert r.t[-1] == pytest.approx(10.0)
    T, n = mean_period(r.t, r["pivot.q"])
    assert n >= 3  # T ~ 2.13 s: 4 upward crossings in 10 s
    rel = abs(T / pendulum_exact_period() - 1.0)
    assert rel < 1e-8, rel
    # the amplitude is kept too (turning points at +-q0 = 1 rad, energy conservation)
    assert abs(np.max(r["pivot.q"]) - 1.0) < 1e-6
    assert abs(np.min(r["pivot.q"]) + 1.0) < 1e-6


# ---------------------------------------------------------------------------------------------
# 2./3. Spatial chain with a floating base: energy, momentum, tolerance proportionality
# ---------------------------------------------------------------------------------------------
def test_spatial_chain_energy_is_conserved(tmp_path):
    r = run(CHAIN, tmp_path)
    assert r.t[-1] == pytest.approx(10.0)
    ke, pe = total_energy(CHAIN, r)
    assert np.all(pe == 0.0)  # gravity off
    e = ke + pe
    drift = np.max(np.abs(e - e[0])) / abs(e[0])
    assert drift < 1e-8, drift


def test_spatial_chain_energy_drift_falls_with_rtol(tmp_path):
    drifts = []
    for rtol in (1e-6, 1e-9):
        r = run(CHAIN, tmp_path, f"rtol{rtol:g}",
                {"integrator.rtol": rtol, "integrator.atol": rtol * 1e-2})
        ke, pe = total_energy(CHAIN, r)
        e = ke + pe
        drifts.append(np.max(np.abs(e - e[0])) / abs(e[0]))
    assert drifts[0] / drifts[1] > 100.0, drifts  # 3 decades of rtol


def chain_rigid_bodies(text):
    """(name, mass, com (3), inertia (6)) of the rigid bodies of a scene written one group
    per line, as input/spatial_chain.nml is."""
    bodies = []
    pat = re.compile(r"&body name='(\w+)', kind='rigid', mass=([^,]+), com=([^=]+), inertia=([^/]+)/")
    for m in pat.finditer(text):
        com = np.array([float(x) for x in m.group(3).rstrip(", ").split(",")])
        i6 = np.array([float(x) for x in m.group(4).split(",")])
        bodies.append((m.group(1), float(m.group(2)), com, i6))
    return bodies


def test_spatial_chain_momentum_is_conserved(tmp_path):
    """Linear momentum and angular momentum about the origin, computed independently of the
    kernel's model: three markers per body (centre of mass, com + e_x, com + e_y in body axes)
    give each body's centre-of-mass velocity, its orientation R and angular velocity w;
    then P = sum m v_c and H = sum (m r_c x v_c + R I R^T w), with the inertia tensor built from
    the scene's Ixx Iyy Izz Ixy Ixz Iyz as I(1,2) = Ixy etc. The kinetic energy from the same
    quantities must also agree with pymr.model_energy."""
    text = CHAIN.read_text()
    bodies = chain_rigid_bodies(text)
    assert len(bodies) == 6
    lines = []
    for name, _, com, _ in bodies:
        for tag, off in (("c", (0, 0, 0)), ("x", (1, 0, 0)), ("y", (0, 1, 0))):
            p = com + np.array(off, float)
            lines.append(f"&marker name='{name}_{tag}', body='{name}', "
                         f"at={float(p[0])!r}, {float(p[1])!r}, {float(p[2])!r} /")
    scene = tmp_path / "chain_markers.nml"
    scene.write_text(text + "\n" + "\n".join(lines) + "\n")
    r = run(scene, tmp_path)

    P = 0.0
    H = 0.0
    ke_indep = 0.0
    for name, mass, _, i6 in bodies:
        pc, vc = r.marker(name + "_c")
        px, vx = r.marker(name + "_x")
        py, vy = r.marker(name + "_y")
        e1, e2 = px - pc, py - pc
        e3 = np.cross(e1, e2)
        d1, d2 = vx - vc, vy - vc
        d3 = np.cross(d1, e2) + np.cross(e1, d2)
        R = np.stack([e1, e2, e3], axis=2)  # R[row] columns = body axes in the inertial frame
        assert np.max(np.abs(np.einsum("rik,ril->rkl", R, R) - np.eye(3))) < 1e-12
        w = 0.5 * (np.cross(e1, d1) + np.cross(e2, d2) + np.cross(e3, d3))
        assert np.max(np.abs(d1 - np.cross(w, e1))) < 1e-12  # rigid-body velocity field
        ib = np.array([[i6[0], i6[3], i6[4]], [i6[3], i6[1], i6[5]], [i6[4], i6[5], i6[2]]])
        lw = np.einsum("rik,kl,rjl,rj->ri", R, ib, R, w)
        P = P + mass * vc
        H = H + mass * np.cross(pc, vc) + lw
        ke_indep = ke_indep + 0.5 * mass * np.sum(vc * vc, axis=1) + 0.5 * np.sum(w * lw, axis=1)

    ke, _ = total_energy(scene, r)
    assert np.max(np.abs(ke_indep - ke)) / np.max(ke) < 1e-12

    assert np.linalg.norm(P[0]) > 0.1 and np.linalg.norm(H[0]) > 0.1  # non-trivial motion
    p_drift = np.max(np.abs(P - P[0])) / np.linalg.norm(P[0])
    h_drift = np.max(np.abs(H - H[0])) / np.linalg.norm(H[0])
    assert p_drift < 1e-8, p_drift
    assert h_drift < 1e-8, h_drift


# ---------------------------------------------------------------------------------------------
# 4. Double pendulum: energy conservation, energy computed by hand
# ---------------------------------------------------------------------------------------------
def double_pendulum_energy(q1, q2, w1, w2, m=1.0, izz=0.0834, lc=0.5, l1=1.0):
    """Planar double pendulum of input/double_pendulum.nml: rods along body x, joints about z,
    the lower joint at x = 1 of the upper body; gravity -y, potential zero at y = 0."""
    a2 = q1 + q2
    w2a = w1 + w2
    vx1, vy1 = -lc * np.sin(q1) * w1, lc * np.cos(q1) * w1
    y1 = lc * np.sin(q1)
    vx2 = -l1 * np.sin(q1) * w1 - lc * np.sin(a2) * w2a
    vy2 = l1 * np.cos(q1) * w1 + lc * np.cos(a2) * w2a
    y2 = l1 * np.sin(q1) + lc * np.sin(a2)
    ke = 0.5 * m * (vx1**2 + vy1**2 + vx2**2 + vy2**2) + 0.5 * izz * (w1**2 + w2a**2)
    pe = m * G * (y1 + y2)
    return ke, pe


def test_double_pendulum_energy_is_conserved(tmp_path):
    r = run(DOUBLE, tmp_path)
    assert r.t[-1] == pytest.approx(10.0)
    q1, q2 = r["shoulder.q"], r["elbow.q"]
    w1, w2 = r["shoulder.qd"], r["elbow.qd"]
    ke, pe = double_pendulum_energy(q1, q2, w1, w2)
    # the kernel's energy agrees with the hand computation ...
    ke_k, pe_k = total_energy(DOUBLE, r)
    assert np.max(np.abs(ke_k - ke)) < 1e-12 * np.max(ke)
    assert np.max(np.abs(pe_k - pe)) < 1e-12 * np.max(ke)
    # ... and the motion is violent (chaotic swings) yet conserves it
    e = ke + pe
    assert np.max(ke) > 10.0
    drift = np.max(np.abs(e - e[0])) / np.max(ke)
    assert drift < 1e-7, drift


# ---------------------------------------------------------------------------------------------
# 5. Constant and sinusoidal generalized forces: closed-form motion
# ---------------------------------------------------------------------------------------------
ADAPTIVE = {"integrator.adaptive": True, "integrator.rtol": 1e-10, "integrator.atol": 1e-12}

# mass properties shared by the small scenes below (products of inertia and an off-axis centre
# of mass on purpose: they must not enter the axial equations)
MASS, COM, INERTIA = 2.0, (0.3, -0.4, 0.25), (0.2, 0.25, 0.3, 0.01, 0.02, 0.03)


def small_scene(tmp_path, name, joint, effects, drive=""):
    com = ", ".join(repr(c) for c in COM)
    inertia = ", ".join(repr(c) for c in INERTIA)
    text = (f"&scene title='{name}', t_end=1.0, gravity=0.0, -9.81, 0.0 /\n"
            f"&integrator method='single', h_slow=1.0e-3 /\n"
            f"&effects {effects} /\n"
            f"&body name='ground', kind='ground' /\n"
            f"&body name='b', kind='rigid', mass={MASS!r}, com={com}, inertia={inertia} /\n"
            f"{joint}\n{drive}\n")
    path = tmp_path / f"{name}.nml"
    path.write_text(text)
    return path


@pytest.mark.parametrize("overrides", [{}, ADAPTIVE], ids=["fixed", "adaptive"])
def test_prismatic_free_fall_along_gravity(tmp_path, overrides):
    scene = small_scene(tmp_path, "fall",
                        "&joint name='slide', kind='prismatic', parent='ground', child='b', "
                        "axis=0.0, -1.0, 0.0 /", "gravity=.true.")
    r = run(scene, tmp_path, overrides=overrides)
    t, q, qd = r.t, r["slide.q"], r["slide.qd"]
    assert t[-1] == pytest.approx(1.0)
    assert abs(q[-1] / (0.5 * G * t[-1] ** 2) - 1.0) < 1e-10
    assert abs(qd[-1] / (G * t[-1]) - 1.0) < 1e-10
    np.testing.assert_allclose(q, 0.5 * G * t**2, rtol=1e-10, atol=1e-14)


def axial_inertia():
    # revolute about z through the body origin: Izz about the com plus m (cx^2 + cy^2)
    return INERTIA[2] + MASS * (COM[0] ** 2 + COM[1] ** 2)


REVOLUTE_Z = ("&joint name='pivot', kind='revolute', parent='ground', child='b', "
              "axis=0.0, 0.0, 1.0 /")


@pytest.mark.parametrize("overrides", [{}, ADAPTIVE], ids=["fixed", "adaptive"])
def test_constant_drive_torque_gives_constant_acceleration(tmp_path, overrides):
    tau = 3.0
    scene = small_scene(tmp_path, "torque", REVOLUTE_Z, "gravity=.false., joint_drives=.true.",
                        f"&drive joint='pivot', offset={tau!r} /")
    r = run(scene, tmp_path, overrides=overrides)
    t, q, qd = r.t, r["pivot.q"], r["pivot.qd"]
    qdd = tau / axial_inertia()
    assert t[-1] == pytest.approx(1.0)
    assert abs(q[-1] / (0.5 * qdd * t[-1] ** 2) - 1.0) < 1e-10
    assert abs(qd[-1] / (qdd * t[-1]) - 1.0) < 1e-10
    np.testing.assert_allclose(q, 0.5 * qdd * t**2, rtol=1e-10, atol=1e-14)


@pytest.mark.parametrize("overrides,tol", [({}, 1e-8), ({**ADAPTIVE, "output.dt": 0.01}, 1e-9)],
                         ids=["fixed", "adaptive"])
def test_sinusoidal_drive_torque(tmp_path, overrides, tol):
    amp, freq, phase = 3.0, 2.0, 0.7
    scene = small_scene(tmp_path, "sine", REVOLUTE_Z, "gravity=.false., joint_drives=.true.",
                        f"&drive joint='pivot', offset=0.0, amplitude={amp!r}, "
                        f"frequency={freq!r}, phase={phase!r} /")
    r = run(scene, tmp_path, overrides=overrides)
    t, q, qd = r.t, r["pivot.q"], r["pivot.qd"]
    w = 2.0 * math.pi * freq
    c = amp / axial_inertia()
    q_exact = c * (-(np.sin(w * t + phase) - math.sin(phase)) / w**2 + t * math.cos(phase) / w)
    qd_exact = c * (math.cos(phase) - np.cos(w * t + phase)) / w
    assert t[-1] == pytest.approx(1.0)
    assert np.max(np.abs(q - q_exact)) < tol * np.max(np.abs(q_exact))
    assert np.max(np.abs(qd - qd_exact)) < tol * np.max(np.abs(qd_exact))


def test_adaptive_steps_never_exceed_h_max(tmp_path):
    """Adaptive steps on the pendulum at rtol 1e-6 grow well past 1e-2 s; with h_max = 4e-3 s
    every step (each one written: output dt = 0) stays within it, so at least t_end / h_max
    steps are taken, and the period stays exact."""
    over = {"integrator.adaptive": True, "integrator.rtol": 1e-6, "integrator.atol": 1e-8, "output.dt": 0.0}
    free = run(PENDULUM, tmp_path, "free", overrides=over)
    assert np.diff(free.t).max() > 1e-2
    capped = run(PENDULUM, tmp_path, "capped", overrides={**over, "integrator.h_max": 4e-3})
    steps = np.diff(capped.t)
    assert steps.max() <= 4e-3 * (1 + 1e-12)
    assert capped.stats["steps_slow"] >= 10.0 / 4e-3
    assert capped.t[-1] == pytest.approx(10.0)
    T, _ = mean_period(capped.t, capped["pivot.q"])
    assert T == pytest.approx(pendulum_exact_period(), rel=1e-6)
