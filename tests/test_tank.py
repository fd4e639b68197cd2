"""The tank gun-turret scene (docs/tank_gun_turret.md) and its hold variant:
energy balance against the drives' work, static sag under gravity, modal-file round
trip, and the batch executable's output."""
from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import simpson

import pymr

ROOT = Path(__file__).resolve().parent.parent
TANK = ROOT / "input" / "tank_gun_turret.nml"
HOLD = ROOT / "input" / "tank_hold.nml"

# pinned barrel data
L, E, RHO, RO, RI = 5.3, 2.07e11, 7850.0, 0.11, 0.06
AREA = np.pi * (RO**2 - RI**2)
EI = E * np.pi / 4 * (RO**4 - RI**4)


def drive_work(res: pymr.Results) -> float:
    """Work of the paper's torques T1, T2 (eqs. 40-41) by Simpson's rule on the rows."""
    t = res.t
    t1 = -45500.0 * np.sin(2 * np.pi * t)
    t2 = 17600.0 * np.sin(2 * np.pi * t) - 33451.0
    return simpson(t1 * res["traverse.qd"] + t2 * res["elevation.qd"], x=t)


def test_tank_energy_equals_drive_work(tmp_path):
    """E(1 s) - E(0) equals the work of the two drive torques to 1e-6 relative."""
    res = pymr.run(TANK, tmp_path / "tank.csv", overrides={"output.dt": 1e-4})
    q, qd = res.coordinates()
    ke, pe = pymr.model_energy(TANK, q, qd)
    energy = ke + pe
    work = drive_work(res)
    assert abs(work) > 1e3  # the drives do real work
    assert abs((energy[-1] - energy[0]) - work) < 1e-6 * abs(work)


def gun_frame_deflection(res: pymr.Results) -> np.ndarray:
    """Muzzle deflection in the gun frame, from the muzzle marker and the joint angles
    (rigid kinematics of the pinned scene, independent of the kernel's mode shapes)."""
    def ry(a):
        c, s = np.cos(a), np.sin(a)
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])

    def rz(a):
        c, s = np.cos(a), np.sin(a)
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])

    pos, _ = res.marker("muzzle")
    out = np.empty_like(pos)
    for i, (q1, q2) in enumerate(zip(res["traverse.q"], res["elevation.q"])):
        r_turret = ry(q1)
        r_gun = r_turret @ rz(-q2)          # elevation axis is -z of the turret
        origin = np.array([0, 1.2, 0]) + r_turret @ (np.array([1.2, 0.5, 0]) + rz(-q2) @ np.array([0.3, 0, 0]))
        out[i] = r_gun.T @ (pos[i] - (origin + r_gun @ np.array([L, 0, 0])))
    return out


def test_hold_settles_to_static_sag(tmp_path):
    """With 5 % modal damping the muzzle settles to w L^4 / (8 EI) = 9.35 mm within 1 %."""
    over = {"scene.t_end": 4.0, "effects.modal_damping": True, "body[gun].modal_damping": 0.05,
            "output.dt": 1e-2}
    res = pymr.run(HOLD, tmp_path / "hold.csv", overrides=over)
    sag = RHO * AREA * 9.81 * L**4 / (8 * EI)
    assert sag == pytest.approx(9.35e-3, rel=1e-3)
    defl = gun_frame_deflection(res)
    assert -defl[-1, 1] == pytest.approx(sag, rel=1e-2)
    assert abs(defl[-1, 2]) < 1e-9                   # no lateral sag
    assert np.abs(res["traverse.q"]).max() < 1e-9    # T1 = 0: no traverse motion
    # undamped, the barrel overshoots to about twice the static sag
    res0 = pymr.run(HOLD, tmp_path / "hold0.csv", overrides={"scene.t_end": 0.2, "output.dt": 1e-3})
    assert -gun_frame_deflection(res0)[:, 1].min() == pytest.approx(2 * sag, rel=0.05)


