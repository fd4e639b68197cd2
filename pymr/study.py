"""``pymr study``: what accuracy costs in time, for one scene and every method.

Each method runs the scene at a range of steps or tolerances. Its error is the largest
distance over the run between a marker's position and the reference's, at common output
times (fixed-step runs write the rows between their steps from dense output, so every run
shares one grid). Its cost is the MEDIAN CPU time of ``repeats`` runs (the kernel's
integration CPU, without the pre-flight stability check; the cases that contend for the
front, FRONT_PASSES runs more) and its full-evaluation equivalents ``rhs_full + w * rhs_fast``.

The weight ``w`` of a fast-only evaluation is measured per coupling from whole runs, so it
holds the integrator's own work per step, not only the right-hand side: ``c_full`` is the
CPU per step of a fixed single-rate run at the scene's h_slow, ``c_fast`` the CPU of a
fixed multirate run at k = 10 less its full evaluations at ``c_full``, per fast-only
evaluation; ``w = c_fast / c_full``.

Methods: pymr single-rate (fixed steps and adaptive with the paper's order-4 formula 'abm4';
adaptive with formula 'adams' of variable order 1-12), multirate with the 'response' coupling
(fixed at several ratios and fast steps, adaptive) and with the paper's 'full' coupling
(fixed, adaptive); peers on the same right-hand side: scipy's DOP853, Radau and LSODA, SUNDIALS
CVODE Adams and BDF through scikit-SUNDAE when it is installed. The peers' CPU time
includes the Python call of every evaluation; their evaluation counts do not depend on it.

The reference is pymr's adaptive single-rate run at rtol 1e-11, cross-checked against
scipy's DOP853 at rtol 1e-12 driving pymr's own right-hand side through the binding.
"""
from __future__ import annotations

import csv
import io
import math
import os
import statistics
import tempfile
import textwrap
import time
from dataclasses import dataclass, asdict
from pathlib import Path

import numpy as np

from .api import Model, PymrError, SceneError, SolverError, initial_state, run, write_file
from ._args import write_files
from ._timing import MAX_REPEATS, shuffled
from .outputs import check_output
from .scene import Scene



def _steps(largest: float, smallest: float) -> tuple[float, ...]:
    """Step factors from `largest` down to `smallest`, sqrt(2) apart (a fourth-order method's
    error changes 4x between neighbours)."""
    n = round(2 * math.log2(largest / smallest))
    return tuple(largest * 2.0 ** (-j / 2) for j in range(n + 1))


#: Fixed steps of single-rate (times the scene's h_slow). Fixed steps need not divide the
#: output interval or t_end (rows between steps come from dense output).
SINGLE_FACTORS = _steps(8.0, 0.25)
#: Multirate couplings, and per coupling the fast steps (times h_slow) and step ratios of
#: its fixed-step cases. 'response' is stable at any ratio (only h_fast is bound), so its
#: grid reaches large ratios; the 'full' coupling's macro step is stability bound.
COUPLINGS = ("response", "full")
FAST_FACTORS = {"response": _steps(4.0, 0.25), "full": _steps(2.0, 0.25)}
RATIOS = {"response": (5, 10, 20, 40), "full": (2, 5, 10, 20, 40)}
#: Tolerances of the adaptive methods: 1e-3 to 1e-10, half a decade apart.
TOLERANCES = tuple(10.0 ** (-e / 2) for e in range(6, 21))
ADAPTIVE_RTOLS = PEER_RTOLS = TOLERANCES
#: The two variable-order codes, pymr's formula 'adams' and CVODE Adams, are compared on a
#: grid twice as fine (a quarter decade): their error is not monotone in rtol within a
#: factor 2-3, as the order they choose changes.
ORDER_RTOLS = tuple(10.0 ** (-e / 4) for e in range(12, 41))
#: The adaptive multirate couplings and 'auto' take the fine grid too: each is set against
#: a fixed-step family whose grid has two settings (h_fast a factor sqrt(2) apart, and k),
#: and on half a decade the first case below an error level overshoots it by up to 3.2x
#: in error (on the tank up to 1.3x in cost).
MULTIRATE_RTOLS = ORDER_RTOLS
#: Adaptive multirate families run with both error norms (&integrator error_norm): 'state'
#: (the default) and 'amplitude' (a mode weighed by its amplitude), as families of their own.
ERROR_NORMS = ("state", "amplitude")
PEERS = ("DOP853", "Radau", "LSODA", "CVODE Adams", "CVODE BDF")
#: The small grid of quick=True (a smoke run, the tests).
QUICK_SINGLE_FACTORS = (4.0, 2.0, 1.0)
QUICK_FAST_FACTORS = {"response": (1.0, 0.5), "full": (0.5, 0.25)}
QUICK_RATIOS = {"response": (10, 40), "full": (5, 20)}
QUICK_TOLERANCES = (1e-3, 1e-6, 1e-9)
#: Step ratio of the multirate runs that measure the cost of a fast-only evaluation (the
#: smaller ones are tried when the pre-flight check refuses it).
WEIGHT_RATIOS = (10, 5, 2)
#: Error levels (m) of the front summary.
FRONT_ERRORS = (1e-4, 1e-5, 1e-6, 1e-7)
#: After the timing passes, the pymr cases that contend for a place on the front (within
#: FRONT_MARGIN of their family's fastest at some error level) take FRONT_PASSES more
#: interleaved passes: the front's ratios then rest on the median of repeats + FRONT_PASSES
#: runs (a median of 5 moved a 3 ms case by 20-40 % between studies).
FRONT_MARGIN = 1.5
FRONT_PASSES = 16
#: Single-rate and multirate families: the two sides of the front summary's ratio.
SINGLE_FAMILIES = ("single fixed", "abm4 adaptive", "adams adaptive")
#: pymr's fixed-order families (the paper's formula), against which variable order is compared.
FIXED_ORDER_FAMILIES = ("single fixed", "abm4 adaptive")
#: Error levels (m) of the variable-order summary.
ORDER_ERRORS = (1e-5, 1e-6, 1e-7, 1e-8)
#: Tolerances of the step and order histories of formula 'adams'.
HISTORY_RTOLS = (1e-4, 1e-8)
MULTIRATE_FAMILIES = ("response fixed", "response adaptive", "response adaptive amplitude", "exponential fixed",
                      "exponential adaptive", "exponential adaptive amplitude")
