"""HDF5 results written by the kernel (issue 33): the same numbers as the CSV of the same run,
read back by h5py alone and by pymr.load_results, the run's description in the file, and the
CSV's data safety (a kill at any moment, a restart, a full disk, a refused run)."""
from __future__ import annotations

import json
import random
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import pymr

ROOT = Path(__file__).resolve().parent.parent
ALL = "coordinates markers marker_accelerations marker_orientations reactions energy"
LONG = ROOT / "input" / "hard" / "tank_long.nml"


def run(mrsim, args, cwd, **kw):
    return subprocess.run([mrsim, *map(str, args)], cwd=cwd, capture_output=True, text=True, timeout=300, **kw)


def both_formats(mrsim, scene, tmp_path, *sets):
    """The same run written as CSV and as HDF5 (of two names: out.csv and out.h5 would share
    out.json, which a run refuses)."""
    over = [a for s in sets for a in ("--set", s)]
    for out in ("out.csv", "out_h5.h5"):
        fmt = "hdf5" if out.endswith(".h5") else "csv"
        r = run(mrsim, [scene, "-o", out, "--quiet", "--set", f"output.format={fmt}", *over], tmp_path)
        assert r.returncode == 0, r.stderr
    return pymr.load_results(tmp_path / "out.csv"), pymr.load_results(tmp_path / "out_h5.h5")


@pytest.mark.parametrize("scene, sets", [
    ("tank_gun_turret.nml", [f"output.quantities={ALL}"]),
    ("spacecraft.nml", [f"output.quantities={ALL}", "scene.t_end=0.3"]),
    ("tank_on_the_move.nml", ["scene.t_end=0.81"]),
])
def test_hdf5_holds_the_numbers_of_the_csv(mrsim, tmp_path, scene, sets):
    """Every column of every row equals the CSV's (17 digits read back exactly: the same
    doubles), the columns come back in the CSV's order, and the statistics are OUT.json's."""
    csv, h5 = both_formats(mrsim, ROOT / "input" / scene, tmp_path, *sets)
    assert h5.columns == csv.columns
    assert h5.data.shape == csv.data.shape and csv.data.shape[0] > 10
    assert np.array_equal(h5.data, csv.data)
    assert h5.stats["status"] == "complete" and h5.stats["columns"] == csv.stats["columns"]
    assert h5.title == csv.title and h5.method == csv.method
    assert [c.unit for c in h5.column_info] == [c.unit for c in csv.column_info]


READER = r"""
import json, sys
sys.modules["pymr"] = None                  # pymr cannot be imported here
import h5py, numpy as np
with h5py.File(sys.argv[1], "r") as f:
    text = lambda v: v.decode() if isinstance(v, bytes) else str(v)
    order = text(f.attrs["column_order"]).split(",")
    place = {text(c): (name, k) for name, d in f.items() for k, c in enumerate(d.attrs["columns"])}
    units = {text(c): text(u) for name, d in f.items() for c, u in zip(d.attrs["columns"], d.attrs["units"])}
    cols = [f[place[c][0]][:] if f[place[c][0]].ndim == 1 else f[place[c][0]][:, place[c][1]] for c in order]
    np.save(sys.argv[2], np.column_stack(cols))
    stats = json.loads(text(f.attrs["statistics"]))
    print(json.dumps({"order": order, "units": units, "status": text(f.attrs["status"]),
                      "fingerprint": text(f.attrs["scene_fingerprint"]), "stats_fingerprint": stats["scene_fingerprint"],
                      "scene": text(f.attrs["resolved_scene"]), "integrator": json.loads(text(f.attrs["integrator"])),
                      "chunks": f["markers"].chunks, "compression": f["markers"].compression}))
"""


