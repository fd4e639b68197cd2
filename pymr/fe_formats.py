"""What finite-element codes write, read for ``pymr modal-import``: sparse matrices and nodes.

Matrices (:func:`read_matrix`, the format told from the file):

- **Matrix Market** (``%%MatrixMarket matrix coordinate|array real general|symmetric``);
  its rows are laid out by ``dofs_per_node`` or a DOF map;
- **Abaqus** matrix output (``*MATRIX GENERATE`` with ``*MATRIX OUTPUT, FORMAT=MATRIX
  INPUT``): lines ``node, dof, node, dof, value``, each row labelled with its node and DOF;
- **Nastran DMIG** cards in bulk data or punch files (``PARAM,EXTOUT,DMIGPCH``), each row
  labelled with its grid and component; read by pyNastran;
- **Nastran OP4** (ASCII or binary), read by pyNastran; laid out like Matrix Market;
- **Ansys full files** (``.full``, both matrices in one), read by ansys-mapdl-reader, each
  row labelled with its node and DOF.

A symmetric matrix may be given by one triangle (either) or both. Nodes (:func:`read_nodes`):
lines ``id, x, y, z`` (CSV), an Abaqus input deck's ``*NODE`` blocks, Nastran ``GRID``
cards (positions in the basic system), or an Ansys archive (``.cdb``) or result file
(``.rst``).
"""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import scipy.sparse as sp

from .errors import ImportInputError

#: names of the six DOFs of a node, in the order of dofs_per_node 6 and DOF numbers 1-6
DOF_NAMES = ("u_x", "u_y", "u_z", "theta_x", "theta_y", "theta_z")
#: file endings of Nastran bulk data (DMIG, GRID) and of OP4 files
NASTRAN_BULK = (".bdf", ".dat", ".pch", ".nas", ".blk", ".bulk")
OP4 = (".op4",)
#: the matrices of an Ansys full file, by the role the caller reads it for
ANSYS_FULL = {"mass": "MASS", "stiffness": "STIFF"}
#: what the text formats are called where a file is none of them (a binary file)
TEXT_MATRIX = "a text matrix file (Matrix Market, or Abaqus matrix output)"
NODES_TEXT = "a nodes file (lines 'node id, x, y, z')"
DOF_MAP_TEXT = "a DOF map (lines 'row node dof')"


# ----------------------------------------------------------------------------- text files

def _unreadable(path: Path, exc: OSError) -> ImportInputError:
    """The error of a file that cannot be read, in pymr's words (not Python's '[Errno 21] ...')."""
    if isinstance(exc, FileNotFoundError):
        return ImportInputError(f"{path}: no such file")
    if isinstance(exc, IsADirectoryError):
        return ImportInputError(f"{path}: a directory, not a file")
    return ImportInputError(f"{path}: cannot read: {exc.strerror or exc}")


def _text(path: Path, what: str) -> str:
    """The text of `path`, which should be `what` (a binary file is named as none, with the
    line that is not UTF-8 text, not by the codec's message)."""
    try:
        return path.read_text(encoding="utf-8")
    except OSError as exc:
        raise _unreadable(path, exc) from None
    except UnicodeDecodeError as exc:
        line = exc.object[:exc.start].count(b"\n") + 1
        raise ImportInputError(f"{path}: not {what}: line {line} is not UTF-8 text") from None


def _lines(path: Path, comment: str, what: str):
    """(line number, stripped text) of the file's lines that are not blank or comments; the
    file should be `what` (for the message when it is not text)."""
    for k, line in enumerate(_text(path, what).splitlines(), 1):
        s = line.strip()
        if s and not s.startswith(comment):
            yield k, s


def _number(path: Path, k: int, s: str) -> float:
    try:
        v = float(s)
    except ValueError:
        raise ImportInputError(f"{path}: line {k}: expected a number, got {s!r}") from None
    if not np.isfinite(v):
        raise ImportInputError(f"{path}: line {k}: {s} is not finite")
    return v


# ----------------------------------------------------------------------------- matrices

