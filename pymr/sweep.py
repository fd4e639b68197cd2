"""``pymr sweep SWEEP.toml``: a base scene and a parameter grid, expanded into cases, run on
Dask and collected into one summary CSV; or, with ``--emit-slurm DIR``, written out as case
namelists (and the deviation metric's reference runs') and a SLURM job-array script that
runs ``mrsim`` per namelist, whose results ``--collect DIR`` sums up.

SWEEP.toml::

    scene = "input/tank_gun_turret.nml"     # relative to the TOML file
    output = "sweep"                         # folder for the cases' results and the summary,
                                             # relative to the working folder (default: the
                                             # TOML file's stem, in the working folder)
    metric = "deviation:muzzle"              # or "final:COLUMN", "max_abs:COLUMN"

    [grid]                                   # every combination of these values is a case
    "integrator.h_slow" = [1e-3, 5e-4]
    "body[gun].modal_damping" = [0.0, 0.02]

    [fixed]                                  # overrides shared by every case (optional)
    "integrator.method" = "multirate"

    [reference]                              # integration settings of the reference runs
    "integrator.h_slow" = 2.5e-5

Keys are ``--set`` keys: ``group.item``, with repeated groups named by their name (body,
joint, marker), joint (drive, spring, motion) or marker (load). ``deviation:MARKER`` is the
largest distance over the run between the marker's position and its reference run's, at the
same output times. Each case's reference run is the case itself, its [fixed] and [grid]
values, with the [reference] overrides on top: it shares the case's physics (a grid of
damping values gets a damped reference for each damped case), so the deviation measures
the case's integration error, not a difference of physics. Cases with the same reference
share its run (``referenceNNNN.csv`` in the output folder; the summary names each case's).

The output folder, like every output of pymr, is relative to the working folder (not to
the TOML file, which may sit in a checkout or in the installed package). Before any case
runs, every case's scene (and its reference's) is read by the kernel, and the metric's
marker or column is looked up in the columns the case's (and reference's) results will
have: a bad key, value or metric is one line naming the sweep file, with exit 1. So is
what every case would fail on after its run: results other than CSV, a checkpoint_file
over an input or shared by two runs (each case's default checkpoint, beside its results,
is its own), a reference whose output times are not its case's; and a [reference] table
beside a metric that runs no references.
"""
from __future__ import annotations

import csv
import io
import itertools
import math
import os
import re
import stat
import sys
import time
import tomllib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._args import canonical_address, sync_to_disk
from .api import PymrError, SceneError, run, write_file
from .errors import OutputError, ResultsError
from .outputs import _folder_of, _is_dir, check_output
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


#: Worker processes of a LocalCluster at most: each is a Python process on this machine
#: (2**64 of them were started until the machine ran out of memory).
MAX_WORKERS = 256


def load_sweep(path: str | os.PathLike) -> Sweep:
    path = Path(path)
    try:
        spec = tomllib.loads(_sweep_text(path))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
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
    grid, fixed, reference = named_once(path, spec)
    metric = spec.get("metric", "")
    if metric and not re.fullmatch(r"(deviation|final|max_abs):[\w.\[\]]+", metric):
        raise SweepError(f"{path}: metric: {metric!r} is not 'deviation:MARKER', 'final:COLUMN' or 'max_abs:COLUMN'")
    check_reference_used(path, spec, metric)
    scene = (path.parent / spec["scene"]).resolve()
    try:
        found = scene.exists()
    except OSError as exc:       # a name the system cannot take (too long, a component too long)
        raise SweepError(f"{path}: scene: {scene}: {exc.strerror}") from None
    if not found:
        raise SweepError(f"{path}: scene: {scene} not found")
    if spec.get("output", None) == "":
        raise SweepError(f"{path}: output: an empty folder name (leave it out for {path.stem}/ in the working folder)")
    # outputs are relative to the working folder, as every pymr output is (not to the TOML file)
    output = Path(spec.get("output", path.stem)).resolve()
    sw = Sweep(path, scene, output, metric, grid, fixed, reference)
    tasks = check_cases(sw)
    check_task_outputs(sw, tasks)
    check_metric(sw, tasks)
    check_reference_times(sw, tasks)
    return sw


def check_reference_used(path: Path, spec: dict, metric: str) -> None:
    """A [reference] table only where the metric runs references (deviation): beside
    another metric, or none, it was ignored, its unknown items and bad values unread."""
    if "reference" in spec and not metric.startswith("deviation:"):
        used = f"the metric is {metric!r}" if metric else "there is no metric"
        raise SweepError(f"{path}: [reference]: only the metric 'deviation:MARKER' runs reference runs, and {used}: "
                         "remove [reference]")


