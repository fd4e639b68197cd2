"""``pymr study``: what accuracy costs in time, for one scene and every method.

Each method runs the scene at a range of steps or tolerances. Its error is the largest
distance over the run between a marker's position and the reference's, at common output
times; its cost is the run's CPU time and its full-evaluation equivalents (fast-only
evaluations of the multirate method weighted by their measured cost against a full one).

The reference is pymr's adaptive single-rate run at rtol 1e-11, cross-checked against
scipy's DOP853 at rtol 1e-12 driving pymr's own right-hand side through the binding.
Peers on the same right-hand side: scipy's DOP853 and LSODA, and SUNDIALS CVODE (Adams)
through scikit-SUNDAE when it is installed. Their CPU time includes the Python call of
every evaluation; the evaluation counts do not depend on it.
"""
from __future__ import annotations

import csv
import math
import os
import tempfile
import time
from dataclasses import dataclass, asdict
from pathlib import Path

import numpy as np

from .api import Model, PymrError, run, time_fast_evaluation
from .scene import Scene

#: Step factors (times the scene's h_slow) of single-rate fixed steps, and fast steps of multirate.
SINGLE_FACTORS = (8.0, 4.0, 2.0, 1.0, 0.5)
FAST_FACTORS = (2.0, 1.0, 0.5, 0.25)
RATIOS = (2, 5, 10, 20)
ADAPTIVE_RTOLS = tuple(10.0**-e for e in range(3, 11))
MULTIRATE_RTOLS = tuple(10.0**-e for e in range(3, 9))
PEER_RTOLS = tuple(10.0**-e for e in range(3, 11))


@dataclass
class Case:
    """One run of the study."""
    method: str
    setting: str
    error_m: float = math.nan
    cpu_s: float = math.nan
    rhs_full: int = 0
    rhs_fast: int = 0
    equivalents: float = math.nan
    status: str = "ok"


