"""Floor plans to gmsh meshes (MSH 2.2) with named boundary groups.

The plan (TOML, or a DXF drawing or WKT polygon) is read and checked by :mod:`femcrowd.mesh.plan`, its internal
walls cut out by :mod:`femcrowd.mesh.partitions`; the format and its rules are docs/plans.md.

Exits split the edge they lie on, and so do the ends of doors. The mesh has
one physical line group per exit name and per door name, "wall" for every
other boundary curve (outer and holes) and the physical surface "domain". Triangles come from gmsh's Frontal-Delaunay
algorithm with a few smoothing passes: nearly equilateral and Delaunay (the
two angles opposite an interior edge sum to at most pi), so the circumcentre
distances used by the two-point flux are positive. They are also almost all
non-obtuse, which a uniform refinement needs to stay Delaunay (it copies each
angle of a triangle to both sides of the inner edge facing it).
"""


import pathlib
from collections import defaultdict

import gmsh
import numpy as np

from ..errors import InputError
from ..files import make_directory, replaced
from .building import read_toml_building
from .cad import read_plan
from .plan import PlanReader, polygon_edges, read_toml_plan


def _split(loops, exits, tol, ends=np.zeros((0, 2))):
    """Boundary loops split at the exit ends and at the points `ends` (the ends of doors) that lie on them:
    [(points, labels, exit index or None per segment)]."""
    out, first = [], 0
    for p in loops:
        pts, labels, ids = [], [], []
        for i, (a, b) in enumerate(zip(*polygon_edges(p))):
            mine = [(k, t0, t1) for k, (e, t0, t1, *_) in enumerate(exits) if e == first + i]
            t = (ends - a) @ (b - a) / ((b - a) @ (b - a))
            on = (np.linalg.norm(ends - a - t[:, None] * (b - a), axis=1) <= tol) & (t > 0) & (t < 1)
            ts = np.unique([0.0, 1.0] + [t for _, t0, t1 in mine for t in (t0, t1)] + list(t[on]))
            ts = ts[np.r_[True, np.diff(ts) * np.linalg.norm(b - a) > tol]]
            ts[-1] = 1.0
            for s0, s1 in zip(ts[:-1], ts[1:]):
                k = next((k for k, t0, t1 in mine if t0 <= (s0 + s1) / 2 <= t1), None)
                pts.append(a + s0 * (b - a))
                labels.append("wall" if k is None else exits[k][3])
                ids.append(k)
        out.append((np.array(pts), labels, ids))
        first += len(p)
    return out


def build_mesh(geometry_file, out=None, refine_exits=None, gmsh_options=None, cad=None,
               require_exits=False) -> pathlib.Path:
    """Mesh the floor plan ``geometry_file`` (TOML; or a DXF drawing or WKT polygon, mesh/cad.py) and write it
    as MSH 2.2.

    out: the .msh path (default: next to the plan, same stem).
    refine_exits: local cell size near every exit, overriding the per-exit
    ``size`` keys (None: use them).
    gmsh_options: gmsh options overriding femcrowd's (frontal-Delaunay,
    ``Mesh.Algorithm`` 6, with ``Mesh.Smoothing`` 5), e.g. for benchmarks.
    cad: options of the DXF / WKT reader (mesh/cad.py: layer names, size, extra exits, units, wall thickness).
    require_exits: a plan without an exit is an error (``femcrowd mesh`` without ``--no-exits``).
    Raises InputError for a bad floor plan or output path, before meshing; the mesh is written whole or not
    at all (files.replaced: gmsh does not report a full disk, the file's last section is checked), so that a
    failure leaves the `out` there was.
    """
    geometry_file = pathlib.Path(geometry_file)
    out = pathlib.Path(out) if out is not None else geometry_file.with_suffix(".msh")
    if out.is_dir():
        raise InputError(out, None, None, "is a directory: -o names the .msh file to write (e.g. -o "
                         f"{out / geometry_file.with_suffix('.msh').name})")
    if out.suffix.lower() != ".msh":
        raise InputError(out, None, None, "femcrowd mesh writes gmsh .msh files only: give -o a name ending in .msh")
    if geometry_file.suffix.lower() in (".dxf", ".wkt"):
        plan = read_plan(geometry_file, **(cad or {}), require_exits=require_exits)
    else:
        unused = [f"--{k.replace('_', '-')}" for k in ("units", "wall_thickness") if (cad or {}).get(k) is not None]
        if unused:
            raise InputError(geometry_file, unused[0], cad[unused[0][2:].replace("-", "_")],
                             "for DXF and WKT plans only: a TOML plan is in metres, its walls have a 'thickness'")
        plan = read_toml_building(geometry_file, require_exits) or read_toml_plan(geometry_file, require_exits)
    if refine_exits is not None:
        refine_exits = PlanReader(geometry_file).size("refine_exits", refine_exits)
    return mesh_plan(plan, out, geometry_file.stem, refine_exits, gmsh_options)


