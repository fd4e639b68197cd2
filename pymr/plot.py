"""``pymr plot``: figures of result files, headless (matplotlib's Agg renderer).

One figure, one axes per plotted column, every run overlaid in each axes (one colour per
run, the same in every axes) and one legend naming the runs.

- The tank (runs with a ``muzzle`` marker and the modal coordinates of ``gun``): the paper's
  Figs. 5-7, the muzzle's position (x, y, z against t), its velocity (vx, vy, vz) and the
  barrel's modal coordinates (gun.a1 ... gun.a4).
- Any other scene: every marker's position and velocity, every joint's coordinates and
  every flexible body's modal coordinates.

``markers=`` (``--marker``) and ``joints=`` (``--joint``) choose markers and joints by name
instead (for the tank, named joints are added to Figs. 5-7). Each axes is titled with its
column's name and holds one line per run whose data are the run's arrays themselves, so
``{ax.get_title(): ax.get_lines() for ax in fig.axes}`` reads the plotted numbers back.

``columns=`` (``--column``) draws chosen columns instead: names or shell-style patterns
(``energy.*``, ``elevation.f?``, matched by :func:`fnmatch.fnmatchcase` against the first
run's columns, ``t`` left out). The matched columns are grouped into panels by their unit
(the results' column metadata): columns of one unit share a panel, up to
:data:`PANEL_LINES` of them (more make further panels of that unit), the y axis labelled
with what they are and the unit (``force (N)``, ``energy (J)``), each line labelled with its
column's name (and its run's label when there are several runs) in the panel's legend.

In every panel, a still quantity's round-off does not fill the panel: with ``scale`` the
largest magnitude of the runs' columns of the panel's unit (that unit's scale in the runs),
a range of values below 2 :data:`STILL` ``scale`` is drawn as their middle +- :data:`STILL`
``scale`` (:func:`smallest_range`).
"""
from __future__ import annotations

import contextlib
import difflib
import fnmatch
import io
import logging
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Iterable, Mapping, Sequence, Union

import numpy as np

from ._args import _names, _scalar_array, _shown
from .api import PymrError, write_file
from .errors import ArgumentTypeError, ResultsError
from .outputs import check_output
from .results import Results, check_rows, load_results

RunLike = Union[Results, str, os.PathLike]

#: Columns per row of the figure at most (markers use rows of 3: x, y, z).
ROW_WIDTH = 4

#: Columns of one unit in one panel at most (``--column``); more make further panels.
PANEL_LINES = 9

#: Panels side by side in a figure of chosen columns (``--column``).
PANELS_PER_ROW = 2

#: The smallest y range of a panel, relative to the scale of its unit in the run: a range
#: of values below it is round-off of a still quantity (doubles carry 16 digits; a long run's
#: sums lose a few), and the panel shows mean +- STILL * scale instead.
STILL = 1e-9


class PlotError(PymrError, ValueError):
    """Bad input to a plot: a missing or unreadable result file, an unknown marker or joint,
    labels that do not match the runs. The CLI prints it as one line and exits with 1."""


@dataclass
class Row:
    """One row of axes: the columns it plots and the y label they share."""
    columns: list[str]
    ylabel: str


@dataclass
class Panel:
    """One panel of chosen columns (``--column``): columns of one unit and their y label."""
    columns: list[str]
    ylabel: str
    unit: str


def run_list(runs) -> list:
    """`runs` as a list: one run (a results file's path or a Results, not the characters of
    a path) or a sequence of them; anything else an ArgumentTypeError naming it."""
    if isinstance(runs, (Results, str, bytes, os.PathLike)):
        return [runs]
    if isinstance(runs, Mapping) or not isinstance(runs, Iterable):
        raise ArgumentTypeError(f"runs: a results file's path, a pymr.Results or a list of them, got {_shown(runs)}")
    items = list(runs)
    for k, run in enumerate(items):
        if not isinstance(run, (Results, str, bytes, os.PathLike)):
            raise ArgumentTypeError(f"runs[{k}]: a results file's path or a pymr.Results, got {_shown(run)}")
    return items


def load_runs(runs: Sequence[RunLike]) -> list[Results]:
    """Results as given, or loaded from CSV paths (a missing or unreadable file, or Results
    without rows or with a value that is not finite, is a PlotError)."""
    out = []
    for k, run in enumerate(run_list(runs)):
        try:
            if isinstance(run, Results):
                check_rows(_name(run, k), run.data, run.columns)   # a file's were checked as it was read
                out.append(run)
            else:
                out.append(load_results(run))
        except ResultsError as exc:
            raise PlotError(str(exc)) from None
    if not out:
        raise PlotError("no result files to plot")
    return out


