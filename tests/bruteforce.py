"""Brute-force reference for the equations of motion ``M qdd = P`` of rigid-body scenes.

Independent of the kernel's method (spatial vectors, composite-rigid-body recursion):

* the scene is read by a small namelist parser of its own;
* every rigid body is replaced by 6 point masses m/6 at com +- d_i e_i along the principal
  axes of the second-moment matrix J = tr(I)/2 Id - I (d_i = sqrt(3 J_i / m)), which
  reproduces the body's mass, centre of mass and inertia exactly;
* the inertial position r_p(q) of every point comes from plain forward kinematics with
  rotation matrices (Rodrigues' formula), evaluated in a second-order Taylor arithmetic
  ("jets") along the path q + s qd, with complex entries;
* the Jacobians J_p = dr_p/dq come from the complex step (q + i h e_k, h = 1e-30: exact to
  rounding), the velocity-product accelerations (dJ_p/dt) qd = d^2 r_p(q + s qd)/ds^2 at
  s = 0 from the jets' second coefficient (exact, no differencing);
* then  M = sum_p m_p J_p^T J_p  and
        P = sum_p m_p J_p^T g [gravity on] + drive loads - sum_p m_p J_p^T (dJ_p/dt) qd.

Conventions (from the project's design): a body frame coincides with its parent's frame
shifted to the joint point ``at`` (parent frame) when all coordinates are zero;
revolute R = R_par Rot(u, q); prismatic p = p_par + R_par (at + u q);
spherical R = R_par Rx(q1) Ry(q2) Rz(q3); free p = p_par + R_par (at + q[1:3]),
R = R_par Rx(q4) Ry(q5) Rz(q6); fixed: no coordinates. Coordinates are ordered by bodies
in tree order, each joint's coordinates in the order above.

Flexible bodies (kind='beam'): an Euler-Bernoulli beam along the body x axis, clamped at the
body origin, cubic Hermite elements, bending in x-y (v along y, stiffness E Iz) and x-z
(w along z, stiffness E Iy), axial displacement u (stiffness E A, u(0) = 0) and torsion
theta (stiffness G J, theta(0) = 0) on the same elements (nodal values and slopes), line
mass rho A. Its modes (generalised symmetric eigenproblem per family, mass-normalised, tip
value positive) give the deformed section at x: centre x e_x + [u, v, w], small rotation
[theta, -w', v']. Without torsional modes the beam's kinetic energy is represented exactly
by point masses rho A le w_g on the axis at the 4 Gauss-Legendre points of every element
(|r_dot|^2 is a polynomial of degree 6 in x on an element). With torsional modes each of
them is split into four quarter masses at y = +-sqrt(2 Iz/A) and z = +-sqrt(2 Iy/A) of the
section, displaced by the section's rotation (Psi + Phi x r): they carry the section's
rotary inertia rho Iz, rho Iy, rho (Iy + Iz) per length, which the bending eigenproblems
then include (mass rho I int N'N'^T) and torsion's takes (inertia rho (Iy + Iz)).
Elastic forces -omega_k^2 a_k, modal damping -2 zeta omega_k a_k' when &effects
modal_damping is on. A joint on a beam parent sits on the deformed section at ``at`` and
turns with it: joint frame origin p + R (at + (Psi + Phi x r) a) (r the offset of ``at``
from the axis), orientation R expm([Phi a]x), evaluated in the jets by power series
(analytic, so complex steps stay exact). Modal coordinates follow all joint coordinates,
flexible bodies in tree order: x-y modes, x-z modes, axial modes, torsional modes.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.linalg

__all__ = ["parse_namelist", "Scene", "BeamModes", "beam_modes", "point_masses", "point_kinematics",
           "reference_terms", "reference_energy", "reference_terms_lagrange", "hermite_row",
           "gauss_points"]

# ----------------------------------------------------------------------------------------
# namelist text
# ----------------------------------------------------------------------------------------

_TOKEN = re.compile(r"""\s*(?:('(?:[^']|'')*'|"(?:[^"]|"")*")|(=)|(,)|(/)|([^\s=,/'"]+))""")


def _strip_comments(text: str) -> str:
    out, quote = [], None
    for line in text.splitlines():
        buf = []
        for c in line:
            if quote:
                if c == quote:
                    quote = None
            elif c in "'\"":
                quote = c
            elif c == "!":
                break
            buf.append(c)
        out.append("".join(buf))
    return "\n".join(out)


def _value(tok: str):
    if tok[0] in "'\"":
        return tok[1:-1].replace(tok[0] * 2, tok[0])
    low = tok.lower()
    if low in (".true.", ".t.", "t", "true"):
        return True
    if low in (".false.", ".f.", "f", "false"):
        return False
    if "*" in tok:  # repeat count r*value
        r, v = tok.split("*", 1)
        return [_value(v)] * int(r)
    return float(low.replace("d", "e"))


