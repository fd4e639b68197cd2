"""The Python package's own structure (issue 31): pymr.api and pymr.scene do not import
each other, at the top of the file or inside a function; what both need is in pymr._args."""
from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parent.parent / "pymr"


def imported_modules(path: Path) -> set[str]:
    """Every pymr module `path` imports anywhere in it (``from . import x``, ``from .x import
    y``, ``import pymr.x``, ``from pymr.x import y``, inside functions too), by its name in the
    package."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.ImportFrom):
            if node.level == 1 or node.module == "pymr" or (node.module or "").startswith("pymr."):
                module = (node.module or "").removeprefix("pymr").lstrip(".")
                if module:
                    found.add(module.split(".")[0])
                else:                                    # from . import x, y
                    found.update(alias.name for alias in node.names)
        elif isinstance(node, ast.Import):
            for alias in node.names:
                if alias.name.startswith("pymr."):
                    found.add(alias.name.split(".")[1])
    return found


def test_the_import_reader_sees_imports_inside_functions(tmp_path):
    source = tmp_path / "m.py"
    source.write_text("from .a import b\nimport pymr.c\ndef f():\n    from . import d, e\n    from pymr.g import h\n")
    assert imported_modules(source) == {"a", "c", "d", "e", "g"}


def test_api_and_scene_do_not_import_each_other():
    assert "scene" not in imported_modules(PACKAGE / "api.py")
    assert "api" not in imported_modules(PACKAGE / "scene.py")
    # what both use lies below both
    assert "_args" in imported_modules(PACKAGE / "api.py") and "_args" in imported_modules(PACKAGE / "scene.py")
    assert not {"api", "scene"} & imported_modules(PACKAGE / "_args.py")


def test_no_module_reads_kernel_text_with_regexes():
    """Python reads the kernel's errors and columns from structured fields (PymrError.kind,
    .stable_step ...; Results.column_info), never by a regex over its words: only sweep.py
    imports re, to check a sweep file's metric (user input)."""
    users = {path.name for path in PACKAGE.glob("*.py") if "re" in imported_stdlib(path)}
    assert users <= {"sweep.py"}


def imported_stdlib(path: Path) -> set[str]:
    """The top-level names of the absolute imports of `path` (anywhere in it)."""
    found: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.add(node.module.split(".")[0])
    return found
