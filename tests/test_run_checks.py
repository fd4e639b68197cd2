"""What a run checks and reports beyond the scene's items (issue 30): contradictory steps and
missing folders refused before anything runs, every adaptive step's row written once, a
single-rate --set of h_slow setting the step, a static start that has nothing to settle
refused and one that settles reported, a flexible body deflecting beyond linear theory
warned about (or stopped), and the statistics carrying what reproduces the run. The
expectations: the rules as the scene reference states them, the cantilever's analytic sag,
and a second run of the scene the statistics hold."""
from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import tempfile
from pathlib import Path

import numpy as np
import pytest

import pymr

ROOT = Path(__file__).resolve().parent.parent
TANK = ROOT / "input" / "tank_gun_turret.nml"
HOLD = ROOT / "input" / "tank_hold.nml"
PENDULUM = ROOT / "input" / "pendulum.nml"


def mrsim_run(mrsim, scene, out, *sets, cwd=None):
    args = [mrsim, str(scene), "-o", str(out), "--quiet"] + [a for s in sets for a in ("--set", s)]
    return subprocess.run(args, capture_output=True, text=True, timeout=300, cwd=cwd)


def check_refused_at_reading(r, out: Path, *words: str) -> None:
    """Exit 1, one line, the words in it, and nothing written."""
    assert r.returncode == 1, r.stderr
    assert r.stderr.count("\n") == 1 and r.stderr.startswith("mrsim: error: "), r.stderr
    for w in words:
        assert w in r.stderr, r.stderr
    assert not out.exists() and not Path(str(out) + ".partial").exists()


@pytest.mark.parametrize("h_min, h_max", [(1e-3, 1e-4), (2e-5, 1e-5)])
def test_smallest_step_above_the_largest_is_refused_at_reading(tmp_path, mrsim, h_min, h_max):
    """An adaptive run whose h_min exceeds h_max could take no step: refused before it runs
    (it used to fail at run time as a step underflow, exit 2)."""
    out = tmp_path / "p.csv"
    r = mrsim_run(mrsim, PENDULUM, out, "integrator.adaptive=.true.", f"integrator.h_min={h_min!r}",
                  f"integrator.h_max={h_max!r}")
    check_refused_at_reading(r, out, "&integrator: h_min: larger than h_max")
    ok = mrsim_run(mrsim, PENDULUM, out, "integrator.adaptive=.true.", f"integrator.h_min={h_max!r}",
                   f"integrator.h_max={h_min!r}", "scene.t_end=0.1")
    assert ok.returncode == 0, ok.stderr


@pytest.mark.parametrize("where", ["nodir/x.ckpt", "a/b/c.ckpt"])
def test_a_checkpoint_in_a_missing_folder_is_refused_before_the_run(tmp_path, mrsim, where):
    out = tmp_path / "p.csv"
    r = mrsim_run(mrsim, PENDULUM, out, "output.checkpoint_dt=1", f"output.checkpoint_file='{where}'", cwd=tmp_path)
    check_refused_at_reading(r, out, "&output: checkpoint_file: the folder", "does not exist")


def test_a_results_name_longer_than_the_file_system_takes_is_refused_before_the_run(tmp_path, mrsim):
    """A results name whose run's files (X.csv.partial.tmp the longest, 12 bytes more) the
    file system cannot name was blamed on its folder ("cannot write in its folder ."), and
    one within 12 bytes of the limit ran but could not be restarted from its checkpoint
    (a restart rewrites the rows through X.csv.partial.tmp): the longest name that runs is
    the file system's NAME_MAX (os.pathconf) less 12 bytes, and one byte more is refused at
    reading, naming the file and both lengths."""
    most = os.pathconf(tmp_path, "PC_NAME_MAX")
    fits = tmp_path / ("o" * (most - 12 - 4) + ".csv")
    ok = mrsim_run(mrsim, PENDULUM, fits, "scene.t_end=0.01")
    assert ok.returncode == 0 and fits.exists(), ok.stderr
    over = tmp_path / ("p" * (most - 12 - 3) + ".csv")
    r = mrsim_run(mrsim, PENDULUM, over, "scene.t_end=0.01")
    check_refused_at_reading(r, over, f"the run's file {over}.partial.tmp: its name is {most + 1} bytes long, "
                             f"longer than the {most} its file system takes; choose a shorter name")


