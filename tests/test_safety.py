"""Nothing lost, nothing silent (issue 15, first part): LAPACK's error handler returns instead
of stopping the process, the statistics are valid JSON whatever the title holds, text that
is not UTF-8 is refused at read, and an output path that would overwrite what the run reads
(or collide with its own statistics) is refused before anything is written."""
from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr import _testhooks

ROOT = Path(__file__).resolve().parent.parent
TANK = ROOT / "input" / "tank_gun_turret.nml"
PENDULUM = (ROOT / "input" / "pendulum.nml").read_text().replace(
    "&output file = 'pendulum.csv', dt = 0.01 /", "&output dt = 0.01 /").replace("t_end = 10.0", "t_end = 0.05")


def test_lapack_illegal_argument_returns_to_pymr():
    """dpotrf called with uplo = 'X' reports argument 1 to XERBLA; pymr's XERBLA records it
    and returns (the reference one prints and ends the process with status 0), so LAPACK
    gives info = -1 and the process goes on. The test-hook extension is loaded alone in a
    fresh process: LAPACK's call to XERBLA binds to the kernel of the first extension that
    loads LAPACK, and in a process that imported pymr that is pymr._core's copy."""
    probe = ("import importlib.util, sys\n"
             "spec = importlib.util.spec_from_file_location('_testhooks', sys.argv[1])\n"
             "m = importlib.util.module_from_spec(spec); spec.loader.exec_module(m)\n"
             "info, routine, argument = m.pymr_xerbla_probe()\n"
             "print(info, routine.decode().strip(), argument)\n")
    r = subprocess.run([sys.executable, "-c", probe, _testhooks.__file__], capture_output=True, text=True,
                       timeout=60, cwd=ROOT.parent)
    assert r.returncode == 0 and r.stdout.split() == ["-1", "DPOTRF", "1"], (r.stdout, r.stderr)


def test_statistics_are_valid_json_whatever_the_title_holds(tmp_path):
    scene = tmp_path / "t.nml"
    title = 'a tab\there, "quotes", a backslash \\ and ünïcode'
    scene.write_text(PENDULUM.replace("title = 'simple pendulum, 1 rad'", f"title = '{title}'"))
    res = pymr.run(scene, tmp_path / "t.csv")
    stats = json.loads((tmp_path / "t.json").read_text())
    assert stats["title"] == title == res.stats["title"]


def test_text_that_is_not_utf8_is_refused(tmp_path):
    scene = tmp_path / "bad.nml"
    scene.write_bytes(PENDULUM.replace("title = 'simple pendulum, 1 rad'", "title = 'caf\x00'").encode()
                      .replace(b"caf\x00", b"caf\xe9"))
    with pytest.raises(pymr.SceneError, match=r"bad.nml:5: &scene: title: the text holds control characters or "
                                               r"bytes that are not UTF-8"):
        pymr.run(scene)


def test_an_output_that_would_overwrite_the_input_is_refused(tmp_path, mrsim):
    scene = tmp_path / "s.nml"
    scene.write_text(PENDULUM)
    before = scene.read_bytes()
    for out, message in [("s.nml", "output s.nml: would overwrite the scene (s.nml)"),
                         ("./s.nml", "output ./s.nml: would overwrite the scene"),
                         ("out.json", "output out.json: the results and their statistics would both be out.json"),
                         ("s.json", "output s.json: the results and their statistics would both be s.json")]:
        r = subprocess.run([mrsim, "s.nml", "-o", out], cwd=tmp_path, capture_output=True, text=True, timeout=60)
        assert r.returncode == 1 and r.stderr.count("\n") == 1, r.stderr
        assert r.stderr.startswith("mrsim: error: s.nml: " + message), r.stderr
        assert scene.read_bytes() == before
    assert not (tmp_path / "out.json").exists()


@pytest.mark.parametrize("where", ["-o", "file"])
def test_standard_output_is_no_results_file(tmp_path, mrsim, where):
    """'-' is standard output to most tools; the run stages its results and their statistics
    as files, so `-o -` wrote files named '-' and '-.json' with exit 0. Refused in one line,
    from the command line or from &output file, and nothing is written."""
    scene = tmp_path / "s.nml"
    scene.write_text(PENDULUM.replace("&output dt", "&output file = '-', dt") if where == "file" else PENDULUM)
    args = ["s.nml", "-o", "-"] if where == "-o" else ["s.nml"]
    r = run_mrsim(mrsim, args, tmp_path)
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and r.stdout == "", r.stderr
    line = scene.read_text().splitlines().index("&output file = '-', dt = 0.01 /") + 1 if where == "file" else 0
    place = "s.nml: output '-'" if where == "-o" else f"s.nml:{line}: &output: file: '-'"
    assert r.stderr.strip() == (f"mrsim: error: {place}: the results go to a file (with their statistics beside it), "
                                "not to standard output; name a file"), r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.nml"]


@pytest.mark.parametrize("table", ["ballistics.txt", "breech_force.txt"])
def test_an_output_over_any_table_of_the_scene_is_refused(tmp_path, mrsim, table):
    """Every file the scene reads is kept from the results: a &moving_load's and a &load's
    table (the overwrite guard once covered only &drive and &motion tables and modal
    files; the results replaced the table with exit 0)."""
    shutil.copytree(ROOT / "input" / "tank_on_the_move", tmp_path / "tank_on_the_move")
    shutil.copy(ROOT / "input" / "tank_on_the_move.nml", tmp_path)
    path = tmp_path / "tank_on_the_move" / table
    before = path.read_bytes()
    r = run_mrsim(mrsim, ["tank_on_the_move.nml", "-o", f"tank_on_the_move/{table}"], tmp_path)
    assert r.returncode == 1 and r.stderr.count("\n") == 1, r.stderr
    assert re.match(rf"mrsim: error: tank_on_the_move.nml: output tank_on_the_move/{table}: would overwrite an input "
                    rf"of the scene, &(load|moving_load) [^ ]+ file \(tank_on_the_move/{table}\); choose another "
                    rf"results file$", r.stderr.strip()), r.stderr
    assert path.read_bytes() == before


@pytest.mark.parametrize("name, what", [("s.nml", "the scene (s.nml)"), ("s.csv", "the results (s.csv)"),
                                        ("s.json", "their statistics (s.json)")])
def test_a_checkpoint_file_over_the_scene_or_the_results_is_refused(tmp_path, mrsim, name, what):
    """checkpoint_file is kept from what the run reads and writes: the scene became a binary
    checkpoint with exit 0, and a checkpoint named as the results was lost under them."""
    scene = tmp_path / "s.nml"
    scene.write_text(PENDULUM)
    before = scene.read_bytes()
    r = run_mrsim(mrsim, ["s.nml", "--set", "output.checkpoint_dt=1", "--set", f"output.checkpoint_file={name}"],
                  tmp_path)
    assert r.returncode == 1 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.strip() == (f"mrsim: error: s.nml: --set output.checkpoint_file={name}: &output: checkpoint_file: "
                                f"would overwrite {what}; choose another checkpoint file")
    assert scene.read_bytes() == before and not (tmp_path / "s.csv").exists()


