"""Correction step: projection of rho~ onto {rho <= 1} (design note, sec. 2, step 2).

Find phi = tau p on the cells such that

    w = M_L (1 - rho~) + A phi >= 0,   phi >= 0,   phi . w = 0,

with A the two-point Laplacian (an M-matrix, exits Dirichlet, walls Neumann)
and M_L the cell areas; then |K| rho_K = |K| rho~_K - (A phi)_K, i.e.
rho = 1 - w / |K|. The linear complementarity problem is solved exactly by
primal-dual active-set iterations (Hintermueller, Ito, Kunisch 2003): on the
saturated set S solve A_SS phi_S = -b_S, set phi = 0 elsewhere, then
S <- {phi >= 0 on S} U {w < 0 off S}; for an M-matrix this terminates in
finitely many steps.

Cost (docs/performance.md), with the result unchanged:
- warm start: a dense crowd moves the front of the saturated zone by several
  cells per step while an active-set iteration adds one layer. With a kept
  factorisation (and an S of at least PREDICT_MIN cells), S and phi are
  predicted without a new one (_predict):
  alternating Schwarz between the factorised previous S (one substitution) and
  the band of cells around the front (local active-set iterations, small
  sparse solves); the exact iterations then start from that S and decide.
  Without one (AMG path), the previous phi gives a first active-set update and
  the overflow of the cells that join is spread to the next ones (a few sweeps
  of a divisible sandpile, _spill); that spill also speeds up cold starts;
- inexact Newton (AMG): intermediate iterations solve to a loose density tolerance
  (only their signs matter); from the iteration where S (nearly) settles, the
  solves are tight, and the loop stops only on an S reproduced by a tight solve;
- the exact iterations work on S and its neighbour layer L only (index arrays,
  persistent scratch vectors, no full-length temporaries); the predictor makes
  a few O(n) passes (masks, four mat-vecs with A) per step, ~15 % of its time;
- systems up to ``direct_max`` unknowns are factorised (sparse Cholesky, in a
  nested-dissection order of the mesh computed once): the
  symbolic analysis of an envelope of S (S and a few layers of neighbours) is
  kept between iterations and steps, so a new S inside it costs one numeric
  factorisation, and an S that only adds a few cells to the factorised one (the
  stragglers of the last active-set iteration) none: it is solved by bordering
  (EnvelopeCholesky); larger systems are solved by CG
  preconditioned with a Ruge-Stuben AMG V-cycle, the hierarchy kept while S
  is unchanged, initial guesses from the previous phi;
- iterative solves stop when every cell's density is within ``tol`` of its
  target (|r_K| <= tol |K|) or at the round-off level of A phi, so the bound
  rho <= 1 + tol holds whatever the conditioning (a relative residual of 1e-12
  stagnated at round-off on 10^5 unknowns and ran to the iteration limit).
"""

import time

import numpy as np
import pymetis
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from .linear import EnvelopeCholesky, Hierarchy, cholesky_solve, pcg

#: layers of neighbours around S in the envelope of a factorisation (the front moves a few cells per step)
ENVELOPE_LAYERS = 8
#: density tolerance of the intermediate active-set iterations (only their signs matter)
LOOSE = 1e-6
#: sweeps of the overflow predictor (see _spill), applied to at most MAX_SPILLS growing updates per step
#: (a cap: after it the plain active-set iteration, monotone for an M-matrix, finishes the step; a cold
#: start on the 10^6-triangle benchmark hall took 43 iterations with 3 spills and 11 with 16)
SPILL_SWEEPS = 8
MAX_SPILLS = 16
#: solves are tight from the iteration that changes fewer than this fraction of S
TIGHT_SWITCH = 1e-3
#: the warm-start predictor (_predict): layers of cells of S around the cells that join it (outside the
#: factorised set) in the band of the local solves, and global corrections (substitutions with the kept
#: factor) after the first pass. On the 10^6-triangle hall (5.4 10^5 cells in S, ~700 joining per step) the
#: guess then misses 2-8 cells (bordered, no factorisation); with 8 layers and no correction, 30-50; with 32
#: layers and none, 7-16 for a band 5x as large
FRONT_LAYERS = 8
PREDICTOR_ROUNDS = 1
#: local active-set iterations per round of the predictor (a cap: 3-4 are used on the benchmark hall)
MAX_LOCAL = 10
#: the predictor is used from this size of the last S: below it, its fixed cost (~30 numpy calls and a
#: small CHOLMOD solve per local iteration) exceeds the factorisations it saves (benchmark hall at 10^4
#: triangles, 3.5 10^3 cells in S: 9-12 ms against 3-4 ms for a factorisation)
PREDICT_MIN = 10_000
#: round-off of (A phi)_K in units of eps * A_KK * max|phi| (floor of the iterative stopping test)
ROUNDOFF = 64 * np.finfo(float).eps


