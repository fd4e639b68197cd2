"""Checkpoint and restart (issue 7): a run stopped after a checkpoint and continued from it
equals the uninterrupted run (the test asks 1e-10; measured: bit-identical), with no result
row lost or duplicated, for every method; bad checkpoints are one-line errors."""
from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import pymr

ROOT = Path(__file__).resolve().parent.parent
TANK = ROOT / "input" / "tank_gun_turret.nml"

METHODS = {
    "single": {},
    "multirate response": {"integrator.method": "multirate", "integrator.h_slow": 1e-3, "integrator.h_fast": 1e-4},
    "multirate full": {"integrator.method": "multirate", "integrator.coupling": "full", "integrator.h_slow": 1e-3,
                       "integrator.h_fast": 1e-4},
    "adaptive": {"integrator.adaptive": True, "integrator.rtol": 1e-7},
    "adaptive adams fixed-point order 6": {"integrator.adaptive": True, "integrator.rtol": 1e-7,
                                           "integrator.corrector": "fixed-point", "integrator.order": 6},
    "adaptive abm4": {"integrator.adaptive": True, "integrator.rtol": 1e-7, "integrator.formula": "abm4"},
    "adaptive multirate": {"integrator.method": "multirate", "integrator.adaptive": True, "integrator.rtol": 1e-6},
    "adaptive multirate full": {"integrator.method": "multirate", "integrator.coupling": "full",
                                "integrator.adaptive": True, "integrator.rtol": 1e-6},
    "multirate exponential": {"integrator.method": "multirate", "integrator.coupling": "exponential",
                              "integrator.h_slow": 1e-3, "integrator.h_fast": 1e-3},
    "adaptive multirate exponential": {"integrator.method": "multirate", "integrator.coupling": "exponential",
                                       "integrator.adaptive": True, "integrator.rtol": 1e-6},
    "adaptive multirate amplitude norm": {"integrator.method": "multirate", "integrator.adaptive": True,
                                          "integrator.rtol": 1e-6, "integrator.error_norm": "amplitude"},
}


@pytest.mark.parametrize("method", list(METHODS))
def test_restarted_run_equals_the_uninterrupted_one(tmp_path, method):
    """Checkpoints every 0.2 s; the job is 'killed' at 0.55 s (a run with t_end = 0.55 that
    wrote rows past its last checkpoint at 0.4 s) and restarted: rows, statistics and
    evaluation counts equal the uninterrupted run's."""
    over = METHODS[method]
    full = pymr.run(TANK, tmp_path / "full.csv", overrides=over)
    out = tmp_path / "job.csv"
    cut = pymr.run(TANK, out, overrides={**over, "scene.t_end": 0.55, "output.checkpoint_dt": 0.2})
    assert cut.t[-1] == pytest.approx(0.55)
    assert (tmp_path / "job.ckpt").exists() and not (tmp_path / "job.ckpt.tmp").exists()
    res = pymr.run(TANK, out, overrides={**over, "output.checkpoint_dt": 0.2}, restart=tmp_path / "job.ckpt")
    assert np.array_equal(res.t, full.t)                      # nothing lost, nothing twice
    assert np.abs(res.data - full.data).max() <= 1e-10 * np.abs(full.data).max()
    for key in ("steps_slow", "steps_fast", "rhs_full", "rhs_fast", "rejected_steps", "rows"):
        assert res.stats[key] == full.stats[key], key
    assert res.stats["effects"]["gravity"]["evaluations"] == full.stats["effects"]["gravity"]["evaluations"]


def test_a_restart_keeps_the_exponential_stepper_s_watch_of_its_drift(tmp_path):
    """Adaptive 'exponential' on the tank with its elevation cylinder freezes its response
    anew for accuracy (42 times over the second at rtol 1e-6) once its drift's vibration has
    exceeded the tolerance at four steps in a row: a run continued from a checkpoint keeps
    that count, so it equals the uninterrupted run (rows to 1e-10, the same evaluations).
    Killed every 0.04 s (checkpoints every 0.05 s), so that some restarts fall within a
    drift's count: with the count started afresh on loading, those from the checkpoints at
    0.25 and 0.6 s ended 1.1e-8 and 3.6e-9 of the largest value away."""
    scene = ROOT / "input" / "tank_elevation_cylinder.nml"
    over = {"integrator.method": "multirate", "integrator.coupling": "exponential", "integrator.adaptive": True,
            "integrator.error_norm": "amplitude", "output.checkpoint_dt": 0.05}
    full = pymr.run(scene, tmp_path / "full.csv", overrides=over)
    for cut in np.arange(0.06, 1.0, 0.04):
        out = tmp_path / "job.csv"
        pymr.run(scene, out, overrides={**over, "scene.t_end": cut})
        res = pymr.run(scene, out, overrides=over, restart=out.with_suffix(".ckpt"))
        assert np.array_equal(res.t, full.t)
        assert np.abs(res.data - full.data).max() <= 1e-10 * np.abs(full.data).max(), cut
        for key in ("steps_slow", "rhs_full", "rejected_steps"):
            assert res.stats[key] == full.stats[key], (cut, key)


