"""Feedback drives (&control, issue 32): a PD controller on a rotor against the closed-form
closed loop (and its frequency and damping ratio fitted from the response), a pendulum's
settled error under gravity against the static balance kp e = m g l sin(th), zero error
with ki and the integral that holds the weight, the bang-bang parabola of a saturated
drive, the orientation sensor against the coordinate sensor on a rigid body and, on a
flexible beam, against its tip frame's written orientation (settled angle, and the rate
through the drive's work), the integral carried through a restart and a multirate run,
the energy balance, and bad input refused in one line. Scenes are written inline."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import pymr
from refusal import check_refused_in_one_line

# a rotor of inertia J about z on a revolute joint, no gravity, driven by a controller
ROTOR = """
&scene title = 'servo on a rotor', t_end = {t_end}, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', {integrator} /
&effects controls = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'rotor', kind = 'rigid', mass = 1.0, inertia = 1.0, 1.0, 2.0, 0.0, 0.0, 0.0 /
&joint name = 'shaft', kind = 'revolute', parent = 'ground', child = 'rotor', axis = 0.0, 0.0, 1.0 /
&marker name = 'rim', body = 'rotor', at = 1.0, 0.0, 0.0 /
&control name = 'servo', joint = 'shaft', {control} /
&output dt = 1.0e-2, quantities = 'coordinates', 'energy' /
"""
J_ROTOR = 2.0

# a pendulum (1 kg bob 1 m below the pivot, axis z) under gravity, held by a controller
PENDULUM = """
&scene title = 'servo on a pendulum', t_end = {t_end}, gravity = 0.0, -9.81, 0.0 /
&integrator method = 'single', h_slow = 1.0e-3 /
&effects gravity = .true., controls = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'bob', kind = 'rigid', mass = 1.0, com = 0.0, -1.0, 0.0,
      inertia = 4.0e-5, 4.0e-5, 4.0e-5, 0.0, 0.0, 0.0 /
&joint name = 'pivot', kind = 'revolute', parent = 'ground', child = 'bob', axis = 0.0, 0.0, 1.0 /
&marker name = 'tip', body = 'bob', at = 0.0, -1.0, 0.0 /
&control name = 'servo', joint = 'pivot', {control} /
&output dt = 1.0e-2, quantities = 'coordinates', 'energy' /
"""
MGL, J_PEND = 9.81, 1.0 + 4.0e-5


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def rotor(tmp_path: Path, control: str, integrator: str = "h_slow = 1.0e-3", t_end: float = 3.0,
          name: str = "rotor.nml") -> Path:
    return write(tmp_path, name, ROTOR.format(control=control, integrator=integrator, t_end=t_end))


def pendulum(tmp_path: Path, control: str, t_end: float, name: str = "pend.nml") -> Path:
    return write(tmp_path, name, PENDULUM.format(control=control, t_end=t_end))


def second_order_step(t: np.ndarray, j: float, kp: float, kd: float, sp: float, k: float | None = None):
    """th(t) of j th'' + kd th' + k th = kp sp from rest at 0 (k = kp unless given)."""
    k = kp if k is None else k
    wn, final = np.sqrt(k / j), kp * sp / k
    zeta = kd / (2 * np.sqrt(k * j))
    wd = wn * np.sqrt(1 - zeta**2)
    return final * (1 - np.exp(-zeta * wn * t) * (np.cos(wd * t) + zeta * wn / wd * np.sin(wd * t)))


