"""The cylindrical, universal and planar joints (issue 32), chains of one-coordinate
primitives (driver/build.f90 add_joint), against independent solutions:

- a cylindrical joint under gravity along its axis with an initial spin: q1 = v0 t - g t^2/2
  and a constant spin rate;
- a free planar body under gravity in its plane: its centre of mass flies a parabola and its
  spin stays constant;
- a universal-joint pendulum against the same system built from two revolute joints with a
  (nearly) massless intermediate body, with the default and a given axis2;
- a body hanging at rest on each kind: the `reactions` output balances its weight;
- the articulated and mass-matrix paths agree; a drive on a joint's second coordinate;
- each as a loop-closing (cut) joint on a free or spherical tree joint: the same motion and
  reactions as the tree joint;
- bad input refused with one line, exit 1.
"""
from __future__ import annotations

import re
import subprocess

import numpy as np
import pytest

import pymr

G = 9.81
HEAD = ("&scene title = 'new joints', t_end = {t_end!r}, gravity = {g} /\n"
        "&integrator method = 'single', h_slow = 1.0e-3 /\n"
        "&effects gravity = .true., joint_drives = .true. /\n"
        "&body name = 'ground', kind = 'ground' /\n")
OUT = "&output dt = 0.01, quantities = 'coordinates', 'markers', 'reactions' /\n"


def scene(tmp_path, body, joints, t_end=2.0, g="0.0, -9.81, 0.0", extra="", name="s"):
    path = tmp_path / f"{name}.nml"
    path.write_text(HEAD.format(t_end=t_end, g=g) + body + joints + extra + OUT)
    return path


def rigid(name, mass, com="0.0, 0.0, 0.0", inertia="0.1, 0.2, 0.3, 0.0, 0.0, 0.0"):
    return f"&body name = '{name}', kind = 'rigid', mass = {mass!r}, com = {com}, inertia = {inertia} /\n"


def run(path):
    return pymr.run(path, path.with_suffix(".csv"))


def test_cylindrical_joint_falls_along_its_axis_and_spins_steadily(tmp_path):
    """Gravity along the axis (given as (0, 2, 0): not unit) and a centre of mass off the
    axis: q1 = v0 t - g t^2/2 and q2 = w0 t, to 1e-9 (measured 4e-13)."""
    path = scene(tmp_path, rigid("b", 2.0, com="0.3, 0.0, 0.1"),
                 "&joint name = 'c', kind = 'cylindrical', parent = 'ground', child = 'b', axis = 0.0, 2.0, 0.0, "
                 "q0 = 0.0, 0.0, qd0 = 0.5, 3.0 /\n")
    r = run(path)
    t = r["t"]
    assert np.abs(r["c.q1"] - (0.5 * t - G * t**2 / 2)).max() < 1e-9
    assert np.abs(r["c.qd1"] - (0.5 - G * t)).max() < 1e-9
    assert np.abs(r["c.q2"] - 3.0 * t).max() < 1e-9
    assert np.abs(r["c.qd2"] - 3.0).max() < 1e-9


def test_planar_body_flies_a_parabola_and_spins_steadily(tmp_path):
    """Plane normal z (translations x then y), gravity -y, centre of mass 0.2 m from the joint
    point: the centre of mass (q1 + 0.2 cos q3, q2 + 0.2 sin q3) flies the parabola from its
    initial velocity and q3 = w0 t, to 1e-9 (measured 3e-11)."""
    path = scene(tmp_path, rigid("b", 1.5, com="0.2, 0.0, 0.0") +
                 "&marker name = 'cm', body = 'b', at = 0.2, 0.0, 0.0 /\n",
                 "&joint name = 'p', kind = 'planar', parent = 'ground', child = 'b', axis = 0.0, 0.0, 1.0, "
                 "q0 = 0.1, -0.2, 0.0, qd0 = 1.0, 2.0, 4.0 /\n")
    r = run(path)
    t = r["t"]
    w0 = 4.0
    x0, y0 = 0.1 + 0.2, -0.2
    vx0, vy0 = 1.0, 2.0 + 0.2 * w0
    assert np.abs(r["p.q3"] - w0 * t).max() < 1e-9
    assert np.abs(r["p.qd3"] - w0).max() < 1e-9
    cx = r["p.q1"] + 0.2 * np.cos(r["p.q3"])
    cy = r["p.q2"] + 0.2 * np.sin(r["p.q3"])
    assert np.abs(cx - (x0 + vx0 * t)).max() < 1e-9
    assert np.abs(cy - (y0 + vy0 * t - G * t**2 / 2)).max() < 1e-9
    # the marker at the centre of mass says the same (the in-plane directions are x and y)
    assert np.abs(r["cm.x"] - cx).max() < 1e-12 and np.abs(r["cm.y"] - cy).max() < 1e-12
    assert np.abs(r["cm.z"]).max() < 1e-12


