"""Direct solves of A_SS x = b on the saturated sets S of the projection, inside a fixed envelope of cells.

One symbolic analysis per envelope, one numeric factorisation per S, and none for an S
that grows by a few cells (bordering, a Schur complement on the new cells).
"""

import numpy as np

from .cholmod import Cholesky, lower_pattern
from .rows import rows as gather

#: a factorisation is replaced by a tighter one when S shrinks below SHRINK times the S it was made for
SHRINK = 0.6
#: an S that grows by at most this many cells from the factorised one is solved by bordering (a Schur
#: complement on the new cells: k + 1 forward and one backward substitution with the kept factor) instead
#: of a new numeric factorisation; beyond it bordering costs more (benchmarks/bordering.py,
#: docs/performance.md "Bordered solves")
BORDER_MAX = 8
#: from this many cells in the envelope a solve on the factorised S keeps its forward substitution L^{-1} P b, and
#: a bordered solve that follows with the same right-hand side on S_0 (the next active-set iteration of a step:
#: b does not change within a step) substitutes only the columns of B; below it a solve on S_0 is CHOLMOD's
#: solve in one call, as before (small runs unchanged bit for bit)
KEEP_FORWARD_MIN = 10_000


class EnvelopeCholesky:
    """Sparse Cholesky factorisation of A_SS for every S inside a fixed envelope E of cells.

    The matrix factorised is K = T A_EE T + diag(A_EE) (I - T), T = diag(1_S): A_SS on S and
    its diagonal elsewhere (so x = 0 off S). Its sparsity pattern is that of A_EE whatever S
    is, so the symbolic analysis (fill-reducing ordering, supernodes) is done once per
    envelope and a new S costs one numeric factorisation (CHOLMOD rather than SuperLU or an
    AMG set-up: docs/performance.md).

    An S that differs from the factorised S_0 by a few cells (the last stragglers of an
    active-set iteration: J joined, D left) is solved by bordering. The cells of D keep their
    rows of A_00 but x_D = 0 is imposed by a multiplier on their equations: with
    B = [A_{S_0 J} | E_D] (E_D the unit columns of D) and z = (x_J, multipliers),

        Sigma = diag(A_JJ, 0) - B^T A_00^{-1} B,   Sigma z = (b_J, 0) - B^T A_00^{-1} b_0,
        x_0 = A_00^{-1} (b_0 - B z)   (b_0 = 0 on D, and then x_D = 0),

    through the factor P A_00 P^T = L D L^T: |J| + |D| + 1 forward substitutions and one
    backward; |J| + |D| when the last solve on S_0 had the same b_0 (its L^{-1} P b_0 is kept, from
    KEEP_FORWARD_MIN cells; b_0 on D only changes the multipliers, so the same on S_0 minus D suffices).
    """

    def __init__(self, A, envelope, size, order=None):
        """envelope: the cells of E (sorted); size: |S| of the S that E was made around; order: rank
        of every cell in a fill-reducing order (None: CHOLMOD's own choice)."""
        self.A, self.cells, self.size = A, envelope, size
        self.position = np.full(A.shape[0], -1, np.intp)  # position of a cell in E (-1: not in E)
        self.position[envelope] = np.arange(len(envelope))
        self.row, self.col, self.values = lower_pattern(A[envelope][:, envelope])
        self.diagonal = self.row == self.col
        self.factor = Cholesky(self.row, self.col, len(envelope), None if order is None else order[envelope])
        self.active = None                 # positions of the factorised S in E
        self.mask = np.zeros(len(envelope), bool)  # the factorised S as a mask on E
        self.inverse_d = None              # D^{-1} of the factor (ones for a supernodal L L^T)
        self.forwarded = None              # (b_0, L^{-1} P b_0) of the last solve on the factorised S

    def fits(self, cells):
        """cells inside the envelope, and not fewer than SHRINK times the S it was made around
        (else a new, tighter one pays off)."""
        return len(cells) >= SHRINK * self.size and bool(np.all(self.position[cells] >= 0))

    def factorised(self):
        """The cells of the factorised S (sorted)."""
        return self.cells[self.active]

    def needs_factorisation(self, cells):
        """False when S = cells is the factorised S or differs from it by at most BORDER_MAX cells (joined
        or left)."""
        if self.active is None:
            return True
        kept = np.count_nonzero(self.mask[self.position[cells]])
        return (len(self.active) - kept) + (len(cells) - kept) > BORDER_MAX

    def prepare(self, cells):
        """Numeric factorisation of K for S = cells when needed; returns whether one was made."""
        if not self.needs_factorisation(cells):
            return False
        self.active = self.position[cells]
        self.mask[:] = False
        self.mask[self.active] = True
        keep = self.diagonal | (self.mask[self.row] & self.mask[self.col])
        self.factor.factorise(np.where(keep, self.values, 0.0))
        self.inverse_d = self.forwarded = None
        return True

    def solve(self, cells, rhs):
        """x on S = cells with A_SS x = rhs (after prepare(cells))."""
        at = self.position[cells]
        old = self.mask[at]
        self.mask[at] = False
        gone = self.mask[self.active]
        left = self.active[gone]   # D: factorised, no longer in S
        self.mask[at[old]] = True
        if old.all() and not left.size:
            return self._substitute(rhs)
        new = at[~old]
        rows = gather(self.A, self.cells[new])
        k, d = len(new), len(left)
        row = np.repeat(np.arange(k), np.diff(rows.indptr))
        position = self.position[rows.indices]
        coupled = (position >= 0) & self.mask[position]  # entries of C^T = A_{J S_0}
        j = np.minimum(np.searchsorted(new, position), k - 1)
        within = new[j] == position                       # entries of A_JJ
        sigma = np.zeros((k + d, k + d))
        np.add.at(sigma, (row[within], j[within]), rows.data[within])
        # b_0 on D only changes the multipliers: the kept forward serves if b_0 is the same on the cells still in S
        reuse = self.forwarded is not None and np.array_equal(self.forwarded[0][~gone], rhs[old])
        first = 0 if reuse else 1
        V = np.zeros((len(self.cells), first + k + d), order="F")  # [b_0 |] B, then L^{-1} P [b_0 |] B
        if not reuse:
            V[at[old], 0] = rhs[old]
        V[position[coupled], first + row[coupled]] = rows.data[coupled]
        V[left, first + k + np.arange(d)] = 1.0
        V = self._forward(V)
        y, V = (self.forwarded[1], V) if reuse else (V[:, 0], V[:, 1:])
        Dy, DV = self._inverse_d() * y, self._inverse_d()[:, None] * V
        sigma -= V.T @ DV
        z = np.linalg.solve(sigma, np.concatenate([rhs[~old], np.zeros(d)]) - V.T @ Dy)
        x = np.empty(len(at))
        x[~old] = z[:k]
        x[old] = self._backward(Dy - DV @ z)[at[old]]
        return x

    def _substitute(self, rhs):
        """K^{-1} b on the factorised S, for b = rhs there and 0 elsewhere (L^{-1} P b kept from KEEP_FORWARD_MIN
        cells)."""
        b = np.zeros(len(self.cells))
        b[self.active] = rhs
        if len(self.cells) < KEEP_FORWARD_MIN:
            return np.array(self.factor.solve(b)).ravel()[self.active]
        y = self._forward(b)
        self.forwarded = (np.array(rhs, float), y)
        return self._backward(self._inverse_d() * y)[self.active]

    def _inverse_d(self):
        """D^{-1} of the factor as a vector (computed once per factorisation)."""
        if self.inverse_d is None:
            self.inverse_d = np.array(self.factor.solve(np.ones(len(self.cells)), "D")).ravel()
        return self.inverse_d

    def _forward(self, b):
        """L^{-1} P b."""
        return np.array(self.factor.solve(self.factor.solve(b, "P"), "L")).reshape(b.shape, order="F")

    def _backward(self, y):
        """P^T L^{-T} y (y already scaled by D^{-1})."""
        return np.array(self.factor.solve(self.factor.solve(y, "Lt"), "Pt")).ravel()