def _name(res: Results, k: int) -> str:
    return res.path or f"run {k + 1}"


def default_labels(runs: Sequence[Results]) -> list[str]:
    """Each run's method from its CSV comment lines (``single fixed h=1.000E-04``), else the
    file's stem; when two runs would share a label, the stem is put in front of the method."""
    def method(r: Results) -> str:
        return " ".join(r.method.split()).replace("= ", "=")

    def stem(r: Results, k: int) -> str:
        return Path(r.path).stem if r.path else f"run {k + 1}"

    labels = [method(r) or stem(r, k) for k, r in enumerate(runs)]
    if len(set(labels)) < len(labels):
        labels = [f"{stem(r, k)}: {method(r)}" if method(r) else stem(r, k) for k, r in enumerate(runs)]
    return labels


def is_tank(res: Results) -> bool:
    """True for the paper's tank: a ``muzzle`` marker and the barrel ``gun``'s modal coordinates."""
    return "muzzle" in res.markers and "gun" in res.flexible_bodies


def _chunks(columns: list[str], ylabel: str, width: int = ROW_WIDTH) -> list[Row]:
    return [Row(columns[i:i + width], ylabel) for i in range(0, len(columns), width)]


def layout(runs: Sequence[Results], markers: Sequence[str] | None = None,
           joints: Sequence[str] | None = None) -> list[Row]:
    """The rows of axes for these runs (see the module's docstring). Every run must have
    every chosen marker and joint; an unknown one is a PlotError naming the file."""
    first = runs[0]
    tank = is_tank(first)
    if markers is None:
        markers = ["muzzle"] if tank else first.markers
    if joints is None:
        joints = [] if tank else first.joints
    bodies = ["gun"] if tank else first.flexible_bodies
    markers, joints = list(markers), list(joints)
    for k, res in enumerate(runs):
        for m in markers:
            if m not in res.markers:
                raise PlotError(f"{_name(res, k)}: no marker {m!r} (markers: {', '.join(res.markers) or 'none'})")
        for j in joints:
            if j not in res.joints:
                raise PlotError(f"{_name(res, k)}: no joint {j!r} (joints: {', '.join(res.joints) or 'none'})")
        for b in bodies:
            if b not in res.flexible_bodies:
                raise PlotError(f"{_name(res, k)}: no modal coordinates of body {b!r}, which "
                                f"{_name(first, 0)} has: the runs are of different scenes")
    rows: list[Row] = []
    for m in markers:
        rows.append(Row([f"{m}.{c}" for c in ("x", "y", "z")], f"{m} position (m)"))
        rows.append(Row([f"{m}.{c}" for c in ("vx", "vy", "vz")], f"{m} velocity (m/s)"))
    jcols = [c for j in joints for c in first.joint_columns(j)]
    rows += _chunks(jcols, "joint coordinate (rad or m)")
    for b in bodies:
        rows += _chunks(first.modal_columns(b), f"{b} modal coordinate (m kg^0.5)")
    if not rows:
        raise PlotError(f"{_name(first, 0)}: nothing to plot (no markers, joints or modal coordinates)")
    return rows


def _metadata(res: Results, k: int) -> list:
    """The run's column metadata (a PlotError naming the file when it has none)."""
    try:
        return res.column_info
    except ResultsError as exc:
        raise PlotError(str(exc)) from None


def match_columns(runs: Sequence[Results], patterns: Sequence[str]) -> list[str]:
    """The first run's columns that the names or shell-style patterns match (``t`` left out),
    in the patterns' order, each pattern's matches in the file's order, each column once. A
    pattern matching nothing is a PlotError naming it and a few close column names; every
    other run must have every matched column."""
    first = runs[0]
    names = [c for c in first.columns if c != "t"]
    chosen: dict[str, None] = {}
    for pattern in patterns:
        found = [c for c in names if fnmatch.fnmatchcase(c, pattern)]
        if not found:
            close = difflib.get_close_matches(pattern, names, n=5, cutoff=0.4)
            hint = f"close: {', '.join(close)}" if close else \
                f"columns: {', '.join(names[:6])}{', ...' if len(names) > 6 else ''}"
            raise PlotError(f"{_name(first, 0)}: no column matches {pattern!r} ({hint})")
        chosen.update(dict.fromkeys(found))
    for k, res in enumerate(runs[1:], start=1):
        for c in chosen:
            if c not in res.columns:
                raise PlotError(f"{_name(res, k)}: no column {c!r}, which {_name(first, 0)} has: "
                                "the runs are of different scenes")
    return list(chosen)


