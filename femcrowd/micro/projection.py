"""Projection of the desired velocities on the feasible set (Maury 2014, eqs. 15-17).

Solves the sparse QP

    min_v 1/2 |v - U|^2   s.t.   B v <= d          (d = D / tau)

whose KKT system is Maury 2014, eq. (16): u + B^T lambda = U, B u <= d,
lambda >= 0, (B u - d) . lambda = 0.

``method="exact"`` (default):

1. Not jammed (fewer active contacts than discs in the warm start):
   semismooth Newton on the augmented Lagrangian (proximal method of
   multipliers), warm-started with the previous step's multipliers. For a
   multiplier estimate lambda, ``phi(v) = 1/2 |v - U|^2 + 1/(2 rho)
   |[lambda + rho (B v - d)]_+|^2`` is strongly convex and piecewise
   quadratic; its Newton matrix ``I + rho B_A^T B_A`` is symmetric positive
   definite whatever the rank of B_A. Exact piecewise line search;
   residuals and multipliers in increment form, so the KKT residual reaches
   round-off although rho is large; a multiplier drift along a self-stress
   (B^T dlambda = 0) is extrapolated to the first lambda_i = 0.
2. Jammed (hyperstatic and degenerate contacts, Maury 2014, Fig. 3), or
   when stage 1 needs more than ``max_fact`` factorisations: a primal-dual
   interior point, Mehrotra's predictor-corrector (1992) with Gondzio's
   centrality correctors (1996), on ``I + B^T diag(lambda / s) B``; it stops
   at strict feasibility and a certified relative objective gap (see
   :func:`_ipm`), or is polished to round-off by stage 1 when its last
   affine step nearly fits.

Both factorise matrices I + B^T diag(w) B of one sparsity pattern, whose
symbolic analysis a :class:`NewtonPattern` keeps between projections (sparse
Cholesky, CHOLMOD). Rows that the desired motion cannot reach are left out
of the solve and checked afterwards (added back if violated): the result is
the projection on the full candidate set.

``method="uzawa"``: Maury 2014, eq. (17), projected gradient on the dual
with a fixed step nu < 2 / ||B||^2, kept for comparison (slow in jams: its
rate degrades with cond(B B^T)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..linalg.cholmod import Cholesky
from .contacts import Constraints


@dataclass
class ProjectionResult:
    """u: velocities (N, 2); lam: multipliers (m,); kkt: max KKT residual
    (stationarity, feasibility, complementarity, in velocity units);
    iterations: Newton steps (exact) or Uzawa sweeps; factorizations: sparse
    Cholesky factorisations; converged: kkt <= requested tolerance."""

    u: np.ndarray
    lam: np.ndarray
    iterations: int
    factorizations: int
    kkt: float
    converged: bool
    method: str
    fallback: bool = False  # the interior point was needed (exact method)
    gap: float = 0.0     # certified relative objective gap (P(u) - D(lam)) / P(u); 0: exact to round-off
    change: float = 0.0  # max per-disc velocity change of one more (affine) interior-point step; 0: exact

    @property
    def active(self) -> int:
        return int(np.count_nonzero(self.lam > 0))


def kkt_residual(constraints: Constraints, U, d, u, lam) -> float:
    """max of |u + B^T lam - U|, |min(lam, d - B u)| (feasibility + complementarity)."""
    U = np.asarray(U, float)
    stat = np.abs(u + constraints.rmatvec(lam) - U).max() if constraints.N else 0.0
    if constraints.m == 0:
        return float(stat)
    nat = np.abs(np.minimum(lam, d - constraints.matvec(u))).max()
    return float(max(stat, nat))


def project(
    constraints: Constraints,
    U,
    d,
    *,
    method: str = "exact",
    lam0=None,
    tol: float = 1e-12,
    max_iter: int | None = None,
    rho: float = 1e4,
    nu: float | None = None,
    max_fact: int = 10,
    gap_tol: float = 1e-7,
    pattern: NewtonPattern | None = None,
) -> ProjectionResult:
    """Project U (N, 2) on {v : B v <= d} (Maury 2014, eqs. 15-16).

    tol is relative to max(1, max|U|); lam0 warm-starts the multipliers.
    method "exact": warm-started semismooth Newton, exact to round-off; in a
    jam (the warm start has at least as many active contacts as discs), or
    when the Newton iteration needs more than max_fact factorisations, an
    interior point method stopped at strict feasibility and a certified
    relative objective gap <= gap_tol (see :func:`_exact`).
    """
    U = np.asarray(U, dtype=float).reshape(constraints.N, 2)
    d = np.asarray(d, dtype=float).reshape(constraints.m)
    lam = np.zeros(constraints.m) if lam0 is None else np.maximum(np.asarray(lam0, float).reshape(constraints.m), 0.0)
    atol = tol * max(1.0, float(np.abs(U).max()) if constraints.N else 1.0)
    if method == "exact":
        solve = lambda rows, d_rows, lam_rows: _exact(rows, U, d_rows, lam_rows, atol, max_iter, rho,  # noqa: E731
                                                      max_fact, gap_tol, pattern)
    elif method == "uzawa":
        solve = lambda rows, d_rows, lam_rows: _uzawa(rows, U, d_rows, lam_rows, atol, max_iter or 100_000, nu)  # noqa: E731
    else:
        raise ValueError(f"unknown projection method {method!r} (exact, uzawa)")
    if constraints.m == 0:
        return solve(constraints, d, lam)
    # working set: rows that the desired motion can reach (|B_i v| <= |v_i| + |v_j|);
    # the others are checked afterwards and added if violated, so the result is the
    # projection on the full set.
    speed = np.sqrt((U * U).sum(1))
    reach = np.concatenate([speed[constraints.pi] + speed[constraints.pj], speed[constraints.wi]])
    working = (d <= 2.0 * reach + atol) | (lam > 0)
    total_iterations = total_factorizations = 0
    fallback = False
    lam_full = lam.copy()
    for _ in range(50):
        rows = constraints.subset(working) if not working.all() else constraints
        result = solve(rows, d[working], lam_full[working])
        total_iterations += result.iterations
        total_factorizations += result.factorizations
        fallback |= result.fallback
        lam_full = np.zeros(constraints.m)
        lam_full[np.flatnonzero(working)] = result.lam
        violated = ~working & (constraints.matvec(result.u) - d > atol)
        if not violated.any():
            break
        working = working | violated
    kkt = kkt_residual(constraints, U, d, result.u, lam_full)
    return ProjectionResult(result.u, lam_full, total_iterations, total_factorizations, kkt, kkt <= atol,
                            result.method, fallback, result.gap, result.change)


class NewtonPattern:
    """The kept symbolic analysis of the Newton matrices I + B^T diag(w) B.

    A pattern is a set of discs and of disc pairs (global indices); its fill-reducing order and
    supernodes are computed once and serve every projection whose rows fit in it: from step to step
    the contact network changes little, so the analysis is redone only when a working row falls
    outside (a new pair, a new disc) or when the discs are renumbered (:meth:`forget`).
    """

    def __init__(self):
        self.forget()

    def forget(self) -> None:
        """Drop the analysis (the discs renumbered otherwise than by :meth:`keep`: a restart)."""
        self.N, self.keys, self.fact, self.analyses = -1, None, None, 0

    def keep(self, kept) -> None:
        """The discs of the boolean mask `kept` stay, renumbered in order (the others left: exits);
        the slots of those that left stay in the pattern as identity blocks, so no new analysis."""
        kept = np.asarray(kept, bool)
        if self.keys is None or len(kept) != self.N:
            self.forget()
            return
        new = np.cumsum(kept) - 1
        a, b = self.keys // self.N, self.keys % self.N
        both = kept[a] & kept[b]
        self.N = int(kept.sum())
        self.keys = new[a[both]] * self.N + new[b[both]]
        self.off = self.off[both]
        self.discs = np.where(kept[np.maximum(self.discs, 0)] & (self.discs >= 0),
                              new[np.maximum(self.discs, 0)], -1)
        self.where = self.where[kept]

    def matrix(self, constraints: Constraints) -> _NewtonMatrix:
        """The Newton matrix of the rows of `constraints`, on the kept pattern if they fit in it."""
        lo, hi = np.minimum(constraints.pi, constraints.pj), np.maximum(constraints.pi, constraints.pj)
        keys = lo.astype(np.int64) * constraints.N + hi
        discs = np.unique(np.concatenate([constraints.pi, constraints.pj, constraints.wi]))
        if not (constraints.N == self.N and np.all(self.where[discs] >= 0) and _contains(self.keys, keys)):
            self._analyse(constraints.N, np.unique(keys), discs)
        return _NewtonMatrix(constraints, self, keys, len(discs))

    def _analyse(self, N, keys, discs):
        """Entries of the lower triangle: per disc its 2x2 diagonal block (xx, yx, yy), per pair the
        off-diagonal block of (higher, lower) disc; all distinct, sorted column-major for CHOLMOD."""
        n = len(discs)
        self.N, self.keys, self.discs, self.analyses = N, keys, discs, self.analyses + 1
        self.where = np.full(N, -1, dtype=np.intp)
        self.where[discs] = np.arange(n)
        a, b = self.where[keys // N], self.where[keys % N]          # a < b
        k = np.arange(n)
        rows = np.concatenate([2 * k, 2 * k + 1, 2 * k + 1, 2 * b, 2 * b + 1, 2 * b, 2 * b + 1])
        cols = np.concatenate([2 * k, 2 * k, 2 * k + 1, 2 * a, 2 * a, 2 * a + 1, 2 * a + 1])
        order = np.argsort(cols.astype(np.int64) * (2 * n) + rows, kind="stable")
        rank = np.empty_like(order)
        rank[order] = np.arange(len(order))
        self.diag = rank[: 3 * n].reshape(3, n).T                  # (n, 3) positions
        self.off = rank[3 * n:].reshape(4, -1).T                   # (pairs, 4) positions
        self.identity = np.zeros(len(order))                      # the I of I + B^T diag(w) B
        self.identity[self.diag[:, [0, 2]].ravel()] = 1.0
        self.entries = np.stack([rows[order], cols[order]])      # what the analysis was made of (a checkpoint)
        self.fact = Cholesky(rows[order], cols[order], 2 * n, supernodal=2, print=0) if n else None

    #: the arrays of a kept pattern (:meth:`state`)
    STATE = ("keys", "discs", "where", "diag", "off", "identity", "entries")

    def state(self) -> dict:
        """The kept analysis as arrays (a checkpoint): with :meth:`restore` a resumed run factorises in
        the same order as the uninterrupted one, hence the same round-off."""
        if self.keys is None:
            return {"N": -1}
        return {"N": self.N, "analyses": self.analyses, **{k: getattr(self, k) for k in self.STATE}}

    def restore(self, state: dict) -> None:
        """The analysis of :meth:`state` (made again from the same entries: CHOLMOD's analysis of one pattern
        is deterministic)."""
        self.forget()
        if int(state["N"]) < 0:
            return
        for k in self.STATE:
            setattr(self, k, np.array(state[k]))
        self.N, self.analyses = int(state["N"]), int(state["analyses"])
        rows, cols = self.entries
        n = len(self.diag)
        self.fact = Cholesky(rows, cols, 2 * n, supernodal=2, print=0) if n else None


def _contains(sorted_keys, keys) -> bool:
    """All keys are in the sorted array (None: no pattern yet)."""
    if sorted_keys is None or len(sorted_keys) == 0:
        return sorted_keys is not None and len(keys) == 0
    pos = np.minimum(np.searchsorted(sorted_keys, keys), len(sorted_keys) - 1)
    return bool(np.all(sorted_keys[pos] == keys))


class _NewtonMatrix:
    """I + B^T diag(w) B for the rows of `constraints`, on a pattern that holds them.

    Row i (pair a-b with normal c, or disc a against a wall with normal c) adds w_i c c^T to the
    diagonal blocks of its discs and -w_i c c^T to the off-diagonal block of the pair: the values
    of a factorisation are one weighted bincount over these contributions.
    """

    def __init__(self, constraints: Constraints, pattern: NewtonPattern, keys, touched: int):
        self.touched = touched   # discs that the rows touch
        slot_of = pattern.where
        pair = np.searchsorted(pattern.keys, keys)
        cp, cw = constraints.cp, constraints.cw
        block = lambda c: np.stack([c[:, 0] ** 2, c[:, 0] * c[:, 1], c[:, 1] ** 2], 1)  # noqa: E731
        pair_block, wall_block = block(cp), block(cw)
        off = np.stack([pair_block[:, 0], pair_block[:, 1], pair_block[:, 1], pair_block[:, 2]], 1)
        self.position = np.concatenate([pattern.diag[slot_of[constraints.pi]].ravel(),
                                        pattern.diag[slot_of[constraints.pj]].ravel(),
                                        pattern.diag[slot_of[constraints.wi]].ravel(), pattern.off[pair].ravel()])
        self.base = np.concatenate([pair_block.ravel(), pair_block.ravel(), wall_block.ravel(), -off.ravel()])
        rows = np.arange(constraints.m)
        self.row = np.concatenate([np.repeat(rows[: constraints.mp], 3), np.repeat(rows[: constraints.mp], 3),
                                   np.repeat(rows[constraints.mp:], 3), np.repeat(rows[: constraints.mp], 4)])
        self.identity = pattern.identity
        self.fact, self.slots = pattern.fact, len(pattern.discs)
        # the pattern's slots whose disc is still here (one that left holds -1), and those discs
        self.slot = np.flatnonzero(pattern.discs >= 0)
        self.disc = pattern.discs[self.slot]

    def factor(self, w):
        """Numeric factorisation of I + B^T diag(w) B (w: one weight per row)."""
        if self.fact is not None:
            w = np.asarray(w, float)
            self.fact.factorise(self.identity + np.bincount(self.position, self.base * w[self.row],
                                                            len(self.identity)))


def _psolve(newton, x):
    """Apply the factorised Newton matrix's inverse (identity off its discs)."""
    y = x.copy()
    if newton.fact is not None:
        packed = np.zeros((newton.slots, 2))
        packed[newton.slot] = x[newton.disc]
        y[newton.disc] = np.array(newton.fact.solve(packed.ravel())).reshape(-1, 2)[newton.slot]
    return y


