"""What pymr's modules share on the way into and out of the kernel: the public functions'
arguments checked and converted (paths, names, flags, overrides in namelist syntax, arrays),
a scene given as a path or a :class:`SceneSource` (a :class:`pymr.Scene`), files written
whole, and the kernel's status turned into pymr's exceptions. ``api`` and ``scene`` both use
it and neither imports the other."""
from __future__ import annotations

import contextlib
import os
from pathlib import Path
from typing import Iterable, Mapping

import numpy as np

from . import _kernel as _core
from .errors import ArgumentTypeError, OutputError, PymrError, SceneError, SolverError


class SceneSource:
    """A scene held as data (:class:`pymr.Scene` is one): what every function that takes a
    scene hands the kernel."""

    def kernel_scene(self) -> tuple[str, str]:
        """The scene file's path and its override text (one GROUP.ITEM=VALUE a line)."""
        raise NotImplementedError

    def model_handle(self) -> int:
        """The handle of the kernel's model of :meth:`kernel_scene`, kept open for every
        model function called with this scene; 0: none kept (each call opens its own)."""
        return 0


def open_model(path: str, overrides: str) -> int:
    """Build the model of a scene file and overrides in the kernel and keep it open: its
    handle (pymr_model_open, the binding's one entry point that builds a model), for every
    entry point that works on a built model; the caller closes it (pymr_model_close)."""
    handle, _, stat, msg, detail = _core.pymr_model_open(path, overrides)
    _raise(stat, msg, detail)
    return int(handle)


@contextlib.contextmanager
def model_of(scene, where: tuple[str, str]):
    """The handle of the model of `where`, the kernel's scene and overrides of `scene` (as
    :func:`_scene_and_overrides` gives them): a :class:`SceneSource`'s own open model when
    the call adds no override, else a model opened for the call and closed after it."""
    if isinstance(scene, SceneSource) and where == scene.kernel_scene():
        handle = scene.model_handle()
        if handle:
            yield handle
            return
    handle = open_model(*where)
    try:
        yield handle
    finally:
        _core.pymr_model_close(handle)


def write_file(path: str | os.PathLike, data: str | bytes, what: str) -> Path:
    """Write `data` to `path` whole or not at all: a temporary file beside it, flushed to
    the disk (fsync), then renamed over it, so an earlier complete file survives a failed
    write. A failure is an :class:`OutputError` naming the file and `what` it was to hold."""
    return write_files([(path, data, what)])[0]


def write_files(items) -> list[Path]:
    """Write each (path, data, what) of `items` as :func:`write_file` does, every file
    complete on the disk before the first is renamed into place: a run killed while it
    writes leaves the earlier set whole (a study's table, figure and histories were
    replaced one at a time, each after seconds of plotting). A failure removes the
    temporary files written so far."""
    paths = [_writable(path, what) for path, _, what in items]
    temps = []
    try:
        for path, (_, data, what) in zip(paths, items):
            tmp = path.with_name(f"{path.name}.{os.getpid()}.tmp")
            temps.append(tmp)
            _write_synced(tmp, data.encode() if isinstance(data, str) else data, path, what)
        for path, tmp, (_, _, what) in zip(paths, temps, items):
            try:
                os.replace(tmp, path)
            except OSError as exc:
                raise OutputError(f"{path}: cannot write the {what} ({exc.strerror or exc})") from None
    except OutputError:
        for tmp in temps:
            try:
                tmp.unlink(missing_ok=True)
            except OSError:          # a read-only folder refuses the unlink too: nothing was written
                pass
        raise
    return paths


def _writable(path, what: str) -> Path:
    """`path` as a file pymr may write the `what` to (not a folder, /dev/null or a link
    to it), or an OutputError."""
    path = Path(_path("path", path, OutputError))
    try:
        folder = path.is_dir()
    except OSError:                          # a name too long: the write below says so
        folder = False
    if folder or not path.name:              # '.', '..', '/': no file name to write (or rename) to
        raise OutputError(f"{path}: cannot write the {what} (it is a directory)")
    from .outputs import not_replaceable
    why = not_replaceable(path)              # the rename would replace /dev/null, or a link, itself
    if why:
        raise OutputError(f"{path}: cannot write the {what}: {why}")
    return path


