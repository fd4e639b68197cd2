"""pymr modal-import at real sizes (issue 35): the sparse Craig-Bampton reduction and the
formats finite-element codes write.

- The symbolic factor's column counts (the kernel's pymr_cholesky_counts, which size the
  memory before any numeric work) against a dense Cholesky's nonzeros and CHOLMOD's own.
- A 3,006-DOF frame beam: the 20 frequencies against an independent shift-invert solve
  (SuperLU at another shift, Rayleigh-Ritz with exactly rounded products) to 1e-9, its
  round section's equal pairs equal to 1e-9, and the analytic cantilever.
- The two factorisations (CHOLMOD, SuperLU) give the same body.
- The memory limit refuses a model before any numeric work, in one line.
- Abaqus matrix output with an input deck's nodes, Nastran DMIG with GRID cards, and OP4:
  the body equals the Matrix Market one, and the tank with each barrel moves its muzzle
  the same way.
"""
from __future__ import annotations

import math
import re
from pathlib import Path

import numpy as np
import pytest
import scipy.io
import scipy.linalg
import scipy.sparse as sp
import scipy.sparse.linalg as sla

import pymr
from pymr import craig_bampton as cb
from pymr import _kernel
from pymr.cli import main
from pymr.fe_formats import ImportInputError
from pymr.fe_models import frame_beam, solid_block

ROOT = Path(__file__).resolve().parent.parent
TANK = ROOT / "input" / "tank_gun_turret.nml"
HAVE_CHOLMOD = cb.have_cholmod()
try:
    from pymr.fe_formats import pynastran
    pynastran()
    HAVE_PYNASTRAN = True
except ImportInputError:
    HAVE_PYNASTRAN = False


# ----------------------------------------------------------------------------- symbolic counts

def test_column_counts_are_the_dense_factors_nonzeros():
    """A random sparse SPD pattern in a random order: the kernel's counts equal the nonzeros
    of numpy's dense Cholesky factor column by column (values drawn at random: no exact
    cancellation), and CHOLMOD's simplicial factor's when it is installed."""
    rng = np.random.default_rng(7)
    n = 300
    a = sp.random(n, n, density=0.01, random_state=rng, data_rvs=lambda k: rng.uniform(0.1, 1.0, k))
    a = (a + a.T + sp.diags(np.full(n, 10.0))).tocsc()
    order = rng.permutation(n)
    counts = cb.column_counts(a, order)
    low = np.linalg.cholesky(a.toarray()[np.ix_(order, order)])
    np.testing.assert_array_equal(counts, np.count_nonzero(np.abs(low) > 0, axis=0))
    if HAVE_CHOLMOD:
        from sksparse.cholmod import analyze
        sym = analyze(a, mode="simplicial", ordering_method="metis")
        assert cb.column_counts(a, sym.P()).sum() == sym.cholesky(a).L().nnz


def test_the_plan_counts_the_factor_before_making_it():
    """A solid block's interior: the plan's factor entries bound the factor's from above,
    closely (SuperLU on the envelope ordering stores L and U, less the entries that come
    out exactly 0: 0.1 % here; CHOLMOD stores L, its supernodes within the 25 % slack the
    memory estimate allows)."""
    model = solid_block((12, 3, 3))
    inner = np.arange(3 * 16, model.ndof)
    kii = model.k[inner][:, inner].tocsc()
    p = cb.plan(kii, 0, backend="superlu")
    a = kii[p.order][:, p.order].tocsc()
    lu = sla.splu(a, permc_spec="NATURAL", diag_pivot_thresh=0.0, options={"SymmetricMode": True})
    assert 0.99 * p.factor_entries <= lu.L.nnz + lu.U.nnz <= p.factor_entries
    if HAVE_CHOLMOD:
        q = cb.plan(kii, 0, backend="cholmod")
        stored = q.symbolic.cholesky(kii).L().nnz
        assert q.factor_entries <= stored <= cb.SUPERNODAL_SLACK * q.factor_entries


# ----------------------------------------------------------------------------- accuracy

