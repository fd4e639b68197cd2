"""``pymr view``: one self-contained HTML page of a run, for any browser, offline.

The page (plotly, its plotly.js embedded: no network) shows, on the left, the mechanism in
3-D: the bodies' solids (a box or a cylinder, from :mod:`pymr.geometry`), the flexible
bodies as tubes along their deformed centre lines (deflections magnified by
``exaggerate``), the joints joining each parent's frame origin to its child's, and the
markers with their paths; on the right, the chosen result columns against time, in
panels as ``pymr plot --column`` makes them (one per unit, its rules in :mod:`pymr.plot`),
each with a vertical line at the time shown. A slider (one step per frame) and play/pause buttons move both.

The frames are output rows: every ``every``-th row, then at most ``frames`` of them, evenly
spread (:func:`pymr.geometry.motion`). The column panels hold every ``every``-th row. The
3-D coordinates go into the page as 32-bit floats (a drawing needs no more); the columns as
they are. The page is written whole or not at all (a temporary file, then renamed).
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import numpy as np

from ._args import _names
from .api import write_file
from .outputs import check_output
from .plot import STILL, PlotError, column_panels, match_columns, unit_scale
from .results import Results, load_results

#: Sides of the polygons that stand for round sections (cylinders, tubes).
SIDES = 12

#: Colours of the plotted columns, one each in turn (plotly's, without the red of the time line).
LINES = ["#1f77b4", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22", "#17becf"]

#: The moving 3-D traces, the figure's first: solids, links, joints, joint axes, markers, nodes.
MOVING = 6

#: Colours of the solids, body by body (muted, so that the markers and joint axes stand out).
COLOURS = ["#8c9bb5", "#c9a26b", "#7fb39a", "#b58cae", "#b5b58c", "#8cb5b5", "#c98b7a", "#9a9a9a"]


def select_columns(res: Results, patterns: Sequence[str] | None = None) -> list[str]:
    """The columns to plot: those the names or shell-style patterns match (``energy.*``),
    by ``pymr plot --column``'s rule (:func:`pymr.plot.match_columns`: in the patterns'
    order, each column once; a pattern that matches nothing is a PlotError naming it); none
    given: :func:`default_columns`."""
    if not patterns:
        return default_columns(res)
    return match_columns([res], patterns)


def default_columns(res: Results) -> list[str]:
    """The first marker's position (x, y, z: the tank's muzzle, Fig. 5); without markers,
    the first joint's coordinates; else the first three columns after t."""
    info = res.column_info
    for group, quantity in (("markers", "position"), ("joint_coordinates", None)):
        owners = [c.owner for c in info if c.group == group]
        if owners:
            return [c.name for c in info if c.group == group and c.owner == owners[0]
                    and (quantity is None or c.quantity == quantity)]
    return [c for c in res.columns if c != "t"][:3]


def panels(res: Results, names: list[str]) -> list[tuple[str, list[str]]]:
    """The right-hand panels, (y axis title, columns) each, as ``pymr plot --column`` makes
    them (:func:`pymr.plot.column_panels`): the columns grouped by their unit (the results'
    column metadata), the axis titled with what they are and the unit (``position (m)``)."""
    return [(p.ylabel, p.columns) for p in column_panels([res], [glob_escape(n) for n in names])]


def glob_escape(name: str) -> str:
    """A column's name as a pattern that matches it alone ('[' '*' '?' taken literally)."""
    import glob
    return glob.escape(name)


# ------------------------------------------------------------------ solids

