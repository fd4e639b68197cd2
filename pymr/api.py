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
from .errors import (ArgumentTypeError, OutputError, PymrError, ResultsError, ResultsKeyError,  # noqa: F401
                     SceneError, SolverError)
from .results import Results, load_results
from ._args import (_array, _flag, _name, _names, _path, _raise, _scene_and_overrides, _short, _shown, _text,  # noqa: F401
                    check_not_input, format_overrides, model_of, nml_value, write_file)


def run(scene, output: str | os.PathLike | None = None,
        overrides: Mapping[str, object] | Iterable[str] | None = None,
        restart: str | os.PathLike | None = None, progress: bool | None = None) -> Results:
    """Run a scene (a namelist file's path or a :class:`pymr.Scene`) in the Fortran kernel and
    return its results as numpy arrays.

    ``output`` is the results path, OUT.csv (or OUT.h5 with ``&output format = 'hdf5'``;
    the JSON statistics go beside it); ``""`` lets the kernel choose (``&output file``,
    else SCENE.csv or SCENE.h5); ``None`` writes to a temporary folder, loads the results
    and removes the files.
    ``overrides`` changes namelist values for this run, as ``pymr run --set`` does.
    ``restart`` continues a run from its checkpoint file (``&output checkpoint_dt``): the
    results file keeps the rows written up to the checkpoint and the run goes on from there.
    ``progress`` shows simulated time, percent and ETA (tqdm) while the kernel runs; by
    default only when stderr is a terminal. The kernel runs in a thread and Python reads
    its progress ten times a second: no per-step call crosses into Python.
    Raises :class:`SceneError` for bad input and :class:`SolverError` for a failed run.
    """
    source = scene            # a pymr.Scene's file lives as long as the Scene: held to the end of the run
    scene, text = _scene_and_overrides(source, overrides)
    if output is not None:
        output = _path("output", output, OutputError)
    progress = _flag("progress", progress, none=True)
    ckpt = "" if restart is None else _path("restart", restart)
    if restart is not None and not ckpt:
        # an empty name (an unset variable) would run from the start instead
        raise SceneError("restart: an empty checkpoint path (None runs from the start)")
    if ckpt and output is None:
        raise SceneError("a restart continues an existing results file: give output (or '' for the default)")
    if output == "":
        # let the kernel choose: &output file, else SCENE.csv in the working folder
        stat, msg, detail, summary, written = _run_kernel(scene, text, "", ckpt, progress)
        _raise(stat, msg, detail)
        res = load_results(_text(written))
    elif output is None:
        with tempfile.TemporaryDirectory(prefix="pymr-") as tmp:
            out = str(Path(tmp) / ("results" + _results_suffix(scene, text)))
            stat, msg, detail, summary, _ = _run_kernel(scene, text, out, ckpt, progress)
            _raise(stat, msg, detail)
            res = load_results(out)
        # its 'results:' line named the files just removed
        summary = "\n".join(line if not line.startswith("results: ") else "results: not kept (output=None)"
                             for line in _text(summary).splitlines())
    else:
        out = output
        stat, msg, detail, summary, _ = _run_kernel(scene, text, out, ckpt, progress)
        _raise(stat, msg, detail)
        res = load_results(out)
    res.summary = _text(summary)
    del source
    return res


def _results_suffix(scene: str, text: str) -> str:
    """The results file's suffix for the scene's &output format (.csv, or .h5 for 'hdf5');
    .csv when the scene cannot be read (the run then says why)."""
    value, stat, _, _ = _core.pymr_scene_item(scene, text, "output.format")
    return ".h5" if stat == 0 and "hdf5" in _text(value) else ".csv"


#: How the progress bar shows the simulated time and t_end (4 significant digits).
_SHOWN = ".4g"


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
                    bar_format=f"{{desc}}: {{percentage:3.0f}}%|{{bar}}| t = {{n:{_SHOWN}}} of {{total:{_SHOWN}}} s "
                               "[{elapsed}<{remaining}]")
    try:
        while worker.is_alive():
            worker.join(0.1)
            t, t_end, running = _core.pymr_progress()
            if running and t_end > 0:
                if bar is None:
                    bar = open_bar(t, t_end)
                elif format(float(t), _SHOWN) != format(bar.n, _SHOWN):
                    # redrawn when the time it shows changes: no line repeats the one before it
                    # in a job's log when the kernel advanced less than the digits show
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


