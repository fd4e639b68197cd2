"""pymr export --vtk (issue 33): the ParaView collection of a run, read back with meshio.

Independent expectations: the barrel's centre line in every .vtu ends on the muzzle marker
column the run wrote (and the booms' on their tip markers); the .pvd lists every file at the
results' own times; the point count is the sum of the parts the export's doc lists; a box's
edges are the body's box; a failed or refused export leaves the earlier one whole."""
from __future__ import annotations

import json
import subprocess
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np
import pytest

import pymr
from pymr import export
from pymr.errors import OutputError

ROOT = Path(__file__).resolve().parents[1]
TANK = ROOT / "input" / "tank_gun_turret.nml"
CRAFT = ROOT / "input" / "spacecraft.nml"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    folder = tmp_path_factory.mktemp("export")
    tank = pymr.run(TANK, folder / "tank.csv", overrides={"scene.t_end": 0.3, "output.dt": 0.01})
    craft = pymr.run(CRAFT, folder / "craft.csv", overrides={"scene.t_end": 0.2, "output.dt": 0.01})
    return pymr.load_results(folder / "tank.csv"), pymr.load_results(folder / "craft.csv"), tank, craft


def collection(pvd: Path) -> list[tuple[float, Path]]:
    root = ET.parse(pvd).getroot()
    assert root.get("type") == "Collection"
    return [(float(d.get("timestep")), pvd.parent / d.get("file")) for d in root.iter("DataSet")]


def cells_of(mesh, part: int, **ids):
    """The connectivity of every cell of `part` (and the given ids), by cell type."""
    out = {}
    for k, block in enumerate(mesh.cells):
        keep = mesh.cell_data["part"][k] == part
        for name, value in ids.items():
            keep &= mesh.cell_data[name][k] == value
        if keep.any():
            out.setdefault(block.type, []).append(block.data[keep])
    return {t: np.concatenate(v) for t, v in out.items()}


def line_end(mesh, body: int) -> np.ndarray:
    """The last point of a body's centre line: the one no segment starts from."""
    seg = cells_of(mesh, 2, body=body)["line"]
    (end,) = set(seg[:, 1]) - set(seg[:, 0])
    return mesh.points[end]


def test_tank_export_ends_the_barrel_on_the_muzzle(runs, tmp_path):
    tank = runs[0]
    pvd = export.export_vtk(tank, tmp_path / "vtk", every=3)
    steps = collection(pvd)
    assert [t for t, _ in steps] == list(tank.t[::3]) and len(steps) == 11
    assert sorted(p.name for p in pvd.parent.iterdir()) == sorted(
        [p.name for _, p in steps] + ["tank.pvd", "pymr_export.json"])
    index = json.loads((pvd.parent / "pymr_export.json").read_text())
    bodies = [b["name"] for b in index["bodies"]]
    assert bodies == ["chassis", "turret", "mount", "gun"] and index["markers"] == ["muzzle"]
    gun, muzzle = bodies.index("gun"), tank.marker("muzzle")[0][::3]
    # 2 boxes, the barrel's tube (41 rings of 12) and line (41), 4 frames of 4 points, a marker, 3 joints
    count = 2 * 8 + 41 * 12 + 41 + 4 * 4 + 1 + 3
    for i, (t, path) in enumerate(steps):
        mesh = meshio.read(path)
        assert len(mesh.points) == count
        assert np.abs(line_end(mesh, gun) - muzzle[i]).max() < 1e-9 * 5.3
        (mk,) = cells_of(mesh, 3, marker=0)["vertex"][:, 0]
        assert np.abs(mesh.points[mk] - muzzle[i]).max() < 1e-9 * 5.3
    # the displacement field at the line's end is the muzzle's deflection: centimetres, not zero
    assert np.abs(mesh.point_data["displacement"]).max() > 1e-3
    hexa = mesh.points[cells_of(mesh, 0, body=bodies.index("turret"))["hexahedron"][0]]
    edges = [np.linalg.norm(hexa[1] - hexa[0]), np.linalg.norm(hexa[3] - hexa[0]), np.linalg.norm(hexa[4] - hexa[0])]
    assert edges == pytest.approx(index["bodies"][1]["size"], rel=1e-12)
    (jt,) = cells_of(mesh, 4, joint=0)["vertex"][:, 0]                       # the traverse, about y
    assert np.abs(mesh.point_data["axis"][jt] - [0.0, 1.0, 0.0]).max() < 1e-15
    assert np.abs(mesh.points[jt] - [0.0, 1.2, 0.0]).max() < 1e-15


