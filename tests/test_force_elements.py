"""Force elements between two markers (&force, issue 32): a spring-damper against the
closed-form damped oscillation, a bushing's static deflection F/k in each direction and its
rotation under a gravity moment, the energy balance of the `energy` output, the generalised
forces against the gradient of the potential energy (finite differences), multirate against
single-rate, and bad input refused with one line. Scenes are written inline."""
from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

import pymr
from refusal import check_refused_in_one_line
from pymr.api import initial_state

# a slider of mass 2 kg on a spring-damper to the ground: anchor 1 m behind its origin,
# free length 1 m, so the slider's coordinate x is the spring's stretch
OSCILLATOR = """
&scene title = 'slider on a spring-damper element', t_end = 2.0, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', {integrator} /
&effects force_elements = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'slider', kind = 'rigid', mass = 2.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /
&joint name = 'rail', kind = '{joint}', parent = 'ground', child = 'slider', {joint_items} /
&marker name = 'anchor', body = 'ground', at = -1.0, 0.0, 0.0 /
&marker name = 'hook', body = 'slider', at = 0.0, 0.0, 0.0 /
&force name = 'spring', kind = 'spring_damper', marker_i = 'anchor', marker_j = 'hook',
       stiffness = 50.0, damping = 0.4, free_length = 1.0 /
&output dt = 1.0e-2, quantities = 'coordinates', 'energy' /
"""
X0, M, K, C = 0.1, 2.0, 50.0, 0.4


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def damped_oscillation(t: np.ndarray) -> np.ndarray:
    """x(t) of m x'' + c x' + k x = 0 from x0 at rest."""
    sigma = C / (2 * M)
    wd = np.sqrt(K / M - sigma**2)
    return X0 * np.exp(-sigma * t) * (np.cos(wd * t) + sigma / wd * np.sin(wd * t))


@pytest.mark.parametrize("joint, integrator, tol", [
    ("prismatic", "h_slow = 1.0e-4, dynamics = 'mass_matrix'", 1e-10),
    ("prismatic", "h_slow = 1.0e-4, dynamics = 'articulated'", 1e-10),
    ("free", "h_slow = 1.0e-4, dynamics = 'articulated'", 1e-10),
    ("free", "h_slow = 1.0e-4, adaptive = .true., rtol = 1.0e-10, atol = 1.0e-12", 1e-8),
])
def test_spring_damper_gives_the_closed_form_damped_oscillation(tmp_path, joint, integrator, tol):
    """m = 2 kg, k = 50 N/m, c = 0.4 N s/m: x(t) = x0 e^(-c t/2m) (cos wd t + c/(2 m wd)
    sin wd t), wd = sqrt(k/m - (c/2m)^2), on a prismatic joint and on a free joint."""
    items = "axis = 1.0, 0.0, 0.0, q0 = 0.1" if joint == "prismatic" else "q0 = 0.1, 0, 0, 0, 0, 0"
    scene = write(tmp_path, "osc.nml", OSCILLATOR.format(integrator=integrator, joint=joint, joint_items=items))
    res = pymr.run(scene)
    x = res["rail.q"] if joint == "prismatic" else res["rail.q1"]
    err = np.abs(x - damped_oscillation(res.t)).max()
    assert err < tol, err
    assert res.stats["effects"]["force_elements"]["evaluations"] > 0


# a 3 kg block on a free joint held by a bushing to the ground, its centre of mass `com`
BUSHING = """
&scene title = 'block on a bushing', t_end = 1.0e-3, gravity = {g}, start = 'static' /
&integrator method = 'single', h_slow = 1.0e-4 /
&effects gravity = .true., force_elements = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'block', kind = 'rigid', mass = 3.0, com = {com},
      inertia = 0.2, 0.3, 0.4, 0.0, 0.0, 0.0 /
&joint name = 'mount', kind = 'free', parent = 'ground', child = 'block', settle = .true. /
&marker name = 'seat', body = 'ground', at = 0.0, 0.0, 0.0 /
&marker name = 'pad', body = 'block', at = 0.0, 0.0, 0.0 /
&force name = 'bush', kind = 'bushing', marker_i = 'seat', marker_j = 'pad',
       stiffness = 2.0e4, 3.0e4, 5.0e4, 700.0, 800.0, 900.0, damping = 6*10.0 /
&output dt = 1.0e-3 /
"""
KT = np.array([2.0e4, 3.0e4, 5.0e4])