def test_h5py_alone_reads_the_file(mrsim, tmp_path):
    """A Python with h5py and numpy but no pymr reads the columns, their units and the run's
    description (fingerprint, resolved scene, settings, statistics); the datasets are
    chunked and compressed."""
    csv, h5 = both_formats(mrsim, ROOT / "input" / "tank_gun_turret.nml", tmp_path, f"output.quantities={ALL}")
    r = subprocess.run([sys.executable, "-c", READER, tmp_path / "out_h5.h5", tmp_path / "cols.npy"],
                       capture_output=True, text=True, timeout=60, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    seen = json.loads(r.stdout)
    assert seen["order"] == csv.columns
    assert np.array_equal(np.load(tmp_path / "cols.npy"), csv.data)
    assert seen["units"] == {c.name: c.unit for c in csv.column_info}
    assert seen["status"] == "complete"
    # the run's own statistics beside it (out.json was the CSV run's until a run refused to share it)
    own = json.loads((tmp_path / "out_h5.json").read_text())
    assert seen["fingerprint"] == seen["stats_fingerprint"] == own["scene_fingerprint"] == h5.stats["scene_fingerprint"]
    assert seen["scene"] == own["resolved_scene"]
    assert seen["integrator"] == own["integrator"]
    assert seen["compression"] == "gzip" and seen["chunks"][0] >= 16


def test_a_killed_run_restarts_into_the_same_file(mrsim, tmp_path):
    """SIGKILL at 12 random moments of HDF5 runs and restarts (checkpoint every simulated
    second): after each kill the earlier complete file is byte for byte what it was (or,
    when the kill came after the run had put its own complete result in place, in the few
    milliseconds its statistics' rename and lock release take, that result, equal to the
    uninterrupted run), the killed partial file can be read and holds the run's first rows,
    each restart continues from the last checkpoint's rows, and the result finally completed
    equals the uninterrupted run (the same doubles). Files are compared as booleans: a
    failing comparison of two whole files made pytest diff megabytes for many minutes."""
    common = ["--quiet", "--set", "scene.t_end=40", "--set", "output.checkpoint_dt=1", "--set", "output.format=hdf5"]
    assert run(mrsim, [LONG, "-o", "full.h5", *common], tmp_path).returncode == 0
    full = pymr.load_results(tmp_path / "full.h5")
    assert run(mrsim, [LONG, "-o", "out.h5", "--quiet", "--set", "scene.t_end=1", "--set", "output.format=hdf5"],
               tmp_path).returncode == 0
    complete = (tmp_path / "out.h5").read_bytes()
    rng = random.Random(33)
    kills = 0
    while kills < 12:
        restart = (tmp_path / "out.ckpt").exists()
        args = [LONG, "-o", "out.h5", *common] + (["--restart", "out.ckpt"] if restart else [])
        job = subprocess.Popen([mrsim, *map(str, args)], cwd=tmp_path, stdout=subprocess.DEVNULL,
                               stderr=subprocess.PIPE)
        time.sleep(rng.uniform(0.0, 0.6))
        job.send_signal(signal.SIGKILL)
        _, err = job.communicate(timeout=120)
        if job.returncode == 0:
            assert np.array_equal(pymr.load_results(tmp_path / "out.h5").data, full.data)
            complete = (tmp_path / "out.h5").read_bytes()
            (tmp_path / "out.ckpt").unlink()
            continue
        assert job.returncode == -signal.SIGKILL, err
        kills += 1
        now = (tmp_path / "out.h5").read_bytes()
        if now != complete:          # killed after its complete result was in place
            assert np.array_equal(pymr.load_results(tmp_path / "out.h5").data, full.data)
            assert not (tmp_path / "out.h5.partial").exists()
            complete = now
            (tmp_path / "out.ckpt").unlink(missing_ok=True)
            continue
        partial = tmp_path / "out.h5.partial"
        if partial.exists() and rng.random() < 0.5:
            # the killed file opens (in HDF5's reader mode) and holds a prefix of the run
            # (a kill before the first rows are flushed leaves none)
            try:
                rows = pymr.load_results(partial).data
            except pymr.ResultsError as exc:
                assert "has no result rows" in str(exc)
            else:
                assert np.array_equal(rows, full.data[:len(rows)])
    last = ["--restart", "out.ckpt"] if (tmp_path / "out.ckpt").exists() else []
    r = run(mrsim, [LONG, "-o", "out.h5", *common, *last], tmp_path)
    assert r.returncode == 0, r.stderr
    assert np.array_equal(pymr.load_results(tmp_path / "out.h5").data, full.data)
    assert not (tmp_path / "out.h5.partial").exists()


def test_a_full_disk_is_a_failed_run_naming_the_file_and_the_time(mrsim, tmp_path):
    """Files may not grow beyond 100 kB (SIGXFSZ ignored): exit 2, one line naming the
    partial HDF5 file and the time reached; the earlier complete result is untouched."""
    import resource

    def limit():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (100_000, 100_000))
    fmt = ["--set", "output.format=hdf5"]
    assert run(mrsim, [LONG, "-o", "out.h5", "--quiet", "--set", "scene.t_end=0.5", *fmt], tmp_path).returncode == 0
    before = (tmp_path / "out.h5").read_bytes()
    r = run(mrsim, [LONG, "-o", "out.h5", "--quiet", "--set", "scene.t_end=40", "--set", "output.checkpoint_dt=0.5",
                    *fmt], tmp_path, preexec_fn=limit)
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "out.h5.partial: cannot write the results" in r.stderr, r.stderr
    assert 0.0 < float(r.stderr.split("at t = ")[1].split(" s")[0]) < 40.0
    assert (tmp_path / "out.h5").read_bytes() == before


