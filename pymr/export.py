"""``pymr export OUT.csv --vtk DIR``: the moving mechanism as a ParaView collection.

DIR/NAME.pvd (NAME: the results' stem) lists one unstructured grid DIR/NAME_000000.vtu ...
per output time used, written by meshio; the geometry is :func:`pymr.geometry.motion`'s (the
kernel's kinematics). Each .vtu holds, in the inertial frame (m):

========  ===========================================================================
part      cells
========  ===========================================================================
0 solid   a rigid body's box: one hexahedron; a beam: its tube, quads on 12-sided rings
          around the deformed centre line (in the planes of the body's y and z axes)
1 frame   every body's frame: three lines from its origin along its x, y, z axes
          (cell data ``frame_axis`` 0, 1, 2), each a tenth of the mechanism's size long
2 line    a flexible body's deformed centre line: line cells joining its points (a beam's
          41 points along its axis); a modal-file body's nodes: vertex cells
3 marker  one vertex per marker
4 joint   one vertex per joint, with its ``axis`` (point data; zero for joints with none)
========  ===========================================================================

Cell data: ``part`` (above), ``body`` (the body's index, model order, 0 the ground; -1 for
markers and joints), ``marker`` and ``joint`` (their index; -1 elsewhere), ``frame_axis``
(the frame lines' 0, 1, 2 for x, y, z; -1 elsewhere). Point data: ``displacement`` (the elastic
displacement, unscaled, inertial, m; zero off the flexible bodies), ``axis`` (the joints'
unit axes), ``radius`` (a beam's outer radius on its centre line and tube, m; a tube
filter's radius). DIR/pymr_export.json names the bodies, markers and joints by index, and
the times, the files and ``exaggerate``. With ``--exaggerate X`` the deflections (and so the
centre lines, tubes, markers and everything beyond a flexible body) are drawn X times;
``displacement`` stays the true one.

The collection is written whole or not at all: into a temporary folder beside DIR, then
renamed to DIR (an earlier export there is removed only once the new one is complete, and
only the files its pymr_export.json records). DIR must be new, empty, or an earlier pymr
export (it holds pymr_export.json, and nothing that index does not record): a folder with
anything else in it, or whose index is damaged, is never replaced.
"""
from __future__ import annotations

import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np

from ._args import exchange_paths, sync_to_disk
from .errors import OutputError
from .geometry import BodyTrack, Motion, motion
from .outputs import _folder_of
from .results import Results, load_results

#: The index file of an export: its presence marks a folder pymr may replace.
INDEX = "pymr_export.json"
PARTS = {"solid": 0, "frame": 1, "line": 2, "marker": 3, "joint": 4}
#: Sides of a beam's tube.
TUBE_SIDES = 12
_HEX = np.array([[-1, -1, -1], [1, -1, -1], [1, 1, -1], [-1, 1, -1],
                 [-1, -1, 1], [1, -1, 1], [1, 1, 1], [-1, 1, 1]], dtype=float) / 2   # VTK's corner order


class _Grid:
    """The points and cell blocks of one .vtu, gathered piece by piece."""

    def __init__(self):
        self.points, self.disp, self.axis, self.radius = [], [], [], []
        self.cells, self.data = [], {k: [] for k in ("part", "body", "marker", "joint", "frame_axis")}
        self.n = 0

    def add(self, pts, kind: str, conn, part: str, *, body=-1, marker=-1, joint=-1, axis=-1,
            disp=None, axes=None, radius=0.0) -> None:
        """Points (k, 3) and cells `conn` (c, nodes per cell; indices into pts) of one part."""
        pts = np.asarray(pts, dtype=float).reshape(-1, 3)
        conn = np.asarray(conn, dtype=np.int64).reshape(len(conn), -1)
        self.points.append(pts)
        self.disp.append(np.zeros_like(pts) if disp is None else disp)
        self.axis.append(np.zeros_like(pts) if axes is None else axes)
        self.radius.append(np.full(len(pts), radius))
        self.cells.append((kind, conn + self.n))
        for key, value in (("part", PARTS[part]), ("body", body), ("marker", marker), ("joint", joint)):
            self.data[key].append(np.full(len(conn), value, dtype=np.int32))
        self.data["frame_axis"].append(np.asarray(axis, dtype=np.int32) * np.ones(len(conn), dtype=np.int32))
        self.n += len(pts)

    def mesh(self):
        import meshio
        return meshio.Mesh(np.concatenate(self.points), self.cells,
                           point_data={"displacement": np.concatenate(self.disp),
                                       "axis": np.concatenate(self.axis), "radius": np.concatenate(self.radius)},
                           cell_data=self.data)


