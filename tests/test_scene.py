"""The scene as data (issue 13): one item table per namelist group in the kernel, read,
resolved, fingerprinted and written back through it; pymr.Scene uses the kernel's reader
through the binding. Checked against independent expectations: stored results (within each
scene's measured sensitivity to its last bits, docs/testing.md), the round trip of the
resolved scene (text and values bit for bit, also for random valid scenes), sha256 from
hashlib, the scene reference in docs/scenes.md."""
from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr.scene import parse_value

ROOT = Path(__file__).resolve().parent.parent
INPUT_SCENES = sorted(ROOT.glob("input/*.nml")) + sorted(ROOT.glob("input/hard/*.nml"))
STORED = json.loads((ROOT / "tests" / "data" / "input_results.json").read_text())


def data_lines(csv: Path) -> list[str]:
    return [ln for ln in csv.read_text().splitlines() if not ln.startswith("#")]


# A stored value is matched within this many times its one-ulp sensitivity, plus FLOOR_ULPS
# ulp of the largest magnitude among its owner's columns (a marker's, a joint's: for values
# that no input moves, as in a scene at rest, or a reaction that is zero up to round-off).
# The sensitivity is the largest change that one ulp of an input, glibc's libm on other code
# paths, or OpenBLAS for reference LAPACK made (tests/store_input_results.py). Checked with
# changes it did not see (OpenBLAS's other CPU kernels, OpenBLAS with the other libm): at
# most 0.79 of what is allowed here (docs/testing.md).
SENSITIVITY_FACTOR = 10.0
FLOOR_ULPS = 64


def stored_results_misfit(stored: dict, lines: list[str]) -> tuple[float, str]:
    """The largest |new - stored| / allowed over the kept rows, and where it is (row, column).
    allowed = SENSITIVITY_FACTOR * one-ulp sensitivity + FLOOR_ULPS ulp of the owner's scale."""
    assert lines[0] == stored["header"], "the results' columns differ from the stored ones"
    assert len(lines) - 1 == stored["rows"]
    names = stored["header"].split(",")
    new = np.array([[float(x) for x in lines[1 + i].split(",")] for i in stored["kept_rows"]])
    ref = np.array([[float(x) for x in row] for row in stored["values"]])
    owner = np.array([n.split(".")[0] for n in names])
    scale = np.array([np.abs(ref[:, owner == o]).max() for o in owner])
    allowed = SENSITIVITY_FACTOR * np.array(stored["sensitivity"]) + FLOOR_ULPS * np.spacing(scale)
    ratio = np.abs(new - ref) / allowed
    r, c = np.unravel_index(np.argmax(ratio), ratio.shape)
    return float(ratio[r, c]), f"row {stored['kept_rows'][r]}, column {names[c]}: {new[r, c]!r} against {ref[r, c]!r}"


def run_input_scene(mrsim: str, scene: Path, out: Path, *sets: str) -> subprocess.CompletedProcess:
    """mrsim on the scene, quiet, results to out, with --set for each of sets."""
    extra = [a for item in sets for a in ("--set", item)]
    return subprocess.run([mrsim, str(scene), "-o", str(out), "--quiet", *extra], capture_output=True, text=True, timeout=300)


@pytest.mark.parametrize("scene", INPUT_SCENES, ids=lambda p: p.name)
def test_every_input_scene_gives_its_stored_results(scene, tmp_path, mrsim):
    """Each scene in input/ run by mrsim gives the stored rows (20 evenly spaced and the
    last, every column) within 10 times what one ulp of an input or another libm or LAPACK
    moves each value (tests/store_input_results.py measures and stores both), or is refused
    with the same message. Any fault that moves a result by more than the last bits fails it."""
    stored = STORED[str(scene.relative_to(ROOT))]
    out = tmp_path / "out.csv"
    r = run_input_scene(mrsim, scene, out)
    if "refused" in stored:
        assert r.returncode == 1
        assert r.stderr.strip().removeprefix("mrsim: error: ").replace(str(scene), str(scene.relative_to(ROOT))) \
            .endswith(stored["refused"].split(": ", 1)[1])
        return
    assert r.returncode == 0, r.stderr
    worst, where = stored_results_misfit(stored, data_lines(out))
    assert worst <= 1.0, f"{scene.name}: {worst:.3g} times the allowed change at {where}"


