"""Malformed scenes and --set overrides: one fault, one clear line that points at it.

Contract checked here (the strict scene reader):

* ``tests/bad_scenes/NNN_name.nml`` is a small valid scene with exactly one fault. Its first
  line is ``! expect: REGEX``: a Python regular expression that ``re.search`` must find in
  the message after the ``mrsim: error: `` prefix. Every expectation starts with the file
  name and, where the fault stands on a line of the file, that line
  (``^NNN_name\\.nml:LINE: ``), then names the group (``&body 'bob'``, ``&drive #1``) and
  the item.
* ``mrsim FILE -o OUT.csv`` on such a file exits with status 1, writes exactly one line on
  stderr (``mrsim: error: ...``, never a Python or Fortran traceback) and writes no CSV.
  ``pymr.run(FILE)`` raises :class:`pymr.SceneError` with the same message.
* A bad ``--set GROUP.ITEM=VALUE`` on a valid scene is reported the same way, as
  ``mrsim: error: SCENE.nml: --set ...`` naming the group and item; ``pymr.Scene``
  refuses the same fault with :class:`pymr.SceneError` and is left as it was.
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

HERE = Path(__file__).resolve().parent
BAD_SCENES = HERE / "bad_scenes"
PENDULUM = HERE.parent / "input" / "pendulum.nml"
PREFIX = "mrsim: error: "
# gfortran's and Python's own wording: never on stderr, whatever the input
FORBIDDEN = ("Traceback", "Error termination", "At line", "Fortran runtime")
TIMEOUT = 60

CORPUS = sorted(BAD_SCENES.glob("*.nml"))


# ------------------------------------------------------------------------------ helpers

@pytest.fixture(scope="module")
def mrsim_cmd() -> str:
    """The mrsim executable: next to this Python (a venv's bin/), else on PATH."""
    beside = Path(sys.executable).with_name("mrsim")
    if beside.is_file() and os.access(beside, os.X_OK):
        return str(beside)
    found = shutil.which("mrsim")
    if found is None:
        pytest.fail("mrsim not found next to sys.executable nor on PATH; build and install pymr")
    return found


def expectation(path: Path) -> str:
    """The regular expression on the file's first line, `! expect: REGEX`."""
    first = path.read_text().split("\n", 1)[0]
    assert first.startswith("! expect: "), f"{path.name}: first line is not '! expect: REGEX'"
    return first[len("! expect: "):]


def run_mrsim(mrsim: str, args: list[str], cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([mrsim, *args], cwd=cwd, capture_output=True, text=True,
                          timeout=TIMEOUT, stdin=subprocess.DEVNULL)


def error_message(r: subprocess.CompletedProcess) -> str:
    """mrsim refused the input cleanly: status 1, one `mrsim: error: ` line; its message."""
    for word in FORBIDDEN:
        assert word not in r.stderr, f"{word!r} on stderr:\n{r.stderr}"
    assert r.returncode == 1, f"exit status {r.returncode}, stderr:\n{r.stderr}"
    lines = r.stderr.splitlines()
    assert len(lines) == 1, f"expected one line on stderr, got {len(lines)}:\n{r.stderr}"
    assert lines[0].startswith(PREFIX), f"stderr does not start with {PREFIX!r}: {lines[0]!r}"
    return lines[0][len(PREFIX):]


def assert_matches(pattern: str, message: str) -> None:
    assert re.search(pattern, message), f"\n  expected: {pattern}\n  got:      {message}"


# ------------------------------------------------------------------- the corpus itself

def test_corpus_is_well_formed():
    """At least 110 files named NNN_short_name.nml, numbered without gaps, each expecting
    an error that starts with its own file name."""
    assert len(CORPUS) >= 110, f"only {len(CORPUS)} files in {BAD_SCENES}"
    assert [p for p in BAD_SCENES.iterdir() if p.suffix != ".nml"] == []
    for number, path in enumerate(CORPUS, 1):
        assert re.fullmatch(r"\d{3}_[a-z0-9_]+\.nml", path.name), path.name
        assert int(path.name[:3]) == number, f"{path.name}: expected number {number:03d}"
        pattern = expectation(path)
        re.compile(pattern)
        head = "^" + path.stem + r"\.nml:"
        assert pattern.startswith(head), f"{path.name}: the expectation must start with {head}"


# ------------------------------------------------------------------ corpus through mrsim

@pytest.mark.parametrize("path", CORPUS, ids=[p.stem for p in CORPUS])
def test_mrsim_refuses_bad_scene(mrsim_cmd, tmp_path, path):
    out = tmp_path / "out.csv"
    r = run_mrsim(mrsim_cmd, [path.name, "-o", str(out)], BAD_SCENES)
    assert_matches(expectation(path), error_message(r))
    assert not out.exists(), "a results file was written for a bad scene"


# --------------------------------------------------------------- corpus through pymr.run

@pytest.mark.parametrize("path", CORPUS, ids=[p.stem for p in CORPUS])
def test_run_raises_scene_error(monkeypatch, path):
    monkeypatch.chdir(BAD_SCENES)
    with pytest.raises(pymr.SceneError) as info:
        pymr.run(path.name)
    message = str(info.value)
    assert "\n" not in message.strip(), f"message has several lines: {message!r}"
    assert_matches(expectation(path), message)


# ------------------------------------------------------------------------ --set faults

NOT_IN_SCENE = object()   # a --set text that a Python value cannot give (Scene formats values)


@dataclass(frozen=True)
class SetFault:
    """One bad override: the --set text, the same fault as pymr.Scene[address] = value, and
    the pattern the message must match after `SCENE.nml: --set ...: ` (searched, so it
    names the group and item and ends the message)."""
    id: str
    text: str
    address: str
    value: object
    pattern: str


SET_FAULTS = [
    SetFault("empty_value", "integrator.h_slow=", "integrator.h_slow", "",
             r": &integrator: h_slow: (no value given|'' is not a number)$"),
    SetFault("group_injection", "joint[pivot].q0=1 / &scene t_end=5", "joint[pivot].q0",
             "1 / &scene t_end=5", r": &joint 'pivot': q0: '[^']*' is not a number$"),
    SetFault("mass_fish", "body[bob].mass=fish", "body[bob].mass", "fish",
             r": &body 'bob': mass: 'fish' is not a number$"),
    SetFault("mass_logical", "body[bob].mass=.true.", "body[bob].mass", True,
             r": &body 'bob': mass: '\.true\.' is not a number$"),
    SetFault("mass_nan", "body[bob].mass=nan", "body[bob].mass", float("nan"),
             r": &body 'bob': mass: 'nan' is not a finite number$"),
    SetFault("mass_1e400", "body[bob].mass=1e400", "body[bob].mass", 1e400,
             r": &body 'bob': mass: '(1e400|inf)' is not a finite number$"),
    SetFault("mass_minus_inf", "body[bob].mass=-inf", "body[bob].mass", float("-inf"),
             r": &body 'bob': mass: '-inf' is not a finite number$"),
    SetFault("mass_zero", "body[bob].mass=0", "body[bob].mass", 0.0,
             r": &body 'bob': mass: must be in \[1e-12, 1e\+12\], got 0$"),
    SetFault("mass_two_values", "body[bob].mass=1,2", "body[bob].mass", [1.0, 2.0],
             r": &body 'bob': mass: takes 1 value, got 2$"),
    SetFault("unknown_item", "body[bob].masss=1", "body[bob].masss", 1.0,
             r": &body 'bob': unknown item 'masss' \(known: [a-z0-9_, ]+\); did you mean 'mass'\?$"),
    SetFault("unknown_group", "bodyy[bob].mass=1", "bodyy[bob].mass", 1.0,
             r": unknown group 'bodyy' \(known: [a-z0-9_, ]+\); did you mean '?&?body'?\?$"),
    SetFault("repeated_group_without_name", "body.mass=1", "body.mass", 1.0,
             r": &body is a repeated group: name one as body\[NAME\]\.mass$"),
    SetFault("single_group_with_name", "scene[x].t_end=1", "scene[x].t_end", 1.0,
             r": &scene is not repeated: write scene\.t_end$"),
    SetFault("no_such_body", "body[nobody].mass=1", "body[nobody].mass", 1.0,
             r": no &body group with name 'nobody'$"),
    SetFault("method_singel", "integrator.method=singel", "integrator.method", "singel",
             r": &integrator: method: 'singel' is not one of: single, multirate, auto; did you mean 'single'\?$"),
    SetFault("joint_kind_hinge", "joint[pivot].kind=hinge", "joint[pivot].kind", "hinge",
             r": &joint 'pivot': kind: 'hinge' is not one of: revolute, prismatic, fixed, spherical, free, "
             r"cylindrical, universal, planar$"),
    SetFault("axis_two_values", "joint[pivot].axis=0,1", "joint[pivot].axis", [0.0, 1.0],
             r": &joint 'pivot': axis: takes 3 values, got 2$"),
    SetFault("q0_two_values", "joint[pivot].q0=1,2", "joint[pivot].q0", [1.0, 2.0],
             r": &joint 'pivot': q0: a revolute joint has 1 coordinate, got 2 values$"),
    SetFault("inertia_five_values", "body[bob].inertia=1,1,1,0,0", "body[bob].inertia", [1.0, 1.0, 1.0, 0.0, 0.0],
             r": &body 'bob': inertia: takes 6 values, got 5$"),
    SetFault("gravity_two_values", "scene.gravity=0,-9.81", "scene.gravity", [0.0, -9.81],
             r": &scene: gravity: takes 3 values, got 2$"),
    SetFault("effects_gravity_number", "effects.gravity=3", "effects.gravity", 3,
             r": &effects: gravity: '3' is not a logical \(\.true\. or \.false\.\)$"),
    SetFault("effects_gravity_quoted", "effects.gravity='.true.'", "effects.gravity", ".true.",
             r": &effects: gravity: '\.true\.' is quoted: write \.true\. or \.false\.$"),
    SetFault("joint_drives_maybe", "effects.joint_drives=maybe", "effects.joint_drives", "maybe",
             r": &effects: joint_drives: 'maybe' is not a logical \(\.true\. or \.false\.\)$"),
    SetFault("n_elements_fraction", "body[bob].n_elements=2.5", "body[bob].n_elements", 2.5,
             r": &body 'bob': n_elements: '2\.5' is not a whole number$"),
    SetFault("t_end_negative", "scene.t_end=-1", "scene.t_end", -1.0,
             r": &scene: t_end: must be in \(0, 1e\+9\], got -1$"),
    SetFault("t_end_1e308", "scene.t_end=1e308", "scene.t_end", 1e308,
             r": &scene: t_end: must be in \(0, 1e\+9\], got 1e\+308$"),
    SetFault("output_dt_negative", "output.dt=-1", "output.dt", -1.0,
             r": &output: dt: must be in \[0, 1e\+9\], got -1$"),
    SetFault("rtol_1e-300", "integrator.rtol=1e-300", "integrator.rtol", 1e-300,
             r": &integrator: rtol: must be in \[2.22045e-14, 1\], got 1e-300$"),
    SetFault("title_too_long", "scene.title=" + "x" * 300, "scene.title", "x" * 300,
             r": &scene: title: the text is longer than 256 characters$"),
    # the limit is in bytes: 200 letters of two bytes were "longer than 256 characters"
    SetFault("title_too_long_utf8", "scene.title=" + "\u00e9" * 200, "scene.title", "\u00e9" * 200,
             r": &scene: title: the text is longer than 256 bytes of UTF-8 \(400 bytes: a letter beyond ASCII takes "
             r"2 to 4\)$"),
    SetFault("duplicate_body_name", "body[bob].name=ground", "body[bob].name", "ground",
             r": &body 'bob': name: used by another &body too \(line \d+\)$"),
    SetFault("subscript", "body[bob].mass(1)=1", "body[bob].mass(1)", 1.0,
             r": &body 'bob': (mass: subscripts are not read|unknown item 'mass\(1\)')"),
    SetFault("unclosed_string", "scene.title='unclosed", "scene.title", NOT_IN_SCENE,
             r": &scene: title: the string is not closed"),
    SetFault("malformed_no_equals", "body[bob].mass", "body[bob].mass", NOT_IN_SCENE,
             r": expected GROUP\.ITEM=VALUE or GROUP\[NAME\]\.ITEM=VALUE$"),
    # rules across items: the value that breaks them came from --set, so the message says so
    SetFault("parent_unknown", "joint[pivot].parent=nobody", "joint[pivot].parent", "nobody",
             r": &joint 'pivot': parent: no &body named 'nobody'$"),
    SetFault("marker_body_unknown", "marker[tip].body=nobody", "marker[tip].body", "nobody",
             r": &marker 'tip': body: no &body named 'nobody'$"),
    # a fault on the ground body leaves it the ground: no second line says the scene has none
    SetFault("ground_mass", "body[ground].mass=1", "body[ground].mass", 1.0,
             r": &body 'ground': mass: not an item of a ground body \(it takes name kind\)$"),
    SetFault("single_h_fast_not_h_slow", "integrator.h_fast=5e-4", "integrator.h_fast", 5e-4,
             r": &integrator: h_(fast|slow): method 'single' takes one step for all coordinates"),
]

SET_PARAMS = [pytest.param(f, id=f.id) for f in SET_FAULTS]
SCENE_PARAMS = [pytest.param(f, id=f.id) for f in SET_FAULTS if f.value is not NOT_IN_SCENE]


@pytest.fixture
def pendulum(tmp_path) -> Path:
    """input/pendulum.nml copied to tmp_path (the working folder of the run)."""
    return Path(shutil.copy(PENDULUM, tmp_path / "pendulum.nml"))


@pytest.mark.parametrize("fault", SET_PARAMS)
def test_mrsim_refuses_bad_set(mrsim_cmd, pendulum, fault):
    out = pendulum.parent / "out.csv"
    r = run_mrsim(mrsim_cmd, [pendulum.name, "-o", out.name, "--set", fault.text], pendulum.parent)
    message = error_message(r)
    assert message.startswith("pendulum.nml: --set "), f"not reported as the --set entry: {message!r}"
    assert_matches(fault.pattern, message)
    assert not out.exists(), "a results file was written for a bad --set"


@pytest.mark.parametrize("text", ["integrator.method=single", "scene.title=a b"])
def test_mrsim_accepts_bare_words(mrsim_cmd, pendulum, text):
    """A string item takes a bare word, and in --set the rest of the entry, spaces and all."""
    r = run_mrsim(mrsim_cmd, [pendulum.name, "-o", "out.csv", "--set", "scene.t_end=0.05",
                              "--set", text], pendulum.parent)
    assert r.returncode == 0, f"exit status {r.returncode}, stderr:\n{r.stderr}"
    assert (pendulum.parent / "out.csv").exists()


@pytest.mark.parametrize("word", ["R&D", "b$b"])
def test_a_bare_word_may_hold_an_ampersand_or_a_dollar(mrsim_cmd, pendulum, word):
    """A bare word with '&' or '$' inside was read as a group's start when the items were
    counted: "more items than the group has '=' signs", with no item named (the same word
    as the group's last item was read). A group starts only after a separator."""
    text = pendulum.read_text()
    assert "title = 'simple pendulum, 1 rad'\n  t_end" in text       # the title is not the group's last item
    pendulum.write_text(text.replace("title = 'simple pendulum, 1 rad'", f"title = {word}"))
    r = run_mrsim(mrsim_cmd, [pendulum.name, "-o", "out.csv", "--set", "scene.t_end=0.05"], pendulum.parent)
    assert r.returncode == 0, f"exit status {r.returncode}, stderr:\n{r.stderr}"
    assert r.stdout.startswith(f"scene: {word}\n")


@pytest.mark.parametrize("fault", SCENE_PARAMS)
def test_scene_refuses_bad_item(pendulum, monkeypatch, fault):
    monkeypatch.chdir(pendulum.parent)
    scene = pymr.Scene(pendulum.name)
    scene["integrator.method"] = "single"          # a good override, kept through the failure
    before = scene.overrides
    with pytest.raises(pymr.SceneError) as info:
        scene[fault.address] = fault.value
    message = str(info.value)
    assert "\n" not in message.strip(), f"message has several lines: {message!r}"
    assert message.startswith("pendulum.nml: --set "), f"not reported as the override: {message!r}"
    assert_matches(fault.pattern, message)
    assert scene.overrides == before, "a refused value was kept"
    assert scene["body[bob].mass"] == 1.0         # the scene still reads
    assert scene["integrator.method"] == "single"


def test_scene_accepts_bare_words(pendulum, monkeypatch):
    monkeypatch.chdir(pendulum.parent)
    scene = pymr.Scene(pendulum.name)
    scene["integrator.method"] = "single"
    scene["scene.title"] = "a b"
    assert scene["scene.title"] == "a b"
