"""Faults a fuzzing campaign found in the Python side's handling of bad input: each one is now
pymr's one-line refusal (the API: a pymr exception naming the file or the argument; the
CLI: ``pymr: error: ...`` and exit 1), never a hang, a traceback, a silent NaN or a file of
the user's destroyed."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pymr
import pymr.export

ROOT = Path(__file__).resolve().parent.parent
PENDULUM = ROOT / "input" / "pendulum.nml"


def cli(*args, cwd=None, timeout=120):
    """`pymr ARGS` in a fresh process (the timeout only keeps a hang from stalling the suite)."""
    return subprocess.run([sys.executable, "-m", "pymr", *map(str, args)], capture_output=True, text=True,
                          cwd=cwd, timeout=timeout, stdin=subprocess.DEVNULL)


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
