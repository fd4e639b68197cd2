"""Files that contradict themselves (issue 30): every one is bad input, one line naming the
file, the line and the item, exit status 1 (a pymr exception in Python); never a run on
what the reader guessed, a compiler's runtime message, a LAPACK failure or a traceback.

- Modal data files: each line holds exactly the numbers its header's counts give, every
  number is finite, a count fits the file's size before anything is allocated by it, nothing
  follows the points, and the modes are mass-normalised (to the kernel's stated 1e-4).
- Time-history tables: two numbers a line, no third column.
- ``pymr modal-import``: a Matrix Market size line is checked against the DOF layout and the
  file before the dense matrix is allocated; its arguments are checked before any work;
  its output may not be one of its inputs (by any spelling) nor a directory.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import pymr
from pymr.fe_formats import ImportInputError, read_matrix_market

ROOT = Path(__file__).resolve().parent.parent
TANK = ROOT / "input" / "tank_gun_turret.nml"
BEAM = ("  name = 'gun', kind = 'beam'\n  length = 5.3, youngs_modulus = 2.07e11, density = 7850.0\n"
        "  r_outer = 0.11, r_inner = 0.06\n  n_elements = 20, modes_y = 2, modes_z = 2\n")


def pymr_cli(*args, cwd):
    """`pymr ARGS` in a fresh process of this interpreter (so the package under test runs)."""
    return subprocess.run([sys.executable, "-m", "pymr", *map(str, args)], cwd=cwd, capture_output=True, text=True,
                          timeout=300)


def one_line(r) -> str:
    """The single line of stderr of a run refused as bad input (exit status 1)."""
    assert r.returncode == 1, (r.returncode, r.stdout, r.stderr)
    lines = r.stderr.splitlines()
    assert len(lines) == 1, r.stderr
    return lines[0]


# ----------------------------------------------------------------------------- modal files

@pytest.fixture(scope="module")
def gun_modal(tmp_path_factory) -> str:
    """The tank barrel's modal file, as `pymr modal-file input/tank_gun_turret.nml gun` writes it:
    2 comment lines, 'pymr-modal 1' (line 3), 'modes 4' (4), frequencies (5), 'points 101' (6),
    then the 101 points, 28 numbers each (lines 7-107)."""
    tmp = tmp_path_factory.mktemp("gun")
    r = pymr_cli("modal-file", TANK, "gun", "-o", "gun.modal", cwd=tmp)
    assert r.returncode == 0, r.stderr
    text = (tmp / "gun.modal").read_text()
    lines = text.splitlines()
    assert lines[2:4] == ["pymr-modal 1", "modes 4"] and lines[5] == "points 101" and len(lines) == 107
    assert {len(line.split()) for line in lines[6:]} == {28}
    return text


@pytest.fixture
def modal_scene(tmp_path):
    """The tank with its barrel read from g.modal; returns (folder, scene name, the error
    prefix of a fault in g.modal)."""
    text = TANK.read_text()
    assert BEAM in text
    text = text.replace(BEAM, "  name = 'gun', kind = 'modal', modal_file = 'g.modal'\n")
    (tmp_path / "s.nml").write_text(text)
    line = text.splitlines().index("  name = 'gun', kind = 'modal', modal_file = 'g.modal'") + 1   # modal_file's line
    return tmp_path, "s.nml", f"mrsim: error: s.nml:{line}: &body 'gun': modal_file: g.modal: "


def mrsim_run(mrsim, folder, scene):
    return subprocess.run([mrsim, scene, "-o", "out.csv", "--set", "scene.t_end=0.002"], cwd=folder,
                          capture_output=True, text=True, timeout=120)


def set_word(text: str, line: int, word: int, value: str) -> str:
    """`text` with word `word` (1-based) of line `line` (1-based) replaced."""
    lines = text.splitlines()
    words = lines[line - 1].split()
    words[word - 1] = value
    lines[line - 1] = " ".join(words)
    return "\n".join(lines) + "\n"


def edit_lines(text: str, edit) -> str:
    """`text` with each point line (7-107) replaced by edit(numbers)."""
    lines = text.splitlines()
    for i in range(6, len(lines)):
        v = [float(x) for x in lines[i].split()]
        lines[i] = " ".join(repr(x) for x in edit(v))
    return "\n".join(lines) + "\n"


def scale_mode(k: int, s: float):
    """Point-line edit: the translational shape psi of mode k (1-4) times s."""
    def edit(v):
        for c in range(3):
            v[4 + 3 * (k - 1) + c] *= s
        return v
    return edit


def mix_modes(v):
    """Point-line edit: mode 2's psi plus 1 % of mode 1's (no longer orthogonal)."""
    for c in range(3):
        v[7 + c] += 0.01 * v[4 + c]
    return v


POINT = "expected 28 numbers (x y z mass, then psi and phi of each of the 4 modes)"

# (id, corruption of the file's text, expected fault after 'g.modal: '); {size} is the
# corrupted file's size in bytes
MODAL_CORRUPTIONS = [
    ("modes_fewer_than_frequencies", lambda t: t.replace("modes 4", "modes 3"),
     "line 5: frequencies_hz: expected 3 positive frequencies (modes 3), got 4 numbers"),
    ("modes_zero", lambda t: t.replace("modes 4", "modes 0"),
     "line 5: frequencies_hz: expected 0 positive frequencies (modes 0), got 4 numbers"),
    ("modes_fewer_than_the_rows_hold",
     lambda t: re.sub(r"(frequencies_hz.*) \S+\n", r"\1\n", t.replace("modes 4", "modes 3")),
     "line 7: point 1: expected 22 numbers (x y z mass, then psi and phi of each of the 3 modes), got 28"),
    ("modes_zero_rows_hold_four",
     lambda t: re.sub(r"frequencies_hz.*", "frequencies_hz", t.replace("modes 4", "modes 0")),
     "line 7: point 1: expected 4 numbers (x y z mass, then psi and phi of each of the 0 modes), got 28"),
    ("modes_more_than_the_rows_hold", lambda t: t.replace("modes 4", "modes 5").replace(
        "frequencies_hz ", "frequencies_hz 100.0 "),
     "line 7: point 1: expected 34 numbers (x y z mass, then psi and phi of each of the 5 modes), got 28"),
    ("format_version_3", lambda t: t.replace("pymr-modal 1", "pymr-modal 3"),
     "line 3: pymr-modal: expected the format version 1 or 2, got '3'"),
    ("format_version_1.0", lambda t: t.replace("pymr-modal 1", "pymr-modal 1.0"),
     "line 3: pymr-modal: expected the format version 1 or 2, got '1.0'"),
    ("format_version_two_words", lambda t: t.replace("pymr-modal 1", "pymr-modal 1 2"),
     "line 3: pymr-modal: expected the format version 1 or 2, got '1 2'"),
    ("extra_column", lambda t: set_word(t, 9, 28, t.splitlines()[8].split()[27] + " 0.5"),
     f"line 9: point 3: {POINT}, got 29"),
    ("missing_column", lambda t: "\n".join(
        (" ".join(ln.split()[:-1]) if k == 99 else ln) for k, ln in enumerate(t.splitlines())) + "\n",
     f"line 100: point 94: {POINT}, got 27"),
    ("extra_frequency", lambda t: t.replace("frequencies_hz ", "frequencies_hz 3.0 "),
     "line 5: frequencies_hz: expected 4 positive frequencies (modes 4), got 5 numbers"),
    ("count_with_words_after", lambda t: t.replace("modes 4", "modes 4 modes"),
     "line 4: modes: expected a count, got '4 modes'"),
    ("nan_mass", lambda t: set_word(t, 7, 4, "NaN"), "line 7: point 1: mass: NaN is not a finite number"),
    ("inf_psi", lambda t: set_word(t, 8, 5, "Inf"), "line 8: point 2: psi_x of mode 1: Inf is not a finite number"),
    ("minus_inf_phi", lambda t: set_word(t, 50, 28, "-inf"),
     "line 50: point 44: phi_z of mode 4: -inf is not a finite number"),
    ("nan_frequency", lambda t: set_word(t, 5, 3, "nan"),
     "line 5: frequencies_hz: frequency 2: nan is not a finite number"),
    ("overflowing_number", lambda t: set_word(t, 7, 1, "1e999"), "line 7: point 1: x: 1e999 is not a finite number"),
    ("not_a_number", lambda t: set_word(t, 8, 9, "abc"), "line 8: point 2: psi_y of mode 2: 'abc' is not a number"),
    ("fortran_slash", lambda t: set_word(t, 8, 2, "1/2"), "line 8: point 2: y: '1/2' is not a number"),
    ("fortran_repeat", lambda t: set_word(t, 8, 2, "2*0"), "line 8: point 2: y: '2*0' is not a number"),
    ("negative_frequency", lambda t: set_word(t, 5, 3, "-40"),
     "line 5: frequencies_hz: frequency 2: expected a positive frequency (Hz), got -40"),
    ("points_more_than_the_file_holds", lambda t: t.replace("points 101", "points 102"),
     "line 6: points: 102 points, but the file ends after 101 (line 107)"),
    ("points_fewer_than_the_file_holds", lambda t: t.replace("points 101", "points 100"),
     "line 107: more lines than the 100 points of line 6"),
    ("points_2e9", lambda t: t.replace("points 101", "points 2000000000"),
     "line 6: points: 2000000000 lines of 28 numbers cannot be in this file ({size} bytes)"),
    ("modes_2e9", lambda t: t.replace("modes 4", "modes 2000000000"),
     "line 4: modes: 2000000000 frequencies cannot be in this file ({size} bytes)"),
    ("points_beyond_an_integer", lambda t: t.replace("points 101", "points 99999999999"),
     "line 6: points: expected a positive count, got '99999999999'"),
    ("mode_not_mass_normalised", lambda t: edit_lines(t, scale_mode(2, 1.01)),
     "line 6: points: the modes are not mass-normalised: the sum of mass psi_2.psi_2 over the points is 1.0201, "
     "expected 1 (to 0.0001)"),
    ("modes_not_orthogonal", lambda t: edit_lines(t, mix_modes),
     "line 6: points: the modes are not mass-normalised: the sum of mass psi_1.psi_2 over the points is 0.01, "
     "expected 0 (to 0.0001)"),
    ("point_beyond_the_bound_on_lengths", lambda t: set_word(t, 9, 1, "2e6"),
     "line 9: point 3: x: must be in [-1e+6, 1e+6] m, got 2e6"),
    ("masses_below_a_body_s", lambda t: edit_lines(t, lambda v: v[:3] + [v[3] * 1e-300] + v[4:]),
     "line 6: points: their masses sum to 1.111e-297 kg; a body's mass must be in [1e-12, 1e+12] kg"),
    ("word_of_a_megabyte", lambda t: set_word(t, 7, 2, "x" * 10**6),
     "line 7: " + ("point 1: y: '" + "x" * 10**6)[:500] + f" ... ({10**6 + 30} characters)"),
    # 1e-400 read as 0, as Fortran reads it: refused as the scene's values and tables are
    ("below_the_smallest_normal_number", lambda t: set_word(t, 7, 5, "1e-400"),
     "line 7: point 1: psi_x of mode 1: the value 1e-400 is below the smallest normal number (2.22507e-308): "
     "give 0 or a larger magnitude"),
    ("more_modes_than_masses_can_carry", lambda t: "\n".join(t.replace("points 101", "points 1").splitlines()[:7]) + "\n",
     "line 4: modes: 4 modes, but 1 point carries mass: at most 3 modes a point can be mass-normalised"),
]


@pytest.mark.parametrize("corrupt, fault", [c[1:] for c in MODAL_CORRUPTIONS], ids=[c[0] for c in MODAL_CORRUPTIONS])
def test_a_modal_file_that_contradicts_itself_is_one_line_exit_1(gun_modal, modal_scene, mrsim, corrupt, fault):
    """Each corruption of a real modal file: mrsim's exit status 1 and one line naming the
    scene's group, the modal file, its line and the item (never a run, exit 2 or a runtime
    message)."""
    folder, scene, prefix = modal_scene
    text = corrupt(gun_modal)
    assert text != gun_modal
    (folder / "g.modal").write_text(text)
    fault = fault.format(size=len(text.encode()))
    assert one_line(mrsim_run(mrsim, folder, scene)) == prefix + fault
    assert not (folder / "out.csv").exists()


def test_the_real_modal_file_runs_and_python_gets_the_same_line(gun_modal, modal_scene, mrsim):
    """The file as written runs (exit 0); through Python a fault is a SceneError of the same
    one line, and `pymr run` says it with exit status 1."""
    folder, scene, prefix = modal_scene
    (folder / "g.modal").write_text(gun_modal)
    r = mrsim_run(mrsim, folder, scene)
    assert r.returncode == 0, r.stderr
    (folder / "g.modal").write_text(set_word(gun_modal, 7, 4, "NaN"))
    fault = "line 7: point 1: mass: NaN is not a finite number"
    with pytest.raises(pymr.SceneError) as exc:
        pymr.run(folder / scene, folder / "py.csv", overrides={"scene.t_end": 0.002})
    line = re.search(r"s\.nml:(\d+):", prefix).group(1)
    assert str(exc.value) == f"{folder / scene}:{line}: &body 'gun': modal_file: {folder / 'g.modal'}: {fault}"
    r = pymr_cli("run", scene, "-o", "cli.csv", "--set", "scene.t_end=0.002", cwd=folder)
    assert one_line(r) == "pymr: error: " + prefix.removeprefix("mrsim: error: ") + fault


@pytest.mark.parametrize("digits, runs", [(6, True), (4, False)])
def test_mass_normalisation_tolerance_is_the_stated_one(gun_modal, modal_scene, mrsim, digits, runs):
    """The kernel's tolerance, 1e-4 on |M_ij - delta_ij|: the barrel's file rounded to 6
    significant digits (measured 2.0e-6 off) runs; a mode scaled so that its modal mass is
    1 + 0.5e-4 runs, 1 + 2e-4 is refused. Rounded to 4 digits (1.6e-4 off) it is refused."""
    folder, scene, prefix = modal_scene
    rounded = re.sub(r"-?\d\.\d+E[+-]\d+", lambda m: f"{float(m.group(0)):.{digits - 1}e}", gun_modal)
    (folder / "g.modal").write_text(rounded)
    r = mrsim_run(mrsim, folder, scene)
    if runs:
        assert r.returncode == 0, r.stderr
    else:
        assert re.fullmatch(re.escape(prefix) + r"line 6: points: the modes are not mass-normalised: the sum of "
                            r"mass psi_\d\.psi_\d over the points is [-0-9.e]+, expected [01] \(to 0\.0001\)",
                            one_line(r))
    for scale, ok in ((1 + 0.5e-4, True), (1 + 2e-4, False)):
        (folder / "g.modal").write_text(edit_lines(gun_modal, scale_mode(3, float(np.sqrt(scale)))))
        r = mrsim_run(mrsim, folder, scene)
        if ok:
            assert r.returncode == 0, r.stderr
        else:
            assert one_line(r) == prefix + ("line 6: points: the modes are not mass-normalised: the sum of mass "
                                            "psi_3.psi_3 over the points is 1.0002, expected 1 (to 0.0001)")


FORMAT2 = ("pymr-modal 2\nmodes 1\nfrequencies_hz 5.0\ninvariants\nmass 2.0\nfirst_moments\n0 1 0 0\n1 0 0 0\n"
           "second_moments\n0 0 1 0 0 0 0 0 0 0 0\n0 1 0 0 0 0 0 0 0 0 0\n1 1 1 0 0 0 0 0 0 0 0\npoints 1\n"
           "0 0 0 0 0 1 0 0 0 1\n")
FORMAT2_CORRUPTIONS = [
    ("nan_in_w", FORMAT2.replace("1 1 1 0 0 0 0 0", "1 1 1 0 0 0 NaN 0"),
     "line 12: second_moments: W(2, 2, 1, 1): NaN is not a finite number"),
    ("extra_column_in_first_moments", FORMAT2.replace("0 1 0 0\n", "0 1 0 0 0\n"),
     "line 7: first_moments: expected 0 and F(1:3, 0), 4 numbers, got 5"),
    ("extra_column_in_second_moments", FORMAT2.replace("0 1 0 0 0 0 0 0 0 0 0\n", "0 1 0 0 0 0 0 0 0 0 0 0\n"),
     "line 11: second_moments: expected 0 1 and the 9 numbers of W(1:3, 1:3, 0, 1) row by row, 11 numbers, got 12"),
    ("words_after_invariants", FORMAT2.replace("invariants\n", "invariants 2\n"),
     "line 4: invariants: nothing may follow it on its line, got '2'"),
    ("inf_mass", FORMAT2.replace("mass 2.0", "mass inf"), "line 5: mass: inf is not a finite number"),
    # a wrong index with the right count was told as 'expected 1 and F(1:3, 1), 4 numbers, got 4'
    ("wrong_index_in_first_moments", FORMAT2.replace("1 0 0 0\n", "0 0 0 0\n"),
     "line 8: first_moments: expected the line of F(1:3, 1), which begins with 1, got '0' first"),
    ("wrong_index_in_second_moments", FORMAT2.replace("0 1 0 0 0 0 0 0 0 0 0\n", "1 0 0 0 0 0 0 0 0 0 0\n"),
     "line 11: second_moments: expected the line of W(1:3, 1:3, 0, 1), which begins with 0 1, got '1 0' first"),
    ("not_mass_normalised", FORMAT2.replace("1 1 1 0 0 0 0 0 0 0 0", "1 1 0.5 0 0 0 0 0 0 0 0"),
     "line 12: second_moments: the modes are not mass-normalised: W11+W22+W33 of modes 1 and 1 is 0.5, expected 1 "
     "(to 0.0001)"),
    # W(:,:,0,0) with W(2,1) alone set ran with exit 0 and an inertia no symmetric W gives
    ("w00_not_symmetric", FORMAT2.replace("0 0 1 0 0 0 0 0 0 0 0", "0 0 1 0 0 0.4 1 0 0 0 1"),
     "line 10: second_moments: W(1:3, 1:3, 0, 0) is not symmetric: W(1, 2) = 0, W(2, 1) = 0.4 (a column's second "
     "moment with itself is)"),
    # 1e-300 Hz passed as positive, and its (2 pi f)^2 was 0: a free mode (the barrel's muzzle ended 9 m away)
    ("frequency_underflows", FORMAT2.replace("frequencies_hz 5.0", "frequencies_hz 1e-300"),
     "line 3: frequencies_hz: frequency 1: 1e-300 Hz is too small (its (2 pi f)^2 underflows)"),
    # 1e150 Hz was read, and a run from rest failed at t = 0 (exit 2) where LAPACK overflows
    ("frequency_beyond_lapack", FORMAT2.replace("frequencies_hz 5.0", "frequencies_hz 1e150"),
     "line 3: frequencies_hz: frequency 1: 1e150 Hz is too large (its stiffness (2 pi f)^2 is beyond 1e+150, "
     "where LAPACK overflows)"),
    # moments no mass distribution has ran with exit 0 (the joint saw a positive inertia), or
    # failed at t = 0 with exit 2; a mass of 1e-300 kg failed at t = 0 with a NaN mass matrix
    ("mass_below_a_body_s", FORMAT2.replace("mass 2.0", "mass 1e-300"),
     "line 5: mass: must be in [1e-12, 1e+12] kg, got 1e-300"),
    ("point_beyond_the_bound_on_lengths", FORMAT2.replace("points 1\n0 0 0", "points 1\n0 -1e100 0"),
     "line 14: point 1: y: must be in [-1e+6, 1e+6] m, got -1e100"),
    ("central_inertia_negative", FORMAT2.replace("0 1 0 0\n1 0", "0 3 0 0\n1 0"),
     "line 10: second_moments: W(1:3, 1:3, 0, 0), with F(1:3, 0) and the mass, gives an inertia about the centre "
     "of mass with a negative principal moment (-3.5 kg m^2): no mass distribution has it"),
    ("w00_negative", FORMAT2.replace("0 0 1 0 0 0 0 0 0 0 0", "0 0 -1 0 0 0 0 0 0 0 0"),
     "line 10: second_moments: W(1:3, 1:3, 0, 0), with F(1:3, 0) and the mass, gives an inertia about the centre "
     "of mass with a negative principal moment (-1.5 kg m^2): no mass distribution has it"),
    # |F(1, 1)|^2 = 25 > m W(1, 1, 1, 1) = 2: a mode that carries more momentum than the body
    ("modal_first_moment_beyond_the_mass", FORMAT2.replace("1 0 0 0\nsecond", "1 5 0 0\nsecond"),
     "line 4: invariants: the mass matrix of the body's rigid motions and modes is not positive semi-definite: "
     "no mass distribution has these first and second moments (the first moments F(1:3, 1:) or the second "
     "moments W(1:3, 1:3, 0, 1:) too large for the modes' masses)"),
    ("second_moments_beyond_the_file", "pymr-modal 2\nmodes 1000\nfrequencies_hz" + " 1" * 1000 +
     "\ninvariants\nmass 2.0\nfirst_moments\n", "line 2: modes 1000: 501501 second_moments lines of 11 numbers "
     "cannot be in this file ({size} bytes)"),
]


@pytest.mark.parametrize("text, fault", [c[1:] for c in FORMAT2_CORRUPTIONS], ids=[c[0] for c in FORMAT2_CORRUPTIONS])
def test_a_format_2_file_that_contradicts_itself_is_one_line(tmp_path, text, fault):
    """Format 2 (the invariants block that modal-import writes): the same rules, through
    Python's SceneError (the kernel's one line)."""
    scene = tmp_path / "s.nml"
    scene.write_text("&scene t_end = 0.01 /\n&integrator method = 'single', h_slow = 1e-3 /\n"
                     "&body name = 'g', kind = 'ground' /\n&body name = 'b', kind = 'modal', modal_file = 'b.modal' /\n"
                     "&joint name = 'j', kind = 'fixed', parent = 'g', child = 'b' /\n")
    (tmp_path / "b.modal").write_text(FORMAT2)
    pymr.run(scene, tmp_path / "ok.csv")
    (tmp_path / "b.modal").write_text(text)
    with pytest.raises(pymr.SceneError) as exc:
        pymr.run(scene, tmp_path / "x.csv")
    where = f"{scene}:4: &body 'b': modal_file: {tmp_path / 'b.modal'}: "
    assert str(exc.value) == where + fault.format(size=len(text.encode()))


# ----------------------------------------------------------------------------- tables

RAIL = """&scene title = 'slider on a rail', t_end = 0.05 /
&integrator method = 'single', h_slow = 1e-2 /
&effects {effect} = .true. /
&body name = 'ground', kind = 'ground' /
&body name = 'slider', kind = 'rigid', mass = 2.0, inertia = 1.0, 1.0, 1.0, 0.0, 0.0, 0.0 /
&joint name = 'rail', kind = 'prismatic', parent = 'ground', child = 'slider', axis = 1.0, 0.0, 0.0 /
{group}
"""
TABLE = "# t (s), value\n0.0 0.0\n0.5, 2.0\n1.0 2.0\n"
TABLE_CORRUPTIONS = [
    ("three_columns", TABLE.replace("0.5, 2.0", "0.5, 2.0, 7.0"),
     "line 3: expected two finite numbers (time, value), got 3: 0.5, 2.0, 7.0"),
    ("three_columns_blanks", TABLE.replace("1.0 2.0", "1.0 2.0 3.0"),
     "line 4: expected two finite numbers (time, value), got 3: 1.0 2.0 3.0"),
    ("one_column", TABLE.replace("1.0 2.0", "1.0"), "line 4: expected two finite numbers (time, value), got 1: 1.0"),
    ("trailing_comment", TABLE.replace("1.0 2.0", "1.0 2.0 # held"),
     "line 4: expected two finite numbers (time, value), got 4: 1.0 2.0 # held"),
    ("fortran_slash", TABLE.replace("1.0 2.0", "1.0 2/3"), "line 4: expected two finite numbers (time, value), got: 1.0 2/3"),
    ("nan", TABLE.replace("1.0 2.0", "1.0 nan"), "line 4: expected two finite numbers (time, value), got: 1.0 nan"),
    # found by fuzzing: an empty value between commas was skipped; a finite 1e308 overflowed the model
    ("double_comma", TABLE.replace("0.5, 2.0", "0.5,, 2.0"),
     "line 3: a comma with no value beside it (an empty value): 0.5,, 2.0"),
    ("trailing_comma", TABLE.replace("0.5, 2.0", "0.5, 2.0,"),
     "line 3: a comma with no value beside it (an empty value): 0.5, 2.0,"),
    ("beyond_range", TABLE.replace("0.5, 2.0", "0.5, 1e308"), "line 3: the value 1e+308 is beyond +-{limit}"),
    ("leading_comma", TABLE.replace("0.5, 2.0", ", 0.5 2.0"),
     "line 3: a comma with no value beside it (an empty value): , 0.5 2.0"),
    ("comma_alone", TABLE.replace("0.5, 2.0", ","), "line 3: a comma with no value beside it (an empty value): ,"),
    ("subnormal", TABLE.replace("0.5, 2.0", "0.5, 1e-310"),
     "line 3: the value 1e-310 is below the smallest normal number (2.22507e-308): give 0 or a larger magnitude"),
    ("rounding_to_zero", TABLE.replace("0.5, 2.0", "0.5, 1e-400"),
     "line 3: the value 1e-400 is below the smallest normal number (2.22507e-308): give 0 or a larger magnitude"),
    # a line of a megabyte was echoed whole: its first 500 bytes and its length now
    ("line_of_a_megabyte", TABLE.replace("0.5, 2.0", "0.5 " + "1" * 10**6),
     "line 3: " + ("expected two finite numbers (time, value), got: 0.5 " + "1" * 10**6)[:500]
     + f" ... ({52 + 10**6} characters)"),
]


@pytest.mark.parametrize("group, effect, where, limit", [
    ("&drive joint = 'rail', form = 'table', file = 't.csv' /", "joint_drives", "s.nml:7: &drive #1: file", "1e+12"),
    ("&motion joint = 'rail', form = 'table', file = 't.csv' /", "base_motion", "s.nml:7: &motion #1: file", "1e+6"),
], ids=["drive", "motion"])
@pytest.mark.parametrize("table, fault", [c[1:] for c in TABLE_CORRUPTIONS], ids=[c[0] for c in TABLE_CORRUPTIONS])
def test_a_table_line_of_other_than_two_numbers_is_one_line_exit_1(tmp_path, mrsim, group, effect, where, limit,
                                                                   table, fault):
    """A drive's or a motion's table with a third column (a file written for something
    else) was read as its first two; now any line of other than two numbers is refused:
    exit 1, one line naming the scene's item, the table file and its line. A value beyond
    the range of the item the table stands in for (a drive's force 1e12 N, a motion's
    position 1e6 m) is refused too."""
    fault = fault.format(limit=limit)
    (tmp_path / "s.nml").write_text(RAIL.format(group=group, effect=effect))
    (tmp_path / "t.csv").write_text(TABLE)
    r = subprocess.run([mrsim, "s.nml", "-o", "ok.csv"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    (tmp_path / "t.csv").write_text(table)
    r = subprocess.run([mrsim, "s.nml", "-o", "out.csv"], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert one_line(r) == f"mrsim: error: {where}: 't.csv' {fault}"


def test_a_scene_with_old_mac_line_ends_reads_as_with_line_feeds(tmp_path, mrsim):
    """A file whose lines end in a carriage return alone (old Mac) read as one line: its
    first comment swallowed the scene ('&scene: missing group'). It now runs, and gives the
    rows the same scene with line feeds gives, byte for byte (the same run)."""
    text = (ROOT / "input" / "pendulum.nml").read_text()
    (tmp_path / "lf.nml").write_text(text)
    (tmp_path / "cr.nml").write_bytes(text.replace("\n", "\r").encode())
    for name in ("lf", "cr"):
        r = subprocess.run([mrsim, f"{name}.nml", "-o", f"{name}.csv", "--set", "scene.t_end=0.5"], cwd=tmp_path,
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 0, r.stderr
    rows = [[ln for ln in (tmp_path / f"{name}.csv").read_text().splitlines() if not ln.startswith("#")]
            for name in ("lf", "cr")]
    assert len(rows[0]) == 52 and rows[0] == rows[1]          # a header and 51 rows, 0 to 0.5 s


# ----------------------------------------------------------------------------- pymr modal-import

from test_modal_import import beam_matrices, write_fe  # noqa: E402


@pytest.fixture
def fe(tmp_path):
    """A 4-element beam (5 nodes, 6 DOFs each: 30 rows) as Matrix Market files and a nodes
    file, and a DOF map of its rows; the folder and the files' names."""
    k, m, nodes = beam_matrices(2.0, 2e11, 7800.0, 1e-3, 1e-7, 2e-7, 4)
    write_fe(tmp_path, k, m, nodes)
    (tmp_path / "map.txt").write_text("".join(f"{r + 1} {r // 6 + 1} {r % 6 + 1}\n" for r in range(30)))
    return tmp_path


