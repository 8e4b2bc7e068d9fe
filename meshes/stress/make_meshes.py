"""Build the meshes of the stress scenes (cases/stress): python meshes/stress/make_meshes.py

- every ``*.toml`` floor plan here -> ``*.msh`` with femcrowd.geometry.build_mesh;
- ``trapped.msh``: two rooms that do not touch, only the left one has an exit
  (gmsh; surface groups ``open_room`` and ``trapped_room``);
- ``slivers.msh``: a hand-made triangulation of [0, 2] x [0, 1] that gmsh would
  never produce: jittered grid nodes (non-Delaunay pairs) and a strip of caps
  (angles near 180 degrees) and needles along x = 1 (meshio, MSH 2.2).

The outputs are deterministic (fixed seed) and committed next to this script.
"""

import pathlib

import gmsh
import meshio
import numpy as np

from femcrowd.geometry import build_mesh

HERE = pathlib.Path(__file__).resolve().parent


def trapped(out, size=0.05):
    """Room [0, 1]^2 with its side x = 0 as exit, and a closed room [1.5, 2.5] x [0, 1]."""
    gmsh.initialize(readConfigFiles=False, interruptible=False)
    try:
        gmsh.option.setNumber("General.Terminal", 0)
        geo = gmsh.model.geo
        surfaces, lines = [], {}
        for name, x0 in (("open_room", 0.0), ("trapped_room", 1.5)):
            pts = [geo.addPoint(x, y, 0, size) for x, y in ((x0, 0), (x0 + 1, 0), (x0 + 1, 1), (x0, 1))]
            lines[name] = [geo.addLine(a, b) for a, b in zip(pts, pts[1:] + pts[:1])]
            surfaces.append((name, geo.addPlaneSurface([geo.addCurveLoop(lines[name])])))
        geo.synchronize()
        exit_line = lines["open_room"][3]  # (0, 1) -> (0, 0)
        walls = [c for cs in lines.values() for c in cs if c != exit_line]
        gmsh.model.addPhysicalGroup(1, [exit_line], name="exit")
        gmsh.model.addPhysicalGroup(1, walls, name="wall")
        for name, s in surfaces:
            gmsh.model.addPhysicalGroup(2, [s], name=name)
        for option, value in [("Mesh.Algorithm", 5), ("Mesh.Smoothing", 0),
                              ("Mesh.MshFileVersion", 2.2), ("Mesh.Binary", 0)]:
            gmsh.option.setNumber(option, value)
        gmsh.model.mesh.generate(2)
        gmsh.write(str(out))
    finally:
        gmsh.finalize()


def _zip(left, right, y):
    """Triangulate the strip between two node chains (index arrays sorted by height y, same ends)."""
    tris, i, j = [], 0, 0
    while i < len(left) - 1 or j < len(right) - 1:
        if j == len(right) - 1 or (i < len(left) - 1 and y[left[i + 1]] <= y[right[j + 1]]):
            tris.append((left[i], right[j], left[i + 1]))
            i += 1
        else:
            tris.append((left[i], right[j], right[j + 1]))
            j += 1
    return tris


def slivers(out, h=0.1, gap=0.004, jitter=0.25, seed=0):
    """[0, 2] x [0, 1]: grid of size h with jittered interior nodes, plus a column of nodes at
    x = 1 + gap placed at mid-heights, which makes caps (angle ~ 170 deg) and needles."""
    rng = np.random.default_rng(seed)
    ys = np.linspace(0, 1, round(1 / h) + 1)
    columns, points = [], []
    xs = list(np.linspace(0, 2, round(2 / h) + 1))
    xs.insert(xs.index(1.0) + 1, 1.0 + gap)
    for x in xs:
        yc = np.r_[0.0, ys[:-1] + h / 2, 1.0] if x == 1.0 + gap else ys
        columns.append(np.arange(len(points), len(points) + len(yc)))
        points += [(x, y) for y in yc]
    p = np.array(points)
    tris = [t for a, b in zip(columns, columns[1:]) for t in _zip(a, b, p[:, 1])]
    # jitter nodes off the boundary and off the sliver strip (connectivity fixed: non-Delaunay pairs)
    free = (p[:, 0] > 0) & (p[:, 0] < 2) & (p[:, 1] > 0) & (p[:, 1] < 1) & (np.abs(p[:, 0] - 1 - gap / 2) > gap)
    p[free] += jitter * h * rng.uniform(-1, 1, (free.sum(), 2))
    t = np.array(tris)
    a, b, c = p[t[:, 0]], p[t[:, 1]], p[t[:, 2]]
    cross = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0])
    t[cross < 0] = t[cross < 0][:, [0, 2, 1]]
    assert np.all(np.abs(cross) > 0)
    # boundary edges: those in a single triangle; the side x = 0 is the exit
    edges = np.sort(np.concatenate([t[:, [0, 1]], t[:, [1, 2]], t[:, [2, 0]]]), axis=1)
    unique, count = np.unique(edges, axis=0, return_counts=True)
    boundary = unique[count == 1]
    on_exit = np.all(p[boundary, 0] == 0.0, axis=1)
    tags = np.where(on_exit, 1, 2)
    mesh = meshio.Mesh(np.column_stack([p, np.zeros(len(p))]), [("line", boundary), ("triangle", t)],
                       cell_data={"gmsh:physical": [tags, np.full(len(t), 3)],
                                  "gmsh:geometrical": [tags, np.full(len(t), 1)]},
                       field_data={"exit": np.array([1, 1]), "wall": np.array([2, 1]),
                                   "domain": np.array([3, 2])})
    meshio.write(str(out), mesh, file_format="gmsh22", binary=False)


if __name__ == "__main__":
    for plan in sorted(HERE.glob("*.toml")):
        print(build_mesh(plan))
    trapped(HERE / "trapped.msh")
    print(HERE / "trapped.msh")
    slivers(HERE / "slivers.msh")
    print(HERE / "slivers.msh")
