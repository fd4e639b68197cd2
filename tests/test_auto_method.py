"""`&integrator method = 'auto'` (issue 34): the kernel probes its candidate methods from the
initial state and runs the scene with the one whose predicted run is cheapest, going on from
its probe where it can. The run is then exactly the chosen method's run (the probes work on
copies of the model) unless a review handed it to another method, it continues from a
checkpoint with the method that wrote it, and the choice and the reviews are reported in
the summary and the JSON."""
from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr import _testhooks
from energy_balance import balance

ROOT = Path(__file__).resolve().parent.parent
SPACECRAFT = ROOT / "input" / "spacecraft.nml"
PENDULUM = ROOT / "input" / "pendulum.nml"
CHAIN = ROOT / "input" / "flexible_chain.nml"
TANK = ROOT / "input" / "tank_gun_turret.nml"
AUTO = {"integrator.method": "auto", "integrator.adaptive": True}
#: the explicit settings of each label the choice reports (a scene that gives no error_norm
#: runs its candidates with 'amplitude', unless a loop closes through a flexible body)
METHOD_OF = {
    "single-rate 'adams'": {"integrator.method": "single", "integrator.adaptive": True,
                            "integrator.error_norm": "amplitude"},
    "multirate 'exponential'": {"integrator.method": "multirate", "integrator.coupling": "exponential",
                                "integrator.adaptive": True, "integrator.formula": "abm4",
                                "integrator.error_norm": "amplitude"},
    "multirate 'response'": {"integrator.method": "multirate", "integrator.coupling": "response",
                             "integrator.adaptive": True, "integrator.formula": "abm4",
                             "integrator.error_norm": "amplitude"},
}
HUGE = np.finfo(float).max
COUNTS = ("steps_slow", "steps_fast", "rhs_full", "rhs_fast", "rejected_steps", "rows")


def _switched(res) -> bool:
    return any(r["took_over"] for r in res.stats["method_choice"]["reviews"])


def _same_run(a, b):
    assert np.array_equal(a.t, b.t) and np.array_equal(a.data, b.data)
    for key in COUNTS:
        assert a.stats[key] == b.stats[key], key


def test_a_scene_without_modal_coordinates_runs_single_rate_with_no_probe(tmp_path):
    auto = pymr.run(PENDULUM, tmp_path / "auto.csv", overrides=AUTO)
    choice = auto.stats["method_choice"]
    assert choice["chosen"] == "single-rate 'adams'" and "no fast (modal) coordinates" in choice["reason"]
    assert choice["probe_t_end"] == 0 and len(choice["candidates"]) == 1
    _same_run(auto, pymr.run(PENDULUM, tmp_path / "single.csv", overrides=METHOD_OF[choice["chosen"]]))


@pytest.mark.parametrize("quantities", [["coordinates", "markers"], ["coordinates", "markers", "energy"]])
def test_the_run_is_the_chosen_method_s_run_and_the_choice_is_reported(tmp_path, quantities):
    """Spacecraft over 0.5 s at rtol 1e-6: 'exponential' costs about 1/20 of 'adams' there, so
    the choice is 'exponential'; the run equals that method's own run (rows, counts), both
    where it goes on from the chosen probe and where it starts again (the energy columns'
    works integrate over the steps, which the probe did not); the chosen one has the least
    predicted CPU among the probes that finished; the summary names it and every
    candidate."""
    over = {**AUTO, "scene.t_end": 0.5, "output.quantities": quantities}
    auto = pymr.run(SPACECRAFT, tmp_path / "auto.csv", overrides=over)
    choice = auto.stats["method_choice"]
    assert choice["chosen"] == "multirate 'exponential'"
    assert choice["probe_t_end"] == pytest.approx(0.03 * 0.5)
    labels = [c["method"] for c in choice["candidates"]]
    assert sorted(labels) == sorted(METHOD_OF)
    finished = [c for c in choice["candidates"] if c["probe_cpu_s"] is not None]
    best = min(finished, key=lambda c: c["predicted_cpu_s"])
    assert best["method"] == choice["chosen"]
    assert all(c["failure"].startswith("stopped at t = ") or c["failure"].startswith("left out: ")
               for c in choice["candidates"] if c not in finished)
    assert auto.stats["integrator"]["method"] == "multirate"
    assert auto.stats["integrator"]["coupling"] == "exponential"
    assert auto.stats["integrator"]["error_norm"] == "amplitude"
    _same_run(auto, pymr.run(SPACECRAFT, tmp_path / "direct.csv", overrides={
        **METHOD_OF[choice["chosen"]], "scene.t_end": 0.5, "output.quantities": quantities}))
    line = next(s for s in auto.summary.splitlines() if s.startswith("auto: "))
    assert line.startswith("auto: multirate 'exponential', error_norm 'amplitude' (least predicted CPU; probes from 0 "
                           "to 0.015 s:")
    given = pymr.run(SPACECRAFT, tmp_path / "given.csv", overrides={**over, "integrator.error_norm": "state"})
    assert given.stats["integrator"]["error_norm"] == "state"      # a norm the scene gives is kept
    assert "error_norm 'state' (" in given.summary
    assert all(label in line for label in labels)


