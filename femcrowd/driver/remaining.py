"""Who is left at the end of a run and why, and who can never leave (docs/case-format.md, "Outputs"; both models).

The people inside are sorted by the region of the floor plan they stand in (``Domain.region``: the connected
parts of the mesh, mesh/checks.py) and by the exits of that region over the doors' schedule (``Door.spans``):

- ``no reachable exit``: no exit of their region is ever open;
- ``closed door``: their region has exits, all closed at the end;
- ``time.end``: an exit of their region is open: still on their way when the run reached time.end
  (``interrupted`` when it stopped before);
- ``evacuated``: nobody is left, or at most the threshold of the model (a density: time.empty_fraction of the
  crowd; discs: none).

A region's people can never leave when none of its exits is open at any later time: a warning at the set-up
(:meth:`Regions.warn_trapped`, for the regions with no exit open during the run) and at the end
(:meth:`Regions.remaining`). A case without any exit (a closed room on purpose) gets no warning.
"""

import logging

import numpy as np

from ..case.units import people_unit

log = logging.getLogger("femcrowd")

#: the reasons, by the code remaining() gives each region
REASONS = ("no reachable exit", "closed door", "time.end")
NONE, CLOSED, MOVING = range(3)


class Regions:
    """The regions of a scene's floor plan, the exits of each and the sources that feed each; ``names``: the
    populations."""

    def __init__(self, scene, names):
        domain, case = scene.domain, scene.case
        self.region, self.centroid = domain.region, domain.centroid
        self.exits = [door for door in scene.boundary.doors if door.exit]
        self.has = np.zeros((int(self.region.max()) + 1, len(self.exits)), bool)   # region r has facets of exit k
        for k, door in enumerate(self.exits):
            self.has[self.region[domain.f2t[0][door.facets]], k] = True
        self.fed = {source.key: self.region[domain.f2t[0][source.facets]] for source in scene.sources}
        self.names, self.end, self.file, self.mesh = list(names), case["time"]["end"], case.file, domain.source
        self.unit = people_unit(case.config)

    def _open(self, start: float, stop: float = np.inf) -> np.ndarray:
        """Per region: is one of its exits open at some time in [start, stop)?"""
        return self.has[:, [door.open_during(start, stop) for door in self.exits]].any(axis=1)

    def warn_trapped(self, people: np.ndarray) -> None:
        """Warn of the people (per cell, at t = 0) and the sources in regions with no exit open during the run."""
        if not self.exits:
            return
        trapped = ~self._open(0.0, self.end)
        inside = np.bincount(self.region, people, len(trapped))
        sources = [key for key, regions in self.fed.items() if trapped[regions].any()]
        caught = trapped & (inside > 0)
        if caught.any() or sources:
            x, y = self.centroid[np.flatnonzero((caught if caught.any() else trapped)[self.region])[0]]
            fed = f" and the arrivals of {', '.join(sources)}" if sources else ""
            log.warning("%s: %d of the %d regions of the mesh %s have no exit open during the run (one at (%.4g, "
                        "%.4g)): %s%s can never leave", self.file, np.count_nonzero(trapped), len(trapped),
                        self.mesh.name if self.mesh else "", x, y, crowd_text(inside[trapped].sum(), self.unit), fed)

    def remaining(self, t: float, people: np.ndarray, out: bool, threshold: float = 0.0) -> dict:
        """The summary entry "remaining" at time t: people (populations, cells + 1; the last column: people
        outside every cell, counted as on their way), how many in all, why ("evacuated" when `out`, the model's
        own verdict, the one that stops the run; else the reasons with more than `threshold`, the largest
        first), how many per reason and per population. Warns of those who can never leave."""
        ever, later = self._open(0.0), self._open(t)
        now = self.has[:, [door.is_open(t) for door in self.exits]].any(axis=1)
        code = np.where(~ever, NONE, np.where(now, MOVING, CLOSED))
        cell_code = np.append(code[self.region], MOVING)
        by_reason = np.bincount(np.broadcast_to(cell_code, people.shape).ravel(), people.ravel(), len(REASONS))
        order = np.argsort(-by_reason, kind="stable")
        listed = [r for r in order if by_reason[r] > threshold] or list(order[:1])
        names = [REASONS[r] if r != MOVING or t >= self.end else "interrupted" for r in listed]
        number = int if np.issubdtype(people.dtype, np.integer) else float
        total = number(people.sum())
        if out:
            listed, names = [], ["evacuated"]
        elif self.exits:
            self._warn_never(t, people, ~later, by_reason[NONE] if NONE in listed else 0.0, threshold)
        return {"people": total, "reason": ", ".join(names),
                "by_reason": {name: number(by_reason[r]) for r, name in zip(listed, names)},
                "per_population": {name: number(v) for name, v in zip(self.names, people.sum(axis=1))}}

    def _warn_never(self, t, people, stuck, no_exit, threshold) -> None:
        """Warn of the people in the regions `stuck` (no exit open after t): `no_exit` of them in regions with no
        exit ever open, the others behind exits closed for good."""
        inside = np.bincount(self.region, people[:, :-1].sum(axis=0), len(stuck))
        never = float(inside[stuck].sum())
        if never <= threshold:
            return
        closed = [door.name for k, door in enumerate(self.exits) if self.has[stuck & (inside > 0), k].any()]
        parts = [f"{crowd_text(no_exit, self.unit)} in regions with no exit"] if no_exit else []
        if closed:
            parts.append(f"{crowd_text(never - no_exit, self.unit)} behind exits closed for good ({', '.join(closed)})")
        log.warning("%s: %s can never leave (t = %.4g s): %s", self.file, crowd_text(never, self.unit), t,
                    "; ".join(parts))


def crowd_text(n: float, unit: str = "people") -> str:
    """'1 person', '0 people', '19.2 people' (4 digits), or n in another unit of the crowd ('0.5 m^2 at rho_max',
    case/units.py)."""
    text = f"{n:.4g}"
    if unit != "people":
        return f"{text} {unit}"
    return "1 person" if text == "1" else f"{text} people"


def remaining_text(remaining: dict, unit: str = "people") -> str:
    """The summary's "remaining" in a few words: '19.2 people (closed door 12.1, time.end 7.1)'."""
    by = remaining["by_reason"]
    why = ", ".join(f"{reason} {value:.4g}" for reason, value in by.items()) if len(by) > 1 else remaining["reason"]
    return f"{crowd_text(remaining['people'], unit)} ({why})"
