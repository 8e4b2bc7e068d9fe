"""Refinement studies of the extensions against their exact solutions (``femcrowd extensions``,
docs/extensions.md): LWR Riemann problems with the linear speed law, two populations meeting head-on,
the saturated evacuation in two colours. Each run steps exactly as ``femcrowd run`` does
(femcrowd.Simulation, in memory). The tests (tests/macro/test_extensions_exact.py) call the same
functions on fewer levels.
"""


import numpy as np

from .. import shipped
from ..case import load_case
from ..driver import Simulation
from ..macro.diagnostics import SATURATED
from ..macro.exact import ColouredEvacuation, HeadOnPopulations, LWRRiemann
from ..timer import Stopwatch


def run_level(case_dir, level, overrides=None):
    """One level of a series: (Result, run seconds); time.end is reached even when the crowd has left."""
    case = load_case(case_dir, {**(overrides or {}), "mesh.refine": level, "output.every": 1e9})
    clock = Stopwatch()
    result = Simulation(case).run(stop_when_empty=False)
    return result, clock.seconds


def _common(result, seconds, level):
    """The columns every row has: the mesh, the run, and the invariants over every step."""
    h, s, d = result.history, result.summary, result.domain
    row = {"level": level, "cells": d.ncells, "h": d.h, "steps": s["steps"], "seconds": seconds,
           "projection_steps": s["active_set_iterations"]["steps_with_projection"],
           "mass_error": s["max_mass_error"], "min_density": float(h["min_density"].min()),
           "max_density": float(h["max_density"].max()), "min_pressure": float(h["min_pressure"].min()),
           "complementarity": s["max_complementarity"]}
    for name, entry in s.get("populations", {}).items():
        row[f"mass_error_{name}"] = entry["max_mass_error"]
        row[f"min_density_{name}"] = entry["min_density_ever"]
    return row


def crossing(domain, rho, level, x0, x1, samples=256):
    """Where the transverse average of rho crosses `level` between x0 and x1 (the first crossing, linear
    interpolation between samples h/4 apart)."""
    lo, hi = domain.points.min(0), domain.points.max(0)
    xs = np.arange(x0, x1, domain.h / 4)
    ys = lo[1] + (np.arange(samples) + 0.5) * (hi[1] - lo[1]) / samples
    X, Y = np.meshgrid(xs, ys, indexing="ij")
    cell = domain.locate(np.column_stack([X.ravel(), Y.ravel()])).reshape(X.shape)
    profile = np.where(cell >= 0, rho[np.maximum(cell, 0)], 0.0).mean(1) - level
    k = np.flatnonzero(np.sign(profile[1:]) != np.sign(profile[:-1]))[0]
    return float(xs[k] + profile[k] / (profile[k] - profile[k + 1]) * (xs[k + 1] - xs[k]))


def lwr_riemann(levels=4, kind="shock", overrides=None):
    """cases/lwr-shock or cases/lwr-fan on `levels` refinements (with `overrides`, a dict): L1 error of the density
    at t = 1, the shock position (kind "shock") or the fan's mid-point position (where rho = (left + right) / 2)."""
    exact = LWRRiemann(0.1, 0.7) if kind == "shock" else LWRRiemann(0.9, 0.1)
    rows = []
    for level in range(levels):
        result, seconds = run_level(shipped.cases(f"lwr-{kind}"), level, overrides)
        domain, state = result.domain, result.state
        reference = domain.cell_average(exact.density, t=state.t)
        mid = (exact.left + exact.right) / 2
        position = crossing(domain, state.density, mid, *exact.cuts)
        expected = exact.x0 + (exact.shock_speed if kind == "shock" else 1 - 2 * mid) * state.t
        rows.append({**_common(result, seconds, level), "l1": float(domain.area @ np.abs(state.density - reference)),
                     "position_error": position - expected})
    return rows


def head_on(levels=4, t=None):
    """Two populations (east: U = +1, west: U = -1) meeting head-on in the channel of cases/stress/head-on,
    measured when the last of each block arrives (t = 0.9): the total against solution 1 (L1, saturated
    length), each population against the mixing fan of HeadOnPopulations (L1), and the share of each
    population on the far side of the contact line x = 0."""
    exact = HeadOnPopulations(0.6, 0.5, 1.5)
    t = exact.valid_until if t is None else t
    overrides = {"initial.density": 0.0, "velocity.ux": 0.0, "time.end": t,
                 "populations.east.density": "0.6 * (x > -1.5) * (x < -0.5)", "populations.east.ux": "1",
                 "populations.west.density": "0.6 * (x > 0.5) * (x < 1.5)", "populations.west.ux": "-1"}
    rows = []
    for level in range(levels):
        result, seconds = run_level(shipped.cases("stress", "head-on"), level, overrides)
        domain, state = result.domain, result.state
        x = domain.centroid[:, 0]
        width = domain.area.sum() / 4.0
        east, west = state.rho
        far = [float(domain.area[x > 0] @ east[x > 0] / (domain.area @ east)),
               float(domain.area[x < 0] @ west[x < 0] / (domain.area @ west))]
        rows.append({**_common(result, seconds, level),
                     "l1": float(domain.area @ np.abs(state.density - domain.cell_average(exact.density, t=t))),
                     "front_error": float(domain.area[state.density >= SATURATED].sum() / (2 * width)
                                          - exact.total.front(t)),
                     "l1_east": float(domain.area @ np.abs(east - domain.cell_average(exact.density_a, t=t))),
                     "l1_west": float(domain.area @ np.abs(west - domain.cell_average(exact.density_b, t=t))),
                     "far_east": far[0], "far_west": far[1], "far_exact": exact.far_share(t)})
    return rows