@pytest.mark.parametrize("dynamics", ["articulated", "mass_matrix"])
def test_pd_rotor_follows_the_closed_form_closed_loop(tmp_path, dynamics):
    """J th'' + kd th' + kp th = kp sp (J = 2, kp = 50, kd = 4, sp = 0.5): the rotor's angle
    against the closed form to 1e-9 rad on both solution paths, and the natural frequency
    and damping ratio fitted from the simulated response within 1e-7 of sqrt(kp/J) and
    kd/(2 sqrt(kp J))."""
    from scipy.optimize import least_squares
    kp, kd, sp = 50.0, 4.0, 0.5
    res = pymr.run(rotor(tmp_path, f"kp = {kp}, kd = {kd}, setpoint = {sp}",
                         f"h_slow = 1.0e-3, dynamics = '{dynamics}'"))
    th = res["shaft.q"]
    assert np.abs(th - second_order_step(res.t, J_ROTOR, kp, kd, sp)).max() < 1e-9

    def residual(p):
        wn, zeta = p
        return second_order_step(res.t, 1.0, wn**2, 2 * zeta * wn, sp) - th
    wn, zeta = least_squares(residual, [4.0, 0.1], xtol=1e-15, ftol=1e-15, gtol=1e-15).x
    assert abs(wn / np.sqrt(kp / J_ROTOR) - 1) < 1e-7, wn
    assert abs(zeta / (kd / (2 * np.sqrt(kp * J_ROTOR))) - 1) < 1e-7, zeta
    assert res.stats["effects"]["controls"]["evaluations"] > 0


def test_pendulum_settles_with_the_static_error_of_its_weight(tmp_path):
    """PD (kp = 100, kd = 20) holding a pendulum at sp = 0.3 rad: it settles where
    kp (sp - th) = m g l sin th (solved by Newton here), to 1e-9 rad; a small step
    (sp = 1e-3) follows the linearised loop J th'' + kd th' + (kp + m g l) th = kp sp to
    1e-6 of the step."""
    kp, kd = 100.0, 20.0
    res = pymr.run(pendulum(tmp_path, f"kp = {kp}, kd = {kd}, setpoint = 0.3", 8.0))
    th = 0.3
    for _ in range(50):
        th -= (kp * (0.3 - th) - MGL * np.sin(th)) / (-kp - MGL * np.cos(th))
    assert abs(res["pivot.q"][-1] - th) < 1e-9, res["pivot.q"][-1] - th
    assert 0.3 - th > 0.01                                          # a real offset
    small = pymr.run(pendulum(tmp_path, f"kp = {kp}, kd = {kd}, setpoint = 1.0e-3", 2.0, "small.nml"))
    linear = second_order_step(small.t, J_PEND, kp, kd, 1e-3, k=kp + MGL)
    assert np.abs(small["pivot.q"] - linear).max() < 1e-6 * 1e-3


def test_integral_action_removes_the_error_and_holds_the_weight(tmp_path):
    """PID (ki = 200) at sp = 0.3 rad: the settled angle is the setpoint (to 1e-9 rad) and
    the integral state holds the weight, ki I = m g l sin(sp) (to 1e-8 relative)."""
    res = pymr.run(pendulum(tmp_path, "kp = 100.0, kd = 20.0, ki = 200.0, setpoint = 0.3", 20.0))
    assert abs(res["pivot.q"][-1] - 0.3) < 1e-9
    assert abs(200.0 * res["servo.integral"][-1] / (MGL * np.sin(0.3)) - 1) < 1e-8
    assert res.column_info[[c.name for c in res.column_info].index("servo.integral")].unit == "rad s"


def test_modes_linearise_the_closed_loop_with_its_integral(tmp_path):
    """pymr.modes of the PID pendulum at rest: the roots of J s^3 + kd s^2 + (kp + m g l) s
    + ki (a vibration and a decaying drift, to 1e-6 relative: central differences), and
    the controller's double integral as the one rigid-body motion (nothing depends on it)."""
    kp, kd, ki = 100.0, 20.0, 200.0
    scene = pendulum(tmp_path, f"kp = {kp}, kd = {kd}, ki = {ki}", 1.0)
    m = pymr.modes(scene, np.zeros(2), np.zeros(2))
    roots = np.roots([J_PEND, kd, kp + MGL, ki])
    pair, real = roots[np.abs(roots.imag) > 0][0], roots[np.abs(roots.imag) == 0][0].real
    assert len(m.frequency) == 1 and len(m.drift_rate) == 1 and m.rigid.shape[1] == 1
    assert abs(m.frequency[0] * 2 * np.pi / abs(pair) - 1) < 1e-6               # natural frequency |lambda|
    assert abs(m.damping[0] / (-pair.real / abs(pair)) - 1) < 1e-6
    assert abs(m.drift_rate[0] / real - 1) < 1e-6
    assert np.allclose(np.abs(m.rigid[:, 0]), [0.0, 1.0])


