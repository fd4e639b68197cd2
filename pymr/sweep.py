"""``pymr sweep SWEEP.toml``: a base scene and a parameter grid, expanded into cases, run on
Dask and collected into one summary CSV; or, with ``--emit-slurm DIR``, written out as case
namelists and a SLURM job-array script that runs ``mrsim`` per case.

SWEEP.toml::

    scene = "input/tank_gun_turret.nml"     # relative to the TOML file
    output = "sweep"                         # folder for the cases' results and the summary,
                                             # relative to the TOML file (default: its stem)
    metric = "deviation:muzzle"              # or "final:COLUMN", "max_abs:COLUMN"

    [grid]                                   # every combination of these values is a case
    "integrator.h_slow" = [1e-3, 5e-4]
    "body[gun].modal_damping" = [0.0, 0.02]

    [fixed]                                  # overrides shared by every case (optional)
    "integrator.method" = "multirate"

    [reference]                              # overrides of the reference run (deviation metric)
    "integrator.h_slow" = 2.5e-5

Keys are ``--set`` keys: ``group.item``, with repeated groups named by their name (body,
joint, marker), joint (drive, spring, motion) or marker (load). ``deviation:MARKER`` is the
largest distance over the run between the marker's position and the reference run's (the
base scene with the [reference] overrides, at the same output times).
"""
from __future__ import annotations

import csv
import io
import itertools
import math
import os
import re
import sys
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .api import PymrError, SceneError, run, write_file
from .results import load_results
from .scene import Scene


class SweepError(PymrError):
    """A bad sweep file."""


@dataclass
class Sweep:
    """A parsed sweep: base scene, cases (each a dict of overrides), metric."""
    path: Path
    scene: Path
    output: Path
    metric: str
    grid: dict
    fixed: dict = field(default_factory=dict)
    reference: dict = field(default_factory=dict)

    @property
    def cases(self) -> list[dict]:
        keys = list(self.grid)
        return [dict(zip(keys, values)) for values in itertools.product(*(self.grid[k] for k in keys))]


def load_sweep(path: str | os.PathLike) -> Sweep:
    path = Path(path)
    try:
        spec = tomllib.loads(path.read_text())
    except FileNotFoundError:
        raise SweepError(f"{path}: not found") from None
    except (tomllib.TOMLDecodeError, UnicodeDecodeError, IsADirectoryError) as exc:
        raise SweepError(f"{path}: not a TOML sweep file ({exc})") from None
    check_types(path, spec)
    for key in spec:
        if key not in ("scene", "output", "metric", "grid", "fixed", "reference"):
            raise SweepError(f"{path}: unknown key {key!r} (known: scene, output, metric, grid, fixed, reference)")
    if "scene" not in spec:
        raise SweepError(f"{path}: scene: missing (the base scene's namelist file)")
    grid = spec.get("grid", {})
    if not grid:
        raise SweepError(f"{path}: [grid]: missing or empty (parameter = [values, ...])")
    for k, v in grid.items():
        if not isinstance(v, list) or not v:
            raise SweepError(f"{path}: [grid] {k}: must be a non-empty list of values")
    metric = spec.get("metric", "")
    if metric and not re.fullmatch(r"(deviation|final|max_abs):[\w.\[\]]+", metric):
        raise SweepError(f"{path}: metric: {metric!r} is not 'deviation:MARKER', 'final:COLUMN' or 'max_abs:COLUMN'")
    scene = (path.parent / spec["scene"]).resolve()
    if not scene.exists():
        raise SweepError(f"{path}: scene: {scene} not found")
    output = (path.parent / spec.get("output", path.stem)).resolve()
    sw = Sweep(path, scene, output, metric, grid, spec.get("fixed", {}), spec.get("reference", {}))
    check_cases(sw)
    return sw


#: The sweep file's keys and the TOML type each must have.
KEY_TYPES = {"scene": (str, "a file name (a string)"), "output": (str, "a folder name (a string)"),
             "metric": (str, "a string such as 'final:COLUMN'"), "grid": (dict, "a table ([grid])"),
             "fixed": (dict, "a table ([fixed])"), "reference": (dict, "a table ([reference])")}


def check_types(path: Path, spec: dict) -> None:
    """Each known key of the sweep file has its type (a number where a file name goes gave
    a TypeError traceback)."""
    for key, (kind, what) in KEY_TYPES.items():
        if key in spec and not isinstance(spec[key], kind):
            raise SweepError(f"{path}: {key}: must be {what}, got {spec[key]!r}")


def check_cases(sw: Sweep) -> None:
    """Every case's scene (and the reference's) read and checked by the kernel before any
    case runs: a bad key or value is one error naming the case."""
    named = [("reference", {**sw.fixed, **sw.reference})] + [(case_name(i), {**sw.fixed, **c})
                                                                for i, c in enumerate(sw.cases)]
    for name, overrides in named:
        try:
            Scene(sw.scene, overrides)
        except SceneError as exc:
            raise SweepError(f"{sw.path}: {name} {overrides}: {exc}") from None


