"""``dnarod export RUN``: (re)make a run's PDB + DCD (+ XTC) exports, a thin shell over :func:`dnarod.run.api.export_run`."""
from __future__ import annotations

import click


@click.command("export")
@click.argument("run_dir", metavar="RUN", type=click.Path(file_okay=False))
@click.option("--xtc/--no-xtc", default=None,
              help="Also write trajectory.xtc [default: as the run's settings say (`simulate --xtc/--no-xtc`)].")
def export_cmd(run_dir, xtc):
    """Write RUN/trajectory.pdb, RUN/trajectory.dcd and RUN/trajectory.xtc from RUN/trajectory.dtraj.

    RUN is the folder of a `dnarod simulate` run. The exports are remade from the trajectory as it is
    now (a run whose export failed, was skipped with --no-export, or was made before the run went on),
    each written beside the old file and put in place only when complete.
    """
    from dnarod.run.api import export_run

    files = export_run(run_dir, xtc=xtc)
    click.echo("wrote: " + ", ".join(str(p) for p in files.values()))
