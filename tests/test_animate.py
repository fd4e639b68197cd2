"""pymr animate (issue 17, item 7): the moving mechanism drawn from a run's results.

Independent expectations: the markers recomputed from the result's coordinates equal the
marker columns the run wrote; the tree's rigid geometry (the traverse joint point, the
turret's lever to the trunnion) holds in every frame; one GIF frame per chosen row."""
from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr.animate import animate, motion
from pymr.geometry import GeometryError

ROOT = Path(__file__).resolve().parents[1]
TANK = ROOT / "input" / "tank_gun_turret.nml"


@pytest.fixture(scope="module")
def tank_results(tmp_path_factory):
    out = tmp_path_factory.mktemp("anim") / "tank.csv"
    pymr.run(TANK, out, overrides={"scene.t_end": 0.3, "output.dt": 0.01})
    return pymr.load_results(out)


def test_drawn_points_are_the_run_s_kinematics(tank_results):
    """Frames from the CSV's coordinates: the muzzle equals the run's own muzzle columns to
    1e-9 m; the turret's origin stays on the traverse joint point (0, 1.2, 0) and the mount's
    1.3 m from it (the trunnion at (1.2, 0.5, 0) in the turret's frame), every frame; with
    the deflections scaled 50x the muzzle moves off its place by the scaled deflection."""
    t, pos, parent, markers, on = motion(tank_results)
    assert np.abs(markers["muzzle"] - tank_results.marker("muzzle")[0]).max() < 1e-9
    assert list(parent) == [-1, 0, 1, 2] and on["muzzle"] == 3
    assert np.abs(pos[:, 1] - [0.0, 1.2, 0.0]).max() < 1e-12
    assert np.linalg.norm(pos[:, 2] - pos[:, 1], axis=1) == pytest.approx(1.3, abs=1e-12)
    _, _, _, big, _ = motion(tank_results, exaggerate=50.0)
    rigid = motion(tank_results, exaggerate=0.0)[3]["muzzle"]
    assert np.abs((big["muzzle"] - rigid) - 50.0 * (markers["muzzle"] - rigid)).max() < 1e-3 * np.abs(
        big["muzzle"] - rigid).max()


def test_animation_is_written_frame_by_frame(tank_results, tmp_path):
    from PIL import Image
    out = animate(tank_results, tmp_path / "a.gif", exaggerate=20.0, frames=12)
    with Image.open(out) as im:
        assert im.n_frames == 12
    r = subprocess.run(["pymr", "animate", tank_results.path, "-o", str(tmp_path / "b.gif"), "--frames", "5",
                        "--view", "xz"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "b.gif").stat().st_size > 1000


def test_a_run_with_overrides_is_drawn_from_the_scene_its_statistics_hold(tmp_path):
    """A run whose --set overrides moved the geometry is drawn from the resolved scene its
    statistics hold (issue 30: it was refused as 'not the scene of this run'). Given the
    scene file instead, which is not the run's, it is refused in one line (exit 1) that
    asks for the resolved scene; results with no statistics file need --scene."""
    out = tmp_path / "o.csv"
    over = {"scene.t_end": 0.05, "marker[muzzle].at": [5.0, 0.0, 0.0]}
    pymr.run(TANK, out, overrides=over)
    r = subprocess.run(["pymr", "animate", str(out), "-o", str(tmp_path / "a.gif"), "--frames", "3"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "a.gif").stat().st_size > 1000
    r = subprocess.run(["pymr", "animate", str(out), "--scene", str(TANK), "-o", str(tmp_path / "b.gif")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and r.stderr.count("\n") == 1
    assert "is not the scene of this run" in r.stderr and "--scene" in r.stderr
    resolved = pymr.Scene(TANK, over).write(tmp_path / "resolved.nml", absolute_paths=True)
    animate(out, tmp_path / "ok.gif", scene=resolved, frames=3)
    (tmp_path / "o.json").unlink()
    with pytest.raises(GeometryError, match="the results name no scene"):
        animate(out, tmp_path / "x.gif")


def test_results_without_coordinates_are_refused(tmp_path):
    """A run that wrote markers and reactions but no coordinates cannot be drawn: one line,
    exit 1, naming the quantity to ask for."""
    out = tmp_path / "m.csv"
    pymr.run(TANK, out, overrides={"scene.t_end": 0.05, "output.quantities": ["markers", "reactions"]})
    r = subprocess.run(["pymr", "animate", str(out)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and r.stderr.count("\n") == 1
    assert "hold 0 of the scene's 6 coordinates" in r.stderr and "'coordinates'" in r.stderr
