"""pymr study: references that agree, tolerance proportionality of adaptive runs on the
tank, the measured cost weights of fast-only evaluations, refused cases, the peers
(scipy, CVODE Adams and BDF) on the same right-hand side, the front summary, and the
table, CSV and figure it writes."""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr.study import Case, Study

TANK = Path(__file__).resolve().parent.parent / "input" / "tank_gun_turret.nml"


@pytest.fixture(scope="module")
def study() -> Study:
    s = Study(TANK, "muzzle", quick=True, progress=None, repeats=3)
    s.reference()
    s.weights()
    return s


def test_reference_is_cross_checked_by_dop853_on_the_same_rhs(study):
    """pymr at rtol 1e-11 and scipy's DOP853 at 1e-12 (through the binding's right-hand side)
    agree on the muzzle to 1.8e-12 m (measured). The common grid is every 40 h = 4 ms."""
    assert study.ref_check < 1e-10
    assert len(study.grid) == 251 and study.grid[-1] == pytest.approx(1.0)
    assert study.ref.shape == (251, 3)


def test_model_rhs_through_the_binding_equals_the_kernel_accelerations():
    with pymr.Model(TANK) as model:
        rng = np.random.default_rng(3)
        x = rng.standard_normal(2 * model.n) * 0.1
        f = model.rhs(0.3, x)
        assert model.evaluations == 1
    qdd = pymr.model_accelerations(TANK, 0.3, x[:6], x[6:])
    assert np.array_equal(f[:6], x[6:]) and np.abs(f[6:] - qdd).max() <= 1e-12 * np.abs(qdd).max()


def test_adaptive_error_falls_tenfold_per_decade_of_rtol(study):
    """Tolerance proportionality of the paper's fixed-order formula on the tank: measured
    1.15e-4, 1.16e-6, 1.19e-9 m at rtol 1e-3, 1e-5, 1e-8 (10.0x per decade)."""
    errs = []
    for rtol in (1e-3, 1e-5, 1e-8):
        c = study._pymr_case("abm4 adaptive", f"{rtol}", {"integrator.adaptive": True, "integrator.rtol": rtol,
                                                            "integrator.atol": rtol * 1e-2,
                                                            "integrator.formula": "abm4"}, repeats=1)
        assert c.status == "ok" and c.runs == 1
        errs.append(c.error_m)
    per_decade = np.diff(np.log10(errs)) / np.diff(np.log10([1e-3, 1e-5, 1e-8]))
    assert per_decade == pytest.approx([1.0, 1.0], abs=0.1)


def test_fast_evaluations_are_weighted_by_their_measured_cost(study):
    """Weights measured from whole runs (integrator work included): a 'response' surrogate
    step costs about 8 % of a full single-rate step, a 'full' coupling fast step about 48 %
    (measured 0.073-0.088 and 0.478-0.56 over several studies; c_full 3.2-4.0 us per
    step). Multirate cases count rhs_full + w rhs_fast, single-rate cases rhs_full; the
    Table 1 case (k = 10, h_fast = 1e-4 s) makes 1000 macro steps of 10 fast steps, so
    its full plus fast-only evaluations are the 10000 steps plus a few of the start, and
    with 'response' one surrogate evaluation more per macro step (at its end, for the
    correction)."""
    w = study.weight
    assert 0 < w["response"] < 0.3 and 0.1 < w["full"] < 1.5
    assert w["response"] < w["full"]                 # the surrogate is cheaper than the fast rows of 'full'
    assert study.weight_ratio == {"response": 10, "full": 10}
    for coupling in ("response", "full"):
        assert w[coupling] == pytest.approx(study.c_fast[coupling] / study.c_full)
        c = study._pymr_case(f"{coupling} fixed k=10", "h_fast=1e-4", study._multirate(coupling, 10, 1e-4),
                             repeats=2)
        assert c.status == "ok" and c.runs == 2
        extra = 1000 if coupling == "response" else 0
        assert 10000 + extra <= c.rhs_full + c.rhs_fast <= 10100 + extra and 1000 <= c.rhs_full <= 1100
        assert c.equivalents == pytest.approx(c.rhs_full + w[coupling] * c.rhs_fast)
    single = study._pymr_case("single fixed", "h=1e-4", {}, repeats=1)
    assert single.rhs_fast == 0 and single.equivalents == single.rhs_full == 10007