def test_stored_results_check_sees_a_change_beyond_the_last_bits(tmp_path, mrsim):
    """The comparison is not blind: the tank run with its barrel's density moved by 1e-9
    (a million ulp) is refused, and the same run moved by one ulp is accepted."""
    scene = ROOT / "input" / "tank_gun_turret.nml"
    stored = STORED["input/tank_gun_turret.nml"]
    for density, fits in ((7850.0 * (1 + 1e-9), False), (float(np.nextafter(7850.0, 0.0)), True)):
        out = tmp_path / "out.csv"
        r = run_input_scene(mrsim, scene, out, f"body[gun].density={density!r}")
        assert r.returncode == 0, r.stderr
        assert (stored_results_misfit(stored, data_lines(out))[0] <= 1.0) == fits


@pytest.mark.parametrize("scene", INPUT_SCENES, ids=lambda p: p.name)
def test_resolved_scene_reads_back_to_itself(scene, tmp_path):
    """Reading the printed resolved scene gives the same scene: the same text, so the same
    fingerprint, which is the sha256 of the text without its fingerprint line, with the
    files it names relative to the scene's folder (so that a scene moved with its files
    keeps its fingerprint): also the fingerprint of the text with absolute paths."""
    relative = pymr.Scene(scene).resolved()
    body, last = relative.rstrip("\n").rsplit("\n", 1)
    assert last == "! fingerprint sha256:" + hashlib.sha256((body + "\n").encode()).hexdigest()
    text = pymr.Scene(scene).resolved(absolute_paths=True)
    assert text.rstrip("\n").rsplit("\n", 1)[1] == last
    shutil.copytree(scene.parent, tmp_path / "copy")         # the scene's folder, with its files
    again = tmp_path / "copy" / "again.nml"
    again.write_text(relative)
    assert pymr.Scene(again).resolved() == relative
    elsewhere = tmp_path / "elsewhere.nml"                   # absolute names: read from anywhere
    elsewhere.write_text(text)
    assert pymr.Scene(elsewhere).resolved(absolute_paths=True).rsplit("\n! fingerprint", 1)[0] == \
        text.rsplit("\n! fingerprint", 1)[0]


ITEMS = [  # (address, lower, upper) of real items of the tank scene, drawn at random
    ("scene.gravity", -20.0, 20.0), ("integrator.rtol", 1e-12, 1e-2),
    ("body[turret].mass", 1.0, 1e5), ("body[turret].com", -1.0, 1.0), ("body[mount].inertia", 400.0, 600.0),
    ("joint[traverse].at", -2.0, 2.0), ("joint[elevation].q0", -0.1, 0.1), ("joint[elevation].qd0", -1.0, 1.0),
    ("body[gun].density", 1000.0, 9000.0), ("body[gun].youngs_modulus", 1e10, 3e11),
    ("drive[traverse].amplitude", -1e5, 1e5), ("marker[muzzle].at", 0.1, 5.2),
]


@pytest.mark.parametrize("seed", range(6))
def test_random_valid_scenes_round_trip_bit_for_bit(seed, tmp_path):
    """Random values of 17 significant digits (any double) set through pymr.Scene are read
    back from the resolved scene exactly, and the resolved text reads back to itself."""
    rng = np.random.default_rng(seed)
    tank = ROOT / "input" / "tank_gun_turret.nml"
    scene = pymr.Scene(tank)
    chosen = {}
    for address, lo, hi in ITEMS:
        n = np.size(scene[address])
        value = rng.uniform(lo, hi, n) if n > 1 else float(rng.uniform(lo, hi))
        if address == "body[mount].inertia":
            value = np.concatenate([rng.uniform(lo, hi, 3), [0.0, 0.0, 0.0]])
        scene[address] = value
        chosen[address] = value
    text = scene.resolved()
    again = tmp_path / "again.nml"
    again.write_text(text)
    back = pymr.Scene(again)
    assert back.resolved() == text
    for address, value in chosen.items():
        # an item of several values reads back as a list, even of one (joint q0: real(1..6))
        assert np.array_equal(np.atleast_1d(np.asarray(back[address], dtype=float)),
                              np.atleast_1d(np.asarray(value, dtype=float))), address


