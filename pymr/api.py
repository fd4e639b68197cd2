"""Python entry points into the Fortran kernel (one call per run, never per step)."""
from __future__ import annotations

import os
import sys
import tempfile
import threading
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np

try:
    from . import _kernel as _core
except ImportError:
    raise ImportError("pymr's compiled kernel (pymr._core) is not here: this is the source folder, not the "
                      "installed package. Build and install it with 'bash .ci/setup' (or 'pip install "
                      "--no-build-isolation .') and import pymr from outside the checkout.") from None
from .errors import OutputError, PymrError, ResultsError, SceneError, SolverError  # noqa: F401
from .results import Results, load_results


def write_file(path: str | os.PathLike, data: str | bytes, what: str) -> Path:
    """Write `data` to `path` whole or not at all: a temporary file beside it, flushed to
    the disk (fsync), then renamed over it, so an earlier complete file survives a failed
    write. A failure is an :class:`OutputError` naming the file and `what` it was to hold."""
    path = Path(path)
    tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
    try:
        if path.is_dir():
            raise IsADirectoryError(21, "it is a directory")
        with open(tmp, "wb") as fh:
            fh.write(data.encode() if isinstance(data, str) else data)
            fh.flush()
            os.fsync(fh.fileno())
        os.replace(tmp, path)
    except OSError as exc:
        tmp.unlink(missing_ok=True)
        raise OutputError(f"{path}: cannot write the {what} ({exc.strerror or exc})") from None
    return path


def check_not_input(scene, path: str | os.PathLike, what: str, overrides=None) -> None:
    """`path`, an output, is none of the scene's inputs (the scene, its modal and table files:
    the kernel's rule, which the results and modal files obey too); else a SceneError."""
    found, stat, msg = _core.pymr_scene_input(*_scene_and_overrides(scene, overrides), os.fspath(path))
    _raise(stat, msg)
    if _text(found):
        raise SceneError(f"{path}: would overwrite {_text(found)}; choose another {what}")


def _raise(stat: int, message: bytes | str) -> None:
    if stat == 0:
        return
    raise (SceneError if stat == 1 else SolverError)(_text(message))


def format_overrides(overrides: Mapping[str, object] | Iterable[str] | None) -> str:
    """Turn ``{"integrator.h_slow": 5e-4}`` or ``["integrator.h_slow=5e-4"]`` into the
    kernel's override text (one ``GROUP.ITEM=VALUE`` per line, values in namelist syntax)."""
    if not overrides:
        return ""
    if isinstance(overrides, Mapping):
        items = [f"{k}={nml_value(v)}" for k, v in overrides.items()]
    elif isinstance(overrides, str):
        items = [overrides]        # one override (iterating it gave one per character)
    else:
        items = [str(s) for s in overrides]
    for item in items:
        if "\n" in item or "\r" in item:
            # the kernel reads one override a line: a line break would make two of one
            raise SceneError(f"--set {item!r}: a line break in an override (one GROUP.ITEM=VALUE, on one line)")
    return "\n".join(items)   # the kernel checks each entry and names the scene file


def nml_value(v: object) -> str:
    if isinstance(v, bool):
        return ".true." if v else ".false."
    if isinstance(v, str):
        return "'" + v.replace("'", "''") + "'"
    if isinstance(v, (list, tuple, np.ndarray)):
        return ", ".join(nml_value(x) for x in v)
    return repr(float(v)) if isinstance(v, float) else str(v)


def _scene_and_overrides(scene, overrides) -> tuple[str, str]:
    """The scene file and the override text for the kernel: a :class:`pymr.Scene` brings its
    own overrides, which the call's overrides follow (and so win)."""
    text = format_overrides(overrides)
    from .scene import Scene
    if isinstance(scene, Scene):
        return str(scene.path), "\n".join(t for t in (scene.overrides, text) if t)
    return os.fspath(scene), text


