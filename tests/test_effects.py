"""Effects (issue 5): each one off costs nothing and changes nothing, on with zero
magnitude changes nothing, and on it matches an independent figure. Scenes are written
inline so that each test shows the physics it checks."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import pymr

PENDULUM_SPRING = """
&scene title = 'pendulum on a torsion spring-damper', t_end = 4.0, gravity = 0.0, -9.81, 0.0 /
&integrator method = 'single', h_slow = 1.0e-4 /
&effects gravity = .true. {extra} /
&body name = 'ground', kind = 'ground' /
&body name = 'bob', kind = 'rigid', mass = 1.0, com = 0.0, -1.0, 0.0,
      inertia = 4.0e-5, 4.0e-5, 4.0e-5, 0.0, 0.0, 0.0 /
&joint name = 'pivot', kind = 'revolute', parent = 'ground', child = 'bob', axis = 0.0, 0.0, 1.0, q0 = 1.0 /
{groups}
&output dt = 1.0e-3 /
"""

SPRING = "&spring joint = 'pivot', stiffness = {k}, damping = {c}, free_position = {q0} /"

SPIN = """
&scene title = 'beam spun about a vertical axis', t_end = {t_end}, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', h_slow = 1.0e-3 /
&effects base_motion = .true., geometric_stiffening = {gs} /
&body name = 'ground', kind = 'ground' /
&body name = 'beam', kind = 'beam', length = 10.0, youngs_modulus = 1.4e10, density = 1200.0,
      area = 1.0e-3, iy = 1.0e-6, iz = 1.0e-6, n_elements = 20, modes_y = {modes}, modes_z = {modes} /
&joint name = 'hub', kind = 'revolute', parent = 'ground', child = 'beam', axis = 0.0, 1.0, 0.0 /
&motion joint = 'hub', form = 'spinup', rate = {rate}, ramp_time = {ramp} /
&marker name = 'tip', body = 'beam', at = 10.0, 0.0, 0.0 /
&output dt = 1.0e-2 /
"""


def write(tmp_path: Path, name: str, text: str) -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def pendulum(tmp_path, name="p.nml", extra="", groups=""):
    return write(tmp_path, name, PENDULUM_SPRING.format(extra=extra, groups=groups))


def stats_effects(res: pymr.Results) -> dict:
    return res.stats["effects"]


# ---------------------------------------------------------------- joint springs

def test_spring_damper_dissipates_the_integral_of_its_power(tmp_path):
    """E(t) - E(0) = -int c qd^2 dt for a pendulum on a torsion spring-damper (gravity,
    spring and damper together); the energy includes the spring's 1/2 k (q - q0)^2."""
    scene = pendulum(tmp_path, extra=", joint_springs = .true.", groups=SPRING.format(k=5.0, c=0.3, q0=0.2))
    res = pymr.run(scene, tmp_path / "p.csv")
    q, qd = res["pivot.q"], res["pivot.qd"]
    ke, pe = pymr.model_energy(scene, q[:, None], qd[:, None])
    energy = ke + pe
    # Simpson's rule on the 1 ms output of the damper's power c qd^2
    power = 0.3 * qd**2
    h = res.t[1] - res.t[0]
    dissipated = h / 3 * (power[0] + power[-1] + 4 * power[1:-1:2].sum() + 2 * power[2:-1:2].sum())
    assert len(res.t) % 2 == 1
    assert dissipated > 1.0                      # a real loss, not a rounding
    assert energy[-1] - energy[0] == pytest.approx(-dissipated, rel=1e-8)
    eff = stats_effects(res)
    assert eff["joint_springs"]["evaluations"] == res.stats["rhs_full"]
    assert eff["joint_springs"]["cpu_time_s"] >= 0.0


def test_spring_mass_oscillates_at_sqrt_k_over_m(tmp_path):
    """A 2 kg slider on a 50 N/m spring (no gravity): x(t) = x0 cos(5 t)."""
    scene = write(tmp_path, "s.nml", """
&scene title = 'spring-mass', t_end = 2.0, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', h_slow = 1.0e-4 /
&effects joint_springs = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'slider', kind = 'rigid', mass = 2.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /
&joint name = 'rail', kind = 'prismatic', parent = 'ground', child = 'slider', axis = 1.0, 0.0, 0.0, q0 = 0.1 /
&spring joint = 'rail', stiffness = 50.0 /
&output dt = 1.0e-2 /
""")
    res = pymr.run(scene)
    assert np.abs(res["rail.q"] - 0.1 * np.cos(5.0 * res.t)).max() < 1e-10


# ------------------------------------------------------- off, zero magnitude, missing

@pytest.mark.parametrize("effect, groups", [
    ("joint_springs", SPRING.format(k=5.0, c=0.3, q0=0.2)),
    ("base_motion", "&motion joint = 'pivot', amplitude = 0.5, frequency = 1.0 /"),
    ("joint_drives", "&drive joint = 'pivot', amplitude = 3.0, frequency = 1.0 /"),
])
def test_effect_off_costs_nothing_and_changes_nothing(tmp_path, effect, groups):
    """Turned off on purpose, an effect's groups are ignored: no evaluation, and results
    bit-identical to the scene without the groups."""
    plain = pymr.run(pendulum(tmp_path, "plain.nml"))
    off = pymr.run(pendulum(tmp_path, "off.nml", extra=f", {effect} = .false.", groups=groups))
    assert np.array_equal(off.data, plain.data)
    assert effect not in stats_effects(off)
    assert set(stats_effects(off)) == {"gravity"}


