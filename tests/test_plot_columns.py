"""pymr plot --column (issue 33, "pymr plot draws any column"): names and shell-style
patterns choose columns; each line's data are the column's array itself; columns of one unit
share a panel whose y label holds that unit (the results' column metadata); a still
quantity's round-off does not fill its panel; a pattern matching nothing is one line, exit 1."""
from __future__ import annotations

import fnmatch
from pathlib import Path

import numpy as np
import pytest

import pymr
import pymr.cli
import pymr.plot
from pymr.plot import STILL, PlotError, plot_results

ROOT = Path(__file__).resolve().parent.parent
TANK = ROOT / "input" / "tank_gun_turret.nml"
QUANTITIES = {"scene.t_end": 0.02, "output.quantities": ["coordinates", "markers", "reactions", "energy"]}


@pytest.fixture(scope="module")
def tank(tmp_path_factory):
    """The tank for 20 ms with reactions and energies, and a second run with the step halved."""
    d = tmp_path_factory.mktemp("columns")
    res = pymr.run(TANK, d / "tank.csv", overrides=QUANTITIES)
    half = pymr.run(TANK, d / "half.csv", overrides={**QUANTITIES, "integrator.h_fast": 5e-5,
                                                     "integrator.h_slow": 5e-5, "output.dt": 1e-3})
    return d / "tank.csv", res, d / "half.csv", half


def lines_by_label(fig) -> dict:
    """Line label -> (the line, its axes)."""
    return {line.get_label(): (line, ax) for ax in fig.axes for line in ax.get_lines()}


def drawn(monkeypatch) -> list:
    """The figures pymr.plot.plot_results draws from now on (for the CLI's)."""
    figures = []
    real = pymr.plot.plot_results
    monkeypatch.setattr(pymr.plot, "plot_results", lambda *a, **k: figures.append(real(*a, **k)) or figures[-1])
    return figures


def test_patterns_draw_the_columns_with_their_units(tank, tmp_path, monkeypatch):
    csv, res, _, _ = tank
    figures = drawn(monkeypatch)
    out = tmp_path / "cols.png"
    assert pymr.cli.main(["plot", str(csv), "--column", "energy.*", "elevation.f?", "--column", "gun.a1",
                          "-o", str(out), "-q"]) == 0
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    lines = lines_by_label(figures[0])
    chosen = [c for c in res.columns if fnmatch.fnmatchcase(c, "energy.*")] + \
        ["elevation.fx", "elevation.fy", "elevation.fz", "gun.a1"]
    assert len(chosen) == 13 and list(lines) == chosen
    for name, (line, ax) in lines.items():
        assert np.array_equal(line.get_xdata(), res.t) and np.array_equal(line.get_ydata(), res[name]), name
        assert ax.get_ylabel().endswith(f"({res.unit(name)})"), (name, ax.get_ylabel())
    # one panel per unit: the nine energies (J), the forces (N), the modal coordinate
    assert [ax.get_ylabel() for ax in figures[0].axes] == ["energy (J)", "force (N)", "modal coordinate (m kg^0.5)"]
    assert {lines[c][1] for c in chosen if c.startswith("energy.")} == {figures[0].axes[0]}


def test_several_runs_overlaid_in_a_panel(tank):
    csv, res, half_csv, half = tank
    fig = plot_results([csv, half_csv], columns="elevation.m*", labels=["h", "h/2"])
    (ax,) = fig.axes
    lines = lines_by_label(fig)
    assert list(lines) == [f"elevation.m{c} ({run})" for c in "xyz" for run in ("h", "h/2")]
    for c in "xyz":
        assert np.array_equal(lines[f"elevation.m{c} (h)"][0].get_ydata(), res[f"elevation.m{c}"])
        assert np.array_equal(lines[f"elevation.m{c} (h/2)"][0].get_ydata(), half[f"elevation.m{c}"])
    assert ax.get_ylabel() == "moment (N m)"


