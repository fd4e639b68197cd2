"""The ``pymr`` command line: ``pymr run``, ``pymr scene``, ``pymr modal-file``,
``pymr modal-import``, ``pymr bench``, ``pymr modes``, ``pymr animate``, ``pymr export``, ``pymr study``,
``pymr sweep``, ``pymr plot``, ``pymr view``."""
from __future__ import annotations

import argparse
import errno
import os
import sys
import warnings

import numpy as np

from .api import PymrError, SceneError, SolverError, run, write_file
from ._timing import MAX_REPEATS
from .sweep import MAX_WORKERS
from .outputs import check_output


def _stem(path: str) -> str:
    """A file's name without its folder and suffix, for the file names that messages offer."""
    from pathlib import Path
    return Path(path).stem or "out"


def _cmd_run(args: argparse.Namespace) -> int:
    if args.output is not None:
        # the rest of the rule (the scene's inputs, the statistics, the checkpoint) is the kernel's
        check_output(args.output, "results file", example=_stem(args.scene) + ".csv")
    res = run(args.scene, output=args.output or "", overrides=args.set or None, restart=args.restart,
              progress=None if args.progress is None else args.progress)
    if not args.quiet:
        print(res.summary)
    return 0


def _cmd_scene(args: argparse.Namespace) -> int:
    from .scene import Scene, schema
    if args.schema:
        print(schema(), end="")
        return 0
    if not args.scene:
        raise SceneError("pymr scene: give a scene file (or --schema)")
    print(Scene(args.scene, args.set or None).resolved(absolute_paths=args.absolute_paths), end="")
    return 0


def _cmd_bench(args: argparse.Namespace) -> int:
    from . import bench
    if args.json is not None:
        check_output(args.json, "figures (JSON)", option="--json", example=f"{args.what}.json",
                     if_left_out="no JSON file")
    return bench.main(args.what, repeats=args.repeats, json_path=args.json, pinocchio_cpp=args.pinocchio_cpp,
                      sizes=args.sizes)


def _cmd_modal_file(args: argparse.Namespace) -> int:
    from .api import _write_modal_file
    _write_modal_file(args.scene, args.body, args.output, args.set or None, "-o")
    if not args.quiet:
        print(f"wrote the modes of beam {args.body!r} to {args.output}")
    return 0


def _cmd_modal_import(args: argparse.Namespace) -> int:
    from .errors import PymrWarning
    from .modal_import import modal_import
    from .outputs import check_output
    check_output(args.output, "modal data file", example="body.modal", if_left_out=None)
    modes = None if args.modes == "all" else _count("--modes", args.modes)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", PymrWarning)        # the body's own list, printed below
        body = modal_import(args.mass, args.stiffness, args.nodes, args.interface, args.output,
                            dofs_per_node=args.dofs_per_node, dof_map=args.dof_map,
                            modes=modes, keep=args.keep, clamp=args.clamp or (), mass_name=args.mass_name,
                            stiffness_name=args.stiffness_name, memory_limit=args.memory_limit,
                            progress=not args.quiet and sys.stderr.isatty())
    for doubt in body.warnings:                              # -q keeps them: they are about the body written
        print(f"pymr: warning: {doubt}", file=sys.stderr)
    if not args.quiet:
        k = body.kept
        print(f"wrote {args.output}: {k['modes_written']} modes of the Craig-Bampton body ({k['fixed_interface_modes']} "
              f"fixed-interface + {k['constraint_modes']} constraint modes), mass {body.mass:.6g} kg")
        print("frequencies (Hz): " + " ".join(f"{f:.6g}" for f in body.frequencies_hz))
        print(f"points (node ids): {' '.join(str(n) for n in body.point_ids)}; inertia invariants {body.exact}")
    return 0


