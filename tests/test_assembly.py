"""The kernel's recursively assembled M and P of ``M qdd = P`` against a brute-force
reference (tests/bruteforce.py: point masses, own forward kinematics, complex-step
Jacobians, Taylor jets for the velocity-product accelerations).

Run ``pytest tests/test_assembly.py -q -s`` to see the measured errors.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bruteforce as bf  # noqa: E402

import pymr  # noqa: E402
from pymr.scenes import spatial_chain  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
INPUT = ROOT / "input"
RTOL = 1e-10

DRIVE = "&drive joint='j3', offset=1.5, amplitude=2.0, frequency=0.7, phase=0.3 /\n"

# Every joint kind in one chain, a non-default gravity vector and two drives (one on the
# second coordinate of a spherical joint).
MIXED = """\
&scene title='every joint kind', t_end=1.0, gravity=0.3, -9.81, 0.5 /
&integrator method='single', h_slow=0.001 /
&effects gravity=.true., joint_drives=.true. /
&body name='ground', kind='ground' /
&body name='a', kind='rigid', mass=1.3, com=0.2, 0.03, -0.04, inertia=0.15, 0.19, 0.15, 0.006, 0.004, 0.003 /
&body name='b', kind='rigid', mass=0.9, com=0.1, -0.05, 0.02, inertia=0.12, 0.10, 0.09, -0.003, 0.002, 0.001 /
&body name='c', kind='rigid', mass=1.1, com=0.3, 0.01, 0.05, inertia=0.08, 0.11, 0.12, 0.001, -0.004, 0.002 /
&body name='d', kind='rigid', mass=0.7, com=-0.1, 0.2, 0.0, inertia=0.05, 0.06, 0.07, 0.002, 0.001, -0.003 /
&body name='e', kind='rigid', mass=1.2, com=0.25, 0.0, -0.1, inertia=0.09, 0.08, 0.10, -0.002, 0.003, 0.001 /
&body name='f', kind='rigid', mass=0.8, com=0.15, 0.05, 0.05, inertia=0.04, 0.05, 0.06, 0.001, 0.002, 0.0015 /
&joint name='j1', kind='free', parent='ground', child='a', at=0.1, 1.0, -0.2 /
&joint name='j2', kind='spherical', parent='a', child='b', at=0.5, 0.02, -0.01 /
&joint name='j3', kind='prismatic', parent='b', child='c', at=0.4, -0.03, 0.02, axis=1, 2, -1 /
&joint name='j4', kind='fixed', parent='c', child='d', at=0.3, 0.1, 0.05 /
&joint name='j5', kind='revolute', parent='d', child='e', at=0.2, -0.1, 0.3, axis=1, 1, 1 /
&joint name='j6', kind='spherical', parent='e', child='f', at=0.5, 0.0, 0.1 /
&drive joint='j2', coordinate=2, offset=0.5, amplitude=1.0, frequency=1.3, phase=-0.2 /
&drive joint='j3', offset=-1.0, amplitude=0.5, frequency=0.4, phase=0.1 /
"""


def _with_drive(text: str) -> str:
    text = text.replace("&effects gravity=.true. /", "&effects gravity=.true., joint_drives=.true. /")
    text = text.replace("&effects gravity=.false. /", "&effects gravity=.false., joint_drives=.true. /")
    assert "joint_drives=.true." in text
    return text + DRIVE


def _scene_file(tmp_path: Path, text: str, name: str = "scene.nml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def _states(scene: bf.Scene, seed: int, count: int = 3):
    """The scene's initial state, `count` random states and, with gravity on, a state at rest."""
    rng = np.random.default_rng(seed)
    q0, qd0 = scene.initial_state()
    states = [(q0, qd0)]
    for _ in range(count):
        q = rng.uniform(-math.pi, math.pi, scene.n)
        for j in scene.joints:  # free-joint translations: a few metres
            if j.kind == "free":
                q[j.first:j.first + 3] = rng.uniform(-2.0, 2.0, 3)
        states.append((q, rng.normal(0.0, 1.5, scene.n)))
    if scene.gravity_on:
        states.append((states[1][0], np.zeros(scene.n)))
    return states