def run(scene, output: str | os.PathLike | None = None,
        overrides: Mapping[str, object] | Iterable[str] | None = None,
        restart: str | os.PathLike | None = None, progress: bool | None = None) -> Results:
    """Run a scene (a namelist file's path or a :class:`pymr.Scene`) in the Fortran kernel and
    return its results as numpy arrays.

    ``output`` is the CSV path (the JSON statistics go beside it); ``""`` lets the kernel
    choose (``&output file``, else SCENE.csv); ``None`` writes to a temporary folder,
    loads the results and removes the files.
    ``overrides`` changes namelist values for this run, as ``pymr run --set`` does.
    ``restart`` continues a run from its checkpoint file (``&output checkpoint_dt``): the
    results file keeps the rows written up to the checkpoint and the run goes on from there.
    ``progress`` shows simulated time, percent and ETA (tqdm) while the kernel runs; by
    default only when stderr is a terminal. The kernel runs in a thread and Python reads
    its progress ten times a second: no per-step call crosses into Python.
    Raises :class:`SceneError` for bad input and :class:`SolverError` for a failed run.
    """
    scene, text = _scene_and_overrides(scene, overrides)
    ckpt = "" if restart is None else os.fspath(restart)
    if restart is not None and not ckpt:
        # an empty name (an unset variable) would run from the start instead
        raise SceneError("restart: an empty checkpoint path (None runs from the start)")
    if ckpt and output is None:
        raise SceneError("a restart continues an existing results file: give output (or '' for the default)")
    if output == "":
        # let the kernel choose: &output file, else SCENE.csv in the working folder
        stat, msg, summary, written = _run_kernel(scene, text, "", ckpt, progress)
        _raise(stat, msg)
        res = load_results(_text(written))
    elif output is None:
        with tempfile.TemporaryDirectory(prefix="pymr-") as tmp:
            out = str(Path(tmp) / "results.csv")
            stat, msg, summary, _ = _run_kernel(scene, text, out, ckpt, progress)
            _raise(stat, msg)
            res = load_results(out)
    else:
        out = os.fspath(output)
        stat, msg, summary, _ = _run_kernel(scene, text, out, ckpt, progress)
        _raise(stat, msg)
        res = load_results(out)
    res.summary = _text(summary)
    return res


def _run_kernel(scene: str, text: str, out: str, ckpt: str, progress: bool | None):
    """pymr_run_scene, with a progress bar on a terminal (or when asked). The bar appears
    once the kernel has started stepping and knows its t_end (not 't = 0 of 1 s' before),
    and is drawn for the last time by tqdm's close (not once more before it); a run that
    never started stepping (bad input) shows no bar."""
    show = sys.stderr.isatty() if progress is None else progress
    if not show:
        return _core.pymr_run_scene(scene, text, out, ckpt)
    from tqdm import tqdm
    result: list = []
    worker = threading.Thread(target=lambda: result.append(_core.pymr_run_scene(scene, text, out, ckpt)))
    worker.start()
    bar = None

    def open_bar(t: float, t_end: float, draw: bool = True):
        return tqdm(total=float(t_end), initial=float(t), unit="s", desc=f"pymr {Path(scene).name}", file=sys.stderr,
                    delay=0 if draw else float("inf"),
                    bar_format="{desc}: {percentage:3.0f}%|{bar}| t = {n:.4g} of {total:.4g} s "
                               "[{elapsed}<{remaining}]")
    try:
        while worker.is_alive():
            worker.join(0.1)
            t, t_end, running = _core.pymr_progress()
            if running and t_end > 0:
                if bar is None:
                    bar = open_bar(t, t_end)
                elif float(t) != bar.n:
                    bar.n = float(t)
                    bar.refresh()
        t, t_end, _ = _core.pymr_progress()
        ok = bool(result) and result[0][0] == 0
        if bar is None and ok and t_end > 0:
            # a run over before the first look: drawn once, by close (delay 0 from here)
            bar = open_bar(t_end, t_end, draw=False)
            bar.delay = 0
        elif bar is not None:
            bar.n = float(t_end) if ok else float(t)
    finally:
        if bar is not None:
            bar.close()                           # draws the last state once, and ends the line
    return result[0]


def _text(value: bytes | str) -> str:
    """A fixed-length character result of the binding as a stripped str (a path in it as
    the file system names it: bytes that are not UTF-8 survive, as os.fsdecode keeps them)."""
    return (os.fsdecode(value) if isinstance(value, bytes) else str(value)).strip()


