"""A pymr.Scene keeps one model open in the kernel for every model function called with it
(issue 31: every binding entry point that works on a built model takes its handle): repeated
calls give what a model built afresh gives, bit for bit, and an edit of the Scene closes the
model so that the next call builds the scene as edited."""
import gc
import os

import numpy as np
import pytest

import pymr
import pymr.api

HERE = os.path.dirname(os.path.abspath(__file__))
TANK = os.path.join(HERE, "..", "input", "tank_gun_turret.nml")


def _state(n):
    rng = np.random.default_rng(7)
    return 0.1 * rng.standard_normal(n), 0.2 * rng.standard_normal(n)


def test_repeated_calls_on_one_scene_are_identical_and_match_a_fresh_build():
    scene = pymr.Scene(TANK)
    n = pymr.model_size(scene)[0]
    q, qd = _state(n)
    mm, p = pymr.model_terms(scene, q, qd, t=0.3)
    # calls that change the model's work arrays and counters in between change nothing
    pymr.model_accelerations(scene, 0.3, q, qd)
    pymr.modes(scene, q, qd)
    pymr.api.initial_state(scene)
    pymr.step_history(scene, {"scene.t_end": 2e-3})     # an override: its own model
    for _ in range(3):
        mm2, p2 = pymr.model_terms(scene, q, qd, t=0.3)
        assert np.array_equal(mm2, mm) and np.array_equal(p2, p)
    # the same as the path's model, built for the call
    mm3, p3 = pymr.model_terms(TANK, q, qd, t=0.3)
    assert np.array_equal(mm3, mm) and np.array_equal(p3, p)
    qdd = pymr.model_accelerations(scene, 0.3, q, qd)
    assert np.array_equal(qdd, pymr.model_accelerations(scene, 0.3, q, qd))
    assert np.array_equal(qdd, pymr.model_accelerations(TANK, 0.3, q, qd))


def test_an_edit_reopens_the_model_mass_enters_the_traverse_inertia():
    """The turret (mass m, centre of mass at (-0.3, 0.4, 0) in its frame, on the vertical
    traverse axis through its origin) adds m r^2 with r = 0.3 m (its centre's distance from
    the axis) to M's traverse entry at q = 0, its inertia about its centre unchanged: 1000 kg
    more add 90 kg m^2 there, and nothing elsewhere (no other coordinate moves the turret)."""
    scene = pymr.Scene(TANK)
    n = pymr.model_size(scene)[0]
    q, qd = np.zeros(n), np.zeros(n)
    m0 = pymr.model_terms(scene, q, qd)[0]
    handle = scene.model_handle()
    scene["body[turret].mass"] = 10000.0
    m1 = pymr.model_terms(scene, q, qd)[0]
    assert m1[0, 0] - m0[0, 0] == pytest.approx(1000.0 * 0.3**2, rel=1e-12)
    changed = np.zeros((n, n), dtype=bool)
    changed[0, 0] = True
    assert np.array_equal(m1[~changed], m0[~changed])
    # the edited scene's model is the one a fresh build of the edit gives
    m2 = pymr.model_terms(TANK, q, qd, overrides={"body[turret].mass": 10000.0})[0]
    assert np.array_equal(m1, m2)
    assert scene.model_handle() != 0
    # an edit back gives the first model again
    scene["body[turret].mass"] = 9000.0
    assert np.array_equal(pymr.model_terms(scene, q, qd)[0], m0)
    del handle


def test_a_refused_edit_keeps_the_scene_and_its_results():
    scene = pymr.Scene(TANK)
    n = pymr.model_size(scene)[0]
    q, qd = _state(n)
    mm = pymr.model_terms(scene, q, qd)[0]
    with pytest.raises(pymr.SceneError):
        scene["body[turret].mass"] = -1.0
    assert np.array_equal(pymr.model_terms(scene, q, qd)[0], mm)


def test_the_model_is_closed_with_the_scene():
    """A collected Scene's handle is free again: the kernel refuses it as closed, and it is
    taken again before the registry grows (the kernel opens the lowest free handle; models
    that earlier tests left for the collector may free lower ones at the same collection)."""
    from pymr import _core
    from pymr._args import _text
    scene = pymr.Scene(TANK)
    handle = scene.model_handle()
    assert handle > 0
    del scene
    gc.collect()
    stat, message = _core.pymr_model_size(handle)[3:5]
    assert stat != 0 and "closed" in _text(message)
    others = [pymr.Scene(TANK) for _ in range(handle)]
    assert handle in [o.model_handle() for o in others]


def test_an_edit_closes_the_model():
    scene = pymr.Scene(TANK)
    handle = scene.model_handle()
    _, closer, _ = scene._model
    scene["integrator.h_slow"] = 2e-4
    assert not closer.alive and scene._model is None
    assert scene.model_handle() > 0 and handle > 0


def test_a_copy_opens_its_own_model():
    import copy
    scene = pymr.Scene(TANK)
    scene.model_handle()
    twin = copy.deepcopy(scene)
    assert twin.model_handle() != scene.model_handle()
    twin["body[turret].mass"] = 10000.0
    n = pymr.model_size(scene)[0]
    q, qd = np.zeros(n), np.zeros(n)
    assert pymr.model_terms(twin, q, qd)[0][0, 0] - pymr.model_terms(scene, q, qd)[0][0, 0] \
        == pytest.approx(90.0, rel=1e-12)


def test_model_rhs_counts_its_own_evaluations():
    """pymr.Model's evaluations go on from call to call; the model functions' calls on a
    Scene's model are not counted there (each works on a copy of the model as built)."""
    with pymr.Model(TANK) as model:
        x = np.zeros(2 * model.n)
        f1 = model.rhs(0.0, x)
        first = model.evaluations
        f2 = model.rhs(0.0, x)
        assert model.evaluations == first + 1 > 0
        assert np.array_equal(f1, f2)


