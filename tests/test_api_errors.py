"""Issue 30: every bad input to the Python API gets pymr's answer, and pymr modes labels
what is not a vibration.

- Every public function, called with arguments of the wrong type, shape or value, raises
  a pymr exception (never numpy's or f2py's TypeError or ValueError) whose one line names
  the argument (or, for what the kernel judges, the scene file). The fuzz test walks
  pymr.__all__: a new public function without an entry in CALLS fails it.
- Quiet wrong results: NaN states are refused naming q or qd; bytes are not stored as
  "b'...'"; list items are Python lists both ways.
- pymr.modes and pymr modes: rigid-body motions and drifts are told apart from vibrations
  (physics checks against closed forms).
"""
from __future__ import annotations

import inspect
import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pymr

ROOT = Path(__file__).resolve().parent.parent
PENDULUM = ROOT / "input" / "pendulum.nml"
TANK = ROOT / "input" / "tank_gun_turret.nml"
SHORT = ["scene.t_end=0.01"]

# --------------------------------------------------------------------- the fuzz

# wrong types, shapes and values: each replaces one argument of a valid call
BAD = [5, 2.5, None, True, b"bytes", "abc", "", [1.0, "a"], [[1.0], [1.0, 2.0]], [np.nan], np.nan, np.inf, 1j,
       [1j], object(), {"a": 1}, {5: 1}, np.zeros((2, 2, 2)), ["scene.t_end=0.01", 3]]


def _model_call(method):
    def call(**kwargs):
        with pymr.Model(PENDULUM) as model:
            return getattr(model, method)(**kwargs)
    return call


def _scene_call(method):
    def call(*args, **kwargs):
        return getattr(pymr.Scene(PENDULUM), method)(*args, **kwargs)
    return call


# public callable -> (the function to call, a valid call's arguments by name, the scene its
# kernel messages name)
CALLS = {
    "run": (pymr.run, dict(scene=PENDULUM, output=None, overrides=SHORT, restart=None, progress=False)),
    "model_size": (pymr.model_size, dict(scene=PENDULUM, overrides=None)),
    "model_terms": (pymr.model_terms, dict(scene=PENDULUM, q=[0.1], qd=[0.0], t=0.0, overrides=None)),
    "model_accelerations": (pymr.model_accelerations, dict(scene=PENDULUM, t=0.0, q=[0.1], qd=[0.0], overrides=None)),
    "model_energy": (pymr.model_energy, dict(scene=PENDULUM, q=[0.1], qd=[0.0], overrides=None)),
    "loop_rows": (pymr.loop_rows, dict(scene=PENDULUM, q=[0.1], qd=[0.0], overrides=None)),
    "force_response": (pymr.force_response, dict(scene=TANK, q=np.zeros(6), qd=np.zeros(6), t=0.0, overrides=None)),
    "modes": (pymr.modes, dict(scene=PENDULUM, q=[0.1], qd=[0.0], t=0.0, overrides=None)),
    "marker_shapes": (pymr.marker_shapes, dict(scene=PENDULUM, markers=["tip"], q=[0.1], qd=[0.0],
                                               shapes=np.ones((1, 1)), t=0.0, overrides=None)),
    "step_history": (pymr.step_history, dict(scene=PENDULUM, overrides=SHORT, max_steps=1000)),
    "write_modal_file": (pymr.write_modal_file, dict(scene=PENDULUM, body="bob", path="out.modal", overrides=None)),
    "load_results": (pymr.load_results, dict(csv_path="pendulum.csv")),
    "schema": (pymr.schema, dict()),
    "Scene": (pymr.Scene, dict(path=PENDULUM, overrides=None)),
    "Model": (pymr.Model, dict(scene=PENDULUM, overrides=None)),
    "Model.rhs": (_model_call("rhs"), dict(t=0.0, x=[0.1, 0.0])),
    "Model.marker": (_model_call("marker"), dict(name="tip", t=0.0, q=[0.1], qd=[0.0])),
    "Model.frames": (_model_call("frames"), dict(t=0.0, q=[0.1], qd=[0.0], nb=2)),
    "Model.marker_body": (_model_call("marker_body"), dict(name="tip")),
    "Scene.__getitem__": (_scene_call("__getitem__"), dict(address="scene.title")),
    "Scene.__setitem__": (_scene_call("__setitem__"), dict(address="scene.title", value="x")),
    "Scene.resolved": (_scene_call("resolved"), dict(absolute_paths=False)),
    "Scene.write": (_scene_call("write"), dict(path="resolved.nml", absolute_paths=False)),
}
# public names that are not functions of scenes and states: exceptions, result types, and
# modal_import (its arguments are checked in modal_import.py, tested with it)
NOT_CALLED = {"PymrError", "SceneError", "ArgumentTypeError", "SolverError", "OutputError", "ResultsError",
              "ResultsKeyError", "PlotError", "SweepError", "PymrWarning", "Results", "ModalBody", "Modes", "modal_import", "__version__"}


