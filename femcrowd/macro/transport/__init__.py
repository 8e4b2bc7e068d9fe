"""The prediction step of the macro model: transport schemes, and the registry that names them.

Every scheme is built as ``Scheme(domain, exits, normal_velocity, potential=None)`` (potential: a
cell field decreasing downstream, when U has one) and offers ``step(rho, dt) -> (rho~, outflow per
exit)``, ``facet_flux(rho, dt, facets)`` (the mass each facet carries in that step, for measurement lines;
computed only when asked), ``max_dt`` (the CFL-1 step of the upwind scheme for this U) and
``max_cfl`` (the largest fraction of it the scheme accepts). ``TRANSPORTS`` is the one list of
schemes: ``[scheme] transport`` of a case takes its keys. ``LWRTransport`` (the fluxes of a speed
that depends on the density, built with the law instead of a potential) is chosen by
``[velocity] speed_law``, not by name; ``LWR_TRANSPORTS`` gives the speed-law scheme of each transport that has
one (``muscl``: Godunov's flux between limited reconstructions, SSP-RK2, ``MUSCLLWRTransport``, the
populations stepping together; ``implicit``: the linearly implicit ``ImplicitLWRTransport``;
``implicit-godunov``: the explicit fluxes' rates frozen at the step's start, implicit only in the cells whose
CFL step the step exceeds, ``ImplicitGodunovTransport``, for f = 1 too). ``IMPLICIT``: the transports positive at
any step (their step may be set by a quantile of the cells', their density may pass 1 within a step).
"""

from .implicit import ImplicitGodunovTransport, ImplicitLWRTransport, ImplicitUpwindTransport
from .lwr import LWRTransport
from .muscl import CompressiveTransport, MUSCLTransport
from .muscl_lwr import MUSCLLWRTransport
from .upwind import UpwindTransport

#: [scheme] transport: order-0 upwind; linear reconstruction + SSP-RK2; the same with one Euler stage;
#: backward-Euler upwind (any time step); implicit-godunov is built by LWR_TRANSPORTS for every law, f = 1 too
#: (MacroSolver.transports), its entry here names it
TRANSPORTS = {"upwind": UpwindTransport, "muscl": MUSCLTransport, "compressive": CompressiveTransport,
              "implicit": ImplicitUpwindTransport, "implicit-godunov": ImplicitUpwindTransport}
#: the scheme of a population with a speed law, per [scheme] transport (the others refuse a speed law)
LWR_TRANSPORTS = {"upwind": LWRTransport, "muscl": MUSCLLWRTransport, "implicit": ImplicitLWRTransport,
                  "implicit-godunov": ImplicitGodunovTransport}
#: the transports positive at any step
IMPLICIT = ("implicit", "implicit-godunov")

__all__ = ["IMPLICIT", "LWR_TRANSPORTS", "TRANSPORTS", "CompressiveTransport", "ImplicitGodunovTransport",
           "ImplicitLWRTransport", "ImplicitUpwindTransport", "LWRTransport", "MUSCLLWRTransport", "MUSCLTransport",
           "UpwindTransport"]
