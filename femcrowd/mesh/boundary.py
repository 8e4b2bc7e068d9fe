"""Doors: the boundary conditions of a floor plan as objects, one place for each (docs/model.md, "Doors").

A :class:`Door` is a named line group of the mesh through which people pass: an *exit* (boundary
facets: people leave the domain, the pressure is 0 outside) or an *interior door* (facets between
two rooms). It owns its facets, its schedule (when it is open; a closed exit is a wall) and its
capacity (the most it lets through, per metre and per second; the :class:`~.capacity.Capacities` of
the open doors that have one). Every solver consults the doors open at a time through one
:class:`Doors` object: the transports (walls, outflow per exit, capped facets), the projection (the
Laplacian, the door nodes of the capacities), the pressure flux of measurements and of the output
velocity, the disc model (wall and exit segments). Everything built from the doors depends only on
the set of open ones, so :class:`Boundary` hands out one :class:`Doors` per set and the solvers cache
what they build on it.
"""

from bisect import bisect_right
from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from .capacity import Capacities
from .domain import Domain


@dataclass(frozen=True, eq=False)
class Door:
    """A named line group people pass through: its facets, whether it is an exit (boundary facets) or an
    interior door, its capacity (persons per metre per second in units of rho_max x m/s; inf: no cap) and
    its schedule (spans [from, to) when it is open; None: always open)."""

    name: str
    facets: np.ndarray
    exit: bool
    width: float
    capacity: float = np.inf
    spans: tuple = None

    def is_open(self, t: float) -> bool:
        return self.spans is None or any(a <= t < b for a, b in self.spans)

    def open_during(self, start: float, stop: float = np.inf) -> bool:
        """Is the door open at some time in [start, stop)?"""
        return self.spans is None or any(a < stop and start < b for a, b in self.spans)

    @property
    def capped(self) -> bool:
        return bool(np.isfinite(self.capacity))


class Doors:
    """The doors open at some time: facet masks, the Laplacian with the open exits Dirichlet, the capacities.

    ``names`` are all the exits of the case (the evacuated_<name> columns, open or not);
    ``group[e]`` is the index in ``names`` of the open exit that facet e belongs to (a facet
    counts once, in its first group), -1 for interior facets, walls and closed exits.
    ``caps`` are the capacities of the open doors that have one (None when no open door has one:
    the free exits of the paper).
    """

    def __init__(self, domain: Domain, doors, open_names):
        self.domain = domain
        exits = [door for door in doors if door.exit]
        self.names = [door.name for door in exits]
        self.doors = {door.name: door for door in exits}
        self.open = tuple(name for name in self.names if name in set(open_names))
        self.group = np.full(len(domain.length), -1)
        for g, door in reversed(list(enumerate(exits))):
            if door.name in self.open:
                self.group[door.facets] = g
        self.exit = self.group >= 0
        self.exit_facets = np.flatnonzero(self.exit)
        self.wall = ~domain.interior & ~self.exit
        self.transmissibility = np.where(self.wall, 0.0, domain.transmissibility)
        capped = [door for door in doors if door.capped and (not door.exit or door.name in self.open)]
        self.caps = Capacities(domain, capped, self.group) if capped else None
        self._laplacian = self._pressure_outflow = None

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
        e = self.exit_facets
        return sp.csr_matrix((weights[e], (self.group[e], self.domain.f2t[0][e])),
                             shape=(len(self.names), self.domain.ncells))

    def pressure_flux(self, phi: np.ndarray, jump: np.ndarray = None, facets=slice(None)) -> np.ndarray:
        """The mass T_e (phi_K - phi_L - j_e) each facet (of `facets`, default all) carries f2t[0] -> f2t[1] for
        a pressure phi on the cells (phi_L = 0 across an open exit, nothing through walls) and the pressure
        jumps j of the capped door facets (one value per facet, None: no jump)."""
        k0, k1 = self.domain.f2t[0][facets], self.domain.f2t[1][facets]
        far = np.where(k1 >= 0, phi[np.maximum(k1, 0)], 0.0)
        drop = phi[k0] - far
        if jump is not None:
            drop = drop - jump[facets]
        return self.transmissibility[facets] * drop

    def pressure_outflow(self, phi: np.ndarray, jump: np.ndarray = None) -> np.ndarray:
        """The mass the pressure phi (with the jumps of the capped door facets) pushes out through each exit."""
        if self._pressure_outflow is None:
            self._pressure_outflow = self.outflow_matrix(self.transmissibility)
        out = self._pressure_outflow @ phi
        if jump is not None:
            e = self.exit_facets
            out -= np.bincount(self.group[e], self.transmissibility[e] * jump[e], len(self.names))
        return out

    def edges(self) -> np.ndarray:
        """Node pairs (E, 2) of the open exit facets (the sources of the distance field)."""
        return self.domain.mesh.facets[:, self.exit].T

    def segments(self, which: str) -> np.ndarray:
        """Segments (n, 2, 2) of the 'wall' or 'exit' facets (for the disc model and pictures)."""
        mask = self.wall if which == "wall" else self.exit
        return self.domain.points[self.domain.mesh.facets[:, mask].T]


