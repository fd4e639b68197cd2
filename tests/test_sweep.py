"""pymr sweep (issue 7): a grid of tank variants run on a Dask LocalCluster with 2 workers
equals the same cases run one by one; a failing case is recorded and the others run; the
SLURM emission writes case namelists (the kernel's resolved scenes) whose mrsim runs equal the override runs."""
from __future__ import annotations

import csv
import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr.sweep import SweepError, emit_slurm, load_sweep, run_sweep

ROOT = Path(__file__).resolve().parent.parent
TANK = ROOT / "input" / "tank_gun_turret.nml"

GRID = """
scene = "{scene}"
output = "out"
metric = "deviation:muzzle"
[grid]
"integrator.h_slow" = [5e-4, 1e-3]
"integrator.coupling" = ["full", "response"]
"body[gun].modal_damping" = [0.0, 0.02]
[fixed]
"integrator.method" = "multirate"
"integrator.h_fast" = 1e-4
"effects.modal_damping" = true
[reference]
"integrator.method" = "single"
"integrator.h_slow" = 1e-4
"""


def test_sweep_on_a_local_cluster_equals_the_cases_run_one_by_one(tmp_path):
    """8 variants (step ratio 5 and 10, both couplings, damping 0 and 0.02) on 2 Dask
    workers: every case's results file equals a run of the same overrides in this process,
    and the summary's metric is the muzzle's largest deviation from the reference run."""
    toml = tmp_path / "tank.toml"
    toml.write_text(GRID.format(scene=TANK))
    sw = load_sweep(toml)
    assert len(sw.cases) == 8
    rows = run_sweep(sw, workers=2)
    assert [r["status"] for r in rows] == ["ok"] * 8
    ref = pymr.run(TANK, overrides={**sw.fixed, **sw.reference})
    for i, (case, row) in enumerate(zip(sw.cases, rows)):
        alone = pymr.run(TANK, overrides={**sw.fixed, **case})
        swept = pymr.load_results(sw.output / f"case{i:04d}.csv")
        assert np.array_equal(swept.data, alone.data)
        dev = np.linalg.norm(alone.marker("muzzle")[0] - ref.marker("muzzle")[0], axis=1).max()
        assert row["metric"] == dev
    summary = list(csv.DictReader(open(sw.output / "summary.csv")))
    assert len(summary) == 8 and summary[3]["integrator.coupling"] == "response"
    assert float(summary[3]["metric"]) == rows[3]["metric"]


#: Two cases; the first (multirate k = 50 with the stability check off) breaks down.
FAILING_CASE = """
scene = "{scene}"
metric = "final:elevation.q"
{top}
[grid]
"integrator.h_slow" = [5e-3, 2e-4]
[fixed]
"integrator.method" = "multirate"
"integrator.coupling" = "full"
"integrator.h_fast" = 1e-4
"integrator.stability_check" = false
"output.dt" = 1e-2
{extra}
"""


def test_a_failing_case_is_recorded_and_the_others_run(tmp_path):
    """A case whose run breaks down (multirate k = 50 with the stability check off: the
    linearised macro step grows by 1.42 per step) is recorded with its error; the others run
    and equal the same overrides run alone."""
    toml = tmp_path / "bad.toml"
    toml.write_text(FAILING_CASE.format(scene=TANK, top="", extra=""))
    rows = run_sweep(load_sweep(toml), workers=2)
    # the run breaks down where its values first leave LAPACK's range (which matrix: roundoff)
    assert rows[0]["status"].startswith("error: ") and re.search(r"at t = .* s: .*(M_e|M_ff|mass matrix)",
                                                                  rows[0]["status"])
    assert np.isnan(rows[0]["metric"])
    assert rows[1]["status"] == "ok"
    alone = pymr.run(TANK, overrides={"integrator.method": "multirate", "integrator.coupling": "full",
                                      "integrator.h_fast": 1e-4,
                                      "integrator.h_slow": 2e-4, "integrator.stability_check": False,
                                      "output.dt": 1e-2})
    assert rows[1]["metric"] == alone["elevation.q"][-1]


def test_a_case_the_kernel_refuses_stops_the_sweep_before_any_case_runs(tmp_path):
    """Every case's scene is read and checked by the kernel when the sweep is loaded: a
    value it refuses (h_slow not a multiple of h_fast) is one error naming the case."""
    toml = tmp_path / "bad.toml"
    toml.write_text(f"""
scene = "{TANK}"
metric = "final:elevation.q"
output = "{tmp_path / 'runs'}"
[grid]
"integrator.h_slow" = [2e-4, 2.5e-4]
[fixed]
"integrator.method" = "multirate"
"integrator.h_fast" = 1e-4
""")
    with pytest.raises(pymr.SweepError, match=r"case0001 .*--set integrator.h_slow=0.00025: &integrator: h_slow: "
                                              r"must be an integer multiple of h_fast, got h_slow/h_fast = 2.5"):
        load_sweep(toml)
    assert not (tmp_path / "runs").exists()