def test_modal_file_round_trip(tmp_path):
    """The barrel written to a modal file and read back as kind='modal' gives the same
    results as the built-in beam to 1e-12."""
    modal = tmp_path / "gun.modal"
    pymr.write_modal_file(TANK, "gun", modal)
    text = TANK.read_text()
    text, count = re.subn(r"&body\s*\n\s*name = 'gun'.*?/\n",
                          f"&body name = 'gun', kind = 'modal', modal_file = '{modal.name}' /\n", text, flags=re.S)
    assert count == 1
    scene = tmp_path / "tank_modal.nml"
    scene.write_text(text)
    over = {"scene.t_end": 0.3}
    a = pymr.run(TANK, tmp_path / "a.csv", overrides=over)
    b = pymr.run(scene, tmp_path / "b.csv", overrides=over)
    assert a.columns == b.columns
    scale = np.maximum(np.abs(a.data).max(axis=0), 1e-300)
    assert (np.abs(a.data - b.data).max(axis=0) / scale).max() < 1e-12
    assert np.abs(a["gun.a1"]).max() > 1e-3          # the barrel really deflects


def test_modal_file_errors(tmp_path):
    modal = tmp_path / "bad.modal"
    modal.write_text("pymr-modal 1\nmodes 1\nfrequencies_hz 5.0\npoints 1\n0 0 0 1.0 0 1 0\n")
    scene = tmp_path / "s.nml"
    beam = ("  name = 'gun', kind = 'beam'\n  length = 5.3, youngs_modulus = 2.07e11, density = 7850.0\n"
            "  r_outer = 0.11, r_inner = 0.06\n  n_elements = 20, modes_y = 2, modes_z = 2\n")
    assert beam in TANK.read_text()
    scene.write_text(TANK.read_text().replace(beam, "  name = 'gun', kind = 'modal', modal_file = 'bad.modal'\n"))
    with pytest.raises(pymr.SceneError, match=r"&body 'gun'.*modal_file: .*bad.modal: line 5: point 1: expected 10"):
        pymr.run(scene, tmp_path / "x.csv")


def test_mrsim_writes_muzzle_motion(tmp_path, mrsim):
    """mrsim runs the tank and writes the muzzle's position and velocity; the muzzle
    starts at the pinned geometry (1.2 + 0.3 + 5.3, 1.2 + 0.5, 0) m at rest."""
    out = tmp_path / "tank.csv"
    r = subprocess.run([mrsim, str(TANK), "-o", str(out), "--set", "scene.t_end=0.05"],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    assert r.stderr == ""
    assert "muzzle" in r.stdout
    res = pymr.load_results(out)
    pos, vel = res.marker("muzzle")
    assert pos[0] == pytest.approx([6.8, 1.7, 0.0], abs=1e-12)
    assert np.abs(vel[0]).max() == 0.0
    assert res.stats["rhs_full"] > 0 and res.stats["steps_slow"] == 500
    assert set(res.stats["effects"]) == {"gravity", "joint_drives", "deformation_inertia"}


def test_the_readme_s_first_command_writes_the_scene_s_own_output(tmp_path):
    """`pymr run input/tank_gun_turret.nml` with no -o (the README's first command): the
    results go to the scene's &output file beside the working folder, the summary is printed
    and the status is 0. (gfortran 12 returned the default path with a garbage length, and
    this command ended in a UnicodeDecodeError.)"""
    import shutil
    import subprocess
    scene = tmp_path / "tank.nml"
    shutil.copy(Path(__file__).resolve().parent.parent / "input" / "tank_gun_turret.nml", scene)
    r = subprocess.run(["pymr", "run", "tank.nml", "--no-progress"], cwd=tmp_path, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    assert "results: tank_gun_turret.csv, tank_gun_turret.json" in r.stdout
    res = pymr.load_results(tmp_path / "tank_gun_turret.csv")
    assert res.t[-1] == 1.0 and res.stats["status"] == "complete"
