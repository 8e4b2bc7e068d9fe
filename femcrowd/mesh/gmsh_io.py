"""Reading gmsh meshes: checked, triangle-only MeshTri with named groups, in a cache-friendly order.

``read_mesh`` accepts gmsh .msh 2.2 and 4.1 (through meshio) and reads the
ASCII MSH 2.2 files that ``femcrowd mesh`` writes with a numpy parser of its
own (see :func:`_read_msh22_ascii`). Named physical lines become
``mesh.boundaries``, named physical surfaces ``mesh.subdomains``; cells and
nodes are renumbered along a Z-order curve. A mesh whose z varies is a building (docs/floors.md): its
elevations are kept as ``mesh.z``, its (x, y) as the plan; a planar mesh has ``mesh.z = None``.
"""

import hashlib
import shlex
import warnings
from pathlib import Path

import meshio
import numpy as np
import skfem

from ..errors import InputError
from .checks import check_cracks, check_pieces, check_triangles

_SOLID = {"tetra", "hexahedron", "wedge", "pyramid", "tetra10", "hexahedron20", "hexahedron27"}


def read_mesh(path: Path, case_file) -> skfem.MeshTri:
    """Read a gmsh .msh with meshio and check it is a triangle-only, finite mesh, without degenerate or
    inverted triangles (in plan) nor cracks (checks.py); z, if it varies, is the elevation of a building.

    meshio.gmsh.read is called directly: meshio.read prints to stdout and calls
    sys.exit when no reader accepts a file. skfem's reader would silently drop z
    (a 3D surface), pick quads or tetrahedra, or crash on a mesh of lines only.
    """
    def fail(message):
        raise InputError(case_file, "mesh.file", str(path), message)

    try:
        data = _read_msh22_ascii(path.read_bytes()) or meshio.gmsh.read(str(path))
    except Exception as err:  # meshio raises many types for malformed files
        message = str(err).splitlines()[0] if str(err).strip() else type(err).__name__
        fail(f"cannot read a gmsh .msh (2.2 or 4.1) file: {message}")
    kinds = {c.type for c in data.cells if len(c.data)}
    if kinds & _SOLID:
        fail(f"this is a 3D mesh ({', '.join(sorted(kinds & _SOLID))} cells); femcrowd needs a 2D triangle mesh")
    if "triangle" not in kinds:
        fail("the mesh has no triangles" + (f" (only {', '.join(sorted(kinds))} cells)" if kinds else " (no cells)"))
    if kinds - {"triangle", "line", "vertex"}:
        fail(f"the mesh has {', '.join(sorted(kinds - {'triangle', 'line', 'vertex'}))} cells; "
             "femcrowd needs a mesh of linear triangles only")
    points = data.points
    if not np.all(np.isfinite(points)):
        fail("the mesh has non-finite node coordinates")
    check_triangles(points, np.concatenate([c.data for c in data.cells if c.type == "triangle"]), fail)
    mesh = _ordered_mesh(data)
    extent = float(np.ptp(points[:, :2], axis=0).max())
    z = points[mesh.order, 2] if points.shape[1] > 2 else np.zeros(len(points))
    mesh.z = z if np.ptp(z) > 1e-12 * extent else None
    if mesh.z is not None:
        check_pieces(mesh, 1e-9 * max(extent, np.ptp(z)), fail)
    check_cracks(mesh, fail)
    return mesh


#: gmsh element type -> (meshio cell type, nodes) read by _read_msh22_ascii
_MSH22_TYPES = {15: ("vertex", 1), 1: ("line", 2), 2: ("triangle", 3)}


def _read_msh22_ascii(raw):
    """meshio.Mesh of an ASCII MSH 2.2 file of vertices, lines and triangles (what
    femcrowd.geometry writes), parsed with numpy; None for any other file (left to meshio).

    Hand-written because meshio reads the elements of this format one line at a time in
    Python: most of the 6-10 s that loading a 10^6-triangle mesh took (~3 s with this reader).
    The result is meshio's: points (n, 3) in file order, cells in file order per type with
    their "gmsh:physical" tags (the first tag), physical names as field_data {name: [tag, dim]}.
    Sections other than $PhysicalNames, $Nodes and $Elements are skipped.
    """
    if not raw.startswith(b"$MeshFormat\n2.2 0 8\n"):
        return None
    body = _msh22_sections(raw)
    if b"Nodes" not in body or b"Elements" not in body:
        return None
    try:   # ValueError: not the simple format, left to meshio
        field_data = _msh22_physical_names(body.get(b"PhysicalNames", b"0\n"))
        points, index = _msh22_nodes(body[b"Nodes"])
        cells, physical = _msh22_elements(body[b"Elements"], index)
    except ValueError:
        return None
    return meshio.Mesh(points, cells, cell_data={"gmsh:physical": physical}, field_data=field_data)