@pytest.mark.parametrize("effect, groups", [
    ("joint_springs", SPRING.format(k=0.0, c=0.0, q0=0.3)),
    ("joint_drives", "&drive joint = 'pivot', amplitude = 0.0, frequency = 1.0 /"),
])
def test_effect_on_with_zero_magnitude_changes_nothing(tmp_path, effect, groups):
    plain = pymr.run(pendulum(tmp_path, "plain.nml"))
    zero = pymr.run(pendulum(tmp_path, "zero.nml", extra=f", {effect} = .true.", groups=groups))
    assert np.abs(zero.data - plain.data).max() < 1e-12
    assert stats_effects(zero)[effect]["evaluations"] == zero.stats["rhs_full"]


@pytest.mark.parametrize("groups, group, effect", [
    (SPRING.format(k=5.0, c=0.0, q0=0.0), ":9: &spring #1", "joint_springs"),
    ("&motion joint = 'pivot', amplitude = 0.5, frequency = 1.0 /", ":9: &motion #1", "base_motion"),
    ("&drive joint = 'pivot', amplitude = 3.0 /", ":9: &drive #1", "joint_drives"),
])
def test_groups_of_an_effect_not_turned_on_are_an_error(tmp_path, groups, group, effect):
    scene = pendulum(tmp_path, groups=groups)
    with pytest.raises(pymr.SceneError) as exc:
        pymr.run(scene)
    msg = str(exc.value)
    assert str(scene) in msg and group in msg and f"&effects {effect} is not on" in msg
    assert "\n" not in msg.strip()


def test_modal_damping_given_but_not_turned_on_is_an_error():
    tank = Path(__file__).resolve().parent.parent / "input" / "tank_hold.nml"
    with pytest.raises(pymr.SceneError, match=r"--set body\[gun\].rayleigh_alpha=0.5: &body 'gun': rayleigh_alpha: "
                                               r"the body gives modal damping but &effects modal_damping is not on"):
        pymr.model_size(tank, {"body[gun].rayleigh_alpha": 0.5})


# -------------------------------------------------------------- prescribed motion

def spin_scene(tmp_path, gs=".true.", rate=2.0, ramp=1.0, modes=1, t_end=2.0, name="spin.nml"):
    return write(tmp_path, name, SPIN.format(gs=gs, rate=rate, ramp=ramp, modes=modes, t_end=t_end))


def spinup(t, rate, ramp):
    """Kane, Ryan and Banerjee's hub angle and rate."""
    w = 2 * np.pi / ramp
    theta = np.where(t <= ramp, rate / ramp * (t**2 / 2 + (np.cos(w * t) - 1) / w**2), rate * (t - ramp / 2))
    rate_t = np.where(t <= ramp, rate / ramp * (t - np.sin(w * t) / w), rate)
    return theta, rate_t


def test_prescribed_joint_follows_its_function_to_roundoff(tmp_path):
    res = pymr.run(spin_scene(tmp_path, rate=6.0, ramp=1.5, t_end=3.0))
    theta, rate = spinup(res.t, 6.0, 1.5)
    assert np.abs(res["hub.q"] - theta).max() < 1e-13 * np.abs(theta).max()
    assert np.abs(res["hub.qd"] - rate).max() < 1e-13 * 6.0
    assert stats_effects(res)["base_motion"]["evaluations"] == res.stats["rhs_full"]


def test_the_summary_s_final_markers_are_the_results_last_row(tmp_path):
    """A motion faster than the step resolves (ramp 1e-4 s, steps of 1e-3 s): the results
    write the prescribed angle and rate exactly (Kane's spin-up), and so does the summary's
    final line now. It took the integrated coordinate: the tip at (0, -1) while the last row
    said (0.0499, -0.9988)."""
    scene = write(tmp_path, "fast.nml", PENDULUM_SPIN)
    res = pymr.run(scene)
    theta, rate = spinup(res.t[-1:], 1.0, 1e-4)
    assert res["pivot.q"][-1] == pytest.approx(theta[0], rel=1e-13)
    line = next(x for x in res.summary.splitlines() if x.startswith("final tip:"))
    numbers = [float(w) for w in line.replace(",", " ").split() if w[0] in "-0123456789"]
    last = [res[c][-1] for c in ("tip.x", "tip.y", "tip.z", "tip.vx", "tip.vy", "tip.vz")]
    assert numbers == pytest.approx(last, abs=1e-6)
    assert numbers[:2] == pytest.approx([np.sin(theta[0]), -np.cos(theta[0])], abs=1e-6)


@pytest.mark.parametrize("ramp", [2.3e-308, 3.4e-308, 1e-300])
def test_a_spin_up_shorter_than_any_step_is_a_step_in_rate(tmp_path, ramp):
    """A ramp time near the smallest normal number: the angle is rate (t - T/2) = rate t
    from the first step on. 2 pi/T overflowed below 3.5e-308, and the run failed at t = 0
    with a NaN angle."""
    scene = write(tmp_path, "fast.nml", PENDULUM_SPIN.replace("ramp_time = 1e-4", f"ramp_time = {ramp!r}"))
    res = pymr.run(scene)
    assert res["pivot.q"][0] == 0.0
    assert res["pivot.q"][1:] == pytest.approx(res.t[1:], rel=1e-13)
    assert np.all(res["pivot.qd"][1:] == 1.0)


