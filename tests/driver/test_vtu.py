"""The VTU frames of driver/vtu.py read back by meshio: the mesh and every field exactly, the mesh kept from one
frame to the next only while it stays the same."""

import base64
import zlib

import meshio
import numpy as np
import pytest

from femcrowd.driver.output import FrameSeries, disc_frame, triangle_frame
from femcrowd.driver.vtu import BLOCK, encoded

from ..support import unit_square


def read(directory, stem, k):
    return meshio.read(directory / f"{stem}_{k:05d}.vtu")


def test_triangle_frames_read_back_exactly_the_mesh_kept(tmp_path):
    """Two frames of the density model on one mesh (the second writes the kept mesh): points, triangles and each
    cell field (scalars and 3-component vectors) as meshio's own writer gives them back."""
    domain = unit_square(40)   # 3 200 triangles: fields of several compressed blocks
    rng = np.random.default_rng(1)
    series = FrameSeries(tmp_path, "solution")
    fields = []
    for k in range(2):
        data = {"density": rng.uniform(0, 5.4, domain.ncells), "pressure": rng.uniform(0, 1, domain.ncells),
                "velocity": rng.normal(size=(domain.ncells, 2))}
        mesh = triangle_frame(domain, data)
        series.write(0.5 * k, mesh)
        fields.append(mesh)
    meshio.vtu.write(str(tmp_path / "meshio.vtu"), fields[1], binary=True, compression="zlib")
    theirs = meshio.read(tmp_path / "meshio.vtu")
    for k, mesh in enumerate(fields):
        ours = read(tmp_path, "solution", k)
        np.testing.assert_array_equal(ours.points, mesh.points)
        np.testing.assert_array_equal(ours.cells_dict["triangle"], domain.triangles)
        for name, values in mesh.cell_data.items():
            np.testing.assert_array_equal(ours.cell_data[name][0], values[0])
    ours = read(tmp_path, "solution", 1)
    assert ours.cell_data.keys() == theirs.cell_data.keys()
    for name in theirs.cell_data:
        np.testing.assert_array_equal(ours.cell_data[name][0], theirs.cell_data[name][0])
        assert ours.cell_data[name][0].dtype == theirs.cell_data[name][0].dtype


@pytest.mark.parametrize("counts", [(5, 7), (9000, 9000)])
def test_disc_frames_follow_the_moving_discs(tmp_path, counts):
    """Disc frames (vertex cells, point data): each frame has its own discs' positions (the kept mesh is not
    reused once the points move), in more than one compressed block too (9 000 discs)."""
    rng = np.random.default_rng(2)
    series = FrameSeries(tmp_path, "discs")
    written = []
    for k, n in enumerate(counts):
        q, u = rng.uniform(0, 10, (n, 2)), rng.normal(size=(n, 2))
        mesh = disc_frame(q, np.full(n, 0.2), u, rng.uniform(0, 1, n))
        series.write(float(k), mesh)
        written.append(mesh)
    for k, mesh in enumerate(written):
        ours = read(tmp_path, "discs", k)
        np.testing.assert_array_equal(ours.points, mesh.points)
        assert len(ours.points) == counts[k]
        for name, values in mesh.point_data.items():
            np.testing.assert_array_equal(ours.point_data[name], values)


@pytest.mark.parametrize("n", [0, 1000, 5000])
def test_an_array_in_blocks_of_its_header(n):
    """VTK's compressed binary layout: a UInt32 header (blocks, block size, last block's size, compressed sizes),
    then the blocks; an empty array one empty block."""
    array = np.arange(n, dtype=np.float64)
    text = encoded(array)
    blocks = max(-(-array.nbytes // BLOCK), 1)
    head = np.frombuffer(base64.b64decode(text[:4 * ((4 * (3 + blocks) + 2) // 3)]), np.uint32)
    assert head[0] == blocks and head[1] == BLOCK and head[2] == array.nbytes - (blocks - 1) * BLOCK
    data = base64.b64decode(text[4 * ((4 * (3 + blocks) + 2) // 3):])
    assert len(data) == head[3:].sum()
    offsets = np.concatenate([[0], np.cumsum(head[3:])]).astype(int)
    raw = b"".join(zlib.decompress(data[a:b]) for a, b in zip(offsets[:-1], offsets[1:]))
    np.testing.assert_array_equal(np.frombuffer(raw, np.float64), array)
