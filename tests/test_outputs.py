"""Outputs on demand (&output quantities; issue 17 item 3): each group of columns checked
against an independent value.

* reactions: a pendulum's pivot force against Newton's law on the bob from its angle, rate
  and the equation of motion; the drive torques of the tank about their joint axes; the held
  barrel's trunnion load against the hand-calculated weight and its moment; a free-floating
  body (no joint load at all);
* marker accelerations and orientations: the pendulum's closed forms; the muzzle's
  acceleration against a difference of its velocity, and its orientation against the
  barrel's tangent from two markers;
* energy: the columns' sum, and the balance E - E(0) = W_drive + W_load + W_motion - D_damping
  on every effect that does work (measured balances in the test docstrings);
* restart: the works go on from a checkpoint as in the uninterrupted run.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

import pymr
from energy_balance import balance

ROOT = Path(__file__).resolve().parents[1]
INPUT = ROOT / "input"
TANK = INPUT / "tank_gun_turret.nml"
ALL = ["coordinates", "markers", "marker_accelerations", "marker_orientations", "reactions", "energy"]

# pendulum.nml: 1 kg bob 1 m below the pivot, inertia 4e-5 kg m^2 about its centre
M, L, G, I_C = 1.0, 1.0, 9.81, 4.0e-5


def pendulum(tmp_path, **over):
    return pymr.run(INPUT / "pendulum.nml", tmp_path / "p.csv",
                    overrides={"output.quantities": ALL, "scene.t_end": 3.0, **over})


def test_the_pendulum_pivot_reaction_is_newton_on_the_bob(tmp_path):
    """In the bob's frame (x along the swing, y from the bob to the pivot) the pivot pulls
    with f_x = m l th'' + m g sin th and f_y = m (g cos th + l th'^2), th'' = -m g l sin th /
    (m l^2 + I_c); no out-of-plane force or moment, no moment about the free axis.
    Measured: 7e-15 N."""
    res = pendulum(tmp_path)
    th, w = res["pivot.q"], res["pivot.qd"]
    acc = -M * G * L * np.sin(th) / (M * L * L + I_C)
    assert np.abs(res["pivot.fx"] - (M * L * acc + M * G * np.sin(th))).max() < 1e-10
    assert np.abs(res["pivot.fy"] - M * (G * np.cos(th) + L * w ** 2)).max() < 1e-10
    for c in ("fz", "mx", "my", "mz"):
        assert np.abs(res[f"pivot.{c}"]).max() < 1e-10, c


def test_the_pendulum_tip_acceleration_and_orientation_are_the_closed_forms(tmp_path):
    """The tip 1 m below the pivot: a = l th'' t + l th'^2 n (t along the swing, n towards the
    pivot) and the bob's frame is the rotation th about z: q = (cos th/2, 0, 0, sin th/2)."""
    res = pendulum(tmp_path)
    th, w = res["pivot.q"], res["pivot.qd"]
    acc = -M * G * L * np.sin(th) / (M * L * L + I_C)
    t_dir = np.column_stack([np.cos(th), np.sin(th)])
    n_dir = np.column_stack([-np.sin(th), np.cos(th)])
    a = L * acc[:, None] * t_dir + L * (w ** 2)[:, None] * n_dir
    assert np.abs(res["tip.ax"] - a[:, 0]).max() < 1e-10
    assert np.abs(res["tip.ay"] - a[:, 1]).max() < 1e-10
    assert np.abs(res["tip.az"]).max() < 1e-12
    quat = np.column_stack([res[f"tip.q{c}"] for c in "wxyz"])
    assert np.abs(quat - np.column_stack([np.cos(th / 2), 0 * th, 0 * th, np.sin(th / 2)])).max() < 1e-12


@pytest.mark.parametrize("over", [{}, {"integrator.method": "multirate", "integrator.h_slow": 1e-3,
                                       "integrator.h_fast": 1e-4},
                                  {"integrator.adaptive": True, "integrator.rtol": 1e-8}],
                         ids=["single", "multirate", "adams"])
def test_the_tank_joints_pass_their_drive_torques_about_their_axes(tmp_path, over):
    """tank_gun_turret.nml drives the traverse (axis y) with -45500 sin(2 pi t) N m and the
    elevation (axis -z) with -33451 + 17600 sin(2 pi t) N m. A revolute joint passes to its
    child, about its axis, exactly the drive torque (the row of M qdd = P): the trunnion
    torque is the drive torque, whatever the inertia terms are. Measured: 5e-10 N m."""
    text = TANK.read_text()
    assert "&drive joint = 'traverse', amplitude = -45500.0, frequency = 1.0 /" in text
    assert "&drive joint = 'elevation', offset = -33451.0, amplitude = 17600.0, frequency = 1.0 /" in text
    res = pymr.run(TANK, tmp_path / "t.csv", overrides={"output.quantities": ["reactions"], **over})
    t = res.t
    assert np.abs(res["traverse.my"] - (-45500.0 * np.sin(2 * np.pi * t))).max() < 1e-8
    assert np.abs(-res["elevation.mz"] - (-33451.0 + 17600.0 * np.sin(2 * np.pi * t))).max() < 1e-8
    # the bracket is fixed: it carries the gun's whole load, beyond the drive's share
    assert np.abs(res["bracket.mz"]).max() > 1e3


