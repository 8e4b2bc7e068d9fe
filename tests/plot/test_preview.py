"""femcrowd plot CASE_DIR: the scene before any run (issue 25): walls, exits named with their schedules, sources,
lines, areas, the initial crowd and its number of people, in a picture that is not blank."""

import imageio.v3 as iio
import matplotlib.text
import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd import Simulation, load_case
from femcrowd.cli import main
from femcrowd.plot.preview import scene_figure

from ..support import CASES


def texts(fig) -> str:
    """Every text of a matplotlib figure (labels, titles, legend), one per line."""
    return "\n".join(t.get_text() for t in fig.findobj(matplotlib.text.Text))


def test_preview_of_a_case_directory_writes_a_picture_of_its_scene(tmp_path):
    result = CliRunner().invoke(main, ["plot", str(CASES / "entrance"), "-o", str(tmp_path)])
    assert result.exit_code == 0, result.output
    path = tmp_path / "entrance-preview.png"
    assert result.output == f"wrote {path}\n"
    assert [p.name for p in tmp_path.iterdir()] == ["entrance-preview.png"]   # nothing else, no run
    image = iio.imread(path)[..., :3].astype(float)
    assert image.std() > 20   # not blank: floor, walls, labels
    assert len(np.unique(image.reshape(-1, 3) @ [65536, 256, 1])) > 50


def test_the_preview_names_the_exits_with_their_schedules_sources_lines_and_areas():
    fig, people = scene_figure(load_case(CASES / "entrance"))
    text = texts(fig)
    assert "door\nopen 0-10 s, from 15 s" in text   # the exit and its [boundary.open]
    assert "entrance: source 1.2 persons/(m s), 0-30 s" in text
    assert {"middle", "door", "front"} <= set(text.splitlines())   # the lines and the area
    assert people == 0 and "0 people" in fig.get_suptitle()


@pytest.mark.parametrize("name", ["two-exits", "two-groups-micro"])
def test_the_preview_counts_the_people_a_run_starts_with(name):
    case = load_case(CASES / name)
    fig, people = scene_figure(case)
    model = Simulation(case).model
    start = model.initial_count if case["model"]["type"] == "micro" else model.mass * case["model"]["rho_max"]
    assert people == pytest.approx(start, rel=1e-12)
    assert people > 10
    text = texts(fig)
    for exit in case["boundary"]["exits"]:
        assert f"{exit}\nalways open" in text


def test_an_exit_closed_at_the_start_is_drawn_closed_and_says_when_it_opens():
    fig, _ = scene_figure(load_case(CASES / "room", {"boundary.open": {"exit": [[5, float("inf")]]}}))
    text = texts(fig)
    assert "exit\nopen from 5 s" in text and "exit, closed at t = 0" in text and "exit, open at t = 0" not in text


def test_a_bad_case_or_a_run_option_is_one_line(tmp_path):
    runner = CliRunner()
    for args, key in ([str(CASES / "room"), "--times", "1"], "--times"), \
                     ([str(CASES / "room"), "--set", "initial.density=7"], "initial.density"):
        result = runner.invoke(main, ["plot", *args, "-o", str(tmp_path)])
        assert result.exit_code == 2 and result.stderr.count("\n") == 1 and key in result.stderr, result.output
    assert not any(tmp_path.iterdir())
