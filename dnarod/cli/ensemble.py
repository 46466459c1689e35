"""``dnarod ensemble``: run an ensemble spec on a local dask cluster or an existing scheduler."""
from __future__ import annotations

import sys

import click


@click.command("ensemble")
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option("-o", "--out", "outdir", required=True, type=click.Path(file_okay=False),
              help="Ensemble folder (created; the same spec again resumes it).")
@click.option("--scheduler", default=None, help="Address of a running dask scheduler, e.g. tcp://HOST:8786 "
              "[default: a local cluster].")
@click.option("--workers", type=int, default=None,
              help="Local cluster worker processes [default: the cores]; 0 runs the members in this process.")
@click.option("--timeout", type=float, default=10.0, show_default=True,
              help="Seconds to wait for --scheduler to answer.")
@click.option("--overwrite", is_flag=True, help="Replace a folder made by another spec.")
@click.option("--dashboard", is_flag=True, help="Serve the local cluster's dask dashboard (needs bokeh).")
@click.option("--progress/--no-progress", default=True, show_default=True)
def ensemble_cmd(spec, outdir, scheduler, workers, timeout, overwrite, dashboard, progress):
    """Run the ensemble SPEC (a TOML file: [ensemble], [base], [axes], [analysis]) into OUT.

    Each member is a run directory OUT/members/<id>/; finished members are skipped and partial
    ones resume from their checkpoints when the command is run again. Writes OUT/results.parquet,
    OUT/results.csv, OUT/plot_<axis>.png and OUT/summary.json. Exit status 1 if members failed.
    """
    import logging

    from dnarod.core.errors import ParameterError
    from dnarod.workflows.ensemble.cluster import available_cores, connect
    from dnarod.workflows.ensemble.ensemble import Ensemble

    from dnarod.workflows.ensemble.cluster import check_workers

    check_workers(workers)
    import math
    import re

    if not (math.isfinite(timeout) and timeout > 0):
        raise ParameterError(f"--timeout {timeout}: give the seconds to wait for --scheduler (a number > 0)")
    if scheduler is not None and not re.fullmatch(r"([a-z][a-z0-9+.-]*://)?[^\s:/]+:\d+/?", scheduler):
        raise ParameterError(f"--scheduler {scheduler}: not a scheduler address; write tcp://HOST:PORT "
                             f"(e.g. tcp://127.0.0.1:8786)")
    if workers is not None and scheduler:
        raise ParameterError("--workers sizes a local cluster; with --scheduler the cluster's workers are used")
    # dask logs lost connections with tracebacks; this command reports them itself, in one line
    logging.getLogger("distributed").setLevel(logging.CRITICAL)
    ens = Ensemble.from_toml(spec, outdir, overwrite=overwrite)
    client = connect(scheduler, timeout) if scheduler else None     # a dead address fails here, in one line
    try:
        ens.prepare()
        done = len(ens.members) - len(ens.pending())
        where = f"scheduler {scheduler}" if scheduler else "this process (no dask)" if workers == 0 else \
            f"a local cluster of {workers or available_cores()} workers"
        click.echo(f"ensemble {ens.spec.name!r}: {len(ens.members)} members ({done} already finished) -> {outdir} "
                   f"on {where}", err=True)
        ens.run(client=client, workers=workers, progress=progress, dashboard=dashboard)
    finally:
        if client is not None:
            client.close()
    s = ens.summary
    st = s["status"]
    click.echo(f"members: {s['n_members']}  ok: {st.get('ok', 0)}  failed: {st.get('failed', 0)}  "
               f"wall: {s['wall_s']:.1f} s  member CPU: {s['member_cpu_s_total']:.1f} s")
    click.echo(f"wrote: {s['files']['table']}, {s['files']['csv']}, {outdir}/summary.json"
               + (f", {len(s['files']['plots'])} plots" if s['files']['plots'] else ""))
    for f in s["failed"]:
        click.echo(f"failed: member {f['index']} ({f['member']}): {f['error']}", err=True)
    if s["failed"]:
        sys.exit(1)
