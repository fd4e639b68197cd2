"""Benchmarks that print figures (``pymr bench ...``). Medians of repeated timings in one
process; ratios are formed within the same run. Tests never assert wall time."""
from __future__ import annotations

import json
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from . import _kernel as _core
from .api import SceneError, _raise, format_overrides, model_size, write_file
from ._args import _text, model_of
from ._timing import shuffled
from .scenes import ROD_LENGTH, ROD_MASS, ROD_RADIUS, serial_chain, spatial_chain


def _median_seconds(per_call, repeats: int, min_time: float = 0.05) -> float:
    """Median over `repeats` of per_call(reps), the seconds of one call timed over reps calls,
    reps grown until a timing lasts min_time."""
    reps = 1
    while per_call(reps) * reps < min_time and reps < 1 << 20:
        reps *= 4
    return statistics.median(per_call(reps) for _ in range(repeats))


def time_evaluation(scene: str, q: np.ndarray, qd: np.ndarray, repeats: int = 7,
                    min_time: float = 0.05, overrides: str = "") -> float:
    """Median CPU seconds of one model evaluation (kinematics, body terms, loads, and the
    solve of M qdd = P by the scene's forward-dynamics path)."""
    with model_of(scene, (scene, overrides)) as handle:
        def per_call(reps: int) -> float:
            sec, stat, msg, detail = _core.pymr_time_evaluation(handle, q, qd, reps)
            _raise(stat, msg, detail)
            return sec
        return _median_seconds(per_call, repeats, min_time)


def _chains(scene_text, sizes):
    """(size, scene path, q, qd) per size: the scene scene_text(size) in a temporary folder
    and a random state (0.3 rad or m, 0.3 per s; the same sequence in every run)."""
    rng = np.random.default_rng(0)
    with tempfile.TemporaryDirectory(prefix="pymr-bench-") as tmp:
        for size in sizes:
            path = Path(tmp) / f"chain{size}.nml"
            path.write_text(scene_text(size))
            n, _, _ = model_size(path)
            yield size, path, 0.3 * rng.standard_normal(n), 0.3 * rng.standard_normal(n)


def bench_rhs(sizes=(5, 20, 100), repeats: int = 7) -> list[dict]:
    """Cost of one evaluation of the spatial chain (free base) for several lengths."""
    rows = []
    for nb, path, q, qd in _chains(spatial_chain, sizes):
        n = len(q)
        sec = time_evaluation(str(path), q, qd, repeats=repeats)
        rows.append({"scene": f"chain-{nb}", "bodies": nb, "coordinates": n, "median_us": sec * 1e6})
    return rows


#: The shipped scenes: installed with the package (pymr/input), or the checkout's input/.
INPUT_FOLDERS = (Path(__file__).resolve().parent / "input", Path(__file__).resolve().parent.parent / "input")


def _scene_path(name: str) -> Path:
    """A scene shipped with pymr (installed beside the package, or in the checkout)."""
    for base in INPUT_FOLDERS:
        if (base / name).exists():
            return base / name
    from .api import SceneError
    raise SceneError(f"input/{name} not found: this installation of pymr has no shipped scenes (reinstall it)")


def bench_scenes(repeats: int = 7) -> list[dict]:
    """Cost of one evaluation of the shipped flexible scenes at their initial state."""
    rows = []
    for name in ("tank_gun_turret.nml", "flexible_chain.nml"):
        path = _scene_path(name)
        n, nb, _ = model_size(path)
        res_q = np.zeros(n)
        sec = time_evaluation(str(path), res_q, res_q, repeats=repeats)
        rows.append({"scene": name.removesuffix(".nml"), "bodies": nb - 1, "coordinates": n, "median_us": sec * 1e6})
    return rows


def bench_tank_run(repeats: int = 3) -> dict:
    """CPU time of the tank's 1 s single-rate run (h = 1e-4 s), median of repeats."""
    from .api import run
    cpu = []
    with tempfile.TemporaryDirectory(prefix="pymr-bench-") as tmp:
        for _ in range(repeats):
            res = run(_scene_path("tank_gun_turret.nml"), Path(tmp) / "tank.csv")
            cpu.append(res.stats["cpu_time_s"])
    return {"scene": "tank_gun_turret", "median_cpu_s": statistics.median(cpu), "steps": res.stats["steps_slow"],
            "rhs_full": res.stats["rhs_full"]}


CHAIN_LINKS = (5, 10, 20, 30, 50, 100, 200)


def pinocchio_chain(links: int):
    """Pinocchio's model of ``scenes.serial_chain(links)`` (needs the optional package ``pin``)."""
    import pinocchio as pin
    model = pin.Model()
    parent = 0
    i_axial, i_cross = 0.5 * ROD_MASS * ROD_RADIUS ** 2, ROD_MASS * ROD_LENGTH ** 2 / 12.0
    for i in range(links):
        placement = pin.SE3(np.eye(3), np.array([0.0 if i == 0 else ROD_LENGTH, 0.0, 0.0]))
        joint = pin.JointModelRZ() if i % 2 == 0 else pin.JointModelRX()
        jid = model.addJoint(parent, joint, placement, "j%d" % (i + 1))
        model.appendBodyToJoint(jid, pin.Inertia(ROD_MASS, np.array([ROD_LENGTH / 2, 0.0, 0.0]),
                                                 np.diag([i_axial, i_cross, i_cross])), pin.SE3.Identity())
        parent = jid
    model.gravity = pin.Motion(np.array([0.0, -9.81, 0.0]), np.zeros(3))
    return model