def test_response_is_probed_where_the_exponential_probe_froze_its_response_anew(tmp_path):
    """The tank's 'exponential' probe keeps the linear response it froze at the start, so
    'response', which carries the same frozen response by explicit fast steps, is left out
    of the start's probes, saying why. The flexible chain spinning at 10 rad/s in each joint
    from the start makes 'exponential' freeze anew inside its probe: 'response' is probed
    there (measured: predicted 38 ms against 42 for 'exponential')."""
    tank = pymr.run(TANK, tmp_path / "tank.csv", overrides={**AUTO, "scene.t_end": 0.3})
    by_method = {c["method"]: c for c in tank.stats["method_choice"]["candidates"]}
    assert by_method["multirate 'exponential'"]["probe_cpu_s"] is not None
    left = by_method["multirate 'response'"]
    assert left["probe_cpu_s"] is None and left["failure"] == ("left out: 'exponential' kept its frozen response "
                                                               "over its probe")
    assert "multirate 'response' left out," in tank.summary
    spin = {f"joint[{j}].qd0": 10.0 for j in ("waist", "shoulder", "elbow")}
    chain = pymr.run(CHAIN, tmp_path / "chain.csv", overrides={**AUTO, "scene.t_end": 0.5, **spin})
    probed = {c["method"]: c for c in chain.stats["method_choice"]["candidates"]}["multirate 'response'"]
    assert not probed["failure"].startswith("left out")
    assert probed["probe_cpu_s"] is not None or probed["failure"].startswith("stopped at t = ")


def test_a_loop_through_a_flexible_body_leaves_exponential_out(tmp_path):
    """'exponential' refuses such a loop, so it is no candidate; the run is the chosen one's."""
    from test_loops import flexible_coupler_scene
    scene, _ = flexible_coupler_scene(tmp_path)
    over = {**AUTO, "scene.t_end": 0.2, "integrator.rtol": 1e-6}
    auto = pymr.run(scene, tmp_path / "auto.csv", overrides=over)
    choice = auto.stats["method_choice"]
    assert sorted(c["method"] for c in choice["candidates"]) == ["multirate 'response'", "single-rate 'adams'"]
    assert auto.stats["integrator"]["error_norm"] == "state"       # 'amplitude' does not take the loop
    direct = {**METHOD_OF[choice["chosen"]], "scene.t_end": 0.2, "integrator.rtol": 1e-6,
              "integrator.error_norm": "state"}
    if choice["chosen"] == "multirate 'response'":
        direct["integrator.k_max"] = auto.stats["integrator"]["k_max"]
    run = pymr.run(scene, tmp_path / "direct.csv", overrides=direct)
    if _switched(auto):           # a review handed the run over: it ends where the method chosen first does
        assert np.abs(auto.data[-1] - run.data[-1]).max() <= 1e-3 * np.abs(run.data[-1]).max()
    else:
        _same_run(auto, run)


