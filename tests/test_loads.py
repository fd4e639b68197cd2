"""Point loads at markers (&load, issue 32): the forms 'constant', 'sine' and 'table' beside
the 'pulse', forces and torques, body-fixed (follower) and inertial directions, each against
an independent solution: a constant inertial force on a spinning free body (x = F t^2/2m),
a constant follower torque on a revolute joint (theta = M t^2/2I), a pendulum under an
inertial and a body-fixed force against a tight solve_ivp of its equation, a sine load on a
spring-mass against the forced response, a table equal to a constant, the energy balance
with the loads' work (rigid and flexible bodies), and bad input refused with one line.
Scenes are written inline."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import pymr
from refusal import check_refused_in_one_line

TIGHT = "h_slow = 1.0e-3, adaptive = .true., rtol = 1.0e-11, atol = 1.0e-13"


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


# a 2 kg block on a free joint spinning about z at 3 rad/s, the load at its centre of mass
SPINNER = """
&scene title = 'spinning block under a load', t_end = 1.0, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', {integrator} /
&effects firing_load = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'block', kind = 'rigid', mass = 2.0, inertia = 0.5, 0.5, 0.5, 0.0, 0.0, 0.0 /
&joint name = 'mount', kind = 'free', parent = 'ground', child = 'block', qd0 = 0, 0, 0, 0, 0, 3.0 /
&marker name = 'c', body = 'block', at = 0.0, 0.0, 0.0 /
&load marker = 'c', direction = 0.6, 0.8, 0.0, {load} /
&output dt = 1.0e-2, quantities = 'coordinates', 'energy' /
"""


def test_constant_inertial_force_moves_a_spinning_body_by_f_t2_over_2m(tmp_path):
    """F = 3 N along (0.6, 0.8, 0) fixed in space, on a body spinning about z: its centre
    moves by F t^2/(2 m) along that direction however the body turns."""
    scene = write(tmp_path, "spin.nml", SPINNER.format(
        integrator="h_slow = 1.0e-3", load="form = 'constant', offset = 3.0, frame = 'inertial'"))
    res = pymr.run(scene)
    s = 3.0 * res.t**2 / (2 * 2.0)
    assert np.abs(res["mount.q1"] - 0.6 * s).max() < 1e-12
    assert np.abs(res["mount.q2"] - 0.8 * s).max() < 1e-12
    assert np.abs(res["mount.q3"]).max() == 0.0
    # the same force fixed in the body turns with it at w = 3 rad/s: with z = x + i y and
    # d = 0.6 + 0.8 i, m z'' = F d e^(i w t), so z = (F d/m) ((1 - e^(i w t))/w^2 + i t/w)
    body = pymr.run(write(tmp_path, "spin_b.nml", SPINNER.format(
        integrator="h_slow = 1.0e-3", load="form = 'constant', offset = 3.0")))
    w, t = 3.0, body.t
    z = 3.0 * (0.6 + 0.8j) / 2.0 * ((1 - np.exp(1j * w * t)) / w**2 + 1j * t / w)
    err = np.abs(body["mount.q1"] + 1j * body["mount.q2"] - z).max()
    assert err < 1e-9, err


# a rotor on a revolute joint about z, I = 0.4 kg m^2 about the axis, the marker off the axis
ROTOR = """
&scene title = 'rotor under a torque', t_end = 1.0, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', {integrator} /
&effects firing_load = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'rotor', kind = 'rigid', mass = 5.0, inertia = 0.3, 0.3, 0.4, 0.0, 0.0, 0.0 /
&joint name = 'hub', kind = 'revolute', parent = 'ground', child = 'rotor', axis = 0.0, 0.0, 1.0 /
&marker name = 'rim', body = 'rotor', at = 0.5, 0.2, 0.1 /
&load marker = 'rim', kind = 'torque', direction = 0.0, 0.0, 2.0, {load} /
&output dt = 1.0e-2, quantities = 'coordinates', 'energy' /
"""


@pytest.mark.parametrize("frame", ["body", "inertial"])
def test_constant_torque_turns_a_rotor_by_m_t2_over_2i(tmp_path, frame):
    """M = 1.2 N m about the axis (a moment: where the marker is does not matter):
    theta = M t^2/(2 I), the load's work equal to the kinetic energy."""
    scene = write(tmp_path, "rotor.nml", ROTOR.format(
        integrator="h_slow = 1.0e-3", load=f"form = 'constant', offset = 1.2, frame = '{frame}'"))
    res = pymr.run(scene)
    assert np.abs(res["hub.q"] - 1.2 * res.t**2 / (2 * 0.4)).max() < 1e-12
    assert np.abs(res["energy.load_work"] - res["energy.kinetic"]).max() < 1e-9


