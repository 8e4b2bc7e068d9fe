"""Discs arriving through boundary facets (``[[sources]]``, docs/scenes.md): slots one radius behind each entrance,
filled when free (random sequential addition, as the initial sampling does); the others wait."""

import json

import numpy as np
from scipy.spatial import cKDTree

from ..profiles import amounts
from .contacts import WallSet


class Arrivals:
    """The discs that enter a micro run: per source its facets, its rate (discs per second at the level of its
    profile, femcrowd/profiles.py), its profile, its population index and its span [start, end]; discs of radius
    `radius` (or drawn in [min, max]); `walls` the segments the slots must clear; drawn from default_rng(seed)."""

    def __init__(self, domain, facets, rates, profiles, populations, spans, radius, walls, seed: int = 1):
        lo, hi = (radius, radius) if np.isscalar(radius) else radius
        self.populations, self.rate, self.profiles = list(populations), np.asarray(rates, float), profiles
        self.start, self.end = np.asarray(spans, float).reshape(-1, 2).T
        self.r = float(hi)   # slots fit the largest disc; arrivals get radii drawn like the initial ones
        self.radius = (float(lo), float(hi))
        self.slots = [self._slots(domain, f, WallSet(walls)) for f in facets]
        self.pending = np.zeros(len(self.rate))
        self.rng = np.random.default_rng(seed)
        self.inflow = 0

    def _slots(self, domain, facets, walls) -> np.ndarray:
        """Disc centres 1.01 r behind the facets, at least 2 r apart, clear of every wall (set-up only)."""
        r, out = self.r, []
        for facet in facets:
            a, b = domain.points[domain.mesh.facets[:, facet]]
            n = int(np.ceil(4 * np.linalg.norm(b - a) / r))
            along = (np.arange(n) + 0.5) / n
            out.append(a + along[:, None] * (b - a) - 1.01 * r * domain.normal[facet])
        candidates = np.concatenate(out)
        if walls.n:
            hit, _, _, dist = walls.near(candidates, r)
            clear = np.ones(len(candidates), bool)
            clear[hit[dist < r]] = False
            candidates = candidates[clear]
        kept = []   # greedy thinning along the entrance: a handful of slots, once
        for candidate in candidates[np.lexsort(candidates.T[::-1])]:
            if not kept or np.min(np.linalg.norm(np.array(kept) - candidate, axis=1)) >= 2 * r:
                kept.append(candidate)
        return np.array(kept).reshape(-1, 2)

    def __call__(self, t: float, dt: float, q: np.ndarray, r: np.ndarray):
        """Centres, radii and population indices of the discs that enter during [t, t + dt] next to the
        discs (q, r)."""
        self.pending += self.rate * amounts(self.profiles, self.start, self.end, t, dt)
        wanted = np.floor(self.pending + 1e-9).astype(int)
        if not wanted.any():
            return np.zeros((0, 2)), np.zeros(0), np.zeros(0, int)
        tree = cKDTree(q) if len(q) else None
        reach = self.r + (r.max() if len(r) else 0.0)
        new_q, new_r, new_p = [], [], []
        for k, slots in enumerate(self.slots):
            if not wanted[k] or not len(slots):
                continue
            free = np.ones(len(slots), bool)
            if tree is not None:
                dist, nearest = tree.query(slots, k=min(8, len(q)), distance_upper_bound=reach)
                dist, nearest = dist.reshape(len(slots), -1), nearest.reshape(len(slots), -1)
                valid = nearest < len(q)
                free = ~(valid & (dist < r[np.minimum(nearest, len(q) - 1)] + self.r)).any(axis=1)
            chosen = self.rng.permutation(np.flatnonzero(free))[:wanted[k]]
            new_q.append(slots[chosen])
            lo, hi = self.radius
            new_r.append(np.full(len(chosen), lo) if lo == hi else self.rng.uniform(lo, hi, len(chosen)))
            new_p.append(np.full(len(chosen), self.populations[k]))
            self.pending[k] -= len(chosen)
        q_in = np.concatenate(new_q) if new_q else np.zeros((0, 2))
        r_in = np.concatenate(new_r) if new_r else np.zeros(0)
        p_in = np.concatenate(new_p).astype(int) if new_p else np.zeros(0, int)
        self.inflow += len(q_in)
        return q_in, r_in, p_in

    @property
    def queued(self) -> float:
        return float(np.floor(self.pending + 1e-9).sum())

    def snapshot(self) -> dict:
        return {"pending": self.pending.copy(), "inflow": self.inflow,
                "rng": json.dumps(self.rng.bit_generator.state)}

    def restore(self, data: dict) -> None:
        self.pending, self.inflow = data["pending"].copy(), int(data["inflow"])
        self.rng.bit_generator.state = json.loads(str(data["rng"]))