def test_refused_cases_are_recorded_not_fatal(study):
    """The 'full' coupling at k = 40, h_fast = 1e-4 s is refused by the pre-flight check
    (its largest stable ratio is 33); the 'response' coupling at the same steps runs, its
    macro step of 4 ms bound only by accuracy (muzzle error measured 6.0e-6 m), with one
    full evaluation per macro step besides the first macro steps: at most 250 + 3 * 40 +
    a few. Its rows between steps come from dense output (k = 40, h_fast = 2e-4 s: the
    macro step of 8 ms spans two 4 ms output times; measured 8.2e-5 m)."""
    full = study._pymr_case("full fixed k=40", "h_fast=1e-4", study._multirate("full", 40, 1e-4), repeats=1)
    assert full.status.startswith("refused") and "largest stable ratio is k = 33" in full.status
    assert full.stable_ratio == 33 and full.stable_step is None        # the error's fields, kept
    assert np.isnan(full.error_m) and np.isnan(full.cpu_s)
    resp = study._pymr_case("response fixed k=40", "h_fast=1e-4", study._multirate("response", 40, 1e-4),
                            repeats=1)
    assert resp.status == "ok" and resp.error_m < 1e-5 and resp.rhs_full <= 250 + 3 * 40 + 10
    wide = study._pymr_case("response fixed k=40", "h_fast=2e-4", study._multirate("response", 40, 2e-4),
                            repeats=1)
    assert wide.status == "ok" and 1e-5 < wide.error_m < 1e-3   # every one of the 251 grid times compared


def test_cvode_bdf_reaches_the_accuracy_of_its_tolerance(study):
    """SUNDIALS CVODE with BDF (dense Newton, difference-quotient Jacobian, whose
    evaluations Model.evaluations counts) on the tank at rtol 1e-6: muzzle error below
    1e-4 m (measured 6.3e-7 m with 3934 evaluations)."""
    pytest.importorskip("sksundae")
    c = study._peer("CVODE BDF", 1e-6, repeats=1)
    assert c.status == "ok"
    assert c.error_m < 1e-4 and c.rhs_full > 1000 and c.equivalents == c.rhs_full


def _front_cases() -> list[Case]:
    def ok(method, setting, err, cpu):
        return Case(method, setting, error_m=err, cpu_s=cpu, rhs_full=100, equivalents=100.0, runs=5)
    return [
        ok("single fixed", "h=4e-4", 1.4e-5, 0.009),
        ok("single fixed", "h=2e-4", 8.7e-7, 0.017),
        ok("abm4 adaptive", "rtol=1e-4", 1.2e-5, 0.010),
        ok("abm4 adaptive", "rtol=1e-5", 1.2e-6, 0.018),
        ok("response fixed k=40", "h_fast=4e-4", 1.2e-4, 0.0017),     # fastest of all, never accurate enough
        ok("response fixed k=20", "h_fast=2e-4", 6.3e-6, 0.0026),
        ok("response fixed k=40", "h_fast=1e-4", 6.0e-6, 0.0034),
        ok("response fixed k=20", "h_fast=1e-4", 8.6e-7, 0.0041),
        ok("response adaptive", "rtol=1e-5", 1.7e-6, 0.0060),
        ok("full fixed k=2", "h_fast=1e-4", 9.0e-7, 0.0010),           # fast, but not the 'response' coupling
        Case("full fixed k=40", "h_fast=1e-4", status="refused: largest stable ratio is k = 33", stable_ratio=33),
        Case("response fixed k=80", "h_fast=1e-4", error_m=1e-9, cpu_s=1e-4, status="failed: made up"),
        ok("CVODE BDF", "rtol=1e-5", 4.5e-6, 0.035),
        ok("response adaptive amplitude", "rtol=3.2e-5", 8.0e-6, 0.0031),
    ]


