"""A static start (&scene start = 'static', &joint settle; issue 17 item 1): the modal
coordinates, and the coordinates of joints marked settle, in static equilibrium at t = 0.

Independent expectations: the cantilever's tip deflection from the continuous Euler-Bernoulli
modes truncated as the scene truncates them (and w L^4/(8 EI) in the limit), a pendulum's
equilibrium angle under a constant torque, and a still muzzle (a state of equilibrium does
not move)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import quad
from scipy.optimize import brentq

import pymr

ROOT = Path(__file__).resolve().parents[1]
HOLD = ROOT / "input" / "tank_hold.nml"

# tank_hold.nml's barrel: a steel tube, 5.3 m, r 0.11 / 0.06 m
E, RHO, R_OUT, R_IN, LENGTH, G = 2.07e11, 7850.0, 0.11, 0.06, 5.3, 9.81


def held_tank(tmp_path: Path) -> Path:
    """The hold scene with both joints held by prescribed motion (so that the barrel is a
    cantilever on a fixed mount) instead of drive torques."""
    text = HOLD.read_text()
    text = text.replace("&drive joint = 'traverse', offset = 0.0 /", "&motion joint = 'traverse', offset = 0.0 /")
    text = text.replace("&drive joint = 'elevation', offset = -33451.0 /", "&motion joint = 'elevation', offset = 0.0 /")
    text = text.replace("joint_drives = .true.", "base_motion = .true.")
    path = tmp_path / "held.nml"
    path.write_text(text)
    return path


def cantilever_truncation(n: int) -> float:
    """Tip deflection under a uniform load over w L^4/(8 EI) from the first n modes of the
    continuous clamped-free Euler-Bernoulli beam (each mode's static share
    phi_i(L) int phi_i / (int phi_i^2 beta_i^4), L = EI = w = 1)."""
    def phi(b, x):
        s = (math.cosh(b) + math.cos(b)) / (math.sinh(b) + math.sin(b))
        return math.cosh(b * x) - math.cos(b * x) - s * (math.sinh(b * x) - math.sin(b * x))
    total = 0.0
    for k in range(n):
        b = brentq(lambda b: math.cos(b) * math.cosh(b) + 1.0, (k + 0.5) * math.pi - 1.0 + (k == 0) * 0.6,
                   (k + 0.5) * math.pi + 1.0)
        norm = quad(lambda x: phi(b, x) ** 2, 0.0, 1.0, limit=200)[0]
        share = quad(lambda x: phi(b, x), 0.0, 1.0, limit=200)[0]
        total += phi(b, 1.0) * share / (norm * b ** 4)
    return 8.0 * total


@pytest.mark.parametrize("modes", [1, 2, 4])
def test_static_tip_of_the_cantilever_is_the_truncated_modal_solution(tmp_path, modes):
    """The barrel held on its mount, started static: the muzzle sits below its undeformed
    place by w L^4/(8 EI) times the truncation of its modes (1.0134, 0.99909, 0.999958 for
    1, 2 and 4 modes per plane), to 1e-6 (measured 1e-10)."""
    scene = held_tank(tmp_path)
    over = {"body[gun].modes_y": modes, "body[gun].modes_z": modes, "scene.t_end": 1e-3}
    rest = pymr.run(scene, overrides={**over, "scene.start": "rest"}).marker("muzzle")[0][0]
    static = pymr.run(scene, overrides={**over, "scene.start": "static"}).marker("muzzle")[0][0]
    area, inertia = math.pi * (R_OUT ** 2 - R_IN ** 2), math.pi / 4 * (R_OUT ** 4 - R_IN ** 4)
    exact = RHO * area * G * LENGTH ** 4 / (8 * E * inertia)
    sag = rest[1] - static[1]
    assert sag / exact == pytest.approx(cantilever_truncation(modes), rel=1e-6)
    assert abs(rest[0] - static[0]) < 1e-3 * sag and abs(rest[2] - static[2]) < 1e-9


def test_a_static_start_stays_still(tmp_path):
    """Started static, the held barrel does not move: the muzzle stays within 1e-9 m of its
    start over 1 s (measured 0); started undeformed it swings about the sag by twice it
    (measured 18.9 mm)."""
    scene = held_tank(tmp_path)
    over = {"integrator.adaptive": True, "integrator.rtol": 1e-10, "integrator.atol": 1e-12}
    static = pymr.run(scene, overrides={**over, "scene.start": "static"}).marker("muzzle")[0]
    assert np.linalg.norm(static - static[0], axis=1).max() <= 1e-9
    rest = pymr.run(scene, overrides={**over, "scene.start": "rest"}).marker("muzzle")[0]
    assert np.linalg.norm(rest - rest[0], axis=1).max() > 0.015


def test_a_joint_marked_settle_finds_its_equilibrium_angle(tmp_path):
    """A 1 kg pendulum (1 m) under a constant 3 N m torque, its pivot marked settle and
    started at 1 rad: it settles where m g l sin(theta) = T, theta = asin(3/9.81), to 1e-10
    rad, and stays there."""
    text = (ROOT / "input" / "pendulum.nml").read_text()
    text = text.replace("gravity = .true.", "gravity = .true., joint_drives = .true.")
    text += "\n&drive joint = 'pivot', offset = 3.0 /\n"
    scene = tmp_path / "pendulum.nml"
    scene.write_text(text)
    res = pymr.run(scene, overrides={"scene.start": "static", "joint[pivot].settle": True, "scene.t_end": 1.0,
                                     "integrator.adaptive": True, "integrator.rtol": 1e-10, "integrator.atol": 1e-12})
    q, _ = res.coordinates()
    assert q[0, 0] == pytest.approx(math.asin(3.0 / 9.81), abs=1e-10)
    assert np.abs(q[:, 0] - q[0, 0]).max() < 1e-9


@pytest.mark.parametrize("over, message", [
    ({"joint[elevation].settle": True}, r"&joint 'elevation': settle: joints settle only in a static start"),
    ({"scene.start": "static", "joint[bracket].settle": True},
     r"&joint 'bracket': settle: a 'fixed' joint has no coordinates to settle"),
    ({"scene.start": "static", "joint[elevation].settle": True},
     r"&scene: start: no static equilibrium at t = 0: the stiffness of the coordinates to settle is singular"),
    ({"scene.start": "steady"}, r"&scene: start: "),
])
def test_static_starts_that_cannot_be_are_one_line_errors(tmp_path, over, message):
    """The drive-held hold scene has no equilibrium angle for its elevation (a constant torque
    near the horizontal: no stiffness)."""
    with pytest.raises(pymr.SceneError, match=message):
        pymr.run(HOLD, tmp_path / "x.csv", overrides=over)