def test_the_held_barrel_hangs_its_weight_on_the_trunnion(tmp_path):
    """The hold scene with both joints held level by prescribed motion and started static:
    the trunnion carries the weight of mount and barrel, (m_mount + m_gun) g upwards, and its
    moment g (m_mount x_mount + m_gun x_gun) about z (the barrel's bending is transverse, so
    its centre stays at x = 0.3 + L/2 on the mount); the bracket carries the barrel's alone.
    Measured: 1e-10 relative, constant over the second."""
    text = (INPUT / "tank_hold.nml").read_text()
    text = text.replace("&drive joint = 'traverse', offset = 0.0 /", "&motion joint = 'traverse', offset = 0.0 /")
    text = text.replace("&drive joint = 'elevation', offset = -33451.0 /",
                        "&motion joint = 'elevation', offset = 0.0 /")
    text = text.replace("joint_drives = .true.", "base_motion = .true.")
    scene = tmp_path / "held.nml"
    scene.write_text(text)
    res = pymr.run(scene, overrides={"scene.start": "static", "output.quantities": ["reactions"],
                                     "integrator.adaptive": True, "integrator.rtol": 1e-10,
                                     "integrator.atol": 1e-12})
    m_gun = 7850.0 * math.pi * (0.11 ** 2 - 0.06 ** 2) * 5.3
    weight = (1000.0 + m_gun) * G
    moment = G * (1000.0 * 0.1324 + m_gun * (0.3 + 5.3 / 2))
    force, torque = res.reaction("elevation")
    assert np.array_equal(force[:, 1], res["elevation.fy"]) and np.array_equal(torque[:, 2], res["elevation.mz"])
    assert np.abs(res["elevation.fy"] / weight - 1.0).max() < 1e-9
    assert np.abs(res["elevation.mz"] / moment - 1.0).max() < 1e-9
    assert np.abs(res["bracket.fy"] / (m_gun * G) - 1.0).max() < 1e-9
    assert np.abs(res["bracket.mz"] / (m_gun * G * 5.3 / 2) - 1.0).max() < 1e-9
    for c in ("fx", "fz", "mx", "my"):
        assert np.abs(res[f"elevation.{c}"]).max() < 1e-9 * weight, c


def test_a_free_body_has_no_joint_load(tmp_path):
    """A tumbling body on a 'free' joint under gravity: nothing passes through the joint
    (all six components 0, the body's momentum balance closing without it)."""
    scene = tmp_path / "free.nml"
    scene.write_text("""&scene t_end = 1.0, gravity = 0.0, -9.81, 0.0 /
&integrator method = 'single', h_slow = 1.0e-3 /
&effects gravity = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'box', kind = 'rigid', mass = 2.0, com = 0.1, 0.2, 0.3, inertia = 0.2, 0.25, 0.3, 0.01, 0.02, 0.0 /
&joint name = 'float', kind = 'free', parent = 'ground', child = 'box', qd0 = 0.1, 0.2, 0.3, 1.0, -2.0, 3.0 /
&output dt = 0.01, quantities = 'reactions', 'energy' /
""")
    res = pymr.run(scene, tmp_path / "free.csv")
    for c in ("fx", "fy", "fz", "mx", "my", "mz"):
        assert np.abs(res[f"float.{c}"]).max() < 1e-9, c
    assert np.abs(balance(res)).max() < 1e-6 * res["energy.kinetic"].max()


