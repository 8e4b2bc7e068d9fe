"""Meshes that would make a run silently wrong are refused at load time (mesh/checks.py): degenerate and inverted
(folded) triangles, cracks from duplicated nodes; the regions of a floor plan are its connected parts."""

import meshio
import numpy as np
import pytest

from femcrowd.errors import InputError
from femcrowd.mesh import load_domain
from femcrowd.mesh.triangles import doubled_areas


def square(n=4, x0=0.0):
    """[x0, x0 + 1] x [0, 1] cut into 2 n^2 counter-clockwise triangles: points, triangles, and the boundary
    segments of its sides {"left": ..., "wall": the three others}."""
    number = lambda i, j: j * (n + 1) + i  # noqa: E731
    points = np.array([(x0 + i / n, j / n) for j in range(n + 1) for i in range(n + 1)])
    triangles = []
    for i in range(n):
        for j in range(n):
            a, b, c, d = number(i, j), number(i + 1, j), number(i + 1, j + 1), number(i, j + 1)
            triangles += [(a, b, c), (a, c, d)]
    left = [(number(0, k), number(0, k + 1)) for k in range(n)]
    wall = [pair for k in range(n) for pair in ((number(n, k), number(n, k + 1)), (number(k, 0), number(k + 1, 0)),
                                                 (number(k, n), number(k + 1, n)))]
    return points, np.array(triangles), {"left": left, "wall": wall}


def write_msh(path, points, triangles, groups):
    """A gmsh 2.2 file (written by meshio) with the line groups {name: [(node, node), ...]} and the surface
    "domain"."""
    lines = np.array([pair for segments in groups.values() for pair in segments])
    line_tags = np.concatenate([np.full(len(segments), k + 1) for k, segments in enumerate(groups.values())])
    tags = [line_tags, np.full(len(triangles), 100)]
    field_data = {name: np.array([k + 1, 1]) for k, name in enumerate(groups)} | {"domain": np.array([100, 2])}
    mesh = meshio.Mesh(np.column_stack([points, np.zeros(len(points))]), [("line", lines), ("triangle", triangles)],
                       cell_data={"gmsh:physical": tags, "gmsh:geometrical": tags}, field_data=field_data)
    meshio.write(path, mesh, file_format="gmsh22", binary=False)
    return path


def refused(path, *words):
    with pytest.raises(InputError) as err:
        load_domain(path, ["left"], case_file="case.toml")
    message = str(err.value)
    assert message.startswith(f"case.toml: mesh.file = {str(path)!r}: "), message
    for word in words:
        assert word in message, message
    return message


def test_the_square_loads(tmp_path):
    domain = load_domain(write_msh(tmp_path / "square.msh", *square()), ["left"])
    assert domain.area.sum() == pytest.approx(1.0) and domain.ncells == 32
    assert (domain.region == 0).all()


def test_a_triangle_in_the_other_node_order_is_refused(tmp_path):
    points, triangles, groups = square()
    triangles[13] = triangles[13][::-1]
    refused(write_msh(tmp_path / "flipped.msh", points, triangles, groups), "1 inverted triangles", "other 31",
            "folded", f"first at ({points[triangles[13]].mean(axis=0)[0]:.4g}, ")


def test_a_folded_mesh_is_refused(tmp_path):
    """A node pushed across its neighbours: the triangles around it overlap and their areas summed exceed 1."""
    points, triangles, groups = square()
    points[12] = (0.5 + 0.6, 0.5)            # the centre node, past the node (0.75, 0.5)
    folded = np.abs(doubled_areas(points, triangles)).sum() / 2
    assert folded > 1.0 + 1e-3               # what was accepted as the area of the room
    refused(write_msh(tmp_path / "folded.msh", points, triangles, groups), "inverted triangles", "folded")


def test_a_sliver_is_refused(tmp_path):
    """A triangle 1e-11 high on a 1 m side: degenerate relative to its size (the room's size made it pass)."""
    points = np.array([(0, 0), (1, 0), (1, 1), (0, 1), (0.5, 1e-11)])
    triangles = np.array([(0, 1, 4), (0, 4, 3), (4, 1, 2), (4, 2, 3)])
    groups = {"left": [(0, 3)], "wall": [(0, 1), (1, 2), (2, 3)]}
    refused(write_msh(tmp_path / "sliver.msh", points, triangles, groups), "1 degenerate", "first at (0.5, 3.333e-12)")


def cracked(named=False):
    """The square with the triangles right of x = 1/2 on copies of the nodes of that line: a crack; its edges
    (both sides) in a group of their own if named."""
    points, triangles, groups = square()
    on_line = np.flatnonzero(np.isclose(points[:, 0], 0.5))
    copy = np.arange(len(points))
    copy[on_line] = len(points) + np.arange(len(on_line))
    right = points[triangles].mean(axis=1)[:, 0] > 0.5
    triangles[right] = copy[triangles[right]]
    groups["wall"] = [tuple(copy[list(pair)]) if points[list(pair)].mean(axis=0)[0] > 0.5 else pair
                      for pair in groups["wall"]]
    if named:
        groups["partition"] = [(a, b) for a, b in zip(on_line, on_line[1:])] + \
                              [(a, b) for a, b in zip(copy[on_line], copy[on_line][1:])]
    return np.vstack([points, points[on_line]]), triangles, groups


def test_a_line_of_duplicated_nodes_is_refused(tmp_path):
    """The crack would be a wall nobody named: half the room cut off from the exit."""
    refused(write_msh(tmp_path / "crack.msh", *cracked()), "crack", "8 boundary edges lie on each other",
            "from (0.5, 0) to (0.5, 1)", "no named line group")


def test_a_named_crack_is_a_wall(tmp_path):
    domain = load_domain(write_msh(tmp_path / "partition.msh", *cracked(named=True)), ["left"])
    assert np.array_equal(domain.region, (domain.centroid[:, 0] > 0.5).astype(int))
    assert len(domain.groups["partition"]) == 8 and not domain.interior[domain.groups["partition"]].any()


def test_regions_are_the_connected_parts(tmp_path):
    points, triangles, groups = square()
    other, other_triangles, other_groups = square(x0=2.0)
    two = write_msh(tmp_path / "two.msh", np.vstack([points, other]),
                    np.vstack([triangles, other_triangles + len(points)]),
                    {"left": groups["left"], "wall": groups["wall"] + [tuple(np.add(pair, len(points))) for pair in
                                                                        other_groups["left"] + other_groups["wall"]]})
    domain = load_domain(two, ["left"])
    assert np.array_equal(domain.region, (domain.centroid[:, 0] > 1.5).astype(int))