def test_results_named_as_their_own_default_checkpoint_are_refused(tmp_path, mrsim):
    """-o run.ckpt with checkpoints on: the default checkpoint beside the results is
    run.ckpt, the results file itself. The run ended with exit 0 and the checkpoints lost
    under the results ("not a pymr checkpoint" on restart); the same clash written as
    checkpoint_file was already refused."""
    (tmp_path / "s.nml").write_text(PENDULUM)
    r = run_mrsim(mrsim, ["s.nml", "-o", "run.ckpt", "--set", "output.checkpoint_dt=0.01"], tmp_path)
    assert r.returncode == 1 and r.stderr.count("\n") == 1, r.stderr
    assert r.stderr.strip() == ("mrsim: error: s.nml: output run.ckpt: its checkpoint run.ckpt: would overwrite the "
                                "results (run.ckpt); choose another results file, or a checkpoint_file in &output"), \
        r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.nml"]


def test_no_file_the_run_writes_through_replaces_an_input(tmp_path, mrsim):
    """The run writes its results through OUT.partial, OUT.lock and staging files: a scene
    named r.csv.partial was deleted by a successful run to r.csv, and a checkpoint_file
    named r.csv.lock was lost. Both are refused; the scene stays."""
    scene = tmp_path / "r.csv.partial"
    scene.write_text(PENDULUM)
    before = scene.read_bytes()
    r = run_mrsim(mrsim, ["r.csv.partial", "-o", "r.csv"], tmp_path)
    assert r.returncode == 1 and r.stderr.strip() == (
        "mrsim: error: r.csv.partial: output r.csv: the run's file r.csv.partial would overwrite the scene "
        "(r.csv.partial); choose another results file"), r.stderr
    assert scene.read_bytes() == before
    (tmp_path / "s.nml").write_text(PENDULUM)
    r = run_mrsim(mrsim, ["s.nml", "-o", "r.csv", "--set", "output.checkpoint_dt=1", "--set",
                          "output.checkpoint_file=r.csv.lock"], tmp_path)
    assert r.returncode == 1 and r.stderr.strip().endswith(
        "&output: checkpoint_file: would overwrite the run's file r.csv.lock; choose another checkpoint file"), r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.csv.partial", "s.nml"]


def run_mrsim(mrsim, args, cwd):
    return subprocess.run([mrsim, *args], cwd=cwd, capture_output=True, text=True, timeout=300)


def test_refused_and_failed_runs_leave_the_earlier_complete_result(tmp_path, mrsim):
    """An earlier complete result stays as it was after a run refused before its first step
    (a stiff step) and after a run that fails on the way (multirate k = 50 forced past the
    stability check); the failed run's rows stay in OUT.csv.partial, described by
    OUT.json.partial with status 'failed', the error and the time reached."""
    tank = ROOT / "input" / "tank_gun_turret.nml"
    good = run_mrsim(mrsim, [str(tank), "-o", "out.csv", "--quiet", "--set", "scene.t_end=0.05"], tmp_path)
    assert good.returncode == 0, good.stderr
    csv_before, json_before = (tmp_path / "out.csv").read_bytes(), (tmp_path / "out.json").read_bytes()
    assert json.loads(json_before)["status"] == "complete"
    assert not (tmp_path / "out.csv.partial").exists()
    refused = run_mrsim(mrsim, [str(ROOT / "input" / "hard" / "stiff_barrel.nml"), "-o", "out.csv"], tmp_path)
    assert refused.returncode == 1 and "is not stable" in refused.stderr
    assert not (tmp_path / "out.csv.partial").exists()
    failed = run_mrsim(mrsim, [str(tank), "-o", "out.csv", "--set", "integrator.method=multirate", "--set",
                               "integrator.h_fast=1e-4", "--set", "integrator.h_slow=5e-3", "--set",
                               "output.dt=5e-3", "--set", "integrator.stability_check=.false.", "--set",
                               "integrator.coupling='full'"], tmp_path)
    assert failed.returncode == 2 and "at t = " in failed.stderr
    assert (tmp_path / "out.csv").read_bytes() == csv_before
    assert (tmp_path / "out.json").read_bytes() == json_before
    partial = json.loads((tmp_path / "out.json.partial").read_text())
    # the diverging run fails where its values first leave LAPACK's range (which matrix that
    # is depends on roundoff); the partial JSON carries that error and the time reached
    assert partial["status"] == "failed" and partial["error"] == failed.stderr.strip().removeprefix("mrsim: error: ")
    assert re.search(r"at t = .* s: .*(M_e|M_ff|mass matrix)", partial["error"])
    rows = [ln for ln in (tmp_path / "out.csv.partial").read_text().splitlines() if not ln.startswith("#")][1:]
    assert len(rows) >= 2 and float(rows[-1].split(",")[0]) <= partial["t_reached"] + 1e-12
    # every row the run wrote before it failed is on disk (none left in a buffer): as many
    # as the partial JSON counts, the last within one output step of the time reached
    assert len(rows) == partial["rows"] and float(rows[-1].split(",")[0]) > partial["t_reached"] - 5e-3 - 1e-12


@pytest.mark.parametrize("delay", [0.15, 0.45, 0.9])
def test_a_run_killed_at_any_moment_loses_nothing(tmp_path, mrsim, delay):
    """A run killed (SIGKILL) at a moment: the earlier complete result is untouched (unless
    the kill came after the run had put its own complete result in place, in the few
    milliseconds its statistics' rename and lock release take: then that result is the
    uninterrupted run's); the restart from the last checkpoint (if one was written) ends
    with results equal to an uninterrupted run's, row for row. The run takes about 0.5 s,
    so the 0.45 s kill can land there; files are compared as booleans, which pytest does
    not diff byte by byte."""
    import signal
    import time
    scene = ROOT / "input" / "hard" / "tank_long.nml"
    common = ["--quiet", "--set", "scene.t_end=40", "--set", "output.checkpoint_dt=2"]
    assert run_mrsim(mrsim, [str(scene), "-o", "full.csv", *common], tmp_path).returncode == 0
    earlier = run_mrsim(mrsim, [str(scene), "-o", "out.csv", "--quiet", "--set", "scene.t_end=1"], tmp_path)
    assert earlier.returncode == 0
    before = (tmp_path / "out.csv").read_bytes()
    job = subprocess.Popen([mrsim, str(scene), "-o", "out.csv", *common], cwd=tmp_path)
    time.sleep(delay)
    job.send_signal(signal.SIGKILL)
    job.wait(timeout=60)
    now = (tmp_path / "out.csv").read_bytes()
    if job.returncode == 0 or now != before:      # it finished first: a complete result
        same = now == (tmp_path / "full.csv").read_bytes()
        assert same
        assert not (tmp_path / "out.csv.partial").exists()
        return
    if (tmp_path / "out.ckpt").exists():
        again = run_mrsim(mrsim, [str(scene), "-o", "out.csv", *common, "--restart", "out.ckpt"], tmp_path)
        assert again.returncode == 0, again.stderr
        rows = [ln for ln in (tmp_path / "out.csv").read_text().splitlines() if not ln.startswith("#")]
        full = [ln for ln in (tmp_path / "full.csv").read_text().splitlines() if not ln.startswith("#")]
        assert rows == full
        assert not (tmp_path / "out.csv.partial").exists()


