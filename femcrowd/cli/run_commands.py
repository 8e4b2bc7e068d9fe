"""``femcrowd run`` and ``femcrowd compare``: commands that run a case."""

import shlex
from pathlib import Path

import click

from ..case import load_case
from .main import case_run_options, main


@main.command()
@case_run_options
@click.option("--resume", is_flag=True,
              help="Continue the run in the output directory from its checkpoint (written at every frame and on "
                   "Ctrl-C; a run that ended between two frames goes on from the last one), e.g. after an "
                   "interruption or with a larger time.end.")
@click.option("--no-limits", is_flag=True,
              help="Run even what the estimate finds beyond the limits: more than 1e5 frames or 1e8 steps, more "
                   "than 80 % of this machine's memory, more than 50 GB of files (docs/tools.md, \"Limits\"; "
                   "femcrowd info shows the estimate).")
def run(case_dir, overrides, out, force, quiet, threads, resume, no_limits):
    """Run the case in CASE_DIR (a directory with case.toml).

    \b
    Examples:
      femcrowd run cases/room --set time.end=5 --out results/room
      femcrowd run cases/narrow-door-micro        (model.type = "micro": discs)
      femcrowd run cases/room --resume            (continue after Ctrl-C)
    """
    from ..case.units import people_unit
    from ..driver import run as run_case
    from ..driver.limits import LIMITS
    from ..driver.remaining import remaining_text

    case = load_case(case_dir, overrides)
    summary = run_case(case, out, force, quiet, threads=threads, resume=resume,
                       limits=None if no_limits else LIMITS).summary
    if case["model"]["type"] == "micro":
        click.echo(f"{summary['status']}: {summary['steps']} steps to t = {summary['final_time']:.4g} s "
                   f"in {summary['timing']['wall']:.1f} s; {summary['initial_count']} discs, "
                   f"{summary['evacuated']} evacuated; max overlap {summary['max_overlap_r']:.1e} r")
    else:
        click.echo(f"{summary['status']}: {summary['steps']} steps to t = {summary['final_time']:.4g} s "
                   f"in {summary['timing']['wall']:.1f} s; mass error {summary['mass_error']:.1e}; "
                   f"density in [{summary['min_density_ever']:.3g}, {summary['max_density_ever']:.6g}]")
    click.echo(f"left inside: {remaining_text(summary['remaining'], people_unit(case.config))}")
    if summary["evacuation_time"] is not None:
        click.echo(f"evacuation time: {summary['evacuation_time']:.4g} s")
    click.echo(f"results: {summary['output_dir']}")
    click.echo(f"look at them: {_look(summary['output_dir'], case['model']['type'])}")


def _look(out_dir, model="macro"):
    """The commands that show a run directory's results."""
    pvd = Path(out_dir) / ("discs.pvd" if model == "micro" else "solution.pvd")
    return f"femcrowd plot {shlex.quote(str(out_dir))}   (or ParaView: paraview {shlex.quote(str(pvd))})"


@main.command()
@case_run_options
def compare(case_dir, overrides, out, force, quiet, threads):
    """Run CASE_DIR with the macro and the micro model on the same scene and compare them.

    Writes OUT/macro, OUT/micro (the usual outputs), comparison.csv (people inside for both
    models and the W2 distance between the crowds at each frame time), evacuation.png and
    side-by-side pictures.

    \b
    Example:
      femcrowd compare cases/narrow-door
    """
    from ..studies.compare import compare as run_comparison

    result = run_comparison(load_case(case_dir, overrides), out, force, quiet, threads=threads)
    last = result["rows"][-1]
    for model in ("macro", "micro"):
        t = result[model]["evacuation_time"]
        click.echo(f"{model}: " + (f"evacuated in {t:.4g} s" if t is not None else
                                   f"{last[model + '_inside']:.3g} of {result['discs']} people still "
                                   f"inside at t = {last['time']:.4g} s"))
    click.echo(f"results: {result['output_dir']} (comparison.csv, evacuation.png, side_by_side_*.png)")
