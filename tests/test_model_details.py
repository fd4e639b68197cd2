"""Model details no other test reaches (issue 29, mutation testing of the suite): a prescribed
joint below a free one in the articulated-body algorithm, a tabulated drive's offset, and
the assembly of a driven loop given off closure. Each expectation is independent of the
code: momentum balance, the closed-form integral of a known force, the prescribed function
and the closed-form four-bar loop."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

import pymr

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_effects import rail, spinup  # noqa: E402
from test_loops import L0, fourbar_angles, fourbar_scene  # noqa: E402

# ------------------------------------------- prescribed joint below a free joint

# cart on a frictionless rail along x (pushed by a constant force), carrying an arm whose
# swing about z is prescribed: theta(t) = OFFSET + AMP sin(2 pi FREQ t + PHASE)
M_CART, M_ARM, ARM_COM, PUSH, V0 = 3.0, 1.0, 0.4, 1.5, 0.2
OFFSET, AMP, FREQ, PHASE = -1.0, 0.6, 1.5, 0.3


def cart_scene(tmp_path: Path) -> Path:
    """The cart (its centre of mass off its joint) on the prismatic 'rail', the arm on the
    revolute 'swing' at (0.2, -0.1, 0) of the cart, gravity along -y (across the rail)."""
    path = tmp_path / "cart.nml"
    path.write_text(
        "&scene title = 'cart carrying a swung arm', t_end = 1.0, gravity = 0.0, -9.81, 0.0 /\n"
        "&integrator method = 'single', h_slow = 1.0e-3 /\n"
        "&effects gravity = .true., joint_drives = .true., base_motion = .true. /\n"
        "&body name = 'ground', kind = 'ground' /\n"
        f"&body name = 'cart', kind = 'rigid', mass = {M_CART!r}, com = 0.1, 0.05, 0.0, "
        "inertia = 0.1, 0.2, 0.3, 0.0, 0.0, 0.0 /\n"
        f"&body name = 'arm', kind = 'rigid', mass = {M_ARM!r}, com = {ARM_COM!r}, 0.0, 0.0, "
        "inertia = 1.0e-3, 0.05, 0.05, 0.0, 0.0, 0.0 /\n"
        f"&joint name = 'rail', kind = 'prismatic', parent = 'ground', child = 'cart', axis = 1.0, 0.0, 0.0, "
        f"qd0 = {V0!r} /\n"
        "&joint name = 'swing', kind = 'revolute', parent = 'cart', child = 'arm', at = 0.2, -0.1, 0.0 /\n"
        f"&drive joint = 'rail', offset = {PUSH!r} /\n"
        f"&motion joint = 'swing', form = 'sine', offset = {OFFSET!r}, amplitude = {AMP!r}, "
        f"frequency = {FREQ!r}, phase = {PHASE!r} /\n"
        "&output dt = 0.01 /\n")
    return path


def swing(t):
    """The prescribed arm angle and its first two derivatives."""
    w = 2 * np.pi * FREQ
    s, c = np.sin(w * t + PHASE), np.cos(w * t + PHASE)
    return OFFSET + AMP * s, AMP * w * c, -AMP * w * w * s


def cart_acceleration(th, thd, thdd):
    """Momentum balance along the rail: (m_cart + m_arm) x'' + m_arm d^2/dt^2 (c cos theta)
    = F, the arm's centre of mass at c along the arm."""
    return (PUSH + M_ARM * ARM_COM * (np.sin(th) * thdd + np.cos(th) * thd**2)) / (M_CART + M_ARM)


@pytest.mark.parametrize("dynamics", ["articulated", "mass_matrix"])
def test_a_cart_under_a_prescribed_swing_accelerates_by_momentum_balance(tmp_path, dynamics):
    """A prescribed joint hung below a free one: the swing's known acceleration loads the
    cart. At three states on the prescribed motion the cart's acceleration by the
    articulated-body algorithm and by M qdd = P equals the momentum balance's to 1e-10 of its
    size (measured 9e-16 m/s^2 of 2.5 to 4.1 m/s^2; leaving the swing's acceleration out of the
    articulated bias gives 1.2 to 4.5 m/s^2 of error), and the swing's own acceleration is
    its function's."""
    scene = cart_scene(tmp_path)
    with pymr.Model(scene, {"integrator.dynamics": dynamics}) as model:
        for t, x in ((0.0, 0.3), (0.13, -0.2), (0.41, 1.1)):
            th, thd, thdd = swing(t)
            f = model.rhs(t, np.array([x, th, 0.7, thd]))
            ref = cart_acceleration(th, thd, thdd)
            assert abs(ref) > 1.0
            assert abs(f[2] - ref) < 1e-10 * abs(ref), (t, f[2], ref)
            assert abs(f[3] - thdd) < 1e-12 * abs(thdd) + 1e-12, t


