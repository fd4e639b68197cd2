"""Shared fixtures of pymr's tests."""
from __future__ import annotations

import os

# One BLAS thread, as Dask's workers run (their nanny sets these): with OpenBLAS the thread
# count changes the last bits of LAPACK's sums, and the sweep tests compare a worker's run
# with the same run here. Set before anything loads the BLAS.
for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

import pytest  # noqa: E402

from pymr._locate import mrsim_path


@pytest.fixture(scope="session")
def mrsim() -> str:
    """Path of the mrsim executable; the test fails (it is not skipped) when it is missing."""
    path = mrsim_path()
    if path is None or not os.path.isfile(path) or not os.access(path, os.X_OK):
        pytest.fail(f"mrsim executable not found (pymr._locate.mrsim_path() gave {path!r}); "
                    "build the package or set PYMR_MRSIM")
    return path