def model_size(scene: str | os.PathLike, overrides=None) -> tuple[int, int, int]:
    """(coordinates, bodies including the ground, markers) of a scene's model."""
    with model_of(scene, _scene_and_overrides(scene, overrides)) as handle:
        n, nb, nm, stat, msg, detail = _core.pymr_model_size(handle)
    _raise(stat, msg, detail)
    return int(n), int(nb), int(nm)


def initial_state(scene: str | os.PathLike, overrides=None) -> tuple[np.ndarray, np.ndarray]:
    """The state ``(q, qd)`` (each of shape (n,), model order) a run of the scene starts
    from, as its first row has it (the initial values, the loops assembled, a static start
    settled), without running."""
    with model_of(scene, _scene_and_overrides(scene, overrides)) as handle:
        n, _, _, stat, msg, detail = _core.pymr_model_size(handle)
        _raise(stat, msg, detail)
        n = int(n)
        x, stat, msg, detail = _core.pymr_initial_state(handle, n)
    _raise(stat, msg, detail)
    return x[:n].copy(), x[n:].copy()


def _states(q, qd) -> tuple[np.ndarray, np.ndarray]:
    """q and qd as finite float arrays of one shape (a SceneError naming q or qd otherwise:
    a NaN state would come back as NaN, or be blamed on the mass matrix or on LAPACK). None
    is no number (numpy made it NaN: 'q: nan is not a finite number')."""
    for name, value in (("q", q), ("qd", qd)):
        if any(v is None for v in np.asarray(value, dtype=object).ravel()):
            raise ArgumentTypeError(f"{name}: an array of real numbers, got {_shown(value)}")
    q = _array("q", q)
    qd = _array("qd", qd)
    if q.ndim >= 1 and q.shape[-1] == 0:
        # f2py takes no empty array (a bare ValueError); no scene's state is empty
        raise SceneError(f"q: a state of no coordinates (shape {q.shape}): a state holds the scene's coordinates")
    if q.shape != qd.shape:
        raise SceneError(f"qd: shape {qd.shape} differs from q's {q.shape}")
    _finite("q", q)
    _finite("qd", qd)
    return q, qd


def _finite(name: str, v: np.ndarray, where: str = "") -> None:
    """A SceneError naming `name` unless every entry of `v` is finite."""
    if not np.isfinite(v).all():
        k = int(np.argmin(np.isfinite(v).ravel()))
        raise SceneError(f"{name}: {v.flat[k]} is not a finite number{where}")


def _many_states(t, q, qd) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times (m,) and states q, qd (m, n) (one state (n,) is m = 1) for the kernel: t as
    an array of m finite times, q and qd finite and transposed to (n, m) in Fortran order."""
    q, qd = _states(q, qd)
    if q.ndim not in (1, 2):
        raise SceneError(f"q: one state of shape (n,) or states of shape (m, n) expected, got shape {q.shape}")
    if q.ndim == 2 and q.shape[0] == 0:
        # the kernel's arrays cannot be empty (f2py raised its own ValueError)
        raise SceneError(f"q: no states (shape {q.shape}): give at least one, of shape (n,) or (m, n)")
    q2 = np.asfortranarray(np.atleast_2d(q).T)
    qd2 = np.asfortranarray(np.atleast_2d(qd).T)
    if t is None:                  # numpy makes None a NaN: 'nan is not a finite time' named no fault
        raise ArgumentTypeError("t: a time or an array of times (s), got None")
    t1 = np.atleast_1d(_array("t", t))
    if t1.shape != (q2.shape[1],):
        raise SceneError(f"t: one time per state expected, shape ({q2.shape[1]},), got shape {t1.shape}")
    if not np.isfinite(t1).all():
        raise SceneError(f"t: {t1[np.argmin(np.isfinite(t1))]} is not a finite time")
    return t1, q2, qd2


def _count(name: str, value) -> int:
    """A whole number from 1 to the kernel's largest (a C int): f2py raised OverflowError
    above it and a ValueError about 'intent(cache|hide)' arrays below 1."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or not 1 <= value < 2**31 - 1:
        raise SceneError(f"{name}: a whole number from 1 to {2**31 - 2}, got {_short(value)}")
    return int(value)