def _median_cpu(f, repeats: int, min_time: float = 0.05) -> float:
    """Median CPU seconds of one call of f()."""
    def per_call(reps: int) -> float:
        c0 = time.process_time()
        for _ in range(reps):
            f()
        return (time.process_time() - c0) / reps
    return _median_seconds(per_call, repeats, min_time)


def _pinocchio_python(links: int, q: np.ndarray, qd: np.ndarray, repeats: int) -> tuple[float, float, np.ndarray]:
    """Pinocchio through its Python binding: ABA and CRBA + Cholesky (us per call, a Python
    call's overhead included), and ABA's accelerations."""
    import pinocchio as pin
    model = pinocchio_chain(links)
    data = model.createData()
    tau = np.zeros(links)

    def crba_cholesky():
        pin.crba(model, data, q)
        pin.nonLinearEffects(model, data, q, qd)
        pin.cholesky.decompose(model, data)
        pin.cholesky.solve(model, data, -data.nle)
    aba = _median_cpu(lambda: pin.aba(model, data, q, qd, tau), repeats) * 1e6
    crba = _median_cpu(crba_cholesky, repeats) * 1e6
    return aba, crba, pin.aba(model, data, q, qd, tau).copy()


def _pinocchio_compiled(exe: str, q: np.ndarray, qd: np.ndarray) -> tuple[float, float]:
    """Pinocchio compiled (docs/pinocchio_chain.cpp): ABA and CRBA + Cholesky, us."""
    import subprocess
    text = "%d\n%s\n%s\n" % (len(q), " ".join("%.17g" % x for x in q), " ".join("%.17g" % x for x in qd))
    try:
        out = subprocess.run([exe], input=text, capture_output=True, text=True, check=True).stdout.split("\n")
        aba, crba = (float(x) for x in out[1].split())
    except OSError as exc:
        raise SceneError(f"--pinocchio-cpp {exe}: cannot run it ({exc.strerror or exc})") from None
    except (subprocess.CalledProcessError, ValueError, IndexError):
        raise SceneError(f"--pinocchio-cpp {exe}: it did not print the two timings of a build of "
                         "docs/pinocchio_chain.cpp") from None
    return aba, crba


def bench_chain(links=CHAIN_LINKS, repeats: int = 7, pinocchio_cpp: str | None = None) -> list[dict]:
    """One evaluation of the serial chain per length: pymr by each forward-dynamics path,
    Pinocchio (Python binding, and compiled when given) at the same random state."""
    try:
        import pinocchio  # noqa: F401
        have_pin = True
    except ImportError:
        have_pin = False
    rows = []
    for n, path, q, qd in _chains(serial_chain, links):
        row = {"links": n}
        for dyn in ("articulated", "mass_matrix"):
            row[dyn] = time_evaluation(str(path), q, qd, repeats, overrides=f"integrator.dynamics='{dyn}'") * 1e6
        if have_pin:
            from .api import Model
            row["pin_aba_py"], row["pin_crba_py"], ref = _pinocchio_python(n, q, qd, repeats)
            with Model(path, {"integrator.dynamics": "articulated"}) as model:
                ours = model.rhs(0.0, np.concatenate([q, qd]))[n:]
            row["pin_difference"] = float(np.abs(ours - ref).max() / np.abs(ref).max())
        if pinocchio_cpp:
            row["pin_aba"], row["pin_crba"] = _pinocchio_compiled(pinocchio_cpp, q, qd)
        rows.append(row)
    return rows


def print_chain(rows: list[dict]) -> None:
    print("pymr bench chain: one evaluation of a serial chain of N rods (revolute axes alternating z and x, "
          "hanging), median us of CPU")
    head = f"{'N':>5} {'articulated':>12} {'growth':>7} {'mass_matrix':>12}"
    pin_py = "pin_aba_py" in rows[0]
    pin_c = "pin_aba" in rows[0]
    if pin_c:
        head += f" {'pin ABA':>8} {'pin CRBA+chol':>13} {'art/ABA':>8} {'art/CRBA':>9}"
    if pin_py:
        head += f" {'pin ABA (py)':>12} {'CRBA+chol (py)':>14} {'|dqdd|/|qdd|':>12}"
    print(head)
    prev = None
    for r in rows:
        growth = ""
        if prev is not None:
            growth = "N^%.2f" % (np.log(r["articulated"] / prev["articulated"]) / np.log(r["links"] / prev["links"]))
        line = f"{r['links']:>5} {r['articulated']:>12.2f} {growth:>7} {r['mass_matrix']:>12.2f}"
        if pin_c:
            line += (f" {r['pin_aba']:>8.2f} {r['pin_crba']:>13.2f} {r['articulated'] / r['pin_aba']:>8.2f} "
                     f"{r['articulated'] / r['pin_crba']:>9.2f}")
        if pin_py:
            line += f" {r['pin_aba_py']:>12.2f} {r['pin_crba_py']:>14.2f} {r['pin_difference']:>12.1e}"
        print(line)
        prev = r
    if not pin_py:
        print("(Pinocchio columns need the optional package pin: pip install pin)")


def loaded_lapack() -> str:
    """The LAPACK library this process has loaded (its path), from /proc/self/maps."""
    try:
        paths = {line.split()[-1] for line in open("/proc/self/maps") if "lapack" in line or "openblas" in line}
    except OSError:
        return "unknown"
    return ", ".join(sorted(p for p in paths if "/" in p and "scipy" not in p and "numpy" not in p)) or "unknown"