def test_an_auto_run_continues_from_its_checkpoint_with_the_method_it_chose(tmp_path):
    """Spacecraft cut at 0.55 s after a checkpoint at 0.4 s and restarted: the rows and counts
    equal the chosen method's uninterrupted run (no probe at the restart, which could choose
    another). 'exponential' costs a seventh of the others there, so no review hands it over."""
    over = {**AUTO, "integrator.rtol": 1e-6, "output.checkpoint_dt": 0.2, "scene.t_end": 1.0}
    out = tmp_path / "job.csv"
    cut = pymr.run(SPACECRAFT, out, overrides={**over, "scene.t_end": 0.55})
    chosen = cut.stats["method_choice"]["chosen"]
    assert not _switched(cut)
    res = pymr.run(SPACECRAFT, out, overrides=over, restart=tmp_path / "job.ckpt")
    assert res.stats["method_choice"]["chosen"] == chosen
    assert res.stats["method_choice"]["reason"] == "the method the checkpoint was written with"
    full = pymr.run(SPACECRAFT, tmp_path / "full.csv", overrides={**METHOD_OF[chosen], "integrator.rtol": 1e-6,
                                                                   "scene.t_end": 1.0})
    assert np.array_equal(res.t, full.t)
    assert np.abs(res.data - full.data).max() <= 1e-10 * np.abs(full.data).max()
    for key in COUNTS:
        assert res.stats[key] == full.stats[key], key


def test_auto_with_fixed_steps_is_refused_in_one_line(tmp_path, mrsim):
    r = subprocess.run([mrsim, str(TANK), "-o", "x.csv", "--set", "integrator.method=auto"], capture_output=True,
                       text=True, cwd=tmp_path)
    assert r.returncode == 1 and r.stdout == ""
    msg = r.stderr.strip()
    assert "\n" not in msg and "&integrator: method: 'auto' chooses among adaptive methods" in msg
    assert "set adaptive = .true." in msg and not (tmp_path / "x.csv").exists()


def test_the_json_names_the_choice_for_post_processing(tmp_path):
    auto = pymr.run(SPACECRAFT, tmp_path / "auto.csv", overrides={**AUTO, "scene.t_end": 0.2})
    stats = json.loads((tmp_path / "auto.json").read_text())
    assert stats["method_choice"] == auto.stats["method_choice"]
    assert set(stats["method_choice"]) == {"chosen", "reason", "probe_t_end", "candidates", "reviews", "ended_with"}
    for c in stats["method_choice"]["candidates"]:
        assert set(c) == {"method", "probe_cpu_s", "predicted_cpu_s", "failure"}
        assert (c["probe_cpu_s"] is None) == (c["predicted_cpu_s"] is None) == bool(c["failure"])


@pytest.mark.parametrize("sets, expected", [
    (["integrator.h_fast=1e-5", "integrator.h_slow=1e-3"],
     "&integrator: h_slow: method 'auto' chooses the steps (its candidates start from h_slow): set h_fast = h_slow"),
    (["integrator.adaptive=.false."], "&integrator: method: 'auto' chooses among adaptive methods"),
])
def test_settings_auto_cannot_take_are_refused_in_one_line(tmp_path, mrsim, sets, expected):
    args = [mrsim, str(SPACECRAFT), "-o", "x.csv", "--set", "integrator.method=auto"]
    for item in sets:
        args += ["--set", item]
    r = subprocess.run(args, capture_output=True, text=True, cwd=tmp_path)
    assert r.returncode == 1 and "\n" not in r.stderr.strip() and expected in r.stderr


def test_a_step_history_of_auto_is_refused_and_a_full_coupling_checkpoint_is_not_continued(tmp_path):
    with pytest.raises(pymr.SceneError, match="method: 'auto' chooses by timing probes"):
        pymr.step_history(TANK, overrides={**AUTO, "scene.t_end": 0.1})
    out = tmp_path / "job.csv"
    full = {"integrator.method": "multirate", "integrator.coupling": "full", "integrator.adaptive": True,
            "integrator.rtol": 1e-6, "output.checkpoint_dt": 0.1}
    pymr.run(TANK, out, overrides={**full, "scene.t_end": 0.15})
    with pytest.raises(pymr.SceneError) as exc:
        pymr.run(TANK, out, overrides={**AUTO, "integrator.rtol": 1e-6, "output.checkpoint_dt": 0.1},
                 restart=tmp_path / "job.ckpt")
    assert "job.ckpt: the checkpoint was written by the 'multirate' stepper, which method 'auto' never chooses" \
        in str(exc.value) and "\n" not in str(exc.value)


