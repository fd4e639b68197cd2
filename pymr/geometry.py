"""The mechanism's 3-D geometry over a run, from its results, through the kernel's kinematics.

:func:`motion` takes a run's results (its coordinates at each output row) back through the
kernel (``pymr.Model``, the binding's ``pymr_model_poses``, ``pymr_model_body_line``,
``pymr_model_joints``): every body's pose, every flexible body's deformed centre line (a
beam's axis at evenly spaced points, a modal-file body's nodes) with its elastic
displacement, every joint's place and axis, every marker. Python computes no kinematics.

``exaggerate`` scales the flexible bodies' modal coordinates (and so the deflections) before
the kinematics, so that millimetres show on metres; the bodies beyond a flexible one, the
markers and the joints then move with the scaled deflection too. The ``displacement`` of a
centre line is the unscaled one.

Simple solids for drawing (:class:`BodyTrack` ``shape``, ``size``, ``centre``):

- a beam: a cylinder along its x axis, of its length and outer radius (``r_outer``, else the
  radius of a full circle of its ``area``), from its origin: ``centre`` = (L/2, 0, 0);
- a rigid body with mass: the uniform box of the same mass and the same moments of inertia
  about the body axes through its centre of mass, ``centre`` = ``com``. A box of edges a, b, c
  has Ixx = m (b^2 + c^2)/12 ..., so a = sqrt(6 (Iyy + Izz - Ixx)/m), b = sqrt(6 (Izz + Ixx -
  Iyy)/m), c = sqrt(6 (Ixx + Iyy - Izz)/m) (a negative radicand, an inertia no box has, gives
  0). The inertia's diagonal in the body axes is used (products of inertia ignored: a box
  drawn in the body axes);
- the ground, massless bodies and modal-file bodies (drawn by their nodes): 'none'.

The model is rebuilt from the scene the results name (the resolved scene their statistics
hold, else the scene file) or the one given, and checked against the run: its markers,
computed from the results' coordinates, must be the marker columns the run wrote (to 1e-9
of their size).
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ._args import _path, _raise, _real, _text
from .api import Model, PymrError, _core
from .results import Results, load_results

#: Points of a beam's drawn centre line (its ends included).
BEAM_POINTS = 41

_KINDS = {0: "ground", 1: "rigid", 2: "beam", 3: "modal"}


class GeometryError(PymrError):
    """Results whose geometry cannot be drawn: no scene, another scene, no coordinates."""


@dataclass
class BodyTrack:
    """One body over the chosen rows (nt of them)."""
    name: str
    kind: str                      # 'rigid', 'beam', 'modal', 'ground'
    origin: np.ndarray             # (nt, 3) inertial position of the body frame's origin
    rotation: np.ndarray           # (nt, 3, 3) body-to-inertial rotation matrix of the body frame
    shape: str                     # 'box' | 'cylinder' | 'none': a simple solid for drawing
    size: np.ndarray               # (3,) box edges in the body frame, or (length, radius, 0) for a cylinder along x
    centre: np.ndarray             # (3,) the solid's centre in the body frame
    line: np.ndarray | None        # flexible bodies: (nt, np, 3) deformed centre line, inertial, scaled deflection
    displacement: np.ndarray | None  # flexible bodies: (nt, np, 3) the unscaled elastic displacement, inertial


@dataclass
class JointTrack:
    """One joint over the chosen rows: a tree joint at its child's origin, a loop's cut joint
    at its parent's point; its axis (unit, inertial) when its coordinates share one
    (revolute, prismatic, cylindrical), else zero."""
    name: str
    kind: str
    parent: str
    child: str
    position: np.ndarray           # (nt, 3)
    axis: np.ndarray               # (nt, 3)


@dataclass
class Motion:
    """The mechanism's geometry at the chosen output rows."""
    t: np.ndarray                  # (nt,) output times used
    bodies: list[BodyTrack]
    joints: list[JointTrack]
    markers: dict[str, np.ndarray]  # name -> (nt, 3) inertial positions (with the scaled deflection)
    exaggerate: float

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(lo(3), hi(3)) over all times of every drawn point: body origins, the corners of
        their solids, the centre lines, joints and markers."""
        pts = [b.origin.reshape(-1, 3) for b in self.bodies]
        pts += [solid_points(b).reshape(-1, 3) for b in self.bodies if b.shape != "none"]
        pts += [b.line.reshape(-1, 3) for b in self.bodies if b.line is not None]
        pts += [j.position for j in self.joints] + list(self.markers.values())
        allp = np.concatenate(pts)
        return allp.min(axis=0), allp.max(axis=0)


def solid_points(body: BodyTrack) -> np.ndarray:
    """The corners of a body's solid (a box's 8; a cylinder's as of its bounding box), inertial,
    (nt, 8, 3); (nt, 0, 3) for 'none'."""
    if body.shape == "none":
        return np.zeros((len(body.origin), 0, 3))
    half = body.size / 2 if body.shape == "box" else np.array([body.size[0], 2 * body.size[1], 2 * body.size[1]]) / 2
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)], dtype=float)
    local = body.centre + signs * half                                    # (8, 3) body frame
    return body.origin[:, None, :] + np.einsum("tij,pj->tpi", body.rotation, local)


def box_of_inertia(mass: float, inertia: np.ndarray) -> np.ndarray:
    """Edges (a, b, c) of the uniform box of this mass with these moments of inertia about its
    axes: Ixx = m (b^2 + c^2)/12 and its turns give a = sqrt(6 (Iyy + Izz - Ixx)/m) ..."""
    i = np.diag(inertia)
    s = i.sum()
    return np.sqrt(np.maximum(6.0 * (s - 2.0 * i) / mass, 0.0))


def rows_of(nt: int, every: int = 1, frames: int | None = None) -> np.ndarray:
    """Rows to use of nt: every `every`-th (the first included), then at most `frames` of
    them evenly spread (the first and the last of those kept)."""
    if isinstance(every, bool) or not isinstance(every, (int, np.integer)) or every < 1:
        raise GeometryError(f"every: a whole number from 1, got {every!r}")
    rows = np.arange(0, nt, min(int(every), max(nt, 1)))   # beyond nt: the first row (numpy's int64 ends below)
    if frames is not None:
        if isinstance(frames, bool) or not isinstance(frames, (int, np.integer)) or frames < 1:
            raise GeometryError(f"frames: a whole number from 1, got {frames!r}")
        if len(rows) > frames:
            rows = rows[np.unique(np.linspace(0, len(rows) - 1, frames).round().astype(int))]
    return rows


def scene_of(res: Results, scene=None):
    """The scene of the results: the one given (a path or a pymr.Scene); else the resolved
    scene their statistics hold (the scene as the run read it, --set overrides applied),
    written to a temporary file; else the scene file their statistics name."""
    from .scene import Scene
    if isinstance(scene, Scene):
        return scene
    if scene is not None:
        # an empty name (an unset shell variable) is refused, not taken as left out
        text = _path("scene", scene)
        if not text:
            raise GeometryError("scene: an empty file name (leave it out for the scene the results name)")
        path = Path(text)
    elif res.stats.get("resolved_scene"):
        path = _resolved_scene_file(res.stats["resolved_scene"])
        try:
            Scene(path)
        except PymrError as exc:     # its messages would name the temporary file, not the statistics
            where = f"{Path(str(res.path)).with_suffix('.json')}: resolved_scene"
            raise GeometryError(str(exc).replace(str(path), where) + " (give the scene with --scene)") from None
        return path
    elif res.stats.get("scene"):
        path = Path(res.stats["scene"])
    else:
        why = "their statistics name none" if res.stats else "no statistics file beside them"
        raise GeometryError(f"{res.path}: the results name no scene ({why}): give --scene")
    if not path.exists():
        raise GeometryError(f"{res.path}: the scene {path} is not there: give --scene")
    return path


_RESOLVED: dict[str, Path] = {}


def _resolved_scene_file(text: str) -> Path:
    """A temporary file holding a resolved scene (one per text, removed at exit)."""
    if text not in _RESOLVED:
        import atexit
        import shutil
        import tempfile
        folder = tempfile.mkdtemp(prefix="pymr-scene-")
        atexit.register(shutil.rmtree, folder, ignore_errors=True)
        _RESOLVED[text] = Path(folder) / "resolved.nml"
        _RESOLVED[text].write_text(text)
    return _RESOLVED[text]


def check_geometry(res: Results, model: Model, path, q: np.ndarray, qd: np.ndarray) -> None:
    """The model's markers at (up to 20 of) the results' states equal the run's marker columns,
    to 1e-9 of their size, or to what the digits the CSV was written with leave (&output
    precision p: its coordinates and markers are rounded to 10^(1-p), 1e-3 at p = 6)."""
    rows = np.unique(np.linspace(0, len(res.t) - 1, min(20, len(res.t))).round().astype(int))
    tol = max(1e-9, 10.0 ** (3 - _written_digits(res)))
    for m in res.markers:
        written = res.marker(m)[0][rows]
        again = model.marker(m, res.t[rows], q[rows], qd[rows])
        if np.abs(again - written).max() > tol * max(1.0, np.abs(written).max()):
            raise GeometryError(f"{res.path}: {path} is not the scene of this run (its marker {m!r} is elsewhere at "
                                "the run's coordinates: the run may have had --set overrides); give the resolved "
                                "scene with --scene (pymr scene SCENE --set ... > resolved.nml)")


def _written_digits(res: Results) -> int:
    """Significant digits of the results' numbers: the run's &output precision for a CSV
    (the item of the resolved scene its statistics hold, read by the kernel), 17 for HDF5
    (every bit) or when the statistics hold no scene."""
    text = res.stats.get("resolved_scene")
    if Path(str(res.path)).suffix.lower() in (".h5", ".hdf5") or not isinstance(text, str) or not text:
        return 17
    from .scene import Scene
    try:
        return int(Scene(_resolved_scene_file(text))["output.precision"])
    except PymrError:          # a scene the kernel no longer reads (the drawing's own scene says why)
        return 17


def deflection_scale(exaggerate) -> float:
    """The scale the deflections are drawn at: a finite number from 0 (0 draws the flexible
    bodies undeformed); else an error naming it. The one rule of every drawing command."""
    if not 0 <= _real("exaggerate", exaggerate) < np.inf:
        raise GeometryError(f"exaggerate: a scale of the deflections, a finite number from 0 (0 draws the bodies "
                            f"undeformed), got {exaggerate!r}")
    return float(exaggerate)


def motion(res: Results | str | os.PathLike, scene=None, exaggerate: float = 1.0, every: int = 1,
           frames: int | None = None) -> Motion:
    """The mechanism's geometry at the results' output rows. every: take every k-th row;
    frames: at most this many rows, evenly spread (both optional)."""
    res = res if isinstance(res, Results) else load_results(res)
    exaggerate = deflection_scale(exaggerate)
    rows = rows_of(len(res.t), every, frames)
    source = scene_of(res, scene)
    q_all, qd_all = res.coordinates()
    with Model(source) as model:
        if q_all.shape[1] != model.n:
            raise GeometryError(f"{res.path}: the results hold {q_all.shape[1]} of the scene's {model.n} coordinates: "
                                "drawing needs them all (run with &output quantities 'coordinates')")
        check_geometry(res, model, getattr(source, "path", source), q_all, qd_all)
        t, q, qd = res.t[rows], q_all[rows], qd_all[rows]
        bodies = _bodies(model, t, q, qd, float(exaggerate))
        joints = _joints(model, t, q, qd, float(exaggerate), [b.name for b in bodies])
        markers = _markers(model, t, q, qd, float(exaggerate))      # every marker of the scene
    drawn = Motion(t=t, bodies=bodies, joints=joints, markers=markers, exaggerate=float(exaggerate))
    if not all((np.abs(x) <= np.finfo(np.float32).max).all() for x in drawn.bounds()):   # nan fails too
        held = f"beyond what a drawing holds (single precision, {np.finfo(np.float32).max:.1e} m)"
        if float(exaggerate) <= 1.0:
            raise GeometryError(f"{res.path}: the run's positions lie {held}: it cannot be drawn")
        raise GeometryError(f"exaggerate: {exaggerate!r} scales the deflections {held}: take a smaller scale")
    return drawn


def _states(t, q, qd):
    return (np.ascontiguousarray(t, dtype=float), np.asfortranarray(q.T, dtype=float),
            np.asfortranarray(qd.T, dtype=float))


def _body_info(model: Model, b: int) -> dict:
    """What the kernel says of body b (1-based, model order); None past the last."""
    name, kind, nodes, mass, com, inertia, length, radius = _core.pymr_model_body_info(model.handle, b)
    if int(kind) < 0:
        return None
    return dict(name=_text(name), kind=_KINDS[int(kind)], nodes=int(nodes), mass=float(mass),
                com=np.array(com, dtype=float), inertia=np.array(inertia, dtype=float),
                length=float(length), radius=float(radius))


def _solid(info: dict) -> tuple[str, np.ndarray, np.ndarray]:
    """(shape, size, centre) of a body's simple solid (the module's doc)."""
    if info["kind"] == "beam":
        return "cylinder", np.array([info["length"], info["radius"], 0.0]), np.array([info["length"] / 2, 0.0, 0.0])
    if info["kind"] == "rigid" and info["mass"] > 0:
        return "box", box_of_inertia(info["mass"], info["inertia"]), info["com"]
    return "none", np.zeros(3), np.zeros(3)


def _bodies(model: Model, t, q, qd, exaggerate: float) -> list[BodyTrack]:
    """Every body's track (model order), with the flexible bodies' centre lines."""
    infos = []
    while (info := _body_info(model, len(infos) + 1)) is not None:
        infos.append(info)
    t1, q2, qd2 = _states(t, q, qd)
    pos, rot, stat, msg, detail = _core.pymr_model_poses(model.handle, len(infos), t1, q2, qd2, exaggerate)
    _raise(stat, msg, detail)
    bodies = []
    for b, info in enumerate(infos):
        line = disp = None
        if info["kind"] in ("beam", "modal"):
            npts = BEAM_POINTS if info["kind"] == "beam" else info["nodes"]
            line, disp, stat, msg, detail = _core.pymr_model_body_line(model.handle, b + 1, npts, t1, q2, qd2,
                                                                       exaggerate)
            _raise(stat, msg, detail)
            line, disp = np.transpose(line, (2, 1, 0)).copy(), np.transpose(disp, (2, 1, 0)).copy()
        shape, size, centre = _solid(info)
        bodies.append(BodyTrack(name=info["name"], kind=info["kind"], origin=np.transpose(pos[:, b, :]).copy(),
                                rotation=np.transpose(rot[:, :, b, :], (2, 0, 1)).copy(), shape=shape, size=size,
                                centre=centre, line=line, displacement=disp))
    return bodies


def _joints(model: Model, t, q, qd, exaggerate: float, names: list[str]) -> list[JointTrack]:
    """Every joint's track: the tree's, then the loops' cut joints."""
    info = []
    while True:
        name, kind, parent, child = _core.pymr_model_joint_info(model.handle, len(info) + 1)
        if not _text(name):
            break
        info.append((_text(name), _text(kind), names[int(parent) - 1], names[int(child) - 1]))
    if not info:
        return []
    t1, q2, qd2 = _states(t, q, qd)
    pos, axis, stat, msg, detail = _core.pymr_model_joints(model.handle, len(info), t1, q2, qd2, exaggerate)
    _raise(stat, msg, detail)
    return [JointTrack(name=n, kind=k, parent=p, child=c, position=np.transpose(pos[:, j, :]).copy(),
                       axis=np.transpose(axis[:, j, :]).copy()) for j, (n, k, p, c) in enumerate(info)]


def _markers(model: Model, t, q, qd, exaggerate: float) -> dict[str, np.ndarray]:
    """Every marker's positions (nt, 3), the modal coordinates scaled (the kernel's marker rule)."""
    names = model.marker_names()
    if not names:
        return {}
    t1, q2, qd2 = _states(t, q, qd)
    pos, stat, msg, detail = _core.pymr_model_markers(model.handle, len(names), t1, q2, qd2, exaggerate)
    _raise(stat, msg, detail)
    return {m: np.transpose(pos[:, k, :]).copy() for k, m in enumerate(names)}
