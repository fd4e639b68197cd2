"""Nothing lost, nothing silent (issue 15, first part): LAPACK's error handler returns instead
of stopping the process, the statistics are valid JSON whatever the title holds, text that
is not UTF-8 is refused at read, and an output path that would overwrite what the run reads
(or collide with its own statistics) is refused before anything is written."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

import pymr
from pymr import _core

ROOT = Path(__file__).resolve().parent.parent
PENDULUM = (ROOT / "input" / "pendulum.nml").read_text().replace(
    "&output file = 'pendulum.csv', dt = 0.01 /", "&output dt = 0.01 /").replace("t_end = 10.0", "t_end = 0.05")


def test_lapack_illegal_argument_returns_to_pymr():
    """dpotrf called with uplo = 'X' reports argument 1 to XERBLA; pymr's XERBLA records it
    and returns (the reference one prints and ends the process with status 0), so LAPACK
    gives info = -1 and this test goes on."""
    info, routine, argument = _core.pymr_xerbla_probe()
    assert info == -1
    assert routine.decode().strip() == "DPOTRF" and argument == 1


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
