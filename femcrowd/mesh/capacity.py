"""Door capacities: the most a door lets through, in the prediction and in the projection (docs/model.md,
"Doors with a capacity"; the constrained conservation laws of Colombo, Goatin 2007, their finite volumes
in Andreianov, Goatin, Seguin 2010).

A door of capacity c (per metre and per second, in units of rho_max x m/s) lets at most c |e| tau cross
each of its facets e in a step of length tau, in either direction.

- Prediction: the net mass F_e that the transports of all populations carry across a capped facet is
  cut to sign(F_e) min(|F_e|, c |e| tau); what does not pass goes back from the receiving cell to the
  sending one, each population its share of the flow. For the LWR fluxes this is Godunov's
  min(D, c, S); for the linear fluxes it is the cap applied after the flux.
- Correction: each capped facet gets a door node per direction it can be crossed in (one for an exit,
  two for an interior door), with a value mu >= 0. The correction moves T_e (phi_K - phi_L - mu + mu')
  across the facet (phi_L = 0 outside an exit) and the door keeps room for it:

      z = s - T_e (phi_K - phi_L - mu + mu') >= 0,   mu >= 0,   mu z = 0,   s = c |e| tau - F_e,

  so mu = 0 is the free door of the paper and mu > 0 a door that passes exactly its capacity and
  pushes back like a wall. These rows are the derivatives of (1/2) T_e (phi_K - phi_L - mu + mu')^2:
  they extend the Laplacian symmetrically, and the whole correction stays one linear complementarity
  problem, solved by the same active sets. For an exit the extended matrix is a graph Laplacian (an
  M-matrix: the active-set iteration is monotone and terminates); an interior door adds entries +T_e
  between a door node and the cell behind it, so there termination is checked, not guaranteed.
"""

import numpy as np
import scipy.sparse as sp

#: ``capacity = "auto"``: the specific flow of the bottleneck experiments, persons/(m s), at a narrow door (up to
#: NARROW m: the mean of the 19 measured figures at 0.8 to 1.2 m, Kretz et al. 2006, Seyfried et al. 2009, Mueller
#: 1981, Liddle et al. 2011) and at a wide one (from WIDE m: the mean of the 10 at 2.4 to 5 m, Liao et al. 2014,
#: Mueller 1981, Liddle et al. 2011); femcrowd/studies/experiments.csv
NARROW, NARROW_CAPACITY = 1.2, 2.08
WIDE, WIDE_CAPACITY = 2.4, 2.57


def width_capacity(width):
    """The capacity of a door of this width (m), persons/(m s): NARROW_CAPACITY up to NARROW, WIDE_CAPACITY from
    WIDE, linear in between (an interpolation: no experiment at 1.2 to 2.4 m says more; docs/validation.md)."""
    return np.interp(width, [NARROW, WIDE], [NARROW_CAPACITY, WIDE_CAPACITY])


