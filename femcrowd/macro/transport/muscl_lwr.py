"""Second-order prediction with a speed law (``scheme.transport = "muscl"``, ``velocity.speed_law``): the LWR
fluxes of lwr.py between the limited linear reconstructions of muscl.py, SSP-RK2 (Shu, Osher 1988).

Each forward-Euler stage E reconstructs every population on the facets of its cells (Barth, Jespersen 1989;
``Reconstruction``) and carries across each facet e, from the sender K to the receiver L,

    F_e = q_e min(D(r_K,e), S(r_L,e))     (Godunov's flux of a unimodal g, Lebacque 1996; lwr.py)

with r_K,e the total density reconstructed on e from K's side (the sum of the populations' facet values, the
empty outside across an exit), each population taking its share rho_i,K,e / r_K,e of the sender's flux; then
rho~ = (rho + E(E(rho))) / 2, the second stage's law seeing the first stage's total. A flux is at most
q_e rho_i,K,e (D(r) <= r), so the reconstruction's positivity limiter keeps rho~ >= 0 at dt <= max_dt; the
step is cfl <= 0.5 times the LWR transport's CFL step (lwr.py joint_max_dt), as for muscl. A receiver's
reconstructed value can differ from its density, so the supply no longer bounds what enters it: rho <= 1 is the
projection's, always (even when f(1) = 0). Mass is conservative (one flux per facet), the evacuated mass the
mean of the stages'.
"""

import numpy as np

from .lwr import LWRTransport
from .muscl import Reconstruction
from .upwind import Prediction


class MUSCLLWRTransport(LWRTransport):
    """The LWR fluxes of one population between limited reconstructed facet values; the populations step
    together (``stages``), every one with this scheme once one has a speed law (f = 1 for the others)."""

    max_cfl = 0.5
    bounded = False
    #: the populations of a case take this scheme all, and step together, once one of them has a speed law
    together = True

    def __init__(self, domain, exits, normal_velocity, law):
        super().__init__(domain, exits, normal_velocity, law)
        self.reconstruction = r = Reconstruction(domain, self.out0, self.out1)
        facet, forward = self.flow_facet, self.flow_sign > 0
        # the flat (3 n) positions of the sender's and the receiver's values on each flow's facet; 3 n: outside
        self.sending = np.where(forward, r.pos0[facet], r.pos1[facet])
        self.receiving = np.where(self.receiver == domain.ncells, 3 * domain.ncells,
                                  np.where(forward, r.pos1[facet], r.pos0[facet]))

    def step(self, rho, dt, total=None) -> Prediction:
        """rho~ of this population alone (one population: ``stages`` steps several together)."""
        if total is not None:
            raise ValueError("several populations step together: muscl_lwr.stages")
        return stages([self], rho[None], dt)[0]

    def facet_flux(self, rho, dt, total=None, facets=slice(None)):
        """The mass each facet (of `facets`) carries f2t[0] -> f2t[1] in the step of rho alone (one population)."""
        if total is not None:
            raise ValueError("several populations step together: muscl_lwr.facet_fluxes")
        return facet_fluxes([self], rho[None], dt, facets)


def _faces(schemes, rho, dt) -> tuple:
    """The facet values of each population (flat, 3 n) and their total (None: one population)."""
    faces = [s.reconstruction(r, dt).ravel() for s, r in zip(schemes, rho)]
    return faces, None if len(faces) == 1 else sum(faces)


def _euler(schemes, rho, dt) -> list:
    """One forward-Euler stage of every population: the Prediction of each."""
    faces, total = _faces(schemes, rho, dt)
    return [s.balance(r, s.flows(f, total), dt) for s, r, f in zip(schemes, rho, faces)]


def stages(schemes, rho, dt) -> list:
    """SSP-RK2 of every population together: the Prediction of each (rho~, the mean of the stages' outflow per
    exit and net mass through the capped door facets)."""
    for s in schemes:
        if dt > s.max_dt * (1 + 1e-12):
            raise ValueError(f"dt = {dt:.6g} exceeds the CFL limit {s.max_dt:.6g} of the LWR transport")
    one = _euler(schemes, rho, dt)
    two = _euler(schemes, [p.rho for p in one], dt)
    return [Prediction(0.5 * (r + b.rho), 0.5 * (a.outflow + b.outflow), 0.5 * (a.through + b.through))
            for r, a, b in zip(rho, one, two)]


def facet_fluxes(schemes, rho, dt, facets=slice(None)) -> np.ndarray:
    """The mass each facet (of `facets`) carries f2t[0] -> f2t[1] in the step of ``stages``, all populations
    (measurement lines): the mean of the two stages' fluxes, only the flows across these facets evaluated."""

    def carried(values):
        faces, total = _faces(schemes, values, dt)
        return sum(LWRTransport.facet_flux(s, f, dt, total, facets) for s, f in zip(schemes, faces))
    return 0.5 * (carried(rho) + carried([p.rho for p in _euler(schemes, rho, dt)]))
