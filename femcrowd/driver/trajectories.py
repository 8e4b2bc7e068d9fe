"""Disc trajectories for PedPy (Juelich Supercomputing Centre, PedPy 2023): trajectories.txt in the Juelich
text format (``ID FR X Y Z`` in metres, ``# framerate:`` in the header) and walkable_area.wkt.

Frames are at the times k / rate, independent of the scheme's steps: a disc moves on a straight line
during a step (q^{n+1} = q^n + tau u^{n+1}), so its position at a frame time inside the step is
q^{n+1} - (t^{n+1} - t_k) u^{n+1}, exactly the scheme's path. A disc that leaves through an exit
during a step has no position after it: its trajectory ends at the last frame before that step.
"""

from pathlib import Path

import numpy as np
import shapely

from ..files import appending, write_text, writing
from ..mesh import Domain
from ..mesh.outline import walkable_area


class TrajectoryFile:
    """trajectories.txt written frame by frame as the run goes (flushed: an interrupted run keeps it)."""

    def __init__(self, directory, rate: float, domain: Domain, frame: int | None = None, surface=None):
        """frame: the next frame of a resumed run (the rows of the later frames, written after its
        checkpoint, are dropped); surface: the Atlas of a building (micro/surface.py), whose layout the discs'
        centres are in: the rows are their (x, y, z), else (x, y, 0)."""
        self.surface = surface
        directory = Path(directory)
        write_text(directory / "walkable_area.wkt", shapely.to_wkt(walkable_area(domain), rounding_precision=9) + "\n")
        self.rate = rate
        self.frame = frame or 0   # the next frame to write
        self.path = directory / "trajectories.txt"
        kept = [] if frame is None else [line for line in self.path.read_text().splitlines(keepends=True)
                                         if line.startswith("#") or int(line.split("\t")[1]) < frame]
        head = "" if frame is not None else (f"# framerate: {rate:g}\n# unit: m\n# written by femcrowd (disc model)\n"
                                             "# ID\tFR\tX\tY\tZ\n")
        write_text(self.path, head + "".join(kept))
        self._file = appending(self.path)

    def start(self, t: float, ids: np.ndarray, q: np.ndarray) -> None:
        """The frames up to t (the initial discs, at rest before t = 0)."""
        with writing(self.path):
            while self.frame / self.rate <= t + 1e-12:
                self._write(ids, q)
            self._file.flush()

    def step(self, t: float, dt: float, ids: np.ndarray, q: np.ndarray, u: np.ndarray) -> None:
        """The frames in (t - dt, t] of a step that ended at t with the discs (ids, q) moving at u."""
        with writing(self.path):
            while self.frame / self.rate <= t + 1e-12:
                back = q - (t - self.frame / self.rate) * u
                if self.surface is not None:   # a disc that crossed a fold in the step was in the piece before
                    back = self.surface.recharted(q, back)[0]
                self._write(ids, back)
            self._file.flush()

    def _write(self, ids, q) -> None:
        xyz = np.column_stack([q, np.zeros(len(ids))]) if self.surface is None else self.surface.xyz(q)
        rows = np.column_stack([ids, np.full(len(ids), self.frame), xyz])
        np.savetxt(self._file, rows, fmt=["%d", "%d", "%.6f", "%.6f", "%.1f" if self.surface is None else "%.6f"],
                   delimiter="\t")
        self.frame += 1

    def close(self) -> None:
        with writing(self.path):
            self._file.close()