@pytest.mark.parametrize("out, sets, words", [
    ("out.csv", ["output.format=hdf5"], ["&output", "format", "out.csv", ".h5"]),
    ("out.h5", [], ["out.h5", "HDF5", "format = 'hdf5'"]),
    ("out.h5", ["output.format=netcdf"], ["format", "'netcdf' is not one of: csv, hdf5"]),
])
def test_a_format_and_file_that_disagree_are_refused(mrsim, tmp_path, out, sets, words):
    """One line naming what disagrees and what to change, exit 1, nothing written."""
    over = [a for s in sets for a in ("--set", s)]
    r = run(mrsim, [ROOT / "input" / "pendulum.nml", "-o", out, *over], tmp_path)
    assert r.returncode == 1 and r.stderr.count("\n") == 1, r.stderr
    assert all(w in r.stderr for w in words), r.stderr
    assert list(tmp_path.iterdir()) == []


def test_a_restart_with_other_columns_is_refused(mrsim, tmp_path):
    """The checkpointed run's file has other columns than the restart would write: exit 1
    naming the file, and the partial file is left as it was."""
    common = ["--quiet", "--set", "scene.t_end=3", "--set", "output.checkpoint_dt=1", "--set", "output.format=hdf5"]
    job = run(mrsim, [LONG, "-o", "out.h5", *common], tmp_path)
    assert job.returncode == 0
    r = run(mrsim, [LONG, "-o", "out.h5", *common, "--set", "output.quantities=coordinates energy",
                    "--restart", "out.ckpt"], tmp_path)
    assert r.returncode == 1 and "its columns are not the ones this run writes" in r.stderr, r.stderr
    assert np.array_equal(pymr.load_results(tmp_path / "out.h5").t[-1:], [3.0])


def test_pymr_run_writes_hdf5_where_the_scene_asks(tmp_path):
    """pymr.run with format 'hdf5': to a temporary file (the suffix from the scene's format)
    and to a named one; the Results equal the CSV run's."""
    scene = ROOT / "input" / "pendulum.nml"
    csv = pymr.run(scene, None, overrides={"scene.t_end": 0.5})
    temp = pymr.run(scene, None, overrides={"scene.t_end": 0.5, "output.format": "hdf5"})
    named = pymr.run(scene, tmp_path / "p.h5", overrides={"scene.t_end": 0.5, "output.format": "hdf5"})
    assert temp.columns == named.columns == csv.columns
    assert np.array_equal(temp.data, csv.data) and np.array_equal(named.data, csv.data)
    assert named.path == str(tmp_path / "p.h5") and (tmp_path / "p.json").exists()
