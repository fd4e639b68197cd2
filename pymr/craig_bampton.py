"""Sparse Craig-Bampton reduction for ``pymr modal-import``: no dense n x n matrix is formed.

1. The interior stiffness K_ii (every interface DOF held) is factored once, sparse: CHOLMOD
   (supernodal, METIS ordering, through scikit-sparse) when it is installed, else scipy's
   SuperLU on a reverse Cuthill-McKee ordering (its fill is then the envelope).
2. Before the factorisation, the symbolic factor's column counts (the kernel's
   ``pymr_cholesky_counts``) give the memory the reduction needs; a model that would not
   fit the memory available is refused with one line, before any numeric work.
3. The static constraint modes are solved from that factor, all interface columns at once.
4. The fixed-interface modes come from ARPACK in shift-invert mode at 0 (``eigsh``), whose
   every step is one solve with the same factor. Asked for all modes (``modes=None``) or
   nearly all of a small model, the dense eigensolver is used instead.
5. The basis T = [Phi Psi; 0 I] projects K and M as T^T (K T): sparse times dense.

The reduced eigenproblem (size modes + interface DOFs) is dense and small.
"""
from __future__ import annotations

import os
import sys
import threading
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as sla

from . import _kernel as _core
from .errors import SolverError
from .errors import ImportInputError

#: bytes of one stored value and one index of a sparse factor
VALUE, INDEX = 8, 4
#: CHOLMOD's supernodes store some zeros beside the column counts (relaxed amalgamation):
#: measured 1.02 times the counts on a 120k-DOF solid block, 1.12 on a 576-DOF one
SUPERNODAL_SLACK = 1.25
#: the largest interior (DOFs) solved dense when all modes are asked for
DENSE_LIMIT = 6000


@dataclass
class Plan:
    """What the factorisation of K_ii will cost, known before it is made."""
    backend: str            # 'cholmod' or 'superlu'
    order: np.ndarray       # the permutation factored (rows of K_ii)
    factor_entries: int     # entries of L (CHOLMOD) or of L and U (SuperLU)
    flops: float            # sum of squared column counts
    bytes: int              # the whole reduction's estimate
    symbolic: object = None  # CHOLMOD's symbolic factor (its analysis, reused by the numeric one)

    def describe(self) -> str:
        return (f"{self.backend}: {self.factor_entries / 1e6:.3g} M entries in the factor, "
                f"{self.flops:.3g} flops, about {self.bytes / 1e9:.3g} GB in all")


def have_cholmod() -> bool:
    try:
        import sksparse.cholmod  # noqa: F401
    except ImportError:
        return False
    return True


def available_memory() -> int:
    """Bytes this process may still use: /proc/meminfo's MemAvailable, capped by the
    cgroup's memory.max (a batch job's limit) less what the cgroup already uses."""
    avail = None
    try:
        with open("/proc/meminfo") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
    except OSError:
        pass
    if avail is None:
        avail = os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    try:
        limit = open("/sys/fs/cgroup/memory.max").read().strip()
        used = int(open("/sys/fs/cgroup/memory.current").read().strip())
        if limit != "max":
            avail = min(avail, int(limit) - used)
    except (OSError, ValueError):
        pass
    return int(avail)


def column_counts(a: sp.spmatrix, order: np.ndarray) -> np.ndarray:
    """Entries of each column of the Cholesky factor of a[order][:, order] (symbolic)."""
    pa = sp.csc_matrix(a)[order][:, order].tocsc()
    pa.sort_indices()
    return np.asarray(_core.pymr_cholesky_counts(pa.indptr.astype(np.int32) + 1, pa.indices.astype(np.int32) + 1),
                      dtype=np.int64)


def plan(kii: sp.spmatrix, dense_columns: int, backend: str | None = None) -> Plan:
    """The ordering and the memory of the reduction: the factor, the matrices, and
    `dense_columns` dense vectors over the interior (Lanczos basis, modes, basis T)."""
    backend = backend or ("cholmod" if have_cholmod() else "superlu")
    symbolic = None
    if backend == "cholmod":
        from sksparse.cholmod import analyze
        symbolic = analyze(sp.csc_matrix(kii), mode="supernodal", ordering_method="metis")
        order = symbolic.P()
    else:
        from scipy.sparse.csgraph import reverse_cuthill_mckee
        order = reverse_cuthill_mckee(sp.csr_matrix(kii), symmetric_mode=True)
    counts = column_counts(kii, order)
    entries = int(counts.sum()) * (1 if backend == "cholmod" else 2)
    slack = SUPERNODAL_SLACK if backend == "cholmod" else 1.0
    n = kii.shape[0]
    total = int(entries * (VALUE + INDEX) * slack + 3 * kii.nnz * (VALUE + INDEX) + dense_columns * n * VALUE)
    return Plan(backend, np.asarray(order), entries, float(np.sum(counts.astype(float) ** 2)), total, symbolic)