#: Per multirate coupling of the front: its fixed-step family and its adaptive ones (both
#: norms), whose fastest case the front summary sets against the fixed family's fastest.
ADAPTIVE_AGAINST_FIXED = {"response": ("response fixed", ("response adaptive", "response adaptive amplitude")),
                          "exponential": ("exponential fixed",
                                          ("exponential adaptive", "exponential adaptive amplitude"))}
#: Method 'auto' (the kernel's choice among the adaptive methods), set against the fastest
#: of the families above at each error level.
AUTO_FAMILY = "auto adaptive"
#: Steps of the 'exponential' coupling (times the scene's h_slow): it has no fast step, and
#: its step is bound by the accuracy of the cubic through the full evaluations alone.
EXPONENTIAL_FACTORS = _steps(128.0, 2.0)
QUICK_EXPONENTIAL_FACTORS = (32.0, 8.0)


@dataclass
class Case:
    """One case of the study (its CPU time is the median over the study's repeats)."""
    method: str
    setting: str
    error_m: float = math.nan
    cpu_s: float = math.nan
    rhs_full: int = 0
    rhs_fast: int = 0
    equivalents: float = math.nan
    status: str = "ok"
    runs: int = 0          # runs the CPU time is the median of
    #: For a case the pre-flight check refused: the largest stable step (s) or step ratio it
    #: named (the error's fields), else None.
    stable_step: float | None = None
    stable_ratio: int | None = None

    @property
    def family(self) -> str:
        """The method without its step ratio: 'response fixed k=10' -> 'response fixed'."""
        return self.method.split(" k=")[0]


#: The kinds of error (PymrError.kind) of a step or step ratio the pre-flight check refuses.
REFUSALS = ("unstable_step", "unstable_ratio")


def _short_reason(case: Case) -> str:
    """The gist of a refusal or failure, for the figure's note: the largest stable step or
    ratio of a refusal, else the start of the status."""
    if case.stable_ratio is not None:
        return f"largest stable ratio is k = {case.stable_ratio}"
    if case.stable_step is not None:
        return f"largest stable step is {case.stable_step:.2E} s"
    return case.status.split(":", 1)[-1].strip()[:100]