BASE = ["--mass", "m.mtx", "--stiffness", "k.mtx", "--nodes", "nodes.csv", "--interface", "1", "5"]
INPUTS = [("mass matrix", "m.mtx"), ("stiffness matrix", "k.mtx"), ("nodes file", "nodes.csv"), ("DOF map", "map.txt")]


@pytest.mark.parametrize("what, name", INPUTS, ids=[i[1] for i in INPUTS])
@pytest.mark.parametrize("spelling", ["same", "dot", "dotdot", "link"])
def test_modal_import_never_writes_over_its_input(fe, what, name, spelling):
    """-o naming one of modal-import's own input files, by any spelling (./m.mtx, a path
    through .., a link to it) replaced it with exit 0; now the kernel's same_file refuses it
    before any work, from the command line (exit 1, one line) and from
    pymr.modal_import(output=...) (ImportInputError), and the input is unchanged. The link
    is a hard one: any symbolic link is refused as one (test_safety)."""
    dof = ["--dof-map", "map.txt"] if name == "map.txt" else []
    out = {"same": name, "dot": f"./{name}", "dotdot": f"../{fe.name}/{name}", "link": "link"}[spelling]
    if spelling == "link":
        os.link(fe / name, fe / "link")
    before = (fe / name).read_bytes()
    shown = str(Path(out))
    r = pymr_cli("modal-import", *BASE, *dof, "-o", out, cwd=fe)
    assert one_line(r) == (f"pymr: error: {shown}: would overwrite the {what} ({name}); choose another modal "
                           "data file (-o)")
    assert (fe / name).read_bytes() == before
    with pytest.raises(ImportInputError, match=r"^[^\n]*: would overwrite the " + what + r" \([^\n]*\)"):
        pymr.modal_import(fe / "m.mtx", fe / "k.mtx", fe / "nodes.csv", [1, 5], output=fe / out,
                          dof_map=fe / "map.txt" if dof else None)
    assert (fe / name).read_bytes() == before
    r = pymr_cli("modal-import", *BASE, *dof, "-o", "body.modal", "-q", cwd=fe)
    assert r.returncode == 0 and r.stderr == "" and (fe / "body.modal").is_file()


