"""The contacts a catching-up step sees (Maury 2014, sec. 2.2-2.3).

A :class:`ContactNetwork` holds the Verlet candidate list at the current
centres and its constraint rows, and what carries over from step to step:
the multipliers of the rows (the projection's warm start, kept pair by pair
across rebuilds of the list and exits of discs) and the kept symbolic
analysis of the projection's Newton matrices (:class:`NewtonPattern`).
"""

from __future__ import annotations

import numpy as np

from .contacts import CandidateList, Constraints, WallSet
from .projection import NewtonPattern


class ContactNetwork:
    """Candidate list, constraint rows, multipliers and factorisation pattern of a crowd of discs.

    skin: the list's skin; None: at the first build 6 times the longest move, at least half the mean
    radius, and after that at least that much. surface: the Atlas of a building (micro/surface.py), or None.
    """

    def __init__(self, walls: WallSet, skin: float | None = None, surface=None):
        self.walls, self.skin, self.surface = walls, skin, surface
        self.pattern = NewtonPattern()
        self.reset()

    def reset(self) -> None:
        """Start afresh at the next step (discs added, walls changed, a restart)."""
        self.cl: CandidateList | None = None
        self._constraints: Constraints | None = None
        self.lam = np.zeros(0)
        self.pattern.forget()

    def cover(self, q, r, travel, desired) -> int:
        """Build the list (its skin from the desired moves' lengths), or rebuild it if moves of the per-disc
        lengths `travel` may leave it; returns the number of (re)builds."""
        if self.cl is None:
            self.base_skin = self.skin if self.skin is not None else max(0.5 * float(r.mean()),
                                                                         6.0 * float(desired.max()))
            self.rebuild(q, r, self.base_skin)
            return 1 + self.cover(q, r, travel, desired)
        if self.cl.travel_ok(q, travel):
            return 0
        self.rebuild(q, r, max(self.base_skin, 2.5 * float(travel.max())))
        return 1

    def rebuild(self, q, r, skin: float) -> None:
        """A new list at q; the multipliers of the pairs (and disc-wall rows) in both lists carry over."""
        old_keys = None if self.cl is None else self.cl.keys(len(q))
        self.cl = CandidateList(q, r, self.walls, skin, self.surface)
        lam = np.zeros(self.cl.m)
        if old_keys is not None and len(old_keys) and len(self.lam) == len(old_keys):
            new_keys = self.cl.keys(len(q))
            order = np.argsort(old_keys)
            pos = np.minimum(np.searchsorted(old_keys[order], new_keys), len(order) - 1)
            hit = old_keys[order][pos] == new_keys
            lam[hit] = self.lam[order][pos[hit]]
        self.lam, self._constraints = lam, None

    def constraints(self, q, r) -> Constraints:
        """The rows of the list at the centres q (computed once per configuration)."""
        if self._constraints is None:
            self._constraints = self.cl.constraints(q, r, self.walls)
        return self._constraints

    def moved(self) -> None:
        """The centres changed: the rows are computed again when asked for."""
        self._constraints = None

    def remove(self, keep) -> None:
        """Discs left (boolean mask of those that stay): their rows and pattern slots go."""
        self.lam = self.lam[self.cl.remove(keep)]
        self.pattern.keep(keep)
        self._constraints = None

    def overlaps(self, q, r) -> tuple[float, float]:
        """The largest overlap at the centres q, in metres and over the smaller radius of the pair."""
        if self.cl is None or not len(q):
            return 0.0, 0.0
        constraints = self.constraints(q, r)
        if not constraints.m:
            return 0.0, 0.0
        radius = np.concatenate([np.minimum(r[constraints.pi], r[constraints.pj]), r[constraints.wi]])
        return max(0.0, float(-constraints.D.min())), max(0.0, float((-constraints.D / radius).max()))

    @property
    def candidates(self) -> int:
        return 0 if self.cl is None else self.cl.m

    def state(self) -> dict:
        """Everything the next steps depend on, as arrays (a checkpoint): the list (its reference centres,
        skin and rows, in their order), the multipliers and the kept factorisation pattern. A network
        rebuilt instead would give other rows, another warm start and another elimination order, hence
        another round-off, and a jam amplifies round-off (docs/micro.md, "Resuming a run")."""
        out = {"lam": self.lam, **{f"pattern.{k}": v for k, v in self.pattern.state().items()}}
        if self.cl is not None:
            out.update({"base_skin": self.base_skin, **{f"cl.{k}": v for k, v in self.cl.arrays().items()}})
        return out

    def restore(self, state: dict) -> None:
        """Continue from :meth:`state` (the walls are this network's: those of the same time)."""
        self.reset()
        if "cl.q_ref" in state:
            self.cl = CandidateList.from_arrays(**{k[3:]: v for k, v in state.items() if k.startswith("cl.")})
            self.base_skin = float(state["base_skin"])
        self.lam = np.array(state["lam"], float)
        self.pattern.restore({k[8:]: v for k, v in state.items() if k.startswith("pattern.")})
