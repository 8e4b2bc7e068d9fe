"""Stress matrix (``femcrowd stress``): stiff and extreme macro scenes, run like any user run.

Every directory of ``cases/stress`` is an ordinary case. :func:`run_scene` runs
it as ``femcrowd run`` does (quiet) and judges it from what a user gets in the
output directory (summary.json, history.csv, the frames):

1. the invariants every macro run must show (docs/model.md, "What every
   run shows"), over all steps: mass(t) + evacuated(t) = mass(0) to
   1e-10 relative; 0 <= rho <= 1 + 1e-9; p >= 0; p = 0 where rho < 1 - 1e-9;
   complementarity |p (1 - rho)| <= 1e-9 max(1, max p); linear residual
   <= 1e-9 (density units); no NaN or inf; the run completed;
2. the scene's own checks (stress_checks.py): fronts and pressures of the exact
   solutions, rho = 1 to 1e-9 and u = 0 in the closed saturated room, p = 0 for
   the expanding block, ...

A scene passes when every check holds.
"""

import csv
import json
import traceback
from dataclasses import dataclass, field
from pathlib import Path

from .. import shipped
from ..case import load_case
from ..driver import run
from ..driver.output import prepare_output_dir
from ..errors import InputError
from ..files import replaced, write_text
from ..timer import Stopwatch
from .execute import Progress
from .stress_checks import CHECKS, LINEAR_TOL, MASS_TOL, RHO_TOL, Check, Output, population_invariants

#: the scenes (shipped with femcrowd)
CASES = shipped.cases("stress")
COLUMNS = ["scene", "steps", "min_rho", "max_rho", "mass_error", "min_p", "complementarity",
           "as_iterations", "linear_residual", "nan", "wall_s", "verdict"]
WIDTHS = [20, 6, 14, 14, 10, 5, 15, 13, 15, 3, 6, 7]


@dataclass
class Result:
    """A scene's run: summary.json, the checks, the wall time (setup included)."""

    name: str
    summary: dict
    checks: list = field(default_factory=list)
    wall: float = 0.0

    @property
    def passed(self):
        return bool(self.checks) and all(c.ok for c in self.checks)

    def failures(self):
        return [c for c in self.checks if not c.ok]

    def row(self):
        s, verdict = self.summary, "PASS" if self.passed else "FAIL"
        if "steps" not in s:  # refused at setup: no step was run
            return dict.fromkeys(COLUMNS, "") | {"scene": self.name, "wall_s": self.wall, "verdict": verdict}
        return {"scene": self.name, "steps": s["steps"], "min_rho": s["min_density_ever"],
                "max_rho": s["max_density_ever"], "mass_error": s["max_mass_error"],
                "min_p": s["min_pressure_ever"], "complementarity": s["max_complementarity"],
                "as_iterations": s["active_set_iterations"]["max"],
                "linear_residual": s["max_linear_residual"], "nan": s["non_finite_values"],
                "wall_s": self.wall, "verdict": verdict}


def invariants(s: dict, rho_max: float = 1.0) -> list:
    """The properties every run must show (docs/model.md) over the whole run, from summary.json."""
    return [
        Check("completed", s["status"] == "completed", s["status"]),
        Check("mass + evacuated conserved", s["max_mass_error"] <= MASS_TOL, f"{s['max_mass_error']:.1e}"),
        Check("rho >= 0", s["min_density_ever"] >= 0, f"{s['min_density_ever']:.3g}"),
        Check("rho <= 1 + 1e-9", s["max_density_ever"] <= rho_max * (1 + RHO_TOL),
              f"{s['max_density_ever'] / rho_max - 1:+.1e}"),
        Check("p >= 0", s["min_pressure_ever"] >= 0, f"{s['min_pressure_ever']:.3g}"),
        Check("p = 0 where rho < 1 - 1e-9", s["max_pressure_unsaturated"] == 0,
              f"{s['max_pressure_unsaturated']:.3g}"),
        Check("complementarity", s["max_complementarity"] <= RHO_TOL * max(1.0, s["max_pressure_ever"]),
              f"{s['max_complementarity']:.1e}"),
        Check("linear residual", s["max_linear_residual"] <= LINEAR_TOL, f"{s['max_linear_residual']:.1e}"),
        Check("no NaN/inf", s["non_finite_values"] == 0, str(s["non_finite_values"])),
        *population_invariants(s),
    ]