def parse_namelist(text: str) -> list[tuple[str, dict]]:
    """Groups of a namelist text, in file order: [(group name, {item: value or list})].
    Scalars stay scalars, several values become a list; names are lower case."""
    text = _strip_comments(text)
    groups: list[tuple[str, dict]] = []
    i = 0
    while True:
        m = re.compile(r"[&$](\w+)").search(text, i)
        if not m:
            return groups
        name, i = m.group(1).lower(), m.end()
        items: dict = {}
        key, vals, prev = None, [], None
        while True:
            t = _TOKEN.match(text, i)
            if t is None or t.end() == i:
                raise ValueError(f"&{name}: unterminated group")
            i = t.end()
            s, eq, comma, slash, word = t.groups()
            if slash:
                break
            if eq:
                # the previous word was the item's name, not a value
                if key is not None:
                    vals.pop()
                    items[key] = vals[0] if len(vals) == 1 else vals
                key, vals = prev.lower(), []
                continue
            if comma:
                continue
            tok = s or word
            prev = tok
            vals.append(tok)
        if key is not None:
            items[key] = vals[0] if len(vals) == 1 else vals
        for k, v in items.items():
            if isinstance(v, list):
                flat = []
                for x in v:
                    y = _value(x)
                    flat.extend(y if isinstance(y, list) else [y])
                items[k] = flat if len(flat) > 1 else flat[0]
            else:
                items[k] = _value(v)
        groups.append((name, items))


# ----------------------------------------------------------------------------------------
# the scene
# ----------------------------------------------------------------------------------------

NDOF = {"revolute": 1, "prismatic": 1, "fixed": 0, "spherical": 3, "free": 6}


def _vec(v, n):
    a = np.atleast_1d(np.asarray(v, dtype=float))
    if a.size != n:
        raise ValueError(f"expected {n} values, got {a.size}")
    return a


@dataclass
class Body:
    name: str
    kind: str
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    inertia: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    # beams
    length: float = 0.0
    youngs_modulus: float = 0.0
    density: float = 0.0
    area: float = 0.0
    iy: float = 0.0
    iz: float = 0.0
    n_elements: int = 20
    modes_y: int = 0
    modes_z: int = 0
    modes_x: int = 0
    modes_t: int = 0
    shear_modulus: float = 0.0
    torsion_constant: float = 0.0
    modal_damping: float = 0.0
    first_mode: int = 0  # index of the body's first modal coordinate
    _modes: "BeamModes | None" = None

    @property
    def n_modes(self) -> int:
        return self.modes_y + self.modes_z + self.modes_x + self.modes_t if self.kind == "beam" else 0

    @property
    def modes(self) -> "BeamModes":
        if self._modes is None:
            self._modes = beam_modes(self)
        return self._modes


@dataclass
class Joint:
    name: str
    kind: str
    parent: str
    child: str
    at: np.ndarray
    axis: np.ndarray
    q0: np.ndarray
    qd0: np.ndarray
    first: int = 0  # index of the joint's first coordinate

    @property
    def ndof(self) -> int:
        return NDOF[self.kind]


@dataclass
class Drive:
    joint: str
    coordinate: int
    offset: float
    amplitude: float
    frequency: float
    phase: float


