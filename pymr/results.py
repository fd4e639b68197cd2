"""Result files: OUT.csv (comment lines, header, rows) and OUT.json (run statistics)."""
from __future__ import annotations

import json
import os
import warnings
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .errors import ArgumentTypeError, ResultsError, ResultsKeyError


@dataclass(frozen=True)
class Column:
    """What the kernel says of one column of a results file (OUT.json's "columns"): its
    name, group ('time', 'joint_coordinates', 'joint_rates', 'controls', 'modal_coordinates',
    'modal_rates', 'markers', 'marker_accelerations', 'marker_orientations', 'reactions',
    'energy', 'sensors'), owner (the joint, flexible body, marker or sensor; '' for t and the
    energies),
    quantity (such as 'angle', 'displacement', 'position', 'force', 'kinetic') and unit."""
    name: str
    group: str
    owner: str
    quantity: str
    unit: str


#: The lists of OUT.json's "columns", in the order of :class:`Column`'s fields.
COLUMN_FIELDS = ("name", "group", "owner", "quantity", "unit")


def column_table(meta, columns: list[str], where: str, why: str = "the file was changed") -> list[Column]:
    """OUT.json's "columns" (`meta`) as one :class:`Column` per column of `columns`, checked:
    an object of the five lists of COLUMN_FIELDS, each of one text per column, the names
    those of `columns`. A damaged or hand-edited one is a ResultsError naming `where`, the
    fault and `why` (it gave TypeError or KeyError tracebacks where it was used)."""
    if not isinstance(meta, dict):
        raise ResultsError(f'{where}: "columns" is not an object of the lists {", ".join(COLUMN_FIELDS)} ({why})')
    for key in COLUMN_FIELDS:
        if key not in meta:
            raise ResultsError(f'{where}: "columns" has no list "{key}" ({why})')
        values = meta[key]
        if not isinstance(values, list) or not all(isinstance(v, str) for v in values):
            raise ResultsError(f'{where}: "columns" "{key}" is not a list of texts, one per column ({why})')
        if len(values) != len(columns):
            raise ResultsError(f'{where}: "columns" "{key}" has {len(values)} entries for the {len(columns)} '
                               f"columns of the results ({why}, or they are another run's)")
    if meta["name"] != list(columns):
        raise ResultsError(f'{where}: "columns" "name" does not match the results\' columns ({why}, or they are '
                           "another run's)")
    return [Column(*fields) for fields in zip(*(meta[k] for k in COLUMN_FIELDS))]


def _unknown(what: str, name: str, known: list[str]) -> ResultsKeyError:
    """The error of a name the results do not have, listing those they have."""
    return ResultsKeyError(f"no {what} {name!r}; {what}s: {', '.join(known) or '(none)'}")


def _key(what: str, name) -> str:
    """A name asked of the results: a str (None, a number or a list was taken as 'every
    owner', or failed inside numpy): an ArgumentTypeError naming `what`."""
    if not isinstance(name, str):
        from ._args import _shown
        raise ArgumentTypeError(f"{what}: a name (str), got {_shown(name)}")
    return name


