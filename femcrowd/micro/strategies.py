"""The desired velocities of the discs beyond "push at full speed" (Maury, Roudneff-Chupin, Santambrogio,
Venel 2011, section on extensions): each disc's own population (desired velocity, exits), a speed that
depends on the density it sees, and what it does behind slower neighbours it can see.

Disc i sees the discs j with |q_j - q_i| <= R (``view_distance``) whose direction from q_i makes an
angle of at most alpha (``view_angle``, the half angle of view) with its desired direction e_i.

- Speed law: U_i = f(rho_i) U0_i with rho_i the density it sees, the area of the discs it sees over the
  area of its view sector alpha R^2, in units of the packing density pi / (2 sqrt 3) (the micro/macro
  normalisation of docs/micro.md), clipped to [0, 1].
- "push": U_i as it is (the model of docs/micro.md).
- "decelerate": when some of the neighbours it sees walk slower than it wants to (their last velocity
  along e_i, u_j . e_i, below |U_i|: someone walking towards it counts as slower, with speed 0), its
  speed becomes the mean of those slower neighbours' speeds weighted by 1 / distance (the nearer, the
  more it counts); its direction is kept. Two groups meeting head-on stop (the strategy's deadlock).
- "bypass": it keeps its speed and, when slower neighbours block its way, turns to the direction
  closest to e_i (steps of 10 degrees, up to 90 degrees either side) whose path over the view distance
  clears those neighbours (a gap of r_i + r_j: it may graze them; the left side first on a tie); with no
  such direction it keeps e_i (and pushes). The paths are checked against the slower neighbours of
  the whole front half (90 degrees either side), not the view cone only: a path that clears the cone
  can run into someone just outside it, beside the disc (measured: a full contact when passing a
  standing disc).

The last velocities are those of the previous step (the desired ones at the first step). Everything is
vectorised over the pairs of discs within R (a KD-tree).
"""

import numpy as np
from scipy.spatial import cKDTree

from .sampling import HEX_PACKING

#: the directions a bypassing disc tries: 0, +-10, ..., +-90 degrees off its desired direction
TURNS = np.radians(np.array([0.0, *[s * a for a in range(10, 91, 10) for s in (1, -1)]]))
STRATEGIES = ("push", "decelerate", "bypass")


class View:
    """The discs each disc sees: within ``distance`` and ``half_angle`` (degrees) of its direction."""

    def __init__(self, distance: float, half_angle: float):
        self.distance, self.half_angle = distance, np.radians(half_angle)

    def pairs(self, q, direction, half_angle=None):
        """(i, j, d_ij, offset q_j - q_i) of the pairs where i sees j (within `half_angle` radians, default
        the view's); direction: (n, 2) unit vectors (zero rows see nothing)."""
        pairs = cKDTree(q).query_pairs(self.distance, output_type="ndarray")
        i, j = np.concatenate([pairs[:, 0], pairs[:, 1]]), np.concatenate([pairs[:, 1], pairs[:, 0]])
        offset = q[j] - q[i]
        d = np.hypot(offset[:, 0], offset[:, 1])
        angle = self.half_angle if half_angle is None else half_angle
        ahead = np.einsum("ij,ij->i", offset, direction[i]) >= np.cos(angle) * d
        keep = ahead & (d > 0) & np.any(direction[i] != 0, axis=1)
        return i[keep], j[keep], d[keep], offset[keep]

    def density(self, r, i, j, n):
        """The density each disc sees, in units of the packing density, clipped to [0, 1]."""
        covered = np.bincount(i, np.pi * r[j] ** 2, n)
        return np.minimum(covered / (self.half_angle * self.distance ** 2) / HEX_PACKING, 1.0)