def test_scene_items_are_the_kernel_s_and_a_refused_set_changes_nothing(tmp_path):
    tank = ROOT / "input" / "tank_gun_turret.nml"
    scene = pymr.Scene(tank)
    assert scene["integrator.method"] == "single"
    assert scene["body[gun].n_elements"] == 20
    assert scene["body[gun].r_outer"] == 0.11
    assert scene["effects.gravity"] is True
    assert scene["joint[elevation].axis"] == [0.0, 0.0, -1.0]
    scene["body[gun].n_elements"] = 40
    scene["integrator.method"] = "multirate"
    assert scene["body[gun].n_elements"] == 40 and scene["integrator.method"] == "multirate"
    before = scene.overrides
    for address, value, message in [
            ("body[gun].n_elements", 2.5, r"n_elements: '2.5' is not a whole number"),
            ("body[gun].n_elementz", 4, r"unknown item 'n_elementz' .*did you mean 'n_elements'\?"),
            ("body[barrel].mass", 1.0, r"no &body group with name 'barrel'"),
            ("integrator.method", "fast", r"method: 'fast' is not one of: single, multirate"),
            ("body[turret].mass", float("nan"), r"mass: 'nan' is not a finite number"),
            ("joint[traverse].axis", [0.0, 1.0], r"axis: takes 3 values, got 2")]:
        with pytest.raises(pymr.SceneError, match=message):
            scene[address] = value
        assert scene.overrides == before
    # run() takes the Scene; its overrides are the same as given to run()
    a = pymr.run(scene, overrides={"scene.t_end": 0.01})
    b = pymr.run(tank, overrides={"body[gun].n_elements": 40, "integrator.method": "multirate",
                                  "scene.t_end": 0.01})
    assert np.array_equal(a.data, b.data)


def test_a_selector_may_quote_the_group_s_name_as_the_scene_does(tmp_path):
    """body['gun'] and body["gun"] name the same group as body[gun]: the same run, and not
    the unchanged scene's (the gun's 20 elements against 10)."""
    tank = ROOT / "input" / "tank_gun_turret.nml"
    runs = [pymr.run(tank, tmp_path / f"{i}.csv", overrides={"scene.t_end": 0.01, address: 10})
            for i, address in enumerate(("body[gun].n_elements", "body['gun'].n_elements",
                                         'body["gun"].n_elements'))]
    plain = pymr.run(tank, tmp_path / "plain.csv", overrides={"scene.t_end": 0.01})
    assert np.array_equal(runs[0].data, runs[1].data) and np.array_equal(runs[0].data, runs[2].data)
    assert np.abs(runs[0]["muzzle.y"] - plain["muzzle.y"]).max() > 1e-9
    assert pymr.Scene(tank, {"body['gun'].n_elements": 10})["body[gun].n_elements"] == 10


def test_a_byte_order_mark_at_the_start_of_a_scene_is_read_as_blanks(tmp_path):
    """A scene saved with a UTF-8 byte-order mark (some editors write one) gives the same
    rows as without it, and its faults keep their lines."""
    pendulum = ROOT / "input" / "pendulum.nml"
    bom = tmp_path / "bom.nml"
    bom.write_bytes(b"\xef\xbb\xbf" + pendulum.read_bytes())
    a = pymr.run(bom, tmp_path / "a.csv")
    b = pymr.run(pendulum, tmp_path / "b.csv")
    assert np.array_equal(a.data, b.data)
    bad = tmp_path / "bad.nml"
    bad.write_bytes(b"\xef\xbb\xbf" + pendulum.read_bytes().replace(b"mass = 1.0", b"mass = -1.0", 1))
    with pytest.raises(pymr.SceneError, match=r"bad\.nml:(\d+): &body 'bob': mass") as e:
        pymr.run(bad, tmp_path / "c.csv")
    line = int(re.search(r"bad\.nml:(\d+):", str(e.value)).group(1))
    assert b"mass = -1.0" in bad.read_bytes().splitlines()[line - 1]