def check_memory(p: Plan, where: str, limit: int | None = None) -> None:
    """Refuse, before any numeric work, a reduction that would not fit `limit` bytes
    (default: what the machine has available)."""
    have = available_memory() if limit is None else int(limit)
    if p.bytes > have:
        raise ImportInputError(f"{where}: the reduction needs about {p.bytes / 1e9:.3g} GB ({p.describe()}), "
                             f"more than the {have / 1e9:.3g} GB available: use a machine with more memory, "
                             "fewer interior DOFs, or install scikit-sparse (CHOLMOD) if it says superlu")


class Ticker:
    """A tqdm bar on stderr for one stage: counted steps, or elapsed time while a single
    long call runs (a thread redraws it twice a second). Silent when `show` is false."""

    def __init__(self, desc: str, show: bool, total: int | None = None, unit: str = "it"):
        self.bar = None
        if show:
            from tqdm import tqdm
            self.bar = tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, leave=True, dynamic_ncols=True)
        self._stop = threading.Event()
        self._thread = None

    def step(self, n: int = 1) -> None:
        if self.bar is not None:
            self.bar.update(n)

    def __enter__(self):
        if self.bar is not None and self.bar.total is None:
            self._thread = threading.Thread(target=self._tick, daemon=True)
            self._thread.start()
        return self

    def _tick(self) -> None:
        while not self._stop.wait(0.5):
            self.bar.refresh()

    def __exit__(self, *exc):
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        if self.bar is not None:
            self.bar.close()
        return False


