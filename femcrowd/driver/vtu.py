"""A frame as a VTU file: VTK's XML UnstructuredGrid, binary and zlib-compressed (vtkZLibDataCompressor, as
meshio writes it), the encoded mesh kept from one frame to the next.

Hand-written because meshio, which wrote the frames before, compresses the points and the cells again for every
frame and keeps no encoded array: the mesh is half the bytes of a density frame and its compression half the
cost of the frames, up to 14 % of a run at a frame every 10 s (docs/performance.md, "Small scenes"). The files have
the layout meshio writes and read back in meshio (tests/driver/test_vtu.py)."""

import base64
import sys
import zlib

import numpy as np

#: bytes per compressed block (VTK's and meshio's)
BLOCK = 32768
#: VTK's cell type of each meshio cell type of a frame
CELL_TYPES = {"vertex": 1, "triangle": 5}
#: VTK's name of a numpy type: its kind and bits (Float64, Int32, UInt8, ...)
KINDS = {"f": "Float", "i": "Int", "u": "UInt"}


def encoded(array: np.ndarray) -> str:
    """The text of a binary DataArray: a UInt32 header (the number of blocks, the block size, the last block's
    size, each block's compressed size), then the zlib-compressed blocks, each part base64. An empty array is one
    empty block (meshio reads no block as no array)."""
    data = np.ascontiguousarray(array).tobytes()
    blocks = [zlib.compress(data[k:k + BLOCK]) for k in range(0, max(len(data), 1), BLOCK)]
    last = len(data) - (len(blocks) - 1) * BLOCK
    header = np.array([len(blocks), BLOCK, last, *map(len, blocks)], np.uint32)
    return base64.b64encode(header.tobytes()).decode() + base64.b64encode(b"".join(blocks)).decode()


def data_array(name: str, array: np.ndarray) -> str:
    """One DataArray element (vectors as rows: NumberOfComponents)."""
    kind = f"{KINDS[array.dtype.kind]}{8 * array.dtype.itemsize}"
    components = f' NumberOfComponents="{array.shape[1]}"' if array.ndim == 2 else ""
    return f'<DataArray type="{kind}" Name="{name}"{components} format="binary">{encoded(array)}</DataArray>\n'


def write(path, mesh, kept: dict) -> None:
    """Write a meshio mesh of one cell block as a VTU file at path. kept: the last mesh written and its encoded
    Points and Cells (a FrameSeries' own dict, updated), written again while the points and cells stay the same."""
    (block,) = mesh.cells
    if not (kept and kept["type"] == block.type and np.array_equal(kept["points"], mesh.points)
            and np.array_equal(kept["cells"], block.data)):
        kept.update(points=mesh.points.copy(), type=block.type, cells=block.data.copy(),
                    text=_geometry(mesh.points, block))
    fields = "".join(f"<{kind}>\n" + "".join(data_array(name, values if kind == "PointData" else values[0])
                                              for name, values in data.items()) + f"</{kind}>\n"
                     for kind, data in (("PointData", mesh.point_data), ("CellData", mesh.cell_data)) if data)
    order = "LittleEndian" if sys.byteorder == "little" else "BigEndian"
    text = (f'<?xml version="1.0"?>\n<VTKFile type="UnstructuredGrid" version="0.1" byte_order="{order}" '
            f'compressor="vtkZLibDataCompressor">\n<UnstructuredGrid>\n'
            f'<Piece NumberOfPoints="{len(mesh.points)}" NumberOfCells="{len(block.data)}">\n'
            f"{kept['text']}{fields}</Piece>\n</UnstructuredGrid>\n</VTKFile>\n")
    with open(path, "w") as f:
        f.write(text)


def _geometry(points, block) -> str:
    """The Points and Cells elements of a mesh."""
    cells = np.asarray(block.data)
    offsets = cells.shape[1] * np.arange(1, len(cells) + 1, dtype=cells.dtype)
    types = np.full(len(cells), CELL_TYPES[block.type], np.uint8)
    return (f"<Points>\n{data_array('Points', np.asarray(points))}</Points>\n<Cells>\n"
            f"{data_array('connectivity', cells.ravel())}{data_array('offsets', offsets)}"
            f"{data_array('types', types)}</Cells>\n")
