"""Disc trajectories read by PedPy (Juelich Supercomputing Centre): its N-t curve at a line against femcrowd's
own count of the line (measurements.csv)."""

import csv

import numpy as np
import pytest

from femcrowd import load_case, run

from ..support import CASES

pedpy = pytest.importorskip("pedpy", reason="pedpy is an optional test dependency (pip install -e '.[test]')")


def test_pedpy_counts_at_a_line_what_femcrowd_counts(tmp_path):
    line = {"name": "middle", "from": [6.0, 0.0], "to": [6.0, 5.0]}
    case = load_case(CASES / "narrow-door-micro", {"time.end": 8.0, "measure.lines": [line],
                                                   "output.trajectory_rate": 10.0})
    result = run(case, tmp_path / "out")
    out = result.output_dir
    traj = pedpy.load_trajectory_from_txt(trajectory_file=out / "trajectories.txt",
                                          default_unit=pedpy.TrajectoryUnit.METER)
    assert traj.frame_rate == 10.0
    walkable = pedpy.WalkableArea((out / "walkable_area.wkt").read_text())
    assert walkable.polygon.area == pytest.approx(result.domain.area.sum(), rel=1e-12)
    nt, _ = pedpy.compute_n_t(traj_data=traj, measurement_line=pedpy.MeasurementLine([line["from"], line["to"]]))
    with open(out / "measurements.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["time"]) for r in rows])
    count = np.array([float(r["middle_count"]) for r in rows])
    assert count[-1] >= 20                               # a real flow through the line
    assert nt["cumulative_pedestrians"].iloc[-1] == count[-1]
    # at each frame time, femcrowd's count then; PedPy dates a crossing to the frame after it
    ours = count[np.searchsorted(t, nt["time"].to_numpy() + 1e-9, side="right") - 1]
    assert np.abs(nt["cumulative_pedestrians"].to_numpy() - ours).max() <= 2


def test_pedpy_counts_each_disc_once_as_passed_does(tmp_path):
    """Discs that walk back across a line (their exit closes) are counted by the signed count once forth and
    once back, by PedPy's N-t once each at their first crossing: femcrowd's <line>_passed is that count."""
    line = {"name": "back", "from": [16.0, 0.3], "to": [16.0, 11.7]}
    case = load_case(CASES / "two-exits", {"model.type": "micro", "time.end": 16.0, "measure.lines": [line],
                                           "boundary.open": {"exit_wide": [[0, 8]]}, "output.trajectory_rate": 10.0})
    out = run(case, tmp_path / "out").output_dir
    traj = pedpy.load_trajectory_from_txt(trajectory_file=out / "trajectories.txt",
                                          default_unit=pedpy.TrajectoryUnit.METER)
    nt, _ = pedpy.compute_n_t(traj_data=traj, measurement_line=pedpy.MeasurementLine([line["from"], line["to"]]))
    with open(out / "measurements.csv", newline="") as f:
        rows = list(csv.DictReader(f))
    t = np.array([float(r["time"]) for r in rows])
    passed = np.array([float(r["back_passed"]) for r in rows])
    count = np.array([float(r["back_count"]) for r in rows])
    assert count[-1] < passed[-1]                        # some discs came back across the line
    assert nt["cumulative_pedestrians"].iloc[-1] == passed[-1]
    ours = passed[np.searchsorted(t, nt["time"].to_numpy() + 1e-9, side="right") - 1]
    assert np.abs(nt["cumulative_pedestrians"].to_numpy() - ours).max() <= 2