@pytest.mark.parametrize("out", [".", "..", "folder"])
def test_modal_import_into_a_directory_is_one_line(fe, out):
    """-o . gave a traceback (ValueError: PosixPath('.') has an empty name); a directory is
    now an OutputError before any work: exit 1, one line."""
    (fe / "folder").mkdir()
    r = pymr_cli("modal-import", *BASE, "-o", out, cwd=fe)
    assert one_line(r) == (f"pymr: error: -o {out}: is a folder, not a file: give a file name for the modal data "
                           f"file, such as {out}/body.modal")
    with pytest.raises(pymr.OutputError, match=r"^output [^\n]*: is a folder, not a file: give a file name for the "
                                               r"modal data file, such as [^\n]*body\.modal$"):
        pymr.modal_import(fe / "m.mtx", fe / "k.mtx", fe / "nodes.csv", [1, 5], output=fe / out)


def test_modal_import_keep_0_says_what_is_wrong_with_keep(fe):
    """--keep 0 blamed the stiffness file ('the reduced body has no mode with mass'); it is
    the option that is wrong. So is --modes 0 with no other interface node."""
    r = pymr_cli("modal-import", *BASE, "--keep", "0", "-o", "b.modal", cwd=fe)
    assert one_line(r) == "pymr: error: --keep 0: the count of modes to write, at least 1 (leave it out for all)"
    r = pymr_cli("modal-import", *BASE[:-1], "--modes", "0", "-o", "b.modal", cwd=fe)
    assert one_line(r) == ("pymr: error: --modes 0: the body would have no mode (no interface node besides the "
                           "origin gives a constraint mode): ask for 1 or more")
    assert not (fe / "b.modal").exists()


