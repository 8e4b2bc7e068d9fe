"""Guesses of the active-set iterations: the saturated set S and phi of the next step, and the next S of an
iteration that grows it.

A dense crowd moves the front of the saturated zone by several cells per step, while an
active-set iteration adds one layer. Three guesses carry it further (only the guess changes:
the exact iterations that follow decide, docs/performance.md has the measured effect):

- :meth:`WarmStart.predict`, when a factorisation of the last S is kept: alternating Schwarz
  between the factorised set (one substitution with the kept factor) and the band of cells
  around the moving front (local active-set iterations with small sparse solves);
- :meth:`WarmStart.advance` after an exact iteration that only grows a large S: the same alternating Schwarz
  from that iteration's phi and factor;
- :meth:`WarmStart.spill` otherwise, and after iterations that only grow a small S: the overflow of the
  cells that join S is spread to the next ones (a few sweeps of a divisible sandpile, the
  deterministic version of the seeds' random walks).
"""

import numpy as np

from ...linalg.cholmod import solve_spd
from ...linalg.envelope import BORDER_MAX
from ...linalg.rows import lower_block, matvec
from ...linalg.rows import rows as gather
from .sets import adjacency_table, product

#: sweeps of the overflow spread (spill), applied to at most MAX_SPILLS growing updates per step (a cap:
#: after it the plain active-set iteration, monotone for an M-matrix, finishes the step)
SPILL_SWEEPS = 8
MAX_SPILLS = 16
#: the predictor: layers of cells of S around the cells that join it (outside the factorised set) in the
#: band of the local solves, and global corrections (substitutions with the kept factor) after the first pass
FRONT_LAYERS = 8
PREDICTOR_ROUNDS = 1
#: local active-set iterations per round of the predictor (a cap)
MAX_LOCAL = 10
#: the predictor is used from this size of the last S: below it its fixed cost (numpy calls, a small CHOLMOD
#: solve per local iteration) exceeds the factorisations it saves
PREDICT_MIN = 10_000
#: the exact iterations that grow S from this size on are carried further by advance() rather than spill(); its
#: local iterations per round (a cap: they stop by themselves after 10-35 on the benchmark hall) and its rounds
ADVANCE_MIN = PREDICT_MIN
ADVANCE_LOCAL = 40
ADVANCE_ROUNDS = 1


