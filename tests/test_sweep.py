"""pymr sweep (issue 7): a grid of tank variants run on a Dask LocalCluster with 2 workers
equals the same cases run one by one; a failing case is recorded and the others run; the
SLURM emission writes case namelists (the kernel's resolved scenes) whose mrsim runs equal the override runs."""
from __future__ import annotations

import csv
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr.sweep import SweepError, collect, emit_slurm, load_sweep, run_sweep

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


def test_sweep_on_a_local_cluster_equals_the_cases_run_one_by_one(tmp_path, monkeypatch):
    """8 variants (step ratio 5 and 10, both couplings, damping 0 and 0.02) on 2 Dask
    workers: every case's results file equals a run of the same overrides in this process,
    and the summary's metric is the muzzle's largest deviation from the case's reference
    run: the case's own scene (damping included) with the [reference] settings."""
    monkeypatch.chdir(tmp_path)
    toml = tmp_path / "tank.toml"
    toml.write_text(GRID.format(scene=TANK))
    sw = load_sweep(toml)
    assert len(sw.cases) == 8 and sw.output == tmp_path / "out"
    rows = run_sweep(sw, workers=2)
    assert [r["status"] for r in rows] == ["ok"] * 8
    for i, (case, row) in enumerate(zip(sw.cases, rows)):
        alone = pymr.run(TANK, overrides={**sw.fixed, **case})
        ref = pymr.run(TANK, overrides={**sw.fixed, **case, **sw.reference})
        swept = pymr.load_results(sw.output / f"case{i:04d}.csv")
        assert np.array_equal(swept.data, alone.data)
        assert np.array_equal(pymr.load_results(sw.output / row["reference"]).data, ref.data)
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


def test_a_failing_case_is_recorded_and_the_others_run(tmp_path, monkeypatch):
    """A case whose run breaks down (multirate k = 50 with the stability check off: the
    linearised macro step grows by 1.42 per step) is recorded with its error; the others run
    and equal the same overrides run alone. An earlier summary in the folder is renamed
    summary.previous.csv before the cases replace its results."""
    monkeypatch.chdir(tmp_path)
    toml = tmp_path / "bad.toml"
    toml.write_text(FAILING_CASE.format(scene=TANK, top="", extra=""))
    (tmp_path / "bad").mkdir()
    (tmp_path / "bad" / "summary.csv").write_text("an earlier sweep's summary\n")
    rows = run_sweep(load_sweep(toml), workers=2)
    assert (tmp_path / "bad" / "summary.csv").exists()       # the default output: the stem, here
    # the earlier summary, whose cases this sweep replaced, is kept under another name
    assert (tmp_path / "bad" / "summary.previous.csv").read_text() == "an earlier sweep's summary\n"
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


def test_a_sweep_without_a_metric_has_no_metric_column(tmp_path, monkeypatch):
    """The metric is optional: without one the summary lists each case's CPU time and
    status and no metric column (it held nan in every row marked ok); each case's CPU time is
    its own run's (positive, finite)."""
    monkeypatch.chdir(tmp_path)
    toml = tmp_path / "plain.toml"
    toml.write_text(f'scene = "{ROOT / "input" / "pendulum.nml"}"\n[fixed]\n"scene.t_end" = 0.05\n'
                    '[grid]\n"integrator.h_slow" = [5e-4, 1e-3]\n')
    rows = run_sweep(load_sweep(toml), workers=1)
    table = list(csv.DictReader(open(tmp_path / "plain" / "summary.csv")))
    assert list(table[0]) == ["case", "integrator.h_slow", "cpu_time_s", "status"]
    assert [r["status"] for r in table] == ["ok", "ok"] and "nan" not in (tmp_path / "plain" / "summary.csv").read_text()
    assert all(0 < float(r["cpu_time_s"]) < 10 for r in table) and len(rows) == 2