def bench_lapack(repeats: int = 5) -> list[dict]:
    """The work pymr hands LAPACK (dpotrf/dpotrs above order 16, dgeev, dsygvd), timed with the
    LAPACK this process loaded: the pre-flight check of 1 s chain runs (2n x 2n eigenvalues),
    the spacecraft's evaluation through its 50 x 50 mass matrix, a 100-link chain's through
    M, and the spacecraft's natural modes."""
    from .api import modes, run
    rows = []
    with tempfile.TemporaryDirectory(prefix="pymr-bench-") as tmp:
        for n in (50, 100, 200):
            path = Path(tmp) / f"chain{n}.nml"
            path.write_text(serial_chain(n, t_end=0.01))
            ms = statistics.median(run(path, Path(tmp) / "c.csv").stats["preflight_cpu_s"] for _ in range(repeats))
            rows.append({"work": f"pre-flight check, chain of {n} (dgeev {2 * n} x {2 * n})", "ms": ms * 1e3})
        sc = _scene_path("spacecraft.nml")
        z = np.zeros(50)
        rows.append({"work": "spacecraft evaluation through M (dpotrf 50 x 50)",
                     "ms": time_evaluation(str(sc), z, z, repeats, overrides="integrator.dynamics='mass_matrix'") * 1e3})
        path = Path(tmp) / "chain100.nml"
        path.write_text(serial_chain(100))
        rng = np.random.default_rng(0)
        q, qd = 0.3 * rng.standard_normal(100), 0.3 * rng.standard_normal(100)
        rows.append({"work": "chain of 100 through M (dpotrf 100 x 100)",
                     "ms": time_evaluation(str(path), q, qd, repeats, overrides="integrator.dynamics='mass_matrix'") * 1e3})
        rows.append({"work": "spacecraft natural modes (dgeev 100 x 100)", "ms": _median_cpu(lambda: modes(sc, z, z),
                                                                                            repeats) * 1e3})
    return rows


def main(what: str, repeats: int | None = None, json_path: str | None = None,
         pinocchio_cpp: str | None = None, sizes: list[int] | None = None) -> int:
    if repeats is not None and (isinstance(repeats, bool) or not isinstance(repeats, int) or repeats < 1):
        raise SceneError(f"repeats: a whole number of timings, at least 1, got {repeats!r}")
    if sizes is not None and what != "modal-import":
        raise SceneError("--sizes: only pymr bench modal-import takes it (the DOF counts of its models)")
    if sizes is not None and not all(isinstance(n, int) and 100 <= n <= 10_000_000 for n in sizes):
        raise SceneError(f"--sizes {' '.join(map(str, sizes))}: DOF counts from 100 to 10000000")
    if what == "lapack":
        rows = bench_lapack(repeats=repeats or 5)
        print(f"pymr bench lapack: LAPACK work, median ms of CPU, with {loaded_lapack()}")
        for r in rows:
            print(f"{r['work']:>55} {r['ms']:10.4f}")
        if json_path:
            write_file(json_path, json.dumps({"lapack": loaded_lapack(), "rows": rows}, indent=2), "figures")
        return 0
    if what == "chain":
        rows = bench_chain(repeats=repeats or 7, pinocchio_cpp=pinocchio_cpp)
        print_chain(rows)
        if json_path:
            write_file(json_path, json.dumps(rows, indent=2), "figures")
        return 0
    if what == "rhs":
        rows, tank = print_rhs(repeats or 7)
        if json_path:
            write_file(json_path, json.dumps({"evaluations": rows, "tank_run": tank}, indent=2), "figures")
        return 0
    if what == "effects":
        rows = bench_effects(repeats=repeats or 7)
        print("pymr bench effects: one tank evaluation (kinematics, assembly, Cholesky solve), "
              f"median CPU of {repeats or 7} timings; each effect alone, then all")
        print(f"{'effect':>22} {'median us':>10} {'extra us':>9}")
        for r in rows:
            print(f"{r['effect']:>22} {r['median_us']:>10.3f} {r['extra_us']:>+9.3f}")
        if json_path:
            write_file(json_path, json.dumps(rows, indent=2), "figures")
        return 0
    if what == "spacecraft":
        rows = bench_spacecraft(repeats=repeats or 5)
        print_spacecraft(rows)
        if json_path:
            write_file(json_path, json.dumps(rows, indent=2), "figures")
        return 0
    if what == "output":
        rows = bench_output(repeats=repeats or 5)
        print_output(rows)
        if json_path:
            write_file(json_path, json.dumps(rows, indent=2), "figures")
        return 0
    if what == "modal-import":
        rows = bench_modal_import(sizes=tuple(sizes) if sizes else MODAL_IMPORT_SIZES)
        print_modal_import(rows)
        if json_path:
            write_file(json_path, json.dumps({"blas": loaded_lapack(), "rows": rows}, indent=2), "figures")
        return 0
    if what == "auto":
        rows = bench_auto(repeats=repeats or 5)
        print_auto(rows, repeats or 5)
        if json_path:
            write_file(json_path, json.dumps(rows, indent=2), "figures")
        return 0
    if what == "table1":
        # runs of 5-30 ms are noisy on a shared machine: 21 interleaved repeats by default
        rows = bench_table1(repeats=max(repeats or 21, 5))
        print_table1(rows)
        path = json_path or "table1.json"
        write_file(path, json.dumps({"paper": PAPER_TABLE1, "cases": rows}, indent=2), "figures")
        print(f"written: {path}")
        return 0
    raise ValueError(what)


