"""The shipped scene input/tank_on_the_move.nml (issue 32) and its tables: the tables are the
generator's (pymr.scenes.tank_on_the_move_tables) and its interior ballistics keeps its own
balances; the scene's motion keeps the energy balance with every part in it."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr import scenes

ROOT = Path(__file__).resolve().parent.parent
SCENE = ROOT / "input" / "tank_on_the_move.nml"
TABLES = ROOT / "input" / "tank_on_the_move"


def test_the_shipped_tables_are_the_generators(tmp_path):
    """Regenerated, every table equals the shipped one (to its 9 printed digits)."""
    scenes.tank_on_the_move_tables(tmp_path)
    for shipped in sorted(TABLES.glob("*.txt")):
        new = np.loadtxt(tmp_path / shipped.name)
        np.testing.assert_allclose(np.loadtxt(shipped), new, rtol=1e-8, atol=0.0, err_msg=shipped.name)


def test_the_interior_ballistics_keeps_its_momentum_and_energy():
    """The shot's speed is the time integral of its acceleration and its kinetic energy the
    work of the base pressure on its travel (Lagrange: (m_p + C/3) a = p A), both to the
    trapezoid rule's error on the 1 us steps (1e-6 relative); it leaves a 5.3 m barrel from
    its seat at 0.4 m after 5.4 ms at 1748 m/s, a tank gun's range of muzzle velocities."""
    sh = scenes.interior_ballistics()
    t, s, v, a = sh["t"], sh["s"], sh["v"], sh["a"]
    assert v[-1] == pytest.approx(np.trapezoid(a, t), rel=1e-9)
    work = np.trapezoid(a, s)                                # per unit of accelerated mass
    assert 0.5 * v[-1] ** 2 == pytest.approx(work, rel=1e-6)
    assert s[-2] < 5.3 <= s[-1] and s[0] == 0.4
    assert 1500.0 < v[-1] < 1900.0 and 4e-3 < t[-1] < 7e-3
    # the breech force is the base pressure's times (1 + C/(2 m_p))
    assert sh["f"].max() == pytest.approx(np.pi * 0.06**2 * 400e6 * (1 + 8.0 / 12.0), rel=1e-6)


def test_the_terrain_bump_meets_each_station_when_the_tank_reaches_it():
    """A 1 - cos bump 0.1 m high and 1.2 m long, 4 m ahead: at 10 m/s the front station
    (2 m ahead of the chassis origin) is on its crest at 0.26 s, the rear one at 0.66 s."""
    t = np.linspace(0.0, 1.0, 100001)
    for station, crest in (("front", 0.26), ("rear", 0.66)):
        h = scenes.terrain_heights(t, scenes.TANK_STATIONS[station])
        assert h.max() == pytest.approx(0.1, rel=1e-9)
        assert t[np.argmax(h)] == pytest.approx(crest, abs=2e-5)
        assert np.all(h[t < crest - 0.06 - 1e-9] == 0.0)