def _write_synced(tmp: Path, data: bytes, path: Path, what: str) -> None:
    """`data` written to `tmp` and flushed to the disk; an OutputError naming `path`."""
    try:
        with open(tmp, "wb") as fh:
            fh.write(data)
            fh.flush()
            os.fsync(fh.fileno())
    except OSError as exc:
        raise OutputError(f"{path}: cannot write the {what} ({exc.strerror or exc})") from None


def sync_to_disk(path: str | os.PathLike) -> None:
    """Flush a file, or a folder's entries (the renames in it), to the disk (fsync): a
    complete file renamed into place is then on the disk before its name is."""
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


def exchange_paths(a: Path, b: Path) -> bool:
    """Swap two existing paths (folders) in one step (Linux renameat2 RENAME_EXCHANGE): a
    process killed at any moment leaves each name holding one of the two. False where the
    system or file system does not do it (the caller then renames one at a time)."""
    import ctypes
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    at_fdcwd, rename_exchange = -100, 2
    renameat2.argtypes = [ctypes.c_int, ctypes.c_char_p, ctypes.c_int, ctypes.c_char_p, ctypes.c_uint]
    return renameat2(at_fdcwd, os.fsencode(a), at_fdcwd, os.fsencode(b), rename_exchange) == 0


def overwritten_input(scene, path: str | os.PathLike, overrides=None) -> str:
    """The scene's input (the scene, a modal or table file) that `path`, an output, would
    overwrite, by the kernel's rule (which the results and modal files obey too); '' for
    none. A scene that cannot be read raises its SceneError."""
    found, stat, msg, detail = _core.pymr_scene_input(*_scene_and_overrides(scene, overrides),
                                                      _path("output", path, OutputError))
    _raise(stat, msg, detail)
    return _text(found)


def canonical_address(address: str) -> str:
    """The one spelling of the item an override address names, by the kernel's rule
    (``Integrator.H_SLOW`` and ``integrator.h_slow``, ``body['gun'].mass`` and
    ``body[gun].mass`` name one item); a SceneError for an address that is none."""
    text, stat, msg, detail = _core.pymr_override_address(address)
    _raise(stat, msg, detail)
    return _text(text)


def check_not_input(scene, path: str | os.PathLike, what: str, overrides=None) -> None:
    """`path`, an output, is none of the scene's inputs; else a SceneError."""
    found = overwritten_input(scene, path, overrides)
    if found:
        raise SceneError(f"{path}: would overwrite {found}; choose another {what}")


def _raise(stat: int, message: bytes | str, detail: bytes | str = "") -> None:
    """Raise the kernel's error of status `stat` (1 bad input: SceneError, 2 failed run:
    SolverError; 0: none) with its message and the structured fields of `detail` (the
    binding's 'name=value' fields, separated by the character 30) as attributes."""
    if stat == 0:
        return
    fields = dict(part.partition("=")[::2] for part in _text(detail).split("\x1e") if part)
    raise (SceneError if stat == 1 else SolverError).from_kernel(_text(message), fields)


# ------------------------------------------------------------------ arguments
# The one place where the public functions' arguments are checked and converted for the
# kernel: a wrong type or shape is an ArgumentTypeError or a SceneError whose one line names
# the argument, never numpy's or f2py's own exception. The kernel checks what the scene
# makes of them (addresses, values, lengths); these check only what Python hands over.

def _short(value: object) -> str:
    """A short repr of `value` on one line, for a message."""
    text = " ".join(repr(value).split())
    return text if len(text) <= 60 else text[:57] + "..."


def _shown(value: object) -> str:
    """`value` for a one-line message: its type and a short repr on one line."""
    return f"{type(value).__name__} {_short(value)}"


