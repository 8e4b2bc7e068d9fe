"""Catching-up scheme for rigid discs (Maury, Venel 2011; Maury 2014, eqs. 14-16).

One step of length tau from the centres q^n:

    u^{n+1} = P_{C(q^n)} U(q^n, t^n),
    C(q) = {v : D_ij(q) + tau G_ij(q) . v >= 0 for disc pairs and disc-wall pairs}
    q^{n+1} = q^n + tau u^{n+1}

The projection is the sparse QP of :mod:`femcrowd.micro.projection`. Gaps are
convex functions of q, so q^{n+1} has no overlap when the QP is solved
exactly and every pair that can touch is a candidate (Verlet list with a
skin, rebuilt and the step redone if a disc travels further than the skin
allows). Negative gaps (round-off, or overlapping input) enter clipped at
-1e-3 min(r): a small overlap is removed at the next step, a large one is
reduced step by step, and the QP stays feasible.

With ``fluctuation`` > 0 the projected velocity is U + xi, xi a seeded
Ornstein-Uhlenbeck perturbation per disc (:mod:`femcrowd.micro.fluctuation`),
advanced after each step by its exact transition over the step: the arches
of rigid discs at narrow doors break (docs/micro.md, "Arch-breaking
fluctuation"). With the default 0 nothing changes.

Discs whose centre crosses an exit segment during the step are removed and
counted as evacuated. :func:`run` yields one :class:`StepInfo` per step so
that output can be plugged in by the caller.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Callable, Iterator

import numpy as np

from ..step import Step
from ..timer import Stopwatch
from .contacts import WallSet, as_segments, merge_collinear
from .crossings import segment_crossings
from .fluctuation import FLUCTUATION_TIME, Fluctuation
from .network import ContactNetwork
from .projection import ProjectionResult, project

#: the projection of a step without discs
NO_DISCS = ProjectionResult(u=np.zeros((0, 2)), lam=np.zeros(0), iterations=0, factorizations=0, kkt=0.0,
                            converged=True, method="none")


@dataclass
class StepInfo(Step):
    """A step of the discs (iterations: the projection's): diagnostics, and arrays of the discs left after it.

    ids: original indices of the remaining discs; q: their centres after the step; r: radii; u: the velocity
    of the step; pressure: sum of the contact multipliers lambda touching each disc (Maury 2014, eq. 16).
    """

    step: int
    count: int
    evacuated: int  # total so far
    evacuated_now: int
    contacts: int  # active constraints (lambda > 0)
    max_overlap: float  # max(-gap) over pairs and walls after the step, 0 if none
    overlap_r: float    # the same divided by the smaller radius of each pair (of the disc, at a wall)
    gap: float          # certified relative objective gap of the projection (0: exact to round-off)
    change: float       # velocity change of one more interior-point step (0: exact)
    factorizations: int
    kkt: float
    converged: bool
    fallback: bool  # the exact projection needed its interior-point stage
    rebuilds: int  # candidate-list rebuilds in this step
    candidates: int
    ids: np.ndarray = field(repr=False)
    q: np.ndarray = field(repr=False)
    r: np.ndarray = field(repr=False)
    u: np.ndarray = field(repr=False)
    pressure: np.ndarray = field(repr=False)

    def row(self) -> dict:
        """The scalar diagnostics (a history.csv row)."""
        return {
            "time": self.time,
            "dt": self.dt,
            "count": self.count,
            "evacuated": self.evacuated,
            "contacts": self.contacts,
            "max_overlap": self.max_overlap,
            "overlap_r": self.overlap_r,
            "gap": self.gap,
            "change": self.change,
            "solver_iterations": self.iterations,
            "kkt": self.kkt,
            "step_seconds": self.seconds,
        }


class Uncovered(RuntimeError):
    """Moves no candidate list covers after rebuilds (velocities beyond any scale of the discs)."""


def _exit_segments(exits) -> np.ndarray:
    """The exit segments (E, 2, 2), collinear neighbours merged into one."""
    return merge_collinear(exits) if len(as_segments(exits)) else as_segments(exits)


class MicroSimulation:
    """State and stepping of the disc model.

    Parameters
    ----------
    q, r : centres (N, 2) and radii (N,) (or a scalar radius).
    walls : (W, 2, 2) wall segments (outer walls and obstacles); collinear
        chains are merged.
    exits : (E, 2, 2) exit segments.
    U : desired velocity, ``U(xy (n, 2), t) -> (n, 2)``.
    tau : time step.
    method : "exact" (default) or "uzawa" (Maury 2014, eq. 17).
    skin : Verlet-list skin (default: 6 tau max|U| at the first step, at
        least half the mean radius).
    tol : relative KKT tolerance of the projection.
    fluctuation : stationary standard deviation (m/s, per component) of the
        random perturbation xi of each disc's desired velocity (0: none, the
        discs of Maury and Venel); fluctuation_time: its correlation time (s);
        seed: the seed of its random numbers (:class:`Fluctuation`).
    surface : the :class:`~femcrowd.micro.surface.Atlas` of a building: q, walls and exits are then in its
        layout, the pairs across its folds are contacts, and a disc crossing a fold changes chart (None: a plane).
    """

    def __init__(
        self,
        q,
        r,
        walls,
        exits,
        U: Callable,
        tau: float,
        *,
        t0: float = 0.0,
        method: str = "exact",
        skin: float | None = None,
        tol: float = 1e-12,
        max_iter: int | None = None,
        ids=None,
        fluctuation: float = 0.0,
        fluctuation_time: float = FLUCTUATION_TIME,
        seed: int | None = 1,
        surface=None,
    ):
        q = np.array(q, dtype=float).reshape(-1, 2)
        r = np.broadcast_to(np.asarray(r, dtype=float), (len(q),)).copy()
        if not (np.all(np.isfinite(q)) and np.all(r > 0)):
            raise ValueError("disc centres must be finite and radii positive")
        if not tau > 0:
            raise ValueError(f"time step tau must be > 0, got {tau}")
        self.q, self.r = q, r
        self.ids = np.arange(len(q)) if ids is None else np.asarray(ids).copy()
        self.surface = surface
        self.contacts = ContactNetwork(WallSet(walls), skin, surface)
        self.exits = _exit_segments(exits)
        self.U = U
        self.tau = float(tau)
        self.t = float(t0)
        self.nstep = 0
        self.evacuated = 0
        self.method = method
        self.tol = tol
        self.max_iter = max_iter
        self.u = np.zeros_like(q)
        # overlaps (round-off, or in the input) are removed by at most this much per
        # step: the QP stays feasible and no overlap can grow
        self._recover = 1e-3 * float(r.min()) if len(r) else 0.0
        self._next_id = int(self.ids.max()) + 1 if len(self.ids) else 0   # the id of the next disc added
        self.moved_to = q               # the centres after the last move, before the discs that left are removed
        # the perturbations of the desired velocities (None: the discs of Maury and Venel, no random numbers)
        self.fluctuation = Fluctuation(fluctuation, len(q), seed, fluctuation_time) if fluctuation > 0 else None

    def set_boundary(self, walls, exits) -> None:
        """New walls and exits (a door that closed or opened); the candidate list is rebuilt at the next step."""
        self.contacts = ContactNetwork(WallSet(walls), self.contacts.skin, self.surface)
        self.exits = _exit_segments(exits)

    def add(self, q, r) -> None:
        """Discs entering the scene (sources), with new ids; the candidate list is rebuilt at the next step."""
        q, r = np.asarray(q, float).reshape(-1, 2), np.asarray(r, float)
        if not len(q):
            return
        first = self._next_id
        self.q, self.r = np.concatenate([self.q, q]), np.concatenate([self.r, r])
        self.ids = np.concatenate([self.ids, np.arange(first, first + len(q))])
        self._next_id = first + len(q)
        self.u = np.concatenate([self.u, np.zeros_like(q)])
        if self.fluctuation is not None:
            self.fluctuation.add(len(q))
        self.contacts.reset()
        self._recover = self._recover or 1e-3 * float(r.min())

    @property
    def count(self) -> int:
        return len(self.q)

    def desired_velocity(self, q=None, t=None):
        q = self.q if q is None else q
        U = np.asarray(self.U(q, self.t if t is None else t), dtype=float)
        if U.shape != q.shape:
            U = np.broadcast_to(U, q.shape).copy()
        if not np.all(np.isfinite(U)):
            raise FloatingPointError("desired velocity U returned NaN or inf")
        return U

    def state(self) -> dict:
        """Everything the next steps depend on, as arrays and numbers (a checkpoint): the discs, and what
        carries over from step to step, the contact network (candidate list, multipliers, factorisation
        pattern) and the perturbations with their random generator. :meth:`restore` continues exactly as
        this simulation would have (docs/micro.md, "Resuming a run")."""
        out = {"q": self.q, "r": self.r, "ids": self.ids, "u": self.u, "t": self.t, "steps": self.nstep,
               "evacuated": self.evacuated, "next_id": self._next_id, "recover": self._recover,
               **{f"contacts.{k}": v for k, v in self.contacts.state().items()}}
        if self.fluctuation is not None:
            out.update({f"fluctuation.{k}": v for k, v in self.fluctuation.state().items()})
        return out

    def restore(self, state: dict) -> None:
        """Continue from :meth:`state` (of a simulation of the same discs, walls and exits, set up alike)."""
        self.q, self.r, self.ids, self.u = (np.array(state[k]) for k in ("q", "r", "ids", "u"))
        self.t, self.nstep, self.evacuated = float(state["t"]), int(state["steps"]), int(state["evacuated"])
        self._next_id, self._recover = int(state["next_id"]), float(state["recover"])
        self.moved_to = self.q
        self.contacts.restore({k[9:]: v for k, v in state.items() if k.startswith("contacts.")})
        if self.fluctuation is not None:
            self.fluctuation.restore({k[12:]: v for k, v in state.items() if k.startswith("fluctuation.")})

    def step(self) -> StepInfo:
        """One catching-up step (Maury 2014, eq. 15): returns its diagnostics."""
        clock = Stopwatch()
        tau = self.tau
        N = self.count
        U = self.desired_velocity() if N else np.zeros((0, 2))
        if self.fluctuation is not None and N:
            U = U + self.fluctuation.xi
        if N:
            projection, constraints, rebuilds = self._project(U)
            pressure = constraints.per_disc_sum(self.contacts.lam)
        else:
            projection, rebuilds, pressure = NO_DISCS, 0, np.zeros(0)
        contacts = int(np.count_nonzero(self.contacts.lam > 0))
        q_new = self.q + tau * projection.u
        gone = segment_crossings(self.q, q_new, self.exits, ending_counts=True).any(axis=1)
        crossed = None
        if self.surface is not None:   # a building: the discs that crossed a fold into the next piece's chart
            q_new, crossed = self.surface.recharted(self.q, q_new)
        self.moved_to = self.q = q_new
        self.u = projection.u
        self.contacts.moved()
        pressure = self._leave(gone, pressure)
        if crossed is not None and crossed[~gone].any():   # the rows of their pairs are those of another piece now
            self.contacts.rebuild(self.q, self.r, self.contacts.cl.skin)
        if self.fluctuation is not None:
            self.fluctuation.advance(tau)   # to the end of the step: the next step's perturbations
        # gaps at the new configuration: diagnostics and next step's constraints
        max_overlap, overlap_r = self.contacts.overlaps(self.q, self.r)
        self.t += tau
        self.nstep += 1
        return StepInfo(
            step=self.nstep, time=self.t, dt=tau, seconds=clock.seconds, iterations=projection.iterations,
            count=self.count, evacuated=self.evacuated, evacuated_now=int(gone.sum()), contacts=contacts,
            max_overlap=max_overlap, overlap_r=overlap_r, gap=projection.gap, change=projection.change,
            factorizations=projection.factorizations, kkt=projection.kkt, converged=projection.converged,
            fallback=projection.fallback, rebuilds=rebuilds, candidates=self.contacts.candidates,
            ids=self.ids, q=self.q, r=self.r, u=self.u, pressure=pressure,
        )

    def _project(self, U):
        """The projected velocity of the step (the QP on candidate pairs that cover the move; the list is rebuilt
        and the QP solved again while a disc moves further than the skin allows): (projection, constraints,
        rebuilds)."""
        tau, network = self.tau, self.contacts
        # the list must cover the predicted moves (desired or last speed, whichever is larger)
        speed = np.sqrt(np.maximum((U * U).sum(1), (self.u * self.u).sum(1)))
        rebuilds = network.cover(self.q, self.r, tau * speed, tau * np.sqrt((U * U).sum(1)))
        projection, feasible_tol = None, self.tol * max(1.0, float(np.abs(U).max()))
        for _ in range(6):
            constraints = network.constraints(self.q, self.r)
            d = np.maximum(constraints.D, -self._recover) / tau
            # after a rebuild, velocities that satisfy the new rows (all inactive) are still the projection
            if projection is None or float((constraints.matvec(projection.u) - d).max(initial=0.0)) > feasible_tol:
                projection = project(constraints, U, d, method=self.method, lam0=network.lam, tol=self.tol,
                                     max_iter=self.max_iter, pattern=network.pattern)
                network.lam = projection.lam
            moved = tau * np.sqrt((projection.u * projection.u).sum(1))
            if network.cl.travel_ok(self.q, moved):
                return projection, constraints, rebuilds
            network.rebuild(self.q, self.r, max(network.base_skin, 2.5 * float(moved.max())))   # carries lam over
            rebuilds += 1
        raise Uncovered(f"the candidate list could not cover the moves of the step from t = {self.t:.6g} s")

    def _leave(self, gone, pressure):
        """Remove the discs that crossed an exit (mask gone) and count them; returns the pressure of those left."""
        nevacuated = int(gone.sum())
        if not nevacuated:
            return pressure
        keep = ~gone
        self.contacts.remove(keep)
        self.q, self.r, self.ids, self.u = self.q[keep], self.r[keep], self.ids[keep], self.u[keep]
        if self.fluctuation is not None:
            self.fluctuation.keep(keep)
        self.evacuated += nevacuated
        return pressure[keep]

    def run(self, t_end: float | None = None, max_steps: int | None = None,
            stop_when_empty: bool = True) -> Iterator[StepInfo]:
        """Yield StepInfo for each step until t_end, max_steps or (by default) no disc is left."""
        taken = 0
        while True:
            if t_end is not None and self.t >= t_end - 1e-12 * max(1.0, abs(t_end)):
                return
            if max_steps is not None and taken >= max_steps:
                return
            if stop_when_empty and self.count == 0:
                return
            yield self.step()
            taken += 1