# a pendulum: a 3 kg bob at 0.8 m from a revolute joint about z, under gravity -y and a
# 20 N load at the bob along (0.6, 0.8, 0), either fixed in space or fixed in the pendulum
PENDULUM = """
&scene title = 'pendulum under a load', t_end = 2.0, gravity = 0.0, -9.81, 0.0 /
&integrator method = 'single', {integrator} /
&effects gravity = .true., firing_load = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'arm', kind = 'rigid', mass = 3.0, com = 0.8, 0.0, 0.0,
      inertia = 0.03, 0.03, 0.05, 0.0, 0.0, 0.0 /
&joint name = 'pivot', kind = 'revolute', parent = 'ground', child = 'arm', axis = 0.0, 0.0, 1.0 /
&marker name = 'bob', body = 'arm', at = 0.8, 0.0, 0.0 /
&load marker = 'bob', direction = 0.6, 0.8, 0.0, form = 'constant', offset = 20.0, frame = '{frame}' /
&output dt = 1.0e-2, quantities = 'coordinates', 'energy' /
"""
M_P, L_P, I_P, F_P, G = 3.0, 0.8, 0.05 + 3.0 * 0.8**2, 20.0, 9.81


def pendulum_reference(t: np.ndarray, frame: str) -> np.ndarray:
    """theta(t) of I theta'' = -m g L cos(theta) + torque of the load: a force F (0.6, 0.8)
    fixed in space at (L cos, L sin) gives F L (0.8 cos(theta) - 0.6 sin(theta)); fixed in the
    arm, F L 0.8 (its part along the arm has no moment). Solved tight."""
    def rhs(_, y):
        th = y[0]
        load = F_P * L_P * (0.8 * np.cos(th) - 0.6 * np.sin(th)) if frame == "inertial" else F_P * L_P * 0.8
        return [y[1], (-M_P * G * L_P * np.cos(y[0]) + load) / I_P]
    sol = solve_ivp(rhs, (0.0, t[-1]), [0.0, 0.0], method="DOP853", t_eval=t, rtol=1e-13, atol=1e-14)
    return sol.y[0]


def test_pendulum_under_an_inertial_and_a_follower_force(tmp_path):
    """The two frames give different motions, each the one its pendulum equation gives."""
    runs = {}
    for frame in ("inertial", "body"):
        scene = write(tmp_path, f"pend_{frame}.nml", PENDULUM.format(integrator=TIGHT, frame=frame))
        res = pymr.run(scene)
        runs[frame] = res["pivot.q"]
        err = np.abs(res["pivot.q"] - pendulum_reference(res.t, frame)).max()
        assert err < 1e-8, (frame, err)
        e, work = res["energy.total"], res["energy.load_work"]
        assert np.abs(work).max() > 1.0
        assert np.abs(e - work - e[0]).max() < 1e-8 * np.abs(work).max()
    assert np.abs(runs["inertial"] - runs["body"]).max() > 0.1


# a 2 kg slider on a prismatic joint along x held by a joint spring of 200 N/m
SPRING_MASS = """
&scene title = 'spring-mass under a load', t_end = 3.0, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', {integrator} /
&effects joint_springs = .true., firing_load = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'slider', kind = 'rigid', mass = 2.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /
&joint name = 'rail', kind = 'prismatic', parent = 'ground', child = 'slider', axis = 1.0, 0.0, 0.0 /
&spring joint = 'rail', stiffness = 200.0 /
&marker name = 'hook', body = 'slider', at = 0.0, 0.3, 0.0 /
&load marker = 'hook', direction = 1.0, 0.0, 0.0, {load} /
&output dt = 1.0e-2, quantities = 'coordinates', 'energy' /
"""


def forced_response(t: np.ndarray, f0: float, a: float, freq: float) -> np.ndarray:
    """x(t) of m x'' + k x = f0 + a sin(W t) from rest at 0 (m = 2, k = 200)."""
    m, k, big_w = 2.0, 200.0, 2 * np.pi * freq
    w = np.sqrt(k / m)
    return f0 / k * (1 - np.cos(w * t)) + a / (k - m * big_w**2) * (np.sin(big_w * t) - big_w / w * np.sin(w * t))