def test_the_muzzle_acceleration_is_the_rate_of_its_velocity(tmp_path):
    """The tank's muzzle (flexible barrel) at 0.1 ms output: its acceleration column against
    the Richardson-extrapolated central difference of its velocity column (error O(dt^4);
    measured 2.6e-7 of the peak, the plain difference's O(dt^2) error is 1e-4), and its
    frame's x axis along the barrel's deflected tangent, from a second marker 1 mm inwards
    (to 1e-6 rad: the chord's curvature error)."""
    text = TANK.read_text().replace("&marker name = 'muzzle', body = 'gun', at = 5.3, 0.0, 0.0 /",
                                    "&marker name = 'muzzle', body = 'gun', at = 5.3, 0.0, 0.0 /\n"
                                    "&marker name = 'inner', body = 'gun', at = 5.299, 0.0, 0.0 /")
    scene = tmp_path / "tank.nml"
    scene.write_text(text)
    res = pymr.run(scene, overrides={"output.quantities": ALL, "output.dt": 1e-4, "scene.t_end": 0.3})
    dt = 1e-4
    for c in "xyz":
        v = res[f"muzzle.v{c}"]
        fd = (4 * (v[3:-1] - v[1:-3]) / (2 * dt) - (v[4:] - v[:-4]) / (4 * dt)) / 3
        a = res[f"muzzle.a{c}"][2:-2]
        assert np.abs(fd - a).max() < 1e-6 * np.abs(res["muzzle.ay"]).max(), c
    pos = np.column_stack([res[f"muzzle.{c}"] for c in "xyz"])
    inner = np.column_stack([res[f"inner.{c}"] for c in "xyz"])
    chord = (pos - inner) / np.linalg.norm(pos - inner, axis=1)[:, None]
    w, x, y, z = (res[f"muzzle.q{c}"] for c in "wxyz")
    axis = np.column_stack([1 - 2 * (y * y + z * z), 2 * (x * y + w * z), 2 * (x * z - w * y)])
    assert np.abs(np.linalg.norm(axis, axis=1) - 1).max() < 1e-12
    assert np.arccos(np.clip(np.sum(axis * chord, axis=1), -1, 1)).max() < 1e-6
    # the barrel does bend: the muzzle's axis leaves the mount's by far more than that
    assert np.abs(res["muzzle.qz"] - np.sin(-res["elevation.q"] / 2)).max() > 1e-4


@pytest.mark.parametrize("scene, over, tol", [
    ("double_pendulum", {}, 1e-6),
    ("tank_gun_turret", {}, 1e-7),
    ("tank_gun_turret", {"integrator.adaptive": True, "integrator.rtol": 1e-8}, 1e-7),
    ("tank_gun_turret", {"integrator.method": "multirate", "integrator.h_slow": 1e-3, "integrator.h_fast": 1e-4}, 1e-7),
    ("tank_firing", {}, 1e-7),
    ("flexible_chain", {}, 1e-7),
    ("spacecraft", {}, 1e-7),
])
def test_the_energy_balance_closes(tmp_path, scene, over, tol):
    """E(t) - E(0) equals the works of the drives, loads and prescribed motions less the
    damping's loss, to `tol` of the largest energy change (the integrator's error). Measured:
    double pendulum 3.8e-7 J in 2.6 J of kinetic energy, tank 6e-5 J (fixed), 3.6e-5 J
    (adams rtol 1e-8), 6.6e-5 J ('response' k = 10) of a 7.9 kJ drive work, the firing tank
    1.3e-3 J of 29 kJ (drive, muzzle load and chassis motion), the damped flexible chain
    5e-6 J of 656 J, the spacecraft 1.4e-7 J of 24 J."""
    res = pymr.run(INPUT / f"{scene}.nml", tmp_path / "e.csv", overrides={"output.quantities": ["energy"], **over})
    parts = sum(res[f"energy.{c}"] for c in ("kinetic", "gravity", "strain", "springs"))
    assert np.abs(parts - res["energy.total"]).max() <= 1e-12 * np.abs(res["energy.total"]).max() + 1e-12
    scale = max(np.ptp(res["energy.total"]), np.abs(res["energy.kinetic"]).max(),
                *(np.abs(res[f"energy.{c}"]).max() for c in ("drive_work", "load_work", "motion_work", "damping_loss")))
    assert np.abs(balance(res)).max() <= tol * scale


def test_the_drive_work_is_the_integral_of_torque_times_rate(tmp_path):
    """The tank's drive_work column against Simpson's rule on the drive torques times the
    joint rates written at 0.1 ms (independent of the run's own quadrature): 1e-7 relative."""
    from scipy.integrate import cumulative_simpson
    res = pymr.run(TANK, tmp_path / "w.csv", overrides={"output.quantities": ["coordinates", "energy"],
                                                       "output.dt": 1e-4, "scene.t_end": 0.5})
    t = res.t
    power = (-45500.0 * np.sin(2 * np.pi * t)) * res["traverse.qd"] + \
        (-33451.0 + 17600.0 * np.sin(2 * np.pi * t)) * res["elevation.qd"]
    w = cumulative_simpson(power, x=t, initial=0.0)
    assert np.abs(w - res["energy.drive_work"]).max() < 1e-7 * np.abs(w).max()


def test_the_works_go_on_after_a_restart(tmp_path):
    """The firing tank (drive, load and motion work) stopped at 0.55 s after a checkpoint at
    0.4 s and restarted: every column, the works included, equals the uninterrupted run's."""
    scene = INPUT / "tank_firing.nml"
    over = {"output.quantities": ALL, "output.checkpoint_dt": 0.2}
    full = pymr.run(scene, tmp_path / "full.csv", overrides=over)
    out = tmp_path / "job.csv"
    pymr.run(scene, out, overrides={**over, "scene.t_end": 0.55})
    res = pymr.run(scene, out, overrides=over, restart=tmp_path / "job.ckpt")
    assert res.columns == full.columns and np.array_equal(res.t, full.t)
    assert np.abs(res.data - full.data).max() <= 1e-10 * np.abs(full.data).max()
    assert full["energy.load_work"][-1] > 1e3 and abs(full["energy.motion_work"][-1]) > 1e3