PENDULUM_SPIN = """&scene title = 'spin-up faster than the step', t_end = 0.05 /
&integrator method = 'single', h_slow = 1e-3 /
&effects base_motion = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'bob', kind = 'rigid', mass = 1.0, com = 0.0, -1.0, 0.0, inertia = 4e-5, 4e-5, 4e-5, 0.0, 0.0, 0.0 /
&joint name = 'pivot', kind = 'revolute', parent = 'ground', child = 'bob', axis = 0, 0, 1 /
&motion joint = 'pivot', form = 'spinup', rate = 1.0, ramp_time = 1e-4 /
&marker name = 'tip', body = 'bob', at = 0.0, -1.0, 0.0 /
&output dt = 0.01 /
"""


# ---------------------------------------------------------- geometric stiffening

def modal_frequencies_squared(scene: Path, t: float) -> np.ndarray:
    """omega^2 of the beam's modes linearised at zero deflection, from central differences
    of the model's right-hand side (K = -dP/da) and its mass matrix."""
    n = pymr.model_size(scene)[0]
    q, qd = np.zeros(n), np.zeros(n)
    k = np.zeros((n, n))
    for i in range(1, n):
        e = np.zeros(n)
        e[i] = 1e-6
        k[:, i] = -(pymr.model_terms(scene, q + e, qd, t=t)[1] - pymr.model_terms(scene, q - e, qd, t=t)[1]) / 2e-6
    m = pymr.model_terms(scene, q, qd, t=t)[0]
    return np.diag(k)[1:] / np.diag(m)[1:]


@pytest.mark.parametrize("rate,axis", [(1.0, "y"), (2.0, "y"), (4.0, "y"), (2.0, "z"), (4.0, "z")])
def test_southwell_coefficient_of_a_spinning_cantilever(tmp_path, rate, axis):
    """Spinning at a constant rate about an axis through its clamped root, a cantilever's
    first out-of-plane frequency rises per Southwell, omega^2 = omega_0^2 + 1.193 Omega^2,
    with geometric stiffening, and stays at omega_0 without it; in plane the centrifugal
    softening of the floating frame takes Omega^2 off (coefficient 0.193 with, -1 without).
    omega_0 = 1.8751^2 sqrt(EI / (rho A L^4)) = 3.798 rad/s. About y the out-of-plane
    deflection is along y (the first mode, modes_y), about z along z (the second, modes_z)."""
    w0sq = (1.875104069**2 * np.sqrt(1.4e4 / (1.2 * 10.0**4)))**2

    def scene(gs, name):
        text = SPIN.format(gs=gs, rate=rate, ramp=1.0, modes=1, t_end=2.0)
        if axis == "z":
            text = text.replace("axis = 0.0, 1.0, 0.0", "axis = 0.0, 0.0, 1.0")
        return write(tmp_path, name, text)
    on = modal_frequencies_squared(scene(".true.", "on.nml"), t=2.0)
    off = modal_frequencies_squared(scene(".false.", "off.nml"), t=2.0)
    out_of_plane, in_plane = (0, 1) if axis == "y" else (1, 0)
    assert (on[out_of_plane] - w0sq) / rate**2 == pytest.approx(1.193, abs=1e-3)
    assert (on[in_plane] - w0sq) / rate**2 == pytest.approx(0.193, abs=1e-3)
    assert off[out_of_plane] == pytest.approx(w0sq, rel=1e-6)
    assert (off[in_plane] - w0sq) / rate**2 == pytest.approx(-1.0, abs=1e-4)
    if rate > np.sqrt(w0sq):
        assert off[in_plane] < 0 < on[in_plane]      # the linear model diverges, the stiffened one does not


def test_geometric_stiffening_with_zero_load_changes_nothing(tmp_path):
    """No rotation and no gravity: the tension is zero, so turning the effect on changes
    the results by nothing but rounding (evaluations counted)."""
    on = pymr.run(spin_scene(tmp_path, rate=0.0, name="on.nml"))
    off = pymr.run(spin_scene(tmp_path, gs=".false.", rate=0.0, name="off.nml"))
    assert np.abs(on.data - off.data).max() < 1e-12
    assert stats_effects(on)["geometric_stiffening"]["evaluations"] == on.stats["rhs_full"]
    assert "geometric_stiffening" not in stats_effects(off)


# ---------------------------------------------------------------- modal damping

def test_rayleigh_and_per_mode_damping_coefficients(tmp_path):
    """-dP/d(ad) of the barrel's modes equals 2 zeta_k omega_k + alpha + beta omega_k^2."""
    tank = Path(__file__).resolve().parent.parent / "input" / "tank_hold.nml"
    zeta = [0.01, 0.02, 0.03, 0.04]
    over = {"effects.modal_damping": True, "body[gun].modal_damping": zeta,
            "body[gun].rayleigh_alpha": 0.5, "body[gun].rayleigh_beta": 1e-4}
    n = pymr.model_size(tank, over)[0]
    q, qd = np.zeros(n), np.zeros(n)
    m, p0 = pymr.model_terms(tank, q, qd, overrides=over)
    rows = range(n - 4, n)
    w = 2 * np.pi * np.array([6.408986, 40.16451, 6.408986, 40.16451])   # y plane, then z plane
    for j, k in enumerate(rows):
        e = np.zeros(n)
        e[k] = 1e-3
        c = -(pymr.model_terms(tank, q, qd + e, overrides=over)[1] - p0)[k] / 1e-3
        assert c == pytest.approx(2 * zeta[j] * w[j] + 0.5 + 1e-4 * w[j]**2, rel=1e-5)


