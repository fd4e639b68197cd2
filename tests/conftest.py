"""Shared fixtures of pymr's tests."""
from __future__ import annotations

import os

# One BLAS thread, as Dask's workers run (their nanny sets these): with OpenBLAS the thread
# count changes the last bits of LAPACK's sums, and the sweep tests compare a worker's run
# with the same run here. Set before anything loads the BLAS.
for _name in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")

from pathlib import Path  # noqa: E402

import numpy as np  # noqa: E402
import pytest  # noqa: E402

import pymr  # noqa: E402
from pymr._locate import mrsim_path

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="session")
def mrsim() -> str:
    """Path of the mrsim executable; the test fails (it is not skipped) when it is missing."""
    path = mrsim_path()
    if path is None or not os.path.isfile(path) or not os.access(path, os.X_OK):
        pytest.fail(f"mrsim executable not found (pymr._locate.mrsim_path() gave {path!r}); "
                    "build the package or set PYMR_MRSIM")
    return path


@pytest.fixture(scope="session")
def stiff_barrel_reference():
    """The stiff barrel's muzzle every 1 ms over 0.2 s from DOP853 at rtol 1e-13 on pymr's own
    right-hand side (scipy, a second integrator): the scene's path and the (201, 3) positions."""
    from scipy.integrate import solve_ivp
    scene = ROOT / "input" / "hard" / "stiff_barrel.nml"
    probe = pymr.run(scene, overrides={"output.dt": 0.0, "scene.t_end": 1e-6})
    q, qd = probe.coordinates()
    x0 = np.concatenate([q[0], qd[0]])
    grid = np.linspace(0.0, 0.2, 201)
    with pymr.Model(scene) as model:
        sol = solve_ivp(model.rhs, (0.0, 0.2), x0, method="DOP853", t_eval=grid, rtol=1e-13, atol=1e-15)
        n = q.shape[1]
        return scene, model.marker("muzzle", sol.t, sol.y[:n].T, sol.y[n:].T)
