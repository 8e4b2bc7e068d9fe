"""The Python API for notebooks (docs/api.md): a scene from shapely geometry (or a floor-plan dict) and settings in
memory, run by either model, its results as pandas DataFrames and numpy arrays, its figures as matplotlib Figures.

    from shapely import LineString, box
    import femcrowd.api as fc
    scene = fc.Scene(box(0, 0, 10, 6), exits={"exit": LineString([(10, 2.5), (10, 3.5)])},
                     settings={"initial": {"people": 60}, "time": {"end": 30}})
    run = scene.run()
    run.history, run.doors, run.density(10.0), run.plot_map(10.0)

The plan goes through the checks and the mesher of ``femcrowd mesh`` (mesh/plan.py, mesh/floorplan.py), the
settings through those of a case file (case/loading.py, the keys of docs/case-format.md); the run is
``femcrowd.Simulation`` without files. The mesh is written to a temporary directory of the Scene (gmsh writes
files), removed with it: nothing is left on disk.
"""

import tempfile
from pathlib import Path

import numpy as np

from .case.loading import case_from_dict
from .driver.run import Simulation
from .mesh.cad import polygon_plan
from .mesh.floorplan import mesh_plan
from .mesh.plan import PlanReader, check_plan

#: the name of the in-memory scene in error messages (there is no file)
SOURCE = "<femcrowd.api scene>"


def _segment(name, line) -> dict:
    """{"name", "from", "to"} of a shapely LineString (or a pair of points)."""
    coords = list(getattr(line, "coords", line))
    return {"name": name, "from": [float(c) for c in coords[0][:2]], "to": [float(c) for c in coords[-1][:2]]}


def plan_from_shapely(walkable, exits, doors=None, obstacles=(), walls=(), size=0.25) -> dict:
    """A floor plan (the tables of a TOML plan, docs/plans.md) from shapely geometry: the walkable area (a Polygon,
    its holes obstacles), more obstacles (Polygons, cut out of it), internal walls (LineStrings), the exits and the
    interior doors ({name: LineString}); size: the cell size (m)."""
    import shapely

    area = shapely.difference(walkable, shapely.union_all(list(obstacles))) if obstacles else walkable
    if area.geom_type != "Polygon":
        raise ValueError(f"the walkable area less the obstacles is a {area.geom_type}, not one polygon")
    return {"size": size, **polygon_plan(area, walls), "exits": [_segment(name, line) for name, line in exits.items()],
            "doors": [_segment(name, line) for name, line in (doors or {}).items()]}


class Scene:
    """A floor plan and the settings of a case, in memory.

    walkable: a shapely Polygon, or a floor-plan dict (docs/plans.md, as a TOML plan's tables; then exits, doors,
    obstacles, walls and size are in it); settings: the tables of a case file without [mesh] file, e.g.
    ``{"initial": {"people": 100}, "model": {"rho_max": 5.4}}``; ``boundary.exits`` defaults to every exit.
    Bad geometry or settings raise InputError naming the key, as for files.
    """

    def __init__(self, walkable, exits=None, doors=None, obstacles=(), walls=(), size=0.25, settings=None):
        plan = walkable if isinstance(walkable, dict) else plan_from_shapely(walkable, exits or {}, doors, obstacles,
                                                                             walls, size)
        self.plan = check_plan(plan, PlanReader(SOURCE))
        self.settings = settings or {}
        self._directory = tempfile.TemporaryDirectory(prefix="femcrowd-scene-")
        self.mesh = mesh_plan(self.plan, Path(self._directory.name) / "scene.msh", "scene")
        self.exit_names = list(dict.fromkeys(e[3] for e in self.plan[3]))

    def case(self, **settings):
        """The case (case/loading.py Case) of the scene's settings updated by `settings` (tables, e.g.
        ``time={"end": 10}``), checked as a case file is."""
        raw = {name: dict(table) if isinstance(table, dict) else table for name, table in self.settings.items()}
        for name, table in settings.items():
            raw[name] = {**raw.get(name, {}), **table} if isinstance(table, dict) else table
        raw["mesh"] = {**raw.get("mesh", {}), "file": str(self.mesh)}
        raw["boundary"] = {"exits": self.exit_names, **raw.get("boundary", {})}
        return case_from_dict(raw, SOURCE)

    def run(self, every=None, **settings) -> "Run":
        """Run the scene (``model={"type": "micro"}`` for discs) without files; the state is kept every `every`
        seconds (default: output.every, the frame times of `femcrowd run`; steps land on these times) for the
        maps."""
        return Run(self, self.case(**settings), every)

    def plot(self, **settings):
        """The plan at t = 0 with the initial crowd and the doors (a matplotlib Figure), before any run."""
        return Run(self, self.case(**settings), run=False).plot_map(0.0, title="the scene: initial crowd")


