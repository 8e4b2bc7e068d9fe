"""Command line: ``femcrowd run CASE``, and the other commands (click).

Bad input is reported as one line on stderr with exit code 2, never a traceback.
"""

import logging
import sys

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


@click.group(cls=FemcrowdGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="femcrowd")
@click.option("-v", "--verbose", is_flag=True, help="Log solver details.")
def main(verbose):
    """femcrowd: crowd motion with hard congestion on unstructured meshes.

    \b
    Examples:
      femcrowd run cases/room
      femcrowd run cases/room --set time.end=5 --set mesh.refine=1 --out /tmp/room
    """
    logging.basicConfig(level=logging.INFO if verbose else logging.WARNING,
                        format="%(name)s: %(message)s")


@main.command()
@click.argument("case_dir", type=click.Path())
@click.option("--set", "overrides", multiple=True, metavar="KEY=VALUE",
              help="Override a case key, e.g. --set time.end=5 (repeatable).")
@click.option("--out", type=click.Path(), help="Output directory (default: [output].dir of the case).")
@click.option("--force", is_flag=True, help="Write into a non-empty directory femcrowd did not create.")
@click.option("-q", "--quiet", is_flag=True, help="No progress bar.")
def run(case_dir, overrides, out, force, quiet):
    """Run the case in CASE_DIR (a directory with case.toml).

    \b
    Example:
      femcrowd run cases/room --set time.end=5 --out /tmp/room
    """
    from .run import run_macro

    case = load_case(case_dir, overrides)
    summary = run_macro(case, out, force, quiet)
    out_dir = summary["output_dir"]
    click.echo(f"{summary['status']}: {summary['steps']} steps to t = {summary['final_time']:.4g} s "
               f"in {summary['timing']['wall']:.1f} s; mass error {summary['mass_error']:.1e}; "
               f"density in [{summary['min_density_ever']:.3g}, {summary['max_density_ever']:.6g}]")
    if summary["evacuation_time"] is not None:
        click.echo(f"evacuation time: {summary['evacuation_time']:.4g} s")
    click.echo(f"results: {out_dir}  (ParaView: paraview {out_dir}/solution.pvd)")