def test_open_models_keep_their_handles_however_many_are_open():
    """Nine models open at once (the handle table grows twice): each still answers with its
    own scene's right-hand side, equal to a fresh evaluation of it."""
    import numpy as np
    scenes = [ROOT / "input" / "pendulum.nml", ROOT / "input" / "double_pendulum.nml",
              ROOT / "input" / "tank_gun_turret.nml"]
    models = [pymr.Model(scenes[k % 3]) for k in range(9)]
    try:
        for k, model in enumerate(models):
            with pymr.Model(scenes[k % 3]) as fresh:
                x = 0.01 * np.arange(1, 2 * fresh.n + 1)
                assert np.array_equal(model.rhs(0.0, x), fresh.rhs(0.0, x))
    finally:
        for model in models:
            model.close()


def test_work_is_bounded_before_and_during_the_run(tmp_path):
    """A fixed-step run needing more than max_steps is refused before it starts (naming the
    count), an adaptive one stops at the limit with exit 2 and the time; results beyond
    max_bytes are refused; rtol below 100 machine epsilons is refused."""
    scene = tmp_path / "p.nml"
    scene.write_text(PENDULUM)
    with pytest.raises(pymr.SceneError, match=r"p.nml:\d+: &integrator: h_slow: the run would take 1e\+12 steps of "
                                               r"0.001 s to t_end = 1e\+9 s, more than max_steps = 100000000"):
        pymr.run(scene, overrides={"scene.t_end": 1e9})
    with pytest.raises(pymr.SolverError, match=r"at t = [\d.e+-]+ s: the run took more than max_steps = 50 steps"):
        pymr.run(scene, tmp_path / "a.csv", overrides={"integrator.adaptive": True, "integrator.max_steps": 50,
                                                        "scene.t_end": 10.0})
    with pytest.raises(pymr.SceneError, match=r"&output: dt: the results would take about [\d.e+]+ bytes "
                                               r"\([\d.e+]+ rows\), more than max_bytes = 1e\+6"):
        pymr.run(scene, overrides={"scene.t_end": 1000.0, "output.max_bytes": 1e6})
    with pytest.raises(pymr.SceneError, match=r"rtol: must be in \[2.22045e-14, 1\], got 1e-15"):
        pymr.run(scene, overrides={"integrator.adaptive": True, "integrator.rtol": 1e-15})


def test_two_runs_never_write_the_same_results(tmp_path, mrsim):
    """While a run writes out.csv it holds out.csv.lock (its process id): a second run to the
    same output is refused with exit 1, and runs after it (or after a killed run, whose lock
    names a process that no longer lives) go ahead."""
    import time
    scene = ROOT / "input" / "hard" / "tank_long.nml"
    first = subprocess.Popen([mrsim, str(scene), "-o", "out.csv", "--quiet"], cwd=tmp_path)
    for _ in range(200):
        if (tmp_path / "out.csv.lock").exists():
            break
        time.sleep(0.005)
    second = run_mrsim(mrsim, [str(scene), "-o", "out.csv", "--set", "scene.t_end=1"], tmp_path)
    assert first.wait(timeout=120) == 0
    assert second.returncode == 1, second.stderr
    assert f"another run (process {first.pid}) is writing these results" in second.stderr
    assert not (tmp_path / "out.csv.lock").exists()
    (tmp_path / "out.csv.lock").write_text("999999999\n")          # a dead process's lock
    again = run_mrsim(mrsim, [str(scene), "-o", "out.csv", "--quiet", "--set", "scene.t_end=1"], tmp_path)
    assert again.returncode == 0, again.stderr
    assert not (tmp_path / "out.csv.lock").exists()


def test_wrong_shapes_and_closed_models_raise_pymr_errors_naming_the_argument():
    import numpy as np
    tank = ROOT / "input" / "tank_gun_turret.nml"
    n = pymr.model_size(tank)[0]
    with pytest.raises(ValueError, match=r"qd: shape \(5,\) differs from q's \(6,\)"):
        pymr.model_terms(tank, np.zeros(n), np.zeros(n - 1))
    with pytest.raises(ValueError, match=r"qd: shape"):
        pymr.model_energy(tank, np.zeros((3, n)), np.zeros((2, n)))
    model = pymr.Model(tank)
    with pytest.raises(ValueError, match=rf"x: the state \[q; qd\] of shape \({2 * n},\) expected, got shape \(3,\)"):
        model.rhs(0.0, np.zeros(3))
    model.close()
    with pytest.raises(pymr.PymrError, match=r"closed|no open model"):
        model.rhs(0.0, np.zeros(2 * n))


def test_an_output_folder_that_cannot_be_written_is_refused_before_the_run(tmp_path, mrsim):
    """A missing folder, and a 'folder' that is a file: exit 1 before anything runs, one line
    naming the output and its folder; nothing is created."""
    scene = tmp_path / "p.nml"
    scene.write_text(PENDULUM)
    (tmp_path / "plain").write_text("a file, not a folder\n")
    for out, reason in ((tmp_path / "missing" / "out.csv", f"the folder '{tmp_path / 'missing'}' does not exist"),
                        (tmp_path / "plain" / "out.csv", f"'{tmp_path / 'plain'}' is not a folder")):
        r = run_mrsim(mrsim, [str(scene), "-o", str(out)], tmp_path)
        assert r.returncode == 1 and r.stderr.count("\n") == 1, r.stderr
        assert r.stderr.startswith(f"mrsim: error: {scene}: output {out}: {reason}"), r.stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["p.nml", "plain"]


def test_files_to_read_that_are_no_regular_files_are_refused_without_waiting(tmp_path, mrsim):
    """A scene, a table file or a checkpoint that is a FIFO would hold the read until
    something writes to it (mrsim hung); a directory cannot be read either. Exit 1 at once,
    one line naming the file and what it is. A loop of symbolic links and a link to nothing
    were 'not found', and said nothing of the link."""
    import os
    os.mkfifo(tmp_path / "fifo")
    (tmp_path / "folder").mkdir()
    os.symlink("loop", tmp_path / "loop")
    os.symlink("nothing", tmp_path / "dangling")
    scene = tmp_path / "p.nml"
    scene.write_text(PENDULUM)
    table = tmp_path / "t.nml"
    table.write_text(PENDULUM.replace("gravity = .true.", "gravity = .true., joint_drives = .true.")
                     + "&drive joint = 'pivot', form = 'table', file = 'fifo' /\n")
    fifo = "it is not a regular file (a FIFO, a socket or a device)"
    for args, message in ((["fifo"], "fifo: cannot read: " + fifo),
                          (["folder"], "folder: cannot read: it is a directory"),
                          (["t.nml"], "t.nml:28: &drive #1: file: 'fifo' cannot be read: " + fifo),
                          (["p.nml", "--restart", "fifo"], "p.nml: fifo: cannot read the checkpoint: " + fifo),
                          (["loop"], "loop: cannot read: it is a loop of symbolic links"),
                          (["dangling"], "dangling: cannot read: it is a symbolic link to nothing"),
                          (["p.nml", "--restart", "loop"],
                           "p.nml: loop: cannot read the checkpoint: it is a loop of symbolic links")):
        r = subprocess.run([mrsim, *args, "-o", "out.csv"], cwd=tmp_path, capture_output=True, text=True, timeout=20)
        assert r.returncode == 1 and r.stderr.count("\n") == 1, r.stderr
        assert r.stderr == "mrsim: error: " + message + "\n"
    assert not (tmp_path / "out.csv").exists()


