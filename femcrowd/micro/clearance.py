"""The desired direction of disc centres with a wall clearance (``micro.walls = "clearance"``, docs/micro.md,
"Walls and corners").

A disc's centre stays a radius r from every wall: it walks the domain eroded by r, whose geodesics round a wall's
end or a convex corner on an arc of radius r. The distance field of the density model (mesh/distance.py) is the
geodesic of the whole domain: past a wall's end it is the distance to the end point c plus |q - c|, so its
direction at a disc touching c points at c, exactly against the contact's normal, and the catching-up projection
(Maury, Venel 2011) leaves u = 0: the disc stays for good, at every point of the arc (the finer the mesh, the
truer the direction, the more discs stay).

Here the eikonal |grad d| = cost has the cost ``SLOWNESS`` in the cells whose centroid lies within r of a wall
(the largest radius of the discs; a closed exit is a wall) and 1 elsewhere: outside that band d is the walking
distance of the eroded domain, up to O(h) (the band cut along the cells), and inside it the direction leads out
of the band towards it. A disc at a wall's end then heads along the arc, not into the end. Solved once per door
state, on the walls of the discs (on a building in the charts of its pieces, micro/surface.py).
"""

import numpy as np

from .contacts import WallSet

#: the cost per metre in a cell within a disc radius of a wall, 1 elsewhere: the geodesics of the centres leave the
#: band the short way (a path along it costs this many times the free walk) and round a wall's end outside it
SLOWNESS = 4.0


class Clearance:
    """The desired velocity of a population (an ExitsVelocity) for disc centres of radius up to `radius`: the same
    speed, the direction of the eikonal with the wall band's cost. centroids: the cells' centroids where `walls`
    (doors -> (S, 2, 2) segments) are measured."""

    def __init__(self, velocity, centroids, walls, radius: float):
        self.velocity, self.centroids, self.walls, self.radius = velocity, centroids, walls, radius
        self.fields = {}   # per set of open exits: the velocity with that door state's band

    def _field(self, exits):
        if exits.open not in self.fields:
            near = WallSet(self.walls(exits)).distance(self.centroids) < self.radius
            self.fields[exits.open] = self.velocity.costed(np.where(near, SLOWNESS, 1.0))
        return self.fields[exits.open]

    def cells(self, exits) -> np.ndarray:
        """U per cell for these open exits."""
        return self._field(exits).cells(exits)

    def at_points(self, xy, t, exits) -> np.ndarray:
        """U of the cell holding each point (0 outside the mesh)."""
        return self._field(exits).at_points(xy, t, exits)