class Run:
    """A finished run of a Scene: its history, door numbers and the states kept at its frame times."""

    def __init__(self, scene, case, every=None, run=True):
        from .plot.pictures import FloorPlan

        self.scene, self.case = scene, case
        self.simulation = Simulation(case)
        model = self.simulation.model
        every = every or case["output"]["every"]
        self.times, self._states, self.result = [], [], None
        self._keep(model)
        if run:   # run=False: the set-up alone, its initial state (Scene.plot)
            stops = np.arange(1, int(np.floor(case["time"]["end"] / every + 1e-9)) + 1) * every
            self.result = self.simulation.run(stops=tuple(stops), on_stop=lambda recorder: self._keep(model))
            if self.times[-1] < model.t:
                self._keep(model)
        self.boundary = self.simulation.scene.boundary
        self.plan = FloorPlan.of(self.boundary)

    def _keep(self, model):
        """The state at model.t: the cell densities (macro, in the case's unit) or the discs' centres and radii."""
        state = model.state
        if hasattr(state, "rho"):
            self._states.append(state.rho.sum(axis=0) * self.case["model"]["rho_max"])
        else:
            self._states.append((state.q.copy(), state.r.copy()))
        self.times.append(float(model.t))

    @property
    def summary(self) -> dict:
        return self.result.summary

    @property
    def history(self):
        """history.csv as a pandas DataFrame (one row per step, the columns of docs/case-format.md, "Outputs")."""
        import pandas as pd

        return pd.DataFrame(self.result.history)

    @property
    def doors(self):
        """One row per door: kind, width, capacity, people through, mean and peak flow, time at capacity
        (report/numbers.py door_numbers)."""
        import pandas as pd

        from .report.numbers import door_numbers

        rows = door_numbers(self.result.history, self.boundary.doors, self.case["model"]["rho_max"])
        return pd.DataFrame.from_dict(rows, orient="index")

    @property
    def times_out(self) -> dict:
        """t50, t90, t99 (s): when 50, 90, 99 % of everyone ever inside are out (nan: never)."""
        from .report.numbers import share_times

        return share_times(self.result.history)

    def _index(self, t) -> int:
        return int(np.argmin(np.abs(np.asarray(self.times) - t)))

    def density(self, t):
        """The cell densities (macro; numpy array, the case's unit) of the kept state nearest to t."""
        return self._states[self._index(t)]

    def discs(self, t):
        """(centres (n, 2), radii (n,)) of the discs (micro) at the kept state nearest to t."""
        return self._states[self._index(t)]

    @property
    def cells(self):
        """The cells of the mesh as a DataFrame: centroid x, y (m) and area (m^2), in the order of density()."""
        import pandas as pd

        domain = self.simulation.scene.domain
        return pd.DataFrame({"x": domain.centroid[:, 0], "y": domain.centroid[:, 1], "area": domain.area})

    def plot_map(self, t, level_of_service=False, title=None):
        """The density (or Fruin's level of service of it; micro: the discs) at the kept time nearest to t on the
        plan with its doors, a matplotlib Figure."""
        from .report.figures import door_names, map_figure

        k = self._index(t)
        domain, state = self.simulation.scene.domain, self._states[k]
        cells, discs = ((domain.points, domain.triangles, state), None) if isinstance(state, np.ndarray) else \
            (None, state)
        names = door_names(self.boundary.doors, self.case["model"]["rho_max"])
        title = title or ("level of service" if level_of_service else "density" if cells else "discs")
        return map_figure(self.plan, self.times[k], title, self.case.config, cells, discs, names, level_of_service)

    def plot_nt(self):
        """The N-t curves (inside, out, through each door) with t50, t90, t99 marked, a matplotlib Figure."""
        from .report.figures import nt_figure
        from .report.numbers import door_curves

        h = self.result.history
        return nt_figure(h, self.case.config, door_curves(h, self.boundary.doors), self.times_out)
