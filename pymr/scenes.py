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


# ---------------------------------------------------------------- the tank on the move

#: Firing time (s) of input/tank_on_the_move.nml, the vehicle's speed (m/s) and its wheel
#: stations (m, along the chassis x axis).
TANK_FIRE_TIME = 0.8
TANK_SPEED = 10.0
TANK_STATIONS = {"front": 2.0, "rear": -2.0}


def terrain_heights(t: np.ndarray, station: float, *, speed: float = TANK_SPEED, bump_at: float = 4.0,
                    height: float = 0.10, length: float = 1.2) -> np.ndarray:
    """Height (m) of the ground under a wheel station at time t: a 1 - cos bump of the given
    height and length whose start is bump_at metres ahead of the chassis origin at t = 0."""
    x = speed * t + station - bump_at
    inside = (x > 0.0) & (x < length)
    return np.where(inside, 0.5 * height * (1.0 - np.cos(2.0 * np.pi * np.clip(x, 0.0, length) / length)), 0.0)


def interior_ballistics(*, bore_radius: float = 0.06, projectile: float = 6.0, charge: float = 8.0,
                        peak_pressure: float = 400e6, peak_time: float = 2.0e-3, seat: float = 0.4,
                        bore_end: float = 5.3, dt: float = 1.0e-6) -> dict[str, np.ndarray]:
    """A lumped interior ballistics of the shot, from the firing (t = 0) to shot exit:
    the base pressure p(t) = p_max (t/t_p)^2 exp(2 (1 - t/t_p)) accelerates the projectile
    and a third of the charge (Lagrange's approximation, a = p A / (m_p + C/3)); the breech
    pressure is p (1 + C/(2 m_p)). Integrated with the trapezoid rule in the acceleration
    (exact for a piecewise-linear acceleration) until the travel reaches bore_end. Returns
    time t, travel s (m along the barrel axis), speed v, acceleration a and breech force
    (N) f, sampled at the integration steps."""
    area = np.pi * bore_radius**2

    def base(tt: float) -> float:
        return peak_pressure * (tt / peak_time) ** 2 * np.exp(2.0 * (1.0 - tt / peak_time))

    t, s, v, a = 0.0, seat, 0.0, 0.0
    rows = [(t, s, v, a)]
    while s < bore_end:
        a2 = base(t + dt) * area / (projectile + charge / 3.0)
        s += v * dt + dt * dt * (a / 3.0 + a2 / 6.0)
        v += 0.5 * dt * (a + a2)
        t, a = t + dt, a2
        rows.append((t, s, v, a))
    t, s, v, a = np.array(rows).T
    f = area * np.array([base(x) for x in t]) * (1.0 + charge / (2.0 * projectile))
    return {"t": t, "s": s, "v": v, "a": a, "f": f, "projectile": np.float64(projectile)}


def tank_on_the_move_tables(folder, *, blowdown: float = 3.0e-3, t_end: float = 1.2) -> dict[str, float]:
    """Write the tables of input/tank_on_the_move.nml into folder: the ground height under the
    front and rear wheel stations (terrain_front.txt, terrain_rear.txt: time, height), the
    shot's travel down the barrel (ballistics.txt: time, travel) and the force on the breech
    (breech_force.txt: time, force). The breech force is the gas force on the breech, decaying
    as exp(-t/blowdown) after shot exit, less the projectile's drive force m_p a: the moving
    load's travel is driven through the barrel (the barrel carries the force along the path
    that keeps the shot on its travel, so it is pushed back by m_p a), so the recoiling parts
    feel the breech's gas force alone. Returns the
    shot exit time (s, after firing) and the muzzle velocity (m/s)."""
    from pathlib import Path
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    times = np.linspace(0.0, t_end, int(round(t_end / 0.005)) + 1)
    for name, station in TANK_STATIONS.items():
        _write_table(folder / f"terrain_{name}.txt", times, terrain_heights(times, station),
                     f"ground height (m) under the {name} wheel station at {TANK_SPEED} m/s")
    sh = interior_ballistics()
    pick = np.unique(np.r_[np.arange(0, sh["t"].size, 50), sh["t"].size - 1])
    t_exit = float(sh["t"][-1])
    # the travel table runs on past the muzzle (the same law, 1 m further), so that the
    # spline through it has no end condition near shot exit
    on = interior_ballistics(bore_end=6.3)
    _write_table(folder / "ballistics.txt", TANK_FIRE_TIME + on["t"][::50], on["s"][::50],
                 "the shot's travel (m) along the barrel's x axis from firing to 1 m past the muzzle")
    after = np.linspace(0.0, 8.0 * blowdown, 33)[1:]
    tf = np.r_[sh["t"][pick], t_exit + after]
    ff = np.r_[sh["f"][pick] - sh["projectile"] * sh["a"][pick], sh["f"][-1] * np.exp(-after / blowdown)]
    _write_table(folder / "breech_force.txt", np.r_[0.0, TANK_FIRE_TIME + tf], np.r_[0.0, ff],
                 "force (N) on the breech, backwards: gas force - the projectile's drive force")
    return {"exit_after_firing": t_exit, "muzzle_velocity": float(sh["v"][-1])}


def _write_table(path, t: np.ndarray, y: np.ndarray, what: str) -> None:
    lines = [f"# {what}", "# written by pymr.scenes.tank_on_the_move_tables"]
    lines += ["%.9g %.9g" % (a, b) for a, b in zip(t, y)]
    path.write_text("\n".join(lines) + "\n")
