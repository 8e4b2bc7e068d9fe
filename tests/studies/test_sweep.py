"""Parameter sweeps: one run per combination of values, each in its own directory, and a table."""

import csv
import json
from pathlib import Path

from femcrowd.studies.sweep import sweep

from ..support import CASES


def test_sweep_writes_one_run_per_value_and_a_table(tmp_path):
    rows, text, root = sweep(CASES / "corridor-wall", ["scheme.transport=upwind,muscl"], out=tmp_path / "sweep",
                             overrides=["time.end=0.2", "output.every=0.2"], serial=True)
    assert [r["scheme.transport"] for r in rows] == ["upwind", "muscl"]
    for r in rows:
        summary = json.loads((Path(r["output_dir"]) / "summary.json").read_text())
        assert summary["status"] == "completed" and summary["case"]["scheme"]["transport"] == r["scheme.transport"]
        assert r["mass_error"] < 1e-10
    with open(root / "sweep.csv") as f:
        assert len(list(csv.DictReader(f))) == 2
    assert "| scheme.transport |" in (root / "sweep.md").read_text()


def test_an_interrupted_sweep_keeps_its_finished_runs_and_says_so(tmp_path, monkeypatch):
    """Ctrl-C during the second run: one line saying how many runs finished (their directories kept), exit 130,
    no traceback."""
    from click.testing import CliRunner

    import femcrowd.studies.sweep as module
    from femcrowd.cli import main

    finished, run_one = [], module.sweep_task

    def second_interrupted(task):
        if finished:
            raise KeyboardInterrupt
        finished.append(run_one(task))
        return finished[-1]

    monkeypatch.setattr(module, "sweep_task", second_interrupted)
    result = CliRunner().invoke(main, ["sweep", str(CASES / "corridor-wall"), "--set-values",
                                       "scheme.transport=upwind,muscl", "--set", "time.end=0.2", "--serial",
                                       "--out", str(tmp_path / "sweep")])
    assert result.exit_code == 130, result.output
    assert result.stderr == ("femcrowd: interrupted; 1 of the study's 2 runs finished, their output directories are "
                             "kept (the study's table is not written: run it again)\n")
    summary = json.loads((Path(finished[0]["output_dir"]) / "summary.json").read_text())
    assert summary["status"] == "completed"


def sweep_with_a_bad_mesh(tmp_path, *options):
    """`femcrowd sweep` of the corridor on its mesh and on a file that is no mesh: the second member fails."""
    from click.testing import CliRunner

    from femcrowd.cli import main

    (tmp_path / "bad.msh").write_text("not a mesh\n")
    meshes = f'mesh.file=["{tmp_path / "bad.msh"}", "{CASES.parent / "meshes" / "corridor.msh"}"]'
    return CliRunner().invoke(main, ["sweep", str(CASES / "corridor-wall"), "--set-values", meshes, "--set",
                                     "time.end=0.2", "--set", "output.every=0.2", "--out", str(tmp_path / "sweep"),
                                     "-q", *options])


def check_failed_member_is_tabulated(tmp_path, result):
    """The finished member is in sweep.csv, sweep.json and sweep.md with its summary, the failed one with its
    one-line reason; the table is printed, then one line on stderr; exit code 1, no traceback."""
    assert result.exit_code == 1, result.output
    assert "Traceback" not in result.output
    root = tmp_path / "sweep"
    with open(root / "sweep.csv") as f:
        bad, good = csv.DictReader(f)
    assert bad["status"] == "failed" and "cannot read a gmsh .msh" in bad["reason"] and bad["steps"] == ""
    assert good["status"] == "completed" and good["reason"] == "" and float(good["mass_error"]) < 1e-10
    assert json.loads((Path(good["output_dir"]) / "summary.json").read_text())["status"] == "completed"
    assert [r["status"] for r in json.loads((root / "sweep.json").read_text())] == ["failed", "completed"]
    text = (root / "sweep.md").read_text()
    assert "**1 of 2 runs failed:**" in text and f'- mesh.file="{tmp_path / "bad.msh"}": ' in text
    assert text in result.stdout
    [line] = result.stderr.splitlines()
    assert line.startswith("femcrowd: error: 1 of 2 sweep runs failed (mesh.file=") and \
        line.endswith(f"the table of all of them: {root}/sweep.csv and sweep.md")


def test_a_failed_member_leaves_the_others_tabulated(tmp_path):
    """One member on a file that is no mesh, in this process: the other still runs and the sweep is written
    (it used to stop at the failure and write no table)."""
    check_failed_member_is_tabulated(tmp_path, sweep_with_a_bad_mesh(tmp_path, "--serial"))


def test_a_failed_member_leaves_the_others_tabulated_through_dask(tmp_path):
    """The same through a dask scheduler (in-process workers, as test_dask_gives_the_serial_numbers)."""
    import dask
    from dask.distributed import LocalCluster

    with dask.config.set({"temporary-directory": str(tmp_path)}), \
            LocalCluster(n_workers=2, threads_per_worker=1, processes=False, dashboard_address=":0") as cluster:
        result = sweep_with_a_bad_mesh(tmp_path, "--scheduler", cluster.scheduler_address)
    check_failed_member_is_tabulated(tmp_path, result)


def test_an_interrupted_sweep_does_not_count_a_failed_member_as_finished(tmp_path, monkeypatch):
    """The first member fails, Ctrl-C in the second: no run finished (a failed one is not counted)."""
    from click.testing import CliRunner

    import femcrowd.studies.sweep as module
    from femcrowd.cli import main

    def fail_then_interrupt(task):
        if task.values["scheme.transport"] == "upwind":
            raise RuntimeError("no step")
        raise KeyboardInterrupt

    monkeypatch.setattr(module, "sweep_task", fail_then_interrupt)
    result = CliRunner().invoke(main, ["sweep", str(CASES / "corridor-wall"), "--set-values",
                                       "scheme.transport=upwind,muscl", "--serial", "--out", str(tmp_path / "sweep"),
                                       "-q"])
    assert result.exit_code == 130, result.output
    assert result.stdout == "  failed: scheme.transport=upwind: RuntimeError: no step\n"
    assert result.stderr.startswith("femcrowd: interrupted; 0 of the study's 2 runs finished")
