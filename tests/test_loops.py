"""Closed loops: loop-closing joints (a &joint whose child already has a parent), the
constrained dynamics M qdd = P + G^T lambda, the projection that keeps the loops closed,
the redundant rows of planar loops of 3-D joints, and the constraint forces.

The four-bar is checked against an independent minimal-coordinate solution: closed-form
loop kinematics (the rocker's pivot from the intersection of two circles), Lagrange's
equation in the crank angle, m(phi) phi'' + m'(phi) phi'^2 / 2 + V'(phi) = 0, integrated by
scipy's DOP853 at 1e-12."""
from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import pymr

G = 9.81
# ground pivots 1 m apart; crank, coupler, rocker: uniform rods (length, mass)
L0 = 1.0
LINKS = [("crank", 0.4, 1.0), ("coupler", 1.0, 2.0), ("rocker", 0.7, 1.5)]


def _n(p):
    return np.array([-np.sin(p), np.cos(p)])


def fourbar_angles(p1):
    """Absolute angles of the coupler (B to C) and of the rocker (C to D) for crank angle p1
    (the branch with C above the line B D), and their rates per unit crank rate."""
    (l1, _), (l2, _), (l3, _) = [(l, m) for _, l, m in LINKS]
    b = l1 * np.array([np.cos(p1), np.sin(p1)]); d = np.array([L0, 0.0])
    dv = d - b; dd = np.hypot(*dv)
    a = (l2**2 - l3**2 + dd**2) / (2 * dd); h = np.sqrt(l2**2 - a**2)
    c = b + a * dv / dd + h * np.array([-dv[1], dv[0]]) / dd
    p2 = np.arctan2(c[1] - b[1], c[0] - b[0]); p3 = np.arctan2(d[1] - c[1], d[0] - c[0])
    r2, r3 = np.linalg.solve(np.column_stack([l2 * _n(p2), l3 * _n(p3)]), -l1 * _n(p1))
    return p2, p3, r2, r3


def fourbar_mass_potential(p1):
    """Generalised mass m(p1) (T = m p1'^2 / 2) and gravity potential V(p1)."""
    (l1, m1), (l2, m2), (l3, m3) = [(l, m) for _, l, m in LINKS]
    p2, p3, r2, r3 = fourbar_angles(p1)
    v1 = l1 / 2 * _n(p1); v2 = l1 * _n(p1) + l2 / 2 * _n(p2) * r2
    v3 = l1 * _n(p1) + l2 * _n(p2) * r2 + l3 / 2 * _n(p3) * r3
    m = (m1 * v1 @ v1 + m2 * v2 @ v2 + m3 * v3 @ v3
         + (m1 * l1**2 + m2 * l2**2 * r2**2 + m3 * l3**2 * r3**2) / 12)
    y1 = l1 / 2 * np.sin(p1); y2 = l1 * np.sin(p1) + l2 / 2 * np.sin(p2)
    y3 = l1 * np.sin(p1) + l2 * np.sin(p2) + l3 / 2 * np.sin(p3)
    return m, G * (m1 * y1 + m2 * y2 + m3 * y3)


def _d(f, x, h=1e-4):
    """Five-point central difference (error O(h^4))."""
    return (f(x - 2 * h) - 8 * f(x - h) + 8 * f(x + h) - f(x + 2 * h)) / (12 * h)


def lagrange_reference(mass_potential, p0, w0, t_end):
    """Lagrange's equation in one coordinate p with generalised mass m(p) and potential V(p),
    m p'' + m'(p) p'^2 / 2 + V'(p) = 0, integrated by DOP853 at 1e-12."""
    def rhs(t, y):
        p, w = y
        m, _ = mass_potential(p)
        dm = _d(lambda x: mass_potential(x)[0], p)
        dv = _d(lambda x: mass_potential(x)[1], p)
        return [w, -(0.5 * dm * w**2 + dv) / m]
    return solve_ivp(rhs, (0, t_end), [p0, w0], rtol=1e-12, atol=1e-12, method="DOP853", dense_output=True)


def fourbar_reference(p0, w0, t_end):
    return lagrange_reference(fourbar_mass_potential, p0, w0, t_end)


def rod(name, length, mass):
    i = mass * length**2 / 12
    return (f"&body name = '{name}', kind = 'rigid', mass = {mass!r}, com = {length / 2!r}, 0.0, 0.0, "
            f"inertia = 1.0e-4, {i!r}, {i!r}, 0.0, 0.0, 0.0 /\n")


def fourbar_scene(p0, w0, t_end=2.0, integrator="adaptive = .true., rtol = 1.0e-10, atol = 1.0e-12", cut="revolute"):
    """The four-bar as a tree crank -> coupler -> rocker (relative angles) closed by the
    revolute 'D' from the rocker's end to the ground; q0 and qd0 from the closed form."""
    p2, p3, r2, r3 = fourbar_angles(p0)
    q = [float(x) for x in (p0, p2 - p0, p3 - p2)]
    qd = [float(x) for x in (w0, (r2 - 1) * w0, (r3 - r2) * w0)]
    (l1, _), (l2, _), (l3, _) = [(l, m) for _, l, m in LINKS]
    return (f"&scene title = 'four-bar', t_end = {t_end}, gravity = 0.0, -9.81, 0.0 /\n"
            f"&integrator method = 'single', h_slow = 1.0e-3, {integrator} /\n"
            "&effects gravity = .true. /\n&body name = 'ground', kind = 'ground' /\n"
            + "".join(rod(*link) for link in LINKS)
            + f"&joint name = 'A', kind = 'revolute', parent = 'ground', child = 'crank', q0 = {q[0]!r}, "
            f"qd0 = {qd[0]!r} /\n"
            f"&joint name = 'B', kind = 'revolute', parent = 'crank', child = 'coupler', at = {l1!r}, 0.0, 0.0, "
            f"q0 = {q[1]!r}, qd0 = {qd[1]!r} /\n"
            f"&joint name = 'C', kind = 'revolute', parent = 'coupler', child = 'rocker', at = {l2!r}, 0.0, 0.0, "
            f"q0 = {q[2]!r}, qd0 = {qd[2]!r} /\n"
            f"&joint name = 'D', kind = '{cut}', parent = 'ground', child = 'rocker', at = {L0!r}, 0.0, 0.0, "
            f"child_at = {l3!r}, 0.0, 0.0 /\n"
            f"&marker name = 'tip', body = 'rocker', at = {l3!r}, 0.0, 0.0 /\n"
            "&output dt = 0.01, quantities = 'coordinates', 'markers', 'reactions', 'energy' /\n")


@pytest.fixture(scope="module", params=["revolute", "spherical"])
def fourbar(tmp_path_factory, request):
    """The four-bar closed by a revolute (5 rows, 3 redundant) or a spherical joint (3 rows,
    1 redundant: the tree's revolutes keep it planar)."""
    d = tmp_path_factory.mktemp("fourbar")
    (d / "fourbar.nml").write_text(fourbar_scene(1.0, 2.0, cut=request.param))
    return pymr.run(d / "fourbar.nml", d / "fourbar.csv"), d