def print_rhs(repeats: int) -> tuple[list[dict], dict]:
    """``bench rhs``: one evaluation of the chains and the shipped scenes, and the tank's 1 s
    run, printed; returns their figures."""
    rows = bench_rhs(repeats=repeats) + bench_scenes(repeats=repeats)
    print(f"pymr bench rhs: median CPU time of one model evaluation ({repeats} repeats)")
    print(f"{'scene':>12} {'bodies':>7} {'coords':>7} {'median us':>11} {'us/body':>9} {'growth':>8}")
    prev = None
    for r in rows:
        growth = ""
        if prev is not None and r["scene"].startswith("chain-"):
            # exponent p in cost ~ bodies^p between consecutive sizes
            growth = "n^%.2f" % (np.log(r["median_us"] / prev["median_us"]) / np.log(r["bodies"] / prev["bodies"]))
        print(f"{r['scene']:>12} {r['bodies']:>7} {r['coordinates']:>7} {r['median_us']:>11.2f} "
              f"{r['median_us'] / r['bodies']:>9.3f} {growth:>8}")
        prev = r
    tank = bench_tank_run()
    print(f"tank 1 s single-rate run (h = 1e-4 s, {tank['steps']} steps, {tank['rhs_full']} evaluations): "
          f"median CPU {tank['median_cpu_s']:.3f} s")
    return rows, tank


#: The effects ``bench effects`` times, each turned on alone (``input/tank_effects.nml`` gives
#: every effect's data with every effect off) and all together; deformation_inertia's case is
#: 'full' against the baseline 'linear'.
EFFECTS = ["gravity", "joint_drives", "modal_damping", "joint_springs", "geometric_stiffening", "base_motion",
           "firing_load", "force_elements", "controls", "moving_loads", "deformation_inertia"]


def _effect_on(effect: str) -> dict:
    """The override that turns `effect` on."""
    return {"effects.deformation_inertia": "full"} if effect == "deformation_inertia" else {f"effects.{effect}": True}


def bench_effects(repeats: int = 7) -> list[dict]:
    """Cost of one tank evaluation with no effect, each effect alone, and all together,
    at a moving, deflected state (median CPU of repeated timings)."""
    rng = np.random.default_rng(1)
    rows = []
    scene = str(_scene_path("tank_effects.nml"))
    every = {k: v for e in EFFECTS for k, v in _effect_on(e).items()}
    cases = ([("none", "")] + [(e, format_overrides(_effect_on(e))) for e in EFFECTS]
             + [("all", format_overrides(every))])
    n, _, _ = model_size(scene)
    q = 0.05 * rng.standard_normal(n)
    qd = 0.5 * rng.standard_normal(n)
    q[2:] *= 1e-3
    # the state by coordinate name: a controller adds its own state coordinates (at 0)
    with model_of(scene, (scene, "")) as handle:
        state = {_coordinate_name(handle, k): (q[k], qd[k]) for k in range(n)}
    # interleaved: every repeat times each case once, so that machine drift hits all alike
    samples: dict[str, list] = {name: [] for name, _ in cases}
    reps = 20000
    for r in range(repeats):
        for name, over in shuffled(cases, r):
            with model_of(scene, (scene, over)) as handle:
                qc, qdc = _state_of(handle, state)
                sec, stat, msg, detail = _core.pymr_time_evaluation(handle, qc, qdc, reps)
            _raise(stat, msg, detail)
            samples[name].append(sec)
    for name, _ in cases:
        rows.append({"effect": name, "median_us": statistics.median(samples[name]) * 1e6})
    base = rows[0]["median_us"]
    for r in rows:
        r["extra_us"] = r["median_us"] - base
    return rows


def _coordinate_name(handle: int, k: int) -> str:
    return _text(_core.pymr_model_coordinate_name(handle, k + 1))


def _state_of(handle: int, state: dict) -> tuple[np.ndarray, np.ndarray]:
    """(q, qd) of an open model from values by coordinate name (0 for a coordinate not named)."""
    n, _, _, stat, msg, detail = _core.pymr_model_size(handle)
    _raise(stat, msg, detail)
    pairs = [state.get(_coordinate_name(handle, k), (0.0, 0.0)) for k in range(int(n))]
    return np.array([a for a, _ in pairs]), np.array([b for _, b in pairs])


#: The paper's Table 1 (Kim and Kim 2000): step ratio -> (CPU s on its machine, speed-up).
PAPER_TABLE1 = {1: (251.06, 1.0), 2: (197.34, 1.272), 5: (162.74, 1.546), 10: (148.90, 1.696)}


def bench_table1(ratios=(1, 2, 5, 10, 20, 50), couplings=("full", "response"), repeats: int = 5,
                 h_fast: float = 1e-4) -> list[dict]:
    """The tank's Table 1 cases: CPU time (median of ``repeats``, interleaved so that machine
    drift hits every case alike), speed-up over case 1, evaluation counts, and the muzzle's
    largest deviation over 0-1 s from case 1 (single-rate h_fast, the paper's measure) and
    from a converged reference (single-rate h = 1e-5 s, within 1e-10 m of the converged
    motion: its distance from h = 2e-5 s is 1.6e-9 m at order 4)."""
    from .api import PymrError, run
    scene = _scene_path("tank_gun_turret.nml")
    cases = [("single", 1)] + [(c, k) for k in ratios for c in couplings if k > 1]
    cpu: dict[tuple, list] = {c: [] for c in cases}
    results: dict[tuple, object] = {}
    errors: dict[tuple, str] = {}
    with tempfile.TemporaryDirectory(prefix="pymr-table1-") as tmp:
        converged = run(scene, Path(tmp) / "converged.csv", overrides={
            "integrator.h_fast": 1e-5, "integrator.h_slow": 1e-5, "output.dt": 1e-3})
        for rep in range(repeats):
            for case in cases:
                if case in errors:
                    continue
                coupling, k = case
                over = {"integrator.h_fast": h_fast, "integrator.h_slow": h_fast * k, "output.dt": 1e-3}
                if coupling != "single":
                    over.update({"integrator.method": "multirate", "integrator.coupling": coupling})
                try:
                    res = run(scene, Path(tmp) / f"{coupling}{k}.csv", overrides=over)
                except PymrError as exc:
                    errors[case] = exc
                    continue
                cpu[case].append(res.stats["cpu_time_s"])
                results[case] = res
    base = results[("single", 1)]
    base_cpu = statistics.median(cpu[("single", 1)])
    rows = []
    for case in cases:
        coupling, k = case
        row = {"coupling": coupling, "ratio": k, "h_fast": h_fast, "h_slow": h_fast * k}
        if case in errors:
            # the largest stable ratio when the pre-flight check refused the ratio, else None
            row.update({"status": "failed", "error": str(errors[case]), "stable_ratio": errors[case].stable_ratio})
            rows.append(row)
            continue
        res = results[case]
        med = statistics.median(cpu[case])
        row.update({"status": "ok", "median_cpu_s": med, "speedup": base_cpu / med,
                    "rhs_full": res.stats["rhs_full"], "rhs_fast": res.stats["rhs_fast"],
                    "muzzle_dev_m": _muzzle_dev(res, base), "muzzle_err_m": _muzzle_dev(res, converged),
                    "repeats": len(cpu[case])})
        rows.append(row)
    return rows


