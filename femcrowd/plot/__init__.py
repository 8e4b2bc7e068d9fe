"""Pictures of a run (``femcrowd plot``): the offscreen canvas of a floor plan and what is drawn on it."""

from .pictures import plot_run

__all__ = ["plot_run"]