def test_the_fourbar_follows_the_minimal_coordinate_solution(fourbar):
    """Crank angle against the one-coordinate Lagrange solution to 1e-6 rad over 2 s at rtol
    1e-10 (measured 1.3e-8), and the other two joints against the closed-form loop."""
    res, _ = fourbar
    ref = fourbar_reference(1.0, 2.0, 2.0)
    p1 = ref.sol(res["t"])[0]
    assert np.abs(res["A.q"] - p1).max() < 1e-6
    # the crank swings through 5.6 rad: the test spans most of the loop's positions
    assert np.ptp(res["A.q"]) > 5.0
    p2, p3 = np.array([fourbar_angles(p)[:2] for p in res["A.q"]]).T
    wrap = lambda a: (a + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(wrap(res["A.q"] + res["B.q"] - p2)).max() < 1e-8
    assert np.abs(wrap(res["A.q"] + res["B.q"] + res["C.q"] - p3)).max() < 1e-8


def test_the_fourbar_loop_stays_closed(fourbar):
    """The rocker's end stays on the ground pivot (1, 0, 0) to 1e-8 m (measured 1e-11), and
    its velocity stays 0."""
    res, _ = fourbar
    gap = np.column_stack([res["tip.x"] - L0, res["tip.y"], res["tip.z"]])
    assert np.abs(gap).max() < 1e-8
    vel = np.column_stack([res["tip.vx"], res["tip.vy"], res["tip.vz"]])
    assert np.abs(vel).max() < 1e-8 * np.abs(res["A.qd"]).max()


def test_the_fourbar_conserves_energy(fourbar):
    """Gravity only and the constraint forces do no work: the total energy stays at its start
    to 1e-8 of the largest kinetic energy (measured 4e-10)."""
    res, _ = fourbar
    e = res["energy.total"]
    assert np.abs(e - e[0]).max() < 1e-8 * res["energy.kinetic"].max()


def test_the_planar_loop_has_three_redundant_rows(fourbar):
    """A planar loop of 3-D joints: of the cut revolute's 5 rows (point 3, axis 2) or the
    spherical's 3 only the 2 in-plane point rows are independent; the multipliers of the
    dropped rows are 0 (no out-of-plane force, no moment at the cut).""" 
    res, d = fourbar
    for c in ("fz", "mx", "my", "mz"):
        assert np.abs(res[f"D.{c}"]).max() < 1e-9, c


def test_the_summary_reports_redundant_rows_and_assembly(tmp_path, mrsim):
    import subprocess
    (tmp_path / "f.nml").write_text(fourbar_scene(1.0, 2.0, t_end=0.1))
    r = subprocess.run([mrsim, "f.nml", "-o", "f.csv"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "loops: 1 closing joints, 5 constraint rows, 3 redundant (dropped)" in r.stdout
    loops = json.loads((tmp_path / "f.json").read_text())["loops"]
    assert (loops["closing_joints"], loops["constraint_rows"], loops["redundant_rows"]) == (1, 5, 3)
    assert loops["assembly_change_q"] < 1e-12       # the given state was closed to rounding
    (tmp_path / "s.nml").write_text(fourbar_scene(1.0, 2.0, t_end=0.1, cut="spherical"))
    r = subprocess.run([mrsim, "s.nml", "-o", "s.csv"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert "loops: 1 closing joints, 3 constraint rows, 1 redundant (dropped)" in r.stdout


def test_the_closure_error_a_step_leaves_is_reported_and_falls_as_the_local_error(tmp_path, mrsim):
    """The statistics report the largest constraint residual a projection removed
    ('closure_drift'): the drift of one fixed ABM step, the position's local error, O(h^5)
    (measured 4.9e-8, 1.5e-9, 4.8e-11 m at h = 2, 1, 0.5 ms: order 5.00, 5.00)."""
    import subprocess
    (tmp_path / "f.nml").write_text(fourbar_scene(1.0, 2.0))
    drift = []
    for h in (2e-3, 1e-3, 5e-4):
        pymr.run(tmp_path / "f.nml", tmp_path / "f.csv", overrides={"integrator.adaptive": False, "integrator.h_slow": h})
        drift.append(json.loads((tmp_path / "f.json").read_text())["loops"]["closure_drift"])
    assert np.log2(np.array(drift[:-1]) / np.array(drift[1:])) == pytest.approx([5.0, 5.0], abs=0.3)
    r = subprocess.run([mrsim, "f.nml", "-o", "g.csv"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    line = next(x for x in r.stdout.splitlines() if x.startswith("loops: the largest closure error"))
    assert float(line.split(": ")[-1].split()[0]) == pytest.approx(
        json.loads((tmp_path / "g.json").read_text())["loops"]["closure_drift"], rel=1e-2)


def test_a_held_joint_keeps_its_given_state_and_the_others_close_the_loop(tmp_path):
    """The crank marked hold keeps q0 = 1 and qd0 = 2 exactly; the coupler and rocker angles,
    given 3e-4 and 2e-4 rad off, are moved onto the closed-form loop (to 1e-12 rad) and their
    rates onto its rates per unit crank rate (1e-12 rad/s). Without hold the least change
    moves the crank as well."""
    p2, p3, r2, r3 = fourbar_angles(1.0)
    qb, qc = float(p2 - 1.0), float(p3 - p2)
    text = fourbar_scene(1.0, 2.0, t_end=0.01)
    text = text.replace(f"q0 = {qb!r}", f"q0 = {qb + 3e-4!r}").replace(f"q0 = {qc!r}", f"q0 = {qc - 2e-4!r}")
    (tmp_path / "free.nml").write_text(text)
    (tmp_path / "held.nml").write_text(text.replace("child = 'crank', q0", "child = 'crank', hold = .true., q0"))
    res = pymr.run(tmp_path / "held.nml", tmp_path / "held.csv")
    assert res["A.q"][0] == 1.0 and res["A.qd"][0] == 2.0
    assert abs(res["B.q"][0] - qb) < 1e-12 and abs(res["C.q"][0] - qc) < 1e-12
    assert abs(res["B.qd"][0] - (r2 - 1) * 2.0) < 1e-12 and abs(res["C.qd"][0] - (r3 - r2) * 2.0) < 1e-12
    free = pymr.run(tmp_path / "free.nml", tmp_path / "free.csv")
    assert abs(free["A.q"][0] - 1.0) > 1e-5


def test_given_initial_state_is_assembled_by_least_change(tmp_path):
    """q0 off the loop by 1e-4 rad (within the tolerance of 1e-3 of the loop's size) and a
    crank rate only: the run starts on the loop (closed to 1e-8 m) with the rates of the
    closed form for the crank rate the velocity projection leaves."""
    text = fourbar_scene(1.0, 2.0, t_end=0.01)
    p2, p3, r2, r3 = fourbar_angles(1.0)
    text = text.replace(f"q0 = {float(p3 - p2)!r}", f"q0 = {float(p3 - p2) + 1e-4!r}")
    assert f"q0 = {float(p3 - p2) + 1e-4!r}" in text
    (tmp_path / "f.nml").write_text(text)
    res = pymr.run(tmp_path / "f.nml", tmp_path / "f.csv")
    assert abs(res["tip.x"][0] - L0) < 1e-8 and abs(res["tip.y"][0]) < 1e-8
    w = res["A.qd"][0]
    q2, q3, s2, s3 = fourbar_angles(res["A.q"][0])
    assert abs(res["B.qd"][0] - (s2 - 1) * w) < 1e-8 and abs(res["C.qd"][0] - (s3 - s2) * w) < 1e-8


@pytest.mark.parametrize("kind", ["revolute", "spherical"])
def test_a_hanging_parallelogram_at_rest_carries_the_hand_calculated_loads(tmp_path, kind):
    """Two 0.5 m cranks hang straight down from pivots 1 m apart, a 1 m coupler between
    their lower ends; the right crank closes the loop at its top pivot. At rest under
    gravity (equilibrium) the cranks pass no horizontal force (a moment about each pivot),
    the coupler hangs half on each crank, so the cut pivot carries the right crank's weight
    and half the coupler's: f = (m3 + m2/2) g up, along the right crank's x axis (it points
    up); the left pivot (a tree joint, whose reaction counts the cut's force) likewise
    (m1 + m2/2) g, along its crank's -x. No other component. The loop stays at rest."""
    m1, m2, m3 = 1.0, 2.0, 1.5
    text = ("&scene title = 'hanging parallelogram', t_end = 0.5, gravity = 0.0, -9.81, 0.0 /\n"
            "&integrator method = 'single', h_slow = 1.0e-3 /\n&effects gravity = .true. /\n"
            "&body name = 'ground', kind = 'ground' /\n"
            + rod("left", 0.5, m1) + rod("coupler", 1.0, m2) + rod("right", 0.5, m3)
            + "&joint name = 'A', kind = 'revolute', parent = 'ground', child = 'left', q0 = -1.5707963267948966 /\n"
            "&joint name = 'B', kind = 'revolute', parent = 'left', child = 'coupler', at = 0.5, 0.0, 0.0, "
            "q0 = 1.5707963267948966 /\n"
            "&joint name = 'C', kind = 'revolute', parent = 'coupler', child = 'right', at = 1.0, 0.0, 0.0, "
            "q0 = 1.5707963267948966 /\n"
            f"&joint name = 'D', kind = '{kind}', parent = 'ground', child = 'right', at = 1.0, 0.0, 0.0, "
            "child_at = 0.5, 0.0, 0.0 /\n"
            "&output dt = 0.05, quantities = 'coordinates', 'reactions' /\n")
    (tmp_path / "p.nml").write_text(text)
    res = pymr.run(tmp_path / "p.nml", tmp_path / "p.csv")
    assert np.abs(res["A.q"] + np.pi / 2).max() < 1e-9
    assert np.abs(res["D.fx"] - (m3 + m2 / 2) * G).max() < 1e-9 * G
    assert np.abs(res["A.fx"] + (m1 + m2 / 2) * G).max() < 1e-9 * G
    for c in ("fy", "fz", "mx", "my", "mz"):
        assert np.abs(res[f"D.{c}"]).max() < 1e-9, c
        assert np.abs(res[f"A.{c}"]).max() < 1e-9, c


def weld_scene(loop: bool, t_end=2.0, th0=1.0, wd0=1.5):
    """A pendulum arm (1 m, 1 kg) carrying a block at its end, 3-D mass distribution (its
    centre of mass off the plane of swing). As a tree: the block on the arm by a 'fixed'
    joint. As a loop: the block on its own 'free' joint from the ground, welded to the arm's
    end by a loop-closing 'fixed' joint named like the tree's."""
    c, s = np.cos(th0), np.sin(th0)
    head = ("&scene title = 'welded block', t_end = %r, gravity = 0.0, -9.81, 0.0 /\n"
            "&integrator method = 'single', h_slow = 1.0e-3, adaptive = .true., rtol = 1.0e-10, atol = 1.0e-12 /\n"
            "&effects gravity = .true. /\n&body name = 'ground', kind = 'ground' /\n" % t_end
            + rod("arm", 1.0, 1.0)
            + "&body name = 'block', kind = 'rigid', mass = 2.0, com = 0.1, 0.05, 0.2, "
              "inertia = 0.02, 0.025, 0.03, 0.001, 0.0, 0.002 /\n"
            + f"&joint name = 'pivot', kind = 'revolute', parent = 'ground', child = 'arm', q0 = {th0!r}, "
              f"qd0 = {wd0!r} /\n")
    if loop:
        joints = (f"&joint name = 'float', kind = 'free', parent = 'ground', child = 'block', "
                  f"q0 = {float(c)!r}, {float(s)!r}, 0.0, 0.0, 0.0, {th0!r}, "
                  f"qd0 = {float(-s * wd0)!r}, {float(c * wd0)!r}, 0.0, 0.0, 0.0, {wd0!r} /\n"
                  "&joint name = 'weld', kind = 'fixed', parent = 'arm', child = 'block', at = 1.0, 0.0, 0.0, "
                  "child_at = 0.0, 0.0, 0.0 /\n")
    else:
        joints = "&joint name = 'weld', kind = 'fixed', parent = 'arm', child = 'block', at = 1.0, 0.0, 0.0 /\n"
    return head + joints + "&output dt = 0.01, quantities = 'coordinates', 'reactions', 'energy' /\n"


def test_a_fixed_cut_welds_like_a_fixed_tree_joint(tmp_path):
    """The welded block swings as the tree with a 'fixed' joint does (arm angle to 1e-7 rad
    over 2 s), the weld's force and moment (the loop's multipliers) equal the tree joint's
    reaction (Newton-Euler on the block) to 1e-6 of the weight, the block's six free
    coordinates stay on the arm's end, and the energy is conserved."""
    (tmp_path / "tree.nml").write_text(weld_scene(False))
    (tmp_path / "loop.nml").write_text(weld_scene(True))
    tree = pymr.run(tmp_path / "tree.nml", tmp_path / "tree.csv")
    loop = pymr.run(tmp_path / "loop.nml", tmp_path / "loop.csv")
    assert np.abs(loop["pivot.q"] - tree["pivot.q"]).max() < 1e-7
    assert np.ptp(tree["pivot.q"]) > 1.0
    weight = 2.0 * G
    for c in ("fx", "fy", "fz", "mx", "my", "mz"):
        assert np.abs(loop[f"weld.{c}"] - tree[f"weld.{c}"]).max() < 1e-6 * weight, c
    # the weld carries an out-of-plane moment (the block's centre of mass is off the plane)
    assert np.abs(tree["weld.mx"]).max() > 0.1 * weight * 0.2
    th = loop["pivot.q"]
    assert np.abs(loop["float.q1"] - np.cos(th)).max() < 1e-8 and np.abs(loop["float.q2"] - np.sin(th)).max() < 1e-8
    assert np.abs(loop["float.q6"] - th).max() < 1e-8
    e = loop["energy.total"]
    assert np.abs(e - e[0]).max() < 1e-8 * loop["energy.kinetic"].max()


def test_fixed_steps_converge_on_the_fourbar(tmp_path):
    """Fixed-step ABM4 with the projection after each step: at h = 5e-4 s the crank angle is
    within 1e-7 rad of the minimal-coordinate solution (measured 7.5e-9), halving the step
    from 1e-3 s cuts the error by more than 8 (measured 32), and the loop stays closed to
    1e-10 m."""
    ref = fourbar_reference(1.0, 2.0, 2.0)
    (tmp_path / "f.nml").write_text(fourbar_scene(1.0, 2.0, integrator="adaptive = .false."))
    err = {}
    for h in (1e-3, 5e-4):
        res = pymr.run(tmp_path / "f.nml", tmp_path / "f.csv", overrides={"integrator.h_slow": h})
        err[h] = np.abs(res["A.q"] - ref.sol(res["t"])[0]).max()
        assert np.abs(res["tip.y"]).max() < 1e-10 and np.abs(res["tip.x"] - L0).max() < 1e-10
    assert err[5e-4] < 1e-7 and err[1e-3] / err[5e-4] > 8


@pytest.mark.parametrize("over", [{"integrator.adaptive": False}, {}], ids=["fixed", "adaptive"])
def test_a_restarted_loop_run_equals_the_uninterrupted_one(tmp_path, over):
    """The projection lives in the steppers' state: a run stopped after its checkpoint at
    0.6 s and restarted gives the uninterrupted run's rows (to 1e-10) and step counts."""
    scene = tmp_path / "f.nml"
    scene.write_text(fourbar_scene(1.0, 2.0, t_end=1.0))
    full = pymr.run(scene, tmp_path / "full.csv", overrides=over)
    out = tmp_path / "job.csv"
    pymr.run(scene, out, overrides={**over, "scene.t_end": 0.75, "output.checkpoint_dt": 0.3})
    res = pymr.run(scene, out, overrides={**over, "output.checkpoint_dt": 0.3}, restart=tmp_path / "job.ckpt")
    assert np.array_equal(res.t, full.t)
    assert np.abs(res.data - full.data).max() <= 1e-10 * np.abs(full.data).max()
    for key in ("steps_slow", "rhs_full", "rejected_steps", "rows"):
        assert res.stats[key] == full.stats[key], key


# crank-slider: crank r, connecting rod l (uniform rods), slider of mass ms on a prismatic
# joint along the ground's x axis; the rod's end pinned to the slider closes the loop
R_CRANK, L_ROD, M_CRANK, M_ROD, M_SLIDER = 0.3, 1.0, 1.0, 2.0, 3.0


def crank_slider_geometry(th):
    """Rod angle phi, slider position x and their rates per unit crank rate (closed form:
    the rod's end stays on the x axis, r sin th + l sin phi = 0)."""
    phi = np.arcsin(-R_CRANK * np.sin(th) / L_ROD)
    dphi = -R_CRANK * np.cos(th) / (L_ROD * np.cos(phi))
    x = R_CRANK * np.cos(th) + L_ROD * np.cos(phi)
    dx = -R_CRANK * np.sin(th) - L_ROD * np.sin(phi) * dphi
    return phi, x, dphi, dx


def crank_slider_mass_potential(th):
    phi, x, dphi, dx = crank_slider_geometry(th)
    vc1 = R_CRANK / 2 * _n(th)
    vc2 = R_CRANK * _n(th) + L_ROD / 2 * _n(phi) * dphi
    m = (M_CRANK * vc1 @ vc1 + M_CRANK * R_CRANK**2 / 12 + M_ROD * vc2 @ vc2 + M_ROD * L_ROD**2 / 12 * dphi**2
         + M_SLIDER * dx**2)
    v = G * (M_CRANK * R_CRANK / 2 * np.sin(th) + M_ROD * (R_CRANK * np.sin(th) + L_ROD / 2 * np.sin(phi)))
    return m, v


def crank_slider_head(title: str, th0: float, w0: float) -> str:
    """The crank-slider scene up to the slider's joints: crank at angle th0 turning at w0 and
    the rod on the loop (adaptive Adams at rtol 1e-10, gravity)."""
    phi, _, dphi, _ = crank_slider_geometry(th0)
    return (f"&scene title = '{title}', t_end = 2.0, gravity = 0.0, -9.81, 0.0 /\n"
            "&integrator method = 'single', h_slow = 1.0e-3, adaptive = .true., rtol = 1.0e-10, atol = 1.0e-12 /\n"
            "&effects gravity = .true. /\n&body name = 'ground', kind = 'ground' /\n"
            + rod("crank", R_CRANK, M_CRANK) + rod("rod", L_ROD, M_ROD)
            + f"&body name = 'slider', kind = 'rigid', mass = {M_SLIDER!r}, inertia = 1.0e-3, 1.0e-3, 1.0e-3, 0.0, 0.0, 0.0 /\n"
            f"&joint name = 'crank', kind = 'revolute', parent = 'ground', child = 'crank', q0 = {th0!r}, qd0 = {w0!r} /\n"
            f"&joint name = 'elbow', kind = 'revolute', parent = 'crank', child = 'rod', at = {R_CRANK!r}, 0.0, 0.0, "
            f"q0 = {float(phi - th0)!r}, qd0 = {float((dphi - 1) * w0)!r} /\n")


def slider_joints(th0: float, w0: float) -> tuple[str, str]:
    """The slider's two joints, wrist (rod to slider) and slide (ground to slider), in the two
    formulations: the loop cut at the slide (a prismatic cut), or the slide a tree joint and
    the loop cut at the wrist."""
    phi, x, dphi, dx = crank_slider_geometry(th0)
    cut = (f"&joint name = 'wrist', kind = 'revolute', parent = 'rod', child = 'slider', at = {L_ROD!r}, 0.0, 0.0, "
           f"q0 = {float(-phi)!r}, qd0 = {float(-dphi * w0)!r} /\n"
           "&joint name = 'slide', kind = 'prismatic', parent = 'ground', child = 'slider', axis = 1.0, 0.0, 0.0, "
           "child_at = 0.0, 0.0, 0.0 /\n")
    tree = (f"&joint name = 'slide', kind = 'prismatic', parent = 'ground', child = 'slider', axis = 1.0, 0.0, 0.0, "
            f"q0 = {float(x)!r}, qd0 = {float(dx * w0)!r} /\n"
            f"&joint name = 'wrist', kind = 'revolute', parent = 'rod', child = 'slider', at = {L_ROD!r}, 0.0, 0.0, "
            "child_at = 0.0, 0.0, 0.0 /\n")
    return cut, tree


def test_the_crank_slider_follows_the_minimal_coordinate_solution(tmp_path):
    """A prismatic tree joint in the loop: crank angle and slider position against the
    one-coordinate Lagrange solution over 2 s (1e-6 rad, 1e-6 m), the rod's end on the slider
    to 1e-8 m, energy constant."""
    th0, w0 = 0.5, 6.0
    phi, x, dphi, dx = crank_slider_geometry(th0)
    text = (crank_slider_head("crank-slider", th0, w0)
            + f"&joint name = 'slide', kind = 'prismatic', parent = 'ground', child = 'slider', axis = 1.0, 0.0, 0.0, "
            f"q0 = {float(x)!r}, qd0 = {float(dx * w0)!r} /\n"
            f"&joint name = 'wrist', kind = 'revolute', parent = 'rod', child = 'slider', at = {L_ROD!r}, 0.0, 0.0, "
            "child_at = 0.0, 0.0, 0.0 /\n"
            f"&marker name = 'end', body = 'rod', at = {L_ROD!r}, 0.0, 0.0 /\n"
            "&output dt = 0.01, quantities = 'coordinates', 'markers', 'energy' /\n")
    (tmp_path / "cs.nml").write_text(text)
    res = pymr.run(tmp_path / "cs.nml", tmp_path / "cs.csv")

    ref = lagrange_reference(crank_slider_mass_potential, th0, w0, 2.0)
    th = ref.sol(res["t"])[0]
    assert np.ptp(res["crank.q"]) > 2 * np.pi                 # the crank turns over
    assert np.abs(res["crank.q"] - th).max() < 1e-6
    assert np.abs(res["slide.q"] - np.array([crank_slider_geometry(p)[1] for p in th])).max() < 1e-6
    assert np.abs(res["end.x"] - res["slide.q"]).max() < 1e-8 and np.abs(res["end.y"]).max() < 1e-8
    e = res["energy.total"]
    assert np.abs(e - e[0]).max() < 1e-8 * res["energy.kinetic"].max()


def _rot(axis, a):
    c, s = np.cos(a), np.sin(a)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3); r[i, i] = r[j, j] = c; r[i, j] = -s; r[j, i] = s
    return r


def _xyz_angles(r):
    """Angles (a, b, c) of r = Rx(a) Ry(b) Rz(c) (the spherical joint's coordinates)."""
    return [float(np.arctan2(-r[1, 2], r[2, 2])), float(np.arcsin(r[0, 2])), float(np.arctan2(-r[0, 1], r[0, 0]))]


def rssr_scene(cut_at_rocker_pivot: bool):
    """A spatial RSSR loop under gravity along -z: crank about z at the origin, coupler on
    spherical joints, rocker about y at D. Closed either at the rocker's pivot (a cut
    revolute; the rocker's frame at C) or at the coupler-rocker ball (a cut spherical; the
    rocker's frame at D, a tree revolute). Same bodies, same start at rest."""
    r1, l3, d, th0, psi0 = 0.3, 0.6, np.array([0.8, 0.3, 0.2]), 0.4, 0.9
    b = _rot(2, th0) @ [r1, 0, 0]
    rr = _rot(1, psi0); c = d - rr @ [l3, 0, 0]
    l2 = float(np.linalg.norm(c - b)); u = _rot(2, th0).T @ (c - b) / l2
    rc = _rot(2, th0) @ _rot(1, np.arctan2(-u[2], u[0])) @ _rot(2, np.arcsin(u[1]))
    sc, sr = _xyz_angles(_rot(2, th0).T @ rc), _xyz_angles(rc.T @ rr)
    fmt = lambda v: ", ".join(repr(float(x)) for x in v)
    text = ("&scene title = 'RSSR', t_end = 2.0, gravity = 0.0, 0.0, -9.81 /\n"
            "&integrator method = 'single', h_slow = 1.0e-3, adaptive = .true., rtol = 1.0e-12, atol = 1.0e-14 /\n"
            "&effects gravity = .true. /\n&body name = 'ground', kind = 'ground' /\n"
            + rod("crank", r1, 1.0) + rod("coupler", l2, 2.0))
    i3 = 1.5 * l3**2 / 12
    if cut_at_rocker_pivot:
        text += (f"&body name = 'rocker', kind = 'rigid', mass = 1.5, com = {l3 / 2!r}, 0.0, 0.0, "
                 f"inertia = 1.0e-4, {i3!r}, {i3!r}, 0.0, 0.0, 0.0 /\n")
    else:
        text += (f"&body name = 'rocker', kind = 'rigid', mass = 1.5, com = {-l3 / 2!r}, 0.0, 0.0, "
                 f"inertia = 1.0e-4, {i3!r}, {i3!r}, 0.0, 0.0, 0.0 /\n")
    text += (f"&joint name = 'crank', kind = 'revolute', parent = 'ground', child = 'crank', q0 = {th0!r} /\n"
             f"&joint name = 'ball1', kind = 'spherical', parent = 'crank', child = 'coupler', at = {r1!r}, 0.0, 0.0, "
             f"q0 = {fmt(sc)} /\n")
    if cut_at_rocker_pivot:
        text += (f"&joint name = 'ball2', kind = 'spherical', parent = 'coupler', child = 'rocker', at = {l2!r}, 0.0, 0.0, "
                 f"q0 = {fmt(sr)} /\n"
                 f"&joint name = 'pivot', kind = 'revolute', parent = 'ground', child = 'rocker', at = {fmt(d)}, "
                 f"axis = 0.0, 1.0, 0.0, child_at = {l3!r}, 0.0, 0.0 /\n"
                 f"&marker name = 'c', body = 'rocker', at = 0.0, 0.0, 0.0 /\n")
    else:
        text += (f"&joint name = 'pivot', kind = 'revolute', parent = 'ground', child = 'rocker', at = {fmt(d)}, "
                 f"axis = 0.0, 1.0, 0.0, q0 = {psi0!r} /\n"
                 f"&joint name = 'ball2', kind = 'spherical', parent = 'coupler', child = 'rocker', at = {l2!r}, 0.0, 0.0, "
                 f"child_at = {-l3!r}, 0.0, 0.0 /\n"
                 f"&marker name = 'c', body = 'rocker', at = {-l3!r}, 0.0, 0.0 /\n")
    return text + "&output dt = 0.01, quantities = 'coordinates', 'markers', 'energy' /\n"


def test_an_rssr_loop_moves_alike_whichever_joint_closes_it(tmp_path):
    """The spatial RSSR four-bar as two different trees (cut at the rocker's revolute, or at
    the coupler-rocker ball): the crank angle and the ball's path agree to 1e-8 over 2 s at
    rtol 1e-12 (measured 2.6e-10; integration error: 1.4e-7 at rtol 1e-10, 9.8e-9 at 1e-11,
    measured before the cut rows were turned into the parent's axes), each loop stays closed
    (the ball on the coupler's end, the rocker on its pivot), and the energy is conserved."""
    res = {}
    for cut in (True, False):
        (tmp_path / f"r{cut}.nml").write_text(rssr_scene(cut))
        res[cut] = pymr.run(tmp_path / f"r{cut}.nml", tmp_path / f"r{cut}.csv")
        e = res[cut]["energy.total"]
        assert np.abs(e - e[0]).max() < 1e-8 * res[cut]["energy.kinetic"].max()
    a, b = res[True], res[False]
    assert np.ptp(a["crank.q"]) > 1.0                          # it moves far
    assert np.abs(a["crank.q"] - b["crank.q"]).max() < 1e-8
    for x in "xyz":
        assert np.abs(a[f"c.{x}"] - b[f"c.{x}"]).max() < 1e-8, x
    # the ball stays 0.6 m from the rocker's pivot on the circle normal to its axis
    p = np.column_stack([a[f"c.{x}"] for x in "xyz"]) - [0.8, 0.3, 0.2]
    assert np.abs(np.linalg.norm(p, axis=1) - 0.6).max() < 1e-8 and np.abs(p[:, 1]).max() < 1e-8


def test_model_accelerations_of_a_loop_are_the_constrained_ones(tmp_path):
    """pymr.model_accelerations on the four-bar (rows chosen at the first evaluation): the
    crank's acceleration is the one-coordinate Lagrange equation's, and the other joints'
    follow the closed-form loop's second derivative (to 1e-6 of the crank's)."""
    scene = tmp_path / "f.nml"
    scene.write_text(fourbar_scene(1.0, 2.0))
    text = scene.read_text()
    p2, p3, r2, r3 = fourbar_angles(1.0)
    q = [1.0, float(p2 - 1.0), float(p3 - p2)]
    qd = [2.0, float((r2 - 1) * 2.0), float((r3 - r2) * 2.0)]
    qdd = pymr.model_accelerations(scene, 0.0, np.array(q), np.array(qd))
    m, _ = fourbar_mass_potential(1.0)
    dm = _d(lambda x: fourbar_mass_potential(x)[0], 1.0); dv = _d(lambda x: fourbar_mass_potential(x)[1], 1.0)
    a1 = -(0.5 * dm * 4.0 + dv) / m
    assert abs(qdd[0] - a1) < 1e-8 * abs(a1)
    # phi_i'' = r_i' w^2 + r_i a1 (r_i the rate per unit crank rate, r_i' its derivative)
    dr2 = _d(lambda x: fourbar_angles(x)[2], 1.0); dr3 = _d(lambda x: fourbar_angles(x)[3], 1.0)
    a2 = dr2 * 4.0 + r2 * a1; a3 = dr3 * 4.0 + r3 * a1
    assert abs(qdd[1] - (a2 - a1)) < 1e-6 * abs(a1) and abs(qdd[2] - (a3 - a2)) < 1e-6 * abs(a1)


def flexible_coupler_scene(tmp_path):
    """The four-bar with its coupler an aluminium tube beam (1 m, 2 + 1 bending modes, no
    damping) of the rigid coupler's mass; the loop is closed at the rigid rocker, so the
    flexible body lies inside the loop (its modal columns enter the constraint rows)."""
    mc = 2700.0 * np.pi * (0.02**2 - 0.015**2) * 1.0
    links = [("crank", 0.4, 1.0), ("coupler", 1.0, mc), ("rocker", 0.7, 1.5)]
    beam = ("&body name = 'coupler', kind = 'beam', length = 1.0, youngs_modulus = 7.0e10, density = 2700.0, "
            "r_outer = 0.02, r_inner = 0.015, n_elements = 10, modes_y = 2, modes_z = 1 /\n")
    saved = LINKS[:]
    LINKS[:] = links
    try:
        text = fourbar_scene(1.0, 2.0)
        ref = fourbar_reference(1.0, 2.0, 2.0)
    finally:
        LINKS[:] = saved
    lines = [beam if line.startswith("&body name = 'coupler'") else line for line in text.splitlines(True)]
    (tmp_path / "flex.nml").write_text("".join(lines))
    return tmp_path / "flex.nml", ref


def test_a_flexible_coupler_keeps_the_loop_closed_and_tends_to_the_rigid_one(tmp_path):
    """Closed to 1e-8 m and energy (kinetic + gravity + strain) constant to 1e-8 of the peak
    kinetic energy (measured 9e-13); the crank angle's departure from the rigid four-bar's
    minimal-coordinate solution falls as 1/E (1.6e-3, 1.6e-4 rad at E = 7e10, 7e11)."""
    scene, ref = flexible_coupler_scene(tmp_path)
    err = {}
    for e_mod in (7e10, 7e11):
        res = pymr.run(scene, tmp_path / "flex.csv", overrides={"body[coupler].youngs_modulus": e_mod})
        assert np.abs(res["tip.x"] - L0).max() < 1e-8 and np.abs(res["tip.y"]).max() < 1e-8
        e = res["energy.total"]
        assert np.abs(e - e[0]).max() < 1e-8 * res["energy.kinetic"].max()
        assert res["energy.strain"].max() > 0                    # it does bend
        err[e_mod] = np.abs(res["A.q"] - ref.sol(res["t"])[0]).max()
    assert err[7e11] < 3e-4 and 7 < err[7e10] / err[7e11] < 13


def flexible_cut_scene(kind: str, side: str, arm: str | None = None) -> str:
    """A tube beam 'arm' (1 m; bending in both planes, stretching and twisting modes) on a
    spherical joint at the ground, and a block on a 'free' joint, joined at the arm's tip
    (a deforming point) by a cut joint of `kind`: the arm its parent (side 'parent') or its
    child ('child'). Both move, and the assembly puts the given rates on the loop. `arm`
    replaces the beam's &body line (a modal body)."""
    arm = arm or ("&body name = 'arm', kind = 'beam', length = 1.0, youngs_modulus = 7.0e9, density = 2700.0, "
                  "shear_modulus = 2.6e9, r_outer = 0.02, r_inner = 0.015, n_elements = 6, modes_y = 2, modes_z = 2, "
                  "modes_x = 1, modes_t = 1 /\n")
    if side == "parent":
        cut = "parent = 'arm', child = 'block', at = 1.0, 0.0, 0.0, child_at = 0.0, 0.0, 0.0"
    else:
        cut = "parent = 'block', child = 'arm', child_at = 1.0, 0.0, 0.0"
    return ("&scene title = 'cut at a flexible point', t_end = 0.02, gravity = 0.0, -9.81, 0.0 /\n"
            "&integrator method = 'single', h_slow = 1.0e-4, adaptive = .true., rtol = 1.0e-10, atol = 1.0e-12 /\n"
            "&effects gravity = .true. /\n&body name = 'ground', kind = 'ground' /\n" + arm
            + "&body name = 'block', kind = 'rigid', mass = 0.5, com = 0.05, 0.02, -0.03, "
              "inertia = 1.0e-3, 2.0e-3, 1.5e-3, 1.0e-4, 0.0, 2.0e-4 /\n"
              "&joint name = 'root', kind = 'spherical', parent = 'ground', child = 'arm', qd0 = 1.0, -0.5, 2.0 /\n"
              "&joint name = 'float', kind = 'free', parent = 'ground', child = 'block', q0 = 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, "
              "qd0 = 0.3, -0.2, 0.5, 1.0, 2.0, -1.5 /\n"
              f"&joint name = 'weld', kind = '{kind}', {cut}, axis = 0.3, 0.5, 0.8 /\n"
              "&marker name = 'tip', body = 'arm', at = 1.0, 0.0, 0.0 /\n"
              "&output dt = 0.01, quantities = 'coordinates', 'energy' /\n")


def check_rows_against_phi(scene, q, qd):
    """G against central differences of phi (steps 1e-6) and gamma against -d/dt (G qd)
    along q + t qd: the largest errors relative to the largest entry of G and of gamma."""
    phi, g, gam = pymr.loop_rows(scene, q, qd)
    eps = 1e-6
    gd = np.column_stack([(pymr.loop_rows(scene, q + eps * e, qd)[0] - pymr.loop_rows(scene, q - eps * e, qd)[0])
                          / (2 * eps) for e in np.eye(len(q))])
    gdot_qd = (pymr.loop_rows(scene, q + eps * qd, qd)[1] - pymr.loop_rows(scene, q - eps * qd, qd)[1]) @ qd / (2 * eps)
    return phi, g, np.abs(g - gd).max() / np.abs(g).max(), np.abs(gam + gdot_qd).max() / np.abs(gam).max()


@pytest.mark.parametrize("side", ["parent", "child"])
@pytest.mark.parametrize("kind", ["spherical", "revolute", "prismatic", "fixed"])
def test_the_rows_at_a_flexible_point_are_the_derivatives_of_phi(tmp_path, kind, side):
    """A cut at a beam's deforming tip, at a state of the run (closed, deflected, moving):
    G equals the derivative of phi (to 1e-7 of its largest entry; measured 7e-10) and gamma
    equals -Gdot qd (to 1e-8; measured 1e-10), where the arm's own modal columns carry a good
    part of G; and the run conserves the energy (kinetic + gravity + strain) to 1e-8 of the
    peak kinetic energy (measured 2e-9)."""
    scene = tmp_path / "cut.nml"
    scene.write_text(flexible_cut_scene(kind, side))
    res = pymr.run(scene, tmp_path / "cut.csv")
    q, qd = res.coordinates()
    n_joint = 3 + 6
    assert np.abs(q[-1, n_joint:]).max() > 1e-4 and np.abs(qd[-1, n_joint:]).max() > 1e-2   # it bends
    phi, g, g_err, gam_err = check_rows_against_phi(scene, q[-1], qd[-1])
    assert np.abs(phi).max() < 1e-12
    assert g_err < 1e-7 and gam_err < 1e-8
    assert np.abs(g[:, n_joint:]).max() > 0.1 * np.abs(g).max()
    e = res["energy.total"]
    assert np.abs(e - e[0]).max() < 1e-8 * res["energy.kinetic"].max()


def test_a_cut_at_a_modal_bodys_node(tmp_path):
    """The arm written to a modal file and read back as kind = 'modal': the cut sits on its
    tip node, and G and gamma are again phi's derivatives (1e-7, 1e-8); a point that is not
    one of the file's nodes is refused in one line, as for a tree joint."""
    beam = tmp_path / "beam.nml"
    beam.write_text(flexible_cut_scene("fixed", "parent"))
    pymr.write_modal_file(beam, "arm", tmp_path / "arm.modal")
    scene = tmp_path / "modal.nml"
    scene.write_text(flexible_cut_scene("fixed", "parent", "&body name = 'arm', kind = 'modal', modal_file = 'arm.modal' /\n"))
    res = pymr.run(scene, tmp_path / "modal.csv")
    q, qd = res.coordinates()
    _, _, g_err, gam_err = check_rows_against_phi(scene, q[-1], qd[-1])
    assert g_err < 1e-7 and gam_err < 1e-8
    scene.write_text(scene.read_text().replace("at = 1.0, 0.0, 0.0, child_at", "at = 0.95, 0.0, 0.0, child_at"))
    with pytest.raises(pymr.SceneError, match=r"modal\.nml:9: &joint 'weld': at: \(0\.95, 0, 0\) is not a point of "
                                              r"modal body 'arm'"):
        pymr.run(scene, tmp_path / "x.csv")


def coupler_cut_scene():
    """The flexible-coupler four-bar (flexible_coupler_scene's bodies and start) as another
    tree: crank and coupler from A, the rocker on its ground pivot D, and the loop closed by
    the revolute 'C' at the coupler's deforming end (the rocker's point 0.7 m out)."""
    mc = 2700.0 * np.pi * (0.02**2 - 0.015**2) * 1.0
    p2, p3, r2, r3 = fourbar_angles(1.0)
    return ("&scene title = 'four-bar cut at its flexible coupler', t_end = 2.0, gravity = 0.0, -9.81, 0.0 /\n"
            "&integrator method = 'single', h_slow = 1.0e-3, adaptive = .true., rtol = 1.0e-10, atol = 1.0e-12 /\n"
            "&effects gravity = .true. /\n&body name = 'ground', kind = 'ground' /\n"
            + rod("crank", 0.4, 1.0) + rod("rocker", 0.7, 1.5)
            + "&body name = 'coupler', kind = 'beam', length = 1.0, youngs_modulus = 7.0e10, density = 2700.0, "
              "r_outer = 0.02, r_inner = 0.015, n_elements = 10, modes_y = 2, modes_z = 1 /\n"
              "&joint name = 'A', kind = 'revolute', parent = 'ground', child = 'crank', q0 = 1.0, qd0 = 2.0 /\n"
              f"&joint name = 'B', kind = 'revolute', parent = 'crank', child = 'coupler', at = 0.4, 0.0, 0.0, "
              f"q0 = {float(p2 - 1.0)!r}, qd0 = {float((r2 - 1) * 2.0)!r} /\n"
              f"&joint name = 'D', kind = 'revolute', parent = 'ground', child = 'rocker', at = 1.0, 0.0, 0.0, "
              f"q0 = {float(p3 + np.pi)!r}, qd0 = {float(r3 * 2.0)!r} /\n"
              "&joint name = 'C', kind = 'revolute', parent = 'coupler', child = 'rocker', at = 1.0, 0.0, 0.0, "
              "child_at = 0.7, 0.0, 0.0 /\n"
              "&marker name = 'end', body = 'coupler', at = 1.0, 0.0, 0.0 /\n"
              "&marker name = 'tip', body = 'rocker', at = 0.7, 0.0, 0.0 /\n"
              "&output dt = 0.01, quantities = 'coordinates', 'markers', 'reactions', 'energy' /\n")


def test_a_fourbar_cut_at_its_flexible_couplers_end(tmp_path):
    """The loop closed at the coupler's deforming end: the coupler's end stays on the
    rocker's to 1e-8 m (measured 1e-13), the energy (kinetic + gravity + strain) is
    constant to 1e-8 of the peak kinetic energy (measured 1.1e-12), and the crank's
    departure from the rigid four-bar's minimal-coordinate solution falls as 1/E (1.6e-3,
    1.6e-4 rad at E = 70, 700 GPa: ratio 9.9). The same mechanism as the tree closed at the
    rigid rocker (flexible_coupler_scene, the rocker hung on the coupler's end by a tree
    revolute) moves alike: crank angle and modal coordinates to 1e-9 (measured 2e-11, 1e-12),
    and the cut's force on the rocker is the tree joint's reaction (to 1e-6 of its peak;
    the rockers' frames are turned by pi about z)."""
    scene = tmp_path / "cutc.nml"
    scene.write_text(coupler_cut_scene())
    tree, ref = flexible_coupler_scene(tmp_path)
    err = {}
    for e_mod in (7e10, 7e11):
        over = {"body[coupler].youngs_modulus": e_mod}
        res = pymr.run(scene, tmp_path / "cutc.csv", overrides=over)
        gap = np.column_stack([res[f"end.{x}"] - res[f"tip.{x}"] for x in "xyz"])
        assert np.abs(gap).max() < 1e-8
        e = res["energy.total"]
        assert np.abs(e - e[0]).max() < 1e-8 * res["energy.kinetic"].max()
        assert res["energy.strain"].max() > 1e-4
        err[e_mod] = np.abs(res["A.q"] - ref.sol(res["t"])[0]).max()
        other = pymr.run(tree, tmp_path / "tree.csv", overrides=over)
        assert np.abs(res["A.q"] - other["A.q"]).max() < 1e-9
        for k in range(1, 4):
            assert np.abs(res[f"coupler.a{k}"] - other[f"coupler.a{k}"]).max() < 1e-9
        peak = np.abs(other["C.fy"]).max()
        for c in ("fx", "fy"):
            assert np.abs(res[f"C.{c}"] + other[f"C.{c}"]).max() < 1e-6 * peak, c
    assert err[7e11] < 3e-4 and 7 < err[7e10] / err[7e11] < 13


# propped cantilever: a steel tube beam clamped at the ground, its tip pinned to the ground
PROP_L, PROP_W = 2.0, 7850.0 * np.pi * (0.03**2 - 0.025**2) * G


def propped_cantilever(n_elements: int, modes_y: int, kind: str = "spherical", start: str = "static",
                       t_end: float = 0.01, damping: str = "") -> str:
    """The beam (2 m; modes_y in-plane and 2 out-of-plane bending modes) clamped by the tree
    joint 'clamp' ('fixed' to the ground) and pinned at its tip by the cut 'pin' (axis z for
    a revolute); gravity along -y."""
    effects = ", modal_damping = .true." if damping else ""
    return (f"&scene title = 'propped cantilever', t_end = {t_end}, gravity = 0.0, -9.81, 0.0, start = '{start}' /\n"
            "&integrator method = 'single', h_slow = 1.0e-4, adaptive = .true., rtol = 1.0e-10, atol = 1.0e-12 /\n"
            f"&effects gravity = .true.{effects} /\n&body name = 'ground', kind = 'ground' /\n"
            f"&body name = 'beam', kind = 'beam', length = {PROP_L}, youngs_modulus = 2.1e11, density = 7850.0, "
            f"r_outer = 0.03, r_inner = 0.025, n_elements = {n_elements}, modes_y = {modes_y}, modes_z = 2{damping} /\n"
            "&joint name = 'clamp', kind = 'fixed', parent = 'ground', child = 'beam' /\n"
            f"&joint name = 'pin', kind = '{kind}', parent = 'ground', child = 'beam', at = {PROP_L}, 0.0, 0.0, "
            f"child_at = {PROP_L}, 0.0, 0.0, axis = 0.0, 0.0, 1.0 /\n"
            f"&marker name = 'tip', body = 'beam', at = {PROP_L}, 0.0, 0.0 /\n"
            "&output dt = 0.005, quantities = 'coordinates', 'markers', 'marker_accelerations', 'reactions', 'energy' /\n")


@pytest.mark.parametrize("kind", ["spherical", "revolute"])
def test_a_propped_cantilever_started_static_carries_three_eighths_of_its_weight_at_the_pin(tmp_path, kind):
    """A statically indeterminate beam: clamped, its tip pinned by a cut joint, started
    static (the modal coordinates in equilibrium on the loop). Euler-Bernoulli: the pin
    carries R = 3 w L / 8, the clamp 5 w L / 8 and the moment w L^2 / 8. Hermite elements
    with the consistent (Gauss-point) load are exact at the nodes, so with every in-plane
    mode of the mesh (modes_y = 2 n_elements) the reactions are exact: to 1e-10 (measured
    1.2e-13 at 4, 8 and 16 elements); truncated bases converge to it (pin: 3.7e-3, 5.7e-4,
    6.4e-5 with 2, 4, 8 of the 16 modes of 8 elements), each doubling gaining more than 5.
    The state is one of rest: zero accelerations at t = 0 (1e-10 m/s^2), the tip on its pin
    to 1e-12 m, the reaction steady."""
    exact = 3 * PROP_W * PROP_L / 8
    err = []
    for n_el, modes in [(8, 2), (8, 4), (8, 8), (8, 16), (4, 8), (16, 32)]:
        (tmp_path / "p.nml").write_text(propped_cantilever(n_el, modes, kind))
        res = pymr.run(tmp_path / "p.nml", tmp_path / "p.csv")
        rel = res["pin.fy"] / exact - 1
        if modes == 2 * n_el:
            assert np.abs(rel).max() < 1e-10, n_el
            assert np.abs(res["clamp.fy"] / (5 * PROP_W * PROP_L / 8) - 1).max() < 1e-10
            assert np.abs(res["clamp.mz"] / (PROP_W * PROP_L**2 / 8) - 1).max() < 1e-10
        else:
            err.append(abs(rel[0]))
        for c in ("fx", "fz", "mx", "my", "mz"):
            assert np.abs(res[f"pin.{c}"]).max() < 1e-9 * exact, c
        assert np.abs(np.column_stack([res["tip.x"] - PROP_L, res["tip.y"], res["tip.z"]])).max() < 1e-12
        q, qd = res.coordinates()
        assert np.abs(pymr.model_accelerations(tmp_path / "p.nml", 0.0, q[0], qd[0])).max() < 1e-10
        assert np.abs(res["tip.ay"]).max() < 1e-10
    assert err[0] > 5 * err[1] > 25 * err[2] and err[2] < 1e-4


def test_a_damped_propped_cantilever_comes_to_the_same_rest(tmp_path):
    """Started undeformed (at rest, not static) with modal damping 0.5, the propped
    cantilever (4 elements, every in-plane mode) rings down to the pin reaction 3 w L / 8:
    within 1e-6 after 0.2 s (measured 2e-8 at rtol 1e-8); the tip stays on its pin to
    1e-10 m; the energy lost to damping is the energy's fall (1e-8 of it)."""
    text = propped_cantilever(4, 8, start="rest", t_end=0.3, damping=", modal_damping = 0.5")
    text = text.replace("rtol = 1.0e-10, atol = 1.0e-12", "rtol = 1.0e-8, atol = 1.0e-10")
    (tmp_path / "d.nml").write_text(text)
    res = pymr.run(tmp_path / "d.nml", tmp_path / "d.csv")
    late = res["t"] >= 0.2
    assert np.abs(res["pin.fy"][late] / (3 * PROP_W * PROP_L / 8) - 1).max() < 1e-6
    assert abs(res["pin.fy"][1] / (3 * PROP_W * PROP_L / 8) - 1) > 1e-3          # it did ring
    assert np.abs(np.column_stack([res["tip.x"] - PROP_L, res["tip.y"], res["tip.z"]])).max() < 1e-10
    fall = res["energy.total"] - res["energy.total"][0]
    assert np.abs(fall + res["energy.damping_loss"]).max() < 1e-8 * np.abs(fall).max()


@pytest.mark.parametrize("base", ["fourbar", "tree"])
def test_a_free_cut_changes_nothing(tmp_path, mrsim, base):
    """A 'free' joint that closes a loop (between the crank and the rocker of the four-bar,
    or between the arm and the ground of the welded pendulum, a tree) imposes no
    constraint: every result equals the same scene's without it to 1e-12 (measured 0), its
    reaction columns are 0, and the summary and statistics say it closes no constraint."""
    import subprocess
    text = fourbar_scene(1.0, 2.0, t_end=0.5) if base == "fourbar" else weld_scene(False, t_end=0.5)
    free = ("&joint name = 'E', kind = 'free', parent = 'crank', child = 'rocker', at = 0.4, 0.0, 0.0, "
            "child_at = 0.0, 0.0, 0.0 /\n" if base == "fourbar"
            else "&joint name = 'E', kind = 'free', parent = 'ground', child = 'arm', child_at = 0.0, 0.0, 0.0 /\n")
    (tmp_path / "plain.nml").write_text(text)
    (tmp_path / "free.nml").write_text(text + free)
    plain = pymr.run(tmp_path / "plain.nml", tmp_path / "plain.csv")
    r = subprocess.run([mrsim, "free.nml", "-o", "free.csv"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    res = pymr.load_results(tmp_path / "free.csv")
    assert np.array_equal(res["t"], plain["t"])
    for c in plain.columns:
        assert np.abs(res[c] - plain[c]).max() <= 1e-12 * max(1.0, np.abs(plain[c]).max()), c
    for c in ("fx", "fy", "fz", "mx", "my", "mz"):
        assert np.abs(res[f"E.{c}"]).max() == 0.0, c
    rows = 5 if base == "fourbar" else 0
    assert f"loops: {1 + (base == 'fourbar')} closing joints (1 'free': no constraint), {rows} constraint rows" in r.stdout
    loops = json.loads((tmp_path / "free.json").read_text())["loops"]
    assert loops["free_closing_joints"] == 1 and loops["constraint_rows"] == rows


def sprung_fourbar_scene(settle=("A", "B", "C")) -> str:
    """The four-bar at rest at crank angle 1, a torsion spring (10 N m/rad, free at 1 rad)
    on the crank, started static with the joints `settle` marked settle."""
    text = fourbar_scene(1.0, 0.0, t_end=1.0).replace("&scene title = 'four-bar',",
                                                       "&scene title = 'four-bar', start = 'static',")
    text = text.replace("&effects gravity = .true. /", "&effects gravity = .true., joint_springs = .true. /")
    for j in settle:
        text = text.replace(f"&joint name = '{j}', kind = 'revolute',", f"&joint name = '{j}', kind = 'revolute', settle = .true.,")
    return text + "&spring joint = 'A', stiffness = 10.0, free_position = 1.0 /\n"


def test_a_static_start_settles_the_fourbar_at_its_potential_minimum(tmp_path):
    """The sprung four-bar started static with its joints marked settle: the crank angle is
    where the minimal-coordinate potential V(p) + k (p - 1)^2 / 2 is stationary (V the
    closed-form loop's gravity potential; the root of its derivative by scipy brentq,
    0.4824 rad) to 1e-10 rad (measured 3e-13), the other joints on the closed-form loop, the
    loop closed, the accelerations at t = 0 zero (1e-10) and the crank still over 1 s."""
    from scipy.optimize import brentq
    (tmp_path / "s.nml").write_text(sprung_fourbar_scene())
    res = pymr.run(tmp_path / "s.nml", tmp_path / "s.csv")
    dv = lambda p: _d(lambda x: fourbar_mass_potential(x)[1], p) + 10.0 * (p - 1.0)
    p_eq = brentq(dv, 0.3, 0.7, xtol=1e-15)
    assert abs(p_eq - 0.4824) < 1e-4                        # far from the start at 1 rad
    assert abs(res["A.q"][0] - p_eq) < 1e-10
    p2, p3, _, _ = fourbar_angles(res["A.q"][0])
    assert abs(res["B.q"][0] - (p2 - p_eq)) < 1e-10 and abs(res["C.q"][0] - (p3 - p2)) < 1e-10
    assert abs(res["tip.x"][0] - L0) < 1e-12 and abs(res["tip.y"][0]) < 1e-12
    q, qd = res.coordinates()
    assert np.abs(pymr.model_accelerations(tmp_path / "s.nml", 0.0, q[0], qd[0])).max() < 1e-10
    assert np.ptp(res["A.q"]) < 1e-9


def test_a_static_start_needs_the_loops_joints_to_settle(tmp_path):
    """Only the crank marked settle: the held coupler and rocker joints hold the loop, which
    is refused in one line naming what to do."""
    (tmp_path / "s.nml").write_text(sprung_fourbar_scene(settle=("A",)))
    with pytest.raises(pymr.SceneError, match=r"s\.nml:\d+: &scene: start: the coordinates to settle \(the modal ones and "
                       r"those of the joints marked settle\) move only 1 of the loops' 2 independent constraints: the "
                       r"joints held fast hold the loops \(mark settle every joint of a loop that should settle\)$"):
        pymr.run(tmp_path / "s.nml", tmp_path / "s.csv")


def test_a_prismatic_cut_closes_the_crank_slider(tmp_path):
    """The crank-slider with its slide as the loop-closing joint (a prismatic cut: two sliding
    rows and three frame rows) and the slider hung from the rod's end by a revolute tree
    joint: the crank angle against the one-coordinate Lagrange solution over 2 s (1e-6 rad),
    the slider on its line and level to 1e-8 (m, rad), energy constant, and the cut's force
    across the slide against the tree formulation's prismatic reaction (1e-5 of the peak)."""
    th0, w0 = 0.5, 6.0
    head = crank_slider_head("crank-slider, prismatic cut", th0, w0)
    tail = ("&marker name = 'block', body = 'slider', at = 0.0, 0.0, 0.0 /\n"
            "&output dt = 0.01, quantities = 'coordinates', 'markers', 'marker_orientations', 'reactions', 'energy' /\n")
    cut, tree = slider_joints(th0, w0)
    (tmp_path / "cut.nml").write_text(head + cut + tail)
    (tmp_path / "tree.nml").write_text(head + tree + tail)
    res = pymr.run(tmp_path / "cut.nml", tmp_path / "cut.csv")
    other = pymr.run(tmp_path / "tree.nml", tmp_path / "tree.csv")
    ref = lagrange_reference(crank_slider_mass_potential, th0, w0, 2.0)
    th = ref.sol(res["t"])[0]
    assert np.ptp(res["crank.q"]) > 2 * np.pi
    assert np.abs(res["crank.q"] - th).max() < 1e-6
    assert np.abs(res["block.x"] - np.array([crank_slider_geometry(p)[1] for p in th])).max() < 1e-6
    assert np.abs(res["block.y"]).max() < 1e-8 and np.abs(res["block.z"]).max() < 1e-8
    assert np.abs(res["block.qz"]).max() < 1e-8 and np.abs(res["block.qw"] - 1.0).max() < 1e-12
    e = res["energy.total"]
    assert np.abs(e - e[0]).max() < 1e-8 * res["energy.kinetic"].max()
    # the ground's push on the slider across the slide: the same load either way
    peak = np.abs(other["slide.fy"]).max()
    assert peak > 1.0 and np.abs(res["slide.fy"] - other["slide.fy"]).max() < 1e-5 * peak


def test_a_prescribed_crank_drives_the_fourbar(tmp_path):
    """The four-bar with its crank prescribed (&motion spin-up to 3 rad/s in 0.5 s): a
    driven mechanism with no free motion left. The coupler and rocker follow the closed-form
    loop to 1e-8 rad, the loop stays closed to 1e-8 m, and the energy the drive puts in
    (motion_work) is the change of the total energy (1e-6 of it). Measured: 1.4e-11 rad,
    1.5e-11 m, 1.3e-9 J of 13.9 J."""
    text = fourbar_scene(1.0, 0.0, t_end=1.5).replace(
        "&effects gravity = .true. /", "&effects gravity = .true., base_motion = .true. /")
    text += "&motion joint = 'A', form = 'spinup', offset = 1.0, rate = 3.0, ramp_time = 0.5 /\n"
    (tmp_path / "driven.nml").write_text(text)
    res = pymr.run(tmp_path / "driven.nml", tmp_path / "driven.csv")
    p1 = res["A.q"]
    assert p1[-1] == pytest.approx(1.0 + 3.0 * (1.5 - 0.25), abs=1e-9)      # the spin-up's angle
    p2, p3 = np.array([fourbar_angles(p)[:2] for p in p1]).T
    wrap = lambda a: (a + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(wrap(p1 + res["B.q"] - p2)).max() < 1e-8
    assert np.abs(wrap(p1 + res["B.q"] + res["C.q"] - p3)).max() < 1e-8
    assert np.hypot(res["tip.x"] - L0, res["tip.y"]).max() < 1e-8
    e = res["energy.total"]
    assert np.abs(e - e[0] - res["energy.motion_work"]).max() < 1e-6 * np.abs(res["energy.motion_work"]).max()


def on_turntable(text: str) -> str:
    """The scene's ground joints moved onto a table turned about the vertical y (in the
    loops' plane) by a spin-up to 3 rad/s in 0.2 s: 2.7 rad after 1 s, through 90 degrees."""
    table = ("&body name = 'table', kind = 'rigid', mass = 10.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /\n"
             "&joint name = 'turn', kind = 'revolute', parent = 'ground', child = 'table', axis = 0.0, 1.0, 0.0 /\n")
    text = text.replace("parent = 'ground'", "parent = 'table'").replace("t_end = 2.0", "t_end = 1.0")
    text = text.replace("&effects gravity = .true. /", "&effects gravity = .true., base_motion = .true. /")
    text = text.replace("&body name = 'ground', kind = 'ground' /\n", "&body name = 'ground', kind = 'ground' /\n" + table)
    return text + "&motion joint = 'turn', form = 'spinup', rate = 3.0, ramp_time = 0.2 /\n"


def test_a_planar_loop_on_a_turning_table_keeps_its_rows(tmp_path):
    """The point and frame rows of a cut are along its parent's axes, so the rows chosen at
    the start stay the loop plane's own when the whole loop turns (in inertial axes, once the
    table turned, the kept rows left the plane: the cut's multipliers grew as tan of the turn,
    to 1.1 kN at the four-bar's cut of 166 N in-plane peak, and would be singular at 90
    degrees). The four-bar (revolute cut) and the crank-slider (prismatic cut: sliding and
    frame rows) on a table turned through 2.7 rad about an axis in their plane: no force or
    moment out of the plane at the cut (the dropped rows) to 1e-9 of the peak in-plane force
    (measured 4e-15 N), the four-bar on its closed-form loop (1e-8 rad; 2e-11) and closed
    (1e-8 m; 2e-11), the slide's force across the slide equal to the tree formulation's
    (1e-6 of its peak; 2e-9), and the energy change equal to the table's motion work (1e-8
    of it; 7e-10)."""
    (tmp_path / "f.nml").write_text(on_turntable(fourbar_scene(1.0, 2.0)).replace(
        "&marker name = 'tip'", "&marker name = 'pivot', body = 'table', at = 1.0, 0.0, 0.0 /\n&marker name = 'tip'"))
    four = pymr.run(tmp_path / "f.nml", tmp_path / "f.csv")
    assert four["turn.q"][-1] > 2.5
    peak = np.hypot(four["D.fx"], four["D.fy"]).max()
    for c in ("fz", "mx", "my", "mz"):
        assert np.abs(four[f"D.{c}"]).max() < 1e-9 * peak, c
    p2, p3 = np.array([fourbar_angles(p)[:2] for p in four["A.q"]]).T
    wrap = lambda a: (a + np.pi) % (2 * np.pi) - np.pi
    assert np.abs(wrap(four["A.q"] + four["B.q"] + four["C.q"] - p3)).max() < 1e-8
    assert max(np.abs(four[f"tip.{x}"] - four[f"pivot.{x}"]).max() for x in "xyz") < 1e-8

    th0, w0 = 0.5, 6.0
    head = crank_slider_head("crank-slider on a table", th0, w0)
    tail = "&output dt = 0.01, quantities = 'coordinates', 'reactions', 'energy' /\n"
    cut, tree = slider_joints(th0, w0)
    (tmp_path / "cut.nml").write_text(on_turntable(head + cut + tail))
    (tmp_path / "tree.nml").write_text(on_turntable(head + tree + tail))
    res = pymr.run(tmp_path / "cut.nml", tmp_path / "cut.csv")
    other = pymr.run(tmp_path / "tree.nml", tmp_path / "tree.csv")
    peak = np.abs(other["slide.fy"]).max()
    assert peak > 1.0 and np.abs(res["slide.fy"] - other["slide.fy"]).max() < 1e-6 * peak
    for c in ("fz", "mx", "my"):
        assert np.abs(res[f"slide.{c}"]).max() < 1e-9 * peak, c
    for r in (four, res, other):
        e = r["energy.total"]
        assert np.abs(e - e[0] - r["energy.motion_work"]).max() < 1e-8 * np.abs(r["energy.motion_work"]).max()


def test_loop_rows_of_a_state_beyond_the_model_s_terms_are_an_error(tmp_path):
    """loop_rows at rates of 1e200 returned gamma = NaN with no error, where
    model_accelerations at that state raises SolverError. At an ordinary state its rows
    stay finite, gamma = -Gdot qd quadratic in qd (doubling qd quadruples it, to 1e-12)."""
    scene = tmp_path / "fb.nml"
    scene.write_text(fourbar_scene(1.0, 2.0))
    q = np.array([1.0, -0.6464848191068708, -2.1465396845740505])
    with pytest.raises(pymr.SolverError, match=r"^the loops' rows are not finite at this state: it overflows the "
                                               r"model's terms$"):
        pymr.loop_rows(scene, q, np.full(3, 1e200))
    one, two = (pymr.loop_rows(scene, q, s * np.ones(3))[2] for s in (1.0, 2.0))
    assert np.isfinite(one).all() and np.abs(two - 4 * one).max() < 1e-12 * np.abs(one).max()
