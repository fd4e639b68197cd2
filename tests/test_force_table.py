"""A nonlinear spring-damper (&force kind='spring_damper' with a force-deflection table
`file`, issue 32): a two-point table against the same `stiffness`, a hardening piecewise
table's energy (its exact integral) conserved and its turning points symmetric, the force
beyond the table on the end segments' lines, the static deflection under gravity against
the table's inverse, and bad tables refused with one line. Scenes are written inline."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import pymr
from refusal import check_refused_in_one_line

# a slider of mass 2 kg on a spring-damper to the ground: anchor 1 m behind its origin,
# free length 1 m, so the slider's coordinate x is the spring's deflection
SLIDER = """
&scene title = 'slider on a nonlinear spring', t_end = {t_end}, gravity = {g}, 0.0, 0.0 {start} /
&integrator method = 'single', {integrator} /
&effects force_elements = .true., gravity = {gravity} /
&body name = 'ground', kind = 'ground' /
&body name = 'slider', kind = 'rigid', mass = 2.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /
&joint name = 'rail', kind = 'prismatic', parent = 'ground', child = 'slider', axis = 1.0, 0.0, 0.0,
       q0 = {x0} {settle} /
&marker name = 'anchor', body = 'ground', at = -1.0, 0.0, 0.0 /
&marker name = 'hook', body = 'slider', at = 0.0, 0.0, 0.0 /
&force name = 'spring', kind = 'spring_damper', marker_i = 'anchor', marker_j = 'hook',
       {spring}, damping = {c}, free_length = 1.0 /
