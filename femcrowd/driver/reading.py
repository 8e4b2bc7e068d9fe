"""Reading a run's output directory back: history.csv, the PVD frame series, summary.json.

The one reader of what the output module writes, used by ``femcrowd plot``, the stress
matrix and the micro/macro comparison.
"""

import csv
import json
import tomllib
import xml.etree.ElementTree as ET
from pathlib import Path

import meshio
import numpy as np

from ..errors import InputError
from ..files import complete
from .output import disc_frame


def read_history(path) -> dict:
    """history.csv as a dict of float arrays (one per column); a run in progress may be mid-row."""
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    if not rows:
        return {}
    complete = [r for r in rows[1:] if len(r) == len(rows[0])]
    values = np.array(complete, float).reshape(-1, len(rows[0]))
    return {name: values[:, k] for k, name in enumerate(rows[0])}


def read_pvd(path) -> list:
    """The (time, file name) list of a PVD collection."""
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError as err:
        raise InputError(path, None, None, f"cannot read the PVD collection: {err}") from None
    return [(float(e.get("timestep", 0.0)), e.get("file")) for e in root.iter("DataSet")]


def read_frame(path) -> meshio.Mesh:
    """One VTU frame. A frame with no points (a micro run after the last disc left) is the empty disc
    frame: meshio's VTU reader cannot decode its empty data arrays."""
    piece = ET.parse(path).getroot().find(".//Piece")
    if piece is not None and int(piece.get("NumberOfPoints", 1)) == 0:
        return disc_frame(np.zeros((0, 2)), np.zeros(0), np.zeros((0, 2)), np.zeros(0))
    return meshio.read(path)


class RunDirectory:
    """What a run directory holds: summary, history columns, frame series {stem: [(time, file)]}."""

    def __init__(self, directory):
        self.directory = d = Path(directory)
        if not d.is_dir():
            raise InputError(d, None, None, "not a directory (give the output directory of a run)")
        self.summary = _summary(d / "summary.json") if (d / "summary.json").is_file() else {}
        self.history = read_history(d / "history.csv") if (d / "history.csv").is_file() else {}
        self.frames = {stem: read_pvd(d / f"{stem}.pvd") for stem in ("solution", "discs")
                       if (d / f"{stem}.pvd").is_file()}
        self.frames = {stem: series for stem, series in self.frames.items() if series}
        if not self.frames:
            raise InputError(d, None, None, "no frames (solution.pvd or discs.pvd): not the output "
                             "directory of a run (femcrowd run CASE writes one)")
        case = self.summary.get("case") or _case_copy(d / "case.toml")  # no summary yet: run in progress
        self.case = case
        self.title = case.get("title") or d.name
        self.rho_max = case.get("model", {}).get("rho_max", 1.0)

    def frame(self, stem: str, k: int) -> meshio.Mesh:
        """Frame k of a series (k = -1: the last)."""
        return read_frame(self.frame_file(stem, k))

    def frame_file(self, stem: str, k: int) -> Path:
        """The file of frame k of a series, there and whole (it ends as a VTU file ends), else InputError naming
        it: the reader is never handed a missing or truncated frame."""
        t, name = self.frames[stem][k]
        path = self.directory / name
        where = f"frame {k % len(self.frames[stem])} of {stem}.pvd (t = {t:g} s)"
        if not path.is_file():
            raise InputError(path, None, None, f"{where} is missing")
        try:
            whole = complete(path)
        except OSError as err:
            raise InputError(path, None, None, f"{where} cannot be read: {err.strerror}") from None
        if not whole:
            raise InputError(path, None, None, f"{where} is incomplete (cut short: a full disk, an interrupted copy?)")
        return path

    def inside(self):
        """(time, people inside) from history.csv, or None."""
        h = self.history
        column = "mass" if "mass" in h else "count" if "count" in h else None
        return (h["time"], h[column]) if column and len(h["time"]) else None

    def time_remaining(self, fraction: float):
        """First history time at which at most ``fraction`` of the initial crowd is inside, or None."""
        inside = self.inside()
        if inside is None or inside[1][0] <= 0:
            return None
        below = np.flatnonzero(inside[1] <= fraction * inside[1][0])
        return float(inside[0][below[0]]) if len(below) else None


def _summary(path) -> dict:
    try:
        return json.loads(path.read_text())
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise InputError(path, None, None, f"cannot read: not JSON ({err}): cut short, or not written by femcrowd?") \
            from None


def _case_copy(path):
    """The run's copy of case.toml as written (no defaults filled), or {}."""
    try:
        return tomllib.loads(path.read_text())
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError):
        return {}
