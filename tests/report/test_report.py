"""femcrowd report: the page's numbers against the run's own record, a page with nothing outside it, bad input."""

import base64
import json
from html.parser import HTMLParser

import numpy as np
import pytest
from click.testing import CliRunner

from femcrowd.cli import main
from femcrowd.driver.reading import read_history

from ..support import CASES


class Page(HTMLParser):
    """The images (src), links (href) and table rows (cell texts) of a page."""

    def __init__(self, text):
        super().__init__()
        self.images, self.links, self.rows, self.sections, self._row, self._cell = [], [], [], [], None, None
        self.feed(text)

    def handle_starttag(self, tag, attrs):
        attrs = dict(attrs)
        if tag == "img":
            self.images.append(attrs.get("src", ""))
        if "href" in attrs or tag in ("script", "link"):
            self.links.append(attrs.get("href") or attrs.get("src") or tag)
        if tag == "section":
            self.sections.append(attrs.get("id"))
        if tag == "tr":
            self._row = []
        if tag in ("td", "th") and self._row is not None:
            self._cell = ""

    def handle_endtag(self, tag):
        if tag in ("td", "th") and self._cell is not None:
            self._row.append(self._cell.strip())
            self._cell = None
        if tag == "tr":
            self.rows.append(self._row)
            self._row = None

    def handle_data(self, data):
        if self._cell is not None:
            self._cell += data


def door_row(page, name):
    header = next(r for r in page.rows if r[:2] == ["door", "kind"])
    return dict(zip(header, next(r for r in page.rows if r[:1] == [name] and len(r) == len(header))))


def test_the_page_holds_its_figures_and_nothing_from_outside(report_page):
    """Every figure is an embedded PNG (the data URI decodes to a PNG), no script, stylesheet or link to anything
    outside the page; the blocks of a run are all there."""
    page = Page(report_page.read_text())
    assert page.sections == ["scene", "evacuation", "doors", "remaining", "maps"]
    assert len(page.images) >= 1 + 1 + 2 * 2   # plan, N-t, density and level of service at 2 times
    for src in page.images:
        assert src.startswith("data:image/png;base64,")
        assert base64.b64decode(src.split(",", 1)[1])[:8] == b"\x89PNG\r\n\x1a\n"
    assert page.links == []


def test_the_door_numbers_agree_with_the_run(capped_run, report_page):
    """The exit's row: people through = the run's evacuated_exit; peak flow <= capacity x width (the cap of the
    prediction, mesh/capacity.py); the time at capacity is the seconds of the steps the run itself counted
    (summary.json's steps_at_capacity), to the page's 4 digits."""
    page = Page(report_page.read_text())
    h = read_history(capped_run / "history.csv")
    summary = json.loads((capped_run / "summary.json").read_text())
    row = door_row(page, "exit")
    assert float(row["through (people)"]) == pytest.approx(h["evacuated_exit"][-1], rel=1e-3)
    assert float(row["capacity (p/(m s))"]) == 1.0 and float(row["width (m)"]) == pytest.approx(1.2)
    assert float(row["peak flow (/s)"]) <= 1.2 * (1 + 1e-9)
    full = h["flow_exit"] >= (1 - 1e-9) * 1.2
    assert np.count_nonzero(full) == summary["doors"]["exit"]["steps_at_capacity"] > 0
    seconds = float(np.sum(np.diff(h["time"], prepend=0.0)[full]))
    assert float(row["time at capacity (s)"]) == pytest.approx(seconds, rel=1e-3)
    assert 0 < seconds <= h["time"][-1]
    checks = {r[0]: r[1] for r in page.rows if len(r) == 2}   # the invariants of the run, as summary.json has them
    assert checks["relative mass error"] == f"{summary['mass_error']:.4g}" and float(checks["least density"]) >= 0
    assert float(checks["largest density"]) <= 5.4 * (1 + 1e-12)
    queue = float(row["longest queue (people)"].split()[0])   # a queue forms, smaller than the crowd
    assert 0 < queue < h["mass"][0]


def test_who_is_left_and_the_times_not_reached(capped_run, report_page):
    """The run stops at time.end with people inside: the page says how many and why, and that the crowd was not
    evacuated; t99 was not reached ('-')."""
    page = Page(report_page.read_text())
    text = report_page.read_text()
    left = json.loads((capped_run / "summary.json").read_text())["remaining"]
    assert f"{left['people']:.4g} people (time.end)" in text and "not evacuated by t = 6 s" in text
    times = next(r for r in page.rows if r[:1] == ["evacuation time"])
    assert page.rows[page.rows.index(times) + 1][times.index("t99")] == "-"


