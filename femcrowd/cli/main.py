"""The ``femcrowd`` command group: one-line errors, exit codes, the options shared by the commands.

The commands parse their arguments and print; the work is done in the package.
"""

import logging
import sys

import click

from .. import __version__
from ..errors import InputError, Interrupted, RunFailed, StudyFailed
from ..studies.execute import StudyInterrupted


class FemcrowdGroup(click.Group):
    """A click group that turns InputError into a one-line message and exit code 2 (a StudyFailed: its report,
    then one line and exit code 1), and gives every command the group's -v/--verbose (so that it may come after
    the command's name as well as before)."""

    def add_command(self, cmd, name=None):
        cmd.params.append(verbose_option())
        super().add_command(cmd, name)

    def invoke(self, ctx):
        try:
            return super().invoke(ctx)
        except RunFailed as err:
            click.echo(f"femcrowd: error: {err}", err=True)
            sys.exit(1)
        except InputError as err:
            click.echo(f"femcrowd: error: {err}", err=True)
            sys.exit(2)
        except Interrupted as err:
            click.echo(f"femcrowd: interrupted; {err}", err=True)
            sys.exit(130)
        except StudyFailed as err:   # the table of the finished runs, then which failed
            click.echo(err.report)
            click.echo(f"femcrowd: error: {err}", err=True)
            sys.exit(1)
        except StudyInterrupted as err:   # a study without a report of its own (sweep, validate)
            done = sum(result is not None and "failed" not in result for result in err.results)
            click.echo(f"femcrowd: interrupted; {done} of the study's {len(err.results)} runs finished, their output "
                       "directories are kept (the study's table is not written: run it again)", err=True)
            sys.exit(130)
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
out_option = click.option("--out", type=click.Path(),
                          help="Output directory, relative to the current directory (default: [output].dir "
                               "of the case, relative to the case file).")
serial_option = click.option("--serial", is_flag=True, help="Run one after the other in this process.")
scheduler_option = click.option("--scheduler", metavar="ADDRESS",
                                help="Use this dask scheduler (default: a LocalCluster on this machine's cores).")


def study_out_option(name):
    """--out of a study: its directory, by default [output].dir/<name> of the case."""
    return click.option("--out", type=click.Path(),
                        help=f"Directory of the study, relative to the current directory (default: "
                             f"[output].dir/{name} of the case).")


threads_option = click.option("--threads", type=click.IntRange(min=1), default=1, show_default=True,
                               help="BLAS/OpenMP threads (more rarely help: femcrowd's work is sparse).")


def case_run_options(command):
    """CASE_DIR, --set, --out, --force, -q, --threads: the arguments of the commands that run a case."""
    for option in reversed([click.argument("case_dir", type=click.Path()), set_option,
                            out_option, force_option, quiet_option, threads_option]):
        command = option(command)
    return command


def verbose_option() -> click.Option:
    """-v/--verbose: femcrowd's log at INFO (solver details) on stderr. The group and each command have one."""
    return click.Option(["-v", "--verbose"], is_flag=True, expose_value=False, callback=_configure_log,
                        help="Log solver details on stderr.")


def _configure_log(ctx, param, verbose):
    """femcrowd's log on stderr, at INFO if -v was given before or after the command's name (ctx.meta is
    shared by the group's context and the command's), WARNING otherwise."""
    verbose = ctx.meta["femcrowd.verbose"] = ctx.meta.get("femcrowd.verbose", False) or verbose
    log = logging.getLogger("femcrowd")
    log.handlers[:] = [_EchoHandler()]
    log.setLevel(logging.INFO if verbose else logging.WARNING)
    log.propagate = False


@click.group(cls=FemcrowdGroup, context_settings={"help_option_names": ["-h", "--help"]},
             params=[verbose_option()])
@click.version_option(__version__, prog_name="femcrowd")
def main():
    """femcrowd: crowd motion with hard congestion on unstructured meshes.

    \b
    Examples:
      femcrowd run cases/room
      femcrowd run cases/room --set time.end=5 --set mesh.refine=1 --out results/room
      femcrowd plot cases/room/output
      femcrowd info cases/room
      femcrowd mesh plan.toml -o plan.msh && femcrowd new my-case --mesh plan.msh
      femcrowd run cases/room -v            (solver details on stderr; -v also before the command)

    \b
    Exit codes:
      0    done
      1    a run failed (the message says why; frames and history so far are kept)
      2    bad input or usage: one line naming the file, the key and the value
      130  interrupted (Ctrl-C); frames, history.csv and summary.json so far are kept

    Run `femcrowd COMMAND --help` for a command's options and examples.
    """


class _EchoHandler(logging.Handler):
    """femcrowd's log lines on stderr, through click (so that they go where click's output goes)."""

    def emit(self, record):
        click.echo(f"{record.name}: {record.getMessage()}", err=True)
