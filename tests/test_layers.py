"""The kernel's folders in one direction (issue 31): env/ (kinds, errors, text, LAPACK)
under everything; integrator/ and model/ above it; io/ (files of the scene, results and
checkpoints) above the model; driver/ (a run: loading, pre-flight, steppers, outputs) above
those; bind/ and app/ on top. A module may use modules of its own folder and of the folders
below it, never of one above: the test reads every `use` of every Fortran source, so a new
upward use fails it. Module names mirror their paths (pymr_FOLDER_FILE)."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent / "fortran"
LAYERS = ["env", "integrator", "model", "io", "driver", "bind", "app"]
LEVEL = {"env": 0, "integrator": 1, "model": 2, "io": 3, "driver": 4, "bind": 5, "app": 5}
USE = re.compile(r"^\s*use\s+(pymr_\w+)", re.I | re.M)
MODULE = re.compile(r"^\s*module\s+(pymr_\w+)\s*$", re.I | re.M)


def sources() -> list[Path]:
    return sorted(p for p in ROOT.rglob("*.f90"))


def module_folders() -> dict[str, str]:
    """Each module's folder (the first part of its path below fortran/)."""
    found = {}
    for p in sources():
        for name in MODULE.findall(p.read_text()):
            found[name.lower()] = p.relative_to(ROOT).parts[0]
    return found


def test_every_source_is_in_a_layer_folder():
    """No Fortran source lies at fortran/'s top level or in a folder outside the layers."""
    outside = [str(p.relative_to(ROOT)) for p in sources() if p.relative_to(ROOT).parts[0] not in LAYERS]
    assert outside == []


def test_no_folder_uses_a_folder_above_it():
    folders = module_folders()
    upward = []
    for p in sources():
        here = p.relative_to(ROOT).parts[0]
        for used in USE.findall(p.read_text()):
            there = folders.get(used.lower())
            assert there is not None, f"{p.relative_to(ROOT)} uses {used}, which no source defines"
            if LEVEL[there] > LEVEL[here]:
                upward.append(f"{p.relative_to(ROOT)} ({here}) uses {used} ({there})")
    assert upward == []


def test_module_names_mirror_their_paths():
    """pymr_<folder>_<file> for every module (pymr_<folder> for the folder's file of its own
    name, model/model.f90), one module a file, so that a `use` line tells where its module
    lives."""
    wrong = []
    for p in sources():
        rel = p.relative_to(ROOT)
        for name in MODULE.findall(p.read_text()):
            expected = f"pymr_{rel.parts[0]}" + ("" if p.stem == rel.parts[0] else f"_{p.stem}")
            if name.lower() != expected:
                wrong.append(f"{rel}: {name} (expected {expected})")
    assert wrong == []


def test_the_shipped_binding_exports_no_test_hook():
    """The test hooks (kernel internals for the suite) live in pymr._testhooks, an extension
    apart from pymr._core, and the ODE test problems are compiled into it alone, not into
    the kernel library that mrsim and _core link."""
    from pymr import _core, _testhooks
    hooks = {n for n in dir(_testhooks) if n.startswith("pymr_")}
    assert len(hooks) == 10 and not hooks & set(dir(_core))
    kernel = (ROOT / "meson.build").read_text().split("kernel_src = files(", 1)[1].split(")", 1)[0]
    assert "test_odes" not in kernel and "test_hooks" not in kernel