def _line_search(v, U, delta, z, w, rho):
    """Exact minimiser in (0, 1] of the convex piecewise quadratic phi(v + a delta).

    phi'(a) = (v - U + a delta).delta + sum_i [z_i + a rho w_i]_+ w_i, w = B delta.
    """
    p0 = float(np.sum((v - U) * delta))
    p1 = float(np.sum(delta * delta))
    active0 = (z > 0) | ((z == 0) & (w > 0))
    C0 = p0 + float(np.dot(z[active0], w[active0]))
    C1 = p1 + rho * float(np.dot(w[active0], w[active0]))
    if C0 >= 0:  # not a descent direction (round-off level gradient)
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):   # w = 0 or tiny: no event
        t = -z / (rho * w)
    events = np.flatnonzero((t > 0) & (t < 1) & (w != 0))
    # derivative at a = 1
    z1 = z + rho * w
    active1 = z1 > 0
    if p0 + p1 + float(np.dot(z1[active1], w[active1])) <= 0:
        return 1.0
    if len(events) == 0:
        return min(1.0, -C0 / C1) if C1 > 0 else 1.0
    order = events[np.argsort(t[events], kind="stable")]
    t_events = t[order]
    sign = np.where(w[order] > 0, 1.0, -1.0)  # enter (w > 0) or leave (w < 0)
    c0 = np.concatenate([[C0], C0 + np.cumsum(sign * z[order] * w[order])])
    c1 = np.concatenate([[C1], C1 + np.cumsum(sign * rho * w[order] ** 2)])
    ends = np.concatenate([t_events, [1.0]])
    slope = c0 + ends * c1
    k = int(np.argmax(slope >= 0)) if np.any(slope >= 0) else len(slope) - 1
    if c1[k] <= 0:
        return float(ends[k])
    lo = 0.0 if k == 0 else float(t_events[k - 1])
    return float(min(max(-c0[k] / c1[k], lo), ends[k]))


