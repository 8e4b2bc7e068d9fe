"""``femcrowd convergence``, ``sweep`` and ``stress``: studies made of many runs."""

import sys
from pathlib import Path

import click

from ..errors import InputError
from ..files import make_directory, write_text
from ..timer import Stopwatch
from .main import force_option, main, quiet_option, scheduler_option, serial_option, set_option, study_out_option


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


def series_options(levels: int):
    """--levels, --cfl and --set-values: the refinement series of a study (convergence, evacuation-times)."""
    options = [
        click.option("--levels", type=click.IntRange(2, 9), default=levels, show_default=True,
                     help="Refinement levels: mesh.refine = base + 0..N-1 (or the first N of [convergence] meshes)."),
        click.option("--cfl", callback=_floats("--cfl"), metavar="C1,C2,...",
                     help="CFL numbers: one series per value (time-step study)."),
        click.option("--set-values", "set_values", multiple=True, metavar="KEY=V1,V2,...",
                     help="One series per value, e.g. scheme.transport=upwind,muscl (repeatable: all combinations)."),
    ]

    def decorate(command):
        for option in reversed(options):
            command = option(command)
        return command
    return decorate


@main.command()
@click.argument("case_dir", type=click.Path())
@series_options(levels=3)
@click.option("--times", callback=_floats("--times"), metavar="T1,T2,...",
              help="Measure also at these times (the final time always).")
@set_option
@study_out_option("convergence")
@serial_option
@scheduler_option
@force_option
@quiet_option
def convergence(case_dir, levels, cfl, set_values, times, overrides, out, serial, scheduler, force, quiet):
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
    from ..studies.convergence import study

    rows, text, out_dir = study(case_dir, levels, out, overrides, cfl, set_values, times, serial,
                                scheduler, force, echo=click.echo, quiet=quiet)
    click.echo(text)
    click.echo(f"report: {out_dir}/convergence.md, convergence.csv, error_vs_h.png, error_vs_time.png")


@main.command("evacuation-times")
@click.argument("case_dir", type=click.Path())
@series_options(levels=4)
@click.option("--settings", type=click.Choice(["case", "recommended", "fast"]), default="case", show_default=True,
              help="case: the case as it is; recommended: the recommended settings of docs/validation.md on it "
                   "(Predtechenskii and Milinskii's law at its free speed, no push, slip walls, cfl 1, the capacity "
                   "of its width on every exit and interior door); fast: the same with the fast step "
                   "(implicit-godunov at 1.5 times the median cell's CFL step), before --set.")
@click.option("--join", type=click.Path(), metavar="DIR",
              help="Tabulate also the levels of an earlier evacuation-times study of the same case and settings (its "
                   "--out), by mesh size: a finer level run alone gets the differences and orders of all of them; a "
                   "mesh run in both must give the same steps and times to the bit.")
@set_option
@study_out_option("evacuation")
@serial_option
@scheduler_option
@force_option
@quiet_option
def evacuation_times(case_dir, levels, cfl, set_values, settings, join, overrides, out, serial, scheduler, force,
                     quiet):
    """Evacuation times of a macro case under mesh refinement: when 50, 90, 99 %, all but
    time.empty_fraction of the crowd and the last person (all but half a person) are out, on each level,
    with the change between levels, the observed order and Richardson's estimate of the converged time.

    Writes evacuation.csv and evacuation.md (docs/convergence.md, "Evacuation times").

    \b
    Examples:
      femcrowd evacuation-times cases/room --levels 3
      femcrowd evacuation-times cases/two-exits --levels 3 --serial --out /tmp/two-exits-times
      femcrowd evacuation-times cases/room --levels 3 --settings recommended
      femcrowd evacuation-times cases/room --levels 3 --settings fast
      femcrowd evacuation-times cases/room --levels 3 --out /tmp/room-times
      femcrowd evacuation-times cases/room --levels 2 --set mesh.refine=2 --join /tmp/room-times --out /tmp/room-4
    """
    from ..studies.evacuation import study

    rows, text, out_dir = study(case_dir, levels, out, overrides, cfl, set_values, serial, scheduler, force,
                                echo=click.echo, quiet=quiet, settings=settings, join=join)
    click.echo(text)
    click.echo(f"report: {out_dir}/evacuation.md, evacuation.csv")