def test_a_checkpoint_folder_the_run_cannot_write_is_refused_before_the_run(tmp_path, mrsim):
    """A checkpoint_file in a folder without write permission ran until its first checkpoint
    and stopped there (exit 2, with the run-time library's message). It is refused at
    reading now, as the results folder is. Root writes anywhere, so as root the run is that
    of the user nobody (setpriv), in a folder it can reach."""
    work = Path(tempfile.mkdtemp(prefix="pymr-ro-"))
    try:
        work.chmod(0o755)
        shutil.copy(mrsim, work / "mrsim")
        shutil.copy(PENDULUM, work / "p.nml")
        (work / "ro").mkdir(mode=0o555)
        (work / "ro").chmod(0o555)
        (work / "out").mkdir(mode=0o777)
        (work / "out").chmod(0o777)
        user = ["setpriv", "--reuid=65534", "--regid=65534", "--clear-groups"] if os.geteuid() == 0 else []
        args = user + [str(work / "mrsim"), "p.nml", "-o", "out/p.csv", "--quiet", "--set", "output.checkpoint_dt=0.05",
                       "--set", "scene.t_end=0.1"]
        r = subprocess.run(args + ["--set", "output.checkpoint_file='ro/p.ckpt'"], cwd=work, capture_output=True,
                           text=True, timeout=60)
        check_refused_at_reading(r, work / "out" / "p.csv", "p.nml: --set output.checkpoint_file='ro/p.ckpt': "
                                 "&output: checkpoint_file: cannot make files in its folder 'ro' (")
        ok = subprocess.run(args + ["--set", "output.checkpoint_file='out/p.ckpt'"], cwd=work, capture_output=True,
                            text=True, timeout=60)
        assert ok.returncode == 0 and (work / "out" / "p.ckpt").exists(), ok.stderr
    finally:
        shutil.rmtree(work, ignore_errors=True)