class _MultiplierUpdate:
    """The multiplier update lam <- [z]_+ on the active rows A. When two successive increments are equal (an
    inconsistent active set: lam drifts along a self-stress, B^T dlam = 0, at rate rho * residual), it jumps
    along the drift to the first lam_i = 0."""

    def __init__(self):
        self.prev_step = None   # the last increment

    def __call__(self, lam, z, active):
        new = np.maximum(np.where(active, z, 0.0), 0.0)
        step = new - lam
        if self.prev_step is not None:
            change = np.abs(step - self.prev_step).max()
            size = np.abs(step).max()
            decreasing = step < 0
            if size > 0 and change <= 1e-3 * size and np.any(decreasing & (new > 0)):
                ratio = new[decreasing] / -step[decreasing]
                t = float(ratio.min())
                if t > 1.0:
                    new = np.maximum(new + t * step, 0.0)
                    new[np.flatnonzero(decreasing)[np.argmin(ratio)]] = 0.0
                    self.prev_step = None
                    return new
        self.prev_step = step
        return new


def _ssn_alm(constraints: Constraints, U, d, lam, atol, max_iter, rho, newton, max_fact=None):
    """Semismooth Newton / multiplier iterations in incremental (refinement) form.

    ``newton``: the :class:`_NewtonMatrix` of the rows of `constraints` (shared with the
    interior point and the polish).
    The residuals r1 = U - v - B^T lam and r2 = d - B v are evaluated without
    the factor rho, and the multipliers are updated by increments, so the
    result reaches round-off accuracy although rho is large (the large rho
    only makes each multiplier update contract by 1 / (1 + rho mu)).
    """
    m = constraints.m
    if m == 0:
        return ProjectionResult(U.copy(), lam, 0, 0, 0.0, True, "exact")
    scale = max(1.0, float(np.abs(U).max()), float(np.abs(d[np.isfinite(d)]).max(initial=0.0)))
    # |z| below eta is round-off (z = lam + rho (B v - d) carries rho * eps * |B v|)
    eta = 1e3 * rho * np.finfo(float).eps * scale
    gtol = min(0.5 * atol, max(1e-2 * atol, 1e-3 * eta))  # inner gradient at round-off
    if np.any(lam > 0):
        v = U - constraints.rmatvec(lam)
        forced = lam > 0
    else:
        v = U.copy()
        forced = None
    factored_rows = None
    factorizations = iterations = 0
    converged = False
    kkt = np.inf
    prev_newton_rows = None

    update = _MultiplierUpdate()

    while True:
        r1 = U - v - constraints.rmatvec(lam)
        r2 = d - constraints.matvec(v)
        kkt = max(np.abs(r1).max(), np.abs(np.minimum(lam, r2)).max())
        if kkt <= atol:
            converged = True
            break
        if iterations >= max_iter or (max_fact is not None and factorizations >= max_fact):
            break
        z = lam - rho * r2
        active = forced if forced is not None else z > 0
        # Newton matrix set: the active rows; a row whose z is round-off keeps its
        # previous status (both are generalised Hessians; flipping would zigzag)
        if forced is not None or prev_newton_rows is None:
            newton_rows = active
        else:
            newton_rows = (z > eta) | ((z > -eta) & prev_newton_rows)
        prev_newton_rows = newton_rows
        # Newton step for phi(.; lam): H_A delta = -grad phi = r1 + B^T(rho r2 on A, lam off A)
        rhs = r1 + constraints.rmatvec(np.where(active, rho * r2, lam))
        if np.abs(rhs).max() <= gtol and forced is None:
            # phi(.; lam) is minimised to round-off: multiplier update
            lam = update(lam, z, active)
            continue
        if factored_rows is None or forced is not None or not np.array_equal(newton_rows, factored_rows):
            newton.factor(rho * newton_rows)
            factorizations += 1
            factored_rows = newton_rows
        delta = _psolve(newton, rhs)
        iterations += 1
        if forced is None and np.abs(delta).max() <= 1e-2 * atol:
            # the Newton step is at round-off: phi(.; lam) is minimised, update lam
            lam = update(lam, z, active)
            continue
        w = constraints.matvec(delta)
        alpha = 1.0 if forced is not None else _line_search(v, U, delta, z, w, rho)
        forced = None
        if alpha <= 0.0:  # no descent left at round-off level: refactor exactly
            factored_rows = None
            continue
        v = v + alpha * delta
        r2_new = r2 - alpha * w  # incremental: d - B v_new
        z_new = lam - rho * r2_new
        new_active = z_new > 0
        if alpha == 1.0 and not np.any((new_active != active) & (np.abs(z_new) > eta)):
            # v minimises phi(.; lam) on this piece: multiplier update
            lam = update(lam, z_new, active)
    return ProjectionResult(v, lam, iterations, factorizations, float(kkt), converged, "exact")