def test_sine_load_on_a_spring_mass_gives_the_forced_response(tmp_path):
    """offset 5 N + 8 N sin(2 pi 1.3 t): the closed-form response, and the work balance."""
    load = "form = 'sine', offset = 5.0, amplitude = 8.0, frequency = 1.3, frame = 'inertial'"
    res = pymr.run(write(tmp_path, "sine.nml", SPRING_MASS.format(integrator=TIGHT, load=load)))
    err = np.abs(res["rail.q"] - forced_response(res.t, 5.0, 8.0, 1.3)).max()
    assert err < 1e-9, err
    e, work = res["energy.total"], res["energy.load_work"]
    assert np.ptp(work) > 0.1
    assert np.abs(e - work - e[0]).max() < 1e-9


def test_table_load_equals_the_constant(tmp_path):
    """A table holding 3 N throughout, plus offset 1 N, is the constant 4 N."""
    (tmp_path / "flat.txt").write_text("# time value\n0.0 3.0\n1.0 3.0\n5.0 3.0\n")
    table = pymr.run(write(tmp_path, "table.nml", SPRING_MASS.format(
        integrator="h_slow = 1.0e-3", load="form = 'table', file = 'flat.txt', offset = 1.0")))
    const = pymr.run(write(tmp_path, "const.nml", SPRING_MASS.format(
        integrator="h_slow = 1.0e-3", load="form = 'constant', offset = 4.0")))
    assert np.abs(table["rail.q"] - const["rail.q"]).max() == 0.0
    assert np.abs(const["rail.q"] - forced_response(const.t, 4.0, 0.0, 1.0)).max() < 1e-8   # fixed step: 2.1e-9


# a beam on a revolute hub about z, loaded at its tip
BEAM = """
&scene title = 'beam under a tip load', t_end = 0.3, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', {integrator} /
&effects firing_load = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'beam', kind = 'beam', length = 2.0, youngs_modulus = 2.0e11, density = 7800.0,
      r_outer = 0.05, r_inner = 0.03, n_elements = 8, modes_y = 2, modes_z = 2 /
&joint name = 'hub', kind = 'revolute', parent = 'ground', child = 'beam', axis = 0.0, 0.0, 1.0 /
&marker name = 'tip', body = 'beam', at = 2.0, 0.0, 0.0 /
&load marker = 'tip', {load} /
&output dt = 1.0e-3, quantities = 'coordinates', 'energy' /
"""


@pytest.mark.parametrize("load", [
    "kind = 'torque', direction = 0.0, 1.0, 1.0, form = 'sine', amplitude = 400.0, frequency = 20.0",
    "kind = 'torque', direction = 0.0, 0.3, 1.0, form = 'constant', offset = 300.0, frame = 'inertial'",
    "kind = 'force', direction = 0.2, 1.0, 0.5, form = 'sine', offset = 50.0, amplitude = 300.0, "
    "frequency = 15.0, frame = 'inertial'",
])
def test_loads_on_a_flexible_body_keep_the_energy_balance(tmp_path, load):
    """Kinetic plus strain energy grows by the loads' work, the moment's through the rotation
    of the marker's frame (its rotation shapes) as well as the hub's."""
    res = pymr.run(write(tmp_path, "beam.nml", BEAM.format(integrator=TIGHT, load=load)))
    e, work, strain = res["energy.total"], res["energy.load_work"], res["energy.strain"]
    assert strain.max() > 1e-3 * np.abs(work).max() > 0.0     # the beam really bends
    assert np.abs(e - work - e[0]).max() < 1e-7 * np.abs(work).max()



# a 2 m steel tube clamped to the ground, a moment about z at its tip, solved statically
CANTILEVER = """
&scene title = 'cantilever under a tip moment', t_end = 1.0e-3, gravity = 0.0, 0.0, 0.0, start = 'static' /
&integrator method = 'single', h_slow = 1.0e-3, adaptive = .true. /
&effects firing_load = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'beam', kind = 'beam', length = 2.0, youngs_modulus = 2.0e11, density = 7800.0,
      r_outer = 0.05, r_inner = 0.03, n_elements = 20, modes_y = {modes}, modes_z = 1 /
&joint name = 'clamp', kind = 'fixed', parent = 'ground', child = 'beam' /
&marker name = 'tip', body = 'beam', at = 2.0, 0.0, 0.0 /
&load marker = 'tip', kind = 'torque', direction = 0.0, 0.0, 1.0, form = 'constant', offset = 1000.0 /
&output dt = 1.0e-3, quantities = 'markers', 'marker_orientations' /
"""


