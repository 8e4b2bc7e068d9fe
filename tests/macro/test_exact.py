"""The macro solver against the exact solutions of docs/model.md (observed rates).

In the style of scikit-fem's tests/test_convergence.py: one TestCase per problem,
errors on a refinement series, the slope of log(error) against log(h) fitted on
the finer pair and compared with the rate expected for DG0
(L1 density ~ h^1/2 across jumps, fronts and evacuated mass ~ h).
"""

from unittest import TestCase

import numpy as np
import skfem

from femcrowd.macro.diagnostics import SATURATED
from femcrowd.macro.exact import DiscProjection
from femcrowd.mesh import Domain
from femcrowd.studies.convergence import collect_rows, plan_study, run_task

from ..support import ROOT, Projector


class ExactRates:
    """Run `case` on `levels` refinements; check rates (finer pair) and decreasing errors."""

    case, levels, overrides = None, 3, ()
    rates = {}          # metric -> lowest acceptable observed order on the finer pair
    decreasing = ()     # metrics whose |error| must decrease at every refinement

    def runTest(self):
        base, exact, tasks = plan_study(ROOT / "cases" / self.case, self.levels, self.overrides)
        self.assertIsNotNone(exact)
        rows = collect_rows(tasks, [run_task(t) for t in tasks])
        hs = np.array([r["h"] for r in rows])
        for row in rows:   # the invariants hold on every level
            self.assertLess(row["mass_error"], 1e-10)
            self.assertGreaterEqual(row["rho_min"], 0.0)
            self.assertLessEqual(row["rho_max"], 1 + 1e-9)
            self.assertGreaterEqual(row["p_min"], 0.0)
        for metric, rate in self.rates.items():
            errors = np.abs([r[metric] for r in rows])
            slope = np.polyfit(np.log10(hs[-2:]), np.log10(errors[-2:]), 1)[0]
            self.assertGreater(slope, rate, f"{self.case} {metric}: errors {errors}, h {hs}")
        for metric in self.decreasing:
            errors = np.abs([r[metric] for r in rows])
            self.assertTrue(np.all(np.diff(errors) < 0), f"{self.case} {metric}: {errors}")


class ConvergenceWallAccumulation(ExactRates, TestCase):
    """Sol. 1: the saturated zone grows from the wall; density jumps -> L1 ~ h^1/2, front ~ h."""

    case = "corridor-wall"
    rates = {"l1": 0.4, "front_error": 0.8, "symdiff": 0.8}
    decreasing = ("pressure_l2", "w1")


class ConvergenceRadial(ExactRates, TestCase):
    """Sol. 2: radial concentration (singular U at the origin)."""

    case = "radial"
    rates = {"l1": 0.4}
    decreasing = ("l1", "front_error", "pressure_l2", "symdiff")


class ConvergenceSaturatedEvacuation(ExactRates, TestCase):
    """Sol. 3: a saturated block pushed out through the exit; evacuated mass ~ h."""

    case = "saturated-exit"
    overrides = ("time.end=0.3",)
    rates = {"evacuated_error": 0.8, "l1": 0.4}
    decreasing = ("pressure_l2", "evacuated_error")


class ConvergenceDiscProjection(TestCase):
    """Sol. 4: one correction step of rho~ = c on r < R on meshes/square_exits.msh."""

    levels = 4

    def runTest(self):
        exact = DiscProjection(c=2.0, R=0.4)
        mesh = skfem.MeshTri.load(str(ROOT / "meshes" / "square_exits.msh"))
        hs, errors = [], []
        for level in range(self.levels):
            domain = Domain(mesh.refined(level) if level else mesh, ["exit"])
            rho_tilde = domain.cell_average(exact.initial)
            rho, phi, _ = Projector(domain)(rho_tilde)
            # rho = 1 on r < R sqrt(c) and 0 beyond, up to the mesh: cells within h/8 of the circle
            r = np.hypot(*domain.points[domain.triangles].transpose(2, 0, 1))   # (M, 3) vertex radii
            tol = domain.h / 8
            inside, outside = r.max(1) < exact.R1 - tol, r.min(1) > exact.R1 + tol
            self.assertTrue(np.all(rho[inside] >= SATURATED))
            self.assertTrue(np.all(rho[outside] == 0.0))
            self.assertAlmostEqual(domain.area @ rho, domain.area @ rho_tilde, delta=1e-12)
            exact_phi = domain.cell_average(lambda x, y, t: exact.phi(x, y))
            errors.append(np.sqrt(domain.area @ (phi - exact_phi) ** 2))
            hs.append(domain.h)
        slope = np.polyfit(np.log10(hs), np.log10(errors), 1)[0]
        self.assertGreater(slope, 0.9, f"phi L2 errors {errors}")
        self.assertLess(errors[-1], 2e-3 * exact.phi(0.0, 0.0))