def static_state(tmp_path: Path, g, com) -> np.ndarray:
    """The settled coordinates of the block (the static start's first output row)."""
    fmt = ", ".join(repr(float(v)) for v in g), ", ".join(repr(float(v)) for v in com)
    scene = write(tmp_path, "bush.nml", BUSHING.format(g=fmt[0], com=fmt[1]))
    res = pymr.run(scene)
    return np.array([res[f"mount.q{i}"][0] for i in range(1, 7)])


@pytest.mark.parametrize("axis", [0, 1, 2])
def test_bushing_deflects_by_f_over_k_in_each_direction(tmp_path, axis):
    """Gravity 9.81 m/s^2 along x, y or z on the block: it settles at m g / k_axis along
    that axis and nowhere else."""
    g = np.zeros(3)
    g[axis] = -9.81
    q = static_state(tmp_path, g, np.zeros(3))
    expected = np.zeros(6)
    expected[axis] = 3.0 * g[axis] / KT[axis]
    assert np.abs(q - expected).max() < 1e-12 * 1e3, (q, expected)
    assert abs(q[axis] - expected[axis]) < 1e-9 * abs(expected[axis])


def test_bushing_turns_by_the_gravity_moment_over_k_rot(tmp_path):
    """The block's centre 0.5 m along x, gravity along -y: it drops m g / k_y and turns
    about z by theta with k_rz theta = -m g a cos(theta) (the moment of its weight about
    the pad), solved here by Newton."""
    q = static_state(tmp_path, [0.0, -9.81, 0.0], [0.5, 0.0, 0.0])
    w, a, kr = 3.0 * 9.81, 0.5, 900.0
    th = 0.0
    for _ in range(50):
        th -= (kr * th + w * a * np.cos(th)) / (kr - w * a * np.sin(th))
    assert th < -0.01                                    # a real turn, 0.0166 rad
    assert q[1] == pytest.approx(-w / KT[1], rel=1e-9)
    assert q[5] == pytest.approx(th, rel=1e-9)
    assert np.abs(q[[0, 2, 3, 4]]).max() < 1e-12


# two rigid blocks on free joints from the ground, joined by a spring-damper off their
# centres and by a bushing, set spinning and moving
TWO_BODIES = """
&scene title = 'two blocks joined by force elements', t_end = 1.0, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', {integrator} /
&effects force_elements = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'a', kind = 'rigid', mass = 2.0, com = 0.1, 0.0, 0.0, inertia = 0.05, 0.07, 0.09, 0.01, 0.0, 0.0 /
&body name = 'b', kind = 'rigid', mass = 1.5, inertia = 0.04, 0.03, 0.05, 0.0, 0.005, 0.0 /
&joint name = 'ja', kind = 'free', parent = 'ground', child = 'a', qd0 = 0.1, -0.2, 0.3, 0.5, -0.4, 0.8 /
&joint name = 'jb', kind = 'free', parent = 'ground', child = 'b', at = 1.0, 0.0, 0.0,
       qd0 = -0.3, 0.2, 0.1, -0.6, 0.7, 0.2 /
&marker name = 'a1', body = 'a', at = 0.3, 0.1, 0.0 /
&marker name = 'a2', body = 'a', at = 0.5, 0.0, 0.05 /
&marker name = 'b1', body = 'b', at = -0.2, 0.05, 0.1 /
&marker name = 'b2', body = 'b', at = -0.5, 0.0, 0.05 /
&force name = 'link', kind = 'spring_damper', marker_i = 'a1', marker_j = 'b1', stiffness = 400.0,
       damping = {c1}, free_length = 0.4 /
&force name = 'mount', kind = 'bushing', marker_i = 'a2', marker_j = 'b2',
       stiffness = 300.0, 200.0, 250.0, 20.0, 30.0, 25.0, damping = {c6} /
&output dt = 1.0e-2, quantities = 'coordinates', 'energy' /
"""
ADAPTIVE = "h_slow = 1.0e-4, adaptive = .true., rtol = 1.0e-10, atol = 1.0e-12"


def two_bodies(tmp_path: Path, integrator: str, damped: bool, name: str = "two.nml") -> Path:
    c1, c6 = ("3.0", "2.0, 1.0, 1.5, 0.1, 0.2, 0.15") if damped else ("0.0", "6*0.0")
    return write(tmp_path, name, TWO_BODIES.format(integrator=integrator, c1=c1, c6=c6))


@pytest.mark.parametrize("integrator", [ADAPTIVE + ", dynamics = 'mass_matrix'",
                                        ADAPTIVE + ", dynamics = 'articulated'"])