@pytest.mark.parametrize("mode", ["emit", "run"])
def test_a_sweep_makes_its_own_folder_only_in_a_folder_that_is_there(tmp_path, monkeypatch, mode):
    """As for every pymr output, the folder a sweep writes into must be in a folder that is
    there: a mistyped path made every missing folder on it (found by fuzzing: /nonexistent)."""
    monkeypatch.chdir(tmp_path)
    toml = tmp_path / "s.toml"
    out = tmp_path / "no" / "such" / "runs"
    toml.write_text(f'scene = "{ROOT / "input" / "pendulum.nml"}"\n' + (f'output = "{out}"\n' if mode == "run" else "")
                    + '[grid]\n"integrator.h_slow" = [1e-3]\n')
    what = "--emit-slurm" if mode == "emit" else "output"
    with pytest.raises(SweepError, match=rf"^{what} {out}: the folder {out.parent} is not there \(make it first\)$"):
        emit_slurm(load_sweep(toml), out) if mode == "emit" else run_sweep(load_sweep(toml), workers=1)
    assert not (tmp_path / "no").exists()


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
    # 8 cases, then 4 references (one per coupling and damping: [reference] sets h_slow)
    assert "#SBATCH --array=0-11" in text and '"$MRSIM" "$case.nml" -o "$case.csv"' in text
    assert sorted(p.name for p in (tmp_path / "slurm").glob("reference*.nml")) == [
        f"reference{k:04d}.nml" for k in range(4)]
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
    # a parameter in both tables ran with the grid's values, the fixed one dropped silently
    ('scene = "{scene}"\n[grid]\n"integrator.h_slow" = [1e-4]\n[fixed]\n"integrator.h_slow" = 2e-4\n',
     r"\[fixed\] integrator.h_slow: also a \[grid\] parameter \(one value would be dropped\): keep it in one table$"),
    # two spellings of one item ran every case with the last value, labelled with the first
    ('scene = "{scene}"\n[grid]\n"integrator.h_slow" = [1e-4, 2e-4]\n"Integrator.H_SLOW" = [3e-4]\n',
     r"\[grid\] 'Integrator.H_SLOW' and 'integrator.h_slow' name one item \(integrator.h_slow\): keep one$"),
    ('scene = "{scene}"\n[grid]\n"body[gun].n_elements" = [10]\n"body[\'gun\'].n_elements" = [20]\n',
     r"\[grid\] \"body\['gun'\].n_elements\" and 'body\[gun\].n_elements' name one item \(body\[gun\].n_elements\)"),
    ('scene = "{scene}"\n[grid]\n"integrator.h_slow" = [1e-4]\n[fixed]\n" Integrator . h_slow" = 2e-4\n',
     r"\[fixed\]  Integrator . h_slow: also a \[grid\] parameter"),
])
def test_bad_sweep_files_are_one_line_errors(tmp_path, text, message):
    toml = tmp_path / "s.toml"
    toml.write_text(text.format(scene=TANK))
    with pytest.raises(SweepError, match=message) as exc:
        load_sweep(toml)
    assert str(exc.value).startswith(str(toml)) and "\n" not in str(exc.value)


def test_a_reference_key_replaces_the_case_s_value_however_spelled(tmp_path):
    """[reference] "integrator.h_slow" replaces the case's "Integrator.H_SLOW" (it was kept
    beside it, and the case's value, later in the overrides, won: the reference ran the
    case's step and every deviation was 0)."""
    (tmp_path / "p.nml").write_text(PENDULUM)
    (tmp_path / "s.toml").write_text('scene = "p.nml"\nmetric = "deviation:tip"\n[grid]\n"Integrator.H_SLOW" = [1e-2, 2e-2]\n'
                                     '[fixed]\n"output.dt" = 0.02\n[reference]\n"integrator.h_slow" = 1e-4\n')
    from pymr.sweep import references
    assert [over for over, _ in references(load_sweep(tmp_path / "s.toml"))] == [{"output.dt": 0.02,
                                                                                  "Integrator.H_SLOW": 1e-4}]


