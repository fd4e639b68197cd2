"""Shared fixtures of pymr's tests."""
from __future__ import annotations

import os

import pytest

from pymr._locate import mrsim_path


@pytest.fixture(scope="session")
def mrsim() -> str:
    """Path of the mrsim executable; the test fails (it is not skipped) when it is missing."""
    path = mrsim_path()
    if path is None or not os.path.isfile(path) or not os.access(path, os.X_OK):
        pytest.fail(f"mrsim executable not found (pymr._locate.mrsim_path() gave {path!r}); "
                    "build the package or set PYMR_MRSIM")
    return path
