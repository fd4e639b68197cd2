"""Forward dynamics by the articulated-body algorithm (issue 18; fortran/model/articulated.f90):
the same accelerations as assembling and factoring M, on every scene of input/ (flexible
bodies, multi-coordinate joints, prescribed coordinates, every effect), at random states;
the same runs; Pinocchio's ABA on the serial chain when the optional package `pin` is there;
and O(n) growth measured by counting, not by timing (timings are `pymr bench chain`'s)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr.api import model_size
from pymr.bench import pinocchio_chain
from pymr.scenes import serial_chain

ROOT = Path(__file__).resolve().parents[1]
SCENES = sorted(ROOT.glob("input/*.nml")) + sorted(ROOT.glob("input/hard/*.nml"))
LOOP_SCENES = {"tank_elevation_cylinder.nml"}


def accelerations(scene, x, dynamics, t=0.0, over=None):
    with pymr.Model(scene, {**(over or {}), "integrator.dynamics": dynamics}) as model:
        return model.rhs(t, x)


@pytest.mark.parametrize("scene", SCENES, ids=lambda p: p.name)
def test_the_articulated_body_algorithm_solves_m_qdd_p(scene):
    """At three random states and times, qdd by the articulated-body algorithm equals the
    Cholesky solution of the assembled M qdd = P to 1e-11 of the largest acceleration
    (measured: 1e-13 to 1e-14; the flexible chain's modal accelerations of 1e7 differ by
    5e-8, 6e-15 relative)."""
    n, _, _ = model_size(scene)
    if scene.name in LOOP_SCENES:
        # a closed loop takes the mass-matrix path only (the constrained solve needs M's factor)
        with pytest.raises(pymr.SceneError, match="loops are not supported by dynamics = 'articulated'"):
            accelerations(scene, np.zeros(2 * n), "articulated")
        return
    rng = np.random.default_rng(7)
    for trial in range(3):
        x = 0.3 * rng.standard_normal(2 * n)
        t = 0.37 * trial
        a = accelerations(scene, x, "mass_matrix", t)
        b = accelerations(scene, x, "articulated", t)
        assert np.abs(a - b).max() <= 1e-11 * np.abs(a).max(), trial


@pytest.mark.parametrize("scene, over", [
    ("tank_firing", {}),
    ("flexible_chain", {}),
    ("spatial_chain", {}),
])
def test_runs_by_either_path_agree(tmp_path, scene, over):
    """Whole fixed-step runs (moving base and firing load; damped flexible chain; free-floating
    chain) by the two paths agree to 1e-9 of each column's range: the paths differ only in
    roundoff (measured 1e-13 to 2e-11)."""
    path = ROOT / "input" / f"{scene}.nml"
    a = pymr.run(path, tmp_path / "a.csv", overrides={**over, "integrator.dynamics": "mass_matrix"})
    b = pymr.run(path, tmp_path / "b.csv", overrides={**over, "integrator.dynamics": "articulated"})
    scale = np.maximum(np.abs(a.data).max(axis=0), 1e-300)
    assert (np.abs(a.data - b.data) / scale).max() < 1e-9


def test_auto_takes_the_faster_path(tmp_path):
    """'auto' takes the articulated-body algorithm without flexible bodies (a 3-link chain),
    and with them from 12 joint coordinates on (the tank with ten more links hung from its
    turret), else M (the tank): the accelerations by 'auto' are bit for bit those of the
    path chosen, and differ in their last bits from the other's."""
    tank = (ROOT / "input" / "tank_gun_turret.nml").read_text()
    links = "".join(f"&body name='l{i}', kind='rigid', mass=1.0, com=0.2, 0.0, 0.0, inertia=0.01, 0.02, 0.02, 0.0, "
                    f"0.0, 0.0 /\n&joint name='p{i}', kind='revolute', parent='{'turret' if i == 1 else f'l{i - 1}'}', "
                    f"child='l{i}', at=0.4, 0.0, 0.0, axis=0.0, 0.0, 1.0 /\n" for i in range(1, 11))
    cases = [("chain.nml", serial_chain(3), "articulated", "mass_matrix"),
             ("tank.nml", tank, "mass_matrix", "articulated"),
             ("tank_links.nml", tank + links, "articulated", "mass_matrix")]
    rng = np.random.default_rng(1)
    for name, text, chosen, other in cases:
        scene = tmp_path / name
        scene.write_text(text)
        n, _, _ = model_size(scene)
        x = 0.3 * rng.standard_normal(2 * n)
        auto = accelerations(scene, x, "auto")
        assert np.array_equal(auto, accelerations(scene, x, chosen)), name
        assert not np.array_equal(auto, accelerations(scene, x, other)), name


@pytest.mark.parametrize("links", [5, 30, 100])
def test_the_chain_against_pinocchio(links, tmp_path):
    """The serial chain of `pymr bench chain` against Pinocchio's ABA (optional package `pin`)
    at a random state: 1e-10 of the largest acceleration, or, where M's conditioning makes
    that meaningless, ten times closer than Pinocchio's own two algorithms (ABA and CRBA +
    Cholesky) agree. Measured: 3.5e-14, 1.5e-11, 1.0e-10 (Pinocchio's spread there: 2e-15,
    5.2e-11, 8.2e-9; cond(M) = 4e3, 4e7, 3e9)."""
    pin = pytest.importorskip("pinocchio")
    scene = tmp_path / "chain.nml"
    scene.write_text(serial_chain(links))
    model = pinocchio_chain(links)
    data = model.createData()
    rng = np.random.default_rng(links)
    q, qd = 0.3 * rng.standard_normal(links), 0.3 * rng.standard_normal(links)
    ref = pin.aba(model, data, q, qd, np.zeros(links)).copy()
    pin.crba(model, data, q)
    pin.nonLinearEffects(model, data, q, qd)
    pin.cholesky.decompose(model, data)
    spread = np.abs(pin.cholesky.solve(model, data, -data.nle) - ref).max()
    ours = accelerations(scene, np.concatenate([q, qd]), "articulated")[links:]
    assert np.abs(ours - ref).max() <= max(1e-10 * np.abs(ref).max(), 0.1 * spread)


def test_an_adaptive_run_by_either_path_is_as_accurate(tmp_path):
    """Adaptive Adams at rtol 1e-8 on the tank: the two paths choose their steps from
    estimates that differ in roundoff, so their runs differ by the integration error, not
    less; both muzzles are within 2e-8 m of the converged motion (measured: 4.6e-9 m)."""
    tank = ROOT / "input" / "tank_gun_turret.nml"
    ref = pymr.run(tank, tmp_path / "ref.csv", overrides={"integrator.h_slow": 1e-5, "integrator.h_fast": 1e-5,
                                                         "output.dt": 1e-3})
    for dyn in ("articulated", "mass_matrix"):
        res = pymr.run(tank, tmp_path / f"{dyn}.csv", overrides={"integrator.adaptive": True, "integrator.rtol": 1e-8,
                                                                 "integrator.dynamics": dyn})
        assert np.abs(res.marker("muzzle")[0] - ref.marker("muzzle")[0]).max() < 2e-8, dyn
