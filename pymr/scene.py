"""A scene as data: a namelist file with overrides, read, checked, resolved and
fingerprinted by the kernel's own reader through the binding. Python states no scene rule:
every address, value and check is the kernel's (``pymr scene --schema`` lists them)."""
from __future__ import annotations

import functools
import os
import tempfile
import weakref
from pathlib import Path
from typing import Iterable, Mapping

from . import _kernel as _core
from ._args import (SceneSource, _flag, _name, _path, _raise, _text, format_overrides, nml_value, open_model,
                    write_file)
from .errors import SceneError


class Scene(SceneSource):
    """A scene file and overrides, addressed as ``--set`` addresses them::

        scene = pymr.Scene("input/tank_gun_turret.nml")
        scene["body[gun].n_elements"] = 40      # checked by the kernel at once
        scene["integrator.method"]              # -> 'single'
        pymr.run(scene)

    Setting an item reads the scene again in the kernel: a bad address or value raises
    :class:`SceneError` with the kernel's message and leaves the scene as it was.

    Values are Python's: a number, a bool (``.true.``/``.false.``), a str, or a list of them.
    An item that takes several values (its type in :func:`schema` has a count, such as
    ``real(3)`` or ``string(1..6)``) is a list both ways, even with one value given:
    ``scene["output.quantities"]`` -> ``['coordinates', 'markers']``, and that list (or one
    str) sets it. Bytes are refused (:class:`pymr.ArgumentTypeError` naming the item), not
    stored as their repr ``"b'abc'"``: text is a str.

    The model functions (:func:`pymr.model_terms`, :func:`pymr.modes` ...) called with a
    Scene share one model the kernel builds at the first of them (from the file as it is
    then) and keeps open; setting an item closes it (the next call builds the scene as it
    now is), and so does the Scene's garbage collection.
    """

    def __init__(self, path: str | os.PathLike,
                 overrides: Mapping[str, object] | Iterable[str] | None = None) -> None:
        self.path = Path(_path("path", path))
        self._overrides: list[str] = []
        self._resolved: str | None = None      # the kernel's text for the current overrides
        self._model: tuple | None = None       # the open model: (handle, its closer, what it was built from)
        text = format_overrides(overrides)
        if text:
            self._overrides = text.split("\n")
        self._check()

    # ------------------------------------------------------------------ items

    def __getitem__(self, address: str) -> object:
        value, stat, msg, detail = _core.pymr_scene_item(str(self.path), self.overrides, _name("address", address))
        _raise(stat, msg, detail)
        return parse_value(_text(value), _is_list(address))

    def __setitem__(self, address: str, value: object) -> None:
        # one override, its value checked and written by the API's one conversion
        address = _name("address", address)
        self._overrides.append(format_overrides([f"{address}={nml_value(value, address)}"]))
        try:
            self._check()
        except SceneError:
            self._overrides.pop()
            self._check()
            raise

    def kernel_scene(self) -> tuple[str, str]:
        """The scene file and its overrides, as every function that takes a scene hands them
        to the kernel."""
        return str(self.path), self.overrides

    def model_handle(self) -> int:
        """The handle of the kernel's model of this scene as it now is, opened at the first
        call and kept until the scene is set or collected (or its path, or the working folder
        a relative path is read from, changed)."""
        where = self.kernel_scene()
        key = (where, None if self.path.is_absolute() else os.getcwd())
        if self._model is not None and (not self._model[1].alive or self._model[2] != key):
            self._close_model()
        if self._model is None:
            handle = open_model(*where)
            self._model = (handle, weakref.finalize(self, _core.pymr_model_close, handle), key)
        return self._model[0]

    def _close_model(self) -> None:
        """Close the open model (if any): the scene has changed."""
        if self._model is not None:
            self._model[1]()                   # a finalizer closes its handle once
            self._model = None

    def __getstate__(self) -> dict:
        # a copy (or pickle) opens its own model: the handle is this object's
        return {**self.__dict__, "_model": None}

    @property
    def overrides(self) -> str:
        """The overrides as the kernel reads them (one GROUP.ITEM=VALUE a line)."""
        return "\n".join(self._overrides)

    # ------------------------------------------------------------- resolving

    def resolved(self, absolute_paths: bool = False) -> str:
        """The scene with every default filled in and every override applied, checked by
        building its model, and a last comment line with its fingerprint. With
        ``absolute_paths`` the files it names are written absolute (for a copy elsewhere).
        The text is the kernel's reading of the file when the Scene was made or last set."""
        if _flag("absolute_paths", absolute_paths):
            return _kernel_text(str(self.path), self.overrides, 2)
        return self._resolved

    @property
    def fingerprint(self) -> str:
        """sha256 of the resolved scene (without its fingerprint line), as in OUT.json."""
        return self.resolved().rstrip("\n").rsplit("\n", 1)[-1].removeprefix("! fingerprint ")

    def write(self, path: str | os.PathLike, absolute_paths: bool = False) -> Path:
        """Write the resolved scene to `path` (a complete scene file)."""
        return write_file(path, self.resolved(absolute_paths), "resolved scene")

    def _check(self) -> None:
        self._close_model()
        self._resolved = None
        self._resolved = _kernel_text(str(self.path), self.overrides, 0)

    def __repr__(self) -> str:
        return f"Scene({str(self.path)!r}, overrides={self._overrides!r})"


