"""The floor plan: gmsh meshes (reading, floor-plan files), finite-volume geometry, exits over time,
point location and the distance to the exits."""

from .boundary import Boundary, Exits
from .domain import Domain, load_domain
from .gmsh_io import file_checksum, read_mesh
from .locate import PointLocator

__all__ = ["Boundary", "Domain", "Exits", "PointLocator", "file_checksum", "load_domain", "read_mesh"]
