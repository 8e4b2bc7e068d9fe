"""The settings docs/validation.md recommends for realistic flows through doors, and where their values come from.

- LAW (``[velocity] speed_law``): Predtechenskii and Milinskii's speed on horizontal paths (1978, as tabled in
  GOST 12.1.004-91; macro/speed_law.py): a published diagram that carries 2.75 persons/(m s) at 5 persons/m^2
  and still moves a saturated crowd (f(rho_max) = 0.303), so a jam drains with no push. Not fitted.
- FREE_SPEED (``[velocity] speed``, m/s): the speed of that table up to D = 0.05 (100 m/min, 1.67 m/s), so that
  the law is the published table and not the table scaled (at Weidmann's 1.34 m/s every speed and flow of the
  table is 0.80 times the published one). What ``femcrowd new`` writes and femcrowd validate runs; a case's own
  ``velocity.speed`` stays (RiMEA test 1 prescribes 1.33 m/s), so MACRO does not set it (docs/model.md, "The
  free speed of the recommended law").
- DOOR_CAPACITY (``[boundary.capacity]`` on every door): "auto", the capacity of the door's width
  (mesh/capacity.py: the mean specific flow of the bottleneck experiments, 2.08 persons/(m s) up to 1.2 m, 2.57
  from 2.4 m, linear between; femcrowd/studies/experiments.csv): calibrated there, validated at every width.
- WALLS (``[velocity] walls``, macro only): "slip", no desired direction into a wall and a path of upwind flows
  to an exit from every cell (docs/model.md, "Walls"); with the paper's direction a saturated cell in front of a
  column or at a door post may keep its people for ever (issue 34). The discs keep the paper's direction: their
  contacts with the walls are the projection's.
- STEP (``[time] cfl``, macro only): the step of the explicit LWR fluxes at their whole CFL step, 1, not the
  schema's 0.5: at the 1 m bottleneck of ``femcrowd validate`` the evacuation times at 50, 90, 99 % and all
  out change by at most 0.03 % from cfl 0.5 on each of two meshes, a fortieth of the change between the meshes,
  in half the steps (docs/performance.md, "The evacuation time against run time"). Every validation figure was
  measured with it. The linearly implicit transport "implicit" (docs/model.md, "Steps by accuracy") is not
  recommended: at the median cell's cfl 1 it is 1.1 to 8.6 % early at t50 against this step on the same mesh on
  the bottleneck, the hall, cases/route-queues, cases/route-choice and RiMEA 12; "implicit-godunov" is within
  0.71 % of it at cfl 1.5 (FAST_STEP; docs/performance.md, "The recommended law's step, explicit or implicit").
- FAST_STEP (``[scheme] transport``, ``[time] cfl_quantile`` and ``cfl``, macro only; FAST with LAW and WALLS):
  the named fast alternative to STEP, implicit-godunov (Godunov's fluxes, implicit only in the cells whose own
  CFL step the step exceeds) at 1.5 times the median cell's CFL step. On the bottleneck, the hall with 100 and
  1 000 people, cases/route-queues, cases/route-choice and RiMEA 12 (two meshes for four of them) every t50, t90,
  t99 and t_last is within 0.71 % of STEP on the same mesh, in 1/3.4 to 1/12 of the steps; of the door flows
  only route-choice's far door misses, by 1.4 %. At cfl 2 route-choice misses by 1.6 to 2.1 %, hence 1.5.
  Not the recommended step, though it gives femcrowd validate's figures: on the coarse meshes of cases/lwr-shock
  and lwr-fan it is more than 1 % from the converged evacuation time where STEP is within 1 % (docs/performance.md,
  "The fast step against the validation").
- The variant "weidmann-push" (WEIDMANN_PUSH, the recommended settings before Predtechenskii and Milinskii's law):
  Weidmann's law (1993) at 1.34 m/s with PUSH, the least factor of the speed law that keeps a jam moving (0.2
  passes 1.9 persons/(m s) through the 1 m bottleneck, converged on three meshes), and PUSH_CAPACITY 1.9 on every
  door (Seyfried et al. 2009: 1.90 at 1.0 m); it falls 35 to 50 % short of the experiments from 1.6 m.
- The discs (``model.type = "micro"``, which has no door capacity): Weidmann's law and PUSH from the density
  each disc sees, the decelerating strategy of Maury et al. (2011) and an arch-breaking fluctuation
  FLUCTUATION (m/s, docs/micro.md): the smallest of those tried (0.5, 1.0) that lets every disc of
  radius 0.2 m through the 0.5 m and 1 m bottlenecks in each of five seeds. Not LAW: without a door capacity
  the discs overshoot the narrow doors' experiments with it (docs/validation.md, "The discs with Predtechenskii
  and Milinskii's law").
"""

from ..macro.speed_law import PM_SPEED

#: the free speed of Predtechenskii and Milinskii's law, m/s (100 m/min: their speed up to D = 0.05)
FREE_SPEED = float(PM_SPEED[0]) / 60.0
#: the capacity of every door: that of its width (mesh/capacity.py width_capacity)
DOOR_CAPACITY = "auto"
#: the variant "weidmann-push": Weidmann's free speed (m/s), the push of its law and the capacity of every door
WEIDMANN_SPEED, PUSH, PUSH_CAPACITY = 1.34, 0.2, 1.9
FLUCTUATION = 0.5

LAW = {"velocity.speed_law": "predtechenskii"}
WALLS = {"velocity.walls": "slip"}
#: the recommended time step of the density model
STEP = {"time.cfl": 1.0}
#: the recommended desired velocity and step of the density model (the speed: FREE_SPEED, or the case's own)
MACRO = {**LAW, **WALLS, **STEP}
#: the fast step: implicit-godunov at 1.5 times the median cell's CFL step
FAST_STEP = {"scheme.transport": "implicit-godunov", "time.cfl_quantile": 0.5, "time.cfl": 1.5}
#: the recommended desired velocity with the fast step
FAST = {**LAW, **WALLS, **FAST_STEP}
#: Weidmann's law with its push, either model
PUSHING = {"velocity.speed_law": "weidmann", "velocity.push": PUSH}
#: the variant "weidmann-push" of the density model (with PUSH_CAPACITY on every door)
WEIDMANN_PUSH = {**PUSHING, **WALLS, **STEP}
DISCS = {**PUSHING, "micro.strategy": "decelerate", "micro.fluctuation": FLUCTUATION}


def door_capacity(doors, capacity=DOOR_CAPACITY) -> dict:
    """The override giving every one of `doors` the recommended capacity (or `capacity`)."""
    return {"boundary.capacity": {door: capacity for door in doors}}
