"""``pymr animate``: the moving mechanism in 3-D, from a run's results.

The geometry is :func:`pymr.geometry.motion`'s (the kernel's kinematics at each output row):
every body as its solid at its pose (a box for a rigid body, a tube around a beam's deformed
centre line, a modal-file body's points), the flexible bodies' centre lines, the joints (a
dot, and a short stroke along the axis of a joint that has one), a link from each joint's
parent's frame to the joint (none for a free joint: nothing holds it there), the markers with
their trails and the inertial axes at the origin. It is drawn by matplotlib's mplot3d in an
orthographic projection with equal scales on the three axes, zoomed so that the mechanism's
bounds over the whole run (every orbit angle included) fill the frame.

The deflections are drawn ``exaggerate`` times (the flexible bodies' modal coordinates
scaled before the kinematics; the markers and everything beyond a flexible body follow). By
default the factor makes the largest deflection of the run 5 % of the mechanism's size
(its bounds' largest extent), rounded to two digits and never below 1 (a rigid mechanism:
1).

The vertical axis is the one gravity acts along (z when there is none). ``view`` is a named
view (``iso``, ``front``: the first horizontal axis across, ``side``, ``top``), an
``ELEV,AZIM`` pair (degrees, matplotlib's), or one of the former 2-D projections ``xy``,
``xz``, ``zy`` (first axis across, second up), now seen face-on in 3-D. ``orbit`` turns the
camera once round the vertical axis over the run.

A ``.png`` output is a still: the frame of the animation nearest the time ``at`` (default:
the last).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ._args import _flag, _shown, sync_to_disk
from .api import _time
from .errors import ArgumentTypeError
from .geometry import BodyTrack, GeometryError, Motion, deflection_scale, motion, scene_of
from .outputs import check_output
from .results import Results, load_results

#: The animation formats: a GIF (Pillow, always here), a video (matplotlib's ffmpeg writer), or a still.
FORMATS = [".gif", ".mp4", ".mkv", ".mov", ".avi", ".webm", ".png"]
#: Named views (elevation, azimuth in degrees) by the vertical axis.
NAMED = {"z": {"iso": (25, -60), "front": (0, -90), "side": (0, 0), "top": (90, -90)},
         "y": {"iso": (25, 30), "front": (0, 0), "side": (0, -90), "top": (90, 0)},
         "x": {"iso": (25, -60), "front": (0, -90), "side": (0, 0), "top": (90, -90)}}
#: The former 2-D projections, face-on: (vertical axis, elevation, azimuth).
PLANES = {"xy": ("y", 0, 0), "xz": ("z", 0, -90), "zy": ("y", 0, -90)}
#: The largest deflection drawn by default, as a fraction of the mechanism's size.
DEFLECTION_SHARE = 0.05
TUBE_SIDES = 8
_BOX_FACES = [[0, 1, 2, 3], [4, 5, 6, 7], [0, 1, 5, 4], [2, 3, 7, 6], [1, 2, 6, 5], [0, 3, 7, 4]]
_HEX = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                 [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float) / 2


class AnimateError(GeometryError):
    """Results that cannot be animated: an unknown view, a bad count (no scene, another scene:
    :class:`pymr.geometry.GeometryError`, of which this is one)."""


def camera(view: str, up: str) -> tuple[str, float, float]:
    """(vertical axis, elevation, azimuth) of a view: a named one, 'ELEV,AZIM', or a plane."""
    if view in PLANES:
        return PLANES[view]
    if view in NAMED[up]:
        return (up, *NAMED[up][view])
    try:
        elev, azim = (float(v) for v in view.split(","))
    except ValueError:
        raise AnimateError(f"view {view!r}: one of {', '.join(NAMED[up])}, ELEV,AZIM (degrees, such as 30,-60), "
                           f"or a plane {', '.join(PLANES)}") from None
    if not (np.isfinite(elev) and np.isfinite(azim)):
        raise AnimateError(f"view {view!r}: the elevation and azimuth must be finite numbers of degrees")
    return up, elev, azim


def vertical_axis(source) -> str:
    """The axis gravity acts along in the scene (z when there is none), as the kernel reads it."""
    from .scene import Scene
    scene = source if isinstance(source, Scene) else Scene(source)
    g = np.abs(np.asarray(scene["scene.gravity"], dtype=float))
    return "xyz"[int(np.argmax(g))] if g.max() > 0 else "z"


def auto_exaggerate(mo: Motion) -> float:
    """The factor that draws the largest deflection as DEFLECTION_SHARE of the mechanism's size
    (two digits, at least 1)."""
    lo, hi = mo.bounds()
    largest = max((float(np.linalg.norm(b.displacement, axis=-1).max()) for b in mo.bodies
                   if b.displacement is not None), default=0.0)
    if largest <= 0.0:
        return 1.0
    return max(1.0, float(f"{DEFLECTION_SHARE * float((hi - lo).max()) / largest:.2g}"))


def box_faces(body: BodyTrack, i: int) -> list[np.ndarray]:
    """The six faces (4 corners each, inertial) of a body's box at row i."""
    corners = body.origin[i] + (body.centre + _HEX * body.size) @ body.rotation[i].T
    return [corners[f] for f in _BOX_FACES]