def _count(name: str, text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise SceneError(f"{name} {text}: a count of modes, or 'all'") from None


def _state_at(scene: str, over: list[str], at: float) -> tuple[np.ndarray, np.ndarray, float]:
    """(q, qd, t) at the end of the scene's run to time `at` (> 0)."""
    try:
        res = run(scene, overrides=over + [f"scene.t_end={at!r}", "output.dt=0.0"])
    except SceneError as exc:
        # the run to T is refused for T itself: say so of --at, not of an override never typed
        # (this override comes last, so a refused value of &scene t_end is its value)
        if (exc.kind, exc.group, exc.item) != ("bad_value", "scene", "t_end"):
            raise
        raise SceneError(f"--at {at:g}: the run cannot be taken to this time (as &scene t_end it {exc.fault})") from None
    q, qd = res.coordinates()
    return q[-1], qd[-1], float(res.t[-1])


def _cmd_modes(args: argparse.Namespace) -> int:
    """Natural modes at the initial state, or at time T of the run (--at T): every motion of
    the linearised model, labelled rigid (nothing holds it), drift (grows or decays without
    oscillating) or vibration (pymr.modes' rule)."""
    import csv
    import io
    import math
    from .api import Model, initial_state, modes, marker_shapes
    from .outputs import check_output
    over = list(args.set or [])
    at = 0.0 if args.at is None else args.at
    if not (0.0 <= at < math.inf):
        raise SceneError(f"--at {at:g}: a time at or after the start of the run (s)")
    if args.output is not None:
        check_output(args.output, "modes file", example="modes.csv", scene=args.scene, overrides=over,
                     if_left_out="no file")
    if at > 0:
        q, qd, t = _state_at(args.scene, over, at)
    else:
        (q, qd), t = initial_state(args.scene, over), 0.0      # the initial state, without a run
    with Model(args.scene, over) as model:
        names, markers = model.coordinate_names(), model.marker_names()
    found = modes(args.scene, q, qd, t=t, overrides=over)
    shapes = found.all_shapes
    moves = marker_shapes(args.scene, markers, q, qd, shapes, t=t, overrides=over)
    counts = {kind: found.kind.count(kind) for kind in ("vibration", "rigid", "drift")}
    print(f"natural modes of {args.scene} linearised at t = {t:g} s ({counts['vibration']} vibrations, "
          f"{counts['rigid']} rigid-body motions, {counts['drift']} drifts)")
    print(f"{'mode':>4} {'kind':<9} {'frequency Hz':>13} {'damping ratio':>13} {'rate 1/s':>11}  "
          "largest motion (shapes scaled to 1 there)" + ("; marker displacement (m)" if moves else ""))
    for i, kind in enumerate(found.kind):
        f, z, r = found.all_frequency[i], found.all_damping[i], found.all_rate[i]
        big = int(np.argmax(np.abs(shapes[:, i])))
        cells = {"vibration": (f"{f:>13.5g}", f"{z:>13.4g}", f"{'':>11}"),
                 "drift": (f"{'-':>13}", f"{'-':>13}", f"{r:>11.4g}"),
                 "rigid": (f"{'-':>13}", f"{'-':>13}", f"{'-':>11}")}[kind]
        line = f"{i + 1:>4} {kind:<9} {' '.join(cells)}  {names[big] if big < len(names) else big}"
        if moves:
            line += "; " + ", ".join(f"{m} {np.linalg.norm(d[:, i]):.4g}" for m, d in moves.items())
        print(line)
    if args.output is not None:
        mcols = [f"{m}.d{c}" for m in moves for c in "xyz"]
        fh = io.StringIO(newline="")
        w = csv.writer(fh)
        w.writerow(["mode", "kind", "frequency_hz", "damping_ratio", "rate_per_s", *names, *mcols])
        for i, kind in enumerate(found.kind):
            w.writerow([i + 1, kind, repr(float(found.all_frequency[i])), repr(float(found.all_damping[i])),
                        repr(float(found.all_rate[i])), *[repr(float(v)) for v in shapes[:, i]],
                        *[repr(float(v)) for d in moves.values() for v in d[:, i]]])
        write_file(args.output, fh.getvalue(), "modes")
        print(f"written: {args.output}")
    return 0


def _cmd_study(args: argparse.Namespace) -> int:
    from . import study
    return study.main(args.scene, marker=args.marker, output=args.output, quick=args.quick, repeats=args.repeats)


def _cmd_animate(args: argparse.Namespace) -> int:
    from . import animate
    return animate.main(args.csv, output=args.output, scene=args.scene, view=args.view, exaggerate=args.exaggerate,
                        fps=args.fps, frames=args.frames, orbit=args.orbit, at=args.at)


def _cmd_export(args: argparse.Namespace) -> int:
    from . import export
    return export.main(args.csv, args.vtk, scene=args.scene, every=args.every, frames=args.frames,
                       exaggerate=args.exaggerate)


def _option_names(option: str, names: list[str] | None) -> list[str] | None:
    """The names given to `option` (--column, --marker, --joint), each checked by the rule
    for a name the functions apply (pymr._args._name), so that a fault names the option
    typed, not the function's argument ('--column: an empty name', not 'columns[0]: ...')."""
    from ._args import _name
    for name in names or ():
        _name(option, name)
    return names


def _cmd_view(args: argparse.Namespace) -> int:
    from . import view
    return view.main(args.csv, output=args.output, scene=args.scene, columns=_option_names("--column", args.column),
                     every=args.every, frames=args.frames, exaggerate=args.exaggerate)


def _cmd_plot(args: argparse.Namespace) -> int:
    from . import plot
    return plot.main(args.csv, output=args.output, markers=_option_names("--marker", args.marker),
                     joints=_option_names("--joint", args.joint), labels=args.labels, title=args.title,
                     quiet=args.quiet, columns=_option_names("--column", args.column))


def _cmd_sweep(args: argparse.Namespace) -> int:
    from . import sweep
    return sweep.main(args.sweep, scheduler=args.scheduler, workers=args.workers, emit=args.emit_slurm,
                      collect_from=args.collect)


class _Once(argparse.Action):
    """An option of one value, refused when given twice (argparse kept the last: `-o a.csv -o
    b.csv` wrote b.csv with no word, as mrsim now refuses too)."""

    def __call__(self, parser, namespace, values, option_string=None):
        given = f"_given_{self.dest}"        # by a mark, not by the value (a default's equal may be given)
        if getattr(namespace, given, False):
            parser.error(f"{option_string}: given twice ({getattr(namespace, self.dest)} before)")
        setattr(namespace, given, True)
        setattr(namespace, self.dest, values)


class _Parser(argparse.ArgumentParser):
    """argparse with pymr's one-line errors: 'pymr: error: run: MESSAGE', exit status 1 (argparse
    prints its usage block first, several lines, and exits 2, the status of a failed run). An
    option that is not repeatable (not 'append' or 'extend') is refused when given twice (_Once)."""

    def add_argument(self, *args, **kwargs):
        if args and args[0].startswith("-") and kwargs.get("action", "store") == "store":
            kwargs["action"] = _Once          # also one of several values (--labels A B): given again, the first went
        return super().add_argument(*args, **kwargs)

    def error(self, message: str):
        command = self.prog.removeprefix("pymr").strip()
        print(f"pymr: error: {command + ': ' if command else ''}{message} "
              f"(pymr {command + ' ' if command else ''}--help)", file=sys.stderr)
        raise SystemExit(1)


def _count_of(what: str, least: int = 1, most: int | None = None):
    """An argparse type: a whole number, at least `least` (and at most `most`), of `what`."""
    def convert(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            value = least - 1
        if value < least:
            raise argparse.ArgumentTypeError(f"{text!r}: a whole number of {what}, at least {least}")
        if most is not None and value > most:
            raise argparse.ArgumentTypeError(f"{text!r}: a whole number of {what}, at most {most}")
        return value
    return convert


def _seconds(text: str) -> float:
    """An argparse type: a time (s), a number."""
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r}: a time in seconds") from None


def build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="pymr", description="Flexible multibody dynamics with multirate "
                                "Nordsieck Adams integration.")
    from . import __version__
    p.add_argument("--version", action="version", version=f"pymr {__version__}")
    sub = p.add_subparsers(dest="command", required=True)
    _add_run(sub)
    _add_scene(sub)
    _add_modal_file(sub)
    _add_modal_import(sub)
    _add_bench(sub)
    _add_modes(sub)
    _add_animate(sub)
    _add_export(sub)
    _add_study(sub)
    _add_sweep(sub)
    _add_plot(sub)
    _add_view(sub)
    return p