BOB = rigid("bob", 1.0, com="0.0, -1.0, 0.2", inertia="0.01, 0.02, 0.03, 0.0, 0.0, 0.0")
LINK = rigid("link", 1e-12, inertia="1.0e-12, 1.0e-12, 1.0e-12, 0.0, 0.0, 0.0")


@pytest.mark.parametrize("axis2, second", [(None, "1.0, 0.0, 0.0"), ("1.0, 1.0, 0.0", "1.0, 1.0, 0.0")])
def test_universal_pendulum_is_two_revolutes_with_a_massless_link(tmp_path, axis2, second):
    """A universal joint (axis z, then axis2: the default x, or (1, 1, 0)) against two
    revolute joints with a 1e-12 kg link between them, over 2 s of large swinging: the
    coordinates agree to 1e-8 rad (measured 5e-12: the link's 1e-12 kg)."""
    a2 = "" if axis2 is None else f", axis2 = {axis2}"
    u = scene(tmp_path, BOB, "&joint name = 'u', kind = 'universal', parent = 'ground', child = 'bob', "
              f"axis = 0.0, 0.0, 1.0{a2}, q0 = 0.8, 0.5, qd0 = 0.3, -1.0 /\n", name="u")
    two = scene(tmp_path, LINK + BOB,
                "&joint name = 'r1', kind = 'revolute', parent = 'ground', child = 'link', axis = 0.0, 0.0, 1.0, "
                "q0 = 0.8, qd0 = 0.3 /\n"
                f"&joint name = 'r2', kind = 'revolute', parent = 'link', child = 'bob', axis = {second}, "
                "q0 = 0.5, qd0 = -1.0 /\n", name="two")
    ru, r2 = run(u), run(two)
    assert np.ptp(ru["u.q2"]) > 0.5 and np.ptp(ru["u.q1"]) > 0.5
    for a, b in (("u.q1", "r1.q"), ("u.q2", "r2.q"), ("u.qd1", "r1.qd"), ("u.qd2", "r2.qd")):
        assert np.abs(ru[a] - r2[b]).max() < 1e-8, a


HANGING = {
    # kind, joint items, centre of mass: each at rest under gravity -y
    "cylindrical": ("axis = 1.0, 0.0, 0.0", "0.0, 0.0, 0.0"),
    "universal": ("axis = 0.0, 0.0, 1.0", "0.0, -1.0, 0.0"),
    "planar": ("axis = 0.0, 1.0, 0.0", "0.3, 0.0, 0.0"),
}


@pytest.mark.parametrize("kind", sorted(HANGING))
def test_reaction_of_a_body_at_rest_balances_its_weight(tmp_path, kind):
    """A 2 kg body at rest on each kind stays at rest, and the joint's reaction on it (child
    frame, about the joint point) is its weight up and the moment of its weight reversed,
    to 1e-9 of the weight (measured: exact)."""
    items, com = HANGING[kind]
    path = scene(tmp_path, rigid("b", 2.0, com=com),
                 f"&joint name = 'j', kind = '{kind}', parent = 'ground', child = 'b', {items} /\n", t_end=0.5)
    r = run(path)
    w = 2.0 * G
    c = np.array([float(v) for v in com.split(",")])
    moment = -np.cross(c, [0.0, -w, 0.0])
    for k, axis in enumerate("xyz"):
        assert np.abs(r[f"j.f{axis}"] - [0.0, w, 0.0][k]).max() < 1e-9 * w, axis
        assert np.abs(r[f"j.m{axis}"] - moment[k]).max() < 1e-9 * w, axis
    n = {"cylindrical": 2, "universal": 2, "planar": 3}[kind]
    for i in range(1, n + 1):
        assert np.abs(r[f"j.q{i}"]).max() < 1e-12