def _time(t, name: str = "t") -> float:
    """One time (s) for the kernel: a finite number (not text, a bool or an array)."""
    try:
        if isinstance(t, (str, bytes, bool, np.bool_)) or np.ndim(t) != 0:
            raise TypeError
        value = float(t)
    except (TypeError, ValueError):
        raise ArgumentTypeError(f"{name}: a time in seconds, got {_short(t)}") from None
    except OverflowError:        # an int past the largest float (10**400)
        value = float("inf")
    if not np.isfinite(value):
        raise SceneError(f"{name}: {value} is not a finite time")
    return value


def _one_state(q, qd) -> tuple[np.ndarray, np.ndarray]:
    """q and qd of one state (shape (n,)), finite and contiguous, for the kernel."""
    q, qd = _states(q, qd)
    if q.ndim != 1:
        raise SceneError(f"q: one state of shape (n,) expected, got shape {q.shape}")
    return np.ascontiguousarray(q), np.ascontiguousarray(qd)


def model_terms(scene: str | os.PathLike, q, qd, t: float = 0.0, overrides=None):
    """Mass matrix M and right-hand side P of ``M qdd = P`` at (t, q, qd)."""
    q, qd = _one_state(q, qd)
    where = _scene_and_overrides(scene, overrides)
    t = _time(t)
    with model_of(scene, where) as handle:
        mm, p, stat, msg, detail = _core.pymr_model_terms(handle, t, q, qd)
    _raise(stat, msg, detail)
    return mm, p


def force_response(scene: str | os.PathLike, q, qd, t: float = 0.0, overrides=None):
    """The 'response' coupling's terms at (t, q, qd): ``g = M^-1 E`` (shape (n, nf)), the
    response of every acceleration to a unit force on each modal coordinate, and the modal
    stiffness ``kf`` and damping ``df`` (shape (nf,)) of the fast forces ``kf a + df ad``:
    ``kf`` is omega^2 plus the diagonal of the geometric stiffness the state adds."""
    where = _scene_and_overrides(scene, overrides)
    t = _time(t)
    q, qd = _one_state(q, qd)
    with model_of(scene, where) as handle:
        nf, g, kf, df, stat, msg, detail = _core.pymr_force_response(handle, t, q, qd)
    _raise(stat, msg, detail)
    nf = int(nf)
    return g[:, :nf].copy(), kf[:nf].copy(), df[:nf].copy()


class Modes(tuple):
    """What :func:`modes` gives: unpacked, ``(frequency, damping, shapes)`` of the
    vibrations (``freq, zeta, shapes = pymr.modes(...)``); as attributes, every motion of the
    linearised model by its kind:

    - ``frequency`` (Hz, ascending), ``damping`` (ratios) and ``shapes`` (n, vibrations):
      the vibrations, complex pairs of eigenvalues lambda whose size is resolved;
    - ``rigid`` (n, r): the rigid-body motions, eigenvalues at zero within what the
      linearisation resolves: nothing holds them (a free joint, an unloaded free chain, a
      free body under gravity, whose uniform field neither restores nor pushes its
      coordinates apart), an orthogonal basis of them;
    - ``drift_rate`` (1/s) and ``drift_shapes`` (n, d): real eigenvalues that are resolved,
      motions that grow (rate > 0, as an inverted pendulum falls) or decay (rate < 0,
      overdamped) without oscillating;
    - ``kind``, ``all_shapes``, ``all_frequency``, ``all_damping``, ``all_rate``: the same,
      one entry per motion in the order rigid, drift (growing first), vibration, with
      ``kind`` 'rigid', 'drift' or 'vibration' (what ``pymr modes`` prints).

    Each shape is the coordinates' motion, its largest component 1."""

    def __new__(cls, kind, freq, zeta, rate, shapes):
        kind = np.array(kind, dtype=object)
        vib, rigid, drift = (kind == "vibration"), (kind == "rigid"), (kind == "drift")
        self = super().__new__(cls, (freq[vib].copy(), zeta[vib].copy(), shapes[:, vib].copy()))
        self.frequency, self.damping, self.shapes = self
        self.rigid = shapes[:, rigid].copy()
        self.drift_rate, self.drift_shapes = rate[drift].copy(), shapes[:, drift].copy()
        self.kind = [str(k) for k in kind]
        self.all_frequency, self.all_damping, self.all_rate, self.all_shapes = freq, zeta, rate, shapes
        return self

    def __repr__(self) -> str:
        return (f"Modes({len(self.frequency)} vibrations at {np.array2string(self.frequency, precision=5)} Hz, "
                f"{self.rigid.shape[1]} rigid-body motions, {len(self.drift_rate)} drifts)")


