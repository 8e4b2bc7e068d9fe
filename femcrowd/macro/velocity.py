"""Desired velocity U (docs/model.md, "Desired velocity"): what each population would do alone.

Every kind offers the same interface, evaluated for a state (its time t, and its density
for a speed that depends on it) and the exits open at that time:

- ``normal_on_facets(state, exits)``: (2, F) U . n on each facet seen from f2t[0] and from
  f2t[1] (n oriented f2t[0] -> f2t[1]), what the transport needs;
- ``at_points(xy, t, exits)``: (m, 2) at points, for the discs of the micro model;
- ``potential(exits)``: a cell field that decreases downstream, or None (it orders the solves of
  the implicit transport).

- ``version(state, exits)``: what U depends on beyond the open exits (None: nothing; the time for a
  field that depends on t; the count of route solves for the route choice): the transport is rebuilt
  when it changes.

Two kinds, chosen by ``[velocity].type``:

- ``field``: U = (ux, uy), expressions in x, y, t. The transport uses U . n at facet
  midpoints; no distance field is computed.
- ``exits``: U = -v grad d / |grad d|, with d the shortest-path distance inside the domain
  to the nearest open exit of those the population heads for (nodal,
  :func:`femcrowd.mesh.distance.exit_distance`, computed once per set of open exits) and grad d
  the P1 gradient per triangle; each facet has the normal velocity of each of its two cells
  (flux splitting, see transport/upwind.py). Where
  d is infinite (no path to any exit) or grad d vanishes, U = 0: people who cannot reach an
  exit stay where they are (but are still pushed by the pressure if their region is saturated).

With ``[velocity] walls = "slip"`` the cellwise U of ``exits`` (and of the route choice) has no component into a
wall and a path of upwind flows to an exit from every cell (macro/walls.py; docs/model.md, "Walls").

With ``[velocity] clearance = r`` the distance is the walk of people who keep a body's clearance r from the
walls: the eikonal costs SLOWNESS per metre in the cells within r of a wall (the band of the discs' clearance,
micro/clearance.py), so the shortest paths round a door post on an arc of radius r instead of meeting at the post
(docs/model.md, "A clearance at the walls").

With ``[velocity] route = "congestion"`` the distance becomes Hughes' potential (Hughes 2002):
:class:`CongestionVelocity`, re-solved every ``route_every`` seconds and at every door change.
"""

import copy
import json

import numpy as np

from ..mesh.distance import Eikonal
from ..micro.clearance import SLOWNESS
from .walls import wall_treatment

#: the least f(rho) the route choice counts: a jam costs at most 1 / ROUTE_FLOOR times the free walk
ROUTE_FLOOR = 0.05


def lifted(domain, normal_velocity, facets=slice(None)):
    """(2, F) U . n of a plan velocity on `facets`, as the flux through the facets on the surface of a building
    (domain.lift; docs/floors.md), per unit of their length there; unchanged on a plane floor plan."""
    return normal_velocity if domain.lift is None else normal_velocity * domain.lift[:, facets]


class FieldVelocity:
    """U given by expressions ux(x, y, t), uy(x, y, t)."""

    def __init__(self, domain, ux, uy):
        self.domain, self.ux, self.uy = domain, ux, uy
        self.steady = not (ux.depends_on_time or uy.depends_on_time)

    def at_points(self, xy: np.ndarray, t: float = 0.0, exits=None) -> np.ndarray:
        return np.column_stack([self.ux(xy[:, 0], xy[:, 1], t), self.uy(xy[:, 0], xy[:, 1], t)])

    def at_centroids(self, t: float = 0.0, exits=None) -> np.ndarray:
        """U at the cell centroids."""
        return self.at_points(self.domain.centroid, t)

    def potential(self, exits=None):
        return None

    def version(self, state, exits=None):
        return None if self.steady else state.t

    def normal_on_facets(self, state, exits=None, facets=slice(None)) -> np.ndarray:
        """(2, F): U(m_e) . n_e on `facets` (default all), the same seen from both cells of the facet."""
        a = np.einsum("ij,ij->i", self.at_points(self.domain.midpoint[facets], state.t), self.domain.normal[facets])
        return lifted(self.domain, np.stack([a, a]), facets)