def _exact(constraints: Constraints, U, d, lam, atol, max_iter, rho, max_fact, gap_tol, pattern):
    """Semismooth Newton (exact to round-off) unless the crowd is jammed; in a jam, or when the Newton
    iteration needs more than max_fact factorisations, the interior point (:func:`_ipm`), polished to
    round-off by the Newton iteration when its last affine step nearly fits (small, non-degenerate
    problems). One Newton-matrix pattern, kept by `pattern` between projections, serves every stage.
    """
    newton = (pattern or NewtonPattern()).matrix(constraints)
    jammed = np.count_nonzero(lam > 0) >= newton.touched > 0   # a hyperstatic contact network
    iterations = factorizations = 0
    if not jammed:
        result = _ssn_alm(constraints, U, d, lam, atol, max_iter or 200, rho, newton, max_fact=max_fact)
        if result.converged or constraints.m == 0:
            return result
        iterations, factorizations = result.iterations, result.factorizations
    ipm = _ipm(constraints, U, d, lam, atol, 80, newton, gap_tol)
    iterations, factorizations = iterations + ipm.iterations, factorizations + ipm.iterations + 1
    if ipm.affine_step >= 0.9:
        s = d - constraints.matvec(ipm.u)
        polished = _ssn_alm(constraints, U, d, np.where(ipm.lam > s, ipm.lam, 0.0), atol, max_iter or 60, rho,
                            newton, max_fact=max_fact)
        iterations, factorizations = iterations + polished.iterations, factorizations + polished.factorizations
        if polished.converged:
            return ProjectionResult(polished.u, polished.lam, iterations, factorizations, polished.kkt, True, "exact",
                                    fallback=True)
    s = d - constraints.matvec(ipm.u)
    lam_ipm = np.where(ipm.lam > s, ipm.lam, 0.0)   # the contacts the interior point holds active
    kkt = kkt_residual(constraints, U, d, ipm.u, lam_ipm)
    return ProjectionResult(ipm.u, lam_ipm, iterations, factorizations, kkt, kkt <= atol, "exact", fallback=True,
                            gap=ipm.gap, change=ipm.change)