MATRIX_CORRUPTIONS = [
    ("rows_1e9", "%%MatrixMarket matrix coordinate real symmetric\n1000000000 1000000000 1\n1 1 1.0\n",
     "line 2: 1000000000 rows, but nodes.csv has 5 nodes x 6 DOFs = 30"),
    ("array_rows_1e9", "%%MatrixMarket matrix array real general\n1000000000 1000000000\n1.0\n",
     "line 2: 1000000000 rows, but nodes.csv has 5 nodes x 6 DOFs = 30"),
    ("entries_1e9", "%%MatrixMarket matrix coordinate real symmetric\n30 30 1000000000\n1 1 1.0\n",
     "line 2: the size line gives 1000000000 entries (30 x 30, symmetric), the file holds 1"),
    ("array_values_short", "%%MatrixMarket matrix array real general\n30 30\n1.0\n2.0\n",
     "line 2: the size line gives 900 values (30 x 30, general), the file holds 2"),
    ("rows_short", "%%MatrixMarket matrix coordinate real general\n24 24 1\n1 1 1.0\n",
     "line 2: 24 rows, but nodes.csv has 5 nodes x 6 DOFs = 30"),
]


@pytest.mark.parametrize("which", ["m.mtx", "k.mtx"])
@pytest.mark.parametrize("text, fault", [c[1:] for c in MATRIX_CORRUPTIONS], ids=[c[0] for c in MATRIX_CORRUPTIONS])
def test_a_matrix_size_line_is_checked_before_allocation(fe, which, text, fault):
    """A Matrix Market size line of 1e9 rows gave numpy's _ArrayMemoryError traceback: the
    size line is now held against the DOF layout (nodes x DOFs, or the DOF map's lines) and
    against the entries the file holds before the dense matrix is allocated."""
    (fe / which).write_text(text)
    r = pymr_cli("modal-import", *BASE, "-o", "b.modal", cwd=fe)
    assert one_line(r) == f"pymr: error: {which}: {fault}"
    r = pymr_cli("modal-import", *BASE, "--dof-map", "map.txt", "-o", "b.modal", cwd=fe)
    by_map = fault.replace("nodes.csv has 5 nodes x 6 DOFs = 30", "map.txt maps 30 rows (one a line)")
    assert one_line(r) == f"pymr: error: {which}: {by_map}"
    assert not (fe / "b.modal").exists()