def test_result_json_carries_the_fingerprint_of_the_resolved_scene(tmp_path):
    tank = ROOT / "input" / "tank_gun_turret.nml"
    over = {"scene.t_end": 0.01, "body[gun].n_elements": 10}
    res = pymr.run(tank, tmp_path / "t.csv", overrides=over)
    scene = pymr.Scene(tank, over)
    assert res.stats["scene_fingerprint"] == scene.fingerprint
    body = scene.resolved().rstrip("\n").rsplit("\n", 1)[0] + "\n"
    assert scene.fingerprint == "sha256:" + hashlib.sha256(body.encode()).hexdigest()
    # a different scene, a different fingerprint; the same scene written differently, the same
    assert pymr.Scene(tank, {**over, "body[gun].n_elements": 11}).fingerprint != scene.fingerprint
    rewritten = tmp_path / "same.nml"
    rewritten.write_text(scene.resolved().replace("\n  ", "\n      ").replace(" = ", "="))
    assert pymr.Scene(rewritten).fingerprint == scene.fingerprint


def test_pymr_scene_command_prints_the_resolved_scene_and_the_schema(tmp_path):
    tank = ROOT / "input" / "tank_gun_turret.nml"
    r = subprocess.run(["pymr", "scene", str(tank), "--set", "integrator.method=multirate"], capture_output=True,
                       text=True, cwd=tmp_path, timeout=60)
    assert r.returncode == 0, r.stderr
    assert r.stdout == pymr.Scene(tank, ["integrator.method=multirate"]).resolved()
    assert "  method = 'multirate'\n" in r.stdout
    r = subprocess.run(["pymr", "scene", "--schema"], capture_output=True, text=True, cwd=tmp_path, timeout=60)
    assert r.returncode == 0 and r.stdout == pymr.schema()
    r = subprocess.run(["pymr", "scene", str(tank), "--set", "body[gun].mass=1"], capture_output=True, text=True,
                       cwd=tmp_path, timeout=60)
    assert r.returncode == 1 and r.stderr.count("\n") == 1
    assert "&body 'gun': mass: not an item of a beam body" in r.stderr


def schema_markdown() -> str:
    """docs/scenes.md's scene reference as the schema gives it: one table per group."""
    out = []
    # a group starts at a line '&name' (an item's meaning may hold '&' too: '&effects gravity')
    for block in re.split(r"^&", pymr.schema(), flags=re.M)[1:]:
        name, *rows = block.rstrip("\n").split("\n")
        out += [f"**&{name}**", "", "| item | type | default | allowed | unit | meaning |", "|---|---|---|---|---|---|"]
        for row in rows:
            cells = [c.replace("|", "\\|") for c in row.split("\t")]
            out.append("| " + " | ".join(f"`{cells[0]}`" if i == 0 else c for i, c in enumerate(cells)) + " |")
        out.append("")
    return "\n".join(out)


def test_readme_scene_reference_is_the_schema():
    readme = (ROOT / "docs" / "scenes.md").read_text()
    m = re.search(r"<!-- schema begin -->\n(.*?)<!-- schema end -->", readme, re.S)
    assert m, "docs/scenes.md has no generated scene reference"
    assert m.group(1) == schema_markdown(), "docs/scenes.md's scene reference differs from `pymr scene --schema`: " \
        "regenerate it as docs/development.md says"


def test_a_scene_file_changed_on_disk_is_read_again(tmp_path):
    """A Scene made from a file, the file then rewritten (t_end 1 -> 0.5, the gun's modes_y 2
    -> 1): its resolved text, fingerprint and model are the new file's, as a Scene made
    afresh from it gives them and as run() reads it; they were the old text's."""
    path = tmp_path / "tank.nml"
    text = (ROOT / "input" / "tank_gun_turret.nml").read_text()
    path.write_text(text)
    scene = pymr.Scene(path)
    old_size = pymr.model_size(scene)
    old_print = scene.fingerprint
    new_text = re.sub(r"t_end\s*=\s*[0-9.]+", "t_end = 0.5", text, count=1).replace("modes_y = 2, modes_z = 2", "modes_y = 1, modes_z = 2", 1)
    assert new_text != text
    path.write_text(new_text)
    st = path.stat()
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 1_000_000_000))    # a clock that did not move
    fresh = pymr.Scene(path)
    assert scene.fingerprint == fresh.fingerprint != old_print
    assert scene["scene.t_end"] == 0.5 and "t_end = 0.5" in scene.resolved()
    assert pymr.model_size(scene) == pymr.model_size(fresh) != old_size


