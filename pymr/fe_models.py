"""Finite-element models of any size for ``pymr bench modal-import``: sparse mass and stiffness
matrices assembled here (vectorised), with their nodes.

- :func:`frame_beam`: a straight 3-D frame beam along x, Euler-Bernoulli bending in y and z,
  bar and torsion; 6 DOFs a node, consistent mass (the torsion carries rho J_p).
- :func:`frame_lattice`: a 3-D frame of tubes along x, y and z on a grid (a tower); 6 DOFs
  a node, lumped mass.
- :func:`solid_block`: a box of 8-node trilinear solid elements, 3 DOFs a node, isotropic,
  consistent mass, 2 x 2 x 2 Gauss.

Both number their nodes from 1 and lay out their rows node by node (dofs_per_node 6 or 3).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import scipy.io
import scipy.sparse as sp


@dataclass
class FEModel:
    k: sp.csc_matrix
    m: sp.csc_matrix
    ids: np.ndarray           # node ids, from 1
    xyz: np.ndarray           # (nodes, 3)
    dofs_per_node: int

    @property
    def ndof(self) -> int:
        return self.k.shape[0]

    def write(self, folder: Path) -> tuple[Path, Path, Path]:
        """M and K (lower triangles, symmetric Matrix Market) and the nodes (CSV)."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        mp, kp, npath = folder / "m.mtx", folder / "k.mtx", folder / "nodes.csv"
        for path, a in ((mp, self.m), (kp, self.k)):
            scipy.io.mmwrite(path, sp.tril(a).tocoo(), symmetry="symmetric", precision=17)
        lines = (f"{i}, {x!r}, {y!r}, {z!r}\n" for i, (x, y, z) in zip(self.ids.tolist(), self.xyz.tolist()))
        npath.write_text("id, x, y, z\n" + "".join(lines))
        return mp, kp, npath


def assemble(element_k: np.ndarray, element_m: np.ndarray, dofs: np.ndarray, n: int):
    """K and M (CSC) of identical elements whose global rows are `dofs` (elements, nd)."""
    ne, nd = dofs.shape
    rows, cols = np.repeat(dofs, nd, axis=1).ravel(), np.tile(dofs, (1, nd)).ravel()
    k = sp.coo_matrix((np.tile(element_k.ravel(), ne), (rows, cols)), shape=(n, n)).tocsc()
    m = sp.coo_matrix((np.tile(element_m.ravel(), ne), (rows, cols)), shape=(n, n)).tocsc()
    k.sum_duplicates()
    m.sum_duplicates()
    return k, m


def frame_element(le: float, e: float, g: float, rho: float, area: float, iy: float, iz: float):
    """12 x 12 stiffness and consistent mass of a frame element along x, DOFs (u_x u_y u_z
    theta_x theta_y theta_z) at each end (v' = theta_z, w' = -theta_y)."""
    k, m = np.zeros((12, 12)), np.zeros((12, 12))
    bar, bar_m = np.array([[1.0, -1.0], [-1.0, 1.0]]) / le, le / 6 * np.array([[2.0, 1.0], [1.0, 2.0]])
    ax, tx = [0, 6], [3, 9]
    k[np.ix_(ax, ax)] += e * area * bar
    m[np.ix_(ax, ax)] += rho * area * bar_m
    k[np.ix_(tx, tx)] += g * (iy + iz) * bar
    m[np.ix_(tx, tx)] += rho * (iy + iz) * bar_m
    kb = lambda ei: ei / le**3 * np.array([[12, 6 * le, -12, 6 * le], [6 * le, 4 * le**2, -6 * le, 2 * le**2],
                                            [-12, -6 * le, 12, -6 * le], [6 * le, 2 * le**2, -6 * le, 4 * le**2]])
    mb = rho * area * le / 420 * np.array([[156, 22 * le, 54, -13 * le], [22 * le, 4 * le**2, 13 * le, -3 * le**2],
                                           [54, 13 * le, 156, -22 * le], [-13 * le, -3 * le**2, -22 * le, 4 * le**2]])
    flip = np.diag([1.0, -1.0, 1.0, -1.0])
    y, z = [1, 5, 7, 11], [2, 4, 8, 10]
    k[np.ix_(y, y)] += kb(e * iz)
    m[np.ix_(y, y)] += mb
    k[np.ix_(z, z)] += flip @ kb(e * iy) @ flip
    m[np.ix_(z, z)] += flip @ mb @ flip
    return k, m