def _msh22_sections(raw) -> dict:
    """The count line and the data lines of the $PhysicalNames, $Nodes and $Elements sections."""
    body = {}
    for name in (b"PhysicalNames", b"Nodes", b"Elements"):
        start = raw.find(b"\n$" + name + b"\n")
        end = raw.find(b"\n$End" + name, start)
        if start >= 0 and end >= 0:
            body[name] = raw[start + len(name) + 3:end + 1]
    return body


def _msh22_physical_names(section) -> dict:
    """{name: [tag, dim]} of the $PhysicalNames section."""
    count, *lines = section.decode().splitlines()
    field_data = {}
    for line in lines[:int(count)]:
        dim, tag, name = shlex.split(line)  # names are quoted and may hold spaces
        field_data[name] = np.array([int(tag), int(dim)])
    return field_data


def _msh22_nodes(section):
    """The points (n, 3) of the $Nodes section in file order, and the index of each node number."""
    nodes = _numbers(section, float)
    count = int(nodes[0])
    if nodes.size != 1 + 4 * count:
        raise ValueError("node lines of another shape")
    nodes = nodes[1:].reshape(count, 4)
    number = nodes[:, 0].astype(np.int64)
    if count == 0 or number.min() < 0:
        raise ValueError("no nodes, or negative node numbers")
    index = np.full(number.max() + 1, -1)
    index[number] = np.arange(count)
    return nodes[:, 1:], index


def _msh22_elements(section, index):
    """The cells of the $Elements section per known type, in file order, as node indices, and their physical
    tags (the first tag)."""
    head, _, lines = section.partition(b"\n")
    ints = _numbers(lines, np.int64)
    per_line = _tokens_per_line(lines)
    if len(per_line) != int(head) or per_line.sum() != ints.size:
        raise ValueError("element count or line lengths do not match")
    start = np.cumsum(per_line) - per_line
    kind, ntags = ints[start + 1], ints[start + 2]
    nodes_of = np.zeros(max(_MSH22_TYPES) + 1, np.int64)
    for code, (_, n) in _MSH22_TYPES.items():
        nodes_of[code] = n
    known = (kind >= 0) & (kind < len(nodes_of))
    if not known.all() or (ntags < 1).any() or (per_line != 3 + ntags + nodes_of[kind]).any():
        raise ValueError("element types other than vertices, lines and triangles")
    cells, physical = [], []
    for code, (cell_type, n) in _MSH22_TYPES.items():
        mine = kind == code
        if mine.any():
            number = ints[(start[mine] + 3 + ntags[mine])[:, None] + np.arange(n)]
            if number.max() >= len(index) or (index[number] < 0).any():
                raise ValueError("elements of unknown nodes")
            cells.append((cell_type, index[number]))
            physical.append(ints[start[mine] + 3])
    return cells, physical


