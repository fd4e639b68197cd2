"""Progress of long runs (issue 7): mrsim --progress prints lines to stderr; pymr run shows a
progress bar on a terminal (a pseudo-terminal here) and nothing in batch; the Python run
reads the kernel's progress from another thread, so the bar moves during the run."""
from __future__ import annotations

import fcntl
import os
import pty
import re
import struct
import subprocess
import sys
import termios
from pathlib import Path

import pytest

import pymr

ROOT = Path(__file__).resolve().parent.parent
LONG = ROOT / "input" / "hard" / "tank_long.nml"


def test_mrsim_progress_lines_only_when_asked(tmp_path, mrsim):
    args = [mrsim, str(LONG), "-o", str(tmp_path / "l.csv"), "--set", "scene.t_end=5", "-q"]
    quiet = subprocess.run(args, capture_output=True, text=True)
    assert quiet.returncode == 0 and quiet.stderr == ""
    loud = subprocess.run(args + ["--progress"], capture_output=True, text=True)
    assert loud.returncode == 0 and loud.stdout == ""
    lines = loud.stderr.strip().splitlines()
    pat = re.compile(r"mrsim: t = +([\d.E+-]+) s of +5\.0000E\+00 s \( *([\d.]+) %\), +[\d.]+ s elapsed"
                     r"(, ETA +[\d.]+ s)?")
    got = [pat.fullmatch(line) for line in lines]
    assert all(got) and len(got) >= 2
    assert float(got[0].group(2)) < 1.0 and float(got[-1].group(2)) == 100.0
    # no time to go at the start (the start-up's pace says nothing of the rest) nor at the end
    assert got[0].group(3) is None and got[-1].group(3) is None
    # each line is news: the simulated time only grows (the last line was not printed twice)
    times = [float(g.group(1)) for g in got]
    assert all(a < b for a, b in zip(times, times[1:])), lines


def _pymr_on_a_terminal(args: list[str], cwd: Path) -> str:
    """Run `pymr ARGS` with stderr on a pseudo-terminal; return what the terminal got. The
    working folder is not the checkout's root, whose pymr/ would shadow the installed one."""
    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 100, 0, 0))     # a 100-column terminal
    proc = subprocess.Popen([sys.executable, "-c", "from pymr.cli import main; raise SystemExit(main())"] + args,
                            stdout=subprocess.DEVNULL, stderr=slave, close_fds=True, cwd=cwd)
    os.close(slave)
    chunks = []
    while True:
        try:
            data = os.read(master, 4096)
        except OSError:
            break
        if not data:
            break
        chunks.append(data)
    proc.wait()
    os.close(master)
    assert proc.returncode == 0
    return b"".join(chunks).decode(errors="replace")


def test_pymr_run_shows_progress_on_a_terminal_and_not_in_batch(tmp_path):
    args = ["run", str(LONG), "-o", str(tmp_path / "l.csv"), "--set", "scene.t_end=5"]
    shown = _pymr_on_a_terminal(args, tmp_path)
    assert "pymr tank_long.nml: 100%" in shown and "t = 5 of 5 s" in shown
    batch = subprocess.run([sys.executable, "-c", "from pymr.cli import main; raise SystemExit(main())"] + args,
                           capture_output=True, text=True, cwd=tmp_path)
    assert batch.returncode == 0 and batch.stderr == ""
    assert "%|" not in _pymr_on_a_terminal(args + ["--no-progress"], tmp_path)


def test_python_progress_reads_the_kernel_during_the_run(tmp_path, capsys):
    """progress=True: the bar's intermediate values come from the running kernel (strictly
    between 0 and t_end); progress=False prints nothing."""
    pymr.run(LONG, tmp_path / "a.csv", overrides={"scene.t_end": 40.0}, progress=True)
    err = capsys.readouterr().err
    values = [float(v) for v in re.findall(r"t = ([\d.]+) of 40 s", err)]
    assert values[-1] == 40.0
    assert any(0.0 < v < 40.0 for v in values), err[-500:]
    pymr.run(LONG, tmp_path / "b.csv", overrides={"scene.t_end": 1.0}, progress=False)
    assert capsys.readouterr().err == ""


def test_the_bar_shows_the_run_s_t_end_from_its_first_line_and_its_last_line_once(tmp_path, capsys):
    """Issue 30: the first line of a 300 s run read 't = 0 of 1 s' (the bar was drawn before
    the kernel had said its t_end) and the last line was drawn twice (once more by tqdm's
    close). A run long enough for several lines: every drawing says 'of 60 s', the time only
    grows, and the last state is drawn once. A run refused before it starts draws no bar."""
    pymr.run(LONG, tmp_path / "a.csv", overrides={"scene.t_end": 60.0}, progress=True)
    err = capsys.readouterr().err
    drawn = [part for part in re.split(r"[\r\n]", err) if part.strip()]
    assert len(drawn) >= 3, err
    totals = [re.search(r"t = [\d.]+ of ([\d.]+) s", d).group(1) for d in drawn]
    assert totals == ["60"] * len(drawn), drawn
    times = [float(re.search(r"t = ([\d.]+) of", d).group(1)) for d in drawn]
    assert all(a < b for a, b in zip(times, times[1:])), drawn
    assert times[-1] == 60.0 and "100%" in drawn[-1]
    assert err.endswith("\n") and err.count("\n") == 1
    with pytest.raises(pymr.SceneError):
        pymr.run(LONG, tmp_path / "b.csv", overrides={"scene.t_end": -1.0}, progress=True)
    assert "%|" not in capsys.readouterr().err


def test_a_run_over_before_the_first_look_draws_its_bar_once(tmp_path, capsys):
    """A run shorter than the bar's first look (0.1 s) still shows where it ended, once."""
    pymr.run(LONG, tmp_path / "a.csv", overrides={"scene.t_end": 0.01}, progress=True)
    drawn = [part for part in re.split(r"[\r\n]", capsys.readouterr().err) if part.strip()]
    assert len(drawn) == 1 and "100%" in drawn[0] and "t = 0.01 of 0.01 s" in drawn[0], drawn