# --- running ------------------------------------------------------------------------------------

def scenes(cases=CASES, only=()) -> list:
    """Names of the scene directories (those with a case.toml), or the ones in `only` after checking them."""
    cases = Path(cases)
    if not cases.is_dir():
        raise InputError(cases, None, None, "stress scenes directory not found (give --cases DIR)")
    names = sorted(p.name for p in cases.iterdir() if (p / "case.toml").is_file())
    for name in only:
        if name not in names:
            raise InputError(cases, "--only", name, f"no such scene (scenes: {', '.join(names)})")
    return list(only) or names


def run_scene(name: str, out, cases=CASES, overrides=()) -> Result:
    """Run one scene into ``out`` (a new or femcrowd-written directory) and check it."""
    clock = Stopwatch()
    try:
        case = load_case(Path(cases) / name, overrides)
        summary = run(case, out).summary
    except InputError as err:
        return Result(name, {}, [Check("case accepted", False, str(err))], clock.seconds)
    except Exception as err:  # a solver failure fails the scene, not the matrix
        file = Path(out) / "summary.json"
        summary = json.loads(file.read_text()) if file.is_file() else {}
        where = traceback.extract_tb(err.__traceback__)[-1]
        detail = f"{type(err).__name__}: {err} ({Path(where.filename).name}:{where.lineno})"
        return Result(name, summary, [Check("run", False, detail)], clock.seconds)
    wall = clock.seconds
    checks = invariants(summary, case["model"]["rho_max"])
    if name in CHECKS:
        try:
            checks += CHECKS[name](Output(case, out, summary))
        except Exception as err:
            checks.append(Check("scene checks", False, f"{type(err).__name__}: {err}"))
    return Result(name, summary, checks, wall)


def run_matrix(out, only=(), cases=None, force: bool = False, echo=None, quiet: bool = True) -> tuple[list, Path]:
    """Run the scenes (all of `cases`, or those in `only`) into out/<scene> (out relative to the current
    directory), write the tables out/stress.csv and out/stress.md; echo(result) after each scene, and unless
    quiet a progress bar of the scenes (a scene that fails a check counts as failed).
    Returns the results and the output directory."""
    cases = cases or CASES
    names = scenes(cases, only)
    root = prepare_output_dir(Path(out).resolve(), "femcrowd stress --out", force)
    results = []
    with Progress(len(names), echo, quiet) as progress:
        for name in names:
            results.append(run_scene(name, root / name, cases))
            progress.advance(not results[-1].passed)
            progress.echo(results[-1])
    write_tables(results, root / "stress")
    return results, root


# --- the table ------------------------------------------------------------------------------------

def _cell(key, value):
    if value == "" or key in ("scene", "verdict", "steps", "as_iterations", "nan"):
        return str(value)
    if key == "wall_s":
        return f"{value:.2f}"
    if key in ("min_rho", "max_rho") and 0 < abs(value - 1) < 1e-3:
        return f"1{value - 1:+.1e}"  # distance to saturation
    return f"{value:.3g}" if key in ("min_rho", "max_rho") else f"{value:.1e}" if value else "0"


def header():
    return "  ".join(k.ljust(w) if k == "scene" else k.rjust(w) for k, w in zip(COLUMNS, WIDTHS))


def format_row(result):
    cells = [_cell(k, v) for k, v in result.row().items()]
    return "  ".join(c.ljust(w) if k == "scene" else c.rjust(w) for c, w, k in zip(cells, WIDTHS, COLUMNS))


def markdown(results):
    lines = ["| " + " | ".join(COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]
    lines += ["| " + " | ".join(_cell(k, v) for k, v in r.row().items()) + " |" for r in results]
    return "\n".join(lines) + "\n"


def write_tables(results, stem):
    """stem.csv (full precision, with the failed checks) and stem.md."""
    stem = Path(stem)
    with replaced(stem.with_suffix(".csv"), sync=True) as tmp, open(tmp, "w", newline="") as f:
        writer = csv.DictWriter(f, COLUMNS + ["failed_checks"])
        writer.writeheader()
        for r in results:
            writer.writerow(r.row() | {"failed_checks": "; ".join(f"{c.what}: {c.detail}" for c in r.failures())})
    write_text(stem.with_suffix(".md"), markdown(results), sync=True)