def _tube(body: BodyTrack, i: int) -> tuple[np.ndarray, np.ndarray]:
    """A beam's tube at row i: rings of TUBE_SIDES points of its radius around the line's
    points, in the plane of the body's y and z axes; quads between neighbouring rings."""
    r, line = body.size[1], body.line[i]
    ang = 2 * np.pi * np.arange(TUBE_SIDES) / TUBE_SIDES
    ring = r * (np.cos(ang)[:, None] * body.rotation[i][:, 1] + np.sin(ang)[:, None] * body.rotation[i][:, 2])
    pts = line[:, None, :] + ring[None, :, :]
    p, s = np.meshgrid(np.arange(len(line) - 1), np.arange(TUBE_SIDES), indexing="ij")
    a, b = p * TUBE_SIDES + s, p * TUBE_SIDES + (s + 1) % TUBE_SIDES
    quads = np.stack([a, b, b + TUBE_SIDES, a + TUBE_SIDES], axis=-1).reshape(-1, 4)
    return pts.reshape(-1, 3), quads


def _add_body(grid: _Grid, k: int, body: BodyTrack, i: int, frame_len: float) -> None:
    """Body k's solid, frame and centre line at row i."""
    rot, org = body.rotation[i], body.origin[i]
    if body.shape == "box":
        grid.add(org + (body.centre + _HEX * body.size) @ rot.T, "hexahedron", [range(8)], "solid", body=k)
    if body.shape == "cylinder" and body.line is not None:
        pts, quads = _tube(body, i)
        disp = np.repeat(body.displacement[i], TUBE_SIDES, axis=0)
        grid.add(pts, "quad", quads, "solid", body=k, disp=disp, radius=body.size[1])
    tips = org + frame_len * rot.T
    grid.add(np.vstack([org, tips]), "line", [[0, 1], [0, 2], [0, 3]], "frame", body=k, axis=[0, 1, 2])
    if body.line is not None:
        npt = len(body.line[i])
        if body.kind == "beam":
            conn = np.stack([np.arange(npt - 1), np.arange(1, npt)], axis=1)
            grid.add(body.line[i], "line", conn, "line", body=k, disp=body.displacement[i], radius=body.size[1])
        else:
            grid.add(body.line[i], "vertex", np.arange(npt)[:, None], "line", body=k, disp=body.displacement[i])


def step_mesh(mo: Motion, i: int, frame_len: float):
    """The meshio.Mesh of row i of the motion (the module's table)."""
    grid = _Grid()
    for k, body in enumerate(mo.bodies):
        _add_body(grid, k, body, i, frame_len)
    for k, pos in enumerate(mo.markers.values()):
        grid.add(pos[i], "vertex", [[0]], "marker", marker=k)
    for k, joint in enumerate(mo.joints):
        grid.add(joint.position[i], "vertex", [[0]], "joint", joint=k, axes=joint.axis[i][None, :])
    return grid.mesh()


def check_export_folder(folder, option: str = "--vtk") -> Path:
    """The export's folder, checked before any work: a name (not '.', '..' or empty) in a
    folder that is there and writable; new, empty, or an earlier pymr export (which is
    replaced whole), never a folder holding other files, nor a file."""
    if isinstance(folder, bytes):
        folder = os.fsdecode(folder)
    if not isinstance(folder, (str, os.PathLike)) or os.fspath(folder) == "":
        raise OutputError(f"{option}: a folder's name expected for the export, got {folder!r}")
    text = os.fspath(folder).rstrip("/") or "/"
    if "\0" in text:
        raise OutputError(f"{option} {text!r}: a folder name cannot hold a NUL character")
    out = Path(text)
    if out.name in ("", ".", ".."):
        raise OutputError(f"{option} {text}: name a folder of its own for the export (it is replaced whole)")
    _folder_of(text, option)
    if os.path.lexists(out):
        if out.is_symlink() or not out.is_dir():
            raise OutputError(f"{option} {text}: is not a folder; choose a new folder for the export")
        recorded(out, option)
    return out


def recorded(out: Path, option: str = "--vtk") -> list[str]:
    """The files of the earlier export in the folder `out` that pymr wrote and recorded in
    its index (the .vtu files, the .pvd, the index itself): the only files a new export may
    remove. A folder holding anything else, or whose index is damaged (nothing then proves
    a file pymr's), is refused (OutputError) and left alone; [] for an empty folder."""
    present = sorted(p.name for p in out.iterdir())
    if not present:
        return []
    if INDEX not in present:
        raise OutputError(f"{option} {out}: a folder that holds files and is not a pymr export (no {INDEX}); "
                          "choose a new or empty folder")
    try:
        index = json.loads((out / INDEX).read_text())
        names = [*index["files"], index["collection"], INDEX]
        if not all(isinstance(n, str) and n == Path(n).name and n not in ("", ".", "..") for n in names):
            raise ValueError("a file name that is not a name in the folder")
    except (OSError, ValueError, KeyError, TypeError, RecursionError) as exc:
        raise OutputError(f"{option} {out}: its {INDEX} is damaged ({' '.join(str(exc).split())}), so no file in it "
                          "is known to be an earlier export's: nothing was removed; choose a new or empty folder") \
            from None
    others = [n for n in present if n not in names or not (out / n).is_file() or (out / n).is_symlink()]
    if others:
        raise OutputError(f"{option} {out}: holds files the earlier export did not write ({', '.join(others[:5])}"
                          f"{', ...' if len(others) > 5 else ''}): nothing was removed; move them out or choose a "
                          "new folder")
    return [n for n in present if n in names]


