"""The run's settings in its statistics file ("integrator" of OUT.json) are generated from
the &integrator item table: every item of the schema is there with the scene's resolved
value, and the keys the results have always had keep their values."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

import pymr

ROOT = Path(__file__).resolve().parent.parent

#: The keys of the hand-written settings before issue 31, read by pymr and the tests.
OLD_KEYS = ["method", "h_fast", "h_slow", "rtol", "atol", "h_min", "h_max", "n_corrector", "t_end", "adaptive",
            "coupling", "formula", "order", "corrector", "dynamics", "k_max"]


def integrator_items():
    """The &integrator items of the schema, in its order: {name: type}."""
    items, group = {}, None
    for line in pymr.schema().splitlines():
        if line.startswith("&"):
            group = line[1:]
        elif group == "integrator" and line.strip():
            name, kind = line.split("\t")[:2]
            items[name] = kind
    return items


@pytest.mark.parametrize("scene, overrides", [
    ("pendulum.nml", {"scene.t_end": 0.05}),
    ("pendulum.nml", {"scene.t_end": 0.05, "integrator.adaptive": True, "integrator.rtol": 3e-7,
                      "integrator.formula": "adams", "integrator.order": 5, "integrator.corrector": "fixed-point",
                      "integrator.max_steps": 123456, "integrator.h_max": 0.0125}),
    ("tank_gun_turret.nml", {"scene.t_end": 0.002, "integrator.method": "multirate", "integrator.h_fast": 1e-5,
                             "integrator.h_slow": 1e-4, "integrator.stability_check": False}),
])
def test_every_integrator_item_is_in_the_settings(tmp_path, scene, overrides):
    res = pymr.run(ROOT / "input" / scene, tmp_path / "out.csv", overrides=overrides)
    settings = json.loads((tmp_path / "out.json").read_text())["integrator"]
    resolved = pymr.Scene(ROOT / "input" / scene, overrides)
    items = integrator_items()
    assert len(items) >= 17 and set(OLD_KEYS) - {"t_end"} <= set(items)
    assert sorted(settings) == sorted([*items, "t_end"])
    types = {"real": float, "integer": int, "logical": bool, "string": str}
    for item, kind in items.items():
        value = resolved[f"integrator.{item}"]
        assert type(settings[item]) is types[kind], item
        if kind == "real":
            # ten significant digits, as the settings have always been written
            assert settings[item] == pytest.approx(value, rel=1e-10, abs=0), item
        else:
            assert settings[item] == value, item
    assert settings["t_end"] == overrides["scene.t_end"]
    assert res.stats["integrator"] == settings


def test_settings_keep_their_values(tmp_path):
    """The pendulum's settings, key by key, as the hand-written JSON gave them."""
    pymr.run(ROOT / "input" / "pendulum.nml", tmp_path / "p.csv", overrides={"scene.t_end": 0.05})
    settings = json.loads((tmp_path / "p.json").read_text())["integrator"]
    assert {k: settings[k] for k in OLD_KEYS} == {
        "method": "single", "h_fast": 1e-3, "h_slow": 1e-3, "rtol": 1e-6, "atol": 1e-8, "h_min": 0.0, "h_max": 0.0,
        "n_corrector": 1, "t_end": 0.05, "adaptive": False, "coupling": "response", "formula": "abm4", "order": 4,
        "corrector": "newton", "dynamics": "auto", "k_max": 50}
    text = (tmp_path / "p.json").read_text()
    assert '"h_slow": 0.1000000000E-2' in text and '"stability_check": true' in text


def test_statistics_of_a_scene_named_in_bytes_that_are_not_utf8_stay_json(tmp_path, mrsim):
    """A scene file named in Latin-1 (b'p\\xff\\xc3\\xa9.nml') put its name's raw bytes in
    OUT.json, which was then no UTF-8 JSON: `pymr run` failed after the run, and every reader
    of the results refused them (found by fuzzing). A byte that is no part of a valid UTF-8
    character is written as Python's surrogateescape \\uDCXX, so the JSON loads and
    os.fsencode gives the file's name back, byte for byte."""
    import os
    import subprocess
    name = b"p\xff\xc3\xa9\xc0\xaf\xc2\x85.nml"        # a stray byte, e acute, an overlong '/', U+0085
    scene = os.path.join(os.fsencode(tmp_path), name)
    with open(scene, "wb") as fh:
        fh.write((ROOT / "input" / "pendulum.nml").read_bytes())
    r = subprocess.run([str(mrsim), scene, "-o", "out.csv", "--set", "scene.t_end=0.02", "-q"], cwd=tmp_path,
                       capture_output=True, timeout=120)
    assert r.returncode == 0, r.stderr
    text = (tmp_path / "out.json").read_bytes().decode("utf-8")     # strict: the JSON is UTF-8
    stats = json.loads(text)
    assert os.fsencode(stats["scene"]) == scene
    assert 'p\\uDCFF\u00e9\\uDCC0\\uDCAF\\uDCC2\\uDC85.nml"' in text
    res = pymr.load_results(tmp_path / "out.csv")
    assert res.t[-1] == pytest.approx(0.02) and os.fsencode(res.stats["scene"]) == scene


@pytest.mark.parametrize("h_max", [1e9, 100.0, 123456789.0, 0.5])
def test_a_setting_of_ten_whole_digits_is_json(tmp_path, h_max):
    """h_max = 1e9, its largest value, was written "1000000000." (Fortran's g0 form), which
    no JSON reader takes: mrsim exited 0 and every reader refused the results (found by
    fuzzing). The statistics load, and give the value back."""
    res = pymr.run(ROOT / "input" / "pendulum.nml", tmp_path / "r.csv",
                   overrides={"scene.t_end": 0.02, "integrator.adaptive": True, "integrator.h_max": h_max})
    stats = json.loads((tmp_path / "r.json").read_text())
    assert stats["integrator"]["h_max"] == h_max and res.stats["integrator"]["h_max"] == h_max


def test_statistics_with_three_digit_exponents_are_json(tmp_path):
    """A static start's last change of 1e-200 and more was written by the Fortran format
    es12.5 as "3.41774-301", with no E (a three-digit exponent), which no JSON reader takes:
    mrsim exited 0 and pymr run failed after the run (found by fuzzing). The statistics load."""
    res = pymr.run(ROOT / "input" / "tank_hold.nml", tmp_path / "r.csv",
                   overrides={"scene.t_end": 0.01, "scene.gravity": [0.0, -1.0e-200, 0.0], "scene.start": "static"})
    stats = json.loads((tmp_path / "r.json").read_text())
    assert 0.0 <= stats["static_start"]["last_change"] < 1e-150 and res.stats["static_start"] == stats["static_start"]