def named_once(path: Path, spec: dict) -> tuple[dict, dict, dict]:
    """The [grid], [fixed] and [reference] tables with each item named once (the kernel's
    canonical_address: 'Integrator.H_SLOW' and 'integrator.h_slow' are one item). Two keys
    of one table naming one item, or a [fixed] item also on the grid, are refused: one
    value would be dropped (two spellings of a [grid] key ran every case with the last one
    and labelled them with the first). A [reference] key takes the spelling the [grid] or
    [fixed] table gave its item, so that it replaces the case's value. An address that is
    none is left to check_cases, which names the case."""
    tables, spelled = [], {}
    for name in ("grid", "fixed", "reference"):
        seen: dict[str, str] = {}
        table = {}
        for key, value in spec.get(name, {}).items():
            try:
                item = canonical_address(key)
            except SceneError:
                item = key
            if item in seen:
                raise SweepError(f"{path}: [{name}] {key!r} and {seen[item]!r} name one item ({item}): keep one")
            seen[item] = key
            if name == "fixed" and item in spelled:
                raise SweepError(f"{path}: [fixed] {key}: also a [grid] parameter (one value would be dropped): "
                                 "keep it in one table")
            table[spelled.setdefault(item, key)] = value
        tables.append(table)
    return tables[0], tables[1], tables[2]


def _sweep_text(path: Path) -> str:
    """The text of the sweep file, a regular file as the kernel's scene reader has it: a
    FIFO blocked the read for ever (and a device is no sweep file); a folder is named."""
    try:
        mode = path.stat().st_mode
        if stat.S_ISDIR(mode):
            raise SweepError(f"{path}: cannot read: it is a directory")
        if not stat.S_ISREG(mode):
            raise SweepError(f"{path}: cannot read: it is not a regular file (a FIFO, a socket or a device)")
        return path.read_text()
    except FileNotFoundError:
        raise SweepError(f"{path}: not found") from None
    except OSError as exc:
        raise SweepError(f"{path}: cannot read: {exc.strerror or exc}") from None
    except UnicodeDecodeError:               # not text: the caller says it is no TOML
        raise
    except ValueError:                       # a NUL in the name (Python's 'embedded null byte')
        raise SweepError(f"{str(path)!r}: a file name cannot hold a NUL character") from None


#: The sweep file's keys and the TOML type each must have.
KEY_TYPES = {"scene": (str, "a file name (a string)"), "output": (str, "a folder name (a string)"),
             "metric": (str, "a string such as 'final:COLUMN'"), "grid": (dict, "a table ([grid])"),
             "fixed": (dict, "a table ([fixed])"), "reference": (dict, "a table ([reference])")}


def check_types(path: Path, spec: dict) -> None:
    """Each known key of the sweep file has its type (a number where a file name goes gave
    a TypeError traceback), and a file or folder name holds no NUL character (TOML's
    \\u0000 gave a ValueError traceback) and is not empty."""
    for key, (kind, what) in KEY_TYPES.items():
        if key in spec and not isinstance(spec[key], kind):
            raise SweepError(f"{path}: {key}: must be {what}, got {spec[key]!r}")
    for key in ("scene", "output"):
        if "\0" in spec.get(key, ""):
            raise SweepError(f"{path}: {key}: {spec[key]!r}: a file name cannot hold a NUL character")
    if spec.get("scene", None) == "":
        raise SweepError(f"{path}: scene: an empty file name (the base scene's namelist file)")


@dataclass
class Task:
    """One run of a sweep, a case or (the deviation metric) a reference run: its name in
    messages, its overrides, the kernel's scene of them, and the cases it is (or serves)."""
    name: str
    overrides: dict
    scene: Scene
    cases: list[int]
    reference: bool = False


def check_cases(sw: Sweep) -> list[Task]:
    """Every case's scene (and its reference's) read and checked by the kernel before any
    case runs: a bad key or value is one error naming the case. Returns the runs, the
    cases' first, for the checks that follow."""
    named = [(case_name(i), {**sw.fixed, **c}, [i], False) for i, c in enumerate(sw.cases)]
    if sw.metric.startswith("deviation:"):
        named += [(f"the reference of {', '.join(case_name(i) for i in cases)}", over, cases, True)
                  for over, cases in references(sw)]
    tasks = []
    for name, overrides, cases, reference in named:
        try:
            tasks.append(Task(name, overrides, Scene(sw.scene, overrides), cases, reference))
        except SceneError as exc:
            raise SweepError(f"{sw.path}: {name} {overrides}: {exc}") from None
    return tasks


def item_place(sw: Sweep, address: str, reference: bool = False) -> str:
    """Where a run's value of the item `address` (canonical, 'output.dt') is set: the sweep
    table and key that set it ('[fixed] output.dt'; [reference] first for a reference run),
    else the base scene's group and item ('scene p.nml, &output dt')."""
    tables = [("reference", sw.reference)] if reference else []
    for name, table in tables + [("grid", sw.grid), ("fixed", sw.fixed)]:
        for key in table:
            if canonical_address(key) == address:
                return f"[{name}] {key}"
    group, item = address.split(".", 1)
    return f"scene {sw.scene.name}, &{group} {item}"


def check_task_outputs(sw: Sweep, tasks: list[Task]) -> None:
    """The files each run writes besides its results, checked before any case runs (each
    case refused them as it ran, and the sweep failed case by case, exit 2): results in
    the format the sweep reads, and a checkpoint_file of its own that is no input."""
    for task in tasks:
        check_results_format(sw, task)
        check_checkpoint_file(sw, task)
    check_checkpoints_unshared(sw, tasks)


