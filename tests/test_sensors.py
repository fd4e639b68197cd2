"""&sensor (issue 33, "Sensors a user can ask for"): the distance between two markers and its
rate, and a marker's position and velocity in a body's frame, as output columns.

On the tank (its barrel flexible): the distance equals the norm of the difference of the two
markers' own columns, its rate their (ri - rj).(vi - vj)/d and a central difference of the
distance over dense rows (to the difference's truncation error); the position in the
turret's frame equals R^T (r - o) from a marker at the turret's origin with its orientation
written, its velocity the central difference of that position; a marker of the turret sits
still at its point in the turret's frame; in the ground's frame the sensor is the marker's
columns; the other columns do not change; bad &sensor groups are refused in one line."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import pymr
from refusal import check_refused_in_one_line

ROOT = Path(__file__).resolve().parent.parent
TANK = (ROOT / "input" / "tank_gun_turret.nml").read_text()
PIN_AT = (1.0, 0.8, 0.3)
MARKERS = f"""&marker name = 'pin', body = 'turret', at = {PIN_AT[0]}, {PIN_AT[1]}, {PIN_AT[2]} /
&marker name = 'torigin', body = 'turret' /
"""
SENSORS = """&sensor name = 'reach', kind = 'distance', marker = 'muzzle', to = 'pin' /
&sensor name = 'm_turret', kind = 'position', marker = 'muzzle', frame = 'turret' /
&sensor name = 'pin_turret', kind = 'position', marker = 'pin', frame = 'turret' /
&sensor name = 'm_gun', kind = 'position', marker = 'muzzle', frame = 'gun' /
&sensor name = 'm_ground', kind = 'position', marker = 'muzzle', frame = 'chassis' /
"""
#: Rows at every step (h = 1e-4 s) for the differences, 30 ms of the tank's start, the turret
#: turned by 0.7 rad and turning at 2 rad/s (so that its frame is far from the ground's).
RUN = {"scene.t_end": 0.03, "output.dt": 1.0e-4, "joint[traverse].q0": 0.7, "joint[traverse].qd0": 2.0,
       "output.quantities": ["coordinates", "markers", "marker_orientations"]}


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """The tank with the two markers, with and without the sensors."""
    d = tmp_path_factory.mktemp("sensors")
    with_sensors = pymr.run(write(d, "tank_s.nml", TANK + MARKERS + SENSORS), overrides=RUN)
    without = pymr.run(write(d, "tank_m.nml", TANK + MARKERS), overrides=RUN)
    return with_sensors, without


def vec(res, name: str, prefix: str = "") -> np.ndarray:
    return np.column_stack([res[f"{name}.{prefix}{c}"] for c in "xyz"])


def rotation(qwxyz: np.ndarray) -> np.ndarray:
    """Rotation matrices (rows, 3, 3) of unit quaternions w, x, y, z."""
    w, x, y, z = qwxyz.T
    return np.array([[1 - 2*(y*y + z*z), 2*(x*y - w*z), 2*(x*z + w*y)],
                     [2*(x*y + w*z), 1 - 2*(x*x + z*z), 2*(y*z - w*x)],
                     [2*(x*z - w*y), 2*(y*z + w*x), 1 - 2*(x*x + y*y)]]).transpose(2, 0, 1)


def central(y: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Central differences at the inner rows."""
    return (y[2:] - y[:-2]) / (t[2:] - t[:-2]).reshape((-1,) + (1,) * (y.ndim - 1))


def truncation(y: np.ndarray, h: float) -> np.ndarray:
    """h^2/6 |y'''| at the inner rows (the central difference's leading error), y''' from the
    third differences around each row (the larger of the two sides)."""
    d3 = np.abs(np.diff(y, 3, axis=0)) / h**3
    left, right = np.vstack([d3[:1], d3]), np.vstack([d3, d3[-1:]])
    return h**2 / 6 * np.maximum(left, right)