def frame_beam(nodes: int, length: float = 5.0, e: float = 2.07e11, nu: float = 0.3, rho: float = 7850.0,
               r_outer: float = 0.11, r_inner: float = 0.06) -> FEModel:
    """A tube of `nodes` nodes (6 nodes DOFs each) along x from the origin."""
    ne = nodes - 1
    area = np.pi * (r_outer**2 - r_inner**2)
    i2 = np.pi / 4 * (r_outer**4 - r_inner**4)
    ke, me = frame_element(length / ne, e, e / (2 * (1 + nu)), rho, area, i2, i2)
    dofs = 6 * np.arange(ne)[:, None] + np.arange(12)[None, :]
    k, m = assemble(ke, me, dofs, 6 * nodes)
    xyz = np.column_stack([np.linspace(0.0, length, nodes), np.zeros((nodes, 2))])
    return FEModel(k, m, np.arange(1, nodes + 1), xyz, 6)


def frame_lattice(count: tuple[int, int, int], spacing: float = 0.5, e: float = 2.07e11, nu: float = 0.3,
                  rho: float = 7850.0, r_outer: float = 0.03, r_inner: float = 0.025) -> FEModel:
    """A 3-D frame of (nx, ny, nz) bays of tubes along x, y and z between the nodes of a
    grid (a tower, a truss), 6 DOFs a node, lumped mass: half of each member's mass on each
    end's translations, its rotary inertia on its end's rotations (a consistent frame mass
    couples a node's rotations with two directions at a joint, which the invariants refuse)."""
    nx, ny, nz = count
    area = np.pi * (r_outer**2 - r_inner**2)
    i2 = np.pi / 4 * (r_outer**4 - r_inner**4)
    ke, _ = frame_element(spacing, e, e / (2 * (1 + nu)), rho, area, i2, i2)
    grid = np.arange((nx + 1) * (ny + 1) * (nz + 1)).reshape(nz + 1, ny + 1, nx + 1)   # x fastest
    n = 6 * grid.size
    k = sp.csc_matrix((n, n))
    lumped = np.zeros(n)
    axes = np.eye(3)
    for a, (first, second) in enumerate(((grid[:, :, :-1], grid[:, :, 1:]), (grid[:, :-1, :], grid[:, 1:, :]),
                                         (grid[:-1], grid[1:]))):
        ex, ey = axes[a], axes[(a + 1) % 3]
        rot = np.vstack([ex, ey, np.cross(ex, ey)])                       # local axes as rows
        t = np.kron(np.eye(4), rot)
        ends = np.column_stack([first.ravel(), second.ravel()])
        dofs = (6 * ends[:, :, None] + np.arange(6)).reshape(len(ends), 12)
        k = k + assemble(t.T @ ke @ t, np.zeros((12, 12)), dofs, n)[0]
        for end in (0, 1):
            np.add.at(lumped, (6 * ends[:, end, None] + np.arange(3)).ravel(), rho * area * spacing / 2)
            rotary = rho * spacing / 2 * np.array([i2, i2, i2])
            rotary[a] = rho * spacing / 2 * 2 * i2                       # the polar moment about the member
            np.add.at(lumped, (6 * ends[:, end, None] + 3 + np.arange(3)).ravel(), np.tile(rotary, len(ends)))
    pts = np.meshgrid(np.arange(nx + 1), np.arange(ny + 1), np.arange(nz + 1), indexing="ij")
    xyz = spacing * np.column_stack([g.transpose(2, 1, 0).ravel() for g in pts])
    return FEModel(k.tocsc(), sp.diags(lumped).tocsc(), np.arange(1, grid.size + 1), xyz, 6)