def _errors(mk, pk, mr, pr, qd):
    """max|dM| / max|M| and max|dP| / (max|P| + max|M| max|qd|^2)."""
    em = np.abs(mk - mr).max() / np.abs(mr).max()
    ep = np.abs(pk - pr).max() / (np.abs(pr).max() + np.abs(mr).max() * np.abs(qd).max() ** 2)
    return float(em), float(ep)


def _compare(path: Path, scene: bf.Scene, states, times=(0.0,), label=""):
    worst_m = worst_p = 0.0
    for i, (q, qd) in enumerate(states):
        t = times[i % len(times)]
        mk, pk = pymr.model_terms(path, q, qd, t)
        mr, pr = bf.reference_terms(scene, q, qd, t)
        assert mk.shape == mr.shape == (scene.n, scene.n) and pk.shape == pr.shape == (scene.n,)
        em, ep = _errors(mk, pk, mr, pr, qd)
        worst_m, worst_p = max(worst_m, em), max(worst_p, ep)
        assert em < RTOL, f"{label} state {i}: M differs, rel {em:.3e}; entries (row, col) " \
            f"{np.argwhere(np.abs(mk - mr) > RTOL * np.abs(mr).max()).tolist()}"
        assert ep < RTOL, f"{label} state {i} t={t}: P differs, rel {ep:.3e}; coordinates " \
            f"{np.flatnonzero(np.abs(pk - pr) > RTOL * np.abs(pr).max()).tolist()}"
    print(f"\n{label}: n={scene.n}, {len(states)} states, max rel err M {worst_m:.2e}, P {worst_p:.2e}")
    return worst_m, worst_p


# ----------------------------------------------------------------------------------------
# the reference itself
# ----------------------------------------------------------------------------------------

def test_parser_reads_scene_values():
    sc = bf.Scene.from_file(INPUT / "spatial_chain.nml")
    assert sc.n == 11 and not sc.gravity_on and not sc.drives_on
    assert [j.name for j in sc.joints] == ["j1", "j2", "j3", "j4", "j5", "j6"]
    assert [j.first for j in sc.joints] == [0, 6, 7, 8, 9, 10]
    assert sc.bodies["b1"].mass == 1.25591
    assert sc.bodies["b2"].inertia[0, 2] == -0.00781908 and sc.bodies["b2"].inertia[2, 0] == -0.00781908
    assert sc.bodies["b2"].inertia[1, 2] == -0.00257192 and sc.bodies["b2"].inertia[2, 2] == 0.143394
    np.testing.assert_array_equal(sc.joints[0].q0, [0.1, -0.2, 0.05, 0.3, -0.2, 0.4])
    np.testing.assert_array_equal(sc.joints[3].axis, np.array([1.0, 1.0, 0.0]) / math.sqrt(2.0))
    np.testing.assert_array_equal(sc.gravity, [0.0, -9.81, 0.0])
    multi = bf.Scene.from_file(INPUT / "pendulum.nml")  # items over several lines
    assert multi.gravity_on and multi.n == 1 and multi.bodies["bob"].com[1] == -1.0
    assert multi.bodies["bob"].inertia[0, 0] == 4.0e-5


@pytest.mark.parametrize("text", [spatial_chain(8, seed=3), MIXED])
def test_point_masses_reproduce_bodies(text):
    sc = bf.Scene.from_text(text)
    for b in sc.bodies.values():
        if b.kind != "rigid":
            continue
        m, x = bf.point_masses(b.mass, b.com, b.inertia)
        assert m.sum() == pytest.approx(b.mass, rel=1e-14)
        c = (m[:, None] * x).sum(axis=0) / m.sum()
        np.testing.assert_allclose(c, b.com, rtol=0, atol=1e-14)
        d = x - c
        inertia = sum(mi * (di @ di * np.eye(3) - np.outer(di, di)) for mi, di in zip(m, d))
        np.testing.assert_allclose(inertia, b.inertia, rtol=0, atol=1e-14 * np.abs(b.inertia).max())


PENDULUM = """\
&scene title='pendulum', t_end=1.0, gravity = 0.0, -9.81, 0.0 /
&integrator method='single', h_slow=0.001 /
&effects gravity = .true. /
&body name='ground', kind='ground' /
&body name='bob', kind='rigid', mass=2.5, com=0.3, -1.0, 0.2,
      inertia=0.1, 0.2, 0.25, 0.01, 0.02, 0.03 /
&joint name='pivot', kind='revolute', parent='ground', child='bob', at=0.4, 0.7, -0.1, axis=AXIS /
"""