def _what(infos: list) -> str:
    """The y label's words for columns of one unit: their shared quantity, else their shared
    group (``energy``), else ``value``."""
    for field_ in ("quantity", "group"):
        values = {getattr(c, field_) for c in infos}
        if len(values) == 1:
            return values.pop().replace("_", " ")
    return "value"


def column_panels(runs: Sequence[Results], patterns: Sequence[str]) -> list[Panel]:
    """The panels of the chosen columns: grouped by unit in order of first appearance, at most
    PANEL_LINES columns a panel."""
    info = {c.name: c for c in _metadata(runs[0], 0)}
    by_unit: dict[str, list[str]] = {}
    for name in match_columns(runs, patterns):
        by_unit.setdefault(info[name].unit, []).append(name)
    panels = []
    for unit, names in by_unit.items():
        for i in range(0, len(names), PANEL_LINES):
            part = names[i:i + PANEL_LINES]
            panels.append(Panel(part, f"{_what([info[c] for c in part])} ({unit})", unit))
    return panels


def unit_scale(res: Results, unit: str) -> float:
    """The largest magnitude of the run's columns of `unit` (0 without column metadata)."""
    try:
        cols = [k for k, c in enumerate(res.column_info) if c.unit == unit]
    except ResultsError:
        return 0.0
    return float(abs(res.data[:, cols]).max()) if cols else 0.0


def smallest_range(ax, values: Sequence, scale: float) -> bool:
    """Give the axes `ax` at least the y range mean +- STILL * scale of `values` (the arrays
    it plots; `scale` the largest magnitude of their unit in the runs): a still quantity's
    round-off does not fill the panel. True when the range was set."""
    import numpy as np
    ys = np.concatenate([np.asarray(v, dtype=float).ravel() for v in values])
    half = STILL * scale
    if half == 0.0 or ys.max() - ys.min() >= 2 * half:
        return False
    centre = 0.5 * (ys.max() + ys.min())
    ax.set_ylim(centre - half, centre + half)
    return True


def _column_unit(res: Results, name: str) -> str | None:
    try:
        return res.unit(name)
    except (ResultsError, KeyError):
        return None


def _keep_range(ax, runs: Sequence[Results], columns: Sequence[str]) -> None:
    """smallest_range for an axes plotting `columns` of every run (all of one unit)."""
    unit = _column_unit(runs[0], columns[0])
    if unit is not None:
        scale = max(unit_scale(res, unit) for res in runs)
        smallest_range(ax, [res[c] for res in runs for c in columns], scale)