def test_every_public_function_is_fuzzed():
    """A new public function (or a new argument of one) must be added to CALLS."""
    public = {name for name in pymr.__all__ if name not in NOT_CALLED}
    assert public <= set(CALLS), f"add to CALLS: {sorted(public - set(CALLS))}"
    for name, (function, valid) in CALLS.items():
        if "." in name:
            cls, method = name.split(".")
            function = getattr(getattr(pymr, cls), method)
        params = [p for p in inspect.signature(function).parameters if p != "self"]
        assert set(valid) == set(params), f"{name}: CALLS gives {sorted(valid)}, the function takes {params}"


def _cases():
    for name, (_, valid) in CALLS.items():
        for arg in valid:
            for k in range(len(BAD)):
                yield pytest.param(name, arg, k, id=f"{name}-{arg}-{k}")


@pytest.fixture(scope="module")
def results_csv(tmp_path_factory):
    folder = tmp_path_factory.mktemp("fuzz")
    pymr.run(PENDULUM, folder / "pendulum.csv", overrides=SHORT)
    return folder


@pytest.mark.parametrize("name, arg, k", list(_cases()))
def test_a_wrong_argument_is_a_pymr_error_naming_it(name, arg, k, results_csv, monkeypatch):
    """Any answer but pymr's own one-line error naming the argument (or the scene, where the
    kernel judges the value) fails: Python's TypeError or ValueError, a message over several
    lines, or one that names neither."""
    monkeypatch.chdir(results_csv)
    function, valid = CALLS[name]
    args = dict(valid, **{arg: BAD[k]})
    try:
        function(**args)
    except pymr.PymrError as exc:
        message = str(exc)
        assert "\n" not in message, message
        given = args.get("scene", args.get("path", PENDULUM))
        scene = Path(os.fsdecode(given)).name if isinstance(given, (str, bytes, Path)) else PENDULUM.name
        named = (any(a in message for a in args) or scene in message or "--set" in message
                 or (isinstance(BAD[k], (str, bytes)) and BAD[k] and f"{os.fsdecode(BAD[k])}:" in message)
                 or (arg == "x" and ("q" in message)) or (arg == "csv_path" and "pendulum.csv" in message)
                 or (name == "Scene.__setitem__" and "scene.title" in message))
        assert named, f"{name}({arg}={BAD[k]!r}): {message!r} names neither {arg!r} nor the scene"
    except Exception as exc:         # noqa: BLE001 - any other exception is the failure
        pytest.fail(f"{name}({arg}={BAD[k]!r}) raised {type(exc).__module__}.{type(exc).__name__}: {exc}")


# --------------------------------------------------------------- the named cases