def test_in_and_iteration_say_what_a_scene_and_results_hold(tmp_path):
    """`in` on a Scene is whether an address reads a value; iterating a Scene is refused in
    one line saying how items are read (both fell back to scene[0], "a name (str), got int
    0"). Iterating Results gives its column names, as `in` and res[name] take them."""
    scene = pymr.Scene(ROOT / "input" / "tank_firing.nml")
    assert "scene.t_end" in scene and "body[gun].mass" in scene and "motion[suspension].form" in scene
    assert "x" not in scene and "body[nope].mass" not in scene and "body[gun].masss" not in scene
    assert "motion[suspension].amplitude" not in scene          # six groups, values differ
    with pytest.raises(TypeError, match=r"^a Scene is not iterable: read an item by its address"):
        list(scene)
    res = pymr.run(scene, tmp_path / "r.csv", overrides={"scene.t_end": 0.01})
    assert list(res) == res.columns and all(name in res for name in res)
    assert all(np.array_equal(res[name], res.data[:, k]) for k, name in enumerate(res))


def test_a_name_several_groups_share_reads_their_value_only_when_they_agree():
    """tank_firing's six &motion of joint 'suspension' (lines 27-32): an override sets all
    six, so a read of the same address gives their one value when they agree (form,
    frequency after an override) and is refused, naming two that differ and their lines,
    when they do not (amplitude 0 on line 27 against 0.03 on line 28)."""
    scene = pymr.Scene(ROOT / "input" / "tank_firing.nml")
    assert scene["motion[suspension].form"] == "sine"
    with pytest.raises(pymr.SceneError) as exc:
        scene["motion[suspension].amplitude"]
    assert str(exc.value) == ("motion[suspension].amplitude: 6 &motion groups have joint 'suspension' and their "
                              "amplitude differs (0 in &motion #1 at line 27, 0.03 in &motion #2 at line 28): a read "
                              "gives one value (an override sets them all)")
    scene["motion[suspension].amplitude"] = 0.05
    assert scene["motion[suspension].amplitude"] == 0.05
    assert scene.resolved().count("amplitude = 0.05") == 6


def test_one_fault_an_override_gives_several_groups_is_one_line(tmp_path, mrsim):
    """'rate' is an item of form 'spinup' only: set on the six sine &motion of joint
    'suspension', it is one fault, told once with the count of the other groups (it was six
    lines, one per group); two faults of one scene stay two lines."""
    scene = ROOT / "input" / "tank_firing.nml"
    r = subprocess.run([mrsim, scene, "--set", "motion[suspension].rate=1", "-o", tmp_path / "r.csv"],
                       capture_output=True, text=True)
    assert r.returncode == 1 and r.stdout == ""
    assert r.stderr.splitlines() == [f"mrsim: error: {scene}: --set motion[suspension].rate=1: &motion #1: rate: "
                                     "only form 'spinup' uses it (form is 'sine') (the same in 5 more groups)"]
    r = subprocess.run([mrsim, scene, "--set", "motion[suspension].rate=1", "--set", "body[gun].rayleigh_alpha=0.5",
                        "-o", tmp_path / "r.csv"], capture_output=True, text=True)
    lines = r.stderr.splitlines()
    assert r.returncode == 1 and len(lines) == 2
    assert lines[0].endswith("(the same in 5 more groups)") and "rayleigh_alpha" in lines[1]
    assert not (tmp_path / "r.csv").exists()


def test_readme_scene_reference_has_every_group_and_item_once():
    """Read back apart from the generator: docs/scenes.md's tables name the kernel's groups, in
    its order, each with its items and their type, default, range and unit."""
    readme = (ROOT / "docs" / "scenes.md").read_text()
    ref = re.search(r"<!-- schema begin -->\n(.*?)<!-- schema end -->", readme, re.S).group(1)
    groups = re.findall(r"^\*\*&(.*?)\*\*$", ref, re.M)
    expect = {}
    for line in pymr.schema().splitlines():
        if line.startswith("&"):
            group = line[1:]
            expect[group] = []
        else:
            expect[group].append(line.split("\t"))
    assert groups == list(expect) == ["scene", "integrator", "effects", "output", "body", "joint", "drive",
                                      "spring", "motion", "load", "marker", "force", "control", "moving_load",
                                      "sensor"]
    got = {}
    for group, table in zip(groups, re.split(r"^\*\*&\w+\*\*$", ref, flags=re.M)[1:]):
        rows = [r for r in table.splitlines() if r.startswith("| `")]
        got[group] = [[c.strip().replace("\\|", "|") for c in re.split(r" \| ", r[2:-2])] for r in rows]
        for row in got[group]:
            row[0] = row[0].strip("`")
    assert got == expect