@pytest.mark.parametrize("axis", [(0.0, 0.0, 1.0), (1.0, 2.0, 2.0)])
def test_reference_single_pendulum_analytic(tmp_path, axis):
    """M = u^T I_pivot u with I_pivot = I_c + m (|c|^2 Id - c c^T); for the z axis
    I_pivot,zz = Izz + m (cx^2 + cy^2) and P = -m g (cx cos q - cy sin q); also the kernel."""
    text = PENDULUM.replace("AXIS", "%r, %r, %r" % axis)
    path = _scene_file(tmp_path, text)
    sc = bf.Scene.from_text(text)
    b = sc.bodies["bob"]
    u = np.array(axis) / np.linalg.norm(axis)
    c = b.com
    i_pivot = b.inertia + b.mass * (c @ c * np.eye(3) - np.outer(c, c))
    m_exact = u @ i_pivot @ u
    if axis == (0.0, 0.0, 1.0):
        assert m_exact == pytest.approx(0.25 + 2.5 * (0.3 ** 2 + 1.0), rel=1e-15)
    for q, qd in [(0.0, 0.0), (1.0, 0.7), (-2.3, -1.9), (3.0, 4.0)]:
        mr, pr = bf.reference_terms(sc, [q], [qd])
        assert mr[0, 0] == pytest.approx(m_exact, rel=1e-13)
        if axis == (0.0, 0.0, 1.0):
            p_exact = -b.mass * 9.81 * (c[0] * math.cos(q) - c[1] * math.sin(q))
            assert pr[0] == pytest.approx(p_exact, rel=1e-13, abs=1e-13)
        mk, pk = pymr.model_terms(path, [q], [qd])
        assert mk[0, 0] == pytest.approx(m_exact, rel=RTOL)
        assert pk[0] == pytest.approx(pr[0], rel=RTOL, abs=RTOL * 30.0)


def test_reference_double_pendulum_analytic():
    """Planar double pendulum (input/double_pendulum.nml): the textbook M, Coriolis and
    gravity terms, P1 = h (2 qd1 qd2 + qd2^2) + G1, P2 = -h qd1^2 + G2, h = m2 l1 c2 sin q2."""
    path = INPUT / "double_pendulum.nml"
    sc = bf.Scene.from_file(path)
    up, lo = sc.bodies["upper"], sc.bodies["lower"]
    m1, m2, c1, c2, l1 = up.mass, lo.mass, up.com[0], lo.com[0], 1.0
    i1, i2, g = up.inertia[2, 2], lo.inertia[2, 2], 9.81
    rng = np.random.default_rng(7)
    for _ in range(4):
        q1, q2 = rng.uniform(-math.pi, math.pi, 2)
        qd1, qd2 = rng.normal(0.0, 2.0, 2)
        m11 = i1 + m1 * c1 ** 2 + i2 + m2 * (l1 ** 2 + c2 ** 2 + 2 * l1 * c2 * math.cos(q2))
        m12 = i2 + m2 * (c2 ** 2 + l1 * c2 * math.cos(q2))
        m22 = i2 + m2 * c2 ** 2
        h = m2 * l1 * c2 * math.sin(q2)
        g1 = -m1 * g * c1 * math.cos(q1) - m2 * g * (l1 * math.cos(q1) + c2 * math.cos(q1 + q2))
        g2 = -m2 * g * c2 * math.cos(q1 + q2)
        m_exact = np.array([[m11, m12], [m12, m22]])
        p_exact = np.array([h * (2 * qd1 * qd2 + qd2 ** 2) + g1, -h * qd1 ** 2 + g2])
        mr, pr = bf.reference_terms(sc, [q1, q2], [qd1, qd2])
        np.testing.assert_allclose(mr, m_exact, rtol=0, atol=1e-13 * np.abs(m_exact).max())
        np.testing.assert_allclose(pr, p_exact, rtol=0, atol=1e-13 * np.abs(p_exact).max())
        mk, pk = pymr.model_terms(path, [q1, q2], [qd1, qd2])
        em, ep = _errors(mk, pk, m_exact, p_exact, np.array([qd1, qd2]))
        assert em < RTOL and ep < RTOL


