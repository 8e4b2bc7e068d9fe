"""The models as the driver runs them: one protocol that both adapters implement (PyClaw's Solver as the
Controller sees it; JuPedSim's model facades over one interface), and what they share.

- :class:`Model`: what the time loop (loop.py), the run (run.py) and the studies use of a model;
- :class:`Evacuation`: when the crowd has left, and when it left (the evacuation time), the same rule for a
  density and for discs: less than a threshold inside while nobody arrives any more;
- :data:`SOURCE_COLUMNS`: the history columns of a run with ``[[sources]]``;
- :func:`landing`: the time a step must not pass: the caller's (frames, stops, the end: loop.py) and the next
  change of the doors, on which the steps of both models land.
"""

from typing import Protocol

import numpy as np

from .recorder import Column

#: the history columns of a run with [[sources]]: cumulative people who entered, people waiting outside
SOURCE_COLUMNS = [Column("inflow", (("inflow", "last"),)), Column("queued", (("queued", "last"),))]


class Model(Protocol):
    """A model of a scene as the driver runs it (driver/macro_model.py, driver/micro_model.py).

    ``stem`` names its frame series; ``columns`` its history table; ``timers`` the seconds of its phases;
    ``measurements`` its measurement lines and areas (None without); ``state`` what the Python API hands
    out (a MacroState, a MicroSimulation)."""

    stem: str
    columns: list
    timers: dict
    measurements: object

    @property
    def t(self) -> float: ...

    @property
    def state(self): ...

    def step(self, until: float):
        """One step, not beyond `until`; its diagnostics (handed back to row)."""

    def row(self, info=None) -> dict:
        """The history row of the state after the step `info` (None: the initial state); no side effect."""

    def empty(self) -> bool:
        """Has the crowd left, in a scene that stops then?"""

    def frame(self):
        """The mesh or the points of a frame, with the fields asked for."""

    def snapshot(self) -> dict:
        """The state to continue from (a checkpoint): arrays and numbers."""

    def restore(self, data: dict) -> None:
        """Continue from a snapshot."""

    def open_files(self, directory, resume: bool = False) -> list:
        """The files the model writes itself as the run goes (sinks with close())."""

    def summary(self, recorded: dict) -> dict:
        """What the summary adds to the recorder's entries."""


def landing(boundary, t: float, until: float) -> float:
    """The time a step from t must not pass: `until`, or the next change of the doors' schedule if sooner."""
    return min(until, boundary.next_change(t))


class Evacuation:
    """When the crowd has left: at most a threshold inside (a mass, or a number of discs) while nobody arrives
    any more (``[[sources]]`` over, no one queued outside). The evacuation time (of scenes with exits) is the
    time the last person left: the first step of the last stretch of steps with at most the threshold inside,
    once nobody arrives, in a run that had people (at t = 0, `people`, or later: a run that starts empty and
    fills from its sources). ``stop``: whether the run stops then (time.stop_when_empty)."""

    def __init__(self, stop: bool, exits: bool, sources=None, last_arrival: float = -np.inf, people: bool = True):
        self.stop, self.exits, self.sources, self.last_arrival = stop and exits, exits, sources, last_arrival
        self.people = people   # has anybody been inside so far?
        self.since = None      # the time of the step since which at most the threshold is inside
        self.time = None

    def arriving(self, t: float) -> bool:
        """Are people still arriving or waiting at a source?"""
        return self.sources is not None and (t < self.last_arrival or self.sources.queued > 0)

    def after_step(self, t: float, inside: float, threshold: float) -> None:
        """Follow the stretches with at most `threshold` inside; the evacuation time is the start of the one in
        which arrivals are over."""
        if inside > threshold:
            self.people, self.since = True, None
        elif self.since is None:
            self.since = t
        if self.time is None and self.exits and self.people and self.since is not None and not self.arriving(t):
            self.time = self.since

    def empty(self, t: float, inside: float, threshold: float) -> bool:
        return self.stop and inside <= threshold and not self.arriving(t)

    def snapshot(self) -> dict:
        return {name: np.nan if value is None else float(value)
                for name, value in (("time", self.time), ("since", self.since), ("people", self.people))}

    def restore(self, data: dict) -> None:
        # (a checkpoint of an earlier femcrowd has no time, since nor people)
        self.time, self.since = (None if np.isnan(v) else v for v in (float(data.get(k, np.nan))
                                                                       for k in ("time", "since")))
        self.people = bool(data.get("people", True))