class Boundary:
    """The doors of a domain over time: ``at(t)`` is the :class:`Doors` open at t, one object per set.

    schedule: ``[boundary.open]``, exit name -> [[from, to], ...]: the exit is open for from <= t < to
    (a closed exit is a wall); exits without a schedule are always open. capacity: ``[boundary.capacity]``,
    door name (an exit, or an interior line group) -> persons per metre per second, in units of rho_max
    x m/s. The open set is constant between the schedule's change times, so it is tabulated once per
    interval; without a schedule ``at`` returns the one object of all exits, with no work per call.
    """

    def __init__(self, domain: Domain, schedule=None, capacity=None):
        self.domain = domain
        self._cache = {}
        schedule, capacity = schedule or {}, capacity or {}
        spans = {name: tuple(map(tuple, value)) for name, value in schedule.items()}
        names = list(domain.exit_names) + [name for name in capacity if name not in domain.exit_group]
        self.doors = [Door(name, domain.groups[name], name in domain.exit_group,
                           float(domain.length[domain.groups[name]].sum()), capacity.get(name, np.inf),
                           spans.get(name)) for name in names]
        self.changes = sorted({t for door in self.doors for span in door.spans or () for t in span
                               if np.isfinite(t)})
        # the open set on each interval [changes[k-1], changes[k]), sampled at a time inside it
        self._states = [self.opening([door.name for door in self.doors if door.exit and door.is_open(t)])
                        for t in [0.0, *self.changes]]

    @property
    def capped(self) -> list:
        """The doors with a capacity."""
        return [door for door in self.doors if door.capped]

    def opening(self, open_names) -> Doors:
        """The Doors object of a set of open exits (built once per set)."""
        key = frozenset(open_names)
        if key not in self._cache:
            self._cache[key] = Doors(self.domain, self.doors, key)
        return self._cache[key]

    def segments(self, name: str) -> np.ndarray:
        """Segments (n, 2, 2) of the facets of the door `name` (the disc model's doorways)."""
        door = next(door for door in self.doors if door.name == name)
        return self.domain.points[self.domain.mesh.facets[:, door.facets].T]

    def at(self, t: float) -> Doors:
        """The doors open at time t."""
        if not self.changes:   # no schedule, or exits that never open: one set for the whole run
            return self._states[0]
        return self._states[bisect_right(self.changes, t)]

    def next_change(self, t: float) -> float:
        """The first time after t at which the set of open exits may change (inf: never); steps land on it."""
        if not self.changes:
            return np.inf
        k = bisect_right(self.changes, t)
        return self.changes[k] if k < len(self.changes) else np.inf