def test_no_sweep_output_overwrites_an_input(tmp_path, monkeypatch):
    """A sweep's outputs are refused before any is written when one would be an input: the
    base scene named case0000.nml in the --emit-slurm folder was overwritten by the first
    case's namelist, and a scene named summary.csv in the output folder by the summary (both
    exit 0). The sweep file is an input too."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "em").mkdir()
    (tmp_path / "em" / "case0000.nml").write_text(PENDULUM)
    (tmp_path / "s.toml").write_text('scene = "em/case0000.nml"\n[grid]\n"integrator.h_slow" = [1e-3, 2e-3]\n')
    with pytest.raises(pymr.OutputError, match=r"^--emit-slurm .*em/case0000.nml: would overwrite the scene .*; "
                                               r"choose another folder$"):
        emit_slurm(load_sweep(tmp_path / "s.toml"), tmp_path / "em")
    assert [p.name for p in (tmp_path / "em").iterdir()] == ["case0000.nml"]
    assert (tmp_path / "em" / "case0000.nml").read_text() == PENDULUM
    (tmp_path / "summary.csv").write_text(PENDULUM)
    (tmp_path / "t.toml").write_text('scene = "summary.csv"\noutput = "."\n[grid]\n"integrator.h_slow" = [1e-3]\n')
    with pytest.raises(pymr.OutputError, match=r"t.toml: output .*summary.csv: would overwrite the scene"):
        run_sweep(load_sweep(tmp_path / "t.toml"), workers=1)
    assert (tmp_path / "summary.csv").read_text() == PENDULUM
    (tmp_path / "cases.csv").write_text('scene = "em/case0000.nml"\n[grid]\n"integrator.h_slow" = [1e-3]\n')
    with pytest.raises(pymr.OutputError, match=r"would overwrite the input .*cases.csv"):
        emit_slurm(load_sweep(tmp_path / "cases.csv"), tmp_path)


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
    assert r.stderr.count("\n") == 1 and "pymr: error: of 2 cases, 1 failed (case0000)" in r.stderr, r.stderr
    assert (tmp_path / "runs" / "summary.csv").exists()
    r = subprocess.run(["pymr", "run"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert r.returncode == 1


def test_a_slurm_sweep_is_collected_into_its_summary(tmp_path, mrsim):
    """--emit-slurm names this installation's mrsim by its absolute path (PYMR_MRSIM
    overrides it); after two of the eight tasks ran, --collect writes the summary: those two
    with the metric run_case gives for the same case, the six others 'not run' (not
    'failed'), exit 2."""
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
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert "of 8 cases, 6 not run or not finished (case0000, case0002, case0003, case0004, case0005, case0007)" \
        in r.stderr and "failed" not in r.stderr, r.stderr
    assert "8 cases: 2 ok, 0 failed, 6 not run or not finished" in r.stdout
    rows = list(csv.DictReader((folder / "summary.csv").open()))
    assert [row["status"] for row in rows].count("ok") == 2
    assert all(row["status"] == "not run" for i, row in enumerate(rows) if i not in (1, 6))
    from pymr.sweep import reference_run, references, run_case
    over = next(over for over, cases in references(sw) if 6 in cases)
    ref = reference_run(str(TANK), over, str(tmp_path / "ref.csv"), "muzzle")
    alone = run_case(str(TANK), {**sw.fixed, **sw.cases[6]}, str(tmp_path / "alone.csv"), sw.metric, ref)
    assert float(rows[6]["metric"]) == pytest.approx(alone["metric"], rel=1e-12)


def test_the_job_array_runs_the_references_and_collect_takes_them(tmp_path, monkeypatch, mrsim):
    """With the deviation metric, --emit-slurm puts each reference run in the job array after
    the cases (--collect ran them one after another where it was called, a cluster's login
    node). Every task of the script run as SLURM would (SLURM_ARRAY_TASK_ID 0 to 5: four
    cases, two references shared by the grid's q0 values): --collect runs nothing itself and
    each deviation equals run_case's against the same reference run alone. A reference still
    running leaves its cases 'not finished', a failed one fails them with its error, and one
    whose task has not run is run by --collect as before; a reference namelist of another
    [reference] table is refused."""
    (tmp_path / "p.nml").write_text(PENDULUM)
    (tmp_path / "s.toml").write_text('scene = "p.nml"\nmetric = "deviation:tip"\n[grid]\n'
                                     '"joint[pivot].q0" = [0.5, 0.6]\n"integrator.h_slow" = [2e-3, 4e-3]\n'
                                     '[fixed]\n"output.dt" = 0.01\n"body[bob].com" = [0.0, -1.0, 0.0]\n[reference]\n"integrator.h_slow" = 2.5e-4\n')
    sw = load_sweep(tmp_path / "s.toml")
    folder = tmp_path / "runs"
    script = emit_slurm(sw, folder)
    assert "#SBATCH --array=0-5" in script.read_text()
    for task in range(6):
        r = subprocess.run(["bash", str(script)], cwd=folder, capture_output=True, text=True,
                           env={**os.environ, "SLURM_ARRAY_TASK_ID": str(task), "SLURM_SUBMIT_DIR": str(folder)})
        assert r.returncode == 0, r.stderr
    assert sorted(p.name for p in folder.glob("reference*.csv")) == ["reference0000.csv", "reference0001.csv"]
    import pymr.sweep as sweep_module
    def no_reference_here(*args):
        raise AssertionError("--collect ran a reference itself")
    monkeypatch.setattr(sweep_module, "reference_run", no_reference_here)
    rows = collect(sw, folder)
    assert [row["status"] for row in rows] == ["ok"] * 4
    monkeypatch.undo()
    from pymr.sweep import reference_run, references, run_case
    for over, cases in references(sw):
        ref = reference_run(str(tmp_path / "p.nml"), over, str(tmp_path / "ref.csv"), "tip")
        for i in cases:
            alone = run_case(str(tmp_path / "p.nml"), {**sw.fixed, **sw.cases[i]}, str(tmp_path / "alone.csv"),
                             sw.metric, ref)
            assert rows[i]["metric"] == pytest.approx(alone["metric"], rel=1e-12) and rows[i]["metric"] > 0
    done = (folder / "reference0000.csv").read_text()
    (folder / "reference0000.csv").unlink()
    (folder / "reference0000.csv.partial").write_text(done[:200])
    (folder / "summary.csv").unlink()
    status = [row["status"] for row in collect(sw, folder)]
    users = next(cases for over, cases in references(sw))
    assert all(status[i].startswith("not finished: its reference reference0000 ") for i in users), status
    assert all(status[i] == "ok" for i in range(4) if i not in users), status
    (folder / "reference0000.json.partial").write_text('{"error": "at t = 0.1 s: the step broke down"}')
    (folder / "summary.csv").unlink()
    status = [row["status"] for row in collect(sw, folder)]
    assert all(status[i] == "failed: the reference run failed: reference0000: at t = 0.1 s: the step broke down"
               for i in users), status
    for f in folder.glob("reference0000.*.partial"):
        f.unlink()
    (folder / "summary.csv").unlink()
    rows = collect(sw, folder)
    assert [row["status"] for row in rows] == ["ok"] * 4 and (folder / "reference0000.csv").exists()
    # the sweep file's [reference] changed since the emission: its namelists are refused
    (tmp_path / "s.toml").write_text((tmp_path / "s.toml").read_text().replace("2.5e-4", "5e-4"))
    with pytest.raises(SweepError, match=r"--collect .*runs: its reference0000.nml is not this sweep's reference "
                                         r"\(s\.toml\): emit the cases again with --emit-slurm$"):
        collect(load_sweep(tmp_path / "s.toml"), folder)


# ------------------------------------------------------------- issue 30: sweeps' rough edges

#: A pendulum with two markers, for sweeps that must be quick.
PENDULUM = """\
&scene title = 'pendulum', t_end = 0.2, gravity = 0.0, -9.81, 0.0 /
&integrator method = 'single', h_slow = 1.0e-3 /
&effects gravity = .true., joint_springs = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'bob', kind = 'rigid', mass = 1.0, inertia = 1e-3, 1e-3, 1e-3, 0.0, 0.0, 0.0 /
&joint name = 'pivot', kind = 'revolute', parent = 'ground', child = 'bob', q0 = 0.5 /
&spring joint = 'pivot', stiffness = 0.0, damping = 0.0 /
&marker name = 'tip', body = 'bob', at = 0.0, -1.0, 0.0 /
"""


@pytest.mark.parametrize("metric, message", [
    ("deviation:tipp", r"metric 'deviation:tipp': the results of case0000 have no marker 'tipp' "
                       r"\(did you mean 'tip'\?\)$"),
    ("deviation:nose", r"no marker 'nose' \(markers: tip\)$"),
    ("final:pivot.qq", r"metric 'final:pivot.qq': the results of case0000 have no column 'pivot.qq' \(did you mean "
                       r"'pivot.q' or 'pivot.qd'\?\)$"),
    ("max_abs:zzz", r"have no column 'zzz' \(columns: t, pivot.q, pivot.qd, tip.x, .*\(9 in all\)\)$"),
    ("deviation:tip", r"the results of case0001 have no marker 'tip' \(markers: none \(&output quantities must hold "
                      r"markers\)\)$"),
])
@pytest.mark.parametrize("mode", [[], ["--emit-slurm", "runs"], ["--collect", "runs"]])
def test_a_metric_the_results_lack_is_refused_before_anything_runs(tmp_path, metric, message, mode):
    """Issue 30: a metric naming a marker that does not exist was accepted by --emit-slurm
    and gave a traceback at --collect; a misspelt column was reported after every case had
    run. Every metric kind, in every mode: one line naming the sweep file, exit 1, before
    any case or reference runs (no folder made). The last case makes the columns depend on
    the case: its second case writes no markers."""
    (tmp_path / "p.nml").write_text(PENDULUM)
    grid = ('"output.quantities" = [["coordinates", "markers"], ["coordinates"]]' if metric == "deviation:tip"
            else '"joint[pivot].q0" = [0.5, 0.6]')
    (tmp_path / "s.toml").write_text(f'scene = "p.nml"\noutput = "out"\nmetric = "{metric}"\n[grid]\n{grid}\n')
    if mode and mode[0] == "--collect":
        (tmp_path / "runs").mkdir()
        (tmp_path / "runs" / "sweep.slurm").write_text("")
    r = subprocess.run(["pymr", "sweep", "s.toml", *mode], cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
    assert r.stderr.startswith("pymr: error: s.toml: metric ") and re.search(message, r.stderr.strip()), r.stderr
    assert not (tmp_path / "out").exists()
    assert sorted(p.name for p in (tmp_path / "runs").glob("*")) == (["sweep.slurm"] if mode[:1] == ["--collect"]
                                                                      else [])


def test_collect_lists_each_case_as_ok_failed_not_finished_or_not_run(tmp_path, mrsim):
    """Issue 30: --collect counted cases that never ran as 'failed', and a truncated case CSV
    stopped it with a traceback-free exit 1 instead of being listed. Now each case is listed:
    ok; failed (its run failed: the error from its .json.partial; results cut mid-line or at
    a line's end); not finished (a .csv.partial and no error: running or stopped); not run.
    Exit 2, one line counting both kinds."""
    toml = tmp_path / "s.toml"
    toml.write_text(f"""
scene = "{TANK}"
metric = "final:elevation.q"
[grid]
"integrator.h_slow" = [5e-3, 2e-4, 4e-4, 6e-4, 8e-4, 1e-3]
[fixed]
"integrator.method" = "multirate"
"integrator.coupling" = "full"
"integrator.h_fast" = 1e-4
"integrator.stability_check" = false
"output.dt" = 1e-2
"scene.t_end" = 0.3
""")
    folder = tmp_path / "runs"
    emit_slurm(load_sweep(toml), folder)
    for i in range(4):
        r = subprocess.run([mrsim, f"case{i:04d}.nml", "-o", f"case{i:04d}.csv", "--quiet"], cwd=folder,
                           capture_output=True, text=True)
        assert r.returncode == (2 if i == 0 else 0), r.stderr
    rows = (folder / "case0002.csv").read_text().splitlines(keepends=True)
    (folder / "case0002.csv").write_text("".join(rows[:20]) + rows[20][:7])          # cut mid-line
    (folder / "case0003.csv").write_text("".join(rows[:20]))                        # cut at a line's end
    (folder / "case0005.csv.partial").write_text("".join(rows[:10]))                # a task still running
    r = subprocess.run(["pymr", "sweep", str(toml), "--collect", str(folder)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
    assert ("of 6 cases, 3 failed (case0000, case0002, case0003) and 2 not run or not finished (case0004, "
            "case0005)") in r.stderr
    status = [row["status"] for row in csv.DictReader((folder / "summary.csv").open())]
    assert re.fullmatch(r"failed: .*case0000.nml: at t = .* s: .*", status[0]), status[0]
    assert status[1] == "ok"
    assert status[2].startswith("failed: incomplete results: ") and "case0002.csv" in status[2]
    assert re.fullmatch(r"failed: incomplete results: .*case0003.csv: 1\d rows of the 31 the run wrote \(the file "
                        r"was cut\)", status[3]), status[3]
    assert status[4] == "not run"
    assert status[5].startswith("not finished: case0005.csv.partial")


#: A sweep of the pendulum over q0 (the values), whose metric is the pivot's final angle.
PENDULUM_SWEEP = 'scene = "p.nml"\nmetric = "final:pivot.q"\n[grid]\n"joint[pivot].q0" = [{}]\n[fixed]\n"scene.t_end" = 0.1\n'


def _two_pendulum_cases_run(tmp_path: Path, mrsim: str) -> Path:
    """The pendulum's sweep a.toml (q0 0.5 and 0.6) emitted for SLURM into tmp_path/runs, and
    both its cases run there by mrsim as the job array would: the folder."""
    (tmp_path / "p.nml").write_text(PENDULUM)
    (tmp_path / "a.toml").write_text(PENDULUM_SWEEP.format("0.5, 0.6"))
    folder = tmp_path / "runs"
    emit_slurm(load_sweep(tmp_path / "a.toml"), folder)
    for i in range(2):
        r = subprocess.run([mrsim, f"case{i:04d}.nml", "-o", f"case{i:04d}.csv", "--quiet"], cwd=folder,
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
    return folder


def test_collect_takes_no_results_of_another_emission(tmp_path, mrsim):
    """A second sweep emitted into a folder holding the first one's results was collected
    from them: both cases 'ok' with the second sweep's parameters and the first one's
    metrics. A case's results must be of its namelist (their scene fingerprints), and the
    folder's cases those of the sweep file collecting them."""
    folder = _two_pendulum_cases_run(tmp_path, mrsim)
    (tmp_path / "b.toml").write_text(PENDULUM_SWEEP.format("0.7, 0.8"))
    emit_slurm(load_sweep(tmp_path / "b.toml"), folder)
    rows = collect(load_sweep(tmp_path / "b.toml"), folder)
    assert all(re.fullmatch(rf"failed: .*case000{i}\.csv: the results are of another scene than case000{i}\.nml "
                            r"\(an earlier sweep's, left in the folder\?\): run the case again", row["status"])
               for i, row in enumerate(rows)), [row["status"] for row in rows]
    with pytest.raises(SweepError, match=r"--collect .*runs: its cases.csv is not this sweep's cases \(a\.toml\)"):
        collect(load_sweep(tmp_path / "a.toml"), folder)
    r = subprocess.run([mrsim, "case0000.nml", "-o", "case0000.csv", "--quiet"], cwd=folder, capture_output=True)
    row = collect(load_sweep(tmp_path / "b.toml"), folder)[0]
    assert row["status"] == "ok" and row["metric"] == pytest.approx(pymr.run(
        tmp_path / "p.nml", overrides={"joint[pivot].q0": 0.7, "scene.t_end": 0.1})["pivot.q"][-1], rel=1e-12)


@pytest.mark.parametrize("swapped", [(".csv",), (".csv", ".json")])
def test_collect_takes_no_results_swapped_between_cases(tmp_path, mrsim, swapped):
    """Two cases run, then their CSVs swapped (a copy by hand, a job script's typo), alone or
    with their JSON side-cars: each case is listed failed, naming its file, not 'ok' with the
    other case's metric (the metric differs: q0 0.5 against 0.6). CSVs alone are another
    run's than their JSON (its byte count and last row); the pairs are of the other case's
    namelist (its scene fingerprint). Run again, the case is 'ok' with its own metric."""
    folder = _two_pendulum_cases_run(tmp_path, mrsim)
    ok = collect(load_sweep(tmp_path / "a.toml"), folder)
    assert [row["status"] for row in ok] == ["ok", "ok"] and ok[0]["metric"] != ok[1]["metric"]
    for ext in swapped:
        a, b = folder / f"case0000{ext}", folder / f"case0001{ext}"
        a.rename(folder / "swap"); b.rename(a); (folder / "swap").rename(b)
    rows = collect(load_sweep(tmp_path / "a.toml"), folder)
    for i, row in enumerate(rows):
        assert row["status"].startswith("failed: ") and f"case000{i}" in row["status"], row["status"]
        assert row["metric"] in (None, "") or np.isnan(float(row["metric"])), row
    r = subprocess.run([mrsim, "case0000.nml", "-o", "case0000.csv", "--quiet"], cwd=folder, capture_output=True)
    row = collect(load_sweep(tmp_path / "a.toml"), folder)[0]
    assert row["status"] == "ok" and row["metric"] == pytest.approx(ok[0]["metric"], rel=1e-15)


def test_each_case_s_reference_shares_its_physics(tmp_path, monkeypatch):
    """Issue 30: the shipped sweep put modal damping on a grid axis against one undamped
    reference, so its deviation showed the damping's physics (mm) as integration error. A
    case's reference is now the case itself with the [reference] settings: a grid over
    physics (damping, a drive's amplitude, gravity) whose cases integrate as their
    reference does deviates by exactly 0, and cases sharing a reference share its run."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "s.toml").write_text(f"""
scene = "{TANK}"
metric = "deviation:muzzle"
[grid]
"body[gun].modal_damping" = [0.0, 0.05]
"drive[traverse].amplitude" = [-45500.0, -30000.0]
"scene.gravity" = [[0.0, -9.81, 0.0], [0.0, -1.62, 0.0]]
[fixed]
"effects.modal_damping" = true
"scene.t_end" = 0.2
[reference]
"integrator.h_slow" = 1e-4
"integrator.h_fast" = 1e-4
""")
    sw = load_sweep(tmp_path / "s.toml")
    rows = run_sweep(sw, workers=1)
    assert [r["metric"] for r in rows] == [0.0] * 8, [r["metric"] for r in rows]
    assert len({r["reference"] for r in rows}) == 8
    # the same sweep with a coarser case step: each deviation is that step's error alone
    sw.fixed["integrator.h_slow"] = sw.fixed["integrator.h_fast"] = 4e-4
    rows = run_sweep(sw, workers=1)
    assert all(0 < r["metric"] < 1e-4 for r in rows), [r["metric"] for r in rows]


def test_the_shipped_sweep_measures_integration_error_in_the_working_folder(tmp_path, monkeypatch):
    """input/tank_sweep.toml: each case's reference differs from the case only in
    integration settings ([reference]'s keys, all of &integrator), and its output folder is
    in the working folder, not in the checkout. docs/commands.md prints the same file."""
    from pymr.sweep import references
    monkeypatch.chdir(tmp_path)
    sw = load_sweep(ROOT / "input" / "tank_sweep.toml")
    assert sw.output == tmp_path / "sweep"
    assert all(k.startswith("integrator.") for k in sw.reference)
    for over, users in references(sw):
        for i in users:
            case = {**sw.fixed, **sw.cases[i]}
            assert {k: v for k, v in over.items() if not k.startswith("integrator.")} == \
                   {k: v for k, v in case.items() if not k.startswith("integrator.")}
    readme = (ROOT / "docs" / "commands.md").read_text()
    block = readme.split("```toml\n# input/tank_sweep.toml\n", 1)[1].split("```", 1)[0]
    shipped = (ROOT / "input" / "tank_sweep.toml").read_text().split("\n", 1)[1]
    assert block == shipped


def test_a_sweep_s_output_is_relative_to_the_working_folder(tmp_path, monkeypatch):
    """The output folder (given, or the TOML's stem by default) is in the working folder, as
    every pymr output is; the scene stays relative to the TOML file. An empty output, and a
    summary.csv that is a folder, are refused before anything runs."""
    (tmp_path / "defs").mkdir()
    (tmp_path / "defs" / "p.nml").write_text(PENDULUM)
    (tmp_path / "work").mkdir()
    monkeypatch.chdir(tmp_path / "work")
    (tmp_path / "defs" / "a.toml").write_text('scene = "p.nml"\n[grid]\n"joint[pivot].q0" = [0.5]\n')
    (tmp_path / "defs" / "b.toml").write_text('scene = "p.nml"\noutput = "o/x"\n[grid]\n"joint[pivot].q0" = [0.5]\n')
    (tmp_path / "defs" / "c.toml").write_text('scene = "p.nml"\noutput = ""\n[grid]\n"joint[pivot].q0" = [0.5]\n')
    a, b = load_sweep(tmp_path / "defs" / "a.toml"), load_sweep(tmp_path / "defs" / "b.toml")
    assert (a.output, b.output, a.scene) == (tmp_path / "work" / "a", tmp_path / "work" / "o" / "x",
                                             tmp_path / "defs" / "p.nml")
    with pytest.raises(SweepError, match=r"c.toml: output: an empty folder name"):
        load_sweep(tmp_path / "defs" / "c.toml")
    (tmp_path / "work" / "a" / "summary.csv").mkdir(parents=True)
    with pytest.raises(pymr.OutputError, match=r"a.toml: output .*a/summary.csv: is a folder, not a file"):
        run_sweep(a, workers=1)
    assert list((tmp_path / "work" / "a").iterdir()) == [tmp_path / "work" / "a" / "summary.csv"]


def test_a_killed_emission_over_an_earlier_sweep_is_not_collected(tmp_path, monkeypatch, mrsim):
    """--emit-slurm of b.toml killed after its first namelist, over a folder a.toml was
    emitted into, left case0000.nml of b beside a's case0001.nml and cases.csv; the job
    array then ran the mix and --collect of a.toml summed it up as a's. --collect now holds
    each case's namelist against the sweep file's case, and refuses the mix naming it. The
    earlier summary.csv is renamed summary.previous.csv when the emission starts (its cases
    are about to be replaced), with its rows as they were."""
    import pymr.sweep as sweep_module
    (tmp_path / "p.nml").write_text(PENDULUM)
    text = 'scene = "p.nml"\nmetric = "final:pivot.q"\n[grid]\n"joint[pivot].q0" = [{}]\n[fixed]\n"scene.t_end" = 0.1\n'
    (tmp_path / "a.toml").write_text(text.format("0.5, 0.6"))
    (tmp_path / "b.toml").write_text(text.format("0.7, 0.8"))
    folder = tmp_path / "runs"
    a = load_sweep(tmp_path / "a.toml")
    emit_slurm(a, folder)
    for i in range(2):
        r = subprocess.run([mrsim, f"case{i:04d}.nml", "-o", f"case{i:04d}.csv", "--quiet"], cwd=folder,
                           capture_output=True, text=True)
        assert r.returncode == 0, r.stderr
    rows = collect(a, folder)
    assert [row["status"] for row in rows] == ["ok", "ok"]
    summary = (folder / "summary.csv").read_text()
    written = sweep_module.case_namelist

    def killed_after_one(base, overrides, dest):
        written(base, overrides, dest)
        raise KeyboardInterrupt
    monkeypatch.setattr(sweep_module, "case_namelist", killed_after_one)
    with pytest.raises(KeyboardInterrupt):
        emit_slurm(load_sweep(tmp_path / "b.toml"), folder)
    assert not (folder / "summary.csv").exists() and (folder / "summary.previous.csv").read_text() == summary
    assert "q0 = 0.7" in (folder / "case0000.nml").read_text().replace("q0 = 0.70", "q0 = 0.7")
    with pytest.raises(SweepError, match=r"--collect .*runs: its case0000\.nml is not this sweep's case case0000 "
                                         r"\(a\.toml\): emit the cases again with --emit-slurm"):
        collect(a, folder)
    monkeypatch.setattr(sweep_module, "case_namelist", written)
    emit_slurm(a, folder)
    assert [row["status"] for row in collect(a, folder)] == ["ok", "ok"]


# ------------------------------------------------- faults found before any case runs (audit V5-V7)

#: A pendulum sweep of two (or three) cases, 0.05 s long (a row every step unless output.dt
#: is set): the metric, the grid's values and the lines after the [fixed] table's first item.
SHORT_SWEEP = ('scene = "p.nml"\noutput = "out"\nmetric = "{metric}"\n[grid]\n"joint[pivot].q0" = [{values}]\n'
               '[fixed]\n"scene.t_end" = 0.05\n{extra}\n')


def _sweep_command(cwd: Path, *args: str) -> subprocess.CompletedProcess:
    """pymr sweep ARGS in `cwd`, by the pymr this test imports (not the one first on PATH)."""
    return subprocess.run([sys.executable, "-m", "pymr", "sweep", *args], cwd=cwd, capture_output=True, text=True,
                          timeout=120)


@pytest.mark.parametrize("metric, extra, message", [
    # V5: a checkpoint over the base scene failed every case, exit 2
    ("final:pivot.q", '"output.checkpoint_dt" = 0.01\n"output.checkpoint_file" = "p.nml"',
     r"s.toml: case0000: \[fixed\] output.checkpoint_file = p.nml: would overwrite the scene \(.*p.nml\); choose "
     r"another checkpoint file"),
    # V5: HDF5 results, which no caseNNNN.csv can hold
    ("final:pivot.q", '"output.format" = "hdf5"',
     r"s.toml: \[fixed\] output.format: 'hdf5' in case0000: a sweep writes each run's results as CSV"),
    # V5: a reference whose results lack the marker, or whose output times are not its case's
    ("deviation:tip", '"output.dt" = 0.01\n[reference]\n"output.quantities" = "energy"',
     r"s.toml: metric 'deviation:tip': the results of the reference of case0000 have no marker 'tip'"),
    ("deviation:tip", '"output.dt" = 0.01\n[reference]\n"output.dt" = 0.0',
     r"s.toml: \[reference\] output.dt: 0 in the reference of case0000, 0.01 in case0000: the deviation compares "
     r"the marker at the case's output times, which its reference must share: leave output.dt out of \[reference\]"),
    ("deviation:tip", '"output.dt" = 0.01\n[reference]\n"scene.t_end" = 0.02',
     r"s.toml: \[reference\] scene.t_end: 0.02 in the reference of case0000, 0.05 in case0000: .* leave "
     r"scene.t_end out of \[reference\]"),
    # the base scene writes a row every step, and the reference steps otherwise
    ("deviation:tip", '[reference]\n"integrator.h_slow" = 2.5e-4',
     r"s.toml: scene p.nml, &output dt: 0 \(a row every step\) in case0000 and its reference, which steps by the "
     r"\[reference\] settings: .* give output.dt > 0"),
    # V6: one checkpoint file for every case (they raced on it)
    ("final:pivot.q", '"output.checkpoint_dt" = 0.01\n"output.checkpoint_file" = "same.ckpt"',
     r"s.toml: \[fixed\] output.checkpoint_file: 'same.ckpt' is the checkpoint file of case0000, case0001 and "
     r"case0002: runs of a sweep must not share a file .*: leave checkpoint_file out, and each case writes its "
     r"checkpoint beside its results \(caseNNNN.ckpt\)"),
    # V7: a [reference] the metric does not use was ignored, its faults unseen (exit 0)
    ("final:pivot.q", '[reference]\n"integrator.hslow" = 1e-4',
     r"s.toml: \[reference\]: only the metric 'deviation:MARKER' runs reference runs, and the metric is "
     r"'final:pivot.q': remove \[reference\]"),
    ("", '[reference]\n"integrator.h_slow" = -1',
     r"s.toml: \[reference\]: only the metric 'deviation:MARKER' runs reference runs, and there is no metric: "
     r"remove \[reference\]"),
], ids=["checkpoint_over_scene", "hdf5", "reference_without_marker", "reference_dt", "reference_t_end",
        "every_step", "shared_checkpoint", "unused_reference", "reference_without_metric"])
@pytest.mark.parametrize("mode", [[], ["--emit-slurm", "runs"]], ids=["run", "emit"])
def test_a_fault_every_case_would_meet_stops_the_sweep_before_any_case_runs(tmp_path, metric, extra, message, mode):
    """Audit V5-V7: outputs and [reference] settings that failed every case after it ran
    (exit 2), raced the cases on one file, or were ignored (exit 0) are one line naming the
    sweep file, its table and item, and exit 1, before any case or reference runs: no
    folder is made, no checkpoint written, no namelist emitted."""
    (tmp_path / "p.nml").write_text(PENDULUM)
    values = "0.5, 0.6, 0.7" if "same.ckpt" in extra else "0.5, 0.6"
    (tmp_path / "s.toml").write_text(SHORT_SWEEP.format(metric=metric, values=values, extra=extra))
    r = _sweep_command(tmp_path, "s.toml", *mode)
    assert r.returncode == 1 and r.stdout == "" and r.stderr.count("\n") == 1, (r.returncode, r.stderr)
    assert r.stderr.startswith("pymr: error: s.toml: ") and re.search(message, r.stderr), r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.nml", "s.toml"]
    assert (tmp_path / "p.nml").read_text() == PENDULUM


def test_each_case_s_checkpoint_goes_beside_its_results(tmp_path, monkeypatch):
    """The checkpoints of a sweep without a checkpoint_file (V6's way out): each case and
    reference writes its own beside its results, and every case is ok. Distinct
    checkpoint_files on the grid are no shared file, and are taken."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.nml").write_text(PENDULUM)
    (tmp_path / "s.toml").write_text(SHORT_SWEEP.format(metric="deviation:tip", values="0.5, 0.6", extra=(
        '"output.dt" = 0.01\n"output.checkpoint_dt" = 0.02\n[reference]\n"integrator.h_slow" = 2.5e-4')))
    rows = run_sweep(load_sweep(tmp_path / "s.toml"), workers=1)
    assert [r["status"] for r in rows] == ["ok", "ok"]
    assert sorted(p.name for p in (tmp_path / "out").glob("*.ckpt")) == [
        "case0000.ckpt", "case0001.ckpt", "reference0000.ckpt", "reference0001.ckpt"]
    (tmp_path / "g.toml").write_text('scene = "p.nml"\n[grid]\n"output.checkpoint_file" = ["a.ckpt", "b.ckpt"]\n'
                                     '[fixed]\n"scene.t_end" = 0.05\n"output.checkpoint_dt" = 0.02\n')
    assert len(load_sweep(tmp_path / "g.toml").cases) == 2


def test_a_failed_sweep_s_line_names_the_first_failure_s_cause(tmp_path):
    """V5: max_bytes too small for every case is known only as a case runs (the kernel's
    size check needs the run's built model and columns, and no entry point of the binding
    makes it alone; a row every step here): every case fails, exit 2,
    and the one error line names the first failed case and its cause, which the case
    listing cut at 90 characters before the kernel's reason."""
    (tmp_path / "p.nml").write_text(PENDULUM)
    (tmp_path / "s.toml").write_text(SHORT_SWEEP.format(metric="final:pivot.q", values="0.5, 0.6",
                                                        extra='"output.max_bytes" = 1000'))
    r = _sweep_command(tmp_path, "s.toml", "--workers", "1")
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Traceback" not in r.stderr, r.stderr
    assert re.fullmatch(r"pymr: error: of 2 cases, 2 failed \(case0000, case0001\): see .*summary.csv; case0000: "
                        r".*p.nml: .*&output: dt: the results would take about \d+ bytes \(\d+ rows\), more than "
                        r"max_bytes = 1000 \(a larger dt, or raise max_bytes in &output\)\n", r.stderr), r.stderr
