"""Writing a run: the output directory, VTU frames + PVD collection, history.csv, summary.json, checkpoints.

Every file is written so that an interrupted run leaves what it wrote readable:
frames, the PVD index, summary.json and the checkpoint are written under names of
their own and moved in place, history.csv is flushed with every frame (ownership.py: the
lock that makes a directory one run's, writes that never follow a link out of
it, write errors as one line). A directory holding files that
femcrowd did not write is never written into unless the user forces it. A new
run in a directory of an earlier run replaces that run's files (and says so);
pictures made by ``femcrowd plot`` live apart, in ``plots/``, and are left alone.
"""

import csv
import json
import logging
import os
from pathlib import Path

import meshio
import numpy as np

from ..errors import InputError
from ..files import TEMPORARY, appending, replaced, write_text, writing
from . import vtu
from .ownership import LOCK, RunLock

log = logging.getLogger("femcrowd")

MARKER = ".femcrowd-run"
#: the files of a run: cleared when a new run replaces an old one
RUN_FILES = ("solution_*.vtu", "discs_*.vtu", "solution.pvd", "discs.pvd", "history.csv", "summary.json",
             "case.toml", "checkpoint.npz", "measurements.csv", "trajectories.txt", "walkable_area.wkt", TEMPORARY)


def prepare_output_dir(path, case_file, force=False) -> Path:
    """The directory of a study, made ready as a run's is (own_output_dir); its runs write in directories of
    their own, each locked by its run."""
    lock = own_output_dir(path, case_file, force)
    lock.release()
    return lock.directory


def own_output_dir(path, case_file, force=False, resume=False) -> RunLock:
    """The output directory of a run, locked for it (ownership.RunLock) before anything in it changes: created,
    or cleared of an earlier femcrowd run; resume: the directory of the run to continue, kept as it is but for
    the temporary files of a killed run and links planted at the names of its files. Refused with one line: a
    file, a foreign directory (unless force), the case's own directory, a directory that another run is writing.

    The marker that allows a later run to clear the directory is only left where
    femcrowd owns the directory (new, empty, or marked): after --force into a
    foreign directory the next run needs --force again, so femcrowd never
    deletes a file it did not write.
    """
    path = Path(path)
    case_file = Path(case_file)
    if path.is_dir() and case_file.is_file() and os.path.samefile(path, case_file.parent):
        raise InputError(case_file, "output.dir", str(path), "is the case's own directory: a run would replace "
                         "its case.toml (choose another --out)")
    if resume:
        lock = RunLock(path).acquire()
        with writing(path):
            _rewind(path)
        return lock
    if path.exists() and not path.is_dir():
        raise InputError(case_file, "output.dir", str(path), "exists and is not a directory")
    if path.is_dir() and _entries(path) and not (path / MARKER).exists() and not force:
        raise InputError(case_file, "output.dir", str(path),
                         "directory is not empty and was not written by femcrowd "
                         "(choose another --out, or pass --force to write into it)")
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError as err:
        raise InputError(case_file, "output.dir", str(path), f"cannot create: {err.strerror}") from None
    lock = RunLock(path).acquire()
    try:
        with writing(path):
            _clear(path)
    except BaseException:
        lock.release()
        raise
    return lock


def _rewind(path) -> None:
    """The directory of a run to resume: the temporary files of a killed run removed, and the links planted at
    the names of the run's files (the run replaces these files; a link is removed, its target untouched)."""
    for f in {f for pattern in RUN_FILES for f in path.glob(pattern)}:
        if f.is_symlink() or f.match(TEMPORARY):
            f.unlink()


def _entries(path) -> list:
    return [p for p in path.iterdir() if p.name != LOCK]


def _clear(path) -> None:
    """Remove an earlier femcrowd run (marked directory), or mark a new one."""
    if (path / MARKER).exists():
        old = [f for pattern in RUN_FILES for f in path.glob(pattern)]
        for f in old:
            f.unlink()
        if old:
            plots = " (its pictures in plots/ are kept: `femcrowd plot` remakes them)" \
                if (path / "plots").is_dir() else ""
            log.warning("replacing the earlier run in %s: %d files%s", path, len(old), plots)
    elif not _entries(path):
        write_text(path / MARKER, "written by femcrowd; safe to overwrite with a new run\n")


def write_json(path, data) -> None:
    """Write JSON whole or not at all (files.replaced)."""
    write_text(path, json.dumps(data, indent=2, default=_json_default) + "\n", sync=True)


