"""Axial (modes_x) and torsional (modes_t) modes of built-in beams (issue 17, part 5), each
against an expectation of its own:

* frequencies of the clamped-free bar and shaft against f_n = (2n-1)/(4L) sqrt(E/rho) and
  (2n-1)/(4L) sqrt(G J/(rho Ip)). The fields use the beam's cubic Hermite elements (C1,
  the slope free at the clamp): cubics for a second-order problem, so the eigenvalue error
  is O(h^6). The relative error of f_n is about (k_n h)^6/60480 (k_n = (2n-1) pi/(2L)),
  from above (Rayleigh-Ritz): 3.7e-12 for f_1 with 20 elements;
* the rigid inertia the rings of mass points add (the section's), and the bending modes'
  rotary inertia, against formulas and the brute-force reference's own eigen-solve;
* M and P of a scene with every family of modes against the brute-force reference
  (tests/bruteforce.py: its own shapes, rings and kinematics);
* a static start under gravity along the shaft and across a tip mass's offset: the tip's
  extension and the section's twist against the bar and shaft formulas;
* the energy of a free run of a spinning shaft vibrating in every family;
* the marker shapes of the modes against the continuum's mass-normalised tip values, the
  banded solver of long shafts, the modal file round trip, geometric stiffening's zero
  rows, and the scene's errors.

Run ``pytest tests/test_beam_modes.py -q -s`` to see the measured numbers.
"""
from __future__ import annotations

import math
import re
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bruteforce as bf  # noqa: E402
from test_bad_scenes import error_message, run_mrsim  # noqa: E402

import pymr  # noqa: E402

E, RHO, G = 7.0e10, 2700.0, 2.6e10           # aluminium
LENGTH = 1.5
TUBE = "r_outer = 0.03, r_inner = 0.02"
RO, RI = 0.03, 0.02
# a section with iy != iz and a torsion constant below its polar moment (a rectangle-like one)
SECTION = "area = 3.0e-4, iy = 2.0e-8, iz = 3.0e-8, torsion_constant = 1.5e-8"
AREA, IY, IZ, JT = 3.0e-4, 2.0e-8, 3.0e-8, 1.5e-8

CLAMPED = """\
&scene title = 'clamped shaft', t_end = 0.01, gravity = 0.0, 0.0, 0.0 /
&integrator method = 'single', h_slow = 1.0e-6, stability_check = .false. /
&body name = 'ground', kind = 'ground' /
&body name = 'shaft', kind = 'beam', length = {length}, youngs_modulus = {e}, density = {rho},
      shear_modulus = {g}, {section}, n_elements = 20,
      modes_y = {my}, modes_z = {mz}, modes_x = {mx}, modes_t = {mt} /
&joint name = 'clamp', kind = '{joint}', parent = 'ground', child = 'shaft', axis = {axis} /
"""


def _clamped(tmp_path, section=TUBE, my=0, mz=0, mx=0, mt=0, joint="fixed", axis="0.0, 0.0, 1.0",
             name="clamped.nml") -> Path:
    path = tmp_path / name
    path.write_text(CLAMPED.format(length=LENGTH, e=E, rho=RHO, g=G, section=section, my=my, mz=mz, mx=mx, mt=mt,
                                   joint=joint, axis=axis))
    return path


def _omega2_and_mass(path, overrides=None):
    """The kernel's modal stiffness omega_k^2 (diagonal of K, from P at a = e_k: the modal
    rows of P at rest are -omega^2 a) and its mass matrix at rest, for a clamped beam."""
    n = pymr.model_size(path, overrides)[0]
    z = np.zeros(n)
    m, p0 = pymr.model_terms(path, z, z, overrides=overrides)
    k = np.column_stack([-(pymr.model_terms(path, e, z, overrides=overrides)[1] - p0) for e in np.eye(n)])
    assert np.abs(k - np.diag(np.diag(k))).max() <= 1e-14 * np.abs(k).max()
    return np.diag(k), m


def _rod_frequencies(wave_speed: float, count: int) -> np.ndarray:
    """f_n = (2n-1)/(4L) c of a clamped-free rod (bar: c = sqrt(E/rho); shaft: sqrt(GJ/(rho Ip)))."""
    return (2 * np.arange(1, count + 1) - 1) / (4 * LENGTH) * wave_speed