def test_the_cases_of_the_issue_raise_pymr_errors_naming_the_argument():
    with pytest.raises(pymr.ArgumentTypeError, match=r"^path: a file path \(str or os.PathLike\), got int 5$"):
        pymr.Scene(5)
    with pytest.raises(pymr.ArgumentTypeError, match=r"^q: an array of real numbers, got str 'a'$"):
        pymr.modes(PENDULUM, "a", "b")
    # None became NaN: 'q: nan is not a finite number' (found by the second bad-input audit)
    for q in (None, [None]):
        with pytest.raises(pymr.ArgumentTypeError, match=rf"^q: an array of real numbers, got \w+ {re.escape(repr(q))}$"):
            pymr.model_terms(PENDULUM, q, [0.0])
    with pytest.raises(pymr.ArgumentTypeError, match=r"^overrides: a mapping .* got int 5$"):
        pymr.run(PENDULUM, overrides=5)
    with pytest.raises(pymr.ArgumentTypeError, match=r"^overrides\[1\]: an override 'GROUP.ITEM=VALUE' \(str\), "
                                                     r"got float 2.5$"):
        pymr.run(PENDULUM, overrides=["scene.t_end=0.1", 2.5])
    with pytest.raises(pymr.ArgumentTypeError, match=r"^overrides\['scene.title'\]: a number, a bool, a text"):
        pymr.run(PENDULUM, overrides={"scene.title": None})
    with pytest.raises(pymr.SceneError, match=r"^qd: shape \(2,\) differs from q's \(1,\)$"):
        pymr.model_terms(PENDULUM, [0.1], [0.0, 0.0])
    with pytest.raises(pymr.SceneError, match=r"^q: one state of shape \(n,\) expected, got shape \(1, 1\)$"):
        pymr.loop_rows(PENDULUM, [[0.1]], [[0.0]])
    with pytest.raises(pymr.ArgumentTypeError, match=r"^t: a time in seconds, got '1'$"):
        pymr.model_terms(PENDULUM, [0.1], [0.0], t="1")
    # the wrong types are TypeErrors, the wrong values ValueErrors, as Python's own would be
    assert issubclass(pymr.ArgumentTypeError, TypeError) and issubclass(pymr.ArgumentTypeError, ValueError)


def test_one_string_is_one_override_not_its_characters(tmp_path):
    res = pymr.run(PENDULUM, tmp_path / "p.csv", overrides="scene.t_end=0.05")
    assert res.t[-1] == pytest.approx(0.05)
    with pytest.raises(pymr.SceneError, match=r"pendulum.nml: --set integrator: expected GROUP.ITEM=VALUE"):
        pymr.run(PENDULUM, overrides="integrator")
    assert pymr.marker_shapes(PENDULUM, "tip", [0.1], [0.0], np.ones((1, 1))).keys() == {"tip"}


@pytest.mark.parametrize("call", [
    lambda q, qd: pymr.loop_rows(PENDULUM, q, qd),
    lambda q, qd: pymr.modes(PENDULUM, q, qd),
    lambda q, qd: pymr.model_accelerations(PENDULUM, 0.0, q, qd),
    lambda q, qd: pymr.model_terms(PENDULUM, q, qd),
    lambda q, qd: pymr.model_energy(PENDULUM, q, qd),
    lambda q, qd: pymr.force_response(TANK, np.full(6, q[0]), np.full(6, qd[0])),
    lambda q, qd: pymr.marker_shapes(PENDULUM, ["tip"], q, qd, np.ones((1, 1))),
], ids=["loop_rows", "modes", "model_accelerations", "model_terms", "model_energy", "force_response",
        "marker_shapes"])
def test_a_state_that_is_not_finite_is_named_as_q_or_qd(call):
    """loop_rows returned NaN arrays; modes and the accelerations blamed the mass matrix or
    LAPACK. Every function taking a state names q or qd."""
    with pytest.raises(pymr.SceneError, match=r"^q: nan is not a finite number$"):
        call([np.nan], [0.0])
    with pytest.raises(pymr.SceneError, match=r"^qd: inf is not a finite number$"):
        call([0.1], [np.inf])