def model_size(scene: str | os.PathLike, overrides=None) -> tuple[int, int, int]:
    """(coordinates, bodies including the ground, markers) of a scene's model."""
    n, nb, nm, stat, msg = _core.pymr_model_size(*_scene_and_overrides(scene, overrides))
    _raise(stat, msg)
    return int(n), int(nb), int(nm)


def _states(q, qd) -> tuple[np.ndarray, np.ndarray]:
    """q and qd as float arrays of one shape (ValueError naming qd otherwise)."""
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    if q.shape != qd.shape:
        raise ValueError(f"qd: shape {qd.shape} differs from q's {q.shape}")
    return q, qd


def _finite(q: np.ndarray, qd: np.ndarray) -> None:
    """States whose values the kernel returns as they come (terms, energies, positions) must
    be finite: their results would be NaN with no word. (The accelerations' own checks name
    the LAPACK routine a non-finite entry would reach.)"""
    for name, v in (("q", q), ("qd", qd)):
        if not np.isfinite(v).all():
            raise SceneError(f"{name}: {v.flat[np.argmin(np.isfinite(v))]} is not a finite number")


def _many_states(t, q, qd, finite: bool = True) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (m,) and states q, qd (m, n) (one state (n,) is m = 1) for the kernel: t as
    an array of m finite times, q and qd transposed to (n, m) in Fortran order (and finite
    unless `finite` is False)."""
    q, qd = _states(q, qd)
    if finite:
        _finite(q, qd)
    q2 = np.asfortranarray(np.atleast_2d(q).T)
    qd2 = np.asfortranarray(np.atleast_2d(qd).T)
    t1 = np.atleast_1d(np.asarray(t, dtype=float))
    if t1.shape != (q2.shape[1],):
        raise ValueError(f"t: one time per state expected, shape ({q2.shape[1]},), got shape {t1.shape}")
    if not np.isfinite(t1).all():
        raise SceneError(f"t: {t1[np.argmin(np.isfinite(t1))]} is not a finite time")
    return t1, q2, qd2


def _count(name: str, value) -> int:
    """A whole number from 1 to the kernel's largest (a C int): f2py raised OverflowError
    above it and a ValueError about 'intent(cache|hide)' arrays below 1."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 1 <= value < 2**31 - 1:
        raise SceneError(f"{name}: a whole number from 1 to {2**31 - 2}, got {value!r}")
    return int(value)


def _time(t) -> float:
    """One time (s) for the kernel: a finite number."""
    try:
        value = float(t)
    except (TypeError, ValueError):
        raise SceneError(f"t: a time in seconds, got {t!r}") from None
    if not np.isfinite(value):
        raise SceneError(f"t: {value} is not a finite time")
    return value


def _one_state(q, qd) -> tuple[np.ndarray, np.ndarray]:
    """q and qd of one state (shape (n,)), contiguous, for the kernel."""
    q, qd = _states(q, qd)
    if q.ndim != 1:
        raise ValueError(f"q: one state of shape (n,) expected, got shape {q.shape}")
    return np.ascontiguousarray(q), np.ascontiguousarray(qd)


def model_terms(scene: str | os.PathLike, q, qd, t: float = 0.0, overrides=None):
    """Mass matrix M and right-hand side P of ``M qdd = P`` at (t, q, qd)."""
    q, qd = _one_state(q, qd)
    _finite(q, qd)
    mm, p, stat, msg = _core.pymr_model_terms(*_scene_and_overrides(scene, overrides), _time(t), q, qd)
    _raise(stat, msg)
    return mm, p


def force_response(scene: str | os.PathLike, q, qd, t: float = 0.0, overrides=None):
    """The 'response' coupling's terms at (t, q, qd): ``g = M^-1 E`` (shape (n, nf)), the
    response of every acceleration to a unit force on each modal coordinate, and the modal
    stiffness ``kf`` and damping ``df`` (shape (nf,)) of the fast forces ``kf a + df ad``."""
    nf, g, kf, df, stat, msg = _core.pymr_force_response(*_scene_and_overrides(scene, overrides), _time(t),
                                                        *_one_state(q, qd))
    _raise(stat, msg)
    nf = int(nf)
    return g[:, :nf].copy(), kf[:nf].copy(), df[:nf].copy()