def _error_bound(count: int, n_elements: int) -> np.ndarray:
    """The elements' relative frequency error (k_n h)^6/60480, k_n = (2n-1) pi/(2L)."""
    kh = (2 * np.arange(1, count + 1) - 1) * math.pi / (2 * LENGTH) * LENGTH / n_elements
    return kh ** 6 / 60480


FAMILIES = {
    # family: (section, counts (mx, mt), wave speed)
    "axial": (TUBE, (3, 0), math.sqrt(E / RHO)),
    "torsion, tube": (TUBE, (0, 3), math.sqrt(G / RHO)),   # J = Ip for a tube
    "torsion, section": (SECTION, (0, 3), math.sqrt(G * JT / (RHO * (IY + IZ)))),
}


@pytest.mark.parametrize("family", FAMILIES)
def test_rod_frequencies_converge_at_order_six_to_the_formula(tmp_path, family):
    """The three lowest axial or torsional frequencies on 4, 8, 16, 20 and 32 elements:
    above the exact ones and within (k_n h)^6/60480 of them; the error of f_1 falls by
    2^5.8-2^6 from 8 to 16 elements and that of f_2 by 2^5.85-2^6 from 16 to 32 (order 6,
    approached from below by the next term); at 32 elements f_2's error is 0.9-1 of the
    bound (the leading term). With 20 elements, f_1 within its bound 3.9e-12 (measured
    3.7e-12); the linearised model's frequencies (pymr.modes, central differences and
    dgeev) are these to 1e-9."""
    section, (mx, mt), speed = FAMILIES[family]
    path = _clamped(tmp_path, section=section, mx=mx, mt=mt)
    exact = _rod_frequencies(speed, 3)
    err = {}
    for ne in (4, 8, 16, 20, 32):
        w2, m = _omega2_and_mass(path, {"body[shaft].n_elements": ne})
        assert np.abs(m - np.eye(3)).max() < 1e-13       # the rings carry rho Ip exactly
        err[ne] = np.sqrt(w2) / (2 * math.pi) / exact - 1
        assert np.all(err[ne] > 0), f"{ne} elements: below the exact frequencies: {err[ne]}"
        assert np.all(err[ne] <= _error_bound(3, ne) + 1e-14), f"{ne} elements: {err[ne]} > {_error_bound(3, ne)}"
    rate1 = math.log2(err[8][0] / err[16][0])
    rate2 = math.log2(err[16][1] / err[32][1])
    print(f"\n{family}: f = {np.sqrt(w2) / (2 * math.pi)} Hz, exact {exact} Hz; relative errors "
          f"{ {ne: e.tolist() for ne, e in err.items()} }; rates {rate1:.3f}, {rate2:.3f}")
    assert 5.8 <= rate1 <= 6.0 and 5.85 <= rate2 <= 6.0
    assert 0.9 <= err[32][1] / _error_bound(2, 32)[1] <= 1.0
    assert 0 < err[20][0] <= _error_bound(1, 20)[0]
    freq, zeta, _ = pymr.modes(path, np.zeros(3), np.zeros(3))
    np.testing.assert_allclose(freq, exact * (1 + err[20]), rtol=1e-9)
    assert np.abs(zeta).max() < 1e-9


def test_marker_shapes_of_the_rod_modes_are_the_continuum_ones(tmp_path):
    """pymr.modes and pymr.marker_shapes on the clamped shaft (one axial, one torsional
    mode): a marker at the tip on the axis moves along x by the mass-normalised bar mode's
    tip value sqrt(2/(rho A L)) in the axial mode and not at all in the torsional one; a
    marker 0.02 m off the axis along z moves along y by -0.02 sqrt(2/(rho Ip L)) in the
    torsional mode (the twist carries the offset). To 1e-6 (the marker differences)."""
    path = _clamped(tmp_path, section=SECTION, mx=1, mt=1)
    path.write_text(path.read_text() + f"&marker name = 'end', body = 'shaft', at = {LENGTH}, 0.0, 0.0 /\n"
                    f"&marker name = 'edge', body = 'shaft', at = {LENGTH}, 0.0, 0.02 /\n")
    freq, _, shapes = pymr.modes(path, np.zeros(2), np.zeros(2))
    assert freq[0] < freq[1] and np.array_equal(np.abs(shapes), np.eye(2)[::-1])   # torsion first
    moves = pymr.marker_shapes(path, ["end", "edge"], np.zeros(2), np.zeros(2), shapes)
    tip_u = math.sqrt(2 / (RHO * AREA * LENGTH))
    tip_theta = math.sqrt(2 / (RHO * (IY + IZ) * LENGTH))
    sign = shapes.sum(axis=0)
    np.testing.assert_allclose(moves["end"] * sign, [[0.0, tip_u], [0.0, 0.0], [0.0, 0.0]], rtol=0,
                               atol=1e-6 * tip_u)
    np.testing.assert_allclose(moves["edge"] * sign, [[0.0, tip_u], [-0.02 * tip_theta, 0.0], [0.0, 0.0]],
                               rtol=0, atol=1e-6 * tip_u)