def test_a_saturated_drive_follows_the_bang_bang_parabola(tmp_path):
    """kp = 1e4 and max_effort = 1 N m towards sp = 1 rad: the effort stays at its limit
    until the rotor is within 1e-4 rad, so th = (max_effort/J) t^2/2 up to th = 0.9 sp (to
    1e-10 rad), and the drive's work is max_effort th."""
    res = pymr.run(rotor(tmp_path, "kp = 1.0e4, setpoint = 1.0, max_effort = 1.0"))
    th, t = res["shaft.q"], res.t
    early = th < 0.9
    assert t[early][-1] > 1.8
    assert np.abs(th[early] - 0.5 / J_ROTOR * t[early]**2).max() < 1e-10
    assert np.abs(res["energy.drive_work"][early] - th[early]).max() < 1e-9
    assert th.max() > 1.0                                           # it overshoots: bang-bang


@pytest.mark.parametrize("scene", ["rotor", "pendulum"])
def test_orientation_sensor_on_the_driven_body_equals_the_coordinate_sensor(tmp_path, scene):
    """A gyro on the driven rigid body about the joint's axis measures the joint angle and
    rate: the runs agree to 1e-12 rad (the rotor turns past pi, where the error wraps)."""
    gains = "kp = 50.0, kd = 4.0, ki = 5.0, setpoint = 0.3"
    gyro = ", sensor = 'orientation', marker = '{}', axis = 0.0, 0.0, 1.0"
    if scene == "rotor":
        runs = [pymr.run(rotor(tmp_path, gains + extra, name=f"r{i}.nml"))
                for i, extra in enumerate(["", gyro.format("rim")])]
    else:
        runs = [pymr.run(pendulum(tmp_path, gains + extra, 4.0, name=f"p{i}.nml"))
                for i, extra in enumerate(["", gyro.format("tip")])]
    assert np.abs(runs[0].data - runs[1].data).max() < 1e-12
    assert np.abs(runs[0].coordinates()[0][:, 0]).max() > 0.29


def test_orientation_error_takes_the_short_way_round(tmp_path):
    """Setpoint 3 rad, the gyro's angle in (-pi, pi]: a rotor started at -3 rad turns
    through pi (0.28 rad away), not back through 0 (6 rad), and settles at 3 - 2 pi."""
    text = ROTOR.format(control="kp = 50.0, kd = 20.0, setpoint = 3.0, sensor = 'orientation', marker = 'rim', "
                        "axis = 0.0, 0.0, 1.0", integrator="h_slow = 1.0e-3", t_end=6.0)
    res = pymr.run(write(tmp_path, "wrap.nml", text.replace("axis = 0.0, 0.0, 1.0 /", "axis = 0.0, 0.0, 1.0, "
                                                             "q0 = -3.0 /", 1)))
    th = res["shaft.q"]
    assert th.max() < -3.0 + 1e-12 and abs(th[-1] - (3.0 - 2 * np.pi)) < 1e-6


# a steel beam on a revolute joint about z at its root, bending in the x-y plane under
# gravity, the frame of its point at 0.5 m (a gyro on the cradle: nearer the root, where the
# rate feedback leaves the bending modes damped) held level by a controller
BEAM = """
&scene title = 'gyro-stabilised beam', t_end = {t_end}, gravity = 0.0, -9.81, 0.0 /
&integrator {integrator} /
&effects gravity = .true., controls = .true., modal_damping = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'barrel', kind = 'beam', length = 2.0, youngs_modulus = 2.1e11, density = 7800.0,
      r_outer = 0.03, r_inner = 0.02, n_elements = 12, modes_y = 4, modes_z = 0, modal_damping = 0.05 /
&joint name = 'trunnion', kind = 'revolute', parent = 'ground', child = 'barrel', axis = 0.0, 0.0, 1.0 /
&marker name = 'cradle', body = 'barrel', at = 0.5, 0.0, 0.0 /
&control name = 'stab', joint = 'trunnion', kp = 4.0e3, kd = 400.0, ki = {ki}, sensor = 'orientation',
         marker = 'cradle', axis = 0.0, 0.0, 1.0 /
&output dt = {dt}, quantities = 'coordinates', 'marker_orientations', 'energy' /
"""