def test_an_output_that_is_no_regular_file_is_refused_before_the_run(tmp_path, mrsim, monkeypatch):
    """The results, their statistics and the checkpoints are written beside their place and
    renamed over it: a directory there failed only after the run, leaving partial files, and
    a device (as root, -o /dev/null) was replaced by a regular file. Exit 1 before anything
    is written, one line."""
    import os
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.nml").write_text(PENDULUM)
    os.mkfifo(tmp_path / "fifo.csv")
    for name in ("folder.csv", "stats.json", "run.ckpt", "ckpt"):
        (tmp_path / name).mkdir()
    before = sorted(p.name for p in tmp_path.iterdir())
    for args, message in (
            (["-o", "folder.csv"], "p.nml: output folder.csv: it is a directory; choose another results file"),
            (["-o", "fifo.csv"], "p.nml: output fifo.csv: it is not a regular file (a FIFO, a socket or a device); "
                                 "choose another results file"),
            (["-o", "stats.csv"], "p.nml: output stats.csv: its statistics stats.json: it is a directory; "
                                  "choose another results file"),
            (["-o", "run.csv", "--set", "output.checkpoint_dt=0.01"],
             "p.nml: output run.csv: its checkpoint run.ckpt: it is a directory; choose another results file, "
             "or a checkpoint_file in &output"),
            (["-o", "out.csv", "--set", "output.checkpoint_dt=0.01", "--set", "output.checkpoint_file=ckpt"],
             "p.nml: --set output.checkpoint_file=ckpt: &output: checkpoint_file: it is a directory; "
             "choose another checkpoint file")):
        r = run_mrsim(mrsim, ["p.nml", *args], tmp_path)
        assert r.returncode == 1 and r.stderr == "mrsim: error: " + message + "\n", r.stderr
        with pytest.raises(pymr.SceneError, match="^" + re.escape(message) + "$"):
            pymr.run("p.nml", args[1], overrides=args[3::2] or None)
        assert sorted(p.name for p in tmp_path.iterdir()) == before


def test_a_checkpoint_where_no_file_can_be_made_is_refused_before_the_run(tmp_path, mrsim, monkeypatch):
    """A checkpoint_file in /sys (as root, access() lets one write there, but sysfs takes no new
    file) ran to its first checkpoint: exit 2 with gfortran's "Cannot open file ...:
    Permission denied", no &output item named, and OUT.csv.partial left. Refused as the
    results' folder is, exit 1 before anything is written, naming &output checkpoint_file (on
    its line, from the scene or --set); -o in /sys in the same words. A staging file
    CKPT.tmp that is a directory failed at the first checkpoint too."""
    if not os.path.isdir("/sys"):
        pytest.skip("no /sys")
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.nml").write_text(PENDULUM)
    (tmp_path / "s.nml").write_text(PENDULUM.replace("&output dt = 0.01 /", "&output dt = 0.01,\n"
                                                      "  checkpoint_dt = 0.01, checkpoint_file = '/sys/c.ckpt' /"))
    line = PENDULUM.splitlines().index("&output dt = 0.01 /") + 2
    (tmp_path / "c.ckpt.tmp").mkdir()
    (tmp_path / "out.ckpt.tmp").mkdir()
    before = sorted(p.name for p in tmp_path.iterdir())
    folder = "cannot make files in its folder '/sys' (Permission denied); choose another "
    for scene, args, message in (
            ("p.nml", ["-o", "out.csv", "--set", "output.checkpoint_dt=0.01", "--set",
                       "output.checkpoint_file='/sys/c.ckpt'"],
             "p.nml: --set output.checkpoint_file='/sys/c.ckpt': &output: checkpoint_file: " + folder +
             "checkpoint_file or a folder it can write"),
            ("s.nml", ["-o", "out.csv"],
             f"s.nml:{line}: &output: checkpoint_file: " + folder + "checkpoint_file or a folder it can write"),
            ("p.nml", ["-o", "/sys/c.csv"], "p.nml: output /sys/c.csv: " + folder + "output or a folder it can write"),
            ("p.nml", ["-o", "out.csv", "--set", "output.checkpoint_dt=0.01", "--set", "output.checkpoint_file=c.ckpt"],
             "p.nml: --set output.checkpoint_file=c.ckpt: &output: checkpoint_file: the run's file c.ckpt.tmp: it is "
             "a directory; choose another checkpoint file"),
            ("p.nml", ["-o", "out.csv", "--set", "output.checkpoint_dt=0.01"],
             "p.nml: output out.csv: the run's file out.ckpt.tmp: it is a directory; choose another results file, "
             "or a checkpoint_file in &output")):
        r = run_mrsim(mrsim, [scene, *args], tmp_path)
        assert r.returncode == 1 and r.stderr == "mrsim: error: " + message + "\n", r.stderr
        with pytest.raises(pymr.SceneError, match="^" + re.escape(message) + "$"):
            pymr.run(scene, args[1], overrides=args[3::2] or None)
        assert sorted(p.name for p in tmp_path.iterdir()) == before
        assert not os.path.exists("/sys/c.ckpt") and not os.path.exists("/sys/c.ckpt.tmp")


