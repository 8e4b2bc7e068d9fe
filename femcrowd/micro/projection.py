"""Projection of the desired velocities on the feasible set (seed 000 eqs. 15-17).

Solves the sparse QP

    min_v 1/2 |v - U|^2   s.t.   B v <= d          (d = D / tau)

whose KKT system is seed 000 eq. (16): u + B^T lambda = U, B u <= d,
lambda >= 0, (B u - d) . lambda = 0.

``method="exact"`` (default), three stages, all exact up to round-off:

1. Semismooth Newton on the augmented Lagrangian (proximal method of
   multipliers), warm-started with the previous step's multipliers. For a
   multiplier estimate lambda, ``phi(v) = 1/2 |v - U|^2 + 1/(2 rho)
   |[lambda + rho (B v - d)]_+|^2`` is strongly convex and piecewise
   quadratic; its Newton matrix ``I + rho B_A^T B_A`` (A = {lambda + rho
   (B v - d) > 0}) is symmetric positive definite *whatever the rank of B_A*
   (jams with more contacts than degrees of freedom, seed 000 Fig. 3, make
   B B^T singular). Exact piecewise line search; multiplier update when phi
   is minimised; residuals and multipliers are updated in increment form so
   the KKT residual reaches round-off although rho is large; when an
   inconsistent (hyperstatic) active set makes lambda drift along a
   self-stress (B^T dlambda = 0), the drift is extrapolated to the first
   lambda_i = 0. Sparse Cholesky (CHOLMOD); the pattern is that of all the
   working rows, analysed once per projection and shared by the three
   stages; only discs touched by these rows enter the matrix.
2. If stage 1 needs more than ``max_fact`` factorisations (many contacts
   changing at once: a crowd compacting), a primal-dual interior point
   method (Mehrotra) finds the active set in ~20-35 factorisations of
   ``I + B^T diag(lambda / s) B`` (one pattern).
3. Stage 1 again from the interior-point active set (polish).

Rows that the desired motion cannot reach are left out of the solve and
checked afterwards (added back if violated): the result is the projection
on the full candidate set.

``method="uzawa"``: seed 000 eq. (17), projected gradient on the dual with
a fixed step nu < 2 / ||B||^2, kept for comparison (slow in jams: its rate
degrades with cond(B B^T)).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..linalg.cholmod import Cholesky
from .contacts import Constraints

__all__ = ["ProjectionResult", "project", "kkt_residual"]


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


def kkt_residual(C: Constraints, U, d, u, lam) -> float:
    """max of |u + B^T lam - U|, |min(lam, d - B u)| (feasibility + complementarity)."""
    U = np.asarray(U, float)
    stat = np.abs(u + C.rmatvec(lam) - U).max() if C.N else 0.0
    if C.m == 0:
        return float(stat)
    nat = np.abs(np.minimum(lam, d - C.matvec(u))).max()
    return float(max(stat, nat))


def project(
    C: Constraints,
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
) -> ProjectionResult:
    """Project U (N, 2) on {v : B v <= d} (seed 000 eq. 15-16).

    tol is relative to max(1, max|U|); lam0 warm-starts the multipliers.
    method "exact": warm-started semismooth Newton, exact to round-off; in a
    jam (the warm start has at least as many active contacts as discs), or
    when the Newton iteration needs more than max_fact factorisations, an
    interior point method stopped at strict feasibility and a certified
    relative objective gap <= gap_tol (see :func:`_exact`).
    """
    U = np.asarray(U, dtype=float).reshape(C.N, 2)
    d = np.asarray(d, dtype=float).reshape(C.m)
    lam = np.zeros(C.m) if lam0 is None else np.maximum(np.asarray(lam0, float).reshape(C.m), 0.0)
    atol = tol * max(1.0, float(np.abs(U).max()) if C.N else 1.0)
    if method == "exact":
        solve = lambda Cw, dw, lw: _exact(Cw, U, dw, lw, atol, max_iter, rho, max_fact, gap_tol)  # noqa: E731
    elif method == "uzawa":
        solve = lambda Cw, dw, lw: _uzawa(Cw, U, dw, lw, atol, max_iter or 100_000, nu)  # noqa: E731
    else:
        raise ValueError(f"unknown projection method {method!r} (exact, uzawa)")
    if C.m == 0:
        return solve(C, d, lam)
    # working set: rows that the desired motion can reach (|B_i v| <= |v_i| + |v_j|);
    # the others are checked afterwards and added if violated, so the result is the
    # projection on the full set.
    speed = np.sqrt((U * U).sum(1))
    reach = np.concatenate([speed[C.pi] + speed[C.pj], speed[C.wi]])
    W = (d <= 2.0 * reach + atol) | (lam > 0)
    total_it = total_fact = 0
    fallback = False
    lam_full = lam.copy()
    for _ in range(50):
        Cw = C.subset(W) if not W.all() else C
        res = solve(Cw, d[W], lam_full[W])
        total_it += res.iterations
        total_fact += res.factorizations
        fallback |= res.fallback
        lam_full = np.zeros(C.m)
        lam_full[np.flatnonzero(W)] = res.lam
        viol = ~W & (C.matvec(res.u) - d > atol)
        if not viol.any():
            break
        W = W | viol
    kkt = kkt_residual(C, U, d, res.u, lam_full)
    return ProjectionResult(res.u, lam_full, total_it, total_fact, kkt, kkt <= atol, res.method, fallback,
                            res.gap, res.change)


# --------------------------------------------------------------------------
# exact: semismooth Newton augmented Lagrangian
# --------------------------------------------------------------------------


class _NewtonMatrix:
    """I + B^T diag(w) B for row weights w >= 0 supported in a row superset S.

    The pattern is that of S (symbolic factorisation once); rows of S with
    w = 0 keep their place in the pattern, so a new active set (w = rho on A,
    semismooth Newton) or new barrier weights (w = lambda / s, interior point)
    cost one numeric factorisation only.
    """

    def __init__(self, C: Constraints, S):
        rs = np.flatnonzero(S)
        p = rs[rs < C.mp]
        wr = rs[rs >= C.mp] - C.mp
        pi, pj, cp = C.pi[p], C.pj[p], C.cp[p]
        wi, cw = C.wi[wr], C.cw[wr]
        discs = np.unique(np.concatenate([pi, pj, wi]))
        n = len(discs)
        idx = np.full(C.N, -1, dtype=np.intp)
        idx[discs] = np.arange(n)
        a, b, w = idx[pi], idx[pj], idx[wi]
        nodes = np.concatenate([a, b, w])
        src_d = np.concatenate([p, p, C.mp + wr])
        c = np.concatenate([cp, cp, cw])
        hi, lo = np.maximum(a, b), np.minimum(a, b)
        k = np.arange(n)
        rows = np.concatenate(
            [2 * nodes, 2 * nodes + 1, 2 * nodes + 1, 2 * hi, 2 * hi, 2 * hi + 1, 2 * hi + 1, 2 * k, 2 * k + 1])
        cols = np.concatenate(
            [2 * nodes, 2 * nodes, 2 * nodes + 1, 2 * lo, 2 * lo + 1, 2 * lo, 2 * lo + 1, 2 * k, 2 * k + 1])
        self.base = np.concatenate(
            [c[:, 0] ** 2, c[:, 0] * c[:, 1], c[:, 1] ** 2,
             -cp[:, 0] ** 2, -cp[:, 0] * cp[:, 1], -cp[:, 0] * cp[:, 1], -cp[:, 1] ** 2,
             np.ones(2 * n)])
        self.src = np.concatenate([src_d, src_d, src_d, p, p, p, p, np.full(2 * n, -1)])
        self.discs = discs
        # entries in compressed-column order, duplicates summed (rows of several contacts meet)
        entry, self.entry_of = np.unique(cols.astype(np.int64) * (2 * n) + rows, return_inverse=True)
        self.entries = len(entry)
        self.fact = Cholesky(entry % (2 * n), entry // (2 * n), 2 * n, supernodal=2, print=0) if n else None

    def factor(self, w):
        """Numeric factorisation of I + B^T diag(w) B (w: one weight per row)."""
        if self.fact is not None:
            wts = np.where(self.src >= 0, np.asarray(w, float)[np.maximum(self.src, 0)], 1.0)
            self.fact.factorise(np.bincount(self.entry_of, self.base * wts, self.entries))


def _psolve(fact, discs, x):
    """Apply the factorised Newton matrix's inverse (identity off its discs)."""
    if fact is None or len(discs) == 0:
        return x.copy()
    y = x.copy()
    y[discs] = np.array(fact.solve(x[discs].ravel())).reshape(-1, 2)
    return y


