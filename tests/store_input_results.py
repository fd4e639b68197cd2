"""Store the expected results of every scene in input/ with each scene's own sensitivity.

    python tests/store_input_results.py [SCENE ...]      (run from anywhere; mrsim on PATH)

For each scene this runs mrsim once as given, once for each of a few inputs moved by one ulp
(every rigid body's mass, every beam's density, each non-zero gravity component, the step or
rtol), and once for each of two changes of the last bits alone: glibc's libm on other code
paths, and OpenBLAS's LAPACK in place of the reference one. It keeps N_SAMPLES rows, evenly
spaced, and the last row, and for each kept value its sensitivity: the largest change any of
those runs made to it up to that row. tests/test_scene.py compares a new run against the kept
rows within a multiple of that sensitivity. Both kinds of change are needed: one ulp of an
input moves a beam's modes by about one ulp, while two LAPACKs' eigenvectors differ by about
1e-14 of their size, which moves the modal coordinates 100-1400 times as far
(docs/testing.md). Scenes that mrsim refuses keep their message. Only the scenes named on
the command line are stored again; the others are kept as they are.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
STORE = ROOT / "tests" / "data" / "input_results.json"
N_SAMPLES = 20
OPENBLAS = Path("/usr/lib/x86_64-linux-gnu/openblas-serial")


def scenes() -> list[Path]:
    """Every scene the stored-results test runs, in its order."""
    return sorted(ROOT.glob("input/*.nml")) + sorted(ROOT.glob("input/hard/*.nml"))


def data_lines(csv: Path) -> list[str]:
    """The header and the rows of a results file, without its comment lines."""
    return [ln for ln in csv.read_text().splitlines() if not ln.startswith("#")]


def run(mrsim: str, scene: Path, out: Path, overrides: list[str], env: dict | None = None) -> subprocess.CompletedProcess:
    """mrsim on the scene with the given --set overrides (and environment), quiet, results to out."""
    cmd = [mrsim, str(scene), "-o", str(out), "--quiet"]
    for item in overrides:
        cmd += ["--set", item]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=600,
                          env=None if env is None else {**os.environ, **env})


def last_bit_variants() -> dict[str, dict]:
    """Environments that change the last bits of a run without changing the scene: glibc's
    libm on its code paths without FMA and AVX2, and OpenBLAS's LAPACK in place of the
    reference one (Debian's libopenblas0-serial, which must be installed)."""
    if not OPENBLAS.is_dir():
        raise SystemExit(f"{OPENBLAS} not found: apt-get install libopenblas0-serial "
                         "(then update-alternatives --set liblapack.so.3-x86_64-linux-gnu back to the reference LAPACK)")
    return {"libm without FMA and AVX2": {"GLIBC_TUNABLES": "glibc.cpu.hwcaps=-AVX2,-FMA,-AVX512F"},
            "OpenBLAS LAPACK": {"LD_LIBRARY_PATH": str(OPENBLAS)}}


def sample_rows(n_rows: int) -> list[int]:
    """N_SAMPLES rows evenly spaced from the first to the last, the last always among them."""
    return sorted({int(round(i)) for i in np.linspace(0, n_rows - 1, N_SAMPLES + 1)})


def one_ulp_inputs(scene: Path) -> list[str]:
    """--set items moving one input each by one ulp up: rigid masses, beam densities, gravity."""
    import pymr
    sc = pymr.Scene(scene)
    moved = []
    for b in _names(sc, "body"):
        kind = sc[f"body[{b}].kind"]
        item = {"rigid": "mass", "beam": "density"}.get(kind)
        if item is not None:
            value = float(sc[f"body[{b}].{item}"])
            moved.append(f"body[{b}].{item}={float(np.nextafter(value, np.inf))!r}")
    if sc["integrator.adaptive"]:
        steps = ["integrator.rtol"]
    else:
        steps = ["integrator.h_slow", "integrator.h_fast"]
    moved.append(" ".join(f"{a}={float(np.nextafter(float(sc[a]), np.inf))!r}" for a in steps))
    gravity = np.array(sc["scene.gravity"], dtype=float)
    for i in np.flatnonzero(gravity):
        g = gravity.copy()
        g[i] = np.nextafter(g[i], np.inf)
        moved.append("scene.gravity=" + ",".join(repr(float(x)) for x in g))
    return moved


def _names(sc, group: str) -> list[str]:
    """Names of a group's records, in the resolved scene's order (name is each record's
    first item there)."""
    lines = [ln.strip() for ln in sc.resolved().splitlines()]
    return [nxt.split("'")[1] for ln, nxt in zip(lines, lines[1:])
            if ln == f"&{group}" and nxt.startswith("name = '")]


def store_one(mrsim: str, scene: Path, work: Path) -> dict:
    """The stored entry of one scene: its refusal, or its kept rows and their sensitivity."""
    out = work / "base.csv"
    r = run(mrsim, scene, out, [])
    if r.returncode == 1:
        return {"refused": r.stderr.strip().removeprefix("mrsim: error: ").replace(str(scene), str(scene.relative_to(ROOT)))}
    if r.returncode != 0:
        raise SystemExit(f"{scene}: mrsim exit {r.returncode}: {r.stderr.strip()}")
    lines = data_lines(out)
    header, rows = lines[0], np.array([[float(x) for x in ln.split(",")] for ln in lines[1:]])
    keep = sample_rows(len(rows))
    sens = np.zeros((len(keep), rows.shape[1]))
    changes = [(item.split(" "), None, item) for item in one_ulp_inputs(scene)]
    changes += [([], env, name) for name, env in last_bit_variants().items()]
    for overrides, env, name in changes:
        p = work / "moved.csv"
        rp = run(mrsim, scene, p, overrides, env)
        if rp.returncode != 0:
            raise SystemExit(f"{scene} ({name}): mrsim exit {rp.returncode}: {rp.stderr.strip()}")
        other = np.array([[float(x) for x in ln.split(",")] for ln in data_lines(p)[1:]])
        sens = np.maximum(sens, np.abs(other[keep] - rows[keep]))
    sens = np.maximum.accumulate(sens, axis=0)
    print(f"{scene.relative_to(ROOT)}: {len(rows)} rows, {len(changes)} changes, "
          f"largest sensitivity {sens.max():.3g}", file=sys.stderr)
    return {"rows": len(rows), "header": header, "changes": [name for _, _, name in changes], "kept_rows": keep,
            "values": [[repr(float(x)) for x in rows[i]] for i in keep],
            "sensitivity": [[float(f"{s:.3g}") for s in row] for row in sens]}


def main(argv: list[str]) -> None:
    from pymr._locate import mrsim_path
    mrsim = mrsim_path()
    chosen = [Path(a).resolve() for a in argv] or scenes()
    stored = json.loads(STORE.read_text()) if STORE.exists() else {}
    with tempfile.TemporaryDirectory() as tmp:
        for scene in chosen:
            stored[str(scene.relative_to(ROOT))] = store_one(mrsim, scene, Path(tmp))
    STORE.write_text(json.dumps(stored, indent=1) + "\n")


if __name__ == "__main__":
    main(sys.argv[1:])
