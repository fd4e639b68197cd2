"""The inertia invariants of ``pymr.modal_import`` (issue 29, mutation testing): every block
of the returned ModalBody, W(k, 0) = int rho psi_k s^T included (the file holds only the
blocks a <= b; the body the caller gets holds them all), against expectations that share
nothing with the code:

- a lumped-mass truss (mass matrix diag(m_n) (x) I3): every invariant is a plain sum over
  the nodes, int rho f_i g_j = sum_n m_n f_n,i g_n,j;
- a solid plate of 8-node hexahedra (consistent mass): W(k, 0), W(0, k) and the coupling
  int rho s x psi_k by Gauss quadrature of the solid's own trilinear fields (no mass matrix);
- the file written: its upper blocks, completed by the definition's symmetry
  W(b, a) = W(a, b)^T, are the returned body's.
"""
from __future__ import annotations

import itertools
import re
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_modal_import import HexPlate, write_fe  # noqa: E402

import pymr  # noqa: E402

TOL = 1e-10        # relative to the block's largest entry; measured about 1e-15 (round-off)


def rel_err(got: np.ndarray, want: np.ndarray) -> float:
    return float(np.abs(got - want).max() / np.abs(want).max())


def beyond(errors: dict) -> str:
    """The entries above TOL, for the assertion's message."""
    return "; ".join(f"{name}: relative error {e:.3g}" for name, e in errors.items() if not e < TOL)


def truss():
    """16 nodes on a slightly irregular 4 x 2 x 2 grid, unequal lumped masses, a bar between
    every pair of nodes (EA/L): K and M (3 DOFs a node), nodes (id, x, y, z), masses."""
    xs, ys, zs = [0.0, 0.31, 0.64, 1.0], [0.0, 0.22], [0.0, 0.15]
    xyz = np.array([[x, y, z] for z in zs for y in ys for x in xs])
    xyz += 0.01 * np.column_stack([np.sin(np.arange(16) * 1.3), np.cos(np.arange(16) * 0.7),
                                   np.sin(np.arange(16) * 2.1)]) * (xyz[:, :1] > 0)   # face x = 0 kept flat
    n = len(xyz)
    masses = 0.4 + 0.05 * np.arange(n)
    k = np.zeros((3 * n, 3 * n))
    for a, b in itertools.combinations(range(n), 2):
        d = xyz[b] - xyz[a]
        length = np.linalg.norm(d)
        e = d / length
        kb = 1.0e6 / length * np.outer(e, e)
        ra, rb = slice(3 * a, 3 * a + 3), slice(3 * b, 3 * b + 3)
        k[ra, ra] += kb
        k[rb, rb] += kb
        k[ra, rb] -= kb
        k[rb, ra] -= kb
    m = np.kron(np.diag(masses), np.eye(3))
    nodes = np.column_stack([np.arange(1, n + 1), xyz])
    return k, m, nodes, masses


def test_invariants_of_a_lumped_mass_truss_are_sums_over_its_nodes(tmp_path):
    """Lumped masses m_n at nodes s_n (from the origin node), mode shapes u_n,k: mass
    sum m_n, F(:, 0) = sum m_n s_n, F(:, k) = sum m_n u_n,k, and W(i, j, a, b) =
    sum m_n f_n,i g_n,j for the fields f, g of a, b (field 0 the position s) -- each block,
    W(k, 0) = sum m_n u_n,k s_n^T (not W(0, k)) included. The clamped face x = 0 (nodes 1,
    5, 9, 13) holds the body; nodes 4 and 16 are interfaces (constraint modes)."""
    k, m, nodes, masses = truss()
    mp, kp, npath = write_fe(tmp_path, k, m, nodes)
    body = pymr.modal_import(mp, kp, npath, [1, 4, 16], dofs_per_node=3, modes=5, clamp=[5, 9, 13])
    assert body.exact == "exact"
    nm = body.shapes.shape[1]
    s = nodes[:, 1:] - nodes[0, 1:]
    u = body.shapes.reshape(len(masses), 3, nm)
    assert nm == 11 and np.abs(u[[0, 4, 8, 12]]).max() == 0.0
    want = {"W(0,0)": np.einsum("n,ni,nj->ij", masses, s, s),
            "W(0,k)": np.einsum("n,ni,njk->ijk", masses, s, u),
            "W(k,0)": np.einsum("n,nik,nj->ijk", masses, u, s),
            "W(k,l)": np.einsum("n,nik,njl->ijkl", masses, u, u)}
    w = body.second
    got = {"W(0,0)": w[:, :, 0, 0], "W(0,k)": w[:, :, 0, 1:], "W(k,0)": w[:, :, 1:, 0], "W(k,l)": w[:, :, 1:, 1:]}
    errors = {name: rel_err(got[name], want[name]) for name in want}
    errors["F(:,0)"] = rel_err(body.first[:, 0], masses @ s)
    errors["F(:,k)"] = rel_err(body.first[:, 1:], np.einsum("n,nik->ik", masses, u))
    print("\ntruss invariants, largest relative error against the sums over the nodes: "
          + ", ".join(f"{name} {e:.1e}" for name, e in errors.items()))
    assert body.mass == pytest.approx(masses.sum(), rel=1e-12)
    assert not beyond(errors), beyond(errors)