class Study:
    """The runs of a work-precision study of one scene and marker."""

    def __init__(self, scene: str | os.PathLike | Scene, marker: str | None = None, quick: bool = False,
                 progress=print):
        # a path or a pymr.Scene (its overrides apply to every run of the study)
        self.scene = scene if isinstance(scene, Scene) else Scene(scene)
        self.quick = quick
        self.say = progress or (lambda *a, **k: None)
        probe = run(self.scene, overrides={"output.dt": 0.0, "scene.t_end": 1e-6})
        q, qd = probe.coordinates()
        self.n = q.shape[1]
        self.x0 = np.concatenate([q[0], qd[0]])      # the initial state [q; qd]
        markers = sorted({c.rsplit(".", 1)[0] for c in probe.columns if c.endswith(".x")})
        if not markers:
            raise PymrError(f"{self.scene.path}: the scene has no &marker to measure the error at")
        if marker is None:
            marker = markers[0]
        if marker not in markers:
            raise PymrError(f"{self.scene.path}: no marker {marker!r} (markers: {', '.join(markers)})")
        self.marker = marker
        self.h0 = float(probe.stats["integrator"]["h_slow"])
        self.t_end = self._t_end()
        # common output times: every 40 h0 is a multiple of every fixed step and macro step
        self.dt = 40 * self.h0
        self.grid = np.arange(0.0, self.t_end + 0.5 * self.dt, self.dt)
        self.grid = self.grid[self.grid <= self.t_end + 1e-12]
        self.cases: list[Case] = []

    def _t_end(self) -> float:
        return float(self.scene["scene.t_end"])

    # ------------------------------------------------------------------ reference

    def reference(self) -> None:
        self.say(f"reference: pymr adaptive rtol 1e-11 (cross-check: DOP853 rtol 1e-12) ...")
        res = self._pymr({"integrator.adaptive": True, "integrator.rtol": 1e-11, "integrator.atol": 1e-13})
        self.ref = res.marker(self.marker)[0]
        from scipy.integrate import solve_ivp
        with Model(self.scene) as model:
            x0 = self.x0
            sol = solve_ivp(model.rhs, (0.0, self.t_end), x0, method="DOP853", t_eval=self.grid, rtol=1e-12,
                            atol=1e-14)
            if not sol.success:
                raise PymrError(f"reference DOP853 failed: {sol.message}")
            n = self.n
            pos = model.marker(self.marker, sol.t, sol.y[:n].T, sol.y[n:].T)
        self.ref_check = float(np.linalg.norm(pos - self.ref, axis=1).max())
        self.say(f"  pymr and DOP853 references differ by {self.ref_check:.2e} m at most")

    # ----------------------------------------------------------------- the methods

    def _pymr(self, over: dict):
        over = {"output.dt": self.dt, **over}
        with tempfile.TemporaryDirectory(prefix="pymr-study-") as tmp:
            return run(self.scene, Path(tmp) / "run.csv", overrides=over)

    def _error(self, t: np.ndarray, pos: np.ndarray) -> float:
        idx = np.searchsorted(self.grid, t - 1e-9)
        keep = (idx < len(self.grid)) & (np.abs(self.grid[np.minimum(idx, len(self.grid) - 1)] - t) < 1e-9)
        return float(np.linalg.norm(pos[keep] - self.ref[idx[keep]], axis=1).max())

    def _pymr_case(self, method: str, setting: str, over: dict, weight: float = 0.0) -> Case:
        case = Case(method, setting)
        try:
            res = self._pymr(over)
        except PymrError as exc:
            case.status = "refused" if "not stable" in str(exc) else "failed"
            case.status += ": " + str(exc).split(": ", 1)[-1]
            return case
        case.error_m = self._error(res.t, res.marker(self.marker)[0])
        case.cpu_s = float(res.stats["cpu_time_s"])
        case.rhs_full, case.rhs_fast = int(res.stats["rhs_full"]), int(res.stats["rhs_fast"])
        case.equivalents = case.rhs_full + weight * case.rhs_fast
        return case

    def weights(self) -> None:
        """Cost of a fast evaluation against a full one, per coupling (at the initial state)."""
        x0 = self.x0
        q, qd = x0[:self.n], x0[self.n:]
        self.weight = {}
        for coupling in ("full", "split"):
            fast, full = time_fast_evaluation(self.scene, q, qd, coupling == "split")
            self.weight[coupling] = fast / full
        self.say(f"fast evaluation / full evaluation: 'full' {self.weight['full']:.3f}, "
                 f"'split' {self.weight['split']:.3f}")

    def run_all(self) -> list[Case]:
        self.reference()
        self.weights()
        h0 = self.h0
        single = SINGLE_FACTORS[1:4] if self.quick else SINGLE_FACTORS
        for f in single:
            h = f * h0
            self._add(self._pymr_case("single fixed", f"h={h:.3g}", {"integrator.h_slow": h, "integrator.h_fast": h}))
        ratios = (2, 10) if self.quick else RATIOS
        fasts = FAST_FACTORS[1:3] if self.quick else FAST_FACTORS
        for coupling in ("full", "split"):
            for k in ratios:
                for f in fasts:
                    hf = f * h0
                    self._add(self._pymr_case(f"multirate k={k} {coupling}", f"h_fast={hf:.3g}", {
                        "integrator.method": "multirate", "integrator.coupling": coupling,
                        "integrator.h_fast": hf, "integrator.h_slow": k * hf}, self.weight[coupling]))
        rtols = ADAPTIVE_RTOLS[::3] if self.quick else ADAPTIVE_RTOLS
        for rtol in rtols:
            self._add(self._pymr_case("adaptive single", f"rtol={rtol:.0e}", {
                "integrator.adaptive": True, "integrator.rtol": rtol, "integrator.atol": rtol * 1e-2}))
        mrtols = MULTIRATE_RTOLS[::3] if self.quick else MULTIRATE_RTOLS
        for coupling in ("full", "split"):
            for rtol in mrtols:
                self._add(self._pymr_case(f"adaptive multirate {coupling}", f"rtol={rtol:.0e}", {
                    "integrator.method": "multirate", "integrator.coupling": coupling, "integrator.adaptive": True,
                    "integrator.rtol": rtol, "integrator.atol": rtol * 1e-2, "integrator.h_fast": h0,
                    "integrator.h_slow": h0}, self.weight[coupling]))
        prtols = PEER_RTOLS[::3] if self.quick else PEER_RTOLS
        for name in ("DOP853", "LSODA", "CVODE Adams"):
            for rtol in prtols:
                self._add(self._peer(name, rtol))
        return self.cases

    def _add(self, case: Case) -> None:
        self.cases.append(case)
        if case.status == "ok":
            self.say(f"  {case.method:<26} {case.setting:<16} error {case.error_m:9.2e} m  CPU {case.cpu_s:8.4f} s  "
                     f"full-eval equivalents {case.equivalents:10.0f}")
        else:
            self.say(f"  {case.method:<26} {case.setting:<16} {case.status[:110]}")

    def _peer(self, name: str, rtol: float) -> Case:
        case = Case(name, f"rtol={rtol:.0e}")
        x0 = self.x0
        n = self.n
        with Model(self.scene) as model:
            try:
                if name == "CVODE Adams":
                    try:
                        from sksundae.cvode import CVODE
                    except ImportError:
                        case.status = "skipped: scikit-sundae is not installed (pip install scikit-sundae)"
                        return case

                    def f(t, y, yp):
                        yp[:] = model.rhs(t, y)
                    solver = CVODE(f, method="Adams", rtol=rtol, atol=rtol * 1e-2, max_num_steps=10**7)
                    c0 = time.process_time()
                    sol = solver.solve(self.grid, x0)
                    case.cpu_s = time.process_time() - c0
                    if not sol.success:
                        case.status = f"failed: {sol.message}"
                        return case
                    t, y = sol.t, sol.y
                else:
                    from scipy.integrate import solve_ivp
                    c0 = time.process_time()
                    sol = solve_ivp(model.rhs, (0.0, self.t_end), x0, method=name, t_eval=self.grid, rtol=rtol,
                                    atol=rtol * 1e-2)
                    case.cpu_s = time.process_time() - c0
                    if not sol.success:
                        case.status = f"failed: {sol.message}"
                        return case
                    t, y = sol.t, sol.y.T
            except PymrError as exc:
                case.status = f"failed: {exc}"[:140]
                return case
            pos = model.marker(self.marker, t, y[:, :n], y[:, n:])
            case.rhs_full = model.evaluations
        case.error_m = self._error(np.asarray(t), pos)
        case.equivalents = float(case.rhs_full)
        return case

    # ---------------------------------------------------------------- reporting

    def write_csv(self, path: Path) -> None:
        with open(path, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=list(asdict(self.cases[0])))
            w.writeheader()
            for c in self.cases:
                w.writerow(asdict(c))

    def best_at(self, error: float) -> dict[str, Case]:
        """Per method family, the cheapest case (by CPU) with error <= `error`."""
        best: dict[str, Case] = {}
        for c in self.cases:
            if c.status != "ok" or not c.error_m <= error:
                continue
            if c.method not in best or c.cpu_s < best[c.method].cpu_s:
                best[c.method] = c
        return best

    def plot(self, path: Path) -> None:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        fig, axes = plt.subplots(1, 2, figsize=(13, 5.5), sharey=True)
        methods = list(dict.fromkeys(c.method for c in self.cases))
        for method in methods:
            ok = [c for c in self.cases if c.method == method and c.status == "ok"]
            if not ok:
                continue
            style = "-o" if "adaptive" in method else ("--s" if method in ("DOP853", "LSODA", "CVODE Adams") else ":^")
            for ax, key in zip(axes, ("cpu_s", "equivalents")):
                ax.loglog([getattr(c, key) for c in ok], [c.error_m for c in ok], style, label=method, ms=4)
        axes[0].set_xlabel("CPU time (s)")
        axes[1].set_xlabel("full-evaluation equivalents")
        axes[0].set_ylabel(f"largest error of marker '{self.marker}' (m)")
        for ax in axes:
            ax.grid(True, which="both", alpha=0.3)
        axes[1].legend(fontsize=7, ncol=2)
        fig.suptitle(f"work-precision: {self.scene.path.name} (reference: pymr rtol 1e-11; DOP853 agrees to "
                     f"{self.ref_check:.1e} m)")
        fig.tight_layout()
        fig.savefig(path, dpi=110)
        plt.close(fig)

    def table(self) -> str:
        lines = [f"{'method':<26} {'setting':<16} {'error (m)':>10} {'CPU (s)':>9} {'full evals':>10} "
                 f"{'fast evals':>10} {'equivalents':>11}  status"]
        for c in self.cases:
            if c.status == "ok":
                lines.append(f"{c.method:<26} {c.setting:<16} {c.error_m:10.2e} {c.cpu_s:9.4f} {c.rhs_full:10d} "
                             f"{c.rhs_fast:10d} {c.equivalents:11.0f}  ok")
            else:
                lines.append(f"{c.method:<26} {c.setting:<16} {'':>10} {'':>9} {'':>10} {'':>10} {'':>11}  "
                             f"{c.status[:110]}")
        return "\n".join(lines)


def main(scene: str, marker: str | None = None, output: str | None = None, quick: bool = False) -> int:
    study = Study(scene, marker, quick=quick)
    study.run_all()
    prefix = Path(output) if output else Path(Path(scene).stem + "_study")
    print()
    print(study.table())
    study.write_csv(prefix.with_suffix(".csv"))
    study.plot(prefix.with_suffix(".png"))
    print(f"written: {prefix.with_suffix('.csv')}, {prefix.with_suffix('.png')}")
    return 0