class Study:
    """The runs of a work-precision study of one scene and marker."""

    def __init__(self, scene: str | os.PathLike | Scene, marker: str | None = None, quick: bool = False,
                 progress=print, repeats: int = 5):
        # a path or a pymr.Scene (its overrides apply to every run of the study)
        self.scene = scene if isinstance(scene, Scene) else Scene(scene)
        self.quick = quick
        if isinstance(repeats, bool) or not isinstance(repeats, (int, np.integer)) or not 1 <= repeats <= MAX_REPEATS:
            raise SceneError(f"repeats: a whole number of runs per case from 1 to {MAX_REPEATS}, got {repeats!r}")
        self.repeats = int(repeats)
        self.say = progress or (lambda *a, **k: None)
        q, qd = initial_state(self.scene)
        self.n = q.size
        self.x0 = np.concatenate([q, qd])      # the initial state [q; qd]
        with Model(self.scene) as model:
            markers = sorted(model.marker_names())
        if not markers:
            raise SceneError(f"{self.scene.path}: the scene has no &marker to measure the error at")
        if marker is None:
            marker = markers[0]
        if marker not in markers:
            raise SceneError(f"{self.scene.path}: no marker {marker!r} (markers: {', '.join(markers)})")
        self.marker = marker
        self.h0 = float(self.scene["integrator.h_slow"])
        self.t_end = self._t_end()
        if self.t_end < max(WEIGHT_RATIOS) * self.h0:
            raise SceneError(f"{self.scene.path}: &scene: t_end: {self.t_end:g} s is shorter than {max(WEIGHT_RATIOS)} "
                             f"steps of h_slow ({max(WEIGHT_RATIOS) * self.h0:g} s), the shortest run pymr study "
                             "measures its methods' costs on: lengthen the run or shorten h_slow")
        # every run writes its rows as CSV with the marker's columns, and no checkpoint,
        # whatever the scene's &output says (an 'hdf5' scene was refused as taking no multirate run)
        quantities = list(self.scene["output.quantities"])
        self.outputs = {"output.format": "csv", "output.checkpoint_dt": 0.0,
                        "output.quantities": quantities + ["markers"] * ("markers" not in quantities)}
        # common output times for every run (dense output between steps): every 40 h0, at
        # most about 2000 of them
        self.dt = max(40 * self.h0, self.t_end / 2000)
        # k dt for every k with k dt <= t_end, as the kernel writes its rows (np.arange's
        # float steps gave a time past t_end, or one time too many, for some t_end)
        n = int(np.floor(self.t_end / self.dt + 1e-9))
        self.grid = np.minimum(np.arange(n + 1) * self.dt, self.t_end)
        self.cases: list[Case] = []
        self.weight: dict[str, float] = {}
        self.c_fast: dict[str, float] = {}
        self.weight_ratio: dict[str, int] = {}
        self.c_full = math.nan
        self.ref_check = math.nan
        self._check_multirate()

    def _check_multirate(self) -> None:
        """A study runs multirate cases: a scene the kernel refuses them for (no modal or no
        joint coordinates) is refused at once, before the reference runs, in the kernel's
        words (one step of fixed multirate steps)."""
        try:
            self._pymr({"integrator.method": "multirate", "integrator.coupling": "response", "integrator.adaptive": False,
                        "integrator.h_slow": self.h0, "integrator.h_fast": self.h0, "scene.t_end": self.h0,
                        "integrator.stability_check": False, "output.dt": self.h0})
        except SceneError as exc:
            reason = str(exc).split("method: ", 1)[-1]
            raise SceneError(f"{self.scene.path}: pymr study compares single-rate and multirate methods, and this "
                             f"scene takes no multirate run ({reason})") from None

    def _t_end(self) -> float:
        return float(self.scene["scene.t_end"])

    # ------------------------------------------------------------------ reference

    def reference(self) -> None:
        self.say("reference: pymr adaptive rtol 1e-11, steps at most h_slow/10 (cross-check: DOP853 rtol 1e-12) ...")
        # the step bound keeps the adaptive start from its first large steps, whose error in
        # undamped stiff modes would floor the reference (stiff barrel: 5e-10 m without it)
        res = self._pymr({"integrator.method": "single", "integrator.adaptive": True, "integrator.rtol": 1e-11,
                          "integrator.atol": 1e-13, "integrator.h_max": self.h0 / 10})
        self.ref = self._on_grid(res.t, res.marker(self.marker)[0])
        if not np.ptp(self.ref, axis=0).any():
            raise SceneError(f"{self.scene.path}: marker {self.marker!r} does not move in the reference run, so every "
                             "method's error at it is 0: choose a marker on a moving body")
        from scipy.integrate import solve_ivp
        with Model(self.scene) as model:
            sol = solve_ivp(model.rhs, (0.0, self.t_end), self.x0, method="DOP853", t_eval=self.grid, rtol=1e-12,
                            atol=1e-14)
            if not sol.success:
                raise SolverError(f"reference DOP853 failed: {sol.message}")
            n = self.n
            pos = model.marker(self.marker, sol.t, sol.y[:n].T, sol.y[n:].T)
        self.ref_check = float(np.linalg.norm(pos - self.ref, axis=1).max())
        self.say(f"  pymr and DOP853 references differ by {self.ref_check:.2e} m at most")

    # ----------------------------------------------------------------- the methods

    def _pymr(self, over: dict):
        over = {"output.dt": self.dt, **self.outputs, **over}
        with tempfile.TemporaryDirectory(prefix="pymr-study-") as tmp:
            return run(self.scene, Path(tmp) / "run.csv", overrides=over)

    def _on_grid(self, t: np.ndarray, pos: np.ndarray) -> np.ndarray:
        """The rows of `pos` (at times `t`) at the study's common output times, in their order."""
        idx = np.searchsorted(self.grid, t - 1e-9)
        keep = (idx < len(self.grid)) & (np.abs(self.grid[np.minimum(idx, len(self.grid) - 1)] - t) < 1e-9)
        if keep.sum() != len(self.grid) or len(np.unique(idx[keep])) != len(self.grid):
            raise SolverError(f"the run wrote rows at {int(keep.sum())} of the study's {len(self.grid)} common "
                              "output times")
        return pos[keep]

    def _error(self, t: np.ndarray, pos: np.ndarray) -> float:
        return float(np.linalg.norm(self._on_grid(t, pos) - self.ref, axis=1).max())

    @staticmethod
    def _refusal(case: Case, exc: PymrError) -> None:
        """Mark `case` refused (the pre-flight check refused its step or ratio, whose
        largest stable value it keeps) or failed, with the error's fault (its message when
        the kernel gave no fault apart)."""
        case.status = ("refused" if exc.kind in REFUSALS else "failed") + ": " + (exc.fault or str(exc))
        case.stable_step, case.stable_ratio = exc.stable_step, exc.stable_ratio

    def _pymr_case(self, method: str, setting: str, over: dict, repeats: int | None = None) -> Case:
        """Run one pymr case `repeats` times (default: the study's) in a row: the error and
        evaluation counts of the first run (they do not change between runs), the median
        CPU time of all of them."""
        case = Case(method, setting)
        try:
            res = self._pymr(over)
        except PymrError as exc:
            self._refusal(case, exc)
            return case
        case.error_m = self._error(res.t, res.marker(self.marker)[0])
        case.rhs_full, case.rhs_fast = int(res.stats["rhs_full"]), int(res.stats["rhs_fast"])
        coupling = res.stats["integrator"].get("coupling", "response")
        if case.rhs_fast == 0:
            case.equivalents = float(case.rhs_full)
        else:
            case.equivalents = case.rhs_full + self.weight.get(coupling, math.nan) * case.rhs_fast
        cpu = [float(res.stats["cpu_time_s"])]
        cpu += [self._pymr_cpu(over) for _ in range((repeats or self.repeats) - 1)]
        self._set_cpu(case, cpu)
        return case

    def _pymr_cpu(self, over: dict) -> float:
        return float(self._pymr(over).stats["cpu_time_s"])

    @staticmethod
    def _set_cpu(case: Case, cpu: list[float]) -> None:
        case.cpu_s = float(statistics.median(cpu))
        case.runs = len(cpu)

    def _adaptive_multirate(self, coupling: str, norms: tuple[str, ...]) -> list[tuple]:
        """The adaptive cases of a multirate coupling, a family per error norm ('state' is
        the plain "COUPLING adaptive")."""
        out = []
        for norm in norms:
            family = f"{coupling} adaptive" + ("" if norm == "state" else f" {norm}")
            for rtol in (QUICK_TOLERANCES if self.quick else MULTIRATE_RTOLS):
                out.append(("pymr", family, f"rtol={rtol:.1e}", {
                    "integrator.method": "multirate", "integrator.coupling": coupling, "integrator.adaptive": True,
                    "integrator.rtol": rtol, "integrator.atol": rtol * 1e-2, "integrator.h_fast": self.h0,
                    "integrator.h_slow": self.h0, "integrator.error_norm": norm}))
        return out

    def _multirate(self, coupling: str, k: int, h_fast: float) -> dict:
        return {"integrator.method": "multirate", "integrator.coupling": coupling, "integrator.adaptive": False,
                "integrator.h_fast": h_fast, "integrator.h_slow": k * h_fast}

    def weights(self) -> None:
        """Measured cost of a fast-only evaluation against a full one, per coupling, with the
        integrator's own work: c_full = CPU per step of fixed single-rate at h_slow (halved until stable);
        c_fast = (CPU of fixed multirate at k = 10 - rhs_full c_full) / rhs_fast; medians
        over the repeats (the three runs interleaved, so that a slow spell of the machine
        falls on all of them); weight = c_fast / c_full, at least 0."""
        h0 = self.h0
        while True:                                          # the scene's step, halved until it is stable
            single = {"integrator.method": "single", "integrator.adaptive": False, "integrator.h_slow": h0,
                      "integrator.h_fast": h0}
            try:
                self._pymr(single)                           # also the warm-up (caches, first touch)
                break
            except PymrError as exc:
                if exc.kind == "solver":                     # a run that fails: no weight, the study goes on
                    self.say(f"measured weight w: not measured: the fixed single-rate run at h = {h0:g} s failed "
                             f"({exc}): the multirate cases have no equivalents")
                    self.weight = {c: math.nan for c in COUPLINGS}
                    self.c_fast, self.weight_ratio = dict(self.weight), {}
                    return
                if exc.kind not in REFUSALS or h0 < 1e-3 * self.h0:
                    raise
                h0 /= 2
        multi = {}
        for coupling in COUPLINGS:                          # the largest ratio the pre-flight check passes
            for k in WEIGHT_RATIOS:                          # (and runs to the end)
                try:
                    self._pymr(self._multirate(coupling, k, h0))
                except PymrError as exc:
                    if exc.kind not in REFUSALS + ("solver",):
                        raise
                    continue
                multi[coupling] = k
                break
        samples = {c: [] for c in multi}
        per_step = []
        for _ in range(self.repeats):
            s = self._pymr(single).stats
            per_step.append(float(s["cpu_time_s"]) / int(s["steps_fast"]))
            for coupling, k in multi.items():
                samples[coupling].append(self._pymr(self._multirate(coupling, k, h0)).stats)
        self.c_full = float(statistics.median(per_step))
        self.weight, self.c_fast, self.weight_ratio = {}, {}, dict(multi)
        for coupling in COUPLINGS:
            if coupling not in multi:
                self.c_fast[coupling] = self.weight[coupling] = math.nan
                continue
            self.c_fast[coupling] = float(statistics.median(
                (float(s["cpu_time_s"]) - int(s["rhs_full"]) * self.c_full) / max(int(s["rhs_fast"]), 1)
                for s in samples[coupling]))
            self.weight[coupling] = max(0.0, self.c_fast[coupling] / self.c_full)
        self.say(self.weights_text())

    def weights_text(self) -> str:
        ratios = ", ".join(map(str, WEIGHT_RATIOS))
        parts = [f"'{c}' {self.weight[c]:.3f} (c_fast {self.c_fast[c] * 1e6:.3f} us at k = {self.weight_ratio[c]})"
                 if math.isfinite(self.weight.get(c, math.nan)) else
                 f"'{c}' not measured (at k = {ratios} the pre-flight check refused the run or it failed: its cases "
                 "have no equivalents)"
                 for c in COUPLINGS]
        return (f"measured weight w = c_fast / c_full of a fast-only evaluation (c_full {self.c_full * 1e6:.3f} us "
                f"per single-rate step): " + ", ".join(parts))

    def specs(self) -> list[tuple]:
        """The study's cases: ("pymr", method, setting, overrides) or ("peer", name, rtol)."""
        h0 = self.h0
        quick = self.quick
        out: list[tuple] = []
        for f in (QUICK_SINGLE_FACTORS if quick else SINGLE_FACTORS):
            h = f * h0
            out.append(("pymr", "single fixed", f"h={h:.3g}", {
                "integrator.method": "single", "integrator.adaptive": False, "integrator.h_slow": h,
                "integrator.h_fast": h}))
        for formula in ("abm4", "adams"):
            for rtol in (QUICK_TOLERANCES if quick else ORDER_RTOLS if formula == "adams" else ADAPTIVE_RTOLS):
                out.append(("pymr", f"{formula} adaptive", f"rtol={rtol:.1e}", {
                    "integrator.method": "single", "integrator.adaptive": True, "integrator.rtol": rtol,
                    "integrator.atol": rtol * 1e-2, "integrator.formula": formula}))
        for coupling in COUPLINGS:
            ratios = QUICK_RATIOS[coupling] if quick else RATIOS[coupling]
            fasts = QUICK_FAST_FACTORS[coupling] if quick else FAST_FACTORS[coupling]
            for k in ratios:
                for f in fasts:
                    hf = f * h0
                    out.append(("pymr", f"{coupling} fixed k={k}", f"h_fast={hf:.3g}",
                                self._multirate(coupling, k, hf)))
            out += self._adaptive_multirate(coupling, norms=("state",) if coupling == "full" else ERROR_NORMS)
        for f in (QUICK_EXPONENTIAL_FACTORS if quick else EXPONENTIAL_FACTORS):
            h = f * h0
            out.append(("pymr", "exponential fixed", f"h={h:.3g}", {
                "integrator.method": "multirate", "integrator.coupling": "exponential", "integrator.adaptive": False,
                "integrator.h_slow": h, "integrator.h_fast": h}))
        out += self._adaptive_multirate("exponential", norms=ERROR_NORMS)
        for rtol in (QUICK_TOLERANCES if quick else MULTIRATE_RTOLS):
            out.append(("pymr", "auto adaptive", f"rtol={rtol:.1e}", {
                "integrator.method": "auto", "integrator.adaptive": True, "integrator.rtol": rtol,
                "integrator.atol": rtol * 1e-2}))
        for name in PEERS:
            for rtol in (QUICK_TOLERANCES if quick else ORDER_RTOLS if name == "CVODE Adams" else PEER_RTOLS):
                out.append(("peer", name, rtol))
        return out

    def run_all(self) -> list[Case]:
        """Every case: a first pass for the errors, evaluation counts and a first CPU time,
        then repeats - 1 timing passes over all cases (interleaved, so that a slow spell of
        the machine spreads over many cases instead of spoiling the median of one), then
        (unless quick) FRONT_PASSES over the pymr cases that contend for the front."""
        self.reference()
        self.weights()
        specs = self.specs()
        self.say(f"pass 1 of {self.repeats}: errors and evaluations of {len(specs)} cases")
        first = []
        limited: set[str] = set()
        i = 0
        while i < len(specs):
            spec = specs[i]
            case = self._pymr_case(*spec[1:], repeats=1) if spec[0] == "pymr" else self._peer(*spec[1:], repeats=1)
            self._add(case)
            first.append(case)
            extra = self._at_stable_step(spec, case, limited)
            if extra:
                specs.append(extra)
            i += 1
        samples = [[c.cpu_s] for c in first]
        for p in range(2, self.repeats + 1):
            self.say(f"pass {p} of {self.repeats}: CPU times")
            for spec, case, cpu in shuffled(list(zip(specs, first, samples)), p):
                if case.status != "ok":
                    continue
                if spec[0] == "pymr":
                    cpu.append(self._pymr_cpu(spec[3]))
                else:
                    with Model(self.scene) as model:
                        cpu.append(self._peer_run(model, *spec[1:])[2])
        for case, cpu in zip(first, samples):
            if case.status == "ok":
                self._set_cpu(case, cpu)
        if self.repeats > 1 and not self.quick:
            self._time_front([(spec, case, cpu) for spec, case, cpu in zip(specs, first, samples) if spec[0] == "pymr"])
        return self.cases

    def _time_front(self, runs: list[tuple]) -> None:
        """FRONT_PASSES more interleaved timing passes over the pymr cases (spec, case, CPU
        samples) within FRONT_MARGIN of their family's fastest at some level of FRONT_ERRORS;
        their CPU is then the median of all their samples."""
        best = {level: self.best_at(level) for level in FRONT_ERRORS}
        contenders = [(spec, case, cpu) for spec, case, cpu in runs if case.status == "ok" and any(
            case.error_m <= level and case.cpu_s <= FRONT_MARGIN * best[level][case.family].cpu_s
            for level in FRONT_ERRORS)]
        for p in range(1, FRONT_PASSES + 1):
            self.say(f"front pass {p} of {FRONT_PASSES}: CPU times of {len(contenders)} contending cases")
            for spec, case, cpu in shuffled(contenders, self.repeats + p):
                cpu.append(self._pymr_cpu(spec[3]))
        for spec, case, cpu in contenders:
            self._set_cpu(case, cpu)

    def _at_stable_step(self, spec: tuple, case: Case, limited: set[str]) -> tuple | None:
        """A fixed-step family whose step the pre-flight check refused for a vibration's
        stability gets one more case, at the largest stable step the refusal names (less
        0.5 %): the grid would otherwise leave out its fastest stable run. A multirate case
        scales both its steps alike, so that its step ratio stays the kernel's of the case."""
        if spec[0] != "pymr" or case.stable_step is None or case.method in limited:
            return None
        limited.add(case.method)
        h = 0.995 * case.stable_step
        over = dict(spec[3])
        if over.get("integrator.method") == "multirate":
            scale = h / float(over["integrator.h_fast"])
            over.update({"integrator.h_fast": h, "integrator.h_slow": scale * float(over["integrator.h_slow"])})
            return ("pymr", case.method, f"h_fast={h:.3g} (stable limit)", over)
        over.update({"integrator.h_fast": h, "integrator.h_slow": h})
        return ("pymr", case.method, f"h={h:.3g} (stable limit)", over)

    def _add(self, case: Case) -> None:
        self.cases.append(case)
        if case.status == "ok":
            self.say(f"  {case.method:<22} {case.setting:<16} error {case.error_m:9.2e} m  CPU {case.cpu_s:8.4f} s  "
                     f"full-eval equivalents {case.equivalents:10.0f}")
        else:
            self.say(f"  {case.method:<22} {case.setting:<16} {case.status[:110]}")

    def _peer_run(self, model: Model, name: str, rtol: float):
        """One peer run on `model`'s right-hand side: (t, y, CPU seconds, evaluations, status)."""
        e0 = model.evaluations
        x0 = self.x0
        try:
            if name.startswith("CVODE"):
                from sksundae.cvode import CVODE

                def f(t, y, yp):
                    yp[:] = model.rhs(t, y)
                solver = CVODE(f, method=name.split()[1], rtol=rtol, atol=rtol * 1e-2, max_num_steps=10**7)
                c0 = time.process_time()
                sol = solver.solve(self.grid, x0)
                cpu = time.process_time() - c0
                t, y = sol.t, sol.y
            else:
                from scipy.integrate import solve_ivp
                c0 = time.process_time()
                sol = solve_ivp(model.rhs, (0.0, self.t_end), x0, method=name, t_eval=self.grid, rtol=rtol,
                                atol=rtol * 1e-2)
                cpu = time.process_time() - c0
                t, y = sol.t, sol.y.T
        except PymrError as exc:
            return None, None, math.nan, model.evaluations - e0, f"failed: {exc}"[:140]
        status = "ok" if sol.success else f"failed: {sol.message}"
        return np.asarray(t), y, cpu, model.evaluations - e0, status

    def _peer(self, name: str, rtol: float, repeats: int | None = None) -> Case:
        """A scipy or CVODE run on pymr's right-hand side, `repeats` times in a row (median CPU)."""
        case = Case(name, f"rtol={rtol:.1e}")
        if name.startswith("CVODE"):
            try:
                import sksundae.cvode  # noqa: F401
            except ImportError:
                case.status = "skipped: scikit-sundae is not installed (pip install scikit-sundae)"
                return case
        n = self.n
        with Model(self.scene) as model:
            t, y, cpu, evals, status = self._peer_run(model, name, rtol)
            if status != "ok":
                case.status = status
                return case
            case.rhs_full = evals
            case.error_m = self._error(t, model.marker(self.marker, t, y[:, :n], y[:, n:]))
            cpus = [cpu] + [self._peer_run(model, name, rtol)[2] for _ in range((repeats or self.repeats) - 1)]
        case.equivalents = float(case.rhs_full)
        self._set_cpu(case, cpus)
        return case

    # ---------------------------------------------------------------- reporting

    def write_csv(self, path: Path) -> None:
        write_file(path, self.csv_text(), "study's table")

    def csv_text(self) -> str:
        """The study's table: a row per case."""
        fh = io.StringIO(newline="")
        w = csv.DictWriter(fh, fieldnames=list(asdict(self.cases[0])))
        w.writeheader()
        for c in self.cases:
            row = asdict(c)
            if c.status == "ok" and math.isnan(c.equivalents):
                row["equivalents"] = ""          # a coupling whose weight was not measured (weights_text)
            w.writerow(row)
        return fh.getvalue()

    def best_at(self, error: float) -> dict[str, Case]:
        """Per method family (the method without its step ratio), the fastest case (by median
        CPU) with error <= `error`."""
        best: dict[str, Case] = {}
        for c in self.cases:
            if c.status != "ok" or not c.error_m <= error:
                continue
            fam = c.family
            if fam not in best or c.cpu_s < best[fam].cpu_s:
                best[fam] = c
        return best

    def front_summary(self, errors=FRONT_ERRORS) -> list[dict]:
        """Per error level: the fastest case of each family with error <= level ("best"),
        the fastest single-rate case (fixed or adaptive, "single"), the fastest multirate case
        ('response' or 'exponential', fixed or adaptive, "multirate"), and "ratio" = multirate CPU /
        single-rate CPU (nan when either has no case that accurate)."""
        out = []
        for level in errors:
            best = self.best_at(level)
            single = [best[f] for f in SINGLE_FAMILIES if f in best]
            multi = [best[f] for f in MULTIRATE_FAMILIES if f in best]
            s = min(single, key=lambda c: c.cpu_s) if single else None
            m = min(multi, key=lambda c: c.cpu_s) if multi else None
            ratio = m.cpu_s / s.cpu_s if s and m else math.nan
            pymr_best = [c for f, c in best.items() if f in SINGLE_FAMILIES + MULTIRATE_FAMILIES]
            fastest = min(pymr_best, key=lambda c: c.cpu_s) if pymr_best else None
            auto = best.get(AUTO_FAMILY)
            out.append({"error": level, "best": best, "single": s, "multirate": m, "ratio": ratio,
                        "auto": auto, "fastest": fastest,
                        "auto_ratio": auto.cpu_s / fastest.cpu_s if auto and fastest else math.nan,
                        "adaptive": self._adaptive_against_fixed(best)})
        return out

    @staticmethod
    def _adaptive_against_fixed(best: dict[str, Case]) -> dict[str, tuple]:
        """Per multirate coupling with cases at this level: (fastest adaptive case of either
        norm, fastest fixed case, adaptive CPU / fixed CPU)."""
        out = {}
        for coupling, (fixed_family, adaptive_families) in ADAPTIVE_AGAINST_FIXED.items():
            fixed = best.get(fixed_family)
            adaptive = min((best[f] for f in adaptive_families if f in best), key=lambda c: c.cpu_s, default=None)
            if fixed and adaptive:
                out[coupling] = (adaptive, fixed, adaptive.cpu_s / fixed.cpu_s)
        return out

    def front_text(self, errors=FRONT_ERRORS) -> str:
        lines = ["front: fastest case of each family (median CPU) with error <= level"]
        order = list(dict.fromkeys(c.family for c in self.cases))
        for row in self.front_summary(errors):
            lines.append(f"  error <= {row['error']:.0e} m")
            for fam in order:
                c = row["best"].get(fam)
                if c is None:
                    lines.append(f"    {fam:<30} {'(none this accurate)':<30}")
                else:
                    lines.append(f"    {fam:<30} {' '.join(x for x in (c.method[len(fam):].strip(), c.setting) if x):<30} "
                                 f"error {c.error_m:8.2e} m  CPU {c.cpu_s:8.4f} s  equivalents {c.equivalents:9.0f}")
            s, m = row["single"], row["multirate"]
            if s and m:
                lines.append(f"    fastest multirate / fastest single-rate: {m.cpu_s:.4f} s "
                             f"({m.method} {m.setting}) / {s.cpu_s:.4f} s ({s.method} {s.setting}) "
                             f"= {row['ratio']:.2f}")
            else:
                lines.append("    fastest multirate / fastest single-rate: n/a (a side has no case "
                             "this accurate)")
            for coupling, (a, f, ratio) in row["adaptive"].items():
                lines.append(f"    adaptive / fixed '{coupling}': {a.cpu_s:.4f} s ({a.method} {a.setting}) / "
                             f"{f.cpu_s:.4f} s ({f.method} {f.setting}) = {ratio:.2f}")
            a, f = row["auto"], row["fastest"]
            if a and f:
                lines.append(f"    method 'auto' / fastest pymr method: {a.cpu_s:.4f} s ({a.setting}) / {f.cpu_s:.4f} s "
                             f"({f.method} {f.setting}) = {row['auto_ratio']:.2f}")
        return "\n".join(lines)

    def order_summary(self, errors=ORDER_ERRORS) -> list[dict]:
        """Per error level: the fewest evaluations of formula 'adams' and of CVODE Adams that
        reach it ("adams", "cvode": the cases, None when none does, "evals_ratio"), and the
        CPU of the fastest 'adams' case over that of pymr's fastest fixed-order case
        ("fixed": fixed steps or adaptive 'abm4'; "cpu_ratio")."""
        out = []
        for level in errors:
            ok = [c for c in self.cases if c.status == "ok" and c.error_m <= level]
            adams = [c for c in ok if c.family == "adams adaptive"]
            cvode = [c for c in ok if c.family == "CVODE Adams"]
            fixed = [c for c in ok if c.family in FIXED_ORDER_FAMILIES]
            a = min(adams, key=lambda c: c.rhs_full, default=None)
            v = min(cvode, key=lambda c: c.rhs_full, default=None)
            a_cpu = min(adams, key=lambda c: c.cpu_s, default=None)
            f = min(fixed, key=lambda c: c.cpu_s, default=None)
            out.append({"error": level, "adams": a, "cvode": v, "fixed": f, "adams_cpu": a_cpu,
                        "evals_ratio": a.rhs_full / v.rhs_full if a and v else math.nan,
                        "cpu_ratio": a_cpu.cpu_s / f.cpu_s if a_cpu and f else math.nan})
        return out

    def order_text(self, errors=ORDER_ERRORS) -> str:
        lines = ["variable order: fewest evaluations reaching each error, and CPU against pymr's fastest "
                 "fixed-order run"]
        for r in self.order_summary(errors):
            a, v, f, ac = r["adams"], r["cvode"], r["fixed"], r["adams_cpu"]
            evals = (f"'adams' {a.rhs_full} ({a.setting}) / CVODE Adams {v.rhs_full} ({v.setting}) = "
                     f"{r['evals_ratio']:.2f}") if a and v else "evaluations: n/a (a side has no case this accurate)"
            cpu = (f"CPU 'adams' {ac.cpu_s:.4f} s / {f.method} {f.cpu_s:.4f} s ({f.setting}) = {r['cpu_ratio']:.2f}"
                   if ac and f else "CPU: n/a")
            lines.append(f"  error <= {r['error']:.0e} m: {evals}; {cpu}")
        return "\n".join(lines)

    def histories(self, rtols=HISTORY_RTOLS) -> dict[float, tuple]:
        """Step and order history of formula 'adams' at each tolerance: (t, h, order) of every
        accepted step (pymr.step_history on the study's scene)."""
        from .api import step_history
        out = {}
        for rtol in rtols:
            out[rtol] = step_history(self.scene, {"integrator.method": "single", "integrator.adaptive": True,
                                                  "integrator.rtol": rtol, "integrator.atol": rtol * 1e-2,
                                                  "integrator.formula": "adams"})
        return out

    @staticmethod
    def history_text(hist: dict) -> str:
        lines = ["step and order history of formula 'adams' (accepted steps per order; steps in s)"]
        for rtol, (t, h, q) in hist.items():
            counts = ", ".join(f"{k}: {int((q[1:] == k).sum())}" for k in range(1, 13) if (q[1:] == k).any())
            lines.append(f"  rtol {rtol:.0e}: {len(t) - 1} steps; order {counts}; step min {h[1:].min():.2e} "
                         f"median {np.median(h[1:]):.2e} max {h[1:].max():.2e}")
        return "\n".join(lines)

    @staticmethod
    def histories_text(hist: dict) -> str:
        """The step histories' table: a row per accepted step of each tolerance."""
        fh = io.StringIO(newline="")
        w = csv.writer(fh)
        w.writerow(["rtol", "t", "h", "order"])
        for rtol, (t, h, q) in hist.items():
            for row in zip(t[1:], h[1:], q[1:]):
                w.writerow([f"{rtol:.1e}", f"{row[0]:.10e}", f"{row[1]:.6e}", int(row[2])])
        return fh.getvalue()

    def refused(self) -> list[Case]:
        """The fixed-step multirate cases the pre-flight stability check refused."""
        return [c for c in self.cases if " fixed k=" in c.method and c.status.startswith("refused")]

    def refused_text(self) -> str:
        ref = self.refused()
        if not ref:
            return "fixed multirate cases refused by the pre-flight check: none"
        return "fixed multirate cases refused by the pre-flight check:\n" + "\n".join(
            f"  {c.method:<22} {c.setting:<16} {_short_reason(c)}" for c in ref)

    def not_plotted(self) -> list[str]:
        """The cases that are not points of the figure (refused, failed, skipped): one entry
        per method and reason, naming the settings."""
        groups: dict[tuple, list[str]] = {}
        for c in self.cases:
            if c.status != "ok":
                key = (c.method, c.status.split(":", 1)[0], _short_reason(c))
                groups.setdefault(key, []).append(c.setting)
        return [f"{method} {', '.join(settings)}: {kind} ({reason})"
                for (method, kind, reason), settings in groups.items()]

    def plot(self, path: Path) -> str:
        """The figure (:meth:`figure`) written to `path`; returns its note."""
        note, image = self.figure(Path(path).suffix.lstrip(".") or "png")
        write_file(path, image, "study's figure")
        return note

    def figure(self, kind: str = "png") -> tuple[str, bytes]:
        """The figure in the format `kind`: error against median CPU time and against
        full-evaluation equivalents. A case that is not a point (refused, failed, skipped) is
        counted in its method's legend entry and named in a note under the axes, which this
        returns with the image."""
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        notes = self.not_plotted()
        note = "not plotted: " + "; ".join(notes) if notes else ""
        wrapped = textwrap.fill(note, 190) if note else ""
        extra = 0.16 * (wrapped.count("\n") + 1) if note else 0.0
        fig, axes = plt.subplots(1, 2, figsize=(16, 6.2 + extra), sharey=True)
        methods = list(dict.fromkeys(c.method for c in self.cases))
        colours = {"single": plt.cm.Greys, "abm4": plt.cm.Purples, "adams": plt.cm.Reds, "response": plt.cm.Blues,
                   "full": plt.cm.Oranges, "exponential": plt.cm.Greens, "auto": plt.cm.copper}
        counts = {fam: 0 for fam in colours}
        shades = {fam: sum(1 for m in methods if m.split()[0] == fam) for fam in colours}
        peer_colours = iter(["tab:green", "tab:purple", "tab:olive", "tab:brown", "tab:pink"])
        for method in methods:
            cases = [c for c in self.cases if c.method == method]
            ok = [c for c in cases if c.status == "ok"]
            head = method.split()[0]
            if head in colours:
                counts[head] += 1
                colour = colours[head](0.45 + 0.5 * counts[head] / max(shades[head], 1))
                style = "-o" if "adaptive" in method else ":" + "^v<>Dp"[counts[head] % 6]   # a marker per ratio
            else:
                colour = next(peer_colours, None)
                style = "--s"
            kinds = [c.status.split(":", 1)[0] for c in cases if c.status != "ok"]
            label = method
            if kinds:      # a case that is not a point is named in the legend and in the note below
                label += " (" + ", ".join(f"{kinds.count(k)} {k}" for k in dict.fromkeys(kinds)) + ")"
            for ax, key in zip(axes, ("cpu_s", "equivalents")):
                pts = sorted(((getattr(c, key), c.error_m) for c in ok if np.isfinite(getattr(c, key))))
                ax.loglog([p[0] for p in pts], [p[1] for p in pts], style, label=label, ms=4, color=colour)
        for level in FRONT_ERRORS:
            for ax in axes:
                ax.axhline(level, color="0.6", lw=0.6, ls="-.")
        axes[0].set_xlabel(f"CPU time (s), median of {self.repeats} runs or more" if self.repeats > 1 else "CPU time (s)")
        w = ", ".join(f"{c} {self.weight[c]:.3f}" for c in COUPLINGS if c in self.weight)
        axes[1].set_xlabel(f"full-evaluation equivalents (rhs_full + w rhs_fast; measured w: {w})")
        axes[0].set_ylabel(f"largest error of marker '{self.marker}' (m)")
        for ax in axes:
            ax.grid(True, which="both", alpha=0.3)
        axes[1].legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)
        fig.suptitle(f"work-precision: {self.scene.path.name} (reference: pymr rtol 1e-11; DOP853 agrees to "
                     f"{self.ref_check:.1e} m)")
        if note:
            fig.text(0.01, 0.01, wrapped, fontsize=7, va="bottom", ha="left", color="firebrick")
        fig.tight_layout(rect=(0, extra / (6.2 + extra) + (0.02 if note else 0.0), 1, 1))
        image = io.BytesIO()
        fig.savefig(image, dpi=110, format=kind)
        plt.close(fig)
        return note, image.getvalue()

    def table(self) -> str:
        lines = [f"{'method':<30} {'setting':<16} {'error (m)':>10} {'CPU (s)':>9} {'full evals':>10} "
                 f"{'fast evals':>10} {'equivalents':>11}  status"]
        for c in self.cases:
            if c.status == "ok":
                lines.append(f"{c.method:<30} {c.setting:<16} {c.error_m:10.2e} {c.cpu_s:9.4f} {c.rhs_full:10d} "
                             f"{c.rhs_fast:10d} {c.equivalents:11.0f}  ok")
            else:
                lines.append(f"{c.method:<30} {c.setting:<16} {'':>10} {'':>9} {'':>10} {'':>10} {'':>11}  "
                             f"{c.status.split(':', 1)[0]}: {_short_reason(c)}")
        return "\n".join(lines)


