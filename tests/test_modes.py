"""pymr modes: natural frequencies, damping ratios and shapes of the linearised model (the
pre-flight check's linearisation), against analytic values."""
from __future__ import annotations

import csv
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy.optimize import brentq

import pymr

ROOT = Path(__file__).resolve().parent.parent


def test_double_pendulum_hanging_matches_its_small_oscillation_frequencies():
    """input/double_pendulum.nml hanging straight down: the two frequencies equal those of
    the small-oscillation equations written by hand (M and K of the two links about the
    hanging state, a second formulation): 0.426541 and 1.143819 Hz, to 1e-7 relative; no
    damping."""
    scene = ROOT / "input" / "double_pendulum.nml"
    freq, zeta, shapes = pymr.modes(scene, [-np.pi / 2, 0.0], [0.0, 0.0])
    m, c, l1, inertia, g = 1.0, 0.5, 1.0, 0.0834, 9.81
    mass = np.array([[2 * inertia + m * c * c + m * (l1 * l1 + 2 * l1 * c + c * c), m * (l1 * c + c * c) + inertia],
                     [m * (l1 * c + c * c) + inertia, m * c * c + inertia]])
    stiff = g * np.array([[m * c + m * (l1 + c), m * c], [m * c, m * c]])
    exact = np.sqrt(np.sort(np.linalg.eigvals(np.linalg.solve(mass, stiff)).real)) / (2 * np.pi)
    assert freq == pytest.approx(exact, rel=1e-7)
    assert np.abs(zeta).max() < 1e-9
    assert shapes.shape == (2, 2) and np.allclose(np.abs(shapes).max(axis=0), 1.0)
    # the first mode swings both links the same way, the second against each other
    assert shapes[0, 0] * shapes[1, 0] > 0 > shapes[0, 1] * shapes[1, 1]


def test_clamped_barrel_has_the_cantilever_frequencies(tmp_path):
    """The tank's barrel clamped to the ground, gravity off: two bending modes per plane at
    the Euler-Bernoulli cantilever's frequencies (beta L = 1.8751, 4.6941): 6.409 and
    40.16 Hz, to 1e-5 relative (20 Hermite elements)."""
    scene = tmp_path / "barrel.nml"
    scene.write_text("""&scene title = 'clamped barrel', t_end = 0.01, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', h_slow = 1.0e-4 /
&body name = 'ground', kind = 'ground' /
&body name = 'gun', kind = 'beam', length = 5.3, youngs_modulus = 2.07e11, density = 7850.0,
      r_outer = 0.11, r_inner = 0.06, n_elements = 20, modes_y = 2, modes_z = 2 /
&joint name = 'clamp', kind = 'fixed', parent = 'ground', child = 'gun' /
""")
    n = pymr.model_size(scene)[0]
    freq, zeta, _ = pymr.modes(scene, np.zeros(n), np.zeros(n))
    e, rho, ro, ri, length = 2.07e11, 7850.0, 0.11, 0.06, 5.3
    ei = e * np.pi / 4 * (ro**4 - ri**4)
    area = np.pi * (ro**2 - ri**2)
    roots = [brentq(lambda b: np.cos(b) * np.cosh(b) + 1.0, lo, hi) for lo, hi in ((1.0, 3.0), (4.0, 5.5))]
    exact = np.repeat([b * b / (2 * np.pi * length**2) * np.sqrt(ei / (rho * area)) for b in roots], 2)
    assert exact[0] == pytest.approx(6.409, abs=1e-3) and exact[2] == pytest.approx(40.16, abs=1e-2)
    assert freq == pytest.approx(exact, rel=1e-5)
    assert np.abs(zeta).max() < 1e-9


def test_damped_oscillator_has_its_damping_ratio(tmp_path):
    """A 2 kg slider on a spring of 800 N/m with a damper of 8 N s/m: the natural frequency
    sqrt(k/m)/(2 pi) = 3.1831 Hz and the damping ratio c/(2 sqrt(k m)) = 0.1, to 1e-7."""
    scene = tmp_path / "osc.nml"
    scene.write_text("""&scene title = 'damped oscillator', t_end = 0.01, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', h_slow = 1.0e-3 /
&effects joint_springs = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'block', kind = 'rigid', mass = 2.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /
&joint name = 'rail', kind = 'prismatic', parent = 'ground', child = 'block', axis = 1.0, 0.0, 0.0 /
&spring joint = 'rail', stiffness = 800.0, damping = 8.0 /
""")
    freq, zeta, shapes = pymr.modes(scene, [0.0], [0.0])
    assert freq == pytest.approx([np.sqrt(800.0 / 2.0) / (2 * np.pi)], rel=1e-7)
    assert zeta == pytest.approx([8.0 / (2 * np.sqrt(800.0 * 2.0))], rel=1e-7)
    assert shapes.shape == (1, 1) and shapes[0, 0] == 1.0


def test_mode_shapes_as_marker_displacements():
    """The double pendulum hanging: a mode shape (theta1, theta2) (theta2 relative) moves
    the tip, 2 m below the pivot and 1 m below the second joint, by (2 theta1 + theta2, 0, 0)
    (rotations about z of the two lever arms), to 1e-8 m."""
    scene = ROOT / "input" / "double_pendulum.nml"
    q, qd = np.array([-np.pi / 2, 0.0]), np.zeros(2)
    freq, zeta, shapes = pymr.modes(scene, q, qd)
    tip = pymr.marker_shapes(scene, ["tip"], q, qd, shapes)["tip"]
    assert tip.shape == (3, 2)
    assert tip[0] == pytest.approx(2 * shapes[0] + shapes[1], abs=1e-8)
    assert np.abs(tip[1:]).max() < 1e-8