@main.command()
@click.argument("case_dir", type=click.Path())
@click.option("--set-values", "set_values", multiple=True, required=True, metavar="KEY=V1,V2,...",
              help="Values of a case key, e.g. initial.density=0.4,0.6 (repeatable: all combinations).")
@set_option
@study_out_option("sweep")
@serial_option
@scheduler_option
@force_option
@quiet_option
def sweep(case_dir, set_values, overrides, out, serial, scheduler, force, quiet):
    """Run a case for every combination of parameter values (in parallel through dask).

    Each run writes its own output directory (frames, history.csv, summary.json);
    sweep.csv, sweep.md and sweep.json tabulate their summaries.

    \b
    Example:
      femcrowd sweep cases/room --set-values velocity.speed=1,1.5 --set time.end=20
    """
    from ..studies.sweep import sweep as run_sweep

    rows, text, root = run_sweep(case_dir, set_values, out, overrides, serial, scheduler, force, echo=click.echo,
                                 quiet=quiet)
    click.echo(text)
    click.echo(f"runs and sweep.csv in {root}")


@main.command()
@click.option("--out", type=click.Path(), default="stress-output", show_default=True,
              help="Directory for the runs (one per scene) and the table stress.csv / stress.md, "
                   "relative to the current directory.")
@click.option("--only", multiple=True, metavar="SCENE", help="Run only this scene (repeatable).")
@click.option("--cases", type=click.Path(), help="Directory of scene case directories (default: cases/stress).")
@force_option
@click.option("--checks", is_flag=True, help="Print every check of every scene under its row.")
@quiet_option
def stress(out, only, cases, force, checks, quiet):
    """Run the stiff and extreme scenes of cases/stress and check every invariant.

    Each scene is a normal case run through the controller (femcrowd run); its
    summary.json, history.csv and frames are checked against the invariants of
    docs/model.md and the scene's exact solution. One row per scene; exit
    code 1 if any scene fails.

    \b
    Example:
      femcrowd stress
      femcrowd stress --only closed-saturated --only wall-a0999 --out stress-check
    """
    from ..studies import stress as st

    clock = Stopwatch()

    def echo(result):
        click.echo(st.format_row(result))
        for c in result.checks if checks else ():
            click.echo(f"    {'ok  ' if c.ok else 'FAIL'} {c.what}" + (f": {c.detail}" if c.detail else ""))

    st.scenes(cases or st.CASES, only)  # a bad --only is one line, before the table starts
    click.echo(st.header())
    results, root = st.run_matrix(out, only, cases, force, echo, quiet)
    for r in results:
        for c in r.failures():
            click.echo(f"FAIL {r.name}: {c.what}: {c.detail}")
    passed = sum(r.passed for r in results)
    click.echo(f"{passed}/{len(results)} scenes pass in {clock.seconds:.0f} s; "
               f"table: {root / 'stress.md'}, {root / 'stress.csv'}; runs: {root}/<scene>")
    if passed < len(results):
        sys.exit(1)


@main.command()
@click.option("--out", type=click.Path(), default="rimea-output", show_default=True,
              help="Directory for the runs (OUT/<case>-<model>) and the table rimea.md, relative to the current "
                   "directory.")
@click.option("--only", multiple=True, metavar="TEST", help="Run only this RiMEA test, by number (repeatable).")
@click.option("--model", "models", multiple=True,
              type=click.Choice(["macro", "macro-capacity", "macro-pushing", "macro-recommended",
                                 "macro-weidmann-push", "micro", "micro-recommended", "macro-routes", "micro-routes"]),
              help="Run only this model and setting (repeatable; default: all). macro, micro: the paper's; "
                   "-capacity: a capacity of 1.9 persons/(m s) on every door; -pushing: Weidmann's law with "
                   "push 0.2; -recommended: the settings of docs/validation.md; -weidmann-push: the recommended "
                   "settings before, Weidmann's law, push 0.2 and 1.9 on every door; -routes: the recommended ones "
                   "with the route choice velocity.route = \"congestion\" (tests 10, 11 and 14 only).")
