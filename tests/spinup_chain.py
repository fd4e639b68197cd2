"""An independent reference for the spin-up beam of Kane, Ryan and Banerjee (1987): a
planar chain of N rigid segments joined by rotational springs, its first joint on a hub
whose angle is prescribed. numpy and scipy only; nothing here comes from pymr.

Model (plane of rotation, hub at the origin, hub radius zero):

- Segment i (i = 1..N) has length l = L/N, mass m = rho A l at its midpoint and the rotary
  inertia of its line mass about the midpoint, J = m l^2 / 12. Its absolute angle is phi_i.
- The chain is geometrically exact and inextensible: the centrifugal tension, and so the
  stiffening, comes out of the exact kinematics; no linearisation and no modes.
- Springs: k = EI/l between neighbouring segments, and k_1 = 2 EI/l between the hub and
  segment 1 (see below), with energy V = 1/2 k_1 (phi_1 - theta)^2 + 1/2 k sum (phi_i - phi_{i-1})^2.

Why the root spring is 2 EI/l. A segment's angle stands for the beam's slope at its
midpoint x_i = (i - 1/2) l. The spring between segments i-1 and i carries the bending energy
of the beam between their midpoints, a length l: 1/2 EI kappa^2 l = 1/2 (EI/l) (dphi)^2.
The root spring carries the clamped root's half cell [0, l/2] (the slope at x = 0 is the
hub's), so 1/2 EI kappa^2 (l/2) = 1/2 (2EI/l) (dphi)^2. Check on the static cantilever
with a tip load P: the tip deflection is sum_j P (L - x_j)^2 / k_j over the hinges
x_j = (j-1) l, which is (P l^3/EI)(N^3/3 + N/6) with k_1 = 2EI/l, an error of 1/(2N^2)
against P L^3/(3EI); with k_1 = EI/l it is (P l^3/EI)(N^3/3 + N^2/2 + N/6), an error of
3/(2N) + 1/(2N^2).
:func:`clamped_frequencies` checks the same on the dynamic frequencies.

Equations of motion (Lagrange, absolute angles). Segment i's midpoint is
r_i = sum_j c_ij l e(phi_j) with c_ij = 1 (j < i), 1/2 (j = i), 0 (j > i), so
T = 1/2 sum_jk l^2 A_jk cos(phi_j - phi_k) phid_j phid_k + 1/2 J sum phid_i^2, where
A_jk = m sum_i c_ij c_ik = m (N - max(j,k) + 1/2) for j != k and m (N - j + 1/4) for j = k.
Lagrange's equations give
  sum_k [l^2 A_jk cos(phi_j - phi_k) + J delta_jk] phidd_k
      = - sum_k l^2 A_jk sin(phi_j - phi_k) phid_k^2 - dV/dphi_j.
The hub enters only through theta(t) in the root spring.

Output: the tip's deflection in the rotating hub frame, u = p_tip . e_perp(theta) =
l sum_j sin(phi_j - theta), positive in the direction of rotation (a lagging beam has u < 0).

Run ``python tests/spinup_chain.py 20 40 80`` for the convergence report (N = 80 takes
about 20 s; a run at N = 160 was stopped unfinished after 45 min). Measured, as the largest
difference of u over 0-20 s over the peak |u| = 0.574 m: N = 20 to 40, 2.5e-3; 40 to 80,
6.3e-4 (second order); Radau against DOP853 at N = 20 and 40, 4e-11.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import eigh

# Kane, Ryan and Banerjee (1987), the spin-up beam
LENGTH = 10.0          # m
EI = 1.4e4             # N m^2
RHO_A = 1.2            # kg/m
RATE = 6.0             # Omega_s, rad/s
RAMP = 15.0            # T_s, s


def spinup_hub(t: float, rate: float = RATE, ramp: float = RAMP) -> tuple[float, float, float]:
    """theta, theta', theta'' of Kane, Ryan and Banerjee's hub:
    theta = (Omega_s/T_s)[t^2/2 + (T_s/2pi)^2 (cos(2 pi t/T_s) - 1)] for t <= T_s, then
    constant rate Omega_s."""
    w = 2.0 * np.pi / ramp
    if t <= ramp:
        c = rate / ramp
        return (c * (t * t / 2 + (np.cos(w * t) - 1.0) / w**2),
                c * (t - np.sin(w * t) / w),
                c * (1.0 - np.cos(w * t)))
    return rate * (t - ramp / 2), rate, 0.0


@dataclass
class Chain:
    """The chain in hub-relative angles psi_i = phi_i - theta(t), the state [psi, psi'].

    The equations above are rewritten with phi = psi + theta: the mass matrix and the
    velocity terms depend on differences of angles only, and V on psi only, so
      M(psi) (psi'' + theta'' 1) = - (l^2 A o sin(psi_j - psi_k)) (psi' + theta')^2 - K psi.
    This is the same model (a change of coordinates), but the state stays of the size of
    the deflection: with absolute angles, which grow to 75 rad over the run, the
    cancellation in K phi - k_1 theta costs 1e-10 N m of roundoff per row and stalls the
    implicit integrator's Newton iteration at rtol 1e-9."""

    n: int
    length: float = LENGTH
    ei: float = EI
    rho_a: float = RHO_A
    root_factor: float = 2.0       # k_1 = root_factor * EI / l

    def __post_init__(self):
        n = self.n
        self.l = self.length / n
        self.m = self.rho_a * self.l
        self.j = self.m * self.l**2 / 12.0
        self.k = self.ei / self.l
        self.k1 = self.root_factor * self.ei / self.l
        idx = np.arange(1, n + 1)
        a = self.m * (n - np.maximum.outer(idx, idx) + 0.5)
        a[np.diag_indices(n)] = self.m * (n - idx + 0.25)
        self.al2 = self.l**2 * a
        kk = np.zeros((n, n))      # V = 1/2 psi^T K psi
        kk[0, 0] = self.k1
        for i in range(1, n):
            kk[i - 1:i + 1, i - 1:i + 1] += self.k * np.array([[1.0, -1.0], [-1.0, 1.0]])
        self.kk = kk

    def _terms(self, psi):
        c, s = np.cos(psi), np.sin(psi)
        cos_jk = np.outer(c, c) + np.outer(s, s)             # cos(psi_j - psi_k)
        sin_jk = np.outer(s, c) - np.outer(c, s)             # sin(psi_j - psi_k)
        mm = self.al2 * cos_jk
        mm[np.diag_indices(self.n)] += self.j
        return mm, self.al2 * cos_jk, self.al2 * sin_jk

    def mass(self, psi: np.ndarray) -> np.ndarray:
        return self._terms(psi)[0]

    def accelerations(self, psi, psid, hub_rate, hub_acc) -> np.ndarray:
        """psi'' for the state (psi, psi') and the hub's rate and acceleration."""
        mm, _, as_ = self._terms(psi)
        w = psid + hub_rate
        return np.linalg.solve(mm, -as_ @ (w * w) - self.kk @ psi) - hub_acc

    def jacobian(self, psi, psid, hub_rate) -> np.ndarray:
        """d(psi', psi'')/d(psi, psi') of the first-order system, exact (for the implicit
        integrator). With psi'' + theta'' = M^-1 h =: a,
        d psi''/d psi = M^-1 (dh/dpsi - (dM/dpsi) a) and d psi''/d psi' = M^-1 dh/dpsi'."""
        n = self.n
        mm, ac, as_ = self._terms(psi)
        w = psid + hub_rate
        w2 = w * w
        a = np.linalg.solve(mm, -as_ @ w2 - self.kk @ psi)
        # dh_j/dpsi_i = A_ji cos_ji w_i^2 (i != j); -sum_{k != j} A_jk cos_jk w_k^2 (i = j); -K
        dh = ac * w2[None, :]
        dh[np.diag_indices(n)] = -(ac @ w2 - np.diag(ac) * w2)
        dh -= self.kk
        # (dM/dpsi_i a)_j = A_ji sin_ji a_i (i != j); -sum_k A_jk sin_jk a_k (i = j; sin_jj = 0)
        dm = as_ * a[None, :]
        dm[np.diag_indices(n)] = -(as_ @ a)
        jac = np.zeros((2 * n, 2 * n))
        jac[:n, n:] = np.eye(n)
        jac[n:, :n] = np.linalg.solve(mm, dh - dm)
        jac[n:, n:] = np.linalg.solve(mm, -2.0 * as_ * w[None, :])
        return jac

    def tip_deflection(self, psi: np.ndarray) -> np.ndarray:
        """u = tip position . e_perp(theta) = l sum sin(psi_j); psi of shape (N,) or (N, m)."""
        return self.l * np.sin(np.asarray(psi)).sum(axis=0)

    def energy(self, psi, psid, hub_rate) -> np.ndarray:
        """Kinetic plus spring energy, psi and psid of shape (N, m)."""
        w = psid + hub_rate
        c, s = np.cos(psi), np.sin(psi)
        wc, ws = w * c, w * s
        ke = 0.5 * (np.einsum("jm,jk,km->m", wc, self.al2, wc) + np.einsum("jm,jk,km->m", ws, self.al2, ws)
                    + self.j * (w * w).sum(axis=0))
        return ke + 0.5 * np.einsum("jm,jk,km->m", psi, self.kk, psi)


def clamped_frequencies(n: int, root_factor: float = 2.0, count: int = 3) -> np.ndarray:
    """Lowest natural frequencies (rad/s) of the chain at rest with the hub held still."""
    ch = Chain(n, root_factor=root_factor)
    w2 = eigh(ch.kk, ch.mass(np.zeros(n)), eigvals_only=True, subset_by_index=[0, count - 1])
    return np.sqrt(w2)


@dataclass
class ChainRun:
    t: np.ndarray           # output times (s)
    u: np.ndarray           # tip deflection in the hub frame (m), + in the direction of rotation
    theta: np.ndarray       # hub angle (rad)
    psi: np.ndarray         # hub-relative segment angles, shape (N, len(t))
    psid: np.ndarray
    chain: Chain
    nfev: int


def simulate(n: int = 40, t_end: float = 20.0, dt_out: float = 0.05, rtol: float = 1e-9,
             atol: float = 1e-11, method: str = "Radau", rate: float = RATE, ramp: float = RAMP,
             root_factor: float = 2.0) -> ChainRun:
    """Integrate the chain from rest, undeformed, through the spin-up (Radau with the
    exact Jacobian by default; 'DOP853' gives the same to 4e-11 of the peak but is 4x
    (N = 20) to 20x (N = 40) slower: the chain's top mode, 1.2e4 rad/s at N = 40 and
    4.8e4 rad/s at N = 80, bounds an explicit step)."""
    ch = Chain(n, root_factor=root_factor)

    def f(t, y):
        _, rate_t, acc_t = spinup_hub(t, rate, ramp)
        return np.concatenate([y[n:], ch.accelerations(y[:n], y[n:], rate_t, acc_t)])

    def jac(t, y):
        return ch.jacobian(y[:n], y[n:], spinup_hub(t, rate, ramp)[1])

    options = {"jac": jac} if method in ("Radau", "BDF", "LSODA") else {}
    t_out = np.arange(0.0, t_end + 0.5 * dt_out, dt_out)
    y = np.zeros(2 * n)
    states, nfev = [], 0
    # two legs, split at the ramp's end, where the hub's jerk has a kink
    edges = [0.0, ramp, t_end] if ramp < t_end else [0.0, t_end]
    for leg, (a, b) in enumerate(zip(edges[:-1], edges[1:])):
        sol = solve_ivp(f, (a, b), y, method=method, rtol=rtol, atol=atol, dense_output=True, **options)
        if not sol.success:
            raise RuntimeError(sol.message)
        sel = (t_out >= a if leg == 0 else t_out > a) & (t_out <= b)
        states.append(sol.sol(t_out[sel]))
        y = sol.y[:, -1]
        nfev += sol.nfev
    state = np.concatenate(states, axis=1)
    theta = np.array([spinup_hub(ti, rate, ramp)[0] for ti in t_out])
    return ChainRun(t_out, ch.tip_deflection(state[:n]), theta, state[:n], state[n:], ch, nfev)


if __name__ == "__main__":   # pragma: no cover - the convergence report, by hand
    import sys
    import time

    w_exact = 1.875104069**2 * np.sqrt(EI / (RHO_A * LENGTH**4))
    print("first clamped frequency, relative error: N, k1 = 2EI/l, k1 = EI/l")
    for n in (10, 20, 40, 80):
        print(n, [float(clamped_frequencies(n, rf)[0] / w_exact - 1) for rf in (2.0, 1.0)])
    runs = {}
    for arg in sys.argv[1:] or ["20", "40"]:
        n, method = (arg.split(":") + ["Radau"])[:2]
        t0 = time.process_time()
        runs[arg] = simulate(int(n), method=method, dt_out=0.01)
        print(f"{arg}: cpu {time.process_time() - t0:.2f} s, nfev {runs[arg].nfev}, "
              f"peak |u| {np.abs(runs[arg].u).max():.9f} m")
    keys = list(runs)
    for a, b in zip(keys[:-1], keys[1:]):
        print(f"{a} against {b}: max |du| / peak = "
              f"{np.abs(runs[a].u - runs[b].u).max() / np.abs(runs[b].u).max():.3e}")
