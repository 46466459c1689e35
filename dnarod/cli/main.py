"""Command-line interface: ``dnarod COMMAND``.

Commands live in the module of the concept they serve and are registered at the end of this
file. Errors about bad input are printed as one line and exit with status 2.
"""
from __future__ import annotations

import errno
import sys
import warnings

import click

from dnarod.core.errors import DnarodError, RunWarning


#: File-system errors that are the user's to fix (a path under a regular file, a folder where a
#: file is expected, no permission, a full disk, a name too long): one line, exit status 2.
USER_OS_ERRORS = {errno.ENOTDIR, errno.EISDIR, errno.EEXIST, errno.EACCES, errno.EPERM, errno.ENOSPC,
                  errno.ENAMETOOLONG, errno.ENOENT, errno.EROFS, errno.EDQUOT, errno.EFBIG}


#: click >= 8.2 raises this for a bare group (it shows the help); older click has no such class.
_NO_ARGS_IS_HELP = getattr(click.exceptions, "NoArgsIsHelpError", ())


class OneLineUsageError(click.ClickException):
    """A command-line usage error (unknown option, a value that is not a number, a missing argument) shown
    as one line, ``dnarod: error: ...``, with exit status 2 (click's own shows the usage block too)."""

    exit_code = 2

    def show(self, file=None):
        click.echo(f"dnarod: error: {self.format_message()}", err=True)


def _one_line_usage(exc):
    """The one-line form of a click usage error: the command, the message and where the help is."""
    ctx = exc.ctx
    msg = " ".join(exc.format_message().split())
    where = ctx.command_path if ctx is not None else "dnarod"
    return OneLineUsageError(f"{where}: {msg} (see `{where} --help`)")


class DnarodGroup(click.Group):
    """A click group that turns dnarod's input errors into one-line messages and exit status 2."""

    def make_context(self, info_name, args, parent=None, **extra):
        try:
            return super().make_context(info_name, args, parent=parent, **extra)
        except _NO_ARGS_IS_HELP:
            raise  # a bare `dnarod` (or `dnarod protocol`) prints its help
        except click.UsageError as exc:
            raise _one_line_usage(exc) from None

    def invoke(self, ctx):
        # Python warnings (numpy's "Mean of empty slice", ...) are held back until the command ends: a refused
        # input then prints its one line alone, a finished command prints them after its output. A RunWarning
        # (about a long run that has just begun) is printed when raised, so it is read before the run ends.
        held = []

        def show(message, category, filename, lineno, file=None, line=None):
            if issubclass(category, RunWarning):
                click.echo(f"dnarod: warning: {message}", err=True)
            else:
                held.append(message)

        with warnings.catch_warnings():
            warnings.simplefilter("default")
            warnings.showwarning = show
            rv = self._invoke_one_line(ctx)
        for message in held:
            click.echo(f"dnarod: warning: {message}", err=True)
        return rv

    def _invoke_one_line(self, ctx):
        try:
            return super().invoke(ctx)
        except _NO_ARGS_IS_HELP:
            raise
        except click.UsageError as exc:
            raise _one_line_usage(exc) from None
        except KeyboardInterrupt:
            # click would print "Aborted!" and exit 1; say what is kept and how to go on
            click.echo("dnarod: interrupted; the files written so far are kept (a run continues from its last "
                       "checkpoint with --resume; an ensemble skips its finished members when run again)", err=True)
            sys.exit(130)
        except MemoryError:
            click.echo("dnarod: error: not enough memory for this input (a node count, a sequence or a file too "
                       "large?); give a smaller one", err=True)
            sys.exit(2)
        except EOFError as exc:
            click.echo(f"dnarod: error: an input file ended too early ({exc or 'end of file'}): is it empty or "
                       f"truncated?", err=True)
            sys.exit(2)
        except DnarodError as exc:
            click.echo(f"dnarod: error: {str(exc).splitlines()[0] if str(exc) else type(exc).__name__}", err=True)
            sys.exit(2)
        except OSError as exc:
            if exc.errno not in USER_OS_ERRORS:
                raise
            if exc.filename and exc.errno in (errno.ENOSPC, errno.EDQUOT, errno.EFBIG):
                from dnarod.core.io import write_failure

                click.echo(f"dnarod: error: {write_failure(exc.filename, exc)}", err=True)
                sys.exit(2)
            where = f"{exc.filename}: " if exc.filename else ""
            hint = {errno.ENOTDIR: " (a part of the path is a regular file, not a folder)",
                    errno.EISDIR: " (a folder where a file is expected)"}.get(exc.errno, "")
            click.echo(f"dnarod: error: {where}{exc.strerror}{hint}; choose another path", err=True)
            sys.exit(2)


@click.group(cls=DnarodGroup)
@click.version_option(package_name="dnarod")
def main():
    """dnarod: coarse-grained DNA as a discrete shearable, extensible elastic rod."""


@main.command("forcefields")
@click.argument("name", required=False)
def forcefields_cmd(name):
    """List the bundled force fields, or describe NAME (a bundled name or a .toml path)."""
    import numpy as np

    from dnarod.core.forcefield import available_forcefields, load_forcefield
    from dnarod.physics.thermal import persistence_length
    from dnarod.core.units import kT

    if name is None:
        for n in available_forcefields():
            ff = load_forcefield(n)
            click.echo(f"{n:14s} {ff.kind:14s} {ff.description}")
        return
    ff = load_forcefield(name)
    click.echo(f"name: {ff.name}\nkind: {ff.kind}\nds: {ff.ds} nm\nnode mass: {ff.node_mass:g} amu\n"
               f"node inertia: {np.array2string(ff.node_inertia, precision=4)} amu nm^2\n"
               f"temperature: {ff.temperature:g} K\nstep types: {', '.join(sorted(ff.table))}")
    for s in sorted(ff.table):
        from dnarod.core.parameters import StepParameters
        K, xi0 = ff.table[s]
        lp = persistence_length(StepParameters(K, xi0), ff.ds, kT(ff.temperature))
        click.echo(f"  {s}: bending persistence length (exact, {ff.temperature:g} K) {lp:.2f} nm")


from dnarod.cli.structure import build as _structure_build, pairs as _structure_pairs  # noqa: E402
from dnarod.cli.structure import rebuild as _structure_rebuild, steps as _structure_steps  # noqa: E402

main.add_command(_structure_steps)
main.add_command(_structure_pairs)
main.add_command(_structure_build)
main.add_command(_structure_rebuild)
from dnarod.cli.simulate import lax_run as _lax_run, simulate_cmd as _simulate_cmd  # noqa: E402
main.add_command(_simulate_cmd)
main.add_command(_lax_run)
from dnarod.cli.analyze import analyze_cmd as _analyze_cmd; main.add_command(_analyze_cmd)  # noqa: E402
from dnarod.cli.export import export_cmd as _export_cmd; main.add_command(_export_cmd)  # noqa: E402
from dnarod.cli.validate import validate as _validate; main.add_command(_validate)  # noqa: E402
from dnarod.cli.ensemble import ensemble_cmd as _ensemble_cmd; main.add_command(_ensemble_cmd)  # noqa: E402
from dnarod.cli.protocol import protocol as _protocol_cmd; main.add_command(_protocol_cmd)  # noqa: E402