class ProjectionError(RuntimeError):
    """The active-set iteration did not terminate (it always does for an M-matrix)."""


class Projection:
    """Exact LCP projection with warm-started active sets and reused linear solvers."""

    def __init__(self, domain, direct_max=1_000_000, tol=1e-12, max_iterations=None, reuse=True):
        self.A = domain.laplacian()
        self.A.sort_indices()
        self.area = domain.area
        has_exit = np.bincount(domain.f2t[0][domain.exit], minlength=domain.ncells) > 0
        # A component of S is a closed, fully saturated room (A_SS singular, pure Neumann) exactly when
        # it is a whole connected component of A's graph with no exit cell: found once here.
        ncomp, self.component = connected_components(self.A, directed=False)
        self.closed = np.bincount(self.component, has_exit, ncomp) == 0
        self.component_size = np.bincount(self.component, minlength=ncomp)
        self.first_cell = np.unique(self.component, return_index=True)[1]  # the gauge cell of a closed room
        self.gauge = np.zeros(domain.ncells, bool)  # those cells: never in a band of the predictor, whose
        self.gauge[self.first_cell[self.closed]] = True  # solves are then never singular
        self.adjacent = _adjacency_table(self.A)
        self.direct_max = direct_max
        self.tol = tol
        # S grows by about one layer of cells per iteration, so a stiff front (rho ~ 0.999 running
        # into a wall: the saturated zone advances ~1/(1 - rho) cells per step) needs as many
        # iterations as the front crosses cells; the M-matrix bound is n + 1 (monotone iterates).
        self.max_iterations = max_iterations or domain.ncells + 1
        self.reuse = reuse
        self.active = np.zeros(0, np.intp)      # S of the last call (sorted cells): the warm start
        self.phi_active = np.zeros(0)           # phi on it: the initial guess of the next solve
        self.factor = None                      # the kept EnvelopeCholesky
        self.hierarchy = None                   # the kept Hierarchy
        self.order = None                       # nested-dissection rank of every cell (on first factorisation)
        n = domain.ncells
        self._mark = np.zeros(n, bool)          # scratch, all False between uses
        self._position = np.zeros(n, np.intp)   # scratch: position of a cell in the current local set
        self._scratch = np.zeros(n)             # scratch, all 0 between uses

    def __call__(self, rho_tilde):
        """Return (rho, phi, info) for one correction step.

        info: iterations (active-set iterations, each with a solve on S to the tolerance, or a
        loose one on the AMG path), factorizations (numeric Cholesky factorisations among them),
        band_solves (local solves of the warm-start predictor, before the iterations),
        linear_residual (max |r_K| / |K| of the linear solves), unknowns (|S|), linear_iterations
        (CG of the AMG path), rebuilds (new envelopes / AMG set-ups), and seconds spent in detect
        (rho~ > 1), predict (the predictor), setup (numeric factorisations, AMG set-ups), solve
        and active_set (everything else).
        """
        clock = _Clock()
        b = self.area * (1.0 - rho_tilde)
        over = np.flatnonzero(b < 0)
        info = {"iterations": 0, "factorizations": 0, "band_solves": 0, "linear_residual": 0.0, "unknowns": 0,
                "linear_iterations": 0, "rebuilds": 0, "predict": 0.0, "setup": 0.0, "solve": 0.0}
        if not over.size:
            self.active, self.phi_active = np.zeros(0, np.intp), np.zeros(0)
            info.update(detect=clock.lap(), active_set=0.0)
            return rho_tilde.copy(), np.zeros_like(b), info
        # cells that enter S wherever they are (w = b off the neighbourhood of S)
        strict = over[b[over] < -self.tol * self.area[over]]
        info["detect"] = clock.lap()
        spills, tight = 0, False  # inexact Newton: loose solves until S (nearly) settles, then tight ones
        if self.reuse and self.active.size and len(self.active) >= PREDICT_MIN and self.factor is not None:
            S, x0 = self._predict(b, strict, info)
            info["predict"] = clock.lap()
            spills, tight = 1, True
        else:
            S = self._union(over, self.active)
            x0 = self._carry(self.active, self.phi_active, S)
            if self.active.size:  # warm start: one active-set update with the previous phi, no solve
                S, x0 = self._update(S, x0, b, strict)
                spills, tight = 1, self._changed(self.active, S) <= TIGHT_SWITCH * len(S)
        for iteration in range(1, self.max_iterations + 1):
            rows = self.A[S]
            L, col, in_S, s_in_L = self._neighbourhood(rows, S)
            tight = tight or len(S) <= self.direct_max  # a factorisation solves exactly anyway
            phi_S, keep = self._solve(rows, S, col, in_S, -b[S], x0, info,
                                      self.tol if tight else max(self.tol, LOOSE))
            Aphi = _product(rows, col, len(L), phi_S)
            w = b[L] + Aphi
            # the residual of the linear solve (w = 0 on S but in the gauge cells of closed rooms)
            info["linear_residual"] = float(np.max(np.abs(w[s_in_L][keep]) / self.area[S[keep]], initial=0.0))
            new = self._next(S, phi_S, w, strict, L, in_S, s_in_L)
            if np.array_equal(new, S):
                if tight:
                    break
                tight, x0 = True, phi_S  # S settled on a loose solve: solve it again exactly
                continue
            if spills < MAX_SPILLS and self._changed(S, new) == len(new) - len(S):  # S only grows:
                new, spills = self._spill(S, new, b, L, w), spills + 1  # spread the overflow
            tight = tight or self._changed(S, new) <= TIGHT_SWITCH * len(S)
            x0 = self._carry(S, phi_S, new)
            S = new
        else:
            raise ProjectionError(f"active-set iterations did not terminate in {self.max_iterations}")
        self.active, self.phi_active = S, phi_S
        phi = np.zeros_like(b)
        phi[S] = phi_S
        rho = rho_tilde.copy()
        rho[L] -= Aphi / self.area[L]  # flux form: mass moves between cells or leaves by the exits
        info.update(iterations=iteration, unknowns=len(S))
        info["active_set"] = clock.lap() - info["setup"] - info["solve"]
        return rho, phi, info

    def _union(self, a, b):
        """Sorted union of two sets of cells, through the scratch mask: O(n) with a small constant,
        where np.union1d sorts (47 ms for 5 10^5 cells, 1 ms this way)."""
        self._mark[a] = True
        self._mark[b] = True
        union = np.flatnonzero(self._mark)
        self._mark[union] = False
        return union

    def _changed(self, S, new):
        """Number of cells in one of the sorted sets S and new but not in the other."""
        self._mark[S] = True
        kept = np.count_nonzero(self._mark[new])
        self._mark[S] = False
        return len(new) + len(S) - 2 * kept

    def _next(self, S, phi_S, w, strict, L, in_S, s_in_L):
        """The active-set update: S <- {phi >= 0 on S} U {w < 0 off S}, with w = b + A phi on L."""
        phi_L = np.zeros(len(L))
        phi_L[s_in_L] = phi_S
        # A cell of S with phi = 0 (and w = 0) solves the LCP whether it is in S or not; it
        # stays in S. Dropping it makes a closed saturated room cycle: its gauge cell has
        # phi = 0 exactly, leaves S, and re-enters on a round-off w < 0 the next iteration.
        stay = np.where(in_S, phi_L >= 0, w < -self.tol * self.area[L])
        self._mark[L] = True
        far = strict[~self._mark[strict]]
        self._mark[L] = False
        return self._union(L[stay], far) if far.size else L[stay]

    def _predict(self, b, strict, info):
        """Warm start from the kept factorisation: S and phi of this step, guessed without a new one.

        Alternating Schwarz on the complementarity problem between two overlapping sets of cells:
        - the factorised set G (the last S, but for the cells that were bordered):
          phi_G = A_GG^{-1} (-b - A phi_{off G})_G, one substitution with the kept factor;
        - the band B, the cells of S within FRONT_LAYERS layers of those in S outside G or next
          to a cell that left it: local active-set iterations S <- {phi >= 0 on S} U {w < 0 off S}
          (w = b + A phi, re-evaluated where phi changed), each followed by
          phi_B = A_BB^{-1} (-b - A phi_{off B})_B, a sparse Cholesky solve of a few thousand unknowns.
        The band solves carry the overflow of the cells that join to the cells it fills, many
        layers deep, where each exact iteration adds one layer; the solve on G then brings the far
        field. Only the guess changes: the exact iterations that follow decide.
        """
        A, factor, n = self.A, self.factor, len(b)
        G = factor.factorised()
        in_G = np.zeros(n, bool)
        in_G[G] = True
        inside = in_G.copy()  # S as a mask
        inside[strict] = True
        touched = strict      # every cell that has been in S outside G, or in G outside S
        phi = np.zeros(n)
        threshold = -self.tol * self.area
        for _ in range(PREDICTOR_ROUNDS + 1):
            phi[G] += factor.solve(G, -(b + A @ phi)[G])
            phi[~inside] = 0.0
            region, w = slice(None), b + A @ phi
            for _ in range(MAX_LOCAL):
                flips = np.where(inside[region], phi[region] < 0, w < threshold[region])
                flips = np.flatnonzero(flips) if isinstance(region, slice) else region[flips]
                if not flips.size:
                    break
                inside[flips] = ~inside[flips]
                phi[flips] = 0.0  # the cells that leave; those that join start from 0
                touched = self._distinct(np.concatenate([touched, flips]))
                band = self._band(touched[inside[touched] != in_G[touched]], inside)
                phi[band] += cholesky_solve(A[band][:, band], -(b[band] + A[band] @ phi),
                                            self.nested_dissection()[band])
                info["band_solves"] += 1
                region = self._distinct(A[band].indices)  # where w and the signs of phi can have changed
                w = b[region] + A[region] @ phi
        S = np.flatnonzero(inside)
        return S, phi[S]

    def _band(self, changed, inside):
        """The cells of S (mask inside) within FRONT_LAYERS layers of the cells `changed` (those in S
        outside G and the neighbours in S of those in G outside S), but the gauge cells of closed rooms."""
        near = np.concatenate([changed, self.adjacent[changed].ravel()])
        front = self._distinct(near[inside[near]])
        mark = self._mark
        mark[front] = True
        band = [front]
        for _ in range(FRONT_LAYERS):
            neighbours = self.adjacent[front].ravel()
            front = self._distinct(neighbours[inside[neighbours] & ~mark[neighbours]])
            mark[front] = True
            band.append(front)
        band = np.concatenate(band)
        mark[band] = False
        return band[~self.gauge[band]]

    def _distinct(self, cells):
        """The cells without repeats (in no particular order): O(len(cells)) through the scratch positions."""
        order = np.arange(len(cells))
        self._position[cells] = order
        return cells[self._position[cells] == order]

    def _update(self, S, phi_S, b, strict):
        """One active-set update from a given phi on S (no solve); returns the new S and phi on it."""
        rows = self.A[S]
        L, col, in_S, s_in_L = self._neighbourhood(rows, S)
        w = b[L] + _product(rows, col, len(L), phi_S)
        new = self._spill(S, self._next(S, phi_S, w, strict, L, in_S, s_in_L), b, L, w)
        return new, self._carry(S, phi_S, new)

    def _spill(self, S, new, b, L, w):
        """The next S guessed by spreading the overflow -w of the cells that join S, and the residual
        -w that the guessed phi leaves in S, outwards (divisible sandpile).

        A dense crowd running into the saturated zone moves its front by several cells per
        step, and an active-set iteration adds one layer of cells: each cell with an overflow
        passes it to its neighbours outside S in proportion to the transmissibilities (a cell
        with none, to its other neighbours), and those it overfills join too (a few sweeps).
        Only the guess of the next iteration changes; the active-set iteration after it
        decides (and drops any wrong cell).
        """
        level = b.copy()            # w of every cell with phi = 0 outside L
        level[L] = w
        inside = self._mark
        inside[S] = True
        joining = new[~inside[new]]
        inside[new] = True
        # the overflow of the cells that join, and what the guessed phi leaves in S: at a warm start,
        # the capacity that the cells that joined at the last step used up (their residual, all
        # within two layers of the front of S, matched the capacity of the cells that join next
        # to within 5 % on the benchmark hall)
        front = np.concatenate([joining, S[level[S] < -self.tol * self.area[S]]])
        added = [joining]
        for _ in range(SPILL_SWEEPS):
            front = front[level[front] < -self.tol * self.area[front]]
            if not front.size:
                break
            rows = self.A[front]
            row = np.repeat(np.arange(len(front)), np.diff(rows.indptr))
            neighbour = rows.indices != front[row]
            out = ~inside[rows.indices]
            # to the neighbours outside the set; a cell with none (second layer) passes to its others
            closed = np.bincount(row, out, len(front)) == 0
            receives = neighbour & (out | closed[row])
            weight = np.where(receives, -rows.data, 0.0)
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
        return self._union(new, grown) if grown.size else new

    def _carry(self, cells, values, new_cells):
        """values on `cells` moved to `new_cells` (0 on cells that are new): the initial guess."""
        self._scratch[cells] = values
        out = self._scratch[new_cells]
        self._scratch[cells] = 0.0
        return out

    def _neighbourhood(self, rows, S):
        """L = S and its neighbours (sorted), the position in L of every entry of rows, S as a mask on L,
        and the positions of S in L."""
        self._mark[rows.indices] = True
        self._mark[S] = True
        L = np.flatnonzero(self._mark)
        self._mark[L] = False
        self._position[L] = np.arange(len(L))
        col = self._position[rows.indices]
        s_in_L = self._position[S]
        in_S = np.zeros(len(L), bool)
        in_S[s_in_L] = True
        return L, col, in_S, s_in_L

    def _solve(self, rows, S, col, in_S, rhs, x0, info, tol):
        """Solve A_SS phi_S = rhs; returns phi_S and the mask of the cells of S whose equation holds.

        A closed room (a component of A's graph with no exit) that is entirely in S is fully
        saturated: A is singular there (pure Neumann) and the solution is fixed up to a
        constant. We pin its first cell (phi = 0), solve, then shift the room so that
        min phi = 0 (the gauge of the design note); the incompatibility of the data, pure
        round-off since the mass fits, lands in the pinned cell.
        """
        full = np.zeros(0, np.intp)
        if self.closed.any():
            inside = np.bincount(self.component[S], minlength=len(self.closed))
            full = np.flatnonzero(self.closed & (inside == self.component_size))
        keep = np.ones(len(S), bool)
        keep[np.searchsorted(S, self.first_cell[full])] = False
        x = np.zeros(len(S))
        if keep.any():
            def matrix():  # A on S[keep], for the AMG path only
                A_SS = _restriction(rows, col, in_S)
                return A_SS if keep.all() else A_SS[keep][:, keep]
            x[keep] = self._linear_solve(matrix, S[keep], rhs[keep], x0[keep], info, tol)
        if full.size:
            label = self.component[S]
            lowest = np.full(len(self.closed), np.inf)
            np.minimum.at(lowest, label, x)
            x -= np.where(np.isin(label, full), lowest[label], 0.0)
        return x, keep

    def _linear_solve(self, matrix, cells, rhs, x0, info, tol):
        """A_SS x = rhs on S = cells: factorised up to ``direct_max`` unknowns, else AMG + CG (on the
        matrix() builds) to the density tolerance tol from x0."""
        clock = _Clock()
        if len(cells) <= self.direct_max:
            factor = self.factor if self.reuse else None
            if factor is None or not factor.fits(cells):
                factor = self.factor = EnvelopeCholesky(self.A, self._envelope(cells), len(cells),
                                                         self.nested_dissection())
                info["rebuilds"] += 1
            info["factorizations"] += factor.prepare(cells)
            info["setup"] += clock.lap()
            x = factor.solve(cells, rhs)
            info["solve"] += clock.lap()
            return x
        # An AMG hierarchy is reused only on the same S: one built for an S that differs by 24
        # cells out of 3 10^5 (embedded, Jacobi on the new cells) took 29-37 CG iterations where
        # a new one took 11-16, and 500 changed cells took 54 instead of 5, more than the set-up
        # (~15 iterations) it saves.
        K = matrix()
        self.factor = None  # no longer the factorisation of the last S
        hierarchy = self.hierarchy if self.reuse else None
        if hierarchy is None or not np.array_equal(hierarchy.cells, cells):
            hierarchy = self.hierarchy = Hierarchy(K, cells)
            info["rebuilds"] += 1
            info["setup"] += clock.lap()
        x, its, ok = pcg(K, rhs, x0, hierarchy.vcycle, self._threshold(K, cells, tol), maxiter=500)
        info["solve"] += clock.lap()
        info["linear_iterations"] += its
        return x

    def nested_dissection(self):
        """Rank of every cell in a nested-dissection order of A's graph (METIS), computed on first use.

        Restricted to an envelope it orders that envelope's factorisation: the separators of the
        mesh, restricted to a subset of it, separate the subset. On the 5.4 10^5-cell saturated
        zone of the 10^6-triangle hall the numeric factorisation takes 0.41 s instead of 0.60 s
        in CHOLMOD's own order (AMD), and the symbolic analysis 0.15 s instead of 0.5 s; METIS
        takes ~5 s, once, for the 10^6 cells.
        """
        if self.order is None:
            graph = self.A.copy()
            graph.setdiag(0.0)
            graph.eliminate_zeros()
            _, rank = pymetis.nested_dissection(pymetis.CSRAdjacency(graph.indptr, graph.indices))
            self.order = np.asarray(rank, np.intp)
        return self.order

    def _envelope(self, cells):
        """`cells` and ENVELOPE_LAYERS layers of their neighbours (sorted): the index set of a factorisation."""
        mark = self._mark
        mark[cells] = True
        front = cells
        for _ in range(ENVELOPE_LAYERS):
            neighbours = self.A[front].indices
            front = np.unique(neighbours[~mark[neighbours]])
            mark[front] = True
        envelope = np.flatnonzero(mark)
        mark[envelope] = False
        return envelope

    def _threshold(self, K, cells, tol):
        """Per-row stopping test of CG: |r_K| <= tol |K|, or the round-off of (K x)_K."""
        area, floor = tol * self.area[cells], ROUNDOFF * K.diagonal()
        return lambda x: np.maximum(area, floor * max(float(np.abs(x).max()), 1e-300))