@pytest.mark.parametrize("where", ["missing", "empty", "file"])
def test_a_bad_outdir_is_one_line_and_exit_code_2(tmp_path, where):
    """No directory, a directory without a run, a file: one line naming it, exit code 2, nothing written."""
    target = tmp_path / where
    if where == "empty":
        target.mkdir()
    elif where == "file":
        target.write_text("x")
    result = CliRunner().invoke(main, ["report", str(target)])
    assert result.exit_code == 2 and isinstance(result.exception, SystemExit)   # no traceback
    assert result.output.count("\n") == 1 and str(target) in result.output and "error" in result.output
    assert sorted(p.name for p in tmp_path.rglob("*")) == ([] if where == "missing" else [where])


def test_the_page_goes_where_out_says(report_page):
    """-o: the page written there, the run's directory left as it was."""
    out = report_page.parent.parent / "elsewhere.html"
    before = sorted(p.name for p in report_page.parent.iterdir())
    result = CliRunner().invoke(main, ["report", str(report_page.parent), "-o", str(out), "--times", "2"])
    assert result.exit_code == 0, result.output
    assert result.output == f"wrote {out}\n" and Page(out.read_text()).sections[-1] == "maps"
    assert sorted(p.name for p in report_page.parent.iterdir()) == before


def test_the_report_of_a_disc_run(tmp_path):
    """A micro run: the discs on the maps (no level of service: no density field), its exit's row without flows
    (the disc model records none per door), the people counted in discs."""
    out = tmp_path / "discs"
    result = CliRunner().invoke(main, ["run", str(CASES / "narrow-door-micro"), "--out", str(out), "-q",
                                       "--set", "time.end=1", "--set", "output.every=0.5"])
    assert result.exit_code == 0, result.output
    result = CliRunner().invoke(main, ["report", str(out)])
    assert result.exit_code == 0, result.output
    page = Page((out / "report.html").read_text())
    h = read_history(out / "history.csv")
    assert "Density and level of service" not in (out / "report.html").read_text()
    assert len(page.images) >= 2 + 4 and all(src.startswith("data:image/png;base64,") for src in page.images)
    row = door_row(page, "exit")
    assert row["kind"] == "exit" and row["through (people)"] == "-" and row["longest queue (people)"] == "-"
    people = next(r for r in page.rows if r[:1] == ["people at t = 0"])
    assert people[1] == f"{h['count'][0]:.4g} people"


def test_the_values_of_a_case_are_escaped():
    """A title (user input) with markup is shown as text, never run: no script on the page."""
    from femcrowd.report.page import render

    text = render({"title": "<script>alert(1)</script> & co", "directory": "d", "run": None, "study": None})
    assert "<script>" not in text and "&lt;script&gt;alert(1)&lt;/script&gt; &amp; co" in text
    assert Page(text).links == []


def test_the_maps_of_a_building_draw_each_floor_beside_the_others(tmp_path):
    """A building's frames are at their elevations: the maps lay the floors side by side as the pictures do
    (plot/levels.py), each floor's cells under its own walls, not all of them on the ground floor's."""
    from femcrowd.driver.reading import RunDirectory
    from femcrowd.plot.pictures import FloorPlan
    from femcrowd.report.figures import frame_figure

    out = tmp_path / "building"
    result = CliRunner().invoke(main, ["run", str(CASES / "three-storeys"), "--out", str(out), "-q",
                                       "--set", "time.end=0.5"])
    assert result.exit_code == 0, result.output
    run = RunDirectory(out)
    plan = FloorPlan(run)
    figure = frame_figure(run, plan, 0, "the scene")
    cells = figure.axes[0].collections[0]                       # the tripcolor of the densities
    x = np.concatenate([path.vertices[:, 0] for path in cells.get_paths()])
    walls = plan.levels.segments(np.ones(plan.levels.domain.mesh.facets.shape[1], bool))[..., 0]
    assert x.min() == pytest.approx(walls.min()) and x.max() == pytest.approx(walls.max())
    assert x.max() - x.min() > 2.5 * np.ptp(plan.levels.domain.points[:, 0])   # three floors over each other in plan