@click.option("--seeds", type=click.IntRange(min=1), default=None, metavar="N",
              help="Run each disc variant N times, with micro.seed = 1 to N (OUT/<case>-<model>-seed<k>), and give "
                   "each of its figures as the median (min-max) over the seeds, its verdict as pass k/N, fail k/N (the "
                   "discs' sampling, their fluctuation and which arch holds at a door vary with the seed); the macro "
                   "variants, deterministic, run once. Default: one run with the case's seed.")
@quiet_option
def rimea(out, only, models, seeds, quiet):
    """Run the RiMEA verification tests of cases/rimea with both models and print the table.

    Tests 1 (corridor), 2 and 3 (up and down a stair), 4 (fundamental
    diagram), 6 (corner), 8 (a three-storey building), 9 (four doors, then
    two), 10 (assigned exits), 11 (exit choice), 12 (bottlenecks), 13 (a jam
    in front of a stair) and 14 (routes over floors) of the RiMEA guideline,
    as docs/rimea.md describes them: the criterion as RiMEA states it, each
    model and setting's result, pass or fail (8 and 14: documented). A failed
    verdict is a result (the docs say where a model cannot meet a criterion,
    and why), not an error.

    \b
    Examples:
      femcrowd rimea
      femcrowd rimea --only 9 --model macro --out /tmp/rimea
      femcrowd rimea --only 10 --only 11 --out /tmp/rimea
      femcrowd rimea --seeds 5 --model micro --model micro-recommended
    """
    from ..studies import rimea as rm

    clock = Stopwatch()
    try:
        rm.select(only)
    except ValueError as err:
        raise click.BadParameter(str(err), param_hint="--only") from None
    rows = rm.run_all(only, models or rm.MODELS, out=out, echo=click.echo, seeds=seeds, quiet=quiet)
    table = rm.table_markdown(rows)
    write_text(make_directory(out) / "rimea.md", table, sync=True)
    click.echo("\n" + table)
    failed = sum(v[0].passed is False for _, verdicts in rows for v in verdicts.values() if v is not None)
    click.echo(f"{len(rows)} tests, {failed} failed verdicts, in {clock.seconds:.0f} s; "
               f"table: {Path(out) / 'rimea.md'}; runs: {out}/<case>-<model>")


@main.command()
@click.option("--scene", type=click.Choice(["bottleneck", "corridor"]), default="bottleneck", show_default=True,
              help="bottleneck: the flow through bottlenecks of 0.5 to 2.4 m against the experiments the settings "
                   "were calibrated on; corridor: femcrowd's independent check, a 1.8 m corridor with a narrowing "
                   "of 0.7, 0.95, 1.2 or 1.8 m at its exit (the Hermes 2009 uni-directional runs), never used to "
                   "calibrate anything.")
@click.option("--out", type=click.Path(), default=None,
              help="Directory of the runs' table, relative to the current directory (default: validation-output, "
                   "or corridor-output for --scene corridor): validation.csv, validation.md and validation.png, or "
                   "corridor.csv and corridor.md.")
@click.option("--settings", default=None, metavar="S1,S2,...",
              help="Settings to run (default: all): paper, weidmann, pushing, capacity, weidmann-push, recommended, "
                   "fast (the recommended ones with the fast step), discs-paper, discs.")
@click.option("--widths", callback=_floats("--widths"), metavar="W1,W2,...",
              help="Bottleneck widths in m (default: 0.5,0.8,1,1.2,1.6,2,2.4,3,3.6,4.4,5), or the corridor's exit "
                   "widths (default: 0.7,0.95,1.2,1.8, the experiment's).")
@click.option("--inflow", type=float, default=None, metavar="PERSONS/S",
              help="--scene corridor: persons per second arriving at the corridor's entrance (default: the mean "
                   "flow of the experiment's run without a narrowing, 2.943).")
@click.option("--levels", type=click.IntRange(1, 5), default=3, show_default=True,
              help="Meshes of the macro settings: the plan's and uniform refinements.")
@click.option("--seeds", type=click.IntRange(1, 50), default=5, show_default=True,
              help="Seeds of the disc settings.")
@click.option("--diagram", is_flag=True,
              help="Instead of the bottleneck: speed and specific flow against density in RiMEA test 4's corridor, "
                   "each macro setting with a speed law beside the law's published diagram (diagram.csv, diagram.md).")