def _add_run(sub) -> None:
    """The `pymr run` subcommand and its options."""
    r = sub.add_parser("run", help="run a scene (namelist file) and write OUT.csv and OUT.json")
    r.add_argument("scene", help="scene namelist file")
    r.add_argument("-o", "--output", help="results file: OUT.csv, or OUT.h5 with &output format = 'hdf5' "
                   "(default: &output file, else SCENE.csv or SCENE.h5)")
    r.add_argument("--set", action="append", metavar="GROUP.ITEM=VALUE",
                   help="override a namelist value for this run, e.g. integrator.h_slow=5e-4 or "
                        "body[turret].mass=1000 (repeatable)")
    r.add_argument("--restart", metavar="CKPT", help="continue a run from its checkpoint file (written with "
                   "&output checkpoint_dt); the results file keeps the rows up to the checkpoint")
    r.add_argument("--progress", action=argparse.BooleanOptionalAction, default=None,
                   help="progress bar (simulated time, percent, ETA) on stderr; default: when stderr is a terminal")
    r.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    r.set_defaults(func=_cmd_run)


def _add_scene(sub) -> None:
    """The `pymr scene` subcommand and its options."""
    sc = sub.add_parser("scene", help="print the resolved scene (every default filled in, every --set applied, "
                        "checked) and its fingerprint; --schema: every group and item")
    sc.add_argument("scene", nargs="?", help="scene namelist file")
    sc.add_argument("--set", action="append", metavar="GROUP.ITEM=VALUE", help="override (repeatable)")
    sc.add_argument("--schema", action="store_true", help="print the groups and items: name, type(count), default, "
                    "range or choices, unit, meaning (tab-separated)")
    sc.add_argument("--absolute-paths", action="store_true",
                    help="write the files the scene names (modal_file, file) as absolute paths")
    sc.set_defaults(func=_cmd_scene)