def test_modes_command_writes_the_tank_s_coupled_modes(tmp_path):
    """pymr modes on the tank at rest: the free turret and elevation joints are rigid-body
    motions (labelled 'rigid'), and four vibrations remain, the barrel's modes coupled to the joints, above the clamped
    6.409 and 40.16 Hz (measured 8.85, 20.3, 41.6, 52.9 Hz); the CSV holds them with a shape
    column per coordinate. --at 0.5 linearises at the run's state at 0.5 s."""
    tank = ROOT / "input" / "tank_gun_turret.nml"
    out = tmp_path / "modes.csv"
    r = subprocess.run(["pymr", "modes", str(tank), "-o", str(out)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader(out.open()))
    # the free turret and elevation are the two rigid-body motions, labelled as such (issue 30)
    assert [row["kind"] for row in rows] == ["rigid", "rigid"] + ["vibration"] * 4
    rows = [row for row in rows if row["kind"] == "vibration"]
    freq = np.array([float(row["frequency_hz"]) for row in rows])
    assert len(rows) == 4 and set(rows[0]) >= {"traverse.q", "elevation.q", "gun.a1", "gun.a4"}
    assert freq[0] > 6.409 and freq[2] > 40.16 and np.all(np.diff(freq) > 0)
    assert freq == pytest.approx([8.85, 20.3, 41.6, 52.9], abs=0.05)
    assert {"muzzle.dx", "muzzle.dy", "muzzle.dz"} <= set(rows[0])      # shapes as marker displacements
    # each mode moves the muzzle; the largest motion of each is the barrel's own bending
    assert all(np.hypot(float(row["muzzle.dy"]), float(row["muzzle.dz"])) > 1e-3 for row in rows)
    assert all(max(("traverse.q", "elevation.q", "gun.a1", "gun.a2", "gun.a3", "gun.a4"),
                   key=lambda c: abs(float(row[c]))).startswith("gun.") for row in rows)
    r = subprocess.run(["pymr", "modes", str(tank), "--at", "0.5", "-o", str(out)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0 and "linearised at t = 0.5 s" in r.stdout, r.stderr


BARREL = """&scene title = 'clamped barrel', t_end = 1.0, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', h_slow = 1.0e-4 /
&body name = 'ground', kind = 'ground' /
&body name = 'gun', kind = 'beam', length = 5.3, youngs_modulus = 2.07e11, density = 7850.0,
      r_outer = 0.11, r_inner = 0.06, n_elements = 20, modes_y = 2, modes_z = 2{state} /
&joint name = 'clamp', kind = 'fixed', parent = 'ground', child = 'gun' /
&output dt = 1.0e-3 /
"""


def test_a_flexible_body_starts_from_its_given_modal_state(tmp_path):
    """&body a0, ad0 (issue 17): the clamped barrel started with a1 = 0.01 and ad2 = 0.5 (in
    m kg^0.5 and per second) swings in its first two modes alone: a1 = 0.01 cos(w1 t) and
    a2 = 0.5/w2 sin(w2 t), w the Euler-Bernoulli cantilever's (6.409 and 40.16 Hz), over
    1 s to 2e-3 of the amplitudes (the model's frequencies differ from the analytic ones by
    about 1e-6)."""
    scene = tmp_path / "barrel.nml"
    scene.write_text(BARREL.format(state=", a0 = 0.01, 0.0, 0.0, 0.0, ad0 = 0.0, 0.5, 0.0, 0.0"))
    res = pymr.run(scene, tmp_path / "b.csv")
    e, rho, ro, ri, length = 2.07e11, 7850.0, 0.11, 0.06, 5.3
    c = np.sqrt(e * np.pi / 4 * (ro**4 - ri**4) / (rho * np.pi * (ro**2 - ri**2))) / length**2
    w1, w2 = (brentq(lambda b: np.cos(b) * np.cosh(b) + 1.0, lo, hi) ** 2 * c for lo, hi in ((1.0, 3.0), (4.0, 5.5)))
    assert np.abs(res["gun.a1"] - 0.01 * np.cos(w1 * res.t)).max() < 2e-3 * 0.01
    assert np.abs(res["gun.a2"] - 0.5 / w2 * np.sin(w2 * res.t)).max() < 2e-3 * 0.5 / w2
    assert np.abs(res["gun.a3"]).max() == 0.0 and np.abs(res["gun.a4"]).max() == 0.0


@pytest.mark.parametrize("state, item", [(", a0 = 0.01, 0.0, 0.0", "a0"), (", ad0 = 1.0", "ad0")])
def test_a_modal_state_must_give_every_mode(tmp_path, state, item):
    scene = tmp_path / "barrel.nml"
    scene.write_text(BARREL.format(state=state))
    with pytest.raises(pymr.SceneError, match=rf"barrel.nml:5: &body 'gun': {item}: give one value per mode "
                                              rf"\(4 modes\), got \d"):
        pymr.run(scene, tmp_path / "b.csv")
