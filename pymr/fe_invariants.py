"""The inertia invariants of a finite-element body from its (sparse) mass matrix, for
``pymr modal-import``: the mass, first and second moments over the modes (modal file format
2). What is exact, and for which meshes, is in :func:`inertia_invariants`."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .errors import ImportInputError
from .fe_formats import DOF_NAMES


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


#: The stiffness's largest response to a rigid motion of the nodes (rigid_response) above
#: which modal-import warns. Measured: an elastic body's is its rounding, 1e-16 (1e-13 for
#: nodes 1000 lengths from the origin), 2e-5 for a K written with 5 digits (Nastran's short
#: fields); nodes or a DOF layout that are not the matrices' (a beam along x given nodes
#: along y, two DOFs swapped) give 1.
RIGID_RESPONSE_LIMIT = 1e-3
RIGID_MOTIONS = ("translation along x", "translation along y", "translation along z", "rotation about x",
                 "rotation about y", "rotation about z")


def rigid_response(k: sp.spmatrix, dof: np.ndarray, xyz: np.ndarray) -> tuple[float, str]:
    """How far K holds the rigid-body motions r of the nodes (about their centroid): the
    largest, over the rows i and the six motions, of |(K r)_i| / (|K_i| |r|)_i (the sum of
    the row's terms' sizes: 1 where nothing cancels), and which motion gives it. An elastic
    body's K r is 0 to the rounding of its rows; Nastran's GROUNDCHECK makes the same test."""
    r = rigid_modes(dof, xyz - xyz.mean(axis=0), k.shape[0])
    a = sp.csr_matrix(k)
    a = sp.diags(1.0 / np.maximum(abs(a).max(axis=1).toarray().ravel(), np.finfo(float).tiny)) @ a   # rows to 1
    with np.errstate(invalid="ignore", divide="ignore"):
        response = np.abs(a @ r) / (abs(a) @ np.abs(r))
    response = np.nan_to_num(response, nan=0.0).max(axis=0)    # a row the motion leaves still: 0/0
    worst = int(np.argmax(response))
    return float(response[worst]), RIGID_MOTIONS[worst]


def direction_groups(m: sp.spmatrix, dof: np.ndarray, ids: list, path: Path) -> np.ndarray:
    """Group of each DOF: 0-2 the translation direction it carries (translations, and the
    rotations the mass matrix couples with translations of that one direction), 3-5 a
    rotation the mass matrix couples with no translation (its axis, e.g. torsion). The mass
    matrix must be block-diagonal by group; else the message says which rows break it."""
    ndof = m.shape[0]
    c = sp.coo_matrix(m)
    tol = 1e-12 * np.abs(c.data).max()
    big = np.abs(c.data) > tol
    row, col = c.row[big], c.col[big]
    direction = np.full(ndof, -1)
    for d in range(3):
        direction[dof[:, d]] = d
    node, kind = np.full(ndof, -1), np.full(ndof, -1)
    for d in range(6):
        has = dof[:, d] >= 0
        node[dof[has, d]], kind[dof[has, d]] = np.nonzero(has)[0], d
    hit = np.zeros((ndof, 3), dtype=bool)
    near = direction[col] >= 0
    hit[row[near], direction[col[near]]] = True
    group = direction.copy()
    rotations = np.nonzero(kind >= 3)[0]
    several = rotations[hit[rotations].sum(axis=1) > 1]
    if several.size:
        d = several[0]
        raise ImportInputError(f"{path}: node {ids[node[d]]} {DOF_NAMES[kind[d]]} is coupled with translations along "
                               f"{' and '.join('xyz'[i] for i in np.nonzero(hit[d])[0])}: the invariants need a mass "
                               "matrix block-diagonal by direction (solids Ms (x) I3; beams along and plates in the "
                               "body axes)")
    coupled = hit[rotations].any(axis=1)
    group[rotations] = np.where(coupled, np.argmax(hit[rotations], axis=1), kind[rotations])
    cross = group[row] != group[col]
    if cross.any():
        w = np.nonzero(cross)[0][np.argmax(np.abs(c.data[big][cross]))]
        i, j = int(row[w]), int(col[w])
        raise ImportInputError(f"{path}: rows {i + 1} and {j + 1} (node {ids[node[i]]} {DOF_NAMES[kind[i]]}, node "
                               f"{ids[node[j]]} {DOF_NAMES[kind[j]]}) couple different directions: the invariants need "
                               "a mass matrix block-diagonal by direction (solids Ms (x) I3; beams along and plates "
                               "in the body axes)")
    return group


def transport(m: sp.spmatrix, dof: np.ndarray, group: np.ndarray, i: int, j: int):
    """Signed node-by-node map from the DOFs of direction i to those of direction j, with
    S M_ii S^T = M_jj: the two directions' fields are interpolated alike and the cross
    integrals int rho f_i g_j follow from M. As (source rows, target rows, signs), or None
    when there is no such map (other DOFs, or other mass blocks: a beam's axial and bending
    directions)."""
    rot = np.where(dof[:, 3:] >= 0, dof[:, 3:], 0)
    in_i = (dof[:, 3:] >= 0) & (group[rot] == i)
    in_j = (dof[:, 3:] >= 0) & (group[rot] == j)
    if (in_i.sum(axis=1) != in_j.sum(axis=1)).any() or in_i.sum(axis=1).max() > 1:
        return None
    nodes = np.nonzero(in_i.any(axis=1))[0]
    ri, rj = rot[nodes, np.argmax(in_i[nodes], axis=1)], rot[nodes, np.argmax(in_j[nodes], axis=1)]
    m = sp.csc_matrix(m)
    sign = np.ones(dof.shape[0] + len(nodes))
    if len(nodes):
        # the sign that carries each rotation's coupling with its direction's translations
        p = np.asarray(abs(m[dof[:, i]][:, ri]).argmax(axis=0)).ravel()
        col_i = np.asarray(m[dof[p, i], ri]).ravel()
        col_j = np.asarray(m[dof[p, j], rj]).ravel()
        sign[dof.shape[0]:] = np.where(col_i * col_j < 0, -1.0, 1.0)
    src, dst = np.concatenate([dof[:, i], ri]), np.concatenate([dof[:, j], rj])
    if len(src) != np.count_nonzero(group == i) or len(dst) != np.count_nonzero(group == j):
        return None
    s = sp.diags(sign)
    gap = (s @ m[src][:, src] @ s - m[dst][:, dst]).tocoo()
    if gap.nnz and np.abs(gap.data).max() > 1e-10 * abs(m).max():
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
