"""``pymr modal-import``: a ``kind='modal'`` body from finite-element matrices.

Input: the mass and stiffness matrices (Matrix Market, as FE codes export them), the node
coordinates (``id, x, y, z`` per line) and the DOF layout (``dofs_per_node`` 3 or 6, rows
node by node in the nodes file's order, or a DOF map file of ``row node dof`` lines, dof 1-6
= u_x u_y u_z theta_x theta_y theta_z). The interface nodes are where joints, markers and
loads attach; the first is the body frame's origin, where the body is clamped to its joint
(with the ``clamp`` nodes, for meshes whose nodes carry no rotations).

Craig-Bampton reduction: the lowest ``modes`` normal modes with every interface node held
(fixed-interface modes) and the static constraint modes of the interface DOFs that are not
clamped. The clamped DOFs' constraint modes would be the rigid-body motions the floating
frame carries: they are left out. The reduced eigenproblem (K_r, M_r) makes the basis
orthogonal: the modes written are mass-normalised, with their frequencies (the lowest
``keep`` of them).

The inertia invariants go into the file's invariants block (format 2), computed from the
matrices (see :func:`inertia_invariants` for what is exact), and the points are the
interface nodes with their mode shapes at zero mass.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import _kernel as _core
from .api import SceneError, write_file
from .outputs import check_output

#: names of the six DOFs of a node, in the order of dofs_per_node 6 and DOF map numbers 1-6
DOF_NAMES = ("u_x", "u_y", "u_z", "theta_x", "theta_y", "theta_z")


class ImportInputError(SceneError):
    """Bad input of ``pymr modal-import``: one line naming the file and the fault."""


@dataclass
class ModalBody:
    """An imported body: its modes over the full FE DOFs and what the modal file holds."""
    frequencies_hz: np.ndarray            # (m,)
    shapes: np.ndarray                    # (ndof, m) mass-normalised modes, zero on the clamped DOFs
    mass: float
    first: np.ndarray                     # F(3, 0:m)
    second: np.ndarray                    # W(3, 3, 0:m, 0:m)
    point_ids: list                       # node ids of the points (interface and clamped nodes)
    points: np.ndarray                    # (P, 3) body-frame positions
    psi: np.ndarray                       # (P, 3, m)
    phi: np.ndarray                       # (P, 3, m)
    origin: np.ndarray                    # the origin node's mesh coordinates
    exact: str = ""                       # what the invariants' structure allowed (see inertia_invariants)
    kept: dict = field(default_factory=dict)   # counts: fixed-interface modes, constraint modes, reduced size


# ----------------------------------------------------------------------------- input files

def _lines(path: Path, comment: str):
    """(line number, stripped text) of the file's lines that are not blank or comments."""
    try:
        text = path.read_text()
    except FileNotFoundError:
        raise ImportInputError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ImportInputError(f"{path}: cannot read: {exc}") from None
    for k, line in enumerate(text.splitlines(), 1):
        s = line.strip()
        if s and not s.startswith(comment):
            yield k, s