def test_undamped_elements_keep_the_total_energy(tmp_path, integrator):
    """Kinetic plus the elements' spring energy stays constant to the integrator's
    tolerance, while energy moves between them."""
    res = pymr.run(two_bodies(tmp_path, integrator, damped=False))
    e, springs = res["energy.total"], res["energy.springs"]
    assert np.ptp(springs) > 0.1 * e[0]                       # energy really moves
    assert np.abs(e - e[0]).max() < 1e-8 * e[0]
    assert np.abs(res["energy.damping_loss"]).max() == 0.0


def test_damping_loss_accounts_for_the_energy_lost(tmp_path):
    """With dampers the total falls, and by the integrated damping loss."""
    res = pymr.run(two_bodies(tmp_path, ADAPTIVE, damped=True))
    e, loss = res["energy.total"], res["energy.damping_loss"]
    assert loss[-1] > 0.2 * e[0]                              # a real loss
    assert np.abs(e + loss - e[0]).max() < 1e-7 * e[0]
    # the energy the model function gives is the output's
    q, qd = res.coordinates()
    ke, pe = pymr.model_energy(two_bodies(tmp_path, ADAPTIVE, True), q, qd)
    assert np.abs(ke + pe - e).max() < 1e-12 * e[0]


# a beam on a revolute hub and a rigid block on a free joint, joined by a spring-damper
# and two bushings (one from a beam marker, one to a beam marker), so through its mode shapes
FLEXIBLE = """
&scene title = 'beam and block joined by force elements', t_end = {t_end}, gravity = 0.0, 0.0, 0.0 /
&integrator {integrator} /
&effects force_elements = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'beam', kind = 'beam', length = 2.0, youngs_modulus = 7.0e10, density = 2700.0,
      r_outer = 0.03, r_inner = 0.025, n_elements = 10, modes_y = 2, modes_z = 2, modes_x = 1, modes_t = 1,
      shear_modulus = 2.6e10 /
&body name = 'block', kind = 'rigid', mass = 5.0, inertia = 0.1, 0.12, 0.08, 0.0, 0.0, 0.0 /
&joint name = 'hub', kind = 'revolute', parent = 'ground', child = 'beam', axis = 0.0, 1.0, 0.0 /
&joint name = 'jb', kind = 'free', parent = 'ground', child = 'block', at = 2.2, 0.3, 0.0,
       qd0 = 0.2, -0.1, 0.3, 0.4, -0.2, 0.5 /
&marker name = 'tip', body = 'beam', at = 2.0, 0.0, 0.0 /
&marker name = 'mid', body = 'beam', at = 1.2, 0.0, 0.0 /
&marker name = 'b1', body = 'block', at = -0.1, -0.2, 0.05 /
&marker name = 'b2', body = 'block', at = -1.0, -0.3, 0.0 /
&marker name = 'quarter', body = 'beam', at = 1.6, 0.0, 0.0 /
&marker name = 'b3', body = 'block', at = -0.6, -0.3, 0.0 /
&force name = 'link', kind = 'spring_damper', marker_i = 'tip', marker_j = 'b1', stiffness = 3.0e4,
       damping = 20.0, free_length = 0.15 /
&force name = 'mount', kind = 'bushing', marker_i = 'b2', marker_j = 'mid',
       stiffness = 2.0e4, 1.0e4, 3.0e4, 500.0, 400.0, 300.0, damping = 6*5.0 /
&force name = 'mount2', kind = 'bushing', marker_i = 'quarter', marker_j = 'b3',
       stiffness = 1.0e4, 2.0e4, 1.5e4, 300.0, 200.0, 400.0, damping = 4.0, 3.0, 2.0, 1.0, 0.5, 0.2 /
&output dt = 1.0e-3, quantities = 'coordinates', 'energy' /
"""


def flexible(tmp_path: Path, integrator: str, t_end: float = 0.05, name: str = "flex.nml") -> Path:
    return write(tmp_path, name, FLEXIBLE.format(integrator=integrator, t_end=t_end))


