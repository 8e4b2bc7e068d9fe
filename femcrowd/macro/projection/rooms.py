"""Closed rooms: the components of the domain with no open exit, where a saturated crowd makes A_SS singular.

A component of S is a closed, fully saturated room (pure Neumann problem) exactly when it
is a whole connected component of A's graph with no exit cell, so the components are found
once per set of open exits. There the solution exists (rho stays 1) and phi is fixed up to a
constant: one cell per room is pinned (phi = 0) for the solve, then the room is shifted so
that min phi = 0 (the gauge of docs/model.md).

The columns of A sum to 0 over a closed room, so there sum w = sum b: the pinned cell, whose
equation is not solved, is left with w = sum b. A room with space to spare (sum b > IMBALANCE |K|: a room
behind an exit at capacity, whose door node pushes back like a wall, after a short step) is not
all saturated; the cells where the shifted phi is 0 then leave S (:meth:`ClosedRooms.spare`):
with phi = 0 there the rest keeps phi >= 0 and w = 0, and they take w = sum b > 0.
"""

import numpy as np
from scipy.sparse.csgraph import connected_components

#: w / |K| of a pinned cell up to which a full room's imbalance sum b is taken for round-off (the sum over the
#: room's cells: up to 4e-12 in the stress matrix's closed-saturated scene), and the room kept whole in S
IMBALANCE = 1e-9


class ClosedRooms:
    """Components of A's graph, which of them have no exit, and their gauge cells."""

    def __init__(self, A, has_exit: np.ndarray):
        ncomp, self.component = connected_components(A, directed=False)
        self.closed = np.bincount(self.component, has_exit, ncomp) == 0
        self.size = np.bincount(self.component, minlength=ncomp)
        self.first_cell = np.unique(self.component, return_index=True)[1]  # the gauge cell of a closed room
        self.gauge = np.zeros(len(has_exit), bool)
        self.gauge[self.first_cell[self.closed]] = True

    def full(self, S: np.ndarray) -> np.ndarray:
        """The closed rooms entirely inside the sorted set S."""
        if not self.closed.any():
            return np.zeros(0, np.intp)
        inside = np.bincount(self.component[S], minlength=len(self.closed))
        return np.flatnonzero(self.closed & (inside == self.size))

    def unpinned(self, S: np.ndarray, full: np.ndarray) -> np.ndarray:
        """Mask of the cells of S that are not the pinned cell of a full room."""
        keep = np.ones(len(S), bool)
        keep[np.searchsorted(S, self.first_cell[full])] = False
        return keep

    def spare(self, S: np.ndarray, full: np.ndarray, x: np.ndarray, w: np.ndarray, area: np.ndarray) -> np.ndarray:
        """Positions in S of the cells that leave it: those with x = 0 (the gauge-shifted solution) in each full
        room whose pinned cell is left with w > IMBALANCE |K| (w, area on S)."""
        pinned = np.searchsorted(S, self.first_cell[full])
        loose = full[w[pinned] > IMBALANCE * area[pinned]]
        if not loose.size:
            return np.zeros(0, np.intp)
        return np.flatnonzero(np.isin(self.component[S], loose) & (x == 0.0))

    def gauge_shift(self, x: np.ndarray, S: np.ndarray, full: np.ndarray) -> np.ndarray:
        """x on S shifted in each full room so that its minimum is 0."""
        if not full.size:
            return x
        label = self.component[S]
        lowest = np.full(len(self.closed), np.inf)
        np.minimum.at(lowest, label, x)
        return x - np.where(np.isin(label, full), lowest[label], 0.0)
