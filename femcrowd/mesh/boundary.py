"""Boundary conditions as time-dependent data: which exits are open at t.

An exit lets people out (upwind outflow, p = 0: Dirichlet for the pressure);
a closed exit is a wall (no flux, Neumann). Everything that depends on the
exits - the Laplacian, its closed rooms, the distance field, the outflow
matrices - depends only on the set of open exits, so :class:`Boundary` hands
out one :class:`Exits` object per set and the solvers cache what they build
on it.
"""

from bisect import bisect_right

import numpy as np
import scipy.sparse as sp

from .domain import Domain


class Exits:
    """The exits open at some time: facet masks, the Laplacian with these Dirichlet facets, outflows.

    ``names`` are all the exits of the case (the evacuated_<name> columns, open or not);
    ``group[e]`` is the index in ``names`` of the open exit that facet e belongs to (a facet
    counts once, in its first group), -1 for interior facets, walls and closed exits.
    """

    def __init__(self, domain: Domain, open_names):
        self.domain = domain
        self.names = list(domain.exit_group)
        self.open = tuple(name for name in self.names if name in set(open_names))
        self.group = np.full(len(domain.length), -1)
        for g, name in reversed(list(enumerate(self.names))):
            if name in self.open:
                self.group[domain.exit_group[name]] = g
        self.exit = self.group >= 0
        self.wall = ~domain.interior & ~self.exit
        self.transmissibility = np.where(self.wall, 0.0, domain.transmissibility)
        self._laplacian = None

    def any(self) -> bool:
        """Is any exit open?"""
        return bool(self.exit.any())

    def laplacian(self) -> sp.csr_matrix:
        """The two-point (negative) Laplacian A (M-matrix, CSR): (A phi)_K = sum_e T_e (phi_K - phi_L),
        with phi_L = 0 across open exits and no flux across walls (built once per set of open exits)."""
        if self._laplacian is None:
            d = self.domain
            f = ~self.wall
            k0, k1, T = d.f2t[0][f], d.f2t[1][f], self.transmissibility[f]
            inner = k1 >= 0
            rows = np.concatenate([k0, k1[inner], k0[inner], k1[inner]])
            cols = np.concatenate([k0, k1[inner], k1[inner], k0[inner]])
            vals = np.concatenate([T, T[inner], -T[inner], -T[inner]])
            self._laplacian = sp.csr_matrix((vals, (rows, cols)), shape=(d.ncells, d.ncells))
        return self._laplacian

    def outflow_matrix(self, weights: np.ndarray) -> sp.csr_matrix:
        """Sparse (exits x cells) matrix: row g sums weights_e * value_K(e) over the facets e of exit g."""
        e = np.flatnonzero(self.exit)
        return sp.csr_matrix((weights[e], (self.group[e], self.domain.f2t[0][e])),
                             shape=(len(self.names), self.domain.ncells))

    def edges(self) -> np.ndarray:
        """Node pairs (E, 2) of the open exit facets (the sources of the distance field)."""
        return self.domain.mesh.facets[:, self.exit].T

    def segments(self, which: str) -> np.ndarray:
        """Segments (n, 2, 2) of the 'wall' or 'exit' facets (for the disc model and pictures)."""
        mask = self.wall if which == "wall" else self.exit
        return self.domain.points[self.domain.mesh.facets[:, mask].T]


class Boundary:
    """The exits of a domain over time: ``at(t)`` is the :class:`Exits` open at t, one object per set.

    schedule: ``[boundary.open]``, exit name -> [[from, to], ...]: the exit is open for from <= t < to
    (a closed exit is a wall); exits without a schedule are always open. The open set is constant
    between the schedule's change times, so it is tabulated once per interval; without a schedule
    ``at`` returns the one object of all exits, with no work per call.
    """

    def __init__(self, domain: Domain, schedule=None):
        self.domain = domain
        self._cache = {}
        schedule = schedule or {}
        self.changes = sorted({t for spans in schedule.values() for span in spans for t in span if np.isfinite(t)})
        # the open set on each interval [changes[k-1], changes[k]), sampled at a time inside it
        starts = [0.0, *self.changes]
        self._states = [self.exits([name for name in domain.exit_names
                                    if name not in schedule or any(a <= t < b for a, b in schedule[name])])
                        for t in starts]

    def exits(self, open_names) -> Exits:
        """The Exits object of a set of open exits (built once per set)."""
        key = frozenset(open_names)
        if key not in self._cache:
            self._cache[key] = Exits(self.domain, key)
        return self._cache[key]

    def at(self, t: float) -> Exits:
        """The exits open at time t."""
        if not self.changes:   # no schedule, or exits that never open: one set for the whole run
            return self._states[0]
        return self._states[bisect_right(self.changes, t)]

    def next_change(self, t: float) -> float:
        """The first time after t at which the set of open exits may change (inf: never); steps land on it."""
        if not self.changes:
            return np.inf
        k = bisect_right(self.changes, t)
        return self.changes[k] if k < len(self.changes) else np.inf