def read_matrix(path: str | os.PathLike, rows: tuple[int, str] | None = None, name: str | None = None,
                role: str = "stiffness"):
    """The matrix in `path` as (scipy CSC, labels): labels (rows, 2) of (node, dof 1-6) for
    formats that label their rows, else None. `rows`: (count, why) the caller's DOF layout
    gives, checked against unlabelled formats; `name`: the matrix in a Nastran file holding
    several; `role`: 'mass' or 'stiffness', the matrix an Ansys full file gives."""
    path = Path(path)
    if name is not None and path.suffix.lower() not in OP4 + NASTRAN_BULK:
        # it was ignored, and the file's one matrix read as if it were the one named
        raise ImportInputError(f"{path}: a {role} matrix's name ({name!r}) picks one of the matrices of a Nastran "
                               "file (DMIG, OP4); this file holds one matrix: leave the name out")
    if path.suffix.lower() == ".full":
        return read_full(path, role)
    if path.suffix.lower() in OP4:
        return read_op4(path, name, rows), None
    if path.suffix.lower() in NASTRAN_BULK:
        return read_dmig(path, name)
    try:
        with open(path, "rb") as fh:
            start = fh.read(14).lower()
    except OSError as exc:
        raise _unreadable(path, exc) from None
    if start.startswith(b"%%matrixmarket") or not start.strip():
        return read_matrix_market(path, rows), None
    return read_abaqus(path)


def read_matrix_market(path: str | os.PathLike, rows: tuple[int, str] | None = None) -> sp.csc_matrix:
    """A real Matrix Market matrix (coordinate or array; general or symmetric), sparse.
    `rows`: (count, why) when the caller knows how many rows the matrix must have (`why` says
    from what, for the message). The size line is checked against it, and against the
    entries the file holds, before anything is allocated."""
    path = Path(path)
    text = _text(path, TEXT_MATRIX)
    header = text.split("\n", 1)[0].split()
    if len(header) != 5 or header[0].lower() != "%%matrixmarket" or header[1].lower() != "matrix":
        raise ImportInputError(f"{path}: line 1: not a Matrix Market matrix (expected '%%MatrixMarket matrix ...')")
    form, kind, sym = (h.lower() for h in header[2:])
    if form not in ("coordinate", "array") or kind not in ("real", "integer", "double") \
            or sym not in ("general", "symmetric"):
        raise ImportInputError(f"{path}: line 1: {' '.join(header[2:])}: only real coordinate or array matrices, "
                               "general or symmetric, are read")
    nr, body, values = _size_line(path, text, form, sym, rows)
    if form == "array":
        return _array_matrix(path, body, nr, sym)
    if values is None:
        values = _entries_slowly(path, nr, sym)
    i, j, v = values[0::3], values[1::3], values[2::3]
    bad = (i != np.round(i)) | (j != np.round(j)) | ~(1 <= i) | ~(i <= nr) | ~(1 <= j) | ~(j <= nr) \
        | ~np.isfinite(v) | ((i < j) if sym == "symmetric" else False)
    if bad.any():
        _entries_slowly(path, nr, sym)             # names the first bad line
    i, j = i.astype(np.int64) - 1, j.astype(np.int64) - 1
    a = sp.coo_matrix((v, (i, j)), shape=(nr, nr))
    if sym == "symmetric":
        off = i != j
        a = a + sp.coo_matrix((v[off], (j[off], i[off])), shape=(nr, nr))
    return a.tocsc()