def test_quantities_choose_the_columns_and_nothing_else_is_computed(tmp_path):
    """Only the asked groups are written, in the documented order; the output's evaluations
    are not counted as the integrator's (the same counts as a run without them)."""
    plain = pymr.run(TANK, tmp_path / "a.csv", overrides={"scene.t_end": 0.1})
    res = pymr.run(TANK, tmp_path / "b.csv", overrides={"scene.t_end": 0.1, "output.quantities": ["reactions",
                                                                                                  "energy"]})
    assert res.columns[0] == "t" and res.columns[1:7] == [f"traverse.{c}" for c in ("fx", "fy", "fz", "mx", "my",
                                                                                     "mz")]
    assert len(res.columns) == 1 + 3 * 6 + 9 and res.columns[-1] == "energy.damping_loss"
    assert res.stats["rhs_full"] == plain.stats["rhs_full"]
    assert res.stats["effects"]["gravity"]["evaluations"] == plain.stats["effects"]["gravity"]["evaluations"]
    assert plain.columns == pymr.run(TANK, tmp_path / "c.csv", overrides={
        "scene.t_end": 0.1, "output.quantities": ["coordinates", "markers"]}).columns


@pytest.mark.parametrize("over", [{}, {"integrator.method": "multirate", "integrator.h_slow": 1e-3,
                                       "integrator.h_fast": 1e-4}],
                         ids=["single", "multirate"])
@pytest.mark.parametrize("dt", [0.0015, 0.00123])
def test_rows_at_any_time_are_as_accurate_as_the_steps(tmp_path, over, dt):
    """Output at any time (issue 17 item 4): a 1e-4 s run of the tank written every 1.5 ms
    and every 1.23 ms (not a multiple of any step) against a converged run (h = 1e-5 s) at
    those times: the rows' muzzle error is at most twice the run's error at its own step
    ends (written every 0.1 ms), the method's error; the rows are at k dt exactly, the last
    at t_end. Measured: rows 1.66e-8 and 1.69e-8 m against 1.69e-8 m at the steps (single),
    1.94e-8 and 1.97e-8 against 1.98e-8 m (multirate k = 10)."""
    base = {"scene.t_end": 0.3, **over}
    ref = pymr.run(TANK, tmp_path / "ref.csv", overrides={"scene.t_end": 0.3, "integrator.h_slow": 1e-5,
                                                         "integrator.h_fast": 1e-5, "output.dt": dt})
    rows = pymr.run(TANK, tmp_path / "rows.csv", overrides={**base, "output.dt": dt})
    steps = pymr.run(TANK, tmp_path / "steps.csv", overrides={**base, "output.dt": 1e-4})
    fine = pymr.run(TANK, tmp_path / "fine.csv", overrides={"scene.t_end": 0.3, "integrator.h_slow": 1e-5,
                                                          "integrator.h_fast": 1e-5, "output.dt": 1e-4})
    k = np.arange(len(rows.t) - 1)
    assert np.array_equal(rows.t[:-1], k * dt) and rows.t[-1] == 0.3 and np.array_equal(rows.t, ref.t)
    err_rows = np.abs(rows.marker("muzzle")[0] - ref.marker("muzzle")[0]).max()
    err_steps = np.abs(steps.marker("muzzle")[0] - fine.marker("muzzle")[0]).max()
    assert err_rows <= 2.0 * err_steps


def test_a_restart_with_other_columns_is_refused(tmp_path):
    """A restart must write the columns of the checkpointed run: asked for other quantities
    it is refused in one line before anything is written, and the earlier rows stay."""
    out = tmp_path / "job.csv"
    over = {"output.checkpoint_dt": 0.2, "output.quantities": ["coordinates", "energy"]}
    pymr.run(TANK, out, overrides={**over, "scene.t_end": 0.55})
    before = (tmp_path / "job.csv").read_bytes()
    with pytest.raises(pymr.SceneError, match=r"its columns are not the ones this run writes \(&output quantities"):
        pymr.run(TANK, out, overrides={**over, "output.quantities": ["coordinates", "reactions"]},
                 restart=tmp_path / "job.ckpt")
    assert (tmp_path / "job.csv").read_bytes() == before
    res = pymr.run(TANK, out, overrides=over, restart=tmp_path / "job.ckpt")
    assert res.t[-1] == 1.0 and "energy.total" in res.columns