# ------------------------------------------------------------------- firing load

def pulse_energy_balance(tmp_path, h: float) -> tuple[float, float, pymr.Results]:
    """(energy gained, work of the load) for the pendulum hit by the pulse, step h."""
    load = ("&marker name = 'tip', body = 'bob', at = 0.0, -1.0, 0.0 /\n"
            "&load marker = 'tip', direction = 1.0, 0.0, 0.0, peak = 100.0, start = 0.01, duration = 0.01 /")
    text = (PENDULUM_SPRING.format(extra=", firing_load = .true.", groups=load)
            .replace("t_end = 4.0", "t_end = 0.04").replace("dt = 1.0e-3", f"dt = {h}")
            .replace("h_slow = 1.0e-4", f"h_slow = {h}"))
    scene = write(tmp_path, f"f{h}.nml", text)
    res = pymr.run(scene)
    q, qd = res["pivot.q"], res["pivot.qd"]
    ke, pe = pymr.model_energy(scene, q[:, None], qd[:, None])
    _, v = res.marker("tip")
    t = res.t
    force = np.where((t >= 0.01) & (t <= 0.02), 100.0 * np.sin(np.pi * (t - 0.01) / 0.01), 0.0)
    f = force[:, None] * np.stack([np.cos(q), np.sin(q), 0 * q], axis=1)    # body x axis, inertial
    power = (f * v).sum(axis=1)
    dt = t[1] - t[0]
    work = dt / 3 * (power[0] + power[-1] + 4 * power[1:-1:2].sum() + 2 * power[2:-1:2].sum())
    return (ke + pe)[-1] - (ke + pe)[0], work, res


def test_pulse_load_work_equals_energy_gain(tmp_path):
    """A 100 N half-sine pulse of 10 ms at the bob, along the bob's x axis: the energy gained
    equals the work int f . v dt of the load (Simpson on output at every step). The pulse's
    slope jumps at its start and end, so the fixed-step ABM converges at order 2 across it:
    measured -8.2e-5, -2.1e-5, -5.1e-6 relative at h = 1e-4, 5e-5, 2.5e-5."""
    errs = []
    for h in (1e-4, 5e-5, 2.5e-5):
        gained, work, res = pulse_energy_balance(tmp_path, h)
        assert work > 0.1
        errs.append(gained / work - 1)
    orders = np.log2(np.abs(errs[:-1]) / np.abs(errs[1:]))
    assert orders == pytest.approx([2.0, 2.0], abs=0.1)
    assert abs(errs[-1]) < 1e-5
    assert stats_effects(res)["firing_load"]["evaluations"] == res.stats["rhs_full"]


def test_load_off_is_bit_identical(tmp_path):
    marker = "&marker name = 'tip', body = 'bob', at = 0.0, -1.0, 0.0 /\n"
    load = "&load marker = 'tip', direction = 1.0, 0.0, 0.0, peak = 100.0, start = 0.01, duration = 0.01 /"
    plain = pymr.run(pendulum(tmp_path, "plain.nml", groups=marker))
    off = pymr.run(pendulum(tmp_path, "off.nml", extra=", firing_load = .false.", groups=marker + load))
    assert np.array_equal(off.data, plain.data)
    assert "firing_load" not in stats_effects(off)
    with pytest.raises(pymr.SceneError, match=r":10: &load #1: the scene gives loads but &effects "
                                               r"firing_load is not on"):
        pymr.run(pendulum(tmp_path, "missing.nml", groups=marker + load))


def test_tank_firing_on_a_moving_chassis():
    """input/tank_firing.nml: the chassis follows its road motion to roundoff; before the
    shot the run is bit-identical to the same scene with the load turned off, after it the
    barrel whips; halving the step moves the muzzle by under 1e-5 m (measured 7.4e-7)."""
    scene = Path(__file__).resolve().parent.parent / "input" / "tank_firing.nml"
    fired = pymr.run(scene)
    quiet = pymr.run(scene, overrides={"effects.firing_load": False})
    t = fired.t
    assert np.abs(fired["suspension.q2"] - 0.03 * np.sin(3 * np.pi * t)).max() < 1e-15
    assert np.abs(fired["suspension.q6"] - 0.02 * np.sin(3 * np.pi * t + 1.5707963)).max() < 1e-15
    assert np.abs(fired["suspension.q1"]).max() == 0.0
    before = t < 0.5
    assert np.array_equal(fired.data[before], quiet.data[before])
    whip = np.abs(fired.marker("muzzle")[0] - quiet.marker("muzzle")[0])[~before].max()
    assert whip > 1e-3
    half = pymr.run(scene, overrides={"integrator.h_slow": 5e-5, "integrator.h_fast": 5e-5})
    assert np.abs(half.marker("muzzle")[0] - fired.marker("muzzle")[0]).max() < 1e-5


# ---------------------------------------------------------- deformation inertia

TANK_HOLD = Path(__file__).resolve().parent.parent / "input" / "tank_hold.nml"
TANK_Q = ["traverse.q", "elevation.q", "gun.a1", "gun.a2", "gun.a3", "gun.a4"]