def test_a_checkpoint_that_cannot_be_written_mid_run_is_said_in_pymrs_words(tmp_path, mrsim):
    """The checkpoint's folder removed while the run goes on (stopped after its start, before
    its first checkpoint): exit 2, one line naming the time and the system's reason, not the
    run-time library's message ("Cannot open file 'ck/p.ckpt.tmp': No such file or
    directory")."""
    (tmp_path / "p.nml").write_text(PENDULUM)
    (tmp_path / "ck").mkdir()
    args = [mrsim, "p.nml", "-o", "p.csv", "--quiet", "--set", "scene.t_end=2000", "--set", "output.dt=100",
            "--set", "output.checkpoint_dt=1000", "--set", "output.checkpoint_file='ck/p.ckpt'"]
    proc = subprocess.Popen(args, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        deadline = time.monotonic() + 60
        while not (tmp_path / "p.csv.partial").exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(1e-4)
        os.kill(proc.pid, signal.SIGSTOP)
        assert not any((tmp_path / "ck").iterdir()), "the first checkpoint came before the stop"
        shutil.rmtree(tmp_path / "ck")
    finally:
        os.kill(proc.pid, signal.SIGCONT)
        out, err = proc.communicate(timeout=120)
    assert proc.returncode == 2, err
    assert err == "mrsim: error: p.nml: at t = 1000 s: ck/p.ckpt: cannot write the checkpoint (No such file or " \
                  "directory)\n", err


def test_results_of_the_other_format_keep_their_statistics(tmp_path, mrsim, monkeypatch):
    """OUT.csv and OUT.h5 share the statistics file OUT.json: a run to out.h5 replaced the
    statistics of a complete out.csv, which then no longer loaded ('1001 rows of the 501
    the run wrote'; found by an audit of kills). Refused before the run, one line, for
    either format; out.csv and its statistics stay as they were and still load, and a run
    to out.csv itself goes on replacing them."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.nml").write_text(PENDULUM)
    first = pymr.run("p.nml", "out.csv")
    kept = {name: (tmp_path / name).read_bytes() for name in ("out.csv", "out.json")}
    for name in ("out.h5", "out.hdf5"):
        message = (f"p.nml: output {name}: its statistics out.json are those of out.csv, which would no longer "
                   "load: give another name, or remove out.csv")
        r = run_mrsim(mrsim, ["p.nml", "-o", name, "--set", "output.format='hdf5'"], tmp_path)
        assert r.returncode == 1 and r.stderr == "mrsim: error: " + message + "\n", r.stderr
        with pytest.raises(pymr.SceneError, match="^" + re.escape(message) + "$"):
            pymr.run("p.nml", name, overrides={"output.format": "hdf5"})
    assert {name: (tmp_path / name).read_bytes() for name in kept} == kept
    assert np.array_equal(pymr.load_results("out.csv").data, first.data)
    assert run_mrsim(mrsim, ["p.nml", "-o", "out.csv", "--set", "scene.t_end=0.5"], tmp_path).returncode == 0
    assert pymr.load_results("out.csv").t[-1] == 0.5


LINK = "it is a symbolic link, which the finished file, renamed into place, would replace (not the file it points to)"


def test_an_output_that_is_a_symbolic_link_is_refused_and_kept(tmp_path, mrsim, monkeypatch):
    """Every file is written whole beside its place and renamed over it, and a rename replaces
    a link, not the file it points to: -o link.csv left link.csv a plain file and its target
    as it was, and with stdout sent to a file `mrsim -o /dev/stdout` replaced /dev/stdout (a
    link) and exited 0 (found by fuzzing). A link is refused like a device, before the run,
    and it and its target are left as they were."""
    import os
    monkeypatch.chdir(tmp_path)
    (tmp_path / "p.nml").write_text(PENDULUM)
    for name in ("target.csv", "target.json", "target.ckpt"):
        (tmp_path / name).write_text("earlier\n")
    for link, target in (("link.csv", "target.csv"), ("stats.json", "target.json"), ("run.ckpt", "target.ckpt"),
                         ("ckpt", "target.ckpt")):
        os.symlink(target, tmp_path / link)
    before = {p.name: (p.is_symlink(), p.read_text()) for p in tmp_path.iterdir()}
    for args, message in (
            (["-o", "link.csv"], f"p.nml: output link.csv: {LINK}; choose another results file"),
            (["-o", "stats.csv"], f"p.nml: output stats.csv: its statistics stats.json: {LINK}; "
                                  "choose another results file"),
            (["-o", "run.csv", "--set", "output.checkpoint_dt=0.01"],
             f"p.nml: output run.csv: its checkpoint run.ckpt: {LINK}; choose another results file, "
             "or a checkpoint_file in &output"),
            (["-o", "out.csv", "--set", "output.checkpoint_dt=0.01", "--set", "output.checkpoint_file=ckpt"],
             f"p.nml: --set output.checkpoint_file=ckpt: &output: checkpoint_file: {LINK}; "
             "choose another checkpoint file")):
        r = run_mrsim(mrsim, ["p.nml", *args], tmp_path)
        assert r.returncode == 1 and r.stderr == "mrsim: error: " + message + "\n", r.stderr
        with pytest.raises(pymr.SceneError, match="^" + re.escape(message) + "$"):
            pymr.run("p.nml", args[1], overrides=args[3::2] or None)
        assert {p.name: (p.is_symlink(), p.read_text()) for p in tmp_path.iterdir()} == before
    # the Python writers: a scene written out, and the command line's own outputs
    with pytest.raises(pymr.OutputError, match="^" + re.escape(f"path link.csv: {LINK}; choose another scene file")):
        pymr.Scene("p.nml").write("link.csv")
    r = subprocess.run([sys.executable, "-m", "pymr", "modal-file", "p.nml", "bob", "-o", "link.csv"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and r.stderr == f"pymr: error: -o link.csv: {LINK}; choose another modal file\n", r.stderr
    assert {p.name: (p.is_symlink(), p.read_text()) for p in tmp_path.iterdir()} == before
    # /dev/stdout is a link too; with stdout sent to a file the device check alone let it through
    with open(tmp_path / "so.txt", "w") as out:
        r = subprocess.run([str(mrsim), "p.nml", "-o", "/dev/stdout"], cwd=tmp_path, stdout=out, stderr=subprocess.PIPE,
                           text=True, timeout=120)
    assert r.returncode == 1 and r.stderr.startswith("mrsim: error: p.nml: output /dev/stdout: it is a symbolic link")
    assert os.path.islink("/dev/stdout") and not os.path.exists("/dev/stdout.json")


def _file_size_limit(limit: int):
    """preexec_fn: files may not grow beyond `limit` bytes, and writing past it fails with
    EFBIG instead of killing the process (SIGXFSZ ignored): a full disk, as the run sees it."""
    import resource
    import signal

    def apply():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))
    return apply


def test_a_full_disk_is_a_failed_run_naming_the_file_and_the_time(tmp_path, mrsim):
    """Results larger than the disk allows (RLIMIT_FSIZE of 200 kB, SIGXFSZ ignored): exit 2,
    one line naming the partial results file and the simulated time reached; the earlier
    complete result is untouched; the partial rows that fit stay under their partial name."""
    scene = ROOT / "input" / "hard" / "tank_long.nml"
    assert run_mrsim(mrsim, [str(scene), "-o", "out.csv", "--quiet", "--set", "scene.t_end=0.5"],
                     tmp_path).returncode == 0
    before = (tmp_path / "out.csv").read_bytes()
    r = subprocess.run([mrsim, str(scene), "-o", "out.csv", "--quiet", "--set", "scene.t_end=20"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=300, preexec_fn=_file_size_limit(200_000))
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "out.csv.partial: cannot write the results" in r.stderr, r.stderr
    t_failed = float(r.stderr.split("at t = ")[1].split(" s")[0])
    assert 0.0 < t_failed < 20.0
    assert (tmp_path / "out.csv").read_bytes() == before
    assert 0 < (tmp_path / "out.csv.partial").stat().st_size <= 200_000
    assert not (tmp_path / "out.csv.lock").exists()


def _rows(path: Path) -> np.ndarray:
    return np.loadtxt(path, delimiter=",", comments="#", skiprows=4)


def test_fifty_kills_at_random_moments_lose_nothing(tmp_path, mrsim):
    """SIGKILL at 50 random moments of runs and of restarts (a third of the restarts killed in
    their first 30 ms, among their first rows; with a checkpoint every simulated second, 40 in
    a run of about 0.8 s, many kills land inside a checkpoint write). After every kill the
    earlier complete result is byte for byte what it was; each restart continues from the
    last checkpoint left whole. The result finally completed equals the uninterrupted run to
    1e-10 (measured: identical)."""
    import random
    import signal
    import time
    scene = ROOT / "input" / "hard" / "tank_long.nml"
    common = ["--quiet", "--set", "scene.t_end=40", "--set", "output.checkpoint_dt=1"]
    assert run_mrsim(mrsim, [str(scene), "-o", "full.csv", *common], tmp_path).returncode == 0
    full = _rows(tmp_path / "full.csv")
    assert run_mrsim(mrsim, [str(scene), "-o", "out.csv", "--quiet", "--set", "scene.t_end=1"],
                     tmp_path).returncode == 0
    complete = (tmp_path / "out.csv").read_bytes()
    rng = random.Random(15)
    kills = restarts_killed = 0
    while kills < 50:
        restart = (tmp_path / "out.ckpt").exists()
        args = [str(scene), "-o", "out.csv", *common] + (["--restart", "out.ckpt"] if restart else [])
        delay = rng.uniform(0.0, 0.03) if restart and rng.random() < 1 / 3 else rng.uniform(0.0, 0.9)
        job = subprocess.Popen([mrsim, *args], cwd=tmp_path, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
        time.sleep(delay)
        job.send_signal(signal.SIGKILL)
        _, err = job.communicate(timeout=120)
        if job.returncode == 0:             # it finished first: a new complete result
            assert np.allclose(_rows(tmp_path / "out.csv"), full, rtol=1e-10, atol=1e-12)
            complete = (tmp_path / "out.csv").read_bytes()
            (tmp_path / "out.ckpt").unlink()
            continue
        assert job.returncode == -signal.SIGKILL, err
        kills += 1
        restarts_killed += restart
        assert (tmp_path / "out.csv").read_bytes() == complete
    assert restarts_killed >= 10
    last = ["--restart", "out.ckpt"] if (tmp_path / "out.ckpt").exists() else []
    r = run_mrsim(mrsim, [str(scene), "-o", "out.csv", *common, *last], tmp_path)
    assert r.returncode == 0, r.stderr
    assert np.allclose(_rows(tmp_path / "out.csv"), full, rtol=1e-10, atol=1e-12)
    assert not (tmp_path / "out.csv.partial").exists() and not (tmp_path / "out.csv.lock").exists()


@pytest.mark.parametrize("q, qd, routine", [(0.0, 1e200, "dpotrs: the right-hand side for the mass matrix"),
                                            (1e200, 0.0, "dpotrf: the mass matrix")])
def test_non_finite_values_never_reach_lapack(q, qd, routine):
    """States whose terms overflow (velocities of 1e200, coordinates of 1e200 whose sines
    are NaN): the accelerations raise pymr's SolverError naming the LAPACK routine and the
    matrix that would have received the non-finite entry, instead of calling LAPACK. A NaN
    state itself is bad input, named as q or qd before the kernel sees it (issue 30)."""
    tank = ROOT / "input" / "tank_gun_turret.nml"
    with pytest.raises(pymr.SolverError, match=rf"{routine} has a non-finite entry \(NaN\); not solved"):
        pymr.model_accelerations(tank, 0.0, np.full(6, q), np.full(6, qd))
    with pytest.raises(pymr.SceneError, match=r"^qd: nan is not a finite number$"):
        pymr.model_accelerations(tank, 0.0, np.full(6, q), np.full(6, np.nan))


def test_a_modal_file_never_overwrites_the_scene_and_is_written_whole(tmp_path, monkeypatch):
    """`pymr modal-file SCENE BODY -o SCENE` replaced the scene with the modal data (found by
    fuzzing the command line); the kernel now refuses an output that is one of the scene's
    inputs, as for results, and writes the file whole (a directory in its place is refused,
    no temporary file is left)."""
    scene = tmp_path / "chain.nml"
    scene.write_bytes((ROOT / "input" / "flexible_chain.nml").read_bytes())
    before = scene.read_bytes()
    for out in ("chain.nml", "./chain.nml"):
        r = subprocess.run(["pymr", "modal-file", "chain.nml", "link1", "-o", out], cwd=tmp_path, capture_output=True,
                           text=True, timeout=60)
        assert r.returncode == 1, r.stderr
        assert r.stderr == (f"pymr: error: -o {out}: would overwrite the scene (chain.nml); "
                            "choose another modal file\n")
        assert scene.read_bytes() == before
    (tmp_path / "folder").mkdir()
    monkeypatch.chdir(tmp_path)
    with pytest.raises(pymr.OutputError, match=r"^path folder: is a folder, not a file"):
        pymr.write_modal_file(scene, "link1", "folder")
    with pytest.raises(pymr.OutputError, match=r"^path chain.nml: would overwrite the scene \(.*chain.nml\)"):
        pymr.write_modal_file(scene, "link1", "chain.nml")
    pymr.write_modal_file(scene, "link1", tmp_path / "link1.modal")
    assert (tmp_path / "link1.modal").read_text().splitlines()[2] == "pymr-modal 1"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["chain.nml", "folder", "link1.modal"]


def test_states_that_are_not_finite_are_refused_not_returned_as_nan():
    """model_terms, model_energy and Model.marker returned NaN for a NaN or infinite state
    with no word (found by fuzzing the API); they raise SceneError naming the argument, and
    times that do not match the states are named too."""
    scene = ROOT / "input" / "pendulum.nml"
    with pytest.raises(pymr.SceneError, match=r"^q: nan is not a finite number$"):
        pymr.model_terms(scene, [np.nan], [0.0])
    with pytest.raises(pymr.SceneError, match=r"^qd: inf is not a finite number$"):
        pymr.model_energy(scene, [[0.1]], [[np.inf]])
    with pymr.Model(scene) as model:
        with pytest.raises(pymr.SceneError, match=r"^q: nan is not a finite number$"):
            model.marker("tip", 0.0, [np.nan], [0.0])
        with pytest.raises(ValueError, match=r"^t: one time per state expected, shape \(2,\), got shape \(3,\)$"):
            model.marker("tip", [0.0, 1.0, 2.0], [[0.1], [0.2]], [[0.0], [0.0]])
        with pytest.raises(ValueError, match=r"^q: states of 1 coordinates expected, got 2$"):
            model.frames(0.0, [0.1, 0.2], [0.0, 0.0], 2)
        assert np.isfinite(model.marker("tip", [0.0, 1.0], [[0.1], [0.2]], [[0.0], [0.0]])).all()
    with pytest.raises(pymr.SceneError, match=r"^t: a time in seconds, got \[\]$"):
        pymr.modes(scene, [0.1], [0.0], t=[])


@pytest.mark.parametrize("max_steps", [0, -5, 10**12, 2.5, True])
def test_step_history_takes_a_whole_count_of_steps(max_steps):
    """step_history(max_steps=10**12) raised f2py's OverflowError, -5 its ValueError about an
    'intent(cache|hide)' array, 0 'the run takes more than 0 steps' (found by fuzzing the API)."""
    with pytest.raises(pymr.SceneError, match=rf"^max_steps: a whole number from 1 to 2147483646, got "
                                              rf"{re.escape(repr(max_steps))}$"):
        pymr.step_history(ROOT / "input" / "pendulum.nml", max_steps=max_steps)


def test_step_history_makes_room_as_the_run_needs_it(monkeypatch):
    """step_history(max_steps=2**31 - 2) made arrays of that many entries first: numpy's
    MemoryError under a 4 GB limit, the process killed without one (found by the second
    bad-input audit). Its room now doubles while the run needs more: the largest count
    gives the default's history, and so does a first room of 1000 steps (the run taken
    again four times)."""
    import pymr.api
    scene = ROOT / "input" / "pendulum.nml"
    want = pymr.step_history(scene)
    assert len(want[0]) > 5000
    for room in (pymr.api.HISTORY_ROOM, 1000):
        monkeypatch.setattr(pymr.api, "HISTORY_ROOM", room)
        got = pymr.step_history(scene, max_steps=2**31 - 2)
        assert all(np.array_equal(a, b) for a, b in zip(got, want))
    with pytest.raises(pymr.SolverError, match=r"^max_steps: the run takes more than 5000 steps"):
        pymr.step_history(scene, max_steps=5000)


def test_model_terms_that_overflow_are_a_solver_error_not_nan():
    """model_terms at velocities of 1e300 returned P = NaN with no word (found by fuzzing the
    API; the accelerations refuse the same state): the kernel checks M and P and names the
    coordinate."""
    scene = ROOT / "input" / "pendulum.nml"
    with pytest.raises(pymr.SolverError, match=r"^at t = 0.00000E\+00 s: non-finite mass matrix or force term of "
                                               r"coordinate pivot.q \(the state or a load is out of range\)$"):
        pymr.model_terms(scene, [1e300], [1e300])
    mm, p = pymr.model_terms(scene, [0.1], [0.0])
    assert np.isfinite(mm).all() and np.isfinite(p).all()


def test_marker_shapes_names_shapes_of_the_wrong_shape():
    """marker_shapes raised 'IndexError: tuple index out of range' for shapes that are not an
    array (n, modes) (found by fuzzing the API)."""
    scene = ROOT / "input" / "pendulum.nml"
    for shapes, got in [(np.zeros(3), r"\(3,\)"), (None, r"\(\)"), (np.ones((2, 1)), r"\(2, 1\)")]:
        with pytest.raises(ValueError, match=rf"^shapes: an array \(1, modes\) expected \(modes\(\) gives one\), "
                                             rf"got shape {got}$"):
            pymr.marker_shapes(scene, ["tip"], [0.1], [0.0], shapes)
    moves = pymr.marker_shapes(scene, ["tip"], [0.1], [0.0], np.ones((1, 1)))
    assert moves["tip"].shape == (3, 1) and np.isfinite(moves["tip"]).all()


def test_a_run_failing_in_its_start_keeps_its_partial_files_not_an_earlier_run_s(tmp_path, mrsim):
    """A fixed-step run whose start-up steps failed (a 1e12 N m/rad spring at 1e6 rad/s)
    removed its partial file as a refused run does, and left an earlier failed run's
    OUT.json.partial describing rows no longer there. Now it is a failed run: its partial
    file holds its first row and its statistics say so."""
    sets = ["effects.joint_springs=.true.", "spring[traverse].stiffness=1e12", "integrator.stability_check=.false.",
            "output.dt=0"]
    scene = ROOT / "input" / "tank_effects.nml"
    first = run_mrsim(mrsim, [str(scene), "-o", "f.csv", *[a for s in sets + ["joint[traverse].qd0=1"]
                                                           for a in ("--set", s)]], tmp_path)
    assert first.returncode == 2 and json.loads((tmp_path / "f.json.partial").read_text())["rows"] > 10
    r = run_mrsim(mrsim, [str(scene), "-o", "f.csv", *[a for s in sets + ["joint[traverse].qd0=1e6"]
                                                       for a in ("--set", s)]], tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "at t = 2.00000E-04 s: " in r.stderr, r.stderr
    stats = json.loads((tmp_path / "f.json.partial").read_text())
    rows = [line for line in (tmp_path / "f.csv.partial").read_text().splitlines() if line[:1].isdigit()]
    assert stats["status"] == "failed" and stats["rows"] == len(rows) == 1
    assert stats["overrides"][-1] == "joint[traverse].qd0=1e6" and not (tmp_path / "f.csv").exists()


@pytest.mark.parametrize("program", ["mrsim", "pymr run"])
@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_run_stops_in_one_line_and_keeps_the_earlier_results(tmp_path, mrsim, program, sig):
    """Ctrl-C (SIGINT) or SIGTERM during a run. pymr run went on to the run's end, replaced
    the earlier results and only then printed a KeyboardInterrupt traceback; mrsim died with
    no line, its lock left behind (found by an audit of kills). Now the run stops after the
    step it is in, as a failed run: exit 2, one line naming the time and the signal, the
    earlier complete results byte for byte as they were, the rows so far in the partial
    file (every one a row of the same run as the complete one, to its time), no lock left."""
    scene = tmp_path / "tank.nml"
    scene.write_text(TANK.read_text())
    out = tmp_path / "out.csv"
    pymr.run(scene, out, overrides={"scene.t_end": 0.2})
    kept = {p.name: p.read_bytes() for p in (out, tmp_path / "out.json")}
    command = [mrsim] if program == "mrsim" else [sys.executable, "-m", "pymr", "run"]
    p = subprocess.Popen([*command, str(scene), "-o", str(out), "-q", "--set", "scene.t_end=1e4"], cwd=tmp_path,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    partial = tmp_path / "out.csv.partial"
    deadline = time.monotonic() + 60
    while not (partial.exists() and partial.stat().st_size > 100_000) and time.monotonic() < deadline:
        time.sleep(0.05)
    p.send_signal(sig)
    _, err = p.communicate(timeout=60)
    name = {signal.SIGINT: "SIGINT", signal.SIGTERM: "SIGTERM"}[sig]
    assert p.returncode == 2 and err.count("\n") == 1 and "Traceback" not in err, (p.returncode, err)
    assert re.search(rf"error: {re.escape(str(scene))}: at t = \S+ s: stopped by {name} \(the rows so far are kept "
                     r"in the partial results file\)$", err.strip()), err
    assert {name_: (tmp_path / name_).read_bytes() for name_ in kept} == kept
    assert not (tmp_path / "out.csv.lock").exists()
    rows = np.loadtxt(partial, delimiter=",", comments="#", skiprows=4)
    t_stop = float(re.search(r"at t = (\S+) s", err).group(1))
    assert rows[-1, 0] <= t_stop and np.array_equal(rows[:len(pymr.load_results(out).t)], pymr.load_results(out).data)


@pytest.mark.parametrize("sig", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_command_says_so_in_one_line(tmp_path, sig):
    """Ctrl-C to any pymr command printed a KeyboardInterrupt traceback of 9-74 lines, and
    SIGTERM ended it with no line at all (found by an audit of kills). pymr animate of 200
    frames (about 20 s) stopped after 2 s: one line naming the signal, exit 2, no animation
    in place and the earlier one kept."""
    out = tmp_path / "t.csv"
    pymr.run(TANK, out, overrides={"scene.t_end": 0.3})
    gif = tmp_path / "t.gif"
    gif.write_bytes(b"GIF89a earlier")
    p = subprocess.Popen([sys.executable, "-m", "pymr", "animate", str(out), "-o", str(gif)], cwd=tmp_path,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(2.0)
    p.send_signal(sig)
    _, err = p.communicate(timeout=60)
    name = {signal.SIGINT: "SIGINT", signal.SIGTERM: "SIGTERM"}[sig]
    assert p.returncode == 2 and err == (f"pymr: error: stopped by {name} (a file it was writing is not in place; "
                                         "an earlier one is kept)\n"), (p.returncode, err)
    assert gif.read_bytes() == b"GIF89a earlier"


def test_a_dead_run_s_lock_is_taken_over_by_one_run_only(tmp_path, mrsim):
    """Two runs started together beside a killed run's lock each removed it and made their
    own: both wrote one partial file, one exited 2 ('the disk took 237720 of 237717 bytes')
    and the other renamed a mix of the two over the earlier results (2 times in 40; found
    by an audit of kills). The lock is now an flock the system drops with its process: 20
    times, two runs of different lengths started together beside a stale lock (and a lock
    naming a living process that holds no lock: a reused process id) leave the results of
    one of them, whole, and a run refused says which process holds the lock."""
    (tmp_path / "p.nml").write_text(PENDULUM)
    want = {}
    for t_end in ("0.6", "0.9"):
        r = run_mrsim(mrsim, ["p.nml", "-o", f"ref{t_end}.csv", "-q", "--set", f"scene.t_end={t_end}"], tmp_path)
        assert r.returncode == 0, r.stderr
        want[t_end] = pymr.load_results(tmp_path / f"ref{t_end}.csv").data
    for attempt in range(20):
        (tmp_path / "out.csv.lock").write_text("999999999\n" if attempt % 2 else f"{os.getppid()}\n")
        runs = [subprocess.Popen([mrsim, "p.nml", "-o", "out.csv", "-q", "--set", f"scene.t_end={t_end}"],
                                 cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
                for t_end in want]
        for p in runs:
            _, err = p.communicate(timeout=60)
            assert p.returncode == 0 or (p.returncode == 1 and "another run (process " in err), (p.returncode, err)
        got = pymr.load_results(tmp_path / "out.csv").data
        assert any(np.array_equal(got, w) for w in want.values())
        assert not (tmp_path / "out.csv.lock").exists()


def test_results_and_statistics_of_different_runs_are_not_loaded_as_one(tmp_path, mrsim):
    """A kill between the renames of OUT.csv and OUT.json left the new rows beside the old
    statistics: with as many rows they loaded as one run, the statistics describing the
    other (found by an audit of kills, strace killing the second rename). The statistics
    now name the file's size and last row: two runs of one length that differ in their
    start are told apart, either way round, and each file still loads with its own."""
    (tmp_path / "p.nml").write_text(PENDULUM)
    for name, q0 in (("a", "1.0"), ("b", "0.5")):
        r = run_mrsim(mrsim, ["p.nml", "-o", f"{name}.csv", "-q", "--set", f"joint[pivot].q0={q0}"], tmp_path)
        assert r.returncode == 0, r.stderr
    a, b = (pymr.load_results(tmp_path / f"{n}.csv") for n in "ab")
    assert len(a.t) == len(b.t) and not np.array_equal(a.data, b.data)
    stats = json.loads((tmp_path / "a.json").read_text())
    assert stats["results_bytes"] == (tmp_path / "a.csv").stat().st_size
    assert stats["last_row"] == (tmp_path / "a.csv").read_text().splitlines()[-1]
    for rows, statistics in (("b", "a"), ("a", "b")):
        mixed = tmp_path / f"{rows}_with_{statistics}.csv"
        shutil.copy(tmp_path / f"{rows}.csv", mixed)
        shutil.copy(tmp_path / f"{statistics}.json", mixed.with_suffix(".json"))
        with pytest.raises(pymr.ResultsError, match=rf"^{re.escape(str(mixed))}: {mixed.stem}\.json describes "
                                                    r"another run's results \(\d+ bytes, this file \d+, and another "
                                                    r"last row\): the two were not written together"):
            pymr.load_results(mixed)


def test_a_set_of_files_is_put_in_place_only_when_each_is_written_whole(tmp_path, monkeypatch):
    """write_files (a study's table, figure and step histories): a write failing at the
    second file leaves the three earlier files byte for byte and no temporary file; a
    complete write replaces all three. Before, the table was replaced, then seconds of
    plotting, then the figure: a kill between left a new table beside an old figure."""
    from pymr import _args
    paths = [tmp_path / name for name in ("s.csv", "s.png", "s_history.csv")]
    for p in paths:
        p.write_text(f"earlier {p.name}\n")
    calls = []
    synced = _args._write_synced

    def fails_at_second(tmp, data, path, what):
        calls.append(path.name)
        if len(calls) == 2:
            raise pymr.OutputError(f"{path}: cannot write the {what} (No space left on device)")
        synced(tmp, data, path, what)
    monkeypatch.setattr(_args, "_write_synced", fails_at_second)
    with pytest.raises(pymr.OutputError, match=r"s\.png: cannot write the figure \(No space left on device\)"):
        _args.write_files([(p, f"new {p.name}\n", w) for p, w in zip(paths, ("table", "figure", "histories"))])
    assert [p.read_text() for p in paths] == [f"earlier {p.name}\n" for p in paths]
    assert sorted(os.listdir(tmp_path)) == sorted(p.name for p in paths)
    monkeypatch.setattr(_args, "_write_synced", synced)
    _args.write_files([(p, f"new {p.name}\n", "file") for p in paths])
    assert [p.read_text() for p in paths] == [f"new {p.name}\n" for p in paths]
    assert sorted(os.listdir(tmp_path)) == sorted(p.name for p in paths)