class Capacities:
    """The capped facets of the open doors: their cells, their rates c |e|, and the door nodes of the projection.

    ``facets``: the capped facets (doors in order); ``door``: the index of each one's door in ``doors``;
    ``rate``: c |e|, mass per second; ``receiver``: f2t[1], -1 across an exit; ``group``: the exit of each
    facet (-1 for interior doors). The door nodes: ``node_facet`` (position in ``facets``), ``node_sign``
    (+1: crossed f2t[0] -> f2t[1], -1: back), ``node_cell`` (the cell they let people out of).
    """

    def __init__(self, domain, doors, group):
        self.doors = list(doors)
        self.facets = np.concatenate([door.facets for door in self.doors])
        self.door = np.concatenate([np.full(len(door.facets), k) for k, door in enumerate(self.doors)])
        self.length = domain.length[self.facets]
        self.rate = np.concatenate([np.full(len(d.facets), d.capacity) for d in self.doors]) * self.length
        self.sender, self.receiver = domain.f2t[0][self.facets], domain.f2t[1][self.facets]
        self.group = group[self.facets]
        self.transmissibility = domain.transmissibility[self.facets]
        self.ncells, self.nfacets = domain.ncells, len(domain.length)
        inner = np.flatnonzero(self.receiver >= 0)
        m = len(self.facets)
        self.node_facet = np.concatenate([np.arange(m), inner])
        self.node_sign = np.concatenate([np.ones(m), -np.ones(len(inner))])
        self.node_cell = np.where(self.node_sign > 0, self.sender[self.node_facet],
                                  self.receiver[self.node_facet])

    @property
    def nodes(self) -> int:
        return len(self.node_facet)

    def limit(self, rho_tilde: np.ndarray, outflow: np.ndarray, through: np.ndarray, dt: float,
              area: np.ndarray) -> np.ndarray:
        """Cap the prediction, in place: rho_tilde (populations, cells), outflow (populations, exits) and
        through (populations, capped facets), the net mass each population's transport carried across each
        capped facet f2t[0] -> f2t[1]. Returns the net mass of all populations across each capped facet
        after the cap.

        The receiving cell gives back at most what this facet brought it (each population its part of
        the flow in the direction of the total), so it stays >= 0 for every one-stage explicit scheme."""
        total = through.sum(axis=0)
        excess = np.abs(total) - self.rate * dt
        over = np.flatnonzero(excess > 0)
        if not over.size:
            return total
        sign = np.sign(total[over])
        part = np.maximum(sign * through[:, over], 0.0)
        back = part * (excess[over] / part.sum(axis=0))          # (populations, over)
        forward = sign > 0
        sender = np.where(forward, self.sender[over], self.receiver[over])
        receiver = np.where(forward, self.receiver[over], self.sender[over])
        inside = receiver >= 0
        for i in range(len(rho_tilde)):
            np.add.at(rho_tilde[i], sender, back[i] / area[sender])
            np.subtract.at(rho_tilde[i], receiver[inside], back[i, inside] / area[receiver[inside]])
            np.maximum.at(rho_tilde[i], receiver[inside], 0.0)    # round-off of order 1e-17
            np.subtract.at(outflow[i], self.group[over[~inside]], back[i, ~inside])
        total[over] = sign * self.rate[over] * dt
        return total

    def rooms(self, A: sp.spmatrix) -> sp.csr_matrix:
        """The graph of the rooms: the extended Laplacian A (extend) without its links across the capped interior
        facets (the two cells, each door node and the cell it lets people into, the two nodes of a facet). Its
        components are the rooms, each with the door nodes that let people out of it: a room all in S with all
        those nodes in S (every door at capacity: they push back like walls) has A_SS singular, 1 on the room
        and its nodes in the kernel, as a closed room (macro/projection/rooms.py)."""
        n = self.ncells
        inner = np.flatnonzero(self.receiver >= 0)
        if not inner.size:   # exits only: each door node is a leaf of the room it lets people out of
            return A
        node = n + np.arange(self.nodes)
        across = self.receiver[self.node_facet] >= 0
        into = np.where(self.node_sign > 0, self.receiver[self.node_facet], self.sender[self.node_facet])[across]
        forward, back = self.pairs(n)
        i = np.concatenate([self.sender[inner], node[across], forward])
        j = np.concatenate([self.receiver[inner], into, back])
        cut = sp.csr_matrix((np.ones(len(i)), (i, j)), shape=A.shape)
        graph = A - A.multiply(cut + cut.T)
        graph.eliminate_zeros()
        return graph.tocsr()

    def pairs(self, offset: int) -> tuple:
        """(forward, back): the unknowns (door node + offset) of the two door nodes of each capped interior facet."""
        back = np.flatnonzero(self.node_sign < 0)
        return offset + self.node_facet[back], offset + back

    def room(self, passed: np.ndarray, dt: float) -> np.ndarray:
        """s = c |e| tau - F_e of each door node: what the door can still let through in its direction after
        the prediction's net flow `passed` (per capped facet, f2t[0] -> f2t[1])."""
        s = self.rate[self.node_facet] * dt - self.node_sign * passed[self.node_facet]
        return np.maximum(s, 0.0)

    def extend(self, A: sp.spmatrix) -> sp.csr_matrix:
        """The Laplacian A (cells) extended by the rows and columns of the door nodes (cells first)."""
        n, m = self.ncells, self.nodes
        node = n + np.arange(m)
        T = self.transmissibility[self.node_facet]
        sign = self.node_sign
        sender, receiver = self.sender[self.node_facet], self.receiver[self.node_facet]
        inner = receiver >= 0
        pair = np.flatnonzero(sign < 0)                 # the back node of an interior facet ...
        ahead = n + self.node_facet[pair]               # ... and its forward node (same position in facets)
        rows = np.concatenate([sender, node, receiver[inner], node[inner], node, node[pair], ahead])
        cols = np.concatenate([node, sender, node[inner], receiver[inner], node, ahead, node[pair]])
        vals = np.concatenate([-sign * T, -sign * T, sign[inner] * T[inner], sign[inner] * T[inner], T,
                               -T[pair], -T[pair]])
        border = sp.csr_matrix((vals, (rows, cols)), shape=(n + m, n + m))
        return (sp.block_diag([A, sp.csr_matrix((m, m))], format="csr") + border).tocsr()

    def jump(self, mu: np.ndarray) -> np.ndarray:
        """The pressure jump j_e = mu - mu' of each capped facet: the correction moves T_e (phi_K - phi_L - j_e)."""
        return np.bincount(self.node_facet, self.node_sign * mu, len(self.facets))

    def jumps(self, mu: np.ndarray) -> np.ndarray:
        """The pressure jumps on every facet of the mesh (0 but on the capped ones)."""
        jump = np.zeros(self.nfacets)
        jump[self.facets] = self.jump(mu)
        return jump

    def report(self, passed: np.ndarray, moved: np.ndarray, mu: np.ndarray, dt: float) -> dict:
        """What each door let through in a step and how hard the crowd pushed on it: {name: (flow, pressure)},
        flow = the mass per second that crossed it (prediction `passed` plus correction `moved`, per capped
        facet; an interior door's facets counted in the direction of their flow), pressure = the mean of
        mu / tau over its facets (by length; mu = None: no correction)."""
        flow = self._per_door(np.abs(passed + moved)) / dt
        pushed = np.zeros(len(self.facets)) if mu is None else np.bincount(self.node_facet, mu, len(self.facets))
        pressure = self._per_door(pushed * self.length) / np.array([d.width for d in self.doors]) / dt
        return {door.name: (float(f), float(p)) for door, f, p in zip(self.doors, flow, pressure)}

    def _per_door(self, values: np.ndarray) -> np.ndarray:
        """Sums of a value per capped facet over each door's facets."""
        return np.bincount(self.door, values, len(self.doors))