@pytest.mark.parametrize("dt", [3e-3, 2e-2])
def test_a_restart_with_another_output_interval_writes_its_rows_on_it(tmp_path, dt):
    """A restart may change &output dt: the rows after the checkpoint follow the new interval.
    They were timed by the old row count times the new dt (a row at 0.126 s after one at
    0.4 s, with the values of 0.126 s's neighbour, exit 0; with a longer dt the rows from 0.4
    to 0.8 s were missing). Fixed steps: the rows after the checkpoint equal those of a run
    at the new interval from the start."""
    over = {"scene.t_end": 0.5, "output.dt": 1e-2, "output.checkpoint_dt": 0.2}
    pymr.run(TANK, tmp_path / "job.csv", overrides=over)
    new = {**over, "scene.t_end": 1.0, "output.dt": dt}
    res = pymr.run(TANK, tmp_path / "job.csv", overrides=new, restart=tmp_path / "job.ckpt")
    whole = pymr.run(TANK, tmp_path / "whole.csv", overrides={**new, "output.checkpoint_dt": 0.0})
    assert (np.diff(res.t) > 0).all() and res.t[-1] == pytest.approx(1.0)
    before = res.t <= 0.4 + 1e-9
    assert np.allclose(res.t[before], np.arange(41) * 1e-2, rtol=0, atol=1e-12)
    after = res.data[~before]
    assert np.array_equal(after[:, 0], whole.t[whole.t > 0.4 + 1e-9])
    assert np.abs(after - whole.data[whole.t > 0.4 + 1e-9]).max() <= 1e-10 * np.abs(whole.data).max()


@pytest.mark.parametrize("fmt", ["csv", "hdf5"])
@pytest.mark.parametrize("other", ["output interval", "physics"])
def test_a_restart_refuses_the_results_of_another_run(tmp_path, fmt, other):
    """A restart kept its rows from whatever results file was there: the complete results
    of a run at another output interval (8.9 s of rows lost, exit 0) or of other physics (a
    jump in pivot.q at the checkpoint, exit 0), where its own file was lost. The checkpoint
    records the last row the results held; the kept file's row there must be it. The file is
    left as it was."""
    scene = ROOT / "input" / "pendulum.nml"
    out = tmp_path / f"job.{'h5' if fmt == 'hdf5' else 'csv'}"
    base = {"output.checkpoint_dt": 1.0, "output.format": fmt, "scene.t_end": 3.0}
    theirs = {**base, **({"output.dt": 0.001} if other == "output interval" else {"joint[pivot].q0": 0.5})}
    pymr.run(scene, out, overrides=theirs)                  # another run's complete results
    before = out.read_bytes()
    pymr.run(scene, tmp_path / "mine.csv", overrides={**base, "output.format": "csv"})
    shutil.copy(tmp_path / "mine.ckpt", tmp_path / "job.ckpt")
    if fmt == "hdf5":                                     # the checkpoint of an HDF5 run
        pymr.run(scene, tmp_path / "mine_h5.h5", overrides=base)
        shutil.copy(tmp_path / "mine_h5.ckpt", tmp_path / "job.ckpt")
    column = "t" if other == "output interval" else "pivot.q"
    with pytest.raises(pymr.SceneError, match=rf"job\.(csv|h5): row 201, column {column} is .*, where the "
                                               r"checkpointed run wrote .*: the file is another run's results"):
        pymr.run(scene, out, overrides={**base, "scene.t_end": 4.0}, restart=tmp_path / "job.ckpt")
    assert out.read_bytes() == before