def tube_faces(body: BodyTrack, i: int) -> list[np.ndarray]:
    """Quads of a beam's tube at row i: rings of its radius around every second point of its
    deformed centre line, in the plane of the body's y and z axes."""
    line = body.line[i][::2] if len(body.line[i]) > 4 else body.line[i]
    ang = 2 * np.pi * np.arange(TUBE_SIDES + 1) / TUBE_SIDES
    rot = body.rotation[i]
    ring = body.size[1] * (np.cos(ang)[:, None] * rot[:, 1] + np.sin(ang)[:, None] * rot[:, 2])
    pts = line[:, None, :] + ring[None, :, :]
    return [np.array([pts[p, s], pts[p, s + 1], pts[p + 1, s + 1], pts[p + 1, s]])
            for p in range(len(line) - 1) for s in range(TUBE_SIDES)]


class Drawing:
    """The figure of a motion and its artists; :meth:`draw` puts them at row i."""

    def __init__(self, mo: Motion, view: str = "iso", up: str = "z", orbit: bool = False, title: str = ""):
        import matplotlib.pyplot as plt
        self.mo, self.orbit, self.title_text = mo, orbit, title
        self.up, self.elev, self.azim = camera(view, up)
        lo, hi = mo.bounds()
        self.size = max(float((hi - lo).max()), 1e-3)
        pad = 0.02 * self.size
        self.lo, self.hi = lo - pad, hi + pad
        self.fig = plt.figure(figsize=(8, 6))
        self.ax = self.fig.add_axes((0.0, 0.0, 1.0, 0.94), projection="3d", proj_type="ortho")
        self.ax.set_axis_off()
        self.ax.view_init(self.elev, self.azim, vertical_axis=self.up)
        self._limits(np.zeros(3), 1.0)
        self._make_artists()
        self._fit()

    def _limits(self, shift: np.ndarray, zoom: float) -> None:
        """The axes' limits (the bounds moved by shift) at equal scales, and the zoom."""
        self.lo, self.hi = self.lo + shift, self.hi + shift
        for k, axis in enumerate("xyz"):
            getattr(self.ax, f"set_{axis}lim")(self.lo[k], self.hi[k])
        self.ax.set_box_aspect(self.hi - self.lo, zoom=zoom)
        self.zoom = zoom

    def _angles(self) -> np.ndarray:
        """The azimuths the camera takes: one, or a whole turn when orbiting."""
        if not self.orbit:
            return np.array([self.azim])
        return self.azim + np.linspace(0.0, 360.0, 37)

    def _cloud(self) -> np.ndarray:
        """Every drawn point over the run (body origins, solids' corners, lines, joints,
        markers; at most 50 rows)."""
        from .geometry import solid_points
        mo = self.mo
        rows = np.unique(np.linspace(0, len(mo.t) - 1, min(50, len(mo.t))).round().astype(int))
        pts = [b.origin[rows] for b in mo.bodies] + [j.position[rows] for j in mo.joints]
        pts += [solid_points(b)[rows].reshape(-1, 3) for b in mo.bodies if b.shape != "none"]
        pts += [b.line[rows].reshape(-1, 3) for b in mo.bodies if b.line is not None]
        pts += [p[rows] for p in mo.markers.values()] + [np.zeros((1, 3)), 0.115 * self.size * np.eye(3)]
        return np.concatenate(pts)

    def _screen(self, pts: np.ndarray, azim: float) -> np.ndarray:
        """Pixel places of points seen from azim (after one draw has set the axes' transform)."""
        from mpl_toolkits.mplot3d import proj3d
        self.ax.view_init(self.elev, azim, vertical_axis=self.up)
        x, y, _ = proj3d.proj_transform(*pts.T, self.ax.get_proj())
        return self.ax.transData.transform(np.column_stack([x, y]))

    def _extent(self, cloud: np.ndarray) -> np.ndarray:
        """The largest (width, height) in pixels of the cloud over the camera's angles."""
        return np.max([np.ptp(self._screen(cloud, a), axis=0) for a in self._angles()], axis=0)

    def _fit(self) -> None:
        """The figure of the mechanism's aspect (about 48 square inches), the drawn points
        centred (one view) and zoomed to fill 94 % of the axes at the tightest angle."""
        cloud = self._cloud()
        self.fig.canvas.draw()
        ext = self._extent(cloud)
        aspect = float(np.clip(ext[0] / max(ext[1], 1e-9), 0.6, 2.2))
        width, height = np.sqrt(48 * aspect), np.sqrt(48 / aspect) / 0.94
        self.fig.set_size_inches(width, height)
        # mplot3d keeps its axes square: a square as wide as the drawing's area, centred on it
        side = max(width, 0.94 * height)
        self.ax.set_position(((width - side) / 2 / width, (0.47 * height - side / 2) / height, side / width,
                              side / height))
        self.fig.canvas.draw()
        dpi = self.fig.dpi
        room, middle = 0.94 * dpi * np.array([width, 0.94 * height]), dpi * np.array([width / 2, 0.47 * height])
        for _ in range(4):
            if not self.orbit:
                centre = (self.lo + self.hi) / 2
                jac = (self._screen(centre + np.eye(3), self.azim) - self._screen(centre[None, :], self.azim)).T
                px = self._screen(cloud, self.azim)
                self._limits(np.linalg.pinv(jac) @ ((px.min(axis=0) + px.max(axis=0)) / 2 - middle), self.zoom)
            self._limits(np.zeros(3), self.zoom * float(np.min(room / self._extent(cloud))))
        self.ax.view_init(self.elev, self.azim, vertical_axis=self.up)

    def _make_artists(self) -> None:
        from mpl_toolkits.mplot3d.art3d import Poly3DCollection
        ax, mo = self.ax, self.mo
        self.solids, self.lines, self.links, self.axes_of, self.dots, self.trails = {}, {}, {}, {}, {}, {}
        for k, b in enumerate(mo.bodies):
            colour = f"C{k % 10}"
            if b.shape == "box" or (b.shape == "cylinder" and b.line is not None):
                self.solids[b.name] = ax.add_collection3d(Poly3DCollection(
                    [], facecolor=colour, edgecolor="0.25", linewidths=0.3, alpha=0.45))
            if b.line is not None:
                style = "-" if b.kind == "beam" else "."
                self.lines[b.name] = ax.plot([], [], [], style, color="0.1", lw=1.2, ms=3)[0]
        for j in mo.joints:
            if j.kind != "free":
                self.links[j.name] = ax.plot([], [], [], "--", color="0.45", lw=0.8)[0]
            self.axes_of[j.name] = ax.plot([], [], [], "-o", color="k", lw=2.0, ms=3, markevery=[1])[0]
        for n, name in enumerate(mo.markers):
            self.dots[name] = ax.plot([], [], [], "o", color=f"C{(n + 3) % 10}", ms=5, label=name)[0]
            self.trails[name] = ax.plot([], [], [], "-", color=f"C{(n + 3) % 10}", lw=0.8, alpha=0.7)[0]
        arm = 0.1 * self.size
        for k, axis in enumerate("xyz"):                    # the inertial axes at the origin
            tip = np.zeros(3)
            tip[k] = arm
            ax.plot([0, tip[0]], [0, tip[1]], [0, tip[2]], "-", color="rgb"[k], lw=1.5)
            ax.text(*(1.15 * tip), axis, color="rgb"[k], fontsize=9)
        if mo.markers:
            self.fig.legend(handles=list(self.dots.values()), loc="upper right", fontsize=8)
        self.title = self.fig.suptitle("", fontsize=10)

    def draw(self, i: int) -> list:
        """Every artist at row i (and the camera, when orbiting); returns them."""
        mo, origin = self.mo, {b.name: b.origin[i] for b in self.mo.bodies}
        for b in mo.bodies:
            if b.name in self.solids:
                self.solids[b.name].set_verts(box_faces(b, i) if b.shape == "box" else tube_faces(b, i))
            if b.name in self.lines:
                self.lines[b.name].set_data_3d(*b.line[i].T)
        stroke = 0.04 * self.size
        for j in mo.joints:
            p, a = j.position[i], j.axis[i]
            if j.name in self.links:
                self.links[j.name].set_data_3d(*np.array([origin[j.parent], p]).T)
            self.axes_of[j.name].set_data_3d(*np.array([p - stroke * a, p, p + stroke * a]).T)
        for name, pos in mo.markers.items():
            self.dots[name].set_data_3d(*pos[i:i + 1].T)
            self.trails[name].set_data_3d(*pos[:i + 1].T)
        if self.orbit:
            self.ax.view_init(self.elev, self._angles()[0] + 360.0 * i / max(len(mo.t) - 1, 1), vertical_axis=self.up)
        note = f", deflections x{mo.exaggerate:g}" if mo.exaggerate != 1.0 else ""
        self.title.set_text(f"{self.title_text}: t = {mo.t[i]:.3f} s{note}")
        return [*self.solids.values(), *self.lines.values(), *self.links.values(), *self.axes_of.values(),
                *self.dots.values(), *self.trails.values(), self.title]