def check_results_format(sw: Sweep, task: Task) -> None:
    """A sweep's runs write CSV (caseNNNN.csv, referenceNNNN.csv), which its summary and
    --collect read: &output format 'hdf5' failed every case (the kernel writes HDF5 only to
    a .h5 file)."""
    kind = task.scene["output.format"]
    if kind != "csv":
        raise SweepError(f"{sw.path}: {item_place(sw, 'output.format', task.reference)}: {kind!r} in {task.name}: a "
                         "sweep writes each run's results as CSV (caseNNNN.csv), which its summary and --collect read: "
                         "leave output.format out")


def checkpoint_file(task: Task) -> str:
    """The checkpoint_file a run writes ('' for none, or for the default beside its results)."""
    return task.scene["output.checkpoint_file"] if task.scene["output.checkpoint_dt"] > 0 else ""


def check_checkpoint_file(sw: Sweep, task: Task) -> None:
    """A run's checkpoint_file checked as every pymr output is (check_output, with the
    kernel's rule on the scene's inputs), before any case runs: one over the base scene
    failed every case."""
    file = checkpoint_file(task)
    if file:
        check_output(file, "checkpoint file", option=f"{sw.path}: {task.name}: "
                     f"{item_place(sw, 'output.checkpoint_file', task.reference)} =", inputs=[sw.path],
                     scene=sw.scene, overrides=task.overrides)


def check_checkpoints_unshared(sw: Sweep, tasks: list[Task]) -> None:
    """No two runs write one checkpoint_file: the cases run at once and each replaced the
    others' file (a [fixed] checkpoint_file failed cases with a misleading 'the disk took
    -1 bytes', and --emit-slurm wrote it into every namelist). Each case's default
    checkpoint, beside its results (caseNNNN.ckpt), is its own."""
    users: dict[str, list[Task]] = {}
    for task in tasks:
        if checkpoint_file(task):
            users.setdefault(os.path.abspath(checkpoint_file(task)), []).append(task)
    for file, shared in users.items():
        if len(shared) > 1:
            raise SweepError(f"{sw.path}: {item_place(sw, 'output.checkpoint_file', shared[-1].reference)}: "
                             f"{checkpoint_file(shared[0])!r} is the checkpoint file of {_listed(shared)}: runs of a "
                             "sweep must not share a file (each would overwrite the others'): leave checkpoint_file "
                             "out, and each case writes its checkpoint beside its results (caseNNNN.ckpt)")


def _listed(tasks: list[Task]) -> str:
    """The runs' names as a list in a sentence ('case0000, case0001 and case0002')."""
    names = [task.name for task in tasks]
    return names[0] if len(names) == 1 else f"{', '.join(names[:-1])} and {names[-1]}"


#: The items that set a run's output times: the deviation metric compares a case's marker
#: with its reference's at the same rows.
OUTPUT_TIMES = ("scene.t_end", "output.dt")


def check_reference_times(sw: Sweep, tasks: list[Task]) -> None:
    """Each reference run writes its rows at its cases' output times, found before any case
    runs: a [reference] with another t_end or output.dt failed every case after its run
    ('output times differ'), and so did output.dt = 0 (a row every step) when the
    [reference] settings change the reference's steps from its cases'."""
    cases = [task for task in tasks if not task.reference]
    for ref in (task for task in tasks if task.reference):
        case = cases[ref.cases[0]]
        for address in OUTPUT_TIMES:
            mine, theirs = case.scene[address], ref.scene[address]
            if mine != theirs:
                raise SweepError(f"{sw.path}: {item_place(sw, address, True)}: {theirs:g} in {ref.name}, {mine:g} in "
                                 f"{case.name}: the deviation compares the marker at the case's output times, which "
                                 f"its reference must share: leave {address} out of [reference]")
        if ref.scene["output.dt"] == 0 and ref.overrides != case.overrides:
            raise SweepError(f"{sw.path}: {item_place(sw, 'output.dt', True)}: 0 (a row every step) in {case.name} "
                             "and its reference, which steps by the [reference] settings: the deviation compares the "
                             "marker at output times the two share: give output.dt > 0")


def references(sw: Sweep) -> list[tuple[dict, list[int]]]:
    """The deviation metric's reference runs: each case's overrides (fixed, then grid) with
    the [reference] overrides on top, so that the reference shares the case's physics; the
    cases with the same overrides share one run. A list of (overrides, case indices)."""
    out: dict[str, tuple[dict, list[int]]] = {}
    for i, case in enumerate(sw.cases):
        over = {**sw.fixed, **case, **sw.reference}
        out.setdefault(repr(sorted(over.items(), key=lambda kv: kv[0])), (over, []))[1].append(i)
    return list(out.values())


def reference_name(k: int) -> str:
    """The name of reference run k: its job array task's namelist and results are NAME.nml
    and NAME.csv."""
    return f"reference{k:04d}"


def reference_file(k: int) -> str:
    return f"{reference_name(k)}.csv"


