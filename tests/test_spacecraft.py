"""input/spacecraft.nml (issue 14's scene where the scales separate): a rigid core turned by a
slow torque, carrying two 4 m booms with 12 bending modes per plane each (48 modal
coordinates, 6 Hz to 2.2 kHz). Checked against the analytic cantilever frequencies and
against a single-rate run."""
from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import pymr

SCENE = Path(__file__).resolve().parent.parent / "input" / "spacecraft.nml"


def test_top_boom_mode_is_the_clamped_cantilever_s_twelfth():
    """The pre-flight check names the stiffest mode: the booms' 12th bending mode, whose
    clamped-cantilever frequency is (36.128)^2/(2 pi L^2) sqrt(EI/rho A) = 2223.5 Hz for the
    aluminium tube (24 elements and the turning core's coupling: within 1 %)."""
    r_o, r_i, e, rho, length = 0.05, 0.045, 7.0e10, 2700.0, 4.0
    beta_l = (2 * 12 - 1) * np.pi / 2     # the root of cos(bL) cosh(bL) = -1, to e^-36 at n = 12
    f12 = beta_l**2 / (2 * np.pi * length**2) * np.sqrt(e * (r_o**2 + r_i**2) / 4 / rho)
    assert f12 == pytest.approx(2223.5, abs=0.2)
    with pytest.raises(pymr.SceneError) as exc:
        pymr.run(SCENE, overrides={"integrator.adaptive": False, "integrator.h_slow": 1e-4, "scene.t_end": 0.01})
    m = re.search(r"body 'boom_(left|right)', mode 12 \(([\d.]+) Hz", str(exc.value))
    assert m, str(exc.value)
    assert float(m.group(2)) == pytest.approx(f12, rel=0.01)


def test_multirate_follows_the_single_rate_run_to_a_millionth_of_the_tip_travel():
    """Over 0.3 s, multirate ('response', h_fast = 2.5e-5 s, k = 10) and adaptive multirate
    (rtol 1e-6, fast step held below the top mode's stability limit) keep the right boom's
    tip within 1e-6 of its travel of single-rate steps of 3e-5 s."""
    over = {"scene.t_end": 0.3, "output.dt": 3e-3}
    single = pymr.run(SCENE, overrides={**over, "integrator.adaptive": False, "integrator.h_slow": 3e-5})
    travel = np.abs(single.marker("tip_right")[0] - single.marker("tip_right")[0][0]).max()
    assert travel > 1e-3
    for setting in ({"integrator.adaptive": False, "integrator.h_fast": 2.5e-5, "integrator.h_slow": 2.5e-4},
                    {"integrator.rtol": 1e-6, "integrator.atol": 1e-9}):
        res = pymr.run(SCENE, overrides={**over, "integrator.method": "multirate", **setting})
        assert res.t == pytest.approx(single.t)
        assert np.abs(res.marker("tip_right")[0] - single.marker("tip_right")[0]).max() < 1e-6 * travel


@pytest.mark.parametrize("zeta", [0.0, 0.05])
def test_response_is_the_single_rate_method_where_the_only_stiffness_is_modal(zeta):
    """At rest and without gravity, the spacecraft's linearised stiffness and damping are the
    booms' modal ones alone. On such a model the 'response' surrogate is exact, and a macro
    step is k single-rate steps of h_fast: the pre-flight check therefore judges 'response'
    by the modes alone, without the macro-step map. Over 0.3 s at k = 100 (H = 2.5e-3 s),
    undamped and with 5 % modal damping, the right tip stays within 1e-8 of its travel of
    single-rate steps of h_fast (measured 7.8e-11, every column within 8e-13 of its largest
    value: roundoff). A surrogate that extrapolated the modal forces would be off by about
    (omega_1 H)^4 = 1e-4 of the travel (first mode 6 Hz)."""
    h = 2.5e-5
    over = {"scene.t_end": 0.3, "output.dt": 3e-3, "integrator.adaptive": False}
    if zeta:
        over.update({"effects.modal_damping": True, "body[boom_right].modal_damping": zeta,
                     "body[boom_left].modal_damping": zeta})
    single = pymr.run(SCENE, overrides={**over, "integrator.h_slow": h})
    multi = pymr.run(SCENE, overrides={**over, "integrator.method": "multirate", "integrator.h_slow": 100 * h,
                                       "integrator.h_fast": h})
    tip, tip_m = single.marker("tip_right")[0], multi.marker("tip_right")[0]
    travel = np.abs(tip - tip[0]).max()
    assert travel > 1e-3
    assert np.abs(tip_m - tip).max() < 1e-8 * travel


def test_a_refused_full_ratio_names_the_largest_stable_one_from_the_map_s_blocks():
    """The pre-flight check takes the macro-step map apart where its state components do not
    act on each other (the spacecraft's 'full' map of 400: blocks of 200, 96, 96 and 8, the
    booms' bending out of the slew's plane apart) and solves each block's eigenproblem. The
    scan for the largest stable ratio, block by block, names k = 13 at h_fast = 2.5e-5 s, as
    dgeev on the whole map did (commit 0e16ce4); the growth it reports at k = 50 comes from
    the whole map, with the dominant mode's vector."""
    with pytest.raises(pymr.SceneError) as exc:
        pymr.run(SCENE, overrides={"integrator.method": "multirate", "integrator.coupling": "full",
                                   "integrator.adaptive": False, "integrator.h_slow": 1.25e-3,
                                   "integrator.h_fast": 2.5e-5})
    msg = str(exc.value)
    assert "(k = 50, coupling 'full') is not stable" in msg and "\n" not in msg
    assert "the largest stable ratio is k = 13 " in msg
    assert exc.value.stable_ratio == 13
    growth = float(re.search(r"by (\d\.\d+);", msg).group(1))
    assert growth == pytest.approx(1.0039, abs=1e-4)