def chain(tmp_path):
    """A chain through every new kind, with tilted axes, so that each coordinate couples."""
    return scene(tmp_path, rigid("a", 2.0, com="0.2, -0.3, 0.1") + rigid("b", 1.0, com="0.0, -0.5, 0.2") +
                 rigid("c", 0.7, com="0.1, 0.1, -0.4"),
                 "&joint name = 'ju', kind = 'universal', parent = 'ground', child = 'a', axis = 0.0, 0.3, 1.0, "
                 "axis2 = 1.0, 0.0, 0.0 /\n"
                 "&joint name = 'jp', kind = 'planar', parent = 'a', child = 'b', at = 0.1, -0.6, 0.0, "
                 "axis = 1.0, 1.0, 0.0 /\n"
                 "&joint name = 'jc', kind = 'cylindrical', parent = 'b', child = 'c', at = 0.0, -1.0, 0.0, "
                 "axis = 0.2, 0.0, 1.0 /\n"
                 "&drive joint = 'jc', coordinate = 2, offset = 0.7 /\n", name="chain")


def test_articulated_and_mass_matrix_paths_agree(tmp_path):
    """At random states of the chain, qdd by the articulated-body algorithm equals the
    mass-matrix solution to 1e-11 of the largest acceleration (measured 3e-15)."""
    path = chain(tmp_path)
    rng = np.random.default_rng(3)
    for trial in range(3):
        x = 0.5 * rng.standard_normal(14)
        acc = []
        for dyn in ("mass_matrix", "articulated"):
            with pymr.Model(path, {"integrator.dynamics": dyn}) as model:
                acc.append(model.rhs(0.1 * trial, x))
        assert np.abs(acc[0] - acc[1]).max() <= 1e-11 * np.abs(acc[0]).max(), trial
    # and whole runs (2 s, the drive on): the coordinates agree to 1e-10 (measured 6e-14)
    a = pymr.run(path, tmp_path / "a.csv", overrides={"integrator.dynamics": "mass_matrix"})
    b = pymr.run(path, tmp_path / "b.csv", overrides={"integrator.dynamics": "articulated"})
    names = [c for c in a.columns if c.endswith((".q1", ".q2", ".q3", ".qd1", ".qd2", ".qd3"))]
    assert len(names) == 14
    for c in names:
        assert np.abs(a[c] - b[c]).max() < 1e-10, c


def test_chain_conserves_energy_and_names_its_coordinates(tmp_path):
    """Without the drive the chain's energy stays at its start to 1e-7 of its swing over 1 s
    (fixed step 1e-3; measured 2e-11); the coordinates are named JOINT.q1 ... in order."""
    path = chain(tmp_path)
    path.write_text(path.read_text().replace("joint_drives = .true.", "joint_drives = .false.")
                    .replace("axis = 0.2, 0.0, 1.0 /", "axis = 0.2, 0.0, 1.0, qd0 = 0.3, 2.0 /"))
    r = pymr.run(path, tmp_path / "e.csv", overrides={"scene.t_end": 1.0})
    names = [c for c in r.columns if c.endswith((".q1", ".q2", ".q3"))]
    assert names == ["ju.q1", "ju.q2", "jp.q1", "jp.q2", "jp.q3", "jc.q1", "jc.q2"]
    q, qd = r.coordinates()
    ke, pe = (np.asarray(v) for v in pymr.model_energy(path, q, qd))
    e = ke + pe
    assert np.ptp(pe) > 1.0
    assert np.abs(e - e[0]).max() < 1e-7 * np.ptp(pe)


