"""pymr plot: the figure's lines are the runs' arrays exactly (the tank's muzzle position,
velocity and modal coordinates, the paper's Figs. 5-7; a pendulum's markers and joints by
name), the legend names each run, the PNG is written, and bad input is one line, exit 1."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pymr
import pymr.cli
import pymr.plot
from pymr.plot import PlotError, plot_results

ROOT = Path(__file__).resolve().parent.parent
TANK = ROOT / "input" / "tank_gun_turret.nml"
MULTIRATE_K10 = {"integrator.method": "multirate", "integrator.h_slow": 1e-3, "integrator.h_fast": 1e-4,
                 "output.dt": 1e-3}
PNG = b"\x89PNG\r\n\x1a\n"
TANK_PANELS = ["muzzle.x", "muzzle.y", "muzzle.z", "muzzle.vx", "muzzle.vy", "muzzle.vz",
               "gun.a1", "gun.a2", "gun.a3", "gun.a4"]


@pytest.fixture(scope="module")
def tank(tmp_path_factory):
    """The tank over 1 s, single-rate and multirate k = 10, as CSV files and Results."""
    d = tmp_path_factory.mktemp("tank")
    single = pymr.run(TANK, d / "single.csv")
    k10 = pymr.run(TANK, d / "k10.csv", overrides=MULTIRATE_K10)
    return d / "single.csv", d / "k10.csv", single, k10


@pytest.fixture(scope="module")
def double_pendulum(tmp_path_factory):
    d = tmp_path_factory.mktemp("dp")
    res = pymr.run(ROOT / "input" / "double_pendulum.nml", d / "dp.csv", overrides={"scene.t_end": 1.0})
    return d / "dp.csv", res


def panels(fig) -> dict:
    """Axes title (the column's name) -> the axes' lines, one per run."""
    return {ax.get_title(): ax.get_lines() for ax in fig.axes}


def legend_labels(fig) -> list[str]:
    assert len(fig.legends) == 1
    return [t.get_text() for t in fig.legends[0].get_texts()]


def assert_tank_lines(fig, runs, labels):
    lines = panels(fig)
    assert list(lines) == TANK_PANELS
    for k, res in enumerate(runs):
        pos, vel = res.marker("muzzle")
        a, _ = res.modal("gun")
        expected = dict(zip(TANK_PANELS, [*pos.T, *vel.T, *a.T]))
        for col, y in expected.items():
            line = lines[col][k]
            assert len(lines[col]) == len(runs)
            assert np.array_equal(line.get_xdata(), res.t)
            assert np.array_equal(line.get_ydata(), y)
            assert np.array_equal(line.get_ydata(), res[col])
            assert line.get_label() == labels[k]
    assert legend_labels(fig) == labels


def test_tank_figs_5_to_7_overlay(tank, tmp_path):
    """Figs. 5-7: muzzle position, velocity and gun.a1..a4 of both runs, read back exactly;
    the legend names each run by its method."""
    s_csv, k_csv, single, k10 = tank
    out = tmp_path / "fig.png"
    fig = plot_results([s_csv, k_csv], out)
    assert out.read_bytes()[:8] == PNG
    labels = legend_labels(fig)
    assert labels[0] == "single fixed h=1.000E-04"
    assert labels[1].startswith("multirate") and "h_slow=1.000E-03" in labels[1] and "h_fast=1.000E-04" in labels[1]
    assert_tank_lines(fig, [single, k10], labels)
    # the two runs differ (k = 10 is a few mm off), so the overlay shows two curves
    assert not np.array_equal(single["muzzle.y"], k10["muzzle.y"])
    assert "Figs. 5-7" in fig._suptitle.get_text()


def test_tank_from_results_and_labels(tank):
    """Results objects plot the same; given labels replace the methods; named joints are
    added to the tank's panels."""
    _, _, single, k10 = tank
    fig = plot_results([single, k10], labels=["single-rate", "k = 10"], joints=["elevation"])
    lines = panels(fig)
    assert list(lines) == TANK_PANELS[:6] + ["elevation.q"] + TANK_PANELS[6:]
    assert np.array_equal(lines["elevation.q"][1].get_ydata(), k10.joint("elevation")[0][:, 0])
    assert legend_labels(fig) == ["single-rate", "k = 10"]


def test_default_labels_fall_back_to_stem(tank):
    """No method in the metadata: the file's stem; two runs with one method: stem and method."""
    s_csv, _, single, _ = tank
    bare = pymr.Results(columns=single.columns, data=single.data, meta={}, path="/x/case_a.csv")
    assert pymr.plot.default_labels([bare]) == ["case_a"]
    twin = pymr.load_results(s_csv)
    twin.path = "/y/again.csv"
    assert pymr.plot.default_labels([single, twin]) == ["single: single fixed h=1.000E-04",
                                                         "again: single fixed h=1.000E-04"]


def test_cli_tank(tank, tmp_path, monkeypatch, capsys):
    """pymr plot A.csv B.csv -o FIG.png --labels ...: the PNG, and the figure the command drew
    holds the runs' arrays."""
    s_csv, k_csv, single, k10 = tank
    figures = []

    def spy(*args, **kw):
        figures.append(real(*args, **kw))
        return figures[-1]

    real = pymr.plot.plot_results
    monkeypatch.setattr(pymr.plot, "plot_results", spy)
    out = tmp_path / "table1.png"
    assert pymr.cli.main(["plot", str(s_csv), str(k_csv), "-o", str(out), "--labels", "single", "k = 10"]) == 0
    assert out.read_bytes()[:8] == PNG
    assert f"wrote {out}" in capsys.readouterr().out
    assert_tank_lines(figures[0], [single, k10], ["single", "k = 10"])

    # default output: the first CSV's stem + .png, in the working folder; labels from metadata
    monkeypatch.chdir(tmp_path)
    assert pymr.cli.main(["plot", str(s_csv), str(k_csv), "--quiet"]) == 0
    assert (tmp_path / "single.png").read_bytes()[:8] == PNG
    assert capsys.readouterr().out == ""
    assert legend_labels(figures[1])[0] == "single fixed h=1.000E-04"


@pytest.mark.parametrize("suffix", [".eps", ".ps"])
def test_a_postscript_figure_prints_nothing_but_its_line(double_pendulum, tmp_path, suffix):
    """PostScript has no transparency: a grid or legend drawn at 0.3 or 0.8 opacity made
    matplotlib warn on stderr at every figure, and '-q' let it through. The figure is drawn
    opaque now; its grid is matplotlib's grey at 0.3 opacity on white (0.907)."""
    csv, _ = double_pendulum
    out = tmp_path / f"fig{suffix}"
    for quiet, said in ((["-q"], ""), ([], f"wrote {out}: 1 run, ")):
        r = subprocess.run([sys.executable, "-m", "pymr", "plot", str(csv), "-o", str(out), *quiet],
                           capture_output=True, text=True, cwd=tmp_path)
        assert (r.returncode, r.stderr) == (0, "") and r.stdout.startswith(said)
        assert out.read_bytes()[:4] in (b"%!PS", b"\xc5\xd0\xd3\xc6")
    assert float(pymr.plot.GRID_GREY) == pytest.approx(1 - 0.3 * (1 - 0xb0 / 255), abs=1e-3)


def test_other_scene_markers_and_joints(double_pendulum, tmp_path):
    """The double pendulum: its marker's position and velocity and every joint by name."""
    csv, res = double_pendulum
    assert res.markers == ["tip"] and res.joints == ["shoulder", "elbow"]
    fig = plot_results([csv], tmp_path / "dp.png")
    assert (tmp_path / "dp.png").read_bytes()[:8] == PNG
    lines = panels(fig)
    assert list(lines) == ["tip.x", "tip.y", "tip.z", "tip.vx", "tip.vy", "tip.vz", "shoulder.q", "elbow.q"]
    pos, vel = res.marker("tip")
    for i, c in enumerate("xyz"):
        assert np.array_equal(lines[f"tip.{c}"][0].get_ydata(), pos[:, i])
        assert np.array_equal(lines[f"tip.v{c}"][0].get_ydata(), vel[:, i])
    for j in ("shoulder", "elbow"):
        (line,) = lines[f"{j}.q"]
        assert np.array_equal(line.get_xdata(), res.t)
        assert np.array_equal(line.get_ydata(), res.joint(j)[0][:, 0])
        assert np.array_equal(line.get_ydata(), res[f"{j}.q"])
    assert res.method == "single adaptive adams rtol= 1.00E-09 atol= 1.00E-11"
    assert legend_labels(fig) == ["single adaptive adams rtol=1.00E-09 atol=1.00E-11"]


def test_cli_chosen_joint(double_pendulum, tmp_path, monkeypatch):
    csv, res = double_pendulum
    figures = []
    real = pymr.plot.plot_results
    monkeypatch.setattr(pymr.plot, "plot_results", lambda *a, **k: figures.append(real(*a, **k)) or figures[-1])
    out = tmp_path / "elbow.png"
    assert pymr.cli.main(["plot", str(csv), "--marker", "tip", "--joint", "elbow", "-o", str(out), "-q"]) == 0
    assert out.read_bytes()[:8] == PNG
    lines = panels(figures[0])
    assert list(lines) == ["tip.x", "tip.y", "tip.z", "tip.vx", "tip.vy", "tip.vz", "elbow.q"]
    assert np.array_equal(lines["elbow.q"][0].get_ydata(), res["elbow.q"])


@pytest.mark.parametrize("extra, words", [
    (["--marker", "nose"], ["no marker 'nose'", "markers: muzzle"]),
    (["--joint", "elbow"], ["no joint 'elbow'", "joints: traverse, elevation"]),
    (["--labels", "a", "b"], ["labels: 2 given for 1 result files"]),
])
def test_cli_bad_names_one_line(tank, tmp_path, capsys, extra, words):
    s_csv = tank[0]
    out = tmp_path / "never.png"
    assert pymr.cli.main(["plot", str(s_csv), "-o", str(out), *extra]) == 1
    err = capsys.readouterr().err
    assert err.startswith("pymr: error: ") and err.count("\n") == 1
    for w in words:
        assert w in err
    assert not out.exists()


@pytest.mark.parametrize("option", ["--column", "--marker", "--joint"])
@pytest.mark.parametrize("name", ["", " "], ids=["empty", "blank"])
def test_cli_an_empty_name_is_named_by_its_option(double_pendulum, tmp_path, capsys, option, name):
    """`--column ''` (an unset shell variable) said 'columns[0]: an empty name', the plotting
    function's argument, not the option typed; the function keeps its argument's name."""
    csv, res = double_pendulum
    out = tmp_path / "never.png"
    assert pymr.cli.main(["plot", str(csv), option, name, "-o", str(out)]) == 1
    assert capsys.readouterr().err == f"pymr: error: {option}: an empty name\n"
    assert not out.exists()
    with pytest.raises(pymr.SceneError, match=r"^columns\[1\]: an empty name$"):
        plot_results([res], columns=["tip.x", name])


def test_cli_missing_or_bad_csv(tmp_path, capsys):
    missing = tmp_path / "missing.csv"
    assert pymr.cli.main(["plot", str(missing)]) == 1
    err = capsys.readouterr().err
    assert err == f"pymr: error: {missing}: no such result file\n"
    bad = tmp_path / "bad.csv"
    bad.write_text("a,b\n1,2\n")
    assert pymr.cli.main(["plot", str(bad)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"pymr: error: {bad}: not a pymr result file") and err.count("\n") == 1


def test_api_errors(tank, double_pendulum):
    s_csv, _, single, _ = tank
    with pytest.raises(PlotError, match="no marker 'nose'"):
        plot_results([single], markers=["nose"])
    with pytest.raises(PlotError, match="no joint 'wrist'"):
        plot_results([s_csv], joints=["wrist"])
    # runs of different scenes: the second lacks what the first plots, named with its file
    with pytest.raises(PlotError, match=r"dp\.csv: no marker 'muzzle'"):
        plot_results([s_csv, double_pendulum[0]])
    assert issubclass(PlotError, pymr.PymrError)


def test_a_value_beyond_what_the_axes_scale_is_refused_naming_the_column(double_pendulum, tmp_path):
    """A column holding 1e308 (finite, so the results are read) was drawn with numpy's
    overflow warnings from matplotlib's ticks on stderr and exit 0; animate and view refused
    it. The column is named; with it left out the figure is drawn; 1e300 is drawn."""
    import copy
    _, res = double_pendulum
    big = copy.deepcopy(res)
    col = big.columns.index("tip.x")
    big.data[5, col] = 1e308
    with pytest.raises(PlotError, match=r"column tip\.x holds 1e\+308, beyond what a plot's axes scale \(\+-1e\+300\)"):
        plot_results([big], tmp_path / "p.png")
    assert not (tmp_path / "p.png").exists()
    plot_results([big], tmp_path / "q.png", columns=["tip.y"])
    big.data[5, col] = 1e300
    plot_results([big], tmp_path / "r.png")
    assert (tmp_path / "q.png").read_bytes()[:8] == PNG == (tmp_path / "r.png").read_bytes()[:8]