def _add_modal_file(sub) -> None:
    """The `pymr modal-file` subcommand and its options."""
    m = sub.add_parser("modal-file", help="write a beam's modes to a modal data file (for kind='modal')")
    m.add_argument("scene", help="scene namelist file")
    m.add_argument("body", help="name of a kind='beam' body")
    m.add_argument("-o", "--output", required=True, help="modal data file to write")
    m.add_argument("--set", action="append", metavar="GROUP.ITEM=VALUE", help="namelist override (repeatable)")
    m.add_argument("-q", "--quiet", action="store_true")
    m.set_defaults(func=_cmd_modal_file)


def _add_modal_import(sub) -> None:
    """The `pymr modal-import` subcommand and its options."""
    mi = sub.add_parser("modal-import", help="a kind='modal' body from finite-element mass and stiffness matrices "
                        "(Craig-Bampton reduction)")
    mi.add_argument("--mass", required=True, help="mass matrix: Matrix Market, Abaqus matrix output (.mtx), Nastran "
                    "DMIG in bulk data or punch files (.bdf .dat .pch .nas .blk .bulk), OP4 (.op4) or an Ansys full "
                    "file (.full)")
    mi.add_argument("--stiffness", required=True, help="stiffness matrix (the same formats)")
    mi.add_argument("--mass-name", help="the mass matrix's name in a Nastran file holding several (DMIG, OP4)")
    mi.add_argument("--stiffness-name", help="the stiffness matrix's name in a Nastran file holding several")
    mi.add_argument("--nodes", required=True, help="node coordinates: lines 'id, x, y, z', an Abaqus input deck "
                    "(.inp, its *NODE blocks), Nastran bulk data (GRID cards) or an Ansys archive or result file "
                    "(.cdb, .rst)")
    lay = mi.add_mutually_exclusive_group()
    lay.add_argument("--dofs-per-node", type=int, choices=[3, 6], default=None,
                     help="rows node by node in the nodes file's order: 3 (u_x u_y u_z) or 6 (and theta_x theta_y "
                          "theta_z) (default 6)")
    lay.add_argument("--dof-map", help="file of lines 'row node dof' (dof 1-6: u_x u_y u_z theta_x theta_y theta_z)")
    mi.add_argument("--interface", required=True, nargs="+", type=int, metavar="NODE",
                    help="interface node ids (joints, markers, loads); the first is the body frame's origin, where "
                         "the body is clamped to its joint")
    mi.add_argument("--clamp", nargs="+", type=int, metavar="NODE",
                    help="more nodes clamped with the origin (a mesh whose nodes carry no rotations needs them)")
    mi.add_argument("--modes", default="10", help="fixed-interface modes in the reduction, or 'all' (default 10)")
    mi.add_argument("--keep", type=int, help="write only the lowest KEEP modes of the reduced body (default: all)")
    mi.add_argument("--memory-limit", type=float, metavar="GB",
                    help="refuse, before any numeric work, a model whose reduction needs more (default: the memory "
                         "available, within a batch job's cgroup limit)")
    mi.add_argument("-o", "--output", required=True, help="modal data file to write (format 2)")
    mi.add_argument("-q", "--quiet", action="store_true")
    mi.set_defaults(func=_cmd_modal_import)


