"""Command line: ``femcrowd run CASE``, and the other commands (click).

Bad input is reported as one line on stderr with exit code 2, never a traceback.
"""

import logging
import shlex
import sys
from pathlib import Path

import click

from . import __version__
from .case import load_case
from .errors import InputError

log = logging.getLogger("femcrowd")


class FemcrowdGroup(click.Group):
    """A click group that turns InputError into a one-line message and exit code 2."""

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except InputError as err:
            click.echo(f"femcrowd: error: {err}", err=True)
            sys.exit(2)
        except KeyboardInterrupt:
            click.echo("femcrowd: interrupted; frames, history.csv and summary.json written so far "
                       "are kept", err=True)
            sys.exit(130)


# options shared by several commands
set_option = click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
                          help="Override a case key, e.g. --set time.end=5 (repeatable).")
force_option = click.option("--force", is_flag=True,
                            help="Write into a non-empty directory femcrowd did not create.")
quiet_option = click.option("-q", "--quiet", is_flag=True, help="No progress bars.")


def case_run_options(command):
    """CASE_DIR, --set, --out, --force, -q: the arguments of the commands that run a case."""
    for option in reversed([click.argument("case_dir", type=click.Path()), set_option,
                            click.option("--out", type=click.Path(),
                                         help="Output directory (default: [output].dir of the case)."),
                            force_option, quiet_option]):
        command = option(command)
    return command


@click.group(cls=FemcrowdGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="femcrowd")
@click.option("-v", "--verbose", is_flag=True, help="Log solver details.")
def main(verbose):
    """femcrowd: crowd motion with hard congestion on unstructured meshes.

    \b
    Examples:
      femcrowd run cases/room
      femcrowd run cases/room --set time.end=5 --set mesh.refine=1 --out /tmp/room
      femcrowd plot cases/room/output
      femcrowd info cases/room
      femcrowd mesh plan.toml -o plan.msh && femcrowd new my-case --mesh plan.msh
      femcrowd -v run cases/room            (solver details on stderr)

    \b
    Exit codes:
      0    done
      1    a run failed (the message says why; frames and history so far are kept)
      2    bad input or usage: one line naming the file, the key and the value
      130  interrupted (Ctrl-C); frames, history.csv and summary.json so far are kept

    Run `femcrowd COMMAND --help` for a command's options and examples.
    """
    logging.basicConfig(level=logging.INFO if verbose else logging.WARNING,
                        format="%(name)s: %(message)s")


@main.command()
@case_run_options
def run(case_dir, overrides, out, force, quiet):
    """Run the case in CASE_DIR (a directory with case.toml).

    \b
    Examples:
      femcrowd run cases/room --set time.end=5 --out /tmp/room
      femcrowd run cases/narrow-door-micro        (model.type = "micro": discs)
    """
    case = load_case(case_dir, overrides)
    if case["model"]["type"] == "micro":
        from .micro.run import run_micro

        summary = run_micro(case, out, force, quiet)
        click.echo(f"{summary['status']}: {summary['steps']} steps to t = {summary['final_time']:.4g} s "
                   f"in {summary['timing']['wall']:.1f} s; {summary['initial_count']} discs, "
                   f"{summary['evacuated']} evacuated; max overlap {summary['max_overlap_over_radius']:.1e} r")
    else:
        from .run import run_macro

        summary = run_macro(case, out, force, quiet)
        click.echo(f"{summary['status']}: {summary['steps']} steps to t = {summary['final_time']:.4g} s "
                   f"in {summary['timing']['wall']:.1f} s; mass error {summary['mass_error']:.1e}; "
                   f"density in [{summary['min_density_ever']:.3g}, {summary['max_density_ever']:.6g}]")
    if summary["evacuation_time"] is not None:
        click.echo(f"evacuation time: {summary['evacuation_time']:.4g} s")
    click.echo(f"results: {summary['output_dir']}")
    click.echo(f"look at them: {_look(summary['output_dir'], case['model']['type'])}")