def coloured_evacuation(levels=4, t=0.6):
    """Solution 3 (cases/saturated-exit) with the block in two colours (front: x < 0.5, back: 0.5 < x < 1):
    the total against the one-colour run of the same mesh (round-off) and the exact solution, each colour
    against ColouredEvacuation (L1 at t, evacuated mass: max error over the steps)."""
    exact = ColouredEvacuation(1.0, 1.0, 0.5)
    overrides = {"initial.density": 0.0, "time.end": t,
                 "populations.front.density": "1.0 * (x < 0.5)",
                 "populations.back.density": "1.0 * (x >= 0.5) * (x < 1)"}
    rows = []
    for level in range(levels):
        one, _ = run_level(shipped.cases("saturated-exit"), level, {"time.end": t})
        result, seconds = run_level(shipped.cases("saturated-exit"), level, overrides)
        domain, state, h = result.domain, result.state, result.history
        front, back = state.rho
        width = domain.area.sum() / 2.0
        times = h["time"]
        rows.append({**_common(result, seconds, level),
                     "total_vs_one_colour": float(np.abs(state.density - one.state.density).max()),
                     "l1": float(domain.area @ np.abs(state.density - domain.cell_average(exact.total.density, t=t))),
                     "l1_front": float(domain.area @ np.abs(front - domain.cell_average(exact.density_front, t=t))),
                     "l1_back": float(domain.area @ np.abs(back - domain.cell_average(exact.density_back, t=t))),
                     "evacuated_front_error": float(np.max(np.abs(
                         h["evacuated_front"] - width * np.array([exact.evacuated_front(s) for s in times])))),
                     "evacuated_back_error": float(np.max(np.abs(
                         h["evacuated_back"] - width * np.array([exact.evacuated_back(s) for s in times]))))})
    return rows


def observed_order(rows, metric):
    """The slope of log|error| against log h over the finer pair of levels."""
    e = np.abs([rows[-2][metric], rows[-1][metric]])
    return float(np.log(e[0] / e[1]) / np.log(rows[-2]["h"] / rows[-1]["h"]))


def table(rows, metrics):
    """A markdown table: cells, h, steps, run time, then each metric with its observed order."""
    lines = ["| cells | h | steps | run time (s) | " + " | ".join(metrics) + " |",
             "|---|---|---|---|" + "---|" * len(metrics)]
    for k, row in enumerate(rows):
        cells = []
        for metric in metrics:
            value = f"{row[metric]:.3g}"
            if k and metric not in ("far_east", "far_west", "far_exact") and row[metric] and rows[k - 1][metric]:
                value += f" ({observed_order(rows[k - 1:k + 1], metric):.2f})"
            cells.append(value)
        lines.append(f"| {row['cells']} | {row['h']:.3g} | {row['steps']} | {row['seconds']:.2f} | "
                     + " | ".join(cells) + " |")
    return "\n".join(lines)


def report(levels: int = 4) -> str:
    """The tables of docs/extensions.md: every study on `levels` levels, errors with observed orders, and the
    invariants over every step of every level."""
    studies = [("LWR shock (cases/lwr-shock, t = 1)", lwr_riemann(levels, "shock"), ["l1", "position_error"]),
               ("LWR fan (cases/lwr-fan, t = 1)", lwr_riemann(levels, "fan"), ["l1", "position_error"]),
               ("Two populations head-on (t = 0.9)", head_on(levels),
                ["l1", "front_error", "l1_east", "l1_west", "far_east", "far_west", "far_exact"]),
               ("Saturated evacuation in two colours (t = 0.6)", coloured_evacuation(levels),
                ["l1", "l1_front", "l1_back", "evacuated_front_error", "evacuated_back_error"])]
    parts = []
    for title, rows, metrics in studies:
        worst = {k: max(abs(r[k]) for r in rows) for k in rows[0] if k.startswith(("mass_error", "total_vs"))}
        parts.append(f"\n{title}; error (observed order)\n\n{table(rows, metrics)}\n\nover every step of every "
                     "level: " + ", ".join(f"{k} <= {v:.1e}" for k, v in worst.items())
                     + f"; min density {min(r['min_density'] for r in rows):.2g}, max density "
                     f"{max(r['max_density'] for r in rows):.12g}; steps with a projection "
                     f"{[r['projection_steps'] for r in rows]}")
    return "\n".join(parts)