def beam(tmp_path: Path, integrator: str = "method = 'single', h_slow = 4.0e-5", t_end: float = 1.0,
         ki: float = 1.5e4, dt: float = 1.0e-3, name: str = "beam.nml") -> Path:
    return write(tmp_path, name, BEAM.format(integrator=integrator, t_end=t_end, ki=ki, dt=dt))


def tip_angle(res) -> np.ndarray:
    """The cradle marker frame's angle about z from its written quaternion (u = x axis)."""
    w, x, y, z = (res[f"cradle.{c}"] for c in "qw qx qy qz".split())
    rx = np.stack([1 - 2 * (y**2 + z**2), 2 * (x * y + w * z), 2 * (x * z - w * y)])
    return np.arctan2(rx[1], rx[0])


def test_gyro_on_a_flexible_beam_levels_its_marker_not_its_root(tmp_path):
    """With integral action the gyro's angle (the marker frame's, with the beam's small
    rotation there) settles at 0, read back from the written orientation to 1e-9 rad; the
    joint then stands at the static slope there under the beam's weight, w x (3 L^2 - 3 L x
    + x^2)/(6 EI) at x = 0.5 m (cantilever, uniform load), to the modal truncation: 2e-4
    relative with 6 bending modes (measured -4.6e-5; 4 modes: 9.6e-4, 8 modes: -7.5e-5)."""
    text = beam(tmp_path, "method = 'single', h_slow = 1.0e-5, adaptive = .true., rtol = 1.0e-9", t_end=8.0,
                dt=1.0e-2).read_text()
    res = pymr.run(write(tmp_path, "six.nml", text.replace("n_elements = 12, modes_y = 4",
                                                            "n_elements = 16, modes_y = 6")))
    assert abs(tip_angle(res)[-1]) < 1e-9
    area, inertia = np.pi * (0.03**2 - 0.02**2), np.pi / 4 * (0.03**4 - 0.02**4)
    x, length = 0.5, 2.0
    slope = 7800.0 * area * 9.81 * x * (3 * length**2 - 3 * length * x + x**2) / (6 * 2.1e11 * inertia)
    assert abs(res["trunnion.q"][-1] / slope - 1) < 2e-4, res["trunnion.q"][-1] / slope - 1


def test_gyro_rate_is_the_rate_of_its_angle_on_a_flexible_beam(tmp_path):
    """kd alone (kp = ki = 0 is refused, so kp tiny): the drive's work is the integral of
    -kd (rate) th_joint'; with the rate taken as the time derivative of the tip angle read
    from the written orientation it agrees to 1e-6 of the work, while the root's rate alone
    (no small rotation) misses it by more than 1e-4 (measured 1.3e-3)."""
    text = BEAM.format(integrator="method = 'single', h_slow = 2.0e-5", t_end=0.2, ki=0.0, dt=2.0e-5)
    text = text.replace("kp = 4.0e3, kd = 400.0", "kp = 1.0e-9, kd = 50.0")
    res = pymr.run(write(tmp_path, "rate.nml", text))
    ang, qd = tip_angle(res), res["trunnion.qd"]
    t = res.t

    def work(rate):
        p = -50.0 * rate * qd - 1.0e-9 * ang * qd
        return np.concatenate([[0.0], np.cumsum(0.5 * (p[1:] + p[:-1]) * np.diff(t))])
    w = res["energy.drive_work"]
    scale = np.abs(w).max()
    assert scale > 1e-3
    assert np.abs(work(np.gradient(ang, t, edge_order=2)) - w).max() < 1e-6 * scale
    assert np.abs(work(qd) - w).max() > 1e-4 * scale