def _line_search(v, U, delta, z, w, rho):
    """Exact minimiser in (0, 1] of the convex piecewise quadratic phi(v + a delta).

    phi'(a) = (v - U + a delta).delta + sum_i [z_i + a rho w_i]_+ w_i, w = B delta.
    """
    p0 = float(np.sum((v - U) * delta))
    p1 = float(np.sum(delta * delta))
    act0 = (z > 0) | ((z == 0) & (w > 0))
    C0 = p0 + float(np.dot(z[act0], w[act0]))
    C1 = p1 + rho * float(np.dot(w[act0], w[act0]))
    if C0 >= 0:  # not a descent direction (round-off level gradient)
        return 0.0
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -z / (rho * w)
    ev = np.flatnonzero((t > 0) & (t < 1) & (w != 0))
    # derivative at a = 1
    z1 = z + rho * w
    a1 = z1 > 0
    if p0 + p1 + float(np.dot(z1[a1], w[a1])) <= 0:
        return 1.0
    if len(ev) == 0:
        return min(1.0, -C0 / C1) if C1 > 0 else 1.0
    o = ev[np.argsort(t[ev], kind="stable")]
    te = t[o]
    sgn = np.where(w[o] > 0, 1.0, -1.0)  # enter (w > 0) or leave (w < 0)
    c0 = np.concatenate([[C0], C0 + np.cumsum(sgn * z[o] * w[o])])
    c1 = np.concatenate([[C1], C1 + np.cumsum(sgn * rho * w[o] ** 2)])
    ends = np.concatenate([te, [1.0]])
    val = c0 + ends * c1
    k = int(np.argmax(val >= 0)) if np.any(val >= 0) else len(val) - 1
    if c1[k] <= 0:
        return float(ends[k])
    lo = 0.0 if k == 0 else float(te[k - 1])
    return float(min(max(-c0[k] / c1[k], lo), ends[k]))