def test_columns_and_their_metadata(runs):
    res, _ = runs
    info = {c.name: c for c in res.column_info}
    assert (info["reach.d"].group, info["reach.d"].owner, info["reach.d"].quantity, info["reach.d"].unit) == \
        ("sensors", "reach", "distance", "m")
    assert (info["reach.d_dot"].quantity, info["reach.d_dot"].unit) == ("distance_rate", "m/s")
    for s in ("m_turret", "pin_turret", "m_gun", "m_ground"):
        assert [info[f"{s}.{c}"].unit for c in ("x", "y", "z", "vx", "vy", "vz")] == ["m"] * 3 + ["m/s"] * 3
        assert {info[f"{s}.{c}"].quantity for c in "xyz"} == {"position"} and info[f"{s}.vx"].owner == s
    sensors = [c.name for c in res.column_info if c.group == "sensors"]
    assert res.columns[-len(sensors):] == sensors and len(sensors) == 2 + 4 * 6


def test_sensors_change_no_other_column(runs):
    res, without = runs
    assert res.columns[:len(without.columns)] == without.columns
    assert np.array_equal(res.data[:, :len(without.columns)], without.data)


def test_distance_and_its_rate(runs):
    res, _ = runs
    ri, vi, rj, vj = vec(res, "muzzle"), vec(res, "muzzle", "v"), vec(res, "pin"), vec(res, "pin", "v")
    d = np.linalg.norm(ri - rj, axis=1)
    assert np.max(np.abs(res["reach.d"] - d) / d) < 1e-12
    rate = np.einsum("ij,ij->i", ri - rj, vi - vj) / d
    assert np.max(np.abs(res["reach.d_dot"] - rate)) < 1e-12 * np.abs(rate).max()
    # the rate against the central difference of the distance, within its truncation error
    # h^2/6 |d'''| (twice, for the estimate of d''') and round-off (|d| eps / h)
    t, h = res.t, 1.0e-4
    assert np.allclose(np.diff(t), h, rtol=1e-9)
    fd, bound = central(res["reach.d"], t), truncation(res["reach.d"][:, None], h)[:, 0]
    err = np.abs(fd - res["reach.d_dot"][1:-1])
    assert np.all(err <= 2 * bound + 100 * np.finfo(float).eps * d.max() / h)
    assert np.abs(res["reach.d_dot"]).max() > 1e3 * err.max()     # the check can see the rate


def test_position_in_a_rigid_bodys_frame(runs):
    """R^T (r - o) from the turret's origin marker and its orientation; the velocity is the
    time derivative of that position; the turret's own marker sits still at its point."""
    res, _ = runs
    rot = rotation(np.column_stack([res[f"torigin.q{c}"] for c in "wxyz"]))
    p = np.einsum("nji,nj->ni", rot, vec(res, "muzzle") - vec(res, "torigin"))
    assert np.max(np.abs(vec(res, "m_turret") - p)) < 1e-12 * np.abs(p).max()
    t, h = res.t, 1.0e-4
    pos, vel = vec(res, "m_turret"), vec(res, "m_turret", "v")
    err = np.abs(central(pos, t) - vel[1:-1])
    assert np.all(err <= 2 * truncation(pos, h) + 100 * np.finfo(float).eps * np.abs(pos).max() / h)
    assert np.abs(vel).max() > 1e2 * err.max()
    # a point of the turret, in the turret's frame: its place, at rest (the turret turns)
    assert np.ptp(res["traverse.q"]) > 0.05 and np.abs(vec(res, "pin", "v")).max() > 0.5
    assert np.max(np.abs(vec(res, "pin_turret") - PIN_AT)) < 1e-14
    assert np.max(np.abs(vec(res, "pin_turret", "v"))) < 1e-14


def test_position_in_a_flexible_bodys_frame_and_the_ground(runs):
    """In the barrel's frame the muzzle moves only by the barrel's deflection (the velocity is
    that position's derivative); in the ground's frame the sensor is the marker's columns."""
    res, _ = runs
    t, h = res.t, 1.0e-4
    pos, vel = vec(res, "m_gun"), vec(res, "m_gun", "v")
    assert np.allclose(pos[0], [5.3, 0.0, 0.0], rtol=0, atol=1e-15)
    assert 1e-4 < np.abs(pos[:, 1]).max() < 0.05                  # the deflection, mm
    err = np.abs(central(pos, t) - vel[1:-1])
    assert np.all(err <= 2 * truncation(pos, h) + 100 * np.finfo(float).eps * 5.3 / h)
    assert np.array_equal(vec(res, "m_ground"), vec(res, "muzzle"))
    assert np.array_equal(vec(res, "m_ground", "v"), vec(res, "muzzle", "v"))


