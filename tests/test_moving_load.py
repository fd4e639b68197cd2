"""Moving loads (&moving_load, issue 32): a point mass and force travelling along a beam,
each check against an independent expectation: a moving force on a cantilever against the
modal superposition of the analytic clamped-free Euler-Bernoulli modes, the kinetic energy
of the point mass against the mass matrix's share (a finite difference of its position), the
energy balance with the travel law's work, the moving-mass terms against a moving force of
equal weight, shot exit against the travel law and the output row there, multirate against a
tight single-rate run, the articulated path against the mass matrix's, a restart against the
uninterrupted run, and bad input refused with one line. Scenes are written inline."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.interpolate import CubicSpline
from scipy.optimize import brentq

import pymr
from refusal import check_refused_in_one_line

TIGHT = "h_slow = 1.0e-4, adaptive = .true., rtol = 1.0e-11, atol = 1.0e-13"
# a load leaving the beam stops its terms at once: adaptive steps shrink there to rtol times
# the jump, and below rtol 1e-10 they pass h_min (runs that exit use this)
EXIT_TOL = "h_slow = 1.0e-4, adaptive = .true., rtol = 1.0e-10, atol = 1.0e-12"
# the steel tube of the cantilever: 2 m, E 2e11 Pa, rho 7800 kg/m^3, radii 0.05 and 0.03 m
LENGTH, E, RHO = 2.0, 2.0e11, 7800.0
AREA = np.pi * (0.05**2 - 0.03**2)
EI = E * np.pi / 4 * (0.05**4 - 0.03**4)
BETA_L = [1.8751040687, 4.6940911330, 7.8547574382]


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


CANTILEVER = """
&scene title = 'moving load on a cantilever', t_end = {t_end}, gravity = 0.0, -9.81, 0.0 /
&integrator method = 'single', {integrator} /
&effects moving_loads = .true., gravity = {gravity} /
&body name = 'ground', kind = 'ground' /
&body name = 'beam', kind = 'beam', length = 2.0, youngs_modulus = 2.0e11, density = 7800.0,
      r_outer = 0.05, r_inner = 0.03, n_elements = 20, modes_y = 3 /
