"""Result files: the CSV's numbers read back to the last bits, columns and JSON fields
as ARCHITECTURE.md fixes them."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

import pymr

ROOT = Path(__file__).resolve().parent.parent


def test_csv_numbers_round_trip(tmp_path):
    """17 significant digits: t = k dt to 2 ulp, and the pendulum's tip stays exactly 1 m
    from the pivot (a rigid-body identity) to 4e-16 in the written numbers."""
    res = pymr.run(ROOT / "input" / "pendulum.nml", tmp_path / "p.csv", overrides={"scene.t_end": 1.0})
    k = np.arange(len(res.t))
    assert np.all(np.abs(res.t - k * 0.01) <= 2 * np.spacing(np.maximum(res.t, 1e-300)))
    pos, vel = res.marker("tip")
    assert np.abs(np.hypot(pos[:, 0], pos[:, 1]) - 1.0).max() < 4e-16
    # tip velocity = qd x r (planar rotation about z), from independent columns
    qd = res["pivot.qd"]
    assert np.abs(vel[:, 0] + qd * pos[:, 1]).max() < 1e-14
    assert np.abs(vel[:, 1] - qd * pos[:, 0]).max() < 1e-14


def test_csv_layout_and_json(tmp_path):
    out = tmp_path / "tank.csv"
    pymr.run(ROOT / "input" / "tank_gun_turret.nml", out, overrides={"scene.t_end": 0.01})
    lines = out.read_text().splitlines()
    assert [ln[:1] for ln in lines[:3]] == ["#", "#", "#"]
    assert lines[3].split(",") == ["t", "traverse.q", "traverse.qd", "elevation.q", "elevation.qd",
                                   "gun.a1", "gun.a2", "gun.a3", "gun.a4", "gun.ad1", "gun.ad2", "gun.ad3",
                                   "gun.ad4", "muzzle.x", "muzzle.y", "muzzle.z", "muzzle.vx", "muzzle.vy",
                                   "muzzle.vz"]
    data = np.loadtxt(out, delimiter=",", comments="#", skiprows=4)
    assert data.shape == (11, 19)
    stats = json.loads(out.with_suffix(".json").read_text())
    for key in ("cpu_time_s", "wall_time_s", "steps_slow", "steps_fast", "rhs_full", "rhs_fast",
                "rejected_steps", "effects", "integrator"):
        assert key in stats
    assert stats["integrator"]["method"] == "single" and stats["integrator"]["h_slow"] == 1e-4
    assert stats["effects"]["gravity"]["evaluations"] == stats["rhs_full"]
