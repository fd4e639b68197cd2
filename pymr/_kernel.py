"""pymr._core as the package calls it: text arguments go in as bytes, in the file system's
encoding. f2py passes a str to the kernel only when it is ASCII, and otherwise fails with a
misleading TypeError ('function takes exactly 5 arguments (1 given)'), so a scene path, an
override or an output path with any other character (``pendel_ü.nml``, ``scene.title=Zürich``)
raised a traceback. Bytes that come back are read with :func:`os.fsdecode` (api._text)."""
from __future__ import annotations

import os

from . import _core


def _bytes(value):
    return os.fsencode(value) if isinstance(value, str) else value


def __getattr__(name: str):
    function = getattr(_core, name)
    if not callable(function):
        return function

    def call(*args, **kwargs):
        return function(*map(_bytes, args), **{k: _bytes(v) for k, v in kwargs.items()})
    call.__name__ = name
    call.__doc__ = function.__doc__
    return call