def modes(scene: str | os.PathLike, q, qd, t: float = 0.0, overrides=None):
    """Natural modes of the model linearised at (t, q, qd), by the pre-flight check's
    linearisation (central differences of P, LAPACK dgeev of the state matrix): frequencies
    (Hz, ascending), damping ratios, and shapes (shape (n, number of modes): each column the
    coordinates' motion, its largest component 1); with closed loops, the constrained ones.
    Drifting motions (a free joint) are not modes and are left out."""
    nm, freq, zeta, shapes, stat, msg = _core.pymr_modes(*_scene_and_overrides(scene, overrides), _time(t),
                                                          *_one_state(q, qd))
    _raise(stat, msg)
    nm = int(nm)
    return freq[:nm].copy(), zeta[:nm].copy(), shapes[:, :nm].copy()


def marker_shapes(scene, markers, q, qd, shapes, t: float = 0.0, overrides=None) -> dict[str, np.ndarray]:
    """Mode shapes as marker displacements: for each named marker, an array (3, modes) of
    the derivative of its inertial position along each shape (the columns of `shapes`, as
    :func:`modes` gives them) at (t, q, qd), by central differences of 1e-6 times the shape:
    metres per unit of the shape's coordinates."""
    q, qd = _one_state(q, qd)
    shapes = np.asarray(shapes, dtype=float)
    if shapes.ndim != 2 or shapes.shape[0] != q.size:
        raise ValueError(f"shapes: an array ({q.size}, modes) expected (modes() gives one), got shape {shapes.shape}")
    eps = 1e-6
    out = {}
    with Model(scene, overrides) as model:
        for name in markers:
            plus = model.marker(name, np.full(shapes.shape[1], t), (q[:, None] + eps * shapes).T,
                                np.tile(qd, (shapes.shape[1], 1)))
            minus = model.marker(name, np.full(shapes.shape[1], t), (q[:, None] - eps * shapes).T,
                                 np.tile(qd, (shapes.shape[1], 1)))
            out[name] = ((plus - minus) / (2 * eps)).T.copy()
    return out


def step_history(scene: str | os.PathLike, overrides=None, max_steps: int = 200_000):
    """The run's own stepper from the initial state to t_end, without output: arrays of the
    time reached, the step taken and the method's order at each accepted step (entry 0 is
    the start: its step 0, its order the starting one). More than ``max_steps`` steps is an
    error."""
    t, h, q, nh, stat, msg = _core.pymr_step_history(*_scene_and_overrides(scene, overrides),
                                                     _count("max_steps", max_steps) + 1)
    _raise(stat, msg)
    nh = int(nh)
    return t[:nh].copy(), h[:nh].copy(), q[:nh].copy()


def model_accelerations(scene: str | os.PathLike, t, q, qd, overrides=None) -> np.ndarray:
    """Accelerations for one state (q of shape (n,)) or many (shape (m, n), t of shape (m,))."""
    single = np.ndim(q) == 1
    t1, q2, qd2 = _many_states(t, q, qd, finite=False)
    qdd, stat, msg = _core.pymr_model_accelerations(*_scene_and_overrides(scene, overrides), t1, q2, qd2)
    _raise(stat, msg)
    return qdd[:, 0].copy() if single else qdd.T.copy()


