"""The house rules of issue 31, read from the sources: derived types of at most 40
components, routines of at most 80 lines (Fortran and the pymr package), effects as
records (no numbered parameter columns, no dispatch of effects by `select case`), and every
effect of the registry a type extending effect_t. A change that breaks one of them fails
here with the place named."""
from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
FORTRAN = sorted((ROOT / "fortran").rglob("*.f90"))
MAX_FIELDS = 40
MAX_LINES = 80

HEAD = re.compile(r"^\s*(?:(?:pure|elemental|recursive|impure|module)\s+)*"
                  r"(?:(?:real|integer|logical|character)(?:\([^)]*\))?\s+)?(subroutine|function)\s+(\w+)", re.I)
END = re.compile(r"^\s*end\s+(subroutine|function)\b", re.I)
TYPE = re.compile(r"^\s*type\s*(?:,[^:]*)?::\s*(\w+)\s*$|^\s*type\s+(\w+)\s*$", re.I)


def code(line: str) -> str:
    """A Fortran line without its comment (no '!' inside the strings of these checks)."""
    return line.split("!")[0].rstrip()


def routine_lengths(path: Path) -> list[tuple[str, int]]:
    stack, out = [], []
    for i, line in enumerate(path.read_text().splitlines()):
        s = code(line)
        if END.match(s):
            name, start = stack.pop()
            out.append((name, i - start + 1))
        elif HEAD.match(s) and not s.lstrip().lower().startswith("end"):
            stack.append((HEAD.match(s).group(2), i))
    return out


def declared_names(decl: str) -> int:
    """Names in the entity list after '::' (commas inside brackets do not count)."""
    depth, n = 0, 1
    for ch in decl:
        depth += ch in "([" and 1 or (-1 if ch in ")]" else 0)
        n += ch == "," and depth == 0
    return n


def type_sizes(path: Path) -> list[tuple[str, int]]:
    out, name, count, statement = [], None, 0, ""
    for line in path.read_text().splitlines():
        s = code(line).strip()
        if name is None:
            m = TYPE.match(s)
            if m and not s.lower().startswith("type("):
                name, count = m.group(1) or m.group(2), 0
            continue
        if s.lower().startswith(("end type", "contains")):
            out.append((name, count))
            name = None
            continue
        statement = statement + " " + s.lstrip("&") if statement else s
        if statement.endswith("&"):
            statement = statement[:-1]
            continue
        if "::" in statement:
            count += declared_names(statement.split("::", 1)[1])
        statement = ""
    return out


def test_no_derived_type_has_more_than_40_components():
    big = [f"{p.relative_to(ROOT)}: {name} ({n})" for p in FORTRAN for name, n in type_sizes(p) if n > MAX_FIELDS]
    assert big == []


def test_the_counter_sees_the_model_types():
    """The component counter is not blind: model_work and model_data are counted, as
    many components as their declarations list (a check of the check)."""
    sizes = dict(type_sizes(ROOT / "fortran/model/types.f90"))
    assert 25 <= sizes["model_data"] <= MAX_FIELDS
    assert sizes["model_work"] >= 20
    assert sizes["marker_set"] == 6


def test_no_fortran_routine_is_longer_than_80_lines():
    long = [f"{p.relative_to(ROOT)}: {name} ({n} lines)" for p in FORTRAN for name, n in routine_lengths(p)
            if n > MAX_LINES]
    assert long == []


def test_no_python_function_is_longer_than_80_lines():
    long = []
    for p in sorted((ROOT / "pymr").glob("*.py")):
        for node in ast.walk(ast.parse(p.read_text())):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                n = node.end_lineno - node.lineno + 1
                if n > MAX_LINES:
                    long.append(f"{p.name}: {node.name} ({n} lines)")
    assert long == []


def test_no_parameter_is_kept_in_a_numbered_column():
    """Effect parameters are named record components: no `*_par` arrays, no `p(1..6)`
    read-backs of an associated column."""
    found = []
    for p in FORTRAN:
        for i, line in enumerate(p.read_text().splitlines(), 1):
            s = code(line)
            if re.search(r"\b\w+_par\s*\(", s) or re.search(r"associate\s*\(\s*p\s*=>", s):
                found.append(f"{p.relative_to(ROOT)}:{i}: {s.strip()}")
    assert found == []


def registry_effects() -> list[str]:
    """The constructors the registry (driver/build_effects.f90) appends."""
    text = (ROOT / "fortran/driver/build_effects.f90").read_text()
    return re.findall(r"call append\(list, (\w+?)_of\(", text)


def test_every_registered_effect_is_a_record_extending_effect_t():
    names = registry_effects()
    assert len(names) == 11
    types = {}
    for p in (ROOT / "fortran/model").glob("effect_*.f90"):
        for m in re.finditer(r"type, extends\(effect_t\) :: (\w+)", p.read_text()):
            types[m.group(1)] = p.name
    constructors = {re.sub(r"_effect$", "", t): t for t in types}
    for name in names:
        base = re.sub(r"_effect$", "", name)
        assert base in constructors or name in types, f"{name} has no record type extending effect_t"


def test_the_model_dispatches_no_effect():
    """model/model.f90 runs the effects' list by stage: no `select case`, and no effect
    named in its code."""
    text = "\n".join(code(line) for line in (ROOT / "fortran/model/model.f90").read_text().lower().splitlines())
    assert "select case" not in text
    for effect in ("gravity", "joint_drives", "modal_damping", "joint_springs", "geometric_stiffening",
                   "firing_load", "base_motion", "deformation_inertia", "force_elements", "moving_load"):
        assert effect not in text, effect