def case_name(i: int) -> str:
    return f"case{i:04d}"


def run_case(scene: str, overrides: dict, out: str, metric: str, reference: np.ndarray | None) -> dict:
    """Run one case; return its metric, CPU time and status (errors are recorded, not raised)."""
    row = {"metric": math.nan, "cpu_time_s": math.nan, "status": "ok"}
    try:
        res = run(scene, out, overrides=overrides, progress=False)
    except PymrError as exc:
        row["status"] = f"error: {exc}"
        return row
    row["cpu_time_s"] = float(res.stats["cpu_time_s"])
    row["metric"], row["status"] = case_metric(res, metric, reference)
    return row


def case_metric(res, metric: str, reference: np.ndarray | None) -> tuple[float, str]:
    """The sweep's metric of one case's results, and its status ('ok' or the error)."""
    if not metric:
        return math.nan, "ok"
    kind, what = metric.split(":", 1)
    try:
        if kind == "deviation":
            pos = res.marker(what)[0]
            if reference is None or len(reference) != len(pos):
                return math.nan, "error: the case's output times differ from the reference's"
            return float(np.linalg.norm(pos - reference, axis=1).max()), "ok"
        if kind == "final":
            return float(res[what][-1]), "ok"
        return float(np.abs(res[what]).max()), "ok"
    except KeyError as exc:
        return math.nan, f"error: {exc.args[0]}"


def reference_positions(sw: Sweep, folder: Path | None = None) -> np.ndarray | None:
    if not sw.metric.startswith("deviation:"):
        return None
    res = run(sw.scene, (folder or sw.output) / "reference.csv", overrides={**sw.fixed, **sw.reference},
              progress=False)
    return res.marker(sw.metric.split(":", 1)[1])[0]


def collect(sw: Sweep, folder: str | os.PathLike) -> list[dict]:
    """The summary of a sweep run as a SLURM job array (``--emit-slurm``): each case's
    complete results in `folder` give its metric and CPU time; a case without them is
    recorded as missing (not run yet, or failed: its caseNNNN.json.partial says why). The
    deviation metric's reference is run here. Writes folder/summary.csv."""
    folder = Path(folder)
    if not (folder / "sweep.slurm").exists():
        raise SweepError(f"{folder}: no sweep.slurm here (emit the cases with --emit-slurm first)")
    ref = reference_positions(sw, folder)
    rows = []
    for i, case in enumerate(sw.cases):
        row = {"case": case_name(i), **case, "metric": math.nan, "cpu_time_s": math.nan}
        out = folder / f"{case_name(i)}.csv"
        if not out.exists():
            partial = folder / f"{case_name(i)}.json.partial"
            row["status"] = ("failed: see " + partial.name) if partial.exists() else "missing: no results yet"
        else:
            res = load_results(out)
            row["cpu_time_s"] = float(res.stats.get("cpu_time_s", math.nan))
            row["metric"], row["status"] = case_metric(res, sw.metric, ref)
        rows.append(row)
    write_summary(sw, rows, folder)
    return rows


#: Thread counts of the BLAS libraries a LAPACK may use (OpenBLAS, OpenMP, MKL): a sweep's
#: cases run one per core, so each case's BLAS takes one thread (pymr bench lapack measured
#: threaded OpenBLAS slower on pymr's matrix sizes anyway).
BLAS_THREADS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def run_sweep(sw: Sweep, scheduler: str | None = None, workers: int = 2) -> list[dict]:
    """Run every case on Dask (a LocalCluster of `workers` processes, or the scheduler at
    `scheduler`) and write the summary CSV; returns its rows."""
    try:
        from dask.distributed import Client, LocalCluster
    except ImportError:
        raise SweepError("pymr sweep runs its cases on Dask, which is not installed: "
                         "pip install 'dask[distributed]' (or write SLURM files with --emit-slurm)") from None
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 1:
        raise SweepError(f"workers: a whole number of worker processes, at least 1, got {workers!r}")
    make_folder(sw.output, "output")
    ref = reference_positions(sw)
    cases = sw.cases
    cluster = None
    if scheduler:
        try:
            client = Client(scheduler)
        except OSError as exc:
            raise SweepError(f"--scheduler {scheduler}: cannot reach it ({' '.join(str(exc).split())})") from None
    else:
        # one thread per worker process, BLAS included: the workers inherit these
        for name in BLAS_THREADS:
            os.environ.setdefault(name, "1")
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        futures = [client.submit(run_case, str(sw.scene), {**sw.fixed, **case},
                                 str(sw.output / f"{case_name(i)}.csv"), sw.metric, ref, pure=False)
                   for i, case in enumerate(cases)]
        results = client.gather(futures, errors="skip")
        done = {f.key: r for f, r in zip([f for f in futures if f.status == "finished"], results)}
        rows = []
        for i, (case, fut) in enumerate(zip(cases, futures)):
            row = done.get(fut.key) or {"metric": math.nan, "cpu_time_s": math.nan,
                                        "status": f"error: {fut.exception()!r}"}
            rows.append({"case": case_name(i), **case, **row})
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    write_summary(sw, rows)
    return rows