_MODE_KINDS = {1: "vibration", 2: "rigid", 3: "drift"}


def modes(scene: str | os.PathLike, q, qd, t: float = 0.0, overrides=None) -> Modes:
    """Natural modes of the model linearised at (t, q, qd), by the pre-flight check's
    linearisation (central differences, LAPACK dgeev of the state matrix; with closed loops,
    the constrained one), each motion labelled: vibrations, rigid-body motions and drifts
    (see :class:`Modes`). Unpacked, the vibrations: ``freq, zeta, shapes = pymr.modes(...)``.

    The rule (the kernel's, preflight.f90 normal_modes): an eigenvalue lambda whose size is
    at most the largest of 1e-6 of the largest |lambda|, the square root of the difference
    error of M^-1 K (1e-8 |M^-1| (|P| + |M| |qdd|), 1/s^2) and 1e-9 /s (an e-fold in no less
    than the longest run, 1e9 s) is not resolved: with the motions it spans that nothing
    holds and that keep the loops closed, a rigid-body motion. A resolved complex pair is a vibration (frequency |lambda|/(2 pi), damping ratio
    -Re(lambda)/|lambda|), a resolved real lambda a drift (rate lambda). At a state that
    accelerates, the stiffness includes the change of the mass matrix with q (the
    accelerations' own derivative), so a falling free body has six rigid-body motions and no
    vibration."""
    where = _scene_and_overrides(scene, overrides)
    t = _time(t)
    q, qd = _one_state(q, qd)
    with model_of(scene, where) as handle:
        nm, kind, freq, zeta, rate, shapes, stat, msg, detail = _core.pymr_modes(handle, t, q, qd)
    _raise(stat, msg, detail)
    nm = int(nm)
    return Modes([_MODE_KINDS[int(k)] for k in kind[:nm]], freq[:nm].copy(), zeta[:nm].copy(), rate[:nm].copy(),
                 shapes[:, :nm].copy())


def marker_shapes(scene, markers, q, qd, shapes, t: float = 0.0, overrides=None) -> dict[str, np.ndarray]:
    """Mode shapes as marker displacements: for each named marker, an array (3, modes) of
    the derivative of its inertial position along each shape (the columns of `shapes`, as
    :func:`modes` gives them) at (t, q, qd), by central differences of 1e-6 times the shape:
    metres per unit of the shape's coordinates."""
    q, qd = _one_state(q, qd)
    markers = _names("markers", markers)
    t = _time(t)
    shapes = _array("shapes", shapes)
    if shapes.ndim != 2 or shapes.shape[0] != q.size:
        raise SceneError(f"shapes: an array ({q.size}, modes) expected (modes() gives one), got shape {shapes.shape}")
    _finite("shapes", shapes)
    eps = 1e-6
    out = {}
    if shapes.shape[1] == 0:             # no modes: each marker moves (3, 0)
        with Model(scene, overrides) as model:
            for name in markers:
                model.marker_body(name)      # a marker the model does not have is named
        return {name: np.zeros((3, 0)) for name in markers}
    with Model(scene, overrides) as model:
        for name in markers:
            plus = model.marker(name, np.full(shapes.shape[1], t), (q[:, None] + eps * shapes).T,
                                np.tile(qd, (shapes.shape[1], 1)))
            minus = model.marker(name, np.full(shapes.shape[1], t), (q[:, None] - eps * shapes).T,
                                 np.tile(qd, (shapes.shape[1], 1)))
            out[name] = ((plus - minus) / (2 * eps)).T.copy()
    return out


#: Steps step_history makes room for at first (it doubles the room while the run needs more).
HISTORY_ROOM = 100_000


