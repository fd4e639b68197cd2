"""Find the ``mrsim`` executable: on PATH (package install) or beside the build."""
from __future__ import annotations

import os
import shutil
import sys
from pathlib import Path


def mrsim_path() -> str | None:
    """Path of the mrsim executable, or None when it cannot be found."""
    env = os.environ.get("PYMR_MRSIM")
    if env and Path(env).exists():
        return env
    scripts = Path(sys.executable).parent / "mrsim"
    if scripts.exists():
        return str(scripts)
    found = shutil.which("mrsim")
    if found:
        return found
    # editable installs: meson-python builds in build/cp3XX beside the sources
    root = Path(__file__).resolve().parent.parent
    for cand in sorted(root.glob("build/*/fortran/mrsim")):
        return str(cand)
    return None