def test_tip_moment_bends_a_cantilever_by_m_l2_over_2ei(tmp_path):
    """Euler-Bernoulli: a tip moment M gives the tip deflection M L^2/(2 E I) and slope
    M L/(E I). The modal model converges to both as modes are added (the slope slowly, the
    moment's static shape being a sum of all modes): measured deflection 0.970, 0.9964,
    0.99912 and slope 0.801, 0.933, 0.966 of the exact ones with 2, 6 and 12 modes."""
    ei = 2.0e11 * np.pi / 4 * (0.05**4 - 0.03**4)
    y_exact, slope_exact = 1000.0 * 2.0**2 / (2 * ei), 1000.0 * 2.0 / ei
    ys, slopes = [], []
    for modes in (2, 6, 12):
        res = pymr.run(write(tmp_path, f"cant{modes}.nml", CANTILEVER.format(modes=modes)))
        ys.append(res["tip.y"][0] / y_exact)
        slopes.append(2 * np.arcsin(res["tip.qz"][0]) / slope_exact)
    assert np.all(np.diff(ys) > 0) and np.all(np.diff(slopes) > 0)
    assert abs(ys[-1] - 1) < 1.0e-3 and abs(slopes[-1] - 1) < 0.04

# ----------------------------------------------------------------------- short pulses

# 2 kg on a frictionless rail, hit by a pulse far shorter than the steps the motion allows
SLIDER = """
&scene title = 'slider hit by a short pulse', t_end = 0.01, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', {integrator} /
&effects firing_load = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'slider', kind = 'rigid', mass = 2.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /
&joint name = 'rail', kind = 'prismatic', parent = 'ground', child = 'slider', axis = 1.0, 0.0, 0.0 /
&marker name = 'm', body = 'slider' /
&load marker = 'm', direction = 1.0, 0.0, 0.0, peak = 1000.0, start = 0.00105, duration = 1.0e-4 /
&output quantities = 'coordinates', 'energy' /
"""


@pytest.mark.parametrize("formula", ["adams", "abm4"])
def test_a_pulse_shorter_than_the_steps_gives_its_impulse(tmp_path, formula):
    """A 0.1 ms half-sine pulse of 1 kN on 2 kg, with steps of up to 1 ms around it: the
    slider leaves at J/m = 2 peak duration/(pi m) and has moved by J/m (t_end - start -
    duration/2), to 1e-7 (measured 1.7e-8 'adams', 2.8e-10 'abm4'), and its kinetic energy
    is the load's work, to 1e-5 (measured 1.9e-8 'adams'; 8.9e-7 'abm4' at any rtol: the
    work's quadrature over its Runge-Kutta starts after each stop). Adaptive steps end on
    the pulse's start, peak and end; before they did, a step passed over the whole pulse
    (both ends, where the load is 0, evaluated) and the slider never moved."""
    scene = write(tmp_path, "slider.nml", SLIDER.format(
        integrator=f"formula = '{formula}', h_slow = 1.0e-3, adaptive = .true., rtol = 1.0e-9, atol = 1.0e-11"))
    res = pymr.run(scene)
    v = 2 * 1000.0 * 1.0e-4 / (np.pi * 2.0)
    assert res["rail.qd"][-1] == pytest.approx(v, rel=1e-7)
    assert res["rail.q"][-1] == pytest.approx(v * (0.01 - 0.00105 - 0.5e-4), rel=1e-7)
    assert res["energy.load_work"][-1] == pytest.approx(0.5 * 2.0 * v**2, rel=1e-5)


# the beam on its hub, a 0.1 ms, 10 kN pulse across its tip
PULSE = "kind = 'force', direction = 0.0, 1.0, 0.0, frame = 'inertial', peak = 1.0e4, start = 0.00505, duration = 1.0e-4"


@pytest.mark.parametrize("integrator", [
    "method = 'single'", "method = 'single', formula = 'abm4'", "method = 'multirate', coupling = 'response'",
    "method = 'multirate', coupling = 'exponential'", "method = 'auto'"])
def test_every_adaptive_method_feels_a_short_pulse_on_a_flexible_body(tmp_path, integrator):
    """The beam on its free hub, hit across its tip by a pulse a tenth of a millisecond long,
    at rtol 1e-8: the hub's rate and a modal rate at 20 ms are those of fixed steps of 5e-7
    and 2.5e-7 s extrapolated (order 2: the pulse's slope jumps at its ends), to 1e-6
    relative (measured 1.7e-8 to 3.4e-7). Steps end on the pulse's start,
    peak and end (a start again after each, bounded by the step it was taking: 'abm4''s
    and 'response''s Runge-Kutta start, unchecked before, carried 7 % into the hub's rate
    from the pulse's end); before, 'adams', 'response' and 'auto' stepped over a 1 ms
    pulse unseen."""
    base = BEAM.replace("t_end = 0.3", "t_end = 0.02").replace("method = 'single', ", "")
    fixed = [pymr.run(write(tmp_path, f"f{k}.nml", base.format(integrator=f"method = 'single', h_slow = {h}",
                                                                load=PULSE)))
             for k, h in enumerate(("5.0e-7", "2.5e-7"))]
    res = pymr.run(write(tmp_path, "a.nml", base.format(
        integrator=integrator + ", h_slow = 1.0e-3, adaptive = .true., rtol = 1.0e-8, atol = 1.0e-10", load=PULSE)))
    for column in ("hub.qd", "beam.ad1"):
        ref = fixed[1][column][-1] + (fixed[1][column][-1] - fixed[0][column][-1]) / 3
        assert abs(res[column][-1] - ref) < 1e-6 * abs(ref), (column, res[column][-1], ref)
    assert abs(fixed[1]["hub.qd"][-1]) > 0.1