&joint name = 'clamp', kind = 'fixed', parent = 'ground', child = 'beam' /
&marker name = 'tip', body = 'beam', at = 2.0, 0.0, 0.0 /
&moving_load name = 'shot', body = 'beam', {load} /
&output dt = {dt}, quantities = 'coordinates', 'markers', 'marker_orientations', 'energy' /
"""


def cantilever(tmp_path, name, load, t_end=0.1, integrator=TIGHT, gravity=".false.", dt=1.0e-3, **over):
    scene = write(tmp_path, name, CANTILEVER.format(load=load, t_end=t_end, integrator=integrator,
                                                    gravity=gravity, dt=dt))
    return pymr.run(scene, overrides=over or None)


def clamped_free_mode(n: int, x: np.ndarray) -> np.ndarray:
    """Mode n (0-based) of a clamped-free Euler-Bernoulli beam, mass-normalised:
    int rho A phi^2 dx = 1."""
    b = BETA_L[n] / LENGTH
    sigma = (np.cosh(BETA_L[n]) + np.cos(BETA_L[n])) / (np.sinh(BETA_L[n]) + np.sin(BETA_L[n]))
    shape = np.cosh(b * x) - np.cos(b * x) - sigma * (np.sinh(b * x) - np.sin(b * x))
    return shape / np.sqrt(RHO * AREA * LENGTH)


def test_a_moving_force_bends_a_cantilever_as_the_analytic_modes_say(tmp_path):
    """A force of 1 kN (-y) crossing the cantilever at 20 m/s (mass 0, gravity off): the tip
    deflection against the superposition of the first three analytic clamped-free modes,
    each forced by F phi_n(v t) (their modal equations solved by solve_ivp at rtol 1e-12).
    pymr keeps three bending modes of a 20-element Hermite beam, whose frequencies and shapes
    are the analytic ones (20.65, 129.4, 362.4 Hz) to about 1e-6: the two agree to 1e-4 of
    the peak (measured 1.3e-7), a truncation to two modes on the analytic side differs by
    2.9e-3."""
    v, f = 20.0, 1000.0
    res = cantilever(tmp_path, "force.nml", f"mass = 0.0, force = 0.0, -{f}, 0.0, speed = {v}", t_end=0.099)
    omega = [bl**2 * np.sqrt(EI / (RHO * AREA)) / LENGTH**2 for bl in BETA_L]

    def modal(t, y, k):
        return [y[1], -omega[k]**2 * y[0] - f * clamped_free_mode(k, np.array(v * t))]
    tips = []
    for k in range(3):
        sol = solve_ivp(modal, (0, res.t[-1]), [0.0, 0.0], args=(k,), t_eval=res.t, rtol=1e-12, atol=1e-16,
                        method="DOP853")
        tips.append(sol.y[0] * clamped_free_mode(k, np.array(LENGTH)))
    exact = np.sum(tips, axis=0)
    err = np.abs(res["tip.y"] - exact).max() / np.abs(exact).max()
    truncated = np.abs(np.sum(tips[:2], axis=0) - exact).max() / np.abs(exact).max()
    assert err < 1e-4 < truncated, (err, truncated)


def test_the_point_mass_adds_its_kinetic_energy_to_the_mass_matrix(tmp_path):
    """A beam on a free joint (every rigid and modal coordinate moving), the 7 kg point mass
    resting at 1.3 m (its travel starts later): 1/2 qd^T (M_with - M_without) qd equals
    1/2 m |v|^2, v from a central difference of the point's place (a marker there) along qd
    (measured 1.5e-11 at the step 1e-5; 7.2e-9 at 1e-4, the difference's O(h^2))."""
    scene = write(tmp_path, "free.nml", """
&scene title = 'point mass on a free beam', t_end = 0.1, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', h_slow = 1.0e-4 /
&effects moving_loads = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'beam', kind = 'beam', length = 2.0, youngs_modulus = 2.0e11, density = 7800.0,
      r_outer = 0.05, r_inner = 0.03, n_elements = 8, modes_y = 2, modes_z = 2, modes_x = 1 /
&joint name = 'float', kind = 'free', parent = 'ground', child = 'beam' /
&marker name = 'p', body = 'beam', at = 1.3, 0.0, 0.0 /
&moving_load name = 'm', body = 'beam', mass = 7.0, s0 = 1.3, speed = 10.0, start = 5.0 /
&output dt = 1.0e-3 /
""")
    n = pymr.model_size(scene)[0]
    rng = np.random.default_rng(3)
    q, qd = 0.3 * rng.standard_normal(n), rng.standard_normal(n)
    m_on, _ = pymr.model_terms(scene, q, qd)
    m_off, _ = pymr.model_terms(scene, q, qd, overrides={"effects.moving_loads": False})
    h = 1e-5
    with pymr.Model(scene) as model:
        r = model.marker("p", np.zeros(2), np.array([q + h * qd, q - h * qd]), np.array([qd, qd]))
    v = (r[0] - r[1]) / (2 * h)
    t_mass = 0.5 * qd @ (m_on - m_off) @ qd
    assert t_mass == pytest.approx(0.5 * 7.0 * v @ v, rel=1e-9)


HUB = """
&scene title = 'moving mass on a spinning beam', t_end = {t_end}, gravity = 0.0, -9.81, 0.0 /
&integrator {integrator} /
&effects moving_loads = .true., gravity = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'beam', kind = 'beam', length = 2.0, youngs_modulus = 2.0e11, density = 7800.0,
      r_outer = 0.05, r_inner = 0.03, n_elements = 8, modes_y = 3, modes_z = 2 /
&joint name = 'hub', kind = 'revolute', parent = 'ground', child = 'beam', axis = 0.0, 0.0, 1.0, qd0 = 2.0 /
&marker name = 'tip', body = 'beam', at = 2.0, 0.0, 0.0 /
&moving_load name = 'shot', body = 'beam', mass = 5.0, force = 100.0, 300.0, -50.0, s0 = 0.1, speed = 120.0 /
&output dt = 1.0e-4, quantities = 'coordinates', 'markers', 'energy' {output} /
"""


def hub(tmp_path, name, integrator, t_end=0.015, output="", out=None, restart=None, **over):
    scene = write(tmp_path, name, HUB.format(integrator=integrator, t_end=t_end, output=output))
    return pymr.run(scene, out, overrides=over or None, restart=restart)


def imbalance(res) -> float:
    """Largest |E - E(0) - W| over the run: the energy against the works of the loads and of
    the travel law."""
    e = res["energy.total"]
    work = res["energy.load_work"] + res["energy.motion_work"]
    return float(np.abs(e - e[0] - work).max())


def test_the_energy_balance_of_a_moving_mass_closes_with_the_travel_law_work(tmp_path):
    """5 kg at 120 m/s with a 320 N force along a beam spinning on a hub under gravity, before
    the exit: the energy (the mass's 1/2 m |v|^2 and -m g . r with the beam's) changes by the
    force's work and the travel law's. The imbalance falls with the tolerance: measured
    1.2e-5, 6.3e-7, 2.4e-7 and 9.7e-8 J at rtol 1e-7, 1e-8, 1e-9 and 1e-10 (the energy
    36209 J, the works ~200 J; dropping half the Coriolis term leaves 34 J, dropping the
    centripetal sd^2 Psi'' a term 0.87 J)."""
    coarse = hub(tmp_path, "c.nml", "method = 'single', h_slow = 1.0e-4, adaptive = .true., rtol = 1.0e-7, "
                 "atol = 1.0e-12")
    fine = hub(tmp_path, "f.nml", "method = 'single', h_slow = 1.0e-4, adaptive = .true., rtol = 1.0e-10, "
               "atol = 1.0e-12")
    work = np.abs(fine["energy.motion_work"]).max()
    assert work > 100.0 and np.abs(fine["energy.load_work"]).max() > 100.0
    assert imbalance(fine) < 1e-8 * fine["energy.total"][0]
    assert imbalance(fine) < 0.1 * imbalance(coarse)


def test_the_energy_balance_closes_with_a_travel_table(tmp_path):
    """The same beam with the mass driven by a table from rest, s = 0.1 + 1e7 t^4 m every
    0.5 ms to 20 ms: through the spline, the travel's acceleration along the path is in the
    mass's inertia, so the energy (to 1.9e5 J) changes by the works to 1e-8 of them
    (measured 5e-10 at rtol 1e-10)."""
    t = np.linspace(0.0, 0.02, 41)
    (tmp_path / "acc.txt").write_text("".join(f"{a!r} {b!r}\n" for a, b in zip(t.tolist(), (0.1 + 1e7 * t**4).tolist())))
    scene = write(tmp_path, "t.nml", HUB.format(integrator="method = 'single', h_slow = 1.0e-4, adaptive = .true., "
                                                "rtol = 1.0e-10, atol = 1.0e-12", t_end=0.019, output="")
                  .replace("s0 = 0.1, speed = 120.0", "form = 'table', file = 'acc.txt'"))
    res = pymr.run(scene)
    work = np.abs(res["energy.motion_work"]).max()
    assert work > 1e5 and not res.stats["moving_loads"][0]["exited"]
    assert imbalance(res) < 1e-8 * work, imbalance(res) / work


def test_a_shot_driven_down_a_free_barrel_keeps_the_momentum(tmp_path):
    """A free beam (78.4 kg, at rest, no gravity) and a 6 kg mass driven along its axis by a
    travel table from rest: the travel's force is internal, so the beam recoils with
    m_b v = -m (v + s') along its axis (s' the rate of scipy's natural spline through the
    table), to 1e-9 of the mass's speed (measured 1.3e-11): the beam carries the force that
    drives the mass, and is pushed back by it."""
    t = np.linspace(0.0, 0.02, 41)
    s = 0.1 + 1e7 * t**4
    (tmp_path / "shot.txt").write_text("".join(f"{a!r} {b!r}\n" for a, b in zip(t.tolist(), s.tolist())))
    scene = write(tmp_path, "free.nml", """
&scene title = 'shot in a free barrel', t_end = 0.019, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', h_slow = 1.0e-4, adaptive = .true., rtol = 1.0e-11, atol = 1.0e-13 /
&effects moving_loads = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'barrel', kind = 'beam', length = 2.0, youngs_modulus = 2.0e11, density = 7800.0,
      r_outer = 0.05, r_inner = 0.03, n_elements = 8, modes_y = 2, modes_z = 2, modes_t = 1,
      shear_modulus = 8.0e10 /
&joint name = 'float', kind = 'free', parent = 'ground', child = 'barrel' /
&moving_load name = 'shot', body = 'barrel', mass = 6.0, form = 'table', file = 'shot.txt' /
&output dt = 1.0e-4 /
""")
    res = pymr.run(scene)
    m_b = RHO * AREA * LENGTH
    rate = CubicSpline(t, s, bc_type="natural")(res.t, 1)
    # the spline's rate at its first time (-7.2e-4 m/s) starts without an impulse
    expect = -6.0 * (rate - rate[0]) / (m_b + 6.0)
    assert np.abs(res["float.qd1"] - expect).max() < 1e-9 * rate.max()
    assert np.abs(res.data[:, 1:]).max() > 0.01                       # it did move


def test_the_moving_mass_terms_matter(tmp_path):
    """A 60 kg mass (the beam's is 98 kg) crossing the cantilever at 150 m/s under gravity,
    against a moving force of its weight (mass 0): the tip deflections differ by far more
    than either's integration error (measured: they differ by 0.63 of the peak, the run at
    rtol 1e-8 repeats the one at 1e-11 to 7.8e-8 of it)."""
    load = "s0 = 0.0, speed = 150.0"
    mass = cantilever(tmp_path, "m.nml", f"mass = 60.0, {load}", t_end=0.013, gravity=".true.", dt=1.0e-4)
    force = cantilever(tmp_path, "f.nml", f"mass = 0.0, force = 0.0, {-60.0 * 9.81}, 0.0, {load}", t_end=0.013,
                       dt=1.0e-4)
    rough = cantilever(tmp_path, "r.nml", f"mass = 60.0, {load}", t_end=0.013, gravity=".true.", dt=1.0e-4,
                       integrator=TIGHT.replace("1.0e-11", "1.0e-8"))
    peak = np.abs(mass["tip.y"]).max()
    accuracy = np.abs(mass["tip.y"] - rough["tip.y"]).max() / peak
    differ = np.abs(mass["tip.y"] - force["tip.y"]).max() / peak
    assert accuracy < 1e-5 and differ > 0.05, (accuracy, differ)


def rotation_vector(quat: np.ndarray) -> np.ndarray:
    """Rotation vectors (axis times angle) of unit quaternions [w, x, y, z] (rows)."""
    vec = quat[:, 1:]
    norm = np.linalg.norm(vec, axis=1)
    angle = 2 * np.arctan2(norm, quat[:, 0])
    return vec * np.where(norm > 0, angle / np.where(norm > 0, norm, 1), 2.0)[:, None]


# a travel from rest: s = 0.2 + 6e6 (t - 5 ms)^4 m, every millisecond from 5 to 30 ms
TRAVEL_T = np.arange(5, 31) * 1.0e-3
TRAVEL_S = 0.2 + 6.0e6 * (TRAVEL_T - 5.0e-3)**4


# the same travel backwards, towards the root: s = 1.8 - 6e6 (t - 5 ms)^4 m
BACK_S = LENGTH - TRAVEL_S


def spline_exit(positions=TRAVEL_S, end=LENGTH) -> float:
    """Where the natural cubic spline through the travel table passes the end s = `end` of
    the beam (scipy)."""
    spline = CubicSpline(TRAVEL_T, positions, bc_type="natural")
    i = int(np.argmax((positions > LENGTH) | (positions < 0)))
    return brentq(lambda t: spline(t) - end, TRAVEL_T[i - 1], TRAVEL_T[i], xtol=1e-16, rtol=1e-15)


def write_travel(path: Path, positions=TRAVEL_S) -> None:
    path.write_text("".join(f"{t!r} {s!r}\n" for t, s in zip(TRAVEL_T.tolist(), positions.tolist())))


@pytest.mark.parametrize("load, t_exit, end", [
    ("mass = 20.0, s0 = 0.5, speed = 50.0, start = 0.01", 0.04, "tip"),
    ("mass = 20.0, form = 'table', file = 'travel.txt'", spline_exit(), "tip"),
    # through the root, s0 + speed (t - start) = 0: 0.01 + 1.5/50 s (neither acted on nor
    # reported: "did not leave its body", found by an audit)
    ("mass = 20.0, s0 = 1.5, speed = -50.0, start = 0.01", 0.01 + 1.5 / 50.0, "root"),
    ("mass = 20.0, form = 'table', file = 'back.txt'", spline_exit(BACK_S, 0.0), "root"),
])
def test_shot_exit_is_at_the_travel_laws_time_with_the_markers_state_there(tmp_path, load, t_exit, end):
    """The exit time is the travel law's (start + (L - s0)/speed, or start - s0/speed through
    the root; for a table where scipy's natural cubic spline through it passes L = 2 m, or
    0), the end it leaves through is named, and the reported state of the tip
    marker equals the output row there (both from the stepper's dense
    output): position, velocity, angle (from the row's quaternion) and angular rate (from
    the rows' angles about z before it, a second-order one-sided difference: to 1e-3 of the
    largest rate with rows every 7 to 10 us, the third mode at 362 Hz)."""
    write_travel(tmp_path / "travel.txt")
    write_travel(tmp_path / "back.txt", BACK_S)
    # rows every t_exit/4000 (7 to 10 us), so that one lands on the exit
    res = cantilever(tmp_path, "exit.nml", load, t_end=0.05, gravity=".true.", dt=t_exit / 4000, integrator=EXIT_TOL)
    [shot] = res.stats["moving_loads"]
    assert shot["name"] == "shot" and shot["exited"] is True and shot["exit_end"] == end
    assert shot["t_exit"] == pytest.approx(t_exit, rel=1e-14)
    k = int(np.argmin(np.abs(res.t - t_exit)))
    assert abs(res.t[k] - t_exit) < 1e-12
    tip = shot["markers_at_exit"]["tip"]
    assert np.allclose(tip["position"], [res["tip.x"][k], res["tip.y"][k], res["tip.z"][k]], rtol=0, atol=1e-13)
    assert np.allclose(tip["velocity"], [res["tip.vx"][k], res["tip.vy"][k], res["tip.vz"][k]], rtol=0, atol=1e-11)
    quat = np.column_stack([res[f"tip.q{c}"] for c in "wxyz"])
    angle = rotation_vector(quat)
    assert np.allclose(tip["angle"], angle[k], rtol=0, atol=1e-13)
    # one-sided (the angular acceleration jumps at the exit), second order
    rate = (3 * angle[k, 2] - 4 * angle[k - 1, 2] + angle[k - 2, 2]) / (res.t[k] - res.t[k - 2])
    assert abs(tip["angular_rate"][2] - rate) < 1e-3 * np.abs(np.diff(angle[:, 2]) / np.diff(res.t)).max()
    said = {"tip": "moving load 'shot': shot exit at t = ",
            "root": "moving load 'shot': left its body through its root (s = 0) at t = "}
    assert said[end] in res.summary and "did not leave" not in res.summary


def test_an_adaptive_run_ends_a_step_on_a_root_exit(tmp_path):
    """Adaptive steps end exactly on the exit through the root, as on the shot exit (the
    load's terms stop there at once): with a row at every step (output dt = 0), one is at
    t_exit = start + s0/|speed| to rounding."""
    t_exit = 0.01 + 1.5 / 50.0
    res = cantilever(tmp_path, "root.nml", "mass = 20.0, s0 = 1.5, speed = -50.0, start = 0.01", t_end=0.05,
                     gravity=".true.", dt=0.0, integrator=EXIT_TOL)
    [shot] = res.stats["moving_loads"]
    assert shot["exit_end"] == "root" and shot["t_exit"] == pytest.approx(t_exit, rel=1e-14)
    assert res.t[-1] == pytest.approx(0.05) and np.min(np.abs(res.t - t_exit)) < 1e-15


def test_the_exit_angle_near_a_half_turn_is_the_rotation_vector(tmp_path):
    """The beam held still (no force, no mass, no gravity) on a hub whose spherical joint is
    turned by pi - 1e-9 rad about (1, 1, 1)/sqrt(3): the tip's angle at exit is that rotation vector. It was
    taken from the skew part of the rotation matrix, which vanishes at pi (0 there) and near
    it gives the axis to rounding over sin(angle) (3e-7 rad off here)."""
    from scipy.spatial.transform import Rotation
    turn = (np.pi - 1e-9) * np.ones(3) / np.sqrt(3.0)
    q0 = ", ".join(repr(float(a)) for a in Rotation.from_rotvec(turn).as_euler("XYZ"))
    scene = CANTILEVER.format(load="s0 = 0.5, speed = 50.0", t_end=0.05, integrator=TIGHT, gravity=".false.", dt=1e-3)
    scene = scene.replace("&joint name = 'clamp', kind = 'fixed', parent = 'ground',",
                          "&body name = 'hub', kind = 'rigid', mass = 1.0, inertia = 1, 1, 1, 0, 0, 0 /\n"
                          f"&joint name = 'ball', kind = 'spherical', parent = 'ground', child = 'hub', q0 = {q0} /\n"
                          "&joint name = 'clamp', kind = 'fixed', parent = 'hub',")
    res = pymr.run(write(tmp_path, "turned.nml", scene))
    [shot] = res.stats["moving_loads"]
    assert shot["t_exit"] == pytest.approx(0.03, rel=1e-14)
    assert np.allclose(shot["markers_at_exit"]["tip"]["angle"], turn, rtol=0, atol=1e-12), \
        np.subtract(shot["markers_at_exit"]["tip"]["angle"], turn)


def test_the_exit_state_of_any_size_is_valid_json(tmp_path):
    """A 1e-200 N force leaves velocities of 1e-204 at the exit: the statistics wrote them
    as 6.76546752407431037-204 (es25.17 drops the E of a three-digit exponent), which no
    JSON reader takes, with exit 0. The state is written exactly, as the rows are."""
    res = cantilever(tmp_path, "tiny.nml", "force = 0.0, 1.0e-200, 0.0, s0 = 0.5, speed = 50.0, start = 0.01",
                     t_end=0.05, dt=1e-5)
    stats = res.stats                       # read from the run's JSON (it failed to parse)
    tip = stats["moving_loads"][0]["markers_at_exit"]["tip"]
    k = int(np.argmin(np.abs(res.t - stats["moving_loads"][0]["t_exit"])))
    assert 0 < abs(tip["velocity"][1]) < 1e-190
    assert tip["velocity"][1] == pytest.approx(res["tip.vy"][k], rel=1e-6)


def test_a_load_that_has_not_reached_the_end_has_no_exit(tmp_path):
    res = cantilever(tmp_path, "short.nml", "mass = 20.0, s0 = 0.5, speed = 50.0", t_end=0.02)
    [shot] = res.stats["moving_loads"]
    assert shot["exited"] is False and shot["t_exit"] is None and shot["exit_end"] is None
    assert "did not leave its body by t = 0.02 s" in res.summary


def multirate_error(tmp_path, ref, coupling, h_fast, h_slow) -> float:
    """Largest error of the tip's place in a fixed-step multirate run against `ref`, over
    the tip's travel in y."""
    mr = hub(tmp_path, f"{coupling}.nml", f"method = 'multirate', coupling = '{coupling}', h_fast = {h_fast}, "
             f"h_slow = {h_slow}")
    span = np.abs(ref["tip.y"] - ref["tip.y"][0]).max()
    return max(np.abs(mr[f"tip.{c}"] - ref[f"tip.{c}"]).max() for c in "xyz") / span


def test_multirate_follows_a_tight_single_rate_run(tmp_path):
    """Fixed steps h_fast = 1e-5 s, k = 10, against the single-rate run at rtol 1e-11: the
    'response' coupling within 1e-5 of the tip's travel (measured 1.6e-6). The 'full'
    coupling's macro steps cost it more on this spinning beam (3.4e-3; 2.2e-4 without the
    moving load), and it converges: halving both steps divides its error by more than 4
    (measured 6.6, to 5.1e-4)."""
    ref = hub(tmp_path, "ref.nml", "method = 'single', " + TIGHT)
    assert multirate_error(tmp_path, ref, "response", 1.0e-5, 1.0e-4) < 1e-5
    coarse = multirate_error(tmp_path, ref, "full", 1.0e-5, 1.0e-4)
    fine = multirate_error(tmp_path, ref, "full", 5.0e-6, 5.0e-5)
    assert fine < coarse / 4 and coarse < 1e-2, (coarse, fine)


def test_the_articulated_path_gives_the_mass_matrix_path(tmp_path):
    """dynamics = 'articulated' condenses the point mass's modal mass with the beam's: the
    same run as through M (fixed steps, to rounding: measured 6e-16)."""
    fixed = "method = 'single', h_slow = 1.0e-5, dynamics = '{}'"
    a = hub(tmp_path, "a.nml", fixed.format("articulated"))
    m = hub(tmp_path, "m.nml", fixed.format("mass_matrix"))
    assert np.abs(a.data - m.data).max() < 1e-9 * np.abs(m.data).max()


@pytest.mark.parametrize("t_cut", [0.014, 0.022])
def test_a_restart_equals_the_uninterrupted_run(tmp_path, t_cut):
    """Checkpoints every 5 ms, the job cut at 14 ms (its last checkpoint before the exit at
    15.8 ms) or 22 ms (after it: the exit comes from the checkpoint) and restarted: the rows
    and the exit report equal the uninterrupted run's."""
    integ = "method = 'multirate', coupling = 'response', h_fast = 1.0e-5, h_slow = 1.0e-4"
    full = hub(tmp_path, "s.nml", integ, t_end=0.03, out=tmp_path / "full.csv")
    out = tmp_path / "job.csv"
    hub(tmp_path, "s.nml", integ, t_end=t_cut, output=", checkpoint_dt = 5.0e-3", out=out)
    res = hub(tmp_path, "s.nml", integ, t_end=0.03, output=", checkpoint_dt = 5.0e-3", out=out,
              restart=tmp_path / "job.ckpt")
    assert np.array_equal(res.t, full.t)
    assert np.abs(res.data - full.data).max() <= 1e-10 * np.abs(full.data).max()
    assert res.stats["moving_loads"] == full.stats["moving_loads"]
    assert full.stats["moving_loads"][0]["exited"]


# ----------------------------------------------------------------------- bad input

@pytest.mark.parametrize("replace, expect", [
    (("body = 'beam', mass", "body = 'block', mass"), r":\d+: &moving_load 'shot': body: 'block' is not a flexible body"),
    (("mass = 5.0", "mass = -5.0"), r":\d+: &moving_load 'shot': mass: must be in \[0, "),
    (("s0 = 0.1", "s0 = 2.5"), r":\d+: &moving_load 'shot': s0: 2.5 m is off the beam 'beam' \(0 to its length, 2 m\)"),
    (("speed = 120.0", "speed = 0.0"), r":\d+: &moving_load 'shot': speed: missing or 0"),
    (("s0 = 0.1, speed = 120.0", "form = 'table', file = 'bad.txt'"),
     r":\d+: &moving_load 'shot': file: .*times must increase"),
    (("s0 = 0.1, speed = 120.0", "form = 'table', file = 'off.txt'"),
     r":\d+: &moving_load 'shot': file: the first position, 3 m, is off the beam"),
    (("s0 = 0.1, speed = 120.0", "form = 'table'"), r":\d+: &moving_load 'shot': file: missing"),
    (("moving_loads = .true., ", ""), r":\d+: &moving_load 'shot': the scene gives moving loads but &effects "
                                       "moving_loads is not on"),
    # a load that has left by the run's start never acts; it was reported as not having left
    # its body (found by the second bad-input audit): at the end when the run starts, at
    # start + (L - s0)/speed = 0; before it, at -0.1 + 1.9/120 s; a table crossing before 0
    (("s0 = 0.1", "s0 = 2.0"), r":\d+: &moving_load 'shot': start: the load leaves the beam 'beam' \(its end at 2 m\) "
                               r"at t = 0 s, not after the run starts \(t = 0\): it would never act$"),
    (("s0 = 0.1", "s0 = 0.1, start = -0.1"), r":\d+: &moving_load 'shot': start: the load leaves the beam 'beam' "
                                             r"\(its end at 2 m\) at t = -0.0841667 s, not after the run starts"),
    (("s0 = 0.1, speed = 120.0", "form = 'table', file = 'early.txt'"),
     r":\d+: &moving_load 'shot': file: the load leaves the beam 'beam' \(its end at 2 m\) at t = -0.0\d+ s, not after"),
    # the same through the root (s < 0), which ran with exit 0 and "did not leave its body":
    # at the root when the run starts, before it at -1 + 0/300 s, a table that has passed it
    # (its rate at its last time, 0 m, continues it) and one that crosses it before t = 0
    (("s0 = 0.1, speed = 120.0", "s0 = 0.0, speed = -300.0"),
     r":\d+: &moving_load 'shot': start: the load leaves the beam 'beam' \(its root at 0 m\) at t = 0 s, not after the "
     r"run starts \(t = 0\): it would never act$"),
    (("s0 = 0.1, speed = 120.0", "s0 = 0.0, speed = -300.0, start = -1.0"),
     r":\d+: &moving_load 'shot': start: the load leaves the beam 'beam' \(its root at 0 m\) at t = -1 s, not after"),
    (("s0 = 0.1, speed = 120.0", "form = 'table', file = 'gone.txt'"),
     r":\d+: &moving_load 'shot': file: the load leaves the beam 'beam' \(its root at 0 m\) at t = -0.5 s, not after"),
    (("s0 = 0.1, speed = 120.0", "form = 'table', file = 'back.txt'"),
     r":\d+: &moving_load 'shot': file: the load leaves the beam 'beam' \(its root at 0 m\) at t = -0.00\d+ s, not "
     r"after the run starts \(t = 0\): it would never act$"),
])
def test_bad_moving_loads_are_refused_in_one_line(tmp_path, mrsim, replace, expect):
    (tmp_path / "bad.txt").write_text("0.0 0.1\n0.02 0.5\n0.01 0.9\n")
    (tmp_path / "off.txt").write_text("0.0 3.0\n0.02 4.0\n")
    (tmp_path / "early.txt").write_text("-0.02 1.8\n-0.01 2.1\n0.0 2.4\n")
    (tmp_path / "gone.txt").write_text("-2 1\n-1 0.5\n-0.5 0\n")
    (tmp_path / "back.txt").write_text("-0.02 0.3\n-0.01 0.1\n0.0 -0.2\n")
    text = HUB.format(integrator="method = 'single', h_slow = 1.0e-4", t_end=0.01, output="")
    text = text.replace("&marker", "&body name = 'block', kind = 'rigid', mass = 1.0, inertia = 1, 1, 1, 0, 0, 0 /\n"
                        "&joint name = 'pin', kind = 'revolute', parent = 'ground', child = 'block' /\n&marker")
    assert replace[0] in text
    scene = write(tmp_path, "bad.nml", text.replace(*replace, 1))
    check_refused_in_one_line(mrsim, scene, expect)


def test_a_moving_mass_on_a_flexible_coupler_keeps_the_loop_closed_and_the_energy_balance(tmp_path):
    """The four-bar of tests/test_loops.py whose coupler is a beam inside the loop, with a
    0.2 kg mass crossing the coupler at 2 m/s under gravity (exit at 0.5 s; the travel law's
    work 0.16 of the peak kinetic energy): the loop stays closed to 1e-8 m and, up to the
    exit, the energy changes by the travel law's work, to 1e-10 of the peak kinetic energy
    single-rate (measured 1.7e-12) and 1e-5 multirate at h_fast = 1e-5 s, k = 10 (measured
    1.6e-9 'response', 5.7e-7 'full')."""
    from test_loops import L0, flexible_coupler_scene
    scene, _ = flexible_coupler_scene(tmp_path)
    text = scene.read_text().replace("&effects gravity = .true.", "&effects gravity = .true., moving_loads = .true.")
    text = text.replace("t_end = 2.0", "t_end = 0.7") + \
        "&moving_load name = 'cart', body = 'coupler', mass = 0.2, s0 = 0.0, speed = 2.0 /\n"
    scene.write_text(text)
    multirate = {"integrator.method": "multirate", "integrator.adaptive": False, "integrator.h_fast": 1e-5,
                 "integrator.h_slow": 1e-4}
    for over, tol in (({}, 1e-10), ({**multirate, "integrator.coupling": "response"}, 1e-5),
                      ({**multirate, "integrator.coupling": "full"}, 1e-5)):
        res = pymr.run(scene, tmp_path / "loop.csv", overrides=over)
        assert np.abs(res["tip.x"] - L0).max() < 1e-8 and np.abs(res["tip.y"]).max() < 1e-8
        before = res.t < 0.5
        e = res["energy.total"][before]
        gap = np.abs(e - e[0] - res["energy.motion_work"][before]).max() / res["energy.kinetic"].max()
        assert np.abs(res["energy.motion_work"]).max() > 0.1 * res["energy.kinetic"].max()
        assert gap < tol, (over, gap)
        assert res.stats["moving_loads"][0]["t_exit"] == pytest.approx(0.5, rel=1e-14)


def test_a_modal_file_body_is_refused_in_one_line(tmp_path, mrsim):
    """A modal-file body keeps its shapes at its nodes only, not between them: refused."""
    text = HUB.format(integrator="method = 'single', h_slow = 1.0e-4", t_end=0.01, output="")
    beam = write(tmp_path, "beam.nml", text)
    pymr.write_modal_file(beam, "beam", tmp_path / "b.modal", overrides={"effects.moving_loads": False})
    start = text.index("&body name = 'beam'")
    end = text.index("/", start) + 1
    scene = write(tmp_path, "modal.nml", text[:start] + "&body name = 'beam', kind = 'modal', modal_file = 'b.modal' /"
                  + text[end:])
    check_refused_in_one_line(mrsim, scene, r":\d+: &moving_load 'shot': body: 'beam' is a "
                              "modal-file body, whose shapes between its nodes are not known")


def test_off_or_at_zero_mass_and_force_the_load_changes_nothing(tmp_path):
    """moving_loads off: the scene runs as without its &moving_load, bit for bit, and the
    effect is not evaluated; on with mass 0 and force 0: the same results to 1e-12."""
    integ = "method = 'single', h_slow = 1.0e-4, adaptive = .true., rtol = 1.0e-9, atol = 1.0e-12"
    text = HUB.format(integrator=integ, t_end=0.01, output="")
    bare = pymr.run(write(tmp_path, "bare.nml", text[:text.index("&moving_load")] + text[text.index("&output"):]
                          .replace("moving_loads = .true., ", "")))
    off = hub(tmp_path, "off.nml", integ, t_end=0.01, **{"effects.moving_loads": False})
    assert np.array_equal(off.data, bare.data)
    assert "moving_loads" not in off.stats["effects"] and "moving_loads" not in off.stats
    zero = hub(tmp_path, "zero.nml", integ, t_end=0.01,
               **{"moving_load[shot].mass": 0.0, "moving_load[shot].force": [0.0, 0.0, 0.0]})
    assert zero.stats["effects"]["moving_loads"]["evaluations"] == zero.stats["rhs_full"]
    assert np.abs(zero.data - bare.data).max() <= 1e-12 * np.abs(bare.data).max()


def test_a_travel_starting_mid_run_is_stepped_onto(tmp_path):
    """A 6 kg load resting at s0 = 1.5 m from the root until 0.01 s, then travelling back at
    50 m/s under gravity: its speed jumps at its start, where adaptive steps now end (as at
    its exit). At rtol 1e-11 the run used to stop at 0.01 s with a step-size underflow; now
    the tip's velocity at the exit (0.04 s, through the root) agrees with rtol 1e-9's to
    1e-6 (measured 1.2e-8)."""
    tips = []
    for rtol in (1e-9, 1e-11):
        res = cantilever(tmp_path, f"back{rtol}.nml", "mass = 6.0, s0 = 1.5, speed = -50.0, start = 0.01",
                         t_end=0.05, gravity=".true.",
                         integrator=f"h_slow = 1.0e-3, adaptive = .true., rtol = {rtol}, atol = {rtol * 1e-2}")
        (shot,) = res.stats["moving_loads"]
        assert shot["exit_end"] == "root" and shot["t_exit"] == pytest.approx(0.04, rel=1e-12)
        tips.append(shot["markers_at_exit"]["tip"]["velocity"][1])
    assert abs(tips[0]) > 0.1
    assert tips[0] == pytest.approx(tips[1], rel=1e-6)