@dataclass
class _IPMResult:
    u: np.ndarray
    lam: np.ndarray
    iterations: int
    gap: float          # certified relative objective gap at u, lam
    change: float       # max |a dv| per disc of the affine step from u
    affine_step: float  # its length a in (0, 1]


def _ipm(constraints: Constraints, U, d, lam0, atol, max_iter, newton, gap_tol):
    """Primal-dual interior point (Mehrotra 1992 predictor-corrector) for the QP, on the slack form
    B v + s = d, s >= 0, lam >= 0, lam s = mu.

    The Newton matrix I + B^T diag(lam / s) B keeps one sparsity pattern: one numeric factorisation per
    iteration, whatever the contacts (degenerate, hyperstatic jams included). It stops when v is strictly
    feasible (max(B v - d) <= 1e-12 max|U|) and the relative gap (P(v) - D(lam)) / P(v) <= gap_tol,
    where P(v) = 1/2 |v - U|^2 and D(lam) = lam.(B U - d) - 1/2 |B^T lam|^2 <= min P is the Lagrangian dual
    bound: the gap it reports bounds the true one.
    """
    m = constraints.m
    scale = max(1.0, float(np.abs(U).max()))
    feasible_tol = 1e-12 * scale
    floor = 1e-14 * 0.5 * float(np.sum(U * U))   # gap at round-off relative to 1/2 |U|^2 (v = U): 0
    BU_d = constraints.matvec(U) - d
    v = U.copy()
    # start well inside (s, lam >= 0.3 max|U|: nearer the boundary costs more iterations, measured)
    s = np.maximum(-BU_d, 0.3 * scale)
    lam = np.maximum(lam0, 0.3 * scale)

    def direction(rd, rp, rc):
        """Newton direction for v - U + B^T lam = rd, B v + s - d = rp, lam s = rc (residuals to cancel)."""
        dv = _psolve(newton, -rd - constraints.rmatvec((lam * rp - rc) / s))
        ds = -rp - constraints.matvec(dv)
        return dv, ds, (-rc - lam * ds) / s

    def step_length(ds, dl):
        """The largest a <= 1 with s + a ds >= 0 and lam + a dl >= 0."""
        x, dx = np.concatenate([s, lam]), np.concatenate([ds, dl])
        ratio = np.divide(-x, dx, out=np.full_like(x, np.inf), where=dx < 0)
        return min(1.0, float(ratio.min()))

    iterations, gap, last_change = 0, np.inf, np.inf
    while True:
        Bv, BTlam = constraints.matvec(v), constraints.rmatvec(lam)
        rd = v - U + BTlam
        rp = Bv + s - d
        mu = float(lam @ s) / m
        primal = 0.5 * float(np.sum((v - U) ** 2))
        dual = float(lam @ BU_d) - 0.5 * float(np.sum(BTlam ** 2))
        # (a tiny positive floor when U = 0: discs that stand still, a closed door, overlaps to undo; a gap
        # above 0 over it is inf, not converged)
        with np.errstate(over="ignore"):
            gap = 0.0 if primal - dual <= floor else (primal - dual) / max(primal, floor, np.finfo(float).tiny)
        feasible = float((Bv - d).max()) <= feasible_tol
        try:
            newton.factor(lam / s)
        except ArithmeticError:   # weights lam / s so large that round-off breaks the factorisation:
            return _IPMResult(v, lam, iterations, gap, last_change, 1.0)   # the active set is clear, polish it
        dv, ds, dl = direction(rd, rp, lam * s)          # affine (predictor) direction
        a = step_length(ds, dl)
        if (feasible and gap <= gap_tol) or iterations >= max_iter:
            change = a * float(np.sqrt((dv * dv).sum(1)).max()) if len(dv) else 0.0
            return _IPMResult(v, lam, iterations, gap, change, a)
        sigma_mu = (float((s + a * ds) @ (lam + a * dl)) / m / mu) ** 3 * mu
        rc = lam * s + ds * dl - sigma_mu                 # Mehrotra's corrector
        dv, ds, dl = direction(rd, rp, rc)
        a = step_length(ds, dl)
        for _ in range(2):                               # Gondzio's centrality correctors (1996)
            trial = min(1.0, 2.0 * a)  # aim at a longer step: push the products lam s into [0.1, 10] sigma mu
            prod = (s + trial * ds) * (lam + trial * dl)
            t = np.clip(prod, 0.1 * sigma_mu, 10.0 * sigma_mu) - prod
            t = np.maximum(t, -10.0 * sigma_mu)
            cv, cs, cl = direction(rd, rp, rc - t)
            ca = step_length(cs, cl)
            if ca < a + 0.1 * (trial - a):
                break
            rc, dv, ds, dl, a = rc - t, cv, cs, cl, ca
        a *= 0.995
        v = v + a * dv
        s = s + a * ds
        lam = lam + a * dl
        iterations += 1
        last_change = a * float(np.sqrt((dv * dv).sum(1)).max())


