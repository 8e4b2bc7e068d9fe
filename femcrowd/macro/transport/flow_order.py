"""The cells in the order of the flow, and the solve of an upwind system in that order.

The graph of an upwind scheme has an edge K -> L when mass flows from K to L. Its strongly connected
components (Tarjan 1972, scipy.sparse.csgraph) taken in a topological order, the cells of each component
together, put every upwind system A = |K| I + tau (out - in) in block lower triangular form (Duff, Reid 1978,
"An implementation of Tarjan's algorithm for the block triangularization of a matrix"): the diagonal blocks
D are the cycles of the flow (a facet crossed both ways, a whirl), single cells elsewhere. With N = A - D
(the flows between blocks),

    A x = b   <=>   (I + D^{-1} N) x = D^{-1} b,

and I + D^{-1} N is unit lower triangular (a row of D^{-1} N mixes the rows of one block, whose entries lie
in earlier blocks): one substitution after inverting the small blocks. The order and the patterns depend only
on the flow directions, so they are built once per transport (per door state), the pattern of D^{-1} N and
the products of its entries included; a step only fills in the values (`_Substitution`). A cycle of more than
SMALL cells is solved by an LU of A in this fixed order (fill only in the rows and columns of the cyclic
blocks).
"""

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components

# SuperLU's triangular solve, the one spsolve_triangular (scipy >= 1.14) ends in. Called directly: the public
# wrapper builds an identity, sets the diagonal twice (a sorted search in every column) and checks the matrix at
# each call, 2.5 to 14 times the solve itself on a fixed pattern (docs/performance.md, "Small scenes").
# tests/macro/test_implicit_lwr.py checks that the two give the same solution bit for bit. A scipy without it
# (a private module may move) falls back on the public wrapper, which gives the same x.
try:
    from scipy.sparse.linalg._dsolve._superlu import gstrs
except ImportError:  # pragma: no cover - scipy's private layout changed
    gstrs = None

#: the largest cycle whose block is inverted as a dense matrix
SMALL = 16


class FlowOrder:
    """The block triangular order of the upwind systems of flows ``sender -> receiver`` between n cells."""

    def __init__(self, sender: np.ndarray, receiver: np.ndarray, n: int):
        graph = sp.csr_matrix((np.ones(len(sender)), (sender, receiver)), shape=(n, n))
        count, component = connected_components(graph, directed=True, connection="strong")
        across = component[sender] != component[receiver]
        level = levels(count, component[sender[across]], component[receiver[across]])[component]
        #: the cells in flow order: by level of their component, each component's cells together
        self.order = np.lexsort((component, level))
        self.acyclic = count == n
        self.n = n
        position = np.empty(n, np.intp)
        position[self.order] = np.arange(n)
        # the entries of A: the diagonal first, then one per flow (row: the receiver), in flow order
        rows = position[np.concatenate([np.arange(n), receiver])]
        cols = position[np.concatenate([np.arange(n), sender])]
        size = np.bincount(component)
        self.small = size.max() <= SMALL
        if not self.small:
            self._lu = _Pattern(rows, cols, n)
            return
        block = component[self.order]
        first = np.empty(count, np.intp)                 # each block's first position
        starts = np.flatnonzero(np.r_[True, block[1:] != block[:-1]])
        first[block[starts]] = starts
        self._inside = np.flatnonzero(np.r_[np.ones(n, bool), ~across])
        self._between = np.flatnonzero(np.r_[np.zeros(n, bool), across])
        row, col = rows[self._inside], cols[self._inside]
        start = first[block[row]]
        self._blocks = []                                # per block size s: (s, blocks, entries, their places)
        dense_rows, dense_cols = [], []
        for s in np.unique(size):
            which = np.flatnonzero(size == s)
            local = np.zeros(count, np.intp)
            local[which] = np.arange(len(which))
            entries = np.flatnonzero(size[block[row]] == s)
            place = (local[block[row[entries]]] * s + row[entries] - start[entries]) * s + col[entries] - start[entries]
            self._blocks.append((s, len(which), entries, place))
            cells = first[which][:, None] + np.arange(s)   # the positions of each block, row-major blocks
            dense_rows.append(np.repeat(cells, s, axis=1).ravel())
            dense_cols.append(np.tile(cells, s).ravel())
        self._substitution = _Substitution(np.concatenate(dense_rows), np.concatenate(dense_cols),
                                           rows[self._between], cols[self._between], n)

    def solve(self, diagonal: np.ndarray, flow: np.ndarray, b: np.ndarray) -> np.ndarray:
        """x of A x = b, A with ``diagonal`` on the diagonal and ``flow`` at (receiver, sender) of each flow."""
        values = np.concatenate([diagonal, flow])
        if not self.small:
            ordered = spla.splu(self._lu.matrix(values), permc_spec="NATURAL").solve(b[self.order])
        else:
            inside = values[self._inside]
            inverses = []
            for s, m, entries, place in self._blocks:
                dense = np.zeros(m * s * s)
                dense[place] = inside[entries]
                inverses.append(1.0 / dense if s == 1 else np.linalg.inv(dense.reshape(m, s, s)).ravel())
            ordered = self._substitution.solve(np.concatenate(inverses), values[self._between], b[self.order])
        x = np.empty_like(ordered)
        x[self.order] = ordered
        return x