def check_animation_path(output, option: str, res: Results, scene=None) -> Path:
    """The animation's path checked by pymr's output rule before anything is drawn: not a
    folder, in a folder that is there, a GIF, a still (.png) or a video where ffmpeg is
    installed, none of the run's files (CSV, JSON) or the scene's."""
    out = check_output(output, "animation", option=option, suffixes=FORMATS,
                       example=(Path(res.path).stem if res.path else "anim") + ".gif",
                       inputs=([res.path, Path(res.path).with_suffix(".json")] if res.path else [])
                       + ([res.stats["scene"]] if res.stats.get("scene") else []),
                       scene=scene_of(res, scene))
    if out.suffix.lower() not in (".gif", ".png"):
        from matplotlib import animation
        if not animation.writers.is_available("ffmpeg"):
            raise AnimateError(f"{option} {out}: a {out.suffix} video needs ffmpeg, which is not installed here "
                               "(write a .gif)")
    return out


#: The fewest frames of an animation (one frame is a still: a .png output).
LEAST_FRAMES = 2


def check_drawing(view, exaggerate, frames, orbit) -> None:
    """The drawing's options, each checked alone and named: `view` a text, `exaggerate`
    None or a scale from 0 (deflection_scale), `frames` a whole number of at least LEAST_FRAMES, `orbit` a
    bool (a wrong type is an ArgumentTypeError; they were TypeErrors and AttributeErrors
    from inside, and frames and exaggerate shared one message)."""
    if not isinstance(view, str):
        raise ArgumentTypeError(f"view: a named view or 'ELEV,AZIM' (str), got {_shown(view)}")
    if exaggerate is not None:
        deflection_scale(exaggerate)
    _whole("frames", frames, LEAST_FRAMES, " (one frame is a still: write a .png)")
    _flag("orbit", orbit)