def _ssn_alm(C: Constraints, U, d, lam, atol, max_iter, rho, newton, max_fact=None):
    """Semismooth Newton / multiplier iterations in incremental (refinement) form.

    ``newton``: the :class:`_NewtonMatrix` of all rows of C (shared with the
    interior point, so its symbolic analysis is done once per projection).
    The residuals r1 = U - v - B^T lam and r2 = d - B v are evaluated without
    the factor rho, and the multipliers are updated by increments, so the
    result reaches round-off accuracy although rho is large (the large rho
    only makes each multiplier update contract by 1 / (1 + rho mu)).
    """
    m = C.m
    if m == 0:
        return ProjectionResult(U.copy(), lam, 0, 0, 0.0, True, "exact")
    scale = max(1.0, float(np.abs(U).max()), float(np.abs(d[np.isfinite(d)]).max(initial=0.0)))
    # |z| below eta is round-off (z = lam + rho (B v - d) carries rho * eps * |B v|)
    eta = 1e3 * rho * np.finfo(float).eps * scale
    gtol = min(0.5 * atol, max(1e-2 * atol, 1e-3 * eta))  # inner gradient at round-off
    if np.any(lam > 0):
        v = U - C.rmatvec(lam)
        forced = lam > 0
    else:
        v = U.copy()
        forced = None
    fact = fact_act = discs = None
    nfact = it = 0
    converged = False
    kkt = np.inf
    prev_step = None  # last multiplier increment (drift detection)
    hprev = None

    def update(lam, z, act):
        """Multiplier update lam <- [z]_+ on A; when two successive increments are
        equal (inconsistent active set: lam drifts along a self-stress, B^T dlam = 0,
        at rate rho * residual), jump along the drift to the first lam_i = 0."""
        nonlocal prev_step
        new = np.maximum(np.where(act, z, 0.0), 0.0)
        step = new - lam
        if prev_step is not None:
            ds = np.abs(step - prev_step).max()
            sm = np.abs(step).max()
            dec = step < 0
            if sm > 0 and ds <= 1e-3 * sm and np.any(dec & (new > 0)):
                ratio = new[dec] / -step[dec]
                t = float(ratio.min())
                if t > 1.0:
                    new = np.maximum(new + t * step, 0.0)
                    new[np.flatnonzero(dec)[np.argmin(ratio)]] = 0.0
                    prev_step = None
                    return new
        prev_step = step
        return new

    while True:
        r1 = U - v - C.rmatvec(lam)
        r2 = d - C.matvec(v)
        kkt = max(np.abs(r1).max(), np.abs(np.minimum(lam, r2)).max())
        if kkt <= atol:
            converged = True
            break
        if it >= max_iter or (max_fact is not None and nfact >= max_fact):
            break
        z = lam - rho * r2
        act = forced if forced is not None else z > 0
        # Newton matrix set: the active rows; a row whose z is round-off keeps its
        # previous status (both are generalised Hessians; flipping would zigzag)
        if forced is not None or hprev is None:
            hact = act
        else:
            hact = (z > eta) | ((z > -eta) & hprev)
        hprev = hact
        # Newton step for phi(.; lam): H_A delta = -grad phi = r1 + B^T(rho r2 on A, lam off A)
        rhs = r1 + C.rmatvec(np.where(act, rho * r2, lam))
        if np.abs(rhs).max() <= gtol and forced is None:
            # phi(.; lam) is minimised to round-off: multiplier update
            lam = update(lam, z, act)
            continue
        delta = None
        if delta is None:
            if fact_act is None or forced is not None or not np.array_equal(hact, fact_act):
                newton.factor(rho * hact)
                fact, discs = newton.fact, newton.discs
                nfact += 1
                fact_act = hact
            delta = _psolve(fact, discs, rhs)
        it += 1
        if forced is None and np.abs(delta).max() <= 1e-2 * atol:
            # the Newton step is at round-off: phi(.; lam) is minimised, update lam
            lam = update(lam, z, act)
            continue
        w = C.matvec(delta)
        alpha = 1.0 if forced is not None else _line_search(v, U, delta, z, w, rho)
        forced = None
        if alpha <= 0.0:  # no descent left at round-off level: refactor exactly
            fact_act = None
            continue
        v = v + alpha * delta
        r2n = r2 - alpha * w  # incremental: d - B v_new
        zn = lam - rho * r2n
        new_act = zn > 0
        if alpha == 1.0 and not np.any((new_act != act) & (np.abs(zn) > eta)):
            # v minimises phi(.; lam) on this piece: multiplier update
            lam = update(lam, zn, act)
    return ProjectionResult(v, lam, it, nfact, float(kkt), converged, "exact")