def factor(kii: sp.spmatrix, p: Plan, what: str, show: bool):
    """A solve x = K_ii^-1 b (b a vector or columns) from one sparse factorisation. A matrix
    that is not positive definite raises ImportInputError with `what` (the message)."""
    with Ticker(f"factorising K_ii ({p.factor_entries / 1e6:.3g} M entries, {p.flops:.2g} flops)", show):
        if p.backend == "cholmod":
            from sksparse.cholmod import CholmodNotPositiveDefiniteError
            try:
                return p.symbolic.cholesky(sp.csc_matrix(kii))
            except CholmodNotPositiveDefiniteError:
                raise ImportInputError(what) from None
        a = sp.csc_matrix(kii)[p.order][:, p.order].tocsc()
        try:
            lu = sla.splu(a, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
        except RuntimeError:
            raise ImportInputError(what) from None
        pivots = lu.U.diagonal()
        if not np.all(pivots > 1e-14 * np.abs(pivots).max()):
            raise ImportInputError(what)
        inverse = np.argsort(p.order)

        def solve(b):
            b = np.asarray(b, dtype=float)
            return lu.solve(np.ascontiguousarray(b[p.order]))[inverse]
        return solve


def fixed_interface_modes(kii, mii, solve, nf: int, with_mass: int, show: bool) -> tuple[np.ndarray, np.ndarray]:
    """The lowest `nf` eigenpairs of K_ii v = lambda M_ii v (ARPACK, shift-invert at 0, to
    machine precision): lambda ascending and v mass-normalised. Its basis holds at most
    `with_mass` vectors (the DOFs with mass span the Krylov space).

    ARPACK solves for theta = 1/lambda and takes a Ritz value as converged when its residual
    is below machine precision times max(theta, eps^(2/3)): an absolute floor, which
    matrices in units where lambda is beyond about 3e10 reach (K in 2^60 and M in 2^-100
    gave frequencies 8e-10 off). The mass matrix is therefore taken times r, the power of
    2 nearest max|K| / max|M| (an exact scaling, so theta = r/lambda is at least about 1
    below the highest mode), and lambda is r times ARPACK's."""
    n = kii.shape[0]
    r = 2.0 ** np.frexp(abs(kii).max() / abs(mii).max())[1]
    ncv = min(n - 1, with_mass, max(2 * nf + 1, 20))
    with Ticker(f"eigensolve ({nf} modes)", show, unit=" solves") as tick:
        def apply(b):
            tick.step()
            return solve(b)
        op = sla.LinearOperator((n, n), matvec=apply, dtype=float)
        try:
            # a fixed start vector: the same model gives the same body, run after run
            start = np.random.default_rng(35).standard_normal(n)
            lam, v = sla.eigsh(sp.csc_matrix(kii), k=nf, M=sp.csc_matrix(mii) * r, sigma=0.0, OPinv=op, which="LM",
                               ncv=ncv, tol=0.0, v0=start)
        except (sla.ArpackNoConvergence, sla.ArpackError) as exc:
            raise SolverError(f"the fixed-interface eigensolve (ARPACK, {nf} modes of {n} DOFs) failed: "
                              f"{str(exc).splitlines()[0]}") from None
    order = np.argsort(lam)
    lam, v = lam[order] * r, v[:, order]
    modal_mass = np.einsum("ij,ij->j", v, mii @ v)
    return lam, v / np.sqrt(modal_mass)


def massive_dofs(mii) -> int:
    """Interior DOFs whose diagonal mass is not 0: the most modes with mass there can be."""
    d = np.abs(sp.csr_matrix(mii).diagonal())
    return int(np.count_nonzero(d > 1e-13 * (d.max() if d.size else 0.0)))


def flexibility_modes(k: np.ndarray, m: np.ndarray, what: str) -> tuple[np.ndarray, np.ndarray]:
    """Dense eigenpairs of K v = lambda M v in the flexibility form M v = mu K v (K positive
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


def projected(a: sp.spmatrix, t: np.ndarray) -> np.ndarray:
    """T^T A T with A T's products and sums in extended precision (numpy's longdouble: 64
    bits of mantissa on x86). A stiff mesh's K holds entries 1e9 times the energy of its
    lowest modes, whose sums cancel: in double, T^T K T moved the lowest frequencies of a
    3,006-DOF beam by 1.6e-6 and split its equal pairs by 4e-8; in longdouble by 2e-11."""
    a = sp.csr_matrix(a)
    at = np.zeros(t.shape, dtype=np.longdouble)
    if a.nnz:
        data = a.data.astype(np.longdouble)
        starts = np.minimum(a.indptr[:-1], a.nnz - 1)
        full = np.diff(a.indptr) > 0
        for c in range(t.shape[1]):
            at[full, c] = np.add.reduceat(data * t[a.indices, c], starts)[full]
    return np.asarray(t.T.astype(np.longdouble) @ at, dtype=float)


@dataclass
class Reduction:
    """The Craig-Bampton body: frequencies (Hz), modes over all DOFs (mass-normalised, zero
    on the clamped DOFs) and the counts kept."""
    frequencies_hz: np.ndarray
    modes: np.ndarray
    counts: dict
    plan: Plan | None = None


def interior_modes(kii, mii, kib, modes, messages, show: bool, memory_limit, backend):
    """The fixed-interface modes (lambda ascending, mass-normalised) and the constraint modes
    -K_ii^-1 K_ib: sparse (a count asked) or dense (all asked, small interiors)."""
    n, nb = kii.shape[0], kib.shape[1]
    if n == 0:
        return np.zeros(0), np.zeros((0, 0)), np.zeros((0, nb)), None
    with_mass = massive_dofs(mii)
    if modes is not None and modes > with_mass:
        raise ImportInputError(messages["count"].format(with_mass))
    # ARPACK needs a basis of 2 modes + 1 vectors, and in shift-invert mode its Krylov space
    # lies in K^-1 M's range: massless DOFs (the small beam's torsion) leave fewer than n, and
    # 10 modes of 24 DOFs with 20 massive failed ("could not build an Arnoldi factorization")
    if modes is None or 2 * modes + 1 > with_mass:
        if n > DENSE_LIMIT:
            raise ImportInputError(f"--modes {'all' if modes is None else modes}: the interior has {n} DOFs; "
                                   f"all modes are solved dense up to {DENSE_LIMIT}: ask for fewer")
        kd, md = kii.toarray(), mii.toarray()
        mu, v = flexibility_modes(kd, md, messages["inner"])
        with_mass = int(np.count_nonzero(mu > 1e-13 * mu[0]))
        nf = with_mass if modes is None else modes
        if nf > with_mass:
            raise ImportInputError(messages["count"].format(with_mass))
        return 1.0 / mu[:nf], v[:, :nf] / np.sqrt(mu[:nf]), -np.linalg.solve(kd, kib.toarray()), None
    p = plan(kii, max(2 * modes + 1, 20) + 2 * (modes + nb) + 4, backend)
    check_memory(p, messages["where"], memory_limit)
    solve = factor(kii, p, messages["inner"], show)
    psi = -np.asarray(solve(kib.toarray()) if nb else np.zeros((n, 0))).reshape(n, nb)
    if modes == 0:
        return np.zeros(0), np.zeros((n, 0)), psi, p
    lam, phi = fixed_interface_modes(kii, mii, solve, modes, with_mass, show)
    if not (np.all(np.isfinite(lam)) and lam.min() > 0 and lam.max() < 1e13 * lam.min()):
        raise ImportInputError(messages["count"].format(int(np.count_nonzero(np.isfinite(lam) & (lam > 0)))))
    return lam, phi, psi, p


def reduce(k, m, clamped: np.ndarray, boundary: np.ndarray, modes: int | None, keep: int | None, kpath, attach: str,
           show: bool = False, memory_limit: int | None = None, backend: str | None = None) -> Reduction:
    """Craig-Bampton reduction of the sparse (K, M) with the `clamped` DOFs fixed (the body
    frame's attachment) and the `boundary` DOFs (other interface nodes) kept as static
    constraint modes; `modes` fixed-interface modes (None: all with mass). The reduced body's
    lowest `keep` modes (None: all) are returned over all DOFs."""
    ndof = k.shape[0]
    free = np.setdiff1d(np.arange(ndof), clamped)
    inner = np.setdiff1d(free, boundary)
    # a matrix of extreme units taken in units of its largest entry (a power of 2: exact), the
    # modes and frequencies given back in its own (ARPACK's start vector underflowed,
    # 'starting vector is zero', for a mass matrix of 6e-139 that MATRIX_SCALE accepts)
    cm, ck = unit_scale(m), unit_scale(k)
    k, m = sp.csr_matrix(k) * ck, sp.csr_matrix(m) * cm
    kii, mii = k[inner][:, inner].tocsc(), m[inner][:, inner].tocsc()
    messages = {"inner": f"{kpath}: not positive definite with every interface node held ({attach}): a mechanism "
                         "or rigid motion of the inner nodes is left free",
                "count": f"--modes {modes}: the inner DOFs have only {{}} modes with mass",
                "where": f"{kpath}"}
    lam, phi, psi, p = interior_modes(kii, mii, k[inner][:, boundary], modes, messages, show, memory_limit, backend)
    nf = len(lam)
    if nf + len(boundary) == 0:
        raise ImportInputError(f"--modes {modes}: the body would have no mode (no interface node besides the origin "
                               "gives a constraint mode): ask for 1 or more")
    order = np.concatenate([inner, boundary])
    t = np.zeros((len(order), nf + len(boundary)))
    t[:len(inner), :nf] = phi
    t[:len(inner), nf:] = psi
    t[len(inner):, nf:] = np.eye(len(boundary))
    ko, mo = k[order][:, order], m[order][:, order]
    kr, mr = projected(ko, t), t.T @ (mo @ t)       # M's sums do not cancel: double will do
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
    full[order] = t @ (x[:, :nr] / np.sqrt(mur[:nr])) * np.sqrt(cm)
    counts = {"fixed_interface_modes": nf, "constraint_modes": len(boundary), "reduced_size": nf + len(boundary),
              "modes_written": nr}
    return Reduction(np.sqrt(cm / (ck * mur[:nr])) / (2 * np.pi), signed(full), counts, p)


#: Largest entries of K and M the reduction takes as they are. Beyond, a matrix is scaled:
#: not within, as scaling moved the highest modes of the 3,006-DOF tube by 4e-10 between
#: CHOLMOD and SuperLU (5e-11 unscaled), near ARPACK's accuracy there.
PLAIN_UNITS = (1e-50, 1e50)


def unit_scale(a) -> float:
    """1 when the largest entry of `a` is within PLAIN_UNITS (or `a` is 0), else the power of
    2 that brings it into [0.5, 1)."""
    big = float(abs(a).max()) if a.nnz else 0.0
    if big == 0.0 or PLAIN_UNITS[0] <= big <= PLAIN_UNITS[1]:
        return 1.0
    return 2.0 ** -np.frexp(big)[1]