#: The groups whose items can change the columns of the results (the markers, joints,
#: flexible bodies' modes and &output quantities); the others (integrator, effects, drives,
#: ...) cannot, so cases differing only in them share one probe in check_metric.
COLUMN_GROUPS = ("body", "joint", "marker", "output")


def check_metric(sw: Sweep, tasks: list[Task]) -> None:
    """The metric's marker or column is one the cases' (and references') results will have, found before any
    case runs (it was found only after every case had run, or at --collect as a traceback):
    a probe run of the case's (or reference's) scene to t = 1e-9 s (from rest, without the pre-flight check:
    only its columns are wanted), one for each distinct set of the overrides that can change
    the columns. A probe the kernel cannot run leaves that case to report its own error."""
    if not sw.metric:
        return
    kind, what = sw.metric.split(":", 1)
    probed: dict[str, list[str] | None] = {}
    for task in tasks:
        over = task.overrides
        key = repr(sorted((k, v) for k, v in over.items() if k.split(".")[0].split("[")[0] in COLUMN_GROUPS))
        if key not in probed:
            probe = {**over, "scene.t_end": 1e-9, "scene.start": "rest", "output.dt": 0.0,
                     "output.checkpoint_dt": 0.0, "integrator.stability_check": False}
            try:
                res = run(sw.scene, overrides=probe, progress=False)
                probed[key] = (res.markers if kind == "deviation" else list(res.columns))
            except PymrError:
                probed[key] = None
            names = probed[key]
            if names is not None and what not in names:
                raise SweepError(f"{sw.path}: metric {sw.metric!r}: " + _missing(kind, what, names, task.name))


def _missing(kind: str, what: str, names: list[str], case: str) -> str:
    """One line: the results of `case` have no marker (or column) `what`; the names like it."""
    import difflib
    noun = "marker" if kind == "deviation" else "column"
    near = difflib.get_close_matches(what, names, n=4, cutoff=0.6)
    if near:
        hint = "did you mean " + " or ".join(repr(n) for n in near) + "?"
    elif kind == "deviation":
        hint = f"markers: {', '.join(names) or 'none (&output quantities must hold markers)'}"
    else:
        hint = f"columns: {', '.join(names[:8])}{', ...' if len(names) > 8 else ''} ({len(names)} in all)"
    return f"the results of {case} have no {noun} {what!r} ({hint})"


def case_name(i: int) -> str:
    return f"case{i:04d}"


def run_case(scene: str, overrides: dict, out: str, metric: str, reference) -> dict:
    """Run one case; return its metric, CPU time and status (errors are recorded, not
    raised). `reference` is the marker's positions of the case's reference run, or the
    reference run's error (a string)."""
    row = {"metric": math.nan, "cpu_time_s": math.nan, "status": "ok"}
    try:
        res = run(scene, out, overrides=overrides, progress=False)
    except PymrError as exc:
        row["status"] = f"error: {exc}"
        return row
    row["cpu_time_s"] = float(res.stats["cpu_time_s"])
    row["metric"], row["status"] = case_metric(res, metric, reference)
    return row


def case_metric(res, metric: str, reference) -> tuple[float, str]:
    """The sweep's metric of one case's results, and its status ('ok' or the error)."""
    if not metric:
        return math.nan, "ok"
    kind, what = metric.split(":", 1)
    try:
        if kind == "deviation":
            if isinstance(reference, str):
                return math.nan, f"error: the reference run failed: {reference}"
            pos = res.marker(what)[0]
            if reference is None or len(reference) != len(pos):
                return math.nan, "error: the case's output times differ from the reference's"
            return float(np.linalg.norm(pos - reference, axis=1).max()), "ok"
        if kind == "final":
            return float(res[what][-1]), "ok"
        return float(np.abs(res[what]).max()), "ok"
    except KeyError as exc:
        return math.nan, f"error: {exc.args[0]}"


def reference_run(scene: str, overrides: dict, out: str, marker: str):
    """One reference run: the marker's positions, or its error as a string (recorded by the
    cases that use it, not raised)."""
    try:
        res = run(scene, out, overrides=overrides, progress=False)
    except PymrError as exc:
        return str(exc)
    return _marker_positions(res, marker)


def reference_names(sw: Sweep) -> list[str]:
    """Each case's reference file name ('' without the deviation metric)."""
    names = [""] * len(sw.cases)
    if sw.metric.startswith("deviation:"):
        for k, (_, cases) in enumerate(references(sw)):
            for i in cases:
                names[i] = reference_file(k)
    return names


#: The statuses of a collected case that has not run to its end (a SLURM task not started,
#: still running, or stopped by its time limit): not counted as failed.
NOT_RUN = ("not run", "not finished")


