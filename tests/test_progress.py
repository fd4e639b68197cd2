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
    pat = re.compile(r"mrsim: t = +([\d.E+-]+) s of +5\.0000E\+00 s \( *([\d.]+) %\), +[\d.]+ s elapsed, ETA +[\d.]+ s")
    got = [pat.fullmatch(line) for line in lines]
    assert all(got) and len(got) >= 2
    assert float(got[0].group(2)) < 1.0 and float(got[-1].group(2)) == 100.0


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
