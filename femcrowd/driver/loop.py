"""The time loop of a run, the same for both models and every study (PyClaw's Controller).

Where the steps of a run land: on the frame times (frame k at k x every), on the stops of a study and on the
end (here), and on the changes of the doors' schedule (driver/model.py, ``landing``); each model takes the
largest step its own stability allows (MacroSolver.stable_dt, the discs' tau) up to that time.
"""

import logging
import signal
import threading
from dataclasses import dataclass

import numpy as np
from tqdm import tqdm

log = logging.getLogger("femcrowd")


@dataclass
class Controller:
    """The schedule of a run: its end, the time between frames, the stops of a study (on_stop(recorder) is
    called at each), and whether to show a progress bar."""

    end: float
    every: float
    stops: tuple = ()
    on_stop: object = None
    quiet: bool = True

    def run(self, model, recorder, sink, timer, next_frame: int | None = None) -> None:
        """Advance `model` from its time to the end, recording a row after each step (and one at t = 0).

        sink.frame() is called at t = 0, at each frame time and after the last step, sink.checkpoint(next_frame)
        after each frame and when the run is interrupted, but not after a last step cut short to land on an end
        between two frame times (resumed, the run goes on from the checkpoint before). The loop ends at the end,
        or once the model is empty (``model.empty()``). A Ctrl-C ends the step under way (a second one stops at
        once), checkpoints, then raises KeyboardInterrupt; a step that does not advance t checkpoints and raises
        Stalled; whatever else a step raises goes on to the caller. next_frame: the index of the next frame of a
        resumed run (its row at t and its frame are already written). The seconds of the loop's own work (rows,
        progress, stops) go to the timer's "recording"."""
        if next_frame is None:
            with timer("recording"):
                recorder.add(model.row())
            sink.frame()
            sink.checkpoint(1)
        elif model.empty():  # a resumed run that had ended because the crowd left
            return
        frames = next_frame or 1  # frame k at k * every (a product: summed, 8 x 0.05 < 0.4 made a step of 6e-17)
        stops = sorted(s for s in self.stops if s > model.t)
        bar = tqdm(total=self.end, initial=model.t, disable=self.quiet, delay=2.0, unit="s", desc="simulated time",
                   bar_format="{l_bar}{bar}| {n:.3g}/{total:.3g} s [{elapsed}<{remaining}]")
        try:
            with _InterruptAfterTheStep() as interrupted:
                while model.t < self.end:
                    frame_time = min(frames * self.every, self.end)
                    before = model.t
                    info = model.step(min([frame_time, *stops[:1]]))
                    with timer("recording"):
                        recorder.add(model.row(info))
                        bar.update(model.t - before)
                        emptied = model.empty()
                        while stops and model.t >= stops[0]:
                            self.on_stop(recorder)
                            stops.pop(0)
                    # a last step cut short to land on an end off the frame times is not a step of the run continued
                    # further: no checkpoint there, a --resume goes on from the last one (the same steps, bit for bit)
                    kept = model.t < self.end or model.t >= frames * self.every
                    if model.t >= frame_time or emptied:
                        frames += model.t >= frames * self.every
                        sink.frame()
                        if kept:
                            sink.checkpoint(frames)
                        if log.isEnabledFor(logging.INFO):
                            log.info("t = %.6g s: %s", model.t, ", ".join(f"{k} {recorder.rows[k][-1]:.6g}"
                                                                         for k in recorder.history_columns[2:6]))
                    if interrupted:
                        if kept:
                            sink.checkpoint(frames)
                        raise KeyboardInterrupt
                    if model.t <= before:   # the step is below one ulp of t: t would never advance
                        sink.checkpoint(frames)
                        raise Stalled(model.t, info.dt)
                    if emptied:
                        bar.total = model.t   # the crowd is out: the bar ends here, not at time.end
                        break
        finally:
            bar.close()


class Stalled(Exception):
    """A step that left t where it was (its dt below the resolution of t): the run would go on for ever."""

    def __init__(self, t: float, dt: float):
        super().__init__(f"the run cannot advance beyond t = {t!r} s: its step dt = {dt:.3g} s is below the "
                         f"resolution of t ({np.spacing(t):.3g} s)")


#: the signals that end a run after its step, as Ctrl-C does: SIGTERM (kill, a batch system's time limit) and
#: SIGHUP (the terminal closed) too
STOP_SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))


class _InterruptAfterTheStep:
    """A context in which the first SIGINT, SIGTERM or SIGHUP only marks the loop as interrupted (a list made
    non-empty): the step under way ends, so that the state is whole. A second one interrupts at once. Signals
    with a handler of someone else's keep it; outside the main thread (where Python delivers signals) nothing
    changes."""

    def __enter__(self):
        self.flag, self.previous = [], {}
        if threading.current_thread() is threading.main_thread():
            for stop in STOP_SIGNALS:
                default = signal.default_int_handler if stop == signal.SIGINT else signal.SIG_DFL
                if signal.getsignal(stop) is default:
                    self.previous[stop] = signal.signal(stop, self._handle)
        return self.flag

    def _handle(self, signum, frame):
        if self.flag:
            raise KeyboardInterrupt
        self.flag.append(signum)

    def __exit__(self, *exc):
        for stop, handler in self.previous.items():
            signal.signal(stop, handler)
        return False
