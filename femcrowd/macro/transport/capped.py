"""Door capacities inside the linearly implicit prediction (implicit.py, ImplicitLWRTransport; docs/model.md,
"Doors with a capacity").

A capped facet e passes at most c |e| per second (mesh/capacity.py). The explicit transports cut the flux after
the step and give what did not pass back from the receiver to the sender; after an implicit step that is not
positive, the mass that crossed may have moved on within the step. So the cap goes into the solve, as an
active set on the capped interior facets:

- a facet whose net flow (all populations) would exceed c |e| is *active*: the flows across it in the direction
  of the net flow carry theta_e q_e f(rho^n_L) rho~_K instead of q_e f(rho^n_L) rho~_K, one factor
  0 <= theta_e <= 1 for every population (each passes its share of the flow), chosen so that the net flow is
  c |e| exactly. The matrix stays that of ImplicitLWRTransport with smaller rates: an M-matrix with the same
  pattern and the same order of the flow (flow_order.py, built once per door state, is reused as it is);
  rho~ >= 0 and the mass of each population is conserved at any step, whatever theta.
- theta_e follows from the sender's row: with B_i = |K| rho_i,K / tau + the inflow of population i into K
  (from the cells upstream) and D_i = |K| / tau + the rates leaving K but e's, population i sends
  theta s_i B_i / (D_i + theta s_i) across e (s_i its unscaled rate), concave and increasing in theta: Newton's
  iteration from theta = 1 lands below the root and then rises to it monotonically (Newton's method on a concave
  increasing function, Ortega, Rheinboldt 1970, Iterative Solution of Nonlinear Equations, ch. 13). The facet
  is active when theta = 1 sends more than c |e| plus the flow the other way (its B_i are those of the current
  solve: semismooth Newton on min(flux, c |e|), Hintermueller, Ito, Kunisch 2003). With an implicit share
  omega < 1 at the sender (ImplicitGodunovTransport: the flows carry omega rho~_K + (1 - omega) rho_K) the row
  gives theta s_i B'_i / (D_i + omega theta s_i), B'_i = omega B_i + (1 - omega) rho_i,K D_i, B_i and D_i with the
  explicit part of the other rates: the same Newton iteration, exact at once where omega = 0 (linear in theta).
- Sweeps: solve every population with the current factors, recompute the active set and the factors from the
  solve, until neither changes. In the order of the flow the inflow B of a sender depends only on the cells
  upstream of it: a capped facet with no active one upstream has its exact factor after the first sweep, and each
  sweep settles the capped facets one step further down the flow (a sender fed by the sender of another capped
  facet waits for it): two or three sweeps for one door, three for two doors in a row
  (tests/macro/test_implicit_capacity.py). A sender on a cycle of the flow through its door (a facet crossed both
  ways) converges geometrically instead: at most SWEEPS sweeps are made, then the last solve stands (positive and
  conservative, the cut of mesh/capacity.py taking what is left above the cap).

The flows across a capped exit are not scaled: the doors' cut after the step (Capacities.limit) stays theirs,
as before, and gives back only to the sender, which is positive.
"""

import numpy as np

from .implicit import carried

#: the most sweeps of the active set (solves of every population)
SWEEPS = 50
#: the change of every factor theta below which the active set has converged
TOL = 1e-13


def capped_step(schemes, rho, dt, seen, caps, sources=None) -> tuple[list, int]:
    """The Prediction of each population (ImplicitLWRTransport `schemes`, densities `rho`, the extra argument
    `seen` of each: the total density its law sees, the density arriving during the step in `sources`, None for
    none) with the caps of the interior doors among `caps` (mesh/capacity.py Capacities) in the solve, and the
    number of sweeps."""
    m = len(caps.facets)
    sources = [None] * len(schemes) if sources is None else sources
    theta, direction = np.ones(m), np.zeros(m)   # direction: +1 the flows f2t[0] -> f2t[1] scaled, -1 back, 0 free
    speeds = [scheme.speeds(r, *extra) for scheme, r, extra in zip(schemes, rho, seen)]
    shares = [scheme.share(dt, speed) for scheme, speed in zip(schemes, speeds)]   # of the unscaled speeds
    for sweep in range(1, SWEEPS + 1):
        scaled = [_scaled(scheme, speed, theta, direction) for scheme, speed in zip(schemes, speeds)]
        rho_t = [scheme.solve(r, dt, speed, share, source)
                 for scheme, r, speed, share, source in zip(schemes, rho, scaled, shares, sources)]
        new_theta, new_direction = _factors(schemes, rho, rho_t, dt, speeds, scaled, shares, caps.rate, sources)
        settled = np.array_equal(new_direction, direction) and np.all(np.abs(new_theta - theta) <= TOL)
        theta, direction = new_theta, new_direction
        if settled:
            break
    return [scheme.prediction(r, x, dt, speed, share)
            for scheme, r, x, speed, share in zip(schemes, rho, rho_t, scaled, shares)], sweep