def test_plate_rotation_mode_coupling_against_quadrature(tmp_path):
    """A solid plate (4 x 2 x 1 hexahedra, consistent mass) clamped at its face x = 0:
    W(i, j, k, 0) = int rho psi_k,i s_j and W(i, j, 0, k) = int rho s_i psi_k,j, and the
    angular coupling int rho s x psi_k taken from each, against 2 x 2 x 2 Gauss quadrature of
    the solid's trilinear fields (exact for the box; no mass matrix involved)."""
    p = HexPlate(count=(4, 2, 1))
    mp, kp, npath = write_fe(tmp_path, p.k, p.m, np.column_stack([p.ids, p.x]))
    lx, ly, _ = p.size
    origin = p.node(0, 0, 0)
    clamp = [n for n in p.face(0, 0.0) if n != origin]
    body = pymr.modal_import(mp, kp, npath, [origin, p.node(lx, ly, 0)], dofs_per_node=3, modes=6, clamp=clamp)
    nm = body.shapes.shape[1]
    shapes = body.shapes.reshape(len(p.ids), 3, nm)
    x0 = p.x[origin - 1]
    # int rho psi_k,i s_j over the undeformed solid: c is the Gauss point, uk (3, nm) the shapes there
    wk0 = p._quad(lambda c, uk: np.einsum("ik,j->ijk", uk, c - x0), np.zeros_like(p.x), shapes)
    coupling = p._quad(lambda c, uk: np.cross(c - x0, uk.T).T, np.zeros_like(p.x), shapes)     # (3, nm)
    w = body.second
    eps = np.zeros((3, 3, 3))
    eps[0, 1, 2] = eps[1, 2, 0] = eps[2, 0, 1] = 1.0
    eps[0, 2, 1] = eps[2, 1, 0] = eps[1, 0, 2] = -1.0
    errors = {"W(k,0)": rel_err(w[:, :, 1:, 0], wk0),
              "W(0,k)": rel_err(w[:, :, 0, 1:], wk0.transpose(1, 0, 2)),
              "s x psi_k from W(k,0)": rel_err(np.einsum("abc,cbk->ak", eps, w[:, :, 1:, 0]), coupling),
              "s x psi_k from W(0,k)": rel_err(np.einsum("abc,bck->ak", eps, w[:, :, 0, 1:]), coupling)}
    print("\nplate, largest relative error against quadrature: "
          + ", ".join(f"{name} {e:.1e}" for name, e in errors.items()))
    assert np.abs(coupling).max() > 0.1 * np.abs(wk0).max()       # the coupling is no small part of the block
    assert not beyond(errors), beyond(errors)


def read_second_moments(path: Path, nm: int) -> np.ndarray:
    """W(3, 3, 0:nm, 0:nm) from a format 2 modal file's lines 'a b W(1, 1:3) W(2, 1:3) W(3, 1:3)'
    (a <= b, row by row), the blocks b < a from the definition's symmetry W(b, a) = W(a, b)^T."""
    text = path.read_text()
    block = text.split("\nsecond_moments\n")[1].split("\n#")[0].split("\npoints")[0]
    w = np.full((3, 3, nm + 1, nm + 1), np.nan)
    for line in block.strip().splitlines():
        v = line.split()
        a, b = int(v[0]), int(v[1])
        w[:, :, a, b] = np.array([float(x) for x in v[2:]]).reshape(3, 3)
        w[:, :, b, a] = w[:, :, a, b].T
    assert re.search(r"^pymr-modal 2$", text, flags=re.M) and not np.isnan(w).any()
    return w


def test_returned_invariants_are_the_written_files_completed_by_symmetry(tmp_path):
    """The body returned and the file written hold the same second moments: the file's blocks
    a <= b, and b < a as their transposes (W(i, j, b, a) = int rho psi_b,i psi_a,j =
    W(j, i, a, b)), equal the returned W(:, :, a, b) to round-off (printed with 17 digits)."""
    k, m, nodes, masses = truss()
    mp, kp, npath = write_fe(tmp_path, k, m, nodes)
    body = pymr.modal_import(mp, kp, npath, [1, 16], tmp_path / "truss.modal", dofs_per_node=3, modes=4,
                             clamp=[5, 9, 13])
    nm = body.shapes.shape[1]
    w = read_second_moments(tmp_path / "truss.modal", nm)
    err = np.abs(body.second - w).max() / np.abs(w).max()
    err_k0 = np.abs(body.second[:, :, 1:, 0] - w[:, :, 1:, 0]).max() / np.abs(w[:, :, 1:, 0]).max()
    print(f"\nreturned W against the file's: largest relative difference {err:.1e} (W(k,0) {err_k0:.1e})")
    assert err < 1e-12, f"returned W differs from the file's by {err:.3g} (W(k,0) by {err_k0:.3g})"