def collect(sw: Sweep, folder: str | os.PathLike) -> list[dict]:
    """The summary of a sweep run as a SLURM job array (``--emit-slurm``): each case's
    complete results in `folder` give its metric and CPU time. A case is 'ok', 'failed: ...'
    (its run failed: its caseNNNN.json.partial holds the error; or its results cannot be
    read, a truncated file), 'not finished' (a caseNNNN.csv.partial without an error: still
    running, or stopped by its time limit, or its reference still running) or 'not run' (no
    files). The deviation metric's references come from the job array's reference tasks
    (collected_references). Writes folder/summary.csv."""
    folder = Path(folder)
    if not (folder / "sweep.slurm").exists():
        raise SweepError(f"--collect {folder}: no sweep.slurm here (emit the cases with --emit-slurm first)")
    check_output(folder / "summary.csv", "sweep's summary", option="--collect", inputs=[sw.path], scene=sw.scene,
                 overrides=sw.fixed)
    if _text_of(folder / "cases.csv") != cases_text(sw):
        raise SweepError(f"--collect {folder}: its cases.csv is not this sweep's cases ({sw.path.name}): collect "
                         "with the sweep file its cases were emitted from")
    check_case_namelists(sw, folder)
    ref = collected_references(sw, folder)
    names = reference_names(sw)
    rows = []
    for i, case in enumerate(sw.cases):
        row = {"case": case_name(i), **case, "metric": math.nan, "cpu_time_s": math.nan, "reference": names[i]}
        reference = ref[i] if ref else None
        if isinstance(reference, ReferenceNotFinished):      # the case's own fault first
            status = collected_results(folder, case_name(i))[1]
            row["status"] = status if status != "ok" else f"not finished: its reference {reference}"
        else:
            row.update(collect_case(folder, case_name(i), sw.metric, reference))
        rows.append(row)
    write_summary(sw, rows, folder)
    return rows


def check_case_namelists(sw: Sweep, folder: Path) -> None:
    """Each caseNNNN.nml in `folder` must be this sweep's case as --emit-slurm writes it: an
    --emit-slurm killed over an earlier sweep's folder left the new cases' namelists beside
    the old ones and the old cases.csv, and the job array ran the mix."""
    for i, case in enumerate(sw.cases):
        nml = folder / f"{case_name(i)}.nml"
        if _text_of(nml) != namelist_text(sw.scene, {**sw.fixed, **case}, nml.name):
            raise SweepError(f"--collect {folder}: its {nml.name} is not this sweep's case {case_name(i)} "
                             f"({sw.path.name}): emit the cases again with --emit-slurm")


class ReferenceNotFinished(str):
    """A reference run of the job array that has not finished (its text says which)."""


def collected_references(sw: Sweep, folder: Path) -> list | None:
    """Each case's reference for --collect (None without the deviation metric): the marker's
    positions from the job array's referenceNNNN task; the error of a reference that failed
    (a string); a ReferenceNotFinished while its task runs. A reference whose task has not
    run, or a folder emitted before the job array ran the references (no referenceNNNN.nml),
    is run here."""
    if not sw.metric.startswith("deviation:"):
        return None
    marker = sw.metric.split(":", 1)[1]
    out: list = [None] * len(sw.cases)
    for k, (over, cases) in enumerate(references(sw)):
        name = reference_name(k)
        nml = folder / f"{name}.nml"
        emitted = nml.exists()        # not in a folder emitted before the array ran references
        if emitted and _text_of(nml) != namelist_text(sw.scene, over, nml.name):
            raise SweepError(f"--collect {folder}: its {nml.name} is not this sweep's reference ({sw.path.name}): "
                             "emit the cases again with --emit-slurm")
        res, status = collected_results(folder, name) if emitted else (None, "not run")
        if status == "ok":
            pos = _marker_positions(res, marker)
        elif status == "not run":
            scene, scene_over = (nml, {}) if emitted else (sw.scene, over)
            pos = reference_run(str(scene), scene_over, str(folder / reference_file(k)), marker)
        elif status.startswith("not finished"):
            pos = ReferenceNotFinished(f"{name} {status.removeprefix('not finished: ')}")
        else:
            pos = f"{name}: {status.removeprefix('failed: ')}"
        for i in cases:
            out[i] = pos
    return out


def _text_of(path: Path) -> str | None:
    """A file's text, or None when it cannot be read as text."""
    try:
        return path.read_bytes().decode()
    except (OSError, UnicodeDecodeError):
        return None


def _marker_positions(res, marker: str):
    """A reference's marker positions, or why it has none (a string)."""
    try:
        return res.marker(marker)[0]
    except KeyError as exc:
        return str(exc.args[0])


def collect_case(folder: Path, name: str, metric: str, reference) -> dict:
    """One case of --collect: its status, and its metric and CPU time when it is complete."""
    res, status = collected_results(folder, name)
    if status != "ok":
        return {"status": status}
    value, status = case_metric(res, metric, reference)
    return {"metric": value, "cpu_time_s": float(res.stats.get("cpu_time_s", math.nan)),
            "status": "failed: " + status.removeprefix("error: ") if status != "ok" else "ok"}