def test_model_rhs_names_q_or_qd_of_a_state_that_is_not_finite():
    with pymr.Model(PENDULUM) as model:
        assert np.isfinite(model.rhs(0.0, [0.1, 0.0])).all()
        with pytest.raises(pymr.SceneError, match=r"^q: nan is not a finite number \(x\[0\], entry 0 of q in "
                                                  r"x = \[q; qd\]\)$"):
            model.rhs(0.0, [np.nan, 0.0])
        with pytest.raises(pymr.SceneError, match=r"^qd: nan is not a finite number \(x\[1\], entry 0 of qd"):
            model.rhs(0.0, [0.1, np.nan])


def test_bytes_are_refused_naming_the_item_not_stored_as_their_repr():
    scene = pymr.Scene(PENDULUM)
    with pytest.raises(pymr.ArgumentTypeError, match=r"^scene.title: bytes b'abc': give text as a str"):
        scene["scene.title"] = b"abc"
    assert scene["scene.title"] == "simple pendulum, 1 rad"        # left as it was
    scene["scene.title"] = "abc"
    assert scene["scene.title"] == "abc"
    with pytest.raises(pymr.ArgumentTypeError, match=r"^overrides\['scene.title'\]: bytes"):
        pymr.run(PENDULUM, overrides={"scene.title": b"abc"})


def test_list_items_are_python_lists_both_ways():
    """output.quantities came back as "coordinates', 'markers" and was refused when set back."""
    scene = pymr.Scene(PENDULUM, {"output.quantities": ["coordinates", "markers"]})
    assert scene["output.quantities"] == ["coordinates", "markers"]
    scene["output.quantities"] = scene["output.quantities"]
    assert scene["output.quantities"] == ["coordinates", "markers"]
    scene["output.quantities"] = "markers"                           # one value of a list item: a list
    assert scene["output.quantities"] == ["markers"]
    assert scene["scene.gravity"] == [0, -9.81, 0]
    scene["scene.gravity"] = scene["scene.gravity"]
    scene["scene.title"] = "a, 'b', c"                               # text with commas and quotes: one str
    assert scene["scene.title"] == "a, 'b', c"
    assert scene["body[bob].mass"] == 1.0 and scene["integrator.method"] == "single"
    assert scene["joint[pivot].q0"] == [1.0]                         # q0 takes up to 6 values


def test_every_list_item_of_the_schema_reads_back_as_a_list():
    """Each item whose schema type has a count reads as a list (a new list item is caught)."""
    scene = pymr.Scene(ROOT / "input" / "tank_gun_turret.nml")
    group = None
    checked = 0
    for line in pymr.schema().splitlines():
        if line.startswith("&"):
            group = line[1:].strip()
            continue
        name, kind = line.split("\t")[:2]
        address = {"body": "body[gun]", "joint": "joint[elevation]", "marker": "marker[muzzle]"}.get(group, group)
        try:
            value = scene[f"{address}.{name}"]
        except pymr.SceneError:
            continue          # a group the tank does not have
        if value is None:
            continue          # no value given and none by default
        assert isinstance(value, list) == ("(" in kind), (group, name, kind, value)
        checked += "(" in kind
    assert checked >= 5


# --------------------------------------------------------------------- modes

FREE = """&scene title = 'free body', t_end = 1.0, gravity = 0.0, -9.81, 0.0 /
&integrator method = 'single', h_slow = 1.0e-3 /
&effects gravity = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'block', kind = 'rigid', mass = 2.0, com = 0.1, 0.2, 0.0, inertia = {inertia}, 0.0, 0.0, 0.0 /
&joint name = 'float', kind = 'free', parent = 'ground', child = 'block' /
&marker name = 'c', body = 'block', at = 0.0, 0.0, 0.0 /
"""

