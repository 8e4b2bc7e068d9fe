"""The cells in the order of the flow, and the solve of an upwind system in that order.

The graph of an upwind scheme has an edge K -> L when mass flows from K to L. Its strongly connected
components (Tarjan 1972, scipy.sparse.csgraph) taken in a topological order, the cells of each component
together, put every upwind system |K| I + tau (out - in) in block lower triangular form (Duff, Reid 1978,
"An implementation of Tarjan's algorithm for the block triangularization of a matrix"): the diagonal blocks
are the cycles of the flow (a facet crossed both ways, a whirl), single cells elsewhere. The order and the
pattern of the matrix depend only on the flow directions, so they are built once per transport (per door
state); a step only fills in the values. Acyclic flow: the matrix is lower triangular and the solve is one
substitution (SuperLU's triangular solve, spsolve_triangular). Otherwise an LU in this fixed order: fill only
in the rows and columns of the cyclic blocks, no fill-reducing ordering to compute.
"""

import numpy as np
import scipy.sparse as sp
import scipy.sparse.linalg as spla
from scipy.sparse.csgraph import connected_components


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
        position = np.empty(n, np.intp)
        position[self.order] = np.arange(n)
        # the CSC pattern of the ordered matrix with the diagonal first, then one entry per flow (row: receiver)
        rows = position[np.concatenate([np.arange(n), receiver])]
        cols = position[np.concatenate([np.arange(n), sender])]
        self._slot = np.lexsort((rows, cols))
        self._indices = rows[self._slot].astype(np.int32)
        self._indptr = np.concatenate([[0], np.cumsum(np.bincount(cols, minlength=n))]).astype(np.int32)
        self.n = n

    def solve(self, diagonal: np.ndarray, flow: np.ndarray, b: np.ndarray) -> np.ndarray:
        """x of A x = b, A with ``diagonal`` on the diagonal and ``flow`` at (receiver, sender) of each flow."""
        values = np.concatenate([diagonal, flow])[self._slot]
        matrix = sp.csc_matrix((values, self._indices, self._indptr), shape=(self.n, self.n))
        if self.acyclic:
            ordered = spla.spsolve_triangular(matrix, b[self.order], lower=True, overwrite_A=True, overwrite_b=True)
        else:
            ordered = spla.splu(matrix, permc_spec="NATURAL").solve(b[self.order])
        x = np.empty_like(ordered)
        x[self.order] = ordered
        return x


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