def test_long_shafts_take_the_banded_solver_and_stay_accurate(tmp_path):
    """With 2,000 elements (more than 100: inverse iteration on the banded matrices) the
    axial and torsional frequencies are the formulas' to 1e-13 (the elements' error is
    ~1e-20 there; measured 1e-15) and the modes stay mass-normalised (1e-13)."""
    path = _clamped(tmp_path, section=SECTION, my=1, mx=3, mt=3)
    w2, m = _omega2_and_mass(path, {"body[shaft].n_elements": 2000})
    f = np.sqrt(w2) / (2 * math.pi)
    assert np.abs(np.diag(m) - 1).max() < 1e-13
    np.testing.assert_allclose(f[1:4], _rod_frequencies(math.sqrt(E / RHO), 3), rtol=1e-13)
    np.testing.assert_allclose(f[4:], _rod_frequencies(math.sqrt(G * JT / (RHO * (IY + IZ))), 3), rtol=1e-13)


@pytest.mark.parametrize("section", [TUBE, SECTION])
def test_rings_add_the_section_inertia_and_the_bending_modes_their_rotary_inertia(tmp_path, section):
    """With torsional modes the mass points are rings around the axis: the undeformed beam
    pinned about z has the inertia rho A L^3/3 + rho Iz L (about y: + rho Iy L, about x:
    rho (Iy + Iz) L), exactly; without them a line mass's rho A L^3/3. The bending modes then
    solve the Rayleigh beam's eigenproblem (rotary inertia rho I int N'N'): their omega^2
    equal the reference's (tests/bruteforce.py, its own matrices and scipy eigh) to 1e-10
    (scipy's eigh leaves 1.8e-11 on the lowest one, the kernel 1.3e-12: measured against a
    Rayleigh-quotient refinement in long double, the same with and without the rotary
    inertia) and lie below the Euler-Bernoulli ones (by 0.07 % and 0.5 % for the tube);
    the modal mass is the identity."""
    area, iy, iz = (math.pi * (RO**2 - RI**2), math.pi / 4 * (RO**4 - RI**4), math.pi / 4 * (RO**4 - RI**4)) \
        if section == TUBE else (AREA, IY, IZ)
    line = RHO * area * LENGTH ** 3 / 3
    for axis, section_part in (("0.0, 0.0, 1.0", RHO * iz * LENGTH), ("0.0, 1.0, 0.0", RHO * iy * LENGTH),
                               ("1.0, 0.0, 0.0", RHO * (iy + iz) * LENGTH)):
        pinned = _clamped(tmp_path, section=section, my=2, mz=2, mx=1, mt=1, joint="revolute", axis=axis)
        z = np.zeros(7)
        m, _ = pymr.model_terms(pinned, z, z)
        expect = section_part + (0.0 if axis.startswith("1.0") else line)
        assert m[0, 0] == pytest.approx(expect, rel=1e-13)
        np.testing.assert_allclose(m[1:, 1:], np.eye(6), rtol=0, atol=1e-13)
    no_ring = _clamped(tmp_path, section=section, my=2, mz=2, mx=1, joint="revolute", name="no_ring.nml")
    assert pymr.model_terms(no_ring, np.zeros(6), np.zeros(6))[0][0, 0] == pytest.approx(line, rel=1e-13)
    clamped = _clamped(tmp_path, section=section, my=2, mz=2, mx=1, mt=1)
    w2, _ = _omega2_and_mass(clamped)
    ref = bf.Scene.from_file(clamped).bodies["shaft"].modes.omega2
    np.testing.assert_allclose(w2, ref, rtol=1e-10)
    w2_eb, _ = _omega2_and_mass(_clamped(tmp_path, section=section, my=2, mz=2, name="eb.nml"))
    shift = w2[:4] / w2_eb - 1
    print(f"\nrotary inertia lowers the bending omega^2 by {shift}")
    assert np.all(shift < 0) and np.all(shift > -0.01)


