"""The numbers of a run's report (``femcrowd report``), from what the run wrote (history.csv, the frames,
summary.json): the times at which shares of the crowd are out, and per door the people through, the mean and
peak flow, the time at capacity and the longest queue.

Definitions (docs/tools.md, "Report"):

- t50, t90, t99: the first times at which 50, 90, 99 % of everyone who was ever inside (the initial crowd and
  the arrivals) are out (``evacuation_times`` of studies/evacuation.py, linear between the steps);
- people through a door: an exit's ``evacuated_<exit>``; a door with a capacity between two rooms: its flow
  ``flow_<door>`` summed over the steps (flow x dt);
- peak flow: the largest mean flow over time bins of PEAK_BIN seconds (at least two steps);
- mean flow: the people between the first and the last MEAN_SHARE of them, over the time they took;
- counting lines ([[measure.lines]], measurements.csv): the same, of their signed count ``<line>_count``;
- time at capacity: the seconds of the steps whose flow is the door's capacity x width (to 1e-9, as the run's
  ``steps_at_capacity``);
- queue at a door (macro): the people in the connected set of cells at a density of at least QUEUE_DENSITY x
  rho_max that touches the door (Fruin's level of service F starts at 2.17 of Weidmann's 5.4 persons/m^2); its
  largest value over the frames is the longest queue.
"""

import numpy as np
import scipy.sparse as sp
from scipy.sparse.csgraph import connected_components

from ..plot.pictures import binned_rate
from ..studies.evacuation import evacuation_times

SHARES = (0.5, 0.9, 0.99)
PEAK_BIN = 1.0          # s: the bins of the peak flow
MEAN_SHARE = 0.01       # the mean flow is taken from the first to the last 1 % of the people through a door
QUEUE_DENSITY = 0.4     # x rho_max: a queue's cells (2.17 / 5.4, Fruin's level F)


def inside_and_out(history) -> tuple:
    """(time, people inside, people out) of a history (macro: mass; micro: count)."""
    return history["time"], history["mass" if "mass" in history else "count"], history["evacuated"]


def share_times(history) -> dict:
    """{"t50": ..., "t90": ..., "t99": ...} (nan: never reached) of everyone ever inside."""
    t, inside, out = inside_and_out(history)
    total = inside[0] + (history["inflow"][-1] if "inflow" in history else 0.0)
    times = evacuation_times(t[1:], out[1:], total, SHARES) if total > 0 else [np.nan] * len(SHARES)
    return {f"t{100 * share:g}": value for share, value in zip(SHARES, times)}


def door_curves(history, doors) -> dict:
    """{door name: cumulative people through it at the history's times} of the exits (``evacuated_<name>``) and of
    the doors with a flow column (``flow_<name>``: a door with a capacity between two rooms)."""
    t, curves = history["time"], {}
    for door in doors:
        if door.exit and f"evacuated_{door.name}" in history:
            curves[door.name] = history[f"evacuated_{door.name}"]
        elif f"flow_{door.name}" in history:
            curves[door.name] = np.cumsum(history[f"flow_{door.name}"] * np.diff(t, prepend=t[0]))
    return curves


def flow_numbers(time, curve) -> dict:
    """People through (the curve's last value), mean and peak flow of a cumulative count over time."""
    dt = np.diff(time, prepend=time[0])
    width = max(PEAK_BIN, 2 * float(np.median(dt[1:]))) if len(time) > 2 else PEAK_BIN
    through = float(curve[-1]) if len(curve) else np.nan
    row = {"through": through, "mean_flow": np.nan, "peak_flow": np.nan}
    if len(time) > 1:
        row["peak_flow"] = float(np.max(binned_rate(time, curve, width)[1]))
        if through > 0:
            first, last = np.interp([MEAN_SHARE * through, (1 - MEAN_SHARE) * through], curve, time)
            row["mean_flow"] = (1 - 2 * MEAN_SHARE) * through / (last - first) if last > first else np.nan
    return row


def door_numbers(history, doors, rho_max) -> dict:
    """Per door (mesh/boundary.py Door) its row of the report: kind, width, capacity (persons/(m s), None
    without), people through, mean and peak flow (people/s), seconds at capacity (None without a capacity)."""
    t, rows = history["time"], {}
    dt = np.diff(t, prepend=t[0])
    curves = door_curves(history, doors)
    for door in doors:
        capacity = door.capacity * rho_max if door.capped else None
        row = {"kind": "exit" if door.exit else "interior door", "width": door.width, "capacity": capacity,
               "through": np.nan, "mean_flow": np.nan, "peak_flow": np.nan, "at_capacity": None}
        if door.name in curves:
            row.update(flow_numbers(t, curves[door.name]))
        if capacity is not None and f"flow_{door.name}" in history:
            full = history[f"flow_{door.name}"] >= (1 - 1e-9) * capacity * door.width
            row["at_capacity"] = float(np.sum(dt[full & (history[f"flow_{door.name}"] > 0)]))
        rows[door.name] = row
    return rows


def line_numbers(measurements, lengths) -> dict:
    """Per counting line of measurements.csv (``<line>_count``, the signed count left to right) its row of the
    door table, as "line <name>": people through (net), mean and peak flow; lengths: {line: length (m)}."""
    t = measurements["time"]
    return {f"line {name}": {"kind": "counting line", "width": lengths.get(name, np.nan), "capacity": None,
                   **flow_numbers(t, measurements[f"{name}_count"]), "at_capacity": None}
            for name in (c[: -len("_count")] for c in measurements if c.endswith("_count"))}


def cell_adjacency(domain) -> sp.csr_matrix:
    """The cells' adjacency through the interior facets (f2t of the mesh), a symmetric sparse matrix."""
    a, b = domain.f2t[:, domain.interior]
    n = domain.ncells
    return sp.coo_matrix((np.ones(len(a)), (a, b)), shape=(n, n)).tocsr()


def queues(domain, doors, density, rho_max, adjacency=None) -> dict:
    """{door name: people in its queue} for one frame's cell densities (in the run's unit): the connected
    components of the cells at QUEUE_DENSITY x rho_max or more that hold a cell next to the door."""
    adjacency = cell_adjacency(domain) if adjacency is None else adjacency
    dense = density >= QUEUE_DENSITY * rho_max
    keep = sp.diags(dense.astype(float))
    _, label = connected_components(keep @ adjacency @ keep, directed=False)
    people = np.bincount(label, np.where(dense, density * domain.area, 0.0))
    result = {}
    for door in doors:
        cells = domain.f2t[:, door.facets].ravel()
        cells = cells[cells >= 0]
        result[door.name] = float(people[np.unique(label[cells[dense[cells]]])].sum())
    return result
