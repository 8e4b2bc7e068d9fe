"""Correction step: the projection of rho~ onto {rho <= 1} as a linear complementarity problem
(Maury, Roudneff-Chupin, Santambrogio 2010; docs/model.md, "The catching-up scheme").

Find phi = tau p on the cells such that

    w = M_L (1 - rho~) + A phi >= 0,   phi >= 0,   phi . w = 0,

with A the two-point Laplacian of the open exits (an M-matrix, exits Dirichlet, walls
Neumann) and M_L the cell areas; then |K| rho_K = |K| rho~_K - (A phi)_K. It is solved
exactly by primal-dual active-set iterations (Hintermueller, Ito, Kunisch 2003): on the
saturated set S solve A_SS phi_S = -b_S, set phi = 0 elsewhere, then
S <- {phi >= 0 on S} U {w < 0 off S}; for an M-matrix this terminates in finitely many
steps. The iterations work on S and its neighbour layer only; intermediate AMG solves are
loose (only their signs matter) until S (nearly) settles (inexact Newton), and the loop
stops only on an S reproduced by a tight solve.
"""

from dataclasses import dataclass

import numpy as np

from ...linalg.rows import rows as gather
from ...timer import Stopwatch, timed
from .rooms import ClosedRooms
from .sets import CellSets, product, restriction
from .solvers import CellOrder, SaturatedSolver
from .warm_start import MAX_SPILLS, WarmStart

#: density tolerance of the intermediate active-set iterations (only their signs matter)
LOOSE = 1e-6
#: solves are tight from the iteration that changes fewer than this fraction of S
TIGHT_SWITCH = 1e-3


class ProjectionError(RuntimeError):
    """The active-set iteration did not terminate (it always does for an M-matrix)."""


@dataclass
class PressureFlux:
    """The correction of one step: phi = tau p and the mass it moves, -div(grad phi).

    ``outflow[i] = (A phi)_K`` for the cells K = ``cells[i]`` (S and its neighbours, A phi = 0
    elsewhere) is the net mass K sends across its facets in the step, the sum of the facet
    fluxes T_e (phi_K - phi_L - j_e) (phi_L = 0 across an open exit; j_e the pressure jump of a capped
    door facet, ``jump``: None without capacities): :meth:`facet_flux` gives those, for a split of the
    correction among populations or a measurement line. ``door``: the values of the door nodes.
    """

    phi: np.ndarray
    cells: np.ndarray
    outflow: np.ndarray
    door: np.ndarray = None
    jump: np.ndarray = None

    def apply(self, rho_tilde: np.ndarray, area: np.ndarray) -> np.ndarray:
        """rho = rho~ - (A phi) / |K|: mass moves between cells or leaves through the exits."""
        rho = rho_tilde.copy()
        rho[self.cells] -= self.outflow / area[self.cells]
        return rho

    def facet_flux(self, domain, exits, facets=slice(None)) -> np.ndarray:
        """Mass moved across each facet (of `facets`) in the step, f2t[0] -> f2t[1] (out of the domain through
        an exit)."""
        return exits.pressure_flux(self.phi, self.jump, facets)