def test_energy_balance_closes_with_the_drive_work(tmp_path):
    """Pendulum under PID (no dissipation but the controller's): kinetic + gravity energy
    minus the drive's work stays at its start value to the integration error, which falls
    at fourth order (measured 8.7e-8 J at h = 1e-3 s, 5.4e-9 J at 5e-4 s, of 6.9 J of work);
    with the effort saturated at first (max_effort 40 N m) it still closes, at second order
    by the kink of the limit (2.6e-5 J, 6.3e-6 J)."""
    for gains, most, ratio in [("", 1e-8, 10.0), (", max_effort = 40.0", 1e-5, 3.0)]:
        scene = pendulum(tmp_path, "kp = 100.0, kd = 5.0, ki = 50.0, setpoint = 0.5" + gains, 3.0)
        err = []
        for h in (1e-3, 5e-4):
            res = pymr.run(scene, overrides={"integrator.h_slow": h})
            e, w = res["energy.total"], res["energy.drive_work"]
            assert np.abs(w).max() > 1.0
            err.append(np.abs(e - w - e[0]).max())
        assert err[1] < most and err[0] / err[1] > ratio, err


def test_a_setpoint_table_is_followed(tmp_path):
    """A setpoint ramp from a file (0 to 0.2 rad over 1 s, then held), stiff PD with
    integral action: the rotor ends on 0.2 + setpoint (offset 0.05) to 1e-8 rad."""
    (tmp_path / "sp.txt").write_text("0.0 0.0\n1.0 0.2\n5.0 0.2\n")
    res = pymr.run(rotor(tmp_path, "kp = 400.0, kd = 60.0, ki = 500.0, setpoint = 0.05, file = 'sp.txt'",
                         t_end=12.0))
    assert abs(res["shaft.q"][-1] - 0.25) < 1e-8
    assert abs(res["shaft.q"][50] - 0.25) > 0.1                     # the ramp is followed, not jumped


# ------------------------------------------------------------- state carried through runs

@pytest.mark.parametrize("kind", ["single", "multirate"])
def test_a_restarted_run_carries_the_integral(tmp_path, kind):
    """Stopped after its checkpoint and restarted, the PID pendulum's rows (single-rate) and
    the gyro-stabilised beam's ('response' multirate), the integral among them, equal the
    uninterrupted run's bit for bit."""
    if kind == "single":
        scene, t_stop, t_ckpt = pendulum(tmp_path, "kp = 100.0, kd = 20.0, ki = 200.0, setpoint = 0.3", 4.0), 2.5, 2.0
    else:
        scene, t_stop, t_ckpt = beam(tmp_path, "method = 'multirate', h_fast = 2.0e-5, h_slow = 1.0e-4",
                                     t_end=0.3), 0.25, 0.2
    full = pymr.run(scene, tmp_path / "full.csv")
    out = tmp_path / "job.csv"
    pymr.run(scene, out, overrides={"scene.t_end": t_stop, "output.checkpoint_dt": t_ckpt})
    res = pymr.run(scene, out, overrides={"output.checkpoint_dt": t_ckpt}, restart=tmp_path / "job.ckpt")
    assert np.array_equal(res.t, full.t)
    assert np.array_equal(res.data, full.data)
    assert np.abs(full[[c for c in full.columns if c.endswith(".integral")][0]]).max() > 1e-4