&output dt = 1.0e-2, quantities = 'coordinates', 'energy' /
"""
FIXED = "h_slow = 1.0e-4"
ADAPTIVE = "h_slow = 1.0e-4, adaptive = .true., rtol = 1.0e-10, atol = 1.0e-12"
TIGHT = "h_slow = 1.0e-4, adaptive = .true., rtol = 1.0e-12, atol = 1.0e-14"
# hardening, odd: 100 N/m to 0.05 m, 300 N/m to 0.1 m, 1000 N/m to 0.2 m
HARDENING = [(-0.2, -120.0), (-0.1, -20.0), (-0.05, -5.0), (0.0, 0.0), (0.05, 5.0), (0.1, 20.0), (0.2, 120.0)]


def scene(tmp_path: Path, spring: str, *, x0=0.1, c=0.0, integrator=FIXED, t_end=1.0, g=0.0,
          start="", settle="", name="slider.nml") -> Path:
    path = tmp_path / name
    path.write_text(SLIDER.format(t_end=t_end, g=g, start=start, integrator=integrator,
                                  gravity=".true." if g else ".false.", x0=x0, settle=settle, spring=spring, c=c))
    return path


def table(tmp_path: Path, rows, name="spring.txt") -> str:
    (tmp_path / name).write_text("# deflection (m)  force (N)\n" + "".join(f"{x!r} {f!r}\n" for x, f in rows))
    return f"file = '{name}'"


def test_a_two_point_table_moves_as_its_stiffness(tmp_path):
    """The table (-1 m, -50 N), (1 m, 50 N) is k = 50 N/m: the same motion, damped, to
    round-off, and the same spring energy."""
    lin = pymr.run(scene(tmp_path, "stiffness = 50.0", c=0.4, name="k.nml"))
    tab = pymr.run(scene(tmp_path, table(tmp_path, [(-1.0, -50.0), (1.0, 50.0)]), c=0.4, name="t.nml"))
    x, xt = lin["rail.q"], tab["rail.q"]
    assert np.ptp(x) > 0.15                                   # a real oscillation
    assert np.abs(xt - x).max() < 1e-13, np.abs(xt - x).max()
    assert np.abs(tab["energy.springs"] - lin["energy.springs"]).max() < 1e-13
    assert tab["energy.springs"][0] == pytest.approx(0.5 * 50.0 * 0.1**2, rel=1e-14)


def test_a_hardening_table_keeps_the_energy_it_integrates(tmp_path):
    """From 0.15 m at rest, undamped: the spring energy at the start is the table's
    integral (0.125 + 0.625 + 2.25 = 3 J, by hand), and kinetic plus spring energy stays
    3 J to the integrator's tolerance: the error falls with rtol (the force's kinks at the
    table's points cost the steps that cross them some order: 4.4e-8 at rtol 1e-10, 1.5e-9
    at 1e-12, measured), while the slider crosses every segment and turns at -0.15 m (the
    odd table's equal energy)."""
    errors = []
    for integrator in (ADAPTIVE, TIGHT):
        res = pymr.run(scene(tmp_path, table(tmp_path, HARDENING), x0=0.15, integrator=integrator, t_end=2.0))
        e, springs, x = res["energy.total"], res["energy.springs"], res["rail.q"]
        assert springs[0] == pytest.approx(3.0, rel=1e-14)
        assert springs.min() < 1e-3 * springs[0]              # all of it turns kinetic
        errors.append(np.abs(e - 3.0).max() / 3.0)
    assert errors[0] < 1e-7 and errors[1] < 1e-8, errors
    assert errors[1] < errors[0] / 10, errors
    assert x.min() == pytest.approx(-0.15, abs=2e-3)          # output rows near the turn


def test_beyond_the_table_the_end_segments_continue(tmp_path):
    """At 0.3 m and -0.3 m (the table ends at 0.2 m) the spring's force is the last
    segment's line, 120 + 1000 * 0.1 = 220 N, and its energy the integral of that line:
    3 + 0.05 (70 + 120)/2 + 0.1 (120 + 220)/2 J; a run through there keeps it."""
    path = scene(tmp_path, table(tmp_path, HARDENING), x0=0.3, integrator=TIGHT, t_end=1.0)
    for x in (0.3, -0.3):
        _, p = pymr.model_terms(path, np.array([x]), np.zeros(1))
        assert p[0] == pytest.approx(-np.sign(x) * 220.0, rel=1e-14)
    e_expected = 3.0 + 0.05 * (70.0 + 120.0) / 2 + 0.1 * (120.0 + 220.0) / 2
    _, pe = pymr.model_energy(path, np.array([[0.3], [-0.3]]), np.zeros((2, 1)))
    assert np.allclose(pe, e_expected, rtol=1e-14, atol=0.0), pe
    res = pymr.run(path)
    assert np.abs(res["energy.total"] - e_expected).max() < 1e-8 * e_expected
    assert res["rail.q"].min() < -0.25


def test_the_force_is_minus_the_gradient_of_the_energy(tmp_path):
    """Off the table's points, inside and beyond it, in tension and compression: the
    generalised force P of M qdd = P is minus the central difference of the spring energy
    (the table's integral), to 1e-7."""
    path = scene(tmp_path, table(tmp_path, HARDENING))
    xs = np.array([-0.27, -0.13, -0.07, -0.02, 0.01, 0.04, 0.08, 0.17, 0.31])
    eps = 1e-6
    for x in xs:
        _, p = pymr.model_terms(path, np.array([x]), np.zeros(1))
        _, pe = pymr.model_energy(path, np.array([[x + eps], [x - eps]]), np.zeros((2, 1)))
        grad = (pe[0] - pe[1]) / (2 * eps)
        assert abs(p[0]) > 0.5                               # a real force
        assert abs(p[0] + grad) < 1e-7 * abs(p[0]), (x, p[0], grad)


@pytest.mark.parametrize("how", ["damped run", "static start"])
def test_static_deflection_is_the_tables_inverse(tmp_path, how):
    """Gravity 9.81 m/s^2 along the rail pulls the 2 kg slider: it settles where the
    table's force is m g = 19.62 N, on the 300 N/m segment: x = 0.05 + (19.62 - 5)/300 m,
    after a damped run (c = 40 N s/m, from the free length) and by the static start."""
    x_expected = 0.05 + (2.0 * 9.81 - 5.0) / 300.0
    spring = table(tmp_path, HARDENING)
    if how == "damped run":
        res = pymr.run(scene(tmp_path, spring, x0=0.0, c=40.0, integrator=ADAPTIVE, t_end=4.0, g=9.81))
        x = res["rail.q"][-1]
    else:
        res = pymr.run(scene(tmp_path, spring, x0=0.0, c=40.0, t_end=1.0e-3, g=9.81,
                             start=", start = 'static'", settle=", settle = .true."))
        x = res["rail.q"][0]
    assert x == pytest.approx(x_expected, rel=1e-9), (x, x_expected)


# ----------------------------------------------------------------------- bad input

@pytest.mark.parametrize("rows, extra, expect", [
    ("0.0 0.0\n0.1 10.0\n0.05 20.0\n", "",
     r":12: &force 'spring': file: '.*spring.txt' line 3: deflections must increase, but deflection = 0.05 "
     r"follows deflection = 0.1"),
    ("0.0 0.0\n", "", r":12: &force 'spring': file: '.*spring.txt' has 1 rows; a table needs at least 2"),
    ("0.0 0.0\n0.1 ten\n", "",
     r":12: &force 'spring': file: '.*spring.txt' line 2: expected two finite numbers \(deflection, force\)"),
    ("0.0 0.0\n0.1 10.0 3.0\n", "", r":12: &force 'spring': file: '.*spring.txt' line 2: expected two"),
    ("0.0 0.0\n0.1 10.0\n", "stiffness = 50.0, ", r":12: &force 'spring': stiffness: not with a file"),
])
def test_bad_tables_are_refused_with_one_line(tmp_path, mrsim, rows, extra, expect):
    (tmp_path / "spring.txt").write_text(rows)
    path = scene(tmp_path, extra + "file = 'spring.txt'", name="bad.nml")
    check_refused_in_one_line(mrsim, path, expect)


def test_a_bushing_takes_no_table(tmp_path, mrsim):
    (tmp_path / "spring.txt").write_text("0.0 0.0\n0.1 10.0\n")
    path = scene(tmp_path, "stiffness = 6*50.0, file = 'spring.txt'", name="bad.nml")
    path.write_text(path.read_text().replace("'spring_damper'", "'bushing'").replace(", free_length = 1.0", "")
                    .replace("damping = 0.0", "damping = 6*0.0"))
    check_refused_in_one_line(mrsim, path, r":12: &force 'spring': file: only a 'spring_damper' takes")
