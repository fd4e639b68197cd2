"""pymr modal-import (issue 17, part 6): bodies from finite-element matrices.

- A Hermite beam exported as Matrix Market gives the built-in beam's frequencies, and the
  tank's barrel imported that way gives the built-in barrel's muzzle motion.
- A plate of 8-node solid elements (assembled here) runs end to end: its first frequency
  against scipy's eigh of the full matrices with the clamped face held, the static sag under
  gravity against the full K u = f, and the kernel's mass matrix at a deformed state against
  a quadrature of the solid's own fields.
- Bad input: one line naming the file and the fault, exit status 1.
"""
from __future__ import annotations

import importlib.util
import re
import warnings
from pathlib import Path

import numpy as np
import pytest
import scipy.io
import scipy.linalg
import scipy.sparse

import pymr
from pymr.cli import main

ROOT = Path(__file__).resolve().parent.parent
TANK = ROOT / "input" / "tank_gun_turret.nml"
L, E, RHO, RO, RI = 5.3, 2.07e11, 7850.0, 0.11, 0.06
AREA = np.pi * (RO**2 - RI**2)
I2 = np.pi / 4 * (RO**4 - RI**4)


# ----------------------------------------------------------------------------- FE models

def beam_matrices(length, e, rho, area, iy, iz, ne, polar_mass=0.0):
    """Euler-Bernoulli beam along x, nodes 1..ne+1 from x = 0, 6 DOFs per node (u_x u_y u_z
    theta_x theta_y theta_z): closed-form Hermite bending elements (v' = theta_z,
    w' = -theta_y), linear bar and torsion; line mass, no rotary inertia (as the built-in
    beam) unless polar_mass (rho J_p, kg m) gives the torsion its own. Returns K, M, nodes
    (id, x, y, z)."""
    le = length / ne
    n = 6 * (ne + 1)
    k, m = np.zeros((n, n)), np.zeros((n, n))
    bar = np.array([[1.0, -1.0], [-1.0, 1.0]]) / le
    bar_m = le / 6 * np.array([[2.0, 1.0], [1.0, 2.0]])

    def kb(ei):
        return ei / le**3 * np.array([[12, 6 * le, -12, 6 * le], [6 * le, 4 * le**2, -6 * le, 2 * le**2],
                                      [-12, -6 * le, 12, -6 * le], [6 * le, 2 * le**2, -6 * le, 4 * le**2]])
    mb = rho * area * le / 420 * np.array([[156, 22 * le, 54, -13 * le], [22 * le, 4 * le**2, 13 * le, -3 * le**2],
                                           [54, 13 * le, 156, -22 * le], [-13 * le, -3 * le**2, -22 * le, 4 * le**2]])
    flip = np.diag([1.0, -1.0, 1.0, -1.0])
    for el in range(ne):
        a, b = 6 * el, 6 * (el + 1)
        ax, tx = [a, b], [a + 3, b + 3]
        k[np.ix_(ax, ax)] += e * area * bar
        m[np.ix_(ax, ax)] += rho * area * bar_m
        k[np.ix_(tx, tx)] += e / 2.6 * (iy + iz) * bar
        m[np.ix_(tx, tx)] += polar_mass * bar_m
        y, z = [a + 1, a + 5, b + 1, b + 5], [a + 2, a + 4, b + 2, b + 4]
        k[np.ix_(y, y)] += kb(e * iz)
        m[np.ix_(y, y)] += mb
        k[np.ix_(z, z)] += flip @ kb(e * iy) @ flip
        m[np.ix_(z, z)] += flip @ mb @ flip
    nodes = np.column_stack([np.arange(1, ne + 2), np.linspace(0, length, ne + 1), np.zeros((ne + 1, 2))])
    return k, m, nodes


HEX_CORNERS = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                        [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float)
GAUSS2 = np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)]) / np.sqrt(3.0)


def hex_shape(xi):
    """Trilinear shape functions (8) and their derivatives (8, 3) at xi."""
    t = 1.0 + HEX_CORNERS * xi
    n = t.prod(axis=1) / 8
    dn = np.stack([HEX_CORNERS[:, d] * np.prod(np.delete(t, d, axis=1), axis=1) / 8 for d in range(3)], axis=1)
    return n, dn