def _numbers(text, dtype):
    """All whitespace-separated numbers of text; ValueError on anything else."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy only warns when it stops at a bad token
        try:
            return np.fromstring(text, dtype=dtype, sep=" ")
        except DeprecationWarning as err:
            raise ValueError(str(err)) from None


def _tokens_per_line(text):
    """Number of whitespace-separated tokens on each line of text (which ends with a newline)."""
    chars = np.frombuffer(text, np.uint8)
    if len(chars) == 0:
        return np.zeros(0, np.int64)
    blank = chars <= 32  # space, tab, CR, LF
    first = ~blank  # first character of a token
    first[1:] &= blank[:-1]
    line_start = np.r_[0, np.flatnonzero(chars[:-1] == 10) + 1, len(chars)]
    return np.diff(np.searchsorted(np.flatnonzero(first), line_start))


def _ordered_mesh(data):
    """A MeshTri from meshio gmsh data, with cells and nodes renumbered along a Z-order curve.

    Named physical groups become boundaries (line cells, matched to facets) and
    subdomains (triangles); unnamed tags are dropped. The ordering puts
    neighbouring cells near each other in memory: gmsh numbers them in no useful
    order, and at 10^6 triangles that made the transport mat-vec 2-3x slower.
    Facets, t2f and f2t are built here with one 1-D integer sort, the same
    arrays as skfem's, whose np.unique(axis=1) takes ~20 s at 10^6 triangles.
    """
    names = {(int(tag), int(dim)): name for name, (tag, dim) in data.field_data.items()}
    physical = data.cell_data.get("gmsh:physical", [np.zeros(len(c.data), int) for c in data.cells])
    blocks = {kind: [(c.data, tags) for c, tags in zip(data.cells, physical) if c.type == kind]
              for kind in ("triangle", "line")}
    t = np.concatenate([cells for cells, _ in blocks["triangle"]])
    t_tags = np.concatenate([tags for _, tags in blocks["triangle"]])
    xy = data.points[:, :2]
    node_order = np.argsort(_zorder(xy), kind="stable")
    new_node = np.empty(len(xy), np.int64)
    new_node[node_order] = np.arange(len(xy))
    t = new_node[t]
    cell_order = np.argsort(_zorder(xy[node_order][t].mean(axis=1)), kind="stable")
    t, t_tags = t[cell_order], t_tags[cell_order]
    mesh = skfem.MeshTri(np.ascontiguousarray(xy[node_order].T), np.ascontiguousarray(t.T), validate=False)
    t = mesh.t.T.astype(np.int64)  # skfem may reorder the nodes of each triangle
    mesh.order = node_order   # the file's node of each node

    nt, nv = len(t), len(xy)
    local = ((0, 1), (1, 2), (0, 2))  # skfem's facet numbering of a triangle
    pairs = np.sort(np.concatenate([t[:, list(f)] for f in local]), axis=1)
    key = pairs[:, 0] * nv + pairs[:, 1]
    order = np.argsort(key, kind="stable")
    sorted_key = key[order]
    first = np.r_[True, sorted_key[1:] != sorted_key[:-1]]
    start = np.flatnonzero(first)
    count = np.diff(np.r_[start, len(key)])
    t2f = np.empty(len(key), np.int64)
    t2f[order] = np.cumsum(first) - 1
    facet_key = sorted_key[start]
    mesh._facets = np.vstack([facet_key // nv, facet_key % nv])
    mesh._t2f = t2f.reshape(3, nt)
    mesh._f2t = np.vstack([order[start] % nt, np.where(count > 1, order[start + count - 1] % nt, -1)])

    boundaries = {}
    if blocks["line"]:
        lines = np.sort(new_node[np.concatenate([cells for cells, _ in blocks["line"]])], axis=1)
        line_tags = np.concatenate([tags for _, tags in blocks["line"]])
        line_key = lines[:, 0] * nv + lines[:, 1]
        facet = np.minimum(np.searchsorted(facet_key, line_key), len(facet_key) - 1)
        found = facet_key[facet] == line_key
        for tag in np.unique(line_tags):
            if (int(tag), 1) in names:
                boundaries[names[int(tag), 1]] = np.unique(facet[found & (line_tags == tag)])
    subdomains = {names[int(tag), 2]: np.flatnonzero(t_tags == tag)
                  for tag in np.unique(t_tags) if (int(tag), 2) in names}
    mesh._boundaries, mesh._subdomains = boundaries or None, subdomains or None
    return mesh


def _zorder(xy):
    """Morton (Z-order) keys of points, 16 bits per axis."""
    low, span = xy.min(axis=0), np.ptp(xy, axis=0)
    q = ((xy - low) / np.where(span > 0, span, 1.0) * 65535).astype(np.uint64)
    for shift, mask in ((8, 0x00FF00FF), (4, 0x0F0F0F0F), (2, 0x33333333), (1, 0x55555555)):
        q = (q | (q << np.uint64(shift))) & np.uint64(mask)
    return q[:, 0] | (q[:, 1] << np.uint64(1))


def file_checksum(path) -> str:
    """sha256 of a file (recorded with the run so that it can be reproduced)."""
    return hashlib.sha256(Path(path).read_bytes()).hexdigest()