def test_drive_on_the_second_coordinate_of_a_cylindrical_joint(tmp_path):
    """No gravity, a constant torque T on coordinate 2 (the angle): q2 = T t^2 / (2 I), I the
    inertia about the axis (0.3 about z, centre of mass on the axis), q1 stays 0."""
    path = scene(tmp_path, rigid("b", 2.0),
                 "&joint name = 'c', kind = 'cylindrical', parent = 'ground', child = 'b' /\n"
                 "&drive joint = 'c', coordinate = 2, offset = 0.6 /\n", g="0.0, 0.0, 0.0")
    r = run(path)
    t = r["t"]
    assert np.abs(r["c.q2"] - 0.6 * t**2 / (2 * 0.3)).max() < 1e-9
    assert np.abs(r["c.q1"]).max() < 1e-14


BAD = [
    ("kind = 'universal', axis = 0.0, 0.0, 1.0, axis2 = 1.0, 0.0, 0.1",
     r"axis2: not normal to axis \(the cosine of the angle between them is 0\.0995037\)"),
    ("kind = 'universal', axis2 = 0.0, 0.0, 0.0", "axis2: zero length; give a direction normal to axis"),
    ("kind = 'cylindrical', axis = 0.0, 0.0, 0.0", "axis: zero length; give a direction in the parent frame"),
    ("kind = 'planar', axis = 0.0, 0.0, 0.0", "axis: zero length; give a direction in the parent frame"),
    ("kind = 'revolute', axis2 = 1.0, 0.0, 0.0",
     r"axis2: only a 'universal' joint takes axis2 \(this joint is 'revolute'\)"),
    ("kind = 'planar', q0 = 1.0, 2.0", "q0: a planar joint has 3 coordinates, got 2 values$"),
    ("kind = 'cylindrical', qd0 = 1.0, 2.0, 3.0", "qd0: a cylindrical joint has 2 coordinates, got 3 values$"),
]


@pytest.mark.parametrize("items, message", BAD)
def test_bad_joint_items_are_refused_in_one_line(tmp_path, mrsim, items, message):
    path = scene(tmp_path, rigid("b", 1.0), f"&joint name = 'j', parent = 'ground', child = 'b', {items} /\n")
    p = subprocess.run([mrsim, str(path)], capture_output=True, text=True, cwd=tmp_path)
    assert p.returncode == 1
    lines = [ln for ln in p.stderr.splitlines() if "&joint" in ln or "s.nml" in ln]
    assert len(lines) == 1, p.stderr
    assert re.search(message, lines[0]), lines[0]


FREE = "&joint name = 'j', kind = 'free', parent = 'ground', child = 'b', "


def test_cylindrical_cut_is_the_cylindrical_joint(tmp_path):
    """A body on a free tree joint, closed to the ground by a cylindrical cut along y: it
    falls along y and spins about it as on the tree joint (free q2 = v0 t - g t^2/2, q5 =
    w0 t, the other four 0), to 1e-8 (measured 4e-13), and the cut's reaction is the tree
    joint's to 1e-9 N, N m (measured 4e-13; the centripetal force is 5.4 N)."""
    body = rigid("b", 2.0, com="0.3, 0.0, 0.1")
    cut = scene(tmp_path, body, FREE + "qd0 = 0.0, 0.5, 0.0, 0.0, 3.0, 0.0 /\n"
                "&joint name = 'c', kind = 'cylindrical', parent = 'ground', child = 'b', axis = 0.0, 1.0, 0.0, "
                "child_at = 0.0, 0.0, 0.0 /\n", name="cut")
    tree = scene(tmp_path, body, "&joint name = 'c', kind = 'cylindrical', parent = 'ground', child = 'b', "
                 "axis = 0.0, 1.0, 0.0, qd0 = 0.5, 3.0 /\n", name="tree")
    rc, rt = run(cut), run(tree)
    t = rc["t"]
    assert np.abs(rc["j.q2"] - (0.5 * t - G * t**2 / 2)).max() < 1e-8
    assert np.abs(rc["j.q5"] - 3.0 * t).max() < 1e-8
    for k in (1, 3, 4, 6):
        assert np.abs(rc[f"j.q{k}"]).max() < 1e-8, k
    assert np.abs(rt["c.fx"]).max() > 1.0
    for col in ("fx", "fy", "fz", "mx", "my", "mz"):
        assert np.abs(rc[f"c.{col}"] - rt[f"c.{col}"]).max() < 1e-9, col