class WarmStart:
    """The last step's S and phi, and the two ways of guessing the next ones from them."""

    def __init__(self, A, area, tol, sets, solver, gauge, cells=None, predictor=True):
        """cells: the number of cells (the unknowns after them are the door nodes of capacities, which the
        overflow is not spread to: they join S by the exact iterations); predictor: whether predict() may be
        used (not with interior doors, whose two door nodes must not both be in S)."""
        self.A, self.area, self.tol, self.sets, self.solver, self.gauge = A, area, tol, sets, solver, gauge
        self.cells = len(area) if cells is None else cells
        self.predictor = predictor
        self.adjacent = adjacency_table(A)
        self.active = np.zeros(0, np.intp)  # S of the last step (sorted cells)
        self.phi_active = np.zeros(0)       # phi on it

    def remember(self, S, phi_S):
        self.active, self.phi_active = S, phi_S

    def forget(self):
        self.active, self.phi_active = np.zeros(0, np.intp), np.zeros(0)

    def can_predict(self) -> bool:
        return self.predictor and len(self.active) >= PREDICT_MIN and self.solver.factor is not None

    def first_update(self, over, b, strict, next_set):
        """Without the predictor: S = the cells over 1 and the last S, phi carried over; when there was a
        last S, one active-set update with its phi (no solve) followed by a spill. Returns S, phi_S and
        whether the update was made."""
        S = self.sets.union(over, self.active)
        x0 = self.sets.carry(self.active, self.phi_active, S)
        if not self.active.size:
            return S, x0, False
        rows = gather(self.A, S)
        L, col, in_S, s_in_L = self.sets.neighbourhood(rows, S)
        w = b[L] + product(rows, col, len(L), x0)
        new = self.spill(S, next_set(S, x0, w, strict, L, in_S, s_in_L), b, L, w)
        return new, self.sets.carry(S, x0, new), True

    def predict(self, b, strict, info):
        """S and phi of this step, guessed from the kept factorisation without a new one.

        Alternating Schwarz on the complementarity problem between two overlapping sets of cells:
        - the factorised set G (the last S, but for the cells that were bordered): phi_G += A_GG^{-1} r_G,
          one substitution with the kept factor, r = -(b + A phi) on G in S and 0 on the cells of G that
          left S (their equation is phi = 0, not w = 0: their spare capacity b > 0 would pull phi down
          over the whole rear of a draining queue);
        - the band B, the cells of S within FRONT_LAYERS layers of those in S outside G or next
          to a cell that left it: local active-set iterations S <- {phi >= 0 on S} U {w < 0 off S}
          (w = b + A phi, re-evaluated where phi changed), each followed by
          phi_B = A_BB^{-1} (-b - A phi_{off B})_B, a sparse Cholesky solve of a few thousand unknowns.
        The band solves carry the overflow of the cells that join to the cells it fills, many
        layers deep, where each exact iteration adds one layer; the solve on G then brings the far field.
        """
        n = len(b)
        G = self.solver.factor.factorised()
        in_G = np.zeros(n, bool)
        in_G[G] = True
        inside = in_G.copy()  # S as a mask
        inside[strict] = True
        phi = np.zeros(n)
        self._alternate(b, phi, inside, in_G, strict, info, PREDICTOR_ROUNDS + 1, MAX_LOCAL)
        S = np.flatnonzero(inside)
        return S, phi[S]

    def advance(self, S, phi_S, b, info):
        """The next S of an exact active-set iteration that grows S, carried further by the alternating Schwarz of
        :meth:`predict` from the exact phi on S (the factor just made, G = S but for bordered cells): local
        iterations first, then, if they changed more cells than a bordered solve takes, ADVANCE_ROUNDS substitutions
        each followed by local iterations. The band solves move the front several layers where an active-set update
        moves it one."""
        n = len(b)
        in_G = np.zeros(n, bool)
        in_G[self.solver.factor.factorised()] = True
        inside = np.zeros(n, bool)
        inside[S] = True
        phi = np.zeros(n)
        phi[S] = phi_S
        start = inside.copy()
        touched = self._local(b, phi, inside, in_G, np.flatnonzero(inside != in_G), info, ADVANCE_LOCAL)
        if np.count_nonzero(inside[touched] != start[touched]) > BORDER_MAX:  # else the next iteration borders them
            self._alternate(b, phi, inside, in_G, touched, info, ADVANCE_ROUNDS, ADVANCE_LOCAL)
        return np.flatnonzero(inside)

    def _alternate(self, b, phi, inside, in_G, touched, info, rounds, iterations):
        """`rounds` times: a substitution with the kept factor on its set G, phi_G += A_GG^{-1} r_G (r = -(b + A phi)
        on G in S, 0 on the cells of G that left S), then local iterations (_local). Returns the cells touched."""
        factor = self.solver.factor
        G = factor.factorised()
        for _ in range(rounds):
            residual = -(b + self.A @ phi)[G]
            residual[~inside[G]] = 0.0   # the cells of G that left S carry no equation (their phi is 0)
            phi[G] += factor.solve(G, residual)
            phi[~inside] = 0.0
            touched = self._local(b, phi, inside, in_G, touched, info, iterations)
        return touched

    def _local(self, b, phi, inside, in_G, touched, info, iterations):
        """Local active-set iterations S <- {phi >= 0 on S} U {w < 0 off S} (S the mask `inside`, updated, phi
        updated), each followed by a solve on the band of the cells touched so far (every cell that has been in S
        outside G, or in G outside S: `touched` and the flips) whose membership differs from in_G; returns the cells
        touched."""
        A, threshold = self.A, -self.tol * self.area
        region, w = slice(None), b + A @ phi
        for _ in range(iterations):
            flips = np.where(inside[region], phi[region] < 0, w < threshold[region])
            flips = np.flatnonzero(flips) if isinstance(region, slice) else region[flips]
            if not flips.size:
                break
            inside[flips] = ~inside[flips]
            phi[flips] = 0.0  # the cells that leave; those that join start from 0
            touched = self.sets.distinct(np.concatenate([touched, flips]))
            band = self._band(touched[inside[touched] != in_G[touched]], inside)
            rows = gather(A, band)
            phi[band] += solve_spd(lower_block(rows, band), len(band), -(b[band] + matvec(rows, phi)),
                                   self.solver.nested_dissection()[band])
            info["band_solves"] += 1
            region = self.sets.distinct(rows.indices)  # where w and the signs of phi can have changed
            w = b[region] + matvec(gather(A, region), phi)
        return touched

    def _band(self, changed, inside):
        """The cells of S (mask inside) within FRONT_LAYERS layers of the cells `changed` (those in S
        outside G and the neighbours in S of those in G outside S), but the gauge cells of closed rooms
        (so that the band solves are never singular)."""
        near = np.concatenate([changed, self.adjacent[changed].ravel()])
        front = self.sets.distinct(near[inside[near]])
        mark = self.sets.mark
        mark[front] = True
        band = [front]
        for _ in range(FRONT_LAYERS):
            neighbours = self.adjacent[front].ravel()
            front = self.sets.distinct(neighbours[inside[neighbours] & ~mark[neighbours]])
            mark[front] = True
            band.append(front)
        band = np.concatenate(band)
        mark[band] = False
        return band[~self.gauge[band]]

    def grow(self, S, phi_S, new, b, L, w, info):
        """The next S after an exact iteration that only grows S (new, from phi_S on S; w on L): advance() from
        ADVANCE_MIN cells with a factor, spill() otherwise."""
        if self.predictor and len(S) >= ADVANCE_MIN and self.solver.factor is not None:
            return self.advance(S, phi_S, b, info)
        return self.spill(S, new, b, L, w)

    def spill(self, S, new, b, L, w):
        """The next S guessed by spreading the overflow -w of the cells that join S, and the residual
        -w that the guessed phi leaves in S, outwards (divisible sandpile).

        Each cell with an overflow passes it to its neighbours outside S in proportion to the
        transmissibilities (a cell with none, to its other neighbours), and those it overfills
        join too (SPILL_SWEEPS sweeps). At a warm start the residual left in S is the capacity
        that the cells that joined at the last step used up.
        """
        level = b.copy()            # w of every cell with phi = 0 outside L
        level[L] = w
        inside = self.sets.mark
        inside[S] = True
        joining = new[~inside[new]]
        inside[new] = True
        front = np.concatenate([joining, S[level[S] < -self.tol * self.area[S]]])
        added = [joining]
        for _ in range(SPILL_SWEEPS):
            front = front[level[front] < -self.tol * self.area[front]]
            if not front.size:
                break
            rows = gather(self.A, front)
            row = np.repeat(np.arange(len(front)), np.diff(rows.indptr))
            neighbour = (rows.indices != front[row]) & (rows.indices < self.cells)
            out = ~inside[rows.indices]
            # to the neighbours outside the set; a cell with none (second layer) passes to its others
            closed = np.bincount(row, out, len(front)) == 0
            receives = neighbour & (out | closed[row])
            weight = np.where(receives, np.maximum(-rows.data, 0.0), 0.0)   # (+T_e beside an interior door node)
            total = np.bincount(row, weight, len(front))
            share = weight * (-level[front] / np.where(total > 0, total, 1.0))[row]
            np.subtract.at(level, rows.indices[receives], share[receives])
            level[front] = 0.0
            targets = np.unique(rows.indices[receives])
            front = targets[level[targets] < -self.tol * self.area[targets]]
            joining = front[~inside[front]]
            inside[joining] = True
            added.append(joining)
        inside[S] = False
        inside[new] = False
        grown = np.concatenate(added[1:]) if len(added) > 1 else added[0][:0]
        inside[grown] = False
        return self.sets.union(new, grown) if grown.size else new
