"""The check a refused scene must pass, shared by the tests of scene groups: `mrsim` exits 1
with one line naming the file (and what `pattern` says after it), writes no results, and
`pymr.run` raises SceneError."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest

import pymr


def check_refused_in_one_line(mrsim: str, scene: Path, pattern: str) -> None:
    out_csv = scene.with_suffix(".csv")
    out = subprocess.run([mrsim, str(scene), "-o", str(out_csv)], capture_output=True, text=True, timeout=60)
    assert out.returncode == 1
    lines = out.stderr.strip().split("\n")
    assert len(lines) == 1 and lines[0].startswith("mrsim: error: "), out.stderr
    assert re.search(re.escape(scene.name) + pattern, lines[0]), lines[0]
    assert not out_csv.exists()
    with pytest.raises(pymr.SceneError):
        pymr.run(scene)