def exact_products(a: sp.csr_matrix, x: np.ndarray) -> np.ndarray:
    """A x with each row's sum exactly rounded: every product split exactly in two (Dekker)
    and the row summed by math.fsum."""
    a = sp.csr_matrix(a)
    out = np.empty(x.shape)
    split = 134217729.0                                    # 2^27 + 1
    for c in range(x.shape[1]):
        u, v = a.data, x[a.indices, c]
        p = u * v
        uh = u * split - (u * split - u)
        vh = v * split - (v * split - v)
        e = ((uh * vh - p) + uh * (v - vh) + (u - uh) * vh) + (u - uh) * (v - vh)
        for i in range(a.shape[0]):
            s = slice(a.indptr[i], a.indptr[i + 1])
            out[i, c] = math.fsum(np.concatenate([p[s], e[s]]).tolist())
    return out


@pytest.fixture(scope="module")
def beam3006(tmp_path_factory):
    folder = tmp_path_factory.mktemp("beam3006")
    model = frame_beam(501)
    return model, model.write(folder)


def test_frequencies_to_1e9_against_an_independent_shift_invert_solve(beam3006):
    """The 3,006-DOF tube clamped at node 1, 20 modes: SuperLU shift-invert at 0.3 omega_1^2
    (not 0, not CHOLMOD) with a Rayleigh-Ritz of exactly rounded products is the reference.
    Measured 2e-11; the round section's pairs equal to 3e-11; the first bending frequency
    within 1e-6 of Euler-Bernoulli's 1.8751^2/(2 pi) sqrt(EI/(rho A L^4)) (the mesh's own
    error, 500 elements)."""
    model, (mp, kp, npath) = beam3006
    body = pymr.modal_import(mp, kp, npath, [1], modes=20)
    f = body.frequencies_hz
    inner = np.arange(6, model.ndof)
    k, m = model.k[inner][:, inner].tocsr(), model.m[inner][:, inner].tocsr()
    shift = 0.3 * (2 * np.pi * f[0]) ** 2
    _, v = sla.eigsh(k.tocsc(), k=20, M=m.tocsc(), sigma=shift, which="LM", tol=0.0)
    kr, mr = v.T @ exact_products(k, v), v.T @ (m @ v)
    ref = np.sqrt(scipy.linalg.eigh(0.5 * (kr + kr.T), 0.5 * (mr + mr.T), eigvals_only=True)) / (2 * np.pi)
    err = np.abs(f - ref) / ref
    pairs = [abs(f[i + 1] - f[i]) / f[i] for i in (0, 2, 4)]
    ei, rho_a = 2.07e11 * np.pi / 4 * (0.11**4 - 0.06**4), 7850.0 * np.pi * (0.11**2 - 0.06**2)
    euler = 1.875104068711961**2 / (2 * np.pi) * np.sqrt(ei / (rho_a * 5.0**4))
    print(f"\n3,006 DOF: f1 {f[0]:.12f} Hz, largest error {err.max():.1e}, pairs {['%.1e' % p for p in pairs]}, "
          f"Euler-Bernoulli {euler:.9f}")
    assert err.max() < 1e-9
    assert max(pairs) < 1e-9
    assert abs(f[0] - euler) / euler < 1e-6


@pytest.mark.skipif(not HAVE_CHOLMOD, reason="scikit-sparse (CHOLMOD) not installed")
def test_cholmod_and_superlu_give_the_same_body(beam3006):
    """Two factorisations of the same interior, two orderings: the frequencies agree to 1e-9
    (each is held to 1e-9 of an independent solve above) and the modes span the same spaces:
    their overlap a^T M b is orthogonal to 1e-8, and couples no two modes whose frequencies
    differ (a round section's pairs may turn within their plane). The lowest pair differs
    most: 6.6e-11 with reference LAPACK, 1.6e-10 with OpenBLAS's."""
    model, _ = beam3006
    args = (model.k, model.m, np.arange(6), np.array([6 * 500 + d for d in range(6)]), 12, None, "k", "node 1")
    a = cb.reduce(*args, backend="cholmod")
    b = cb.reduce(*args, backend="superlu")
    np.testing.assert_allclose(b.frequencies_hz, a.frequencies_hz, rtol=1e-9)
    overlap = a.modes.T @ (model.m @ b.modes)
    np.testing.assert_allclose(overlap.T @ overlap, np.eye(overlap.shape[0]), atol=1e-8)
    f = a.frequencies_hz
    apart = np.abs(f[:, None] - f[None, :]) > 1e-6 * f[:, None]
    assert np.abs(overlap[apart]).max() < 1e-6