def _path(name: str, value, error: type[PymrError] = SceneError) -> str:
    """A file path argument (str or os.PathLike; bytes as the file system names them). A
    NUL character is refused as `error` naming the argument: no file name holds one, and
    the kernel's text would end at it (a file of another name read or written)."""
    if isinstance(value, (str, bytes, os.PathLike)):
        try:
            text = os.fsdecode(os.fspath(value))
        except TypeError:          # an os.PathLike whose __fspath__ gives no str or bytes
            pass
        else:
            if "\0" in text:
                raise error(f"{name}: {text!r}: a file path cannot hold a NUL character")
            return text
    raise ArgumentTypeError(f"{name}: a file path (str or os.PathLike), got {_shown(value)}")


def _name(name: str, value) -> str:
    """A name argument (a marker's, a body's, an item's address): text, not empty, and with
    no NUL (the binding passes text as C does, up to its first NUL: 'gun\\0x' was 'gun')."""
    if not isinstance(value, str):
        raise ArgumentTypeError(f"{name}: a name (str), got {_shown(value)}")
    if not value.strip():
        raise SceneError(f"{name}: an empty name")
    if "\0" in value:
        raise SceneError(f"{name}: {value!r}: a name cannot hold a NUL character")
    return value


def _scalar_array(value) -> bool:
    """A 0-d numpy array: Iterable by its type, yet iterating it fails (no list of anything)."""
    return isinstance(value, np.ndarray) and value.ndim == 0


def _names(name: str, value) -> list[str]:
    """Names: one str (one name, not its characters) or an iterable of str."""
    if isinstance(value, str):
        return [value]
    if isinstance(value, (bytes, Mapping)) or not isinstance(value, Iterable) or _scalar_array(value):
        raise ArgumentTypeError(f"{name}: a name or a list of names (str), got {_shown(value)}")
    items = list(value)
    for k, item in enumerate(items):
        _name(f"{name}[{k}]", item)
    return items


def _real(name: str, value) -> float:
    """A real number argument (int or float; not text, a bool or an array): the float, any
    range (the caller judges it); an ArgumentTypeError naming `name` otherwise."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ArgumentTypeError(f"{name}: a number, got {_shown(value)}")
    try:
        return float(value)
    except OverflowError:        # an int past the largest float (10**400): as large as a float goes
        return float("inf") if value > 0 else float("-inf")


def _flag(name: str, value, none: bool = False) -> bool | None:
    """A True/False argument (or None where `none`)."""
    if value is None and none:
        return None
    if not isinstance(value, (bool, np.bool_)):
        raise ArgumentTypeError(f"{name}: True or False{' (or None)' if none else ''}, got {_shown(value)}")
    return bool(value)


def format_overrides(overrides: Mapping[str, object] | Iterable[str] | None, name: str = "overrides") -> str:
    """Turn ``{"integrator.h_slow": 5e-4}`` or ``["integrator.h_slow=5e-4"]`` into the
    kernel's override text (one ``GROUP.ITEM=VALUE`` per line, values in namelist syntax).
    One str is one override (``"integrator.h_slow=5e-4"``), not a list of its characters;
    an empty one is refused (the kernel skipped its empty line), and so is a set (no order).
    Anything else (a number, bytes, a list of non-text) is an :class:`ArgumentTypeError`
    naming `name`; the kernel checks each entry's address and value and names the scene."""
    if overrides is None:
        return ""
    if isinstance(overrides, Mapping):
        items = []
        for k, v in overrides.items():
            if not isinstance(k, str):
                raise ArgumentTypeError(f"{name}: keys are addresses GROUP.ITEM (str), got {_shown(k)}")
            items.append(f"{k}={nml_value(v, f'{name}[{k!r}]')}")
    elif isinstance(overrides, str):
        items = [overrides]        # one override (iterating it gave one per character)
    elif isinstance(overrides, (bytes, bytearray, set, frozenset)) or not isinstance(overrides, Iterable) \
            or _scalar_array(overrides):
        # a set has no order, and a later override must win over an earlier one
        raise ArgumentTypeError(f"{name}: a mapping {{'GROUP.ITEM': value}} or a list of 'GROUP.ITEM=VALUE' "
                                f"texts, got {_shown(overrides)}")
    else:
        items = list(overrides)
        for k, item in enumerate(items):
            if not isinstance(item, str):
                raise ArgumentTypeError(f"{name}[{k}]: an override 'GROUP.ITEM=VALUE' (str), got {_shown(item)}")
    for item in items:
        if not item.strip():
            # an unset shell variable: refused as mrsim refuses it, not skipped
            raise SceneError("--set needs GROUP.ITEM=VALUE (got an empty one)")
        if "\0" in item:
            # the binding passes the text as C does, up to its first NUL: what follows was lost
            raise SceneError(f"--set {item!r}: a NUL character in an override")
        if "\n" in item or "\r" in item:
            # the kernel reads one override a line: a line break would make two of one
            raise SceneError(f"--set {item!r}: a line break in an override (one GROUP.ITEM=VALUE, on one line)")
    return "\n".join(items)   # the kernel checks each entry and names the scene file


