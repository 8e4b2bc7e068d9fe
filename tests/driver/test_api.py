"""The Python API of the README: load a case with overrides, run it with or without files, arrays back."""

import numpy as np
import pytest

import femcrowd
from femcrowd.driver.reading import read_history

from ..support import CASES


def test_run_in_memory_writes_nothing_and_returns_arrays(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    case = femcrowd.load_case(CASES / "room", {"time.end": 2.0, "output.every": 1.0})
    assert case["time"]["end"] == 2.0
    default = CASES / "room" / "output"
    before = sorted((p, p.stat().st_mtime_ns) for p in default.rglob("*")) if default.exists() else None
    result = femcrowd.Simulation(case).run()
    assert result.output_dir is None and not any(tmp_path.iterdir())
    after = sorted((p, p.stat().st_mtime_ns) for p in default.rglob("*")) if default.exists() else None
    assert after == before
    h = result.history
    assert h["time"][0] == 0 and h["time"][-1] == 2.0 and len(h["time"]) == result.summary["steps"] + 1
    state = result.state
    assert state.t == 2.0 and state.rho.shape == (1, result.domain.ncells)
    mass = result.domain.area @ state.density
    assert mass == pytest.approx(h["mass"][-1], rel=1e-14)
    assert abs(mass + state.evacuated.sum() - h["mass"][0]) <= 1e-12 * h["mass"][0]
    assert state.p.min() >= 0 and state.density.max() <= 1 + 1e-9


def test_run_with_files_gives_the_same_numbers(tmp_path):
    case = femcrowd.load_case(CASES / "room", ["time.end=2", "output.every=1"])
    in_memory = femcrowd.Simulation(case).run()
    on_disk = femcrowd.run(case, out=tmp_path / "room")
    assert on_disk.output_dir == tmp_path / "room"
    written = read_history(tmp_path / "room" / "history.csv")
    for column in ("time", "mass", "evacuated", "max_density", "max_pressure"):
        assert np.array_equal(written[column], in_memory.history[column])
    assert np.array_equal(on_disk.state.rho, in_memory.state.rho)


def test_disc_model_through_the_same_api():
    case = femcrowd.load_case(CASES / "narrow-door-micro", {"time.end": 1.0})
    result = femcrowd.Simulation(case).run()
    assert result.summary["initial_count"] == len(result.state.q) + result.summary["evacuated"]
    assert result.history["count"][0] == result.summary["initial_count"]


def test_bad_override_is_an_input_error():
    with pytest.raises(femcrowd.errors.InputError, match="time.ende"):
        femcrowd.load_case(CASES / "room", {"time.ende": 1.0})