def test_when_every_probe_fails_the_single_rate_run_reports_why(tmp_path, mrsim):
    """h_min = 0.05 s leaves no candidate a step it can take: the run is single-rate, fails
    with exit 2 naming the time and the cause, and its partial JSON keeps each probe's
    failure."""
    r = subprocess.run([mrsim, str(TANK), "-o", "f.csv", "--set", "integrator.method=auto", "--set",
                        "integrator.adaptive=.true.", "--set", "integrator.h_min=0.05"], capture_output=True,
                       text=True, cwd=tmp_path)
    assert r.returncode == 2 and "\n" not in r.stderr.strip()
    assert "step size underflow at t = 0 s" in r.stderr
    choice = json.loads((tmp_path / "f.json.partial").read_text())["method_choice"]
    assert choice["chosen"] == "single-rate 'adams'" and choice["reason"].startswith("every probe failed")
    assert all("step size underflow" in c["failure"] and c["probe_cpu_s"] is None for c in choice["candidates"])


CHAIN_AUTO = {**AUTO, "output.quantities": ["coordinates", "markers", "energy"]}


def _balance_carries_across(res, t_cut: float) -> None:
    """The energy balance carries across a change of stepper at t_cut (a hand-over, or a
    restart from a checkpoint): its residual moves from the last row at or before t_cut to
    the next by no more than twice its largest move between any other two rows. A state or
    a work lost there would jump: the drives' work by 1.0 s is about 5e5 rtol of the energy
    scale. How far the residual drifts over the run depends on the method, not on the
    change: on the flexible chain at rtol 1e-6 with error_norm 'amplitude', 'response' alone
    ends within 0.04 rtol and moves by at most 0.007 rtol a row; 'adams' alone ends 4.4 rtol
    away and moves by up to 1.3 rtol a row (its strain energy's error swings with the
    modes), and 'exponential' 8.2 and 0.5."""
    moves = np.abs(np.diff(balance(res) / np.abs(res["energy.kinetic"]).max()))
    i = np.searchsorted(res.t, t_cut + 1e-9, side="right") - 1
    assert 0 <= i < len(moves)
    assert moves[i] <= 2.0 * np.delete(moves, i).max(), (t_cut, moves[i])


def test_the_review_measures_growth_from_the_cheapest_window(tmp_path):
    """Flexible chain with the scene's own rows and error_norm 'state', three runs: where the
    start's probes chose 'exponential', its CPU rate grows as the links spin up, and the
    first review comes before 1 s, more than review_margin (1.5) times its cheapest window.
    With 'state' its first window, in the start's vibration, costs about 1.4x its cheapest:
    measured against the first window, the reviews came at 0.70, 0.94 and 1.18 s, or not at
    all; against the cheapest, the first came at 0.70 s with a growth of 2.26-2.32.

    Each review then decides by its own probes: the cheapest candidate takes over when it
    probed switch_gain (1.2) times below the running method, and none does otherwise.
    Whether one does before 1 s is the machine's: 'adams' probed 1.35x below 'exponential'
    at 0.70 s here, and 1.08x with glibc's libm on its code paths without FMA and AVX2
    (GLIBC_TUNABLES), where the review kept 'exponential' and a later one handed over (at
    0.86 s, in 11 of 12 runs)."""
    for i in range(3):
        over = {**AUTO, "integrator.error_norm": "state"}
        choice = pymr.run(CHAIN, tmp_path / f"a{i}.csv", overrides=over).stats["method_choice"]
        if choice["chosen"] != "multirate 'exponential'":
            continue
        assert choice["reviews"][0]["t"] < 1.0 and choice["reviews"][0]["rate_growth"] > 1.5
        labels = [c["method"] for c in choice["candidates"]]
        running = labels.index(choice["chosen"])
        for review in choice["reviews"]:
            rates = review["cpu_s_per_s"]
            best = int(np.argmin(rates))
            cheaper = best != running and 1.2 * rates[best] < rates[running]
            assert review["took_over"] == (labels[best] if cheaper else None), (review, labels)
            running = best if cheaper else running


@pytest.mark.parametrize("rates, run, stopped, lead", [
    ([0.02, 0.03, 0.05], 1, [0, 0, 0], 1.5),          # the next cheapest finished probe's rate over the runner's
    ([0.02, 0.10, 0.08], 1, [0, 1, 1], 1.5),          # stopped probes: means with their starts, capped at 1.5
    ([0.02, 0.025, 0.08], 1, [0, 1, 0], 1.25),        # a stopped probe below the cap counts as measured
    ([0.05, 0.02, HUGE], 1, [0, 0, 0], 0.4),          # another cheaper: lead below 1; a failed probe left out
    ([0.05, HUGE, HUGE], 1, [0, 0, 0], HUGE)])        # every other failed