def test_emitted_slurm_cases_run_by_mrsim_equal_the_override_runs(tmp_path, mrsim):
    toml = tmp_path / "tank.toml"
    toml.write_text(GRID.format(scene=TANK))
    sw = load_sweep(toml)
    script = emit_slurm(sw, tmp_path / "slurm")
    text = script.read_text()
    assert "#SBATCH --array=0-7" in text and '"$MRSIM" "$case.nml" -o "$case.csv"' in text
    # one CPU per task, and one BLAS thread in it
    assert "#SBATCH --cpus-per-task=1" in text
    assert "export OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1" in text
    assert sorted(p.name for p in (tmp_path / "slurm").glob("case*.nml")) == [f"case{i:04d}.nml" for i in range(8)]
    for i in (0, 5):
        r = subprocess.run([mrsim, f"case{i:04d}.nml", "-o", f"case{i:04d}.csv", "--quiet"],
                           cwd=tmp_path / "slurm", capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
        emitted = pymr.load_results(tmp_path / "slurm" / f"case{i:04d}.csv")
        alone = pymr.run(TANK, overrides={**sw.fixed, **sw.cases[i]})
        assert np.array_equal(emitted.data, alone.data)


@pytest.mark.parametrize("text, message", [
    ('scene = "nope.nml"\n[grid]\n"integrator.h_slow" = [1e-4]\n', r"scene: .*nope.nml not found"),
    ('scene = "{scene}"\n', r"\[grid\]: missing or empty"),
    ('scene = "{scene}"\n[grid]\n"integrator.h_slow" = 1e-4\n', r"\[grid\] integrator.h_slow: must be a non-empty list"),
    ('scene = "{scene}"\nmetric = "median:x"\n[grid]\n"integrator.h_slow" = [1e-4]\n', r"metric: 'median:x' is not"),
    ('scene = "{scene}"\nworkers = 3\n[grid]\n"integrator.h_slow" = [1e-4]\n', r"unknown key 'workers'"),
    # a number where a string goes raised a TypeError traceback (found by fuzzing sweep files)
    ('scene = "{scene}"\noutput = 3\n[grid]\n"integrator.h_slow" = [1e-4]\n',
     r"output: must be a folder name \(a string\), got 3$"),
    ('scene = "{scene}"\nmetric = 7\n[grid]\n"integrator.h_slow" = [1e-4]\n',
     r"metric: must be a string such as 'final:COLUMN', got 7$"),
    ('scene = "{scene}"\nfixed = 5\n[grid]\n"integrator.h_slow" = [1e-4]\n', r"fixed: must be a table \(\[fixed\]\), got 5$"),
])
def test_bad_sweep_files_are_one_line_errors(tmp_path, text, message):
    toml = tmp_path / "s.toml"
    toml.write_text(text.format(scene=TANK))
    with pytest.raises(SweepError, match=message) as exc:
        load_sweep(toml)
    assert str(exc.value).startswith(str(toml)) and "\n" not in str(exc.value)


def test_sweep_command_exit_statuses(tmp_path):
    """pymr sweep: a sweep file that is not TOML (binary bytes) is one line and exit 1; a sweep
    whose case fails runs the others, lists the failed case and exits 2. A bad command line
    is exit 1 too."""
    (tmp_path / "bin.toml").write_bytes(bytes(range(256)))
    r = subprocess.run(["pymr", "sweep", "bin.toml"], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and "not a TOML sweep file" in r.stderr, r.stderr
    (tmp_path / "fail.toml").write_text(FAILING_CASE.format(scene=TANK, top='output = "runs"',
                                                            extra='"scene.t_end" = 0.3'))
    r = subprocess.run(["pymr", "sweep", "fail.toml", "--workers", "1"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 2, r.stderr
    assert "pymr: error: 1 of 2 cases failed: case0000" in r.stderr
    assert (tmp_path / "runs" / "summary.csv").exists()
    r = subprocess.run(["pymr", "run"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert r.returncode == 1


def test_a_slurm_sweep_is_collected_into_its_summary(tmp_path, mrsim):
    """--emit-slurm names this installation's mrsim by its absolute path (PYMR_MRSIM
    overrides it); after two of the eight tasks ran, --collect writes the summary: those two
    with the metric run_case gives for the same case, the six others missing, exit 2."""
    toml = tmp_path / "tank.toml"
    toml.write_text(GRID.format(scene=TANK))
    sw = load_sweep(toml)
    folder = tmp_path / "slurm"
    text = emit_slurm(sw, folder).read_text()
    assert f'MRSIM="${{PYMR_MRSIM:-{mrsim}}}"' in text and f"--collect {folder}" in text
    for i in (1, 6):
        r = subprocess.run([mrsim, f"case{i:04d}.nml", "-o", f"case{i:04d}.csv", "--quiet"], cwd=folder,
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
    r = subprocess.run(["pymr", "sweep", str(toml), "--collect", str(folder)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 2 and "6 of 8 cases failed" in r.stderr, r.stderr
    rows = list(csv.DictReader((folder / "summary.csv").open()))
    assert [row["status"] for row in rows].count("ok") == 2
    assert all(row["status"].startswith("missing") for i, row in enumerate(rows) if i not in (1, 6))
    from pymr.sweep import reference_positions, run_case
    ref = reference_positions(sw, tmp_path)
    alone = run_case(str(TANK), {**sw.fixed, **sw.cases[6]}, str(tmp_path / "alone.csv"), sw.metric, ref)
    assert float(rows[6]["metric"]) == pytest.approx(alone["metric"], rel=1e-12)
