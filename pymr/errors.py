"""pymr's exceptions: every error the package raises for bad input or a failed run is one of
these, with a one-line message."""
from __future__ import annotations


class PymrError(RuntimeError):
    """Base class of pymr's errors.

    An error the kernel raised carries its structured fields beside its message (callers act
    on these, never on the words of the message):

    - ``kind``: a short keyword: ``'unstable_step'`` (a fixed step the pre-flight check
      refuses), ``'unstable_ratio'`` (a multirate step ratio it refuses), ``'bad_value'`` (an
      item's value refused), else ``'bad_input'`` or ``'solver'``; ``''`` for an error raised
      in Python;
    - ``group``, ``item``: the scene group and item it is about (``''`` when none);
    - ``fault``: what is wrong without where (for ``'bad_value'``: ``'must be in (0, 1e+9],
      got 1e+308'``), ``''`` when not kept;
    - ``stable_step``: for ``'unstable_step'``, the largest stable step (s), else None;
    - ``stable_ratio``: for ``'unstable_ratio'``, the largest stable step ratio k (0 when
      none is stable), else None.
    """

    kind: str = ""
    group: str = ""
    item: str = ""
    fault: str = ""
    stable_step: float | None = None
    stable_ratio: int | None = None

    @classmethod
    def from_kernel(cls, message: str, fields: dict[str, str]) -> "PymrError":
        """The error of a kernel's message and its fields (``name: text`` as the binding
        gives them)."""
        error = cls(message)
        error.kind = fields.get("kind", "")
        error.group = fields.get("group", "")
        error.item = fields.get("item", "")
        error.fault = fields.get("fault", "")
        if error.kind == "unstable_step":
            error.stable_step = float(fields["stable_step"])
        if error.kind == "unstable_ratio":
            error.stable_ratio = int(fields["stable_ratio"])
        return error


class PymrWarning(UserWarning):
    """What pymr doubts but does not refuse (``pymr modal-import``: a stiffness that resists
    a rigid motion of the nodes). The command line prints it as one ``pymr: warning:`` line
    on stderr."""


class SceneError(PymrError, ValueError):
    """Bad input: the scene file, a group or an item, or an argument of a pymr function is
    wrong (mrsim exit status 1). The message names the file, group and item, or the argument."""


class ArgumentTypeError(SceneError, TypeError):
    """Bad input: an argument of a pymr function is of the wrong type (a number where a path
    is due, text where an array of numbers is due, bytes where text is due). A
    :class:`SceneError` (and so a ValueError) and a TypeError; the message names the argument."""


class ImportInputError(SceneError):
    """Bad input of ``pymr modal-import``: one line naming the file and the fault."""


class SolverError(PymrError):
    """A run that failed: singular mass matrix, step size underflow, non-finite state."""


class OutputError(PymrError):
    """An output file that cannot be written (its folder is missing, it is a directory, the
    disk refused it): bad input, as mrsim's exit status 1 for an unwritable -o."""


class ResultsError(PymrError, ValueError):
    """A results file that cannot be read: missing, not a pymr CSV, no rows, a broken JSON
    beside it (bad input)."""


class ResultsKeyError(ResultsError, KeyError):
    """A name that results do not have (a column, marker, joint, flexible body, a joint's
    reactions), asked of a :class:`pymr.Results`: a :class:`ResultsError` and, as a mapping's
    unknown key is, a KeyError. The message lists the names the results have."""

    def __str__(self) -> str:
        return BaseException.__str__(self)       # the message itself (KeyError's str quotes it)
