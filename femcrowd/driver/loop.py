"""The time loop of a run, the same for both models and every study (PyClaw's Controller loop)."""

import logging
import signal
import threading
import time

from tqdm import tqdm

log = logging.getLogger("femcrowd")


def drive(model, recorder, end: float, every: float, on_frame, stops=(), on_stop=None, quiet: bool = True,
          timers=None, on_checkpoint=None, next_frame: int | None = None) -> None:
    """Advance `model` from its time to `end`, recording a row of diagnostics at t = 0 and after each step.

    Steps land exactly on the frame times (frame k at k * every), on the `stops` and on `end`;
    on_frame() is called at t = 0, at each frame time and after the last step, on_stop(recorder)
    at each stop, on_checkpoint(next_frame) after each frame and when the run is interrupted. The loop
    ends at `end`, or once the model is empty (``model.empty()``). A Ctrl-C ends the step under way
    (a second one stops at once), checkpoints, then raises KeyboardInterrupt; whatever else a step
    raises goes on to the caller, which records the status. next_frame: the index of the next frame
    of a resumed run (its row at t and its frame are already written). timers: a dict that receives
    the seconds of the loop's own work ("recording": diagnostics, history rows, progress, stops).
    """
    timers = timers if timers is not None else {}
    start, spent = time.perf_counter(), {"step": 0.0, "frame": 0.0}

    def timed(key, call, *args):
        tic = time.perf_counter()
        result = call(*args)
        spent[key] += time.perf_counter() - tic
        return result

    def frame(index):
        timed("frame", on_frame)
        if on_checkpoint is not None:
            timed("frame", on_checkpoint, index)

    if next_frame is None:
        recorder.add(model.row())
        frame(1)
    elif model.empty():  # a resumed run that had ended because the crowd left
        return
    frames = next_frame or 1  # frame k at k * every (a product: summed, 8 x 0.05 < 0.4 made a step of 6e-17)
    stops = sorted(s for s in stops if s > model.t)
    bar = tqdm(total=end, initial=model.t, disable=quiet, delay=2.0, unit="s", desc="simulated time",
               bar_format="{l_bar}{bar}| {n:.3g}/{total:.3g} s [{elapsed}<{remaining}]")
    try:
        with _InterruptAfterTheStep() as interrupted:
            while model.t < end:
                frame_time = min(frames * every, end)
                before = model.t
                info = timed("step", model.step, min([frame_time, *stops[:1]]))
                recorder.add(model.row(info))
                bar.update(model.t - before)
                emptied = model.empty()
                while stops and model.t >= stops[0]:
                    on_stop(recorder)
                    stops.pop(0)
                if model.t >= frame_time or emptied:
                    frames += model.t >= frames * every
                    frame(frames)
                    if log.isEnabledFor(logging.INFO):
                        log.info("t = %.6g s: %s", model.t, ", ".join(f"{k} {recorder.rows[k][-1]:.6g}"
                                                                     for k in recorder.history_columns[2:6]))
                if interrupted:
                    if on_checkpoint is not None:
                        on_checkpoint(frames)
                    raise KeyboardInterrupt
                if emptied:
                    break
    finally:
        bar.close()
        # the loop's own work: diagnostics, history rows, progress bar, stops (the steps and frames are
        # timed by the model and by on_frame)
        timers["recording"] = timers.get("recording", 0.0) + time.perf_counter() - start - spent["step"] \
            - spent["frame"]


class _InterruptAfterTheStep:
    """A context in which the first SIGINT only marks the loop as interrupted (a list made non-empty):
    the step under way ends, so that the state is whole. A second SIGINT interrupts at once. Outside
    the main thread (where Python delivers signals) nothing changes."""

    def __enter__(self):
        self.flag, self.previous = [], None
        if threading.current_thread() is threading.main_thread() \
                and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            self.previous = signal.signal(signal.SIGINT, self._handle)
        return self.flag

    def _handle(self, signum, frame):
        if self.flag:
            raise KeyboardInterrupt
        self.flag.append(signum)

    def __exit__(self, *exc):
        if self.previous is not None:
            signal.signal(signal.SIGINT, self.previous)
        return False