class HexPlate:
    """A box of nx x ny x nz 8-node solid elements (isotropic, consistent mass,
    2 x 2 x 2 Gauss), nodes numbered from 1 at the corner (0, 0, 0), x fastest."""

    def __init__(self, size=(0.6, 0.3, 0.04), count=(6, 3, 1), e=70e9, nu=0.3, rho=2700.0):
        self.size, self.count, self.rho = size, count, rho
        nx, ny, nz = count
        grid = np.meshgrid(*[np.linspace(0, s, c + 1) for s, c in zip(size, count)], indexing="ij")
        self.x = np.column_stack([g.transpose(2, 1, 0).ravel() for g in grid])     # x fastest
        self.ids = np.arange(1, len(self.x) + 1)
        nid = lambda i, j, k: i + (nx + 1) * (j + (ny + 1) * k)
        self.elements = [[nid(i + a, j + b, k + c) for a, b, c in ((HEX_CORNERS + 1) / 2).astype(int)]
                         for k in range(nz) for j in range(ny) for i in range(nx)]
        lam, mu = e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))
        d = np.zeros((6, 6))
        d[:3, :3] = lam
        d[np.arange(6), np.arange(6)] += np.r_[2 * mu * np.ones(3), mu * np.ones(3)]
        n = 3 * len(self.x)
        self.k, self.m = np.zeros((n, n)), np.zeros((n, n))
        for el in self.elements:
            xe = self.x[el]
            ke, ms = np.zeros((24, 24)), np.zeros((8, 8))
            for g in GAUSS2:
                sh, dn = hex_shape(g)
                jac = dn.T @ xe
                dx = dn @ np.linalg.inv(jac).T                          # (8, 3) d/dx
                b = np.zeros((6, 24))
                for a in range(8):
                    gx, gy, gz = dx[a]
                    b[:, 3 * a:3 * a + 3] = [[gx, 0, 0], [0, gy, 0], [0, 0, gz], [gy, gx, 0], [0, gz, gy], [gz, 0, gx]]
                det = np.linalg.det(jac)
                ke += b.T @ d @ b * det
                ms += rho * np.outer(sh, sh) * det
            rows = np.ravel([[3 * a, 3 * a + 1, 3 * a + 2] for a in el])
            self.k[np.ix_(rows, rows)] += ke
            self.m[np.ix_(rows, rows)] += np.kron(ms, np.eye(3))

    def node(self, x, y, z) -> int:
        return int(self.ids[np.argmin(np.linalg.norm(self.x - [x, y, z], axis=1))])

    def face(self, axis: int, value: float) -> list[int]:
        return [int(i) for i in self.ids[np.abs(self.x[:, axis] - value) < 1e-12]]

    def rotational_inertia(self, axis, u):
        """int rho |axis x (s + u(s))|^2 dV and int rho (s + u) x u_k dV . axis over the
        solid's own trilinear fields (u: nodal displacement (nodes, 3); u_k: shapes
        (nodes, 3, m)) by 2 x 2 x 2 Gauss, exact for the box's polynomial integrand."""
        return self._quad(lambda c, uk: np.dot(np.cross(axis, c), np.cross(axis, c)), u, None)

    def coupling(self, axis, u, shapes):
        return self._quad(lambda c, uk: np.cross(c, uk.T) @ axis, u, shapes)

    def _quad(self, f, u, shapes):
        total = 0.0
        for el in self.elements:
            for g in GAUSS2:
                sh, dn = hex_shape(g)
                det = np.linalg.det(dn.T @ self.x[el])
                c = sh @ (self.x[el] + u[el])
                uk = None if shapes is None else np.einsum("a,aim->im", sh, shapes[el])
                total = total + self.rho * det * f(c, uk)
        return total


def write_fe(tmp_path, k, m, nodes, symmetric=True):
    """K (lower triangle, symmetric) and M (general) as Matrix Market, nodes as CSV."""
    kp, mp, npath = tmp_path / "k.mtx", tmp_path / "m.mtx", tmp_path / "nodes.csv"
    scipy.io.mmwrite(kp, scipy.sparse.coo_matrix(np.tril(k) if symmetric else k),
                     symmetry="symmetric" if symmetric else "general")
    scipy.io.mmwrite(mp, scipy.sparse.coo_matrix(m))
    npath.write_text("id, x, y, z\n" + "".join(f"{int(r[0])}, {float(r[1])!r}, {float(r[2])!r}, {float(r[3])!r}\n"
                                              for r in nodes))
    return mp, kp, npath


def builtin_frequencies(tmp_path) -> np.ndarray:
    path = tmp_path / "builtin.modal"
    pymr.write_modal_file(TANK, "gun", path)
    line = re.search(r"^frequencies_hz (.*)$", path.read_text(), flags=re.M).group(1)
    return np.sort([float(v) for v in line.split()])