def collected_results(folder: Path, name: str) -> tuple:
    """A job array task's results (NAME.nml run into NAME.csv) and their status: 'ok' (the
    results, complete and of NAME.nml), 'failed: ...' (the error its NAME.json.partial holds,
    or results cut short or of another scene), 'not finished: ...' (a NAME.csv.partial and
    no error: running, or stopped by its time limit) or 'not run' (no files)."""
    out = folder / f"{name}.csv"
    if not out.exists():
        partial = folder / f"{name}.json.partial"
        if partial.exists():
            return None, f"failed: {_partial_error(partial)}"
        if (folder / f"{name}.csv.partial").exists():
            return None, (f"not finished: {name}.csv.partial without an error (running, or stopped by its time "
                          "limit)")
        return None, "not run"
    try:
        res = load_results(out)
    except ResultsError as exc:
        return None, f"failed: incomplete results: {exc}"
    short = _incomplete(res, out)
    if short:
        return None, f"failed: incomplete results: {short}"
    other = _other_scene(res, out, folder / f"{name}.nml")
    if other:
        return None, f"failed: {other}"
    return res, "ok"


def _incomplete(res, out: Path) -> str:
    """Why a case's results that load are not a complete run ('' when they are): the
    statistics beside them are missing or not 'complete' (a complete run's file cut at a
    line's end does not load: :func:`pymr.results.checked` counts its rows)."""
    stats = res.stats or {}
    if not stats:
        return f"{out}: no statistics file {out.with_suffix('.json').name} beside it"
    if stats.get("status") != "complete":
        return f"{out}: its statistics say status {stats.get('status')!r}, not 'complete'"
    return ""


def _other_scene(res, out: Path, namelist: Path) -> str:
    """Why a case's results are not of its namelist ('' when they are): results an earlier
    sweep emitted into the same folder left there, whose scene fingerprint is another's."""
    try:
        mine = Scene(namelist).fingerprint
    except (PymrError, OSError) as exc:
        return f"{namelist}: cannot read the case's namelist ({exc})"
    if res.stats.get("scene_fingerprint") != mine:
        return (f"{out}: the results are of another scene than {namelist.name} (an earlier sweep's, left in the "
                "folder?): run the case again")
    return ""


def _partial_error(partial: Path) -> str:
    """The error a failed run wrote into its OUT.json.partial (or where to look for it)."""
    import json
    try:
        error = json.loads(partial.read_text()).get("error", "")
    except (OSError, ValueError, AttributeError, RecursionError):
        error = ""
    return " ".join(str(error).split()) or f"see {partial.name}"


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
    if isinstance(workers, bool) or not isinstance(workers, int) or not 1 <= workers <= MAX_WORKERS:
        raise SweepError(f"workers: a whole number of worker processes from 1 to {MAX_WORKERS}, got {workers!r}")
    if scheduler is not None:
        _check_address(scheduler)
    make_folder(sw.output, "output")
    check_outputs(sw, sw.output, f"{sw.path}: output", emitting=False)
    summary = sw.output / "summary.csv"
    retire_summary(sw.output)
    cases = sw.cases
    cluster = None
    if scheduler is not None:
        try:
            client = Client(scheduler)
        except OSError as exc:
            raise SweepError(f"--scheduler {scheduler}: cannot reach it ({' '.join(str(exc).split())})") from None
    else:
        # one thread per worker process, BLAS included: the workers inherit these
        for name in BLAS_THREADS:
            os.environ.setdefault(name, "1")
        # the scheduler's HTTP server on a free port (None takes 8787, and a second sweep on the
        # machine printed Dask's "Port 8787 is already in use" warning into pymr's one-line errors)
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0")
        client = Client(cluster)
    try:
        # the references run on the cluster too; each case waits for its own
        refs: list = [None] * len(cases)
        if sw.metric.startswith("deviation:"):
            marker = sw.metric.split(":", 1)[1]
            for k, (over, users) in enumerate(references(sw)):
                fut = client.submit(reference_run, str(sw.scene), over, str(sw.output / reference_file(k)), marker,
                                    pure=False)
                for i in users:
                    refs[i] = fut
        futures = [client.submit(run_case, str(sw.scene), {**sw.fixed, **case},
                                 str(sw.output / f"{case_name(i)}.csv"), sw.metric, refs[i], pure=False)
                   for i, case in enumerate(cases)]
        results = client.gather(futures, errors="skip")
        done = {f.key: r for f, r in zip([f for f in futures if f.status == "finished"], results)}
        rows = []
        names = reference_names(sw)
        for i, (case, fut) in enumerate(zip(cases, futures)):
            row = done.get(fut.key) or {"metric": math.nan, "cpu_time_s": math.nan,
                                        "status": f"error: {fut.exception()!r}"}
            rows.append({"case": case_name(i), **case, **row, "reference": names[i]})
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    write_summary(sw, rows, summary.parent)
    return rows


def _check_address(scheduler) -> None:
    """A scheduler's address as Dask parses it (host and port, a scheme it knows), checked
    before anything is made: Dask's ValueError ('missing port number', 'unknown address
    scheme') was a traceback."""
    from distributed.comm.addressing import get_address_host_port
    try:
        get_address_host_port(scheduler)
    except (ValueError, TypeError) as exc:
        raise SweepError(f"--scheduler {scheduler}: not the address of a Dask scheduler, such as tcp://HOST:8786 "
                         f"({' '.join(str(exc).split())})") from None


