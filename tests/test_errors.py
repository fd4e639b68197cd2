"""Bad input gives one clear line, never a traceback: mrsim, pymr.run and the pymr CLI.

Contract (ARCHITECTURE.md, "Command line" and "Errors"):

* ``mrsim SCENE.nml [-o OUT.csv] [--set GROUP.ITEM=VALUE ...]`` on bad input exits with
  status 1 and writes exactly one line on stderr,
  ``mrsim: error: SCENE.nml: <group or item>: <what is wrong>``; a failed run (solver
  error) exits with status 2, also with one line. Never a Fortran runtime traceback.
* ``pymr.run(scene, output=..., overrides=...)`` raises ``pymr.SceneError`` (bad input) or
  ``pymr.SolverError`` (failed run) with the same message.
* ``pymr run SCENE.nml --set ...`` (console script and ``python -m pymr``) prints
  ``pymr: error: ...`` and exits with status 1 (2 for a failed run).

Every case below is a small valid scene with one thing broken, written to ``tmp_path``.
"""
from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

import pymr

TIMEOUT = 120

# A valid scene: the pendulum of input/pendulum.nml, run for a short time. No &output
# group, so the result file is always the one given with -o / output=.
BASE = """\
! pendulum for the error tests
&scene
  title = 'pendulum for error tests'
  t_end = 0.05
  gravity = 0.0, -9.81, 0.0
/
&integrator
  method = 'single'
  h_slow = 1.0e-3
/
&effects
  gravity = .true.
/
&body name = 'ground', kind = 'ground' /
&body
  name = 'bob', kind = 'rigid', mass = 1.0
  com = 0.0, -1.0, 0.0
  inertia = 4.0e-5, 4.0e-5, 4.0e-5, 0.0, 0.0, 0.0
/
&joint
  name = 'pivot', kind = 'revolute', parent = 'ground', child = 'bob'
  at = 0.0, 0.0, 0.0, axis = 0.0, 0.0, 1.0, q0 = 1.0
/
&marker name = 'tip', body = 'bob', at = 0.0, -1.0, 0.0 /
"""

SCENE_GROUP = BASE[BASE.index("&scene"):BASE.index("&integrator")]
INTEGRATOR_GROUP = BASE[BASE.index("&integrator"):BASE.index("&effects")]
BODY_GROUP = BASE[BASE.index("&body name = 'ground'"):BASE.index("&joint")]


def replaced(old: str, new: str) -> str:
    """BASE with the first `old` replaced by `new` (which must be there)."""
    assert old in BASE, old
    return BASE.replace(old, new, 1)


def line_of(text: str, needle: str) -> int:
    """1-based line number of the first `needle` in `text`."""
    return text[:text.index(needle)].count("\n") + 1


def rigid(name: str) -> str:
    return (f"&body name = '{name}', kind = 'rigid', mass = 1.0, "
            "inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /\n")


def revolute(name: str, parent: str, child: str) -> str:
    return (f"&joint name = '{name}', kind = 'revolute', parent = '{parent}', "
            f"child = '{child}', axis = 0.0, 0.0, 1.0 /\n")


def damped_beam(damping: str) -> str:
    """BASE with a damped beam 'arm' hung from the bob (two modes: one per plane)."""
    return (BASE.replace("gravity = .true.", "gravity = .true., modal_damping = .true.")
            + "&body name = 'arm', kind = 'beam', length = 1.0, youngs_modulus = 2.0e11, density = 7800.0,\n"
              f"      area = 1.0e-4, iy = 1.0e-9, iz = 1.0e-9, modes_y = 1, modes_z = 1, modal_damping = {damping} /\n"
              "&joint name = 'mount', kind = 'fixed', parent = 'bob', child = 'arm' /\n")


DIRECTORY = "<directory>"          # the scene path is a directory
GARBAGE = bytes(range(256)) * 16   # binary garbage (no '&name' anywhere)


@dataclass(frozen=True)
class Case:
    """One bad input: a scene file (or none), --set entries and the expected message parts."""
    id: str
    scene: str | bytes | None      # text or bytes written to <id>.nml; None: no file
    expect: tuple[str, ...]        # parts the message must contain (besides the file name)
    sets: tuple[str, ...] = ()     # --set GROUP.ITEM=VALUE entries
    pattern: str | None = None     # a regular expression the message must match too

    @property
    def file(self) -> str:
        return f"{self.id}.nml"


_UNKNOWN_ITEM = replaced("mass = 1.0", "masss = 1.0")
_UNKNOWN_GROUP = BASE + "&bodyy name = 'extra', kind = 'rigid' /\n"
# a value that cannot be read is reported at the line where its group starts
BOB_GROUP_START = "&body\n  name = 'bob'"
_MASS_TEXT = replaced("mass = 1.0", "mass = 'abc'")
_MASS_TWO = replaced("mass = 1.0", "mass = 1.0, 2.0")