def _adjacency_table(A):
    """The neighbours of every cell in the graph of A, one row per cell, padded with the cell itself
    (a triangle has at most 3): the band search gathers them without building sparse row slices."""
    n = A.shape[0]
    row = np.repeat(np.arange(n), np.diff(A.indptr))
    off = (A.indices != row) & (A.data != 0)
    count = np.bincount(row[off], minlength=n)
    table = np.repeat(np.arange(n)[:, None], max(int(count.max(initial=0)), 1), axis=1)
    slot = np.arange(np.count_nonzero(off)) - np.repeat(np.cumsum(count) - count, count)
    table[row[off], slot] = A.indices[off]
    return table


def _restriction(rows, col, in_S):
    """A_SS as a CSR matrix from rows = A[S] (col: positions of its entries in L, in_S: S as a mask on L)."""
    m = len(rows.indptr) - 1
    inside = in_S[col]
    row = np.repeat(np.arange(m), np.diff(rows.indptr))
    count = np.bincount(row[inside], minlength=m)
    return sp.csr_matrix((rows.data[inside], (np.cumsum(in_S) - 1)[col[inside]],
                          np.concatenate([[0], np.cumsum(count)])), shape=(m, m))


def _product(rows, col, size, phi_S):
    """A phi on the neighbourhood L of S (positions col of the entries of rows = A[S] in L): A is
    symmetric, so (A phi)_j = sum_{i in S} A_ij phi_i; A phi = 0 off L."""
    return np.bincount(col, rows.data * np.repeat(phi_S, np.diff(rows.indptr)), size)