def test_a_matrix_too_large_for_memory_is_one_line(tmp_path):
    """Read alone (no layout to hold it against), a size line beyond the memory is an
    ImportInputError, not numpy's MemoryError."""
    path = tmp_path / "big.mtx"
    path.write_text("%%MatrixMarket matrix coordinate real symmetric\n10000000000 10000000000 1\n1 1 1.0\n")
    with pytest.raises(ImportInputError, match=r"^[^\n]*big\.mtx: line 2: 10000000000 x 10000000000: too large "
                                               r"for this machine's memory \(320 GB for the row pointers of its copies "
                                               r"alone\)$"):
        read_matrix_market(path)


WRONG_ARGUMENTS = [
    ({"modes": "many"}, "modes='many': a whole number of fixed-interface modes expected (0 or more), or None for all "
                        "with mass"),
    ({"modes": 2.5}, "modes=2.5: a whole number of fixed-interface modes expected (0 or more), or None for all with "
                     "mass"),
    ({"modes": True}, "modes=True: a whole number of fixed-interface modes expected (0 or more), or None for all "
                      "with mass"),
    ({"modes": -1}, "--modes -1: a count of modes (0 or more)"),
    ({"keep": "3"}, "keep='3': a whole number of modes to write expected (1 or more), or None for all"),
    ({"keep": 0}, "--keep 0: the count of modes to write, at least 1 (leave it out for all)"),
    ({"interface": "15"}, "interface='15': node ids expected, whole numbers (a list such as [1, 21])"),
    ({"interface": [1.0]}, "interface=[1.0]: node ids expected, whole numbers (a list such as [1, 21])"),
    ({"interface": None}, "interface=None: node ids expected, whole numbers (a list such as [1, 21])"),
    ({"clamp": "2"}, "clamp='2': node ids expected, whole numbers (a list such as [1, 21])"),
    ({"dofs_per_node": "6"}, "dofs_per_node='6': 3 or 6 expected (or a dof_map)"),
    ({"dofs_per_node": 4}, "--dofs-per-node 4: 3 or 6"),
    ({"mass": 5}, "mass=5: a file name (str or path) expected"),
    ({"stiffness": None}, "stiffness=None: a file name (str or path) expected"),
    ({"nodes": b"nodes.csv"}, "nodes=b'nodes.csv': a file name (str or path) expected"),
    ({"dof_map": 3}, "dof_map=3: a file name (str or path) expected"),
    ({"output": ""}, "output='': a file name (str or path) expected"),
    ({"title": 5}, "title=5: one line of text expected (the file's first comment)"),
    ({"title": "a\npoints 1"}, "title='a\\npoints 1': one line of text expected (the file's first comment)"),
]