def loop_rows(scene: str | os.PathLike, q, qd, overrides=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The loops' constraint rows at one state (method.md section 2.5): the residual
    ``phi`` (shape (r,)), the Jacobian ``G`` (shape (r, n)) and ``gamma = -Gdot qd``
    (shape (r,)) of every loop-closing joint, redundant rows included."""
    q, qd = _one_state(q, qd)
    where = _scene_and_overrides(scene, overrides)
    nr, *_, stat, msg = _core.pymr_loop_rows(*where, 0, q, qd)
    _raise(stat, msg)
    nr = int(nr)
    _, phi, g, gam, stat, msg = _core.pymr_loop_rows(*where, max(nr, 1), q, qd)
    _raise(stat, msg)
    return phi[:nr].copy(), g[:nr].copy(), gam[:nr].copy()


def model_energy(scene: str | os.PathLike, q, qd, overrides=None) -> tuple[np.ndarray, np.ndarray]:
    """Kinetic and potential energy for states q, qd of shape (m, n) (or one state of shape
    (n,)): arrays of shape (m,). The potential energy is the flexible bodies' strain energy,
    plus gravity's and the joint springs' when those effects are on."""
    _, q2, qd2 = _many_states(np.zeros(np.atleast_2d(q).shape[0]), q, qd)
    ke, pe, stat, msg = _core.pymr_model_energy(*_scene_and_overrides(scene, overrides), q2, qd2)
    _raise(stat, msg)
    return ke, pe


def write_modal_file(scene: str | os.PathLike, body: str, path: str | os.PathLike, overrides=None) -> None:
    """Write the modes of beam ``body`` of a scene to a modal data file, which a
    ``kind='modal'`` body can read back (``modal_file=...``)."""
    stat, msg = _core.pymr_write_modal(*_scene_and_overrides(scene, overrides), body, os.fspath(path))
    _raise(stat, msg)


class Model:
    """A scene's model kept open in the kernel, for integrators driven from Python (scipy's
    ``solve_ivp``, SUNDIALS CVODE): ``rhs(t, x)`` is f of ``x' = f(t, x)`` for the state
    ``x = [q; qd]``, ``evaluations`` counts the kernel's full evaluations so far, and
    ``marker(name, t, q, qd)`` gives a marker's positions at states of shape (m, n)."""

    def __init__(self, scene: str | os.PathLike, overrides=None):
        self.scene, text = _scene_and_overrides(scene, overrides)
        handle, n, stat, msg = _core.pymr_model_open(self.scene, text)
        _raise(stat, msg)
        self.handle, self.n, self.evaluations = int(handle), int(n), 0

    def rhs(self, t: float, x) -> np.ndarray:
        x = np.asarray(x, dtype=float)
        if x.shape != (2 * self.n,):
            raise ValueError(f"x: the state [q; qd] of shape ({2 * self.n},) expected, got shape {x.shape}")
        f, evals, stat, msg = _core.pymr_model_rhs(self.handle, float(t), x)
        if stat:
            _raise(stat, msg)
        self.evaluations = int(evals)
        return f

    def marker(self, name: str, t, q, qd) -> np.ndarray:
        k = int(_core.pymr_model_marker_index(self.handle, name))
        if k == 0:
            raise SceneError(f"{self.scene}: no marker {name!r}")
        t1, q2, qd2 = self._states(t, q, qd)
        pos, stat, msg = _core.pymr_model_marker(self.handle, k, t1, q2, qd2)
        _raise(stat, msg)
        return pos.T.copy()

    def frames(self, t, q, qd, nb: int):
        """Every body's frame origin (inertial, m) at states of shape (m, n): an array
        (m, nb, 3), and each body's parent (1-based, 0 for the ground), for drawing."""
        t1, q2, qd2 = self._states(t, q, qd)
        pos, parent, stat, msg = _core.pymr_model_frames(self.handle, _count("nb", nb), t1, q2, qd2)
        _raise(stat, msg)
        return np.transpose(pos, (2, 1, 0)).copy(), np.asarray(parent, dtype=int)

    def _states(self, t, q, qd):
        """The kernel's (t, q, qd) of :func:`_many_states`, each state of this model's n coordinates."""
        t1, q2, qd2 = _many_states(t, q, qd)
        if q2.shape[0] != self.n:
            raise ValueError(f"q: states of {self.n} coordinates expected, got {q2.shape[0]}")
        return t1, q2, qd2

    def marker_body(self, name: str) -> int:
        """The index (0-based, as in :meth:`frames`) of the body marker `name` is on."""
        k = int(_core.pymr_model_marker_index(self.handle, name))
        if k == 0:
            raise SceneError(f"{self.scene}: no marker {name!r}")
        return int(_core.pymr_model_marker_body(self.handle, k)) - 1

    def close(self) -> None:
        if self.handle:
            _core.pymr_model_close(self.handle)
            self.handle = 0

    def __enter__(self) -> "Model":
        return self

    def __exit__(self, *exc) -> None:
        self.close()
