"""``dnarod analyze``: the command-line shell of :func:`dnarod.analysis.report.analyze`."""
from __future__ import annotations

import click
from dnarod.analysis.report import analyze


@click.command("analyze")
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.option("--topology", "-t", type=click.Path(dir_okay=False),
              help="All-atom topology (PDB, PSF, PRMTOP, GRO, ...) or, for a .dtraj, the dnarod model .npz "
                   "(default: final_model.npz next to it).")
@click.option("--forcefield", "-f", default=None,
              help="Force field (bundled name or .toml): ds and node mass for the fitted stiffness file, and the "
                   "exact tangent correlation to compare with. Default dna-default.")
@click.option("--out", "-o", type=click.Path(file_okay=False), help="Output folder (default INPUT_analysis/): new, "
                   "empty or an earlier report's (any other non-empty folder is refused).")
@click.option("--circular", is_flag=True, help="The chain is a ring: the last node joins the first; "
                                               "reports Lk, Tw and Wr.")
@click.option("--temperature", type=float, default=None,
              help="K (default: the trajectory's, else the force field's).")
@click.option("--start", type=int, default=None, help="First frame (0-based).")
@click.option("--stop", type=int, default=None, help="Stop before this frame.")
@click.option("--step", type=int, default=None, help="Use every STEP-th frame.")
@click.option("--exclude-ends", type=int, default=None,
              help="Steps/nodes left out at each end (default 1 for all-atom, 0 for dnarod).")
@click.option("--blocks", type=int, default=10, show_default=True, help="Blocks for the error bars.")
@click.option("--allow-gaps", is_flag=True, help="Accept unevenly spaced (missing) frames.")
@click.option("--duplex", type=int, default=1, show_default=True,
              help="Duplex of an all-atom system, numbered from 1 as `dnarod pairs` lists them.")
@click.option("--overwrite", is_flag=True, help="Replace an earlier report in --out (its files are removed first).")
@click.option("--no-plots", is_flag=True, help="Skip the PNG plots.")
def analyze_cmd(input_path, topology, forcefield, out, circular, temperature, start, stop, step, exclude_ends,
                blocks, allow_gaps, duplex, overwrite, no_plots):
    """Analyse a trajectory: step parameters, strains, stiffness, persistence length, Lk/Tw/Wr.

    INPUT is a dnarod .dtraj trajectory or an all-atom trajectory MDAnalysis reads (with
    --topology), or a PDB/mmCIF file (its models are the frames).
    """
    # the report's lines are printed when the analysis has finished: a refusal found on the way (too few
    # frames, an open chain with --circular) is then its one line on stderr, with nothing on stdout before it
    lines = []
    analyze(input_path, topology, forcefield, out, circular, temperature, start, stop, step, exclude_ends,
            blocks, allow_gaps, duplex, plots=not no_plots, echo=lines.append, overwrite=overwrite)
    for line in lines:
        click.echo(line)