CASES = [
    # 1. unknown item in a group
    Case("unknown_item", _UNKNOWN_ITEM,
         ("&body", "'masss'", "unknown item", f":{line_of(_UNKNOWN_ITEM, 'masss')}: ", "did you mean 'mass'?")),
    # 2. unknown group
    Case("unknown_group", _UNKNOWN_GROUP,
         ("&bodyy", "unknown group", f":{line_of(_UNKNOWN_GROUP, '&bodyy')}: ", "did you mean &body?")),
    # 3. missing required groups; a single group given twice
    Case("missing_scene", BASE.replace(SCENE_GROUP, ""), ("&scene", "missing group")),
    Case("missing_integrator", BASE.replace(INTEGRATOR_GROUP, ""), ("&integrator", "missing group")),
    Case("missing_body", BASE.replace(BODY_GROUP, "").replace(
        "&marker name = 'tip', body = 'bob', at = 0.0, -1.0, 0.0 /\n", ""), ("&body", "missing group")),
    Case("scene_twice", BASE + SCENE_GROUP, ("&scene", "twice")),
    # 4. unknown body name in a joint
    Case("unknown_parent", replaced("parent = 'ground'", "parent = 'nobody'"),
         ("&joint", "'pivot'", "parent", "'nobody'")),
    Case("unknown_child", replaced("child = 'bob'", "child = 'nobody'"),
         ("&joint", "'pivot'", "child", "'nobody'")),
    # 5. two parents for one body: the second joint closes a loop, and has no coordinates to start
    Case("two_parents", BASE + rigid("other") + revolute("j_other", "ground", "other")
         + revolute("second", "other", "bob").replace("'revolute'", "'free'").replace(
             " /\n", ", child_at = 0.0, 0.0, 0.0, qd0 = 0.0, 0.0, 0.0, 0.0, 0.0, 1.0 /\n"),
         ("&joint", "'second'", "qd0", "closes a loop", "no coordinates of its own")),
    # 5b. a second joint to a body that does not say it closes a loop (no child_at): a
    # repeated child written by mistake is refused, not run as a constraint
    Case("repeated_child", BASE + rigid("other") + revolute("j_other", "ground", "other")
         + revolute("second", "other", "bob"),
         ("&joint", "'second'", "child", "'bob' already has a parent joint ('pivot')", "child_at")),
    # 6. a cycle a -> b -> a (the ground reaches 'bob' only), and a body joined to itself
    Case("cycle", BASE + rigid("a") + rigid("b") + revolute("ab", "a", "b") + revolute("ba", "b", "a"),
         ("cycle",), pattern=r"&(body|joint) '(a|b|ab|ba)'"),
    Case("self_joint", BASE + revolute("self", "bob", "bob"),
         ("&joint", "'self'", "'bob'", "itself")),
    # made by a --set of the parent: the --set is named, not the file's child line
    Case("self_joint_by_set", BASE, ("--set joint[pivot].parent=bob: &joint 'pivot': parent: the joint joins body "
                                     "'bob' to itself",), sets=("joint[pivot].parent=bob",)),
    # 7. bad joint kind
    Case("bad_joint_kind", replaced("kind = 'revolute'", "kind = 'hinge'"),
         ("&joint", "'pivot'", "kind", "'hinge'")),
    # 8. mass and inertia
    Case("mass_negative", replaced("mass = 1.0", "mass = -1.0"), ("&body", "'bob'", "mass", "must be in [1e-12, 1e+12], got -1")),
    Case("mass_zero", replaced("mass = 1.0", "mass = 0.0"), ("&body", "'bob'", "mass", "must be in [1e-12, 1e+12], got 0")),
    Case("inertia_not_positive_definite",
         replaced("inertia = 4.0e-5, 4.0e-5, 4.0e-5", "inertia = 1.0, 1.0, -1.0"),
         ("&body", "'bob'", "inertia", "positive definite")),
    Case("inertia_triangle",
         replaced("inertia = 4.0e-5, 4.0e-5, 4.0e-5", "inertia = 1.0, 1.0, 5.0"),
         ("&body", "'bob'", "inertia", "triangle inequality")),
    # 9. h_slow not an integer multiple of h_fast
    Case("h_slow_not_multiple", replaced("h_slow = 1.0e-3", "h_fast = 1.0e-4, h_slow = 2.5e-4"),
         ("&integrator", "h_slow", "h_fast", "integer multiple")),
    # 10. missing file, a directory, binary garbage
    Case("missing_file", None, ("not found",)),
    Case("directory", DIRECTORY, ("cannot read",)),
    Case("garbage", GARBAGE, (":1: ", "text outside a group", "'??????????'")),
    # bytes that are not UTF-8 are quoted as '?' (a message is text, one line, for mrsim and Python);
    # UTF-8 that Python would not decode (an overlong form) is not text either
    Case("value_not_utf8", replaced("mass = 1.0", "mass = 1.0\xff\xfe").encode("latin-1"),
         ("&body", "'bob'", "mass: '1.0??' is not a number")),
    Case("title_overlong_utf8", replaced("title = 'pendulum", "title = '\xe0\x80\x80").encode("latin-1"),
         ("&scene", "title", "not UTF-8")),
    # 11. zero-length axis
    Case("zero_axis", replaced("axis = 0.0, 0.0, 1.0", "axis = 0.0, 0.0, 0.0"),
         ("&joint", "'pivot'", "axis", "zero length")),
    # 12. a value of the wrong type, too many values
    Case("mass_text", _MASS_TEXT,
         ("&body", "mass: 'abc' is not a number", f":{line_of(_MASS_TEXT, 'mass = ')}: ")),
    Case("mass_two_values", _MASS_TWO, ("&body", "mass: takes 1 value, got 2")),
    # 13. --set errors
    Case("set_unknown_group", BASE, ("--set", "bodyy.mass=2", "unknown group", "'bodyy'"),
         sets=("bodyy.mass=2",)),
    Case("set_unknown_item", BASE, ("--set", "&body", "unknown item", "'masss'"),
         sets=("body[bob].masss=2",)),
    Case("set_repeated_group_without_name", BASE, ("--set", "&body", "repeated", "body[NAME].mass"),
         sets=("body.mass=2",)),
    Case("set_name_matches_no_group", BASE, ("--set", "&body", "'nobody'"),
         sets=("body[nobody].mass=2",)),
    Case("set_malformed", BASE, ("--set", "body[bob].mass", "GROUP.ITEM=VALUE"),
         sets=("body[bob].mass",)),
    Case("set_single_group_with_name", BASE, ("--set", "&scene", "scene.t_end"),
         sets=("scene[x].t_end=1",)),
    Case("set_bad_value", BASE, ("--set", "body[bob].mass=abc", "'abc' is not a number"),
         sets=("body[bob].mass=abc",)),
    Case("set_invalid_value", BASE, ("&body", "'bob'", "mass", "must be in [1e-12, 1e+12], got -1"),
         sets=("body[bob].mass=-1",)),
    # items a run does not use, which it ignored
    Case("corrector_of_fixed_steps", BASE, ("&integrator", "corrector", "formula 'adams'", "leave it out"),
         sets=("integrator.corrector='fixed-point'",)),
    Case("articulated_multirate", BASE, ("&integrator", "dynamics", "'articulated'", "multirate", "method = 'single'"),
         sets=("integrator.method='multirate'", "integrator.dynamics='articulated'")),
    # 14. drives given, &effects joint_drives off
    Case("drive_without_joint_drives", BASE + "&drive joint = 'pivot', offset = 1.0 /\n",
         ("&drive", "joint_drives")),
    # 15. modal damping is a fraction of critical: critical (1) and beyond, or negative, is refused
    Case("modal_damping_critical", damped_beam("1.0"),
         ("&body", "'arm'", "modal_damping", "[0, 1)", "got 1")),
    Case("modal_damping_overcritical_mode", damped_beam("0.02, 1.5"),
         ("&body", "'arm'", "modal_damping", "[0, 1)", "got 1.5")),
    Case("modal_damping_negative", damped_beam("-0.01"),
         ("&body", "'arm'", "modal_damping", "[0, 1)", "got -0.01")),
    # 16. found by fuzzing (each was a hang, a crash or a silent acceptance)
    # a beam of more than 100 elements with 51 modes in a family: the banded eigensolver's
    # shifts would need a dense mesh of 408 elements (with 13 it recursed without end)
    Case("banded_beam_modes", damped_beam("0.01").replace("modes_y = 1,", "n_elements = 101, modes_y = 51,"),
         ("&body", "'arm'", "modes_y", "at most 50 modes per family on a beam of more than 100 elements", "got 51")),
    # an adaptive step bound that no step can keep: h_max below h_min's default of 1e-12 s
    Case("h_max_below_h_min", BASE, ("&integrator", "h_max", "below the smallest adaptive step h_min = 1e-12 s"),
         sets=("integrator.adaptive=.true.", "integrator.h_max=1e-13")),
    Case("h_max_too_many_steps", BASE, ("&integrator", "h_max", "more than max_steps = 1000"),
         sets=("integrator.adaptive=.true.", "integrator.h_max=1e-6", "integrator.max_steps=1000")),
    Case("h_min_beyond_t_end", BASE, ("&integrator", "h_min", "must be below t_end = 0.05 s"),
         sets=("integrator.adaptive=.true.", "integrator.h_min=0.1")),
    # a repeat count gives as many values as it stands for
    Case("q0_repeat_count", replaced("q0 = 1.0", "q0 = 3*1.0"),
         ("&joint", "'pivot'", "q0", "a revolute joint has 1 coordinate, got 3 values")),
    # names head the results' columns
    Case("name_with_comma", BASE.replace("'pivot'", "'pi,vot'"),
         ("&joint", "name", "may not hold a comma")),
    # a leading blank ran, and its column ' tip.x' was then refused where the results are read
    Case("name_with_leading_blank", BASE.replace("&marker name = 'tip'", "&marker name = ' tip'"),
         ("&marker", "name", "may not begin with a blank")),
    # a number below the smallest normal one (it made a spin-up's acceleration infinite)
    Case("subnormal_value", BASE, ("&body", "'bob'", "mass", "'4.9e-324' is below the smallest normal number"),
         sets=("body[bob].mass=4.9e-324",)),
    # one that rounds to 0 was taken as 0, silently (q0 = 1e-400 started at 0)
    Case("value_rounding_to_zero", BASE, ("&joint", "'pivot'", "q0", "'1e-400' is below the smallest normal number"),
         sets=("joint[pivot].q0=1e-400",)),
    Case("digits_rounding_to_zero", replaced("mass = 1.0", "mass = 0." + "0" * 400 + "1"),
         ("&body", "'bob'", "mass", "is below the smallest normal number")),
    # a repeat N*VALUE of text (a marker was named "'tip'" with its quotes)
    Case("repeat_of_text", replaced("&marker name = 'tip'", "&marker name = 1*'tip'"),
         ("&marker", "name", "cannot read 1*'tip' (a repeat N*VALUE is of numbers or logicals: give text once)")),
    # an item of another form of &motion (&load, &drive and &moving_load refused theirs)
    Case("motion_item_of_another_form", BASE.replace("gravity = .true.", "gravity = .true., base_motion = .true.")
         + "&motion joint = 'pivot', form = 'sine', amplitude = 0.1, frequency = 1.0, rate = 2.0 /\n",
         ("&motion", "rate", "only form 'spinup' uses it (form is 'sine')")),
]

