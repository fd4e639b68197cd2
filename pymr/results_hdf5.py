"""Reading HDF5 results (``&output format = 'hdf5'``) into :class:`pymr.Results`.

The kernel writes one dataset per group of columns (``time``, ``joint_coordinates``,
``markers``, ``energy`` ...), rows by columns, each with the attributes ``columns``,
``owners``, ``quantities`` and ``units``; the file's attributes hold ``title``, ``method``,
``scene_fingerprint``, ``resolved_scene``, ``integrator`` (JSON), ``column_order`` (the
columns' names in the CSV's order, comma-separated), ``status`` ('partial' while the run
writes, 'complete' at its end) and, when complete, ``statistics`` (the text of OUT.json).
Any HDF5 reader can read it; this module puts the columns back in the CSV's order, so that
both formats give the same :class:`Results`.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from .errors import ResultsError

#: The first bytes of every HDF5 file.
SIGNATURE = b"\x89HDF\r\n\x1a\n"


def is_hdf5(path: Path) -> bool:
    """Does the file at `path` start with HDF5's signature?"""
    try:
        with open(path, "rb") as fh:
            return fh.read(8) == SIGNATURE
    except OSError:
        return False


def _text(value) -> str:
    return value.decode() if isinstance(value, (bytes, np.bytes_)) else str(value)


def read_hdf5(path: Path):
    """The Results of the HDF5 results file at `path` (statistics from the file, else from
    OUT.json beside it), checked as a CSV's are (:func:`pymr.results.checked`)."""
    from .results import _read_stats, checked, parse_stats
    try:
        import h5py
    except ImportError:
        raise ResultsError(f"{path}: an HDF5 results file needs the Python package h5py "
                           "(pip install h5py)") from None
    try:
        with _open(h5py, path) as f:
            if "column_order" not in f.attrs:
                raise ResultsError(f"{path}: not a pymr HDF5 results file (no attribute 'column_order')")
            order = _text(f.attrs["column_order"]).split(",")
            data = _columns_in_order(h5py, f, order, path)
            attrs = {k: _text(v) for k, v in f.attrs.items()}
    except ResultsError:
        raise
    except (OSError, RuntimeError, KeyError, ValueError, TypeError) as exc:
        # h5py raises RuntimeError for some damage (a superblock it cannot decode)
        raise ResultsError(f"{path}: not a pymr HDF5 results file ({' '.join(str(exc).split())})") from None
    if "statistics" in attrs:
        stats, where = parse_stats(attrs["statistics"], f"{path} (its attribute 'statistics')"), \
            f"{path} (its attribute 'statistics')"
    else:
        stats, where = _read_stats(path.with_suffix(".json")), str(path.with_suffix(".json"))
    meta = {"title": attrs.get("title", ""), "method": attrs.get("method", "")}
    return checked(path, order, data, stats, meta, where)


#: What HDF5 says of a file still marked open for writing (a run killed as it wrote): the
#: one reason to open it again in single-writer/multiple-reader mode.
OPEN_FOR_WRITE = "already open for write"


def _open(h5py, path: Path):
    """The file open for reading. A run's partial file that was killed as it wrote is still
    marked open for writing, and opens (once more, no retry loop of ours) in
    single-writer/multiple-reader mode. Any other failure (a truncated file, a damaged
    superblock) is the first open's: SWMR mode would not repair it, and its reads retry a
    damaged file's metadata for minutes before giving up."""
    try:
        return h5py.File(path, "r")
    except OSError as exc:
        if OPEN_FOR_WRITE not in str(exc):
            raise
    return h5py.File(path, "r", swmr=True)


def _columns_in_order(h5py, f, order: list[str], path: Path) -> np.ndarray:
    """The datasets' columns side by side in `order` (rows, columns): each dataset of
    numbers, one row per time, with its attribute 'columns' (a ResultsError naming the
    dataset otherwise)."""
    def fault(text: str) -> ResultsError:
        return ResultsError(f"{path}: not a pymr HDF5 results file ({text})")

    if "time" not in f:
        raise fault("no dataset 'time'")
    place: dict[str, tuple[str, int]] = {}
    arrays = {}
    for name, dataset in f.items():
        if not isinstance(dataset, h5py.Dataset):
            what = ("a group" if isinstance(dataset, h5py.Group) else
                    "a link to nothing" if dataset is None else "a named datatype")
            raise fault(f"{name!r} is {what}, not a dataset of columns")
        if "columns" not in dataset.attrs:
            raise fault(f"dataset {name!r} has no attribute 'columns'")
        for k, column in enumerate(np.atleast_1d(dataset.attrs["columns"])):
            place[_text(column)] = (name, k)
        values = np.asarray(dataset[()])
        if values.dtype.kind not in "iuf":
            raise fault(f"dataset {name!r} does not hold numbers")
        arrays[name] = values
    missing = [c for c in order if c not in place]
    if missing:
        raise fault(f"no dataset holds the columns {', '.join(missing[:5])}")
    rows = len(np.atleast_1d(arrays["time"]))
    data = np.empty((rows, len(order)))
    for j, column in enumerate(order):
        name, k = place[column]
        values = arrays[name]
        if values.ndim not in (1, 2) or len(values) != rows or (values.ndim == 2 and k >= values.shape[1]):
            raise fault(f"dataset {name!r} has shape {values.shape}, not one row per time ({rows}) and a column "
                        f"per name")
        data[:, j] = values if values.ndim == 1 else values[:, k]
    return data
