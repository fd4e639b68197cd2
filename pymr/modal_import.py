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

import scipy.sparse as sp

from . import _kernel as _core
from .api import write_file
from .craig_bampton import reduce
from .fe_formats import (DOF_NAMES, ImportInputError, dof_layout, layout_rows, read_matrix,  # noqa: F401
                         read_matrix_market, read_nodes)
from .outputs import check_output


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


# ----------------------------------------------------------------------------- linear algebra

def check_symmetric(a: sp.spmatrix, path: Path) -> None:
    """The matrix equals its transpose to 1e-10 of its largest entry."""
    a = sp.csr_matrix(a)
    scale = abs(a).max() if a.nnz else 0.0
    if not scale > 0:
        raise ImportInputError(f"{path}: the matrix is zero")
    d = abs(a - a.T).tocoo()
    if d.nnz and d.data.max() > 1e-10 * scale:
        w = int(np.argmax(d.data))
        i, j = int(d.row[w]), int(d.col[w])
        raise ImportInputError(f"{path}: not symmetric (entries ({i + 1}, {j + 1}) and ({j + 1}, {i + 1}) differ "
                               f"by {d.data[w]:.3g}, the largest entry is {scale:.3g})")


def check_mass(m: sp.spmatrix, path: Path) -> None:
    """Positive semi-definite as far as 2 x 2 principal minors tell (a negative diagonal, or
    |m_ij| > sqrt(m_ii m_jj)); the reduced mass matrix is checked whole after the reduction."""
    c = sp.coo_matrix(m)
    d = sp.csr_matrix(m).diagonal()
    tol = 1e-10 * np.abs(c.data).max()
    lowest = d.min()
    if lowest < -tol:
        raise ImportInputError(f"{path}: not positive semi-definite (a diagonal entry {lowest:.3g}): not a mass matrix")
    excess = np.abs(c.data) - np.sqrt(np.maximum(d[c.row], 0) * np.maximum(d[c.col], 0))
    if excess.max() > tol:
        w = int(np.argmax(excess))
        raise ImportInputError(f"{path}: not positive semi-definite (entry ({c.row[w] + 1}, {c.col[w] + 1}) exceeds "
                               f"the root of its diagonal entries' product by {excess[w]:.3g}): not a mass matrix")


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


def modal_import(mass: str | os.PathLike, stiffness: str | os.PathLike, nodes: str | os.PathLike,
                 interface, output: str | os.PathLike | None = None, *, dofs_per_node: int | None = 6,
                 dof_map: str | os.PathLike | None = None, modes: int | None = 10, keep: int | None = None,
                 clamp=(), title: str = "", mass_name: str | None = None, stiffness_name: str | None = None,
                 progress: bool = False, memory_limit: float | None = None) -> ModalBody:
    """Import a finite-element body: the `mass` and `stiffness` matrices (Matrix Market,
    Abaqus matrix output, Nastran DMIG or OP4: :mod:`pymr.fe_formats`; `mass_name`,
    `stiffness_name` pick a matrix from a Nastran file holding several), `nodes` (CSV of id,
    x, y, z, an Abaqus .inp or Nastran GRID cards), the DOF layout of unlabelled formats
    (`dofs_per_node` 3 or 6, rows node by node in the nodes file's order, or a `dof_map`
    file of 'row node dof'), the `interface` node ids (the first is the body frame's origin,
    clamped to its joint; `clamp`: more nodes clamped with it, for meshes without
    rotations), `modes` fixed-interface modes (None: all) and the lowest `keep` modes of the
    reduced body written (None: all). `progress` draws bars on stderr for the factorisation
    and the eigensolve; `memory_limit` (GB, default what the machine has available) refuses
    a model whose reduction would need more, before any numeric work. Writes the modal file
    to `output` when given and returns the :class:`ModalBody`. Bad input raises
    :class:`ImportInputError` (a :class:`pymr.SceneError`) naming the file, or the argument:
    each is checked before any file is read (types, counts: `modes` 0 or more, `keep` 1 or
    more), and `output` may not be one of the input files by any spelling (the kernel's
    same_file) nor a directory (:class:`pymr.OutputError`)."""
    mpath, kpath, npath = (_file_argument(n, v) for n, v in (("mass", mass), ("stiffness", stiffness),
                                                                ("nodes", nodes)))
    dof_map = None if dof_map is None else _file_argument("dof_map", dof_map)
    interface, clamp = _node_ids("interface", interface), _node_ids("clamp", clamp)
    _counts(dofs_per_node, dof_map, modes, keep)
    limit = _memory_limit(memory_limit)
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
    ids, xyz, mm, kk, dof = read_body(mpath, kpath, npath, dofs_per_node, dof_map, mass_name, stiffness_name)
    ids, xyz, dof, attach, boundary_nodes = attachment(ids, xyz, dof, interface, clamp, npath)
    index = {nid: n for n, nid in enumerate(ids)}
    rows = lambda nodes_: np.array(sorted(int(d) for n in nodes_ for d in dof[n] if d >= 0), dtype=int)
    what = "node " + ", ".join(str(n) for n in attach) + " clamped"
    clamped = rows([index[n] for n in attach])
    check_free_body(kk, dof, ids, kpath, clamped)
    red = reduce(kk, mm, clamped, rows([index[n] for n in boundary_nodes]), modes, keep, kpath, what, show=progress,
                 memory_limit=limit)
    u = red.modes
    origin = xyz[index[interface[0]]]
    s = xyz - origin
    mass_, first, w, exact = inertia_invariants(mm, dof, s, u, ids, mpath)
    pts = [index[n] for n in attach + boundary_nodes]
    nm = u.shape[1]
    psi, phi = np.zeros((len(pts), 3, nm)), np.zeros((len(pts), 3, nm))
    for p, n in enumerate(pts):
        psi[p] = u[dof[n, :3]]
        if (dof[n, 3:] >= 0).all():
            phi[p] = u[dof[n, 3:]]
    body = ModalBody(red.frequencies_hz, u, mass_, first, w, [ids[n] for n in pts], s[pts], psi, phi, origin, exact,
                     red.counts)
    if output is not None:
        write_modal_v2(output, body, title or f"imported from {mpath.name}, {kpath.name}, {npath.name}")
    return body