def mesh_plan(plan, out, name="plan", refine_exits=None, gmsh_options=None) -> pathlib.Path:
    """Mesh a checked floor plan (what plan.check_plan returns, or a building: read_toml_building) and write it
    to `out` as MSH 2.2, whole or not at all; ``build_mesh`` of a plan file, and of a plan given in memory
    (femcrowd.api)."""
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        gmsh.model.add(name)
        if len(plan) == 3:   # a building: (size, floors, stairs)
            size, floors, stairs = plan
            _exit_sizes(*_building_geometry(floors, stairs), size, refine_exits)
        else:
            size, loops, circles, exits, tol, doors = plan
            _exit_sizes(exits, _geometry(loops, circles, exits, doors, tol), size, refine_exits)
        options = {"Mesh.MeshSizeMax": size, "Mesh.MeshSizeFromPoints": 0, "Mesh.MeshSizeExtendFromBoundary": 0,
                   "Mesh.Algorithm": 6, "Mesh.Smoothing": 5, "Mesh.MshFileVersion": 2.2, "Mesh.Binary": 0}
        for option, value in {**options, **(gmsh_options or {})}.items():
            gmsh.option.setNumber(option, value)
        gmsh.model.mesh.generate(2)
        with replaced(make_directory(out.parent) / out.name, sync=True) as tmp:
            try:
                gmsh.write(str(tmp))
            except Exception as err:   # gmsh raises Exception; on a full disk it may write part and say nothing
                raise InputError(out, None, None, f"cannot write the mesh: {err}") from None
    finally:
        gmsh.finalize()
    return out


def _geometry(loops, circles, exits, doors, tol) -> dict:
    """The plan in gmsh's geo kernel: the boundary loops split at the exits and at the doors' ends, the circle
    holes, the doors embedded in the surface; one physical line group per exit and door name, "wall" for the
    rest, the surface "domain". Returns the curves of each exit (by its index)."""
    geo = gmsh.model.geo
    curve_loops, groups, exit_curves = [], defaultdict(list), defaultdict(list)
    ends = np.array([end for door in doors for end in door[:2]]).reshape(-1, 2)
    corners = []   # (x, y, tag) of the boundary points, where the doors' ends may join them
    for pts, labels, ids in _split(loops, exits, tol, ends):
        tags = [geo.addPoint(x, y, 0) for x, y in pts]
        corners += [(x, y, tag) for (x, y), tag in zip(pts, tags)]
        lines = [geo.addLine(s, e) for s, e in zip(tags, tags[1:] + tags[:1])]
        curve_loops.append(geo.addCurveLoop(lines))
        for line, label, k in zip(lines, labels, ids):
            groups[label].append(line)
            if k is not None:
                exit_curves[k].append(line)
    for _, c, r in circles:
        centre = geo.addPoint(*c, 0)
        rim = [geo.addPoint(*(c + r * np.array([np.cos(a), np.sin(a)])), 0) for a in np.pi / 2 * np.arange(4)]
        arcs = [geo.addCircleArc(s, centre, e) for s, e in zip(rim, rim[1:] + rim[:1])]
        curve_loops.append(geo.addCurveLoop(arcs))
        groups["wall"] += arcs
    surface = geo.addPlaneSurface(curve_loops)
    door_lines = []
    for start, end, name in doors:
        tags = [next((tag for x, y, tag in corners if np.hypot(x - p[0], y - p[1]) <= tol), None)
                or geo.addPoint(p[0], p[1], 0) for p in (start, end)]
        door_lines.append(geo.addLine(*tags))
        groups[name].append(door_lines[-1])
    geo.synchronize()
    if door_lines:
        gmsh.model.mesh.embed(1, door_lines, 2, surface)
    for name, curves in groups.items():
        gmsh.model.addPhysicalGroup(1, curves, name=name)
    gmsh.model.addPhysicalGroup(2, [surface], name="domain")
    return exit_curves