def test_the_binding_model_functions_are_pure_functions_of_their_inputs():
    """On one handle, pymr_model_rhs's evaluations (which go on counting) change nothing that
    pymr_model_terms returns, and a closed handle is refused."""
    from pymr import _core
    from pymr._args import _text, open_model
    handle = open_model(TANK, "")
    try:
        n = int(_core.pymr_model_size(handle)[0])
        q, qd = _state(n)
        first = _core.pymr_model_terms(handle, 0.3, q, qd)
        for k in range(3):
            f, evals, stat, *_ = _core.pymr_model_rhs(handle, 0.1 * k, np.concatenate([q, qd]))
            assert stat == 0 and evals == k + 1
        again = _core.pymr_model_terms(handle, 0.3, q, qd)
        assert np.array_equal(first[0], again[0]) and np.array_equal(first[1], again[1])
    finally:
        _core.pymr_model_close(handle)
    mm, p, stat, msg, detail = _core.pymr_model_terms(handle, 0.3, q, qd)
    assert stat == 1 and _text(msg) == "the model of this handle is closed"


def test_many_open_models_keep_their_handles():
    """More open models than the kernel's first table holds (4): the table grows and every
    model stays under its handle, each with its own mass."""
    scenes = [pymr.Scene(TANK, {"body[turret].mass": 9000.0 + 100.0 * k}) for k in range(10)]
    n = pymr.model_size(scenes[0])[0]
    q, qd = np.zeros(n), np.zeros(n)
    first = [pymr.model_terms(s, q, qd)[0][0, 0] for s in scenes]
    assert len({s.model_handle() for s in scenes}) == 10
    again = [pymr.model_terms(s, q, qd)[0][0, 0] for s in scenes]
    assert first == again
    assert np.diff(first) == pytest.approx(np.full(9, 100.0 * 0.3**2), rel=1e-9)


def test_a_failed_build_leaves_no_open_model():
    from pymr._args import open_model
    from pymr import _core
    handle = open_model(TANK, "")
    _core.pymr_model_close(handle)
    with pytest.raises(pymr.SceneError):
        open_model(TANK, "body[gun].n_elements=0")
    again = open_model(TANK, "")
    assert again == handle
    _core.pymr_model_close(again)


def test_a_relative_scene_follows_the_working_folder(tmp_path, monkeypatch):
    """A Scene of a relative path reads it from the working folder of each call, as a
    path does: another folder's file of that name is another model."""
    for folder, mass in (("a", 9000.0), ("b", 10000.0)):
        (tmp_path / folder).mkdir()
        text = open(TANK).read().replace("mass = 9000.0", f"mass = {mass}")
        (tmp_path / folder / "tank.nml").write_text(text)
    monkeypatch.chdir(tmp_path / "a")
    scene = pymr.Scene("tank.nml")
    n = pymr.model_size(scene)[0]
    q, qd = np.zeros(n), np.zeros(n)
    m_a = pymr.model_terms(scene, q, qd)[0][0, 0]
    monkeypatch.chdir(tmp_path / "b")
    m_b = pymr.model_terms(scene, q, qd)[0][0, 0]
    assert m_b - m_a == pytest.approx(1000.0 * 0.3**2, rel=1e-12)


def test_a_scene_is_not_written_over_its_own_file_or_what_it_reads(tmp_path):
    """Scene.write over the scene's own file replaced it with the resolved text, its comments
    and layout lost, where every other writer refuses an output over the scene or a file it
    reads (found by fuzzing). Refused, naming the path, the file left as it was; a new file
    is written and reads back as the same scene."""
    import shutil
    source = os.path.join(HERE, "..", "input")
    shutil.copy(os.path.join(source, "tank_on_the_move.nml"), tmp_path / "t.nml")
    shutil.copytree(os.path.join(source, "tank_on_the_move"), tmp_path / "tank_on_the_move")
    scene = pymr.Scene(tmp_path / "t.nml")
    scene["scene.t_end"] = 0.1
    before = (tmp_path / "t.nml").read_text()
    table = next(p for p in (tmp_path / "tank_on_the_move").iterdir())
    table_before = table.read_bytes()
    with pytest.raises(pymr.OutputError, match=r"^path .*t\.nml: would overwrite the scene"):
        scene.write(tmp_path / "t.nml")
    with pytest.raises(pymr.OutputError, match=r"^path .*: would overwrite "):
        scene.write(table)
    assert (tmp_path / "t.nml").read_text() == before and table.read_bytes() == table_before
    scene.write(tmp_path / "new.nml")
    assert pymr.Scene(tmp_path / "new.nml").fingerprint == scene.fingerprint


@pytest.mark.parametrize("group, items, what", [
    ("marker", {"t_end = 1.0\n/\n&integrator\n method": "'x'"}, "item"),
    ("marker\n/\n&output", {"name": "m2"}, "group"),
    ("marker", {"": 1}, "item"),
])
def test_added_groups_and_items_are_names_not_text(group, items, what):
    """Scene.add wrote each item's name into the namelist text as given, so a name holding a
    line break and '/' added a group of its own (found by fuzzing). A group's or an item's
    name is letters, digits and '_', from a letter; the scene is unchanged."""
    scene = pymr.Scene(TANK)
    before = scene.fingerprint
    with pytest.raises(pymr.SceneError, match=rf"^{what} .*: not a name \(letters, digits and '_', from a letter\)$"):
        scene.add(group, **items)
    assert scene.fingerprint == before