def make_folder(folder: Path, what: str) -> None:
    """`folder` made (with its parents) unless it is there; a file in its place, or a folder
    that cannot be made, is a SweepError naming `what` it is for."""
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise SweepError(f"{folder}: cannot make the {what} folder ({exc.strerror or exc})") from None


def write_summary(sw: Sweep, rows: list[dict], folder: Path | None = None) -> Path:
    """folder/summary.csv, written whole (an earlier summary stays until the new one is complete)."""
    fields = ["case", *sw.grid, "metric", "cpu_time_s", "status"]
    fh = io.StringIO(newline="")
    w = csv.DictWriter(fh, fieldnames=fields, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow(r)
    return write_file((folder or sw.output) / "summary.csv", fh.getvalue(), "sweep's summary")


# ------------------------------------------------------------------------ SLURM

def case_namelist(base: Path, overrides: dict, dest: Path) -> None:
    """Write the base scene with the overrides applied and every default filled in (the
    kernel's resolved scene), the files it names made absolute, and no &output file (mrsim
    gets -o)."""
    scene = Scene(base, {**overrides, "output.file": ""})
    text = scene.resolved(absolute_paths=True)
    write_file(dest, f"! {dest.name}: {base.name} with {overrides}\n" + text, "case namelist")


def emit_slurm(sw: Sweep, folder: str | os.PathLike, time_limit: str = "01:00:00") -> Path:
    """Case namelists and a SLURM job-array script running mrsim per case, in `folder`. The
    script names the mrsim of this installation by its absolute path (a compute node need
    not have it on its PATH); the environment variable PYMR_MRSIM overrides it."""
    from ._locate import mrsim_path
    exe = mrsim_path() or "mrsim"
    folder = Path(folder)
    make_folder(folder, "--emit-slurm")
    cases = sw.cases
    for i, case in enumerate(cases):
        case_namelist(sw.scene, {**sw.fixed, **case}, folder / f"{case_name(i)}.nml")
    fh = io.StringIO(newline="")
    w = csv.DictWriter(fh, fieldnames=["case", *sw.grid])
    w.writeheader()
    for i, case in enumerate(cases):
        w.writerow({"case": case_name(i), **case})
    write_file(folder / "cases.csv", fh.getvalue(), "list of cases")
    script = write_file(folder / "sweep.slurm", f"""#!/bin/bash
# SLURM job array for the sweep {sw.path.name}: one task per case namelist.
# Submit from this folder: sbatch sweep.slurm   (results: caseNNNN.csv and .json here)
#SBATCH --job-name=pymr-sweep
#SBATCH --array=0-{len(cases) - 1}
#SBATCH --ntasks=1
#SBATCH --cpus-per-task=1
#SBATCH --time={time_limit}
#SBATCH --output=slurm-%A_%a.out
# Then collect the summary: pymr sweep {sw.path} --collect {folder}
set -euo pipefail
# one CPU per task: no BLAS threads beside it
export {' '.join(f'{name}=1' for name in BLAS_THREADS)}
cd "${{SLURM_SUBMIT_DIR:-$(dirname "$0")}}"
case=$(printf 'case%04d' "${{SLURM_ARRAY_TASK_ID}}")
MRSIM="${{PYMR_MRSIM:-{exe}}}"
"$MRSIM" "$case.nml" -o "$case.csv" --quiet
""", "SLURM script")
    script.chmod(0o755)
    return script


def main(toml: str, scheduler: str | None = None, workers: int = 2, emit: str | None = None,
         collect_from: str | None = None) -> int:
    sw = load_sweep(toml)
    if emit:
        script = emit_slurm(sw, emit)
        print(f"wrote {len(sw.cases)} case namelists and {script} (submit with: cd {emit} && sbatch sweep.slurm; "
              f"then: pymr sweep {toml} --collect {emit})")
        return 0
    t0 = time.time()
    if collect_from:
        rows = collect(sw, collect_from)
        where = Path(collect_from) / "summary.csv"
    else:
        rows = run_sweep(sw, scheduler=scheduler, workers=workers)
        where = sw.output / "summary.csv"
    failed = sum(r["status"] != "ok" for r in rows)
    print(f"{len(rows)} cases, {failed} failed, {time.time() - t0:.1f} s: {where}")
    for r in rows:
        params = ", ".join(f"{k}={r[k]}" for k in sw.grid)
        print(f"  {r['case']}  {params}  metric {r['metric']:.4g}  cpu {r['cpu_time_s']:.3f} s  {r['status'][:90]}")
    if failed:
        print(f"pymr: error: {failed} of {len(rows)} cases failed: "
              + ", ".join(r["case"] for r in rows if r["status"] != "ok"), file=sys.stderr)
        return 2
    return 0