@pytest.mark.parametrize("change, message", WRONG_ARGUMENTS, ids=[f"{next(iter(c))}={c[next(iter(c))]!r}"
                                                                   for c, _ in WRONG_ARGUMENTS])
def test_modal_import_arguments_are_pymr_errors_naming_the_argument(fe, change, message):
    """Wrong argument types raised numpy's or Python's own errors ('many' < 0, int('1') of a
    string taken apart digit by digit); each is now an ImportInputError (a pymr.SceneError)
    of one line naming the argument, raised before any file is read or written."""
    args = {"mass": fe / "m.mtx", "stiffness": fe / "k.mtx", "nodes": fe / "nodes.csv", "interface": [1, 5],
            "output": fe / "b.modal", **change}
    with pytest.raises(ImportInputError) as exc:
        pymr.modal_import(**args)
    assert str(exc.value) == message
    assert isinstance(exc.value, pymr.SceneError)
    assert not (fe / "b.modal").exists()


def test_modal_import_takes_one_interface_node_as_a_number(fe):
    body = pymr.modal_import(fe / "m.mtx", fe / "k.mtx", fe / "nodes.csv", np.int64(1), modes=2)
    assert len(body.frequencies_hz) == 2 and body.point_ids == [1]


# ----------------------------------------------------------------------------- header counts elsewhere