def test_the_review_rules_lead_and_baseline(rates, run, stopped, lead):
    """The two rules a review's timing rests on, apart from any timing: the lead (how much
    dearer the next cheapest candidate probed; a review is called at 1.2 times it) counts a
    stopped probe as at most 1.5 dearer, the race margin that stopped it (its mean holds its
    start's small steps: on the flexible chain two stopped probes' means put the lead past
    any growth, and no review came); and a review that keeps the running method makes the
    window's rate the baseline only when the running method still probed the cheapest."""
    got, baseline = _testhooks.pymr_review_rule(rates, run, stopped, 0.01, 0.03)
    assert got == pytest.approx(lead, rel=1e-15)
    assert baseline == (0.03 if lead >= 1.0 else 0.01)


def test_a_method_that_gets_dearer_is_reviewed_and_handed_over(tmp_path):
    """Flexible chain over 2 s: 'exponential' renews its frozen response more often as the links
    spin up, and from 0.5 s on its steps cost about twice 'adams'' per simulated second
    (docs/integrators.md). Whatever the start's probes chose, the run does not end on it.
    Each review follows the rule (windows 1.5x the baseline; the method that takes over probed
    1.2x cheaper than the running one), the JSON's integrator settings
    are the method the run ended with, and the energy balance carries across each hand-over
    (_balance_carries_across: at 0.38 s from 'exponential' to 'response' it moved by 0.0007
    rtol of the energy scale, against at most 0.007 in the other rows)."""
    auto = pymr.run(CHAIN, tmp_path / "auto.csv", overrides=CHAIN_AUTO)
    choice = auto.stats["method_choice"]
    assert choice["ended_with"] != "multirate 'exponential'"
    labels = [c["method"] for c in choice["candidates"]]
    running = choice["chosen"]
    assert len(choice["reviews"]) <= 3
    for review in choice["reviews"]:
        assert review["rate_growth"] > 1.5 and review["t"] <= 2.0 - 4 * choice["probe_t_end"]
        rates = dict(zip(labels, review["cpu_s_per_s"]))
        if review["took_over"]:
            assert 1.2 * rates[review["took_over"]] < rates[running]
            _balance_carries_across(auto, review["t"])
            running = review["took_over"]
    assert running == choice["ended_with"]
    settings = auto.stats["integrator"]
    assert settings["method"] == METHOD_OF[running]["integrator.method"]
    if settings["method"] == "multirate":
        assert settings["coupling"] == METHOD_OF[running]["integrator.coupling"]
    line = next(s for s in auto.summary.splitlines() if s.startswith("auto: "))
    assert ("took over" in line) == _switched(auto)


def test_a_run_handed_over_continues_from_its_checkpoint(tmp_path):
    """Flexible chain cut at 1.2 s (checkpoints every 0.5 s) and continued to 2 s: the
    checkpoint at 1.0 s was written by the method running then (after a hand-over from
    'exponential' to 'adams' the model is no longer partitioned, as a fresh single-rate
    model is not: the restart reads it). The rows up to the checkpoint are the cut run's,
    the rows count as an uninterrupted run's, and the energy balance carries across the
    restart (the works go on from the checkpoint's; _balance_carries_across: it moved by
    0.0001 rtol of the energy scale there, against at most 0.007 in the other rows; with the
    checkpoint's works read 1e-7 too large it moved by 0.03, while the whole run's balance
    stayed within 0.07 rtol)."""
    over = {**CHAIN_AUTO, "output.checkpoint_dt": 0.5}
    out = tmp_path / "job.csv"
    cut = pymr.run(CHAIN, out, overrides={**over, "scene.t_end": 1.2})
    res = pymr.run(CHAIN, out, overrides=over, restart=tmp_path / "job.ckpt")
    assert res.stats["method_choice"]["reason"] == "the method the checkpoint was written with"
    kept = cut.t <= 1.0 + 1e-9
    assert np.array_equal(res.data[: kept.sum()], cut.data[kept])
    assert res.stats["rows"] == len(res.t) == 2001 and np.allclose(res.t, np.linspace(0.0, 2.0, 2001))
    _balance_carries_across(res, 1.0)