def _look(out_dir, model="macro"):
    """The commands that show a run directory's results."""
    pvd = Path(out_dir) / ("discs.pvd" if model == "micro" else "solution.pvd")
    return f"femcrowd plot {shlex.quote(str(out_dir))}   (or ParaView: paraview {shlex.quote(str(pvd))})"


def _times(values):
    """--times 0,10 --times 20 -> [0.0, 10.0, 20.0]."""
    out = []
    for value in values:
        for item in filter(None, (v.strip() for v in value.split(","))):
            try:
                out.append(float(item))
            except ValueError:
                raise click.BadParameter(f"{item!r} is not a number", param_hint="--times") from None
    return out


@main.command()
@click.argument("outdir", type=click.Path())
@click.option("-t", "--times", "times", multiple=True, metavar="T[,T...]",
              help="Times (s) of the pictures, comma-separated or repeated; the nearest frames are used. "
                   "Default: 4 evenly spaced times until 95% of the crowd has left.")
@click.option("--no-animation", is_flag=True, help="Skip the animation (the slowest part).")
@click.option("--mp4", is_flag=True, help="Animation as MP4 instead of GIF (needs imageio-ffmpeg).")
@click.option("-o", "--out", type=click.Path(), help="Directory for the pictures (default: OUTDIR).")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar, no list of files.")
def plot(outdir, times, no_animation, mp4, out, quiet):
    """Pictures, animation and curves of a run's output directory OUTDIR.

    Writes density_t*.png and pressure_t*.png (micro runs: discs_t*.png) at
    the chosen times, density.gif (micro: discs.gif) and curves.png (people
    inside and evacuated, flow rate per exit, max pressure, saturated area).
    Rendering is offscreen: no display needed.

    \b
    Examples:
      femcrowd plot cases/room/output
      femcrowd plot /tmp/room --times 0,5,10 --no-animation
      femcrowd plot /tmp/room -o /tmp/room-pictures
    """
    from .plot import plot_run

    written = plot_run(outdir, _times(times) or None, not no_animation, out, mp4, quiet)
    if not quiet:
        for path in written:
            click.echo(f"wrote {path}")
    click.echo(f"{len(written)} files in {Path(written[0]).parent if written else outdir}")


@main.command()
@click.argument("geometry", type=click.Path())
@click.option("-o", "--out", type=click.Path(), help="The .msh file (default: GEOMETRY with .msh).")
@click.option("--exit-size", type=click.FloatRange(min=0, min_open=True), metavar="H",
              help="Cell size near every exit (m), overriding the exits' own 'size' keys.")
def mesh(geometry, out, exit_size):
    """Mesh the floor plan GEOMETRY (a .toml file) with gmsh.

    The floor plan gives the outer polygon, holes (polygons or circles),
    named exit segments and the cell size (format: femcrowd/geometry.py and
    the shipped meshes/*.toml). The .msh has one boundary group per exit
    name and "wall" for the rest, ready for a case (femcrowd new).

    \b
    Examples:
      femcrowd mesh meshes/room_one_door.toml
      femcrowd mesh plan.toml -o /tmp/plan.msh --exit-size 0.05
    """
    from .geometry import build_mesh
    from .mesh import load_domain

    path = build_mesh(geometry, out, exit_size)
    stats = load_domain(path).statistics()
    groups = ", ".join(f"{name} {length:.3g} m" for name, length in stats["boundary_groups"].items())
    click.echo(f"wrote {path}: {stats['triangles']} triangles, h in [{stats['h_min']:.3g}, {stats['h_max']:.3g}] m, "
               f"min angle {stats['min_angle_deg']:.1f} deg; boundary groups: {groups}")
    click.echo(f"next: femcrowd new CASE_DIR --mesh {shlex.quote(str(path))}")