def schema() -> str:
    """The scene's groups and items from the kernel's tables: one '&group' line per group,
    then one line per item: name, type(count), default, range or choices, unit, meaning
    (tab-separated)."""
    return _kernel_text("", "", 1)


def _kernel_text(scene: str, overrides: str, what: int) -> str:
    with tempfile.TemporaryDirectory(prefix="pymr-scene-") as tmp:
        out = os.path.join(tmp, "scene.txt")
        stat, msg, detail = _core.pymr_scene_write(scene, overrides, what, out)
        _raise(stat, msg, detail)
        return Path(out).read_text()


def parse_value(text: str, is_list: bool = False) -> object:
    """A resolved value as Python: numbers, .true./.false., quoted text, or a list of them
    (values separated by commas outside quotes: ``'a, b', 'c'`` is two texts). With
    `is_list` (an item of several values) a list even of one value."""
    parts: list[str] = []
    if text:
        quoted, start = False, 0
        for i, ch in enumerate(text):
            if ch == "'":
                quoted = not quoted          # '' inside a text toggles twice
            elif ch == "," and not quoted:
                parts.append(text[start:i].strip())
                start = i + 1
        parts.append(text[start:].strip())
    else:
        parts = [text]
    out = [_one(p) for p in parts]
    return out if is_list or len(out) > 1 else out[0]


@functools.cache
def _list_items() -> frozenset[tuple[str, str]]:
    """(group, item) of every item that takes several values, from the kernel's schema
    (its type has a count: ``real(3)``, ``string(1..6)``)."""
    found, group = set(), ""
    for line in schema().splitlines():
        if line.startswith("&"):
            group = line[1:].strip()
        elif "\t" in line:
            name, kind = line.split("\t")[:2]
            if "(" in kind:
                found.add((group, name))
    return frozenset(found)


def _is_list(address: str) -> bool:
    """Whether the item at `address` (GROUP.ITEM or GROUP[NAME].ITEM, which the kernel has
    just read) takes several values: its group is the address's first word, its item the
    last."""
    group = address.split("[", 1)[0].split(".", 1)[0].strip().lower()
    item = address.rsplit(".", 1)[-1].strip().lower()
    return (group, item) in _list_items()


def _one(p: str) -> object:
    if p.startswith("'") and p.endswith("'") and len(p) >= 2:
        return p[1:-1].replace("''", "'")
    if p in (".true.", ".false."):
        return p == ".true."
    if p == "":
        return None
    try:
        return int(p)
    except ValueError:
        return float(p)