CHAIN = """&scene title = 'free chain', t_end = 1.0, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', h_slow = 1.0e-3 /
&body name = 'ground', kind = 'ground' /
&body name = 'a', kind = 'rigid', mass = 2.0, com = 0.5, 0.0, 0.0, inertia = 0.01, 0.2, 0.2, 0.0, 0.0, 0.0 /
&body name = 'b', kind = 'rigid', mass = 1.0, com = 0.5, 0.0, 0.0, inertia = 0.01, 0.1, 0.1, 0.0, 0.0, 0.0 /
&joint name = 'float', kind = 'free', parent = 'ground', child = 'a' /
&joint name = 'hinge', kind = 'revolute', parent = 'a', child = 'b', at = 1.0, 0.0, 0.0, axis = 0.0, 0.0, 1.0 /
&marker name = 'tip', body = 'b', at = 1.0, 0.0, 0.0 /
"""


@pytest.mark.parametrize("inertia", ["0.1, 0.2, 0.3", "1e-6, 1e-6, 1e-6"])
def test_a_free_body_under_gravity_has_six_rigid_body_motions_and_no_vibration(tmp_path, inertia):
    """A falling free body (com off the joint): nothing holds any of its motions (a uniform
    field neither restores nor pushes its coordinates apart). It showed a 'vibration'
    (0.33 Hz here; 78.8 Hz in the issue's) from linearising P with M frozen at a state
    that accelerates."""
    scene = tmp_path / "free.nml"
    scene.write_text(FREE.format(inertia=inertia))
    found = pymr.modes(scene, np.zeros(6), np.zeros(6))
    assert found.rigid.shape == (6, 6) and len(found.frequency) == 0 and len(found.drift_rate) == 0
    assert found.kind == ["rigid"] * 6
    assert np.linalg.matrix_rank(found.rigid) == 6
    freq, zeta, shapes = found                      # unpacked: the vibrations, as before
    assert freq.shape == (0,) and shapes.shape == (6, 0)


@pytest.mark.parametrize("qd", [np.zeros(7), np.r_[0.1, -0.2, 0.05, 0.0, 0.0, 0.0, 0.0]])
def test_a_free_floating_chain_has_seven_rigid_body_motions(tmp_path, qd):
    """The free chain without gravity, at rest or drifting: no 'vibration' at 1e-6 Hz."""
    scene = tmp_path / "chain.nml"
    scene.write_text(CHAIN)
    found = pymr.modes(scene, np.zeros(7), qd)
    assert found.rigid.shape == (7, 7) and len(found.frequency) == 0 and len(found.drift_rate) == 0


def test_pendulums_hanging_upright_and_weightless():
    """The pendulum (1 kg at L = 1 m, inertia 4e-5 about its centre): hanging, one vibration
    at sqrt(m g L / (I + m L^2))/(2 pi); upright, two drifts at +-sqrt(m g L/(I + m L^2)) (it
    falls away, or creeps back); without gravity, one rigid-body motion and nothing else."""
    rate = np.sqrt(9.81 / (4e-5 + 1.0))
    hanging = pymr.modes(PENDULUM, [0.0], [0.0])
    assert hanging.kind == ["vibration"]
    assert hanging.frequency == pytest.approx([rate / (2 * np.pi)], rel=1e-7)
    upright = pymr.modes(PENDULUM, [np.pi], [0.0])
    assert upright.kind == ["drift", "drift"]
    assert upright.drift_rate == pytest.approx([rate, -rate], rel=1e-6)
    weightless = pymr.modes(PENDULUM, [1.0], [0.0], overrides=["effects.gravity=.false."])
    assert weightless.kind == ["rigid"] and weightless.rigid.shape == (1, 1)