def read_matrix_market(path: str | os.PathLike, rows: tuple[int, str] | None = None) -> np.ndarray:
    """A real Matrix Market matrix (coordinate or array; general or symmetric) as a dense array.
    `rows`: (count, why) when the caller knows how many rows the matrix must have (`why` says
    from what, for the message). The size line is checked against it, and against the
    entries the file holds, before the dense array is allocated (a size line of 1e9 asked
    numpy for exabytes)."""
    path = Path(path)
    try:
        with open(path) as fh:
            header = fh.readline().split()
    except FileNotFoundError:
        raise ImportInputError(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ImportInputError(f"{path}: cannot read: {exc}") from None
    if len(header) != 5 or header[0].lower() != "%%matrixmarket" or header[1].lower() != "matrix":
        raise ImportInputError(f"{path}: line 1: not a Matrix Market matrix (expected '%%MatrixMarket matrix ...')")
    form, kind, sym = (h.lower() for h in header[2:])
    if form not in ("coordinate", "array") or kind not in ("real", "integer", "double") \
            or sym not in ("general", "symmetric"):
        raise ImportInputError(f"{path}: line 1: {' '.join(header[2:])}: only real coordinate or array matrices, "
                               "general or symmetric, are read")
    lines = list(_lines(path, "%"))
    if not lines:
        raise ImportInputError(f"{path}: no size line")
    k, size = lines[0]
    try:
        dims = [int(v) for v in size.split()]
    except ValueError:
        dims = []
    if len(dims) != (3 if form == "coordinate" else 2) or min(dims) < 0:
        raise ImportInputError(f"{path}: line {k}: expected the size line ("
                               f"{'rows columns entries' if form == 'coordinate' else 'rows columns'})")
    nr, nc = dims[:2]
    if nr != nc:
        raise ImportInputError(f"{path}: {nr} x {nc}: a square matrix expected")
    if rows is not None and nr != rows[0]:
        raise ImportInputError(f"{path}: line {k}: {nr} rows, but {rows[1]}")
    body = lines[1:]
    count = (nr * nc if sym == "general" else nr * (nr + 1) // 2) if form == "array" else dims[2]
    if len(body) != count:
        what = "values" if form == "array" else "entries"
        raise ImportInputError(f"{path}: line {k}: the size line gives {count} {what} ({nr} x {nc}, {sym}), "
                               f"the file holds {len(body)}")
    try:
        a = np.zeros((nr, nc))
    except MemoryError:
        raise ImportInputError(f"{path}: line {k}: {nr} x {nc}: too large for this machine's memory as a dense "
                               f"matrix ({8 * nr * nc / 1e9:.3g} GB)") from None
    if form == "array":
        values = [_number(path, k, s) for k, s in body]
        if sym == "general":
            a[:, :] = np.asarray(values).reshape(nc, nr).T
        else:
            il, jl = np.tril_indices(nr)
            order = np.lexsort((il, jl))           # column by column, each from the diagonal down
            a[il[order], jl[order]] = values
            a = np.tril(a) + np.tril(a, -1).T
        return a
    for k, s in body:
        parts = s.split()
        try:
            i, j, v = int(parts[0]), int(parts[1]), float(parts[2])
            if len(parts) != 3:
                raise ValueError
        except (ValueError, IndexError):
            raise ImportInputError(f"{path}: line {k}: expected 'row column value'") from None
        if not (1 <= i <= nr and 1 <= j <= nc):
            raise ImportInputError(f"{path}: line {k}: entry ({i}, {j}) outside the {nr} x {nc} matrix")
        if not np.isfinite(v):
            raise ImportInputError(f"{path}: line {k}: entry ({i}, {j}) is not finite")
        if sym == "symmetric":
            if i < j:
                raise ImportInputError(f"{path}: line {k}: entry ({i}, {j}) above the diagonal of a symmetric matrix")
            if i != j:
                a[j - 1, i - 1] += v
        a[i - 1, j - 1] += v
    return a


def _number(path: Path, k: int, s: str) -> float:
    try:
        v = float(s)
    except ValueError:
        raise ImportInputError(f"{path}: line {k}: expected a number, got {s!r}") from None
    if not np.isfinite(v):
        raise ImportInputError(f"{path}: line {k}: {s} is not finite")
    return v


def read_nodes(path: str | os.PathLike) -> tuple[list[int], np.ndarray]:
    """Node ids and coordinates (N, 3) from lines 'id, x, y, z' (commas or blanks; '#'
    comments; a first line of words is a header)."""
    path = Path(path)
    ids, xyz = [], []
    for n, (k, s) in enumerate(_lines(path, "#")):
        parts = s.replace(",", " ").split()
        try:
            if len(parts) != 4:
                raise ValueError
            nid, x = int(parts[0]), [float(v) for v in parts[1:]]
        except ValueError:
            if n == 0 and not any(c.isdigit() for c in parts[0]):
                continue                            # a header line
            raise ImportInputError(f"{path}: line {k}: expected 'node id, x, y, z'") from None
        if not np.all(np.isfinite(x)):
            raise ImportInputError(f"{path}: line {k}: node {nid}: coordinates not finite")
        ids.append(nid)
        xyz.append(x)
    if not ids:
        raise ImportInputError(f"{path}: no nodes")
    seen = set()
    for nid in ids:
        if nid in seen:
            raise ImportInputError(f"{path}: node {nid} is given twice")
        seen.add(nid)
    return ids, np.asarray(xyz, dtype=float)


def dof_layout(ids: list[int], ndof: int, matrix_path: Path, nodes_path: Path, dofs_per_node: int | None = None,
               dof_map: str | os.PathLike | None = None) -> np.ndarray:
    """Row of each node's DOF: an int array (nodes, 6), -1 where the node has no such DOF.
    Each node has the three translations, and either no rotation or all three."""
    dof = -np.ones((len(ids), 6), dtype=int)
    if dof_map is None:
        if dofs_per_node not in (3, 6):
            raise ImportInputError(f"--dofs-per-node {dofs_per_node}: 3 or 6")
        if ndof != dofs_per_node * len(ids):
            raise ImportInputError(f"{matrix_path}: {ndof} rows, but {nodes_path} has {len(ids)} nodes x "
                                   f"{dofs_per_node} DOFs = {dofs_per_node * len(ids)}")
        dof[:, :dofs_per_node] = np.arange(ndof).reshape(len(ids), dofs_per_node)
        return dof
    path = Path(dof_map)
    index = {nid: k for k, nid in enumerate(ids)}
    seen = np.zeros(ndof, dtype=bool)
    for k, s in _lines(path, "#"):
        try:
            row, nid, c = (int(v) for v in s.replace(",", " ").split())
        except ValueError:
            raise ImportInputError(f"{path}: line {k}: expected 'row node dof' (dof 1-6)") from None
        if not 1 <= row <= ndof:
            raise ImportInputError(f"{path}: line {k}: row {row} outside the matrices' {ndof} rows")
        if nid not in index:
            raise ImportInputError(f"{path}: line {k}: node {nid} is not in {nodes_path}")
        if not 1 <= c <= 6:
            raise ImportInputError(f"{path}: line {k}: dof {c}: 1-6 (u_x u_y u_z theta_x theta_y theta_z)")
        if seen[row - 1] or dof[index[nid], c - 1] >= 0:
            raise ImportInputError(f"{path}: line {k}: row {row} or node {nid} {DOF_NAMES[c - 1]} mapped twice")
        seen[row - 1] = True
        dof[index[nid], c - 1] = row - 1
    if not seen.all():
        raise ImportInputError(f"{path}: row {int(np.argmin(seen)) + 1} of the matrices is not mapped")
    for n, nid in enumerate(ids):
        has = dof[n] >= 0
        if has.any() and not (has[:3].all() and (has[3:].all() or not has[3:].any())):
            raise ImportInputError(f"{path}: node {nid}: give its three translations and none or all three rotations")
    return dof


# ----------------------------------------------------------------------------- linear algebra

def check_symmetric(a: np.ndarray, path: Path) -> None:
    """The matrix equals its transpose to 1e-10 of its largest entry."""
    d = np.abs(a - a.T)
    scale = np.abs(a).max()
    if not scale > 0:
        raise ImportInputError(f"{path}: the matrix is zero")
    if d.max() > 1e-10 * scale:
        i, j = np.unravel_index(np.argmax(d), d.shape)
        raise ImportInputError(f"{path}: not symmetric (entries ({i + 1}, {j + 1}) and ({j + 1}, {i + 1}) differ "
                               f"by {d[i, j]:.3g}, the largest entry is {scale:.3g})")


def flexibility_modes(k: np.ndarray, m: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Eigenpairs of K v = lambda M v in the flexibility form M v = mu K v (K positive
    definite, M semi-definite: a massless DOF has mu = 0): mu descending (lowest frequency
    first) and v with v^T K v = 1. `what` names K for the message when it is not positive
    definite."""
    try:
        low = np.linalg.cholesky(k)
    except np.linalg.LinAlgError:
        raise ImportInputError(what) from None
    x = np.linalg.solve(low, m)
    c = np.linalg.solve(low, x.T)             # L^-1 M L^-T (symmetric)
    mu, y = np.linalg.eigh(0.5 * (c + c.T))
    v = np.linalg.solve(low.T, y)
    return mu[::-1], v[:, ::-1]


def signed(v: np.ndarray) -> np.ndarray:
    """Each column signed so that its largest component is positive."""
    big = v[np.argmax(np.abs(v), axis=0), np.arange(v.shape[1])]
    return v * np.where(big < 0, -1.0, 1.0)


# ----------------------------------------------------------------------------- inertia invariants

def rigid_modes(dof: np.ndarray, s: np.ndarray, ndof: int) -> np.ndarray:
    """Rigid-body motions (ndof, 6): translations along x, y, z, then small rotations about
    the body axes through the origin (u = theta x s at a node, its rotations theta)."""
    r = np.zeros((ndof, 6))
    for c in range(3):
        e = np.eye(3)[c]
        r[dof[:, c], c] = 1.0
        rot = np.cross(e, s)                   # (nodes, 3)
        for i in range(3):
            r[dof[:, i], 3 + c] = rot[:, i]
        has = dof[:, 3 + c] >= 0
        r[dof[has, 3 + c], 3 + c] = 1.0
    return r


def direction_groups(m: np.ndarray, dof: np.ndarray, ids: list, path: Path) -> np.ndarray:
    """Group of each DOF: 0-2 the translation direction it carries (translations, and the
    rotations the mass matrix couples with translations of that one direction), 3-5 a
    rotation the mass matrix couples with no translation (its axis, e.g. torsion). The mass
    matrix must be block-diagonal by group; else the message says which rows break it."""
    ndof = m.shape[0]
    group = np.full(ndof, -1)
    for c in range(3):
        group[dof[:, c]] = c
    tol = 1e-12 * np.abs(m).max()
    trans = [dof[:, c] for c in range(3)]
    where = {int(dof[n, c]): (ids[n], DOF_NAMES[c]) for n in range(len(ids)) for c in range(6) if dof[n, c] >= 0}
    for n in range(len(ids)):
        for c in range(3, 6):
            d = dof[n, c]
            if d < 0:
                continue
            coupled = [i for i in range(3) if np.abs(m[d, trans[i]]).max() > tol]
            if len(coupled) > 1:
                raise ImportInputError(f"{path}: node {ids[n]} {DOF_NAMES[c]} is coupled with translations along "
                                       f"{' and '.join('xyz'[i] for i in coupled)}: the invariants need a mass matrix "
                                       "block-diagonal by direction (solids Ms (x) I3; beams along and plates in "
                                       "the body axes)")
            group[d] = coupled[0] if coupled else c
    cross = np.abs(m) * (group[:, None] != group[None, :])
    if cross.max() > tol:
        i, j = np.unravel_index(np.argmax(cross), cross.shape)
        raise ImportInputError(f"{path}: rows {i + 1} and {j + 1} (node {where[i][0]} {where[i][1]}, node "
                               f"{where[j][0]} {where[j][1]}) couple different directions: the invariants need a "
                               "mass matrix block-diagonal by direction (solids Ms (x) I3; beams along and plates "
                               "in the body axes)")
    return group


def transport(m: np.ndarray, dof: np.ndarray, group: np.ndarray, i: int, j: int):
    """Signed node-by-node map from the DOFs of direction i to those of direction j, with
    S M_ii S^T = M_jj: the two directions' fields are interpolated alike and the cross
    integrals int rho f_i g_j follow from M. As (source rows, target rows, signs), or None
    when there is no such map (other DOFs, or other mass blocks: a beam's axial and bending
    directions)."""
    src, dst, sign = list(dof[:, i]), list(dof[:, j]), [1.0] * dof.shape[0]
    for n in range(dof.shape[0]):
        ri = [d for d in dof[n, 3:] if d >= 0 and group[d] == i]
        rj = [d for d in dof[n, 3:] if d >= 0 and group[d] == j]
        if len(ri) != len(rj) or len(ri) > 1:
            return None
        if ri:
            # the sign that carries the rotation's coupling with its direction's translations
            col_i, col_j = m[dof[:, i], ri[0]], m[dof[:, j], rj[0]]
            p = int(np.argmax(np.abs(col_i)))
            src.append(ri[0])
            dst.append(rj[0])
            sign.append(-1.0 if col_i[p] * col_j[p] < 0 else 1.0)
    src, dst, sign = np.array(src), np.array(dst), np.array(sign)
    if len(src) != np.count_nonzero(group == i) or len(dst) != np.count_nonzero(group == j):
        return None
    if np.abs(m[np.ix_(src, src)] * np.outer(sign, sign) - m[np.ix_(dst, dst)]).max() > 1e-10 * np.abs(m).max():
        return None
    return src, dst, sign


def carried(z: np.ndarray, move) -> np.ndarray:
    """Fields z (ndof, ...) of one direction moved onto another's DOFs by a transport map."""
    src, dst, sign = move
    out = np.zeros_like(z)
    out[dst] = sign.reshape((-1,) + (1,) * (z.ndim - 1)) * z[src]
    return out


def rigid_moments(m: np.ndarray, r: np.ndarray, u: np.ndarray, path: Path):
    """What the rigid motions r give exactly: the mass, the first moments F(3, 0:nm), W(0,0)
    = tr(J0)/2 I - J0 from the inertia tensor J0 about the origin, and the angular couplings
    int rho s x psi_k (3, nm)."""
    mr = r.T @ m
    tt = mr[:3] @ r[:, :3]
    mass = np.trace(tt) / 3.0
    if not mass > 0 or np.abs(tt - mass * np.eye(3)).max() > 1e-8 * mass:
        raise ImportInputError(f"{path}: a rigid translation of the mesh has the masses "
                               f"{np.diag(tt).round(12).tolist()} along x, y, z (off-diagonal "
                               f"{np.abs(tt - np.diag(np.diag(tt))).max():.3g}): not this mesh's mass matrix, or "
                               "another DOF layout")
    a = mr[:3] @ r[:, 3:]                      # a_ij = int rho e_i . (e_j x s) = eps_ijk S_k
    first = np.zeros((3, u.shape[1] + 1))
    first[:, 0] = 0.5 * np.array([a[1, 2] - a[2, 1], a[2, 0] - a[0, 2], a[0, 1] - a[1, 0]])
    first[:, 1:] = mr[:3] @ u
    j0 = mr[3:] @ r[:, 3:]
    j0 = 0.5 * (j0 + j0.T)
    return mass, first, 0.5 * np.trace(j0) * np.eye(3) - j0, mr[3:] @ u


def position_mode_moments(m, dof, s, r, part, u, cr) -> np.ndarray:
    """W(i, j, 0, k) = int rho s_i psi_k,j (3, 3, nm): s_i carried by direction j's DOFs
    (along i itself its nodal values with rotations 0; along j != i the j-part of the rigid
    rotation about the third axis) against M psi_k, with the antisymmetric part set to the
    exact angular couplings cr."""
    mu = m @ u
    w = np.zeros((3, 3, u.shape[1]))
    for i in range(3):
        for j in range(3):
            zij = np.zeros(m.shape[0])
            if i == j:
                zij[dof[:, i]] = s[:, i]
            else:
                c = 3 - i - j
                zij = np.cross(np.eye(3)[c], np.eye(3)[i])[j] * r[:, 3 + c] * part[j]
            w[i, j] = zij @ (part[j][:, None] * mu)
    half = 0.5 * cr
    skew = np.array([[np.zeros_like(half[0]), half[2], -half[1]], [-half[2], np.zeros_like(half[0]), half[0]],
                     [half[1], -half[0], np.zeros_like(half[0])]])
    return 0.5 * (w + w.transpose(1, 0, 2)) + skew


def mode_moments(m, group, part, maps, u) -> np.ndarray:
    """W(i, j, k, l) = int rho psi_k,i psi_l,j (3, 3, nm, nm): each direction's block, the
    transported pairs, and the rotary inertia of rotations coupled with no translation."""
    nm = u.shape[1]
    w = np.zeros((3, 3, nm, nm))
    for i in range(3):
        zi = part[i][:, None] * u
        for j in range(3):
            if i == j:
                w[i, i] = zi.T @ m @ zi
            elif maps[(i, j)] is not None:
                w[i, j] = carried(zi, maps[(i, j)]).T @ m @ (part[j][:, None] * u)
    for c in range(3):
        rot = np.where(group == 3 + c, 1.0, 0.0)[:, None] * u
        if rot.any():
            e = np.eye(3)[c]
            w += 0.5 * (np.eye(3) - np.outer(e, e))[:, :, None, None] * (rot.T @ m @ rot)[None, None]
    return w


def inertia_invariants(m: np.ndarray, dof: np.ndarray, s: np.ndarray, u: np.ndarray, ids: list, path: Path):
    """Mass, first moments F(3, 0:nm) and second moments W(3, 3, 0:nm, 0:nm) of the body whose
    consistent mass matrix is m, nodes at s (body frame), modes u (ndof, nm).

    Exact for any mesh whose elements reproduce rigid motions (the rigid modes R):
    the mass and first moment of the body, its inertia tensor J0 = R_rot^T M R_rot (so
    W(0,0) = tr(J0)/2 I - J0), the modal first moments F_k = R_trans^T M u_k and angular
    couplings int rho s x psi_k = R_rot^T M u_k (W(0,k)'s antisymmetric part).

    The rest needs the components: Z^(i), the part of a field carried by the DOFs of
    direction i (its translations u_i and the rotations coupled with them: a beam's theta_z
    with u_y), gives int rho f_i g_i = Z_f^(i)T M Z_g^(i), exact for block-diagonal M.
    Across directions, int rho f_i g_j = (S Z_f^(i))^T M Z_g^(j) where a signed node-by-node
    map S carries direction i's mass block onto j's (solids M = Ms (x) I3: all pairs; beams
    along x: y and z): exact. The position's component s_i as a field of direction j is the
    j-part of a rigid rotation, so W(0,k) is exact in every direction pair. Without such a
    map (a beam's axial and bending components) int rho psi_k,i psi_l,j is left 0: only the
    second-order deformation inertia (deformation_inertia 'full') of modes of both kinds
    misses it. Rotations coupled with no translation (torsion, drilling) add their rotary
    inertia theta_k^T M theta_l as a section symmetric about the axis does:
    (I - e e^T)/2 in W(k,l), which keeps the modal mass exact.
    """
    ndof, nm = u.shape
    group = direction_groups(m, dof, ids, path)
    r = rigid_modes(dof, s, ndof)
    mass, first, w00, cr = rigid_moments(m, r, u, path)
    part = [np.where(group == i, 1.0, 0.0) for i in range(3)]
    maps = {(i, j): transport(m, dof, group, i, j) for i in range(3) for j in range(3) if i != j}
    w = np.zeros((3, 3, nm + 1, nm + 1))
    w[:, :, 0, 0] = w00
    w[:, :, 0, 1:] = position_mode_moments(m, dof, s, r, part, u, cr)
    w[:, :, 1:, 0] = w[:, :, 0, 1:].transpose(1, 0, 2)
    w[:, :, 1:, 1:] = mode_moments(m, group, part, maps, u)
    # pairs of directions without a transport that the modes both move in
    moves = [np.abs(part[i][:, None] * u).max() > 1e-9 * np.abs(u).max() for i in range(3)]
    missing = [f"{'xyz'[i]}-{'xyz'[j]}" for (i, j), sm in maps.items() if sm is None and i < j and moves[i] and moves[j]]
    exact = "exact" if not missing else \
        f"exact except int rho psi_i psi_j across {', '.join(missing)} (not in the mass matrix: set 0)"
    return mass, first, w, exact


# ----------------------------------------------------------------------------- the reduction

def craig_bampton(k: np.ndarray, m: np.ndarray, clamped: np.ndarray, boundary: np.ndarray, modes: int | None,
                  keep: int | None, kpath: Path, attach: str):
    """Craig-Bampton reduction with the `clamped` DOFs fixed (the body frame's attachment) and
    the `boundary` DOFs (other interface nodes) kept as static constraint modes; `modes`
    fixed-interface modes (None: all with mass). Returns the frequencies (Hz), the modes over
    all DOFs (mass-normalised, lowest `keep`, or all) and the counts kept."""
    ndof = k.shape[0]
    free = np.setdiff1d(np.arange(ndof), clamped)
    inner = np.setdiff1d(free, boundary)
    kii = k[np.ix_(inner, inner)]
    mu, v = flexibility_modes(kii, m[np.ix_(inner, inner)],
                              f"{kpath}: not positive definite with every interface node held ({attach}): "
                              "a mechanism or rigid motion of the inner nodes is left free") \
        if len(inner) else (np.zeros(0), np.zeros((0, 0)))
    with_mass = int(np.count_nonzero(mu > 1e-13 * (mu[0] if len(mu) else 0.0)))
    nf = with_mass if modes is None else modes
    if nf > with_mass:
        raise ImportInputError(f"--modes {modes}: the inner DOFs have only {with_mass} modes with mass")
    if nf + len(boundary) == 0:
        raise ImportInputError(f"--modes {modes}: the body would have no mode (no interface node besides the origin "
                               "gives a constraint mode): ask for 1 or more")
    phi_i = v[:, :nf] / np.sqrt(mu[:nf])
    psi_c = -np.linalg.solve(kii, k[np.ix_(inner, boundary)]) if len(inner) else np.zeros((0, len(boundary)))
    # basis over the free DOFs (inner first, then boundary)
    order = np.concatenate([inner, boundary])
    t = np.zeros((len(order), nf + len(boundary)))
    t[:len(inner), :nf] = phi_i
    t[:len(inner), nf:] = psi_c
    t[len(inner):, nf:] = np.eye(len(boundary))
    kr = t.T @ k[np.ix_(order, order)] @ t
    mr = t.T @ m[np.ix_(order, order)] @ t
    mur, x = flexibility_modes(0.5 * (kr + kr.T), 0.5 * (mr + mr.T),
                               f"{kpath}: not positive definite with the attachment clamped ({attach}): a "
                               "mechanism or rigid motion is left free")
    nr = int(np.count_nonzero(mur > 1e-13 * mur[0])) if len(mur) else 0
    if keep is not None:
        if keep > nr:
            raise ImportInputError(f"--keep {keep}: the reduced body has only {nr} modes with mass")
        nr = keep
    if nr == 0:
        raise ImportInputError(f"{kpath}: the reduced body has no mode with mass")
    full = np.zeros((ndof, nr))
    full[order] = t @ (x[:, :nr] / np.sqrt(mur[:nr]))
    full = signed(full)
    lam = 1.0 / mur[:nr]
    counts = {"fixed_interface_modes": nf, "constraint_modes": len(boundary), "reduced_size": nf + len(boundary),
              "modes_written": nr}
    return np.sqrt(lam) / (2 * np.pi), full, counts


def modal_import(mass: str | os.PathLike, stiffness: str | os.PathLike, nodes: str | os.PathLike,
                 interface, output: str | os.PathLike | None = None, *, dofs_per_node: int | None = 6,
                 dof_map: str | os.PathLike | None = None, modes: int | None = 10, keep: int | None = None,
                 clamp=(), title: str = "") -> ModalBody:
    """Import a finite-element body: Matrix Market `mass` and `stiffness`, `nodes` (id, x, y,
    z), the DOF layout (`dofs_per_node` 3 or 6, rows node by node in the nodes file's order,
    or a `dof_map` file of 'row node dof'), the `interface` node ids (the first is the body
    frame's origin, clamped to its joint; `clamp`: more nodes clamped with it, for meshes
    without rotations), `modes` fixed-interface modes (None: all) and the lowest `keep`
    modes of the reduced body written (None: all). Writes the modal file to `output` when
    given and returns the :class:`ModalBody`. Bad input raises :class:`ImportInputError`
    (a :class:`pymr.SceneError`) naming the file, or the argument: each is checked before
    any file is read (types, counts: `modes` 0 or more, `keep` 1 or more), and `output` may
    not be one of the input files by any spelling (the kernel's same_file) nor a directory
    (:class:`pymr.OutputError`)."""
    mpath, kpath, npath = (_file_argument(n, v) for n, v in (("mass", mass), ("stiffness", stiffness),
                                                                ("nodes", nodes)))
    dof_map = None if dof_map is None else _file_argument("dof_map", dof_map)
    interface, clamp = _node_ids("interface", interface), _node_ids("clamp", clamp)
    _counts(dofs_per_node, dof_map, modes, keep)
    if not isinstance(title, str) or "\n" in title or "\r" in title:
        raise ImportInputError(f"title={title!r}: one line of text expected (the file's first comment)")
    if output is not None:
        output = _file_argument("output", output)
        for what, path in (("mass matrix", mpath), ("stiffness matrix", kpath), ("nodes file", npath),
                           ("DOF map", dof_map)):
            if path is not None and _core.pymr_same_file(os.fspath(output), os.fspath(path)):
                raise ImportInputError(f"{output}: would overwrite the {what} ({path}); choose another modal "
                                       "data file (-o)")
        check_output(output, "modal data file", option="output", example="body.modal", if_left_out=None)
    ids, xyz = read_nodes(npath)
    rows = layout_rows(ids, npath, dofs_per_node, dof_map)
    mm = read_matrix_market(mpath, rows)
    kk = read_matrix_market(kpath, rows)
    check_symmetric(mm, mpath)
    check_symmetric(kk, kpath)
    mm, kk = 0.5 * (mm + mm.T), 0.5 * (kk + kk.T)
    lowest = np.linalg.eigvalsh(mm)[0]
    if lowest < -1e-10 * np.abs(mm).max():
        raise ImportInputError(f"{mpath}: not positive semi-definite (an eigenvalue {lowest:.3g}): not a mass matrix")
    dof = dof_layout(ids, mm.shape[0], mpath, npath, dofs_per_node, dof_map)
    index = {nid: n for n, nid in enumerate(ids)}
    if not interface:
        raise ImportInputError("--interface: give at least the node where the body is attached")
    for nid in interface + clamp:
        if nid not in index:
            raise ImportInputError(f"{npath}: interface node {nid} is not in the mesh")
        if not (dof[index[nid]] >= 0).any():
            raise ImportInputError(f"{npath}: interface node {nid} has no DOF in the matrices")
    if len(set(interface + clamp)) != len(interface + clamp):
        raise ImportInputError("--interface/--clamp: a node is given twice")
    used = (dof >= 0).any(axis=1)             # nodes of the nodes file that the matrices leave out play no part
    ids, xyz, dof = [nid for nid, u_ in zip(ids, used) if u_], xyz[used], dof[used]
    index = {nid: n for n, nid in enumerate(ids)}
    attach = [interface[0]] + clamp
    held = [index[n] for n in attach]
    rows = lambda nodes_: np.array(sorted(int(d) for n in nodes_ for d in dof[n] if d >= 0), dtype=int)
    clamped = rows(held)
    boundary = rows([index[n] for n in interface[1:]])
    what = "node " + ", ".join(str(n) for n in attach) + " clamped"
    freq, u, counts = craig_bampton(kk, mm, clamped, boundary, modes, keep, kpath, what)
    origin = xyz[index[interface[0]]]
    s = xyz - origin
    mass_, first, w, exact = inertia_invariants(mm, dof, s, u, ids, mpath)
    pts = [index[n] for n in [interface[0]] + clamp + interface[1:]]
    nm = u.shape[1]
    psi = np.zeros((len(pts), 3, nm))
    phi = np.zeros((len(pts), 3, nm))
    for p, n in enumerate(pts):
        psi[p] = u[dof[n, :3]]
        if (dof[n, 3:] >= 0).all():
            phi[p] = u[dof[n, 3:]]
    body = ModalBody(freq, u, mass_, first, w, [ids[n] for n in pts], s[pts], psi, phi, origin, exact, counts)
    if output is not None:
        write_modal_v2(output, body, title or f"imported from {mpath.name}, {kpath.name}, {npath.name}")
    return body


# ----------------------------------------------------------------------------- the arguments

def _whole(value) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_))


def _file_argument(name: str, value) -> Path:
    """A file argument: a str or os.PathLike naming a file (not empty)."""
    try:
        path = Path(value)
    except TypeError:
        path = None
    if path is None or os.fspath(value) == "":
        raise ImportInputError(f"{name}={value!r}: a file name (str or path) expected")
    return path


def _node_ids(name: str, value) -> list[int]:
    """Node ids: a whole number or a list of them (a str is not taken apart digit by digit)."""
    if _whole(value):
        return [int(value)]
    if not isinstance(value, (str, bytes)):
        try:
            ids = list(value)
        except TypeError:
            ids = None
        if ids is not None and all(_whole(v) for v in ids):
            return [int(v) for v in ids]
    raise ImportInputError(f"{name}={value!r}: node ids expected, whole numbers (a list such as [1, 21])")


def _counts(dofs_per_node, dof_map, modes, keep) -> None:
    """The counts: dofs_per_node 3 or 6 (None with a DOF map), modes 0 or more (None: all
    with mass), keep 1 or more (None: all)."""
    if not (dofs_per_node is None or _whole(dofs_per_node)):
        raise ImportInputError(f"dofs_per_node={dofs_per_node!r}: 3 or 6 expected (or a dof_map)")
    if dof_map is None and dofs_per_node not in (3, 6):
        raise ImportInputError(f"--dofs-per-node {dofs_per_node}: 3 or 6")
    if not (modes is None or _whole(modes)):
        raise ImportInputError(f"modes={modes!r}: a whole number of fixed-interface modes expected (0 or more), "
                               "or None for all with mass")
    if modes is not None and modes < 0:
        raise ImportInputError(f"--modes {modes}: a count of modes (0 or more)")
    if not (keep is None or _whole(keep)):
        raise ImportInputError(f"keep={keep!r}: a whole number of modes to write expected (1 or more), or None "
                               "for all")
    if keep is not None and keep < 1:
        raise ImportInputError(f"--keep {keep}: the count of modes to write, at least 1 (leave it out for all)")


def layout_rows(ids: list[int], nodes_path: Path, dofs_per_node: int | None, dof_map: Path | None):
    """The matrices' row count the DOF layout gives, and from what (for messages): nodes x
    dofs_per_node, or one row a line of the DOF map. The matrices' size lines are checked
    against it before anything is allocated."""
    if dof_map is None:
        n = dofs_per_node * len(ids)
        return n, f"{nodes_path} has {len(ids)} nodes x {dofs_per_node} DOFs = {n}"
    n = sum(1 for _ in _lines(dof_map, "#"))
    return n, f"{dof_map} maps {n} rows (one a line)"


# ----------------------------------------------------------------------------- the file

def write_modal_v2(path: str | os.PathLike, body: ModalBody, title: str) -> None:
    """The body as a modal file of format 2 (its invariants block, points of zero mass)."""
    nm = len(body.frequencies_hz)
    g = lambda v: " ".join(f"{x:.17e}" for x in np.ravel(v))
    out = [f"# {title}",
           f"# Craig-Bampton: {body.kept['fixed_interface_modes']} fixed-interface modes, "
           f"{body.kept['constraint_modes']} constraint modes; {nm} modes of the reduced body written",
           f"# origin: node {body.point_ids[0]} at {g(body.origin)} of the mesh; inertia invariants {body.exact}",
           "pymr-modal 2", f"modes {nm}", f"frequencies_hz {g(body.frequencies_hz)}", "invariants",
           f"mass {body.mass:.17e}", "first_moments"]
    out += [f"{a} {g(body.first[:, a])}" for a in range(nm + 1)]
    out.append("second_moments")
    out += [f"{a} {b} {g(body.second[:, :, a, b])}" for a in range(nm + 1) for b in range(a, nm + 1)]
    out.append(f"# points: node ids {' '.join(str(n) for n in body.point_ids)}")
    out.append(f"points {len(body.point_ids)}")
    for p in range(len(body.point_ids)):
        out.append(f"{g(body.points[p])} 0 {g(body.psi[p].T)} {g(body.phi[p].T)}")
    write_file(path, "\n".join(out) + "\n", "modal data file")