class Projection:
    """Exact LCP projection on one set of open doors, warm-started from the previous step.

    With door capacities (``exits.caps``, mesh/capacity.py) the unknowns are the cells followed by the
    door nodes: A is the Laplacian extended by their rows, and a door node's "area" (the scale of its
    tolerance) is that of the cell it lets people out of."""

    def __init__(self, domain, exits, direct_max=1_000_000, tol=1e-12, max_iterations=None, reuse=True,
                 order=None):
        self.ncells, caps = domain.ncells, exits.caps
        self.caps = caps
        free = exits.exit.copy()   # the exit facets without a cap: Dirichlet links
        if caps is None:
            self.A, self.area, node_cell = exits.laplacian(), domain.area, None
        else:
            self.A = caps.extend(exits.laplacian())
            self.area, node_cell = np.concatenate([domain.area, domain.area[caps.node_cell]]), caps.node_cell
            free[caps.facets] = False
        self.A.sort_indices()
        self.tol = tol
        self.direct_max = direct_max
        has_exit = np.bincount(domain.f2t[0][free], minlength=len(self.area)) > 0
        self.rooms = ClosedRooms(self.A if caps is None else caps.rooms(self.A), has_exit)
        self.sets = CellSets(len(self.area))
        self.solver = SaturatedSolver(self.A, self.area, direct_max, order or CellOrder(), self.sets, reuse,
                                      node_cell)
        # the two door nodes of a capped interior facet (forward, back): at most one of them in S
        self.pairs = (np.zeros(0, np.intp),) * 2 if caps is None else caps.pairs(self.ncells)
        self.warm = WarmStart(self.A, self.area, tol, self.sets, self.solver, self.rooms.gauge, self.ncells,
                              predictor=not self.pairs[0].size)
        self.reuse = reuse
        # S grows by about one layer of cells per iteration, so a stiff front (rho ~ 0.999 running
        # into a wall: the saturated zone advances ~1/(1 - rho) cells per step) needs as many
        # iterations as the front crosses cells; the M-matrix bound is n + 1 (monotone iterates).
        self.max_iterations = max_iterations or len(self.area) + 1

    @staticmethod
    def counters() -> dict:
        """The info of a projection (see __call__) at zero: a step that needs none reports these."""
        return {"iterations": 0, "factorizations": 0, "band_solves": 0, "linear_residual": 0.0, "unknowns": 0,
                "linear_iterations": 0, "rebuilds": 0, "detect": 0.0, "predict": 0.0, "setup": 0.0, "solve": 0.0,
                "active_set": 0.0}

    def __call__(self, rho_tilde: np.ndarray, room: np.ndarray = None):
        """Return (PressureFlux, info) for one correction step of the total density rho~ (room: what each door
        node can still let through, Capacities.room, with door capacities; default 0).

        info: iterations (active-set iterations, each with a solve on S to the tolerance, or a
        loose one on the AMG path), factorizations (numeric Cholesky factorisations among them),
        band_solves (local solves of the warm-start predictor), linear_residual (max |r_K| / |K|
        of the linear solves), unknowns (|S|), linear_iterations (CG of the AMG path), rebuilds
        (new envelopes / AMG set-ups), and seconds spent in detect (rho~ > 1), predict (the
        predictor), setup (numeric factorisations, AMG set-ups), solve and active_set (the rest).
        """
        clock = Stopwatch()
        info = self.counters()
        with timed(info, "detect"):
            b = self.area[:self.ncells] * (1.0 - rho_tilde)
            over = np.flatnonzero(b < 0)
            if self.caps is not None:   # no room given: the doors are full (the prediction passed their capacity)
                b = np.concatenate([b, np.zeros(self.caps.nodes) if room is None else room])
            # cells that enter S wherever they are (w = b off the neighbourhood of S)
            strict = over[b[over] < -self.tol * self.area[over]]
        if not over.size:
            self.warm.forget()
            return PressureFlux(np.zeros(self.ncells), np.zeros(0, np.intp), np.zeros(0)), info
        spills, tight = 0, False  # inexact Newton: loose solves until S (nearly) settles, then tight ones
        if self.reuse and self.warm.can_predict():
            with timed(info, "predict"):
                S, x0 = self.warm.predict(b, strict, info)
            spills, tight = 1, True
        else:
            S, x0, updated = self.warm.first_update(over, b, strict, self._next)
            if updated:
                spills, tight = 1, self.sets.changed(self.warm.active, S) <= TIGHT_SWITCH * len(S)
        S, phi_S, L, Aphi = self._iterate(S, x0, b, strict, spills, tight, info)
        self.warm.remember(S, phi_S)
        phi = np.zeros_like(b)
        phi[S] = phi_S
        info["unknowns"] = len(S)
        info["active_set"] = clock.seconds - info["detect"] - info["predict"] - info["setup"] \
            - info["solve"]
        if self.caps is None:
            return PressureFlux(phi, L, Aphi), info
        cells, door = L < self.ncells, phi[self.ncells:]
        return PressureFlux(phi[:self.ncells], L[cells], Aphi[cells], door, self.caps.jumps(door)), info

    def _iterate(self, S, x0, b, strict, spills, tight, info):
        """The primal-dual active-set iterations from the guess S (x0: phi on it) until S is reproduced by a tight
        solve: (S, phi on S, its neighbourhood L, A phi on L); info counts the iterations."""
        for iteration in range(1, self.max_iterations + 1):
            rows = gather(self.A, S)
            L, col, in_S, s_in_L = self.sets.neighbourhood(rows, S)
            tight = tight or len(S) <= self.direct_max  # a factorisation solves exactly anyway
            phi_S, keep, full = self._solve(rows, S, col, in_S, -b[S], x0, info,
                                            self.tol if tight else max(self.tol, LOOSE))
            Aphi = product(rows, col, len(L), phi_S)
            w = b[L] + Aphi
            # the residual of the linear solve (w = 0 on S but in the gauge cells of closed rooms)
            info["linear_residual"] = float(np.max(np.abs(w[s_in_L][keep]) / self.area[S[keep]], initial=0.0))
            info["iterations"] = iteration
            spare = self.rooms.spare(S, full, phi_S, w[s_in_L], self.area[S])
            new = self._next(S, phi_S, w, strict, L, in_S, s_in_L, spare)
            if np.array_equal(new, S):
                if tight:
                    return S, phi_S, L, Aphi
                tight, x0 = True, phi_S  # S settled on a loose solve: solve it again exactly
                continue
            if spills < MAX_SPILLS and self.sets.changed(S, new) == len(new) - len(S):  # S only grows:
                new, spills = self.warm.grow(S, phi_S, new, b, L, w, info), spills + 1  # carry the front further
            tight = tight or self.sets.changed(S, new) <= TIGHT_SWITCH * len(S)
            x0 = self.sets.carry(S, phi_S, new)
            S = new
        raise ProjectionError(f"active-set iterations did not terminate in {self.max_iterations}")

    def _next(self, S, phi_S, w, strict, L, in_S, s_in_L, spare=None):
        """The active-set update: S <- {phi >= 0 on S} U {w < 0 off S}, with w = b + A phi on L, but the
        cells `spare` (positions in S) of the full closed rooms with space to spare (ClosedRooms.spare)."""
        phi_L = np.zeros(len(L))
        phi_L[s_in_L] = phi_S
        # A cell of S with phi = 0 (and w = 0) solves the LCP whether it is in S or not; it
        # stays in S. Dropping it makes a closed saturated room cycle: its gauge cell has
        # phi = 0 exactly, leaves S, and re-enters on a round-off w < 0 the next iteration.
        stay = np.where(in_S, phi_L >= 0, w < -self.tol * self.area[L])
        if spare is not None:
            stay[s_in_L[spare]] = False
        mark = self.sets.mark
        mark[L] = True
        far = strict[~mark[strict]]
        mark[L] = False
        new = self.sets.union(L[stay], far) if far.size else L[stay]
        return self._one_direction(new, S, L, w) if self.pairs[0].size else new

    def _one_direction(self, new, S, L, w):
        """A capped interior door is at capacity in one direction at most (both its door nodes in S would make
        A_SS singular, and mean a flux both <= s and >= -s'): of two nodes of one facet in the new S, keep the
        one that joins (the flow turned), or of two that join the one whose room is exceeded more."""
        forward, back = self.pairs
        inside = [np.isin(nodes, new, assume_unique=True) for nodes in (forward, back)]
        both = inside[0] & inside[1]
        if not both.any():
            return new
        forward, back = forward[both], back[both]
        was = [np.isin(nodes, S, assume_unique=True) for nodes in (forward, back)]
        w_at = lambda nodes: w[np.searchsorted(L, nodes)]   # noqa: E731  (both are in L: S and its neighbours)
        drop = np.where(was[0] != was[1], np.where(was[0], forward, back),
                        np.where(w_at(forward) > w_at(back), forward, back))
        return new[~np.isin(new, drop, assume_unique=True)]

    def _solve(self, rows, S, col, in_S, rhs, x0, info, tol):
        """Solve A_SS phi_S = rhs; returns phi_S, the mask of the cells of S whose equation holds
        (all but the pinned cells of the closed rooms entirely in S, see rooms.py) and those rooms."""
        full = self.rooms.full(S)
        keep = self.rooms.unpinned(S, full)
        x = np.zeros(len(S))
        if keep.any():
            def matrix():  # A on S[keep], for the AMG path only
                A_SS = restriction(rows, col, in_S)
                return A_SS if keep.all() else A_SS[keep][:, keep]
            x[keep] = self.solver.solve(matrix, S[keep], rhs[keep], x0[keep], info, tol)
        return self.rooms.gauge_shift(x, S, full), keep, full