def test_every_input_scene_labels_each_motion_once(tmp_path):
    """A new member of the class: on every scene of input/, at its initial state, each
    motion is one of the three kinds, the vibrations are resolved (none below 1e-3 Hz),
    and the motions are no more than the coordinates (a drift pair shares one; a
    controller's state coordinate brings one eigenvalue 0, its double integral, which
    nothing depends on, listed as a rigid-body motion, and one real pole: half a pair
    each)."""
    for path in sorted((ROOT / "input").glob("*.nml")):
        res = pymr.run(path, tmp_path / "r.csv", overrides=["scene.t_end=1e-9", "output.dt=0.0"])
        q, qd = res.coordinates()
        found = pymr.modes(path, q[0], qd[0])
        n = q.shape[1]
        controls = sum(c.endswith(".double_integral") for c in res.columns)
        assert set(found.kind) <= {"rigid", "drift", "vibration"}, path.name
        assert np.all(found.frequency > 1e-3), (path.name, found.frequency)
        assert found.rigid.shape[1] + len(found.frequency) + len(found.drift_rate) / 2 <= n + controls / 2, \
            (path.name, found)


def _pymr(*args, cwd=None):
    """`pymr ARGS`, run outside the checkout unless told (from its root, `python -m pymr`
    would import the source folder, which has no compiled kernel)."""
    return subprocess.run([sys.executable, "-m", "pymr", *map(str, args)], capture_output=True, text=True,
                          timeout=120, cwd=cwd or ROOT.parent)


def test_modes_command_on_a_scene_with_markers_and_no_vibration(tmp_path):
    """The scene reference's four-bar (docs/scenes.md) and a pendulum without gravity gave a
    traceback (ValueError: unexpected array size); the table labels each motion."""
    readme = (ROOT / "docs" / "scenes.md").read_text()
    start = readme.index("&scene title = 'four-bar'")
    (tmp_path / "fourbar.nml").write_text(readme[start:readme.index("```", start)])
    r = _pymr("modes", tmp_path / "fourbar.nml", "-o", tmp_path / "fourbar_modes.csv")
    assert r.returncode == 0 and "Traceback" not in r.stderr, r.stderr
    assert "0 vibrations" in r.stdout
    r = _pymr("modes", PENDULUM, "--set", "scene.gravity=0,0,0")
    assert r.returncode == 0, r.stderr
    assert "0 vibrations, 1 rigid-body motions, 0 drifts" in r.stdout
    assert any(line.split()[:2] == ["1", "rigid"] for line in r.stdout.splitlines())
    scene = tmp_path / "free.nml"
    scene.write_text(FREE.format(inertia="0.1, 0.2, 0.3"))
    r = _pymr("modes", scene)
    assert r.returncode == 0 and "0 vibrations, 6 rigid-body motions" in r.stdout, r.stderr
    assert sum(line.split()[1:2] == ["rigid"] for line in r.stdout.splitlines()) == 6


@pytest.mark.parametrize("args, expect", [
    (["--at", "1e308"], r"^pymr: error: --at 1e\+308: the run cannot be taken to this time \(as &scene t_end it "
                        r"must be in \(0, 1e\+9\], got 1e\+308\)$"),
    (["--at", "-1"], r"^pymr: error: --at -1: a time at or after the start of the run \(s\)$"),
    (["-o", "."], r"^pymr: error: -o \.: is a folder, not a file: give a file name for the modes file, such as "
                r"\./modes\.csv$"),
    (["-o", ""], r"^pymr: error: -o: an empty file name"),
])
def test_modes_command_names_its_own_options(tmp_path, args, expect):
    """--at 1e308 blamed '--set scene.t_end=1e+308', never typed; -o . gave a traceback."""
    r = _pymr("modes", PENDULUM, *args, cwd=tmp_path)
    assert r.returncode == 1, r.stderr
    assert len(r.stderr.splitlines()) == 1 and "Traceback" not in r.stderr, r.stderr
    import re
    assert re.match(expect, r.stderr.strip()), r.stderr