def _muzzle_dev(a, b) -> float:
    """Largest distance (m) of a's muzzle from b's at a's output times (b has them all)."""
    idx = np.searchsorted(b.t, a.t - 1e-12)
    return float(np.linalg.norm(a.marker("muzzle")[0] - b.marker("muzzle")[0][idx], axis=1).max())


def print_table1(rows: list[dict]) -> None:
    print("pymr bench table1: tank gun-turret, 0-1 s, h_fast = 1e-4 s (median CPU of repeated runs, "
          "speed-up over case 1 of the same run)")
    print(f"{'coupling':>8} {'ratio':>5} {'h_slow s':>9} {'CPU s':>9} {'speed-up':>8} {'full evals':>10} "
          f"{'fast evals':>10} {'dev case 1 m':>12} {'error m':>9} | {'paper CPU s':>11} {'paper speed-up':>14}")
    for r in rows:
        paper = PAPER_TABLE1.get(r["ratio"]) if r["coupling"] in ("single", "full") else None
        ptxt = f"{paper[0]:>11.2f} {paper[1]:>14.3f}" if paper else f"{'':>11} {'':>14}"
        if r["status"] != "ok":
            k = r.get("stable_ratio")
            why = (f"refused by the pre-flight check (largest stable ratio is k = {k})" if k is not None
                   else "failed: " + r["error"][-60:])
            print(f"{r['coupling']:>8} {r['ratio']:>5} {r['h_slow']:>9.1e}  {why} | {ptxt}")
            continue
        print(f"{r['coupling']:>8} {r['ratio']:>5} {r['h_slow']:>9.1e} {r['median_cpu_s']:>9.4f} {r['speedup']:>8.2f} "
              f"{r['rhs_full']:>10} {r['rhs_fast']:>10} {r['muzzle_dev_m']:>12.3e} {r['muzzle_err_m']:>9.2e} | {ptxt}")
    print("dev case 1: the muzzle's largest distance from case 1 (the paper's measure); error: from the converged "
          "motion (single-rate h = 1e-5 s)")


#: The spacecraft's cases (docs/performance.md, "Where the scales separate"): name -> overrides.
SPACECRAFT_CASES = {
    "single-rate fixed h = 3e-5 s": {"integrator.adaptive": False, "integrator.h_slow": 3e-5, "integrator.h_fast": 3e-5},
    "single-rate adaptive rtol 1e-4": {"integrator.rtol": 1e-4, "integrator.atol": 1e-7},
    "multirate 'full' k = 10, h_fast = 2.5e-5": {
        "integrator.method": "multirate", "integrator.coupling": "full", "integrator.adaptive": False,
        "integrator.h_slow": 2.5e-4, "integrator.h_fast": 2.5e-5},
    "multirate 'response' k = 10, h_fast = 3e-5": {
        "integrator.method": "multirate", "integrator.adaptive": False, "integrator.h_slow": 3e-4,
        "integrator.h_fast": 3e-5},
    "multirate 'response' k = 100, h_fast = 3e-5": {
        "integrator.method": "multirate", "integrator.adaptive": False, "integrator.h_slow": 3e-3,
        "integrator.h_fast": 3e-5},
    "multirate 'response' adaptive rtol 1e-4, k_max 1000": {
        "integrator.method": "multirate", "integrator.rtol": 1e-4, "integrator.atol": 1e-7, "integrator.k_max": 1000},
    "multirate 'response' adaptive rtol 1e-6, k_max 1000": {
        "integrator.method": "multirate", "integrator.rtol": 1e-6, "integrator.atol": 1e-9, "integrator.k_max": 1000},
    "multirate 'exponential' h = 1.6e-2": {
        "integrator.method": "multirate", "integrator.coupling": "exponential", "integrator.adaptive": False,
        "integrator.h_slow": 1.6e-2, "integrator.h_fast": 1.6e-2},
    "multirate 'exponential' h = 3.2e-2": {
        "integrator.method": "multirate", "integrator.coupling": "exponential", "integrator.adaptive": False,
        "integrator.h_slow": 3.2e-2, "integrator.h_fast": 3.2e-2},
    "multirate 'exponential' adaptive rtol 1e-6": {
        "integrator.method": "multirate", "integrator.coupling": "exponential", "integrator.rtol": 1e-6,
        "integrator.atol": 1e-9},
}