def _whole(name: str, value, least: int, note: str = "") -> int:
    """A whole number argument of at least `least`."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ArgumentTypeError(f"{name}: a whole number, got {_shown(value)}")
    if value < least:
        raise AnimateError(f"{name}: at least {least}, got {value}{note}")
    return int(value)


def drawing(res: Results, scene=None, view: str = "iso", exaggerate: float | None = None, frames: int = 200,
            orbit: bool = False) -> Drawing:
    """The Drawing of at most `frames` evenly spaced output rows (exaggerate None: the default
    factor of the module's doc)."""
    import matplotlib
    matplotlib.use("Agg")
    check_drawing(view, exaggerate, frames, orbit)
    source = scene_of(res, scene)
    up = vertical_axis(source)
    camera(view, up)                                     # a bad view is refused before any work
    mo = motion(res, scene, exaggerate=1.0, frames=frames)
    if exaggerate is None:
        exaggerate = auto_exaggerate(mo)
    if exaggerate != 1.0:
        mo = motion(res, scene, exaggerate=exaggerate, frames=frames)
    return Drawing(mo, view=view, up=up, orbit=orbit, title=res.title or Path(res.path or "run").stem)


def animate(results: Results | str | os.PathLike, output: str | os.PathLike, scene=None, view: str = "iso",
            exaggerate: float | None = None, fps: int = 25, frames: int = 200, orbit: bool = False,
            at: float | None = None, option: str = "output") -> Path:
    """Write the animation (GIF, or a video by the suffix where ffmpeg is installed: .mp4,
    .mkv, .mov, .avi, .webm) of at most ``frames`` evenly spaced output rows, or a still
    (.png: the frame nearest the time `at`, default the last); return its path. The output
    is checked first (:func:`check_animation_path`; `option` names it in messages) and
    written whole or not at all."""
    import logging
    # a writer matplotlib lacks (ffmpeg) is logged, then the Pillow fallback's error is ours
    logging.getLogger("matplotlib.animation").setLevel(logging.ERROR)
    res = results if isinstance(results, Results) else load_results(results)
    check_drawing(view, exaggerate, frames, orbit)       # the options before any work
    _whole("fps", fps, 1)
    if at is not None and not res.t[0] <= _time(at, "at") <= res.t[-1]:
        raise AnimateError(f"at: {at:g} s is outside the run's results, {res.t[0]:g} to {res.t[-1]:g} s")
    out = check_animation_path(output, option, res, scene)
    still = out.suffix.lower() == ".png"
    if at is not None and not still:
        raise AnimateError(f"at: the time of a still (.png); {option} {out} is an animation of the whole run")
    if orbit and still:
        raise AnimateError(f"orbit: turns the camera over an animation; {option} {out} is a still (.png)")
    d = drawing(res, scene, view=view, exaggerate=exaggerate, frames=frames, orbit=orbit)
    # written beside it under a temporary name (of the same suffix: the writers go by it),
    # then renamed over it: an earlier animation survives a failed write
    tmp = out.with_name(f".{out.stem}.{os.getpid()}.tmp{out.suffix}")
    try:
        _write(d, tmp, fps, at)
        sync_to_disk(tmp)                                 # on the disk before its name is
        os.replace(tmp, out)
    except (OSError, ValueError, RuntimeError) as exc:
        raise AnimateError(f"{out}: cannot write the animation ({' '.join(str(exc).split())})") from None
    finally:
        import matplotlib.pyplot as plt
        plt.close(d.fig)
        tmp.unlink(missing_ok=True)
    return out


def _write(d: Drawing, path: Path, fps: int, at: float | None) -> None:
    """The frames of the drawing to `path`: a still (.png) at time `at`, else every frame."""
    from matplotlib.animation import FuncAnimation, PillowWriter
    if path.suffix.lower() == ".png":
        d.draw(int(np.argmin(np.abs(d.mo.t - (d.mo.t[-1] if at is None else at)))))
        d.fig.savefig(path, dpi=100)
        return
    anim = FuncAnimation(d.fig, d.draw, frames=len(d.mo.t), blit=False)
    if path.suffix.lower() == ".gif":
        anim.save(path, writer=PillowWriter(fps=fps))
    else:
        anim.save(path, writer="ffmpeg", fps=fps)


def main(csv: str, output: str | None = None, scene: str | None = None, view: str = "iso",
         exaggerate: float | None = None, fps: int = 25, frames: int = 200, orbit: bool = False,
         at: float | None = None) -> int:
    res = load_results(csv)
    if output is None:
        out, option = Path(csv).with_suffix(".gif"), "the default animation (-o to choose)"
    else:
        out, option = output, "-o"
    out = animate(res, out, scene=scene, view=view, exaggerate=exaggerate, fps=fps, frames=frames, orbit=orbit,
                  at=at, option=option)
    print(f"wrote {out}")
    return 0