CASE_PARAMS = [pytest.param(c, id=c.id) for c in CASES]


def write_case(case: Case, folder: Path) -> str:
    """Create the case's scene in `folder`; return its (relative) file name."""
    path = folder / case.file
    if case.scene is None:
        pass
    elif case.scene == DIRECTORY:
        path.mkdir()
    elif isinstance(case.scene, bytes):
        path.write_bytes(case.scene)
    else:
        path.write_text(case.scene)
    return case.file


def set_args(sets) -> list[str]:
    args: list[str] = []
    for s in sets:
        args += ["--set", s]
    return args


def check_message(message: str, case: Case) -> None:
    """`message` (without the program prefix) names the file first (with the line where the
    fault stands in it), then the case's parts."""
    assert re.match(re.escape(case.file) + r"(:\d+)?: ", message), \
        f"message does not start with the scene file name {case.file!r}: {message!r}"
    for part in case.expect:
        assert part in message, f"{part!r} not in message {message!r}"
    if case.pattern:
        assert re.search(case.pattern, message), f"{case.pattern!r} does not match {message!r}"


def error_line(stderr: str, prefix: str) -> str:
    """The line of stderr that starts with `prefix` (checked for being the only one later)."""
    for line in stderr.splitlines():
        if line.startswith(prefix):
            return line
    pytest.fail(f"no line starting with {prefix!r} on stderr:\n{stderr}")


def check_single_line(stderr: str, prefix: str) -> None:
    """stderr is exactly one line starting with `prefix`: no traceback, no ERROR STOP."""
    assert "Backtrace" not in stderr and "ERROR STOP" not in stderr and "Traceback" not in stderr, \
        f"traceback on stderr:\n{stderr}"
    lines = stderr.splitlines()
    assert len(lines) == 1, f"expected one line on stderr, got {len(lines)}:\n{stderr}"
    assert lines[0].startswith(prefix)