def test_planar_cut_is_the_planar_joint(tmp_path):
    """A body on a free tree joint, closed by a planar cut (plane normal z), gravity with a
    z part the cut holds: the free joint's x, y and z-rotation follow the planar tree joint's
    coordinates to 1e-8 (measured 6e-15), and the cut's reaction is the tree joint's to 1e-9
    (measured 9e-15)."""
    body = rigid("b", 1.5, com="0.2, 0.0, 0.0")
    g = "0.0, -9.81, -3.0"
    cut = scene(tmp_path, body, FREE + "q0 = 0.1, -0.2, 0.0, 0.0, 0.0, 0.0, qd0 = 1.0, 2.0, 0.0, 0.0, 0.0, 4.0 /\n"
                "&joint name = 'p', kind = 'planar', parent = 'ground', child = 'b', child_at = 0.0, 0.0, 0.0 /\n",
                g=g, name="cut")
    tree = scene(tmp_path, body, "&joint name = 'p', kind = 'planar', parent = 'ground', child = 'b', "
                 "q0 = 0.1, -0.2, 0.0, qd0 = 1.0, 2.0, 4.0 /\n", g=g, name="tree")
    rc, rt = run(cut), run(tree)
    for a, b in (("j.q1", "p.q1"), ("j.q2", "p.q2"), ("j.q6", "p.q3")):
        assert np.abs(rc[a] - rt[b]).max() < 1e-8, a
    for k in (3, 4, 5):
        assert np.abs(rc[f"j.q{k}"]).max() < 1e-8, k
    assert np.abs(rt["p.fz"] - 1.5 * 3.0).max() < 1e-9
    # the z part of the weight at the centre of mass (0.2, 0, 0) is held by a moment about y
    assert np.abs(rt["p.my"] + 1.5 * 3.0 * 0.2).max() < 1e-9
    for col in ("fx", "fy", "fz", "mx", "my", "mz"):
        assert np.abs(rc[f"p.{col}"] - rt[f"p.{col}"]).max() < 1e-9, col


def test_universal_cut_is_the_universal_joint(tmp_path):
    """A pendulum on a spherical tree joint closed by a universal cut at the same point (axis
    z, axis2 x) moves as on a universal tree joint: the bob's path agrees to 1e-8 m (measured
    2e-11), and the spherical joint's and the cut's reactions add up to the universal joint's
    to 1e-9 (measured 6e-11 of 11.5 N)."""
    bob = rigid("b", 1.0, com="0.0, -1.0, 0.2", inertia="0.01, 0.02, 0.03, 0.0, 0.0, 0.0") + \
        "&marker name = 'm', body = 'b', at = 0.3, -1.0, 0.2 /\n"
    a = 0.5
    cut = scene(tmp_path, bob, "&joint name = 's', kind = 'spherical', parent = 'ground', child = 'b', "
                f"q0 = {a!r}, 0.0, 0.0, qd0 = -1.0, {float(0.3 * np.sin(a))!r}, {float(0.3 * np.cos(a))!r} /\n"
                "&joint name = 'u', kind = 'universal', parent = 'ground', child = 'b', child_at = 0.0, 0.0, 0.0 /\n",
                name="cut")
    tree = scene(tmp_path, bob, "&joint name = 'u', kind = 'universal', parent = 'ground', child = 'b', "
                 f"q0 = 0.0, {a!r}, qd0 = 0.3, -1.0 /\n", name="tree")
    rc, rt = run(cut), run(tree)
    assert np.ptp(rt["m.x"]) > 0.1 and np.ptp(rt["m.z"]) > 0.1
    for axis in "xyz":
        assert np.abs(rc[f"m.{axis}"] - rt[f"m.{axis}"]).max() < 1e-8, axis
    for col in ("fx", "fy", "fz", "mx", "my", "mz"):
        assert np.abs(rc[f"s.{col}"] + rc[f"u.{col}"] - rt[f"u.{col}"]).max() < 1e-9, col