class ExitsVelocity:
    """U = -speed grad d/|grad d| from the distance d to the open exits (one field per set of open exits);
    ``targets``: the names of the exits this population heads for (None: all exits); ``walls``: "paper" (the
    P1 direction as it is) or "slip" (no component into a wall, every cell drains: macro/walls.py)."""

    def __init__(self, domain, speed, targets=None, walls="paper", clearance=0.0):
        self.domain = domain
        self.walls = walls
        self.clearance = float(clearance)
        self._bands = {}    # per set of open exits: the cost of the clearance band per cell
        self.speed = speed(domain.centroid[:, 0], domain.centroid[:, 1], 0.0)
        self.targets = None if targets is None else frozenset(targets)
        self.eikonal = Eikonal(domain.points, domain.triangles, domain.z)
        self.cost = None    # per cell: None, the geodesic distance (CongestionVelocity sets it)
        self.climbs = None  # the stairs with up and down speeds (macro/stairs.py Climbs; velocity.speeds)
        self._cells = {}  # per set of open target exits
        self.distance = {}

    def version(self, state, exits):
        return None

    def costed(self, cost):
        """This desired velocity with a cost per cell in the eikonal (|grad d| = cost), its fields computed anew
        (the mesh's stencils shared): the discs' clearance of the walls, micro/clearance.py."""
        other = copy.copy(self)
        other.cost, other._cells, other.distance = cost, {}, {}
        return other

    def _costed(self, exits, cost=None):
        """The cost per cell of the eikonal for these open exits: ``cost`` (None: 1) times the clearance band's
        (``[velocity] clearance`` r: SLOWNESS in the cells whose nodes are on average within r of a wall, closed
        doors included, by the walking distance to the walls; 1 elsewhere), or None where both are 1."""
        if self.clearance == 0:
            return cost
        if exits.open not in self._bands:
            walls = self.domain.mesh.facets[:, exits.wall].T
            near = self.eikonal.solve(walls)[self.domain.triangles].mean(axis=1) < self.clearance
            self._bands[exits.open] = np.where(near, SLOWNESS, 1.0)
        return self._bands[exits.open] if cost is None else cost * self._bands[exits.open]

    def cells(self, exits) -> np.ndarray:
        """U per cell for these open exits (the distance field is computed on first use)."""
        heading = self._heading(exits)
        if heading not in self._cells:
            # with several exits, the distance to each too (_on_ridges): all solved together (Eikonal.solve_each,
            # bit for bit the solves one by one)
            edges = [self._edges(exits, (name,)) for name in heading] if len(heading) > 1 else []
            d, *each = self.eikonal.solve_each([self._edges(exits, heading), *edges], self._costed(exits, self.cost))
            self.distance[heading] = d
            grad = self.domain.gradient(d)
            if each:
                self._on_ridges(np.stack(each), grad)
            self._cells[heading] = self._down(grad, exits, d[self.domain.triangles].mean(axis=1))
        return self._cells[heading]

    def _down(self, grad, exits, level) -> np.ndarray:
        """U = -speed grad / |grad| per cell, on a building its lift (_steepest) (0 where the gradient is 0 or not
        finite; on a stair with up and down speeds, the speed of the direction U takes there: macro/stairs.py),
        with the wall treatment of ``walls`` (level: the potential per cell, which orders the cells that are made
        to drain)."""
        grad, norm = self._steepest(grad)
        ok = np.isfinite(norm) & (norm > 0)
        speed = self.speed if self.climbs is None else self.climbs.speed(self.speed, self.domain.slope, -grad)
        cells = np.zeros((self.domain.ncells, 2))
        cells[ok] = -(speed[ok] / norm[ok])[:, None] * grad[ok]
        if self.walls == "slip":
            return wall_treatment(self.domain, exits, cells, speed, level)
        return cells

    def _steepest(self, grad):
        """The direction of steepest descent of d per cell and the norm that makes its lift a unit vector: grad d and
        |grad d| in a plane; on a building (docs/floors.md) G^-1 grad d and (grad d . G^-1 grad d)^(1/2), with
        G = I + s s^T the metric of the cell's plane (s = grad z), G^-1 = I - s s^T / (1 + |s|^2)."""
        s = self.domain.slope
        if s is None:
            return grad, np.hypot(grad[:, 0], grad[:, 1])
        with np.errstate(invalid="ignore"):
            steep = grad - (np.einsum("ij,ij->i", s, grad) / (1 + (s * s).sum(1)))[:, None] * s
            return steep, np.sqrt(np.einsum("ij,ij->i", grad, steep))

    def _on_ridges(self, each, grad):
        """On the ridges of d between two exits (cells whose nodes are nearest to different exits), the
        gradient of the distance to the cell's own nearest exit, in place (each: the distance to each exit
        headed for, per node).

        There the P1 gradient of d = min_e d_e averages two directions: along the ridge, into a wall where
        two doors share it, and across it back and forth; a thin layer of crowd would stay there for good.
        People on a watershed pick one of the exits: the one nearest to the cell (mean of its nodes)."""
        t = self.domain.triangles
        nearest = np.argmin(each, axis=0)[t]   # the nearest exit of each node of each cell
        ridge = np.flatnonzero((nearest != nearest[:, :1]).any(axis=1))
        with np.errstate(invalid="ignore"):
            own = np.argmin(each[:, t[ridge]].mean(axis=2), axis=0)
        for e in np.unique(own):
            cells = ridge[own == e]
            grad[cells] = self.domain.gradient(each[e], cells)

    def _heading(self, exits) -> tuple:
        """The open exits this population heads for."""
        return exits.open if self.targets is None else tuple(n for n in exits.open if n in self.targets)

    def _edges(self, exits, heading):
        """Node pairs of the open exit facets this population heads for."""
        if heading == exits.open:
            return exits.edges()
        wanted = np.isin(exits.group, [exits.names.index(n) for n in heading])
        return self.domain.mesh.facets[:, wanted & exits.exit].T

    def potential(self, exits) -> np.ndarray:
        """The distance to the open exits this population heads for, per cell (mean of its nodes; cells cut
        off from every exit last)."""
        self.cells(exits)
        d = self.distance[self._heading(exits)][self.domain.triangles].mean(axis=1)
        return np.where(np.isfinite(d), d, -1.0)

    def at_points(self, xy: np.ndarray, t: float, exits) -> np.ndarray:
        """U of the triangle containing each point (0 outside the mesh)."""
        cell = self.domain.locate(xy)
        return np.where((cell >= 0)[:, None], self.cells(exits)[np.maximum(cell, 0)], 0.0)

    def at_centroids(self, t: float, exits) -> np.ndarray:
        """U at the cell centroids: U per cell, without locating the centroids (a point locator's set-up)."""
        return self.cells(exits)

    def normal_on_facets(self, state, exits, facets=slice(None)) -> np.ndarray:
        """(2, F): U_K . n_e on `facets` (default all) for K = f2t[0] and K = f2t[1] (f2t[0] again on the
        boundary)."""
        k0, k1 = self.domain.f2t[0][facets], self.domain.f2t[1][facets]
        n, cells = self.domain.normal[facets], self.cells(exits)
        return lifted(self.domain, np.stack([np.einsum("ij,ij->i", cells[k], n)
                                             for k in (k0, np.where(k1 >= 0, k1, k0))]), facets)