def check_outputs(sw: Sweep, folder: Path, option: str, emitting: bool) -> None:
    """Every file the sweep writes in `folder` (`emitting`: the job array's namelists and
    script; else the results and the summary) checked before any is written, as every pymr
    output is (check_output): none may be the sweep file, the base scene or a file a case's
    scene reads (an emitted case0000.nml overwrote the base scene of that name)."""
    refs = references(sw) if sw.metric.startswith("deviation:") else []
    tasks = [(case_name(i), {**sw.fixed, **case}) for i, case in enumerate(sw.cases)]
    tasks += [(reference_name(k), over) for k, (over, _) in enumerate(refs)]
    shared = (("cases.csv", "sweep.slurm") if emitting else ("summary.csv",)) + ("summary.previous.csv",)
    files = [(f"{name}{suffix}", over) for name, over in tasks for suffix in ((".nml", ".csv") if emitting else (".csv",))]
    files += [(name, sw.fixed) for name in shared]
    for k, (name, over) in enumerate(files):
        # a file that is not there is no input (and the folder is checked with the last): a
        # kernel check of each case's names took 0.65 ms each
        if k == len(files) - 1 or os.path.lexists(folder / name):
            check_output(folder / name, "folder", option=option, inputs=[sw.path], scene=sw.scene, overrides=over)


def make_folder(folder: Path, what: str) -> None:
    """`folder` made unless it is there, in a folder that must be there (as for every pymr
    output: a mistyped path made folders wherever it pointed); a file in its place, or a
    folder that cannot be made, is a SweepError naming `what` it is for."""
    if _is_dir(folder):
        return
    try:
        _folder_of(os.fspath(folder), what, beside=False)
    except OutputError as exc:
        raise SweepError(str(exc)) from None
    try:
        folder.mkdir(exist_ok=True)
    except OSError as exc:
        raise SweepError(f"{folder}: cannot make the {what} folder ({exc.strerror or exc})") from None


def retire_summary(folder: Path) -> None:
    """An earlier summary.csv in `folder` renamed summary.previous.csv before a sweep replaces
    the case files it sums up: a sweep killed on its way left the old summary beside new
    results, read as theirs. The new summary is written when every case has run (or been
    collected)."""
    old = folder / "summary.csv"
    if not old.exists():
        return
    try:
        os.replace(old, folder / "summary.previous.csv")
        sync_to_disk(folder)
    except OSError as exc:
        raise SweepError(f"{old}: cannot rename the earlier summary to summary.previous.csv before the cases "
                         f"replace its results ({exc.strerror or exc})") from None


