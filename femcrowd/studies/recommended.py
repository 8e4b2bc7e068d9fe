"""The settings docs/validation.md recommends for realistic flows through doors, and where their values come from.

- DOOR_CAPACITY (persons per metre per second, ``[boundary.capacity]`` on every door): the specific flow of
  the bottleneck experiments at 1 to 1.2 m (Seyfried et al. 2009: 1.90 at 1.0 m, 1.97 at 1.2 m; Kretz et
  al. 2006: 1.76 to 1.85 at 0.7 to 1.2 m; femcrowd/studies/experiments.csv).
- PUSH (``[velocity] push``) with Weidmann's law (``speed_law = "weidmann"``, Weidmann 1993): the least
  factor of the speed law, so that a jam still pushes toward the exits; 0.2 passes 1.9 persons/(m s)
  through the 1 m bottleneck of ``femcrowd validate`` (converged on three meshes): calibrated there,
  validated at the other widths.
- WALLS (``[velocity] walls``, macro only): "slip", no desired direction into a wall and a path of upwind flows
  to an exit from every cell (docs/model.md, "Walls"); with the paper's direction a saturated cell in front of a
  column or at a door post may keep its people for ever (issue 34). The discs keep the paper's direction: their
  contacts with the walls are the projection's.
- STEP (``[time] cfl``, macro only): the step of the explicit LWR fluxes at their whole CFL step, 1, not the
  schema's 0.5: at the 1 m bottleneck of ``femcrowd validate`` the evacuation times at 50, 90, 99 % and all
  out change by at most 0.03 % from cfl 0.5 on each of two meshes, a fortieth of the change between the meshes,
  in half the steps (docs/performance.md, "The evacuation time against run time"). The implicit transport takes
  a speed law (linearly implicit, docs/model.md "Steps by accuracy") but is not recommended: see performance.md.
- The discs (``model.type = "micro"``, which has no door capacity): the same law and push from the density
  each disc sees, the decelerating strategy of Maury et al. (2011) and an arch-breaking fluctuation
  FLUCTUATION (m/s, docs/micro.md): the smallest of those tried (0.5, 1.0) that lets every disc of
  radius 0.2 m through the 0.5 m and 1 m bottlenecks in each of five seeds.
"""

from ..macro.speed_law import PM_SPEED

DOOR_CAPACITY = 1.9
#: the free speed of Predtechenskii and Milinskii's law, m/s (100 m/min: their speed up to D = 0.05)
PM_FREE_SPEED = float(PM_SPEED[0]) / 60.0
PUSH = 0.2
FLUCTUATION = 0.5

#: the overrides of the recommended settings, for either model (the capacity is per door: see door_capacity)
SPEED = {"velocity.speed_law": "weidmann", "velocity.push": PUSH}
WALLS = {"velocity.walls": "slip"}
#: the recommended time step of the density model
STEP = {"time.cfl": 1.0}
#: a law that carries the flows of wide doors (macro/speed_law.py: Predtechenskii, Milinskii 1978; f(rho_max) > 0,
#: no push), with the capacity of each door's width ("auto", mesh/capacity.py): femcrowd validate's "predtechenskii"
CARRYING = {"velocity.speed_law": "predtechenskii", "velocity.speed": PM_FREE_SPEED, **WALLS}
#: the recommended desired velocity and step of the density model
MACRO = {**SPEED, **WALLS, **STEP}
DISCS = {**SPEED, "micro.strategy": "decelerate", "micro.fluctuation": FLUCTUATION}


def door_capacity(doors) -> dict:
    """The override giving every one of `doors` the recommended capacity."""
    return {"boundary.capacity": {door: DOOR_CAPACITY for door in doors}}
