"""Convergence studies and sweeps: observed rates on small series, report files, dask == serial,
self-convergence, bad input."""

import csv
import math

import pytest
from click.testing import CliRunner

from femcrowd.case import load_case
from femcrowd.cli import main
from femcrowd.errors import InputError
from femcrowd.studies.convergence import (
    TIMING,
    collect_rows,
    observed_orders,
    plan_study,
    reference_curves,
    replot,
    run_task,
    study,
)
from femcrowd.studies.execute import execute
from femcrowd.studies.measures import METRICS

from ..support import CASES


@pytest.fixture(scope="module")
def corridor(tmp_path_factory):
    out = tmp_path_factory.mktemp("corridor")
    return study(CASES / "corridor-wall", 3, out=out, serial=True)


def finest_order(rows, metric):
    orders = observed_orders(rows, metric)
    last = max(r["level"] for r in rows)
    return orders[(rows[-1]["series"], rows[-1]["time"], last)]


def test_corridor_observed_orders(corridor):
    rows, text, out = corridor
    assert finest_order(rows, "l1") >= 0.4
    assert finest_order(rows, "front_error") >= 0.8
    l1 = [r["l1"] for r in rows]
    assert l1[0] > l1[1] > l1[2]


def test_report_files(corridor):
    rows, text, out = corridor
    with open(out / "convergence.csv") as f:
        table = list(csv.DictReader(f))
    assert len(table) == 3
    for column in ("series", "level", "cells", "h", "steps", "time", *TIMING, *METRICS, "mass_error"):
        assert column in table[0], column
    assert [int(r["level"]) for r in table] == [0, 1, 2]
    assert float(table[2]["h"]) < float(table[0]["h"])
    md = (out / "convergence.md").read_text()
    assert "exact solution `wall-accumulation`" in md and "## t = 1.2" in md
    # the finer levels carry their observed order in parentheses, e.g. "2.4e-03 (1.04)"
    order = f"({finest_order(rows, 'front_error'):.2f})"
    assert order in md
    for png in ("error_vs_h.png", "error_vs_time.png"):
        data = (out / png).read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 20_000


def test_the_plots_are_drawn_again_from_the_table(corridor, tmp_path):
    """replot: the study's convergence.csv alone (copied elsewhere) gives the plots the study drew, byte for byte
    (matplotlib's PNG of the same figure), and leaves the tables as they are."""
    rows, text, out = corridor
    (tmp_path / "convergence.csv").write_bytes((out / "convergence.csv").read_bytes())
    replot(tmp_path, CASES / "corridor-wall")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["convergence.csv", "error_vs_h.png", "error_vs_time.png"]
    for png in ("error_vs_h.png", "error_vs_time.png"):
        assert (tmp_path / png).read_bytes() == (out / png).read_bytes()


def test_radial_errors_decrease_and_the_reference_curves_are_read(tmp_path):
    rows, text, out = study(CASES / "radial", 3, out=tmp_path, serial=True)
    l1 = [r["l1_pixels"] for r in rows]
    radius = [abs(r["front_error"]) for r in rows]
    assert l1[0] > l1[1] > l1[2] and radius[0] > radius[1] > radius[2]
    assert all(r["mass_error"] < 1e-10 for r in rows)
    assert ("Lagrangian OT, pysdot (bar to beat)", "l1_pixels") in reference_curves(load_case(CASES / "radial"))
    assert (out / "frontier.png").stat().st_size > 20_000 and "frontier.png" in text


def test_dask_gives_the_serial_numbers(tmp_path):
    import dask
    from dask.distributed import LocalCluster

    base, exact, tasks = plan_study(CASES / "corridor-wall", 2)
    serial = collect_rows(tasks, execute(run_task, tasks, serial=True))
    with dask.config.set({"temporary-directory": str(tmp_path)}), \
            LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster:
        parallel = collect_rows(tasks, execute(run_task, tasks, scheduler=cluster.scheduler_address))
    assert len(serial) == len(parallel) == 2
    for a, b in zip(serial, parallel):
        assert {k: v for k, v in a.items() if k not in TIMING + ("solve_seconds",)} == \
               {k: v for k, v in b.items() if k not in TIMING + ("solve_seconds",)}


def test_room_reports_self_convergence(tmp_path):
    rows, text, out = study(CASES / "room", 2, out=tmp_path, overrides=["time.end=0.5"], serial=True)
    assert "self-convergence" in text
    coarse, finest = rows
    assert all(math.isnan(finest[m]) for m in METRICS)
    assert 0 < coarse["l1"] < 1 and coarse["symdiff"] >= 0 and math.isnan(coarse["front_error"])


def test_time_step_series_and_options_make_one_series_each():
    base, exact, tasks = plan_study(CASES / "radial", 2, cfls=(0.5, 0.25), set_values=["scheme.transport=upwind,muscl"])
    assert len(tasks) == 8
    assert {t.series for t in tasks} == {f"scheme.transport={o}, time.cfl={c}" for o in ("upwind", "muscl")
                                         for c in (0.5, 0.25)}
    assert {t.cfl for t in tasks} == {0.5, 0.25}


@pytest.mark.parametrize("args, key", [
    (dict(levels=3, set_values=["scheme.transport"]), "scheme.transport"),
    (dict(levels=3, set_values=["scheme.transport=upwind,dg7"]), "scheme.transport"),
    (dict(levels=3, overrides=["exact.k=2"]), "exact.k"),
    (dict(levels=3, times=(9.0,)), "--times"),
])
def test_bad_study_input_names_the_key(args, key):
    with pytest.raises(InputError) as err:
        plan_study(CASES / "radial", **args)
    assert key in str(err.value)


def test_cli_bad_input_is_one_line_and_writes_nothing(tmp_path):
    result = CliRunner().invoke(main, ["convergence", str(CASES / "radial"), "--set-values", "scheme.transport=dg5",
                                       "--out", str(tmp_path / "report"), "--serial"])
    assert result.exit_code == 2
    assert "scheme.transport" in result.output and "Traceback" not in result.output
    assert not (tmp_path / "report").exists()


def test_higher_order_transports_beat_upwind_on_the_corridor():
    """At equal mesh, the limited reconstructions cut the L1 error of the wall-accumulation case
    (the crowd's free boundary is the error); the one-stage variant keeps it sharpest."""
    base, exact, tasks = plan_study(CASES / "corridor-wall", 2,
                                    set_values=["scheme.transport=upwind,muscl,compressive"])
    finer = [t for t in tasks if t.level == 1]
    rows = collect_rows(finer, execute(run_task, finer, serial=True))
    assert [r["series"] for r in rows] == [f"scheme.transport={s}" for s in ("upwind", "muscl", "compressive")]
    upwind, muscl, compressive = (r["l1"] for r in rows)
    assert muscl < 0.5 * upwind and compressive < 0.5 * muscl


@pytest.mark.parametrize("transport", ["muscl", "compressive"])
def test_a_study_refuses_a_cfl_above_the_transport_limit(transport):
    with pytest.raises(InputError, match="time.cfl"):
        plan_study(CASES / "radial", 2, cfls=(0.5, 0.8), set_values=[f"scheme.transport={transport}"])


def test_levels_of_equal_h_have_no_order():
    """The same mesh listed twice in [convergence] meshes: no order between them (not a ZeroDivisionError)."""
    rows = [{"series": "default", "time": 1.0, "level": k, "h": 0.1, "l1": e} for k, e in enumerate((0.2, 0.1))]
    assert math.isnan(observed_orders(rows, "l1")[("default", 1.0, 1)])