def test_spacecraft_export_ends_the_booms_on_their_tips(runs, tmp_path):
    craft = runs[1]
    pvd = export.export_vtk(craft, tmp_path / "craft_vtk", frames=5)
    steps = collection(pvd)
    rows = np.unique(np.linspace(0, len(craft.t) - 1, 5).round().astype(int))
    assert [t for t, _ in steps] == list(craft.t[rows])
    names = [b["name"] for b in json.loads((pvd.parent / "pymr_export.json").read_text())["bodies"]]
    for i, (_, path) in enumerate(steps):
        mesh = meshio.read(path)
        for boom, tip in (("boom_right", "tip_right"), ("boom_left", "tip_left")):
            assert np.abs(line_end(mesh, names.index(boom)) - craft.marker(tip)[0][rows[i]]).max() < 1e-9 * 4.0


def test_an_earlier_export_survives_a_failed_or_refused_one(runs, tmp_path, monkeypatch):
    """A later export replaces an earlier one whole; one that fails half-way (the disk
    refuses the 4th file) leaves the earlier one as it was and no temporary folder; a folder
    holding other files is refused in one line, exit 1, and left alone."""
    tank = runs[0]
    out = tmp_path / "vtk"
    export.export_vtk(tank, out, frames=4)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    real, calls = export.step_mesh, []

    def failing(*a):
        calls.append(1)
        if len(calls) == 4:
            raise OSError(28, "No space left on device")
        return real(*a)

    monkeypatch.setattr(export, "step_mesh", failing)
    with pytest.raises(OutputError, match="cannot write the export .*No space left"):
        export.export_vtk(tank, out, frames=7)
    monkeypatch.undo()
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    assert sorted(p.name for p in tmp_path.iterdir()) == ["vtk"]
    export.export_vtk(tank, out, frames=6)
    assert len(list(out.glob("*.vtu"))) == 6
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("keep me")
    r = subprocess.run(["pymr", "export", tank.path, "--vtk", str(mine)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 1 and r.stderr.count("\n") == 1 and "not a pymr export" in r.stderr
    assert [p.name for p in mine.iterdir()] == ["notes.txt"]
    r = subprocess.run(["pymr", "export", tank.path, "--vtk", str(tmp_path / "cli"), "--every", "10"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert "wrote" in r.stdout and len(collection(tmp_path / "cli" / "tank.pvd")) == 4
    for bad in (["--vtk", "."], ["--vtk", str(tmp_path / "none" / "x")], ["--vtk", str(tmp_path / "cli" / "tank.pvd")]):
        r = subprocess.run(["pymr", "export", tank.path, *bad], capture_output=True, text=True, timeout=60)
        assert r.returncode == 1 and r.stderr.count("\n") == 1, r.stderr


def test_a_kill_while_the_new_export_moves_in_leaves_one_in_place(runs, tmp_path, monkeypatch):
    """The earlier export was renamed aside, then the new one in: killed between the two,
    DIR was gone and the earlier export only in a hidden folder (found by an audit of
    kills). The two are now exchanged in one step (renameat2): the process 'killed' at its
    next rename leaves DIR holding the new export whole, every file its .pvd names there."""
    tank = runs[0]
    out = tmp_path / "vtk"
    export.export_vtk(tank, out, frames=4)

    class Killed(BaseException):
        pass

    def killed(*a):
        raise Killed

    monkeypatch.setattr(export.os, "rename", killed)
    with pytest.raises(Killed):
        export.export_vtk(tank, out, frames=6)
    monkeypatch.undo()
    steps = collection(next(out.glob("*.pvd")))
    assert len(steps) == 6 and all(f.exists() for _, f in steps)
