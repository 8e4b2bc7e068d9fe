"""The numbers of femcrowd report against histories and densities whose answers are known exactly."""

import json

import numpy as np
import pytest

from femcrowd.mesh import Door
from femcrowd.report.numbers import door_numbers, line_numbers, queues, share_times
from femcrowd.report.study import spread, study_context

from ..support import unit_square


def linear_history(end=10.0, steps=100, rate=10.0):
    """People leave at `rate` per s from 100 inside: evacuated = rate t."""
    t = np.linspace(0.0, end, steps + 1)
    return {"time": t, "mass": 100.0 - rate * t, "evacuated": rate * t}


def test_share_times_of_a_linear_evacuation():
    """100 people out at 10 per s: 50 % at 5 s, 90 % at 9 s, 99 % at 9.9 s."""
    times = share_times(linear_history())
    assert times == pytest.approx({"t50": 5.0, "t90": 9.0, "t99": 9.9}, abs=1e-12)


def test_share_times_count_the_arrivals_and_say_nan_when_not_reached():
    """With 100 more people arrived, 100 out is only 50 %: t90 and t99 are never reached."""
    h = {**linear_history(), "inflow": np.full(101, 100.0)}
    times = share_times(h)
    assert times["t50"] == pytest.approx(10.0) and np.isnan(times["t90"]) and np.isnan(times["t99"])


def test_door_numbers_of_a_door_at_capacity_for_five_seconds():
    """A door of width 1 and capacity 2 persons/(m s) passes 2 per s in (1, 6] s: 10 through, mean and peak flow 2,
    5 s at capacity; a free exit passing nobody has no time at capacity."""
    t = np.linspace(0.0, 10.0, 101)
    flow = np.where((t > 1 + 1e-9) & (t < 6 + 1e-9), 2.0, 0.0)
    h = {"time": t, "flow_door": flow, "evacuated_door": np.cumsum(flow * np.diff(t, prepend=0.0)),
         "evacuated_free": np.zeros_like(t)}
    doors = [Door("door", np.array([0]), True, 1.0, 2.0 / 5.4), Door("free", np.array([1]), True, 0.8)]
    rows = door_numbers(h, doors, rho_max=5.4)
    assert rows["door"]["through"] == pytest.approx(10.0)
    assert rows["door"]["capacity"] == pytest.approx(2.0)
    assert rows["door"]["mean_flow"] == pytest.approx(2.0)
    assert rows["door"]["peak_flow"] == pytest.approx(2.0)
    assert rows["door"]["at_capacity"] == pytest.approx(5.0)
    assert rows["free"]["through"] == 0.0 and rows["free"]["at_capacity"] is None and rows["free"]["capacity"] is None


def test_an_interior_door_counts_its_flow():
    """A door between two rooms (no evacuated column) passes its flow x dt: 1.5 per s for 4 s, 6 people."""
    t = np.linspace(0.0, 8.0, 81)
    flow = np.where((t > 2 + 1e-9) & (t < 6 + 1e-9), 1.5, 0.0)
    rows = door_numbers({"time": t, "flow_ab": flow}, [Door("ab", np.array([0]), False, 1.0, 1.5)], rho_max=1.0)
    assert rows["ab"]["through"] == pytest.approx(6.0) and rows["ab"]["kind"] == "interior door"
    assert rows["ab"]["at_capacity"] == pytest.approx(4.0)


def test_a_counting_line_is_a_row_of_the_door_table():
    """A line crossed at 3 per s for 2 s, then 1 back: net 5 through, peak 3, its length its width."""
    t = np.linspace(0.0, 4.0, 41)
    count = np.interp(t, [0, 1, 3, 3.5, 4], [0, 0, 6, 5, 5])
    rows = line_numbers({"time": t, "gate_flow": np.gradient(count, t), "gate_count": count}, {"gate": 2.5})
    assert list(rows) == ["line gate"]
    row = rows["line gate"]
    assert (row["kind"], row["width"], row["capacity"], row["at_capacity"]) == ("counting line", 2.5, None, None)
    assert row["through"] == pytest.approx(5.0) and row["peak_flow"] == pytest.approx(3.0)


def test_a_queue_is_the_dense_crowd_connected_to_its_door():
    """On the unit square with the right side an exit: a dense band along the right side is its queue (density x
    area, exactly); a dense band along the left side, cut off from it by empty cells, is nobody's queue; the left
    side, a second door, gets the left band."""
    domain = unit_square(8, ["right", "left"])
    x = domain.centroid[:, 0]
    density = np.where(x > 0.75, 0.9, 0.0) + np.where(x < 0.25, 0.6, 0.0) + np.where((x > 0.4) & (x < 0.6), 0.1, 0)
    doors = [Door(name, domain.groups[name], True, 1.0) for name in ("right", "left")]
    q = queues(domain, doors, density, rho_max=1.0)
    assert q["right"] == pytest.approx(0.9 * domain.area[x > 0.75].sum())
    assert q["left"] == pytest.approx(0.6 * domain.area[x < 0.25].sum())
    assert queues(domain, doors[:1], np.where(x < 0.25, 1.0, 0.0), rho_max=1.0)["right"] == 0.0


def test_the_spread_of_a_study_and_its_last_change(tmp_path):
    """Three runs (written as a sweep writes them): the mean, sample standard deviation, min, max and the change
    between the last two of their evacuation times, in the sweep's order."""
    rows = []
    for name, end in (("b", 12.0), ("a", 10.0), ("c", 11.0)):
        run = tmp_path / name
        run.mkdir()
        t = np.linspace(0.0, end, 11)
        (run / "history.csv").write_text("time,mass,evacuated\n" + "".join(
            f"{ti},{100 - 100 * ti / end},{100 * ti / end}\n" for ti in t))
        (run / "summary.json").write_text(json.dumps({"evacuation_time": end, "evacuated": 100.0}))
        rows.append({"output_dir": str(run)})
    (tmp_path / "sweep.json").write_text(json.dumps(rows))
    (tmp_path / "sweep.md").write_text("# Sweep\n")
    study = study_context(tmp_path)
    assert list(study["members"]) == ["b", "a", "c"] and study["kind"] == "sweep"
    s = study["spread"]
    assert s["mean"]["evacuation time"] == pytest.approx(11.0)
    assert s["std"]["evacuation time"] == pytest.approx(1.0)
    assert (s["min"]["t50"], s["max"]["t50"]) == pytest.approx((5.0, 6.0))
    assert s["last change"]["evacuation time"] == pytest.approx(1.0)
    assert spread({}, []) == {}