def test_generalised_forces_are_minus_the_gradient_of_the_potential(tmp_path):
    """At rest (qd = 0, gravity off) the elements' generalised forces (P with them on minus
    P with them off, which removes the beam's elastic forces) are minus the central
    difference of their potential energy (the same difference of the model's potential), to
    1e-6 in every component, at a state with large turns and deflections of the beam."""
    scene = flexible(tmp_path, "method = 'single', h_slow = 1.0e-4")
    q0, _ = initial_state(scene)
    rng = np.random.default_rng(7)
    q = q0 + rng.uniform(-0.3, 0.3, q0.size) * np.where(np.arange(q0.size) >= 7, 0.05, 1.0)
    eps = 1e-6
    states = np.vstack([q + eps * np.eye(q.size), q - eps * np.eye(q.size)])
    p, grad = {}, {}
    for on in (True, False):
        over = {"effects.force_elements": on}
        p[on] = pymr.model_terms(scene, q, np.zeros_like(q), overrides=over)[1]
        pe = pymr.model_energy(scene, states, np.zeros_like(states), overrides=over)[1]
        grad[on] = (pe[:q.size] - pe[q.size:]) / (2 * eps)
    p_el, grad_el = p[True] - p[False], grad[True] - grad[False]
    assert np.abs(p_el).min() > 100.0                        # every coordinate really loaded
    assert np.all(np.abs(p_el + grad_el) < 1e-6 * np.abs(p_el)), np.abs(p_el + grad_el) / np.abs(p_el)


# a rotor on a revolute joint about z held to the ground by a bushing, turned about its axis
ROTOR = """
&scene title = 'rotor on a bushing', t_end = 1.0e-3, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', h_slow = 1.0e-4 /
&effects force_elements = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'rotor', kind = 'rigid', mass = 2.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /
&joint name = 'shaft', kind = 'revolute', parent = 'ground', child = 'rotor', axis = 0.0, 0.0, 1.0 /
&marker name = 'a', body = 'ground' /
&marker name = 'b', body = 'rotor' /
&force name = 'bush', kind = 'bushing', marker_i = 'a', marker_j = 'b', stiffness = 1, 1, 1, 10, 10, 10 /
"""


@pytest.mark.parametrize("turn", [3.0, np.pi - 1e-6, np.pi - 1e-9, np.pi - 1e-12, np.pi, np.pi + 1e-9, 3.3, -3.1,
                                  1e-9, 0.0])
def test_bushing_turned_up_to_half_a_turn_keeps_its_moment(tmp_path, turn):
    """The bushing's rotation is the shortest one between its markers: turned by q about its
    axis, its energy is k (q wrapped into [-pi, pi])^2 / 2 and its moment -k q wrapped, up to
    pi exactly (the rotation vector's axis there comes from the rotation's symmetric part:
    from its skew part, which vanishes with sin q, the moment fell to 1e-12 at pi - 1e-9)."""
    scene = write(tmp_path, "rotor.nml", ROTOR)
    k, wrapped = 10.0, turn - 2 * np.pi * round(turn / (2 * np.pi))     # pi stays pi
    q, qd = np.array([turn]), np.zeros(1)
    p = {on: pymr.model_terms(scene, q, qd, overrides={"effects.force_elements": on})[1][0] for on in (True, False)}
    energy = pymr.model_energy(scene, q[None, :], qd[None, :])[1][0]
    assert energy == pytest.approx(0.5 * k * wrapped**2, rel=1e-12, abs=1e-300)
    assert abs(p[True] - p[False]) == pytest.approx(k * abs(wrapped), rel=1e-9, abs=1e-300)
    if turn != np.pi:
        assert p[True] - p[False] == pytest.approx(-k * wrapped, rel=1e-9, abs=1e-300)


@pytest.fixture(scope="module")
def flexible_reference(tmp_path_factory) -> np.ndarray:
    """The beam and block's coordinates from a tight adaptive single-rate run (M path)."""
    ref = pymr.run(flexible(tmp_path_factory.mktemp("ref"), "method = 'single', " + ADAPTIVE, name="ref.nml"))
    return ref.coordinates()[0]