@pytest.mark.parametrize("integrator, tol", [
    ("method = 'multirate', h_fast = 2.0e-5, h_slow = 1.0e-4", 1e-6),
    ("method = 'multirate', h_slow = 1.0e-4, adaptive = .true., rtol = 1.0e-9, atol = 1.0e-11", 1e-6),
    ("method = 'multirate', coupling = 'full', h_slow = 1.0e-5, adaptive = .true., rtol = 1.0e-9, atol = 1.0e-11",
     1e-7),
    ("method = 'single', h_slow = 1.0e-5, adaptive = .true., rtol = 1.0e-11, atol = 1.0e-13, "
     "dynamics = 'articulated'", 1e-8),
])
def test_multirate_and_articulated_follow_a_tight_single_rate_run(tmp_path, integrator, tol):
    """The gyro-stabilised beam with integral action over 0.3 s: 'response' multirate (fixed:
    measured 2.0e-7 of the largest coordinate; adaptive), adaptive 'full' multirate (7.3e-10)
    and the articulated path end where a tight adaptive single-rate run (M path) ends, the
    controller's integral among the coordinates. (Fixed 'full' steps at k = 5 are refused by
    the pre-flight check here: the rate feedback couples the joint to the modes.)"""
    ref = pymr.run(beam(tmp_path, "method = 'single', h_slow = 1.0e-5, adaptive = .true., rtol = 1.0e-11, atol = 1.0e-13, "
                        "dynamics = 'mass_matrix'", t_end=0.3, name="ref.nml"))
    res = pymr.run(beam(tmp_path, integrator, t_end=0.3))
    q, qr = res.coordinates()[0], ref.coordinates()[0]
    assert q.shape[1] == 6                                          # joint, integral, 4 modes
    assert np.abs(res["stab.integral"] - ref["stab.integral"]).max() < tol * np.abs(ref["stab.integral"]).max()
    assert np.abs(q - qr).max() < tol * np.abs(qr).max(), np.abs(q - qr).max() / np.abs(qr).max()


def test_a_response_macro_step_stable_only_uncorrected_runs_uncorrected(tmp_path):
    """The surrogate's correction narrows the explicit stability of forces outside the
    'response' surrogate's linear response (a damper: |lambda H| 0.24-0.28 to 0.16-0.18; an
    oscillator: omega H 1.1-1.2 to about 0.6, docs/integrators.md). The gyro's rate feedback is such a
    force: at h_fast = 2e-5 s the linearised macro step grows by 1.07 per step at k = 5 with
    the correction and not at all without it. The pre-flight check then runs it without the
    correction and says so (k = 4 keeps it), and both follow the tight single-rate run to
    1e-6 of the largest coordinate (measured 2.0e-7)."""
    ref = pymr.run(beam(tmp_path, "method = 'single', h_slow = 1.0e-5, adaptive = .true., rtol = 1.0e-11, atol = 1.0e-13",
                        t_end=0.3, name="ref.nml"))
    qr = ref.coordinates()[0]
    for k, warned in ((4, False), (5, True)):
        res = pymr.run(beam(tmp_path, f"method = 'multirate', h_fast = 2.0e-5, h_slow = {k * 2.0e-5!r}", t_end=0.3))
        said = [w for w in res.stats["warnings"] if "stable only without the surrogate's correction" in w]
        assert bool(said) == warned, res.stats["warnings"]
        if warned:
            assert said[0].startswith(f"the macro step of k = {k} (coupling 'response')")
        assert np.abs(res.coordinates()[0] - qr).max() < 1e-6 * np.abs(qr).max()


def test_controls_off_on_purpose_change_nothing(tmp_path):
    """controls = .false.: the &control groups are ignored (no state coordinate, no
    effect), results bit-identical to the scene without them."""
    text = ROTOR.format(control="kp = 50.0, setpoint = 0.5", integrator="h_slow = 1.0e-3", t_end=0.5)
    text = text.replace("axis = 0.0, 0.0, 1.0 /", "axis = 0.0, 0.0, 1.0, qd0 = 0.3 /")
    off = text.replace("controls = .true.", "controls = .false.")
    plain = "\n".join(line for line in off.split("\n") if not line.startswith("&control"))
    r_off, r_plain = pymr.run(write(tmp_path, "off.nml", off)), pymr.run(write(tmp_path, "plain.nml", plain))
    assert np.array_equal(r_off.data, r_plain.data) and r_off.columns == r_plain.columns
    assert "controls" not in r_off.stats["effects"]


# ----------------------------------------------------------------------- bad input

BAD_BASE = ROTOR.format(control="kp = 50.0", integrator="h_slow = 1.0e-3", t_end=0.1)
CONTROL_LINE = 9          # the &control group's line in BAD_BASE (after its leading newline)