def _size_line(path: Path, text: str, form: str, sym: str, rows):
    """(rows, the text after the size line, its numbers read fast or None) of a Matrix
    Market file, the size line checked against the layout and the entries held."""
    at, k = 0, 0
    while at < len(text):
        end = text.find("\n", at)
        end = len(text) if end < 0 else end + 1
        line, at, k = text[at:end], end, k + 1
        s = line.strip()
        if not s or s.startswith("%"):
            continue
        try:
            dims = [int(v) for v in s.split()]
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
        count = (nr * nc if sym == "general" else nr * (nr + 1) // 2) if form == "array" else dims[2]
        body = text[at:]
        values = _numbers(body) if form == "coordinate" and "%" not in body else None
        if values is None or values.size != 3 * count:
            held = sum(1 for ln in body.splitlines() if ln.strip() and not ln.lstrip().startswith("%"))
            if held != count:
                what = "values" if form == "array" else "entries"
                raise ImportInputError(f"{path}: line {k}: the size line gives {count} {what} ({nr} x {nc}, "
                                       f"{sym}), the file holds {held}")
            values = None                       # read line by line, to name the bad one
        if 32 * (nr + 1) > _memory_bound():      # the reading, the checks and the reduction hold 4 copies
            raise ImportInputError(f"{path}: line {k}: {nr} x {nc}: too large for this machine's memory "
                                   f"({32 * (nr + 1) / 1e9:.3g} GB for the row pointers of its copies alone)")
        return nr, body, values
    raise ImportInputError(f"{path}: no size line")


def _numbers(body: str) -> np.ndarray | None:
    """The numbers of a Matrix Market body read fast, or None when it holds text that is not
    a number (numpy 2 raises ValueError; the caller then reads it line by line, naming the
    bad line)."""
    try:
        return np.fromstring(body, sep=" ")
    except ValueError:
        return None


def _memory_bound() -> int:
    from .craig_bampton import available_memory
    return available_memory()


def _array_matrix(path: Path, body: str, nr: int, sym: str) -> sp.csc_matrix:
    values = [_number(path, k, s) for k, s in _lines(path, "%", TEXT_MATRIX)][1:]
    a = np.zeros((nr, nr))
    if sym == "general":
        a[:, :] = np.asarray(values).reshape(nr, nr).T
    else:
        il, jl = np.tril_indices(nr)
        order = np.lexsort((il, jl))           # column by column, each from the diagonal down
        a[il[order], jl[order]] = values
        a = np.tril(a) + np.tril(a, -1).T
    return sp.csc_matrix(a)


def _entries_slowly(path: Path, nr: int, sym: str = "general") -> np.ndarray:
    """The coordinate entries line by line, raising at the first bad one (the fast reading
    found a fault and this names its line)."""
    out = []
    for k, s in list(_lines(path, "%", TEXT_MATRIX))[1:]:
        parts = s.split()
        try:
            i, j, v = int(parts[0]), int(parts[1]), float(parts[2])
            if len(parts) != 3:
                raise ValueError
        except (ValueError, IndexError):
            raise ImportInputError(f"{path}: line {k}: expected 'row column value'") from None
        if not (1 <= i <= nr and 1 <= j <= nr):
            raise ImportInputError(f"{path}: line {k}: entry ({i}, {j}) outside the {nr} x {nr} matrix")
        if not np.isfinite(v):
            raise ImportInputError(f"{path}: line {k}: entry ({i}, {j}) is not finite")
        if sym == "symmetric" and i < j:
            raise ImportInputError(f"{path}: line {k}: entry ({i}, {j}) above the diagonal of a symmetric matrix")
        out += [i, j, v]
    return np.asarray(out, dtype=float)


def whole(a: sp.spmatrix) -> sp.csc_matrix:
    """A symmetric matrix given by one triangle (either) mirrored whole; one given by both
    as it is."""
    upper, lower = sp.triu(a, 1), sp.tril(a, -1)
    if upper.nnz == 0 or lower.nnz == 0:
        a = a + (upper + lower).T
    return sp.csc_matrix(a)


def labelled(path: Path, row_nd: np.ndarray, col_nd: np.ndarray, v: np.ndarray):
    """A matrix from entries labelled (node, dof) by row and column: (CSC, labels), rows
    sorted by node then DOF. One triangle is mirrored; both must agree."""
    bad = (row_nd[:, 1] < 1) | (row_nd[:, 1] > 6) | (col_nd[:, 1] < 1) | (col_nd[:, 1] > 6)
    if bad.any():
        w = int(np.argmax(bad))
        node, dof = (row_nd[w] if not 1 <= row_nd[w, 1] <= 6 else col_nd[w]).tolist()
        raise ImportInputError(f"{path}: node {node} DOF {dof}: DOFs 1-6 (u_x u_y u_z theta_x theta_y theta_z) "
                               "expected")
    keys = np.unique(np.concatenate([row_nd, col_nd]), axis=0)
    code = lambda nd: nd[:, 0].astype(np.int64) * 16 + nd[:, 1]
    where = np.searchsorted(code(keys), code(row_nd)), np.searchsorted(code(keys), code(col_nd))
    n = len(keys)
    a = sp.coo_matrix((v, where), shape=(n, n)).tocsr()
    a.sum_duplicates()
    return whole(a), keys


def read_full(path: Path, role: str):
    """The mass or stiffness matrix of an Ansys full file (ansys-mapdl-reader), its rows
    labelled by node and DOF (UX UY UZ ROTX ROTY ROTZ: 1-6)."""
    try:
        from ansys.mapdl.reader import read_binary
    except ImportError:
        raise ImportInputError("reading Ansys full files needs ansys-mapdl-reader: pip install ansys-mapdl-reader") \
            from None
    if not path.is_file():
        raise ImportInputError(f"{path}: no such file")
    try:
        dof_ref, k, m = read_binary(str(path)).load_km(as_sparse=True, sort=True)
    except Exception as exc:        # the reader raises many kinds for a bad file
        raise ImportInputError(f"{path}: not read as an Ansys full file: {_first_line(exc)}") from None
    nd = np.column_stack([np.asarray(dof_ref[:, 0], dtype=np.int64), np.asarray(dof_ref[:, 1], dtype=np.int64) + 1])
    if ((nd[:, 1] < 1) | (nd[:, 1] > 6)).any():
        node, dof = nd[np.argmax((nd[:, 1] < 1) | (nd[:, 1] > 6))].tolist()
        raise ImportInputError(f"{path}: node {node} DOF {dof}: DOFs 1-6 (UX UY UZ ROTX ROTY ROTZ) expected")
    a = sp.csc_matrix(m if role == "mass" else k)          # one triangle; a constrained DOF's row is empty
    return whole(a), nd


def _first_line(exc: Exception) -> str:
    return str(exc).splitlines()[0] if str(exc) else type(exc).__name__


def read_abaqus(path: Path):
    """Abaqus matrix output: lines 'node, dof, node, dof, value' (commas or blanks; '*'
    lines are headings or comments)."""
    rows = []
    for k, s in _lines(path, "*", TEXT_MATRIX):
        parts = s.replace(",", " ").split()
        try:
            if len(parts) != 5:
                raise ValueError
            n1, d1, n2, d2 = (int(p) for p in parts[:4])
            v = float(parts[4].replace("D", "E").replace("d", "e"))
        except ValueError:
            raise ImportInputError(f"{path}: line {k}: expected 'node, dof, node, dof, value' (Abaqus matrix "
                                   "output, FORMAT=MATRIX INPUT), or a Matrix Market file") from None
        if not (1 <= d1 <= 6 and 1 <= d2 <= 6):
            raise ImportInputError(f"{path}: line {k}: dof {d1 if not 1 <= d1 <= 6 else d2}: 1-6 (u_x u_y u_z "
                                   "theta_x theta_y theta_z)")
        if not np.isfinite(v):
            raise ImportInputError(f"{path}: line {k}: value {parts[4]} is not finite")
        rows.append((n1, d1, n2, d2, v))
    if not rows:
        raise ImportInputError(f"{path}: no matrix entries")
    e = np.asarray(rows, dtype=float)
    return labelled(path, e[:, :2].astype(np.int64), e[:, 2:4].astype(np.int64), e[:, 4])


def pynastran():
    """pyNastran's BDF and read_op4, or a one-line error saying how to install it."""
    if not hasattr(np, "in1d"):
        # pyNastran 1.4.1 (the latest release) calls numpy.in1d, which numpy 2.4 removed; isin is its successor
        np.in1d = np.isin
    try:
        from cpylog import SimpleLogger
        from pyNastran.bdf.bdf import BDF
        from pyNastran.op4.op4 import read_op4 as op4
    except ImportError:
        raise ImportInputError("reading Nastran files needs pyNastran: pip install --no-deps pyNastran cpylog "
                               "docopt-ng colorama") from None
    return (lambda: BDF(debug=None, log=SimpleLogger(level="error"))), op4


def read_bulk(path: Path):
    """A Nastran bulk data or punch file through pyNastran (cards not needed are skipped)."""
    new_model, _ = pynastran()
    text = _text(path, "Nastran bulk data")
    model = new_model()
    try:
        model.read_bdf(str(path), xref=False, punch="BEGIN BULK" not in text.upper(), validate=False)
    except Exception as exc:        # pyNastran raises many kinds for a bad deck
        raise ImportInputError(f"{path}: not read as Nastran bulk data: {_first_line(exc)}") from None
    return model


def _named(path: Path, found: dict, name: str | None, what: str):
    if name is not None:
        if name not in found:
            raise ImportInputError(f"{path}: no {what} {name!r} (the file holds {', '.join(sorted(found)) or 'none'})")
        return found[name]
    if len(found) != 1:
        raise ImportInputError(f"{path}: holds {len(found)} {what} matrices ({', '.join(sorted(found)) or 'none'}): "
                               "name the one to read (--stiffness-name, --mass-name)")
    return next(iter(found.values()))


def read_dmig(path: Path, name: str | None):
    """A Nastran DMIG matrix (grid, component labels; components 1-6, scalar points 0 are
    refused) from bulk data or a punch file."""
    dmig = _named(path, read_bulk(path).dmig, name, "DMIG")
    gcj, gci = np.asarray(dmig.GCj, dtype=np.int64).reshape(-1, 2), np.asarray(dmig.GCi, dtype=np.int64).reshape(-1, 2)
    if np.iscomplexobj(dmig.Real) or getattr(dmig, "Complex", None) is not None:
        raise ImportInputError(f"{path}: DMIG {dmig.name}: complex; a real matrix expected")
    for nd in (gcj, gci):
        if ((nd[:, 1] < 1) | (nd[:, 1] > 6)).any():
            g, c = nd[np.argmax((nd[:, 1] < 1) | (nd[:, 1] > 6))]
            raise ImportInputError(f"{path}: DMIG {dmig.name}: grid {g} component {c}: components 1-6 of grid "
                                   "points expected (scalar points have no place in a body)")
    v = np.asarray(dmig.Real, dtype=float)
    if not np.isfinite(v).all():
        raise ImportInputError(f"{path}: DMIG {dmig.name}: a value is not finite")
    return labelled(path, gci, gcj, v)


def read_op4(path: Path, name: str | None, rows) -> sp.csc_matrix:
    """A matrix of a Nastran OP4 file (ASCII or binary) through pyNastran."""
    _, op4 = pynastran()
    if not path.is_file():
        raise ImportInputError(f"{path}: no such file")
    try:
        found = op4(str(path), debug=False)
    except Exception as exc:        # pyNastran raises many kinds for a bad file
        raise ImportInputError(f"{path}: not read as OP4: {_first_line(exc)}") from None
    data = _named(path, {k: m.data for k, m in found.items()}, name, "OP4")
    a = sp.csc_matrix(data, dtype=float)
    if a.shape[0] != a.shape[1]:
        raise ImportInputError(f"{path}: {a.shape[0]} x {a.shape[1]}: a square matrix expected")
    if rows is not None and a.shape[0] != rows[0]:
        raise ImportInputError(f"{path}: {a.shape[0]} rows, but {rows[1]}")
    return whole(a)


# ----------------------------------------------------------------------------- nodes

def read_nodes(path: str | os.PathLike) -> tuple[list[int], np.ndarray]:
    """Node ids and coordinates (N, 3): an Abaqus input deck (.inp: its *NODE blocks),
    Nastran bulk data (GRID cards), else lines 'id, x, y, z' (commas or blanks; '#'
    comments; a first line of words is a header)."""
    path = Path(path)
    if path.suffix.lower() == ".inp":
        ids, xyz = _abaqus_nodes(path)
    elif path.suffix.lower() in (".cdb", ".rst"):
        ids, xyz = _ansys_nodes(path)
    elif path.suffix.lower() in NASTRAN_BULK:
        ids, xyz = _nastran_nodes(path)
    else:
        ids, xyz = _csv_nodes(path)
    if not ids:
        raise ImportInputError(f"{path}: no nodes")
    seen = set()
    for nid in ids:
        if nid in seen:
            raise ImportInputError(f"{path}: node {nid} is given twice")
        seen.add(nid)
    return ids, np.asarray(xyz, dtype=float).reshape(-1, 3)


def _nastran_nodes(path: Path):
    """The GRID cards of Nastran bulk data, in the basic system (each in its CP system)."""
    grids = read_bulk(path).nodes
    ids, xyz = [], []
    for nid in sorted(grids):
        try:
            x = list(grids[nid].get_position())
        except (AttributeError, KeyError, RuntimeError):   # pyNastran: a CP system (or one it refers to) not defined
            raise ImportInputError(f"{path}: GRID {nid}: its coordinate system CP = {grids[nid].cp} (or one it is "
                                   "defined in) is not in the bulk data") from None
        _add_node(ids, xyz, nid, x, f"{path}: GRID card")
    return ids, xyz


def _csv_nodes(path: Path):
    ids, xyz = [], []
    for n, (k, s) in enumerate(_lines(path, "#", NODES_TEXT)):
        parts = s.replace(",", " ").split()
        try:
            if len(parts) != 4:
                raise ValueError
            nid, x = int(parts[0]), [float(v) for v in parts[1:]]
        except ValueError:
            if n == 0 and not any(c.isdigit() for c in parts[0]):
                continue                            # a header line
            raise ImportInputError(f"{path}: line {k}: expected 'node id, x, y, z'") from None
        _add_node(ids, xyz, nid, x, f"{path}: line {k}")
    return ids, xyz


def _add_node(ids: list, xyz: list, nid: int, x: list, where: str) -> None:
    """One node of a node list, its coordinates finite."""
    if not np.all(np.isfinite(x)):
        raise ImportInputError(f"{where}: node {nid}: coordinates not finite")
    ids.append(nid)
    xyz.append(x)


def _ansys_nodes(path: Path):
    """The nodes of an Ansys archive (.cdb) or result file (.rst), by ansys-mapdl-reader."""
    try:
        from ansys.mapdl.reader import Archive, read_binary
    except ImportError:
        raise ImportInputError("reading Ansys files needs ansys-mapdl-reader: pip install ansys-mapdl-reader") from None
    if not path.is_file():
        raise ImportInputError(f"{path}: no such file")
    try:
        mesh = Archive(str(path)) if path.suffix.lower() == ".cdb" else read_binary(str(path)).mesh
        return np.asarray(mesh.nnum).tolist(), np.asarray(mesh.nodes, dtype=float)[:, :3].tolist()
    except Exception as exc:        # the reader raises many kinds for a bad file
        raise ImportInputError(f"{path}: nodes not read from this Ansys file: {_first_line(exc)}") from None


def _abaqus_nodes(path: Path):
    """The *NODE blocks of an Abaqus input deck: lines 'id, x, y[, z]' (z 0 when left out)."""
    ids, xyz, inside = [], [], False
    for k, s in _lines(path, "**", "an Abaqus input deck"):
        if s.startswith("*"):
            inside = s.split(",")[0].strip().upper() == "*NODE"
            continue
        if not inside:
            continue
        parts = [p for p in s.replace(",", " ").split()]
        try:
            if not 3 <= len(parts) <= 4:
                raise ValueError
            nid, x = int(parts[0]), [float(v) for v in parts[1:]] + [0.0] * (4 - len(parts))
        except ValueError:
            raise ImportInputError(f"{path}: line {k}: expected 'node id, x, y, z' in a *NODE block") from None
        _add_node(ids, xyz, nid, x, f"{path}: line {k}")
    return ids, xyz


# ----------------------------------------------------------------------------- the DOF layout

def layout_rows(ids: list[int], nodes_path: Path, dofs_per_node: int | None, dof_map: Path | None):
    """The matrices' row count the DOF layout gives, and from what (for messages): nodes x
    dofs_per_node, or one row a line of the DOF map. The matrices' size lines are checked
    against it before anything is allocated."""
    if dof_map is None:
        n = dofs_per_node * len(ids)
        return n, f"{nodes_path} has {len(ids)} nodes x {dofs_per_node} DOFs = {n}"
    n = sum(1 for _ in _lines(dof_map, "#", DOF_MAP_TEXT))
    return n, f"{dof_map} maps {n} rows (one a line)"


def dof_layout(ids: list[int], ndof: int, matrix_path: Path, nodes_path: Path, dofs_per_node: int | None = None,
               dof_map=None, labels: np.ndarray | None = None) -> np.ndarray:
    """Row of each node's DOF: an int array (nodes, 6), -1 where the node has no such DOF.
    From the matrices' own labels (node, dof) when they have them, else `dofs_per_node`
    (rows node by node in the nodes file's order) or a DOF map file of 'row node dof'.
    Each node has the three translations, and either no rotation or all three."""
    dof = -np.ones((len(ids), 6), dtype=int)
    index = {nid: k for k, nid in enumerate(ids)}
    if labels is not None:
        for row, (nid, c) in enumerate(labels):
            if int(nid) not in index:
                raise ImportInputError(f"{matrix_path}: node {int(nid)} is not in {nodes_path}")
            dof[index[int(nid)], int(c) - 1] = row
        return _whole_nodes(dof, ids, matrix_path)
    if dof_map is None:
        if dofs_per_node not in (3, 6):
            raise ImportInputError(f"--dofs-per-node {dofs_per_node}: 3 or 6")
        if ndof != dofs_per_node * len(ids):
            raise ImportInputError(f"{matrix_path}: {ndof} rows, but {nodes_path} has {len(ids)} nodes x "
                                   f"{dofs_per_node} DOFs = {dofs_per_node * len(ids)}")
        dof[:, :dofs_per_node] = np.arange(ndof).reshape(len(ids), dofs_per_node)
        return dof
    path = Path(dof_map)
    seen = np.zeros(ndof, dtype=bool)
    for k, s in _lines(path, "#", DOF_MAP_TEXT):
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
    return _whole_nodes(dof, ids, path)


def _whole_nodes(dof: np.ndarray, ids: list[int], path: Path) -> np.ndarray:
    for n, nid in enumerate(ids):
        has = dof[n] >= 0
        if has.any() and not (has[:3].all() and (has[3:].all() or not has[3:].any())):
            raise ImportInputError(f"{path}: node {nid}: give its three translations and none or all three rotations")
    return dof


# ----------------------------------------------------------------------------- the body's matrices

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
    check_scale(mm, mpath)
    check_scale(kk, kpath)
    check_symmetric(mm, mpath)
    check_symmetric(kk, kpath)
    mm, kk = (0.5 * (mm + mm.T)).tocsr(), (0.5 * (kk + kk.T)).tocsr()
    check_mass(mm, mpath)
    dof = dof_layout(ids, mm.shape[0], mpath, npath, dofs_per_node, dof_map, labels)
    return ids, xyz, mm, kk, dof


#: The largest entry of a mass or stiffness matrix lies within these (SI units: a steel
#: mesh's K reaches 1e12, a gram's mass 1e-3): beyond, the reduction's products overflow or
#: underflow (LAPACK printed its own error and ARPACK gave another body on each run).
MATRIX_SCALE = (1e-150, 1e150)


def check_scale(a: sp.spmatrix, path: Path) -> None:
    """The matrix's largest entry within MATRIX_SCALE (an ImportInputError naming the file
    otherwise)."""
    big = float(abs(a).max()) if a.nnz else 0.0
    low, high = MATRIX_SCALE
    if big != 0.0 and not low <= big <= high:           # a zero matrix: the mass and stiffness checks say
        raise ImportInputError(f"{path}: its largest entry is {big:.3g}, outside [{low:g}, {high:g}] where the "
                               "reduction keeps its digits: check the matrix's units")


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