def plot_results(runs: Sequence[RunLike], output: str | os.PathLike | None = None, *,
                 markers: Sequence[str] | str | None = None, joints: Sequence[str] | None = None,
                 labels: Sequence[str] | None = None, title: str | None = None,
                 columns: Sequence[str] | str | None = None):
    """Plot one or more runs (``Results`` or CSV paths) and return the matplotlib Figure;
    write it to ``output`` (PNG, or any format matplotlib knows by the suffix) when given.

    ``markers`` and ``joints`` choose what is plotted by name (default: see the module's
    docstring); ``columns`` (names or shell-style patterns) draws those columns instead,
    grouped by unit (not with ``markers`` or ``joints``); ``labels`` name the runs in the
    legend (default: :func:`default_labels`). The figure is not registered with pyplot, so
    nothing needs closing and no display is used.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    runs = run_list(runs)
    if output is not None:
        output = check_figure_path(output, "output", runs)
    markers, joints, columns = (None if v is None else _names(n, v)
                                for n, v in (("markers", markers), ("joints", joints), ("columns", columns)))
    if title is not None and not isinstance(title, str):
        raise ArgumentTypeError(f"title: a text (str), got {_shown(title)}")
    if labels is not None:
        labels = [labels] if isinstance(labels, str) else _texts("labels", labels)
    runs = load_runs(runs)
    if columns is not None and not columns:
        raise PlotError("columns: none given; give at least one column name or pattern (e.g. 'muzzle.*')")
    if columns is not None and (markers is not None or joints is not None):
        raise PlotError("columns draw the chosen columns alone: give markers and joints as columns too "
                        "(e.g. 'muzzle.*', 'elevation.q')")
    if labels is None:
        labels = default_labels(runs)
    labels = list(labels)
    if len(labels) != len(runs):
        raise PlotError(f"labels: {len(labels)} given for {len(runs)} result files; give one per file")
    if columns is not None:
        panels = column_panels(runs, columns)
        fig = Figure(figsize=(16, 3.4 * -(-len(panels) // PANELS_PER_ROW) + 0.9), layout="constrained")
        FigureCanvasAgg(fig)
        _draw_panels(fig, panels, runs, labels)
    else:
        rows = layout(runs, markers, joints)
        fig = Figure(figsize=(16, 2.9 * len(rows) + 0.9), layout="constrained")
        FigureCanvasAgg(fig)
        _draw_rows(fig, rows, runs, labels)
    first = runs[0]
    if title is None:
        title = first.title or (Path(first.path).stem if first.path else "pymr results")
        if is_tank(first) and markers is None and columns is None:
            title += ": muzzle position, velocity and modal coordinates (the paper's Figs. 5-7)"
    fig.suptitle(title)
    if output is not None:
        _write_figure(fig, output)
    return fig


def _texts(name: str, value) -> list[str]:
    """A list of texts (str), each of any content (a label may be empty)."""
    if isinstance(value, (bytes, Mapping)) or not isinstance(value, Iterable) or _scalar_array(value):
        raise ArgumentTypeError(f"{name}: a list of texts (str), got {_shown(value)}")
    items = list(value)
    for k, item in enumerate(items):
        if not isinstance(item, str):
            raise ArgumentTypeError(f"{name}[{k}]: a text (str), got {_shown(item)}")
    return items


def _run_styles(n: int) -> tuple[list[str], list[str], list[float]]:
    """One colour, line style and width per run; later runs thinner, so that coinciding runs
    stay visible."""
    styles = ["-", "--", "-.", ":"]
    return ([f"C{k % 10}" for k in range(n)], [styles[k % len(styles)] for k in range(n)],
            [max(2.0 - 0.4 * k, 0.8) for k in range(n)])


#: The grid's grey: matplotlib's grid grey at 0.3 opacity on white, drawn opaque (PostScript
#: has no transparency and warned of it on every figure).
GRID_GREY = "0.907"

#: The largest magnitude a plot's axes scale: matplotlib's ticks overflow near 1e308
#: (numpy warnings on stderr, with exit 0).
PLOT_MAX = 1e300


def _plotted(res: Results, col: str) -> np.ndarray:
    """Column `col` of a run, to be drawn: a PlotError when it holds a value beyond PLOT_MAX."""
    v = res[col]
    if not (np.abs(v) <= PLOT_MAX).all():
        big = float(v[np.argmax(np.abs(v))])
        raise PlotError(f"{res.path or 'the results'}: column {col} holds {big:.3g}, beyond what a plot's axes "
                        f"scale (+-{PLOT_MAX:.0e}): leave the column out")
    return v


def _draw_rows(fig, rows: list[Row], runs: list[Results], labels: list[str]) -> None:
    """The default figure: one axes per column, every run overlaid, one legend of the runs."""
    from matplotlib.gridspec import GridSpec
    grid = GridSpec(len(rows), 12, figure=fig)
    colours, styles, widths = _run_styles(len(runs))
    for i, row in enumerate(rows):
        span = 12 // max(len(row.columns), 3)
        for j, col in enumerate(row.columns):
            ax = fig.add_subplot(grid[i, j * span:(j + 1) * span])
            for k, (res, label) in enumerate(zip(runs, labels)):
                ax.plot(res.t, _plotted(res, col), styles[k], color=colours[k], label=label, lw=widths[k])
            ax.set_title(col)
            ax.set_xlabel("t (s)")
            ax.set_ylabel(row.ylabel)
            ax.grid(True, color=GRID_GREY)
            _keep_range(ax, runs, [col])
    handles, names = fig.axes[0].get_legend_handles_labels()
    try:
        fig.legend(handles, names, loc="outside lower center", ncol=min(len(runs), 4), fontsize=9, framealpha=1)
    except ValueError:                               # matplotlib < 3.7: no "outside" placement
        fig.legend(handles, names, loc="lower center", ncol=min(len(runs), 4), fontsize=9, framealpha=1)


def _draw_panels(fig, panels: list[Panel], runs: list[Results], labels: list[str]) -> None:
    """The chosen columns: one axes per panel, a colour per column, a line style per run, and
    each panel's legend naming the columns (and the runs, when there are several)."""
    _, styles, widths = _run_styles(len(runs))
    ncols = min(len(panels), PANELS_PER_ROW)
    nrows = -(-len(panels) // ncols)
    for i, panel in enumerate(panels):
        ax = fig.add_subplot(nrows, ncols, i + 1)
        for j, col in enumerate(panel.columns):
            for k, (res, label) in enumerate(zip(runs, labels)):
                name = col if len(runs) == 1 else f"{col} ({label})"
                ax.plot(res.t, _plotted(res, col), styles[k], color=f"C{j % 10}", label=name, lw=widths[k])
        ax.set_title(", ".join(panel.columns) if len(panel.columns) <= 3 else
                     f"{panel.columns[0]} ... {panel.columns[-1]}")
        ax.set_xlabel("t (s)")
        ax.set_ylabel(panel.ylabel)
        ax.grid(True, color=GRID_GREY)
        ax.legend(fontsize=8, framealpha=1)
        _keep_range(ax, runs, panel.columns)


def _write_figure(fig, output: Path) -> None:
    """Draw the figure in memory, then write it whole (an earlier figure survives a failed
    write)."""
    image = io.BytesIO()
    try:
        fig.savefig(image, dpi=100, format=output.suffix.lstrip(".").lower())
    except (OSError, ValueError, RuntimeError) as exc:   # RuntimeError: a format's tool is missing (.pgf: xelatex)
        raise PlotError(f"{output}: cannot draw the figure ({' '.join(str(exc).split())})") from None
    write_file(output, image.getvalue(), "figure")


def figure_formats() -> list[str]:
    """The suffixes of the figure formats matplotlib writes here (".png", ".pdf", ".svg", ...)."""
    from matplotlib.backend_bases import FigureCanvasBase
    formats = FigureCanvasBase.get_supported_filetypes()
    return ["." + f for f in ["png", *sorted(f for f in formats if f != "png")]]


def check_figure_path(output, option: str, runs: Sequence[RunLike]) -> Path:
    """The figure's path checked by pymr's output rule before anything is drawn: not a
    folder, in a folder that is there, of a format matplotlib writes, none of the runs'
    files (their CSV and JSON)."""
    inputs = []
    for run in runs:
        path = run.path if isinstance(run, Results) else run
        if path:
            inputs += [Path(path), Path(path).with_suffix(".json")]
    first = runs[0].path if runs and isinstance(runs[0], Results) else runs[0] if runs else None
    return check_output(output, "figure", option=option, suffixes=figure_formats(), inputs=inputs,
                        example=Path(first).stem + ".png" if first else "fig.png")


@contextlib.contextmanager
def _matplotlib_silenced(quiet: bool):
    """With `quiet`, matplotlib's warnings and log lines (a missing glyph, a backend's
    limits) left unprinted: ``-q`` prints nothing on success. Errors still raise."""
    if not quiet:
        yield
        return
    log = logging.getLogger("matplotlib")
    level = log.level
    log.setLevel(logging.ERROR)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            yield
    finally:
        log.setLevel(level)


def main(csvs: Sequence[str], output: str | None = None, markers: Sequence[str] | None = None,
         joints: Sequence[str] | None = None, labels: Sequence[str] | None = None,
         title: str | None = None, quiet: bool = False, columns: Sequence[str] | None = None) -> int:
    """``pymr plot``: write the figure of the result files (default: FIRST_STEM.png in the
    working folder). The output is checked before anything is read or drawn."""
    if output is None:
        out = check_figure_path(Path(Path(csvs[0]).stem + ".png"), "the default figure (-o to choose)", csvs)
    else:
        out = check_figure_path(output, "-o", csvs)
    with _matplotlib_silenced(quiet):
        fig = plot_results(csvs, out, markers=markers, joints=joints, labels=labels, title=title, columns=columns)
    if not quiet:
        print(f"wrote {out}: {len(csvs)} run{'s' if len(csvs) != 1 else ''}, {len(fig.axes)} panels")
    return 0