def read_body(mpath: Path, kpath: Path, npath: Path, dofs_per_node, dof_map, mass_name, stiffness_name):
    """The nodes, M and K (sparse, symmetric, on the same rows) and the DOF layout."""
    ids, xyz = read_nodes(npath)
    rows = None if dof_map is None and dofs_per_node is None else layout_rows(ids, npath, dofs_per_node, dof_map)
    mm, m_labels = read_matrix(mpath, rows, mass_name, "mass")
    kk, k_labels = read_matrix(kpath, rows, stiffness_name, "stiffness")
    if (m_labels is None) != (k_labels is None):
        raise ImportInputError(f"{mpath if m_labels is None else kpath}: rows not labelled by node and DOF, but "
                               f"{kpath if m_labels is None else mpath}'s are: give both matrices in one kind of file")
    labels = None
    if m_labels is not None:
        labels, mm, kk = on_common_rows(m_labels, mm, k_labels, kk)
    elif mm.shape != kk.shape:
        raise ImportInputError(f"{kpath}: {kk.shape[0]} rows, but {mpath} has {mm.shape[0]}")
    check_symmetric(mm, mpath)
    check_symmetric(kk, kpath)
    mm, kk = (0.5 * (mm + mm.T)).tocsr(), (0.5 * (kk + kk.T)).tocsr()
    check_mass(mm, mpath)
    dof = dof_layout(ids, mm.shape[0], mpath, npath, dofs_per_node, dof_map, labels)
    return ids, xyz, mm, kk, dof


def check_free_body(kk: sp.spmatrix, dof: np.ndarray, ids: list, kpath: Path, clamped: np.ndarray) -> None:
    """No DOF but the clamped ones without stiffness: a constraint applied in the FE code
    zeroes its row (and the mass of the constrained nodes with it)."""
    diagonal = kk.diagonal()
    diagonal[clamped] = 1.0
    zero = np.nonzero(~(diagonal > 0))[0]
    if zero.size:
        n, c = np.argwhere(dof == zero[0])[0]
        raise ImportInputError(f"{kpath}: row {zero[0] + 1} (node {ids[n]} {DOF_NAMES[c]}) has no stiffness, and "
                               f"{zero.size} rows in all: DOFs constrained in the FE code? Export the free body "
                               "(no boundary conditions; --interface and --clamp hold the attachment)")


def on_common_rows(m_labels, mm, k_labels, kk):
    """Both labelled matrices on the union of their rows (a row one leaves out is 0 there:
    a DOF without mass)."""
    code = lambda nd: nd[:, 0].astype(np.int64) * 16 + nd[:, 1]
    labels = np.unique(np.concatenate([m_labels, k_labels]), axis=0)
    out = []
    for lab, a in ((m_labels, mm), (k_labels, kk)):
        at = np.searchsorted(code(labels), code(lab))
        embed = sp.csr_matrix((np.ones(len(at)), (at, np.arange(len(at)))), shape=(len(labels), len(at)))
        out.append((embed @ a @ embed.T).tocsr())
    return labels, out[0], out[1]


def attachment(ids, xyz, dof, interface, clamp, npath):
    """The nodes the matrices use, and the attachment (origin and clamped nodes) and the
    other interface nodes, each checked."""
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
    ids = [nid for nid, u_ in zip(ids, used) if u_]
    return ids, xyz[used], dof[used], [interface[0]] + clamp, interface[1:]


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


def _memory_limit(value) -> int | None:
    """`memory_limit` in GB (positive) as bytes, or None for what the machine has."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not np.isfinite(value) or value <= 0:
        raise ImportInputError(f"memory_limit={value!r}: a positive number of GB expected")
    return int(float(value) * 1e9)


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