# Every family on one shaft: a hub on a skew revolute axis, a rigid tip off the axis, a
# pendulum on a revolute joint off the axis at mid-span, gravity.
EVERY = """\
&scene title = 'every family', t_end = 0.2, gravity = 0.5, -9.81, 2.0 /
&integrator method = 'single', adaptive = .true., rtol = 1.0e-10, atol = 1.0e-12, h_slow = 1.0e-5 /
&effects gravity = GRAVITY /
&body name = 'ground', kind = 'ground' /
&body name = 'shaft', kind = 'beam', length = 1.2, youngs_modulus = 7.0e10, density = 2700.0,
      shear_modulus = 2.6e10, SECTION, n_elements = 6,
      modes_y = 2, modes_z = 2, modes_x = 2, modes_t = 2,
      a0 = 1.0e-3, -5.0e-4, 8.0e-4, 2.0e-4, 1.0e-5, -4.0e-6, 2.0e-5, 3.0e-6,
      ad0 = 0.1, 0.0, -0.05, 0.0, 0.02, 0.0, 0.03, 0.0 /
&body name = 'tip', kind = 'rigid', mass = 0.5, com = 0.02, 0.03, -0.01,
      inertia = 1.0e-3, 2.0e-3, 1.5e-3, 1.0e-4, 0.0, 2.0e-4 /
&body name = 'bob', kind = 'rigid', mass = 0.2, com = 0.0, -0.1, 0.0, inertia = 1.0e-4, 1.0e-4, 1.0e-4, 0.0, 0.0, 0.0 /
&joint name = 'hub', kind = 'revolute', parent = 'ground', child = 'shaft', axis = 0.3, 0.4, 1.0, qd0 = 6.0 /
&joint name = 'weld', kind = 'fixed', parent = 'shaft', child = 'tip', at = TIP /
&joint name = 'swing', kind = 'revolute', parent = 'shaft', child = 'bob', at = 0.7, 0.01, -0.02,
       axis = 1.0, 0.0, 0.0, qd0 = 2.0 /
&marker name = 'edge', body = 'shaft', at = 1.2, 0.0, 0.01 /
&output dt = 1.0e-3 /
"""


def _every(tmp_path, gravity=True, section=SECTION, tip="1.2, 0.01, -0.02", name="every.nml") -> Path:
    path = tmp_path / name
    path.write_text(EVERY.replace("GRAVITY", ".true." if gravity else ".false.").replace("SECTION", section)
                    .replace("TIP", tip))
    return path


@pytest.mark.parametrize("section", [TUBE, SECTION])
def test_every_family_against_the_brute_force_reference(tmp_path, section):
    """M and P with bending, axial and torsional modes, rings of mass points, joints off the
    axis (their points move by Psi + Phi x r), at the initial state and at random states:
    the kernel equals the reference to 1e-9 (measured ~1e-15)."""
    path = _every(tmp_path, section=section)
    sc = bf.Scene.from_file(path)
    assert sc.n == pymr.model_size(path)[0] == 2 + 8
    rng = np.random.default_rng(5)
    states = [sc.initial_state()]
    for _ in range(3):
        q = rng.uniform(-math.pi, math.pi, sc.n)
        q[2:] = rng.uniform(-0.01, 0.01, 8)
        qd = rng.normal(0.0, 1.5, sc.n)
        qd[2:] *= 0.01 * np.sqrt(sc.bodies["shaft"].modes.omega2)
        states.append((q, qd))
    worst = 0.0
    for q, qd in states:
        mk, pk = pymr.model_terms(path, q, qd, 0.3)
        mr, pr = bf.reference_terms(sc, q, qd, 0.3)
        em = np.abs(mk - mr).max() / np.abs(mr).max()
        ep = np.abs(pk - pr).max() / (np.abs(pr).max() + np.abs(mr).max() * np.abs(qd).max() ** 2)
        worst = max(worst, em, ep)
    print(f"\nevery family, {section}: max relative error of M and P {worst:.2e}")
    assert worst < 1e-9
    bf.check_energy_and_accelerations(path, sc, states, 1e-9)


