"""The results' column metadata (issue 31, item 5): the kernel writes, in OUT.json, every
column's group, owner, quantity and unit; pymr.Results reads the joints, bodies, markers
and coordinates from it, not from the column names."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import pymr

ROOT = Path(__file__).resolve().parent.parent
CYLINDER = ROOT / "input" / "tank_elevation_cylinder.nml"
CHAIN = ROOT / "input" / "spatial_chain.nml"


@pytest.fixture(scope="module")
def cylinder(tmp_path_factory):
    """The elevation cylinder (revolute joints, a prismatic stroke, a fixed bracket, a beam
    of 4 modes, three markers), with every group of columns, for 5 ms."""
    out = tmp_path_factory.mktemp("meta") / "cyl.csv"
    return pymr.run(CYLINDER, out, overrides={
        "scene.t_end": 0.005, "output.quantities": ["coordinates", "markers", "marker_accelerations",
                                                    "marker_orientations", "reactions", "energy"]})


def test_every_column_has_its_group_owner_quantity_and_unit(cylinder):
    info = {c.name: c for c in cylinder.column_info}
    assert [c.name for c in cylinder.column_info] == cylinder.columns
    assert (info["t"].group, info["t"].unit) == ("time", "s")
    # a revolute joint's coordinate is an angle in rad, a prismatic's a displacement in m
    assert info["elevation.q"] == pymr.results.Column("elevation.q", "joint_coordinates", "elevation", "angle", "rad")
    assert info["elevation.qd"].unit == "rad/s" and info["elevation.qd"].group == "joint_rates"
    assert info["stroke.q"] == pymr.results.Column("stroke.q", "joint_coordinates", "stroke", "displacement", "m")
    assert (info["stroke.qd"].quantity, info["stroke.qd"].unit) == ("velocity", "m/s")
    assert (info["gun.a1"].group, info["gun.a1"].owner, info["gun.a1"].unit) == ("modal_coordinates", "gun", "m kg^0.5")
    assert info["gun.ad4"].unit == "m kg^0.5/s"
    assert (info["muzzle.vy"].group, info["muzzle.vy"].quantity, info["muzzle.vy"].unit) == ("markers", "velocity", "m/s")
    assert (info["rod_eye.az"].group, info["rod_eye.az"].unit) == ("marker_accelerations", "m/s^2")
    assert (info["muzzle.qw"].group, info["muzzle.qw"].unit) == ("marker_orientations", "1")
    # the fixed bracket has reactions and no coordinates
    assert (info["bracket.fx"].owner, info["bracket.fx"].unit, info["bracket.mz"].unit) == ("bracket", "N", "N m")
    assert "bracket.q" not in info
    energies = [c for c in cylinder.column_info if c.group == "energy"]
    assert [c.quantity for c in energies] == ["kinetic", "gravity", "strain", "springs", "total", "drive_work",
                                              "load_work", "motion_work", "damping_loss"]
    assert {c.unit for c in energies} == {"J"} and cylinder.unit("energy.total") == "J"


def test_results_read_names_from_the_metadata(cylinder):
    # the loop-closing rod_pin has reactions, and no coordinates
    assert cylinder.joints == ["traverse", "elevation", "cyl_hinge", "stroke"]
    assert cylinder.reaction("rod_pin")[0].shape == (len(cylinder.t), 3)
    assert cylinder.flexible_bodies == ["gun"] and cylinder.markers == ["muzzle", "rod_eye", "cradle_pin"]
    n, _, _ = pymr.model_size(CYLINDER)
    q, qd = cylinder.coordinates()
    assert q.shape == qd.shape == (len(cylinder.t), n)
    assert cylinder.coordinate_columns()[:2] == ["traverse.q", "elevation.q"]
    assert np.array_equal(q[:, -4:], cylinder.modal("gun")[0])
    force, moment = cylinder.reaction("bracket")
    assert np.array_equal(force[:, 2], cylinder["bracket.fz"]) and np.array_equal(moment[:, 0], cylinder["bracket.mx"])


def test_a_free_joint_has_three_displacements_then_three_angles(tmp_path):
    res = pymr.run(CHAIN, tmp_path / "chain.csv", overrides={"scene.t_end": 0.002})
    free = [c for c in res.column_info if c.owner == "j1" and c.group == "joint_coordinates"]
    assert [c.name for c in free] == [f"j1.q{k}" for k in range(1, 7)]
    assert [c.unit for c in free] == ["m"] * 3 + ["rad"] * 3
    assert res.joint("j1")[1].shape[1] == 6


def test_results_without_metadata_are_a_clear_error(cylinder, tmp_path):
    """A CSV without OUT.json beside it (or with one written before the metadata) can be read
    by column name, and names no joint or marker: a ResultsError says why."""
    bare = tmp_path / "bare.csv"
    bare.write_text(Path(cylinder.path).read_text())
    res = pymr.load_results(bare)
    assert np.array_equal(res["muzzle.x"], cylinder["muzzle.x"])
    with pytest.raises(pymr.ResultsError, match="no column metadata"):
        res.markers
    stats = json.loads(Path(cylinder.path).with_suffix(".json").read_text())
    del stats["columns"]
    bare.with_suffix(".json").write_text(json.dumps(stats))
    with pytest.raises(pymr.ResultsError, match="run the scene again"):
        pymr.load_results(bare).joint("elevation")


@pytest.mark.parametrize("scene, over", [("tank_elevation_cylinder.nml", {}), ("tank_hold.nml", {"scene.start": "static"}),
                                         ("spatial_chain.nml", {}), ("flexible_chain.nml", {})])
def test_the_initial_state_and_names_come_without_a_run(scene, over, tmp_path):
    """pymr.api.initial_state gives the run's first row (loops assembled, a static start
    settled) bit for bit, and Model the coordinates' and markers' names of its columns."""
    from pymr.api import initial_state
    path = ROOT / "input" / scene
    res = pymr.run(path, tmp_path / "r.csv", overrides={**over, "scene.t_end": 1e-9, "output.dt": 0.0})
    q, qd = initial_state(path, over)
    q0, qd0 = res.coordinates()
    assert np.array_equal(q, q0[0]) and np.array_equal(qd, qd0[0])
    if over:
        assert res.stats["static_start"]["newton_iterations"] > 0
    with pymr.Model(path) as model:
        assert model.coordinate_names() == res.coordinate_columns()
        assert model.marker_names() == res.markers