def tank_fidelity(tmp_path, fidelity: str, gravity: str = ".true.") -> Path:
    """The held tank without drives (conservative), at one deformation_inertia fidelity."""
    text = TANK_HOLD.read_text().replace("joint_drives = .true.",
                                         f"joint_drives = .false., deformation_inertia = '{fidelity}'")
    return write(tmp_path, f"tank_{fidelity}{gravity.strip('.')}.nml", text.replace("gravity = .true.",
                                                                                   f"gravity = {gravity}"))


def moving_state(n: int, scale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(1)
    q, qd = 0.3 * rng.standard_normal(n), rng.standard_normal(n)
    q[2:] = scale * 0.02 * rng.standard_normal(n - 2)
    qd[2:] *= scale * 0.5
    return q, qd


@pytest.mark.parametrize("fidelity", ["full", "linear"])
def test_deformation_inertia_bias_is_the_lagrange_bias_of_its_mass_matrix(tmp_path, fidelity):
    """Each fidelity's velocity terms are those of Lagrange's equations for T = 1/2 qd' M(q) qd
    with its own M: P(q, qd) - P(q, 0) = -(dM/dt qd - 1/2 d(qd' M qd)/dq), dM/dq by central
    differences of the kernel's M (no velocity term of the kernel is used). Measured 9e-7
    (full) and 1.1e-6 (linear) against terms of 126; the two fidelities' terms differ by
    more than 1e-3, so a mixed-up term would fail."""
    scene = tank_fidelity(tmp_path, fidelity, gravity=".false.")
    n = pymr.model_size(scene)[0]
    q, qd = moving_state(n)
    _, p = pymr.model_terms(scene, q, qd)
    _, p0 = pymr.model_terms(scene, q, 0 * qd)
    h = 1e-6
    dm = np.array([(pymr.model_terms(scene, q + h * e, qd)[0] - pymr.model_terms(scene, q - h * e, qd)[0]) / (2 * h)
                   for e in np.eye(n)])
    c = np.einsum("ijk,i,k->j", dm, qd, qd) - 0.5 * np.einsum("ijk,j,k->i", dm, qd, qd)
    assert np.abs(p - p0 + c).max() < 1e-7 * np.abs(c).max()
    other = tank_fidelity(tmp_path, "linear" if fidelity == "full" else "full", gravity=".false.")
    _, p_other = pymr.model_terms(other, q, qd)
    assert np.abs(p_other - p).max() > 1e-3


def test_linear_deformation_inertia_drops_exactly_the_second_order_terms(tmp_path):
    """'linear' drops 1/2 sum m |w x Psi a|^2 + sum m (w x Psi a) . Psi ad from the kinetic
    energy, a form quadratic in (a, ad): halving the deformation quarters the kinetic-energy
    difference and the joint-joint block of M - M_linear (the inertia's a a terms), halves its
    joint-modal block (Cr's part linear in a) and leaves the modal-modal block equal (to 1e-6);
    with no deformation (a = ad = 0) the fidelities agree to 1e-12 at any joint state."""
    full, lin = tank_fidelity(tmp_path, "full"), tank_fidelity(tmp_path, "linear")
    n = pymr.model_size(full)[0]
    dm, dke = [], []
    for scale in (1.0, 0.5, 0.25):
        q, qd = moving_state(n, scale)
        dm.append(pymr.model_terms(full, q, qd)[0] - pymr.model_terms(lin, q, qd)[0])
        dke.append(pymr.model_energy(full, q[None], qd[None])[0][0] - pymr.model_energy(lin, q[None], qd[None])[0][0])
    jj, jm = (slice(0, 2), slice(0, 2)), (slice(0, 2), slice(2, n))
    assert np.abs(dm[0][jj]).max() > 1e-4 and np.abs(dm[0][jm]).max() > 1e-3
    assert np.abs(dm[0][2:, 2:]).max() == 0.0
    for k in (0, 1):
        assert np.abs(dm[k][jj] - 4 * dm[k + 1][jj]).max() < 1e-6 * np.abs(dm[k][jj]).max()
        assert np.abs(dm[k][jm] - 2 * dm[k + 1][jm]).max() < 1e-6 * np.abs(dm[k][jm]).max()
        assert dke[k] / dke[k + 1] == pytest.approx(4.0, rel=1e-6)
    q, qd = moving_state(n, 0.0)
    for a, b in zip(pymr.model_terms(full, q, qd), pymr.model_terms(lin, q, qd)):
        assert np.abs(a - b).max() < 1e-12 * np.abs(a).max()


def test_linear_deformation_inertia_conserves_its_energy(tmp_path):
    """The linear model's equations come from a kinetic energy, so the conservative tank
    (gravity, no drives, turret and gun swinging) keeps its energy: drift over 1 s measured
    2.1e-9, 6.7e-11, 2.1e-12 of the kinetic energy at h = 4e-4, 2e-4, 1e-4 (order 5).
    It runs without any deformation_inertia evaluation."""
    scene = tank_fidelity(tmp_path, "linear")
    drifts = []
    for h in (4e-4, 2e-4, 1e-4):
        res = pymr.run(scene, overrides={"integrator.h_slow": h, "integrator.h_fast": h, "output.dt": 2e-2,
                                         "joint[traverse].qd0": 1.0, "joint[elevation].qd0": 0.3})
        q = np.stack([res[c] for c in TANK_Q], axis=1)
        qd = np.stack([res[c.replace(".q", ".qd").replace(".a", ".ad")] for c in TANK_Q], axis=1)
        ke, pe = pymr.model_energy(scene, q, qd)
        drifts.append(np.abs(ke + pe - ke[0] - pe[0]).max() / ke.max())
        assert "deformation_inertia" not in stats_effects(res)
    assert drifts[-1] < 1e-11
    assert np.log2(drifts[0] / drifts[1]) > 4.5 and np.log2(drifts[1] / drifts[2]) > 4.5


def test_linear_deformation_inertia_loses_the_centrifugal_softening(tmp_path):
    """Spinning cantilever in plane: the softening -Omega^2 of the floating frame comes from
    the second-order inertia, so with 'linear' the in-plane coefficient is 1.193 (Southwell's
    stiffening alone, 0.193 with 'full') and 0 without stiffening (-1 with 'full'); out of
    plane both fidelities give 1.193."""
    w0sq = (1.875104069**2 * np.sqrt(1.4e4 / (1.2 * 10.0**4)))**2
    coeff = {}
    for gs in (".true.", ".false."):
        text = SPIN.format(gs=gs, rate=2.0, ramp=1.0, modes=1, t_end=2.0).replace(
            "base_motion = .true.", "base_motion = .true., deformation_inertia = 'linear'")
        coeff[gs] = (modal_frequencies_squared(write(tmp_path, f"lin{gs}.nml", text), t=2.0) - w0sq) / 4.0
    assert coeff[".true."] == pytest.approx([1.193, 1.193], abs=1e-3)
    assert coeff[".false."] == pytest.approx([0.0, 0.0], abs=1e-4)


def test_deformation_inertia_full_is_counted_and_bad_fidelity_is_an_error(tmp_path):
    res = pymr.run(tank_fidelity(tmp_path, "full"), overrides={"scene.t_end": 0.01})
    assert stats_effects(res)["deformation_inertia"]["evaluations"] == res.stats["rhs_full"]
    with pytest.raises(pymr.SceneError, match=r"&effects: deformation_inertia: 'exact' is not one of: full, linear"):
        pymr.model_size(tank_fidelity(tmp_path, "exact"))


# ------------------------------------------------------------ tabulated histories

RAIL = """
&scene title = 'slider on a rail', t_end = {t_end} /
&integrator method = 'single', h_slow = {h} /
&effects {effect} = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'slider', kind = 'rigid', mass = 2.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /
&joint name = 'rail', kind = 'prismatic', parent = 'ground', child = 'slider', axis = 1.0, 0.0, 0.0 /
{group}
&output dt = {h} /
"""


def rail(tmp_path, group, effect="joint_drives", h=1e-2, t_end=1.0, name="rail.nml"):
    return write(tmp_path, name, RAIL.format(group=group, effect=effect, h=h, t_end=t_end))


def test_tabulated_drive_interpolates_linearly(tmp_path):
    """A force table (comma- and blank-separated, with a comment) ramping from 0 to 2 N over
    0.5 s, then held (and held past its end at 0.8 s), pushes a 2 kg slider: x = t^3/3 up to
    0.5 s, exactly (the ABM step integrates cubics exactly), then x(0.5) + v(0.5)(t - 0.5) +
    (t - 0.5)^2/2. The force's slope jumps at 0.5 s, so the error after it falls at order
    2: measured 8.3e-6, 2.1e-6, 5.2e-7 at h = 1e-2, 5e-3, 2.5e-3."""
    (tmp_path / "push.csv").write_text("# t (s), force (N)\n0.0, 0.0\n0.5, 2.0\n0.8 2.0\n")
    errs = []
    for h in (1e-2, 5e-3, 2.5e-3):
        res = pymr.run(rail(tmp_path, "&drive joint = 'rail', form = 'table', file = 'push.csv' /", h=h))
        t = res.t
        x = np.where(t <= 0.5, t**3 / 3, 0.5**3 / 3 + 0.25 * (t - 0.5) + (t - 0.5)**2 / 2)
        assert np.abs(res["rail.q"] - x)[t <= 0.5].max() < 1e-14
        errs.append(np.abs(res["rail.q"] - x).max())
    assert np.log2(errs[0] / errs[1]) == pytest.approx(2.0, abs=0.1)
    assert np.log2(errs[1] / errs[2]) == pytest.approx(2.0, abs=0.1)


def test_tabulated_motion_is_the_natural_cubic_spline_of_its_table(tmp_path):
    """A prescribed coordinate read from a table of sin(2 pi t) at 21 points follows the
    natural cubic spline through them (scipy's CubicSpline, bc 'natural') to roundoff in
    value and rate, and beyond the table's end (1 s) the straight line of its end value and
    slope. Refining the table, the spline approaches sin(2 pi t) at order 4 (measured
    2.6e-5, 1.6e-6, 9.9e-8 for 21, 41, 81 points)."""
    from scipy.interpolate import CubicSpline
    scene = rail(tmp_path, "&motion joint = 'rail', form = 'table', file = 'path.txt', offset = 0.25 /",
                 effect="base_motion", h=1e-3, t_end=1.2)
    errs = []
    for n in (21, 41, 81):
        tt = np.linspace(0.0, 1.0, n)
        yy = np.sin(2 * np.pi * tt)
        (tmp_path / "path.txt").write_text("\n".join(f"{a!r} {b!r}" for a, b in zip(tt.tolist(), yy.tolist())))
        res = pymr.run(scene)
        t = res.t
        spline = CubicSpline(tt, yy, bc_type="natural")
        inside = t <= 1.0
        assert np.abs(res["rail.q"][inside] - 0.25 - spline(t[inside])).max() < 1e-14
        assert np.abs(res["rail.qd"][inside] - spline(t[inside], 1)).max() < 1e-12
        line = 0.25 + yy[-1] + spline(1.0, 1) * (t[~inside] - 1.0)
        assert np.abs(res["rail.q"][~inside] - line).max() < 1e-14
        assert np.abs(res["rail.qd"][~inside] - spline(1.0, 1)).max() < 1e-12
        errs.append(np.abs(res["rail.q"] - 0.25 - np.sin(2 * np.pi * t))[inside].max())
    assert np.log2(errs[0] / errs[1]) == pytest.approx(4.0, abs=0.2)
    assert np.log2(errs[1] / errs[2]) == pytest.approx(4.0, abs=0.2)


@pytest.mark.parametrize("group, table, message", [
    ("&drive joint = 'rail', form = 'table', file = 'none.csv' /", None,
     r":8: &drive #1: file: '.*none.csv' not found"),
    ("&drive joint = 'rail', form = 'table', file = 't.csv' /", "0 1\n0.5 x\n",
     r":8: &drive #1: file: '.*t.csv' line 2: expected two finite numbers \(time, value\), got: 0.5 x"),
    ("&drive joint = 'rail', form = 'table', file = 't.csv' /", "# t f\n0 1\n0.5 2\n0.5 3\n",
     r":8: &drive #1: file: '.*t.csv' line 4: times must increase, but t = 0.5 follows t = 0.5"),
    ("&drive joint = 'rail', form = 'table', file = 't.csv' /", "0 1\n",
     r":8: &drive #1: file: '.*t.csv' has 1 rows; a table needs at least 2"),
    # rows 1e-300 s apart: a setpoint rate of 1e300 failed at t = 0 with a step-size underflow
    ("&drive joint = 'rail', form = 'table', file = 't.csv' /", "0 0\n1e-300 1\n2 1\n",
     r":8: &drive #1: file: '.*t.csv' line 2: the table rises by 1 over 1e-300 from the row before: a slope beyond "
     r"1e\+150, where LAPACK overflows; give rows farther apart"),
    ("&drive joint = 'rail', form = 'table' /", None,
     r":8: &drive #1: file: missing \(form 'table' reads the history"),
    ("&drive joint = 'rail', form = 'table', file = 't.csv', amplitude = 2.0 /", "0 1\n1 2\n",
     r":8: &drive #1: amplitude: not used by form 'table'"),
    ("&drive joint = 'rail', amplitude = 2.0, file = 't.csv' /", "0 1\n1 2\n",
     r":8: &drive #1: file: only form 'table' reads a file \(form is 'sine'\)"),
    ("&drive joint = 'rail', form = 'ramp' /", None,
     r":8: &drive #1: form: 'ramp' is not one of: sine, table"),
])
def test_bad_tables_are_one_line_errors(tmp_path, group, table, message):
    if table is not None:
        (tmp_path / "t.csv").write_text(table)
    scene = rail(tmp_path, group)
    with pytest.raises(pymr.SceneError, match=message) as exc:
        pymr.run(scene)
    assert str(exc.value).startswith(str(scene)) and "\n" not in str(exc.value).strip()


def test_bad_motion_table_names_the_motion_group(tmp_path):
    (tmp_path / "m.txt").write_text("0 0\n1 1\n0.5 2\n")
    scene = rail(tmp_path, "&motion joint = 'rail', form = 'table', file = 'm.txt' /", effect="base_motion")
    with pytest.raises(pymr.SceneError, match=r"rail.nml:8: &motion #1: file: '.*m.txt' line 3: times "
                                               r"must increase, but t = 0.5 follows t = 1"):
        pymr.run(scene)
    # rows 1e-200 apart (times that increase, values finite) make the spline's slopes
    # overflow: a failed run "at t = 0 s: dptsv: ..." (exit 2) before; bad input now, at the
    # row whose slope is beyond LAPACK's bound
    (tmp_path / "m.txt").write_text("0 0\n1e-200 1\n1 1\n")
    with pytest.raises(pymr.SceneError, match=r"rail.nml:8: &motion #1: file: '.*m.txt' line 2: the table rises by 1 "
                                               r"over 1e-200 from the row before: a slope beyond 1e\+150"):
        pymr.run(scene)
    # slopes within the bound whose change is not: the spline's own check
    (tmp_path / "m.txt").write_text("0 0\n2e-150 1\n4e-150 0\n1 0\n")
    with pytest.raises(pymr.SceneError, match=r"rail.nml:8: &motion #1: file: the spline through the table cannot "
                                               r"be formed: its slope changes by -1e\+150 at the time 2e-150"):
        pymr.run(scene)


def cantilever_slope(n: int, x, length: float, rho_a: float):
    """Slope phi_n'(x) of the n-th continuum Euler-Bernoulli cantilever mode, mass-normalised
    (int rho A phi^2 dx = 1), signed as the kernel's modes (tip moving positively)."""
    beta_l = [1.875104068711961, 4.694091132974175][n]
    b = beta_l / length
    s = (np.cosh(beta_l) + np.cos(beta_l)) / (np.sinh(beta_l) + np.sin(beta_l))
    tip_sign = 1 if n == 0 else -1
    return tip_sign * b * (np.sinh(b * x) + np.sin(b * x) - s * (np.cosh(b * x) - np.cos(b * x))) \
        / np.sqrt(rho_a * length)


def test_geometric_stiffening_of_a_hanging_beam_by_its_weight_and_a_carried_mass(tmp_path):
    """A 2 m cantilever hangs under gravity with a 5 kg body jointed at its tip: its tension
    N(x) = rho A g (L - x) + m g adds K_G = int N(x) phi_i' phi_j' dx to the modal stiffness.
    -dP/da of the kernel (central differences) with the effect on minus off equals that
    integral over the continuum cantilever modes (scipy quad), to the 20-element model's
    accuracy: measured 2e-7 (1st mode) and 4e-6 (2nd) relative; without the carried body's
    share (m g int phi' phi', 71 % of it) the first entry would be 3.5 times too small."""
    from scipy.integrate import quad
    length, rho_a, mass, g = 2.0, 3.0, 5.0, 9.81
    text = f"""
&scene title = 'hanging beam with a tip mass', t_end = 0.1, gravity = {g}, 0.0, 0.0 /
&integrator method = 'single', h_slow = 1e-4 /
&effects gravity = .true., geometric_stiffening = {{gs}} /
&body name = 'ground', kind = 'ground' /
&body name = 'beam', kind = 'beam', length = {length}, youngs_modulus = 2.0e9, density = 3000.0,
      area = 1.0e-3, iy = 1.0e-6, iz = 1.0e-6, n_elements = 20, modes_y = 2, modes_z = 0 /
&body name = 'weight', kind = 'rigid', mass = {mass}, inertia = 0.01, 0.01, 0.01, 0.0, 0.0, 0.0 /
&joint name = 'root', kind = 'fixed', parent = 'ground', child = 'beam' /
&joint name = 'tip', kind = 'fixed', parent = 'beam', child = 'weight', at = {length}, 0.0, 0.0 /
"""

    def stiffness(gs):
        scene = write(tmp_path, f"hang{gs}.nml", text.format(gs=gs))
        q = np.zeros(2)
        cols = [-(pymr.model_terms(scene, q + 1e-6 * e, q)[1] - pymr.model_terms(scene, q - 1e-6 * e, q)[1]) / 2e-6
                for e in np.eye(2)]
        return np.array(cols).T

    kg = stiffness(".true.") - stiffness(".false.")

    def slope(n, x):
        return cantilever_slope(n, x, length, rho_a)
    expected = np.array([[quad(lambda x: (rho_a * g * (length - x) + mass * g) * slope(i, x) * slope(j, x),
                               0, length)[0] for j in range(2)] for i in range(2)])
    assert kg == pytest.approx(expected, rel=2e-5)


@pytest.mark.parametrize("radius", [0.0, 2.0, 5.0])
def test_geometric_stiffening_of_a_beam_on_a_spinning_hub(tmp_path, radius):
    """A cantilever clamped at radius r on a hub spinning at Omega about z: its root moves on a
    circle, accelerating -Omega^2 r along the beam, so the tension N(x) = rho A Omega^2
    [r (L - x) + (L^2 - x^2)/2] has a share from the root's acceleration besides the beam's own
    centrifugal load. The stiffening of each bending mode, omega^2 with the effect minus
    without, equals Omega^2 int N phi'^2 dx / Omega^2 over the continuum mode (scipy quad), to the
    20-element model's accuracy (r = 0: Southwell's 1.193)."""
    from scipy.integrate import quad
    length, rho_a, rate = 10.0, 1.2, 2.0
    text = f"""
&scene title = 'beam on a spinning hub', t_end = 2.0, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', h_slow = 1.0e-3 /
&effects base_motion = .true., geometric_stiffening = {{gs}} /
&body name = 'ground', kind = 'ground' /
&body name = 'hub', kind = 'rigid', mass = 50.0, inertia = 10.0, 10.0, 10.0, 0.0, 0.0, 0.0 /
&body name = 'beam', kind = 'beam', length = {length}, youngs_modulus = 1.4e10, density = 1200.0,
      area = 1.0e-3, iy = 1.0e-6, iz = 1.0e-6, n_elements = 20, modes_y = 1, modes_z = 1 /
&joint name = 'spin', kind = 'revolute', parent = 'ground', child = 'hub', axis = 0.0, 0.0, 1.0 /
&joint name = 'root', kind = 'fixed', parent = 'hub', child = 'beam', at = {radius}, 0.0, 0.0 /
&motion joint = 'spin', form = 'spinup', rate = {rate}, ramp_time = 1.0 /
"""
    on = modal_frequencies_squared(write(tmp_path, "on.nml", text.format(gs=".true.")), t=2.0)
    off = modal_frequencies_squared(write(tmp_path, "off.nml", text.format(gs=".false.")), t=2.0)
    expected = quad(lambda x: rho_a * (radius * (length - x) + (length**2 - x**2) / 2)
                    * cantilever_slope(0, x, length, rho_a)**2, 0, length)[0]
    if radius == 0.0:
        assert expected == pytest.approx(1.193, abs=1e-3)
    assert (on - off) / rate**2 == pytest.approx([expected, expected], rel=2e-5)