def _uzawa(constraints: Constraints, U, d, lam, atol, max_iter, nu):
    """Uzawa's projected gradient on the dual (Maury 2014, eq. 17) with the fixed step nu."""
    if constraints.m == 0:
        return ProjectionResult(U.copy(), lam, 0, 0, 0.0, True, "uzawa")
    if nu is None:
        nu = 1.9 / constraints.norm2_bound()  # 0 < nu < 2 / ||B||^2
    # work with the dual operator M = B B^T as a sparse matrix: one mat-vec per sweep
    B = constraints.to_csr()
    M = (B @ B.T).tocsr()
    c = B @ U.ravel() - d  # B u - d = c - M lam  for u = U - B^T lam
    iterations = 0
    converged = False
    check = 10
    while iterations < max_iter:
        for _ in range(check):
            residual = c - M @ lam  # = B u^{k+1} - d with u^{k+1} = U - B^T lam^k
            lam = np.maximum(lam + nu * residual, 0.0)
        iterations += check
        residual = c - M @ lam
        if np.abs(np.minimum(lam, -residual)).max() <= atol * 1e-2:
            u = U - constraints.rmatvec(lam)
            if kkt_residual(constraints, U, d, u, lam) <= atol:
                converged = True
                break
    u = U - constraints.rmatvec(lam)
    kkt = kkt_residual(constraints, U, d, u, lam)
    return ProjectionResult(u, lam, iterations, 0, kkt, converged, "uzawa")