def test_adaptive_rows_of_every_step_are_written_once_also_across_a_restart(tmp_path, mrsim):
    """output.dt = 0 in an adaptive run writes each step's row once: times strictly rising
    (the t = 0 row was written twice), and a run restarted from its checkpoint gives the same
    rows as the uninterrupted one (bit for bit: one machine, one build)."""
    sets = ["integrator.adaptive=.true.", "output.dt=0", "output.checkpoint_dt=1"]
    full = tmp_path / "full.csv"
    assert mrsim_run(mrsim, PENDULUM, full, *sets, "scene.t_end=2").returncode == 0
    t = pymr.load_results(full)["t"]
    assert t[0] == 0.0 and np.all(np.diff(t) > 0), t[:4]
    part = tmp_path / "part.csv"       # checkpoint near 1 s, rows on to 1.5 s
    assert mrsim_run(mrsim, PENDULUM, part, *sets, "scene.t_end=1.5").returncode == 0
    r = subprocess.run([mrsim, str(PENDULUM), "-o", str(part), "--quiet", "--restart", str(tmp_path / "part.ckpt")]
                       + [a for s in sets + ["scene.t_end=2"] for a in ("--set", s)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    assert np.array_equal(pymr.load_results(part).data, pymr.load_results(full).data)


def test_a_set_of_h_slow_sets_the_step_of_a_single_rate_run(tmp_path, mrsim):
    """The tank scene gives h_fast = h_slow = 1e-4 s; --set integrator.h_slow=5e-4 (the
    example in docs/commands.md) runs at 5e-4 s as a scene file giving both would, and the statistics
    say both steps. A --set of h_fast alone on a single-rate run still contradicts h_slow."""
    out = tmp_path / "a.csv"
    r = mrsim_run(mrsim, TANK, out, "integrator.h_slow=5e-4")
    assert r.returncode == 0, r.stderr
    stats = json.loads((tmp_path / "a.json").read_text())
    assert stats["integrator"]["h_slow"] == stats["integrator"]["h_fast"] == 5e-4
    assert stats["steps_slow"] == 2000
    both = tmp_path / "b.csv"
    assert mrsim_run(mrsim, TANK, both, "integrator.h_slow=5e-4", "integrator.h_fast=5e-4").returncode == 0
    assert np.array_equal(pymr.load_results(out).data, pymr.load_results(both).data)
    r = mrsim_run(mrsim, TANK, tmp_path / "c.csv", "integrator.h_fast=5e-5")
    assert r.returncode == 1 and "method 'single' takes one step" in r.stderr


def test_a_static_start_with_nothing_to_settle_is_refused(tmp_path, mrsim):
    """The rigid pendulum has no modes and no joint marked settle: start = 'static' would do
    nothing, and is refused naming &scene start."""
    out = tmp_path / "p.csv"
    r = mrsim_run(mrsim, PENDULUM, out, "scene.start='static'")
    check_refused_at_reading(r, out, "&scene: start: 'static'", "nothing would settle")


def test_a_static_start_reports_what_it_settled(tmp_path, mrsim):
    """The held tank's barrel settled under gravity: the summary and the statistics say how
    many coordinates (its 4 modes), in how many Newton iterations (the problem is linear in
    the modes: at most a few), and the last change (below 1e-12 m); a start at rest says
    nothing of it."""
    out = tmp_path / "h.csv"
    r = subprocess.run([mrsim, str(HOLD), "-o", str(out), "--set", "scene.start='static'", "--set", "scene.t_end=0.01"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    stats = json.loads((tmp_path / "h.json").read_text())["static_start"]
    assert stats["coordinates_settled"] == 4
    assert 1 <= stats["newton_iterations"] <= 5 and stats["last_change"] < 1e-12
    assert f"static start: 4 coordinates settled in {stats['newton_iterations']} Newton iterations" in r.stdout
    rest = subprocess.run([mrsim, str(HOLD), "-o", str(out), "--set", "scene.t_end=0.01"], capture_output=True,
                          text=True, timeout=300)
    assert "static start" not in rest.stdout
    assert "static_start" not in json.loads((tmp_path / "h.json").read_text())


SAG = 9.35e-3          # the held barrel's static tip sag w L^4/(8 EI) at E = 2.07e11 (docs/tank_gun_turret.md)


@pytest.mark.parametrize("sag", [0.40, 0.70])
def test_a_barrel_deflecting_beyond_a_tenth_of_its_length_is_warned_about(tmp_path, mrsim, sag):
    """The held barrel started in static equilibrium with its Young's modulus lowered so that
    the analytic cantilever sag (9.35 mm at 2.07e11 Pa, linear in 1/E) is 0.40 m (7.6 % of
    its 5.3 m) or 0.70 m (13 %): only the second passes deflection_limit = 0.1 of the
    barrel's size (its farthest mass point, 5.28 m), and is warned about at t = 0, once, in
    the summary and the statistics; with deflection_stop the run fails there (exit 2, one
    line naming the time and the body)."""
    e = 2.07e11 * SAG / sag
    sets = ["scene.start='static'", "scene.t_end=0.01", f"body[gun].youngs_modulus={e!r}"]
    out = tmp_path / "h.csv"
    r = subprocess.run([mrsim, str(HOLD), "-o", str(out)] + [a for s in sets for a in ("--set", s)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    warnings = json.loads((tmp_path / "h.json").read_text())["warnings"]
    if sag < 0.528:
        assert warnings == [] and "warning" not in r.stdout
        return
    assert len(warnings) == 1 and warnings[0].startswith("at t = 0 s: body 'gun' deflects 0.6"), warnings
    assert r.stdout.count("warning: at t = 0 s: body 'gun' deflects") == 1
    stop = mrsim_run(mrsim, HOLD, out, *sets, "scene.deflection_stop=.true.")
    assert stop.returncode == 2 and stop.stderr.count("\n") == 1
    # a failed run's line names the scene first, then the time (the scene was once left out)
    assert stop.stderr.startswith(f"mrsim: error: {HOLD}: at t = 0 s: body 'gun' deflects"), stop.stderr
    assert "deflection_stop" in stop.stderr


@pytest.mark.parametrize("fmt", ["csv", "hdf5"])
def test_a_run_stopped_by_its_deflection_counts_the_row_it_stopped_at(tmp_path, mrsim, fmt):
    """The spin-up beam without geometric stiffening deflects past a tenth of its size at
    6.79 s; with deflection_stop the run fails there, the row of that time in its partial
    file, which its statistics counted one short of (679 of 680 rows)."""
    out = tmp_path / ("d.h5" if fmt == "hdf5" else "d.csv")
    r = mrsim_run(mrsim, ROOT / "input" / "hard" / "spinup_beam.nml", out, "effects.geometric_stiffening=.false.",
                  "scene.deflection_stop=.true.", f"output.format='{fmt}'")
    assert r.returncode == 2 and "at t = 6.79 s: body 'beam' deflects" in r.stderr, r.stderr
    stats = json.loads((tmp_path / "d.json.partial").read_text())
    if fmt == "csv":
        rows = [line for line in (tmp_path / "d.csv.partial").read_text().splitlines() if line[:1].isdigit()]
        last = float(rows[-1].split(",")[0])
    else:
        import h5py
        with h5py.File(tmp_path / "d.h5.partial", "r") as f:
            times = f["time"][:, 0] if f["time"].ndim == 2 else f["time"][:]
        rows, last = times, float(times[-1])
    assert stats["rows"] == len(rows) == 680 and last == pytest.approx(6.79)


def test_the_shipped_scenes_stay_within_linear_deflection(tmp_path, mrsim):
    """The tank's barrel deflects millimetres: no warning."""
    assert mrsim_run(mrsim, TANK, tmp_path / "t.csv").returncode == 0
    assert json.loads((tmp_path / "t.json").read_text())["warnings"] == []


def test_the_statistics_hold_what_reproduces_the_run(tmp_path, mrsim):
    """OUT.json keeps the --set overrides as given and the resolved scene (files absolute):
    that scene, run from another folder with no override, gives the same rows."""
    sets = ["integrator.h_slow=2e-4", "body[turret].mass=9500", "scene.t_end=0.2"]
    out = tmp_path / "a.csv"
    assert mrsim_run(mrsim, TANK, out, *sets).returncode == 0
    stats = json.loads((tmp_path / "a.json").read_text())
    assert stats["overrides"] == sets
    other = tmp_path / "elsewhere"
    other.mkdir()
    (other / "again.nml").write_text(stats["resolved_scene"])
    again = other / "again.csv"
    assert mrsim_run(mrsim, other / "again.nml", again).returncode == 0
    assert np.array_equal(pymr.load_results(again).data, pymr.load_results(out).data)


def test_a_fixed_step_far_beyond_a_stiff_mode_is_told_in_numbers(tmp_path, mrsim):
    """A short stiff barrel (its 6th mode near 170 kHz) at a step of 1e-3 s: the message gives
    omega*h as a number (it overflowed to '*****') and names the barrel's mode."""
    r = mrsim_run(mrsim, TANK, tmp_path / "s.csv", "body[gun].modes_y=6", "body[gun].modes_z=6",
                  "body[gun].length=0.3", "marker[muzzle].at=0.3,0,0", "integrator.h_slow=1e-3")
    assert r.returncode == 1 and "*" not in r.stderr.replace("omega*h", ""), r.stderr
    assert "not stable for body 'gun', mode 6" in r.stderr and "omega*h = 1.07E+03" in r.stderr
    # an integral gain of 1e12 on the pendulum (1 kg m^2 about its pivot): its closed loop's
    # pole at 1e4 rad/s ((ki/I)^(1/3)), so omega*h = 10.0 at 1e-3 s, just below 10, which
    # rounded to 10.000 and overflowed its five characters
    scene = tmp_path / "c.nml"
    scene.write_text(PENDULUM.read_text().replace("&effects", "&control name = 'c', joint = 'pivot', ki = 1.0e12 /\n&effects")
                     .replace("gravity = .true.", "gravity = .true., controls = .true."))
    r = mrsim_run(mrsim, scene, tmp_path / "c.csv")
    assert r.returncode == 1 and "*" not in r.stderr.replace("omega*h", ""), r.stderr
    assert "(1591.5 Hz, omega*h = 1.00E+01)" in r.stderr, r.stderr


def test_modal_file_of_the_ground_says_it_is_not_a_beam(tmp_path):
    r = subprocess.run(["pymr", "modal-file", str(TANK), "chassis", "-o", str(tmp_path / "c.modal")],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and "'chassis' is the ground, not a beam" in r.stderr, r.stderr


def beam_chain(n_beams: int, modes: int, integrator: str) -> str:
    """A chain of n_beams beams on revolute joints, each with `modes` bending modes: n_beams
    x (1 + modes) coordinates."""
    lines = ["&scene title = 'beams', t_end = 1e-6 /", f"&integrator {integrator} /",
             "&body name = 'g', kind = 'ground' /"]
    parent = "g"
    for i in range(n_beams):
        lines.append(f"&body name = 'b{i}', kind = 'beam', length = 1.0, youngs_modulus = 2e11, density = 7850, "
                     f"r_outer = 0.05, r_inner = 0.04, n_elements = 40, modes_y = {modes // 2}, "
                     f"modes_z = {modes // 2} /")
        lines.append(f"&joint name = 'j{i}', kind = 'revolute', parent = '{parent}', child = 'b{i}', "
                     f"at = {0.0 if i == 0 else 1.0}, 0, 0, axis = 0, 0, 1 /")
        parent = f"b{i}"
    return "\n".join(lines) + "\n"


def run_under_limit(mrsim, scene, out, limit):
    import resource
    return subprocess.run([mrsim, str(scene), "-o", str(out)], capture_output=True, text=True, timeout=300,
                          preexec_fn=lambda: resource.setrlimit(resource.RLIMIT_AS, (limit, limit)))


MEMORY_GB = r"its dense matrices need about ([0-9.E+-]+) GB, more than the ([0-9.E+-]+) GB this process may still take"


def let_through(mrsim, scene, out):
    """The scene run under a 45 MiB address-space limit, refused by the memory check in one
    line, exit 2; then under a limit that leaves just the room the refusal asks for (what
    the process held when it checked, plus the need, plus 4 MiB for the arrays that are not
    n x n). The need (bytes) and the second run."""
    small = 45 * 2**20
    r = run_under_limit(mrsim, scene, out, small)
    found = re.search(MEMORY_GB, r.stderr)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and found, r.stderr
    need, room = float(found.group(1)) * 1e9, float(found.group(2)) * 1e9
    return need, run_under_limit(mrsim, scene, out, int(small - room + need) + 4 * 2**20)


def test_a_model_too_large_for_the_memory_fails_in_one_line(tmp_path, mrsim):
    """A chain of 30 beams with 60 modes each has 30 + 30 x 60 = 1830 coordinates; an
    adaptive 'adams' run holds the mass matrix, its factor and the start's working copies,
    and the Newton Jacobian and its factor ((2n)^2 each): 13 n^2 words, 8 x 13 x 1830^2 bytes
    = 0.348293 GB. Under a 250 MiB address-space limit (ulimit -v) the run fails before the
    first step in one line naming both figures, exit 2, where an allocation deep in the run
    ended in the compiler's runtime message and backtrace (exit 1; inside Python, the end of
    the session)."""
    scene = tmp_path / "beams.nml"
    scene.write_text(beam_chain(30, 60, "method = 'single', adaptive = .true., h_slow = 1e-4"))
    r = run_under_limit(mrsim, scene, tmp_path / "beams.csv", 250 * 2**20)
    assert r.returncode == 2, r.stderr
    assert r.stderr.count("\n") == 1 and "Error termination" not in r.stderr, r.stderr
    assert r.stderr.startswith(f"mrsim: error: {scene}: at t = 0 s: the model has 1830 coordinates: its dense "
                               f"matrices need about {8 * 13 * 1830**2 / 1e9:g} GB, more than the "), r.stderr
    assert "GB this process may still take" in r.stderr
    assert not (tmp_path / "beams.csv").exists()


def test_a_beam_whose_quadrature_exceeds_the_memory_fails_in_one_line(tmp_path, mrsim):
    """A ring-section beam of 5000 elements and 50 modes of each of its four kinds has 4
    Gauss points of 4 section points per element, 80,000 points, each with 3 x 200 mode
    shapes and 4 more numbers: 8 x 80,000 x 604 bytes = 0.38656 GB, built before any matrix
    the run's memory check counts (202 coordinates). Under a 300 MiB address-space limit
    that allocation ended in the compiler's runtime message and backtrace (exit 1), or a
    segmentation fault; now one line naming the body and both figures, exit 2."""
    scene = tmp_path / "long.nml"
    scene.write_text(beam_chain(1, 2, "method = 'single', adaptive = .true., h_slow = 1e-4").replace(
        "n_elements = 40, modes_y = 1, modes_z = 1",
        "n_elements = 5000, modes_y = 50, modes_z = 50, modes_x = 50, modes_t = 50, shear_modulus = 8e10"))
    assert "modes_t = 50" in scene.read_text()
    r = run_under_limit(mrsim, scene, tmp_path / "long.csv", 300 * 2**20)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "Error termination" not in r.stderr, r.stderr
    assert f"beam 'b0': its 80000 quadrature points of 200 modes need about {8 * 80000 * 604 / 1e9:g} GB, more " \
           "than the " in r.stderr, r.stderr
    assert not (tmp_path / "long.csv").exists()


@pytest.mark.parametrize("integrator", [
    "method = 'single', formula = 'abm4', adaptive = .false., h_slow = 1e-7",
    "method = 'single', formula = 'abm4', adaptive = .false., h_slow = 1e-7, stability_check = .false.",
    "method = 'single', formula = 'abm4', adaptive = .true., h_slow = 1e-7",
    "method = 'single', adaptive = .true., h_slow = 1e-7",
    "method = 'multirate', coupling = 'response', adaptive = .false., h_slow = 2e-7, h_fast = 1e-7",
    "method = 'multirate', coupling = 'response', adaptive = .true., h_slow = 1e-7",
    "method = 'multirate', coupling = 'full', adaptive = .false., h_slow = 2e-7, h_fast = 1e-7",
    "method = 'multirate', coupling = 'full', adaptive = .true., h_slow = 1e-7",
    "method = 'multirate', coupling = 'exponential', adaptive = .false., h_slow = 2e-7, h_fast = 2e-7",
    "method = 'multirate', coupling = 'exponential', adaptive = .true., h_slow = 1e-7",
    "method = 'auto', adaptive = .true., h_slow = 1e-7",
])
def test_a_run_the_memory_check_lets_through_finishes(tmp_path, mrsim, integrator):
    """The memory check's figure is a bound on what the run takes, by its method: under an
    address-space limit (ulimit -v) that leaves the process just the room the check asks
    for (read from its own refusal at a smaller limit, plus 4 MiB for the arrays that are
    not n x n), the run finishes. 25 beams x 20 modes: 525 coordinates, 5-42 n^2 words.
    Before the check knew the method (a flat 10 n^2 words), 6 of these 11 settings (fixed
    steps with the pre-flight check, 'exponential', 'auto') failed here in a segmentation
    fault or the compiler's runtime message, and it refused 4 others at 1.3-2.4 times the
    room they take."""
    scene = tmp_path / "beams.nml"
    scene.write_text(beam_chain(25, 20, integrator))
    _, r = let_through(mrsim, scene, tmp_path / "beams.csv")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "beams.csv").exists()


def test_auto_on_a_rigid_chain_is_counted_as_the_single_rate_run_it_is(tmp_path, mrsim):
    """Without modal coordinates 'auto' runs single-rate 'adams' with no probe: the check
    counts its 13 n^2 words (the Newton pair beside the mass matrix), not the 40 of a
    flexible scene's probes, and under a limit that leaves just that room the run finishes.
    600 rigid links: 600 coordinates."""
    lines = ["&scene title = 'links', t_end = 1e-6 /", "&integrator method = 'auto', adaptive = .true., h_slow = 1e-7 /",
             "&body name = 'g', kind = 'ground' /"]
    parent = "g"
    for i in range(600):
        lines.append(f"&body name = 'b{i}', kind = 'rigid', mass = 1.0, com = 0.5, 0, 0, inertia = 0.01, 0.1, 0.1, 0, 0, 0 /")
        lines.append(f"&joint name = 'j{i}', kind = 'revolute', parent = '{parent}', child = 'b{i}', "
                     f"at = {0.0 if i == 0 else 1.0}, 0, 0, axis = 0, 0, 1 /")
        parent = f"b{i}"
    scene = tmp_path / "links.nml"
    scene.write_text("\n".join(lines) + "\n")
    need, r = let_through(mrsim, scene, tmp_path / "links.csv")
    assert need == pytest.approx(8 * 13 * 600**2, rel=1e-4)
    assert r.returncode == 0, r.stderr


MODES_CHILD = r"""
import re, resource, sys
import pymr
from pymr.api import initial_state
scene, extra, pattern = sys.argv[1], int(sys.argv[2]), sys.argv[3]
q, qd = initial_state(scene)
held = int([l.split()[1] for l in open("/proc/self/status") if l.startswith("VmSize")][0]) * 1024
resource.setrlimit(resource.RLIMIT_AS, (held + extra, held + extra))
try:
    freq, zeta, shapes = pymr.modes(scene, q, qd)
    print("ok", len(freq))
except pymr.SolverError as e:
    found = re.search(pattern, str(e))
    print("refused", float(found.group(1)) * 1e9, held + extra - float(found.group(2)) * 1e9 - held)
"""


def test_modes_the_memory_check_lets_through_finish(tmp_path):
    """`pymr.modes` takes a working copy of the model and the 2n x 2n eigenproblem beside
    the model it builds (22 n^2 words more): under an address-space limit that leaves the
    process just the room a refusal asks for (+4 MiB), the next check passes and the modes
    come out; every call before is refused in one SolverError. Before, a Python session
    ended in the compiler's runtime message or a segmentation fault (25 beams x 20 modes,
    525 coordinates, at 30-46 MiB of room)."""
    import os
    import sys
    scene = tmp_path / "beams.nml"
    scene.write_text(beam_chain(25, 20, "method = 'single', formula = 'abm4', adaptive = .true., h_slow = 1e-7"))
    env = dict(os.environ, OPENBLAS_NUM_THREADS="1")
    extra, answers = 16 * 2**20, []
    for _ in range(4):
        r = subprocess.run([sys.executable, "-c", MODES_CHILD, str(scene), str(extra), MEMORY_GB], capture_output=True,
                           text=True, timeout=300, env=env, cwd=tmp_path)
        assert r.returncode == 0, r.stderr[-2000:]
        answers.append(r.stdout.split())
        if answers[-1][0] == "ok":
            break
        need, used = float(answers[-1][1]), float(answers[-1][2])
        extra = int(used + need) + 4 * 2**20
    assert answers[-1][0] == "ok" and int(answers[-1][1]) > 0, answers
    assert [a[0] for a in answers[:-1]] == ["refused"] * (len(answers) - 1), answers


def test_max_bytes_holds_for_rows_every_step_and_on_restart(tmp_path, mrsim):
    """&output max_bytes refused a fixed-step run's results before it ran, but an adaptive
    run writing a row every step (no row count known before) wrote 810 kB under
    max_bytes = 1000, and a restart to a longer t_end ran past the limit that refused the
    same run from the start. Now the first fails when its rows reach the limit (exit 2), and
    the second is refused as the fresh run is."""
    r = mrsim_run(mrsim, PENDULUM, tmp_path / "b.csv", "integrator.adaptive=.true.", "output.dt=0",
                  "output.max_bytes=1000")
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    assert re.search(r": at t = \S+ s: the results reach max_bytes = 1000 \(\d+ rows, one every step\): give "
                     r"&output dt, or raise max_bytes$", r.stderr.strip()), r.stderr
    assert not (tmp_path / "b.csv").exists()
    sets = ("output.checkpoint_dt=2", "output.max_bytes=300000")
    assert mrsim_run(mrsim, PENDULUM, tmp_path / "c.csv", *sets).returncode == 0
    before = (tmp_path / "c.csv").read_bytes()
    for restart in ([], ["--restart", str(tmp_path / "c.ckpt")]):
        r = subprocess.run([mrsim, str(PENDULUM), "-o", str(tmp_path / "c.csv"), "--quiet", *restart,
                            *[a for s in (*sets, "scene.t_end=20") for a in ("--set", s)]],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 1 and "&output: dt: the results would take about" in r.stderr, r.stderr
        assert (tmp_path / "c.csv").read_bytes() == before


@pytest.mark.parametrize("sets, named", [
    ({"integrator.rtol": 1e-3}, "rtol"),
    ({"integrator.rtol": 1e-3, "integrator.atol": 1e-6, "integrator.h_min": 1e-9}, "rtol, atol, h_min"),
    ({}, None),
    ({"integrator.rtol": 1e-3, "integrator.adaptive": True}, None),
])
def test_tolerances_a_fixed_step_run_does_not_use_are_said(tmp_path, sets, named):
    """The pendulum at fixed steps with adaptive-only items given: the run goes on (a study
    sets adaptive = .false. on scenes that give their tolerances) and is the same run as
    without them, and its summary and JSON warn, naming them; none without them or when the
    steps are adaptive."""
    res = pymr.run(PENDULUM, tmp_path / "p.csv", overrides=sets)
    warnings = res.stats["warnings"]
    if named is None:
        assert warnings == [] and "warning" not in res.summary
        return
    assert warnings == [f"&integrator {named}: given, but fixed steps (adaptive = .false.) do not use them"]
    assert f"warning: {warnings[0]}" in res.summary
    plain = pymr.run(PENDULUM, tmp_path / "q.csv")
    assert np.array_equal(res.data, plain.data)


def test_a_table_past_4_gib_is_refused_not_read_in_part(tmp_path, mrsim):
    """A table file of 2^32 + 18 bytes (sparse: its rows, NULs in a comment line, a last
    row) was read as its first 18 bytes, the size held in a 32-bit integer: the terrain's
    last row dropped, exit 0; between 2 and 4 GiB it was 'not a regular file' (found by an
    audit of the files scenes read). Now one line naming the file, its size and the limit,
    exit 1."""
    shutil.copytree(ROOT / "input" / "tank_on_the_move", tmp_path / "tank_on_the_move")
    shutil.copy(ROOT / "input" / "tank_on_the_move.nml", tmp_path / "tom.nml")
    table = tmp_path / "tank_on_the_move" / "terrain_front.txt"
    rows = table.read_bytes().rstrip(b"\n").split(b"\n")
    head, tail = b"\n".join(rows[:-1]) + b"\n#", b"\n" + rows[-1] + b"\n"
    for size in (2**32 + len(head) + len(tail), 2**31 + 100):
        with open(table, "wb") as fh:
            fh.write(head)
            fh.seek(size - len(tail))
            fh.write(tail)
        r = subprocess.run([mrsim, "tom.nml", "-o", "t.csv", "-q"], cwd=tmp_path, capture_output=True, text=True,
                           timeout=120)
        assert r.returncode == 1 and r.stderr.count("\n") == 1, r.stderr
        assert (f"file: tank_on_the_move/terrain_front.txt: cannot read: it holds {size} bytes, more than the "
                "2147483647 a text file pymr reads may hold") in r.stderr, r.stderr


FAR = """! a block pushed along x by a constant force, an arm hinged on it
&scene title = 'far', t_end = {t_end}, gravity = 0.0, -9.81, 0.0 /
&integrator method = 'single', h_slow = 1.0e-3, adaptive = .true. /
&effects gravity = .true., joint_drives = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'block', kind = 'rigid', mass = 1.0, inertia = 1.0e-2, 1.0e-2, 1.0e-2, 0.0, 0.0, 0.0 /
{arm}
&joint name = 'slide', kind = 'prismatic', parent = 'ground', child = 'block', axis = 1.0, 0.0, 0.0 /
&drive joint = 'slide', offset = 1.0e6 /
&output dt = 0.01 /
"""
ARM = """&body name = 'arm', kind = 'rigid', mass = 1.0, com = 0.5, 0.0, 0.0, inertia = 1.0e-3, 0.1, 0.1, 0.0, 0.0, 0.0 /
&joint name = 'hinge', kind = 'revolute', parent = 'block', child = 'arm', axis = 0.0, 0.0, 1.0, q0 = -1.0 /"""


def test_a_joint_turning_bodies_far_from_the_origin_stops_the_run_before_its_digits_go(tmp_path, mrsim):
    """The recursive algorithms sum inertias about the origin: a coordinate's inertia J is
    what is left of the bodies' m r^2 = S there, with the roundoff epsilon S. The pre-flight
    check refuses a scene whose J is within 1e4 times that at the start (4 digits); a run
    that went there went on, with exit 0 and its accelerations off (by 4e-4 at 1e7 m), then
    failed as 'articulated inertia 0'. It now stops (exit 2, one line naming the time, the
    coordinate and both figures) by the same rule: the arm's 0.35 kg m^2 about its hinge,
    whose origin travels with the block, at sqrt(1e-4 J / epsilon) = 397 km. The rule against
    a second evaluation: this scene's accelerations do not depend on x, and the model's
    right-hand side there differs from the one at x = 0 by about the rule's 1e-4 (at most
    1.05e-4 over 50 points within 5e-8 of it, median 3e-5, glibc's FMA paths off), a hundred
    times less a tenth as far. A block sliding alone loses nothing: it runs to 5e7 m, as
    x = F t^2 / (2 m) gives it."""
    (tmp_path / "far.nml").write_text(FAR.format(t_end=2.0, arm=ARM))
    r = subprocess.run([mrsim, "far.nml", "-o", "far.csv"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stderr.count("\n") == 1, r.stderr
    m = re.fullmatch(r"mrsim: error: far\.nml: at t = \S+ s: coordinate hinge\.q moves an inertia of 0\.35 kg m\^2, "
                     r"within 10000 times the roundoff \(\S+\) of the inertia about the inertial origin of the bodies "
                     r"it moves, which pymr assembles about \(their m r\^2 up to ([0-9.e+-]+) kg m\^2\): the motion "
                     r"has gone too far from the origin \(place the origin nearer\)\n", r.stderr)
    assert m, r.stderr
    x_stop = np.sqrt(1e-4 * 0.35 / np.finfo(float).eps)
    assert x_stop <= np.sqrt(float(m.group(1))) <= 1.05 * x_stop
    model = pymr.Model(tmp_path / "far.nml")
    near = model.rhs(0.0, np.array([0.0, 0.5, 0.0, 2.0]))
    for x, most in ((x_stop, 5e-4), (0.1 * x_stop, 5e-6)):
        far = model.rhs(0.0, np.array([x, 0.5, 0.0, 2.0]))
        assert np.max(np.abs(far[2:] - near[2:]) / np.abs(near[2:])) < most, x
    (tmp_path / "alone.nml").write_text(FAR.format(t_end=10.0, arm=""))
    res = pymr.run(tmp_path / "alone.nml")
    assert res["slide.q"][-1] == pytest.approx(1e6 * 10.0**2 / 2, rel=1e-10)
