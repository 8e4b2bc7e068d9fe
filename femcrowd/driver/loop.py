"""The time loop of a run, the same for both models and every study (PyClaw's Controller loop)."""

import logging
import time

from tqdm import tqdm

log = logging.getLogger("femcrowd")


def drive(model, recorder, end: float, every: float, on_frame, stops=(), on_stop=None, quiet: bool = True,
          timers=None) -> None:
    """Advance `model` from its time to `end`, recording a row of diagnostics at t = 0 and after each step.

    Steps land exactly on the frame times (every `every` s), on the `stops` and on `end`;
    on_frame() is called at t = 0, at each frame time and after the last step, on_stop(recorder)
    at each stop. The loop ends at `end`, or once the model is empty (``model.empty()``). Whatever a step
    raises (KeyboardInterrupt included) goes on to the caller, which records the status.
    timers: a dict that receives the seconds of the loop's own work ("recording": diagnostics, history
    rows, progress, stops).
    """
    timers = timers if timers is not None else {}
    start, spent = time.perf_counter(), {"step": 0.0, "frame": 0.0}

    def timed(key, call, *args):
        tic = time.perf_counter()
        result = call(*args)
        spent[key] += time.perf_counter() - tic
        return result

    recorder.add(model.row())
    timed("frame", on_frame)
    stops = sorted(s for s in stops if s > model.t)
    frames = 1            # frame k is at k * every (a product: summed, 8 x 0.05 < 0.4 made a step of 6e-17)
    bar = tqdm(total=end, disable=quiet, delay=2.0, unit="s", desc="simulated time",
               bar_format="{l_bar}{bar}| {n:.3g}/{total:.3g} s [{elapsed}<{remaining}]")
    try:
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
                timed("frame", on_frame)
                if log.isEnabledFor(logging.INFO):
                    log.info("t = %.6g s: %s", model.t, ", ".join(f"{k} {recorder.rows[k][-1]:.6g}"
                                                                 for k in recorder.history_columns[2:6]))
                if model.t >= frames * every:
                    frames += 1
            if emptied:
                break
    finally:
        bar.close()
        # the loop's own work: diagnostics, history rows, progress bar, stops (the steps and frames are
        # timed by the model and by on_frame)
        timers["recording"] = timers.get("recording", 0.0) + time.perf_counter() - start - spent["step"] \
            - spent["frame"]