@dataclass
class Scene:
    bodies: dict
    joints: list  # in tree order
    drives: list
    gravity: np.ndarray
    gravity_on: bool
    drives_on: bool
    n: int
    damping_on: bool = False
    n_joint: int = 0  # joint coordinates; modal coordinates follow

    def beams(self) -> list:
        """Flexible bodies in tree order."""
        return [self.bodies[j.child] for j in self.joints if self.bodies[j.child].kind == "beam"]

    @classmethod
    def from_file(cls, path) -> "Scene":
        return cls.from_text(Path(path).read_text())

    @classmethod
    def from_text(cls, text: str) -> "Scene":
        groups = parse_namelist(text)
        gravity, gravity_on, drives_on, damping_on = np.array([0.0, -9.81, 0.0]), False, False, False
        bodies: dict[str, Body] = {}
        joints: list[Joint] = []
        drives: list[Drive] = []
        for name, it in groups:
            if name == "scene" and "gravity" in it:
                gravity = _vec(it["gravity"], 3)
            elif name == "effects":
                gravity_on = bool(it.get("gravity", False))
                drives_on = bool(it.get("joint_drives", False))
                damping_on = bool(it.get("modal_damping", False))
            elif name == "body":
                kind = it["kind"].lower()
                b = Body(it["name"], kind)
                if kind == "rigid":
                    b.mass = float(it["mass"])
                    b.com = _vec(it.get("com", [0, 0, 0]), 3)
                    ixx, iyy, izz, ixy, ixz, iyz = _vec(it["inertia"], 6)
                    b.inertia = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
                elif kind == "beam":
                    b.length = float(it["length"])
                    b.youngs_modulus = float(it["youngs_modulus"])
                    b.density = float(it["density"])
                    if "r_outer" in it:
                        ro, ri = float(it["r_outer"]), float(it.get("r_inner", 0.0))
                        b.area = math.pi * (ro ** 2 - ri ** 2)
                        b.iy = b.iz = math.pi / 4.0 * (ro ** 4 - ri ** 4)
                        b.torsion_constant = math.pi / 2.0 * (ro ** 4 - ri ** 4)
                    else:
                        b.area, b.iy, b.iz = float(it["area"]), float(it["iy"]), float(it["iz"])
                        b.torsion_constant = float(it.get("torsion_constant", 0.0))
                    b.n_elements = int(it.get("n_elements", 20))
                    b.modes_y = int(it.get("modes_y", 0))
                    b.modes_z = int(it.get("modes_z", 0))
                    b.modes_x = int(it.get("modes_x", 0))
                    b.modes_t = int(it.get("modes_t", 0))
                    b.shear_modulus = float(it.get("shear_modulus", 0.0))
                    b.modal_damping = float(it.get("modal_damping", 0.0))
                elif kind != "ground":
                    raise ValueError(f"body kind {kind!r} not supported by the reference")
                bodies[b.name] = b
            elif name == "joint":
                kind = it["kind"].lower()
                nd = NDOF[kind]
                q0 = np.zeros(6)
                qd0 = np.zeros(6)
                if "q0" in it:
                    v = np.atleast_1d(np.asarray(it["q0"], dtype=float)); q0[:v.size] = v
                if "qd0" in it:
                    v = np.atleast_1d(np.asarray(it["qd0"], dtype=float)); qd0[:v.size] = v
                axis = _vec(it.get("axis", [0, 0, 1]), 3)
                joints.append(Joint(it["name"], kind, it["parent"], it["child"],
                                    _vec(it.get("at", [0, 0, 0]), 3), axis / np.linalg.norm(axis),
                                    q0[:nd], qd0[:nd]))
            elif name == "drive":
                drives.append(Drive(it["joint"], int(it.get("coordinate", 1)), float(it.get("offset", 0.0)),
                                    float(it.get("amplitude", 0.0)), float(it.get("frequency", 0.0)),
                                    float(it.get("phase", 0.0))))
        # tree order: parents before children, otherwise file order
        placed = {n for n, b in bodies.items() if b.kind == "ground"}
        ordered, rest = [], list(joints)
        while rest:
            for j in rest:
                if j.parent in placed:
                    ordered.append(j); placed.add(j.child); rest.remove(j)
                    break
            else:
                raise ValueError("joints do not form a tree rooted at the ground")
        n = 0
        for j in ordered:
            j.first = n
            n += j.ndof
        n_joint = n
        for j in ordered:
            b = bodies[j.child]
            if b.kind == "beam":
                b.first_mode = n
                n += b.n_modes
        return cls(bodies, ordered, drives, gravity, gravity_on, drives_on, n, damping_on, n_joint)

    def initial_state(self) -> tuple[np.ndarray, np.ndarray]:
        """Joint coordinates and rates from q0, qd0; modal coordinates and rates zero."""
        q, qd = np.zeros(self.n), np.zeros(self.n)
        for j in self.joints:
            q[j.first:j.first + j.ndof] = j.q0
            qd[j.first:j.first + j.ndof] = j.qd0
        return q, qd

    def modal_slices(self) -> list:
        """(body, slice of its modal coordinates) in tree order."""
        return [(b, slice(b.first_mode, b.first_mode + b.n_modes)) for b in self.beams()]

    def elastic_forces(self, q, qd) -> np.ndarray:
        """-omega^2 a, and -2 zeta omega a' when modal damping is on (zero on joint rows)."""
        f = np.zeros(self.n, dtype=np.result_type(np.asarray(q).dtype, float))
        for b, s in self.modal_slices():
            w2 = b.modes.omega2
            f[s] = -w2 * q[s]
            if self.damping_on:
                f[s] = f[s] - 2.0 * b.modal_damping * np.sqrt(w2) * qd[s]
        return f

    def elastic_energy(self, q) -> float:
        return float(sum(0.5 * np.sum(b.modes.omega2 * np.asarray(q)[s] ** 2) for b, s in self.modal_slices()))

    def generalised_drive_forces(self, t: float) -> np.ndarray:
        f = np.zeros(self.n)
        if not self.drives_on:
            return f
        by_name = {j.name: j for j in self.joints}
        for d in self.drives:
            j = by_name[d.joint]
            f[j.first + d.coordinate - 1] += d.offset + d.amplitude * math.sin(2 * math.pi * d.frequency * t + d.phase)
        return f


