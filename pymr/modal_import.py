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
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import _kernel as _core
from .api import write_file
from .errors import ImportInputError, PymrWarning
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
    warnings: list = field(default_factory=list)   # what the import doubts (rigid_motion_warning), one line each


def modal_import(mass: str | os.PathLike, stiffness: str | os.PathLike, nodes: str | os.PathLike,
                 interface, output: str | os.PathLike | None = None, *, dofs_per_node: int | None = None,
                 dof_map: str | os.PathLike | None = None, modes: int | None = 10, keep: int | None = None,
                 clamp=(), title: str = "", mass_name: str | None = None, stiffness_name: str | None = None,
                 progress: bool = False, memory_limit: float | None = None) -> ModalBody:
    """Import a finite-element body: the `mass` and `stiffness` matrices (Matrix Market,
    Abaqus matrix output, Nastran DMIG or OP4: :mod:`pymr.fe_formats`; `mass_name`,
    `stiffness_name` pick a matrix from a Nastran file holding several), `nodes` (CSV of id,
    x, y, z, an Abaqus .inp or Nastran GRID cards), the DOF layout of unlabelled formats
    (`dofs_per_node` 3 or 6, rows node by node in the nodes file's order, default 6; or a
    `dof_map` file of 'row node dof', not with `dofs_per_node`), the `interface` node ids (the first is the body frame's origin,
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
    if dof_map is not None and dofs_per_node is not None:
        raise ImportInputError(f"dofs_per_node={dofs_per_node!r} and dof_map: give one of them (the DOF map lays out "
                               "the rows itself)")
    if dof_map is None and dofs_per_node is None:
        dofs_per_node = 6
    _counts(dofs_per_node, dof_map, modes, keep)
    limit = _memory_limit(memory_limit)
    if not isinstance(title, str) or "\n" in title or "\r" in title:
        raise ImportInputError(f"title={title!r}: one line of text expected (the file's first comment)")
    for name, value in (("mass_name", mass_name), ("stiffness_name", stiffness_name)):
        if value is not None and (not isinstance(value, str) or not value.strip()):
            raise ImportInputError(f"{name}={value!r}: a matrix's name (str) expected, or None")
    if not isinstance(progress, (bool, np.bool_)):
        raise ImportInputError(f"progress={progress!r}: True or False expected")
    if output is not None:
        output = _file_argument("output", output)
        for what, path in (("mass matrix", mpath), ("stiffness matrix", kpath), ("nodes file", npath),
                           ("DOF map", dof_map)):
            if path is not None and _core.pymr_same_file(os.fspath(output), os.fspath(path)):
                raise ImportInputError(f"{output}: would overwrite the {what} ({path}); choose another modal "
                                       "data file (-o)")
        check_output(output, "modal data file", option="output", example="body.modal", if_left_out=None)
    # scipy loads here, not with pymr (a run's process needs it not)
    from .craig_bampton import reduce
    from .fe_formats import check_free_body, read_body
    ids, xyz, mm, kk, dof = read_body(mpath, kpath, npath, dofs_per_node, dof_map, mass_name, stiffness_name)
    ids, xyz, dof, attach, boundary_nodes = attachment(ids, xyz, dof, interface, clamp, npath)
    index = {nid: n for n, nid in enumerate(ids)}
    rows = lambda nodes_: np.array(sorted(int(d) for n in nodes_ for d in dof[n] if d >= 0), dtype=int)
    what = "node " + ", ".join(str(n) for n in attach) + " clamped"
    clamped = rows([index[n] for n in attach])
    check_free_body(kk, dof, ids, kpath, clamped)
    doubts = rigid_motion_warning(kk, dof, xyz, kpath)
    red = reduce(kk, mm, clamped, rows([index[n] for n in boundary_nodes]), modes, keep, kpath, what, show=progress,
                 memory_limit=limit)
    u = red.modes
    origin = xyz[index[interface[0]]]
    s = xyz - origin
    mass_, first, w, exact = finite_invariants(mm, dof, s, u, ids, mpath, npath, interface[0])
    pts = [index[n] for n in attach + boundary_nodes]
    nm = u.shape[1]
    psi, phi = np.zeros((len(pts), 3, nm)), np.zeros((len(pts), 3, nm))
    for p, n in enumerate(pts):
        psi[p] = u[dof[n, :3]]
        if (dof[n, 3:] >= 0).all():
            phi[p] = u[dof[n, 3:]]
    body = ModalBody(red.frequencies_hz, u, mass_, first, w, [ids[n] for n in pts], s[pts], psi, phi, origin, exact,
                     red.counts, doubts)
    for doubt in doubts:
        warnings.warn(doubt, PymrWarning, stacklevel=2)
    if output is not None:
        write_modal_v2(output, body, title or f"imported from {mpath.name}, {kpath.name}, {npath.name}")
    return body


def rigid_motion_warning(kk, dof, xyz, kpath) -> list[str]:
    """The warning when K resists a rigid motion of the nodes (fe_invariants.rigid_response):
    the nodes or the DOF layout are likely not the matrices', which gives a wrong body with
    no error (a beam's nodes along y for a K along x: a negative second moment of mass).
    Springs between nodes apart, or to the ground, do it too, and may be meant: a warning,
    as Nastran's GROUNDCHECK gives. None for a K with rows constrained in the FE code (all
    clamped, check_free_body): their couplings are gone, and the test with them."""
    from .fe_invariants import RIGID_RESPONSE_LIMIT, rigid_response
    if not (kk.diagonal() > 0).all():
        return []
    response, motion = rigid_response(kk, dof, xyz)
    if not response > RIGID_RESPONSE_LIMIT:
        return []
    return [f"{kpath}: the stiffness resists a rigid {motion} of the nodes (|K r| reaches {response:.2g} of "
            "|K| |r| in a row, an elastic body's is its rounding): check that the nodes and the DOF layout are the "
            "matrices' (springs between nodes apart, or to the ground, also do this)"]


def finite_invariants(mm, dof, s, u, ids, mpath, npath, origin: int):
    """inertia_invariants of the body with nodes at s from node `origin`: an ImportInputError
    when they overflow (nodes far out in the units they are given in)."""
    from .fe_invariants import inertia_invariants
    with np.errstate(over="ignore", invalid="ignore"):
        mass_, first, w, exact = inertia_invariants(mm, dof, s, u, ids, mpath)
    if not all(np.isfinite(a).all() for a in (mass_, first, w)):
        raise ImportInputError(f"{npath}: the nodes lie up to {np.abs(s).max():.3g} from node {origin}, and the "
                               "body's inertia about it overflows: check the nodes' units")
    return mass_, first, w, exact


def attachment(ids, xyz, dof, interface, clamp, npath):
    """The nodes the matrices use, and the attachment (origin and clamped nodes) and the
    other interface nodes, each checked."""
    index = {nid: n for n, nid in enumerate(ids)}
    if not interface:
        raise ImportInputError("interface=[]: give at least the node where the body is attached")
    for nid in interface + clamp:
        if nid not in index:
            raise ImportInputError(f"{npath}: interface node {nid} is not in the mesh")
        if not (dof[index[nid]] >= 0).any():
            raise ImportInputError(f"{npath}: interface node {nid} has no DOF in the matrices")
    twice = sorted({n for n in interface + clamp if (interface + clamp).count(n) > 1})
    if twice:
        raise ImportInputError(f"interface and clamp: node {twice[0]} is given twice")
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
    if "\0" in str(path):
        raise ImportInputError(f"{name}={value!r}: a file name cannot hold a NUL character")
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


#: The smallest memory limit (GB) taken: one kilobyte. Below it no reduction fits, and the
#: limit was most likely given in another unit (it is in GB: 8 for 8 GB).
LEAST_MEMORY_GB = 1e-6
#: The largest (GB): an exabyte. 1e300 GB overflowed the byte count (a traceback).
MOST_MEMORY_GB = 1e9
#: The smallest normal double: a value below it is written as 0 (the kernel refuses it).
TINY = float(np.finfo(float).tiny)


def _memory_limit(value) -> int | None:
    """`memory_limit` in GB (from LEAST_MEMORY_GB to MOST_MEMORY_GB) as bytes, or None for what
    the machine has."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)) \
            or not np.isfinite(value) or value <= 0:
        raise ImportInputError(f"memory_limit={value!r}: a positive number of GB expected")
    if value < LEAST_MEMORY_GB:
        raise ImportInputError(f"memory_limit={value!r}: below {LEAST_MEMORY_GB:g} GB (one kilobyte), in which no "
                               "reduction fits: the limit is in GB (8 for 8 GB)")
    if value > MOST_MEMORY_GB:
        raise ImportInputError(f"memory_limit={value!r}: above {MOST_MEMORY_GB:g} GB, beyond any machine: the limit "
                               "is in GB (8 for 8 GB)")
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
    # below the smallest normal number as 0: the kernel refuses such a value as written
    g = lambda v: " ".join(f"{x if abs(x) >= TINY else 0.0:.17e}" for x in np.ravel(v))
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