def nml_value(v: object, name: str = "value") -> str:
    """A Python value as namelist text: a bool as .true./.false., a str quoted, a number, or
    a list (tuple, 1-D array) of them. Anything else (None, bytes, a nested list) is an
    :class:`ArgumentTypeError` naming `name`: bytes are refused, not decoded or written as
    their repr ``b'...'`` (the text an item holds is a str; decode bytes first)."""
    if isinstance(v, np.ndarray) and v.ndim == 0:   # np.array(2.0): its one value (len() fails on it)
        v = v[()]
    if isinstance(v, (bool, np.bool_)):
        return ".true." if v else ".false."
    if isinstance(v, str):
        return "'" + v.replace("'", "''") + "'"
    if isinstance(v, (int, np.integer)):
        return str(int(v))
    if isinstance(v, (float, np.floating)):
        return repr(float(v))
    if isinstance(v, (bytes, bytearray)):
        raise ArgumentTypeError(f"{name}: bytes {v!r}: give text as a str (bytes are not decoded)")
    if isinstance(v, (list, tuple, np.ndarray)) and len(v) > 0:
        for x in v:
            if isinstance(x, (list, tuple, np.ndarray, bytes, bytearray)) or np.ndim(x) != 0:
                raise ArgumentTypeError(f"{name}: a list of numbers, .true./.false. or texts, got {_shown(v)}")
        return ", ".join(nml_value(x, name) for x in v)
    raise ArgumentTypeError(f"{name}: a number, a bool, a text (str) or a list of them, got {_shown(v)}")


def _scene_and_overrides(scene, overrides) -> tuple[str, str]:
    """The scene file and the override text for the kernel: a :class:`pymr.Scene` brings its
    own overrides, which the call's overrides follow (and so win)."""
    text = format_overrides(overrides)
    if isinstance(scene, SceneSource):
        path, own = scene.kernel_scene()
        return path, "\n".join(t for t in (own, text) if t)
    if isinstance(scene, (str, bytes, os.PathLike)):
        return _path("scene", scene), text
    raise ArgumentTypeError(f"scene: a scene file's path (str or os.PathLike) or a pymr.Scene, got {_shown(scene)}")


def _array(name: str, value) -> np.ndarray:
    """An array of real numbers (any shape) from `value`: numbers, not text, bools or
    complex numbers, and not a ragged list."""
    try:
        a = np.asarray(value)
        if a.dtype.kind == "O":
            a = a.astype(float)
    except (TypeError, ValueError, OverflowError):
        raise ArgumentTypeError(f"{name}: an array of real numbers, got {_shown(value)}") from None
    if a.dtype.kind not in "iuf":
        raise ArgumentTypeError(f"{name}: an array of real numbers, got {_shown(value)}")
    return a.astype(float, copy=False)


def _text(value: bytes | str) -> str:
    """A fixed-length character result of the binding as a stripped str (a path in it as
    the file system names it: bytes that are not UTF-8 survive, as os.fsdecode keeps them)."""
    return (os.fsdecode(value) if isinstance(value, bytes) else str(value)).strip()
