"""Microscopic crowd model: rigid discs, catching-up scheme (Maury, Venel 2011; Maury 2014, sec. 2).

Pure-array interface:

- :class:`MicroSimulation` (state + :meth:`~MicroSimulation.step` +
  :meth:`~MicroSimulation.run` generator of :class:`StepInfo`),
- :func:`project` (the QP of Maury 2014, eq. 16, exact or Uzawa eq. 17),
- :func:`sample_discs`, :func:`read_discs_csv` (initial crowds).
"""

from .contacts import CandidateList, Constraints, WallSet
from .projection import ProjectionResult, kkt_residual, project
from .sampling import read_discs_csv, sample_discs, target_count
from .scheme import MicroSimulation, StepInfo

__all__ = [
    "CandidateList",
    "Constraints",
    "WallSet",
    "ProjectionResult",
    "kkt_residual",
    "project",
    "MicroSimulation",
    "StepInfo",
    "read_discs_csv",
    "sample_discs",
    "target_count",
]