def main(scene: str, marker: str | None = None, output: str | None = None, quick: bool = False,
         repeats: int | None = 5) -> int:
    prefix = check_study_prefix(scene, output)
    study = Study(scene, marker, quick=quick, repeats=5 if repeats is None else repeats)
    study.run_all()
    print()
    print(study.table())
    print()
    print(study.weights_text())
    print(study.refused_text())
    print()
    print(study.front_text())
    print()
    print(study.order_text())
    hist = study.histories()
    print(study.history_text(hist))
    table, figure, history = study_files(prefix)
    # the three files in place together (each written whole before any replaces its earlier one)
    write_files([(table, study.csv_text(), "study's table"),
                 (figure, study.figure(figure.suffix.lstrip("."))[1], "study's figure"),
                 (history, study.histories_text(hist), "step histories")])
    print(f"written: {table}, {figure}, {history}")
    return 0


def check_study_prefix(scene, output: str | os.PathLike | None) -> Path:
    """The output prefix (-o, default SCENE_study in the working folder) and the three files
    it names, checked by pymr's output rule before the study's minutes of runs: the prefix
    is not a folder and its folder is there; no file is a folder, the scene or a file the
    scene reads."""
    option = "-o" if output is not None else "the default prefix (-o to choose)"
    example = Path(getattr(scene, "path", scene)).stem + "_study"
    prefix = check_output(Path(example) if output is None else output, "study's files (a prefix of their names)",
                          option=option,
                          example=example)
    for path, what in zip(study_files(prefix), ("study's table", "study's figure", "step histories")):
        check_output(path, what, option=f"{option} {prefix}:", scene=scene)
    return prefix


def study_files(prefix: Path) -> tuple[Path, Path, Path]:
    """The files a study with output prefix `prefix` writes: its table, figure and step histories."""
    # the names follow the whole prefix: a dot in it ("t_0.05") is no suffix to replace
    return tuple(prefix.with_name(prefix.name + end) for end in (".csv", ".png", "_history.csv"))