def test_front_summary_picks_the_fastest_accurate_case_of_each_family():
    """Hand-made cases: at 1e-5 m the fastest single-rate case is fixed h = 2e-4 (0.017 s:
    h = 4e-4 and rtol 1e-4 miss the level), the fastest 'response' case k = 20, h_fast =
    2e-4 (0.0026 s; k = 40, h_fast = 4e-4 misses it): ratio 0.0026 / 0.017. The 'full'
    coupling's faster case and the failed case with a made-up error do not count; at
    1e-7 m no single-rate case qualifies. Adaptive 'response' is set against its fixed
    steps by the faster of its two error norms' cases."""
    s = Study.__new__(Study)
    s.cases = _front_cases()
    rows = s.front_summary(errors=(1e-4, 1e-5, 1e-6, 1e-7))
    assert [r["error"] for r in rows] == [1e-4, 1e-5, 1e-6, 1e-7]
    r4, r5, r6, r7 = rows
    assert (r4["single"].setting, r4["multirate"].setting) == ("h=4e-4", "h_fast=2e-4")
    assert r4["ratio"] == pytest.approx(0.0026 / 0.009)
    assert set(r5["best"]) == {"single fixed", "abm4 adaptive", "response fixed", "response adaptive",
                               "response adaptive amplitude", "full fixed", "CVODE BDF"}
    assert r5["best"]["abm4 adaptive"].setting == "rtol=1e-5"
    assert r5["best"]["response fixed"].method == "response fixed k=20"
    assert (r5["single"].setting, r5["multirate"].method, r5["multirate"].setting) == \
        ("h=2e-4", "response fixed k=20", "h_fast=2e-4")
    assert r5["ratio"] == pytest.approx(0.0026 / 0.017)
    assert r6["multirate"].setting == "h_fast=1e-4" and r6["ratio"] == pytest.approx(0.0041 / 0.017)
    assert r6["best"]["full fixed"].cpu_s == 0.0010 and "CVODE BDF" not in r6["best"]
    assert r7["single"] is None and r7["multirate"] is None and math.isnan(r7["ratio"])
    # adaptive 'response' against its fixed steps: the faster of its two norms' cases
    a, f, ratio = r5["adaptive"]["response"]
    assert (a.method, f.setting) == ("response adaptive amplitude", "h_fast=2e-4")
    assert ratio == pytest.approx(0.0031 / 0.0026)
    assert "exponential" not in r5["adaptive"] and r6["adaptive"] == {}      # no adaptive case reaches 1e-6 m
    text = s.front_text(errors=(1e-5,))
    assert "= 0.15" in text and "(none this accurate)" not in text
    assert "adaptive / fixed 'response': 0.0031 s (response adaptive amplitude rtol=3.2e-5) / 0.0026 s" in text
    assert [c.setting for c in s.refused()] == ["h_fast=1e-4"]


def test_front_contenders_take_more_timing_passes():
    """The cases within FRONT_MARGIN of their family's fastest at some level of the front
    (hand-made, as above) take FRONT_PASSES more timing runs and their CPU becomes the
    median of all of them; the others keep theirs. Here every added run takes 1 ms: a
    contender with one sample of 3.4 ms ends at 1 ms, a case 2x slower than its family's
    fastest at every level it reaches keeps its 0.034 s."""
    from pymr import study as study_module
    s = Study.__new__(Study)
    s.cases = _front_cases() + [Case("response fixed k=40", "h_fast=5e-5", error_m=5e-6, cpu_s=0.034, runs=1)]
    s.say = lambda *a: None
    s.repeats = 1
    s._pymr_cpu = lambda over: 0.001
    runs = [(("pymr", c.method, c.setting, {}), c, [c.cpu_s]) for c in s.cases]
    slow, k40 = s.cases[-1], s.cases[6]
    assert (k40.method, k40.setting, k40.cpu_s) == ("response fixed k=40", "h_fast=1e-4", 0.0034)
    s._time_front(runs)
    assert k40.runs == 1 + study_module.FRONT_PASSES and k40.cpu_s == 0.001
    assert slow.runs == 1 and slow.cpu_s == 0.034
    assert all(c.runs == 0 for c in s.cases if c.status != "ok")


