"""A random perturbation of the discs' desired velocities, which breaks the arches of rigid discs at
narrow doors (``[micro] fluctuation``; docs/micro.md, "Arch-breaking fluctuation").

Each disc i carries a velocity xi_i(t), added to its desired velocity: the catching-up step projects
U_i(q, t) + xi_i(t) instead of U_i (the projection, hence the absence of overlap, is unchanged). xi is an
Ornstein-Uhlenbeck process (Uhlenbeck, Ornstein 1930), independent from disc to disc and between the
two components,

    d xi = -xi / theta dt + sigma sqrt(2 / theta) dW,

stationary, of mean 0, standard deviation sigma per component (``fluctuation``, m/s) and correlation
E[xi(t) xi(s)] = sigma^2 exp(-|t - s| / theta). It is advanced by its exact transition over a step of
any length dt (Gillespie 1996),

    xi^{n+1} = a xi^n + sigma sqrt(1 - a^2) eta^n,   a = exp(-dt / theta),   eta^n ~ N(0, I) i.i.d.,

so that its statistics do not depend on the time step (fresh white noise at every step would give a
perturbation whose effect on the motion scales with the step). Discs start (and discs from sources
enter) with a draw from the stationary law N(0, sigma^2 I).

It is the individual fluctuation term xi_i of the social force model (Helbing, Farkas, Vicsek 2000:
"Freezing by heating in a driven mesoscopic system", Phys. Rev. Lett. 84, 1240, and "Simulating dynamical
features of escape panic", Nature 407, 487) seen through the velocity: there, white noise in the
acceleration is relaxed by the time tau_i = 0.5 s that brings a pedestrian's velocity to its desired
one, so that the velocity fluctuates as an Ornstein-Uhlenbeck process of correlation time 0.5 s. The
disc model has no inertia: the correlation time theta = 0.5 s (:data:`FLUCTUATION_TIME`) is given to the
perturbation itself.

The draws come from numpy's default_rng seeded from ``[micro] seed`` on a stream of their own (the
sampling of the crowd and the sources use the seed itself): a run is reproducible bit for bit, and its
state (:meth:`Fluctuation.state`) goes into the checkpoints.
"""

from __future__ import annotations

import json
import math

import numpy as np

#: correlation time theta (s) of the perturbation: the relaxation time of Helbing et al. (2000)
FLUCTUATION_TIME = 0.5
#: the perturbation's random stream, apart from the other users of the seed
STREAM = 0x0F1C


class Fluctuation:
    """The perturbations xi (n, 2) of n discs: stationary standard deviation `size` (m/s) per component,
    correlation time `time` (s), random numbers from default_rng((seed, STREAM))."""

    def __init__(self, size: float, n: int, seed: int | None = 1, time: float = FLUCTUATION_TIME):
        if not size > 0 or not time > 0:
            raise ValueError(f"fluctuation size and time must be > 0, got {size}, {time}")
        self.size, self.time = float(size), float(time)
        self.rng = np.random.default_rng(None if seed is None else (int(seed), STREAM))
        self.xi = self.size * self.rng.standard_normal((int(n), 2))

    def advance(self, dt: float) -> None:
        """The exact transition of the process over dt (any length >= 0)."""
        if not len(self.xi) or dt <= 0:
            return
        a = math.exp(-dt / self.time)
        spread = self.size * math.sqrt(-math.expm1(-2.0 * dt / self.time))   # sigma sqrt(1 - a^2)
        self.xi = a * self.xi + spread * self.rng.standard_normal(self.xi.shape)

    def add(self, n: int) -> None:
        """n discs entering, each with a draw from the stationary law."""
        if n:
            self.xi = np.concatenate([self.xi, self.size * self.rng.standard_normal((int(n), 2))])

    def keep(self, kept) -> None:
        """Only the discs of the boolean mask stay (the others left)."""
        self.xi = self.xi[kept]

    def state(self) -> dict:
        """The perturbations and the generator's state (a checkpoint)."""
        return {"xi": self.xi, "rng": json.dumps(self.rng.bit_generator.state)}

    def restore(self, state: dict) -> None:
        self.xi = np.array(state["xi"], float).reshape(-1, 2)
        self.rng.bit_generator.state = json.loads(str(state["rng"]))