def _exit_sizes(exits, exit_curves, size, refine_exits) -> None:
    """The cell size near the exits: h at an exit (its own `size`, or refine_exits), growing linearly to `size`."""
    fields = []
    for k, (*_, h, length) in enumerate(exits):
        h = refine_exits or h
        if h is None or h >= size:
            continue
        dist = gmsh.model.mesh.field.add("Distance")
        gmsh.model.mesh.field.setNumbers(dist, "CurvesList", exit_curves[k])
        gmsh.model.mesh.field.setNumber(dist, "Sampling", int(np.ceil(4 * length / h)) + 20)
        fields.append(gmsh.model.mesh.field.add("Threshold"))
        for option, value in [("InField", dist), ("SizeMin", h), ("SizeMax", size),
                              ("DistMin", 2 * h), ("DistMax", 2 * h + 5 * (size - h))]:
            gmsh.model.mesh.field.setNumber(fields[-1], option, value)
    if fields:
        smallest = gmsh.model.mesh.field.add("Min")
        gmsh.model.mesh.field.setNumbers(smallest, "FieldsList", fields)
        gmsh.model.mesh.field.setAsBackgroundMesh(smallest)


def _building_geometry(floors, stairs) -> tuple:
    """The building in gmsh's geo kernel: each floor's loops at its elevation (split at its exits and at its stair
    ends), each stair a plane surface through the curves of its foot and head; physical groups as the module says,
    and the line groups <stair>_foot and <stair>_head, interior doors (a capacity, a flow column).
    Returns the exits of every floor (stair ends left out) and the curves of each, as _exit_sizes takes them."""
    geo = gmsh.model.geo
    groups, surfaces, all_exits, exit_curves = defaultdict(list), {}, [], defaultdict(list)
    stair_names = {s[0] for s in stairs}
    landing = defaultdict(list)   # stair name -> [(elevation, line, its end points)] of its foot and head
    for name, z, (_, loops, circles, exits, tol, _) in floors:
        curve_loops, first = [], len(all_exits)
        all_exits += [e for e in exits if e[3] not in stair_names]
        number = {k: first + sum(e[3] not in stair_names for e in exits[:k]) for k in range(len(exits))}
        for pts, labels, ids in _split(loops, exits, tol):
            tags = [geo.addPoint(x, y, z) for x, y in pts]
            lines = [geo.addLine(s, e) for s, e in zip(tags, tags[1:] + tags[:1])]
            curve_loops.append(geo.addCurveLoop(lines))
            for line, label, k, ends in zip(lines, labels, ids, zip(tags, tags[1:] + tags[:1])):
                if label in stair_names:
                    landing[label].append((z, line, ends))
                else:
                    groups[label].append(line)
                    if k is not None:
                        exit_curves[number[k]].append(line)
        for _, c, radius in circles:
            centre = geo.addPoint(*c, z)
            rim = [geo.addPoint(*(c + radius * np.array([np.cos(a), np.sin(a)])), z) for a in np.pi / 2 * np.arange(4)]
            arcs = [geo.addCircleArc(s, centre, e) for s, e in zip(rim, rim[1:] + rim[:1])]
            curve_loops.append(geo.addCurveLoop(arcs))
            groups["wall"] += arcs
        surfaces[name] = geo.addPlaneSurface(curve_loops)
    for name, *_ in stairs:
        (_, foot, (a, b)), (_, head, (c, d)) = sorted(landing[name])   # one line each, the foot first
        # the foot runs a -> b; the head must run from the end beside b
        if np.linalg.norm(_xy(b) - _xy(d)) < np.linalg.norm(_xy(b) - _xy(c)):
            head, c, d = -head, d, c
        sides = [geo.addLine(b, c), geo.addLine(d, a)]
        loop = [foot, sides[0], head, sides[1]]
        corners = np.array([_xy(p) for p in (a, b, c, d)])
        if (corners[:, 0] * np.roll(corners[:, 1], -1) - np.roll(corners[:, 0], -1) * corners[:, 1]).sum() < 0:
            loop = [-line for line in loop[::-1]]   # counter-clockwise in plan, as the floors' triangles
        surfaces[name] = geo.addPlaneSurface([geo.addCurveLoop(loop)])
        groups["wall"] += sides
        groups[f"{name}_foot"], groups[f"{name}_head"] = [abs(foot)], [abs(head)]   # interior lines: doors
    geo.synchronize()
    for name, curves in groups.items():
        gmsh.model.addPhysicalGroup(1, curves, name=name)
    for name, surface in surfaces.items():
        gmsh.model.addPhysicalGroup(2, [surface], name=name)
    return all_exits, exit_curves


def _xy(point):
    """The plan coordinates of a geo point."""
    gmsh.model.geo.synchronize()
    return np.array(gmsh.model.getValue(0, point, [])[:2])