def test_peers_table_csv_and_figure(study, tmp_path):
    """DOP853 and CVODE Adams (when installed) on the kernel's right-hand side reach the
    accuracy of their tolerance; the table, CSV and PNG hold every case, and the refused
    case is named in the table and in the figure's note, not silently left out."""
    study.cases = []
    study._add(study._peer("DOP853", 1e-6, repeats=2))
    study._add(study._peer("CVODE Adams", 1e-6, repeats=2))
    study._add(study._pymr_case("single fixed", "h=1e-4", {}, repeats=2))
    study._add(study._pymr_case("full fixed k=40", "h_fast=0.0001", study._multirate("full", 40, 1e-4)))
    dop, cvode, fixed, refused = study.cases
    assert dop.status == "ok" and dop.error_m < 1e-6 and dop.rhs_full > 1000 and dop.runs == 2
    if cvode.status == "ok":
        assert cvode.error_m < 1e-6
    else:
        assert cvode.status.startswith("skipped")
    assert fixed.error_m == pytest.approx(5.5e-8, rel=0.05)        # measured 5.50e-8 m
    study.write_csv(tmp_path / "s.csv")
    rows = list(csv.DictReader(open(tmp_path / "s.csv")))
    assert [r["method"] for r in rows] == ["DOP853", "CVODE Adams", "single fixed", "full fixed k=40"]
    assert float(rows[2]["error_m"]) == fixed.error_m and rows[3]["status"].startswith("refused")
    note = study.plot(tmp_path / "s.png")
    assert (tmp_path / "s.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "full fixed k=40 h_fast=0.0001: refused (largest stable ratio is k = 33)" in note
    table = study.table()
    assert "single fixed" in table and "refused: largest stable ratio is k = 33" in table
    assert "full fixed k=40" in study.refused_text()
    with pytest.raises(ValueError, match="repeats"):
        Study(TANK, "muzzle", repeats=0)


def test_a_coupling_whose_weight_was_not_measured_leaves_its_equivalents_empty(tmp_path):
    """Where the pre-flight check refuses every weight ratio of a coupling (the flexible
    chain's 'full' at k = 10, 5 and 2), its weight is unknown: the weights line says so and
    its cases' equivalents cell is empty, where 'nan' stood in rows marked ok. A measured
    coupling keeps rhs_full + w rhs_fast (10 + 0.25 x 20 = 15)."""
    s = Study.__new__(Study)
    s.c_full = 6.0e-6
    s.weight, s.c_fast, s.weight_ratio = {"response": 0.25, "full": math.nan}, {"response": 1.5e-6, "full": math.nan}, \
        {"response": 10}
    text = s.weights_text()
    assert "'response' 0.250 (c_fast 1.500 us at k = 10)" in text
    assert "'full' not measured (at k = 10, 5, 2 the pre-flight check refused the run or it failed: its cases have no equivalents)" in text
    s.cases = [Case("full fixed k=5", "h_fast=2.5e-05", error_m=2.8e-3, cpu_s=5e-3, rhs_full=10, rhs_fast=20, runs=1),
               Case("response fixed k=5", "h_fast=2.5e-05", error_m=2.8e-3, cpu_s=5e-3, rhs_full=10, rhs_fast=20,
                    equivalents=10 + 0.25 * 20, runs=1)]
    s.write_csv(tmp_path / "w.csv")
    rows = list(csv.DictReader(open(tmp_path / "w.csv")))
    assert [r["equivalents"] for r in rows] == ["", "15.0"]
    assert "nan" not in (tmp_path / "w.csv").read_text()


def test_cpu_time_is_the_median_of_the_repeats():
    """Median, not mean or minimum: of 0.5, 0.1, 0.3 and 9.0 s it is 0.4 s."""
    c = Case("single fixed", "h=1e-4")
    Study._set_cpu(c, [0.5, 0.1, 0.3, 9.0])
    assert c.cpu_s == pytest.approx(0.4) and c.runs == 4


def test_quick_study_end_to_end(tmp_path, capsys):
    """`pymr study --quick` on the tank, 2 runs per case: 52 cases (single-rate 3 fixed
    steps and 3 tolerances of each formula, 'abm4' and 'adams'; per coupling 'response' and
    'full' 2 ratios x 2 fast steps and 3 tolerances, 'response' with both error norms;
    'exponential' 2 steps and 3 tolerances with each norm; method 'auto' at 3 tolerances;
    5 peers x 3 tolerances), none refused (the quick grid's 'full' ratios 5 and 20 at h_fast
    5e-5 and 2.5e-5 s are within the stability limit of 33 at 1e-4 s), the weights, the
    refusals and a front with its ratio at every level (1e-4 to 1e-7 m) printed."""
    from pymr import study as study_mod
    assert study_mod.main(str(TANK), "muzzle", output=str(tmp_path / "q"), quick=True, repeats=2) == 0
    out = capsys.readouterr().out
    rows = list(csv.DictReader(open(tmp_path / "q.csv")))
    assert len(rows) == 52
    assert sum(r["method"] == "auto adaptive" for r in rows) == 3
    assert sum(r["method"].endswith("adaptive amplitude") for r in rows) == 6
    assert sum(r["method"].startswith("response fixed") for r in rows) == 4
    assert sum(r["method"] == "exponential fixed" for r in rows) == 2
    assert all(r["status"] == "ok" or r["status"].startswith("skipped") for r in rows)
    assert all(int(r["runs"]) == 2 for r in rows if r["status"] == "ok")
    h1 = next(r for r in rows if r["method"] == "single fixed" and r["setting"] == "h=0.0001")
    assert float(h1["error_m"]) == pytest.approx(5.5e-8, rel=0.05)
    assert "refused by the pre-flight check: none" in out and "measured weight w" in out
    assert out.count("fastest multirate / fastest single-rate: ") == 4 and "n/a" not in out
    assert out.count("adaptive / fixed 'response': ") >= 1
    # 'auto' at each level some case of it reaches, against the fastest pymr method there
    auto = [float(r["error_m"]) for r in rows if r["method"] == "auto adaptive"]
    assert out.count("method 'auto' / fastest pymr method: ") == sum(min(auto) <= e for e in (1e-4, 1e-5, 1e-6, 1e-7))
    assert (tmp_path / "q.png").stat().st_size > 10000
    assert "variable order: fewest evaluations" in out and "step and order history of formula 'adams'" in out
    hist = list(csv.DictReader(open(tmp_path / "q_history.csv")))
    assert {r["rtol"] for r in hist} == {"1.0e-04", "1.0e-08"}
    assert all(1 <= int(r["order"]) <= 12 for r in hist)


@pytest.mark.parametrize("t_end", [0.05, 0.3, 0.7])
def test_the_common_grid_is_the_kernel_s_rows_for_any_t_end(tmp_path, t_end):
    """The common output times are k dt up to t_end, the times the kernel writes its rows at
    (output.dt = dt). np.arange's float steps gave one time too many at t_end 0.05 (the
    reference's rows and DOP853's did not match: a traceback) and a time past t_end at 0.7
    (solve_ivp refused it)."""
    scene = tmp_path / "tank.nml"
    scene.write_text(TANK.read_text().replace("t_end = 1.0", f"t_end = {t_end}"))
    s = Study(scene, "muzzle", quick=True, progress=None)
    assert s.grid[-1] <= t_end and t_end - s.grid[-1] < s.dt
    assert np.allclose(s.grid, s.dt * np.arange(len(s.grid)), rtol=0, atol=1e-12)
    res = pymr.run(scene, overrides={"output.dt": s.dt})
    assert s._on_grid(res.t, res.marker("muzzle")[0]).shape == (len(s.grid), 3)
    if t_end == 0.05:
        s.reference()
        assert s.ref.shape == (len(s.grid), 3) and s.ref_check < 1e-10


def test_the_files_follow_a_prefix_with_a_dot(tmp_path):
    """A prefix such as t_0.05 names every file: the table and figure were t_0.csv and t_0.png."""
    from pymr.study import study_files
    names = [p.name for p in study_files(tmp_path / "t_0.05")]
    assert names == ["t_0.05.csv", "t_0.05.png", "t_0.05_history.csv"]


def test_a_refused_fixed_step_family_gets_a_case_at_its_largest_stable_step(tmp_path):
    """The stiff barrel's top mode refuses the step 7.07e-5 s; the refusal names the largest
    stable step (6.74e-5 s), and the family gets one case at 0.995 of it, which the
    pre-flight check passes - once per family, and only for such refusals."""
    stiff = Path(__file__).resolve().parent.parent / "input" / "hard" / "stiff_barrel.nml"
    s = Study(stiff, "muzzle", quick=True, progress=None)
    h = 7.07e-5
    short = {"scene.t_end": 0.02, "output.dt": 1e-3}

    def refused(method, over):
        with pytest.raises(pymr.SceneError) as exc:
            pymr.run(stiff, tmp_path / "x.csv", overrides={**over, **short})
        case = Case(method, "")
        Study._refusal(case, exc.value)
        return case

    single = ("pymr", "single fixed", f"h={h}", {"integrator.method": "single", "integrator.adaptive": False,
                                                 "integrator.h_slow": h, "integrator.h_fast": h})
    case = refused("single fixed", single[3])
    assert "largest stable step is 6.74E-05 s" in case.status
    assert case.status.startswith("refused") and case.stable_step == pytest.approx(6.742e-5, rel=1e-4)
    limited: set[str] = set()
    extra = s._at_stable_step(single, case, limited)
    assert extra[3]["integrator.h_slow"] == pytest.approx(0.995 * case.stable_step)
    assert s._at_stable_step(single, case, limited) is None
    pymr.run(stiff, tmp_path / "ok.csv", overrides={**extra[3], **short})          # passes the check
    multi = ("pymr", "response fixed k=10", "h_fast=7.07e-05", {
        "integrator.method": "multirate", "integrator.coupling": "response", "integrator.adaptive": False,
        "integrator.h_fast": h, "integrator.h_slow": 10 * h})
    extra = s._at_stable_step(multi, refused("response fixed k=10", multi[3]), limited)
    assert extra[3]["integrator.h_fast"] == pytest.approx(0.995 * case.stable_step)
    assert extra[3]["integrator.h_slow"] == pytest.approx(10 * extra[3]["integrator.h_fast"])
    pymr.run(stiff, tmp_path / "ok.csv", overrides={**extra[3], **short})
    assert s._at_stable_step(multi, Case("full fixed k=40", "", status="refused: ... largest stable ratio is k = 33",
                                         stable_ratio=33), limited) is None


def test_order_summary_compares_evaluations_and_cpu():
    """Hand-made cases: at 1e-5 m the fewest 'adams' evaluations (800, rtol 1e-4; 700 at
    rtol 1e-3 misses the level) against CVODE Adams' 1000: 0.8; the fastest 'adams' CPU
    (0.004 s) against pymr's fastest fixed-order case (fixed h = 2e-4, 0.017 s; the faster
    'response' case is not fixed-order single-rate): 0.24. At 1e-8 m no case qualifies."""
    def ok(method, setting, err, cpu, evals):
        return Case(method, setting, error_m=err, cpu_s=cpu, rhs_full=evals, equivalents=float(evals), runs=5)
    s = Study.__new__(Study)
    s.cases = [ok("adams adaptive", "rtol=1e-3", 3e-5, 0.003, 700), ok("adams adaptive", "rtol=1e-4", 5e-6, 0.004, 800),
               ok("CVODE Adams", "rtol=1e-4", 5e-6, 0.03, 1000), ok("single fixed", "h=2e-4", 8e-7, 0.017, 5000),
               ok("abm4 adaptive", "rtol=1e-5", 1e-6, 0.02, 6000), ok("response fixed k=20", "h_fast=1e-4", 1e-6, 0.002, 10)]
    r5, r8 = s.order_summary((1e-5, 1e-8))
    assert r5["adams"].rhs_full == 800 and r5["cvode"].rhs_full == 1000 and r5["evals_ratio"] == pytest.approx(0.8)
    assert r5["fixed"].setting == "h=2e-4" and r5["cpu_ratio"] == pytest.approx(0.004 / 0.017)
    assert r8["adams"] is None and math.isnan(r8["evals_ratio"]) and math.isnan(r8["cpu_ratio"])
    assert "= 0.80" in s.order_text((1e-5,))


def test_a_scene_without_modal_coordinates_is_refused_before_the_reference(tmp_path):
    """The pendulum has no modal coordinates, so the study's multirate cases cannot run: it
    is refused at once in the kernel's words (it failed after the reference runs, with a
    message about a method = 'multirate' the user never gave)."""
    said = []
    with pytest.raises(pymr.SceneError, match=r"pendulum\.nml: pymr study compares single-rate and multirate "
                                               r"methods, and this scene takes no multirate run \('multirate' needs "
                                               r"slow \(joint\) and fast \(modal\) coordinates; this scene has 1 and 0"):
        Study(TANK.parent / "pendulum.nml", quick=True, progress=said.append)
    assert said == []


def test_the_study_runs_whatever_the_scene_s_output_says(tmp_path):
    """A scene writing HDF5 was refused as 'taking no multirate run' (the study's own
    run.csv clashed with format 'hdf5'), and one whose &output quantities hold no markers
    stopped with "no marker 'muzzle'": the study's runs write CSV with the marker's
    columns. Their muzzle motion is the scene's own run's (the HDF5 file, read back)."""
    scene = tmp_path / "tank.nml"
    scene.write_text(TANK.read_text().replace("t_end = 1.0", "t_end = 0.05").replace(
        "&output file = 'tank_gun_turret.csv', dt = 1.0e-3 /",
        "&output file = 'tank.h5', format = 'hdf5', dt = 1.0e-3, quantities = 'coordinates' /"))
    s = Study(scene, "muzzle", quick=True, progress=None)
    res = s._pymr({})
    own = pymr.run(scene, tmp_path / "own.h5", overrides={"output.dt": s.dt, "output.quantities": "markers"})
    assert np.array_equal(res.marker("muzzle")[0], own.marker("muzzle")[0])
    assert any(c.startswith("gun.") for c in res.columns)        # the scene's own quantities too


@pytest.mark.parametrize("edit, message", [
    # the study's cost runs take 10 steps of h_slow: a shorter run named a --set it made itself
    (("t_end = 1.0", "t_end = 5e-4"), r"tank.nml: &scene: t_end: 0.0005 s is shorter than 10 steps of h_slow "
                                       r"\(0.001 s\), the shortest run pymr study measures its methods' costs on"),
    # a marker on the ground: every error 0, and matplotlib's warnings about log scales
    (("&marker name = 'muzzle'", "&marker name = 'still', body = 'chassis' /\n&marker name = 'muzzle'"),
     r"tank.nml: marker 'still' does not move in the reference run, so every method's error at it is 0"),
])
def test_a_study_that_could_measure_nothing_is_refused_in_one_line(tmp_path, edit, message):
    scene = tmp_path / "tank.nml"
    scene.write_text(TANK.read_text().replace("t_end = 1.0", "t_end = 0.05").replace(*edit)
                     if edit[0] != "t_end = 1.0" else TANK.read_text().replace(*edit))
    with pytest.raises(pymr.SceneError, match=message):
        s = Study(scene, "still" if "still" in message else "muzzle", quick=True, progress=None)
        s.reference()


def test_a_calibration_run_that_fails_leaves_its_weight_unmeasured(tmp_path, capsys):
    """The tank fired with a 3e9 N pulse (t_end 0.6 s): the muzzle moves so far that fixed
    steps lose the mass matrix's definiteness after the shot, among them the runs the study
    measures its weights with. The study exited 2 with no file written. Now a calibration
    run that fails leaves its coupling's weight unmeasured (its cases without equivalents),
    every failed case is a row of the CSV with the run's own error (the same as pymr.run
    raises), and the study writes its files, exit 0."""
    from pymr import study as study_mod
    scene = tmp_path / "fired.nml"
    text = (TANK.parent / "tank_firing.nml").read_text()
    scene.write_text(text.replace("peak = 1.0e6", "peak = 3.0e9").replace("t_end = 1.0", "t_end = 0.6"))
    assert "peak = 3.0e9" in scene.read_text() and "t_end = 0.6" in scene.read_text()
    assert study_mod.main(str(scene), "muzzle", output=str(tmp_path / "s"), quick=True, repeats=1) == 0
    out = capsys.readouterr().out
    assert "'response' not measured (at k = 10, 5, 2 the pre-flight check refused the run or it failed" in out
    rows = list(csv.DictReader(open(tmp_path / "s.csv")))
    failed = [r for r in rows if r["status"].startswith("failed: ")]
    assert failed and all(r["equivalents"] in ("", "nan") for r in rows if r["method"].startswith("response"))
    first = failed[0]
    assert first["method"] == "single fixed"
    h = float(first["setting"].removeprefix("h="))
    with pytest.raises(pymr.SolverError) as exc:
        pymr.run(scene, tmp_path / "one.csv", overrides={"integrator.method": "single", "integrator.adaptive": False,
                                                          "integrator.h_slow": h, "integrator.h_fast": h})
    assert first["status"] == f"failed: {exc.value}"
    assert all((tmp_path / f"s{suffix}").stat().st_size > 0 for suffix in (".csv", ".png", "_history.csv"))