def _add_bench(sub) -> None:
    """The `pymr bench` subcommand and its options."""
    b = sub.add_parser("bench", help="benchmarks that print figures")
    b.add_argument("what", choices=["rhs", "chain", "lapack", "table1", "effects", "spacecraft", "output",
                                    "modal-import", "auto"],
                   help="rhs: cost of one model evaluation vs chain length; chain: the serial chain of N "
                        "rods, N = 5 to 200, by both forward-dynamics paths and (when installed) Pinocchio; lapack: the "
                        "work pymr hands LAPACK, timed with the LAPACK loaded; "
                        "table1: the paper's Table 1 (tank, step ratios 1-50, both couplings); effects: cost "
                        "of one tank evaluation with each effect on and off; spacecraft: the flexible spacecraft, "
                        "single-rate against multirate; output: what writing a row at every step costs, as CSV "
                        "and as HDF5; modal-import: Craig-Bampton reduction of 3-D frames and solid blocks of 10k, "
                        "100k and 300k DOFs (time, peak memory, frequencies; a dense reduction beside it at 3k); "
                        "auto: method 'auto' against each candidate run directly on every shipped scene")
    b.add_argument("--pinocchio-cpp", metavar="EXE",
                   help="chain: also time Pinocchio compiled, by this build of docs/pinocchio_chain.cpp")
    b.add_argument("--repeats", type=_count_of("repeats", most=MAX_REPEATS), default=None,
                   help="timing repeats, median reported (default 7 for rhs, chain and effects, 5 for lapack, "
                        "spacecraft, output and auto, 21 for table1, which takes at least 5)")
    b.add_argument("--json", help="also write the figures to this JSON file")
    b.add_argument("--sizes", type=int, nargs="+", metavar="DOFS",
                   help="modal-import: the models' DOF counts (default 10000 100000 300000)")
    b.set_defaults(func=_cmd_bench)


def _add_modes(sub) -> None:
    """The `pymr modes` subcommand and its options."""
    md = sub.add_parser("modes", help="natural frequencies, damping ratios and mode shapes of the model "
                        "linearised at the initial state (or at time T of the run); rigid-body motions and drifts "
                        "labelled as such")
    md.add_argument("scene", help="scene namelist file")
    md.add_argument("--at", metavar="T", type=_seconds, help="linearise at time T of the run (s) instead of at the initial state")
    md.add_argument("--set", action="append", metavar="GROUP.ITEM=VALUE", help="override (repeatable)")
    md.add_argument("-o", "--output", help="write the modes to this CSV file (mode, kind, frequency, damping, rate, "
                    "shape)")
    md.set_defaults(func=_cmd_modes)


def _add_animate(sub) -> None:
    """The `pymr animate` subcommand and its options."""
    from .animate import LEAST_FRAMES
    an = sub.add_parser("animate", help="3-D animation of the moving mechanism from a run's results (GIF, video, "
                        "or a .png still)")
    an.add_argument("csv", help="results CSV (its JSON beside it names the scene)")
    an.add_argument("-o", "--output", help="the animation file (default: the CSV's name with .gif; .png: a still)")
    an.add_argument("--scene", help="the scene of the run, when the results' JSON does not name it or the run had "
                    "--set overrides (give the resolved scene)")
    an.add_argument("--view", default="iso", help="iso (default), front, side, top, ELEV,AZIM in degrees (such as "
                    "30,-60), or the plane xy, xz or zy seen face-on (first axis across)")
    an.add_argument("--orbit", action="store_true", help="turn the camera once round the vertical axis over the run")
    an.add_argument("--exaggerate", type=float, default=None, help="scale of the deflections drawn (default: the "
                    "largest shows as 5%% of the mechanism's size, at least 1)")
    an.add_argument("--at", type=_seconds, default=None, help="a .png still's time (s, within the results; default: the last frame)")
    an.add_argument("--fps", type=_count_of("frames per second"), default=25, help="frames per second")
    an.add_argument("--frames", type=_count_of("frames", LEAST_FRAMES), default=200,
                    help=f"most frames (evenly spaced output rows; at least {LEAST_FRAMES})")
    an.set_defaults(func=_cmd_animate)


