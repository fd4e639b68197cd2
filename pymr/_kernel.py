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
    """The binding's function, wrapped only when it takes text (f2py documents such a
    parameter as ``input string``): those that take numbers alone, Model.rhs's evaluation
    among them, are called directly. Resolved once per name."""
    function = resolved = getattr(_core, name)
    if callable(function) and "input string" in (function.__doc__ or ""):
        def resolved(*args, **kwargs):
            return function(*map(_bytes, args), **{k: _bytes(v) for k, v in kwargs.items()})
        resolved.__name__ = name
        resolved.__doc__ = function.__doc__
    globals()[name] = resolved
    return resolved