def _json_default(value):
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(type(value))


class FrameSeries:
    """A time series of VTU files indexed by a PVD collection (ParaView reads the times).

    frames: the (time, file) of the frames already written by the run this one resumes; its later
    frames (written after its checkpoint) are removed.
    """

    def __init__(self, directory, stem, frames=None):
        self.directory, self.stem = Path(directory), stem
        self.frames = [(float(t), str(name)) for t, name in frames or ()]
        self._mesh = {}   # the encoded mesh of the last frame (vtu.write)
        if frames is not None:
            keep = {name for _, name in self.frames}
            for old in self.directory.glob(f"{stem}_*.vtu"):
                if old.name not in keep:
                    with writing(old):
                        old.unlink()
            self._index()

    def write(self, t, mesh):
        name = f"{self.stem}_{len(self.frames):05d}.vtu"
        with replaced(self.directory / name) as tmp:
            vtu.write(tmp, mesh, self._mesh)
        self.frames.append((float(t), name))
        self._index()

    def _index(self):
        """Write the PVD collection (meshio has none: a few lines of XML), atomically."""
        rows = "\n".join(f'    <DataSet timestep="{t!r}" group="" part="0" file="{f}"/>'
                         for t, f in self.frames)
        text = ('<?xml version="1.0"?>\n<VTKFile type="Collection" version="0.1" '
                f'byte_order="LittleEndian">\n  <Collection>\n{rows}\n  </Collection>\n</VTKFile>\n')
        write_text(self.directory / f"{self.stem}.pvd", text)


def triangle_frame(domain, cell_data) -> meshio.Mesh:
    """A meshio mesh of the domain's triangles with cell data (vectors padded to 3 components); a building's
    (docs/floors.md) at the elevations of its nodes, its plan vectors lifted to its surface (z component s . v,
    s = grad z of the cell)."""
    if domain.z is None:
        points = np.column_stack([domain.points, np.zeros(len(domain.points))])
        data = {name: [np.column_stack([v, np.zeros(len(v))]) if v.ndim == 2 and v.shape[1] == 2 else v]
                for name, v in cell_data.items()}
    else:
        points = np.column_stack([domain.points, domain.z])
        data = {name: [np.column_stack([v, (domain.slope * v).sum(axis=1)]) if v.ndim == 2 and v.shape[1] == 2
                       else v] for name, v in cell_data.items()}
    return meshio.Mesh(points, [("triangle", domain.triangles)], cell_data=data)


def disc_frame(q, r, u, pressure, extra=None) -> meshio.Mesh:
    """A meshio point cloud of discs with radius, velocity (3 components) and pressure point data (and the
    arrays of `extra`, e.g. population); q, u: (n, 2) in the plane z = 0, or (n, 3) (a building's discs)."""
    points = q if q.shape[1] == 3 else np.column_stack([q, np.zeros(len(q))])
    velocity = u if u.shape[1] == 3 else np.column_stack([u, np.zeros(len(q))])
    return meshio.Mesh(points, [("vertex", np.arange(len(q)).reshape(-1, 1))],
                       point_data={"radius": r, "velocity": velocity,
                                   "pressure": pressure, **(extra or {})})


class HistoryFile:
    """history.csv, one row per step; rows: those of the steps already done (a resumed run), written with the
    header into a new file (files.replaced). The rows of the steps are kept until flush(), which the run
    calls with every frame and checkpoint (an interrupted run's rows are all there) and at the end: one write
    per frame, not one per step."""

    def __init__(self, path, columns, rows=()):
        self.path, self.columns = Path(path), columns
        with replaced(path) as tmp, open(tmp, "w", newline="") as f:
            writer = csv.writer(f)
            writer.writerow(columns)
            writer.writerows([_fmt(row[c]) for c in columns] for row in rows)
        self._file = appending(path, newline="")
        self._writer = csv.writer(self._file)
        self._rows = []   # the values of the rows not yet written

    def append(self, row) -> None:
        self._rows.append([row[c] for c in self.columns])

    def flush(self) -> None:
        """Write the rows kept so far (once closed, nothing: a write failed)."""
        if self._file.closed:
            return
        with writing(self.path):
            self._writer.writerows([_fmt(v) for v in values] for values in self._rows)
            self._file.flush()
        self._rows.clear()

    def close(self) -> None:
        try:
            self.flush()
        finally:
            with writing(self.path):
                self._file.close()


def _fmt(value):
    return repr(float(value)) if isinstance(value, (float, np.floating)) else value
