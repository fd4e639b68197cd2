"""Result files: the CSV's numbers read back to the last bits, columns and JSON fields
as ARCHITECTURE.md fixes them."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

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


@pytest.mark.parametrize("q0", [np.nextafter(1e-5, 0.0), np.nextafter(0.1, 0.0), np.nextafter(1.0, 0.0),
                                np.nextafter(np.nextafter(1e-3, 0.0), 0.0)])
def test_csv_numbers_just_below_a_power_of_ten_keep_17_digits(tmp_path, q0):
    """A number one or two ulp below a power of ten scales to exactly 10 (or 1) in double
    precision: its digits are then found from the double-double, not the rounded product.
    The pendulum's initial angle is written as d.dddddddddddddddde-XXX, 17 significant
    digits, and reads back exactly (the writer had put 0.9999999999999999e-004, 16 digits)."""
    out = tmp_path / "p.csv"
    res = pymr.run(ROOT / "input" / "pendulum.nml", out, overrides={"scene.t_end": 0.01, "joint[pivot].q0": q0})
    assert res["pivot.q"][0] == q0
    lines = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")]
    text = lines[1].split(",")[lines[0].split(",").index("pivot.q")]
    assert text[0] in "123456789" and text[1] == "." and len(text) == 23 and float(text) == q0


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


@pytest.mark.parametrize("method, coupling", [("multirate", "exponential"), ("multirate", "response"), ("auto", None)])
def test_an_adaptive_multirate_run_names_its_coupling(method, coupling):
    """The method line of an adaptive multirate run names its coupling (an adaptive
    'response' and 'exponential' run printed the same line); a run of method 'auto' names
    the one it chose, as its statistics record it."""
    over = {"scene.t_end": 0.05, "integrator.method": method, "integrator.adaptive": True, "integrator.rtol": 1e-4}
    if coupling:
        over["integrator.coupling"] = coupling
    res = pymr.run(ROOT / "input" / "tank_gun_turret.nml", overrides=over)
    kind, name = (("multirate", coupling) if coupling else res.stats["method_choice"]["chosen"].split("'")[:2])
    label = f"multirate adaptive coupling={name}" if kind.startswith("multirate") else f"single adaptive {name}"
    assert res.method == f"{label} rtol= 1.00E-04 atol= 1.00E-08"   # the choice rests on measured CPU


def test_results_names_meta_and_accessors(tmp_path):
    """Markers, joints and flexible bodies by name; the CSV's title and method; run(output=None)
    leaves no files."""
    out = tmp_path / "tank.csv"
    res = pymr.run(ROOT / "input" / "tank_gun_turret.nml", out, overrides={"scene.t_end": 0.01})
    assert res.markers == ["muzzle"]
    assert res.joints == ["traverse", "elevation"]
    assert res.flexible_bodies == ["gun"]
    assert res.title == res.meta["title"] == "tank gun-turret (Kim and Kim 2000)"
    assert res.method == res.meta["method"] and res.method.startswith("single fixed")
    assert list(res.meta) == ["title", "method"]  # the '# key: value' lines only, as documented
    assert res.scene is None                      # the CSV does not name its scene file
    assert res.stats["steps_slow"] == 100
    q, qd = res.joint("elevation")
    assert q.shape == qd.shape == (11, 1)
    assert np.array_equal(q[:, 0], res["elevation.q"]) and np.array_equal(qd[:, 0], res["elevation.qd"])
    a, ad = res.modal("gun")
    assert a.shape == (11, 4)
    assert np.array_equal(a, np.column_stack([res[f"gun.a{i}"] for i in range(1, 5)]))
    assert np.array_equal(ad[:, 3], res["gun.ad4"])
    for call, arg, listed in ((res.marker, "nose", "markers: muzzle"),
                              (res.joint, "wrist", "joints: traverse, elevation"),
                              (res.modal, "turret", "flexible bodies: gun")):
        try:
            call(arg)
        except KeyError as exc:
            assert repr(arg) in str(exc) and listed in str(exc)
        else:
            raise AssertionError(f"{arg} should be unknown")

    chain = pymr.run(ROOT / "input" / "spatial_chain.nml", None, overrides={"scene.t_end": 0.01})
    assert chain.joints == ["j1", "j2", "j3", "j4", "j5", "j6"] and chain.flexible_bodies == []
    q, qd = chain.joint("j1")
    assert q.shape[1] == 6 and np.array_equal(qd[:, 5], chain["j1.qd6"])
    assert chain.joint_columns("j1") == [f"j1.q{i}" for i in range(1, 7)]
    assert not Path(chain.path).exists()          # output=None: the files are gone
    # and the summary does not name them (its 'results:' line named the removed folder)
    assert chain.summary.splitlines()[-1] == "results: not kept (output=None)"


EXTREME = [1.2345678901234567e-150, -9.8765432109876543e-150, 5.0e-140, 2.5e-300, 7.0e-99, 1.0e-100,
           9.99e-101, -4.4e-123, 6.02214076e-123, 2.2250738585072014e-308]


def test_csv_numbers_with_three_digit_exponents_round_trip(tmp_path):
    """Sliders at rest at positions from 1e-99 down to the smallest normal number (no force
    acts; positions beyond 1e6 m and below the smallest normal number are refused as input;
    the writer's subnormal texts are checked through the writer itself, below): every
    written value, read back by
    Python's own float(), is the position given, and the text has the form
    d.dddddddddddddddde-XXX (17 digits, a three-digit exponent)."""
    bodies = "".join(f"&body name = 'b{i}', kind = 'rigid', mass = 1.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /\n"
                     f"&joint name = 's{i}', kind = 'prismatic', parent = 'ground', child = 'b{i}', "
                     f"axis = 1.0, 0.0, 0.0, q0 = {x!r} /\n" for i, x in enumerate(EXTREME))
    scene = tmp_path / "far.nml"
    scene.write_text("&scene title = 'sliders at rest, far and near', t_end = 0.01 /\n"
                     "&integrator method = 'single', h_slow = 1.0e-3 /\n"
                     "&body name = 'ground', kind = 'ground' /\n" + bodies + "&output dt = 5.0e-3 /\n")
    out = tmp_path / "far.csv"
    pymr.run(scene, out)
    lines = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")]
    header = lines[0].split(",")
    assert len(lines) == 4
    for row in lines[1:]:
        cells = dict(zip(header, row.split(",")))
        for i, x in enumerate(EXTREME):
            text = cells[f"s{i}.q"].strip()
            assert float(text) == x, (text, x)
            mantissa, exponent = text.lower().split("e")
            assert int(exponent) == int(f"{x:.16e}".split("e")[1]), (text, x)
            assert len(mantissa.lstrip("-").replace(".", "")) == 17, text
            assert float(cells[f"s{i}.qd"]) == 0.0


def test_output_precision_sets_the_digits_written(tmp_path):
    """&output precision = 8 writes every value in 8 significant digits, each the value of the
    full-precision run rounded to 8 digits (within half a unit in the 8th digit)."""
    scene = ROOT / "input" / "pendulum.nml"
    full = pymr.run(scene, tmp_path / "full.csv", overrides={"scene.t_end": 0.5})
    short = pymr.run(scene, tmp_path / "short.csv", overrides={"scene.t_end": 0.5, "output.precision": 8})
    nonzero = full.data != 0
    assert np.all(np.abs(short.data - full.data)[nonzero] <= 0.5e-7 * np.abs(full.data)[nonzero] * (1 + 1e-9))
    assert np.array_equal(short.data[~nonzero], full.data[~nonzero])
    row = [c for c in (tmp_path / "short.csv").read_text().splitlines() if not c.startswith("#")][5].split(",")
    assert all(len(c.split("e")[0].lstrip("-").replace(".", "")) == 8 for c in row if c != "0.0")
    with pytest.raises(pymr.SceneError, match=r"&output: precision: must be in \[6, 17\], got 20"):
        pymr.run(scene, overrides={"output.precision": 20})


def test_negative_zero_keeps_its_sign_in_the_csv(tmp_path):
    """A slider at rest at -0.0 is written as -0.0 (and read back with its sign)."""
    scene = tmp_path / "z.nml"
    scene.write_text("&scene title = 'signed zero', t_end = 0.002 /\n&integrator method = 'single', h_slow = 1.0e-3 /\n"
                     "&body name = 'ground', kind = 'ground' /\n"
                     "&body name = 'b', kind = 'rigid', mass = 1.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /\n"
                     "&joint name = 's', kind = 'prismatic', parent = 'ground', child = 'b', axis = 1.0, 0.0, 0.0, "
                     "q0 = -0.0 /\n")
    out = tmp_path / "z.csv"
    pymr.run(scene, out)
    lines = [ln for ln in out.read_text().splitlines() if not ln.startswith("#")]
    first = dict(zip(lines[0].split(","), lines[1].split(",")))
    assert first["s.q"] == "-0.0" and np.signbit(float(first["s.q"]))
    assert first["s.qd"] == "0.0"


def test_every_finite_double_reads_back_from_its_csv_text():
    """The CSV formatter (the kernel's own, through the binding) on 100,000 random bit
    patterns over the whole exponent range (subnormals included) and 100,000 values of
    magnitude 1e-21 to 1e22 (its fast double-double path), with both signs and zeros: every
    17-digit text reads back by Python's float() to the same double (measured: all, 0 ulp),
    and 8-digit texts equal the correctly rounded ones of Python's '%.7e' (all)."""
    from pymr import _testhooks
    rng = np.random.default_rng(7)
    bits = rng.integers(0, 2**63, size=100_000, dtype=np.uint64)
    bits |= rng.integers(0, 2, size=bits.size, dtype=np.uint64) << np.uint64(63)
    wide = bits.view(np.float64)
    wide = wide[np.isfinite(wide)]
    fast = rng.uniform(1.0, 10.0, 100_000) * 10.0 ** rng.integers(-21, 22, 100_000) * rng.choice([-1.0, 1.0], 100_000)
    edge = np.array([0.0, -0.0, 5e-324, -5e-324, 2.2250738585072014e-308, 1.7976931348623157e308, 1e22, 1e-21,
                     9.999999999999999e21, 0.1, 1 / 3])
    x = np.concatenate([wide, fast, edge])

    def texts(values, digits):
        codes = _testhooks.pymr_format_reals(values, digits)
        return [bytes(codes[:, i].astype(np.uint8)).decode().strip() for i in range(values.size)]

    back = np.array([float(s) for s in texts(x, 17)])
    assert np.array_equal(back.view(np.int64), x.view(np.int64))
    eight = texts(fast, 8)
    assert all(float(s) == float("%.7e" % v) for s, v in zip(eight, fast))


@pytest.fixture(scope="module")
def swapped(tmp_path_factory):
    """A pendulum run (pend.csv, pend.json) with its data rows 5 and 6 swapped: the row
    count and the byte count the statistics give still fit."""
    d = tmp_path_factory.mktemp("swapped")
    pymr.run(ROOT / "input" / "pendulum.nml", d / "pend.csv", overrides={"scene.t_end": 0.2})
    lines = (d / "pend.csv").read_text().splitlines(keepends=True)
    head = next(i for i, t in enumerate(lines) if t.startswith("t,"))
    lines[head + 5], lines[head + 6] = lines[head + 6], lines[head + 5]
    (d / "pend.csv").write_text("".join(lines))
    return d / "pend.csv"


@pytest.mark.parametrize("command", [["plot", "-o", "p.png"], ["view", "-o", "v.html"], ["animate", "-o", "a.png"],
                                     ["export", "--vtk", "vtk"]], ids=["plot", "view", "animate", "export"])
def test_every_command_refuses_results_whose_times_go_back(swapped, tmp_path, monkeypatch, capsys, command):
    """Rows out of time order are refused by the results reader for each command that reads
    results (one line naming the file and the row, exit 1, nothing written); two rows of one
    time are not refused there: a run at a low &output precision writes them."""
    from pymr.cli import main
    monkeypatch.chdir(tmp_path)
    assert main([command[0], str(swapped), *command[1:]]) == 1
    assert capsys.readouterr().err == (f"pymr: error: {swapped}: row 6, column t: 0.04 is before the row before it "
                                       "(0.05; a run writes its rows in time: the file was changed)\n")
    assert not list(tmp_path.iterdir())