def bench_spacecraft(repeats: int = 5) -> list[dict]:
    """The flexible spacecraft over 2 s: each case's right-boom tip error against single-rate
    adaptive steps at rtol 1e-10, its CPU and its pre-flight check's CPU (medians of the
    same `repeats` runs, interleaved over the cases), and its speed against the fastest
    single-rate case."""
    from .api import run
    scene = _scene_path("spacecraft.nml")
    with tempfile.TemporaryDirectory(prefix="pymr-spacecraft-") as tmp:
        ref = run(scene, Path(tmp) / "ref.csv", overrides={"integrator.rtol": 1e-10, "integrator.atol": 1e-13,
                                                          "output.dt": 1e-3})
        tip = ref.marker("tip_right")[0]
        travel = float(np.linalg.norm(tip - tip[0], axis=1).max())
        cpu: dict[str, list] = {name: [] for name in SPACECRAFT_CASES}
        preflight: dict[str, list] = {name: [] for name in SPACECRAFT_CASES}
        last = {}
        for r in range(repeats):
            for name, over in shuffled(list(SPACECRAFT_CASES.items()), r):
                res = run(scene, Path(tmp) / "case.csv", overrides={**over, "output.dt": 1e-3})
                cpu[name].append(res.stats["cpu_time_s"])
                preflight[name].append(float(res.stats.get("preflight_cpu_s", 0.0)))
                last[name] = res
    rows = []
    for name in SPACECRAFT_CASES:
        res = last[name]
        err = float(np.linalg.norm(res.marker("tip_right")[0] - tip, axis=1).max())
        rows.append({"case": name, "tip_error_m": err, "travel_m": travel, "median_cpu_s": statistics.median(cpu[name]),
                     "preflight_cpu_s": statistics.median(preflight[name]), "rhs_full": res.stats["rhs_full"],
                     "rhs_fast": res.stats["rhs_fast"], "rejected": res.stats["rejected_steps"]})
    fastest_single = min(r["median_cpu_s"] for r in rows if r["case"].startswith("single"))
    for r in rows:
        r["speed_vs_fastest_single"] = fastest_single / r["median_cpu_s"]
    return rows


def print_spacecraft(rows: list[dict]) -> None:
    print(f"pymr bench spacecraft: 0-2 s, right boom tip (travel {rows[0]['travel_m']:.3f} m); error against "
          "single-rate adaptive rtol 1e-10; median CPU of interleaved repeats")
    print(f"{'case':<52} {'tip error m':>11} {'CPU s':>8} {'pre-flight s':>12} {'share':>6} {'x fastest single':>16}")
    for r in rows:
        share = r["preflight_cpu_s"]/r["median_cpu_s"] if r["median_cpu_s"] > 0 else 0.0
        print(f"{r['case']:<52} {r['tip_error_m']:>11.1e} {r['median_cpu_s']:>8.3f} {r['preflight_cpu_s']:>12.3f} "
              f"{100*share:>5.1f}% {r['speed_vs_fastest_single']:>16.1f}")
    print("pre-flight: the check's CPU, part of the run's; its median over the same repeats, and its share of the "
          "run's median")


#: ``bench output``: the spacecraft over 2 s writing a row at every step, in each format, and
#: the same run writing only its first and last rows (output.dt = t_end).
OUTPUT_CASES = {
    "first and last rows only": {"output.dt": 2.0},
    "csv, every step": {"output.dt": 0.0},
    "hdf5, every step (compression 1)": {"output.dt": 0.0, "output.format": "hdf5", "output.compression": 1},
    "hdf5, every step (uncompressed)": {"output.dt": 0.0, "output.format": "hdf5", "output.compression": 0},
}