BAD_BASE = TANK + MARKERS
SENSOR_LINE = len(BAD_BASE.splitlines()) + 1


@pytest.mark.parametrize("items, item, says", [
    ("kind = 'distance', marker = 'muzzle', to = 'pin'", "name", "missing"),
    ("name = 'pin', kind = 'distance', marker = 'muzzle', to = 'torigin'", "name", "a &marker's name too"),
    ("name = 's', marker = 'muzzle', to = 'pin'", "kind", "missing"),
    ("name = 's', kind = 'angle', marker = 'muzzle'", "kind", "angle"),
    ("name = 's', kind = 'distance', to = 'pin'", "marker", "missing"),
    ("name = 's', kind = 'distance', marker = 'nose', to = 'pin'", "marker", "no &marker named 'nose'"),
    ("name = 's', kind = 'distance', marker = 'muzzle'", "to", "missing"),
    ("name = 's', kind = 'distance', marker = 'muzzle', to = 'tail'", "to", "no &marker named 'tail'"),
    ("name = 's', kind = 'distance', marker = 'muzzle', to = 'muzzle'", "to", "the same marker as marker"),
    ("name = 's', kind = 'distance', marker = 'muzzle', to = 'pin', frame = 'gun'", "frame",
     "not an item of a 'distance' sensor"),
    ("name = 's', kind = 'position', marker = 'muzzle'", "frame", "missing"),
    ("name = 's', kind = 'position', marker = 'muzzle', frame = 'hull'", "frame", "no &body named 'hull'"),
    ("name = 's', kind = 'position', marker = 'muzzle', frame = 'gun', to = 'pin'", "to",
     "not an item of a 'position' sensor"),
])
def test_bad_sensors_are_refused_in_one_line(tmp_path, mrsim, items, item, says):
    scene = write(tmp_path, "bad.nml", BAD_BASE + f"&sensor {items} /\n")
    check_refused_in_one_line(mrsim, scene, rf":{SENSOR_LINE}: &sensor.*{item}.*{re.escape(says)}")


def test_a_sensor_name_twice_is_refused(tmp_path, mrsim):
    twice = BAD_BASE + SENSORS + "&sensor name = 'reach', kind = 'distance', marker = 'pin', to = 'muzzle' /\n"
    check_refused_in_one_line(mrsim, write(tmp_path, "twice.nml", twice),
                              rf":{SENSOR_LINE + 5}: &sensor.*name.*another &sensor")


def test_sensors_in_the_schema_and_the_python_scene(tmp_path):
    assert "\n&sensor\n" in "\n" + pymr.schema()
    scene = pymr.Scene(write(tmp_path, "tank_m.nml", BAD_BASE))
    scene.add("sensor", name="reach", kind="distance", marker="muzzle", to="pin")
    assert "&sensor" in scene.resolved() and "frame" not in scene.resolved().split("&sensor")[1]
    with pytest.raises(pymr.SceneError, match="&sensor.*to: no &marker named 'tail'"):
        scene.add("sensor", name="far", kind="distance", marker="muzzle", to="tail")


def test_a_restarted_run_writes_the_same_sensor_columns(tmp_path):
    """Checkpoint at 10 ms, 'killed' at 15 ms, restarted: the rows, sensors included, are
    the uninterrupted run's (the sensors are recomputed from the state, none in the checkpoint)."""
    scene = write(tmp_path, "tank_s.nml", TANK + MARKERS + SENSORS)
    over = {**RUN, "scene.t_end": 0.02, "output.dt": 1.0e-3}
    full = pymr.run(scene, tmp_path / "full.csv", overrides=over)
    out = tmp_path / "job.csv"
    pymr.run(scene, out, overrides={**over, "scene.t_end": 0.015, "output.checkpoint_dt": 0.01})
    res = pymr.run(scene, out, overrides={**over, "output.checkpoint_dt": 0.01}, restart=tmp_path / "job.ckpt")
    assert res.columns == full.columns and np.array_equal(res.t, full.t)
    sensors = [c.name for c in full.column_info if c.group == "sensors"]
    for name in sensors:
        assert np.abs(res[name] - full[name]).max() <= 1e-10 * np.abs(full[name]).max(), name