def test_parse_value_reads_what_the_kernel_writes():
    assert parse_value("1") == 1 and parse_value("1e-6") == 1e-6 and parse_value(".false.") is False
    assert parse_value("'a, b'") == "a, b" and parse_value("'it''s'") == "it's"
    assert parse_value("0, -9.81, 0") == [0, -9.81, 0]


def test_the_checks_report_every_fault_they_find_up_to_ten(tmp_path, mrsim):
    """The scene's rules are checked in one pass: four independent faults give four lines
    (exit 1), each naming file, line, group and item; fourteen give ten and a count."""
    text = """&scene title = 'faults', t_end = 1.0 /
&integrator method = 'single', h_slow = 1e-3 /
&body name = 'ground', kind = 'ground' /
&body name = 'a', kind = 'rigid', inertia = 1, 1, 1, 0, 0, 0 /
&body name = 'b', kind = 'rigid', mass = 1.0, inertia = 1, 1, 5, 0, 0, 0 /
&joint name = 'j1', kind = 'revolute', parent = 'ground', child = 'a' /
&joint name = 'j2', kind = 'revolute', parent = 'a', child = 'nobody' /
&marker name = 'm', body = 'c' /
"""
    (tmp_path / "four.nml").write_text(text)
    r = subprocess.run([mrsim, "four.nml", "-o", "x.csv"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert r.returncode == 1
    assert r.stderr.splitlines() == [
        "mrsim: error: four.nml:4: &body 'a': mass: missing (kg)",
        "mrsim: error: four.nml:5: &body 'b': inertia: principal moments 1, 1, 5 break the triangle inequality "
        "(no real body has them)",
        "mrsim: error: four.nml:7: &joint 'j2': child: no &body named 'nobody'",
        "mrsim: error: four.nml:8: &marker 'm': body: no &body named 'c'"]
    many = text + "".join(f"&marker name = 'x{i}', body = 'nowhere' /\n" for i in range(10))
    (tmp_path / "many.nml").write_text(many)
    r = subprocess.run([mrsim, "many.nml", "-o", "x.csv"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    lines = r.stderr.splitlines()
    assert r.returncode == 1 and len(lines) == 11 and lines[-1] == "mrsim: error: (and 4 more errors)"
    with pytest.raises(pymr.SceneError) as exc:
        pymr.run(tmp_path / "four.nml")
    assert len(str(exc.value).splitlines()) == 4


def test_import_from_the_source_tree_says_the_kernel_is_not_built():
    """From the checkout root, `import pymr` finds the source folder, which has no compiled
    kernel: the error says so and how to build it (not a circular-import error)."""
    import sys
    r = subprocess.run([sys.executable, "-c", "import pymr"], cwd=ROOT, capture_output=True, text=True, timeout=60)
    assert r.returncode == 1
    last = r.stderr.strip().splitlines()[-1]
    assert last.startswith("ImportError: pymr's compiled kernel (pymr._core) is not here")
    assert "bash .ci/setup" in last


def test_the_corrector_item_states_the_jacobian_age_the_stepper_uses():
    """&integrator corrector's meaning gives the age at which the 'newton' corrector renews its
    Jacobian: the number the stepper uses (fortran/integrator/adams.f90, jac_max_age)."""
    source = (ROOT / "fortran" / "integrator" / "adams.f90").read_text()
    age = re.search(r"integer, parameter :: jac_max_age = (\d+)", source).group(1)
    meaning = next(line.split("\t")[-1] for line in pymr.schema().split("&integrator\n")[1].splitlines()
                   if line.startswith("corrector\t"))
    assert f"renewed when it is {age} steps old" in meaning