@pytest.mark.parametrize("text", [spatial_chain(5, free_base=True, gravity=True), MIXED],
                         ids=["chain5-free-gravity", "mixed"])
def test_reference_newton_equals_lagrange(text):
    """The reference's two routes agree: Jacobians + Taylor accelerations versus
    Lagrange's equations with complex-step derivatives of M(q) and of the potential."""
    sc = bf.Scene.from_text(text)
    for q, qd in _states(sc, seed=11, count=2):
        m1, p1 = bf.reference_terms(sc, q, qd, 0.8)
        m2, p2 = bf.reference_terms_lagrange(sc, q, qd, 0.8)
        em, ep = _errors(m2, p2, m1, p1, qd)
        assert em < 1e-13 and ep < 1e-13


# ----------------------------------------------------------------------------------------
# the kernel against the reference
# ----------------------------------------------------------------------------------------

def test_kernel_spatial_chain_input():
    path = INPUT / "spatial_chain.nml"
    sc = bf.Scene.from_file(path)
    assert pymr.model_size(path)[0] == sc.n
    _compare(path, sc, _states(sc, seed=1, count=4), label="input/spatial_chain.nml")


@pytest.mark.parametrize("n_bodies", [5, 8])
@pytest.mark.parametrize("free_base", [True, False], ids=["free", "fixedbase"])
@pytest.mark.parametrize("gravity", [True, False], ids=["gravity", "nogravity"])
def test_kernel_generated_chain(tmp_path, n_bodies, free_base, gravity):
    text = spatial_chain(n_bodies, free_base=free_base, gravity=gravity, seed=n_bodies)
    path = _scene_file(tmp_path, text)
    sc = bf.Scene.from_text(text)
    assert sc.n == n_bodies + (5 if free_base else 0) and sc.gravity_on == gravity
    _compare(path, sc, _states(sc, seed=100 + n_bodies), label=f"chain n={n_bodies} free={free_base} g={gravity}")


@pytest.mark.parametrize("gravity", [True, False], ids=["gravity", "nogravity"])
def test_kernel_chain_with_drive(tmp_path, gravity):
    text = _with_drive(spatial_chain(5, free_base=True, gravity=gravity, seed=2))
    path = _scene_file(tmp_path, text)
    sc = bf.Scene.from_text(text)
    assert sc.drives_on and len(sc.drives) == 1
    # the drive load reaches coordinate 8 (free base 1-6, j2 7, j3 8) and nothing else
    f = sc.generalised_drive_forces(0.9)
    assert np.flatnonzero(f).tolist() == [7]
    assert f[7] == pytest.approx(1.5 + 2.0 * math.sin(2 * math.pi * 0.7 * 0.9 + 0.3), rel=1e-15)
    _compare(path, sc, _states(sc, seed=5), times=(0.9, 0.0, 2.37, 0.31), label=f"chain + drive g={gravity}")
    # P changes with t by the drive load alone
    q, qd = _states(sc, seed=6, count=1)[1]
    _, pa = pymr.model_terms(path, q, qd, 0.9)
    _, pb = pymr.model_terms(path, q, qd, 2.37)
    expected = sc.generalised_drive_forces(0.9) - sc.generalised_drive_forces(2.37)
    np.testing.assert_allclose(pa - pb, expected, rtol=0, atol=1e-12 * np.abs(pa).max())


def test_kernel_every_joint_kind(tmp_path):
    path = _scene_file(tmp_path, MIXED)
    sc = bf.Scene.from_text(MIXED)
    assert sc.n == 6 + 3 + 1 + 0 + 1 + 3
    _compare(path, sc, _states(sc, seed=9, count=4), times=(0.0, 0.37, 1.9), label="every joint kind")


@pytest.mark.parametrize("which", ["input", "mixed"])
def test_kernel_energy_and_accelerations(tmp_path, which):
    """Kinetic energy, potential differences and accelerations of the kernel agree with
    the reference (residual |M_ref qdd - P_ref| relative to |M||qdd| + |P|)."""
    if which == "input":
        path = INPUT / "spatial_chain.nml"
        sc = bf.Scene.from_file(path)
    else:
        path = _scene_file(tmp_path, MIXED)
        sc = bf.Scene.from_text(MIXED)
    states = _states(sc, seed=21, count=3)
    bf.check_energy_and_accelerations(path, sc, states, RTOL)
