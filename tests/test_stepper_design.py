"""Steppers complete in themselves (issue 31 item 3): the projection of closed loops runs
inside the stepper's advance, so that every caller (the run, pymr.step_history) retraces
the same steps, and a step whose projection fails is redone smaller (adaptive) or stops
the run naming the time (fixed); a checkpoint of an older layout is refused in one line."""
from __future__ import annotations

import hashlib
import struct

import numpy as np
import pytest

import pymr
from pymr import _testhooks
from test_loops import fourbar_scene

# the position projection's tolerance (model/loops.f90 closure_tol): |phi| <= 1e-13 max(size, 1 m)
CLOSURE_TOL = 1.0e-13

STEPPERS = {
    "adaptive abm4": {"integrator.formula": "abm4"},
    "adaptive adams": {"integrator.formula": "adams"},
    "fixed abm4": {"integrator.adaptive": False, "integrator.h_slow": 1e-3},
}


@pytest.mark.parametrize("stepper", list(STEPPERS))
def test_step_history_retraces_the_run_on_a_closed_loop(tmp_path, stepper):
    """The four-bar (a loop closed by a revolute) with a row at every step (output dt = 0):
    pymr.step_history takes the run's own steps. step_history returns the steps, not the
    states; the adaptive steps are chosen from the error estimates of the states reached, so
    equal steps over 0.5 s mean equal (projected) states all along: before the projection
    moved into the stepper, step_history's steps left the run's at 0.034 s (adaptive abm4,
    by 1e-13 s, growing to 1e-6 s; adaptive adams likewise), as its unprojected states gave
    other error estimates. Both are the same computation in the same process, so they agree
    exactly (no tolerance). Fixed steps keep their grid either way: there the test checks
    the grid and the rows' closure. Every row at a step closes the loop to the projection's
    tolerance."""
    scene = tmp_path / "f.nml"
    scene.write_text(fourbar_scene(1.0, 2.0, t_end=0.5).replace("dt = 0.01", "dt = 0.0"))
    over = {"integrator.rtol": 1e-8, "integrator.atol": 1e-10, **STEPPERS[stepper]}
    res = pymr.run(scene, tmp_path / "f.csv", overrides=over)
    t, h, q = pymr.step_history(scene, overrides=over)
    # the run's rows are at its steps (dt = 0), but for the start and t_end, which the last
    # step passes (its row interpolated); the history begins where the start's steps end
    assert len(t) > 50 and t[-1] >= 0.5 > t[-2]
    inside = lambda x: x[(x > t[0]) & (x < 0.5)]
    np.testing.assert_array_equal(inside(res.t), inside(t))
    np.testing.assert_array_equal(np.diff(t), h[1:])
    # the rows at the steps hold the projected states (to 17 digits): their residual is the
    # projection's, closure_tol times the loops' size (the largest distance of a joint from
    # the origin, below the links' and the ground's lengths summed, 3.1 m; measured 1.3e-13 m)
    at_steps = np.isin(res.t, inside(t))
    qn = np.column_stack([res[f"{j}.q"] for j in "ABC"])[at_steps]
    qdn = np.column_stack([res[f"{j}.qd"] for j in "ABC"])[at_steps]
    worst = max(np.abs(pymr.loop_rows(scene, qk, qdk)[0]).max() for qk, qdk in zip(qn, qdn))
    assert worst <= 3.1 * CLOSURE_TOL


def test_a_checkpoint_of_the_older_layout_is_refused_in_one_line(tmp_path):
    """Checkpoint version 14 (6 wrote the stepper as its state vector and its record; 7 named
    the 'response' and 'exponential' steppers apart; 8 keeps the 'response' macro step's
    surrogate correction for its dense output; 9 the results' last row and the run's
    warnings; 10 the step counts of the methods 'auto' handed over from; 11 the adaptive
    multirate steppers' last error estimate and step; 12 the last 'response' macro step's
    error model; 13 the adaptive multirate steppers' last eight; 14 the 'exponential'
    stepper's watch of its response's drift); a version 5 file (the same bytes
    with the older version number and a valid checksum) is refused, naming both versions."""
    scene = tmp_path / "f.nml"
    scene.write_text(fourbar_scene(1.0, 2.0, t_end=0.3))
    out = tmp_path / "f.csv"
    over = {"output.checkpoint_dt": 0.2}
    pymr.run(scene, out, overrides=over)
    data = bytearray((tmp_path / "f.ckpt").read_bytes())
    assert data[:8] == b"PYMRCKPT" and struct.unpack("<i", data[8:12])[0] == 14
    data[8:12] = struct.pack("<i", 5)
    body = bytes(data[:-64])
    (tmp_path / "old.ckpt").write_bytes(body + hashlib.sha256(body).hexdigest().encode())
    with pytest.raises(pymr.SceneError) as exc:
        pymr.run(scene, out, overrides={**over, "scene.t_end": 0.5}, restart=tmp_path / "old.ckpt")
    assert "\n" not in str(exc.value)
    assert "old.ckpt: checkpoint version 5, this pymr reads 14" in str(exc.value)


def _oscillator_on_circle(t_end, h, adaptive, order=-1):
    """pymr_ode_test problem 6: x'' = -x from (1, 0) with |x| = 1 as a constraint, whose
    projection fails further than 1e-9 from the circle (test_odes.f90)."""
    x, steps, evals, rejected, *_, stat, message = _testhooks.pymr_ode_test(
        6, t_end, h, 1 if adaptive else 0, 1e-6, 1e-8, 1, order, 2, 1)
    message = message.decode().strip() if isinstance(message, bytes) else str(message).strip()
    return np.array(x, dtype=float), int(steps), int(rejected), int(stat), message


def test_fixed_steps_stop_at_a_failed_projection_naming_the_time():
    """A fixed step of 0.1 leaves the circle by about 1e-7: the first step after the start
    (two steps to 0.2 s) fails its projection, and the run stops with the time."""
    *_, stat, message = _oscillator_on_circle(10.0, 0.1, False)
    assert stat != 0 and message == "at t = 0.3 s: the projection onto |x| = 1 did not converge"
    x, steps, rejected, stat, _ = _oscillator_on_circle(10.0, 1e-3, False)
    assert stat == 0 and rejected == 0
    assert abs(np.linalg.norm(x) - 1.0) <= 2e-16           # projected at every step, t_end one


@pytest.mark.parametrize("order", [-1, 0], ids=["abm4", "adams"])
def test_adaptive_steps_redo_a_step_whose_projection_fails(order):
    """At rtol 1e-6 the error test lets steps leave the circle by more than the projection
    reaches (1e-9): the stepper redoes each such step at a quarter of it (CVODE's projection
    failure) and the run completes, where it would stop otherwise. The redone steps count
    as rejected: about one per accepted step, as the controller grows the step again after
    each (measured 1160 of 1163 steps for abm4, 558 of 1122 for adams; problem 1, the same
    without the constraint, rejects 1 and 0). The end state, interpolated in the last step,
    is within the projection's reach of the circle and within 1e-7 of cos t, -sin t
    (measured 1.6e-8 and 2.3e-8)."""
    x, steps, rejected, stat, message = _oscillator_on_circle(10.0, 0.1, True, order)
    assert stat == 0, message
    assert rejected > steps // 3
    assert abs(np.linalg.norm(x) - 1.0) <= 1e-9
    assert np.abs(x - [np.cos(10.0), -np.sin(10.0)]).max() < 1e-7
