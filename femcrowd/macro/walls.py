"""The desired direction at walls (``[velocity] walls``, docs/model.md, "Walls").

In the continuum, U = -v grad d / |grad d| never points into a wall: at a wall point the shortest path to
an exit either leaves the wall (U . n < 0, n the outward normal) or runs along it (U . n = 0, where the path
bends around a corner). The P1 gradient of the discrete d breaks this in cells that touch a wall: at a
column's or door post's face, where the shortest paths go around either side (the gradient averages the
two), and along a wall beside a door. With the upwind fluxes of the transport (walls carry nothing) such a
cell sends part or all of its outflow into the wall, and a cell whose every outflow facet is a wall, or
whose outflow goes to a neighbour that sends it back, keeps its mass for ever.

``walls = "slip"`` gives every cell three properties, on the cellwise U that every transport reads:

- **slip**: U_K . n_e <= 0 on each wall facet e of K: the into-wall component is removed, U_K <- U_K -
  (U_K . n_e)^+ n_e, and U_K rescaled to the cell's speed (|grad d| = 1 in the continuum);
- **every cell drains**: in the graph of the dominant upwind flows (K -> L across an interior facet with
  U_K . n_{K,L} > 0 and U_K . n_{K,L} + U_L . n_{K,L} > 0: each cell sends with its own U, and of two flows
  across a facet both ways only the larger counts; K -> outside across an open exit with U_K . n > 0), every
  cell that can reach an exit through the mesh and has a speed has a path to an exit. (With every flow
  counted, a cell in the corner of a small column, sent on to its one neighbour, which sent most of it back,
  kept half its density for seconds: tests/macro/test_walls.py.) A cell without one (in a closed loop of
  flows, or with U = 0 after the slip) heads for the midpoint of its facet to a neighbour that has one, the
  exit first, else the neighbour of least potential: U_K = v_K (m_e - c_K) / |m_e - c_K|, whose only
  outflow facet is e (U_K . n_f = -v_K h_f / (6 |m_e - c_K|) < 0 on the two others, h_f K's height
  over f), layer by layer from the draining cells, a neighbour that does not send back across e first. Only
  such cells change (and those of the next property).
- **no loop of two cells**: where a cell so made to drain through e has no other choice than a neighbour L
  that sends back across e (a pocket of one triangle, whose one open facet is e; a cell beside a wedge on a
  wall), e acts as a wall for L (the slip of L against e), and both steps are made again: otherwise the two
  cells pass the crowd back and forth and lose a few per cent of it per round (tests/macro/test_walls.py).
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import breadth_first_order

#: a component into a wall below this fraction of the speed is round-off
ROUND_OFF = 1e-12
#: rounds of slip and drain in wall_treatment (each closes facets of loops of two cells; a few suffice)
MAX_ROUNDS = 8


def slip(domain, exits, cells, speed, closed=None) -> np.ndarray:
    """U per cell with no component into the wall facets of its cell (to ROUND_OFF of the speed), nor across the
    facets ``closed`` = (cells, their outward normals) that act as walls for those cells, at the cell's speed; 0
    where nothing is left (U normal to the wall, or a corner cell pointing into both its walls)."""
    facets = np.flatnonzero(exits.wall)
    k, n = domain.f2t[0][facets], domain.normal[facets]
    if closed is not None:
        k, n = np.concatenate([k, closed[0]]), np.concatenate([n, closed[1]])
    cells = cells.copy()
    touched = np.zeros(len(cells), bool)
    for _ in range(3):   # a cell has at most three facets that act as walls
        into = np.einsum("ij,ij->i", cells[k], n)
        worst = np.argsort(-into, kind="stable")
        worst = worst[np.unique(k[worst], return_index=True)[1]]   # per cell its facet of largest U . n
        worst = worst[into[worst] > ROUND_OFF * speed[k[worst]]]
        cells[k[worst]] -= into[worst, None] * n[worst]
        touched[k[worst]] = True
    into = np.einsum("ij,ij->i", cells[k], n) > ROUND_OFF * speed[k]
    norm = np.hypot(cells[:, 0], cells[:, 1])
    lost = touched & ((np.bincount(k, into, len(cells)) > 0) | (norm <= ROUND_OFF * speed))
    rescale = touched & ~lost
    cells[rescale] *= (speed[rescale] / norm[rescale])[:, None]
    cells[lost] = 0.0
    return cells


def draining(domain, exits, cells, dominant=False) -> np.ndarray:
    """Per cell: has it a path to an exit in the graph of the upwind flows of U (cells: U per cell)? ``dominant``:
    of two flows across a facet both ways (each cell sends with its own U), only the larger counts."""
    n = domain.ncells
    k0, k1 = domain.f2t
    inner = domain.interior
    a0 = np.einsum("ij,ij->i", cells[k0], domain.normal)
    a1 = np.einsum("ij,ij->i", cells[np.where(inner, k1, k0)], domain.normal)
    ahead, back = inner & (a0 > 0), inner & (a1 < 0)
    if dominant:
        ahead, back = ahead & (a0 + a1 > 0), back & (a0 + a1 < 0)
    out = exits.exit & (a0 > 0)
    # the reversed flows (L <- K as L -> K), the outside as node n
    rows = np.concatenate([k1[ahead], k0[back], np.full(out.sum(), n)])
    cols = np.concatenate([k0[ahead], k1[back], k0[out]])
    graph = sp.csr_matrix((np.ones(len(rows)), (rows, cols)), shape=(n + 1, n + 1))
    reached = np.zeros(n + 1, bool)
    reached[breadth_first_order(graph, n, directed=True, return_predecessors=False)] = True
    return reached[:n]


def drain(domain, exits, cells, speed, level) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """U per cell such that every cell with a speed and a finite level (potential) drains: the cells that do not
    head for the midpoint of a facet to an exit or to a draining neighbour (one that does not send back across it
    if there is one, else any) of least level, layer by layer; and the cells so changed with their facets."""
    drains = draining(domain, exits, cells, dominant=True)
    todo = ~drains & (speed > 0) & np.isfinite(level)
    changed, through = [], []
    cells = cells.copy()
    k0, k1 = domain.f2t
    inner = domain.interior
    # each facet seen from each of its cells: (cell, the cell across or -1 for an open exit, facet)
    sides = np.concatenate([np.flatnonzero(inner | exits.exit), np.flatnonzero(inner)])
    own = np.concatenate([k0[inner | exits.exit], k1[inner]])
    other = np.concatenate([np.where(inner, k1, -1)[inner | exits.exit], k0[inner]])
    outward = np.where((own == k0[sides])[:, None], 1.0, -1.0) * domain.normal[sides]   # n_e out of own
    while todo.any():
        ready = todo[own] & ((other < 0) | drains[np.maximum(other, 0)])
        back = (other >= 0) & (np.einsum("ij,ij->i", cells[np.maximum(other, 0)], outward) < 0)
        if (ready & ~back).any():
            ready &= ~back
        if not ready.any():
            break   # the rest is cut off from the draining cells by cells without a speed
        cell, facet = own[ready], sides[ready]
        key = np.where(other[ready] < 0, -np.inf, level[np.maximum(other[ready], 0)])
        order = np.lexsort((facet, key, cell))
        first = order[np.unique(cell[order], return_index=True)[1]]   # per cell: the least level, then facet
        cell, facet = cell[first], facet[first]
        toward = domain.midpoint[facet] - domain.centroid[cell]
        cells[cell] = (speed[cell] / np.hypot(toward[:, 0], toward[:, 1]))[:, None] * toward
        drains[cell], todo[cell] = True, False
        changed.append(cell)
        through.append(facet)
    return cells, np.concatenate(changed or [np.zeros(0, int)]), np.concatenate(through or [np.zeros(0, int)])


def wall_treatment(domain, exits, cells, speed, level) -> np.ndarray:
    """``walls = "slip"``: the slip of U at the walls, then every cell drains (see the module); where a cell so
    made to drain through facet e receives across e what it sends (its neighbour L sends into it: a loop of two
    cells, a pocket), e acts as a wall for L, and both steps are made again."""
    k0, k1 = domain.f2t
    closed = (np.zeros(0, int), np.zeros((0, 2)))
    for _ in range(MAX_ROUNDS):
        result, changed, through = drain(domain, exits, slip(domain, exits, cells, speed, closed), speed, level)
        inner = domain.interior[through]
        changed, through = changed[inner], through[inner]
        other = np.where(k0[through] == changed, k1[through], k0[through])
        into = np.where((k0[through] == changed)[:, None], -1.0, 1.0) * domain.normal[through]   # n_e out of L
        back = np.einsum("ij,ij->i", result[other], into) > ROUND_OFF * speed[other]
        if not back.any():
            return result
        closed = (np.concatenate([closed[0], other[back]]), np.concatenate([closed[1], into[back]]))
    return result