def test_a_restart_keeps_the_run_s_warnings(tmp_path):
    """The spin-up beam without geometric stiffening deflects past a tenth of its size at
    6.79 s, a warning said once. Restarted from its checkpoint at 9 s the run warned again,
    at 9.01 s with another deflection (the warnings were not in the checkpoint); now its
    statistics and summary say what the uninterrupted run's do."""
    scene = ROOT / "input" / "hard" / "spinup_beam.nml"
    over = {"effects.geometric_stiffening": False, "output.checkpoint_dt": 1.0}
    whole = pymr.run(scene, tmp_path / "whole.csv", overrides=over)
    assert len(whole.stats["warnings"]) == 1 and whole.stats["warnings"][0].startswith("at t = 6.79 s: body 'beam'")
    pymr.run(scene, tmp_path / "job.csv", overrides={**over, "scene.t_end": 10.0})
    res = pymr.run(scene, tmp_path / "job.csv", overrides=over, restart=tmp_path / "job.ckpt")
    assert res.stats["warnings"] == whole.stats["warnings"]
    assert [x for x in res.summary.splitlines() if x.startswith("warning")] == \
        [x for x in whole.summary.splitlines() if x.startswith("warning")]


def test_mrsim_and_pymr_restart_from_the_command_line(tmp_path, mrsim):
    scene = tmp_path / "tank.nml"
    scene.write_text(TANK.read_text().replace("t_end = 1.0", "t_end = 0.3").replace(
        "&output file = 'tank_gun_turret.csv', dt = 1.0e-3 /",
        "&output file = 'tank.csv', dt = 1.0e-3, checkpoint_dt = 0.1 /"))
    r = subprocess.run([mrsim, str(scene), "--set", "scene.t_end=0.25"], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    r = subprocess.run([mrsim, str(scene), "--restart", "tank.ckpt", "--quiet"], capture_output=True, text=True,
                       cwd=tmp_path)
    assert r.returncode == 0 and r.stderr == "" and r.stdout == ""
    continued = pymr.load_results(tmp_path / "tank.csv")
    whole = pymr.run(scene, tmp_path / "whole.csv")
    assert np.array_equal(continued.t, whole.t) and np.array_equal(continued.data, whole.data)
    r = subprocess.run(["pymr", "run", str(scene), "-o", str(tmp_path / "p.csv"), "--set", "scene.t_end=0.15", "-q"],
                       capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    r = subprocess.run(["pymr", "run", str(scene), "-o", str(tmp_path / "p.csv"), "--restart", str(tmp_path / "p.ckpt"),
                        "-q"], capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert np.array_equal(pymr.load_results(tmp_path / "p.csv").data, whole.data)


def test_bad_restarts_are_one_line_errors(tmp_path):
    out = tmp_path / "job.csv"
    pymr.run(TANK, out, overrides={"scene.t_end": 0.3, "output.checkpoint_dt": 0.1})
    with pytest.raises(pymr.SceneError, match=r"nope.ckpt: checkpoint not found"):
        pymr.run(TANK, out, restart=tmp_path / "nope.ckpt")
    pend = ROOT / "input" / "pendulum.nml"
    with pytest.raises(pymr.SceneError, match=r"job.ckpt: the checkpoint is of another model \(6 coordinates, "
                                               r"single\); the scene has \d+ coordinates"):
        pymr.run(pend, tmp_path / "pend.csv", restart=tmp_path / "job.ckpt")
    (tmp_path / "junk.ckpt").write_bytes(b"not a checkpoint at all")
    with pytest.raises(pymr.SceneError, match=r"junk.ckpt: not a pymr checkpoint"):
        pymr.run(TANK, out, restart=tmp_path / "junk.ckpt")
    with pytest.raises(pymr.SceneError, match=r"other.csv: the results of the checkpointed run are missing"):
        pymr.run(TANK, tmp_path / "other.csv", restart=tmp_path / "job.ckpt")
    with pytest.raises(pymr.SceneError, match=r"&output: checkpoint_dt: must be in \[0, 1e\+9\], got -1"):
        pymr.run(TANK, out, overrides={"output.checkpoint_dt": -1.0})


@pytest.mark.parametrize("fmt", ["csv", "hdf5"])
@pytest.mark.parametrize("change", ["nan", "inf"])
def test_a_restart_refuses_kept_rows_that_a_run_cannot_have_written(tmp_path, fmt, change):
    """A restart keeps the rows before its checkpoint as they are in the file. A run writes
    only finite numbers, so a kept row holding a non-finite one was changed after the run:
    the restart is refused naming the file, row and column, and the file is left as it was
    (the restart once continued with exit 0, the value kept in its results)."""
    out = tmp_path / f"job.{'csv' if fmt == 'csv' else 'h5'}"
    over = {"scene.t_end": 0.25, "output.checkpoint_dt": 0.1, "output.format": fmt}
    pymr.run(TANK, out, overrides=over)
    bad = float(change)
    if fmt == "csv":
        lines = out.read_text().splitlines(keepends=True)
        head = next(i for i, t in enumerate(lines) if t.startswith("t,"))
        cells = lines[head + 3].split(",")                    # row 3, column elevation.q
        cells[lines[head].rstrip().split(",").index("elevation.q")] = change
        lines[head + 3] = ",".join(cells)
        out.write_text("".join(lines))
    else:
        import h5py
        with h5py.File(out, "r+") as f:
            block = f["joint_coordinates"][...]
            block[2, 1] = bad                                 # row 3, elevation.q
            f["joint_coordinates"][...] = block
    before = out.read_bytes()
    with pytest.raises(pymr.SceneError, match=rf"{out.name}: row 3, column elevation.q: not a finite number \(a run "
                                              r"writes none: the file was changed after the run\)"):
        pymr.run(TANK, out, overrides={**over, "scene.t_end": 0.3}, restart=tmp_path / "job.ckpt")
    assert out.read_bytes() == before


@pytest.mark.parametrize("change", ["empty", "slash", "repeat", "blank", "swap"])
def test_a_restart_refuses_kept_csv_rows_that_are_not_as_a_run_writes_them(tmp_path, change):
    """Fortran's list-directed READ takes an empty field, '/' (the rest left unread),
    'r*v' (v r times) and blank-separated values: a kept row edited so was continued and its
    line copied into the new results (found in review). Each is refused naming the row, as is
    a row out of time order; the file is left as it was."""
    out = tmp_path / "job.csv"
    over = {"scene.t_end": 0.25, "output.checkpoint_dt": 0.1}
    pymr.run(TANK, out, overrides=over)
    lines = out.read_text().splitlines(keepends=True)
    head = next(i for i, t in enumerate(lines) if t.startswith("t,"))
    cells = lines[head + 3].rstrip("\n").split(",")
    if change == "swap":
        lines[head + 2], lines[head + 3] = lines[head + 3], lines[head + 2]
    else:
        if change == "empty":
            cells[2] = ""
        elif change == "slash":
            cells[2] = "/"
        elif change == "repeat":
            cells[1], cells[2] = "2*" + cells[1], cells[3]          # as many fields as before
        else:
            cells[1] += " 7"
            del cells[2]
            cells.append("9")
        lines[head + 3] = ",".join(cells) + "\n"
    out.write_text("".join(lines))
    before = out.read_bytes()
    expect = (r"job.csv: row 3, column t: 0.001 is before the row before it \(0.002; a run writes its rows in time"
              if change == "swap" else r"job.csv: row 3 is not a row of \d+ numbers \(a run writes no other: the file was "
              r"changed after the run\)")
    with pytest.raises(pymr.SceneError, match=expect):
        pymr.run(TANK, out, overrides={**over, "scene.t_end": 0.3}, restart=tmp_path / "job.ckpt")
    assert out.read_bytes() == before


def test_a_restart_refuses_hdf5_rows_out_of_time_order(tmp_path):
    """The HDF5 file's kept rows are held to the same order: rows 2 and 3 swapped in every
    dataset are refused naming row 3."""
    import h5py
    out = tmp_path / "job.h5"
    over = {"scene.t_end": 0.25, "output.checkpoint_dt": 0.1, "output.format": "hdf5"}
    pymr.run(TANK, out, overrides=over)
    with h5py.File(out, "r+") as f:
        for name in f:
            block = f[name][...]
            block[[1, 2]] = block[[2, 1]]
            f[name][...] = block
    with pytest.raises(pymr.SceneError, match=r"job.h5: row 3, column t: 0.001 is before the row before it"):
        pymr.run(TANK, out, overrides={**over, "scene.t_end": 0.3}, restart=tmp_path / "job.ckpt")


@pytest.mark.parametrize("extra", [1, -1])
def test_a_restart_refuses_an_hdf5_dataset_of_other_width(tmp_path, extra):
    """A dataset rewritten with a column more (its first 6 of 7 columns were kept, shifted:
    exit 0) or one fewer ('cannot read the results') is refused naming the dataset and both
    widths."""
    import h5py
    out = tmp_path / "job.h5"
    over = {"scene.t_end": 0.25, "output.checkpoint_dt": 0.1, "output.format": "hdf5"}
    pymr.run(TANK, out, overrides=over)
    with h5py.File(out, "r+") as f:
        block, attrs = f["markers"][...], dict(f["markers"].attrs)
        del f["markers"]
        block = np.hstack([np.full((block.shape[0], 1), 7.0), block]) if extra > 0 else block[:, 1:]
        data = f.create_dataset("markers", data=block, maxshape=(None, block.shape[1]), chunks=True)
        for key, value in attrs.items():
            data.attrs[key] = value
        width = block.shape[1]
    with pytest.raises(pymr.SceneError, match=rf"job.h5: its dataset markers holds {width} columns, the run writes "
                                              rf"{width - extra} \(the file was changed after the run\)"):
        pymr.run(TANK, out, overrides={**over, "scene.t_end": 0.3}, restart=tmp_path / "job.ckpt")


def test_a_restart_refuses_a_checkpoint_that_does_not_belong_to_its_scene(tmp_path):
    """A checkpoint carries the integrator settings, the model's fingerprint, pymr's version,
    its time and a checksum: a restart with other settings, of another scene of the same
    size, from a damaged file, or with t_end not after the checkpoint is one line saying so.
    A longer t_end and another output are allowed (they are what a restart is for)."""
    out = tmp_path / "job.csv"
    pymr.run(TANK, out, overrides={"scene.t_end": 0.3, "output.checkpoint_dt": 0.2})
    ckpt = tmp_path / "job.ckpt"
    with pytest.raises(pymr.SceneError, match=r"job.ckpt: the checkpoint was written with other integrator "
                                               r"settings: h_fast = 0.0001 then, h_fast = 5e-5 now"):
        pymr.run(TANK, out, overrides={"integrator.h_slow": 5e-5, "integrator.h_fast": 5e-5}, restart=ckpt)
    with pytest.raises(pymr.SceneError, match=r"job.ckpt: the checkpoint is of another scene \(a group other "
                                               r"than &integrator and &output, or a file the scene reads, differs"):
        pymr.run(TANK, out, overrides={"body[turret].mass": 9001.0}, restart=ckpt)
    with pytest.raises(pymr.SceneError, match=r"job.ckpt: t_end = 0.15 s is not after the checkpoint's time 0.2 s"):
        pymr.run(TANK, out, overrides={"scene.t_end": 0.15}, restart=ckpt)
    data = bytearray(ckpt.read_bytes())
    for where in (200, len(data) // 2, len(data) - 70):       # a flipped byte anywhere: header, states
        bad = bytearray(data)
        bad[where] ^= 0x01
        (tmp_path / "bad.ckpt").write_bytes(bytes(bad))
        with pytest.raises(pymr.SceneError, match=r"bad.ckpt: the checkpoint is damaged or truncated \(its checksum "
                                                   r"does not match\)"):
            pymr.run(TANK, out, restart=tmp_path / "bad.ckpt")
    (tmp_path / "short.ckpt").write_bytes(bytes(data[:len(data) // 3]))
    with pytest.raises(pymr.SceneError, match=r"short.ckpt: the checkpoint is damaged or truncated"):
        pymr.run(TANK, out, restart=tmp_path / "short.ckpt")
    res = pymr.run(TANK, out, overrides={"scene.t_end": 0.4, "output.dt": 1e-3}, restart=ckpt)
    assert res.t[-1] == pytest.approx(0.4)
    # formula 'adams': its order and its corrector's iteration are settings of the checkpoint too
    adams = {"integrator.adaptive": True, "scene.t_end": 0.3, "output.checkpoint_dt": 0.2}
    pymr.run(TANK, out, overrides=adams)
    with pytest.raises(pymr.SceneError, match=r"other integrator settings: corrector = 'newton' then, "
                                               r"corrector = 'fixed-point' now"):
        pymr.run(TANK, out, overrides={**adams, "scene.t_end": 0.4, "integrator.corrector": "fixed-point"},
                 restart=ckpt)
    with pytest.raises(pymr.SceneError, match=r"other integrator settings: order = 0 then, order = 5 now"):
        pymr.run(TANK, out, overrides={**adams, "scene.t_end": 0.4, "integrator.order": 5}, restart=ckpt)


@pytest.mark.parametrize("change", [{"control[stabiliser].kp": 1.0e6}, {"moving_load[shot].mass": 60.0}])
def test_a_checkpoint_belongs_to_its_controllers_and_moving_loads(tmp_path, change):
    """The model a checkpoint belongs to is every group but &integrator and &output: a
    restart with another controller gain or shot mass is refused (each was once continued
    with exit 0 from the state the other scene had reached); the same scene goes on."""
    scene = ROOT / "input" / "tank_on_the_move.nml"
    out = tmp_path / "move.csv"
    pymr.run(scene, out, overrides={"scene.t_end": 0.05, "output.checkpoint_dt": 0.02})
    ckpt = tmp_path / "move.ckpt"
    with pytest.raises(pymr.SceneError, match=r"move.ckpt: the checkpoint is of another scene"):
        pymr.run(scene, out, overrides={"scene.t_end": 0.06, **change}, restart=ckpt)
    res = pymr.run(scene, out, overrides={"scene.t_end": 0.06}, restart=ckpt)
    assert res.t[-1] == pytest.approx(0.06)


def test_a_checkpoint_belongs_to_the_contents_of_the_files_its_scene_reads(tmp_path):
    """The model is built from the scene's table files too: a restart after one of them
    changed (a terrain height moved by 1 mm, the scene text the same) is refused, as
    another scene is; with the files as they were, the restart ends on the uninterrupted
    run's rows (continued before, with exit 0, on the other terrain)."""
    import shutil
    scene_dir = tmp_path / "scene"
    shutil.copytree(ROOT / "input" / "tank_on_the_move", scene_dir / "tank_on_the_move")
    scene = scene_dir / "tank_on_the_move.nml"
    shutil.copy(ROOT / "input" / "tank_on_the_move.nml", scene)
    out = tmp_path / "move.csv"
    over = {"scene.t_end": 0.05, "output.checkpoint_dt": 0.02, "output.dt": 1e-3}
    whole = pymr.run(scene, tmp_path / "whole.csv", overrides={**over, "scene.t_end": 0.06})
    pymr.run(scene, out, overrides=over)
    ckpt = tmp_path / "move.ckpt"
    terrain = scene_dir / "tank_on_the_move" / "terrain_front.txt"
    kept = terrain.read_text()
    lines = kept.splitlines()
    t, z = lines[-1].split()
    terrain.write_text("\n".join(lines[:-1] + [f"{t} {float(z) + 1e-3!r}"]) + "\n")
    with pytest.raises(pymr.SceneError, match=r"move.ckpt: the checkpoint is of another scene \(a group other "
                                               r"than &integrator and &output, or a file the scene reads, differs"):
        pymr.run(scene, out, overrides={**over, "scene.t_end": 0.06}, restart=ckpt)
    terrain.write_text(kept)
    res = pymr.run(scene, out, overrides={**over, "scene.t_end": 0.06}, restart=ckpt)
    assert res.t[-1] == pytest.approx(0.06)
    assert np.array_equal(res.t, whole.t)
    assert np.abs(res.data - whole.data).max() <= 1e-10 * np.abs(whole.data).max()


def test_an_empty_checkpoint_or_output_name_is_refused_not_a_fresh_run(tmp_path, mrsim, monkeypatch):
    """`--restart ""` (an unset shell variable) ran the scene from the start, replacing the
    results a restart would have continued (found by fuzzing the command line); so did
    pymr.run(restart=""). An empty -o is refused too (mrsim and pymr run took the default)."""
    monkeypatch.chdir(tmp_path)
    scene = ROOT / "input" / "pendulum.nml"
    cases = [([mrsim], "mrsim: error: --restart needs a checkpoint file (got an empty name)\n",
              "mrsim: error: -o needs a file name (got an empty one)\n"),
             (["pymr", "run"], "pymr: error: restart: an empty checkpoint path (None runs from the start)\n",
              "pymr: error: -o: an empty file name (leave -o out for the default)\n")]
    for exe, no_checkpoint, no_output in cases:
        r = subprocess.run([*exe, str(scene), "-o", "out.csv", "--restart", ""], capture_output=True, text=True,
                           timeout=60)
        assert (r.returncode, r.stderr) == (1, no_checkpoint)
        r = subprocess.run([*exe, str(scene), "-o", ""], capture_output=True, text=True, timeout=60)
        assert (r.returncode, r.stderr) == (1, no_output)
        assert not (tmp_path / "out.csv").exists() and not (tmp_path / "pendulum.csv").exists()
    with pytest.raises(pymr.SceneError, match=r"^restart: an empty checkpoint path \(None runs from the start\)$"):
        pymr.run(scene, output="out.csv", restart="")
