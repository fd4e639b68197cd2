"""Result files: OUT.csv (comment lines, header, rows) and OUT.json (run statistics)."""
from __future__ import annotations

import json
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

_Q = re.compile(r"\.(q\d*|a\d+)$")
_QD = re.compile(r"\.(qd\d*|ad\d+)$")


@dataclass
class Results:
    """A run's results: columns by name as numpy arrays, statistics and comment lines."""

    columns: list[str]
    data: np.ndarray
    stats: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)
    path: str | None = None
    summary: str = ""

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self.data[:, self.columns.index(name)]
        except ValueError:
            raise KeyError(f"no column {name!r}; columns: {', '.join(self.columns)}") from None

    def __contains__(self, name: str) -> bool:
        return name in self.columns

    @property
    def t(self) -> np.ndarray:
        return self["t"]

    def marker(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Position (rows, 3) and velocity (rows, 3) of a marker, inertial frame."""
        pos = np.column_stack([self[f"{name}.{c}"] for c in ("x", "y", "z")])
        vel = np.column_stack([self[f"{name}.{c}"] for c in ("vx", "vy", "vz")])
        return pos, vel

    def coordinates(self) -> tuple[np.ndarray, np.ndarray]:
        """All generalised coordinates and rates (rows, n) in model order: joint
        coordinates (``j.q``, ``j.q1`` ...) first, then modal ones (``body.a1`` ...)."""
        qcols = [c for c in self.columns if _Q.search(c)]
        qdcols = [c for c in self.columns if _QD.search(c)]
        return (np.column_stack([self[c] for c in qcols]) if qcols else np.zeros((len(self.t), 0)),
                np.column_stack([self[c] for c in qdcols]) if qdcols else np.zeros((len(self.t), 0)))


def load_results(csv_path: str | os.PathLike) -> Results:
    """Load OUT.csv and, when present, OUT.json beside it."""
    path = Path(csv_path)
    meta: dict[str, str] = {}
    header: list[str] | None = None
    skip = 0
    with open(path) as fh:
        for line in fh:
            skip += 1
            if line.startswith("#"):
                key, _, value = line[1:].strip().partition(":")
                meta[key.strip()] = value.strip()
                continue
            header = line.strip().split(",")
            break
    if header is None:
        raise ValueError(f"{path}: no header row")
    data = np.loadtxt(path, delimiter=",", comments="#", skiprows=skip, ndmin=2)
    stats = {}
    jpath = path.with_suffix(".json")
    if jpath.exists():
        stats = json.loads(jpath.read_text())
    return Results(columns=header, data=data, stats=stats, meta=meta, path=str(path))