class DesiredVelocity:
    """U(q, t) of the discs of a MicroSimulation (set ``sim`` once it exists): the desired velocity of each
    disc's population, its speed law and the strategy. population: the population index of every disc,
    by its original id; velocities: U0 of each population, ``U0(xy, t) -> (n, 2)``; laws: SpeedLaw or None."""

    def __init__(self, velocities, population, laws, strategy="push", view=None):
        self.velocities, self.population = list(velocities), np.asarray(population)
        self.laws = [None if law is None or law.constant else law for law in laws]
        self.strategy, self.view = strategy, view
        self.sim = None

    @property
    def needs_view(self):
        return self.strategy != "push" or any(law is not None for law in self.laws)

    def __call__(self, q, t):
        population = self.population[self.sim.ids] if self.sim is not None else self.population[: len(q)]
        U = np.zeros((len(q), 2))
        for k, velocity in enumerate(self.velocities):
            mine = population == k
            if mine.any():
                U[mine] = velocity(q[mine], t)
        if not self.needs_view or len(q) < 2:
            return U
        speed = np.hypot(U[:, 0], U[:, 1])
        direction = np.divide(U, speed[:, None], out=np.zeros_like(U), where=speed[:, None] > 0)
        # a path that clears the view cone can run into someone just outside it: bypass looks at the front half
        i, j, d, offset = self.view.pairs(q, direction, np.pi / 2 if self.strategy == "bypass" else None)
        if any(law is not None for law in self.laws):
            cone = np.einsum("pc,pc->p", offset, direction[i]) >= np.cos(self.view.half_angle) * d
            seen = self.view.density(self.sim.r if self.sim is not None else np.zeros(len(q)), i[cone], j[cone],
                                     len(q))
            for k, law in enumerate(self.laws):
                mine = population == k
                if law is not None and mine.any():
                    speed[mine] *= law(seen[mine])
            U = direction * speed[:, None]
        if self.strategy == "push":
            return U
        last = self.sim.u if self.sim is not None and self.sim.nstep and len(self.sim.u) == len(q) else U
        ahead = np.einsum("pc,pc->p", last[j], direction[i])   # how fast j walks the way i wants to go
        slower = ahead < speed[i]
        i, j, d, offset, ahead = i[slower], j[slower], d[slower], offset[slower], np.maximum(ahead[slower], 0.0)
        if self.strategy == "decelerate":
            weight = 1.0 / d
            total = np.bincount(i, weight, len(q))
            mean = np.bincount(i, weight * ahead, len(q))
            behind = total > 0
            speed[behind] = mean[behind] / total[behind]
            return direction * speed[:, None]
        return bypass(q, self.sim.r if self.sim is not None else np.zeros(len(q)), direction, speed, i, j,
                      offset, self.view.distance)


def bypass(q, r, direction, speed, i, j, offset, reach):
    """U of the "bypass" strategy: for each disc i with slower visible neighbours j (pairs i, j), the turn of
    TURNS closest to 0 whose path q_i + s d, 0 <= s <= reach, passes at least r_i + r_j from every q_j."""
    n, k = len(q), len(TURNS)
    cos, sin = np.cos(TURNS), np.sin(TURNS)
    # the candidate directions of the discs that have pairs, (pairs, turns, 2)
    e = direction[i]
    dirs = np.stack([e[:, None, 0] * cos - e[:, None, 1] * sin, e[:, None, 0] * sin + e[:, None, 1] * cos], -1)
    along = np.clip(np.einsum("pkc,pc->pk", dirs, offset), 0.0, reach)
    miss = offset[:, None, :] - along[..., None] * dirs
    blocked = np.hypot(miss[..., 0], miss[..., 1]) < (r[i] + r[j])[:, None]
    closed = np.zeros((n, k), bool)
    np.logical_or.at(closed, i, blocked)
    free = ~closed
    first = np.argmax(free, axis=1)                          # TURNS are ordered by |angle|
    turn = np.where(free.any(axis=1), TURNS[first], 0.0)
    c, s = np.cos(turn), np.sin(turn)
    turned = np.column_stack([direction[:, 0] * c - direction[:, 1] * s, direction[:, 0] * s + direction[:, 1] * c])
    return turned * speed[:, None]