def still_results(values: np.ndarray, unit: str = "J") -> pymr.Results:
    """Results of one column 'box.e' (and t) with its metadata."""
    t = np.linspace(0.0, 1.0, len(values))
    stats = {"columns": {"name": ["t", "box.e"], "group": ["time", "energy"], "owner": ["", ""],
                         "quantity": ["time", "total"], "unit": ["s", unit]}}
    return pymr.Results(columns=["t", "box.e"], data=np.column_stack([t, values]), stats=stats, path="box.csv")


def test_round_off_of_a_still_quantity_does_not_fill_the_panel():
    """A constant 7.9 kJ with round-off (a few ulps, 1e-12 J) is drawn in mean +- STILL * 7.9 kJ;
    a varying column keeps matplotlib's range around its values."""
    rng = np.random.default_rng(33)
    still = 7.9e3 + 1e-12 * rng.standard_normal(200)
    fig = plot_results([still_results(still)], columns=["box.e"])
    lo, hi = fig.axes[0].get_ylim()
    centre = 0.5 * (still.max() + still.min())
    assert hi - lo == pytest.approx(2 * STILL * np.abs(still).max(), rel=1e-6)
    assert lo < still.min() and still.max() < hi and 0.5 * (lo + hi) == pytest.approx(centre, abs=1e-9)
    # the same round-off on a column that moves by 1 mJ: the range is the values'
    moving = still + 1e-3 * np.linspace(0.0, 1.0, 200)
    lo, hi = plot_results([still_results(moving)], columns=["box.e"]).axes[0].get_ylim()
    assert hi - lo == pytest.approx(1e-3, rel=0.2)
    # every value zero: matplotlib's own range
    assert not pymr.plot.smallest_range(None, [np.zeros(5)], 0.0)


def test_a_held_drive_torque_is_drawn_still():
    """The held tank: the elevation joint's moment about the child's z is the drive's
    -33451 N m about the joint's axis -z, constant but for round-off (a few 1e-10 N m); its panel shows STILL times the run's largest
    moment (N m) about it, not the round-off."""
    res = pymr.run(ROOT / "input" / "tank_hold.nml",
                   overrides={"scene.t_end": 0.02, "output.quantities": ["coordinates", "reactions"]})
    y = res["elevation.mz"]
    assert np.allclose(y, 33451.0, rtol=1e-13, atol=0) and 0 < np.ptp(y)
    scale = max(np.abs(res[c.name]).max() for c in res.column_info if c.unit == "N m")
    assert scale > np.abs(y).max()                   # the trunnion's is not the largest moment
    lo, hi = plot_results([res], columns=["elevation.mz"]).axes[0].get_ylim()
    assert hi - lo == pytest.approx(2 * STILL * scale) and lo < 33451.0 < hi
    assert hi - lo > 1e4 * np.ptp(y)


@pytest.mark.parametrize("pattern, words", [
    ("enrgy.kin*", ["no column matches 'enrgy.kin*'", "close: energy.kinetic"]),
    ("elevation.fw", ["no column matches 'elevation.fw'", "elevation.fx"]),
    ("zz*", ["no column matches 'zz*'", "columns: traverse.q, traverse.qd"]),
])
def test_a_pattern_matching_nothing_is_one_line(tank, tmp_path, capsys, pattern, words):
    csv, _, _, _ = tank
    out = tmp_path / "never.png"
    assert pymr.cli.main(["plot", str(csv), "--column", "energy.total", pattern, "-o", str(out)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"pymr: error: {csv}: ") and err.count("\n") == 1, err
    for w in words:
        assert w in err
    assert not out.exists()


def test_columns_alone_and_the_same_scene(tank, tmp_path, capsys):
    csv, res, _, _ = tank
    assert pymr.cli.main(["plot", str(csv), "--column", "energy.*", "--marker", "muzzle"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "draw the chosen columns alone" in err
    other = pymr.run(ROOT / "input" / "pendulum.nml", tmp_path / "p.csv", overrides={"scene.t_end": 0.01})
    with pytest.raises(PlotError, match=r"p\.csv: no column 'elevation\.q'"):
        plot_results([res, other], columns=["elevation.q"])