def _exact(C: Constraints, U, d, lam, atol, max_iter, rho, max_fact, gap_tol):
    """Semismooth Newton (exact to round-off) unless the crowd is jammed; in a jam, or when the Newton
    iteration needs more than max_fact factorisations, the interior point (:func:`_ipm`), polished to
    round-off by the Newton iteration when its last affine step nearly fits (small, non-degenerate
    problems). One Newton-matrix pattern (all rows of C) serves every stage.
    """
    newton = _NewtonMatrix(C, np.ones(C.m, bool))
    jammed = np.count_nonzero(lam > 0) >= len(newton.discs) > 0   # a hyperstatic contact network
    nit = nfact = 0
    if not jammed:
        res = _ssn_alm(C, U, d, lam, atol, max_iter or 200, rho, newton, max_fact=max_fact)
        if res.converged or C.m == 0:
            return res
        nit, nfact = res.iterations, res.factorizations
    ipm = _ipm(C, U, d, lam, atol, 80, newton, gap_tol)
    nit, nfact = nit + ipm.iterations, nfact + ipm.iterations + 1
    if ipm.affine_step >= 0.9:
        s = d - C.matvec(ipm.u)
        pol = _ssn_alm(C, U, d, np.where(ipm.lam > s, ipm.lam, 0.0), atol, max_iter or 60, rho, newton,
                       max_fact=max_fact)
        nit, nfact = nit + pol.iterations, nfact + pol.factorizations
        if pol.converged:
            return ProjectionResult(pol.u, pol.lam, nit, nfact, pol.kkt, True, "exact", fallback=True)
    s = d - C.matvec(ipm.u)
    lam_ipm = np.where(ipm.lam > s, ipm.lam, 0.0)   # the contacts the interior point holds active
    kkt = kkt_residual(C, U, d, ipm.u, lam_ipm)
    return ProjectionResult(ipm.u, lam_ipm, nit, nfact, kkt, kkt <= atol, "exact", fallback=True,
                            gap=ipm.gap, change=ipm.change)


@dataclass
class _IPMResult:
    u: np.ndarray
    lam: np.ndarray
    iterations: int
    gap: float          # certified relative objective gap at u, lam
    change: float       # max |a dv| per disc of the affine step from u
    affine_step: float  # its length a in (0, 1]