@pytest.mark.parametrize("integrator, tol, fast_rows", [
    ("method = 'single', " + ADAPTIVE + ", dynamics = 'articulated'", 1e-9, False),
    ("method = 'multirate', h_fast = 2.0e-6, h_slow = 1.0e-5", 1e-8, False),
    ("method = 'multirate', h_fast = 2.0e-6, h_slow = 1.0e-5, coupling = 'full'", 1e-6, True),
    ("method = 'multirate', h_slow = 1.0e-5, adaptive = .true., rtol = 1.0e-9, atol = 1.0e-11", 1e-7, False),
])
def test_articulated_and_multirate_follow_single_rate(tmp_path, flexible_reference, integrator, tol, fast_rows):
    """The beam and block on the articulated path, and under fixed (the 'response' and the
    'full' coupling, whose fast-row evaluations load the beam alone) and adaptive multirate
    steps, end where the tight single-rate run ends; energy with the damping loss is kept."""
    res = pymr.run(flexible(tmp_path, integrator))
    fx = res.stats["effects"]["force_elements"]["evaluations"]
    assert fx == res.stats["rhs_full"] + (res.stats.get("rhs_fast", 0) if fast_rows else 0)
    q, _ = res.coordinates()
    qr = flexible_reference
    assert np.abs(q - qr).max() < tol * np.abs(qr).max(), np.abs(q - qr).max() / np.abs(qr).max()
    e, loss = res["energy.total"], res["energy.damping_loss"]
    assert loss[-1] > 1e-3 * e[0]
    assert np.abs(e + loss - e[0]).max() < 1e-6 * e[0]


def test_elements_off_on_purpose_change_nothing(tmp_path):
    """force_elements = .false.: the groups are ignored, results bit-identical to the
    scene without them."""
    base = OSCILLATOR.format(integrator="h_slow = 1.0e-3", joint="prismatic", joint_items="axis = 1.0, 0.0, 0.0, q0 = 0.1")
    off = base.replace("force_elements = .true.", "force_elements = .false.")
    plain = "\n".join(line for line in off.split("\n") if not line.startswith(("&force", "       stiffness")))
    r_off = pymr.run(write(tmp_path, "off.nml", off))
    r_plain = pymr.run(write(tmp_path, "plain.nml", plain))
    assert np.array_equal(r_off.data, r_plain.data)
    assert "force_elements" not in r_off.stats["effects"]


# ----------------------------------------------------------------------- bad input

BAD_BASE = OSCILLATOR.format(integrator="h_slow = 1.0e-3", joint="prismatic",
                             joint_items="axis = 1.0, 0.0, 0.0, q0 = 0.1")
FORCE_LINE = 10          # the &force group's first line in BAD_BASE (after its leading newline)
GOOD = ("&force name = 'spring', kind = 'spring_damper', marker_i = 'anchor', marker_j = 'hook',\n"
        "       stiffness = 50.0, damping = 0.4, free_length = 1.0 /")


@pytest.mark.parametrize("replace, expect", [
    (("marker_j = 'hook'", "marker_j = 'nowhere'"), r":10: &force 'spring': marker_j: no &marker named 'nowhere'"),
    (("marker_j = 'hook'", "marker_j = 'anchor'"), r":10: &force 'spring': marker_j: the same marker as marker_i"),
    (("stiffness = 50.0", "stiffness = -50.0"), r":11: &force 'spring': stiffness: .*-50"),
    (("free_length = 1.0", "free_length = -1.0"), r":11: &force 'spring': free_length: .*-1"),
    ((", free_length = 1.0", ""), r":10: &force 'spring': free_length: missing"),
    (("stiffness = 50.0", "stiffness = 50.0, 60.0"),
     r":11: &force 'spring': stiffness: a 'spring_damper' takes 1 value, got 2"),
    (("kind = 'spring_damper'", "kind = 'bushing'"),
     r":11: &force 'spring': stiffness: a 'bushing' takes 6 .*got 1"),
    (("kind = 'spring_damper'", "kind = 'rope'"), r":10: &force 'spring': kind: .*rope"),
    (("damping = 0.4", "damping = 0.4, 0.5"), r":11: &force 'spring': damping: .*takes 1 value .*got 2"),
    (("force_elements = .true.", "gravity = .false."), r":10: &force 'spring'.*&effects force_elements is not on"),
    (("name = 'spring', ", ""), r":10: &force #1: name: missing"),
])
def test_bad_force_elements_are_refused_with_one_line(tmp_path, mrsim, replace, expect):
    text = BAD_BASE.replace(replace[0], replace[1], 1)
    assert text != BAD_BASE
    check_refused_in_one_line(mrsim, write(tmp_path, "bad.nml", text), expect)


def test_force_names_are_unique(tmp_path, mrsim):
    text = BAD_BASE.replace("&output", GOOD + "\n&output")
    scene = write(tmp_path, "dup.nml", text)
    out = subprocess.run([mrsim, str(scene), "-o", str(tmp_path / "d.csv")], capture_output=True, text=True,
                         timeout=60)
    assert out.returncode == 1
    assert "dup.nml:12: &force 'spring': name: used by another &force too (line 10)" in out.stderr
