"""pymr's exceptions: every error the package raises for bad input or a failed run is one of
these, with a one-line message."""


class PymrError(RuntimeError):
    """Base class of pymr's errors."""


class SceneError(PymrError, ValueError):
    """Bad input: the scene file, a group or an item, or an argument of a pymr function is
    wrong (mrsim exit status 1). The message names the file, group and item, or the argument."""


class ArgumentTypeError(SceneError, TypeError):
    """Bad input: an argument of a pymr function is of the wrong type (a number where a path
    is due, text where an array of numbers is due, bytes where text is due). A
    :class:`SceneError` (and so a ValueError) and a TypeError; the message names the argument."""


class SolverError(PymrError):
    """A run that failed: singular mass matrix, step size underflow, non-finite state."""


class OutputError(PymrError):
    """An output file that cannot be written (its folder is missing, it is a directory, the
    disk refused it): bad input, as mrsim's exit status 1 for an unwritable -o."""


class ResultsError(PymrError, ValueError):
    """A results file that cannot be read: missing, not a pymr CSV, no rows, a broken JSON
    beside it (bad input)."""
