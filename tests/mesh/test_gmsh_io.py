"""The numpy reader of ASCII MSH 2.2 files gives meshio's data, and leaves other files to meshio."""


import meshio
import numpy as np
import pytest

from femcrowd.mesh.gmsh_io import _read_msh22_ascii

from ..support import MESHES as MESH_DIR

MESHES = sorted(MESH_DIR.glob("*.msh"))


@pytest.mark.parametrize("path", MESHES, ids=[p.stem for p in MESHES])
def test_msh22_reader_matches_meshio(path):
    ours, reference = _read_msh22_ascii(path.read_bytes()), meshio.gmsh.read(str(path))
    assert ours is not None
    assert np.array_equal(ours.points, reference.points)
    assert [c.type for c in ours.cells] == [c.type for c in reference.cells]
    for a, b in zip(ours.cells, reference.cells):
        assert np.array_equal(a.data, b.data)
    for a, b in zip(ours.cell_data["gmsh:physical"], reference.cell_data["gmsh:physical"]):
        assert np.array_equal(a, b)
    assert {k: list(v) for k, v in ours.field_data.items()} == {k: list(v) for k, v in reference.field_data.items()}


def test_msh22_reader_declines_what_it_does_not_know(tmp_path):
    text = MESHES[0].read_text()
    assert _read_msh22_ascii(b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n") is None       # MSH 4: meshio
    assert _read_msh22_ascii(text.replace("$Elements", "$Elementz").encode()) is None  # no elements
    head, sep, rest = text.partition("$Elements\n")
    count, newline, lines = rest.partition("\n")
    broken = head + sep + count + newline + lines.replace("\n", " x\n", 1)             # a bad token
    assert _read_msh22_ascii(broken.encode()) is None