def _mrsim_cpu(args: list[str], cwd: str) -> float:
    """CPU time (user + system) of one mrsim process, from its start to its exit."""
    import resource
    import subprocess
    from ._locate import mrsim_path
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    done = subprocess.run([mrsim_path(), *args], cwd=cwd, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if done.returncode != 0:
        raise SceneError(done.stderr.strip() or f"mrsim exited with {done.returncode}")
    return (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)


def bench_output(repeats: int = 5) -> list[dict]:
    """What writing the results costs: the spacecraft (48 modal coordinates) over 2 s with a
    row at every step, as CSV and as HDF5, against the same run writing two rows. CPU of the
    whole mrsim process (the files' last flush and rename included), median of `repeats`
    runs interleaved over the cases."""
    scene = str(_scene_path("spacecraft.nml"))
    cpu: dict[str, list] = {name: [] for name in OUTPUT_CASES}
    info: dict[str, dict] = {}
    with tempfile.TemporaryDirectory(prefix="pymr-output-") as tmp:
        for r in range(repeats):
            for name, over in shuffled(list(OUTPUT_CASES.items()), r):
                out = "out_h5.h5" if over.get("output.format") == "hdf5" else "out.csv"   # apart: one .json each
                sets = [a for k, v in over.items() for a in ("--set", f"{k}={v}")]
                cpu[name].append(_mrsim_cpu([scene, "-o", out, "--quiet", *sets], tmp))
                stats = json.loads((Path(tmp) / out).with_suffix(".json").read_text())
                info[name] = {"rows": stats["rows"], "bytes": (Path(tmp) / out).stat().st_size,
                              "columns": len(stats["columns"]["name"])}
    base = statistics.median(cpu["first and last rows only"])
    rows = []
    for name in OUTPUT_CASES:
        med = statistics.median(cpu[name])
        extra_rows = max(info[name]["rows"] - 2, 1)
        rows.append({"case": name, **info[name], "median_cpu_s": med, "added_cpu_fraction": med / base - 1.0,
                     "us_per_row": (med - base) / extra_rows * 1e6})
    return rows


def print_output(rows: list[dict]) -> None:
    print(f"pymr bench output: the spacecraft, 0-2 s, {rows[1]['columns']} columns; CPU of the whole mrsim process, "
          "median of interleaved repeats; added CPU against the same run writing its first and last rows only")
    print(f"{'case':<34} {'rows':>6} {'file MB':>8} {'CPU s':>7} {'added':>7} {'us/row':>7}")
    for r in rows:
        print(f"{r['case']:<34} {r['rows']:>6} {r['bytes'] / 1e6:>8.2f} {r['median_cpu_s']:>7.3f} "
              f"{100 * r['added_cpu_fraction']:>+6.1f}% {r['us_per_row'] if r['rows'] > 2 else 0.0:>7.2f}")
    by = {r["case"]: r for r in rows}
    csv = by["csv, every step"]["us_per_row"]
    for name in ("hdf5, every step (compression 1)", "hdf5, every step (uncompressed)"):
        print(f"cost per row, {name.split(', every step ')[1][1:-1]} HDF5 against CSV: {by[name]['us_per_row'] / csv:.2f}")


#: `pymr bench modal-import`: 3-D frames (towers of tubes, 6 DOFs a node, aspect 4) and solid
#: blocks (8-node bricks, 3 DOFs a node, aspect 10) of about these DOF counts, reduced to 20
#: fixed-interface modes
MODAL_IMPORT_SIZES = (10_000, 100_000, 300_000)
#: the size at which the dense reduction (issue 17's, scipy.linalg.eigh) runs beside it
MODAL_IMPORT_DENSE = 3_000


def _fe_case(kind: str, dofs: int):
    """The model and its attachment: a frame held by its base (z = 0), a block by its x = 0
    face, a beam at node 1."""
    from .fe_models import block_for, frame_beam, frame_lattice, lattice_for, solid_block
    if kind == "beam":
        return frame_beam(max(2, round(dofs / 6))), [1], []
    model = frame_lattice(lattice_for(dofs)) if kind == "frame" else solid_block(block_for(dofs))
    face = model.ids[np.abs(model.xyz[:, 2 if kind == "frame" else 0]) < 1e-12].tolist()
    return model, [face[0]], face[1:]


def modal_import_case(folder: str, interface: list, clamp: list, dofs_per_node: int) -> dict:
    """One reduction of the files in `folder` (run in a process of its own: its peak memory
    is the process's)."""
    import resource
    from .modal_import import modal_import
    folder = Path(folder)
    wall, cpu = time.perf_counter(), time.process_time()
    body = modal_import(folder / "m.mtx", folder / "k.mtx", folder / "nodes.csv", interface, modes=20, clamp=clamp,
                        dofs_per_node=dofs_per_node)
    return {"wall_s": time.perf_counter() - wall, "cpu_s": time.process_time() - cpu,
            "peak_gb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / 1e9,
            "frequencies_hz": body.frequencies_hz.tolist(), "backend": _factor_backend(), "blas": _blas()}


def _blas() -> str:
    """The BLAS libraries this process loaded (the factorisation's speed is theirs)."""
    try:
        paths = {line.split()[-1] for line in open("/proc/self/maps") if "blas" in line}
    except OSError:
        return "unknown"
    return ", ".join(sorted(p for p in paths if "/" in p and "scipy" not in p and "numpy" not in p)) or "unknown"


def _factor_backend() -> str:
    from .craig_bampton import have_cholmod
    return "CHOLMOD" if have_cholmod() else "SuperLU"


def dense_reference(folder: Path, interface: list, clamp: list) -> list:
    """The lowest 20 fixed-interface frequencies by a dense generalized eigensolve of the
    interior (scipy.linalg.eigh), the way issue 17's import solved them."""
    import scipy.io
    import scipy.linalg
    from .fe_formats import read_nodes
    k, m = (scipy.io.mmread(folder / f).tocsr() for f in ("k.mtx", "m.mtx"))
    ids, _ = read_nodes(folder / "nodes.csv")
    dpn = k.shape[0] // len(ids)
    index = {n: i for i, n in enumerate(ids)}
    held = np.concatenate([dpn * index[n] + np.arange(dpn) for n in interface + clamp])
    inner = np.setdiff1d(np.arange(k.shape[0]), held)
    lam = scipy.linalg.eigh(k[inner][:, inner].toarray(), m[inner][:, inner].toarray(), eigvals_only=True,
                            subset_by_index=[0, 19])
    return (np.sqrt(lam) / (2 * np.pi)).tolist()


def bench_modal_import(sizes=MODAL_IMPORT_SIZES, kinds=("frame", "block")) -> list[dict]:
    """Each case written as Matrix Market, then reduced by `pymr.modal_import` in a fresh
    process: wall and CPU time, peak memory, the first frequencies."""
    rows = []
    with tempfile.TemporaryDirectory(prefix="pymr-bench-") as tmp:
        cases = [("frame", MODAL_IMPORT_DENSE)] + [(k, s) for k in kinds for s in sizes]
        for kind, dofs in cases:
            folder = Path(tmp) / f"{kind}{dofs}"
            model, interface, clamp = _fe_case(kind, dofs)
            model.write(folder)
            code = ("import json, sys; from pymr.bench import modal_import_case; print(json.dumps(modal_import_case("
                    f"{str(folder)!r}, {interface!r}, {clamp!r}, {model.dofs_per_node})))")
            r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
            if r.returncode != 0:
                rows.append({"model": kind, "dofs": model.ndof, "error": (r.stderr.strip().splitlines() or ["?"])[-1]})
                continue
            row = {"model": kind, "dofs": model.ndof, "nnz_k": int(model.k.nnz), **json.loads(r.stdout)}
            if dofs == MODAL_IMPORT_DENSE:
                row["dense_hz"] = dense_reference(folder, interface, clamp)
            rows.append(row)
            shutil.rmtree(folder)
    return rows


def print_modal_import(rows: list[dict]) -> None:
    print("pymr bench modal-import: Craig-Bampton reduction to 20 fixed-interface modes from Matrix Market files, "
          "one run a case in its own process")
    print("BLAS of the reductions: " + "; ".join(sorted({r["blas"] for r in rows if "blas" in r})))
    print(f"{'model':>6} {'DOFs':>8} {'nnz(K)':>10} {'factor':>8} {'wall s':>8} {'CPU s':>8} {'peak GB':>8} "
          f"{'f1 Hz':>14} {'f2 Hz':>14} {'|f2-f1|/f1':>11}")
    for r in rows:
        if "error" in r:
            print(f"{r['model']:>6} {r['dofs']:>8} failed: {r['error']}")
            continue
        f = r["frequencies_hz"]
        print(f"{r['model']:>6} {r['dofs']:>8} {r['nnz_k']:>10} {r['backend']:>8} {r['wall_s']:>8.2f} {r['cpu_s']:>8.2f} "
              f"{r['peak_gb']:>8.3f} {f[0]:>14.9f} {f[1]:>14.9f} {abs(f[1] - f[0]) / f[0]:>11.2e}")
        if "dense_hz" in r:
            d = np.asarray(r["dense_hz"])
            gap = np.max(np.abs(np.asarray(f[:len(d)]) - d) / d)
            print(f"{'':>6} {'':>8} dense eigh of the same interior: f1 {d[0]:.9f}, f2 {d[1]:.9f} Hz; largest "
                  f"relative difference over 20 modes {gap:.2e}")


#: ``bench auto``: method 'auto' against each of its candidates run directly, adaptive, at
#: the scene's own tolerances.
AUTO_METHODS = {
    "auto": {"integrator.method": "auto"},
    "single-rate": {"integrator.method": "single"},
    "exponential": {"integrator.method": "multirate", "integrator.coupling": "exponential"},
    "response": {"integrator.method": "multirate", "integrator.coupling": "response"},
}


def shipped_scenes() -> list[Path]:
    """The scenes of input/ and input/hard/ (the first folder of INPUT_FOLDERS that has them)."""
    for base in INPUT_FOLDERS:
        if base.is_dir():
            return sorted(base.glob("*.nml")) + sorted((base / "hard").glob("*.nml"))
    raise SceneError("input/ not found: this installation of pymr has no shipped scenes (reinstall it)")


def bench_auto(repeats: int = 5) -> list[dict]:
    """Each shipped scene run adaptive at its own tolerances by method 'auto' and by each
    candidate directly (a method the scene refuses is None), the candidates with the error
    norm 'auto' ran with (its JSON's integrator, from a first run not timed): the median of
    each one's CPU (its run's own clock, the probes included for 'auto') over `repeats`
    runs interleaved over the scene's methods in a seeded random order, what 'auto' chose,
    and 'auto' over the fastest candidate."""
    from .api import PymrError, run
    rows = []
    with tempfile.TemporaryDirectory(prefix="pymr-auto-") as tmp:
        for scene in shipped_scenes():
            cpu: dict[str, list | None] = {name: [] for name in AUTO_METHODS}
            chosen = ""
            first = run(scene, Path(tmp) / "run.csv", overrides={**AUTO_METHODS["auto"], "integrator.adaptive": True})
            norm = {"integrator.error_norm": first.stats["integrator"]["error_norm"]}
            for r in range(repeats):
                for name, over in shuffled(list(AUTO_METHODS.items()), r):
                    if cpu[name] is None:
                        continue
                    try:
                        res = run(scene, Path(tmp) / "run.csv",
                                  overrides={**over, **norm, "integrator.adaptive": True})
                    except PymrError:
                        cpu[name] = None          # refused (no modal coordinates, a flexible loop) or failed
                        continue
                    cpu[name].append(res.stats["cpu_time_s"])
                    if name == "auto":
                        chosen = res.stats.get("method_choice", {}).get("chosen", "")
            ms = {name: None if not v else 1e3 * statistics.median(v) for name, v in cpu.items()}
            fastest = min((v for k, v in ms.items() if k != "auto" and v is not None), default=None)
            rows.append({"scene": str(scene.relative_to(scene.parents[1] if scene.parent.name == "hard"
                                                        else scene.parent)),
                         "chosen": chosen, **{f"{k}_ms": v for k, v in ms.items()},
                         "auto_over_fastest": None if fastest is None or ms["auto"] is None else ms["auto"] / fastest})
    return rows


def print_auto(rows: list[dict], repeats: int) -> None:
    print("pymr bench auto: each shipped scene adaptive at its own tolerances; median CPU (ms, the run's own clock, "
          f"the probes included for 'auto') of {repeats} runs interleaved in a seeded random order")
    names = list(AUTO_METHODS)
    print(f"{'scene':<30} {'auto chose':<26} " + " ".join(f"{n:>12}" for n in names) + f" {'auto/fastest':>13}")
    for r in rows:
        cells = " ".join(f"{'-':>12}" if r[f'{n}_ms'] is None else f"{r[f'{n}_ms']:>12.2f}" for n in names)
        ratio = "-" if r["auto_over_fastest"] is None else f"{r['auto_over_fastest']:.2f}"
        print(f"{r['scene']:<30} {r['chosen']:<26} {cells} {ratio:>13}")
