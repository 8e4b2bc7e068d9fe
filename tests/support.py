"""Helpers shared by the tests: the repository's paths, a small square mesh, the projection as
(rho, phi, info), the timing check."""

import sys
from pathlib import Path

import numpy as np
import skfem

from femcrowd.macro.projection import Projection
from femcrowd.mesh import Boundary, Domain

ROOT = Path(__file__).resolve().parents[1]
CASES, MESHES = ROOT / "cases", ROOT / "meshes"
FEMCROWD = Path(sys.executable).parent / "femcrowd"  # the installed command, for subprocess tests


def unit_square(n=12, exits=()) -> Domain:
    """Structured mesh of [0, 1]^2 (n = 2^k cells per side) with its sides as groups left, right,
    bottom, top; `exits` among them."""
    mesh = skfem.MeshTri.init_sqsymmetric().refined(int(np.log2(n)))
    mesh = mesh.with_boundaries({
        "left": lambda x: np.isclose(x[0], 0), "right": lambda x: np.isclose(x[0], 1),
        "bottom": lambda x: np.isclose(x[1], 0), "top": lambda x: np.isclose(x[1], 1)})
    return Domain(mesh, exits)


class Projector:
    """The correction step on a domain with all its exits open, as (rho, phi, info) of rho~."""

    def __init__(self, domain, **options):
        self.domain = domain
        self.exits = Boundary(domain).at(0.0)
        self.projection = Projection(domain, self.exits, **options)

    def __call__(self, rho_tilde):
        flux, info = self.projection(rho_tilde)
        return flux.apply(rho_tilde, self.domain.area), flux.phi, info


def assert_phases_within_wall(timing: dict) -> None:
    """The timed phases of a run are disjoint parts of its wall time: each non-negative, their sum at most the
    wall time, whatever the load of the machine. How much of the wall time they leave out is a measure, not a
    test (on a busy machine the scheduler's pauses fall between the phases too): benchmarks/accounted.py."""
    phases = {k: v for k, v in timing.items() if k != "wall"}
    assert phases and min(phases.values()) >= 0, timing
    assert sum(phases.values()) <= timing["wall"] * (1 + 1e-12), timing
