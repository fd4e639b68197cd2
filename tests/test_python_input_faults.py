"""Faults a fuzzing campaign found in the Python side's handling of bad input: each one is now
pymr's one-line refusal (the API: a pymr exception naming the file or the argument; the
CLI: ``pymr: error: ...`` and exit 1), never a hang, a traceback, a silent NaN or a file of
the user's destroyed."""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import tempfile
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import pymr
import pymr.export
import pymr.plot

ROOT = Path(__file__).resolve().parent.parent
PENDULUM = ROOT / "input" / "pendulum.nml"
TANK = ROOT / "input" / "tank_gun_turret.nml"


def cli(*args, cwd=None, timeout=120):
    """`pymr ARGS` in a fresh process (the timeout only keeps a hang from stalling the suite)."""
    # outside the checkout by default: there `python -m pymr` would find the source folder
    return subprocess.run([sys.executable, "-m", "pymr", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd or tempfile.gettempdir(), timeout=timeout, stdin=subprocess.DEVNULL)


def refused(r, text: str) -> None:
    """A CLI refusal: exit 1, one line `pymr: error: ...` holding `text`, no traceback."""
    assert r.returncode == 1, (r.returncode, r.stdout, r.stderr)
    assert r.stderr.startswith("pymr: error: ") and r.stderr.count("\n") == 1, r.stderr
    assert text in r.stderr, r.stderr


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """A short pendulum run as CSV (pend.csv, pend.json) and as HDF5 (pendh.h5, pendh.json)."""
    folder = tmp_path_factory.mktemp("runs")
    pymr.run(PENDULUM, folder / "pend.csv", overrides={"scene.t_end": 0.2})
    pymr.run(PENDULUM, folder / "pendh.h5", overrides={"scene.t_end": 0.2, "output.format": "hdf5"})
    return folder


# ------------------------------------------------------------------ hangs

def test_a_truncated_hdf5_file_is_refused_at_once(runs, tmp_path):
    """The fallback open in single-writer/multiple-reader mode sat in HDF5's retry loop for
    minutes on a truncated file; it is now tried only for a file still marked open for
    writing (a killed run's), and a truncated file is the first open's ResultsError."""
    whole = (runs / "pendh.h5").read_bytes()
    cut = tmp_path / "t.h5"
    cut.write_bytes(whole[:len(whole) // 2])
    with pytest.raises(pymr.ResultsError, match=r"t\.h5: not a pymr HDF5 results file \(.*truncated file"):
        pymr.load_results(cut)
    refused(cli("plot", cut, "-o", tmp_path / "t.png"), "t.h5: not a pymr HDF5 results file (")


def test_a_damaged_hdf5_superblock_is_a_results_error(runs, tmp_path):
    """h5py raised RuntimeError (not OSError) for a superblock it cannot decode."""
    bad = tmp_path / "s.h5"
    bad.write_bytes((runs / "pendh.h5").read_bytes()[:8] + b"\xff" * 64)
    with pytest.raises(pymr.ResultsError, match=r"s\.h5: not a pymr HDF5 results file \("):
        pymr.load_results(bad)


@pytest.mark.parametrize("make, fault", [
    (lambda p: os.mkfifo(p), "cannot read: it is not a regular file (a FIFO, a socket or a device)"),
    (lambda p: p.mkdir(), "cannot read: it is a directory"),
], ids=["fifo", "folder"])
def test_a_sweep_file_that_is_not_a_regular_file_is_refused(tmp_path, make, fault):
    """pymr sweep FIFO.toml blocked for ever in the read; it is refused as the kernel's scene
    reader refuses a FIFO, and a folder is named as one (it was 'Errno 21')."""
    toml = tmp_path / "s.toml"
    make(toml)
    refused(cli("sweep", toml, "--emit-slurm", tmp_path / "out"), f"{toml}: {fault}")
    assert not (tmp_path / "out").exists()


# ------------------------------------------------------------------ data loss

@pytest.mark.parametrize("index", ["{not json", '{"files": "all", "collection": 5}', None],
                         ids=["damaged", "wrong_types", "valid"])
def test_export_never_removes_a_file_its_index_does_not_record(runs, tmp_path, index):
    """pymr export --vtk DIR replaced DIR whole when it held any pymr_export.json: a damaged
    one (or a user's file beside a valid one) lost the user's files. Now only the files a
    valid index records are pymr's to remove; anything else is refused, every file kept."""
    out = tmp_path / "vtk"
    pymr.export.export_vtk(runs / "pend.csv", out, frames=2)
    if index is not None:
        (out / "pymr_export.json").write_text(index)
    (out / "notes.txt").write_text("keep me")
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    fault = "is damaged" if index is not None else "holds files the earlier export did not write (notes.txt)"
    refused(cli("export", runs / "pend.csv", "--vtk", out, "--frames", "2"), f"--vtk {out}: ")
    with pytest.raises(pymr.OutputError, match=f"--vtk {out}: .*{fault.replace('(', '.').replace(')', '.')}"):
        pymr.export.export_vtk(runs / "pend.csv", out, frames=2)
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["vtk"]


def test_export_replaces_an_earlier_export_file_by_recorded_file(runs, tmp_path):
    """An earlier export is still replaced: its recorded files go, the new ones come."""
    out = tmp_path / "vtk"
    pymr.export.export_vtk(runs / "pend.csv", out, frames=3)
    pymr.export.export_vtk(runs / "pend.csv", out, frames=2)
    index = json.loads((out / "pymr_export.json").read_text())
    assert sorted(p.name for p in out.iterdir()) == sorted([*index["files"], index["collection"], "pymr_export.json"])
    assert len(index["files"]) == 2 and sorted(p.name for p in tmp_path.iterdir()) == ["vtk"]


# ------------------------------------------------------------------ reading results

def _h5_copy(runs, tmp_path, change) -> Path:
    """A copy of the HDF5 run, changed by `change(h5py.File)`."""
    import h5py
    path = tmp_path / "h.h5"
    path.write_bytes((runs / "pendh.h5").read_bytes())
    with h5py.File(path, "r+") as f:
        change(f)
    return path


def _h5py():
    import h5py
    return h5py


def _set_value(f, value):
    data = f["markers"][()]
    data[3, 1] = value
    f["markers"][...] = data


@pytest.mark.parametrize("change, message", [
    (lambda f: f.attrs.modify("statistics", "{not json"), r"h\.h5 \(its attribute 'statistics'\): not a pymr "
                                                          r"statistics file \(Expecting property name"),
    (lambda f: f.attrs.modify("statistics", "[1, 2]"), r"h\.h5 \(its attribute 'statistics'\): not a pymr statistics "
                                                       r"file \(not a JSON object\)$"),
    (lambda f: _set_value(f, np.nan), r"h\.h5: row 4, column tip\.y: nan is not a finite number"),
    (lambda f: _set_value(f, np.inf), r"h\.h5: row 4, column tip\.y: inf is not a finite number"),
    (lambda f: f.attrs.__delitem__("column_order"), r"h\.h5: not a pymr HDF5 results file \(no attribute "
                                                    r"'column_order'\)$"),
    (lambda f: f.__setitem__("extra", _h5py().SoftLink("/nowhere")), r"h\.h5: not a pymr HDF5 results file "
                                                                    r"\('extra' is a link to nothing, not a dataset"),
    (lambda f: f.create_group("extra"), r"h\.h5: not a pymr HDF5 results file \('extra' is a group, not a dataset"),
], ids=["statistics_not_json", "statistics_not_object", "nan", "inf", "no_column_order", "dangling_link", "group"])
def test_a_damaged_hdf5_results_file_is_one_results_error(runs, tmp_path, change, message):
    """The statistics attribute gave JSONDecodeError or AttributeError tracebacks, NaN and
    Inf were loaded silently (and crashed pymr plot): each is now refused as the CSV's are."""
    bad = _h5_copy(runs, tmp_path, change)
    with pytest.raises(pymr.ResultsError, match=message):
        pymr.load_results(bad)
    refused(cli("plot", bad, "-o", tmp_path / "h.png"), f"{bad}")


def _sidecar(runs, tmp_path, change, csv: str = "pend.csv") -> Path:
    """A copy of the CSV run whose OUT.json `change(stats)` has changed."""
    out = tmp_path / "r.csv"
    out.write_text((runs / csv).read_text())
    stats = json.loads((runs / csv).with_suffix(".json").read_text())
    change(stats)
    out.with_suffix(".json").write_text(json.dumps(stats))
    return out


def _put(path: str, value):
    def change(stats):
        *keys, last = path.split(".")
        target = stats
        for key in keys:
            target = target[key]
        target[last] = value
    return change


@pytest.mark.parametrize("change, message", [
    (_put("columns.group", 5), r'"columns" "group" is not a list of texts, one per column'),
    (lambda s: s["columns"].pop("unit"), r'"columns" has no list "unit"'),
    (lambda s: s["columns"]["owner"].__setitem__(1, None), r'"columns" "owner" is not a list of texts'),
    (lambda s: s["columns"].__setitem__("quantity", s["columns"]["quantity"][:3]),
     r'"columns" "quantity" has 3 entries for the 9 columns of the results'),
    (_put("columns", [1, 2]), r'"columns" is not an object of the lists name, group, owner, quantity, unit'),
    (_put("scene", 5), r'"scene" is int 5, not a text \(the scene file\)'),
    (_put("resolved_scene", 42), r'"resolved_scene" is int 42, not a text'),
    (_put("cpu_time_s", "fast"), r'"cpu_time_s" is str \'fast\', not a number of seconds'),
    (_put("rows", 500), r"r\.csv: 21 rows of the 500 the run wrote \(the file was cut\)"),
    (_put("rows", 3), r"r\.csv: 21 rows of the 3 the run wrote \(the file was changed\)"),
], ids=["group_int", "no_unit", "owner_null", "short_list", "not_object", "scene_int", "resolved_int", "cpu_str",
        "cut", "changed"])
def test_a_statistics_file_that_does_not_fit_its_results_is_refused(runs, tmp_path, change, message):
    """Malformed column metadata or fields of the wrong type gave TypeError, KeyError or
    AttributeError tracebacks where they were used (plot, view, export, animate, sweep
    --collect); a CSV shorter than its complete run's row count loaded silently. Each is
    refused when the file is read, naming the JSON (or the CSV) and the fault."""
    bad = _sidecar(runs, tmp_path, change)
    with pytest.raises(pymr.ResultsError, match=message):
        pymr.load_results(bad)
    for command in (["plot", bad, "-o", tmp_path / "p.png"], ["view", bad, "-o", tmp_path / "v.html"]):
        refused(cli(*command), str(bad.with_suffix(".json") if "rows" not in message else bad))


def test_a_failed_runs_statistics_do_not_count_the_rows(runs, tmp_path):
    """Only a complete run's row count is compared with the file's: a failed run's
    statistics describe its partial file (status 'failed'), and those rows load."""
    res = pymr.load_results(_sidecar(runs, tmp_path, lambda s: s.update(status="failed", rows=500)))
    assert res.data.shape == (21, 9) and res.stats["rows"] == 500


@pytest.mark.parametrize("make, message", [
    (lambda p: p.mkdir(), "is a folder, not a result file"),
    (lambda p: os.mkfifo(p), "not a regular file (a FIFO, a device or a socket), not a result file"),
], ids=["folder", "fifo"])
def test_a_results_path_that_is_no_file_says_what_it_is(tmp_path, make, message):
    """A folder, a FIFO or /dev/null was 'no such result file'."""
    path = tmp_path / "r.csv"
    make(path)
    with pytest.raises(pymr.ResultsError, match=f"^{path}: {message.replace('(', '.').replace(')', '.')}$"):
        pymr.load_results(path)
    with pytest.raises(pymr.ResultsError, match=r"^/dev/null: not a regular file"):
        pymr.load_results("/dev/null")
    refused(cli("plot", path, "-o", tmp_path / "p.png"), f"{path}: {message}")


@pytest.mark.parametrize("edit, message", [
    (lambda lines: lines[:8] + [lines[8].rsplit(",", 1)[0]] + lines[9:],
     r"r\.csv: not a pymr result file \(line 9 holds 8 values, the header names 9 columns\)$"),
    (lambda lines: lines[:6] + [",".join([lines[6].split(",")[0], "abc", *lines[6].split(",")[2:]])] + lines[7:],
     r"r\.csv: not a pymr result file \(line 7, column pivot.q: 'abc' is not a number\)$"),
    (lambda lines: ["\ufeff" + lines[0]] + lines[1:],
     r"r\.csv: not a pymr result file \(it starts with a byte order mark, U\+FEFF"),
], ids=["short_row", "text", "bom"])
def test_a_damaged_csv_is_named_in_pymrs_words(runs, tmp_path, edit, message):
    """numpy's wording leaked into the message ('the number of columns changed from 9 to 8 at
    row 5; use `usecols`', 'could not convert string 't' to float64')."""
    lines = (runs / "pend.csv").read_text().splitlines()
    bad = tmp_path / "r.csv"
    bad.write_text("\n".join(edit(lines)) + "\n")
    with pytest.raises(pymr.ResultsError, match=message):
        pymr.load_results(bad)


# ------------------------------------------------------------------ pymr sweep

SWEEP = """scene = "{scene}"
output = "{output}"
metric = "final:pivot.q"
[grid]
"integrator.h_slow" = [1e-3, 2e-3]
[fixed]
"scene.t_end" = 0.05
"""


@pytest.mark.parametrize("scene, output, message", [
    ("pend\\u0000ulum.nml", "out", "scene: 'pend\\x00ulum.nml': a file name cannot hold a NUL character"),
    (str(PENDULUM), "o\\u0000ut", "output: 'o\\x00ut': a file name cannot hold a NUL character"),
    ("", "out", "scene: an empty file name"),
], ids=["scene_nul", "output_nul", "scene_empty"])
def test_a_sweep_file_name_with_nul_or_empty_is_refused(tmp_path, scene, output, message):
    """TOML's \\u0000 in scene or output gave a ValueError traceback (embedded null byte)."""
    toml = tmp_path / "s.toml"
    toml.write_text(SWEEP.format(scene=scene, output=output))
    refused(cli("sweep", toml, "--emit-slurm", tmp_path / "slurm", cwd=tmp_path), f"{toml}: {message}")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


@pytest.mark.parametrize("options, message", [
    (["--scheduler", "not an address"], "--scheduler not an address: not the address of a Dask scheduler"),
    (["--scheduler", "ftp://x"], "--scheduler ftp://x: not the address of a Dask scheduler"),
    (["--scheduler", ""], "--scheduler: an empty address (leave --scheduler out for a LocalCluster"),
    (["--emit-slurm", ""], "--emit-slurm: an empty folder name (leave --emit-slurm out to run the cases here)"),
    (["--collect", ""], "--collect: an empty folder name"),
    (["--emit-slurm", "a", "--collect", "a"], "--emit-slurm and --collect: one at a time"),
], ids=["scheduler_garbage", "scheduler_ftp", "scheduler_empty", "emit_empty", "collect_empty", "emit_and_collect"])
def test_sweep_options_that_are_empty_or_no_address_are_refused(tmp_path, options, message):
    """--scheduler 'not an address' gave Dask's ValueError traceback; an empty --emit-slurm
    (or --collect, --scheduler) was taken as not given and the whole sweep ran."""
    toml = tmp_path / "s.toml"
    toml.write_text(SWEEP.format(scene=PENDULUM, output="out"))
    refused(cli("sweep", toml, *options, cwd=tmp_path), message)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.toml"]


def test_collect_lists_a_case_whose_statistics_are_damaged_as_failed(tmp_path):
    """A case JSON whose cpu_time_s is not a number gave a ValueError traceback in --collect;
    the case is now listed as failed (its results cannot be read) and the others collected."""
    from pymr.sweep import emit_slurm, load_sweep
    toml = tmp_path / "s.toml"
    toml.write_text(SWEEP.format(scene=PENDULUM, output="out"))
    folder = tmp_path / "slurm"
    emit_slurm(load_sweep(toml), folder)
    for i in range(2):
        pymr.run(folder / f"case{i:04d}.nml", folder / f"case{i:04d}.csv")
    stats = json.loads((folder / "case0001.json").read_text())
    (folder / "case0001.json").write_text(json.dumps({**stats, "cpu_time_s": "fast"}))
    r = cli("sweep", toml, "--collect", folder)
    assert r.returncode == 2 and "Traceback" not in r.stderr and r.stderr.count("\n") == 1, r.stderr
    assert "of 2 cases, 1 failed (case0001)" in r.stderr
    summary = (folder / "summary.csv").read_text().splitlines()
    assert summary[1].endswith(",ok") and summary[2].startswith("case0001,0.002,nan,nan,\"failed: incomplete results: ")
    assert "cpu_time_s\"\" is str 'fast', not a number of seconds" in summary[2]


# ------------------------------------------------------------------ Results in Python

@pytest.mark.parametrize("call, message", [
    (lambda r: r["nope"], r"^no column 'nope'; columns: t, pivot.q, "),
    (lambda r: r.marker("nope"), r"^no marker 'nope'; markers: tip$"),
    (lambda r: r.marker(""), r"^no marker ''; markers: tip$"),
    (lambda r: r.joint("nope"), r"^no joint 'nope'; joints: pivot$"),
    (lambda r: r.joint_columns("x"), r"^no joint 'x'; joints: pivot$"),
    (lambda r: r.modal("nope"), r"^no flexible body 'nope'; flexible bodies: \(none\)$"),
    (lambda r: r.reaction("pivot"), r"^no reactions of joint 'pivot' \(&output quantities 'reactions'; joints with "
                                    r"reactions: \(none\)\)$"),
    (lambda r: r.unit("nope"), r"^no column 'nope'; columns: t, "),
], ids=["getitem", "marker", "marker_empty", "joint", "joint_columns", "modal", "reaction", "unit"])
def test_an_unknown_name_is_a_results_key_error(runs, call, message):
    """An unknown name raised a bare KeyError from inside the package: now pymr's own
    ResultsKeyError, a ResultsError that is also a KeyError (the documented promise), whose
    message is the text itself (KeyError's str quoted it)."""
    res = pymr.load_results(runs / "pend.csv")
    with pytest.raises(pymr.ResultsKeyError, match=message) as info:
        call(res)
    assert isinstance(info.value, KeyError) and isinstance(info.value, pymr.ResultsError)


@pytest.mark.parametrize("call, argument", [
    (lambda r: r.joint(None), "name"), (lambda r: r.modal(None), "body"), (lambda r: r.marker(3), "name"),
    (lambda r: r.reaction(None), "joint"), (lambda r: r[0], "name"), (lambda r: r[1:3], "name"),
    (lambda r: r[["t"]], "name"), (lambda r: r.unit(None), "name"), (lambda r: r.modal_columns(None), "body"),
    (lambda r: ["t"] in r, "name"), (lambda r: None in r, "name"),
], ids=["joint_none", "modal_none", "marker_int", "reaction_none", "getitem_int", "getitem_slice", "getitem_list",
        "unit_none", "modal_columns_none", "contains_list", "contains_none"])
def test_a_name_that_is_not_text_is_refused(runs, call, argument):
    """res.joint(None) and res.modal(None) returned every joint's (body's) columns; an int,
    a slice or a list gave numpy's or a KeyError. Each is an ArgumentTypeError naming the
    argument."""
    res = pymr.load_results(runs / "pend.csv")
    with pytest.raises(pymr.ArgumentTypeError, match=f"^{argument}: a name \\(str\\), got "):
        call(res)


@pytest.mark.parametrize("kwargs, error, message", [
    (dict(columns=["t"], data=np.zeros(3)), pymr.ResultsError, r"^data: an array \(rows, 1\) for the 1 columns, got "
                                                               r"shape \(3,\)$"),
    (dict(columns=["t", "x"], data=np.zeros((3, 5))), pymr.ResultsError, r"^data: an array \(rows, 2\)"),
    (dict(columns=["x"], data=np.zeros((3, 1))), pymr.ResultsError, r"^columns: the first column is the time 't'"),
    (dict(columns="t", data=np.zeros((3, 1))), pymr.ArgumentTypeError, r"^columns: a list of column names \(str\)"),
    (dict(columns=["t"], data=[["a"]]), pymr.ArgumentTypeError, r"^data: an array of real numbers"),
    (dict(columns=["t"], data=np.zeros((3, 1)), stats=[1]), pymr.ArgumentTypeError, r"^stats: a dict, got list"),
    (dict(columns=["t"], data=np.zeros((3, 1)), meta="x"), pymr.ArgumentTypeError, r"^meta: a dict, got str"),
], ids=["1d", "shape", "no_t", "columns_str", "data_text", "stats_list", "meta_str"])
def test_results_made_by_hand_are_checked(kwargs, error, message):
    """Results(...) with a wrong shape or type failed later with IndexError, KeyError,
    TypeError or AttributeError in whatever used it."""
    with pytest.raises(error, match=message):
        pymr.Results(**kwargs)
    good = pymr.Results(columns=["t", "x"], data=[[0.0, 1.0], [1.0, 2.0]])
    assert good.data.dtype == float and np.array_equal(good["x"], [1.0, 2.0])


# ------------------------------------------------------------------ the API's arguments

def _built() -> pymr.Scene:
    scene = pymr.Scene()
    with scene.editing():
        scene.add("scene", title="p", t_end=0.05, gravity=[0.0, -9.81, 0.0])
        scene.add("integrator", method="single", h_slow=1e-3)
        scene.add("body", name="ground", kind="ground")
        scene.add("body", name="bob", kind="rigid", mass=1.0, com=[0.0, -1.0, 0.0], inertia=[1e-4] * 3 + [0.0] * 3)
        scene.add("joint", name="pivot", kind="revolute", parent="ground", child="bob", axis=[0, 0, 1], q0=0.1)
    return scene


def test_run_keeps_a_scene_built_inline_alive_for_the_call():
    """pymr.run(build()) dropped the last reference to the Scene as it took its path, and its
    private folder was removed before the kernel read the file ('file not found')."""
    res = pymr.run(_built())
    assert res.t[-1] == pytest.approx(0.05) and res.joints == ["pivot"]


@pytest.mark.parametrize("call, error, message", [
    (lambda d: pymr.run(PENDULUM, output=str(d / "r\0s.csv")), pymr.OutputError, r"^output: '.*r\\x00s.csv': a file path "
                                                                                  r"cannot hold a NUL character$"),
    (lambda d: pymr.run(str(PENDULUM) + "\0x"), pymr.SceneError, r"^scene: .*: a file path cannot hold a NUL"),
    (lambda d: pymr.run(PENDULUM, output=d / "r.csv", restart="c\0k"), pymr.SceneError, r"^restart: 'c\\x00k': "),
    (lambda d: pymr.load_results("r\0.csv"), pymr.ResultsError, r"^csv_path: 'r\\x00.csv': a file path cannot hold"),
    (lambda d: pymr.Scene("p\0.nml"), pymr.SceneError, r"^path: 'p\\x00.nml': a file path cannot hold"),
    (lambda d: pymr.Scene(PENDULUM).write(d / "s\0.nml"), pymr.OutputError, r"^path: '.*s\\x00.nml': a file path"),
    (lambda d: pymr.write_modal_file(PENDULUM, "bob", "m\0.modal"), pymr.OutputError, r"^path: 'm\\x00.modal': "),
    # a name: 'gun\0x' was 'gun', whose modes were written (found by fuzzing)
    (lambda d: pymr.write_modal_file(TANK, "gun\0x", d / "g.modal"), pymr.SceneError,
     r"^body: 'gun\\x00x': a name cannot hold a NUL character$"),
    (lambda d: pymr.run(PENDULUM, d / "r.csv", ["scene.t_end=0.05\0", "scene.t_end=0.01"]), pymr.SceneError,
     r"^--set 'scene.t_end=0.05\\x00': a NUL character in an override$"),
], ids=["run_output", "run_scene", "restart", "load_results", "scene", "scene_write", "write_modal_file", "body",
        "override"])
def test_a_path_with_a_nul_character_is_refused_naming_the_argument(tmp_path, call, error, message):
    """A NUL ended the kernel's text early (another file read or written) or gave Python's
    ValueError: refused before anything is read or written."""
    with pytest.raises(error, match=message):
        call(tmp_path)
    assert list(tmp_path.iterdir()) == []


def test_a_scene_whose_file_was_deleted_is_a_scene_error_on_add(tmp_path):
    """Scene(path).add(...) after the file was deleted raised FileNotFoundError."""
    path = tmp_path / "p.nml"
    path.write_text(PENDULUM.read_text())
    scene = pymr.Scene(path)
    path.unlink()
    with pytest.raises(pymr.SceneError, match=f"^{path}: cannot read the scene file \\(No such file or directory\\)$"):
        scene.add("marker", name="m2", body="bob")


def test_scene_write_to_a_folder_that_refuses_the_write_is_an_output_error(tmp_path, monkeypatch):
    """On a read-only folder the failed write's clean-up (unlinking its temporary file) raised
    the bare OSError in place of the OutputError; the folder is simulated here (the tests
    may run as root, whom a read-only mode does not stop)."""
    import errno
    import pathlib

    def refuse(*args, **kwargs):
        raise OSError(errno.EROFS, "Read-only file system")

    monkeypatch.setattr(os, "fsync", refuse)
    monkeypatch.setattr(pathlib.Path, "unlink", refuse)
    with pytest.raises(pymr.OutputError, match=r"s\.nml: cannot write the resolved scene \(Read-only file system\)$"):
        pymr.Scene(PENDULUM).write(tmp_path / "s.nml")


@pytest.mark.parametrize("call", [
    lambda: pymr.model_accelerations(PENDULUM, np.zeros(0), np.zeros((0, 1)), np.zeros((0, 1))),
    lambda: pymr.model_energy(PENDULUM, np.zeros((0, 1)), np.zeros((0, 1))),
], ids=["model_accelerations", "model_energy"])
def test_zero_states_are_refused(call):
    """States of shape (0, n) reached f2py, whose ValueError was the answer."""
    with pytest.raises(pymr.SceneError, match=r"^q: no states \(shape \(0, 1\)\): give at least one"):
        call()


@pytest.mark.parametrize("call", [
    lambda: pymr.model_terms(PENDULUM, np.zeros(0), np.zeros(0)),
    lambda: pymr.model_energy(PENDULUM, np.zeros(0), np.zeros(0)),
    lambda: pymr.modes(PENDULUM, np.zeros(0), np.zeros(0)),
    lambda: pymr.force_response(PENDULUM, np.zeros(0), np.zeros(0)),
    lambda: pymr.model_accelerations(PENDULUM, 0.0, np.zeros((1, 0)), np.zeros((1, 0))),
], ids=["model_terms", "model_energy", "modes", "force_response", "model_accelerations"])
def test_a_state_of_no_coordinates_is_refused(call):
    """A state of shape (0,) reached f2py, whose ValueError ("unexpected array size") was the
    answer; a state of the wrong non-zero length was already a SceneError."""
    with pytest.raises(pymr.SceneError, match=r"^q: a state of no coordinates \(shape \((0,|1, 0)\)\)"):
        call()


def test_energy_of_a_state_beyond_the_model_s_terms_is_an_error():
    """model_energy at q = 1e300 returned NaN and inf with no error, where model_terms and
    modes at that state raise SolverError."""
    with pytest.raises(pymr.SolverError, match=r"^state 2: the energy is not finite \(kinetic .*\): the state "
                                               r"overflows the model's terms$"):
        pymr.model_energy(PENDULUM, np.array([[0.1], [1e300]]), np.array([[0.0], [1e300]]))
    ke, pe = pymr.model_energy(PENDULUM, np.array([0.1]), np.array([2.0]))
    assert np.isfinite(ke).all() and np.isfinite(pe).all()


def test_none_is_no_time():
    """t=None became NaN in numpy and was refused as 'nan is not a finite time'."""
    with pytest.raises(pymr.ArgumentTypeError, match=r"^t: a time or an array of times \(s\), got None$"):
        pymr.model_accelerations(PENDULUM, None, [0.1], [0.0])


@pytest.mark.parametrize("method, args", [
    ("coordinate_names", ()), ("marker_names", ()), ("marker", ("tip", 0.0, [0.1], [0.0])), ("marker_body", ("tip",)),
    ("rhs", (0.0, [0.1, 0.0])), ("frames", (0.0, [0.1], [0.0], 2)),
])
def test_a_closed_model_refuses_every_call(method, args):
    """After close(), coordinate_names and marker_names returned empty values and marker
    said the marker was not there."""
    model = pymr.Model(PENDULUM)
    assert model.marker_names() == ["tip"]
    model.close()
    with pytest.raises(pymr.SceneError, match=r"pendulum.nml: this pymr.Model is closed \(make a new one\)$"):
        getattr(model, method)(*args)


def test_write_modal_file_refuses_an_empty_path():
    """An empty path reached the kernel, which said ': cannot move the new file into place'."""
    with pytest.raises(pymr.OutputError, match=r"^path: an empty file name for the modal file$"):
        pymr.write_modal_file(PENDULUM, "bob", "")


# ------------------------------------------------------------------ empty values

@pytest.mark.parametrize("overrides", [[""], ["scene.t_end=0.05", "  "], ""], ids=["list", "blank", "str"])
def test_an_empty_override_is_refused(tmp_path, overrides):
    """overrides=[''] (and pymr run --set '') was skipped: the run went on as if it had not
    been given. It is refused as mrsim refuses it."""
    with pytest.raises(pymr.SceneError, match=r"^--set needs GROUP.ITEM=VALUE \(got an empty one\)$"):
        pymr.run(PENDULUM, tmp_path / "r.csv", overrides=overrides)
    with pytest.raises(pymr.SceneError, match=r"^--set needs GROUP.ITEM=VALUE \(got an empty one\)$"):
        pymr.Scene(PENDULUM, overrides)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["run", "scene"])
def test_pymr_set_empty_is_refused(tmp_path, command):
    r = cli(command, PENDULUM, "--set", "scene.t_end=0.05", "--set", "", cwd=tmp_path)
    refused(r, "--set needs GROUP.ITEM=VALUE (got an empty one)")
    assert list(tmp_path.iterdir()) == []


def test_overrides_in_a_set_are_refused():
    """A set has no order, and the later of two overrides of one item wins."""
    with pytest.raises(pymr.ArgumentTypeError, match=r"^overrides: a mapping .* got set "):
        pymr.run(PENDULUM, overrides={"scene.t_end=0.05"})


# ------------------------------------------------------------------ plot_results

@pytest.mark.parametrize("kwargs, message", [
    (dict(runs=None), r"^runs: a results file's path, a pymr.Results or a list of them, got NoneType None$"),
    (dict(runs=["RUN", 5]), r"^runs\[1\]: a results file's path or a pymr.Results, got int 5$"),
    (dict(markers=5), r"^markers: a name or a list of names \(str\), got int 5$"),
    (dict(joints=5), r"^joints: a name or a list of names \(str\), got int 5$"),
    (dict(columns=5), r"^columns: a name or a list of names \(str\), got int 5$"),
    (dict(title=5), r"^title: a text \(str\), got int 5$"),
    (dict(labels=[None]), r"^labels\[0\]: a text \(str\), got NoneType None$"),
], ids=["runs_none", "runs_int", "markers_int", "joints_int", "columns_int", "title_int", "labels_none"])
def test_plot_results_refuses_arguments_of_the_wrong_type(runs, kwargs, message):
    """TypeErrors from inside plot (None, 5 where names go), or a figure drawn with a title or
    a label of the wrong type."""
    kwargs.setdefault("runs", [runs / "pend.csv"])
    kwargs["runs"] = [runs / "pend.csv" if r == "RUN" else r for r in kwargs["runs"]] \
        if isinstance(kwargs["runs"], list) else kwargs["runs"]
    with pytest.raises(pymr.ArgumentTypeError, match=message):
        pymr.plot.plot_results(**kwargs)


def test_plot_results_takes_one_run_and_one_name_whole(runs):
    """A str where a list of runs goes was read as its characters ('p: no such result file'),
    and joints='pivot' as the joints 'p', 'i', ...: one str is one run, one name, one label."""
    fig = pymr.plot.plot_results(str(runs / "pend.csv"), joints="pivot", markers="tip", labels="mine")
    titles = [ax.get_title() for ax in fig.axes]
    assert titles == ["tip.x", "tip.y", "tip.z", "tip.vx", "tip.vy", "tip.vz", "pivot.q"]
    assert [t.get_text() for t in fig.legends[0].get_texts()] == ["mine"]


@pytest.mark.parametrize("change, message", [
    (lambda r: r.data.__setitem__((3, 1), np.nan), r"pend\.csv: row 4, column pivot\.q: nan is not a finite number"),
    (lambda r: setattr(r, "data", r.data[:0]), r"pend\.csv: has no result rows$"),
], ids=["nan", "empty"])
def test_plot_results_refuses_results_without_rows_or_with_nan(runs, tmp_path, change, message):
    """A NaN crashed matplotlib's axis limits (ValueError); no rows, numpy's max of nothing."""
    res = pymr.load_results(runs / "pend.csv")
    change(res)
    with pytest.raises(pymr.plot.PlotError, match=message):
        pymr.plot.plot_results([res], tmp_path / "p.png")
    assert list(tmp_path.iterdir()) == []


# ------------------------------------------------------------------ animate and geometry

@pytest.mark.parametrize("kwargs, error, message", [
    (dict(exaggerate="2"), pymr.ArgumentTypeError, r"^exaggerate: a number, got str '2'$"),
    (dict(fps="2"), pymr.ArgumentTypeError, r"^fps: a whole number, got str '2'$"),
    (dict(frames="2"), pymr.ArgumentTypeError, r"^frames: a whole number, got str '2'$"),
    (dict(at="1"), pymr.ArgumentTypeError, r"^at: a time in seconds, got '1'$"),
    (dict(view=5), pymr.ArgumentTypeError, r"^view: a named view or 'ELEV,AZIM' \(str\), got int 5$"),
    (dict(orbit="yes"), pymr.ArgumentTypeError, r"^orbit: True or False, got str 'yes'$"),
    (dict(frames=1), pymr.PymrError, r"^frames: at least 2, got 1 \(one frame is a still: write a .png\)$"),
    (dict(exaggerate=-1.0), pymr.PymrError, r"^exaggerate: a scale of the deflections, a finite number from 0 "
                                            r"\(0 draws the bodies undeformed\), got -1.0$"),
    (dict(scene=""), pymr.PymrError, r"^scene: an empty file name \(leave it out for the scene the results name\)$"),
    (dict(scene=5), pymr.ArgumentTypeError, r"^scene: a file path \(str or os.PathLike\), got int 5$"),
], ids=["exaggerate_str", "fps_str", "frames_str", "at_str", "view_int", "orbit_str", "frames_1", "exaggerate_neg",
        "scene_empty", "scene_int"])
def test_animate_names_each_bad_option(runs, tmp_path, kwargs, error, message):
    """String numbers and wrong types were TypeErrors or AttributeErrors from inside; frames
    and exaggerate shared one message; scene='' was taken as not given."""
    from pymr.animate import animate
    with pytest.raises(error, match=message):
        animate(runs / "pend.csv", tmp_path / "a.png", **kwargs)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("kwargs, error, message", [
    (dict(exaggerate="big"), pymr.ArgumentTypeError, r"^exaggerate: a number, got str 'big'$"),
    (dict(scene=5), pymr.ArgumentTypeError, r"^scene: a file path \(str or os.PathLike\), got int 5$"),
    (dict(scene=""), pymr.PymrError, r"^scene: an empty file name"),
], ids=["exaggerate_str", "scene_int", "scene_empty"])
def test_motion_names_each_bad_argument(runs, kwargs, error, message):
    from pymr.geometry import motion
    with pytest.raises(error, match=message):
        motion(runs / "pend.csv", **kwargs)


@pytest.mark.parametrize("command", [["animate", "-o", "a.png"], ["view", "-o", "v.html"], ["export", "--vtk", "x"]])
def test_an_empty_scene_option_is_refused(runs, tmp_path, command):
    """pymr animate --scene '' drew with the results' own scene (exit 0)."""
    name, *rest = command
    refused(cli(name, runs / "pend.csv", "--scene", "", *rest, cwd=tmp_path), "scene: an empty file name")
    assert list(tmp_path.iterdir()) == []


SCALE_RULE = "exaggerate: a scale of the deflections, a finite number from 0 (0 draws the bodies undeformed), got "


@pytest.mark.parametrize("command", [["animate", "-o", "a.png"], ["view", "-o", "v.html"], ["export", "--vtk", "x"]])
@pytest.mark.parametrize("scale", ["-1", "nan", "inf"])
def test_every_drawing_command_has_one_rule_for_the_scale(runs, tmp_path, command, scale):
    """view and animate refused --exaggerate 0, which export and pymr.geometry.motion draw
    undeformed, and the three said a bad scale three ways."""
    name, *rest = command
    refused(cli(name, runs / "pend.csv", "--exaggerate", scale, *rest, cwd=tmp_path), SCALE_RULE + repr(float(scale)))
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("at", ["-0.5", "1e9"])
def test_a_still_outside_the_run_is_refused(runs, tmp_path, at):
    """--at before the first row or after the last drew the first or the last frame, exit 0."""
    t = pymr.load_results(runs / "pend.csv").t
    refused(cli("animate", runs / "pend.csv", "--at", at, "-o", tmp_path / "a.png"),
            f"at: {float(at):g} s is outside the run's results, {t[0]:g} to {t[-1]:g} s")
    assert not (tmp_path / "a.png").exists()


def test_animate_frames_one_is_refused_by_the_command_line(runs, tmp_path):
    """--frames 1 passed argparse and was refused later with frames' and exaggerate's one message."""
    refused(cli("animate", runs / "pend.csv", "--frames", "1", "-o", tmp_path / "a.png"),
            "animate: argument --frames: '1': a whole number of frames, at least 2")
    assert not (tmp_path / "a.png").exists()


# ------------------------------------------------------------------ modal-import

@pytest.fixture(scope="module")
def fe(tmp_path_factory):
    """A small FE body: a chain of 5 nodes of 3 DOFs (springs between them, lumped masses),
    as Matrix Market files and a nodes file."""
    folder = tmp_path_factory.mktemp("fe")
    n = 15
    k = np.zeros((n, n))
    for node in range(4):
        for d in range(3):
            i, j = 3 * node + d, 3 * node + 3 + d
            k[i, i] += 1e6
            k[j, j] += 1e6
            k[i, j] -= 1e6
            k[j, i] -= 1e6
    for name, matrix in (("k.mtx", k), ("m.mtx", np.eye(n))):
        rows = [f"{i + 1} {j + 1} {float(matrix[i, j])!r}" for j in range(n) for i in range(j, n)
                if matrix[i, j] != 0]
        (folder / name).write_text("%%MatrixMarket matrix coordinate real symmetric\n"
                                   f"{n} {n} {len(rows)}\n" + "\n".join(rows) + "\n")
    (folder / "nodes.csv").write_text("".join(f"{i + 1}, {0.5 * i}, 0, 0\n" for i in range(5)))
    return folder


def _import(fe, tmp_path, **kwargs):
    from pymr.errors import ImportInputError  # noqa: F401
    with warnings.catch_warnings():      # the chain's warning (test_a_small_fe_body_imports)
        warnings.simplefilter("ignore", pymr.PymrWarning)
        return pymr.modal_import(fe / "m.mtx", fe / "k.mtx", fe / "nodes.csv", kwargs.pop("interface", [1, 5]),
                                 tmp_path / "b.modal", dofs_per_node=kwargs.pop("dofs_per_node", 3), modes=2, **kwargs)


def test_a_small_fe_body_imports(fe, tmp_path):
    """The chain's springs along y and z between nodes along x resist a rigid rotation about
    z and y, which an elastic body's stiffness does not: the import warns, as Nastran's
    GROUNDCHECK would. The end node's row, 1 m from the centroid and its neighbour 0.5 m, is
    k (1 - 0.5) against k (1 + 0.5) in |K| |r|: 1/3."""
    body = _import(fe, tmp_path)
    assert len(body.frequencies_hz) == 5 and (tmp_path / "b.modal").exists()
    assert len(body.warnings) == 1 and re.search(r"resists a rigid rotation about [yz] of the nodes \(\|K r\| "
                                                 r"reaches 0.33 of", body.warnings[0]), body.warnings


@pytest.mark.parametrize("kwargs, message", [
    (dict(mass_name="MAAX"), r"m\.mtx: a mass matrix's name \('MAAX'\) picks one of the matrices of a Nastran file "
                             r"\(DMIG, OP4\); this file holds one matrix: leave the name out$"),
    (dict(stiffness_name="KAAX"), r"k\.mtx: a stiffness matrix's name \('KAAX'\) picks one"),
    (dict(mass_name=5), r"^mass_name=5: a matrix's name \(str\) expected, or None$"),
    (dict(stiffness_name=b"K"), r"^stiffness_name=b'K': a matrix's name \(str\) expected, or None$"),
    (dict(progress="no"), r"^progress='no': True or False expected$"),
    (dict(memory_limit=1e-12), r"^memory_limit=1e-12: below 1e-06 GB \(one kilobyte\), in which no reduction fits: "
                               r"the limit is in GB \(8 for 8 GB\)$"),
    (dict(dofs_per_node=6, dof_map="map.txt"), r"^dofs_per_node=6 and dof_map: give one of them"),
    (dict(interface=[]), r"^interface=\[\]: give at least the node where the body is attached$"),
    (dict(interface=[1, 5], clamp=[5]), r"^interface and clamp: node 5 is given twice$"),
], ids=["mass_name_mtx", "stiffness_name_mtx", "mass_name_int", "stiffness_name_bytes", "progress_str",
        "memory_tiny", "dofs_and_map", "interface_empty", "twice"])
def test_modal_import_refuses_arguments_that_do_not_apply(fe, tmp_path, kwargs, message):
    """A matrix name with a Matrix Market file was ignored (the file's one matrix read as
    the one named); mass_name=5 and progress='no' were taken; a memory limit of 1e-12 GB
    passed (a small model never met it); dofs_per_node=6 with a dof_map was ignored; the
    API's messages named the command line's options."""
    from pymr.errors import ImportInputError
    if "dof_map" in kwargs:
        kwargs["dof_map"] = fe / kwargs["dof_map"]
    with pytest.raises(ImportInputError, match=message):
        _import(fe, tmp_path, **kwargs)
    assert list(tmp_path.iterdir()) == []


def test_pymr_modal_import_refuses_a_matrix_name_with_matrix_market(fe, tmp_path):
    """It failed later, on the mode count, as if the name had picked a matrix."""
    r = cli("modal-import", "--mass", fe / "m.mtx", "--stiffness", fe / "k.mtx", "--nodes", fe / "nodes.csv",
            "--interface", "1", "5", "--dofs-per-node", "3", "--modes", "2", "--mass-name", "NOPE",
            "-o", tmp_path / "b.modal")
    refused(r, "m.mtx: a mass matrix's name ('NOPE') picks one of the matrices of a Nastran file")
    r = cli("modal-import", "--mass", fe / "m.mtx", "--stiffness", fe / "k.mtx", "--nodes", fe / "nodes.csv",
            "--interface", "1", "5", "--dofs-per-node", "3", "--modes", "2", "--memory-limit", "1e-12",
            "-o", tmp_path / "b.modal")
    refused(r, "memory_limit=1e-12: below 1e-06 GB")
    assert list(tmp_path.iterdir()) == []


def test_a_matrix_market_entry_that_is_not_a_number_is_named(fe, tmp_path):
    """numpy 2's fromstring raised ValueError ('could not be read to its end due to unmatched
    data') for an entry that is not a number: a traceback, where the line is now named."""
    from pymr.errors import ImportInputError
    lines = (fe / "k.mtx").read_text().splitlines()
    lines[3] = lines[3].rsplit(" ", 1)[0] + " abc"
    bad = tmp_path / "k.mtx"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(ImportInputError, match=r"k\.mtx: line 4: "):
        pymr.modal_import(fe / "m.mtx", bad, fe / "nodes.csv", [1, 5], dofs_per_node=3, modes=2)


@pytest.mark.parametrize("call, message", [
    (lambda fe, d: pymr.modal_import(str(fe / "m.mtx") + "\0", fe / "k.mtx", fe / "nodes.csv", [1, 5]),
     r"^mass='.*m\.mtx\\x00': a file name cannot hold a NUL character$"),
    (lambda fe, d: pymr.modal_import(fe / "m.mtx", fe / "k.mtx", fe / "nodes.csv", [1, 5], dof_map="a\0b"),
     r"^dof_map='a\\x00b': a file name cannot hold a NUL character$"),
    (lambda fe, d: pymr.export.export_vtk(d / "missing.csv", "v\0x"), r"missing.csv: no such result file$"),
    (lambda fe, d: __import__("pymr.sweep").sweep.load_sweep("s\0.toml"),
     r"^'s\\x00.toml': a file name cannot hold a NUL character$"),
], ids=["modal_import_mass", "modal_import_dof_map", "export_results_first", "load_sweep"])
def test_a_nul_in_the_other_functions_paths_is_refused(fe, tmp_path, call, message):
    """modal_import, export_vtk and load_sweep gave Python's ValueError 'embedded null byte'."""
    with pytest.raises(pymr.PymrError, match=message):
        call(fe, tmp_path)


def test_export_refuses_a_nul_in_its_folder(runs):
    with pytest.raises(pymr.OutputError, match=r"^--vtk 'v\\x00x': a folder name cannot hold a NUL character$"):
        pymr.export.export_vtk(runs / "pend.csv", "v\0x")


# ------------------------------------------------------------------ the reader goes away

@pytest.mark.parametrize("args", [("modes", ROOT / "input" / "tank_gun_turret.nml"), ("scene", "--schema")],
                         ids=["modes", "schema"])
def test_output_cut_short_by_its_reader_ends_quietly(args):
    """`pymr modes SCENE | head -1`: the reader closes the pipe before pymr writes, so every
    write fails (EPIPE). pymr stops quietly, with nothing on stderr, and with exit 1, as
    Python does (the command did not finish: a study cut there has written nothing); `pymr
    modes` ended in a BrokenPipeError traceback."""
    p = subprocess.Popen([sys.executable, "-m", "pymr", *map(str, args)], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, stdin=subprocess.DEVNULL, cwd=tempfile.gettempdir())
    p.stdout.close()                                  # before the interpreter has even started
    err = p.stderr.read()
    assert p.wait(timeout=120) == 1 and err == b"", err.decode()


# ------------------------------------------------------------------ overflowing scales, names

@pytest.mark.parametrize("command", ["export", "view", "animate"])
def test_a_deflection_scale_that_overflows_is_refused(tmp_path, command):
    """The tank's barrel deflects about 1e-4 m: scaled by 1e300 its drawn points lie beyond
    what a drawing holds (single precision, 3.4e38 m), as by 1e308.
    Each drawing command refuses the scale in one line (export wrote .vtu files of inf and
    nan with exit 0; view and animate ended in tracebacks)."""
    pymr.run(ROOT / "input" / "tank_gun_turret.nml", tmp_path / "t.csv", overrides={"scene.t_end": 0.02})
    out = {"export": ["--vtk", tmp_path / "vtk"], "view": ["-o", tmp_path / "t.html"],
           "animate": ["-o", tmp_path / "t.gif"]}[command]
    for scale in ("1e300", "1e308"):
        refused(cli(command, tmp_path / "t.csv", *out, "--exaggerate", scale),
                f"exaggerate: {float(scale)!r} scales the deflections beyond what a drawing holds (single "
                "precision, 3.4e+38 m): take a smaller scale")
    assert not any(p.suffix in (".vtu", ".pvd", ".html", ".gif") for p in tmp_path.rglob("*"))
    assert cli(command, tmp_path / "t.csv", *out, "--exaggerate", "1e3").returncode == 0


def test_a_sweep_whose_scene_name_the_system_cannot_take_is_one_line(tmp_path):
    """A scene name of 300 characters (above the file system's 255 per name): one line
    naming the sweep file and the system's reason (it was an OSError traceback)."""
    toml = tmp_path / "long.toml"
    toml.write_text(f'scene = "{"p" * 300}.nml"\n[grid]\n"integrator.h_slow" = [1e-3]\n')
    refused(cli("sweep", toml, "--emit-slurm", tmp_path / "out"), "long.toml: scene: ")
    assert "File name too long" in cli("sweep", toml).stderr


@pytest.mark.parametrize("command, option, suffix", [("export", "--vtk", ""), ("plot", "-o", ".png"),
                                                     ("view", "-o", ".html"), ("animate", "-o", ".gif")])
def test_an_output_name_the_folder_cannot_take_is_refused_before_any_work(runs, tmp_path, command, option, suffix):
    """A name of 300 bytes (the file system takes 255, and pymr writes a temporary file
    beside it, whose name adds up to 24): one line naming the option and the most it may
    take (each was an OSError traceback, the study's only after its runs)."""
    name = tmp_path / ("o" * 300 + suffix)
    refused(cli(command, runs / "pend.csv", option, name), f"{option} {name}: a name of {300 + len(suffix)} bytes; "
            "the folder takes names of 255, and pymr writes a temporary file beside it: take at most 231")
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("command", ["study", "bench"])
def test_repeats_beyond_what_can_end_are_refused(command):
    """--repeats 1e20 was taken, and the study never ended: at most 1000 runs per case."""
    args = ["study", "--quick", PENDULUM] if command == "study" else ["bench", "rhs"]
    r = cli(*args, "--repeats", "99999999999999999999")
    assert r.returncode == 1 and "--repeats: '99999999999999999999': a whole number of" in r.stderr and \
        "at most 1000" in r.stderr and r.stderr.count("\n") == 1, r.stderr
    with pytest.raises(pymr.SceneError, match=r"repeats: a whole number of runs per case from 1 to 1000"):
        from pymr.study import Study
        Study(PENDULUM, repeats=1001)


def test_workers_beyond_one_machine_are_refused(tmp_path):
    """--workers 1e20 started worker processes until the machine ran out of memory (killed,
    exit 137): at most 256 processes of a LocalCluster."""
    r = cli("sweep", ROOT / "input" / "tank_sweep.toml", "--workers", "99999999999999999999")
    assert r.returncode == 1 and "--workers: '99999999999999999999': a whole number of workers, at most 256" \
        in r.stderr and r.stderr.count("\n") == 1, r.stderr
    from pymr.sweep import load_sweep, run_sweep, SweepError
    with pytest.raises(SweepError, match=r"workers: a whole number of worker processes from 1 to 256, got 257"):
        run_sweep(load_sweep(ROOT / "input" / "tank_sweep.toml"), workers=257)


def test_every_beyond_the_rows_takes_the_first_row(runs, tmp_path):
    """--every 2**63 (beyond numpy's int64) was an IndexError traceback in view and export;
    now the first row alone is drawn."""
    r = cli("view", runs / "pend.csv", "-o", tmp_path / "v.html", "--every", str(2**63))
    assert r.returncode == 0 and r.stderr == "", r.stderr
    r = cli("export", runs / "pend.csv", "--vtk", tmp_path / "vtk", "--every", str(2**63))
    assert r.returncode == 0 and "(1 times)" in r.stdout, r.stderr


@pytest.mark.parametrize("fmt", ["csv", "hdf5"])
def test_results_whose_times_do_not_increase_are_refused(runs, tmp_path, fmt):
    """A run writes its rows in time. Rows swapped in the file (CSV lines or HDF5 dataset
    rows) are refused where the results are read, naming the row (export wrote a ParaView
    collection whose times ran backwards, with exit 0)."""
    if fmt == "csv":
        lines = (runs / "pend.csv").read_text().splitlines(keepends=True)
        head = next(i for i, t in enumerate(lines) if t.startswith("t,"))
        lines[head + 2], lines[head + 3] = lines[head + 3], lines[head + 2]      # rows 2 and 3
        path = tmp_path / "pend.csv"
        path.write_text("".join(lines))
        (tmp_path / "pend.json").write_text((runs / "pend.json").read_text())
    else:
        import h5py
        import shutil
        path = Path(shutil.copy(runs / "pendh.h5", tmp_path / "pendh.h5"))
        shutil.copy(runs / "pendh.json", tmp_path / "pendh.json")
        with h5py.File(path, "r+") as f:
            for name in f:
                block = f[name][...]
                block[[1, 2]] = block[[2, 1]]
                f[name][...] = block
    with pytest.raises(pymr.ResultsError, match=r"row 3, column t: 0.01 is before the row before it \(0.02; a "
                                                r"run writes its rows in time: the file was changed\)"):
        pymr.load_results(path)
    refused(cli("export", path, "--vtk", tmp_path / "vtk"), "row 3, column t: 0.01 is before")


@pytest.mark.parametrize("edit, fault", [
    (lambda h: h[:-1] + [h[-2]], r"column 9: 'tip.vy' is named twice"),
    (lambda h: h[:1] + [" " + h[1]] + h[2:], r"column 2: ' pivot.q' is no column name"),
    (lambda h: h[:1] + [""] + h[2:], r"column 2: '' is no column name"),
])
def test_a_header_that_hides_a_column_is_refused(runs, tmp_path, edit, fault):
    """With no statistics beside it a CSV whose header named a column twice was read: the
    name gave one of the two columns, and to_xarray dropped the other. Blank or padded names
    were taken too."""
    lines = (runs / "pend.csv").read_text().splitlines(keepends=True)
    head = next(i for i, t in enumerate(lines) if t.startswith("t,"))
    lines[head] = ",".join(edit(lines[head].strip().split(","))) + "\n"
    path = tmp_path / "cols.csv"
    path.write_text("".join(lines))
    with pytest.raises(pymr.ResultsError, match=rf"cols\.csv: {fault} \(a run writes"):
        pymr.load_results(path)


def test_rows_that_precision_writes_with_one_time_are_read(tmp_path):
    """At &output precision 6, times 1e-5 apart just past 1 s are written alike
    (1.00000e+000 for 1.000001 ... 1.000004): the results the run wrote are read (the
    time-order check once refused them as changed)."""
    res = pymr.run(PENDULUM, tmp_path / "p6.csv", overrides={"scene.t_end": 1.000004, "output.dt": 1e-6,
                                                             "output.precision": 6, "integrator.h_slow": 1e-5,
                                                             "integrator.h_fast": 1e-5,
                                                             "output.quantities": ["coordinates"]})
    assert (res.t[-5:] == 1.0).all() and (np.diff(res.t) >= 0).all()


@pytest.mark.parametrize("digits", [6, 8])
def test_a_run_written_with_few_digits_is_drawn(tmp_path, digits):
    """The drawing checks that the scene's markers at the written coordinates are the written
    markers: to 1e-9 it refused a run's own CSV written at &output precision 6 to 8 (as of
    another scene); the check now allows what those digits leave (10^(3 - precision)). A
    scene whose geometry differs is still refused."""
    scene = ROOT / "input" / "tank_gun_turret.nml"
    pymr.run(scene, tmp_path / "r.csv", overrides={"scene.t_end": 0.05, "output.precision": digits})
    assert cli("export", tmp_path / "r.csv", "--vtk", tmp_path / "vtk").returncode == 0
    other = tmp_path / "other.nml"
    other.write_text(scene.read_text().replace("at = 5.3, 0.0, 0.0", "at = 5.2, 0.0, 0.0"))
    refused(cli("export", tmp_path / "r.csv", "--vtk", tmp_path / "vtk2", "--scene", other),
            "is not the scene of this run (its marker 'muzzle' is elsewhere")


@pytest.mark.parametrize("args", [("scene", PENDULUM), ("scene", "--schema"),
                                  ("modes", ROOT / "input" / "tank_gun_turret.nml")], ids=["scene", "schema", "modes"])
def test_an_output_the_disk_refuses_is_one_line(args):
    """The standard output on a full device (/dev/full): one line naming it and the system's
    reason, exit 1 (each was a 12-line OSError traceback)."""
    with open("/dev/full", "w") as full:
        r = subprocess.run([sys.executable, "-m", "pymr", *map(str, args)], stdout=full, stderr=subprocess.PIPE,
                           text=True, cwd=tempfile.gettempdir(), timeout=120, stdin=subprocess.DEVNULL)
    assert r.returncode == 1 and r.stderr == "pymr: error: the standard output: No space left on device\n", r.stderr


@pytest.mark.parametrize("output", ["full", "closed"])
def test_a_run_whose_summary_is_lost_is_no_success(tmp_path, mrsim, output):
    """mrsim > /dev/full, or with its standard output closed (>&-), exited 0 with the summary
    lost (gfortran's standard output reports no failed write), and `pymr run >&-` failed in
    a traceback (sys.stdout is None). Both now exit 1 in one line naming the standard output;
    the results are complete. With -q nothing is written, and the run succeeds."""
    def launch(command, quiet):
        args = [*command, str(PENDULUM), "-o", str(tmp_path / "r.csv"), "--set", "scene.t_end=0.02"] + \
               (["-q"] if quiet else [])
        with open("/dev/full", "w") as full:
            return subprocess.run(args, stdout=full if output == "full" else None, stderr=subprocess.PIPE, text=True,
                                  cwd=tmp_path, timeout=120, stdin=subprocess.DEVNULL,
                                  preexec_fn=None if output == "full" else (lambda: os.close(1)))
    reason = "No space left on device" if output == "full" else "Bad file descriptor"
    for name, command in (("mrsim", [str(mrsim)]), ("pymr", [sys.executable, "-m", "pymr", "run"])):
        r = launch(command, quiet=False)
        assert r.returncode == 1, (name, r.stderr)
        assert r.stderr.startswith(f"{name}: error: the standard output: {reason}") and r.stderr.count("\n") == 1, \
            r.stderr
        assert pymr.load_results(tmp_path / "r.csv").t[-1] == pytest.approx(0.02)
        assert launch(command, quiet=True).returncode == 0


@pytest.mark.parametrize("fields, error, message", [
    (dict(path=5), pymr.ArgumentTypeError, r"^path: the results file's path \(str\), or None, got int 5"),
    (dict(summary=5), pymr.ArgumentTypeError, r"^summary: a text \(str\), got int 5"),
    (dict(data=[[0.0, None]]), pymr.ResultsError, r"^data: row 1, column x: nan is not a finite number"),
    (dict(columns=["t", "t"]), pymr.ResultsError, r"^columns: column 2: 't' is named twice"),
    (dict(stats={"title": 5}), pymr.ResultsError, r'^stats: "title" is int 5, not a text \(given by hand\)$'),
    (dict(stats={"rows": "1"}), pymr.ResultsError, r'^stats: "rows" is str \'1\', not a whole number'),
    (dict(stats={"columns": {"name": ["t"]}}), pymr.ResultsError, r'^stats: "columns" "name" has 1 entries for the 2 '
                                                                  r"columns of the results \(given by hand, or they are "
                                                                  r"another run's\)$"),
])
def test_results_made_by_hand_are_checked_as_a_file_s(fields, error, message):
    """A Results made by hand took path=5 and summary=5, turned None into NaN, and took a
    column twice, each to fail later where used; the docs say it is checked as a file is."""
    base = dict(columns=["t", "x"], data=[[0.0, 1.0]])
    with pytest.raises(error, match=message):
        pymr.Results(**{**base, **fields})
    assert pymr.Results(**base, path=Path("r.csv")).path == "r.csv"


def test_messages_name_the_user_s_files_not_pymr_s_temporary_ones(runs, tmp_path):
    """A statistics file whose resolved scene the kernel refuses was named as the temporary
    file pymr wrote it to (/tmp/pymr-scene-.../resolved.nml:1); an export folder whose parent
    takes no new entry was named by its staging name (/proc/.xx.tmp-...)."""
    shutil.copy(runs / "pend.csv", tmp_path / "g.csv")
    stats = json.loads((runs / "pend.json").read_text())
    stats["resolved_scene"] = "&scene garbage"
    (tmp_path / "g.json").write_text(json.dumps(stats))
    r = cli("animate", tmp_path / "g.csv", "-o", tmp_path / "a.png")
    refused(r, f"{tmp_path / 'g.json'}: resolved_scene:1: &scene: garbage: expected '=' after the item name")
    assert "pymr-scene-" not in r.stderr and not (tmp_path / "a.png").exists()
    r = cli("export", runs / "pend.csv", "--vtk", "/proc/pymr_export")
    refused(r, "--vtk /proc/pymr_export: cannot write in its folder /proc (")
    assert ".tmp-" not in r.stderr


def test_a_write_never_replaces_a_device_or_a_fifo(tmp_path):
    """Scene.write('/dev/null') renamed its file over the device: /dev/null became a regular
    file holding the scene (the command-line writers refused it). write_file, which every
    writer uses, now refuses a target that is not a regular file."""
    import stat
    fifo = tmp_path / "pipe"
    os.mkfifo(fifo)
    with pytest.raises(pymr.OutputError, match=r"pipe: it is not a regular file \(a FIFO, a socket or a device\); "
                                               r"choose another scene file$"):
        pymr.Scene(PENDULUM).write(fifo)
    assert stat.S_ISFIFO(fifo.stat().st_mode)


@pytest.mark.parametrize("how", ["copy", "deepcopy"])
def test_a_copied_scene_is_independent_of_its_original(tmp_path, how):
    """copy.copy(scene) shared the overrides list: an item set on the copy changed what the
    original ran (from q0 = 0.3), while the original's resolved text still said 1. A scene
    built in Python shared its file too."""
    import copy
    a = pymr.Scene(PENDULUM, overrides={"scene.t_end": 0.01})
    b = getattr(copy, how)(a)
    b["joint[pivot].q0"] = 0.3
    assert a["joint[pivot].q0"] == [1] and b["joint[pivot].q0"] == [0.3]
    assert pymr.run(a)["pivot.q"][0] == 1.0 and pymr.run(b)["pivot.q"][0] == 0.3
    built = pymr.Scene(PENDULUM).add("marker", name="m2", body="bob")      # its text held in Python
    other = getattr(copy, how)(built)
    other["scene.t_end"] = 0.2
    assert built["scene.t_end"] == 10.0 and other["scene.t_end"] == 0.2 and built.path != other.path


def test_a_zero_dimensional_array_is_its_one_value():
    """np.array(0.5) as a value raised a bare TypeError (len() of unsized object) in
    Scene.__setitem__, Scene.add and every overrides mapping; it is its one value."""
    s = pymr.Scene(PENDULUM)
    s["scene.t_end"] = np.array(0.05)
    assert s["scene.t_end"] == 0.05
    res = pymr.run(PENDULUM, overrides={"scene.t_end": np.array(0.05), "joint[pivot].q0": np.array([0.2])})
    assert res.t[-1] == pytest.approx(0.05) and res["pivot.q"][0] == 0.2
    with pytest.raises(pymr.ArgumentTypeError, match=r"^scene.t_end: a number, a bool, a text \(str\) or a list"):
        s["scene.t_end"] = np.array(None)


def test_statistics_nested_beyond_python_s_recursion_are_refused(runs, tmp_path):
    """A statistics file of 100000 nested lists made load_results raise a bare RecursionError
    (plot and view printed its 38-line traceback)."""
    shutil.copy(runs / "pend.csv", tmp_path / "n.csv")
    (tmp_path / "n.json").write_text("[" * 100000 + "]" * 100000)
    with pytest.raises(pymr.ResultsError, match=r"n\.json: not a pymr statistics file \(maximum recursion depth"):
        pymr.load_results(tmp_path / "n.csv")
    refused(cli("plot", tmp_path / "n.csv", "-o", tmp_path / "p.png"), "n.json: not a pymr statistics file")


@pytest.mark.parametrize("path, message", [
    ("nope/x.modal", r"^path nope/x\.modal: the folder nope is not there \(make it first\)$"),
    (".", r"^path \.: is a folder, not a file: give a file name for the modal file"),
])
def test_write_modal_file_output_faults_are_output_errors(tmp_path, monkeypatch, path, message):
    """write_modal_file raised SceneError for an output fault, one of its messages holding
    the Fortran runtime's text ("Cannot open file 'nope/x.modal.tmp'"); it checks its path as
    every writer does (pymr modal-file did, before the call)."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(pymr.OutputError, match=message):
        pymr.write_modal_file(ROOT / "input" / "tank_gun_turret.nml", "gun", path)
    pymr.write_modal_file(ROOT / "input" / "tank_gun_turret.nml", "gun", "gun.modal")
    assert "pymr-modal" in (tmp_path / "gun.modal").read_text()


@pytest.mark.parametrize("call, error, message", [
    (lambda d, r: pymr.run(PENDULUM, None, np.array("scene.t_end=0.05")), pymr.ArgumentTypeError,
     r"^overrides: a mapping .* got ndarray"),
    (lambda d, r: _plot().plot_results(r, markers=np.array("tip")), pymr.ArgumentTypeError,
     r"^markers: a name or a list of names \(str\), got ndarray"),
    (lambda d, r: _plot().plot_results(r, labels=np.array("a")), pymr.ArgumentTypeError,
     r"^labels: a list of texts \(str\), got ndarray"),
    (lambda d, r: _plot().plot_results(r, columns=[]), pymr.PlotError, r"^columns: none given"),
    (lambda d, r: _view().view(r, d / "v.html", columns=5), pymr.ArgumentTypeError,
     r"^columns: a name or a list of names \(str\), got int 5$"),
    (lambda d, r: _view().view(r, d / "v.html", columns={}), pymr.ArgumentTypeError,
     r"^columns: a name or a list of names \(str\), got dict"),
], ids=["overrides_0d", "markers_0d", "labels_0d", "columns_empty", "view_columns_int", "view_columns_dict"])
def test_list_arguments_that_are_no_lists_are_refused_naming_them(tmp_path, call, error, message):
    """A 0-d numpy array passed the Iterable check and failed in iteration (a bare TypeError),
    plot_results(columns=[]) divided by zero, and view(columns=5) failed inside the page's
    making, view(columns={}) was taken as no columns (found by fuzzing)."""
    res = pymr.run(PENDULUM, tmp_path / "r.csv", overrides={"scene.t_end": 0.05})
    with pytest.raises(error, match=message):
        call(tmp_path, res)
    assert not (tmp_path / "v.html").exists()


def _plot():
    import pymr.plot
    return pymr.plot


def _view():
    import pymr.view
    return pymr.view


def test_a_figure_format_whose_tool_is_missing_is_one_line(tmp_path):
    """`pymr plot -o fig.pgf` without xelatex ended in a RuntimeError traceback, though .pgf
    is one of the formats pymr offers (found by fuzzing): one line, exit 1, no file. With
    xelatex the figure is written."""
    import shutil
    pymr.run(PENDULUM, tmp_path / "r.csv", overrides={"scene.t_end": 0.05})
    r = subprocess.run([sys.executable, "-m", "pymr", "plot", "r.csv", "-o", "fig.pgf"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=300, env={**os.environ, "MPLBACKEND": "Agg"})
    if shutil.which("xelatex") is None:
        assert r.returncode == 1 and r.stderr.startswith("pymr: error: fig.pgf: cannot draw the figure ('xelatex' "
                                                         "not found") and r.stderr.count("\n") == 1, r.stderr
        assert not (tmp_path / "fig.pgf").exists()
    else:
        assert r.returncode == 0 and (tmp_path / "fig.pgf").stat().st_size > 0


def test_an_int_past_the_largest_float_is_a_time_too_large_not_an_overflow():
    """t=10**400 raised Python's bare OverflowError from float() (found by fuzzing): it is the
    same SceneError as an infinite time, naming t."""
    q, qd = np.array([1.0]), np.array([0.0])
    for t in (10**400, -10**400):
        with pytest.raises(pymr.SceneError, match=r"^t: -?inf is not a finite time$"):
            pymr.model_terms(PENDULUM, q, qd, t=t)
    with pytest.raises(pymr.SceneError, match=r"^t: inf is not a finite time$"):
        pymr.Model(PENDULUM).rhs(10**400, np.array([1.0, 0.0]))


def test_a_results_value_with_digit_groups_is_named(tmp_path):
    """'1_0' in a results CSV was refused only as 'its rows are not numbers separated by
    commas', with no line or column: Python's float() takes digit groups, numpy's reader
    does not (found by fuzzing). The message names the line, the column and the value."""
    res = pymr.run(PENDULUM, tmp_path / "r.csv", overrides={"scene.t_end": 0.05})
    lines = (tmp_path / "r.csv").read_text().splitlines(keepends=True)
    first = next(k for k, line in enumerate(lines) if line[0].isdigit())
    lines[first] = "1_0" + lines[first][1:]
    (tmp_path / "r.csv").write_text("".join(lines))
    with pytest.raises(pymr.ResultsError, match=rf"line {first + 1}, column t: '1_0.*' is not a number\)$"):
        pymr.load_results(tmp_path / "r.csv")
    assert res.t[0] == 0.0