class _Substitution:
    """(I + D^{-1} N) x = D^{-1} b on a fixed pattern: D^{-1} given by its entries at (inverse_rows, inverse_cols)
    (each row's columns increasing), N by its entries at (flow_rows, flow_cols), all in the flow order.

    The entries of D^{-1} N are sums of products D^{-1}_ik N_kj over the k of one block, taken in increasing k
    (as scipy's sparse product sums them), by one bincount over the pairs (ik, kj) found once. The substitution
    is SuperLU's gstrs with the factors L = I and U = I + (D^{-1} N)^T, transposed (trans "T"), U's strictly
    upper part stored column by column as the rows of D^{-1} N (its unit diagonal lies in L): each x_i is
    D^{-1} b_i minus the products of row i of D^{-1} N with the x before it, as spsolve_triangular computes it.
    """

    def __init__(self, inverse_rows, inverse_cols, flow_rows, flow_cols, n):
        by_row = np.argsort(flow_rows, kind="stable")
        start = np.concatenate([[0], np.cumsum(np.bincount(flow_rows, minlength=n))])
        count = start[inverse_cols + 1] - start[inverse_cols]   # the flows into the column's cell k
        inverse = np.repeat(np.arange(len(inverse_cols)), count)
        flow = by_row[np.repeat(start[inverse_cols] - np.cumsum(count) + count, count) + np.arange(count.sum())]
        key = inverse_rows[inverse] * n + flow_cols[flow]       # the entry (i, j) of D^{-1} N of each pair
        by_entry = np.lexsort((inverse_cols[inverse], key))
        self.inverse, self.flow = inverse[by_entry], flow[by_entry]
        entries, self.entry = np.unique(key[by_entry], return_inverse=True)
        self.indices = (entries % n).astype(np.intc)
        self.indptr = np.concatenate([[0], np.cumsum(np.bincount(entries // n, minlength=n))]).astype(np.intc)
        self.inverse_rows, self.inverse_cols, self.n = inverse_rows, inverse_cols, n
        self.unit = (np.ones(n), np.arange(n, dtype=np.intc), np.arange(n + 1, dtype=np.intc))   # L = I, CSC

    def solve(self, inverse: np.ndarray, flow: np.ndarray, b: np.ndarray) -> np.ndarray:
        """x for the entries of D^{-1} and N in the order of their rows and columns given at construction."""
        n = self.n
        scaled = np.bincount(self.entry, inverse[self.inverse] * flow[self.flow],
                             len(self.indices)).astype(float, copy=False)   # no flow between blocks: int64
        rhs = np.bincount(self.inverse_rows, inverse * b[self.inverse_cols], n)
        if gstrs is None:
            strict = sp.csr_matrix((scaled, self.indices, self.indptr), shape=(n, n))
            return spla.spsolve_triangular(strict + sp.identity(n, format="csr"), rhs, lower=True,
                                           unit_diagonal=True)
        x, info = gstrs("T", n, n, *self.unit, n, len(scaled), scaled, self.indices, self.indptr, rhs)
        assert info == 0   # a unit triangular matrix is never singular
        return x


class _Pattern:
    """A sparse pattern (rows, cols, no duplicates) in compressed sparse columns, filled with new values at each
    step."""

    def __init__(self, rows, cols, n):
        self.slot = np.lexsort((rows, cols))
        self.indices = rows[self.slot].astype(np.int32)
        self.indptr = np.concatenate([[0], np.cumsum(np.bincount(cols, minlength=n))]).astype(np.int32)
        self.n = n

    def matrix(self, values):
        return sp.csc_matrix((values[self.slot], self.indices, self.indptr), shape=(self.n, self.n))


def levels(n: int, sender: np.ndarray, receiver: np.ndarray) -> np.ndarray:
    """The level of each node of a directed acyclic graph: 0 without a predecessor, else one more than the
    largest of its predecessors' (Kahn 1962, removing one generation of sources at a time). Hand-written:
    scipy has no topological sort, and a generation at a time is a few array operations per level."""
    remaining = np.bincount(receiver, minlength=n)   # predecessors not yet placed
    by_sender = np.argsort(sender, kind="stable")
    start = np.concatenate([[0], np.cumsum(np.bincount(sender, minlength=n))])
    level = np.empty(n, np.intp)
    sources, k = np.flatnonzero(remaining == 0), 0
    while sources.size:
        level[sources] = k
        counts = start[sources + 1] - start[sources]
        first = np.repeat(start[sources] - np.cumsum(counts) + counts, counts)
        successors = receiver[by_sender[first + np.arange(counts.sum())]]
        remaining -= np.bincount(successors, minlength=n)
        sources, k = np.unique(successors[remaining[successors] == 0]), k + 1
    if np.any(remaining):
        raise ValueError("the graph has a cycle")
    return level
