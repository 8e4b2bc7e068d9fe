"""Checkpoints of a run: everything needed to continue it, in full precision (``femcrowd run --resume``).

A checkpoint is written next to the frames at every frame time and when the run is interrupted
(at the end of a step): the model's state, the rows of the record so far, the frame series, the
position of the loop and the phase timers, with what identifies the run it belongs to (femcrowd's
version, the case but its end time, the mesh checksum, the model). A resumed run continues from
it and gives the final state, history and frames of an uninterrupted run to round-off: the
linear solvers are rebuilt (another factorisation order, no warm start), not the arithmetic.
"""

import hashlib
import json
import zipfile
from pathlib import Path

import numpy as np

from .. import __version__
from ..errors import InputError
from ..files import replaced

NAME = "checkpoint.npz"


def case_key(config: dict) -> str:
    """What a resumed run must share with the checkpoint's: the resolved case but time.end (a run may
    be continued further than it was planned)."""
    shared = {**config, "time": {k: v for k, v in config["time"].items() if k != "end"}}
    return hashlib.sha256(json.dumps(shared, sort_keys=True, default=str).encode()).hexdigest()


def write(directory, identity: dict, state: dict, rows: dict, position: dict) -> None:
    """Write the checkpoint atomically: identity (femcrowd, case, mesh, model), the model's state
    (arrays and numbers), the record's rows (one array per column), the loop's position."""
    arrays = {f"state/{k}": np.asarray(v) for k, v in state.items()}
    arrays.update({f"row/{k}": np.asarray(v) for k, v in rows.items()})
    meta = json.dumps({"identity": identity, "position": position}, default=str)
    with replaced(Path(directory) / NAME) as tmp, open(tmp, "wb") as f:
        np.savez(f, meta=np.array(meta), **arrays)


def read(directory, identity: dict) -> tuple[dict, dict, dict]:
    """(state, rows, position) of the checkpoint in `directory`, after checking that it belongs to the
    run described by `identity`; InputError (the output is left untouched) otherwise."""
    path = Path(directory) / NAME

    def refuse(message):
        raise InputError(path, "--resume", str(directory), message)

    if not path.is_file():
        refuse("no checkpoint to resume from (a run writes one at every frame and when interrupted)")
    try:
        with np.load(path, allow_pickle=False) as data:
            meta = json.loads(str(data["meta"]))
            state = {k[6:]: data[k] for k in data.files if k.startswith("state/")}
            rows = {k[4:]: data[k] for k in data.files if k.startswith("row/")}
    except (OSError, ValueError, KeyError, zipfile.BadZipFile, json.JSONDecodeError, EOFError) as err:
        refuse(f"the checkpoint cannot be read ({type(err).__name__}): corrupted or incomplete")
    theirs = meta.get("identity", {})
    for key, what in (("femcrowd", "femcrowd version"), ("model", "model"), ("mesh", "mesh"), ("case", "case")):
        if theirs.get(key) != identity[key]:
            refuse(f"the checkpoint is of another {what} ({theirs.get(key)!r}, this run: {identity[key]!r})"
                   if key != "case" else "the checkpoint is of another case (only time.end may change on --resume)")
    return state, rows, meta["position"]


def restore(directory, case, model, recorder, state: dict, rows: dict) -> None:
    """Continue the model and the record from a checkpoint read by :func:`read`; InputError if its arrays do not
    fit this run (a checkpoint made or edited by hand) or if the case now ends before the checkpoint's time."""
    t, end = float(np.asarray(state.get("t", np.nan))), case["time"]["end"]
    if t > end:
        raise InputError(case.file, "time.end", end, f"is before the time of the checkpoint, t = {t:.6g} s: "
                         "--resume continues a run, it cannot end it earlier (run it anew, without --resume)")
    try:
        model.restore(state)
        recorder.restore(rows)
    except (KeyError, ValueError, IndexError, TypeError) as err:
        raise InputError(Path(directory) / NAME, "--resume", str(directory),
                         f"the checkpoint's arrays do not fit this run ({type(err).__name__}: {err}): "
                         "made or edited by hand?") from None


def parts(**components) -> dict:
    """The snapshots of a model's components (sources, measurements), their keys prefixed by the name."""
    return {f"{name}.{k}": v for name, part in components.items() if part is not None
            for k, v in part.snapshot().items()}


def restore_parts(data: dict, **components) -> None:
    """Give each component its part of a snapshot made by parts()."""
    for name, part in components.items():
        if part is not None:
            part.restore({k[len(name) + 1:]: v for k, v in data.items() if k.startswith(name + ".")})


def identity(case_config: dict, mesh_sha256: str, model: str) -> dict:
    return {"femcrowd": __version__, "model": model, "mesh": mesh_sha256, "case": case_key(case_config)}