class _Clock:
    """Seconds since the last lap."""

    def __init__(self):
        self.last = time.perf_counter()

    def lap(self):
        now = time.perf_counter()
        elapsed, self.last = now - self.last, now
        return elapsed


def velocity_correction(domain, p):
    """-grad p per cell, reconstructed from the two-point fluxes G_e = T_e (p_K - p_L).

    For the lowest-order Raviart-Thomas field with facet fluxes G_e, the cell mean
    is (1/|K|) sum_e G_e (m_e - g_K) (m_e facet midpoint, g_K centroid).
    """
    k0, k1 = domain.f2t
    inner = domain.interior
    p_far = np.where(inner, p[np.where(inner, k1, 0)], 0.0)
    return cell_mean(domain, domain.transmissibility * (p[k0] - p_far))


def cell_mean(domain, G, G1=None):
    """Cell means (1/|K|) sum_e G_e (m_e - g_K) of the RT0 field with facet fluxes G (oriented k0 -> k1);
    G1, if given, is the flux seen from the cells f2t[1] (for a field that is discontinuous across facets)."""
    k0, k1 = domain.f2t
    inner = domain.interior
    G1 = G if G1 is None else G1
    out = np.zeros((domain.ncells, 2))
    for c in range(2):
        out[:, c] = np.bincount(k0, G * (domain.midpoint[:, c] - domain.centroid[k0, c]), domain.ncells)
        out[:, c] -= np.bincount(k1[inner], G1[inner] * (domain.midpoint[inner, c]
                                                        - domain.centroid[k1[inner], c]), domain.ncells)
    return out / domain.area[:, None]