@main.command()
@click.argument("case_dir", type=click.Path())
@click.option("--mesh", "mesh_file", required=True, type=click.Path(), help="The gmsh .msh file of the scene.")
def new(case_dir, mesh_file):
    """Write a commented CASE_DIR/case.toml for the mesh FILE.msh.

    Exits are the mesh's boundary groups not named wall*; every other key is
    the default, with a comment. An existing case.toml is never overwritten.

    \b
    Example:
      femcrowd new cases/my-hall --mesh meshes/two_exits.msh
      femcrowd run cases/my-hall
    """
    from .casetools import new_case

    file = new_case(case_dir, mesh_file)
    click.echo(f"wrote {file}; edit [initial] density, then: femcrowd run {shlex.quote(str(case_dir))}")


@main.command()
@click.argument("case_dir", type=click.Path())
@set_option
def info(case_dir, overrides):
    """Resolved configuration, mesh statistics and run estimate of a case.

    Mesh statistics: cells, edge lengths, angles, Delaunay check, boundary
    groups and their lengths. Estimate: number of time steps and a run-time
    range measured from a few steps on this machine (below 1 s for the
    shipped cases). Nothing is written.

    \b
    Examples:
      femcrowd info cases/room
      femcrowd info cases/room --set mesh.refine=2
    """
    from .casetools import case_info, format_info

    click.echo(format_info(case_info(load_case(case_dir, overrides))))


def _floats(option):
    """Click callback: '0.5,0.25' -> (0.5, 0.25)."""
    def parse(ctx, param, value):
        if value is None:
            return ()
        try:
            return tuple(float(v) for v in value.split(",") if v.strip())
        except ValueError:
            raise InputError(option, None, value, "expected comma-separated numbers") from None
    return parse


@main.command()
@click.argument("case_dir", type=click.Path())
@click.option("--levels", type=click.IntRange(2, 9), default=3, show_default=True,
              help="Refinement levels: mesh.refine = base + 0..N-1 (or the first N of [convergence] meshes).")
@click.option("--cfl", callback=_floats("--cfl"), metavar="C1,C2,...",
              help="CFL numbers: one series per value (time-step study).")
@click.option("--set-values", "set_values", multiple=True, metavar="KEY=V1,V2,...",
              help="One series per value, e.g. scheme.transport=upwind,muscl (repeatable: all combinations).")
@click.option("--times", callback=_floats("--times"), metavar="T1,T2,...",
              help="Measure also at these times (the final time always).")
@set_option
@click.option("--out", type=click.Path(), help="Report directory (default: [output].dir/convergence).")
@click.option("--serial", is_flag=True, help="Run the levels one after the other in this process.")
@click.option("--scheduler", metavar="ADDRESS", help="Use this dask scheduler (default: a LocalCluster).")
@force_option
def convergence(case_dir, levels, cfl, set_values, times, overrides, out, serial, scheduler, force):
    """Mesh-convergence study of a case: errors against h and against run time.

    Errors are measured against the case's [exact] solution, otherwise against
    the finest level (self-convergence). Writes convergence.csv, convergence.md
    (tables with observed orders), error_vs_h.png and error_vs_time.png.

    \b
    Examples:
      femcrowd convergence cases/corridor-wall --levels 4
      femcrowd convergence cases/radial --levels 4 --set-values scheme.transport=upwind,muscl,compressive
      femcrowd convergence cases/room --levels 3 --set time.end=5 --serial
    """
    from .convergence import study

    rows, text, out_dir = study(case_dir, levels, out, overrides, cfl, set_values, times, serial,
                                scheduler, force, echo=click.echo)
    click.echo(text)
    click.echo(f"report: {out_dir}/convergence.md, convergence.csv, error_vs_h.png, error_vs_time.png")


@main.command()
@click.argument("case_dir", type=click.Path())
@click.option("--set-values", "set_values", multiple=True, required=True, metavar="KEY=V1,V2,...",
              help="Values of a case key, e.g. initial.density=0.4,0.6 (repeatable: all combinations).")
