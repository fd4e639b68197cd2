"""Scene generators for tests and benchmarks (namelist text)."""
from __future__ import annotations

import numpy as np

from ._args import nml_value


def spatial_chain(n_bodies: int, *, free_base: bool = True, gravity: bool = True, t_end: float = 1.0,
                  h: float = 1e-3, adaptive: bool = False, rtol: float = 1e-8, seed: int = 1) -> str:
    """A chain of ``n_bodies`` rigid bodies with non-parallel revolute axes, on a free
    (floating) base when ``free_base``; masses, inertias and joint points vary along it."""
    rng = np.random.default_rng(seed)

    def f(*vals: float) -> str:
        return ", ".join("%.6g" % float(v) for v in vals)

    lines = ["&scene title='spatial chain of %d bodies', t_end=%r, gravity=0.0, -9.81, 0.0 /" % (n_bodies, t_end),
             "&integrator method='single', h_slow=%g, adaptive=%s, rtol=%g, atol=%g /"
             % (h, nml_value(adaptive), rtol, rtol * 1e-2),
             "&effects gravity=%s /" % nml_value(gravity),
             "&body name='ground', kind='ground' /"]
    for i in range(n_bodies):
        m = 1.0 + 0.5 * rng.random()
        a, b, c = 0.05 + 0.05 * rng.random(3)
        com = f(0.25 + 0.1 * rng.random(), 0.05 * rng.standard_normal(), 0.05 * rng.standard_normal())
        inertia = f(b + c, a + c, a + b, *(0.01 * rng.standard_normal(3)))
        lines.append("&body name='b%d', kind='rigid', mass=%s, com=%s, inertia=%s /" % (i + 1, f(m), com, inertia))
    axes = [(0, 0, 1), (0, 1, 0), (1, 0, 1), (1, 1, 0), (0, 1, 1)]
    for i in range(n_bodies):
        parent = "ground" if i == 0 else "b%d" % i
        if i == 0 and free_base:
            lines.append("&joint name='j1', kind='free', parent='ground', child='b1', at=0.0, 1.0, 0.0, "
                         "q0=0.1, -0.2, 0.05, 0.3, -0.2, 0.4, qd0=0.2, 0.1, -0.3, 0.5, -0.4, 0.3 /")
            continue
        ax = axes[i % len(axes)]
        q0 = 0.4 * rng.standard_normal()
        qd0 = 0.8 * rng.standard_normal()
        at = (0.5, 0.02 * rng.standard_normal(), 0.02 * rng.standard_normal()) if i else (0.0, 1.0, 0.0)
        lines.append("&joint name='j%d', kind='revolute', parent='%s', child='b%d', at=%s, axis=%s, q0=%s, "
                     "qd0=%s /" % (i + 1, parent, i + 1, f(*at), f(*ax), f(q0), f(qd0)))
    return "\n".join(lines) + "\n"


#: The serial chain of ``pymr bench chain``: uniform rods of this length (m), mass (kg) and
#: radius (m), the rods' inertias those of a slender cylinder.
ROD_LENGTH, ROD_MASS, ROD_RADIUS = 0.5, 1.0, 0.02


def serial_chain(links: int, *, t_end: float = 1.0, h: float = 1e-4) -> str:
    """A serial chain of ``links`` uniform rods along their x axes, hanging under gravity
    (-y) from revolute joints whose axes alternate z and x, each at the end of the rod before
    (the benchmark chain of issue 18, and Pinocchio's twin in ``pymr.bench``)."""
    m, length, r = ROD_MASS, ROD_LENGTH, ROD_RADIUS
    i_axial, i_cross = 0.5 * m * r * r, m * length * length / 12.0
    lines = ["&scene title='serial chain of %d rods', t_end=%r, gravity=0.0, -9.81, 0.0 /" % (links, t_end),
             "&integrator method='single', h_slow=%r /" % h,
             "&effects gravity=.true. /",
             "&body name='ground', kind='ground' /"]
    for i in range(links):
        lines.append("&body name='rod%d', kind='rigid', mass=%r, com=%r, 0.0, 0.0, inertia=%r, %r, %r, 0.0, 0.0, "
                     "0.0 /" % (i + 1, m, length / 2, i_axial, i_cross, i_cross))
    for i in range(links):
        parent = "ground" if i == 0 else "rod%d" % i
        axis = "0.0, 0.0, 1.0" if i % 2 == 0 else "1.0, 0.0, 0.0"
        lines.append("&joint name='j%d', kind='revolute', parent='%s', child='rod%d', at=%r, 0.0, 0.0, axis=%s /"
                     % (i + 1, parent, i + 1, 0.0 if i == 0 else length, axis))
    return "\n".join(lines) + "\n"
