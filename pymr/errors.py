"""pymr's exceptions: every error the package raises for bad input or a failed run is one of
these, with a one-line message."""


class PymrError(RuntimeError):
    """Base class of pymr's errors."""


class SceneError(PymrError, ValueError):
    """Bad input: the scene file, a group or an item is wrong (mrsim exit status 1)."""


class SolverError(PymrError):
    """A run that failed: singular mass matrix, step size underflow, non-finite state."""


class OutputError(PymrError):
    """An output file that cannot be written (its folder is missing, it is a directory, the
    disk refused it): bad input, as mrsim's exit status 1 for an unwritable -o."""


class ResultsError(PymrError, ValueError):
    """A results file that cannot be read: missing, not a pymr CSV, no rows, a broken JSON
    beside it (bad input)."""