def run_mrsim(mrsim: str, args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([mrsim, *args], cwd=cwd, capture_output=True, text=True, timeout=TIMEOUT)


def run_cli(command: list[str], args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([*command, *args], cwd=cwd, capture_output=True, text=True, timeout=TIMEOUT)


def console_script() -> str:
    cand = Path(sys.executable).parent / "pymr"
    if cand.exists():
        return str(cand)
    found = shutil.which("pymr")
    if not found:
        pytest.fail("the pymr console script is not installed")
    return found


def read_csv(path: Path) -> tuple[list[str], list[list[float]]]:
    lines = [ln for ln in path.read_text().splitlines() if ln.strip() and not ln.startswith("#")]
    header = [h.strip() for h in lines[0].split(",")]
    rows = [[float(x) for x in ln.split(",")] for ln in lines[1:]]
    return header, rows


# ---------------------------------------------------------------------------------- mrsim

@pytest.mark.parametrize("case", CASE_PARAMS)
def test_mrsim_bad_input(mrsim, tmp_path, case):
    name = write_case(case, tmp_path)
    r = run_mrsim(mrsim, [name, "-o", "out.csv", *set_args(case.sets)], tmp_path)
    assert r.returncode == 1, f"exit status {r.returncode}, stderr:\n{r.stderr}"
    line = error_line(r.stderr, "mrsim: error: ")
    check_message(line[len("mrsim: error: "):], case)
    check_single_line(r.stderr, "mrsim: error: ")
    assert r.stdout == "", f"stdout not empty on bad input:\n{r.stdout}"


@pytest.mark.parametrize("args, expect", [
    pytest.param([], "no scene file", id="no_arguments"),
    pytest.param(["--bogus"], "--bogus", id="unknown_option"),
    pytest.param(["a.nml", "b.nml"], "one scene file", id="two_scenes"),
    pytest.param(["a.nml", "-o"], "-o", id="output_without_name"),
    pytest.param(["a.nml", "--set"], "--set", id="set_without_value"),
    pytest.param(["a.nml", "--set", ""], "--set needs GROUP.ITEM=VALUE (got an empty one)", id="set_empty"),
    # an option where the value belongs: the value was left out (-o --quiet wrote a file '--quiet')
    pytest.param(["a.nml", "-o", "--quiet"], "-o needs a file name (got the option --quiet)", id="output_option"),
    pytest.param(["a.nml", "--restart", "-o", "x.csv"], "--restart needs a checkpoint file (got the option -o)",
                 id="restart_option"),
    pytest.param(["a.nml", "--set", "-o", "x.csv"], "--set needs GROUP.ITEM=VALUE (got the option -o)",
                 id="set_option"),
])
def test_mrsim_usage_error(mrsim, tmp_path, args, expect):
    r = run_mrsim(mrsim, args, tmp_path)
    assert r.returncode == 1, f"exit status {r.returncode}, stderr:\n{r.stderr}"
    line = error_line(r.stderr, "mrsim: error: ")
    assert expect in line
    check_single_line(r.stderr, "mrsim: error: ")
    assert r.stdout == ""


# ------------------------------------------------------------------------------ pymr.run

@pytest.mark.parametrize("case", CASE_PARAMS)
def test_run_raises_scene_error(tmp_path, monkeypatch, case):
    monkeypatch.chdir(tmp_path)
    name = write_case(case, tmp_path)
    with pytest.raises(pymr.SceneError) as info:
        pymr.run(name, output=tmp_path / "out.csv", overrides=list(case.sets) or None)
    message = str(info.value)
    assert "\n" not in message.strip(), f"message has several lines: {message!r}"
    check_message(message, case)


@pytest.mark.parametrize("case", CASE_PARAMS)
def test_run_message_same_as_mrsim(mrsim, tmp_path, monkeypatch, case):
    """pymr.run raises with the very message mrsim prints."""
    monkeypatch.chdir(tmp_path)
    name = write_case(case, tmp_path)
    r = run_mrsim(mrsim, [name, "-o", "out.csv", *set_args(case.sets)], tmp_path)
    line = error_line(r.stderr, "mrsim: error: ")
    with pytest.raises(pymr.SceneError) as info:
        pymr.run(name, output=tmp_path / "out.csv", overrides=list(case.sets) or None)
    assert "mrsim: error: " + str(info.value) == line


def test_run_overrides_mapping_errors(tmp_path, monkeypatch):
    """The mapping form of overrides reports the same errors as the list form."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "base.nml").write_text(BASE)
    with pytest.raises(pymr.SceneError, match=r"--set body\[bob\].masss=2.0: &body 'bob': unknown item 'masss' \(known: .*\); did you mean 'mass'\?"):
        pymr.run("base.nml", output=tmp_path / "out.csv", overrides={"body[bob].masss": 2.0})
    with pytest.raises(pymr.SceneError, match=r"no &body group with name 'nobody'"):
        pymr.run("base.nml", output=tmp_path / "out.csv", overrides={"body[nobody].mass": 2.0})
    with pytest.raises(pymr.SceneError, match=r"repeated group"):
        pymr.run("base.nml", output=tmp_path / "out.csv", overrides={"body.mass": 2.0})


def test_text_beyond_ascii_reaches_the_kernel(tmp_path, monkeypatch):
    """A scene path, an output path and override values with characters beyond ASCII pass
    to the kernel as they are (f2py took only ASCII text, and pymr raised a TypeError with a
    traceback), and a bad one is reported in the kernel's words."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "pendel_ü.nml").write_text(BASE)
    res = pymr.run("pendel_ü.nml", output="ergebnis_ö.csv", overrides={"scene.title": "Zürich"})
    assert res.stats["title"] == "Zürich" and (tmp_path / "ergebnis_ö.csv").exists()
    scene = pymr.Scene("pendel_ü.nml")
    scene["scene.title"] = "Genève"
    assert scene["scene.title"] == "Genève"
    with pytest.raises(pymr.SceneError, match=r"^pendel_ü\.nml: --set body\[bob\]\.mass=é: &body 'bob': "
                                              r"mass: 'é' is not a number$"):
        pymr.run("pendel_ü.nml", overrides=["body[bob].mass=é"])
    r = run_cli([console_script()], ["run", "pendel_ü.nml", "-o", "ö.csv", "--set", "body[bob].mass=é"], tmp_path)
    assert r.returncode == 1
    check_single_line(r.stderr, "pymr: error: pendel_ü.nml: --set body[bob].mass=é: ")


def test_an_empty_scene_path_is_named_as_such(tmp_path, monkeypatch):
    """An empty scene path (mrsim's command line refuses it before the kernel) gave
    ': file not found', a message naming nothing."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(pymr.SceneError, match=r"^no scene file given \(its path is empty\)$"):
        pymr.run("")


# ----------------------------------------------------------------------------- pymr CLI

@pytest.mark.parametrize("case", CASE_PARAMS)
def test_python_m_pymr_bad_input(tmp_path, case):
    name = write_case(case, tmp_path)
    r = run_cli([sys.executable, "-m", "pymr"], ["run", name, "-o", "out.csv", *set_args(case.sets)],
                tmp_path)
    assert r.returncode == 1, f"exit status {r.returncode}, stderr:\n{r.stderr}"
    line = error_line(r.stderr, "pymr: error: ")
    check_message(line[len("pymr: error: "):], case)
    check_single_line(r.stderr, "pymr: error: ")
    assert r.stdout == ""


@pytest.mark.parametrize("case", [c for c in CASE_PARAMS
                                  if c.id in ("unknown_item", "missing_file", "set_unknown_item")])
def test_console_script_bad_input(tmp_path, case):
    name = write_case(case, tmp_path)
    r = run_cli([console_script()], ["run", name, "-o", "out.csv", *set_args(case.sets)], tmp_path)
    assert r.returncode == 1, f"exit status {r.returncode}, stderr:\n{r.stderr}"
    line = error_line(r.stderr, "pymr: error: ")
    check_message(line[len("pymr: error: "):], case)
    check_single_line(r.stderr, "pymr: error: ")
    assert r.stdout == ""


# ---------------------------------------------------------------- overrides take effect

def test_mrsim_without_overrides(mrsim, tmp_path):
    """The base scene runs: q0 = 1, ends at t_end = 0.05 (the reference for the tests below)."""
    (tmp_path / "base.nml").write_text(BASE)
    r = run_mrsim(mrsim, ["base.nml", "-o", "out.csv"], tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""
    header, rows = read_csv(tmp_path / "out.csv")
    assert rows[0][header.index("pivot.q")] == pytest.approx(1.0, abs=1e-12)
    assert rows[-1][header.index("t")] == pytest.approx(0.05, abs=1e-9)


def test_mrsim_set_q0(mrsim, tmp_path):
    (tmp_path / "base.nml").write_text(BASE)
    r = run_mrsim(mrsim, ["base.nml", "-o", "out.csv", "--set", "joint[pivot].q0=0.5"], tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""
    header, rows = read_csv(tmp_path / "out.csv")
    assert rows[0][header.index("t")] == 0.0
    assert rows[0][header.index("pivot.q")] == pytest.approx(0.5, abs=1e-12)


def test_mrsim_set_t_end(mrsim, tmp_path):
    (tmp_path / "base.nml").write_text(BASE)
    r = run_mrsim(mrsim, ["base.nml", "-o", "out.csv", "--set", "scene.t_end=0.5"], tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""
    header, rows = read_csv(tmp_path / "out.csv")
    assert rows[-1][header.index("t")] == pytest.approx(0.5, abs=1e-9)


def test_mrsim_quiet_success_prints_nothing(mrsim, tmp_path):
    (tmp_path / "base.nml").write_text(BASE)
    r = run_mrsim(mrsim, ["base.nml", "-o", "out.csv", "--quiet"], tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stdout == "" and r.stderr == ""


@pytest.mark.parametrize("overrides", [
    pytest.param({"joint[pivot].q0": 0.5, "scene.t_end": 0.5}, id="mapping"),
    pytest.param(["joint[pivot].q0=0.5", "scene.t_end=0.5"], id="list"),
])
def test_run_overrides_take_effect(tmp_path, monkeypatch, overrides):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "base.nml").write_text(BASE)
    res = pymr.run("base.nml", output=tmp_path / "out.csv", overrides=overrides)
    assert res["pivot.q"][0] == pytest.approx(0.5, abs=1e-12)
    assert res.t[-1] == pytest.approx(0.5, abs=1e-9)


def test_python_m_pymr_overrides_take_effect(tmp_path):
    (tmp_path / "base.nml").write_text(BASE)
    r = run_cli([sys.executable, "-m", "pymr"],
                ["run", "base.nml", "-o", "out.csv", "--set", "joint[pivot].q0=0.5",
                 "--set", "scene.t_end=0.5"], tmp_path)
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""
    header, rows = read_csv(tmp_path / "out.csv")
    assert rows[0][header.index("pivot.q")] == pytest.approx(0.5, abs=1e-12)
    assert rows[-1][header.index("t")] == pytest.approx(0.5, abs=1e-9)


# ------------------------------------------------------------- a failed run: exit status 2

# Adaptive steps on the stiff barrel with h_min = 1e-4 s: its 1015 Hz mode needs steps below
# 6.7e-5 s to stay stable, so the controller's next step falls below h_min (step size underflow).
UNDERFLOW = (Path(__file__).resolve().parent.parent / "input" / "hard" / "stiff_barrel.nml").read_text().replace(
    "  h_slow = 1.0e-4\n", "  h_slow = 1.0e-4\n  adaptive = .true.\n  h_min = 1.0e-4\n")


def test_mrsim_solver_failure_exit_2(mrsim, tmp_path):
    (tmp_path / "underflow.nml").write_text(UNDERFLOW)
    r = run_mrsim(mrsim, ["underflow.nml", "-o", "out.csv"], tmp_path)
    assert r.returncode == 2, f"exit status {r.returncode}, stderr:\n{r.stderr}"
    line = error_line(r.stderr, "mrsim: error: ")
    assert "step size underflow" in line
    assert line.startswith("mrsim: error: underflow.nml: "), f"the scene file is not named: {line!r}"
    assert line.count("underflow.nml") == 1, f"the scene file is named twice: {line!r}"
    check_single_line(r.stderr, "mrsim: error: ")


#: A sliding block on a spring of omega = 100 rad/s at h = 1e-2 s (omega h = 1, beyond the
#: step's stability limit 0.43), the pre-flight check off: the motion grows 1.4x a step.
DIVERGING = """&scene title = 'diverging', t_end = 100 /
&integrator method = 'single', h_slow = 1.0e-2, stability_check = .false. /
&effects joint_springs = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'blk', kind = 'rigid', mass = 1.0, inertia = 1, 1, 1, 0, 0, 0 /
&joint name = 'slide', kind = 'prismatic', parent = 'ground', child = 'blk', axis = 1, 0, 0, q0 = 1.0 /
&spring joint = 'slide', stiffness = 1.0e4 /
&output dt = 0.01, quantities = 'coordinates' QUANTITIES /
"""


@pytest.mark.parametrize("energy", [True, False])
def test_a_motion_that_grows_beyond_the_numbers_fails_naming_it(mrsim, tmp_path, energy):
    """With the energy columns the spring's energy overflowed first: its rows held inf and
    NaN, with exit 0. Without them the state overflowed and the run blamed the mass matrix
    ("not positive definite: the articulated inertia of coordinate slide.q is          NaN").
    Each is now exit 2 naming the time and what overflowed, and no row holds a number
    that is not finite."""
    (tmp_path / "d.nml").write_text(DIVERGING.replace(" QUANTITIES", ", 'energy'" if energy else ""))
    r = run_mrsim(mrsim, ["d.nml", "-o", "out.csv"], tmp_path)
    assert r.returncode == 2, r.stderr
    check_single_line(r.stderr, "mrsim: error: ")
    if energy:
        assert re.fullmatch(r"mrsim: error: d\.nml: at t = 4\.\d+ s: the results' column energy\.springs is Inf, not "
                            r"a finite number: the motion has grown beyond what can be written \(an unstable step, "
                            r"or a force that grows without bound\)\n", r.stderr), r.stderr
    else:
        assert re.fullmatch(r"mrsim: error: d\.nml: at t = \S+ s: the motion has grown beyond the numbers: the "
                            r"articulated inertia of coordinate slide\.q is NaN \(an unstable step, or a force that "
                            r"grows without bound\)\n", r.stderr), r.stderr
    rows = [line for line in (tmp_path / "out.csv.partial").read_text().splitlines() if line[:1].isdigit()]
    assert len(rows) > 400 and not any(w in line.lower() for line in rows for w in ("inf", "nan"))
    assert not (tmp_path / "out.csv").exists()


GROWING = """&scene title = 'growing', t_end = 0.05, gravity = 0.0, -9.81, 0.0 /
&integrator method = 'single', h_slow = 1.0e-3, stability_check = .false. /
&effects firing_load = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'block', kind = 'rigid', mass = 1.0, inertia = 1.0e-2, 1.0e-2, 1.0e-2, 0.0, 0.0, 0.0 /
&body name = 'arm', kind = 'rigid', mass = 1.0, com = 0.5, 0.0, 0.0, inertia = 1.0e-3, 0.1, 0.1, 0.0, 0.0, 0.0 /
&joint name = 'slide', kind = 'prismatic', parent = 'ground', child = 'block', axis = 1.0, 0.0, 0.0 /
&joint name = 'hinge', kind = 'revolute', parent = 'block', child = 'arm', axis = 0.0, 0.0, 1.0 /
&marker name = 'tip', body = 'arm', at = 1.0, 0.0, 0.0 /
&load marker = 'tip', direction = 0.0, 1.0, 0.0, frame = 'inertial', form = 'sine', amplitude = 1.0e12, frequency = {f} /
&output dt = 1.0e-3 /
"""


def test_a_motion_flung_beyond_the_bound_on_lengths_fails_naming_the_growth(mrsim, tmp_path):
    """A load of 1e12 N on the arm's tip flings the block 4e10 m in a step: the hinge's
    articulated inertia, summed about the origin, is lost in rounding, and the run blamed the
    mass matrix ('not positive definite: the articulated inertia of coordinate hinge.q is
    -163448'). It now says the motion has grown beyond the numbers, naming the coordinate
    and the distance, beyond the scene's bound on lengths (1e6 m), where the check applies."""
    (tmp_path / "g.nml").write_text(GROWING.format(f=1234.0))
    r = run_mrsim(mrsim, ["g.nml", "-o", "out.csv"], tmp_path)
    assert r.returncode == 2, r.stderr
    check_single_line(r.stderr, "mrsim: error: ")
    assert re.fullmatch(r"mrsim: error: g\.nml: at t = 1\.00000E-03 s: the motion has grown beyond the numbers: "
                        r"coordinate hinge\.q moves bodies [0-9.]+e\+(\d+) m from the origin, where its articulated "
                        r"inertia \(\S+\) is lost in rounding \(an unstable step, or a force that grows without "
                        r"bound\)\n", r.stderr), r.stderr
    assert int(re.search(r"e\+(\d+) m from", r.stderr).group(1)) >= 6


def test_run_solver_failure_raises_solver_error(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "underflow.nml").write_text(UNDERFLOW)
    with pytest.raises(pymr.SolverError) as info:
        pymr.run("underflow.nml", output=tmp_path / "out.csv")
    assert not isinstance(info.value, pymr.SceneError)
    message = str(info.value)
    assert "step size underflow" in message
    assert "\n" not in message.strip()
    assert message.startswith("underflow.nml: "), f"the scene file is not named: {message!r}"


def test_python_m_pymr_solver_failure_exit_2(tmp_path):
    (tmp_path / "underflow.nml").write_text(UNDERFLOW)
    r = run_cli([sys.executable, "-m", "pymr"], ["run", "underflow.nml", "-o", "out.csv"], tmp_path)
    assert r.returncode == 2, f"exit status {r.returncode}, stderr:\n{r.stderr}"
    line = error_line(r.stderr, "pymr: error: ")
    assert "step size underflow" in line
    check_single_line(r.stderr, "pymr: error: ")


def test_version_and_bench_outside_the_checkout(tmp_path, mrsim):
    """`mrsim --version` and `pymr --version` print the package's version and exit 0;
    `pymr bench rhs` runs outside the checkout (the shipped scenes are installed with the
    package) and prints the tank's evaluation."""
    r = subprocess.run([mrsim, "--version"], capture_output=True, text=True, timeout=30)
    assert r.returncode == 0 and r.stdout.strip() == f"mrsim (pymr) {pymr.__version__}"
    r = subprocess.run(["pymr", "--version"], capture_output=True, text=True, timeout=30)
    assert r.returncode == 0 and r.stdout.strip() == f"pymr {pymr.__version__}"
    r = subprocess.run(["pymr", "bench", "rhs", "--repeats", "1"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=120, env={**os.environ, "PYTHONPATH": ""})
    assert r.returncode == 0 and r.stderr == "", r.stderr
    assert re.search(r"tank_gun_turret\s+3\s+6\s+\d", r.stdout), r.stdout


# ------------------------------------------------- the other commands' options (fuzzed)

@pytest.mark.parametrize("args, expect", [
    pytest.param(["run"], "run: the following arguments are required: scene (pymr run --help)", id="run_no_scene"),
    pytest.param(["run", "base.nml", "--bogus"], "unrecognized arguments: --bogus (pymr --help)", id="unknown_option"),
    pytest.param(["run", "base.nml", "-o"], "run: argument -o/--output: expected one argument (pymr run --help)",
                 id="output_without_name"),
    pytest.param(["bench", "rhs", "--repeats", "0"], "bench: argument --repeats: '0': a whole number of repeats, "
                 "at least 1 (pymr bench --help)", id="bench_repeats_0"),
    pytest.param(["bench", "nope"], "bench: argument what: invalid choice: 'nope'", id="bench_unknown"),
    pytest.param(["study", "base.nml", "--repeats", "abc"], "study: argument --repeats: 'abc': a whole number of "
                 "runs per case, at least 1", id="study_repeats_abc"),
    pytest.param(["modes", "base.nml", "--at", "abc"], "modes: argument --at: 'abc': a time in seconds", id="modes_at"),
    pytest.param(["modes", "base.nml", "--at", "nan"], "--at nan: a time at or after the start of the run (s)",
                 id="modes_at_nan"),
    pytest.param(["animate", "out.csv", "--fps", "-1"], "animate: argument --fps: '-1': a whole number of frames "
                 "per second, at least 1", id="animate_fps"),
    pytest.param(["sweep", "s.toml", "--workers", "0"], "sweep: argument --workers: '0': a whole number of workers",
                 id="sweep_workers"),
    pytest.param(["modes", "base.nml", "-o", "nowhere/modes.csv"], "pymr: error: -o nowhere/modes.csv: the folder "
                 "nowhere is not there (make it first)", id="modes_output_folder_missing"),
    pytest.param(["modes", "base.nml", "-o", "base.nml"], "pymr: error: -o base.nml: would overwrite the scene "
                 "(base.nml); choose another modes file", id="modes_output_is_the_scene"),
    pytest.param(["study", "base.nml", "-o", "nowhere/st"], "-o nowhere/st: the folder nowhere is not there",
                 id="study_output_folder_missing"),
    pytest.param(["study", "base.nml", "--marker", "nope"], "base.nml: no marker 'nope' (markers: tip)",
                 id="study_unknown_marker"),
    pytest.param(["animate", "missing.csv"], "missing.csv: no such result file", id="animate_missing"),
    pytest.param(["animate", "base.nml"], "base.nml: not a pymr result file (", id="animate_not_results"),
    pytest.param(["animate", "broken.csv"], "broken.json: not a pymr statistics file (", id="animate_broken_json"),
    pytest.param(["animate", "nan.csv", "--scene", "base.nml"], "nan.csv: row 2, column pivot.q: nan is not a "
                 "finite number", id="animate_nan"),
    pytest.param(["sweep", "s.toml", "--emit-slurm", "base.nml"], "base.nml: cannot make the --emit-slurm folder "
                 "(File exists)", id="sweep_emit_onto_a_file"),
    pytest.param(["bench", "chain", "--repeats", "1", "--pinocchio-cpp", "base.nml"], "--pinocchio-cpp base.nml: "
                 "cannot run it (", id="bench_pinocchio_not_executable"),
])
def test_command_options_fault_in_one_line_exit_1(tmp_path, args, expect):
    """Faults the command-line fuzzing found, each one line and status 1: argparse's usage
    block (exit 2, the failed run's status), tracebacks for unwritable outputs, broken result
    files, --at nan (accepted), --repeats 0 (the default), a study's unknown marker (exit 2)."""
    (tmp_path / "base.nml").write_text(BASE)
    r = run_cli([console_script()], ["run", "base.nml", "-o", "out.csv", "-q"], tmp_path)
    assert r.returncode == 0, r.stderr
    (tmp_path / "broken.csv").write_bytes((tmp_path / "out.csv").read_bytes())
    (tmp_path / "broken.json").write_text("{broken")
    rows = (tmp_path / "out.csv").read_text().splitlines()
    first = next(i for i, line in enumerate(rows) if line[0].isdigit())
    rows[first + 1] = ",".join(["1.0e-3", "nan"] + rows[first + 1].split(",")[2:])
    (tmp_path / "nan.csv").write_text("\n".join(rows) + "\n")
    (tmp_path / "s.toml").write_text('scene = "base.nml"\n[grid]\n"joint[pivot].q0" = [0.5]\n')
    r = run_cli([console_script()], args, tmp_path)
    assert r.returncode == 1, f"exit status {r.returncode}, stderr:\n{r.stderr}"
    check_single_line(r.stderr, "pymr: error: ")
    assert expect in r.stderr, r.stderr
    assert (tmp_path / "base.nml").read_text() == BASE


def test_results_files_that_cannot_be_read_raise_results_error(tmp_path):
    """load_results raised FileNotFoundError, UnicodeDecodeError, numpy's and json's errors
    (pymr animate printed them as tracebacks); each is a ResultsError naming the file."""
    (tmp_path / "base.nml").write_text(BASE)
    res = pymr.run(tmp_path / "base.nml", output=tmp_path / "out.csv")
    (tmp_path / "bytes.csv").write_bytes(b"\xa6\xff\x00garbage")
    (tmp_path / "header.csv").write_text("t,pivot.q\n")
    cases = {"missing.csv": r"missing.csv: no such result file",
             "bytes.csv": r"bytes.csv: not a pymr result file \(",
             "header.csv": r"header.csv: has no result rows"}
    for name, message in cases.items():
        with pytest.raises(pymr.ResultsError, match=message):
            pymr.load_results(tmp_path / name)
    rows = (tmp_path / "out.csv").read_text().splitlines()
    rows[-1] = rows[-1].rsplit(",", 1)[0] + ",inf"
    (tmp_path / "inf.csv").write_text("\n".join(rows) + "\n")
    with pytest.raises(pymr.ResultsError, match=rf"inf.csv: row {len(res.t)}, column {res.columns[-1]}: inf is not "
                                                r"a finite number \(a run writes none: the file was changed\)$"):
        pymr.load_results(tmp_path / "inf.csv")
    (tmp_path / "out.json").write_text("[1, 2]")
    with pytest.raises(pymr.ResultsError, match=r"out.json: not a pymr statistics file \(not a JSON object\)"):
        pymr.load_results(tmp_path / "out.csv")
    assert len(res.t) > 1


def test_an_override_with_a_line_break_is_refused_not_split(tmp_path, mrsim, monkeypatch):
    """The kernel reads one override a line, so a --set value holding a line break became two
    overrides (the second applied silently; found by fuzzing --set), and a string given as
    overrides was read one character at a time ('--set s: expected GROUP.ITEM=VALUE')."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "base.nml").write_text(BASE)
    two = "scene.title=a\nscene.t_end=0.01"
    r = run_mrsim(mrsim, ["base.nml", "-o", "out.csv", "--set", two], tmp_path)
    assert r.returncode == 1 and not (tmp_path / "out.csv").exists(), r.stderr
    check_single_line(r.stderr, "mrsim: error: --set scene.title=a")
    assert r.stderr == ("mrsim: error: --set scene.title=a\\nscene.t_end=0.01: a line break in an override "
                        "(one GROUP.ITEM=VALUE, on one line)\n")
    with pytest.raises(pymr.SceneError, match=r"^--set 'scene.title=a\\nscene.t_end=0.01': a line break in an "
                                              r"override \(one GROUP.ITEM=VALUE, on one line\)$"):
        pymr.run("base.nml", overrides=[two])
    with pytest.raises(pymr.SceneError, match=r"a line break in an override"):
        pymr.Scene("base.nml", {"scene.title": "a\nb"})
    assert pymr.run("base.nml", overrides="scene.t_end=0.01").t[-1] == pytest.approx(0.01)


def test_an_override_is_one_line_whatever_it_holds(tmp_path, mrsim, monkeypatch):
    """A ';' split an override in two, inside quotes too: --set "scene.title='a;b'" was
    refused naming '--set b'' (a fragment never typed), and a scene whose title held a ';'
    could not be set again from Python. A NUL in a Python override ended the text the kernel
    saw: every override after it was dropped silently (found by fuzzing)."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "base.nml").write_text(BASE)
    r = run_mrsim(mrsim, ["base.nml", "-o", "out.csv", "--set", "scene.title='a;b'", "--set", "scene.t_end=0.01"],
                  tmp_path)
    assert r.returncode == 0 and "scene: a;b" in r.stdout, r.stderr
    res = pymr.load_results("out.csv")
    assert res.title == "a;b" and res.t[-1] == pytest.approx(0.01)
    assert pymr.run("base.nml", overrides={"scene.title": "x;y", "scene.t_end": 0.01}).title == "x;y"
    r = run_mrsim(mrsim, ["base.nml", "-o", "out2.csv", "--set", "scene.t_end=0.01;2"], tmp_path)
    assert r.returncode == 1 and r.stderr.endswith(": --set scene.t_end=0.01;2: &scene: t_end: '0.01;2' is not a "
                                                   "number\n"), r.stderr
    for overrides in (["scene.t_end=0.05\0", "scene.t_end=0.01"], {"scene.title": "a\0b"}):
        with pytest.raises(pymr.SceneError, match=r"^--set .*: a NUL character in an override$"):
            pymr.run("base.nml", overrides=overrides)


def test_an_option_of_one_value_given_twice_is_refused(tmp_path, mrsim, monkeypatch):
    """`mrsim -o a.csv -o b.csv` and `pymr run` alike wrote b.csv with no word of a.csv (the
    last one won; found by fuzzing). Refused in one line, exit 1, nothing written; options
    that gather (--set) still take many."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "base.nml").write_text(BASE)
    r = run_mrsim(mrsim, ["base.nml", "-o", "a.csv", "-o", "b.csv"], tmp_path)
    assert r.returncode == 1 and r.stderr == "mrsim: error: -o: the results file is given twice (a.csv before)\n"
    r = run_mrsim(mrsim, ["base.nml", "--restart", "a.ckpt", "--restart", "b.ckpt"], tmp_path)
    assert r.returncode == 1 and r.stderr == "mrsim: error: --restart: the checkpoint is given twice (a.ckpt before)\n"
    r = subprocess.run([sys.executable, "-m", "pymr", "run", "base.nml", "-o", "a.csv", "--output", "b.csv"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and r.stderr == ("pymr: error: run: --output: given twice (a.csv before) "
                                              "(pymr run --help)\n"), r.stderr
    assert not any(p.suffix == ".csv" for p in tmp_path.iterdir())
    # given twice with the default's value too (--workers defaults to 2)
    r = subprocess.run([sys.executable, "-m", "pymr", "sweep", "s.toml", "--workers", "2", "--workers", "2"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and r.stderr == ("pymr: error: sweep: --workers: given twice (2 before) "
                                              "(pymr sweep --help)\n"), r.stderr
    # an option of several values given again dropped the first silently (plot's --labels)
    r = subprocess.run([sys.executable, "-m", "pymr", "plot", "x.csv", "--labels", "a", "--labels", "b"],
                       cwd=tmp_path, capture_output=True, text=True, timeout=120)
    assert r.returncode == 1 and r.stderr == ("pymr: error: plot: --labels: given twice (['a'] before) "
                                              "(pymr plot --help)\n"), r.stderr
    r = run_mrsim(mrsim, ["base.nml", "-o", "c.csv", "--set", "scene.t_end=0.5", "--set", "scene.t_end=0.01"], tmp_path)
    assert r.returncode == 0 and pymr.load_results("c.csv").t[-1] == pytest.approx(0.01)


def test_a_fixed_macro_step_past_the_run_or_the_memory_is_refused(tmp_path, mrsim):
    """A fixed multirate macro step holds the dense output of its k = h_slow/h_fast fast
    steps and takes them all: h_slow = 1000 s on a 0.05 s run allocated 83 GB and died in
    gfortran's runtime (18 lines, a backtrace), or ran for minutes far past t_end (found by
    fuzzing). A macro step longer than the run is bad input (exit 1); one whose buffer the
    process cannot hold is refused before the run by the memory check (exit 2), one line
    each."""
    chain = str(Path(__file__).resolve().parent.parent / "input" / "flexible_chain.nml")
    common = ["--set", "integrator.method=multirate", "--set", "integrator.h_slow=1000"]
    r = run_mrsim(mrsim, [chain, "-o", "a.csv", *common, "--set", "integrator.h_fast=1e-5", "--set",
                          "scene.t_end=0.05"], tmp_path)
    assert r.returncode == 1 and r.stderr.endswith("&integrator: h_slow: a fixed macro step h_slow = 1000 s is longer "
                                                   "than the run (t_end = 0.05 s): take h_slow <= t_end\n"), r.stderr
    r = run_mrsim(mrsim, [chain, "-o", "b.csv", *common, "--set", "integrator.h_fast=1e-6", "--set",
                          "scene.t_end=1000", "--set", "integrator.max_steps=2000000000"], tmp_path)
    assert r.returncode == 2 and r.stderr.count("\n") == 1 and "this process may still take" in r.stderr, r.stderr
    assert not list(tmp_path.glob("*.csv*"))