@pytest.mark.parametrize("dynamics", ["articulated", "mass_matrix"])
def test_a_cart_under_a_prescribed_swing_keeps_the_momentum_its_push_gives(tmp_path, dynamics):
    """Over 1 s (h = 1 ms) the rail's momentum M x' - m_arm c sin(theta) theta' grows as the
    push F t, so x = p0 t / M + F t^2 / (2 M) - m_arm c (cos theta - cos theta0) / M: the
    cart's position and rate against it to 1e-7 (measured 5e-10 m, 6e-10 m/s; with the
    swing's acceleration left out of the articulated bias 0.15 m off), and the swing on its
    function to roundoff."""
    res = pymr.run(cart_scene(tmp_path), tmp_path / "cart.csv", overrides={"integrator.dynamics": dynamics})
    t = res.t
    th, thd, _ = swing(t)
    m = M_CART + M_ARM
    p0 = m * V0 - M_ARM * ARM_COM * np.sin(th[0]) * thd[0]
    x = p0 * t / m + PUSH * t**2 / (2 * m) - M_ARM * ARM_COM * (np.cos(th) - np.cos(th[0])) / m
    v = (p0 + PUSH * t + M_ARM * ARM_COM * np.sin(th) * thd) / m
    assert np.ptp(res["rail.q"]) > 0.3
    assert np.abs(res["rail.q"] - x).max() < 1e-7
    assert np.abs(res["rail.qd"] - v).max() < 1e-7
    assert np.abs(res["swing.q"] - th).max() < 1e-12
    assert np.abs(res["swing.qd"] - thd).max() < 1e-11


# ---------------------------------------------------------------- tabulated drive

def test_a_tabulated_drive_adds_its_offset(tmp_path):
    """A drive of form 'table' (0 to 2 N over 1 s) with offset -0.5 N pushes the 2 kg slider
    by F = -0.5 + 2 t: x = -t^2 / 8 + t^3 / 6 (the ABM step integrates the cubic exactly:
    measured 5e-17 m, x(1) = 0.0417 m; without the offset 0.167 m), and the right-hand side
    P is the offset plus the table's value (to 1e-12 N; without the offset 0.5 N more)."""
    (tmp_path / "push.csv").write_text("0.0 0.0\n1.0 2.0\n")
    scene = rail(tmp_path, "&drive joint = 'rail', form = 'table', file = 'push.csv', offset = -0.5 /")
    res = pymr.run(scene, tmp_path / "rail.csv")
    t = res.t
    assert np.abs(res["rail.q"] - (-t**2 / 8 + t**3 / 6)).max() < 1e-12
    assert np.abs(res["rail.qd"] - (-t / 4 + t**2 / 2)).max() < 1e-12
    for tt in (0.1, 0.7):
        _, p = pymr.model_terms(scene, np.zeros(1), np.array([0.3]), t=tt)
        assert abs(p[0] - (-0.5 + 2.0 * tt)) < 1e-12, tt


# --------------------------------------------------- driven loop given off closure

def test_a_driven_fourbar_given_off_closure_is_closed_by_its_free_joints(tmp_path):
    """The four-bar with its crank prescribed (spin-up from 1 rad to 3 rad/s in 0.5 s), the
    coupler and rocker angles given 3e-4 rad off the loop: the assembly closes the loop by
    moving the free coordinates only. The crank follows its function exactly (1e-12 rad), the
    loop is closed at every output from the first (1e-9 m; measured 1.5e-11) and the coupler
    and rocker lie on the closed-form loop of the crank angle (1e-9 rad; measured 1.4e-11).
    A projection that also moves the crank leaves the start 1.9e-4 m open (the crank put
    back on its function), the coupler 2.3e-4 rad off."""
    p2, p3, _, _ = fourbar_angles(1.0)
    qb, qc = float(p2 - 1.0), float(p3 - p2)
    text = fourbar_scene(1.0, 0.0, t_end=1.0).replace(
        "&effects gravity = .true. /", "&effects gravity = .true., base_motion = .true. /")
    text += "&motion joint = 'A', form = 'spinup', offset = 1.0, rate = 3.0, ramp_time = 0.5 /\n"
    off = text.replace(f"q0 = {qb!r}", f"q0 = {qb + 3e-4!r}").replace(f"q0 = {qc!r}", f"q0 = {qc - 3e-4!r}")
    assert f"q0 = {qb + 3e-4!r}" in off and f"q0 = {qc - 3e-4!r}" in off
    (tmp_path / "driven.nml").write_text(off)
    res = pymr.run(tmp_path / "driven.nml", tmp_path / "driven.csv")
    theta, rate = spinup(res.t, 3.0, 0.5)
    assert np.abs(res["A.q"] - (1.0 + theta)).max() < 1e-12
    assert np.abs(res["A.qd"] - rate).max() < 1e-12
    assert np.hypot(res["tip.x"] - L0, res["tip.y"]).max() < 1e-9
    q2, q3 = np.array([fourbar_angles(p)[:2] for p in res["A.q"]]).T
    wrap = lambda a: (a + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(wrap(res["A.q"] + res["B.q"] - q2)).max() < 1e-9
    assert np.abs(wrap(res["A.q"] + res["B.q"] + res["C.q"] - q3)).max() < 1e-9
    # the given state really was off the loop: the assembly moved the free joints by 3e-4
    assert abs(res["B.q"][0] - (qb + 3e-4)) > 1e-4