def point_masses(mass: float, com: np.ndarray, inertia: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Six point masses (masses (6,), body-frame positions (6, 3)) with the body's mass,
    centre of mass and inertia tensor about the centre of mass."""
    second = 0.5 * np.trace(inertia) * np.eye(3) - inertia  # J = sum m r r^T about the com
    lam, vec = np.linalg.eigh(second)
    if lam.min() < -1e-14 * max(1.0, abs(lam).max()):
        raise ValueError("inertia violates the triangle inequality")
    d = np.sqrt(np.maximum(lam, 0.0) * 3.0 / mass)
    pts = []
    for i in range(3):
        pts.append(com + d[i] * vec[:, i])
        pts.append(com - d[i] * vec[:, i])
    return np.full(6, mass / 6.0), np.array(pts)


# ----------------------------------------------------------------------------------------
# beams: cubic Hermite elements, clamped at x = 0, modes per family (bending planes, axial,
# torsion)
# ----------------------------------------------------------------------------------------

# Quadrature of the beams' mass points and element mass matrices: None = exact 4-point
# Gauss-Legendre rule (numpy); a pair (points, weights) on [0, 1] replaces it (diagnostics:
# e.g. the constants of another implementation, to separate their effect from others).
QUADRATURE: tuple | None = None


def gauss_points(n: int = 4) -> tuple[np.ndarray, np.ndarray]:
    """Gauss-Legendre points and weights on [0, 1] (or the override QUADRATURE)."""
    if QUADRATURE is not None:
        return np.asarray(QUADRATURE[0], dtype=float), np.asarray(QUADRATURE[1], dtype=float)
    x, w = np.polynomial.legendre.leggauss(n)
    return 0.5 * (x + 1.0), 0.5 * w


def _hermite(xi: float, le: float):
    """Hermite shape functions N(xi) (4,) and dN/dx (4,) on an element of length le."""
    n = np.array([1 - 3 * xi ** 2 + 2 * xi ** 3, le * (xi - 2 * xi ** 2 + xi ** 3),
                  3 * xi ** 2 - 2 * xi ** 3, le * (-xi ** 2 + xi ** 3)])
    dn = np.array([-6 * xi + 6 * xi ** 2, le * (1 - 4 * xi + 3 * xi ** 2),
                   6 * xi - 6 * xi ** 2, le * (-2 * xi + 3 * xi ** 2)]) / le
    return n, dn


def hermite_row(x: float, length: float, n_el: int, clamped: int = 2):
    """Rows that map the free nodal DOFs of a field clamped at x = 0 to v(x) and dv/dx(x):
    (v1, v1', ..., v_n, v_n') (2 n_el,) when value and slope are clamped (bending), with v0'
    in front (2 n_el + 1,) when only the value is (clamped = 1: axial, torsion)."""
    le = length / n_el
    e = min(int(math.floor(x / le)), n_el - 1)
    e = max(e, 0)
    xi = (x - e * le) / le
    n, dn = _hermite(xi, le)
    full_n = np.zeros(2 * (n_el + 1))
    full_d = np.zeros(2 * (n_el + 1))
    full_n[2 * e:2 * e + 4] = n
    full_d[2 * e:2 * e + 4] = dn
    return full_n[clamped:], full_d[clamped:]


def _assemble(n_el: int, ke, me, clamped: int):
    """Global K and M of n_el equal elements, the first `clamped` nodal DOFs removed."""
    nd = 2 * (n_el + 1)
    K, M = np.zeros((nd, nd)), np.zeros((nd, nd))
    for e in range(n_el):
        s = slice(2 * e, 2 * e + 4)
        K[s, s] += ke
        M[s, s] += me
    return K[clamped:, clamped:], M[clamped:, clamped:]


def _beam_matrices(length: float, n_el: int, ei: float, rho_a: float, rho_i: float = 0.0):
    """Stiffness and consistent mass of the clamped beam (2 n_el, 2 n_el); the element mass
    by Gauss quadrature of rho A N^T N (exact: degree 6), plus the section's rotary inertia
    rho I N'^T N' when rho_i is given."""
    le = length / n_el
    ke = ei / le ** 3 * np.array([[12, 6 * le, -12, 6 * le],
                                  [6 * le, 4 * le ** 2, -6 * le, 2 * le ** 2],
                                  [-12, -6 * le, 12, -6 * le],
                                  [6 * le, 2 * le ** 2, -6 * le, 4 * le ** 2]])
    xg, wg = gauss_points(4)
    me = np.zeros((4, 4))
    for x, w in zip(xg, wg):
        n, dn = _hermite(x, le)
        me += rho_a * le * w * np.outer(n, n) + rho_i * le * w * np.outer(dn, dn)
    return (*_assemble(n_el, ke, me, 2), ke, me)


def _bar_matrices(length: float, n_el: int, stiffness: float, inertia: float):
    """Stiffness int stiffness N'^T N' and mass int inertia N^T N of a bar (axial: E A, rho A)
    or shaft (torsion: G J, rho Ip) on the Hermite elements, only the value clamped at x = 0
    ((2 n_el + 1) square; Gauss, exact for both)."""
    le = length / n_el
    xg, wg = gauss_points(4)
    ke, me = np.zeros((4, 4)), np.zeros((4, 4))
    for x, w in zip(xg, wg):
        n, dn = _hermite(x, le)
        ke += stiffness * le * w * np.outer(dn, dn)
        me += inertia * le * w * np.outer(n, n)
    return (*_assemble(n_el, ke, me, 1), ke, me)


@dataclass
class BeamModes:
    length: float
    n_el: int
    omega2: np.ndarray       # (nm,) eigenvalues: x-y modes, x-z modes, axial, torsional
    vectors_y: np.ndarray    # (2 n_el, my) mass-normalised nodal mode vectors
    vectors_z: np.ndarray    # (2 n_el, mz)
    omega2_y_all: np.ndarray  # every eigenvalue of each plane
    omega2_z_all: np.ndarray
    x_points: np.ndarray     # (NP,) Gauss points along the beam
    m_points: np.ndarray     # (NP,) their masses
    psi_points: np.ndarray   # (NP, 3, nm) displacement per unit modal coordinate
    vectors_x: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # (2 n_el + 1, mx)
    vectors_t: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)))  # (2 n_el + 1, mt)
    s_points: np.ndarray | None = None  # (NP, 3) body-frame positions of the mass points

    def shapes(self, x: float, offset=(0.0, 0.0)) -> tuple[np.ndarray, np.ndarray]:
        """Psi (3, nm): displacement of the point (x, offset) of the section at x per unit
        modal coordinate; Phi (3, nm): small rotation of the section (x-y mode: about z by v';
        x-z mode: about y by -w'; torsional mode: about x by theta)."""
        hn, hd = hermite_row(x, self.length, self.n_el)
        bn, _ = hermite_row(x, self.length, self.n_el, clamped=1)
        my, mz = self.vectors_y.shape[1], self.vectors_z.shape[1]
        mx, mt = self.vectors_x.shape[1], self.vectors_t.shape[1]
        z, t = my + mz, my + mz + mx
        psi = np.zeros((3, t + mt))
        phi = np.zeros((3, t + mt))
        psi[1, :my] = hn @ self.vectors_y
        phi[2, :my] = hd @ self.vectors_y
        psi[2, my:z] = hn @ self.vectors_z
        phi[1, my:z] = -(hd @ self.vectors_z)
        if mx:
            psi[0, z:t] = bn @ self.vectors_x
        if mt:
            phi[0, t:] = bn @ self.vectors_t
        r = np.array([0.0, *offset])
        return psi + np.cross(phi, r, axis=0), phi


def _plane_modes(K, M, count):
    """All eigenvalues (ascending) and the lowest `count` mass-normalised mode vectors of
    K v = lambda M v. Solved as the flexibility problem M v = mu K v (mu = 1/lambda): the
    stiffness matrix's condition number (~ lambda_max / lambda_1, 1e8 and more) then does
    not spoil the lowest modes (relative error ~ eps instead of ~ eps lambda_max / lambda_1)."""
    mu, vec = scipy.linalg.eigh(M, K)
    mu, vec = mu[::-1], vec[:, ::-1]
    lam = 1.0 / mu
    vec = vec / np.sqrt(np.einsum("ik,ij,jk->k", vec, M, vec))  # v^T M v = 1
    vec = vec * np.where(vec[-2] < 0.0, -1.0, 1.0)                # tip displacement positive
    return lam, vec[:, :count]


def beam_modes(b: Body) -> BeamModes:
    rho_a = b.density * b.area
    ring = b.modes_t > 0   # the section's rotary inertia, by four points around each Gauss point
    ky, mmy, _, _ = _beam_matrices(b.length, b.n_elements, b.youngs_modulus * b.iz, rho_a,
                                   b.density * b.iz if ring else 0.0)
    kz, mmz, _, _ = _beam_matrices(b.length, b.n_elements, b.youngs_modulus * b.iy, rho_a,
                                   b.density * b.iy if ring else 0.0)
    lam_y, vy = _plane_modes(ky, mmy, b.modes_y)
    lam_z, vz = _plane_modes(kz, mmz, b.modes_z)
    lam_x, vx = np.zeros(0), np.zeros((2 * b.n_elements + 1, 0))
    lam_t, vt = np.zeros(0), np.zeros((2 * b.n_elements + 1, 0))
    if b.modes_x:
        lam_x, vx = _plane_modes(*_bar_matrices(b.length, b.n_elements, b.youngs_modulus * b.area, rho_a)[:2],
                                 b.modes_x)
    if ring:
        lam_t, vt = _plane_modes(*_bar_matrices(b.length, b.n_elements, b.shear_modulus * b.torsion_constant,
                                                b.density * (b.iy + b.iz))[:2], b.modes_t)
    le = b.length / b.n_elements
    xg, wg = gauss_points(4)
    xs = np.concatenate([(e + xg) * le for e in range(b.n_elements)])
    ms = np.tile(rho_a * le * wg, b.n_elements)
    offsets = np.zeros((1, 2))
    if ring:
        ry, rz = math.sqrt(2 * b.iz / b.area), math.sqrt(2 * b.iy / b.area)
        offsets = np.array([[ry, 0.0], [-ry, 0.0], [0.0, rz], [0.0, -rz]])
        xs, ms = np.repeat(xs, 4), np.repeat(ms / 4, 4)
    sp = np.zeros((xs.size, 3))
    sp[:, 0] = xs
    sp[:, 1:] = np.tile(offsets, (xs.size // len(offsets), 1))
    omega2 = np.concatenate([lam_y[:b.modes_y], lam_z[:b.modes_z], lam_x[:b.modes_x], lam_t[:b.modes_t]])
    bm = BeamModes(b.length, b.n_elements, omega2, vy, vz, lam_y, lam_z, xs, ms,
                   np.zeros((xs.size, 3, b.n_modes)), vx, vt, sp)
    for i in range(xs.size):
        bm.psi_points[i] = bm.shapes(sp[i, 0], sp[i, 1:])[0]
    return bm


# ----------------------------------------------------------------------------------------
# second-order Taylor jets: arrays with a leading axis [value, d/ds, d^2/ds^2 / 2]
# ----------------------------------------------------------------------------------------

def _jmul(a, b, op):
    return np.stack([op(a[0], b[0]),
                     op(a[0], b[1]) + op(a[1], b[0]),
                     op(a[0], b[2]) + op(a[1], b[1]) + op(a[2], b[0])])


def _mm(a, b):
    return np.matmul(a, b)


def _mv(a, b):
    return np.einsum("...ij,...j->...i", a, b)


def _jsincos(x):
    """sin and cos of a scalar jet x (3, B)."""
    s0, c0 = np.sin(x[0]), np.cos(x[0])
    s = np.stack([s0, c0 * x[1], c0 * x[2] - 0.5 * s0 * x[1] ** 2])
    c = np.stack([c0, -s0 * x[1], -s0 * x[2] - 0.5 * c0 * x[1] ** 2])
    return s, c


def _jrot(u, x):
    """Rotation by the jet angle x (3, B) about the constant unit axis u: jet (3, B, 3, 3),
    Rodrigues: cos x Id + sin x [u]x + (1 - cos x) u u^T."""
    s, c = _jsincos(x)
    kx = np.array([[0.0, -u[2], u[1]], [u[2], 0.0, -u[0]], [-u[1], u[0], 0.0]])
    uu = np.outer(u, u)
    one = np.zeros_like(c)
    one[0] = 1.0
    return (c[..., None, None] * np.eye(3) + s[..., None, None] * kx
            + (one - c)[..., None, None] * uu)


_EX, _EY, _EZ = np.eye(3)
_SERIES = 18  # terms of the power series of sin(t)/t and (1 - cos t)/t^2 in t^2 (|t| < 1.5)


def _jexp_skew(theta):
    """expm([theta]x) for a jet vector theta (3, B, 3): Id + f1(s) [theta]x + f2(s) [theta]x^2,
    s = |theta|^2, f1 = sum (-s)^k / (2k+1)!, f2 = sum (-s)^k / (2k+2)! (entire functions of s,
    so the jets and complex steps stay exact, also at theta = 0)."""
    s = _jmul(theta, theta, lambda a, b: np.sum(a * b, axis=-1))
    kx = np.zeros(theta.shape + (3,), dtype=theta.dtype)
    kx[..., 0, 1], kx[..., 0, 2] = -theta[..., 2], theta[..., 1]
    kx[..., 1, 0], kx[..., 1, 2] = theta[..., 2], -theta[..., 0]
    kx[..., 2, 0], kx[..., 2, 1] = -theta[..., 1], theta[..., 0]

    def series(c):
        f = np.zeros_like(s)
        f[0] = c[-1]
        for ck in c[-2::-1]:
            f = _jmul(f, s, lambda a, b: a * b)
            f[0] = f[0] + ck
        return f

    f1 = series([(-1) ** k / math.factorial(2 * k + 1) for k in range(_SERIES)])
    f2 = series([(-1) ** k / math.factorial(2 * k + 2) for k in range(_SERIES)])
    scal = lambda a, b: a[..., None, None] * b  # noqa: E731
    out = _jmul(f1, kx, scal) + _jmul(f2, _jmul(kx, kx, _mm), scal)
    out[0] = out[0] + np.eye(3)
    return out


def point_kinematics(scene: Scene, q: np.ndarray, qd: np.ndarray):
    """Point masses (NP,) and jets of their inertial positions (3, B, NP, 3) along q + s qd,
    for a batch of states q (B, n) (real or complex) and rates qd (n,) or (B, n)."""
    q = np.atleast_2d(q)
    B = q.shape[0]
    qd = np.broadcast_to(np.asarray(qd), q.shape)
    dtype = np.result_type(q.dtype, qd.dtype, float)

    def coord(k):
        x = np.zeros((3, B), dtype=dtype)
        x[0], x[1] = q[:, k], qd[:, k]
        return x

    def const_vec(v):
        x = np.zeros((3, B, 3), dtype=dtype)
        x[0] = v
        return x

    R = {}
    p = {}
    for name, b in scene.bodies.items():
        if b.kind == "ground":
            R[name] = np.zeros((3, B, 3, 3), dtype=dtype); R[name][0] = np.eye(3)
            p[name] = np.zeros((3, B, 3), dtype=dtype)
    def modal(b):
        return np.stack([coord(b.first_mode + i) for i in range(b.n_modes)], axis=-1)  # (3, B, nm)

    for j in scene.joints:
        Rp, pp = R[j.parent], p[j.parent]
        par = scene.bodies[j.parent]
        k = j.first
        # joint frame (before the joint's own motion): origin o, orientation Rj
        if par.kind == "beam" and par.n_modes:
            psi, phi = par.modes.shapes(j.at[0], j.at[1:])
            a = modal(par)
            o = pp + _jmul(Rp, const_vec(j.at) + np.einsum("in,kbn->kbi", psi, a), _mv)
            Rj = _jmul(Rp, _jexp_skew(np.einsum("in,kbn->kbi", phi, a)), _mm)
        else:
            o = pp + _jmul(Rp, const_vec(j.at), _mv)
            Rj = Rp
        local = None  # joint translation in the joint frame
        Rrel = None
        if j.kind == "revolute":
            Rrel = _jrot(j.axis, coord(k))
        elif j.kind == "prismatic":
            local = coord(k)[..., None] * j.axis
        elif j.kind == "spherical":
            Rrel = _jmul(_jmul(_jrot(_EX, coord(k)), _jrot(_EY, coord(k + 1)), _mm), _jrot(_EZ, coord(k + 2)), _mm)
        elif j.kind == "free":
            local = np.stack([coord(k), coord(k + 1), coord(k + 2)], axis=-1)
            Rrel = _jmul(_jmul(_jrot(_EX, coord(k + 3)), _jrot(_EY, coord(k + 4)), _mm), _jrot(_EZ, coord(k + 5)), _mm)
        elif j.kind != "fixed":
            raise ValueError(j.kind)
        p[j.child] = o if local is None else o + _jmul(Rj, local, _mv)
        R[j.child] = Rj if Rrel is None else _jmul(Rj, Rrel, _mm)
    masses, positions = [], []
    for j in scene.joints:
        b = scene.bodies[j.child]
        if b.kind == "rigid":
            m, x = point_masses(b.mass, b.com, b.inertia)
            masses.append(m)
            # r = p + R x for the 6 points: (3, B, 6, 3)
            positions.append(p[j.child][:, :, None, :] + np.einsum("kbij,pj->kbpi", R[j.child], x))
        elif b.kind == "beam":
            bm = b.modes
            # body-frame positions of the Gauss points on the deformed axis: (3, B, NP, 3)
            x = np.zeros((3, B, bm.x_points.size, 3), dtype=dtype)
            x[0] = bm.s_points
            if b.n_modes:
                x = x + np.einsum("pin,kbn->kbpi", bm.psi_points, modal(b))
            masses.append(bm.m_points)
            positions.append(p[j.child][:, :, None, :] + _jmul(R[j.child], x, lambda a, c: np.einsum("bij,bpj->bpi", a, c)))
    return np.concatenate(masses), np.concatenate(positions, axis=2)


def _jacobians(scene: Scene, q, qd, h=1e-30):
    """Masses (NP,), positions (NP, 3), velocities (NP, 3), Jacobians (NP, 3, n) and
    velocity-product accelerations (NP, 3) at (q, qd)."""
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    n = scene.n
    qc = np.tile(q.astype(complex), (n, 1)) + 1j * h * np.eye(n)
    m, r = point_kinematics(scene, qc, qd)
    jac = np.moveaxis(r[0].imag / h, 0, -1)  # (NP, 3, n)
    pos = r[0, 0].real
    vel = r[1, 0].real
    acc = 2.0 * r[2, 0].real
    return m, pos, vel, jac, acc


def reference_terms(scene: Scene, q, qd, t: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Mass matrix M (n, n) and right-hand side P (n,) of M qdd = P by brute force."""
    m, pos, vel, jac, acc = _jacobians(scene, q, qd)
    M = np.einsum("p,pik,pil->kl", m, jac, jac)
    P = -np.einsum("p,pik,pi->k", m, jac, acc)
    if scene.gravity_on:
        P = P + np.einsum("p,pik,i->k", m, jac, scene.gravity)
    P = P + scene.generalised_drive_forces(t) + scene.elastic_forces(q, qd)
    return M, P


def reference_energy(scene: Scene, q, qd) -> tuple[float, float]:
    """Kinetic energy sum m |v|^2 / 2 and potential: elastic 1/2 sum omega^2 a^2 plus, with
    gravity on, -sum m g.r (zero at the inertial origin)."""
    m, r = point_kinematics(scene, np.asarray(q, dtype=float), np.asarray(qd, dtype=float))
    vel = r[1, 0]
    ke = 0.5 * float(np.einsum("p,pi,pi->", m, vel, vel))
    pe = -float(np.einsum("p,pi,i->", m, r[0, 0], scene.gravity)) if scene.gravity_on else 0.0
    return ke, pe + scene.elastic_energy(q)


# ----------------------------------------------------------------------------------------
# a second route to the same terms (Lagrange), to check the reference against itself
# ----------------------------------------------------------------------------------------

def _mass_matrices(scene: Scene, qs: np.ndarray) -> np.ndarray:
    """M(q) (S, n, n) for states qs (S, n), real or complex, from the jets' velocity
    coefficient with unit rates (J_p e_k = dr_p/ds along q + s e_k): no complex step inside,
    so M is a complex-analytic function of q."""
    n = scene.n
    S = qs.shape[0]
    qb = np.repeat(qs, n, axis=0)                    # (S n, n)
    qdb = np.tile(np.eye(n), (S, 1))                 # unit rates
    m, r = point_kinematics(scene, qb, qdb)
    jac = r[1].reshape(S, n, -1, 3)                  # [state, k, point, xyz]
    return np.einsum("p,skpi,slpi->skl", m, jac, jac)


def reference_terms_lagrange(scene: Scene, q, qd, t: float = 0.0, h: float = 1e-30):
    """M and P from Lagrange's equations: P_k = Q_k - (dM/dt qd)_k + qd^T (dM/dq_k) qd / 2,
    with dM/dt = dM/dq . qd and dM/dq_k by complex steps of M(q), gravity forces as -dV/dq
    of V = -sum m g.r by complex steps of the positions."""
    q = np.asarray(q, dtype=float)
    qd = np.asarray(qd, dtype=float)
    n = scene.n
    qs = np.vstack([q + 1j * h * qd, q + 1j * h * np.eye(n)]).astype(complex)
    Ms = _mass_matrices(scene, qs)
    M = Ms[0].real
    mdot_qd = (Ms[0].imag / h) @ qd
    dmdq = Ms[1:].imag / h                           # [k, i, j]
    P = -mdot_qd + 0.5 * np.einsum("i,kij,j->k", qd, dmdq, qd)
    if scene.gravity_on:
        m, r = point_kinematics(scene, qs[1:], np.zeros(n))
        V = -np.einsum("p,spi,i->s", m, r[0], scene.gravity)
        P = P - V.imag / h
    # elastic forces as -dV/da of V = 1/2 sum omega^2 a^2 (complex steps), damping as given
    Ve = np.array([sum(0.5 * np.sum(b.modes.omega2 * qs[1 + k][s] ** 2) for b, s in scene.modal_slices())
                   for k in range(n)], dtype=complex)
    P = P - Ve.imag / h
    if scene.damping_on:
        for b, s in scene.modal_slices():
            P[s] -= 2.0 * b.modal_damping * np.sqrt(b.modes.omega2) * qd[s]
    P = P + scene.generalised_drive_forces(t)
    return M, P


def check_energy_and_accelerations(path, sc, states, rtol, t=0.45):
    """Assert that the kernel's kinetic energy, potential-energy differences and
    accelerations (as the residual |M_ref qdd - P_ref| / (|M||qdd| + |P|)) agree with
    the reference at the given states, to ``rtol``."""
    import pymr
    qs = np.array([s[0] for s in states])
    qds = np.array([s[1] for s in states])
    ke, pe = pymr.model_energy(path, qs, qds)
    ref = np.array([reference_energy(sc, q, qd) for q, qd in states])
    np.testing.assert_allclose(ke, ref[:, 0], rtol=rtol, atol=rtol * ref[:, 0].max())
    scale = np.abs(ref[:, 1]).max() + 1.0
    np.testing.assert_allclose(pe - pe[0], ref[:, 1] - ref[0, 1], rtol=0, atol=rtol * scale)
    qdd = pymr.model_accelerations(path, np.full(len(states), t), qs, qds)
    for (q, qd), a in zip(states, qdd):
        mr, pr = reference_terms(sc, q, qd, t)
        res = np.abs(mr @ a - pr).max() / (np.abs(mr).max() * np.abs(a).max() + np.abs(pr).max())
        assert res < rtol