# ----------------------------------------------------------------------- bad input

BAD_BASE = """&scene title = 'spring-mass under a load', t_end = 0.1, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', h_slow = 1.0e-3 /
&effects joint_springs = .true., firing_load = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'slider', kind = 'rigid', mass = 2.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /
&joint name = 'rail', kind = 'prismatic', parent = 'ground', child = 'slider', axis = 1.0, 0.0, 0.0 /
&spring joint = 'rail', stiffness = 200.0 /
&marker name = 'hook', body = 'slider', at = 0.0, 0.3, 0.0 /
&load marker = 'hook', direction = 1.0, 0.0, 0.0,
      form = 'constant', offset = 4.0 /
&output dt = 1.0e-2 /
"""


@pytest.mark.parametrize("replace, expect", [
    (("form = 'constant'", "form = 'table'"), r":9: &load #1: file: missing \(form 'table'"),
    (("form = 'constant'", "form = 'wave'"), r":10: &load #1: form: 'wave' is not one of: pulse, constant, sine, table"),
    (("direction", "kind = 'push', direction"), r":9: &load #1: kind: 'push' is not one of: force, torque"),
    (("direction", "frame = 'world', direction"), r":9: &load #1: frame: 'world' is not one of: body, inertial"),
    (("form = 'constant', offset = 4.0", "amplitude = 3.0, duration = 0.1"),
     r":10: &load #1: amplitude: not used by form 'pulse'"),
    (("form = 'constant', offset = 4.0", "peak = 3.0"), r":9: &load #1: duration: missing \(the pulse length, s\)"),
    (("offset = 4.0", "offset = 4.0, peak = 1.0"), r":10: &load #1: peak: only form 'pulse' uses it \(form is 'constant'\)"),
    (("offset = 4.0", "offset = 4.0, start = 0.2"), r":10: &load #1: start: only form 'pulse' uses it"),
    (("offset = 4.0", "offset = 4.0, frequency = 2.0"), r":10: &load #1: frequency: not used by form 'constant'"),
    (("form = 'constant'", "form = 'sine', file = 'flat.txt'"),
     r":10: &load #1: file: only form 'table' reads a file \(form is 'sine'\)"),
    (("form = 'constant'", "form = 'table', file = 'flat.txt', amplitude = 1.0"),
     r":10: &load #1: amplitude: not used by form 'table'"),
    (("form = 'constant'", "form = 'table', file = 'nofile.txt'"), r":10: &load #1: file: '.*nofile.txt' not found"),
    (("direction = 1.0, 0.0, 0.0", "direction = 0.0, 0.0, 0.0"), r":9: &load #1: direction: missing or zero"),
    (("marker = 'hook'", "marker = 'nowhere'"), r":9: &load #1: marker: no &marker named 'nowhere'"),
    ((", firing_load = .true.", ""), r":9: &load #1.*&effects firing_load is not on"),
    (("form = 'constant', offset = 4.0", "peak = 3.0, start = 0.05, duration = 5.0e-4"),
     r":10: &load #1: duration: a pulse of 0.0005 s is shorter than the fixed step h_slow = 0.001 s"),
])
def test_bad_loads_are_refused_with_one_line(tmp_path, mrsim, replace, expect):
    text = BAD_BASE.replace(replace[0], replace[1], 1)
    assert text != BAD_BASE
    (tmp_path / "flat.txt").write_text("0.0 3.0\n1.0 3.0\n")
    check_refused_in_one_line(mrsim, write(tmp_path, "bad.nml", text), expect)


def test_the_good_base_runs(tmp_path):
    """The base of the bad inputs is itself good: x = F/k (1 - cos w t)."""
    res = pymr.run(write(tmp_path, "good.nml", BAD_BASE))
    assert np.abs(res["rail.q"] - forced_response(res.t, 4.0, 0.0, 1.0)).max() < 1e-8