def test_a_checkpoint_s_saved_scene_length_is_held_against_its_size(tmp_path):
    """The checkpoint's one count, the length of its integrator settings' text, goes through
    the same check_header_count as the modal file's (the checksum is made to hold: the file
    is otherwise whole)."""
    import hashlib
    import struct
    out = tmp_path / "job.csv"
    pymr.run(TANK, out, overrides={"scene.t_end": 0.3, "output.checkpoint_dt": 0.2})
    data = bytearray((tmp_path / "job.ckpt").read_bytes())
    assert data[:8] == b"PYMRCKPT"
    assert 0 < struct.unpack_from("<i", data, 60)[0] < len(data)     # after the tag, versions, sizes, name, time
    struct.pack_into("<i", data, 60, 2_000_000_000)
    data[-64:] = hashlib.sha256(bytes(data[:-64])).hexdigest().encode()
    (tmp_path / "job.ckpt").write_bytes(bytes(data))
    with pytest.raises(pymr.SceneError) as exc:
        pymr.run(TANK, out, overrides={"output.checkpoint_dt": 0.2}, restart=tmp_path / "job.ckpt")
    assert str(exc.value) == (f"{TANK}: {tmp_path / 'job.ckpt'}: its integrator settings: 2000000000 bytes cannot "
                              f"be in this file ({len(data)} bytes)")


# ----------------------------------------------------------------------------- outputs over inputs

@pytest.mark.parametrize("spelling", ["./p.nml", "../{folder}/p.nml", "link.nml"])
def test_an_output_is_held_against_the_inputs_as_a_file_not_as_a_spelling(tmp_path, mrsim, spelling):
    """The kernel's scene_input compared absolute paths, so `-o ../DIR/p.nml` was not the
    scene p.nml and the results replaced it; same_file compares the files on the disk (the
    rule modal-import's -o uses through the binding too). The link is a hard one: any
    symbolic link is refused as one (test_safety)."""
    (tmp_path / "p.nml").write_text((ROOT / "input" / "pendulum.nml").read_text())
    os.link(tmp_path / "p.nml", tmp_path / "link.nml")
    before = (tmp_path / "p.nml").read_bytes()
    out = spelling.format(folder=tmp_path.name)
    r = subprocess.run([mrsim, "p.nml", "-o", out], cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert one_line(r) == (f"mrsim: error: p.nml: output {out}: would overwrite the scene (p.nml); choose another "
                           "results file")
    assert (tmp_path / "p.nml").read_bytes() == before
