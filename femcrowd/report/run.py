"""What the report of one run shows (``femcrowd report OUTDIR``), gathered from its directory: the scene, the
headline times, the N-t curves, the doors, who is left, the maps at the chosen times."""

import numpy as np

from ..case.units import counts_people, people_unit
from ..driver.reading import read_history
from ..driver.remaining import remaining_text
from ..plot.pictures import FloorPlan, default_times, frame_index
from .figures import data_uri, door_names, frame_figure, nt_figure
from .numbers import cell_adjacency, door_curves, door_numbers, line_numbers, queues, share_times


def longest_queues(run, plan) -> dict:
    """{door name: (people, time)} of the largest queue over the density frames (macro runs with their mesh)."""
    if "solution" not in run.frames or plan.boundary is None:
        return {}
    domain, doors = plan.boundary.domain, plan.boundary.doors
    adjacency, best = cell_adjacency(domain), {door.name: (0.0, 0.0) for door in doors}
    for k, (t, _) in enumerate(run.frames["solution"]):
        density = np.asarray(run.frame("solution", k).cell_data["density"][0]).ravel()
        for name, people in queues(domain, doors, density, run.rho_max, adjacency).items():
            if people > best[name][0]:
                best[name] = (people, t)
    return best


def run_context(run, times=None) -> dict:
    """The values and figures of a run's page (report/page.py), from its RunDirectory."""
    summary, case, h = run.summary, run.case, run.history
    plan = FloorPlan(run)
    doors = plan.boundary.doors if plan.boundary is not None else []
    stem = "solution" if "solution" in run.frames else "discs"
    rows = door_numbers(h, doors, run.rho_max) if h else {}
    for name, (people, t) in longest_queues(run, plan).items():
        rows[name].update(queue=people, queue_time=t)
    if (run.directory / "measurements.csv").is_file():
        lines = case.get("measure", {}).get("lines", [])
        lengths = {line["name"]: float(np.hypot(*np.subtract(line["to"], line["from"]))) for line in lines}
        rows.update(line_numbers(read_history(run.directory / "measurements.csv"), lengths))
    shares = share_times(h) if h else {}
    names = door_names(doors, run.rho_max)
    series = run.frames[stem]
    chosen = frame_index(series, times if times else default_times(run, series), run.directory)
    maps = [data_uri(frame_figure(run, plan, k, "density" if stem == "solution" else "discs", names))
            for k in chosen]
    service = counts_people(case) and stem == "solution"
    if service:
        maps += [data_uri(frame_figure(run, plan, k, "level of service", names, level_of_service=True))
                 for k in chosen]
    unit = people_unit(case)
    remaining = summary.get("remaining")
    return {
        "title": run.title, "directory": str(run.directory), "unit": unit,
        "version": summary.get("femcrowd", "unknown"), "status": summary.get("status", "no summary.json"),
        "model": case.get("model", {}).get("type", "macro"), "rho_max": run.rho_max,
        "mesh": summary.get("mesh", {}),
        "checks": {name: summary[key] for name, key in (("relative mass error", "mass_error"),
                                                          ("least density", "min_density_ever"),
                                                          ("largest density", "max_density_ever"),
                                                          ("least pressure", "min_pressure_ever"))
                   if summary.get(key) is not None},
        "people": float(h["count" if "count" in h else "mass"][0]) if h else None,
        "arrived": float(h["inflow"][-1]) if "inflow" in h else None,
        "populations": {name: value.get("initial_mass", value.get("initial_count"))
                        for name, value in summary.get("populations", {}).items()},
        "case_text": (run.directory / "case.toml").read_text() if (run.directory / "case.toml").is_file() else "",
        "evacuation_time": summary.get("evacuation_time"), "final_time": summary.get("final_time"),
        "shares": shares, "doors": rows,
        "remaining": remaining_text(remaining, unit) if remaining else None,
        "remaining_by": remaining.get("by_reason", {}) if remaining else {},
        "remaining_populations": remaining.get("per_population", {}) if remaining else {},
        "plan": data_uri(frame_figure(run, plan, 0, "the scene: initial crowd", names)),
        "nt": data_uri(nt_figure(h, case, door_curves(h, doors), shares)) if h else None,
        "maps": maps, "service": service,
        "left": data_uri(frame_figure(run, plan, -1, "left inside", names))
        if remaining and remaining.get("reason") != "evacuated" else None,
    }
