"""The floor plan: gmsh meshes (reading, floor-plan files), finite-volume geometry, the doors (exits and
interior doors, their schedules and capacities), point location and the distance to the exits."""

from .boundary import Boundary, Door, Doors
from .domain import Domain, load_domain
from .gmsh_io import file_checksum, read_mesh
from .locate import PointLocator

__all__ = ["Boundary", "Domain", "Door", "Doors", "PointLocator", "file_checksum", "load_domain", "read_mesh"]