# ----------------------------------------------------------------------------- memory and progress

def test_a_model_too_large_for_the_memory_is_refused_before_the_work(beam3006, tmp_path, capsys):
    """--memory-limit below the estimate: one line naming the file, the estimate and the
    limit, exit 1, no file written; the Python call raises ImportInputError."""
    _, (mp, kp, npath) = beam3006
    out = tmp_path / "b.modal"
    rc = main(["modal-import", "--mass", str(mp), "--stiffness", str(kp), "--nodes", str(npath), "--interface", "1",
               "--memory-limit", "0.0001", "-o", str(out)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1 and len(err) == 1 and not out.exists()
    assert re.match(r"pymr: error: .*k\.mtx: the reduction needs about [0-9.e+-]+ GB \(.*M entries in the factor.*"
                    r"more than the 0\.0001 GB available", err[0]), err
    with pytest.raises(ImportInputError, match="the reduction needs about"):
        pymr.modal_import(mp, kp, npath, [1], memory_limit=1e-4)
    with pytest.raises(ImportInputError, match=r"memory_limit=-1: a positive number of GB"):
        pymr.modal_import(mp, kp, npath, [1], memory_limit=-1)


def test_progress_bars_for_the_factorisation_and_the_eigensolve(beam3006, capsys):
    """progress=True draws the two stages on stderr; the body is the same as without."""
    _, (mp, kp, npath) = beam3006
    a = pymr.modal_import(mp, kp, npath, [1], modes=6, progress=True)
    err = capsys.readouterr().err
    assert "factorising K_ii" in err and "eigensolve (6 modes)" in err and "solves" in err
    b = pymr.modal_import(mp, kp, npath, [1], modes=6)
    np.testing.assert_array_equal(a.frequencies_hz, b.frequencies_hz)


# ----------------------------------------------------------------------------- formats

BARREL = dict(length=5.3, e=2.07e11, rho=7850.0, r_outer=0.11, r_inner=0.06)


@pytest.fixture(scope="module")
def barrel(tmp_path_factory):
    """The tank's barrel as a 21-node frame beam, its entries rounded to the 10 digits a
    Nastran large-field DMIG card holds for a negative number (so that every format carries
    the same numbers), written as Matrix Market."""
    folder = tmp_path_factory.mktemp("barrel")
    model = frame_beam(21, **BARREL)
    for a in (model.k, model.m):
        a.data = np.array([float(f"{x:.9e}") for x in a.data])
    return folder, model, model.write(folder)


def lower_entries(a: sp.spmatrix):
    c = sp.tril(a).tocoo()
    return c.row, c.col, c.data


def write_abaqus(folder: Path, model) -> tuple[Path, Path, Path]:
    """What Abaqus writes: *MATRIX OUTPUT, FORMAT=MATRIX INPUT lines 'node, dof, node, dof,
    value' of the lower triangle, and an input deck whose *NODE block gives the nodes."""
    paths = []
    for name, a in (("job_MASS2.mtx", model.m), ("job_STIF2.mtx", model.k)):
        r, c, v = lower_entries(a)
        lines = [f"{r_ // 6 + 1},{r_ % 6 + 1}, {c_ // 6 + 1},{c_ % 6 + 1}, {float(v_)!r}\n" for r_, c_, v_ in zip(r, c, v)]
        (folder / name).write_text("".join(lines))
        paths.append(folder / name)
    deck = ["*HEADING\nbarrel\n*NODE, NSET=ALL\n"] + [f"{i}, {x!r}, {y!r}, {z!r}\n" for i, (x, y, z) in
                                                     zip(model.ids.tolist(), model.xyz.tolist())]
    (folder / "job.inp").write_text("".join(deck) + "*ELEMENT, TYPE=B31\n1, 1, 2\n")
    return paths[0], paths[1], folder / "job.inp"


def write_dmig(folder: Path, model) -> Path:
    """What Nastran punches (PARAM,EXTOUT,DMIGPCH): GRID cards and the DMIG matrices MAAX
    and KAAX, large field, 11 digits, as pyNastran writes them."""
    new_model, _ = pynastran()
    deck = new_model()
    for i, x in zip(model.ids.tolist(), model.xyz.tolist()):
        deck.add_grid(i, x)
    for name, a in (("MAAX", model.m), ("KAAX", model.k)):
        r, c, v = lower_entries(a)
        deck.add_dmig(name, 6, 2, 1, 0, model.ndof, GCj=[(c_ // 6 + 1, c_ % 6 + 1) for c_ in c],
                      GCi=[(r_ // 6 + 1, r_ % 6 + 1) for r_ in r], Real=list(v))
    path = folder / "barrel.pch"
    deck.write_bdf(str(path), size=16, is_double=True, enddata=False, write_header=False)
    return path


def write_op4(folder: Path, model) -> Path:
    from pyNastran.op4.op4 import write_op4 as op4
    path = folder / "barrel.op4"
    op4(str(path), {"MAA": (2, sp.tril(model.m).tocoo()), "KAA": (2, sp.tril(model.k).tocoo())}, is_binary=False)
    return path


def tank_muzzle(tmp_path: Path, modal: Path, name: str) -> np.ndarray:
    """The muzzle's path in the tank scene with the barrel from `modal`."""
    text, count = re.subn(r"&body\s*\n\s*name = 'gun'.*?/\n",
                          f"&body name = 'gun', kind = 'modal', modal_file = '{modal.name}' /\n", TANK.read_text(),
                          flags=re.S)
    assert count == 1
    scene = modal.parent / f"tank_{name}.nml"
    scene.write_text(text.replace("t_end = 1.0", "t_end = 0.3"))
    return pymr.run(scene, tmp_path / f"{name}.csv").marker("muzzle")[0]


def check_same_body(a, b, tol):
    np.testing.assert_allclose(b.frequencies_hz, a.frequencies_hz, rtol=tol)
    for x, y in ((a.first, b.first), (a.second, b.second), (a.psi, b.psi), (a.phi, b.phi)):
        assert np.abs(x - y).max() <= tol * np.abs(x).max()


FORMATS = ["abaqus", "op4", "dmig"]


@pytest.mark.parametrize("fmt", FORMATS)
def test_each_format_gives_the_matrix_market_body_and_its_motion(barrel, tmp_path, fmt):
    """The barrel clamped at node 1, its muzzle node 21 an interface, 8 fixed-interface
    modes, 4 kept: from Abaqus (.mtx and the deck's *NODE), OP4 and DMIG (with GRID cards)
    the body equals the Matrix Market one to 1e-12 (the same numbers in other files), and
    the tank's muzzle follows the same path over 0.3 s to 1e-9 m."""
    if fmt != "abaqus" and not HAVE_PYNASTRAN:
        pytest.skip("pyNastran not installed")
    folder, model, (mp, kp, npath) = barrel
    ref = pymr.modal_import(mp, kp, npath, [1, 21], tmp_path / "mm.modal", modes=8, keep=4)
    if fmt == "abaqus":
        m2, k2, n2 = write_abaqus(tmp_path, model)
        body = pymr.modal_import(m2, k2, n2, [1, 21], tmp_path / "x.modal", modes=8, keep=4)
    elif fmt == "dmig":
        deck = write_dmig(tmp_path, model)
        body = pymr.modal_import(deck, deck, deck, [1, 21], tmp_path / "x.modal", modes=8, keep=4,
                                 mass_name="MAAX", stiffness_name="KAAX")
    else:
        path = write_op4(tmp_path, model)
        body = pymr.modal_import(path, path, npath, [1, 21], tmp_path / "x.modal", modes=8, keep=4,
                                 mass_name="MAA", stiffness_name="KAA")
    check_same_body(ref, body, 1e-12)
    pa, pb = tank_muzzle(tmp_path, tmp_path / "mm.modal", "mm"), tank_muzzle(tmp_path, tmp_path / "x.modal", fmt)
    assert np.abs(pa - pa[0]).max() > 0.01
    assert np.abs(pa - pb).max() < 1e-9


def test_format_faults_are_one_line(barrel, tmp_path):
    """Each reader's faults name the file (and line where there is one)."""
    folder, model, (mp, kp, npath) = barrel
    m2, k2, n2 = write_abaqus(tmp_path, model)
    bad = tmp_path / "bad.mtx"
    cases = [
        ("1,1, 1,1\n", r"bad\.mtx: line 1: expected 'node, dof, node, dof, value'"),
        ("1,7, 1,1, 2.0\n", r"bad\.mtx: line 1: dof 7: 1-6"),
        ("1,1, 1,1, nan\n", r"bad\.mtx: line 1: value nan is not finite"),
        ("** nothing\n", r"bad\.mtx: no matrix entries"),
    ]
    for text, fault in cases:
        bad.write_text(text)
        with pytest.raises(ImportInputError, match=fault):
            pymr.modal_import(bad, k2, n2, [1])
    with pytest.raises(ImportInputError, match=r"not labelled by node and DOF, but .*job_STIF2\.mtx's are"):
        pymr.modal_import(mp, k2, n2, [1])
    (tmp_path / "few.inp").write_text("*NODE\n1, 0.0, 0.0, 0.0\n2, 1.0, 0.0\n*ELEMENT\n")
    with pytest.raises(ImportInputError, match=r"job_MASS2\.mtx: node 3 is not in .*few\.inp"):
        pymr.modal_import(m2, k2, tmp_path / "few.inp", [1])
    if not HAVE_PYNASTRAN:
        return
    deck = write_dmig(tmp_path, model)
    with pytest.raises(ImportInputError, match=r"barrel\.pch: holds 2 DMIG matrices \(KAAX, MAAX\): name the one"):
        pymr.modal_import(deck, deck, deck, [1])
    with pytest.raises(ImportInputError, match=r"barrel\.pch: no DMIG 'KGG' \(the file holds KAAX, MAAX\)"):
        pymr.modal_import(deck, deck, deck, [1], mass_name="MAAX", stiffness_name="KGG")
    op4 = write_op4(tmp_path, model)
    with pytest.raises(ImportInputError, match=r"barrel\.op4: 126 rows, but .*few\.inp has 2 nodes x 6 DOFs = 12"):
        pymr.modal_import(op4, op4, tmp_path / "few.inp", [1], mass_name="MAA", stiffness_name="KAA")


# ----------------------------------------------------------------------------- Ansys

try:
    from ansys.mapdl.reader import examples as ansys_examples
    from ansys.mapdl.reader import read_binary
    HAVE_ANSYS = True
except ImportError:
    HAVE_ANSYS = False

ANSYS_SCENE = """&scene title = 'Ansys beam', t_end = 1.0e-6, gravity = 0.0, 0.0, -9.81, start = 'static' /
&integrator method = 'single', h_fast = 5.0e-7, h_slow = 5.0e-7 /
&effects gravity = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'beam', kind = 'modal', modal_file = '{file}' /
&joint name = 'hold', kind = 'fixed', parent = 'ground', child = 'beam' /
&marker name = 'tip', body = 'beam', at = {tip} /
&output dt = 1.0e-6 /
"""


@pytest.mark.skipif(not HAVE_ANSYS, reason="ansys-mapdl-reader not installed")
def test_ansys_full_file_with_its_constrained_face_held(tmp_path):
    """The full file ansys-mapdl-reader ships (321 nodes of solid elements; 21 nodes
    constrained in Ansys, their rows 0) with the result file's nodes:
    - not held, the constrained rows are one line naming the first;
    - held (the first of them the origin, the rest clamped, the far corner an interface):
      held alone, the frequencies equal a dense eigensolve of the interior to 1e-9; the body equals
      the one from the same matrices written as Matrix Market with a DOF map, to
      1e-12; and the static sag of the far corner under gravity, in a scene, equals the
      file's own K u = M g to 1e-9 of it (constraint modes make it exact), beside the 8 ulps
      of the 1 m position it is read from."""
    full, rst = Path(ansys_examples.fullfile), Path(ansys_examples.rstfile)
    dof_ref, k, m = read_binary(str(full)).load_km(as_sparse=True, sort=True)
    held = np.unique(dof_ref[k.diagonal() == 0, 0]).tolist()
    mesh = read_binary(str(rst)).mesh
    xyz = dict(zip(mesh.nnum.tolist(), np.asarray(mesh.nodes)[:, :3].tolist()))
    tip = max(xyz, key=lambda n: np.linalg.norm(np.subtract(xyz[n], xyz[held[0]])))
    with pytest.raises(ImportInputError, match=r"file\.full: row \d+ \(node \d+ u_[xyz]\) has no stiffness, and "
                                               r"\d+ rows in all: DOFs constrained in the FE code\?"):
        pymr.modal_import(full, full, rst, [tip])
    body = pymr.modal_import(full, full, rst, [held[0], tip], tmp_path / "ansys.modal", modes=10, clamp=held[1:])
    # the same matrices as Matrix Market (lower triangles) and a DOF map
    for name, a in (("k.mtx", k), ("m.mtx", m)):
        scipy.io.mmwrite(tmp_path / name, sp.tril(a.T).tocoo(), symmetry="symmetric")
    (tmp_path / "map.txt").write_text("".join(f"{r + 1} {n} {d + 1}\n" for r, (n, d) in enumerate(dof_ref.tolist())))
    (tmp_path / "nodes.csv").write_text("".join(f"{n}, {x!r}, {y!r}, {z!r}\n" for n, (x, y, z) in xyz.items()))
    mm = pymr.modal_import(tmp_path / "m.mtx", tmp_path / "k.mtx", tmp_path / "nodes.csv", [held[0], tip],
                           tmp_path / "mm.modal", modes=10, clamp=held[1:], dof_map=tmp_path / "map.txt")
    check_same_body(mm, body, 1e-12)
    # held alone: the fixed-interface modes, against a dense eigensolve of every DOF but the held ones
    rows = {(n, d): r for r, (n, d) in enumerate(dof_ref.tolist())}
    free = np.setdiff1d(np.arange(k.shape[0]), [rows[(n, d)] for n in held for d in range(3)])
    kf, mf = (sp.csr_matrix(a + sp.triu(a, 1).T) for a in (k, m))
    lam = scipy.linalg.eigh(kf[free][:, free].toarray(), mf[free][:, free].toarray(), eigvals_only=True,
                            subset_by_index=[0, 9])
    solo = pymr.modal_import(full, full, rst, [held[0]], modes=10, clamp=held[1:])
    np.testing.assert_allclose(solo.frequencies_hz, np.sqrt(lam) / (2 * np.pi), rtol=1e-9)
    # the static sag: the scene against K u = M g over every DOF but the held ones
    g = np.zeros(k.shape[0])
    g[[rows[(n, 2)] for n in xyz if (n, 2) in rows]] = -9.81
    u = sla.spsolve(kf[free][:, free].tocsc(), (mf @ g)[free])
    want = np.array([u[np.searchsorted(free, rows[(tip, d)])] for d in range(3)])
    scene = tmp_path / "ansys.nml"
    at = ", ".join(repr(float(v) - float(o)) for v, o in zip(xyz[tip], xyz[held[0]]))
    scene.write_text(ANSYS_SCENE.format(file="ansys.modal", tip=at))
    pos = pymr.run(scene, tmp_path / "a.csv").marker("tip")[0][-1]
    got = pos - (np.asarray(xyz[tip]) - np.asarray(xyz[held[0]]))
    print(f"\nAnsys beam: f1 {body.frequencies_hz[0]:.9g} Hz; sag {got} m, K u = M g {want}")
    # the sag is 3 nm on positions of 1 m: the marker's position carries it to its ulps
    assert np.abs(got - want).max() < 1e-9 * np.abs(want).max() + 8 * np.finfo(float).eps * np.abs(pos).max()