def _write_pvd(path: Path, times, files) -> None:
    """The collection index. meshio writes the .vtu files but has no writer for ParaView's
    .pvd collection, a small XML list of (time, file): written with xml.etree."""
    import xml.etree.ElementTree as ET
    root = ET.Element("VTKFile", type="Collection", version="0.1", byte_order="LittleEndian")
    coll = ET.SubElement(root, "Collection")
    for t, f in zip(times, files):
        ET.SubElement(coll, "DataSet", timestep=repr(float(t)), group="", part="0", file=f)
    ET.ElementTree(root).write(path, xml_declaration=True, encoding="utf-8")


def _swap_in(tmp: Path, out: Path, earlier: list[str]) -> None:
    """Rename the complete export `tmp` (flushed to the disk) to `out`. An earlier export at
    `out` is exchanged with it in one step where the system can (a kill between moving it
    aside and renaming the new one in left no `out`), else moved aside first (moved back if
    the rename fails); then only its files `earlier` (those its index records,
    :func:`recorded`) are removed, and its folder if that leaves it empty: a file put there
    meanwhile is left in the folder aside."""
    for entry in [*tmp.iterdir(), tmp]:           # on the disk before any name points to them
        sync_to_disk(entry)
    old = out.with_name(f".{out.name}.old-{os.getpid()}") if os.path.lexists(out) else None
    if old is not None and exchange_paths(tmp, out):     # one step: DIR holds an export throughout
        os.rename(tmp, old)                               # the earlier one, aside
    else:
        if old is not None:
            os.rename(out, old)
        try:
            os.rename(tmp, out)
        except OSError:
            if old is not None:
                os.rename(old, out)
            raise
    sync_to_disk(out.parent)
    if old is not None:
        for name in earlier:
            (old / name).unlink(missing_ok=True)
        try:
            old.rmdir()
        except OSError:
            pass


def _write_all(mo: Motion, tmp: Path, name: str, res: Results) -> list[str]:
    """Every .vtu, the .pvd and the index into the folder tmp; the .vtu names."""
    import meshio
    lo, hi = mo.bounds()
    frame_len = 0.1 * max(float((hi - lo).max()), 1e-3)
    files = []
    for i in range(len(mo.t)):
        files.append(f"{name}_{i:06d}.vtu")
        meshio.write(tmp / files[-1], step_mesh(mo, i, frame_len), file_format="vtu")
    _write_pvd(tmp / f"{name}.pvd", mo.t, files)
    index = {"results": str(res.path), "collection": f"{name}.pvd", "times": [float(t) for t in mo.t],
             "files": files, "exaggerate": mo.exaggerate, "parts": PARTS,
             "bodies": [{"name": b.name, "kind": b.kind, "shape": b.shape, "size": list(map(float, b.size))}
                        for b in mo.bodies],
             "markers": list(mo.markers), "joints": [{"name": j.name, "kind": j.kind} for j in mo.joints]}
    (tmp / INDEX).write_text(json.dumps(index, indent=1) + "\n")
    return files


def export_vtk(results: Results | str | os.PathLike, folder, scene=None, every: int = 1, frames: int | None = None,
               exaggerate: float = 1.0, option: str = "--vtk") -> Path:
    """Write the ParaView collection of a run's results to `folder` (the module's doc);
    return the path of its .pvd."""
    res = results if isinstance(results, Results) else load_results(results)
    out = check_export_folder(folder, option)
    earlier = recorded(out, option) if out.is_dir() else []
    try:
        import meshio  # noqa: F401
    except ImportError:
        raise OutputError(f"{option} {out}: the VTK export needs meshio, which is not installed here "
                          "(pip install meshio)") from None
    mo = motion(res, scene, exaggerate=exaggerate, every=every, frames=frames)
    name = Path(res.path).stem if res.path else "motion"
    try:
        tmp = Path(tempfile.mkdtemp(prefix=f".{out.name}.tmp-", dir=out.parent))
    except OSError as exc:          # a folder that takes no new entry (/proc): named, not the staging name
        raise OutputError(f"{option} {out}: cannot write in its folder {out.parent} ({exc.strerror or exc})") from None
    try:
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o777 & ~umask)
        _write_all(mo, tmp, name, res)
        _swap_in(tmp, out, earlier)
    except OSError as exc:
        raise OutputError(f"{option} {out}: cannot write the export ({' '.join(str(exc).split())})") from None
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return out / f"{name}.pvd"


def main(csv: str, vtk: str, scene: str | None = None, every: int = 1, frames: int | None = None,
         exaggerate: float = 1.0) -> int:
    pvd = export_vtk(csv, vtk, scene=scene, every=every, frames=frames, exaggerate=exaggerate)
    print(f"wrote {pvd} ({len(json.loads((pvd.parent / INDEX).read_text())['files'])} times)")
    return 0
