"""The rule every output path of pymr obeys, checked before any work is done.

Every command's ``-o`` (and ``--json``, a sweep's summary) goes through
:func:`check_output`: an output that
cannot be written is refused at once, in one line naming the option and the path, with
exit status 1 (an :class:`OutputError`, a :class:`pymr.PymrError`), instead of a traceback,
a hidden file (``-o .`` gave ``./.png``) or a refusal after minutes of work. The file is
then written by :func:`pymr.api.write_file` (whole or not at all), whose own check stays as
the last guard.

A file output is refused when it is

- an empty name, or not a file name at all, or ``-`` (standard output in many tools; the
  kernel refuses it for its results too);
- a folder (an existing one, ``.``, ``..``, or a name ending in ``/``): the message names a
  file in it that would do;
- a name that is only a suffix (``.png``, a hidden file with no name) when suffixes are given;
- in a folder that is not there, is not a folder, or cannot be written;
- an existing path that is not a regular file (a FIFO, a device: the final rename would
  replace ``/dev/null`` with a file), or a symbolic link (the rename would replace the link,
  not the file it points to; ``/dev/stdout`` is one);
- of a format the command cannot write (``suffixes``);
- one of the command's inputs (``inputs``), or the scene or a file the scene reads
  (``scene``: the kernel's own rule, :func:`pymr.api.check_not_input`).
"""
from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable, Sequence

from .errors import OutputError


def _text(path, option: str, what: str, if_left_out: str | None) -> str:
    if isinstance(path, bytes):
        path = os.fsdecode(path)
    if not isinstance(path, (str, os.PathLike)):
        raise OutputError(f"{option}: a file name expected for the {what}, got {path!r}")
    text = os.fspath(path)
    if text == "":
        # an unset shell variable: refused, not taken as the default
        hint = f"(leave {option} out for {if_left_out})" if if_left_out else f"for the {what}"
        raise OutputError(f"{option}: an empty file name {hint}")
    if "\0" in text:
        raise OutputError(f"{option} {text!r}: a file name cannot hold a NUL character")
    return text


def _is_dir(path: Path) -> bool:
    try:
        return path.is_dir()
    except (OSError, ValueError):
        return False


def _exists(path: Path) -> bool:
    try:
        return os.path.lexists(path)
    except (OSError, ValueError):
        return False


def not_replaceable(path: Path) -> str:
    """Why an output written whole beside `path` and renamed over it cannot be put there,
    by the kernel's rule (not_replaceable): a directory, a FIFO or a device, or a symbolic
    link, which the rename would replace; '' where it can."""
    from . import _kernel as _core
    from ._args import _text
    return _text(_core.pymr_not_replaceable(os.fsencode(path)))


def _same(a: Path, b: Path) -> bool:
    """Whether a and b name one file: the kernel's same_file (the same file on the disk, links
    followed, or the same absolute path)."""
    from . import _kernel as _core
    return bool(_core.pymr_same_file(os.fspath(a), os.fspath(b)))


def _folder_of(text: str, option: str, beside: bool = True) -> Path:
    """The folder an output path goes in, which must be there and writable; with `beside`
    (a file, or a folder replaced whole, written as a temporary one beside it) the name must
    leave room for the temporary one's."""
    path = Path(text)
    parent = path.parent
    shown = str(parent) if str(parent) != "." else "."
    if not _exists(parent):
        raise OutputError(f"{option} {text}: the folder {shown} is not there (make it first)")
    if not _is_dir(parent):
        raise OutputError(f"{option} {text}: {shown} is not a folder")
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"{option} {text}: cannot write in the folder {shown} (permission denied)")
    room = _name_max(parent) - TEMPORARY_NAME
    if beside and len(os.fsencode(path.name)) > room:
        raise OutputError(f"{option} {text}: a name of {len(os.fsencode(path.name))} bytes; the folder takes "
                          f"names of {room + TEMPORARY_NAME}, and pymr writes a temporary file beside it: "
                          f"take at most {room}")
    return parent


#: Bytes a temporary file's name adds to its output's (NAME.PID.tmp, .NAME.PID.tmp.png, .NAME.tmp-XXXXXXXX).
TEMPORARY_NAME = 24


def _name_max(folder: Path) -> int:
    """The longest file name (bytes) the file system of `folder` takes (255 if it does not say)."""
    try:
        return int(os.pathconf(folder, "PC_NAME_MAX"))
    except (OSError, ValueError):
        return 255


def check_output(path, what: str, *, option: str = "-o", example: str | None = None,
                 suffixes: Sequence[str] | None = None, inputs: Iterable = (), scene=None,
                 overrides=None, if_left_out: str | None = "the default") -> Path:
    """Check an output file before any work; return it as a Path. Refused (OutputError, one
    line naming `option` and the path): see the module's docstring.

    `what` names the file in messages ("figure", "animation"); `example` is a file name the
    message offers when a folder was given (``-o .`` -> "give a file name such as
    ./p.png"); `suffixes` are the formats the command writes (lower case, with the dot;
    None: any); `inputs` are files the command reads, which it must not overwrite; `scene`
    (with `overrides`) is a scene whose own file and the files it reads must not be
    overwritten either (the kernel checks its own outputs, the results and modal files, by
    the same rule); `if_left_out` says what leaving the option out gives (None: it is
    required), for the message on an empty name."""
    text = _text(path, option, what, if_left_out)
    if text == "-":                     # standard output in many tools; here a file named '-'
        raise OutputError(f"{option} -: pymr writes the {what} to a file, not to standard output; name a file")
    out = Path(text)
    ends_as_folder = text.endswith(("/", os.sep)) or out.name in ("", ".", "..") or text in (".", "..")
    if ends_as_folder or _is_dir(out):
        hint = f": give a file name for the {what}" + (f", such as {os.path.join(text, example)}" if example else "")
        raise OutputError(f"{option} {text}: is a folder, not a file{hint}")
    if suffixes is not None:
        suffix = out.suffix.lower()
        allowed = ", ".join(suffixes)
        if out.name.lower() in suffixes:
            raise OutputError(f"{option} {text}: a suffix with no name before it (a hidden file); give the {what} "
                              f"a name such as {example or 'out' + suffixes[0]}")
        if not suffix:
            raise OutputError(f"{option} {text}: no suffix to say the {what}'s format (one of {allowed})")
        if suffix not in suffixes:
            raise OutputError(f"{option} {text}: {suffix} is not a format of the {what} (one of {allowed})")
    _folder_of(text, option)
    why = not_replaceable(out)
    if why:
        raise OutputError(f"{option} {text}: {why}; choose another {what}")
    for source in inputs:
        if source is not None and _same(out, Path(source)):
            raise OutputError(f"{option} {text}: would overwrite the input {source}; choose another {what}")
    if scene is not None:
        from ._args import overwritten_input
        found = overwritten_input(scene, text, overrides)
        if found:
            raise OutputError(f"{option} {text}: would overwrite {found}; choose another {what}")
    return out