class CongestionVelocity(ExitsVelocity):
    """Route choice that sees the crowd. For each open exit e the population heads for:

    - the walking time T_e = phi_e / speed, phi_e solving |grad phi_e| = 1 / max(f(rho), ROUTE_FLOOR), phi_e = 0
      on e (Hughes 2002), rho the total density people see (the density around them, seen_density.py), f the
      population's speed law (Hughes' linear 1 - rho when the speed is constant);
    - at a door with a capacity c_e, the wait W_e = (the crowd heading for e and nearer to it) / (c_e |D_e|):
      the queue ahead divided by what the door lets through (the variant of docs/model.md, "Route choice"), and
      phi_e the walking distance (cost 1, solved once): the queue is counted by W_e, and Hughes' cost would count
      it again, at a speed the jam does not have, with directions that bend around a jam that moves between two
      routes (docs/model.md, "Route choice": the evacuation time then diverged under refinement).

    Each cell heads for the exit of least max(T_e, W_e) (one cannot pass a door before walking there, nor before
    those ahead have passed it), along -grad phi_e; a cell leaves the exit of its last route only for one faster
    by more than route_every. The waits are those of the last route's choices, up to route_every old: without
    that margin the routes are a best response that flip-flops (docs/model.md, "Route choice"). The routes are
    re-solved every ``route_every`` seconds of simulated time and at every door change. At rho = 0 phi_e is the
    distance of :class:`ExitsVelocity`."""

    def __init__(self, domain, speed, targets, law, route_every: float, walls="paper", clearance=0.0):
        super().__init__(domain, speed, targets, walls, clearance)
        self.f = law if not law.constant else (lambda rho: 1.0 - np.clip(rho, 0.0, 1.0))
        self.route_every = float(route_every)
        self.mass = np.zeros(domain.ncells)   # the crowd per cell at the last route
        self.choice = {}                      # per heading: the exit each cell heads for (index into the heading)
        self.walk = {}                        # per exit with a capacity (and door state, with a clearance): the walk
        self.hughes = {}                      # per exit without: (cost, Hughes' potential at the nodes), last solve
        # the density people see, from the density given to route(), for Hughes' cost: the macro solver's
        # SeenDensity (macro/seen_density.py); None, the density itself, for the discs (already an average over 1 m)
        self.seen = None
        self.routes = 0                       # route solves so far
        self.routed = (-np.inf, None)         # time and open exits of the last one

    def route(self, t: float, density: np.ndarray, exits) -> bool:
        """Re-solve the routes for the total density per cell at time t if it is due (route_every elapsed, or the
        doors changed); whether it was."""
        if not self.due(t, exits):
            return False
        hughes = self.seen is not None and any(not exits.doors[name].capped for name in self._heading(exits))
        cost = 1.0 / np.maximum(self.f(self.seen(density) if hughes else density), ROUTE_FLOOR)
        self.cost = None if np.all(cost == 1.0) else cost
        self.mass = density * self.domain.area
        self._cells.clear()
        self.distance.clear()
        self.routes += 1
        self.routed = (t, exits.open)
        self.cells(exits)
        return True

    def due(self, t: float, exits) -> bool:
        """Are the routes to be re-solved at time t: route_every elapsed since the last solve, or the doors changed?"""
        last, opened = self.routed
        return exits.open != opened or t >= last + self.route_every * (1 - 1e-9)

    def version(self, state, exits):
        self.route(state.t, state.density, exits)
        return self.routes

    def cells(self, exits) -> np.ndarray:
        """U per cell: towards the exit of least max(T_e, W_e), along -grad phi_e."""
        heading = self._heading(exits)
        if heading in self._cells:
            return self._cells[heading]
        cells = np.arange(self.domain.ncells)
        if not heading:   # no exit open: nobody walks (the pressure still pushes)
            self.choice[heading], self.distance[heading] = np.zeros(len(cells), int), np.full(len(cells), np.inf)
            self._cells[heading] = np.zeros((len(cells), 2))
            return self._cells[heading]
        phi = self._phi(exits, heading)
        on_cells = phi.take(self.domain.triangles, axis=1).mean(axis=2)          # (exits, cells)
        with np.errstate(divide="ignore", invalid="ignore"):
            walk = np.where(self.speed > 0, on_cells / self.speed, np.inf)
        # the queues are those of the last route's choices (the first: the nearest exits)
        previous = self.choice.get(heading, np.argmin(on_cells, axis=0))
        time = np.maximum(walk, self._waits(exits, heading, phi, previous))
        # the least time; between times equal but for round-off, the nearer exit; between those, the exit of before
        near = np.where(time <= time.min(axis=0) * (1 + 1e-9), walk, np.inf)
        nearest = near <= near.min(axis=0) * (1 + 1e-9)
        choice = np.where(nearest[previous, cells], previous, np.argmin(near, axis=0))
        if heading in self.choice:   # a switch must gain more than the lag of the waits (see the class)
            choice = np.where(time[previous, cells] <= time[choice, cells] + self.route_every, previous, choice)
        grad = np.empty((len(cells), 2))
        for e in np.unique(choice):
            to_e = np.flatnonzero(choice == e)
            grad[to_e] = self.domain.gradient(phi[e], to_e)
        self.choice[heading] = choice
        self.distance[heading] = on_cells[choice, cells]
        self._cells[heading] = self._down(grad, exits, self.distance[heading])
        return self._cells[heading]

    def _phi(self, exits, heading) -> np.ndarray:
        """(exits, nodes): phi_e of each exit of the heading. Hughes' potential on the density of the last route, the
        doors without a capacity solved together (Eikonal.solve_each, bit for bit the solves one by one) and only if
        the cost changed since their last solve (a crowd gone, or that did not move: the same field); at a door with
        a capacity the walking distance (its queue is the wait; computed once)."""
        cost = self._costed(exits, self.cost)
        stale = [name for name in heading if not exits.doors[name].capped
                 and not (name in self.hughes and _same(self.hughes[name][0], cost))]
        if stale:
            solved = self.eikonal.solve_each([self._edges(exits, (name,)) for name in stale], cost)
            self.hughes.update({name: (cost, phi) for name, phi in zip(stale, solved)})
        band = None if self.clearance == 0 else exits.open   # the clearance band follows the doors (closed: walls)
        for name in heading:
            if exits.doors[name].capped and (name, band) not in self.walk:
                self.walk[name, band] = self.eikonal.solve(self._edges(exits, (name,)), self._costed(exits))
        return np.stack([self.walk[name, band] if exits.doors[name].capped else self.hughes[name][1]
                         for name in heading])

    def _waits(self, exits, heading, phi, choice) -> np.ndarray:
        """W_e per cell: the crowd that headed for e at the last route and is nearer to e (smaller phi_e, the cell's
        own crowd left out), over what the door lets through; 0 at doors without a capacity. phi: (exits, nodes);
        choice: the exit each cell heads for."""
        waits = np.zeros((len(heading), self.domain.ncells))
        if not any(exits.doors[name].capped for name in heading):
            return waits
        on_cells = phi.take(self.domain.triangles, axis=1)             # (exits, cells, 3)
        for e, name in enumerate(heading):
            door = exits.doors[name]
            if door.capped:
                queued = np.where(choice == e, self.mass, 0.0)
                ahead = _mass_ahead(on_cells[e].mean(axis=1), on_cells[e].min(axis=1), on_cells[e].max(axis=1),
                                    queued)
                waits[e] = ahead / (door.capacity * door.width)
        return waits

    def snapshot(self) -> dict:
        """The routes in use (a checkpoint): a resumed run heads the same way and re-solves at the same times."""
        last, opened = self.routed
        heading = next(iter(self._cells), ())
        return {"t": last, "open": json.dumps(opened), "routes": self.routes, "mass": self.mass,
                "cost": np.ones(0) if self.cost is None else self.cost, "heading": json.dumps(heading),
                **({} if not heading else {"cells": self._cells[heading], "choice": self.choice[heading],
                                           "distance": self.distance[heading]})}

    def restore(self, data: dict) -> None:
        opened, heading = json.loads(str(data["open"])), tuple(json.loads(str(data["heading"])))
        self.routed = (float(data["t"]), None if opened is None else tuple(opened))
        self.routes, self.mass = int(data["routes"]), data["mass"].copy()
        self.cost = data["cost"].copy() if len(data["cost"]) else None
        self._cells.clear()
        self.distance.clear()
        if heading:
            self._cells[heading], self.choice[heading] = data["cells"].copy(), data["choice"].copy()
            self.distance[heading] = data["distance"].copy()

    def potential(self, exits) -> np.ndarray:
        """phi of the exit each cell heads for (cells cut off from every exit last)."""
        self.cells(exits)
        d = self.distance[self._heading(exits)]
        return np.where(np.isfinite(d), d, -1.0)