def test_free_run_keeps_its_energy(tmp_path):
    """The spinning shaft without gravity or damping, started with every family deflected
    and moving (a0, ad0): kinetic energy (pymr.model_energy) plus strain energy
    1/2 sum omega_k^2 a_k^2 stays constant over 0.2 s to 1e-6 of the energy the modes trade
    with the motion (adaptive run, rtol 1e-10; measured ~1e-8), and that trade is real."""
    path = _every(tmp_path, gravity=False)
    res = pymr.run(path)
    q, qd = res.coordinates()
    assert q.shape == (201, 10)
    kinetic, _ = pymr.model_energy(path, q, qd)
    n = q.shape[1]
    z = np.zeros(n)
    p0 = pymr.model_terms(path, z, z)[1]
    w2 = np.array([-(pymr.model_terms(path, e, z)[1] - p0)[k] for k, e in enumerate(np.eye(n))])
    strain = 0.5 * (w2[2:] * q[:, 2:] ** 2).sum(axis=1)
    total = kinetic + strain
    traded = strain.max() - strain.min()
    drift = np.abs(total - total[0]).max()
    print(f"\nfree run: energy {total[0]:.6g} J, strain energy traded {traded:.3g} J, drift {drift:.3g} J "
          f"({drift / traded:.2e} of the trade)")
    assert traded > 0.1 * strain[0]
    assert drift < 1e-6 * traded


STATIC = """\
&scene title = 'hanging shaft', t_end = 1.0e-5, gravity = {gx}, 0.0, {gz}, start = 'static' /
&integrator method = 'single', h_slow = 1.0e-6, stability_check = .false. /
&effects gravity = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'shaft', kind = 'beam', length = {length}, youngs_modulus = {e}, density = {rho},
      shear_modulus = {g}, {section}, n_elements = 4, modes_x = 9, modes_t = 9 /
&body name = 'tip', kind = 'rigid', mass = {mass}, com = 0.0, {c}, 0.0,
      inertia = 1.0e-3, 1.0e-3, 1.0e-3, 0.0, 0.0, 0.0 /
&joint name = 'clamp', kind = 'fixed', parent = 'ground', child = 'shaft' /
&joint name = 'weld', kind = 'fixed', parent = 'shaft', child = 'tip', at = {length}, 0.0, 0.0 /
&marker name = 'end', body = 'shaft', at = {length}, 0.0, 0.0 /
&marker name = 'edge', body = 'shaft', at = {length}, 0.0, {r} /
&output dt = 1.0e-5 /
"""


def test_static_start_stretches_and_twists_the_shaft_as_the_formulas(tmp_path):
    """The shaft hangs along gravity's x component and carries a 2 kg tip mass whose centre
    sits 0.1 m off the axis along y, with gravity g_z across it: a static start (all 9
    axial and 9 torsional modes of 4 elements: the exact fields, quadratic and linear, lie
    in the cubic elements' space) gives the tip's extension rho g_x L^2/(2E) + m g_x L/(EA)
    (marker on the axis) to 1e-9 and the twist theta = c m g_z L cos(theta)/(G J) (marker
    0.01 m off the axis: y = -0.01 theta; cos: the tip mass turns with the section) to 1e-8."""
    gx, gz, mass, c, r = 9.81, -4.0, 2.0, 0.1, 0.01
    path = tmp_path / "static.nml"
    path.write_text(STATIC.format(gx=gx, gz=gz, length=LENGTH, e=E, rho=RHO, g=G, section=SECTION, mass=mass,
                                  c=c, r=r))
    res = pymr.run(path)
    end, _ = res.marker("end")
    edge, _ = res.marker("edge")
    extension = RHO * gx * LENGTH ** 2 / (2 * E) + mass * gx * LENGTH / (E * AREA)
    k = c * mass * gz * LENGTH / (G * JT)
    theta = k
    for _ in range(50):                      # theta = k cos(theta), a contraction for |k| < 1
        theta = k * math.cos(theta)
    print(f"\nstatic: extension {end[0, 0] - LENGTH:.12e} m (formula {extension:.12e}), "
          f"twist {-edge[0, 1] / r:.12e} rad (formula {theta:.12e})")
    assert end[0, 0] - LENGTH == pytest.approx(extension, rel=1e-9)
    assert -edge[0, 1] / r == pytest.approx(theta, rel=1e-8)
    assert abs(end[0, 1]) < 1e-15 and abs(end[0, 2]) < 1e-15