def step_history(scene: str | os.PathLike, overrides=None, max_steps: int = 200_000):
    """The run's own stepper from the initial state to t_end, without output: arrays of the
    time reached, the step taken and the method's order at each accepted step (entry 0 is
    the start: its step 0, its order the starting one). More than ``max_steps`` steps is an
    error."""
    where = _scene_and_overrides(scene, overrides)
    limit = _count("max_steps", max_steps)
    # room for the steps, doubled (the run taken again) while the run needs more: arrays of
    # max_steps entries made first took 16 GiB for max_steps = 2**31 - 2 (a numpy
    # MemoryError, or the process killed)
    room = min(limit, HISTORY_ROOM)
    with model_of(scene, where) as handle:
        while True:
            try:
                t, h, q, nh, stat, msg, detail = _core.pymr_step_history(handle, room + 1)
            except MemoryError:
                raise SolverError(f"max_steps: the history of {room + 1} steps needs {20 * (room + 1) / 2**30:.1f} "
                                  "GiB, more than this process can take (give a smaller max_steps)") from None
            if not (stat and int(nh) > room and room < limit):
                break
            room = min(2 * room, limit)
    if stat and int(nh) > max_steps:
        # the kernel's 'the run takes more than N steps' is about this argument: name it
        raise SolverError(f"max_steps: {_text(msg)} (give a larger max_steps)")
    _raise(stat, msg, detail)
    nh = int(nh)
    return t[:nh].copy(), h[:nh].copy(), q[:nh].copy()


def model_accelerations(scene: str | os.PathLike, t, q, qd, overrides=None) -> np.ndarray:
    """Accelerations for one state (q of shape (n,)) or many (shape (m, n), t of shape (m,))."""
    t1, q2, qd2 = _many_states(t, q, qd)
    with model_of(scene, _scene_and_overrides(scene, overrides)) as handle:
        qdd, stat, msg, detail = _core.pymr_model_accelerations(handle, t1, q2, qd2)
    _raise(stat, msg, detail)
    return qdd[:, 0].copy() if np.ndim(q) == 1 else qdd.T.copy()


