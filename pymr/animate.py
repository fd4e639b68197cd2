"""``pymr animate``: a picture of the moving mechanism from a run's results.

Each output row's coordinates go back through the kernel's kinematics (``pymr.Model``): the
frame origin of every body, joined to its parent's as the tree runs, and every marker, with
its trail. The view is a projection on two inertial axes (``xy``, ``xz`` or ``zy``: the
first is drawn across, the second up). Modal coordinates can be scaled (``exaggerate``) so
that deflections of millimetres show on a mechanism of metres; the markers then move with
the scaled deflection too.

The model is rebuilt from the scene file the results name (their JSON), or the one given,
and checked against the run: its markers, computed from the results' coordinates, must be
the marker columns the run wrote (to 1e-9 of their size). A run whose ``--set`` overrides
changed the geometry needs the resolved scene (``pymr scene SCENE --set ... > resolved.nml``).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .api import Model, model_size
from .geometry import GeometryError, check_geometry, scene_of
from .outputs import check_output
from .results import Results, load_results

VIEWS = {"xy": (0, 1), "xz": (0, 2), "zy": (2, 1)}

#: The animation formats: a GIF (Pillow, always here), or a video (matplotlib's ffmpeg writer).
FORMATS = [".gif", ".mp4", ".mkv", ".mov", ".avi", ".webm"]


class AnimateError(GeometryError):
    """Results that cannot be animated: an unknown view, a bad count (no scene, another scene:
    :class:`pymr.geometry.GeometryError`, of which this is one)."""


def motion(res: Results, scene: str | os.PathLike | None = None, exaggerate: float = 1.0,
           rows: np.ndarray | None = None):
    """Positions to draw at the chosen rows (default: all): (t, frames (rows, bodies, 3),
    parent of each body (-1 for the ground), markers {name: (rows, 3)}, the body of each
    marker {name: index})."""
    path = scene_of(res, scene)
    q_all, qd_all = res.coordinates()
    q, qd, t = q_all, qd_all, res.t
    if rows is not None:
        q, qd, t = q[rows], qd[rows], t[rows]
    n_joint = sum(len(res.joint_columns(j)) for j in res.joints)
    q = q.copy()
    q[:, n_joint:] *= exaggerate
    n, nb, _ = model_size(path)
    if q.shape[1] != n:
        raise GeometryError(f"{res.path}: the results hold {q.shape[1]} of the scene's {n} coordinates: animating "
                           "needs them all (run with &output quantities 'coordinates')")
    with Model(path) as model:
        check_geometry(res, model, path, q_all, qd_all)
        frames, parent = model.frames(t, q, qd, nb)
        markers = {m: model.marker(m, t, q, qd) for m in res.markers}
        on = {m: model.marker_body(m) for m in res.markers}
    return t, frames, parent - 1, markers, on


def check_animation_path(output, option: str, res: Results, scene=None) -> Path:
    """The animation's path checked by pymr's output rule before anything is drawn: not a
    folder, in a folder that is there, a GIF (or a video where ffmpeg is installed), none of
    the run's files (CSV, JSON) or the scene's."""
    out = check_output(output, "animation", option=option, suffixes=FORMATS,
                       example=(Path(res.path).stem if res.path else "anim") + ".gif",
                       inputs=([res.path, Path(res.path).with_suffix(".json")] if res.path else [])
                       + ([res.stats["scene"]] if res.stats.get("scene") else []),
                       scene=scene_of(res, scene))
    if out.suffix.lower() != ".gif":
        from matplotlib import animation
        if not animation.writers.is_available("ffmpeg"):
            raise AnimateError(f"{option} {out}: a {out.suffix} video needs ffmpeg, which is not installed here "
                               "(write a .gif)")
    return out


def animate(results: Results | str | os.PathLike, output: str | os.PathLike, scene=None, view: str = "xy",
            exaggerate: float = 1.0, fps: int = 25, frames: int = 200, option: str = "output") -> Path:
    """Write the animation (GIF, or a video by the suffix where ffmpeg is installed: .mp4,
    .mkv, .mov, .avi, .webm) of at most ``frames`` evenly spaced output rows; return its
    path. The output is checked first (:func:`check_animation_path`; `option` names it in
    messages) and written whole or not at all."""
    import logging
    import matplotlib
    matplotlib.use("Agg")
    # a writer matplotlib lacks (ffmpeg) is logged, then the Pillow fallback's error is ours
    logging.getLogger("matplotlib.animation").setLevel(logging.ERROR)
    import matplotlib.pyplot as plt
    from matplotlib.animation import FuncAnimation, PillowWriter

    res = results if isinstance(results, Results) else load_results(results)
    if view not in VIEWS:
        raise AnimateError(f"view {view!r}: one of {', '.join(VIEWS)}")
    if frames < 2 or fps < 1 or not 0 < exaggerate < np.inf:
        raise AnimateError("frames (at least 2), fps (at least 1) and exaggerate (above 0) must be positive")
    out = check_animation_path(output, option, res, scene)
    rows = np.unique(np.linspace(0, len(res.t) - 1, min(frames, len(res.t))).round().astype(int))
    t, pos, parent, markers, on = motion(res, scene, exaggerate, rows)
    a, b = VIEWS[view]
    everything = np.concatenate([pos.reshape(-1, 3)] + [m for m in markers.values()])
    lo, hi = everything.min(axis=0), everything.max(axis=0)
    pad = 0.05 * max(hi[a] - lo[a], hi[b] - lo[b], 1e-3)
    fig, ax = plt.subplots(figsize=(7, 6))
    ax.set_xlim(lo[a] - pad, hi[a] + pad)
    ax.set_ylim(lo[b] - pad, hi[b] + pad)
    ax.set_aspect("equal")
    ax.set_xlabel(f"{'xyz'[a]} (m)")
    ax.set_ylabel(f"{'xyz'[b]} (m)")
    ax.grid(True, alpha=0.3)
    links = [ax.plot([], [], "-o", color="0.35", lw=2, ms=4)[0] for k in range(pos.shape[1]) if parent[k] >= 0]
    dots = {m: ax.plot([], [], "o", color=f"C{i + 3}", label=m)[0] for i, m in enumerate(markers)}
    arms = {m: ax.plot([], [], "-", color="0.35", lw=2)[0] for m in markers}     # body origin to marker
    trails = {m: ax.plot([], [], "-", color=f"C{i + 3}", lw=0.8, alpha=0.6)[0] for i, m in enumerate(markers)}
    if markers:
        ax.legend(loc="upper right", fontsize=8)
    note = f", deflections x{exaggerate:g}" if exaggerate != 1.0 else ""
    title = ax.set_title("")

    def draw(i):
        children = [k for k in range(pos.shape[1]) if parent[k] >= 0]
        for line, k in zip(links, children):
            line.set_data([pos[i, parent[k], a], pos[i, k, a]], [pos[i, parent[k], b], pos[i, k, b]])
        for m, p in markers.items():
            dots[m].set_data([p[i, a]], [p[i, b]])
            arms[m].set_data([pos[i, on[m], a], p[i, a]], [pos[i, on[m], b], p[i, b]])
            trails[m].set_data(p[:i + 1, a], p[:i + 1, b])
        title.set_text(f"{res.title or Path(res.path).stem}: t = {t[i]:.3f} s{note}")
        return [*links, *arms.values(), *dots.values(), *trails.values(), title]

    anim = FuncAnimation(fig, draw, frames=len(t), blit=False)
    # written beside it under a temporary name (of the same suffix: the writers go by it),
    # then renamed over it: an earlier animation survives a failed write
    tmp = out.with_name(f".{out.stem}.{os.getpid()}.tmp{out.suffix}")
    try:
        if out.suffix.lower() == ".gif":
            anim.save(tmp, writer=PillowWriter(fps=fps))
        else:
            anim.save(tmp, writer="ffmpeg", fps=fps)
        os.replace(tmp, out)
    except (OSError, ValueError, RuntimeError) as exc:
        raise AnimateError(f"{out}: cannot write the animation ({' '.join(str(exc).split())})") from None
    finally:
        plt.close(fig)
        tmp.unlink(missing_ok=True)
    return out


def main(csv: str, output: str | None = None, scene: str | None = None, view: str = "xy",
         exaggerate: float = 1.0, fps: int = 25, frames: int = 200) -> int:
    res = load_results(csv)
    if output is None:
        out, option = Path(csv).with_suffix(".gif"), "the default animation (-o to choose)"
    else:
        out, option = output, "-o"
    out = animate(res, out, scene=scene, view=view, exaggerate=exaggerate, fps=fps, frames=frames, option=option)
    print(f"wrote {out}")
    return 0
