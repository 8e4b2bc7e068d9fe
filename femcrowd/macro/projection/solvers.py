"""The linear solves A_SS x = b of the active-set iterations, with the factorisations and AMG
hierarchies kept between iterations and steps.

Systems up to ``direct_max`` unknowns are factorised (sparse Cholesky on an envelope of S,
:class:`~femcrowd.linalg.envelope.EnvelopeCholesky`, in a nested-dissection order of the mesh
computed once); larger ones are solved by CG preconditioned with a Ruge-Stuben V-cycle, the
hierarchy kept while S is unchanged. Iterative solves stop when every cell's density is within
``tol`` of its target (|r_K| <= tol |K|) or at the round-off level of A phi, so the bound
rho <= 1 + tol holds whatever the conditioning. Measured choices: docs/performance.md.
"""


import signal

import numpy as np
import pymetis

from ...linalg.amg import Hierarchy, pcg
from ...linalg.envelope import EnvelopeCholesky
from ...linalg.rows import rows as gather
from ...timer import timed

#: layers of neighbours around S in the envelope of a factorisation (the front moves a few cells per step)
ENVELOPE_LAYERS = 8
#: round-off of (A phi)_K in units of eps * A_KK * max|phi| (floor of the iterative stopping test)
ROUNDOFF = 64 * np.finfo(float).eps


class CellOrder:
    """Rank of every cell in a nested-dissection order of the cells' adjacency (METIS; Karypis, Kumar 1998),
    computed on first use and shared by the projections of every set of open exits (A's graph is the
    mesh's: the exits only change its diagonal). Restricted to an envelope it orders that envelope's
    factorisation: the separators of the mesh, restricted to a subset of it, separate the subset.

    The door nodes of capacities (appended after the cells) are ranked just before the cell they let
    people out of: eliminating a leaf, or a node whose neighbours are already adjacent, makes no fill."""

    def __init__(self):
        self.rank = None

    def __call__(self, A, node_cell=None) -> np.ndarray:
        """The rank of the unknowns of A: its cells, then the door nodes of node_cell (None: none)."""
        ncells = A.shape[0] - (0 if node_cell is None else len(node_cell))
        if self.rank is None:
            graph = A[:ncells, :ncells] if node_cell is not None else A.copy()
            graph.setdiag(0.0)
            graph.eliminate_zeros()
            self.rank = np.asarray(metis_order(graph)[1], np.intp)
        if node_cell is None:
            return self.rank
        key = np.concatenate([2 * self.rank + 1, 2 * self.rank[node_cell]])
        rank = np.empty(len(key), np.intp)
        rank[np.argsort(key, kind="stable")] = np.arange(len(key))
        return rank


def metis_order(graph):
    """METIS's nested dissection of a graph (a CSR matrix's pattern): (permutation, rank).

    METIS traps SIGTERM while it runs (GKlib's error signal is SIGTERM), jumps out of its handler, which leaves
    the signal blocked in this thread, and returns an error: a kill, or a batch system's time limit, that falls
    in that window ended a run with "Caught an unknown exception!" instead of at the end of its step
    (driver/loop.py), and the signal was lost. So after an error the signal mask is restored, the ordering
    computed again and SIGTERM raised once more, for the handler that was there before METIS's (a METIS error of
    its own fails again and goes on to the caller)."""
    adjacency = pymetis.CSRAdjacency(graph.indptr, graph.indices)
    posix = hasattr(signal, "pthread_sigmask")
    mask = signal.pthread_sigmask(signal.SIG_BLOCK, []) if posix else None
    try:
        return pymetis.nested_dissection(adjacency)
    except RuntimeError:
        if posix:
            signal.pthread_sigmask(signal.SIG_SETMASK, mask)
        ordering = pymetis.nested_dissection(adjacency)
        signal.raise_signal(signal.SIGTERM)
        return ordering


class SaturatedSolver:
    """A_SS x = rhs on the saturated set S, with the kept EnvelopeCholesky or AMG Hierarchy."""

    def __init__(self, A, area, direct_max: int, order: CellOrder, sets, reuse: bool = True, node_cell=None):
        self.A, self.area, self.direct_max, self.order, self.sets, self.reuse = A, area, direct_max, order, sets, reuse
        self.node_cell = node_cell   # the cells of the door nodes (capacities), None without
        self.factor = None      # the kept EnvelopeCholesky
        self.hierarchy = None   # the kept Hierarchy
        self._rank = None

    def nested_dissection(self) -> np.ndarray:
        if self._rank is None:
            self._rank = self.order(self.A, self.node_cell)
        return self._rank

    def solve(self, matrix, cells, rhs, x0, info, tol):
        """A_SS x = rhs on S = cells: factorised up to ``direct_max`` unknowns, else AMG + CG (on the
        matrix that matrix() builds) to the density tolerance tol from x0. Counts in info."""
        if len(cells) <= self.direct_max:
            with timed(info, "setup"):
                factor = self.factor if self.reuse else None
                if factor is None or not factor.fits(cells):
                    factor = self.factor = EnvelopeCholesky(self.A, self.envelope(cells), len(cells),
                                                             self.nested_dissection())
                    info["rebuilds"] += 1
                info["factorizations"] += factor.prepare(cells)
            with timed(info, "solve"):
                return factor.solve(cells, rhs)
        # An AMG hierarchy is reused only on the same S: one built for a slightly different S
        # took more CG iterations than its set-up saves (docs/performance.md).
        with timed(info, "setup"):
            K = matrix()
            self.factor = None  # no longer the factorisation of the last S
            hierarchy = self.hierarchy if self.reuse else None
            if hierarchy is None or not np.array_equal(hierarchy.cells, cells):
                hierarchy = self.hierarchy = Hierarchy(K, cells)
                info["rebuilds"] += 1
        with timed(info, "solve"):
            x, its, _ = pcg(K, rhs, x0, hierarchy.vcycle, self._threshold(K, cells, tol), maxiter=500)
        info["linear_iterations"] += its
        return x

    def envelope(self, cells):
        """`cells` and ENVELOPE_LAYERS layers of their neighbours (sorted): the index set of a factorisation."""
        mark = self.sets.mark
        mark[cells] = True
        front = cells
        for _ in range(ENVELOPE_LAYERS):
            neighbours = gather(self.A, front).indices
            front = np.unique(neighbours[~mark[neighbours]])
            mark[front] = True
        envelope = np.flatnonzero(mark)
        mark[envelope] = False
        return envelope

    def _threshold(self, K, cells, tol):
        """Per-row stopping test of CG: |r_K| <= tol |K|, or the round-off of (K x)_K."""
        area, floor = tol * self.area[cells], ROUNDOFF * K.diagonal()
        return lambda x: np.maximum(area, floor * max(float(np.abs(x).max()), 1e-300))