@set_option
@serial_option
@scheduler_option
@force_option
@quiet_option
def validate(scene, out, settings, widths, inflow, levels, seeds, diagram, overrides, serial, scheduler, force,
             quiet):
    """Flow through a bottleneck against its width, each model beside the experiments;
    or, with --scene corridor, femcrowd's independent check.

    A crowd of 90 waits in front of a corridor 2 m long and 0.5 ... 2.4 m
    wide (wider: the same scene magnified); each setting (the paper's
    models, a speed law that pushes, door capacities, the recommended
    settings, Predtechenskii and Milinskii's law with capacities of the
    width, arch-breaking discs) runs on three meshes or five seeds. Writes
    validation.csv (every run), validation.md (specific flows, converged)
    and validation.png (with the published experiments). docs/validation.md
    shows the result; all settings take about an hour on 2 cores.

    With --scene corridor: people enter a corridor 8 m long and 1.8 m wide
    and leave through an opening of 0.7, 0.95, 1.2 or 1.8 m in its end
    wall; each setting's exit flow, last person out and density in front of
    the exit, divided by the experiment's figures (docs/validation.md, "An
    independent check"). Writes corridor.csv and corridor.md.

    \b
    --set changes a key in every run (after the setting's own keys), e.g.
    another fluctuation of the discs.

    \b
    Examples:
      femcrowd validate --settings pushing,capacity --widths 1.0 --levels 2 --out /tmp/validation
      femcrowd validate --settings discs-paper --widths 0.5 --set micro.fluctuation=2.5 --out /tmp/discs
      femcrowd validate --scene corridor --settings recommended --widths 0.7 --levels 1 --serial
      femcrowd validate --diagram --settings recommended --out /tmp/diagram
      femcrowd validate
    """
    from ..studies import validation as va

    clock = Stopwatch()
    if diagram and scene == "corridor":
        raise InputError("--diagram", None, True, "not with --scene corridor: the diagram has its own corridor")
    if diagram:
        from ..studies import diagram as fd

        chosen = tuple(s.strip() for s in settings.split(",")) if settings else None
        table, text, root = fd.diagram(out or "validation-output", chosen, levels=levels, overrides=overrides,
                                       serial=serial, scheduler=scheduler, force=force, echo=click.echo, quiet=quiet)
        click.echo("\n" + text)
        click.echo(f"{len(table)} rows in {clock.seconds:.0f} s; table: {root / 'diagram.md'}, "
                   f"runs: {root / 'diagram.csv'}")
        return
    chosen = tuple(s.strip() for s in settings.split(",")) if settings else tuple(va.SETTINGS)
    if scene == "corridor":
        from ..studies import corridor

        table, text, root = corridor.check(out or "corridor-output", chosen, widths or tuple(corridor.runs()),
                                           levels, seeds, overrides, inflow, serial, scheduler, force,
                                           echo=click.echo, quiet=quiet)
        click.echo("\n" + text)
        click.echo(f"{len(table)} rows in {clock.seconds:.0f} s; table: {root / 'corridor.md'}, "
                   f"runs: {root / 'corridor.csv'}")
        return
    if inflow is not None:
        raise InputError("--inflow", None, inflow, "only for --scene corridor")
    table, text, root = va.validate(out or "validation-output", chosen, widths or va.WIDTHS, levels, seeds,
                                    overrides, serial, scheduler, force, echo=click.echo, quiet=quiet)
    click.echo("\n" + text)
    click.echo(f"{len(table)} rows in {clock.seconds:.0f} s; table: {root / 'validation.md'}, "
               f"runs: {root / 'validation.csv'}, plot: {root / 'validation.png'}")


@main.command()
@click.option("--levels", type=click.IntRange(2, 6), default=4, show_default=True,
              help="Levels of uniform refinement.")
def extensions(levels):
    """Refinement studies of the extensions against their exact solutions.

    The LWR Riemann problems of the linear speed law, two populations
    meeting head-on and the saturated evacuation in two colours, each on
    LEVELS meshes: the errors with their observed orders, and the
    invariants over every step of every level (the tables of
    docs/extensions.md).

    \b
    Example:
      femcrowd extensions --levels 3
    """
    from ..studies.extensions import report

    click.echo(report(levels))
