"""pymr.geometry (issue 33): the mechanism's 3-D geometry from a run's results.

Independent expectations: the deformed centre line's end equals the marker column the run
wrote at the same point (the output's own path through the kernel), where the undeformed
line's end is centimetres off; a modal-file body written from the beam draws the same line
at its nodes; rotation matrices are orthonormal; the origins are pymr_model_frames'; the
box drawn for a rigid body has the body's mass and moments of inertia; the scaled deflection
is the deflection times the factor; the joints sit on their scene points and axes."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr.geometry import GeometryError, box_of_inertia, motion, rows_of

ROOT = Path(__file__).resolve().parents[1]
TANK = ROOT / "input" / "tank_gun_turret.nml"
CRAFT = ROOT / "input" / "spacecraft.nml"


@pytest.fixture(scope="module")
def tank(tmp_path_factory):
    out = tmp_path_factory.mktemp("geom") / "tank.csv"
    pymr.run(TANK, out, overrides={"scene.t_end": 0.3, "output.dt": 0.01})
    return pymr.load_results(out)


@pytest.fixture(scope="module")
def craft(tmp_path_factory):
    out = tmp_path_factory.mktemp("geom") / "craft.csv"
    pymr.run(CRAFT, out, overrides={"scene.t_end": 0.3, "output.dt": 0.01})
    return pymr.load_results(out)


def body(mo, name):
    return next(b for b in mo.bodies if b.name == name)


def test_the_barrel_s_deformed_end_is_the_muzzle_marker(tank):
    """At every output row the centre line's end (x = L) equals the run's muzzle column to
    1e-9 of the barrel's length; the undeformed line (exaggerate 0) misses it by the
    deflection, which is far beyond that at the rows checked."""
    mo = motion(tank)
    gun = body(mo, "gun")
    muzzle = tank.marker("muzzle")[0]
    assert gun.line.shape == (len(tank.t), 41, 3)
    assert np.abs(gun.line[:, -1] - muzzle).max() < 1e-9 * 5.3
    rigid = body(motion(tank, exaggerate=0.0), "gun").line[:, -1]
    off = np.linalg.norm(rigid - muzzle, axis=1)
    bent = off > 1e-3                                  # rows where the barrel is deflected by > 1 mm
    assert bent.sum() > 20 and off.max() > 1e-2
    # the unscaled displacement is the deformed line less the undeformed one
    assert np.abs(gun.displacement[:, -1] - (muzzle - rigid)).max() < 1e-12
    # the line runs along the barrel: 41 points 5.3/40 m apart when undeformed
    seg = np.linalg.norm(np.diff(body(motion(tank, exaggerate=0.0), "gun").line, axis=1), axis=2)
    assert np.abs(seg - 5.3 / 40).max() < 1e-12


def test_poses_are_orthonormal_and_the_kernel_s_frames(tank):
    mo = motion(tank)
    rot = np.stack([b.rotation for b in mo.bodies])
    assert np.abs(np.einsum("btji,btjk->btik", rot, rot) - np.eye(3)).max() < 1e-12
    assert np.abs(np.linalg.det(rot) - 1.0).max() < 1e-12
    q, qd = tank.coordinates()
    with pymr.Model(TANK) as model:
        frames, parent = model.frames(tank.t, q, qd, len(mo.bodies))
    origins = np.stack([b.origin for b in mo.bodies], axis=1)
    assert np.abs(origins - frames).max() < 1e-12
    assert [b.kind for b in mo.bodies] == ["ground", "rigid", "rigid", "beam"]


def test_solids_have_the_bodies_mass_properties(tank):
    """A box of edges a, b, c and mass m has Ixx = m (b^2 + c^2)/12 ...: the turret's and the
    mount's boxes give back their scene inertias; the barrel is a cylinder of its length and
    r_outer, the ground none."""
    mo = motion(tank, frames=2)
    for name, m, inertia, com in (("turret", 9000.0, [9000.0, 16000.0, 12000.0], [-0.3, 0.4, 0.0]),
                                  ("mount", 1000.0, [150.0, 600.0, 600.0], [0.1324, 0.0, 0.0])):
        b = body(mo, name)
        a2 = b.size**2
        assert b.shape == "box"
        assert m * (a2[[1, 2, 0]] + a2[[2, 0, 1]]) / 12 == pytest.approx(inertia, rel=1e-12)
        assert b.centre == pytest.approx(com)
    gun = body(mo, "gun")
    assert gun.shape == "cylinder" and list(gun.size) == [5.3, 0.11, 0.0] and gun.centre[0] == 2.65
    assert body(mo, "chassis").shape == "none"
    assert box_of_inertia(1.0, np.diag([1.0, 1.0, 5.0]))[2] == 0.0      # no box has it: a flat one
    lo, hi = mo.bounds()
    assert (hi - lo).max() > 5.3 and np.all(hi >= lo)


def test_exaggerate_scales_the_deflection_and_the_markers(tank):
    """The barrel hangs on rigid bodies, so its pose does not change with the scale: the
    drawn line moves off the undeformed one by 50 times the deflection, and so does the
    muzzle marker; the unscaled displacement stays the same."""
    one, fifty, zero = (motion(tank, exaggerate=x, every=3) for x in (1.0, 50.0, 0.0))
    g1, g50, g0 = (body(m, "gun") for m in (one, fifty, zero))
    d = g1.line - g0.line
    assert np.abs((g50.line - g0.line) - 50 * d).max() < 1e-12 * 50 * 5.3
    assert np.abs(fifty.markers["muzzle"] - g50.line[:, -1]).max() < 1e-12
    assert np.abs(g50.displacement - g1.displacement).max() < 1e-15
    assert np.abs(one.t - tank.t[::3]).max() == 0


def test_joints_sit_on_their_points_and_axes(tank):
    mo = motion(tank)
    j = {x.name: x for x in mo.joints}
    assert [(x.kind, x.parent, x.child) for x in mo.joints] == [
        ("revolute", "chassis", "turret"), ("revolute", "turret", "mount"), ("fixed", "mount", "gun")]
    assert np.abs(j["traverse"].position - [0.0, 1.2, 0.0]).max() < 1e-15
    assert np.abs(j["traverse"].axis - [0.0, 1.0, 0.0]).max() < 1e-15
    # the trunnion turns with the turret about y: its axis stays level and unit
    assert np.abs(j["elevation"].axis[:, 1]).max() < 1e-15
    assert np.abs(np.linalg.norm(j["elevation"].axis, axis=1) - 1).max() < 1e-15
    assert np.abs(j["bracket"].axis).max() == 0.0
    assert np.abs(j["bracket"].position - body(mo, "gun").origin).max() == 0.0


def test_spacecraft_booms_end_at_their_tip_markers(craft):
    mo = motion(craft, frames=15)
    rows = rows_of(len(craft.t), 1, 15)
    for boom, tip in (("boom_right", "tip_right"), ("boom_left", "tip_left")):
        line = body(mo, boom).line
        marker = craft.marker(tip)[0][rows]
        assert np.abs(line[:, -1] - marker).max() < 1e-9 * 4.0
        assert np.abs(body(mo, boom).displacement[:, -1]).max() > 1e-6     # the boom does bend


def test_a_modal_file_body_draws_its_nodes_on_the_beam_s_line(tank, tmp_path):
    """The barrel written to a modal file and run as kind='modal': its line is its file's
    points (the mass points and the element nodes, 101); those at x = k L/40 along the barrel
    (the 21 element nodes) lie on the built-in beam's line at the same x to 1e-9 m, and the
    one at x = L is the muzzle."""
    modal = tmp_path / "gun.modal"
    pymr.write_modal_file(TANK, "gun", modal)
    text, count = re.subn(r"&body\s*\n\s*name = 'gun'.*?/\n",
                          f"&body name = 'gun', kind = 'modal', modal_file = '{modal}' /\n",
                          TANK.read_text(), flags=re.S)
    assert count == 1
    scene = tmp_path / "tank_modal.nml"
    scene.write_text(text)
    res = pymr.run(scene, tmp_path / "m.csv", overrides={"scene.t_end": 0.3, "output.dt": 0.01})
    gun_modal = body(motion(res, every=5), "gun")
    gun_beam = body(motion(tank, every=5), "gun")
    assert gun_modal.kind == "modal" and gun_modal.shape == "none"
    x = gun_modal.line - gun_modal.displacement             # the undeformed points, inertial
    s = np.einsum("pi,i->p", x[0] - gun_modal.origin[0], gun_modal.rotation[0][:, 0])   # along the barrel
    k = s / (5.3 / 40)
    on = np.abs(k - k.round()) < 1e-9
    assert on.sum() == 21 and sorted(k[on].round().astype(int)) == list(range(0, 41, 2))
    assert np.abs(gun_modal.line[:, on] - gun_beam.line[:, k[on].round().astype(int)]).max() < 1e-9
    tip = int(np.argmax(s))
    assert np.abs(gun_modal.line[:, tip] - res.marker("muzzle")[0][::5]).max() < 1e-9 * 5.3


def test_bad_requests_are_refused_in_one_line(tank, tmp_path):
    with pytest.raises(GeometryError, match="every: a whole number"):
        motion(tank, every=0)
    with pytest.raises(GeometryError, match="frames: a whole number"):
        motion(tank, frames=0)
    with pytest.raises(GeometryError, match="exaggerate"):
        motion(tank, exaggerate=-1.0)
    assert list(rows_of(10, 3)) == [0, 3, 6, 9] and list(rows_of(101, 1, 5)) == [0, 25, 50, 75, 100]


def test_markers_the_run_did_not_write_are_drawn_too(tank, tmp_path):
    """A run that wrote its coordinates only still has the scene's muzzle drawn: at the run's
    own muzzle column of the full run (the same motion) to 1e-9 of the barrel's length."""
    res = pymr.run(TANK, tmp_path / "c.csv", overrides={"scene.t_end": 0.3, "output.dt": 0.01,
                                                        "output.quantities": ["coordinates"]})
    assert res.markers == []
    mo = motion(res)
    assert np.abs(mo.markers["muzzle"] - tank.marker("muzzle")[0]).max() < 1e-9 * 5.3