@dataclass
class Results:
    """A run's results: columns by name as numpy arrays, statistics and comment lines.

    - ``res["elevation.q"]``, ``res.t``: one column by name (a view into ``data``).
    - ``stats``: the run statistics of OUT.json (empty when there is none).
    - ``meta``: the CSV's comment lines as ``key: value`` (``title``, ``method``, and
      ``scene`` when the file names it); ``title`` and ``method`` are also properties.
    - ``markers``, ``joints``, ``flexible_bodies``: names in column order;
      ``marker(name)``, ``joint(name)``, ``modal(body)``: their arrays.
    """

    columns: list[str]
    data: np.ndarray
    stats: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)
    path: str | None = None
    summary: str = ""

    def __post_init__(self) -> None:
        """Results made by hand are checked as a file's are: column names (str) from 't', a
        (rows, columns) array of real numbers, statistics and comment lines as dicts (an
        ArgumentTypeError or a ResultsError naming the field, not an error where used)."""
        from ._args import _array, _shown
        if isinstance(self.columns, str) or not isinstance(self.columns, (list, tuple)) \
                or not all(isinstance(c, str) for c in self.columns):
            raise ArgumentTypeError(f"columns: a list of column names (str), got {_shown(self.columns)}")
        self.columns = list(self.columns)
        if not self.columns or self.columns[0] != "t":
            raise ResultsError(f"columns: the first column is the time 't', got {_shown(self.columns)}")
        self.data = _array("data", self.data)
        if self.data.ndim != 2 or self.data.shape[1] != len(self.columns):
            raise ResultsError(f"data: an array (rows, {len(self.columns)}) for the {len(self.columns)} columns, "
                               f"got shape {self.data.shape}")
        for name in ("stats", "meta"):
            if not isinstance(getattr(self, name), dict):
                raise ArgumentTypeError(f"{name}: a dict, got {_shown(getattr(self, name))}")
        _check_stats(self.stats, self.columns, "stats", "given by hand")
        if self.path is not None and not isinstance(self.path, (str, os.PathLike)):
            raise ArgumentTypeError(f"path: the results file's path (str), or None, got {_shown(self.path)}")
        self.path = None if self.path is None else os.fspath(self.path)
        if not isinstance(self.summary, str):
            raise ArgumentTypeError(f"summary: a text (str), got {_shown(self.summary)}")
        check_columns("columns", self.columns)
        check_rows("data", self.data, self.columns)

    @classmethod
    def _of_checked_file(cls, path: Path, columns: list[str], data: np.ndarray, stats: dict,
                         meta: dict) -> "Results":
        """The Results of a file that :func:`checked` has checked in the file's words, made
        without __post_init__ (which would check every field again, in the words of Results
        made by hand)."""
        from ._args import _array
        res = cls.__new__(cls)
        res.columns, res.data, res.stats, res.meta = list(columns), _array("data", data), stats, meta
        res.path, res.summary = str(path), ""
        return res

    def __getitem__(self, name: str) -> np.ndarray:
        if _key("name", name) not in self.columns:
            raise _unknown("column", name, self.columns)
        return self.data[:, self.columns.index(name)]

    def __contains__(self, name: str) -> bool:
        return _key("name", name) in self.columns

    def __iter__(self):
        """The column names, as `in` and ``res[name]`` take them (iteration fell back to
        ``res[0]``, refused as "a name (str), got int 0")."""
        return iter(self.columns)

    @property
    def t(self) -> np.ndarray:
        return self["t"]

    @property
    def title(self) -> str:
        """The scene's title (``# title:`` line), or ``""``."""
        return self.meta.get("title", "")

    @property
    def method(self) -> str:
        """The integration method (``# method:`` line), e.g. ``single fixed h= 1.000E-04``, or ``""``."""
        return self.meta.get("method", "")

    @property
    def scene(self) -> str | None:
        """The scene file when the CSV names it (``# scene:`` line), else None."""
        return self.meta.get("scene") or None

    @property
    def column_info(self) -> list[Column]:
        """Every column's :class:`Column`, in the file's order, from OUT.json's column
        metadata (a :class:`ResultsError` when the results have none: OUT.json missing, or
        written before pymr wrote it)."""
        meta = self.stats.get("columns")
        cached = self.__dict__.get("_column_cache")
        if cached is not None and cached[0] is meta and cached[1] == self.columns:
            return cached[2]
        where = self.path or "these results"
        if not isinstance(meta, dict) or meta.get("name") != self.columns:
            raise ResultsError(f"{where}: no column metadata matching the columns (OUT.json beside the results "
                               "file gives it: run the scene again to write it)")
        info = column_table(meta, self.columns, where)
        self.__dict__["_column_cache"] = (meta, list(self.columns), info)
        return info

    def unit(self, name: str) -> str:
        """The unit of column `name` (``'rad'``, ``'m'``, ``'J'`` ...)."""
        _key("name", name)
        for c in self.column_info:
            if c.name == name:
                return c.unit
        raise _unknown("column", name, self.columns)

    def _names(self, group: str, owner: str | None = None, quantity: str | None = None) -> list[str]:
        """The names of the columns of `group` (of `owner`, of `quantity`), in column order."""
        return [c.name for c in self.column_info if c.group == group and (owner is None or c.owner == owner)
                and (quantity is None or c.quantity == quantity)]

    def _owners(self, group: str) -> list[str]:
        return list(dict.fromkeys(c.owner for c in self.column_info if c.group == group))

    @property
    def markers(self) -> list[str]:
        """Names of the markers with position and velocity columns, in column order."""
        return self._owners("markers")

    @property
    def joints(self) -> list[str]:
        """Names of the joints with coordinates (``j.q`` or ``j.q1`` ...), in column order."""
        return self._owners("joint_coordinates")

    @property
    def flexible_bodies(self) -> list[str]:
        """Names of the bodies with modal coordinates (``body.a1`` ...), in column order."""
        return self._owners("modal_coordinates")

    def joint_columns(self, name: str) -> list[str]:
        """Coordinate column names of joint ``name``: ``["j.q"]`` or ``["j.q1", ..., "j.qn"]``."""
        cols = self._names("joint_coordinates", _key("name", name))
        if not cols:
            raise _unknown("joint", name, self.joints)
        return cols

    def modal_columns(self, body: str) -> list[str]:
        """Modal coordinate column names of flexible body ``body``: ``["b.a1", ..., "b.aM"]``."""
        cols = self._names("modal_coordinates", _key("body", body))
        if not cols:
            raise ResultsKeyError(f"no flexible body {body!r}; flexible bodies: "
                                  f"{', '.join(self.flexible_bodies) or '(none)'}")
        return cols

    def _stack(self, names: list[str]) -> np.ndarray:
        """The columns `names` side by side, shape (rows, len(names))."""
        return np.column_stack([self[c] for c in names]) if names else np.zeros((len(self.t), 0))

    def marker(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position (rows, 3) and velocity (rows, 3) of a marker, inertial frame."""
        if _key("name", name) not in self.markers:
            raise _unknown("marker", name, self.markers)
        return (self._stack(self._names("markers", name, "position")),
                self._stack(self._names("markers", name, "velocity")))

    def reaction(self, joint: str) -> tuple[np.ndarray, np.ndarray]:
        """Force (rows, 3; N) and moment (rows, 3; N m) that ``joint`` passes to its child, in
        the child's axes, the moment about the joint point (``&output quantities 'reactions'``)."""
        force = self._names("reactions", _key("joint", joint), "force")
        moment = self._names("reactions", joint, "moment")
        if not force:
            raise ResultsKeyError(f"no reactions of joint {joint!r} (&output quantities 'reactions'; joints with "
                                  f"reactions: {', '.join(self._owners('reactions')) or '(none)'})")
        return self._stack(force), self._stack(moment)

    def joint(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Coordinates (rows, n) and rates (rows, n) of joint ``name`` (n = 1 for a revolute)."""
        return self._stack(self.joint_columns(name)), self._stack(self._names("joint_rates", name))

    def modal(self, body: str) -> tuple[np.ndarray, np.ndarray]:
        """Modal coordinates (rows, M) and their rates (rows, M) of flexible body ``body``."""
        return self._stack(self.modal_columns(body)), self._stack(self._names("modal_rates", body))

    def coordinate_columns(self) -> list[str]:
        """The names of the generalised coordinates' columns in model order: joint
        coordinates first, then the controllers' states, then modal ones."""
        return (self._names("joint_coordinates") + self._names("controls", quantity="double_integral")
                + self._names("modal_coordinates"))

    def coordinates(self) -> tuple[np.ndarray, np.ndarray]:
        """All generalised coordinates and rates (rows, n) in model order: joint
        coordinates (``j.q``, ``j.q1`` ...) first, then the controllers' states
        (``c.double_integral``; rates ``c.integral``), then modal ones (``body.a1`` ...)."""
        return (self._stack(self.coordinate_columns()),
                self._stack(self._names("joint_rates") + self._names("controls", quantity="integral")
                            + self._names("modal_rates")))


    def _column_table(self) -> list[Column]:
        """Every column's :class:`Column`; with no column metadata (a CSV without its OUT.json),
        the names with group, owner, quantity and unit all ``''`` (unknown)."""
        meta = self.stats.get("columns")
        if isinstance(meta, dict) and meta.get("name") == self.columns:
            return self.column_info
        return [Column(name, "", "", "", "") for name in self.columns]

    def _description(self) -> dict:
        """The run's title, method, scene fingerprint and scene file ('' when unknown)."""
        return {"title": self.title, "method": self.method,
                "fingerprint": str(self.stats.get("scene_fingerprint", "")),
                "scene": str(self.stats.get("scene") or self.scene or "")}

    def to_pandas(self):
        """The results as a :class:`pandas.DataFrame`: time as the index (named ``'t'``), one
        column per other result column, its values this object's arrays unchanged.

        ``df.attrs`` describes them, from OUT.json's column metadata:

        - ``"columns"``: ``{name: {"group", "owner", "quantity", "unit"}}`` for every column,
          ``'t'`` included;
        - ``"units"``: ``{name: unit}`` (``'t'``: ``'s'``), the same units, for quick use;
        - ``"title"``, ``"method"``, ``"fingerprint"``, ``"scene"``: the run's.

        Without column metadata (a CSV read without its OUT.json) the values are the same and
        every group, owner, quantity and unit is ``''``: unknown, not guessed from the names.
        pandas is imported here; without it, a :class:`ResultsError`.
        """
        pd = _optional("pandas", "to_pandas")
        info = self._column_table()
        df = pd.DataFrame(self.data[:, 1:], index=pd.Index(self.data[:, 0], name="t"), columns=self.columns[1:])
        df.attrs["columns"] = {c.name: {"group": c.group, "owner": c.owner, "quantity": c.quantity, "unit": c.unit}
                               for c in info}
        df.attrs["units"] = {c.name: c.unit for c in info}
        df.attrs.update(self._description())
        return df

    def to_xarray(self):
        """The results as an :class:`xarray.Dataset`: coordinate ``'t'`` and one data variable
        per other column along it, the values this object's arrays unchanged.

        Each variable's (and ``t``'s) attrs: ``unit`` and ``units`` (the same text: ``units`` is
        the CF convention's name, which xarray's plots and netCDF readers use), ``group``,
        ``owner``, ``quantity`` (OUT.json's column metadata) and ``long_name`` (the column's
        name). The dataset's attrs: ``title``, ``method``, ``fingerprint`` and ``scene``.
        Without column metadata the unit and the rest are ``''`` (see :meth:`to_pandas`).
        xarray is imported here; without it, a :class:`ResultsError`.
        """
        xr = _optional("xarray", "to_xarray")

        def attrs(c: Column) -> dict:
            return {"unit": c.unit, "units": c.unit, "group": c.group, "owner": c.owner,
                    "quantity": c.quantity, "long_name": c.name}

        info = self._column_table()
        coords = {"t": ("t", self.data[:, 0], attrs(info[0]))}
        variables = {c.name: ("t", self.data[:, k], attrs(c)) for k, c in enumerate(info) if k > 0}
        return xr.Dataset(variables, coords=coords, attrs=self._description())


def _optional(package: str, method: str):
    """The module `package`, imported when a method needs it (a ResultsError without it)."""
    import importlib
    try:
        return importlib.import_module(package)
    except ImportError:
        raise ResultsError(f"Results.{method}() needs the Python package {package}, which is not installed "
                           f"(pip install {package})") from None


def load_results(csv_path: str | os.PathLike) -> Results:
    """Load OUT.csv and, when present, OUT.json beside it; or an HDF5 results file (OUT.h5,
    :mod:`pymr.results_hdf5`), to the same Results. A file that is missing, is no
    pymr results file (header from the column 't', rows of finite numbers) or has no rows,
    and a JSON beside it that is not JSON, raise :class:`ResultsError`."""
    from ._args import _path             # the one check of a path argument
    text = _path("csv_path", csv_path, ResultsError)
    if not text:
        raise ResultsError("csv_path: an empty path (give a results file, OUT.csv)")
    path = Path(text)
    _check_file(path)
    from .results_hdf5 import is_hdf5, read_hdf5
    if is_hdf5(path):
        return read_hdf5(path)
    meta, header, skip = _read_head(path)
    if not header or header[0] != "t":
        raise ResultsError(f"{path}: not a pymr result file (its header does not start with the column 't')")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")      # numpy's "input contained no data"
            data = np.loadtxt(path, delimiter=",", comments="#", skiprows=skip, ndmin=2)
    except ValueError:
        raise ResultsError(f"{path}: not a pymr result file ({_row_fault(path, skip, header)})") from None
    except OSError as exc:
        raise ResultsError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    if data.shape[0] and data.shape[1] != len(header):
        raise ResultsError(f"{path}: not a pymr result file ({_row_fault(path, skip, header)})")
    jpath = path.with_suffix(".json")
    res = checked(path, header, data, _read_stats(jpath), meta, str(jpath))
    _check_pairing(path, res.stats, data[-1], jpath)
    return res


def _check_pairing(path: Path, stats: dict, last: np.ndarray, jpath: Path) -> None:
    """The statistics of a complete run name its results file's size and last row: a file
    of other bytes is another run's (a kill between the renames of the two, or a results
    file copied over another's), which loaded as one run when the row counts agreed. The
    row is compared as read (`last`, the file's last row): one text gives one number."""
    if stats.get("status") != "complete" or "results_bytes" not in stats:
        return                             # a failed run's, or statistics written before pymr kept these
    size = path.stat().st_size
    try:
        same_row = "last_row" not in stats or np.array_equal(
            np.array(stats["last_row"].split(","), dtype=float), last)
    except ValueError:                     # not a row of numbers: not this file's
        same_row = False
    if size != stats["results_bytes"] or not same_row:
        raise ResultsError(f"{path}: {jpath.name} describes another run's results ({stats['results_bytes']} bytes, "
                           f"this file {size}, and another last row): the two were not written together (a run "
                           "killed between them, or a file copied over the other)")


def checked(path: Path, columns: list[str], data: np.ndarray, stats: dict, meta: dict, where: str) -> Results:
    """The Results of a results file read (CSV or HDF5: one rule for both), refused unless
    it has rows, every value is finite (a run writes none that is not) and its statistics
    (read from `where`) are whole: the fields pymr reads of their types, the column
    metadata one entry per column, and a complete run's row count the file's."""
    check_columns(path, columns)
    check_rows(path, data, columns)
    _check_stats(stats, columns, where)
    rows = stats.get("rows")
    if stats.get("status") == "complete" and rows is not None and rows != data.shape[0]:
        # a failed run's statistics ('failed') count its partial file's rows, not these
        fault = "the file was cut" if data.shape[0] < rows else "the file was changed"
        raise ResultsError(f"{path}: {data.shape[0]} row{'s' if data.shape[0] != 1 else ''} of the {rows} the run "
                           f"wrote ({fault})")
    return Results._of_checked_file(path, columns, data, stats, meta)


def check_columns(where, columns: list[str]) -> None:
    """Column names as a run writes them: each given once, none empty, no blanks around one
    (a ResultsError naming `where` and the column otherwise: a repeated name hid a column)."""
    seen = set()
    for k, name in enumerate(columns):
        if not name or name != name.strip():
            raise ResultsError(f"{where}: column {k + 1}: {name!r} is no column name (a run writes none: the file "
                               "was changed)")
        if name in seen:
            raise ResultsError(f"{where}: column {k + 1}: {name!r} is named twice (a run writes each column once: "
                               "the file was changed)")
        seen.add(name)


def check_rows(where, data: np.ndarray, columns: list[str]) -> None:
    """Results' rows as a run writes them: at least one, every value finite, their times
    (column t) in order (a ResultsError naming `where`, the row and the column otherwise;
    two rows may show one time where &output precision is below the digits that tell them
    apart)."""
    if data.shape[0] == 0:
        raise ResultsError(f"{where}: has no result rows")
    if not np.isfinite(data).all():
        row, col = np.argwhere(~np.isfinite(data))[0]
        raise ResultsError(f"{where}: row {row + 1}, column {columns[col]}: {data[row, col]} is not a finite number "
                           "(a run writes none: the file was changed)")
    if columns and columns[0] == "t" and not (np.diff(data[:, 0]) >= 0).all():
        row = int(np.argmin(np.diff(data[:, 0]) >= 0)) + 2
        raise ResultsError(f"{where}: row {row}, column t: {float(data[row - 1, 0])!r} is before the row before it "
                           f"({float(data[row - 2, 0])!r}; a run writes its rows in time: the file was changed)")


#: The statistics fields pymr reads, and what each must be (besides "columns":
#: :func:`column_table`). A field of another type is refused where the file is read.
STATS_FIELDS = {"status": (str, "a text"), "scene": (str, "a text (the scene file)"),
                "resolved_scene": (str, "a text (the scene as the run read it)"),
                "scene_fingerprint": (str, "a text"), "title": (str, "a text"),
                "rows": (int, "a whole number"), "cpu_time_s": ((int, float), "a number of seconds"),
                "results_bytes": (int, "a whole number of bytes"), "last_row": (str, "a text (a row)")}


def _check_stats(stats: dict, columns: list[str], where: str, why: str = "the file was changed") -> None:
    """The statistics' fields that pymr reads are of their types (a ResultsError naming
    `where`, the field and `why` otherwise)."""
    for key, (kind, what) in STATS_FIELDS.items():
        value = stats.get(key)
        if key in stats and (not isinstance(value, kind) or isinstance(value, bool)):
            from ._args import _shown
            raise ResultsError(f'{where}: "{key}" is {_shown(value)}, not {what} ({why})')
    if "columns" in stats:
        column_table(stats["columns"], columns, where, why)


def _check_file(path: Path) -> None:
    """A results file is there and is a regular file (a ResultsError saying what it is
    otherwise: missing, a folder, a FIFO or a device, unreadable)."""
    import stat
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise ResultsError(f"{path}: no such result file") from None
    except OSError as exc:
        raise ResultsError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    if stat.S_ISDIR(mode):
        raise ResultsError(f"{path}: is a folder, not a result file")
    if not stat.S_ISREG(mode):
        raise ResultsError(f"{path}: not a regular file (a FIFO, a device or a socket), not a result file")


def _read_head(path: Path) -> tuple[dict[str, str], list[str], int]:
    """The comment lines as key: value, the header's columns and the lines up to it."""
    meta: dict[str, str] = {}
    skip = 0
    try:
        with open(path, encoding="utf-8") as fh:
            for line in fh:
                if skip == 0 and line.startswith("\ufeff"):
                    raise ResultsError(f"{path}: not a pymr result file (it starts with a byte order mark, U+FEFF, "
                                       "which pymr never writes: another program saved it)")
                skip += 1
                if line.startswith("#"):
                    key, colon, value = line[1:].strip().partition(":")
                    if colon:                    # '# key: value' (not the '# pymr 0.1.0 results' line)
                        meta[key.strip()] = value.strip()
                    continue
                return meta, line.strip().split(","), skip
    except UnicodeDecodeError:
        raise ResultsError(f"{path}: not a pymr result file (line {skip + 1} is not UTF-8 text)") from None
    except OSError as exc:
        raise ResultsError(f"{path}: cannot read it ({exc.strerror or exc})") from None
    return meta, [], skip


def _row_fault(path: Path, skip: int, header: list[str]) -> str:
    """Why the lines after the header (the first `skip` lines) are not rows of numbers, one
    per column: the first line that is not, in pymr's words (numpy's counted rows from the
    header and suggested its own arguments)."""
    from ._args import _short
    with open(path, "rb") as fh:
        for number, raw in enumerate(fh, start=1):
            if number <= skip:
                continue
            try:
                line = raw.decode("utf-8").split("#", 1)[0].strip()
            except UnicodeDecodeError:
                return f"line {number} is not UTF-8 text"
            if not line:
                continue
            values = line.split(",")
            if len(values) != len(header):
                return f"line {number} holds {len(values)} values, the header names {len(header)} columns"
            for name, value in zip(header, values):
                try:
                    if "_" in value:         # float() takes Python's digit groups (1_0); numpy does not
                        raise ValueError
                    float(value)
                except ValueError:
                    return f"line {number}, column {name}: {_short(value.strip())} is not a number"
    return "its rows are not numbers separated by commas"


def _read_stats(jpath: Path) -> dict:
    """OUT.json's statistics ({} when there is none)."""
    if not jpath.exists():
        return {}
    try:
        text = jpath.read_text()
    except (OSError, ValueError) as exc:
        raise ResultsError(f"{jpath}: not a pymr statistics file ({' '.join(str(exc).split())})") from None
    return parse_stats(text, str(jpath))


def parse_stats(text: str, where: str) -> dict:
    """The statistics in `text` (OUT.json's, or an HDF5 file's attribute) as a dict; a
    ResultsError naming `where` when they are not a JSON object."""
    try:
        stats = json.loads(text)
    except (ValueError, RecursionError) as exc:         # RecursionError: nesting no run writes
        raise ResultsError(f"{where}: not a pymr statistics file ({' '.join(str(exc).split())})") from None
    if not isinstance(stats, dict):
        raise ResultsError(f"{where}: not a pymr statistics file (not a JSON object)")
    return stats