def box_points(size: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A box's 8 corners (body frame) and its 12 triangles."""
    signs = np.array([[i, j, k] for i in (-0.5, 0.5) for j in (-0.5, 0.5) for k in (-0.5, 0.5)])
    faces = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                      [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return centre + signs * size, faces


def ring_faces(rings: int, sides: int = SIDES) -> np.ndarray:
    """Triangles of a tube of `rings` rings of `sides` points each (ring after ring), with
    its two ends closed (fans from the first point of the end rings)."""
    faces = []
    for r in range(rings - 1):
        for s in range(sides):
            a, b = r * sides + s, r * sides + (s + 1) % sides
            faces += [[a, b, b + sides], [a, b + sides, a + sides]]
    for base in (0, (rings - 1) * sides):
        faces += [[base, base + s, base + s + 1] for s in range(1, sides - 1)]
    return np.array(faces)


def cylinder_points(size: np.ndarray, centre: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A cylinder along the body's x (length size[0], radius size[1]) about `centre`: its
    two rings of points (body frame) and its triangles."""
    length, radius = size[0], size[1]
    angle = 2 * np.pi * np.arange(SIDES) / SIDES
    ring = np.column_stack([np.zeros(SIDES), radius * np.cos(angle), radius * np.sin(angle)])
    ends = [ring + [x, 0.0, 0.0] for x in (-0.5 * length, 0.5 * length)]
    return centre + np.concatenate(ends), ring_faces(2)


def tube_points(line: np.ndarray, radius: float) -> np.ndarray:
    """Rings of SIDES points of `radius` about a centre line's points, each ring across the
    line's local direction: line (nt, np, 3) -> (nt, np * SIDES, 3)."""
    tangent = np.gradient(line, axis=1)
    tangent /= np.maximum(np.linalg.norm(tangent, axis=2, keepdims=True), 1e-300)
    helper = np.where(np.abs(tangent[..., :1]) < 0.9, [1.0, 0.0, 0.0], [0.0, 1.0, 0.0])
    u = np.cross(tangent, helper)
    u /= np.linalg.norm(u, axis=2, keepdims=True)
    v = np.cross(tangent, u)
    angle = 2 * np.pi * np.arange(SIDES) / SIDES
    rings = (line[:, :, None, :] + radius * (np.cos(angle)[None, None, :, None] * u[:, :, None, :]
                                             + np.sin(angle)[None, None, :, None] * v[:, :, None, :]))
    return rings.reshape(line.shape[0], -1, 3)


def body_solid(body) -> tuple[np.ndarray, np.ndarray] | None:
    """One body's solid over the frames: points (nt, nv, 3, inertial) and triangles; a
    beam's is a tube along its deformed centre line (a modal-file body's nodes are drawn as
    points: :func:`nodes`); None for no solid."""
    if body.kind == "beam" and body.line is not None and len(body.line[0]) > 1:
        span = np.linalg.norm(body.line[0, -1] - body.line[0, 0])
        radius = body.size[1] if body.shape == "cylinder" and body.size[1] > 0 else 0.02 * span
        return tube_points(body.line, radius), ring_faces(body.line.shape[1])
    if body.shape == "box":
        local, faces = box_points(np.asarray(body.size, float), np.asarray(body.centre, float))
    elif body.shape == "cylinder":
        local, faces = cylinder_points(np.asarray(body.size, float), np.asarray(body.centre, float))
    else:
        return None
    return body.origin[:, None, :] + np.einsum("tij,vj->tvi", body.rotation, local), faces


def solids(motion) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """Every body's solid as one mesh: points (nt, nv, 3), triangles, a colour per triangle."""
    points, faces, colours, start = [], [], [], 0
    for k, body in enumerate(motion.bodies):
        solid = body_solid(body)
        if solid is None:
            continue
        p, f = solid
        points.append(p)
        faces.append(f + start)
        colours += [COLOURS[k % len(COLOURS)]] * len(f)
        start += p.shape[1]
    if not points:
        return np.zeros((len(motion.t), 0, 3)), np.zeros((0, 3), int), []
    return np.concatenate(points, axis=1), np.concatenate(faces), colours


# ------------------------------------------------------------------ the 3-D traces

def _f32(a) -> np.ndarray:
    """Coordinates for drawing: 32-bit floats (half the page of 64-bit ones)."""
    return np.asarray(a, dtype=np.float32)


def polylines(pieces: list[np.ndarray]) -> np.ndarray:
    """Polylines (each (nt, n, 3)) as one (nt, m, 3) array, a NaN point between them (a gap)."""
    if not pieces:
        return np.zeros((0, 0, 3))
    gap = np.full((pieces[0].shape[0], 1, 3), np.nan)
    return np.concatenate([part for p in pieces for part in (p, gap)][:-1], axis=1)


def links(motion) -> np.ndarray:
    """The tree's links: for each joint, its parent's frame origin, the joint, its child's
    frame origin, as polylines (nt, m, 3)."""
    origin = {b.name: b.origin for b in motion.bodies}
    pieces = []
    for j in motion.joints:
        ends = [origin.get(j.parent), j.position, origin.get(j.child)]
        pieces.append(np.stack([e for e in ends if e is not None], axis=1))
    return polylines(pieces)


def nodes(motion) -> np.ndarray:
    """The deformed nodes of the modal-file bodies (points, not a line: their order is the
    file's), (nt, m, 3)."""
    pieces = [b.line for b in motion.bodies if b.kind != "beam" and b.line is not None]
    return np.concatenate(pieces, axis=1) if pieces else np.zeros((len(motion.t), 0, 3))


def joint_axes(motion, length: float) -> np.ndarray:
    """A segment of `length` along each joint's axis, centred on the joint (nt, m, 3)."""
    pieces = [np.stack([j.position - 0.5 * length * j.axis, j.position + 0.5 * length * j.axis], axis=1)
              for j in motion.joints if np.any(j.axis)]
    return polylines(pieces)


def frame_traces(motion, mesh, k: int, size: float) -> list[dict]:
    """The moving 3-D traces at frame k: solids, links, joints, joint axes, markers, the
    modal-file bodies' nodes (the figure's first six traces, in this order)."""
    import plotly.graph_objects as go
    points = mesh[0][k]
    tree, axes = links(motion), joint_axes(motion, 0.15 * size)
    joints = np.array([j.position[k] for j in motion.joints]).reshape(-1, 3)
    marks = np.array([p[k] for p in motion.markers.values()]).reshape(-1, 3)

    def xyz(a):
        a = _f32(a).reshape(-1, 3)
        return {"x": a[:, 0], "y": a[:, 1], "z": a[:, 2]}

    return [go.Mesh3d(**xyz(points)),
            go.Scatter3d(**xyz(tree[k] if tree.size else [])),
            go.Scatter3d(**xyz(joints)),
            go.Scatter3d(**xyz(axes[k] if axes.size else [])),
            go.Scatter3d(**xyz(marks)),
            go.Scatter3d(**xyz(nodes(motion)[k]))]


def mechanism(fig, motion, mesh, size: float) -> None:
    """The 3-D traces of the first frame, styled, then the markers' paths (which stay)."""
    import plotly.graph_objects as go
    first = frame_traces(motion, mesh, 0, size)
    faces = mesh[1]
    first[0].update(i=faces[:, 0], j=faces[:, 1], k=faces[:, 2], facecolor=mesh[2], flatshading=True,
                    name="bodies", hoverinfo="skip", lighting={"ambient": 0.55, "diffuse": 0.7},
                    opacity=0.7)     # the joints and links inside the solids show through
    first[1].update(mode="lines", line={"color": "#444444", "width": 5}, name="joints' links", hoverinfo="skip")
    first[2].update(mode="markers", marker={"size": 4, "color": "#222222", "symbol": "diamond"}, name="joints",
                    text=[j.name for j in motion.joints], hoverinfo="text")
    first[3].update(mode="lines", line={"color": "#d62728", "width": 3}, name="joint axes", hoverinfo="skip")
    first[4].update(mode="markers+text", marker={"size": 5, "color": "#1f77b4"}, name="markers",
                    text=list(motion.markers), textposition="top center", hoverinfo="text")
    first[5].update(mode="markers", marker={"size": 3, "color": "#7f7f7f"}, name="flexible bodies' nodes",
                    hoverinfo="skip")
    for trace in first:
        fig.add_trace(trace.update(showlegend=False), row=1, col=1)
    for name, p in motion.markers.items():
        fig.add_trace(go.Scatter3d(x=_f32(p[:, 0]), y=_f32(p[:, 1]), z=_f32(p[:, 2]), mode="lines",
                                   line={"color": "#1f77b4", "width": 2}, opacity=0.5, name=f"{name}'s path",
                                   hoverinfo="skip", showlegend=False), row=1, col=1)


# ------------------------------------------------------------------ the column panels

def y_range(values: np.ndarray, scale: float) -> list[float]:
    """A panel's y range: the values' with 5 % either side; a still quantity's, whose range
    is below ``pymr plot``'s smallest (STILL times `scale`, the largest magnitude of its
    unit in the run: :func:`pymr.plot.smallest_range`), that smallest range about its middle,
    so that its round-off does not fill the panel."""
    lo, hi = float(np.min(values)), float(np.max(values))
    half = STILL * scale
    if hi - lo < 2 * half:
        return [0.5 * (lo + hi) - half, 0.5 * (lo + hi) + half]
    pad = 0.05 * (hi - lo) if hi > lo else max(0.05 * abs(lo), 1.0)
    return [lo - pad, hi + pad]


def add_panels(fig, res: Results, chosen: list[tuple[str, list[str]]], rows: np.ndarray,
               t0: float) -> tuple[list[list[float]], list[int]]:
    """Each panel's columns against t at `rows`, and its vertical line at t0; the panels'
    y ranges and the indices of their vertical lines among the figure's traces."""
    import plotly.graph_objects as go
    ranges, follow = [], []
    for p, (title, names) in enumerate(chosen, start=1):
        data = np.column_stack([res[n][rows] for n in names])
        for n, y in zip(names, data.T):
            colour = LINES[len(fig.data) % len(LINES)]
            fig.add_trace(go.Scatter(x=res.t[rows], y=y, mode="lines", name=n, line={"color": colour}), row=p, col=2)
        ranges.append(y_range(data, unit_scale(res, res.unit(names[0]))))
        fig.add_trace(go.Scatter(x=[t0, t0], y=ranges[-1], mode="lines", line={"color": "#d62728", "width": 1.5},
                                 name="time shown", showlegend=p == 1, legendrank=2000, hoverinfo="skip"),
                      row=p, col=2)
        follow.append(len(fig.data) - 1)
        fig.update_yaxes(title_text=title, range=ranges[-1], row=p, col=2)
        fig.update_xaxes(range=[float(res.t[0]), float(res.t[-1])], row=p, col=2,
                         title_text="t (s)" if p == len(chosen) else None)
    return ranges, follow


def up_axis(res: Results, scene=None) -> np.ndarray:
    """The view's up direction: against the scene's gravity; z where there is none."""
    from .api import PymrError
    from .geometry import scene_of
    from .scene import Scene
    try:
        source = scene_of(res, scene)
        g = np.asarray((source if isinstance(source, Scene) else Scene(source))["scene.gravity"], dtype=float)
    except (PymrError, KeyError, TypeError, ValueError):
        g = np.zeros(3)
    return -g / np.linalg.norm(g) if np.linalg.norm(g) > 0 else np.array([0.0, 0.0, 1.0])


def scene_layout(motion, up: np.ndarray) -> dict:
    """The 3-D scene's axes (ranges fixed over all frames, one scale on all three: the
    mechanism's true proportions, each axis at least a third of the longest, so a flat
    mechanism keeps some depth) and camera (up against gravity, looking from a corner)."""
    lo, hi = (np.asarray(b, float) for b in motion.bounds())
    longest = max(float(np.max(hi - lo)), 1e-9)
    half = 0.5 * np.maximum(hi - lo, longest / 3) + 0.05 * longest
    centre = 0.5 * (lo + hi)
    axes = {f"{a}axis": {"range": [float(centre[i] - half[i]), float(centre[i] + half[i])], "title": f"{a} (m)"}
            for i, a in enumerate("xyz")}
    ratio = dict(zip("xyz", map(float, half / half.max())))
    side = np.array([1.0, 1.0, 1.0]) - up * 0.4
    eye = 1.45 * side / np.linalg.norm(side)
    return {**axes, "aspectmode": "manual", "aspectratio": ratio,
            "camera": {"up": dict(zip("xyz", map(float, up))), "eye": dict(zip("xyz", map(float, eye)))}}


# ------------------------------------------------------------------ frames, slider, page

def animation_frames(motion, mesh, size: float, follow: list[int], ranges: list[list[float]]) -> list:
    """One plotly frame per time of the motion, named by its index: the moving 3-D traces
    (the figure's first MOVING) and each panel's vertical line (traces `follow`)."""
    import plotly.graph_objects as go
    frames = []
    for k, t in enumerate(motion.t):
        lines = [go.Scatter(x=[float(t), float(t)], y=r) for r in ranges]
        frames.append(go.Frame(name=str(k), data=frame_traces(motion, mesh, k, size) + lines,
                               traces=list(range(MOVING)) + follow))
    return frames


def controls(times: np.ndarray) -> dict:
    """The time slider (a step per frame) and the play/pause buttons."""
    still = {"mode": "immediate", "frame": {"duration": 0, "redraw": True}, "transition": {"duration": 0}}
    steps = [{"method": "animate", "label": f"{t:.4g}", "args": [[str(k)], still]} for k, t in enumerate(times)]
    # a label per step would crowd the rail: the step labels are hidden, the time shown above it
    slider = {"active": 0, "steps": steps, "x": 0.1, "len": 0.9, "y": 0.0, "yanchor": "top", "pad": {"t": 30},
              "font": {"color": "rgba(0,0,0,0)"}, "transition": {"duration": 0},
              "currentvalue": {"prefix": "t = ", "suffix": " s", "xanchor": "right", "font": {"color": "#222222"}}}
    play = {"label": "play", "method": "animate",
            "args": [None, {**still, "frame": {"duration": 60, "redraw": True}, "fromcurrent": True}]}
    pause = {"label": "pause", "method": "animate",
             "args": [[None], {**still, "frame": {"duration": 0, "redraw": False}}]}
    buttons = {"type": "buttons", "direction": "left", "x": 0.0, "y": 0.0, "xanchor": "left", "yanchor": "top",
               "pad": {"t": 48, "r": 8}, "showactive": False, "buttons": [play, pause]}
    return {"sliders": [slider], "updatemenus": [buttons]}


def figure(motion, res: Results, columns: list[str], up: np.ndarray, every: int = 1):
    """The page's figure: the mechanism (left), the panels of `columns` at every `every`-th
    row (right), the frames and the controls that move both."""
    from plotly.subplots import make_subplots
    chosen = panels(res, columns)
    n = len(chosen)
    specs = [[{"type": "scene", "rowspan": n}, {"type": "xy"}]] + [[None, {"type": "xy"}]] * (n - 1)
    fig = make_subplots(rows=n, cols=2, specs=specs, column_widths=[0.6, 0.4], horizontal_spacing=0.07,
                        vertical_spacing=min(0.08, 0.3 / n))
    lo, hi = (np.asarray(b, float) for b in motion.bounds())
    size = max(float(np.max(hi - lo)), 1e-9)
    mesh = solids(motion)
    mechanism(fig, motion, mesh, size)
    from .geometry import rows_of
    rows = rows_of(len(res.t), every)
    ranges, follow = add_panels(fig, res, chosen, rows, float(motion.t[0]))
    fig.frames = animation_frames(motion, mesh, size, follow, ranges)
    note = f"deflections x{motion.exaggerate:g}" if motion.exaggerate != 1 else "deflections to scale"
    fig.update_layout(**controls(motion.t), scene=scene_layout(motion, up), height=760, uirevision="view",
                      title={"text": f"{res.title or Path(res.path or 'results').stem}: {note}", "x": 0.02},
                      legend={"orientation": "h", "x": 0.63, "y": 1.0, "yanchor": "bottom"},
                      margin={"l": 10, "r": 10, "t": 80, "b": 90})
    return fig


def page(motion, res: Results, columns: Sequence[str] | None = None, every: int = 1,
         up: np.ndarray | None = None) -> str:
    """The HTML page of a motion (:class:`pymr.geometry.Motion`) and its results, the
    `columns` (names or patterns; None: the default ones) beside it: one file, plotly.js in
    it, nothing fetched from the network."""
    fig = figure(motion, res, select_columns(res, columns), np.array([0.0, 0.0, 1.0]) if up is None else up, every)
    return fig.to_html(include_plotlyjs=True, full_html=True, div_id="pymr-view", auto_play=False,
                       config={"displaylogo": False, "responsive": True})


def check_options(every: int, frames: int, exaggerate: float) -> None:
    """--every and --frames whole numbers of at least 1 (else a PlotError naming the option),
    --exaggerate a scale from 0 (deflection_scale)."""
    from .geometry import deflection_scale
    for option, value, least in (("--every", every, 1), ("--frames", frames, 1)):
        if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < least:
            raise PlotError(f"{option} {value!r}: a whole number, at least {least}")
    deflection_scale(exaggerate)


def view(results: Results | str | os.PathLike, output: str | os.PathLike, scene=None,
         columns: Sequence[str] | None = None, every: int = 1, frames: int = 100, exaggerate: float = 1.0,
         option: str = "-o") -> Path:
    """Write the view of a run's results (OUT.csv or a loaded :class:`Results`) to `output`
    (.html), its geometry from the scene the results' JSON holds (or `scene`); return the
    page's path. The output is checked before anything is computed (`option` names it in
    messages), and written whole or not at all."""
    from .geometry import scene_of
    try:
        import plotly  # noqa: F401  (the page's library: an optional dependency)
    except ImportError:
        raise PlotError("pymr view needs plotly, which is not installed (pip install plotly)") from None
    res = results if isinstance(results, Results) else load_results(results)
    columns = None if columns is None else _names("columns", columns)
    check_options(every, frames, exaggerate)
    out = check_output(output, "view", option=option, suffixes=[".html", ".htm"],
                       example=(Path(res.path).stem if res.path else "view") + ".html",
                       inputs=([res.path, Path(res.path).with_suffix(".json")] if res.path else [])
                       + ([res.stats["scene"]] if res.stats.get("scene") else []),
                       scene=scene_of(res, scene))
    select_columns(res, columns)                     # an unknown column is refused before the work
    from .geometry import motion as motion_of
    motion = motion_of(res, scene, exaggerate=exaggerate, every=every, frames=frames)
    write_file(out, page(motion, res, columns, every, up_axis(res, scene)), "view")
    return out


def main(csv: str, output: str | None = None, scene: str | None = None, columns: Sequence[str] | None = None,
         every: int = 1, frames: int = 100, exaggerate: float = 1.0) -> int:
    """``pymr view``: the page beside the results (OUT.html) unless -o names it."""
    if output is None:
        out, option = Path(csv).with_suffix(".html"), "the default view (-o to choose)"
    else:
        out, option = output, "-o"
    out = view(csv, out, scene=scene, columns=columns, every=every, frames=frames, exaggerate=exaggerate,
               option=option)
    print(f"wrote {out} ({out.stat().st_size / 1e6:.1f} MB)")
    return 0
