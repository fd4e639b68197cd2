"""A scene as data: a namelist file with overrides, or a scene built in Python (groups added
and removed), read, checked, resolved and fingerprinted by the kernel's own reader through
the binding. Python states no scene rule: every address, value and check is the kernel's
(``pymr scene --schema`` lists them)."""
from __future__ import annotations

import contextlib
import functools
import os
import tempfile
import weakref
from pathlib import Path
from typing import Iterable, Iterator, Mapping

from . import _kernel as _core
from ._args import (SceneSource, _flag, _name, _path, _raise, _text, format_overrides, nml_value, open_model,
                    write_file)
from .errors import OutputError, SceneError


def _word(what: str, name: str) -> str:
    """A group's or an item's name as the namelist writes it: letters, digits and '_', from a
    letter (a SceneError naming it otherwise: 't_end = 1\\n/\\n&integrator' added a group)."""
    if not (name[:1].isascii() and name[:1].isalpha() and all(c.isascii() and (c.isalnum() or c == "_")
                                                              for c in name)):
        raise SceneError(f"{what} {name!r}: not a name (letters, digits and '_', from a letter)")
    return name


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

    **Building a scene.** ``add(group, **items)`` adds one group, ``remove(group, name)``
    takes the groups of that name away (``remove(group)`` a single group such as
    ``'output'``); both return the scene, so calls chain. ``Scene()`` (no path) is a new,
    empty scene, its relative file names relative to the working folder::

        scene = pymr.Scene()
        scene.add("scene", title="pendulum", t_end=2.0, gravity=[0.0, -9.81, 0.0])
        scene.add("integrator", method="single", h_slow=1e-3)
        scene.add("effects", gravity=True)
        scene.add("body", name="ground", kind="ground")
        scene.add("body", name="bob", kind="rigid", mass=1.0, com=[0.0, -1.0, 0.0], inertia=[1e-4] * 3 + [0.0] * 3)
        scene.add("joint", name="pivot", kind="revolute", parent="ground", child="bob", axis=[0, 0, 1], q0=0.1)
        pymr.run(scene)
        scene.remove("joint", "pivot")         # SceneError: &body 'bob': not connected to the ground ...

    The values are converted as for setting an item, and the kernel judges the result: an
    add or remove is the kernel reading the scene's text with that group appended, or
    without it. Once the kernel accepts the scene whole (as it accepts a file scene at
    once), every add and remove is checked on the whole scene (its rules, its model built)
    and a refused one raises :class:`SceneError` with the kernel's line, the scene
    unchanged. A new scene is a draft until then: each add is checked on its groups and
    items alone (unknown groups and items, values out of range or choice) and the rest
    waits until the scene is whole (:meth:`resolved` raises the kernel's reason meanwhile).
    Edits that only make a scene together (a body and its joint) go in one
    ``with scene.editing():`` block, checked whole at its end.
    An edited scene holds its text (the kernel's resolved text, files named absolute) in a
    private file, ``path``; :meth:`write` saves it as a scene file, and one read back runs
    the same, with the same fingerprint.
    """

    def __init__(self, path: str | os.PathLike | None = None,
                 overrides: Mapping[str, object] | Iterable[str] | None = None) -> None:
        self._overrides: list[str] = []
        self._resolved: str | None = None      # the kernel's text for the current overrides
        self._stamp: tuple | None = None       # the scene file as it was read for it (_file_stamp)
        self._model: tuple | None = None       # the open model: (handle, its closer, what it was built from)
        self._text: str | None = None          # the scene's text once built or edited in Python
        self._tmp = None                       # the private folder of that text's file
        self._whole = True                     # whether the kernel accepts the scene whole
        self._batch = False                    # inside editing(): edits checked as a draft's
        text = format_overrides(overrides)
        if path is None:
            if text:
                raise SceneError("overrides: a new scene has no items yet: add its groups")
            self._home = os.path.join(os.getcwd(), "<scene built in Python>")
            self._whole = False
            self._set_text("")
            return
        self.path = Path(_path("path", path))
        self._home = str(self.path)            # the kernel's name of the scene: messages, relative files
        if text:
            self._overrides = text.split("\n")
        self._check()

    def __copy__(self) -> "Scene":
        """An independent scene: its own overrides, its own file for a text built or edited
        in Python, no model shared (copy.copy shared the overrides list: setting an item of
        the copy changed what the original ran)."""
        new = Scene.__new__(Scene)
        new.__dict__.update(self.__dict__)
        new._overrides, new._model, new._tmp, new._batch = list(self._overrides), None, None, False
        if self._text is not None:
            new._set_text(self._text)
        return new

    def __deepcopy__(self, memo) -> "Scene":
        return self.__copy__()

    # ------------------------------------------------------------- building

    def add(self, group: str, **items: object) -> "Scene":
        """Add one `group` (``'body'``, ``'joint'``, ``'marker'``, ``'output'`` ...) with
        its `items`, converted as :meth:`__setitem__` converts a value."""
        group = _word("group", _name("group", group))
        lines = "".join(f"  {_word('item', k)} = {nml_value(v, f'{group}.{k}')}\n" for k, v in items.items())
        return self._edit(f"&{group}\n{lines}/\n")

    def remove(self, group: str, name: str | None = None) -> "Scene":
        """Remove the `group` groups whose naming item is `name` (a body's, joint's,
        marker's, force's name; a drive's, spring's or motion's joint; a load's marker), or
        the single `group` (``'output'``, ``'effects'`` ...) when `name` is None."""
        address = _name("group", group) + ("" if name is None else f"[{_name('name', name)}]")
        return self._edit("", omit=address)

    @contextlib.contextmanager
    def editing(self) -> Iterator["Scene"]:
        """Edits that only make a scene together (a body and the joint that holds it, added
        or removed): inside the ``with`` block they are checked as a draft's, and the scene
        whole at its end, where a refusal undoes them all::

            with scene.editing():
                scene.add("body", name="arm2", ...)
                scene.add("joint", name="elbow", parent="arm", child="arm2", ...)
        """
        saved = (self._text, list(self._overrides), self._whole, self.path, self._batch)
        self._batch = True
        try:
            yield self
            self._batch = saved[4]
            if self._text is not None and not self._batch:
                self._settle(saved[2])
        except BaseException:
            self._text, self._overrides, self._whole, self.path, self._batch = saved
            if self._text is not None:
                self._set_text(self._text)
            self._check()
            raise

    def _settle(self, was_whole: bool) -> None:
        """After edits: the scene checked whole; refused (a SceneError) if it was whole
        before, else a draft still."""
        try:
            _edited_text(self._text, self._home, "", "", whole=True)
            self._whole = True
        except SceneError:
            if was_whole:
                raise
            self._whole = False
        self._check()

    def _edit(self, appended: str = "", overrides: str = "", omit: str = "") -> "Scene":
        """The scene's text with `appended`, `overrides` and without `omit`, read by the
        kernel (a draft: its groups and items), then whole: refused, nothing changes."""
        if self._text is None:                 # the file's text and its overrides, as given
            try:
                data = self.path.read_bytes()
            except OSError as exc:             # the file was deleted (or made unreadable) since
                raise SceneError(f"{self.path}: cannot read the scene file ({exc.strerror or exc})") from None
            base = _edited_text(os.fsdecode(data), self._home, self.overrides, "", whole=False)
        else:
            base = self._text
        text = _edited_text(base + appended, self._home, overrides, omit, whole=False)
        whole = self._whole
        if not self._batch:
            try:
                text = _edited_text(text, self._home, "", "", whole=True)
                whole = True
            except SceneError:
                if self._whole:
                    raise
        else:
            whole = False
        self._set_text(text)
        self._overrides, self._whole = [], whole
        self._check()
        return self

    def _set_text(self, text: str) -> None:
        """Hold `text` as the scene, in the file the kernel reads (`path`)."""
        if self._tmp is None:
            self._tmp = tempfile.TemporaryDirectory(prefix="pymr-scene-")
        self._text = text
        self.path = Path(self._tmp.name) / "scene.nml"
        self.path.write_text(text)

    # ------------------------------------------------------------------ items

    def __getitem__(self, address: str) -> object:
        self._require_whole()
        value, stat, msg, detail = _core.pymr_scene_item(str(self.path), self.overrides, _name("address", address))
        _raise(stat, msg, detail)
        return parse_value(_text(value), _is_list(address))

    def __contains__(self, address: str) -> bool:
        """Whether ``scene[address]`` reads a value (``'body[gun].mass' in scene``): False for
        an unknown group, item or name, and for a name several groups share whose values
        differ."""
        try:
            self[address]
        except SceneError:
            return False
        return True

    def __iter__(self):
        raise TypeError("a Scene is not iterable: read an item by its address, scene['group.item'], "
                        "and see every group and item in pymr.schema() or scene.resolved()")

    def __setitem__(self, address: str, value: object) -> None:
        # one override, its value checked and written by the API's one conversion
        address = _name("address", address)
        entry = format_overrides([f"{address}={nml_value(value, address)}"])
        if self._text is not None:             # a built scene takes it into its text
            self._edit(overrides=entry)
            return
        self._overrides.append(entry)
        try:
            self._check()
        except SceneError:
            self._overrides.pop()
            self._check()
            raise

    def kernel_scene(self) -> tuple[str, str]:
        """The scene file and its overrides, as every function that takes a scene hands them
        to the kernel (a draft is refused first)."""
        self._require_whole()
        return str(self.path), self.overrides

    def _require_whole(self) -> None:
        """A draft is no scene yet: refused with the kernel's reason, by the scene's name
        (its messages named pymr's private file of its text)."""
        if self._text is not None and not self._whole:
            _edited_text(self._text, self._home, "", "", whole=True)

    def model_handle(self) -> int:
        """The handle of the kernel's model of this scene as it now is, opened at the first
        call and kept until the scene is set or collected (or its path, its file on disk, or
        the working folder a relative path is read from, changed)."""
        self._follow_file()
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
        # a copy (or pickle) opens its own model and keeps its text in its own file
        return {**self.__dict__, "_model": None, "_tmp": None}

    def __setstate__(self, state: dict) -> None:
        self.__dict__.update(state)
        if self._text is not None:
            self._set_text(self._text)

    @property
    def overrides(self) -> str:
        """The overrides as the kernel reads them (one GROUP.ITEM=VALUE a line)."""
        return "\n".join(self._overrides)

    # ------------------------------------------------------------- resolving

    def resolved(self, absolute_paths: bool = False) -> str:
        """The scene with every default filled in and every override applied, checked by
        building its model, and a last comment line with its fingerprint. With
        ``absolute_paths`` the files it names are written absolute (for a copy elsewhere).
        The text is the kernel's reading of the file as it is now: a file changed since the
        last reading is read again."""
        self._follow_file()
        if _flag("absolute_paths", absolute_paths) or self._resolved is None:
            self._require_whole()
            return _kernel_text(str(self.path), self.overrides, 2 if absolute_paths else 0)
        return self._resolved

    @property
    def fingerprint(self) -> str:
        """sha256 of the resolved scene (without its fingerprint line), as in OUT.json."""
        return self.resolved().rstrip("\n").rsplit("\n", 1)[-1].removeprefix("! fingerprint ")

    def write(self, path: str | os.PathLike, absolute_paths: bool = False) -> Path:
        """Write the resolved scene to `path` (a complete scene file). Not over the scene's
        own file, nor a file it reads (an :class:`OutputError`, as every writer of pymr
        refuses them): its comments and layout would be lost; write a new file."""
        text = self.resolved(absolute_paths)
        from .outputs import check_output
        check_output(_path("path", path, OutputError), "scene file", option="path", if_left_out=None, scene=self)
        return write_file(path, text, "resolved scene")

    def _check(self) -> None:
        self._close_model()
        self._resolved = None
        self._stamp = self._file_stamp()
        if self._whole:                        # a draft is not a scene yet
            self._resolved = _kernel_text(str(self.path), self.overrides, 0)

    def _file_stamp(self) -> tuple | None:
        """The scene file's identity and change time (None when it cannot be read: the
        kernel then says why)."""
        try:
            st = os.stat(self.path)
        except OSError:
            return None
        return (st.st_dev, st.st_ino, st.st_size, st.st_mtime_ns)

    def _follow_file(self) -> None:
        """A scene file changed on disk since it was read (its resolved text, fingerprint
        and model were its older text's) is read again."""
        if self._text is None and self._file_stamp() != self._stamp:
            self._check()

    def __repr__(self) -> str:
        if self._text is not None:
            groups = sum(line.startswith("&") for line in self._text.splitlines())
            return f"<Scene built in Python: {groups} groups{'' if self._whole else ', a draft'}>"
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


def _edited_text(text: str, home: str, overrides: str, omit: str, whole: bool) -> str:
    """The kernel's resolved text (files absolute, no fingerprint) of scene `text` named
    `home` with `overrides`, without the groups `omit` names; `whole`: checked as a scene,
    else as a draft."""
    with tempfile.TemporaryDirectory(prefix="pymr-scene-") as tmp:
        out = os.path.join(tmp, "scene.txt")
        stat, msg, detail = _core.pymr_scene_edit(text, home, overrides, omit, int(whole), out)
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