def _ipm(C: Constraints, U, d, lam0, atol, max_iter, newton, gap_tol):
    """Primal-dual interior point (Mehrotra 1992 predictor-corrector) for the QP, on the slack form
    B v + s = d, s >= 0, lam >= 0, lam s = mu.

    The Newton matrix I + B^T diag(lam / s) B keeps one sparsity pattern: one numeric factorisation per
    iteration, whatever the contacts (degenerate, hyperstatic jams included). It stops when v is strictly
    feasible (max(B v - d) <= 1e-12 max|U|) and the relative gap (P(v) - D(lam)) / P(v) <= gap_tol,
    where P(v) = 1/2 |v - U|^2 and D(lam) = lam.(B U - d) - 1/2 |B^T lam|^2 <= min P is the Lagrangian dual
    bound: the gap it reports bounds the true one.
    """
    m = C.m
    scale = max(1.0, float(np.abs(U).max()))
    feasible_tol = 1e-12 * scale
    BU_d = C.matvec(U) - d
    v = U.copy()
    s = np.maximum(-BU_d, 1e-2 * scale)
    lam = np.maximum(lam0, 1e-2 * scale)

    def direction(rd, rp, rc):
        rhs = -rd - C.rmatvec((-rc + lam * rp) / s)
        dv = _psolve(newton.fact, newton.discs, rhs)
        ds = -rp - C.matvec(dv)
        return dv, ds, (-rc - lam * ds) / s

    def max_step(x, dx):
        neg = dx < 0
        return min(1.0, float((-x[neg] / dx[neg]).min())) if neg.any() else 1.0

    it, gap, last_change = 0, np.inf, np.inf
    while True:
        rd = v - U + C.rmatvec(lam)
        rp = C.matvec(v) + s - d
        mu = float(lam @ s) / m
        primal = 0.5 * float(np.sum((v - U) ** 2))
        dual = float(lam @ BU_d) - 0.5 * float(np.sum(C.rmatvec(lam) ** 2))
        # at round-off relative to 1/2 |U|^2 the gap is 0 (v = U: nothing to project)
        floor = 1e-14 * 0.5 * float(np.sum(U * U))
        gap = 0.0 if primal - dual <= floor else (primal - dual) / max(primal, floor)
        feasible = float((C.matvec(v) - d).max()) <= feasible_tol
        try:
            newton.factor(lam / s)
        except ArithmeticError:   # weights lam / s so large that round-off breaks the factorisation:
            return _IPMResult(v, lam, it, gap, last_change, 1.0)   # the active set is clear, polish it
        dv, ds, dl = direction(rd, rp, lam * s)          # affine (predictor) direction
        a = min(max_step(s, ds), max_step(lam, dl))
        if (feasible and gap <= gap_tol) or it >= max_iter:
            change = a * float(np.sqrt((dv * dv).sum(1)).max()) if len(dv) else 0.0
            return _IPMResult(v, lam, it, gap, change, a)
        mu_aff = float((s + a * ds) @ (lam + a * dl)) / m
        sigma = (mu_aff / mu) ** 3
        dv, ds, dl = direction(rd, rp, lam * s + ds * dl - sigma * mu)
        a = 0.995 * min(max_step(s, ds), max_step(lam, dl))
        v = v + a * dv
        s = s + a * ds
        lam = lam + a * dl
        it += 1
        last_change = a * float(np.sqrt((dv * dv).sum(1)).max())


# --------------------------------------------------------------------------
# Uzawa (seed 000 eq. 17)
# --------------------------------------------------------------------------


def _uzawa(C: Constraints, U, d, lam, atol, max_iter, nu):
    if C.m == 0:
        return ProjectionResult(U.copy(), lam, 0, 0, 0.0, True, "uzawa")
    if nu is None:
        nu = 1.9 / C.norm2_bound()  # 0 < nu < 2 / ||B||^2
    # work with the dual operator M = B B^T as a sparse matrix: one mat-vec per sweep
    B = C.to_csr()
    M = (B @ B.T).tocsr()
    c = B @ U.ravel() - d  # B u - d = c - M lam  for u = U - B^T lam
    it = 0
    converged = False
    check = 10
    while it < max_iter:
        for _ in range(check):
            res = c - M @ lam  # = B u^{k+1} - d with u^{k+1} = U - B^T lam^k
            lam = np.maximum(lam + nu * res, 0.0)
        it += check
        res = c - M @ lam
        if np.abs(np.minimum(lam, -res)).max() <= atol * 1e-2:
            u = U - C.rmatvec(lam)
            if kkt_residual(C, U, d, u, lam) <= atol:
                converged = True
                break
    u = U - C.rmatvec(lam)
    kkt = kkt_residual(C, U, d, u, lam)
    return ProjectionResult(u, lam, it, 0, kkt, converged, "uzawa")
