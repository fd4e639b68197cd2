"""pymr animate (issues 17 and 33): the moving mechanism drawn in 3-D from a run's results.

Independent expectations: the drawn markers and the barrel's drawn end equal the marker
columns the run wrote; the default magnification draws the largest deflection as 5 % of the
mechanism's size; the drawn points fill the frame and stay inside it; a free joint gets no
link from the ground; the views put the axes where they are named; one GIF frame per row."""
from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr.animate import AnimateError, animate, drawing
from pymr.geometry import GeometryError, motion

ROOT = Path(__file__).resolve().parents[1]
TANK = ROOT / "input" / "tank_gun_turret.nml"
CHAIN = ROOT / "input" / "spatial_chain.nml"


@pytest.fixture(scope="module")
def tank_results(tmp_path_factory):
    out = tmp_path_factory.mktemp("anim") / "tank.csv"
    pymr.run(TANK, out, overrides={"scene.t_end": 0.3, "output.dt": 0.01})
    return pymr.load_results(out)


def drawn(artist) -> np.ndarray:
    """The 3-D points a line artist holds, (k, 3)."""
    return np.column_stack(artist.get_data_3d())


def test_drawn_points_are_the_run_s_kinematics(tank_results):
    """At true scale the muzzle dot and the barrel's drawn end are the run's muzzle column
    (to 1e-9 m) at every frame; the default scale draws the largest deflection as 5 % of the
    mechanism's size (two digits), and the muzzle then sits off its undeformed place by that
    factor times its deflection; at scale 0 it is the undeformed place."""
    d = drawing(tank_results, exaggerate=1.0, frames=31)
    muzzle = tank_results.marker("muzzle")[0]
    for i in range(0, 31, 5):
        d.draw(i)
        assert np.abs(drawn(d.dots["muzzle"])[0] - muzzle[i]).max() < 1e-9
        assert np.abs(drawn(d.lines["gun"])[-1] - muzzle[i]).max() < 1e-9
        assert np.abs(drawn(d.trails["muzzle"]) - muzzle[:i + 1]).max() < 1e-9
    auto = drawing(tank_results, frames=31)
    x = auto.mo.exaggerate
    true = motion(tank_results)
    lo, hi = true.bounds()
    deflection = max(np.linalg.norm(b.displacement, axis=-1).max() for b in true.bodies if b.displacement is not None)
    assert x * deflection / (hi - lo).max() == pytest.approx(0.05, rel=0.05) and x > 5
    rigid = motion(tank_results, exaggerate=0.0).markers["muzzle"]
    auto.draw(30)
    assert np.abs(drawn(auto.dots["muzzle"])[0] - (rigid[30] + x * (muzzle[30] - rigid[30]))).max() < 1e-3 * deflection
    undeformed = drawing(tank_results, exaggerate=0.0, frames=31)    # scale 0: the rigid muzzle (was refused)
    undeformed.draw(30)
    assert np.abs(drawn(undeformed.dots["muzzle"])[0] - rigid[30]).max() < 1e-9


def test_the_mechanism_fills_the_frame(tank_results):
    """Every drawn point (solids' corners, lines, markers, joints, over the run) lands inside
    the figure, and they span at least 90 % of its width or of its height below the title;
    orbiting, inside at every angle of the turn and so at the tightest one."""
    for view, orbit in (("iso", False), ("top", False), ("front", True)):
        d = drawing(tank_results, view=view, frames=10, orbit=orbit)
        d.fig.canvas.draw()
        w, h = d.fig.get_size_inches() * d.fig.dpi
        cloud, fill = d._cloud(), []
        for azim in d._angles():
            px = d._screen(cloud, azim)
            assert px.min() >= 0 and px[:, 0].max() <= w and px[:, 1].max() <= 0.94 * h
            fill.append(max(np.ptp(px[:, 0]) / w, np.ptp(px[:, 1]) / (0.94 * h)))
        assert max(fill) > 0.9


def test_a_free_joint_is_not_a_rod_from_the_ground(tmp_path):
    """The spatial chain's base body floats on a free joint: no link is drawn for it; every
    other joint's link runs from its parent's origin to the joint."""
    out = tmp_path / "chain.csv"
    pymr.run(CHAIN, out, overrides={"scene.t_end": 0.2})
    d = drawing(pymr.load_results(out), frames=5)
    kinds = {j.name: j for j in d.mo.joints}
    assert kinds["j1"].kind == "free" and "j1" not in d.links and d.links
    origin = {b.name: b.origin for b in d.mo.bodies}
    d.draw(4)
    for name, link in d.links.items():
        j = kinds[name]
        assert np.abs(drawn(link) - [origin[j.parent][4], j.position[4]]).max() < 1e-15


def test_views_put_the_axes_where_they_are_named(tank_results):
    """Screen directions (right, up) of the inertial axes: 'xy' has x across and y up; 'xz' x
    across and z up; 'zy' z across; the tank's vertical is y (its gravity), up in every named view
    but 'top'; 'ELEV,AZIM' is taken as given; a bad view is one line."""
    def screen(view):
        d = drawing(tank_results, view=view, frames=3)
        d.fig.canvas.draw()
        c = (d.lo + d.hi) / 2
        return (d._screen(c + np.eye(3), d.azim) - d._screen(c[None, :], d.azim)), d
    for view, right, up in (("xy", 0, 1), ("xz", 0, 2), ("zy", 2, 1), ("front", 0, 1), ("iso", None, 1)):
        j, d = screen(view)
        assert j[up, 1] > 0.9 * np.linalg.norm(j[up]) and abs(j[up, 0]) < 1e-9 * np.linalg.norm(j[up])
        if right is not None:
            assert j[right, 0] > 0.99 * np.linalg.norm(j[right])
    _, d = screen("10,-20")
    assert (d.elev, d.azim, d.up) == (10.0, -20.0, "y")
    with pytest.raises(AnimateError, match="view 'sideways': one of iso, front, side, top, ELEV,AZIM"):
        drawing(tank_results, view="sideways")


def test_animation_is_written_frame_by_frame(tank_results, tmp_path):
    from PIL import Image
    out = animate(tank_results, tmp_path / "a.gif", exaggerate=20.0, frames=6)
    with Image.open(out) as im:
        assert im.n_frames == 6
    r = subprocess.run(["pymr", "animate", tank_results.path, "-o", str(tmp_path / "b.gif"), "--frames", "5",
                        "--view", "xz", "--orbit"], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    with Image.open(tmp_path / "b.gif") as im:
        assert im.n_frames == 5
    r = subprocess.run(["pymr", "animate", tank_results.path, "-o", str(tmp_path / "s.png"), "--at", "0.2"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    with Image.open(tmp_path / "s.png") as im:
        assert im.format == "PNG" and im.size[0] > 600


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


def test_options_the_output_does_not_use_are_refused(tank_results, tmp_path):
    """--at with an animation and --orbit with a still were ignored silently (found by
    fuzzing): a user asking for a frame at 0.2 s got the whole run. Refused in one line,
    exit 1, nothing written."""
    for args, message in ((["-o", str(tmp_path / "a.gif"), "--at", "0.2"],
                           "pymr: error: at: the time of a still (.png); -o "),
                          (["-o", str(tmp_path / "a.png"), "--orbit"],
                           "pymr: error: orbit: turns the camera over an animation; -o ")):
        r = subprocess.run(["pymr", "animate", tank_results.path, *args], capture_output=True, text=True, timeout=120)
        assert r.returncode == 1 and r.stderr.startswith(message) and r.stderr.count("\n") == 1, r.stderr
    assert not any(tmp_path.iterdir())