@set_option
@click.option("--out", type=click.Path(), help="Sweep directory (default: [output].dir/sweep).")
@click.option("--serial", is_flag=True, help="Run one after the other in this process.")
@click.option("--scheduler", metavar="ADDRESS", help="Use this dask scheduler (default: a LocalCluster).")
@force_option
def sweep(case_dir, set_values, overrides, out, serial, scheduler, force):
    """Run a case for every combination of parameter values (in parallel through dask).

    Each run writes its own output directory (frames, history.csv, summary.json);
    sweep.csv, sweep.md and sweep.json tabulate their summaries.

    \b
    Example:
      femcrowd sweep cases/room --set-values velocity.speed=1,1.5 --set time.end=20
    """
    from .convergence import sweep as run_sweep

    rows, text, root = run_sweep(case_dir, set_values, out, overrides, serial, scheduler, force, echo=click.echo)
    click.echo(text)
    click.echo(f"runs and sweep.csv in {root}")


@main.command()
@click.option("--out", type=click.Path(), default="stress-output", show_default=True,
              help="Directory for the runs (one per scene) and the table stress.csv / stress.md.")
@click.option("--only", multiple=True, metavar="SCENE", help="Run only this scene (repeatable).")
@click.option("--cases", type=click.Path(), help="Directory of scene case directories (default: cases/stress).")
@force_option
@click.option("--checks", is_flag=True, help="Print every check of every scene under its row.")
def stress(out, only, cases, force, checks):
    """Run the stiff and extreme scenes of cases/stress and check every invariant.

    Each scene is a normal case run through the controller (femcrowd run); its
    summary.json, history.csv and frames are checked against the invariants of
    the design note and the scene's exact solution. One row per scene; exit
    code 1 if any scene fails.

    \b
    Example:
      femcrowd stress --out /tmp/stress
      femcrowd stress --only closed-saturated --only wall-a0999
    """
    import time

    from . import stress as st
    from .output import prepare_output_dir

    tic = time.perf_counter()
    cases = cases or st.CASES
    names = st.scenes(cases, only)
    root = prepare_output_dir(out, "femcrowd stress --out", force)
    click.echo(st.header())

    def echo(result):
        click.echo(st.format_row(result))
        for c in result.checks if checks else ():
            click.echo(f"    {'ok  ' if c.ok else 'FAIL'} {c.what}" + (f": {c.detail}" if c.detail else ""))

    results = st.run_all(names, root, cases, echo)
    for r in results:
        for c in r.failures():
            click.echo(f"FAIL {r.name}: {c.what}: {c.detail}")
    st.write_tables(results, root / "stress")
    passed = sum(r.passed for r in results)
    click.echo(f"{passed}/{len(results)} scenes pass in {time.perf_counter() - tic:.0f} s; "
               f"table: {root / 'stress.md'}, {root / 'stress.csv'}; runs: {root}/<scene>")
    if passed < len(results):
        sys.exit(1)


@main.command()
@case_run_options
def compare(case_dir, overrides, out, force, quiet):
    """Run CASE_DIR with the macro and the micro model on the same scene and compare them.

    Writes OUT/macro, OUT/micro (the usual outputs), comparison.csv (people inside for both
    models and the W2 distance between the crowds at each frame time), evacuation.png and
    side-by-side pictures.

    \b
    Example:
      femcrowd compare cases/narrow-door --out /tmp/narrow
    """
    from .compare import compare as run_comparison

    result = run_comparison(load_case(case_dir, overrides), out, force, quiet)
    last = result["rows"][-1]
    for model in ("macro", "micro"):
        t = result[model]["evacuation_time"]
        click.echo(f"{model}: " + (f"evacuated in {t:.4g} s" if t is not None else
                                   f"{last[model + '_inside']:.3g} of {result['discs']} people still "
                                   f"inside at t = {last['time']:.4g} s"))
    click.echo(f"results: {result['output_dir']} (comparison.csv, evacuation.png, side_by_side_*.png)")
