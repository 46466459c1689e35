"""``dnarod validate``: run the validation suite and write the report folder."""
from __future__ import annotations

import sys
import time

import click

from dnarod.validate import CHECKS


@click.command("validate")
@click.option("--quick", is_flag=True, help="Short runs, without the slow force-extension check (a few minutes).")
@click.option("-o", "--out", "out_dir", default="validation", show_default=True, type=click.Path(file_okay=False),
              help="Report folder: report.md, results.json and PNG plots; new, empty or a report's (any other "
                   "non-empty folder is refused); locked (OUT/.dnarod.lock) while the checks run.")
@click.option("--only", "only", multiple=True, type=click.Choice(list(CHECKS)),
              help="Run only this check (repeatable).")
@click.option("--overwrite", is_flag=True,
              help="Replace the report already in --out (report.md, results.json and its plots, when the new "
                   "report is written). Without it a folder holding a report is refused.")
def validate(quick, out_dir, only, overwrite):
    """Check the engines against each other and against exact results.

    OUT must be new, empty, or a report folder: a folder holding a report is refused unless --overwrite. Exit
    status 0 if every check passed, 1 otherwise.
    """
    from dnarod.core.io import check_dir_path
    from dnarod.validate import run_validation
    from dnarod.validate.report import summary_table

    check_dir_path(out_dir, what="report folder")  # before the checks run, not after
    t0 = time.perf_counter()
    res = run_validation(out_dir, quick=quick, checks=list(only) or None, echo=lambda m: click.echo(m, err=True),
                         overwrite=overwrite)
    wall = time.perf_counter() - t0
    click.echo(summary_table(res))
    ok = all(r["passed"] for r in res["checks"].values())
    click.echo(f"{'all checks passed' if ok else 'SOME CHECKS FAILED'}; runtime {wall:.1f} s; report: {out_dir}/report.md")
    sys.exit(0 if ok else 1)