def lattice_for(dofs: int, aspect: float = 4.0) -> tuple[int, int, int]:
    """Bays (n, n, nz) of a frame lattice of about `dofs` DOFs, a tower nz = aspect n high."""
    n = max(1, round(((dofs / 6) / aspect) ** (1 / 3)) - 1)
    nz = max(1, round(dofs / 6 / (n + 1) ** 2) - 1)
    return n, n, nz


def hex_element(h: np.ndarray, e: float, nu: float, rho: float):
    """24 x 24 stiffness and consistent mass of a box element of sides h (3,)."""
    corners = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                        [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float)
    lam, mu = e * nu / ((1 + nu) * (1 - 2 * nu)), e / (2 * (1 + nu))
    d = np.zeros((6, 6))
    d[:3, :3] = lam
    d[np.arange(6), np.arange(6)] += np.r_[2 * mu * np.ones(3), mu * np.ones(3)]
    det = np.prod(h) / 8
    k, m = np.zeros((24, 24)), np.zeros((24, 24))
    for g in np.array([[a, b, c] for a in (-1, 1) for b in (-1, 1) for c in (-1, 1)]) / np.sqrt(3.0):
        q = 1 + corners * g
        shape = np.prod(q, axis=1) / 8
        dx = np.empty((8, 3))
        for a in range(3):
            r = q.copy()
            r[:, a] = corners[:, a]
            dx[:, a] = np.prod(r, axis=1) / 8 * 2 / h[a]
        b = np.zeros((6, 24))
        for a in range(8):
            gx, gy, gz = dx[a]
            b[:, 3 * a:3 * a + 3] = [[gx, 0, 0], [0, gy, 0], [0, 0, gz], [gy, gx, 0], [0, gz, gy], [gz, 0, gx]]
        k += b.T @ d @ b * det
        m += rho * np.kron(np.outer(shape, shape), np.eye(3)) * det
    return k, m


def solid_block(count: tuple[int, int, int], size: tuple[float, float, float] = (2.0, 0.2, 0.2), e: float = 2.07e11,
                nu: float = 0.3, rho: float = 7850.0) -> FEModel:
    """A box of count = (nx, ny, nz) solid elements from the origin, nodes x fastest."""
    nx, ny, nz = count
    ke, me = hex_element(np.asarray(size) / count, e, nu, rho)
    nid = lambda i, j, k: i + (nx + 1) * (j + (ny + 1) * k)
    i, j, k = (a.ravel() for a in np.meshgrid(np.arange(nx), np.arange(ny), np.arange(nz), indexing="ij"))
    corners = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 0, 1), (1, 0, 1), (1, 1, 1), (0, 1, 1)]
    nodes = np.column_stack([nid(i + a, j + b, k + c) for a, b, c in corners])
    dofs = (3 * nodes[:, :, None] + np.arange(3)).reshape(len(nodes), 24)
    count_nodes = (nx + 1) * (ny + 1) * (nz + 1)
    kk, mm = assemble(ke, me, dofs, 3 * count_nodes)
    grid = np.meshgrid(*[np.linspace(0, s, c + 1) for s, c in zip(size, count)], indexing="ij")
    xyz = np.column_stack([g.transpose(2, 1, 0).ravel() for g in grid])
    return FEModel(kk, mm, np.arange(1, count_nodes + 1), xyz, 3)


def block_for(dofs: int, aspect: float = 10.0) -> tuple[int, int, int]:
    """Element counts (nx, n, n) of a block of about `dofs` DOFs, nx = aspect n."""
    n = max(1, round(((dofs / 3) / aspect) ** (1 / 3)))
    nx = max(1, round(dofs / 3 / (n + 1) ** 2) - 1)
    return nx, n, n
