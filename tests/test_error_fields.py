"""Kernel errors carry structured fields beside their message (issue 31, item 5): the
binding returns them and pymr's exceptions hold them as attributes, so that no Python code
reads the kernel's words."""
from __future__ import annotations

from pathlib import Path

import pytest

import pymr

ROOT = Path(__file__).resolve().parent.parent
PENDULUM = ROOT / "input" / "pendulum.nml"
TANK = ROOT / "input" / "tank_gun_turret.nml"
STIFF = ROOT / "input" / "hard" / "stiff_barrel.nml"


def test_a_refused_fixed_step_carries_its_largest_stable_step(tmp_path):
    """The stiff barrel's mode 8 (1015 Hz) refuses h = 7.07e-5 s; the largest stable step,
    0.430 / omega, is 6.742e-5 s (the message rounds it to 6.74E-05)."""
    with pytest.raises(pymr.SceneError) as exc:
        pymr.run(STIFF, tmp_path / "x.csv", overrides={"integrator.adaptive": False, "integrator.h_slow": 7.07e-5,
                                                       "integrator.h_fast": 7.07e-5, "scene.t_end": 0.02})
    e = exc.value
    assert (e.kind, e.group, e.item, e.stable_ratio) == ("unstable_step", "integrator", "h_slow", None)
    assert e.stable_step == pytest.approx(6.742e-5, rel=1e-4)
    assert f"the largest stable step is {e.stable_step:.2E} s" in str(e)


def test_a_refused_step_ratio_carries_the_largest_stable_ratio(tmp_path):
    """The tank's 'full' coupling at h_fast = 1e-4 s is stable up to k = 33 (test_hard_cases)."""
    with pytest.raises(pymr.SceneError) as exc:
        pymr.run(TANK, tmp_path / "x.csv", overrides={
            "integrator.method": "multirate", "integrator.coupling": "full", "integrator.h_fast": 1e-4,
            "integrator.h_slow": 50e-4, "output.dt": 50e-4})
    e = exc.value
    assert (e.kind, e.group, e.item, e.stable_ratio, e.stable_step) == (
        "unstable_ratio", "integrator", "h_slow", 33, None)


def test_a_refused_value_names_its_group_item_and_fault():
    with pytest.raises(pymr.SceneError) as exc:
        pymr.Scene(PENDULUM, {"scene.t_end": 1e308})
    e = exc.value
    assert (e.kind, e.group, e.item) == ("bad_value", "scene", "t_end")
    assert e.fault == "must be in (0, 1e+9], got 1e+308" and str(e).endswith(": t_end: " + e.fault)
    with pytest.raises(pymr.SceneError) as exc:
        pymr.Scene(PENDULUM, {"joint[pivot].q0": "x"})
    assert (exc.value.kind, exc.value.group, exc.value.item) == ("bad_value", "joint", "q0")


def test_other_errors_have_the_kind_of_their_status():
    """Bad input without a kind of its own is 'bad_input'; an error raised in Python has no
    kernel fields."""
    with pytest.raises(pymr.SceneError) as exc:
        pymr.Scene(PENDULUM, ["nogroup.item=1"])
    assert (exc.value.kind, exc.value.stable_step, exc.value.stable_ratio) == ("bad_input", None, None)
    with pytest.raises(pymr.SceneError) as exc:
        pymr.run(PENDULUM, restart="")
    assert exc.value.kind == "" and exc.value.group == ""