def _add_export(sub) -> None:
    """The `pymr export` subcommand and its options."""
    ex = sub.add_parser("export", help="the moving mechanism as a ParaView collection (.pvd of .vtu files)")
    ex.add_argument("csv", help="results CSV (its JSON beside it names the scene)")
    ex.add_argument("--vtk", required=True, metavar="DIR", help="folder of the collection: DIR/OUT.pvd and one "
                    ".vtu per output time (new, empty, or an earlier export, which is replaced)")
    ex.add_argument("--scene", help="the scene of the run, when the results' JSON does not name it or the run had "
                    "--set overrides (give the resolved scene)")
    ex.add_argument("--every", type=_count_of("output rows"), default=1, help="every K-th output row (default 1)")
    ex.add_argument("--frames", type=_count_of("frames"), default=None, help="at most N output times, evenly "
                    "spaced (default: all)")
    ex.add_argument("--exaggerate", type=float, default=1.0, help="scale of the deflections drawn (default 1)")
    ex.set_defaults(func=_cmd_export)


def _add_study(sub) -> None:
    """The `pymr study` subcommand and its options."""
    s = sub.add_parser("study", help="work-precision study: error against CPU time and evaluations for every "
                       "method (fixed, multirate, adaptive, scipy DOP853/LSODA, CVODE)")
    s.add_argument("scene", help="scene namelist file (with at least one &marker)")
    s.add_argument("--marker", help="marker whose position error is measured (default: the first by name)")
    s.add_argument("-o", "--output", help="prefix of the files written: PREFIX.csv, PREFIX.png, PREFIX_history.csv "
                   "(default: SCENE_study)")
    s.add_argument("--quick", action="store_true", help="fewer steps and tolerances (a smoke run)")
    s.add_argument("--repeats", type=_count_of("runs per case", most=MAX_REPEATS), default=5, help="runs per case; the CPU time is their median (default 5)")
    s.set_defaults(func=_cmd_study)


def _add_sweep(sub) -> None:
    """The `pymr sweep` subcommand and its options."""
    w = sub.add_parser("sweep", help="run a parameter sweep (SWEEP.toml) on Dask, or emit SLURM job-array files")
    w.add_argument("sweep", help="sweep file (TOML: scene, output, metric, [grid], [fixed], [reference]); its "
                   "output folder is relative to the working folder (default: the sweep file's stem)")
    w.add_argument("--scheduler", metavar="ADDRESS", help="an existing Dask scheduler (e.g. from dask-jobqueue on "
                   "SLURM or PBS); default: a LocalCluster on this machine")
    w.add_argument("--workers", type=_count_of("workers", most=MAX_WORKERS), default=2, help="LocalCluster worker processes (default 2)")
    w.add_argument("--emit-slurm", metavar="DIR", help="write the case namelists (and the deviation metric's "
                   "reference runs') and a SLURM job-array script running mrsim per namelist to DIR instead of running")
    w.add_argument("--collect", metavar="DIR", help="after the SLURM job array ran: the summary (DIR/summary.csv) "
                   "of the cases' results in DIR")
    w.set_defaults(func=_cmd_sweep)


def _add_plot(sub) -> None:
    """The `pymr plot` subcommand and its options."""
    pl = sub.add_parser("plot", help="plot result files, overlaid (the tank: muzzle position, velocity and "
                        "modal coordinates, the paper's Figs. 5-7; other scenes: markers and joints)")
    pl.add_argument("csv", nargs="+", help="result files (OUT.csv, with OUT.json beside it: its column metadata "
                    "names the markers, joints and bodies)")
    pl.add_argument("-o", "--output", help="figure to write (default: the first CSV's stem + .png, here)")
    pl.add_argument("--marker", action="append", metavar="NAME",
                    help="plot this marker's position and velocity (repeatable; default: the tank's "
                         "muzzle, else every marker)")
    pl.add_argument("--joint", action="extend", nargs="+", metavar="NAME",
                    help="plot these joints' coordinates (default: none for the tank, else every joint)")
    pl.add_argument("--column", action="extend", nargs="+", metavar="PATTERN",
                    help="plot these columns instead: names or shell-style patterns, quoted "
                         "('energy.*', 'elevation.fz'); columns of one unit share a panel")
    pl.add_argument("--labels", nargs="+", metavar="LABEL",
                    help="legend labels, one per CSV (default: each run's method, else the file's stem)")
    pl.add_argument("--title", help="figure title (default: the first run's scene title)")
    pl.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")
    pl.set_defaults(func=_cmd_plot)