def test_modal_file_round_trip_keeps_every_family(tmp_path):
    """The shaft written to a modal file (its rings of mass points with their shapes, and its
    nodes) and read back as kind='modal' gives the same M and P to 1e-12 (the tip jointed at
    the end node, a file point)."""
    path = _every(tmp_path, tip="1.2, 0.0, 0.0")
    text = path.read_text().replace("swing', kind = 'revolute', parent = 'shaft', child = 'bob', at = 0.7, 0.01, -0.02",
                                    "swing', kind = 'revolute', parent = 'shaft', child = 'bob', at = 0.6, 0.0, 0.0")
    text = re.sub(r"&marker .*?/\n", "", text)   # off the axis: not a point of the file
    path.write_text(text)
    modal = tmp_path / "shaft.modal"
    pymr.write_modal_file(path, "shaft", modal)
    again, count = re.subn(r"&body name = 'shaft'.*?/\n",
                           "&body name = 'shaft', kind = 'modal', modal_file = 'shaft.modal',\n"
                           "      a0 = 1.0e-3, -5.0e-4, 8.0e-4, 2.0e-4, 1.0e-5, -4.0e-6, 2.0e-5, 3.0e-6 /\n",
                           text, flags=re.S)
    assert count == 1
    modal_scene = tmp_path / "modal.nml"
    modal_scene.write_text(again)
    rng = np.random.default_rng(8)
    for _ in range(3):
        q, qd = rng.normal(size=10) * 0.5, rng.normal(size=10)
        q[2:] *= 0.01
        ma, pa = pymr.model_terms(path, q, qd)
        mb, pb = pymr.model_terms(modal_scene, q, qd)
        assert np.abs(ma - mb).max() < 1e-12 * np.abs(ma).max()
        assert np.abs(pa - pb).max() < 1e-12 * (np.abs(pa).max() + np.abs(ma).max() * np.abs(qd).max() ** 2)


def test_geometric_stiffening_leaves_the_axial_and_torsional_modes_alone(tmp_path):
    """Geometric stiffening by an axial load (gravity along -x: the shaft in compression
    N(x) = rho A g_x (L - x)) changes the bending block of the modal stiffness by
    int N v_k' v_l' dx (the reference's mode slopes, 8-point Gauss per element; to 1e-9)
    and gives the axial and torsional modes zero rows and columns (modal stiffness from P at
    a = e_k: the effect adds K_G a)."""
    path = _clamped(tmp_path, section=SECTION, my=2, mz=1, mx=2, mt=2)
    gx = -9.81
    text = path.read_text().replace("gravity = 0.0, 0.0, 0.0", f"gravity = {gx}, 0.0, 0.0")
    path.write_text(text.replace("&body name = 'ground'", "&effects gravity = .true., geometric_stiffening = .true. /\n"
                                 "&body name = 'ground'"))
    n = 7
    z = np.zeros(n)

    def stiffness(over):
        p0 = pymr.model_terms(path, z, z, overrides=over)[1]
        return np.column_stack([-(pymr.model_terms(path, e, z, overrides=over)[1] - p0) for e in np.eye(n)])

    kg = stiffness({}) - stiffness({"effects.geometric_stiffening": False})
    modes = bf.Scene.from_file(path).bodies["shaft"].modes
    x8, w8 = np.polynomial.legendre.leggauss(8)
    le = LENGTH / 20
    expect = np.zeros((3, 3))
    for e in range(20):
        for xi, wi in zip(0.5 * (x8 + 1), 0.5 * w8):
            x = (e + xi) * le
            _, phi = modes.shapes(x)
            slope = np.concatenate([phi[2, :2], -phi[1, 2:3]])
            same_plane = np.add.outer([0, 0, 1], [0, 0, 1]) != 1
            expect += le * wi * RHO * AREA * gx * (LENGTH - x) * np.outer(slope, slope) * same_plane
    print(f"\ngeometric stiffness of the bending modes {np.diag(kg)[:3]}, expected {np.diag(expect)}")
    np.testing.assert_allclose(kg[:3, :3], expect, rtol=0, atol=1e-9 * np.abs(expect).max())
    assert np.all(np.diag(expect) < 0)
    assert np.abs(kg[3:, :]).max() == 0.0 and np.abs(kg[:, 3:]).max() == 0.0