def loop_rows(scene: str | os.PathLike, q, qd, overrides=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The loops' constraint rows at one state (method.md section 2.5): the residual
    ``phi`` (shape (r,)), the Jacobian ``G`` (shape (r, n)) and ``gamma = -Gdot qd``
    (shape (r,)) of every loop-closing joint, redundant rows included."""
    q, qd = _one_state(q, qd)
    where = _scene_and_overrides(scene, overrides)
    with model_of(scene, where) as handle:
        nr, *_, stat, msg, detail = _core.pymr_loop_rows(handle, 0, q, qd)
        _raise(stat, msg, detail)
        nr = int(nr)
        _, phi, g, gam, stat, msg, detail = _core.pymr_loop_rows(handle, max(nr, 1), q, qd)
    _raise(stat, msg, detail)
    return phi[:nr].copy(), g[:nr].copy(), gam[:nr].copy()


def model_energy(scene: str | os.PathLike, q, qd, overrides=None) -> tuple[np.ndarray, np.ndarray]:
    """Kinetic and potential energy for states q, qd of shape (m, n) (or one state of shape
    (n,)): arrays of shape (m,). The potential energy is the flexible bodies' strain energy,
    plus gravity's and the joint springs' when those effects are on."""
    q, qd = _states(q, qd)
    _, q2, qd2 = _many_states(np.zeros(np.atleast_2d(q).shape[0]), q, qd)
    with model_of(scene, _scene_and_overrides(scene, overrides)) as handle:
        ke, pe, stat, msg, detail = _core.pymr_model_energy(handle, q2, qd2)
    _raise(stat, msg, detail)
    return ke, pe


def write_modal_file(scene: str | os.PathLike, body: str, path: str | os.PathLike, overrides=None) -> None:
    """Write the modes of beam ``body`` of a scene to a modal data file, which a
    ``kind='modal'`` body can read back (``modal_file=...``)."""
    _write_modal_file(scene, body, path, overrides, "path")


def _write_modal_file(scene, body, path, overrides, option: str) -> None:
    """write_modal_file, its messages naming the output `option` (`pymr modal-file`: -o)."""
    where = _scene_and_overrides(scene, overrides)
    body, path = _name("body", body), _path(option, path, OutputError)
    if not path:
        raise OutputError(f"{option}: an empty file name for the modal file")
    # an output fault (no folder, a folder, the scene itself) is an OutputError, as for every writer
    from .outputs import check_output
    check_output(path, "modal file", option=option, example=f"{body}.modal", if_left_out=None, scene=scene,
                 overrides=overrides)
    with model_of(scene, where) as handle:
        stat, msg, detail = _core.pymr_write_modal(handle, body, path)
    _raise(stat, msg, detail)


class Model:
    """A scene's model kept open in the kernel, for integrators driven from Python (scipy's
    ``solve_ivp``, SUNDIALS CVODE): ``rhs(t, x)`` is f of ``x' = f(t, x)`` for the state
    ``x = [q; qd]``, ``evaluations`` counts the kernel's full evaluations so far, and
    ``marker(name, t, q, qd)`` gives a marker's positions at states of shape (m, n)."""

    def __init__(self, scene: str | os.PathLike, overrides=None):
        self.scene, text = _scene_and_overrides(scene, overrides)
        handle, n, stat, msg, detail = _core.pymr_model_open(self.scene, text)
        _raise(stat, msg, detail)
        self.handle, self.n, self.evaluations = int(handle), int(n), 0

    def rhs(self, t: float, x) -> np.ndarray:
        x = _array("x", x)
        if x.shape != (2 * self.n,):
            raise SceneError(f"x: the state [q; qd] of shape ({2 * self.n},) expected, got shape {x.shape}")
        if not np.isfinite(x).all():
            # named here: the kernel would blame the mass matrix (its articulated inertia)
            k = int(np.argmin(np.isfinite(x)))
            part, i = ("q", k) if k < self.n else ("qd", k - self.n)
            _finite(part, x[k:k + 1], f" (x[{k}], entry {i} of {part} in x = [q; qd])")
        f, evals, stat, msg, detail = _core.pymr_model_rhs(self._live(), _time(t), x)
        if stat:
            _raise(stat, msg, detail)
        self.evaluations = int(evals)
        return f

    def _live(self) -> int:
        """The open model's handle; a SceneError once the model is closed (its names came
        back empty, its markers 'not found')."""
        if self.handle <= 0:
            raise SceneError(f"{self.scene}: this pymr.Model is closed (make a new one)")
        return self.handle

    def marker(self, name: str, t, q, qd) -> np.ndarray:
        k = int(_core.pymr_model_marker_index(self._live(), _name("name", name)))
        if k == 0:
            raise SceneError(f"{self.scene}: no marker {name!r}")
        t1, q2, qd2 = self._states(t, q, qd)
        pos, stat, msg, detail = _core.pymr_model_marker(self.handle, k, t1, q2, qd2)
        _raise(stat, msg, detail)
        return pos.T.copy()

    def frames(self, t, q, qd, nb: int):
        """Every body's frame origin (inertial, m) at states of shape (m, n): an array
        (m, nb, 3), and each body's parent (1-based, 0 for the ground), for drawing."""
        t1, q2, qd2 = self._states(t, q, qd)
        pos, parent, stat, msg, detail = _core.pymr_model_frames(self._live(), _count("nb", nb), t1, q2, qd2)
        _raise(stat, msg, detail)
        return np.transpose(pos, (2, 1, 0)).copy(), np.asarray(parent, dtype=int)

    def _states(self, t, q, qd):
        """The kernel's (t, q, qd) of :func:`_many_states`, each state of this model's n coordinates."""
        t1, q2, qd2 = _many_states(t, q, qd)
        if q2.shape[0] != self.n:
            raise SceneError(f"q: states of {self.n} coordinates expected, got {q2.shape[0]}")
        return t1, q2, qd2

    def marker_names(self) -> list[str]:
        """The model's markers' names, in the scene's order."""
        names, handle = [], self._live()
        while name := _text(_core.pymr_model_marker_name(handle, len(names) + 1)):
            names.append(name)
        return names

    def coordinate_names(self) -> list[str]:
        """The coordinates' column names (``joint.q``, ``body.a1`` ...), in model order."""
        handle = self._live()
        return [_text(_core.pymr_model_coordinate_name(handle, k + 1)) for k in range(self.n)]

    def marker_body(self, name: str) -> int:
        """The index (0-based, as in :meth:`frames`) of the body marker `name` is on."""
        k = int(_core.pymr_model_marker_index(self._live(), _name("name", name)))
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