def _add_view(sub) -> None:
    """The `pymr view` subcommand and its options."""
    v = sub.add_parser("view", help="one HTML page of a run, offline: the mechanism in 3-D with a time slider and "
                       "play/pause, and chosen columns against time")
    v.add_argument("csv", help="results file (its JSON beside it holds the scene and the columns' units)")
    v.add_argument("-o", "--output", help="the page (.html; default: the results' name with .html)")
    v.add_argument("--scene", help="the scene of the run, when the results' JSON does not hold it")
    v.add_argument("--column", action="extend", nargs="+", metavar="NAME",
                   help="columns to plot beside the mechanism: names or patterns such as 'energy.*' (default: the "
                        "first marker's position, else the first joint's coordinates)")
    v.add_argument("--every", type=_count_of("rows"), default=1, help="take every K-th output row (default 1)")
    v.add_argument("--frames", type=_count_of("frames"), default=100,
                   help="most frames of the 3-D view, evenly spread (default 100)")
    v.add_argument("--exaggerate", type=float, default=1.0, help="scale of the deflections (default 1)")
    v.set_defaults(func=_cmd_view)


class _ClosedOutput:
    """The standard output of a process started with it closed (``>&-``: sys.stdout is None):
    a write fails as a closed file does (``mrsim`` too), so a summary printed there is an
    error (exit 1), not lost with exit 0; ``-q`` writes nothing and succeeds."""

    def write(self, text: str) -> int:
        raise OSError(errno.EBADF, os.strerror(errno.EBADF))

    def flush(self) -> None:
        pass


class _Terminated(Exception):
    """SIGTERM, raised in the main thread as Ctrl-C raises KeyboardInterrupt."""


def _on_sigterm(signum, frame):
    raise _Terminated


def main(argv: list[str] | None = None) -> int:
    if sys.stdout is None:
        sys.stdout = _ClosedOutput()
    try:
        args = build_parser().parse_args(argv)
    except SystemExit as exc:          # argparse: a bad command line is bad input, status 1
        return 0 if exc.code in (0, None) else 1
    import signal
    try:                               # SIGTERM ended the process with no line (a run's kernel
        before = signal.signal(signal.SIGTERM, _on_sigterm)    # catches it itself: the run stops)
    except ValueError:                 # not the main thread: left as it is
        before = None
    try:
        status = args.func(args)
        sys.stdout.flush()             # a full disk under the output is seen here, not at exit
        return status
    except (KeyboardInterrupt, _Terminated) as exc:   # a traceback of 9-74 lines: one line, a failure
        name = "SIGINT" if isinstance(exc, KeyboardInterrupt) else "SIGTERM"
        print(f"pymr: error: stopped by {name} (a file it was writing is not in place; an earlier one is kept)",
              file=sys.stderr)
        return 2
    except BrokenPipeError:            # the reader of the output went away (`| head`): stop quietly,
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())   # nor fail flushing at exit,
        return 1                       # and not as a success: the command did not finish its work
    except OSError as exc:             # the standard output refused (a full disk); or a file pymr
        if exc.filename is None and not isinstance(sys.stdout, _ClosedOutput):   # reads or writes without
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())       # naming the fault in its words
        where = exc.filename if exc.filename is not None else "the standard output"
        print(f"pymr: error: {where}: {exc.strerror or exc}", file=sys.stderr)
        return 1
    except PymrError as exc:
        for line in str(exc).splitlines() or [""]:
            print(f"pymr: error: {line}", file=sys.stderr)
        return 2 if isinstance(exc, SolverError) else 1      # a failed run, else bad input
    finally:
        if before is not None:
            signal.signal(signal.SIGTERM, before)


if __name__ == "__main__":
    raise SystemExit(main())