# -------------------------------------------------------------------------- scene errors

BAD_BASE = """\
&scene title = 'bad shaft', t_end = 0.01 /
&integrator method = 'single', h_slow = 1.0e-6 /
&effects modal_damping = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'shaft', kind = 'beam', length = 1.0, youngs_modulus = 7.0e10, density = 2700.0,
      SECTION, n_elements = 4,
      ITEMS /
&joint name = 'clamp', kind = 'fixed', parent = 'ground', child = 'shaft' /
"""

BAD = [
    ("no_shear_modulus", TUBE, "modes_y = 1, modes_t = 2",
     r"5: &body 'shaft': shear_modulus: missing \(Pa\): torsional modes \(modes_t = 2\) need the shear modulus"),
    ("no_torsion_constant", "area = 3.0e-4, iy = 2.0e-8, iz = 3.0e-8", "shear_modulus = 2.6e10, modes_t = 1",
     r"5: &body 'shaft': torsion_constant: missing \(m\^4\): torsional modes \(modes_t = 1\) of a section given "
     r"by area, iy and iz need its torsion constant"),
    ("torsion_constant_of_a_tube", TUBE, "torsion_constant = 1.0e-8, shear_modulus = 2.6e10, modes_t = 1",
     r"7: &body 'shaft': torsion_constant: a tube has pi/2 \(r_outer\^4 - r_inner\^4\); give torsion_constant "
     r"only with area, iy and iz"),
    ("modes_x_above", TUBE, "modes_x = 10",
     r"7: &body 'shaft': modes_x: must be 0 to 2\*n_elements \+ 1 = 9, got 10"),
    ("modes_t_above", TUBE, "shear_modulus = 2.6e10, modes_t = 10",
     r"7: &body 'shaft': modes_t: must be 0 to 2\*n_elements \+ 1 = 9, got 10"),
    ("a0_count", TUBE, "shear_modulus = 2.6e10, modes_y = 1, modes_x = 2, modes_t = 1, a0 = 0.0, 1.0e-6, 0.0",
     r"7: &body 'shaft': a0: give one value per mode \(4 modes\), got 3"),
    ("ad0_count", TUBE, "modes_z = 1, modes_x = 1, ad0 = 0.0, 1.0, 2.0",
     r"7: &body 'shaft': ad0: give one value per mode \(2 modes\), got 3"),
    ("modal_damping_count", TUBE, "shear_modulus = 2.6e10, modes_x = 2, modes_t = 2, modal_damping = 0.01, 0.02",
     r"7: &body 'shaft': modal_damping: give one value or one per mode \(4 modes\), got 2"),
]


@pytest.mark.parametrize("case", BAD, ids=[c[0] for c in BAD])
def test_bad_beam_modes_are_refused_in_one_line(tmp_path, mrsim, case):
    """mrsim exits 1 with one line naming the file, the line, the group and the item (as the
    bad-scene corpus, tests/test_bad_scenes.py); pymr.run raises SceneError with it. The
    counts of a0, ad0 and modal_damping include the axial and torsional modes."""
    name, section, items, pattern = case
    path = tmp_path / f"{name}.nml"
    path.write_text(BAD_BASE.replace("SECTION", section).replace("ITEMS", items))
    out = tmp_path / "out.csv"
    message = error_message(run_mrsim(mrsim, [path.name, "-o", str(out)], tmp_path))
    assert re.fullmatch(re.escape(path.name) + ":" + pattern, message), message
    assert not out.exists()
    with pytest.raises(pymr.SceneError) as info:
        pymr.run(path)
    assert str(info.value).endswith(message.split(":", 1)[1])