def _same(cost, other) -> bool:
    """Are two costs per cell (None: 1 everywhere) the same bit for bit?"""
    return cost is other or (cost is not None and other is not None and np.array_equal(cost, other))


def _mass_ahead(level, low, high, mass) -> np.ndarray:
    """Per cell k: the mass of the other cells below its level, each cell's mass spread evenly over its span
    [low, high] of phi: sum_{j != k} m_j clip((level_k - low_j) / (high_j - low_j), 0, 1). Continuous in the
    levels, so cells at the same level in exact arithmetic see the same mass ahead whatever the round-off of phi."""
    finite = np.isfinite(low) & np.isfinite(high) & (mass > 0)
    floor = 1e-6 * float(high[finite].max(initial=1.0))       # a level set of cells: a steep ramp
    width = np.maximum(high - low, floor)
    own = np.where(finite, mass * np.clip((level - low) / width, 0.0, 1.0), 0.0)
    if not finite.any():
        return np.zeros(len(level))
    low, width, mass = low[finite], width[finite], mass[finite]
    at = np.concatenate([low, low + width])
    order = np.argsort(at, kind="stable")
    slope, at = np.concatenate([mass / width, -mass / width])[order], at[order]
    below = np.concatenate([[0.0], np.cumsum(np.cumsum(slope)[:-1] * np.diff(at))])
    return np.interp(level, at, below, left=0.0, right=float(mass.sum())) - own
