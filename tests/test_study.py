"""pymr study: references that agree, tolerance proportionality of adaptive runs on the
tank, peers on the same right-hand side, and the table, CSV and figure it writes."""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr.study import Study

TANK = Path(__file__).resolve().parent.parent / "input" / "tank_gun_turret.nml"


@pytest.fixture(scope="module")
def study() -> Study:
    s = Study(TANK, "muzzle", quick=True, progress=None)
    s.reference()
    s.weights()
    return s


def test_reference_is_cross_checked_by_dop853_on_the_same_rhs(study):
    """pymr at rtol 1e-11 and scipy's DOP853 at 1e-12 (through the binding's right-hand side)
    agree on the muzzle to 1.8e-12 m (measured)."""
    assert study.ref_check < 1e-10
    assert study.ref.shape == (len(study.grid), 3)


def test_model_rhs_through_the_binding_equals_the_kernel_accelerations():
    with pymr.Model(TANK) as model:
        rng = np.random.default_rng(3)
        x = rng.standard_normal(2 * model.n) * 0.1
        f = model.rhs(0.3, x)
        assert model.evaluations == 1
    qdd = pymr.model_accelerations(TANK, 0.3, x[:6], x[6:])
    assert np.array_equal(f[:6], x[6:]) and np.abs(f[6:] - qdd).max() <= 1e-12 * np.abs(qdd).max()


def test_adaptive_error_falls_tenfold_per_decade_of_rtol(study):
    """Tolerance proportionality on the tank: measured 1.15e-4, 1.16e-6, 1.19e-9 m at rtol
    1e-3, 1e-5, 1e-8 (10.0x per decade)."""
    errs = []
    for rtol in (1e-3, 1e-5, 1e-8):
        c = study._pymr_case("adaptive single", f"{rtol}", {"integrator.adaptive": True, "integrator.rtol": rtol,
                                                            "integrator.atol": rtol * 1e-2})
        assert c.status == "ok"
        errs.append(c.error_m)
    per_decade = np.diff(np.log10(errs)) / np.diff(np.log10([1e-3, 1e-5, 1e-8]))
    assert per_decade == pytest.approx([1.0, 1.0], abs=0.1)


def test_fast_evaluations_are_weighted_by_their_measured_cost(study):
    """A 'split' fast evaluation costs about 1 % of a full one, a 'full' one about 45 %
    (measured 0.010 and 0.445); multirate cases count rhs_full + weight * rhs_fast."""
    assert 0 < study.weight["split"] < 0.1 < study.weight["full"] < 1.0
    c = study._pymr_case("multirate k=10 split", "h_fast=1e-4", {
        "integrator.method": "multirate", "integrator.coupling": "split", "integrator.h_fast": 1e-4,
        "integrator.h_slow": 1e-3}, study.weight["split"])
    assert c.equivalents == pytest.approx(c.rhs_full + study.weight["split"] * c.rhs_fast)


def test_refused_steps_are_recorded_not_fatal(study):
    c = study._pymr_case("multirate k=40 full", "h_fast=1e-4", {
        "integrator.method": "multirate", "integrator.h_fast": 1e-4, "integrator.h_slow": 4e-3})
    assert c.status.startswith("refused") and "largest stable ratio" in c.status and np.isnan(c.error_m)


def test_peers_table_csv_and_figure(study, tmp_path):
    """DOP853 and CVODE (when installed) on the kernel's right-hand side reach the accuracy
    of their tolerance; the table, CSV and PNG hold every case."""
    study.cases = []
    study._add(study._peer("DOP853", 1e-6))
    study._add(study._peer("CVODE Adams", 1e-6))
    study._add(study._pymr_case("single fixed", "h=1e-4", {}))
    dop, cvode, fixed = study.cases
    assert dop.status == "ok" and dop.error_m < 1e-6 and dop.rhs_full > 1000
    if cvode.status == "ok":
        assert cvode.error_m < 1e-6
    else:
        assert cvode.status.startswith("skipped")
    assert fixed.error_m == pytest.approx(5.5e-8, rel=0.05)        # measured 5.50e-8 m
    study.write_csv(tmp_path / "s.csv")
    rows = list(csv.DictReader(open(tmp_path / "s.csv")))
    assert [r["method"] for r in rows] == ["DOP853", "CVODE Adams", "single fixed"]
    assert float(rows[2]["error_m"]) == fixed.error_m
    study.plot(tmp_path / "s.png")
    assert (tmp_path / "s.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert "single fixed" in study.table()