def write_summary(sw: Sweep, rows: list[dict], folder: Path | None = None) -> Path:
    """folder/summary.csv, written whole (an earlier summary stays until the new one is complete);
    a sweep without a metric has no metric column (it held nan in every row)."""
    fields = ["case", *sw.grid, *(["metric"] if sw.metric else []),
              *(["reference"] if sw.metric.startswith("deviation:") else []), "cpu_time_s", "status"]
    fh = io.StringIO(newline="")
    w = csv.DictWriter(fh, fieldnames=fields, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow(r)
    return write_file((folder or sw.output) / "summary.csv", fh.getvalue(), "sweep's summary")


# ------------------------------------------------------------------------ SLURM

def namelist_text(base: Path, overrides: dict, name: str) -> str:
    """The namelist `name` of a job array task: the base scene with the overrides applied
    and every default filled in (the kernel's resolved scene), the files it names made
    absolute, and no &output file (mrsim gets -o)."""
    scene = Scene(base, {**overrides, "output.file": ""})
    return f"! {name}: {base.name} with {overrides}\n" + scene.resolved(absolute_paths=True)


def case_namelist(base: Path, overrides: dict, dest: Path) -> None:
    """Write the namelist of a job array task (namelist_text) to dest."""
    write_file(dest, namelist_text(base, overrides, dest.name), "case namelist")


def cases_text(sw: Sweep) -> str:
    """The sweep's cases.csv: each case's name and parameters."""
    fh = io.StringIO(newline="")
    w = csv.DictWriter(fh, fieldnames=["case", *sw.grid])
    w.writeheader()
    for i, case in enumerate(sw.cases):
        w.writerow({"case": case_name(i), **case})
    return fh.getvalue()


def emit_slurm(sw: Sweep, folder: str | os.PathLike, time_limit: str = "01:00:00") -> Path:
    """Case namelists and a SLURM job-array script running mrsim per case, in `folder`; with
    the deviation metric its reference runs too, as tasks after the cases' (referenceNNNN).
    The script names the mrsim of this installation by its absolute path (a compute node
    need not have it on its PATH); the environment variable PYMR_MRSIM overrides it."""
    from ._locate import mrsim_path
    exe = mrsim_path() or "mrsim"
    folder = Path(folder)
    make_folder(folder, "--emit-slurm")
    check_outputs(sw, folder, "--emit-slurm", emitting=True)
    retire_summary(folder)
    cases = sw.cases
    for i, case in enumerate(cases):
        case_namelist(sw.scene, {**sw.fixed, **case}, folder / f"{case_name(i)}.nml")
    refs = references(sw) if sw.metric.startswith("deviation:") else []
    for k, (over, _) in enumerate(refs):
        case_namelist(sw.scene, over, folder / f"{reference_name(k)}.nml")
    write_file(folder / "cases.csv", cases_text(sw), "list of cases")
    script = write_file(folder / "sweep.slurm", f"""#!/bin/bash
# SLURM job array for the sweep {sw.path.name}: one task per case namelist (caseNNNN),
# then one per reference run of the deviation metric (referenceNNNN, {len(refs)} here).
# Submit from this folder: sbatch sweep.slurm   (results: caseNNNN.csv and .json here)
#SBATCH --job-name=pymr-sweep
#SBATCH --array=0-{len(cases) + len(refs) - 1}
#SBATCH --ntasks=1
#SBATCH --cpus-per-task=1
#SBATCH --time={time_limit}
#SBATCH --output=slurm-%A_%a.out
# Then collect the summary: pymr sweep {sw.path} --collect {folder}
set -euo pipefail
# one CPU per task: no BLAS threads beside it
export {' '.join(f'{name}=1' for name in BLAS_THREADS)}
cd "${{SLURM_SUBMIT_DIR:-$(dirname "$0")}}"
task="${{SLURM_ARRAY_TASK_ID}}"
if [ "$task" -lt {len(cases)} ]; then
  case=$(printf 'case%04d' "$task")
else
  case=$(printf 'reference%04d' "$((task - {len(cases)}))")
fi
MRSIM="${{PYMR_MRSIM:-{exe}}}"
"$MRSIM" "$case.nml" -o "$case.csv" --quiet
""", "SLURM script")
    script.chmod(0o755)
    return script


def main(toml: str, scheduler: str | None = None, workers: int = 2, emit: str | None = None,
         collect_from: str | None = None) -> int:
    """``pymr sweep``: exit 0 when every case ran and gave its metric; 2 when a case failed,
    or (--collect) has not run or not finished: the summary lists every case either way.
    An option given empty (an unset shell variable) is refused, not taken as left out."""
    for option, value, left_out in (("--emit-slurm", emit, "to run the cases here"),
                                    ("--collect", collect_from, "to run the cases here"),
                                    ("--scheduler", scheduler, "for a LocalCluster on this machine")):
        if value is not None and not value.strip():
            raise SweepError(f"{option}: an empty {'address' if option == '--scheduler' else 'folder name'} "
                             f"(leave {option} out {left_out})")
    if emit is not None and collect_from is not None:
        raise SweepError("--emit-slurm and --collect: one at a time (emit the cases, run them, then collect)")
    sw = load_sweep(toml)
    if emit is not None:
        script = emit_slurm(sw, emit)
        print(f"wrote {len(sw.cases)} case namelists and {script} (submit with: cd {emit} && sbatch sweep.slurm; "
              f"then: pymr sweep {toml} --collect {emit})")
        return 0
    t0 = time.time()
    if collect_from is not None:
        rows = collect(sw, collect_from)
        where = Path(collect_from) / "summary.csv"
    else:
        rows = run_sweep(sw, scheduler=scheduler, workers=workers)
        where = sw.output / "summary.csv"
    not_run = [r["case"] for r in rows if r["status"].startswith(NOT_RUN)]
    failed = [r["case"] for r in rows if r["status"] != "ok" and r["case"] not in not_run]
    counts = f"{len(rows) - len(failed) - len(not_run)} ok, {len(failed)} failed"
    if collect_from is not None:
        counts += f", {len(not_run)} not run or not finished"
    print(f"{len(rows)} cases: {counts}, {time.time() - t0:.1f} s: {where}")
    for r in rows:
        params = ", ".join(f"{k}={r[k]}" for k in sw.grid)
        metric = f"  metric {r['metric']:.4g}" if sw.metric else ""        # no metric: no 'metric nan'
        print(f"  {r['case']}  {params}{metric}  cpu {r['cpu_time_s']:.3f} s  {r['status'][:90]}")
    if failed or not_run:
        parts = [f"{len(failed)} failed ({', '.join(failed)})"] if failed else []
        if not_run:
            parts.append(f"{len(not_run)} not run or not finished ({', '.join(not_run)})")
        print(f"pymr: error: of {len(rows)} cases, {' and '.join(parts)}: see {where}{first_failure(rows, failed)}",
              file=sys.stderr)
        return 2
    return 0


def first_failure(rows: list[dict], failed: list[str]) -> str:
    """'; case0000: CAUSE', the first failed case's error for the one line that ends a failed
    sweep ('' when none failed): the case listing cuts each status at 90 characters, before
    the cause of a long kernel message (a max_bytes refusal named the scene and the --set)."""
    row = next((r for r in rows if r["case"] in failed), None)
    if row is None:
        return ""
    cause = " ".join(row["status"].split()).removeprefix("error: ").removeprefix("failed: ")
    return f"; {row['case']}: {cause}"