@pytest.fixture(scope="module")
def barrel(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("barrel")
    k, m, nodes = beam_matrices(L, E, RHO, AREA, I2, I2, 20)
    return tmp, write_fe(tmp, k, m, nodes)


# ----------------------------------------------------------------------------- the beam

def test_beam_from_matrices_has_the_builtin_frequencies(barrel):
    """The tank's barrel assembled from closed-form Hermite elements, clamped at its root
    node: the fixed-interface modes are the cantilever's, equal to the built-in beam's
    (its own Gauss-integrated assembly and LAPACK eigensolver) to 1e-6 (measured 5e-12)."""
    tmp, (mp, kp, npath) = barrel
    body = pymr.modal_import(mp, kp, npath, [1], tmp / "root.modal", modes=4)
    ref = builtin_frequencies(tmp)
    err = np.abs(body.frequencies_hz - ref) / ref
    print(f"\nbeam from matrices: f = {body.frequencies_hz} Hz, relative error {err}")
    assert err.max() < 1e-6
    assert body.mass == pytest.approx(RHO * AREA * L, rel=1e-13)
    # mass-normalised, their stiffness omega^2
    k, m, _ = beam_matrices(L, E, RHO, AREA, I2, I2, 20)
    u = body.shapes
    np.testing.assert_allclose(u.T @ m @ u, np.eye(4), atol=1e-10)
    np.testing.assert_allclose(u.T @ k @ u, np.diag((2 * np.pi * body.frequencies_hz) ** 2), rtol=1e-9, atol=1e-6)


@pytest.mark.parametrize("scale_m, scale_k", [(1e-140, 1.0), (1e140, 1e-140), (2.0**-100, 2.0**60)])
def test_the_reduction_holds_its_digits_over_the_matrices_units(barrel, tmp_path, scale_m, scale_k):
    """Matrices in any units MATRIX_SCALE takes: M c and K d give the frequencies times
    sqrt(d / c), to rounding (the eigensolve's mass matrix is scaled by a power of 2 near
    max|K| / max|M|: ARPACK's convergence test has an absolute floor, which K in 2^60 and
    M in 2^-100 reached, 8e-10 off, 1.9e-9 with OpenBLAS), and shapes normalised to the scaled mass matrix with the scaled
    stiffness omega^2 (the beam's bending pairs are double eigenvalues: their shapes are any
    basis of their plane). A mass matrix of 6e-139 failed in ARPACK ('starting vector is
    zero', exit 2; found by the second bad-input audit): a matrix whose largest entry is
    beyond 1e+-50 is now taken in units of that entry."""
    tmp, (mp, kp, npath) = barrel
    ref = pymr.modal_import(mp, kp, npath, [1, 21], modes=6, keep=4)
    k, m, nodes = beam_matrices(L, E, RHO, AREA, I2, I2, 20)
    mp2, kp2, np2 = write_fe(tmp_path, k * scale_k, m * scale_m, nodes)
    body = pymr.modal_import(mp2, kp2, np2, [1, 21], modes=6, keep=4)
    np.testing.assert_allclose(body.frequencies_hz, ref.frequencies_hz * np.sqrt(scale_k / scale_m), rtol=1e-9)
    u = body.shapes
    np.testing.assert_allclose(u.T @ (m * scale_m) @ u, np.eye(4), atol=1e-10)
    np.testing.assert_allclose(u.T @ (k * scale_k) @ u, np.diag((2 * np.pi * body.frequencies_hz) ** 2), rtol=1e-9,
                               atol=1e-9 * (2 * np.pi * body.frequencies_hz.max()) ** 2)


def test_beam_with_a_tip_interface_converges_to_the_cantilever(barrel):
    """With the muzzle node as a second interface, its 6 constraint modes join the
    fixed-interface (clamped-clamped) modes: the reduced body's lowest 4 frequencies approach
    the cantilever's from above as modes are added, and with all of them they are exact."""
    tmp, (mp, kp, npath) = barrel
    ref = builtin_frequencies(tmp)
    errs = []
    for n in (4, 8, 16, None):
        f = pymr.modal_import(mp, kp, npath, [1, 21], modes=n, keep=4).frequencies_hz
        errs.append((f - ref) / ref)
    print("\ntip interface, 4/8/16/all fixed-interface modes: relative error of f1..f4",
          [f"{e.max():.2e}" for e in errs])
    assert all(e.min() > -1e-9 for e in errs)                   # Ritz values: from above
    assert errs[0].max() > errs[1].max() > errs[2].max()
    assert np.abs(errs[-1]).max() < 1e-9


def test_tank_barrel_from_matrices_gives_the_same_muzzle_motion(barrel, tmp_path):
    """The tank with its barrel imported (root clamped, muzzle node an interface, all
    fixed-interface modes, the lowest 4 modes kept like the built-in beam's): the muzzle
    follows the built-in barrel's path to 1e-8 m over the run (measured 9e-13 m)."""
    tmp, (mp, kp, npath) = barrel
    pymr.modal_import(mp, kp, npath, [1, 21], tmp_path / "gun.modal", modes=None, keep=4)
    text, count = re.subn(r"&body\s*\n\s*name = 'gun'.*?/\n",
                          "&body name = 'gun', kind = 'modal', modal_file = 'gun.modal' /\n", TANK.read_text(),
                          flags=re.S)
    assert count == 1
    scene = tmp_path / "tank_fe.nml"
    scene.write_text(text)
    a = pymr.run(TANK, tmp_path / "a.csv")
    b = pymr.run(scene, tmp_path / "b.csv")
    pa, _ = a.marker("muzzle")
    pb, _ = b.marker("muzzle")
    diff = np.abs(pa - pb).max()
    print(f"\nmuzzle: largest difference {diff:.2e} m over {a.t[-1]} s (travel {np.abs(pa - pa[0]).max():.3f} m)")
    assert np.abs(pa - pa[0]).max() > 0.5 and np.abs(a["gun.a1"]).max() > 1e-3
    assert diff < 1e-8


def test_torsion_mass_enters_as_rotary_inertia(tmp_path):
    """A tube with its polar mass rho J_p on theta_x (coupled with no translation): on a
    revolute joint about its axis the kernel's M_00 is rho J_p L (the line mass adds
    nothing about the axis), the first torsion mode's coupling M_0k is the continuum's
    rho J_p int phi = sqrt(2 rho J_p L) 2/pi (within the 20 elements' 1e-3), and the modal
    mass matrix stays the identity (the rule (I - e e^T)/2 keeps its trace)."""
    jp = 2 * I2
    k, m, nodes = beam_matrices(L, E, RHO, AREA, I2, I2, 20, polar_mass=RHO * jp)
    mp, kp, npath = write_fe(tmp_path, k, m, nodes)
    body = pymr.modal_import(mp, kp, npath, [1, 21], tmp_path / "tube.modal", modes=None, keep=12)
    ft = np.sqrt(E / 2.6 / RHO) / (4 * L)                      # first torsion frequency, GJ = G J_p
    tors = int(np.argmin(np.abs(body.frequencies_hz - ft)))
    assert abs(body.frequencies_hz[tors] - ft) < 1e-3 * ft
    scene = tmp_path / "tube.nml"
    scene.write_text("&scene t_end = 0.01 /\n&integrator method = 'single', h_slow = 1e-5 /\n"
                     "&body name = 'g', kind = 'ground' /\n&body name = 'tube', kind = 'modal', modal_file = 'tube.modal' /\n"
                     "&joint name = 'spin', kind = 'revolute', parent = 'g', child = 'tube', axis = 1.0, 0.0, 0.0 /\n")
    n = 1 + len(body.frequencies_hz)
    mm, _ = pymr.model_terms(scene, np.zeros(n), np.zeros(n))
    continuum = np.sqrt(2 * RHO * jp * L) * 2 / np.pi
    print(f"\ntube: M_00 rel err {(mm[0, 0] - RHO * jp * L) / (RHO * jp * L):.1e}; torsion mode {tors + 1} "
          f"({body.frequencies_hz[tors]:.2f} Hz): M_0k {abs(mm[0, 1 + tors]):.6g}, continuum {continuum:.6g}")
    assert mm[0, 0] == pytest.approx(RHO * jp * L, rel=1e-12)
    assert abs(mm[0, 1 + tors]) == pytest.approx(continuum, rel=1e-3)
    np.testing.assert_allclose(mm[1:, 1:], np.eye(n - 1), atol=1e-12)


# ----------------------------------------------------------------------------- a solid plate

PLATE_SCENE = """&scene title = 'imported plate', t_end = 1.0e-6, gravity = 0.0, 0.0, -9.81, start = 'static' /
&integrator method = 'single', h_fast = 5.0e-7, h_slow = 5.0e-7 /
&effects gravity = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'plate', kind = 'modal', modal_file = '{file}' /
&joint name = 'hold', kind = '{joint}', parent = 'ground', child = 'plate'{axis} /
&marker name = 'c1', body = 'plate', at = {c1} /
&marker name = 'c2', body = 'plate', at = {c2} /
&output dt = 1.0e-6 /
"""


@pytest.fixture(scope="module")
def plate(tmp_path_factory):
    tmp = tmp_path_factory.mktemp("plate")
    p = HexPlate()
    nodes = np.column_stack([p.ids, p.x])
    files = write_fe(tmp, p.k, p.m, nodes)
    lx, ly, _ = p.size
    origin = p.node(0, 0, 0)
    clamp = [n for n in p.face(0, 0.0) if n != origin]
    tips = [p.node(lx, 0, 0), p.node(lx, ly, 0)]
    held = sorted(3 * (n - 1) + c for n in [origin] + clamp for c in range(3))
    free = np.setdiff1d(np.arange(3 * len(p.ids)), held)
    return tmp, p, files, origin, clamp, tips, free


def plate_scene(tmp, p, tips, file, joint="fixed", axis=""):
    at = lambda n: ", ".join(repr(float(v)) for v in p.x[n - 1])
    path = tmp / f"plate_{file}_{joint}.nml"
    path.write_text(PLATE_SCENE.format(file=file, joint=joint, axis=axis, c1=at(tips[0]), c2=at(tips[1])))
    return path


@pytest.mark.parametrize("modes, tol_f", [(None, 1e-9), (6, 1e-3)])
def test_plate_runs_and_matches_the_full_model(plate, modes, tol_f):
    """A solid plate (6 x 3 x 1 hexahedra, 56 nodes) clamped at its face x = 0 (origin node
    and 7 clamp nodes), its tip corners as interfaces, jointed to the ground with gravity
    along -z. With all fixed-interface modes the reduced body is the full FE model: its first
    frequency (pymr.modes of the scene) equals scipy's eigh of (K, M) with the face held to
    1e-9; with 6 fixed-interface modes (plus the corners' 6 constraint modes) the truncation
    leaves f1 above it within 1e-3 (measured 5e-5). The static start's sag of the corners
    equals the full K u = M g to 1e-9 with any number of modes: Craig-Bampton's reduced
    stiffness is block-diagonal, so the constraint modes carry the exact static condensation
    onto the interface (measured 4e-12; points inside the plate would need the modes).
    """
    tmp, p, (mp, kp, npath), origin, clamp, tips, free = plate
    name = f"plate_{modes}.modal"
    body = pymr.modal_import(mp, kp, npath, [origin] + tips, tmp / name, dofs_per_node=3, modes=modes, clamp=clamp)
    assert body.exact == "exact"
    kf, mf = p.k[np.ix_(free, free)], p.m[np.ix_(free, free)]
    lam = scipy.linalg.eigh(kf, mf, eigvals_only=True, subset_by_index=[0, 0])[0]
    f_full = np.sqrt(lam) / (2 * np.pi)
    scene = plate_scene(tmp, p, tips, name)
    res = pymr.run(scene)
    q, qd = res.coordinates()
    freq, _, _ = pymr.modes(scene, q[0] * 0, qd[0] * 0)
    g = np.tile([0.0, 0.0, -9.81], len(p.ids))
    u = np.zeros(3 * len(p.ids))
    u[free] = np.linalg.solve(kf, (p.m @ g)[free])
    rel_f = (freq[0] - f_full) / f_full
    sags = []
    for name_, n in zip(("c1", "c2"), tips):
        pos, _ = res.marker(name_)
        full = u[3 * (n - 1):3 * n]
        sags.append(np.abs(pos[0] - p.x[n - 1] - full).max() / np.abs(full).max())
    print(f"\nplate, modes={modes}: f1 = {freq[0]:.6f} Hz (full FE {f_full:.6f}, rel {rel_f:.2e}); "
          f"corner sag {u[3 * (tips[1] - 1) + 2] * 1e3:.4f} mm, relative error {max(sags):.2e}")
    assert abs(rel_f) < tol_f and rel_f > -1e-9
    assert max(sags) < 1e-9


def test_plate_inertia_at_a_deformed_state_against_quadrature(plate):
    """The kernel's mass matrix of the imported plate on a revolute joint about a skew axis,
    at a deformed state: M_00 = int rho |n x c|^2 (c = s + u, the deformed body) and
    M_0k = n . int rho c x psi_k, against 2 x 2 x 2 Gauss quadrature of the solid's own
    trilinear fields (independent of the mass matrix and of the invariants), to 1e-10."""
    tmp, p, (mp, kp, npath), origin, clamp, tips, free = plate
    body = pymr.modal_import(mp, kp, npath, [origin] + tips, tmp / "plate_rev.modal", dofs_per_node=3, modes=6,
                             clamp=clamp)
    axis = np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    scene = plate_scene(tmp, p, tips, "plate_rev.modal", joint="revolute",
                        axis=", axis = " + ", ".join(repr(float(v)) for v in axis))
    nm = body.shapes.shape[1]
    a = np.zeros(nm)
    a[:3] = [0.04, -0.025, 0.015]                        # deflections of centimetres
    q = np.r_[0.0, a]
    mm, _ = pymr.model_terms(scene, q, np.zeros_like(q))
    shapes = body.shapes.reshape(len(p.ids), 3, nm)
    u = shapes @ a
    j = p.rotational_inertia(axis, u)
    c = p.coupling(axis, u, shapes)
    print(f"\nplate on a revolute joint, deformed by {np.abs(u).max() * 1e3:.1f} mm: M_00 rel err "
          f"{(mm[0, 0] - j) / j:.2e}, M_0k largest err {np.abs(mm[0, 1:] - c).max():.2e} (of {np.abs(c).max():.3g})")
    assert np.abs(u).max() > 0.01
    assert mm[0, 0] == pytest.approx(j, rel=1e-10)
    np.testing.assert_allclose(mm[0, 1:], c, rtol=0, atol=1e-10 * np.abs(c).max())
    np.testing.assert_allclose(mm[1:, 1:], np.eye(nm), atol=1e-10)


# ----------------------------------------------------------------------------- format 2

def test_format_2_errors(tmp_path):
    """The invariants block: only in format 2, its points massless, its lines in order."""
    scene = tmp_path / "s.nml"
    scene.write_text("&scene t_end = 0.01 /\n&integrator method = 'single', h_slow = 1e-3 /\n"
                     "&body name = 'g', kind = 'ground' /\n&body name = 'b', kind = 'modal', modal_file = 'b.modal' /\n"
                     "&joint name = 'j', kind = 'fixed', parent = 'g', child = 'b' /\n")
    inv = "invariants\nmass 2.0\nfirst_moments\n0 1 0 0\n1 0 0 0\nsecond_moments\n0 0 1 0 0 0 0 0 0 0 0\n" \
          "0 1 0 0 0 0 0 0 0 0 0\n1 1 1 0 0 0 0 0 0 0 0\n"
    good = "pymr-modal 2\nmodes 1\nfrequencies_hz 5.0\n" + inv + "points 1\n0 0 0 0 0 1 0 0 0 1\n"
    (tmp_path / "b.modal").write_text(good)
    pymr.run(scene)
    for text, fault in [(good.replace("pymr-modal 2", "pymr-modal 1"), r"line 4: invariants: needs pymr-modal 2"),
                        (good.replace("pymr-modal 2", "pymr-modal 3"), r"line 1: pymr-modal: expected the format "
                                                                       r"version 1 or 2"),
                        (good.replace("0 0 0 0 0 1 0 0 0 1", "0 0 0 1 0 1 0 0 0 1"), r"line 14: point 1: mass must be 0"),
                        (good.replace("1 1 1 0 0", "1 0 1 0 0"),
                         r"line 12: second_moments: expected the line of W\(1:3, 1:3, 1, 1\), which begins with 1 1, "
                         r"got .1 0. first"),
                        (good.replace("mass 2.0", "mass -2.0"), r"line 5: mass: expected a positive mass")]:
        (tmp_path / "b.modal").write_text(text)
        with pytest.raises(pymr.SceneError, match=r"&body 'b'.*b\.modal: " + fault):
            pymr.run(scene)


# ----------------------------------------------------------------------------- bad input

def _cli(capsys, *args):
    rc = main(["modal-import", *args])
    err = capsys.readouterr().err
    return rc, err


@pytest.fixture
def small(tmp_path):
    k, m, nodes = beam_matrices(2.0, 2e11, 7800.0, 1e-3, 1e-7, 2e-7, 4)   # no repeated frequency
    return tmp_path, k, m, nodes


def test_bad_inputs_name_the_file_and_the_fault(small, capsys):
    tmp, k, m, nodes = small
    mp, kp, npath = write_fe(tmp, k, m, nodes)
    base = ["--mass", str(mp), "--stiffness", str(kp), "--nodes", str(npath), "-o", str(tmp / "x.modal")]

    def swap(flag, value):
        out = list(base)
        out[out.index(flag) + 1] = str(value)
        return out

    bad = tmp / "bad.mtx"
    nonsym = k.copy()
    nonsym[0, 6] += 1.0
    scipy.io.mmwrite(tmp / "nonsym.mtx", scipy.sparse.coo_matrix(nonsym))
    negm = m.copy()
    negm[1, 1] = -negm[1, 1]
    scipy.io.mmwrite(tmp / "negm.mtx", scipy.sparse.coo_matrix(negm))
    small_k = k[:24, :24]
    scipy.io.mmwrite(tmp / "smallk.mtx", scipy.sparse.coo_matrix(small_k))
    free_k = k.copy()
    free_k[:, 3::6] = 0.0
    free_k[3::6, :] = 0.0                                # no torsion stiffness: a mechanism
    scipy.io.mmwrite(tmp / "freek.mtx", scipy.sparse.coo_matrix(free_k))
    bad.write_text("%%MatrixMarket matrix coordinate complex general\n1 1 1\n1 1 1.0 0.0\n")
    (tmp / "nodes_dup.csv").write_text(npath.read_text() + "3, 9.0, 0.0, 0.0\n")
    (tmp / "map.txt").write_text("".join(f"{r + 1} {r // 6 + 1} {r % 6 + 1}\n" for r in range(29)) + "30 77 6\n")
    cases = [
        (swap("--mass", tmp / "none.mtx") + ["--interface", "1"], r"none\.mtx: no such file"),
        (swap("--stiffness", tmp / "nonsym.mtx") + ["--interface", "1"], r"nonsym\.mtx: not symmetric"),
        (swap("--stiffness", tmp / "freek.mtx") + ["--interface", "1"],
         r"freek\.mtx: row 10 \(node 2 theta_x\) has no stiffness, and 4 rows in all: DOFs constrained in the FE "
         r"code\? Export the free body"),
        (swap("--mass", tmp / "negm.mtx") + ["--interface", "1"], r"negm\.mtx: not positive semi-definite"),
        (swap("--stiffness", tmp / "smallk.mtx") + ["--interface", "1"],
         r"smallk\.mtx: line 3: 24 rows, but .*nodes\.csv has 5 nodes x 6 DOFs = 30"),
        (swap("--mass", bad) + ["--interface", "1"], r"bad\.mtx: line 1: coordinate complex general: only real"),
        (base + ["--interface", "1", "9"], r"nodes\.csv: interface node 9 is not in the mesh"),
        (base + ["--interface", "1", "--dofs-per-node", "3"], r"m\.mtx: line 3: 30 rows, but .*nodes\.csv has 5 nodes x 3"),
        (swap("--nodes", tmp / "nodes_dup.csv") + ["--interface", "1"], r"nodes_dup\.csv: node 3 is given twice"),
        (base + ["--interface", "1", "--dof-map", str(tmp / "map.txt")], r"map\.txt: line 30: node 77 is not in"),
        (base + ["--interface", "1", "--modes", "99"], r"--modes 99: the inner DOFs have only 20 modes with mass"),
        # the inertia about node 1 overflowed: NaN and inf in the .modal file, exit 0
        (swap("--nodes", tmp / "nodes_far.csv") + ["--interface", "1"],
         r"nodes_far\.csv: the nodes lie up to 2e\+300 from node 1, and the body's inertia about it overflows"),
        # matrices in units far from SI: LAPACK's own error text on stdout, or another body each run
        (swap("--stiffness", tmp / "k_tiny.mtx") + ["--interface", "1"],
         r"k_tiny\.mtx: its largest entry is [0-9.]+e-19\d, outside \[1e-150, 1e\+150\] where the reduction keeps its "
         r"digits: check the matrix's units"),
        (swap("--mass", tmp / "m_huge.mtx") + ["--interface", "1"], r"m_huge\.mtx: its largest entry is [0-9.]+e\+30\d"),
        # an overflow of the byte count (a traceback)
        (base + ["--interface", "1", "--memory-limit", "1e300"], r"memory_limit=1e\+300: above 1e\+09 GB"),
    ]
    scipy.io.mmwrite(tmp / "k_tiny.mtx", scipy.sparse.coo_matrix(k * 1e-200))
    scipy.io.mmwrite(tmp / "m_huge.mtx", scipy.sparse.coo_matrix(m * 1e300))
    (tmp / "nodes_far.csv").write_text("".join(f"{int(r[0])}, {float(r[1]) * 1e300!r}, {float(r[2])!r}, {float(r[3])!r}\n" for r in nodes))
    if importlib.util.find_spec("pyNastran") is not None:     # .ci/setup installs it
        grids = [f"GRID,{int(r[0])},,{float(r[1])!r},{float(r[2])!r},{float(r[3])!r}\n" for r in nodes]
        (tmp / "nan.bdf").write_text("".join(grids[:-1]) + grids[-1].replace(f"{float(nodes[-1][1])!r}", "nan", 1))
        (tmp / "cp.bdf").write_text(grids[0] + grids[1].replace(",,", ",7,", 1) + "".join(grids[2:]))
        cases += [
            # NaN coordinates of GRID cards reached the .modal file with exit 0
            (swap("--nodes", tmp / "nan.bdf") + ["--interface", "1"], r"nan\.bdf: GRID card: node 5: coordinates "
                                                                       r"not finite"),
            # a coordinate system not defined was an AttributeError traceback inside pyNastran
            (swap("--nodes", tmp / "cp.bdf") + ["--interface", "1"],
             r"cp\.bdf: GRID 2: its coordinate system CP = 7 \(or one it is defined in\) is not in the bulk data"),
        ]
    for args, fault in cases:
        rc, err = _cli(capsys, *args)
        assert rc == 1, (args, err)
        assert "Traceback" not in err
        lines = err.strip().splitlines()
        assert len(lines) == 1 and re.match(r"pymr: error: .*" + fault, lines[0]), (fault, err)


NOT_TEXT = b"\x80\xfe\x00\x01binary\xff" * 20


@pytest.mark.parametrize("option, content, fault", [
    ("--mass", NOT_TEXT, r"bin: not a text matrix file \(Matrix Market, or Abaqus matrix output\): line 1 is not "
                         r"UTF-8 text"),
    ("--stiffness", b"%%MatrixMarket matrix coordinate real general\n30 30 1\n" + NOT_TEXT,
     r"bin: not a text matrix file \(Matrix Market, or Abaqus matrix output\): line 3 is not UTF-8 text"),
    ("--nodes", NOT_TEXT, r"bin: not a nodes file \(lines 'node id, x, y, z'\): line 1 is not UTF-8 text"),
    ("--dof-map", NOT_TEXT, r"bin: not a DOF map \(lines 'row node dof'\): line 1 is not UTF-8 text"),
    ("--mass", None, r"bin: a directory, not a file"),
], ids=["mass", "stiffness_after_its_header", "nodes", "dof_map", "mass_a_folder"])
def test_a_file_that_is_not_text_is_named_in_one_line(small, capsys, option, content, fault):
    """A binary file given for a text format printed Python's codec message ("cannot read:
    'utf-8' codec can't decode byte 0x80 ..."), and a folder as a matrix "[Errno 21] Is a
    directory"; each is one line naming the file and what it should have been."""
    tmp, k, m, nodes = small
    mp, kp, npath = write_fe(tmp, k, m, nodes)
    args = {"--mass": str(mp), "--stiffness": str(kp), "--nodes": str(npath)}
    if content is None:
        (tmp / "bin").mkdir()
    else:
        (tmp / "bin").write_bytes(content)
    args[option] = str(tmp / "bin")
    rc, err = _cli(capsys, *[a for pair in args.items() for a in pair], "--interface", "1", "-o", str(tmp / "x.modal"))
    assert rc == 1 and re.fullmatch(r"pymr: error: \S*/" + fault + "\n", err), err
    assert not (tmp / "x.modal").exists()


def test_a_count_of_modes_beyond_the_massive_dofs_basis_is_solved_dense(small):
    """The small beam has 24 interior DOFs, 20 of them with mass (no torsion mass). The
    default 10 modes asked ARPACK for a basis of 21 vectors, more than the 20 its
    shift-invert Krylov space holds: "could not build an Arnoldi factorization", exit 2, for
    a valid model. Now such a count is solved dense: the 10 lowest of all the modes."""
    tmp, k, m, nodes = small
    mp, kp, npath = write_fe(tmp, k, m, nodes)
    ten = pymr.modal_import(mp, kp, npath, [1], modes=10)
    every = pymr.modal_import(mp, kp, npath, [1], modes=None)
    np.testing.assert_allclose(ten.frequencies_hz, np.sort(every.frequencies_hz)[:10], rtol=1e-10)


def test_cli_writes_a_file_the_kernel_reads(small, capsys):
    """pymr modal-import writes format 2; a scene runs with it; a DOF map file in reversed row
    order gives the same body."""
    tmp, k, m, nodes = small
    mp, kp, npath = write_fe(tmp, k, m, nodes)
    rc = main(["modal-import", "--mass", str(mp), "--stiffness", str(kp), "--nodes", str(npath),
               "--interface", "1", "5", "--modes", "all", "-o", str(tmp / "b.modal")])
    out = capsys.readouterr().out
    assert rc == 0 and "fixed-interface" in out and "points (node ids): 1 5" in out
    text = (tmp / "b.modal").read_text()
    assert "pymr-modal 2" in text and "\ninvariants\n" in text
    perm = np.arange(30)[::-1]
    scipy.io.mmwrite(tmp / "mp.mtx", scipy.sparse.coo_matrix(m[np.ix_(perm, perm)]))
    scipy.io.mmwrite(tmp / "kp.mtx", scipy.sparse.coo_matrix(k[np.ix_(perm, perm)]))
    (tmp / "map.txt").write_text("".join(f"{r + 1} {perm[r] // 6 + 1} {perm[r] % 6 + 1}\n" for r in range(30)))
    a = pymr.modal_import(mp, kp, npath, [1, 5], modes=None)
    b = pymr.modal_import(tmp / "mp.mtx", tmp / "kp.mtx", npath, [1, 5], modes=None, dof_map=tmp / "map.txt")
    np.testing.assert_allclose(b.frequencies_hz, a.frequencies_hz, rtol=1e-10)
    np.testing.assert_allclose(b.second, a.second, atol=1e-9 * np.abs(a.second).max())


def test_nodes_or_dofs_that_are_not_the_matrices_are_warned(tmp_path, capsys):
    """A beam's matrices along x with its nodes given along y, or with one node's two
    bending rotations swapped in both matrices (a wrong DOF layout), were imported without a
    word: the first body's second moment of mass has a negative diagonal, which no body has.
    The stiffness of the right nodes holds the six rigid motions to its rounding (under 1e-12
    of |K| |r| in every row; 2e-5 with K in 5 digits); the wrong ones leave a row with nothing
    cancelled (1): one PymrWarning, and on the command line one 'pymr: warning:' line, exit 0,
    even with -q."""
    from pymr.fe_invariants import rigid_response
    k, m, nodes = beam_matrices(2.0, 2e11, 7800.0, 1e-3, 1e-7, 2e-7, 10)
    dof = np.arange(k.shape[0]).reshape(-1, 6)
    five = np.vectorize(lambda x: float(f"{x:.4e}"))(k)            # K as 5-digit fields write it
    assert 1e-6 < rigid_response(scipy.sparse.csr_matrix(five), dof, nodes[:, 1:])[0] < 1e-4
    swapped = np.arange(k.shape[0])
    swapped[[28, 29]] = swapped[[29, 28]]             # node 5's theta_y and theta_z
    along_y = nodes[:, [0, 2, 1, 3]]
    for name, (kk, mm, nn) in {"right": (k, m, nodes), "along_y": (k, m, along_y),
                               "swapped": (k[swapped][:, swapped], m[swapped][:, swapped], nodes)}.items():
        folder = tmp_path / name
        folder.mkdir()
        mp, kp, npath = write_fe(folder, kk, mm, nn)
        response = rigid_response(scipy.sparse.csr_matrix(kk), dof, nn[:, 1:])[0]
        assert response < 1e-12 if name == "right" else response == pytest.approx(1.0, abs=1e-12)
        with warnings.catch_warnings(record=True) as seen:
            warnings.simplefilter("always")
            body = pymr.modal_import(mp, kp, npath, [1], modes=4)
        doubts = [str(w.message) for w in seen if issubclass(w.category, pymr.PymrWarning)]
        assert doubts == body.warnings and len(doubts) == (name != "right"), doubts
        if name == "right":
            assert np.linalg.eigvalsh(body.second[:, :, 0, 0]).min() > -1e-9 * body.second[0, 0, 0, 0]
            continue
        assert re.fullmatch(rf"{re.escape(str(kp))}: the stiffness resists a rigid rotation about [xyz] of the nodes "
                            r"\(\|K r\| reaches 1 of \|K\| \|r\| in a row, an elastic body's is its rounding\): check "
                            r"that the nodes and the DOF layout are the matrices' \(.*\)", doubts[0]), doubts[0]
        if name == "along_y":
            assert np.diag(body.second[:, :, 0, 0]).min() < 0
        assert main(["modal-import", "--mass", str(mp), "--stiffness", str(kp), "--nodes", str(npath),
                     "--interface", "1", "-o", str(folder / "b.modal"), "-q"]) == 0
        err = capsys.readouterr().err
        assert err == f"pymr: warning: {doubts[0]}\n" and (folder / "b.modal").stat().st_size > 0