def _scaled(scheme, speed, theta, direction):
    """The speeds of a population with the factors of the active doors on their flows in the active direction."""
    if not np.any(direction):
        return speed
    flows, position = scheme.door_flows, scheme.door_position
    active = direction[position] == scheme.flow_sign[flows]
    scaled = speed.copy()
    scaled[flows[active]] *= theta[position[active]]
    return scaled


def _factors(schemes, rho, rho_t, dt, speeds, scaled, shares, rate, sources):
    """The factor theta and the active direction of each capped facet from a solve (rho~ of each population with
    the `scaled` speeds, the implicit `shares` omega and the arriving density of `sources`): per door flow of each
    population the terms (facet, sign, s, B, D, omega) of the sender's row, the flow at theta = 1 each way, then
    Newton's iteration on the active facets."""
    m = len(rate)
    terms = []
    for scheme, r, x, speed, current, share, source in zip(schemes, rho, rho_t, speeds, scaled, shares, sources):
        n, area = len(r), scheme.domain.area
        inner = scheme.inner
        inflow = np.bincount(scheme.receiver[inner], current[inner] * carried(r, x, share)[scheme.sender[inner]], n)
        others = np.bincount(scheme.sender, current, n)
        leaving = area / dt + share * others
        flows = scheme.door_flows
        sender = scheme.sender[flows]
        omega, rest = share[sender], others[sender] - current[flows]   # rest: the rates leaving but e's
        kept = area[sender] * r[sender] / dt - (1.0 - omega) * rest * r[sender]
        if source is not None:   # arrivals enter the implicit part (ImplicitLWRTransport.solve)
            kept = kept + area[sender] * source[sender] / dt
        D = leaving[sender] - omega * current[flows]
        B = omega * (kept + inflow[sender]) + (1.0 - omega) * r[sender] * D
        terms.append((scheme.door_position, scheme.flow_sign[flows], speed[flows], B, D, omega))
    position, sign, s, B, D, omega = (np.concatenate(column) for column in zip(*terms))
    free = s * B / (D + omega * s)           # what each flow would carry unscaled, from its sender's inflow
    ahead = np.bincount(position, np.where(sign > 0, free, 0.0), m)
    back = np.bincount(position, np.where(sign < 0, free, 0.0), m)
    net = ahead - back
    direction = np.where(np.abs(net) > rate, np.sign(net), 0.0)
    target = rate + np.where(direction > 0, back, ahead)   # c |e| plus the flow the other way
    chosen = np.flatnonzero(direction[position] == sign)
    return (_newton(position[chosen], s[chosen], B[chosen], D[chosen], omega[chosen], target, direction != 0),
            direction)


def _newton(position, s, B, D, omega, target, active):
    """theta in [0, 1] of each active facet with sum over its flows of theta s B / (D + omega theta s) = target (1 on
    the others): Newton's iteration from 1 on a concave increasing function (a handful of iterations to
    round-off; one where omega = 0, the flow linear in theta)."""
    m = len(target)
    theta = np.ones(m)
    for _ in range(100):
        t = theta[position] * s
        h = np.bincount(position, t * B / (D + omega * t), m) - target
        slope = np.bincount(position, s * B * D / (D + omega * t) ** 2, m)
        new = np.where(active & (slope > 0), np.clip(theta - h / np.where(slope > 0, slope, 1.0), 0.0, 1.0), 1.0)
        if np.all(np.abs(new - theta) <= 4 * np.finfo(float).eps):
            return new
        theta = new
    return theta