@pytest.mark.parametrize("items, item, says", [
    ("joint = 'nowhere', kp = 1.0", "joint", "no &joint named 'nowhere'"),
    ("joint = 'shaft', coordinate = 2, kp = 1.0", "coordinate", "has 1 coordinate, got 2"),
    ("joint = 'shaft', sensor = 'compass', kp = 1.0", "sensor", "compass"),
    ("joint = 'shaft', sensor = 'orientation', kp = 1.0, axis = 0.0, 0.0, 1.0", "marker", "missing"),
    ("joint = 'shaft', sensor = 'orientation', marker = 'nope', kp = 1.0, axis = 0.0, 0.0, 1.0", "marker",
     "no &marker named 'nope'"),
    ("joint = 'shaft', sensor = 'orientation', marker = 'rim', kp = 1.0", "axis", "missing or zero"),
    ("joint = 'shaft', marker = 'rim', kp = 1.0", "marker", "only sensor 'orientation'"),
    ("joint = 'shaft'", "kp", "all 0"),
    ("joint = 'shaft', kp = -1.0", "kp", ""),
    ("joint = 'shaft', kp = 1.0, max_effort = 0.0", "max_effort", ""),
    ("joint = 'shaft', kp = 1.0, file = 'missing.txt'", "file", ""),
])
def test_bad_controls_are_refused_in_one_line(tmp_path, mrsim, items, item, says):
    """Each fault of a &control group: exit 1, one line naming the file, line, group and
    item, no results."""
    text = BAD_BASE.replace("&control name = 'servo', joint = 'shaft', kp = 50.0 /",
                            f"&control name = 'servo', {items} /")
    scene = write(tmp_path, "bad.nml", text)
    check_refused_in_one_line(mrsim, scene, rf":{CONTROL_LINE}: &control.*{item}.*{re.escape(says)}")


def test_controls_forgotten_or_prescribed_or_twice_are_refused(tmp_path, mrsim):
    """&control without &effects controls; a controller on a coordinate a &motion
    prescribes; two controllers of one name: each one line naming the group and item."""
    forgot = write(tmp_path, "forgot.nml", BAD_BASE.replace("controls = .true.", "gravity = .false."))
    check_refused_in_one_line(mrsim, forgot, rf":{CONTROL_LINE}: &control.*controls is not on")
    moved = BAD_BASE.replace("controls = .true.", "controls = .true., base_motion = .true.") + \
        "&motion joint = 'shaft', amplitude = 0.1, frequency = 1.0 /\n"
    check_refused_in_one_line(mrsim, write(tmp_path, "moved.nml", moved),
                              rf":{CONTROL_LINE}: &control.*coordinate.*prescribed by the &motion")
    twice = BAD_BASE + "&control name = 'servo', joint = 'shaft', kd = 1.0 /\n"
    check_refused_in_one_line(mrsim, write(tmp_path, "twice.nml", twice), r":\d+: &control.*name.*another &control")


def test_a_controller_on_a_closed_loop(tmp_path):
    """PID on the four-bar's crank (a tree joint of a loop closed by a revolute), from its
    swing at 2 rad/s to setpoint 1.2 rad: the loop stays closed (1e-9 m), the crank settles on
    the setpoint (1e-8 rad), and kinetic plus gravity energy minus the drive's work keeps its
    start value to 1e-7 of the work (adaptive, rtol 1e-10; measured: loop 4.9e-13 m, crank
    1.1e-12 rad, energy 1.8e-10)."""
    from test_loops import fourbar_scene, L0
    text = fourbar_scene(1.0, 2.0, t_end=20.0).replace("&effects gravity = .true. /",
                                                       "&effects gravity = .true., controls = .true. /")
    text += "&control name = 'servo', joint = 'A', kp = 200.0, kd = 60.0, ki = 150.0, setpoint = 1.2 /\n"
    res = pymr.run(write(tmp_path, "fourbar.nml", text))
    assert np.abs(res["tip.y"]).max() < 1e-9 and np.abs(res["tip.x"] - L0).max() < 1e-9
    assert abs(res["A.q"][-1] - 1.2) < 1e-8
    e, w = res["energy.total"], res["energy.drive_work"]
    assert np.abs(w).max() > 0.3
    assert np.abs(e - w - e[0]).max() < 1e-7 * np.abs(w).max()
