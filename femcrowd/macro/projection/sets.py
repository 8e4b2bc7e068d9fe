"""Sets of cells as sorted index arrays, and the restrictions of A to them, in O(size) per operation.

Scratch arrays of the mesh size (a mask, positions, values), all reset after each use, replace
sorting and np.union1d, which sort the whole set at every operation (docs/performance.md).
"""

import numpy as np
import scipy.sparse as sp


class CellSets:
    """Set operations on the cells of one mesh through persistent scratch arrays."""

    def __init__(self, ncells: int):
        self.mark = np.zeros(ncells, bool)          # all False between uses
        self.position = np.zeros(ncells, np.intp)   # position of a cell in the current local set
        self.values = np.zeros(ncells)              # all 0 between uses

    def union(self, a, b):
        """Sorted union of two sets of cells."""
        self.mark[a] = True
        self.mark[b] = True
        union = np.flatnonzero(self.mark)
        self.mark[union] = False
        return union

    def changed(self, S, new):
        """Number of cells in one of the sets S and new but not in the other."""
        self.mark[S] = True
        kept = np.count_nonzero(self.mark[new])
        self.mark[S] = False
        return len(new) + len(S) - 2 * kept

    def distinct(self, cells):
        """The cells without repeats (in no particular order)."""
        order = np.arange(len(cells))
        self.position[cells] = order
        return cells[self.position[cells] == order]

    def carry(self, cells, values, new_cells):
        """values on `cells` moved to `new_cells` (0 on cells that are new): an initial guess."""
        self.values[cells] = values
        out = self.values[new_cells]
        self.values[cells] = 0.0
        return out

    def neighbourhood(self, rows, S):
        """L = S and its neighbours (sorted), the position in L of every entry of rows = A[S],
        S as a mask on L, and the positions of S in L."""
        self.mark[rows.indices] = True
        self.mark[S] = True
        L = np.flatnonzero(self.mark)
        self.mark[L] = False
        self.position[L] = np.arange(len(L))
        col = self.position[rows.indices]
        s_in_L = self.position[S]
        in_S = np.zeros(len(L), bool)
        in_S[s_in_L] = True
        return L, col, in_S, s_in_L


def adjacency_table(A):
    """The neighbours of every cell in the graph of A, one row per cell, padded with the cell itself
    (a triangle has at most 3): gathered without building sparse row slices."""
    n = A.shape[0]
    row = np.repeat(np.arange(n), np.diff(A.indptr))
    off = (A.indices != row) & (A.data != 0)
    count = np.bincount(row[off], minlength=n)
    table = np.repeat(np.arange(n)[:, None], max(int(count.max(initial=0)), 1), axis=1)
    slot = np.arange(np.count_nonzero(off)) - np.repeat(np.cumsum(count) - count, count)
    table[row[off], slot] = A.indices[off]
    return table


def restriction(rows, col, in_S):
    """A_SS as a CSR matrix from rows = A[S] (col: positions of its entries in L, in_S: S as a mask on L)."""
    m = len(rows.indptr) - 1
    inside = in_S[col]
    row = np.repeat(np.arange(m), np.diff(rows.indptr))
    count = np.bincount(row[inside], minlength=m)
    return sp.csr_matrix((rows.data[inside], (np.cumsum(in_S) - 1)[col[inside]],
                          np.concatenate([[0], np.cumsum(count)])), shape=(m, m))


def product(rows, col, size, phi_S):
    """A phi on the neighbourhood L of S (positions col of the entries of rows = A[S] in L): A is
    symmetric, so (A phi)_j = sum_{i in S} A_ij phi_i; A phi = 0 off L."""
    return np.bincount(col, rows.data * np.repeat(phi_S, np.diff(rows.indptr)), size)
