"""``dnarod ensemble``: run an ensemble spec on a private local dask cluster or an existing scheduler."""
from __future__ import annotations

import sys

import click


@click.command("ensemble")
@click.argument("spec", type=click.Path(dir_okay=False))
@click.option("-o", "--out", "outdir", required=True, type=click.Path(file_okay=False),
              help="Ensemble folder (created; the same spec again resumes it).")
@click.option("--scheduler", default=None, help="Address of a running dask scheduler, tcp://HOST:8786 or (with "
              "certificates) tls://HOST:PORT [default: a local cluster on 127.0.0.1].")
@click.option("--workers", type=int, default=None,
              help="Local cluster worker processes [default: the cores]; 0 runs the members in this process.")
@click.option("--timeout", type=float, default=10.0, show_default=True,
              help="Seconds to wait for --scheduler to answer.")
@click.option("--tls-ca-file", type=click.Path(dir_okay=False), default=None,
              help="CA certificate (PEM) that signed the scheduler's certificate [default: dask's "
              "distributed.comm.tls.ca-file].")
@click.option("--tls-cert", type=click.Path(dir_okay=False), default=None,
              help="This client's certificate (PEM), signed by that CA [default: distributed.comm.tls.client.cert].")
@click.option("--tls-key", type=click.Path(dir_okay=False), default=None,
              help="This client's private key (PEM), unless it is in --tls-cert [default: "
              "distributed.comm.tls.client.key].")
@click.option("--overwrite", is_flag=True, help="Replace a folder made by another spec.")
@click.option("--dashboard", is_flag=True, help="Serve the local cluster's dask dashboard on 127.0.0.1 (needs "
              "bokeh); without it nothing is served over HTTP.")
@click.option("--progress/--no-progress", default=True, show_default=True)
def ensemble_cmd(spec, outdir, scheduler, workers, timeout, tls_ca_file, tls_cert, tls_key, overwrite, dashboard,
                 progress):
    """Run the ensemble SPEC (a TOML file: [ensemble], [base], [axes], [analysis]) into OUT.

    Each member is a run directory OUT/members/<id>/; finished members are skipped and partial
    ones resume from their checkpoints when the command is run again. Writes OUT/results.parquet,
    OUT/results.csv, OUT/plot_<axis>.png and OUT/summary.json; dask's own log goes to OUT/ensemble.log.
    Exit status 1 if members failed, 2 for bad input, a wrong or lost scheduler or a full disk, 130 on Ctrl-C.
    """
    import math
    import re

    import dnarod.workflows.protocols  # noqa: F401 -- registers the protocols that specs name
    from dnarod.core.errors import ParameterError
    from dnarod.workflows.ensemble.cluster import DaskLog, check_workers, route_dask_logs

    check_workers(workers)
    if not (math.isfinite(timeout) and timeout > 0):
        raise ParameterError(f"--timeout {timeout}: give the seconds to wait for --scheduler (a number > 0)")
    if scheduler is not None and not re.fullmatch(r"([a-z][a-z0-9+.-]*://)?[^\s:/]+:\d+/?", scheduler):
        raise ParameterError(f"--scheduler {scheduler}: not a scheduler address; write tcp://HOST:PORT "
                             f"(e.g. tcp://127.0.0.1:8786)")
    if workers is not None and scheduler:
        raise ParameterError("--workers sizes a local cluster; with --scheduler the cluster's workers are used")
    tls_given = [o for o, v in (("--tls-ca-file", tls_ca_file), ("--tls-cert", tls_cert), ("--tls-key", tls_key))
                 if v is not None]
    if tls_given and not scheduler:
        raise ParameterError(f"{tls_given[0]} is for a remote scheduler (--scheduler tls://HOST:PORT); a local "
                             f"cluster listens on 127.0.0.1 only")
    if dashboard and scheduler:
        raise ParameterError("--dashboard serves a local cluster's dashboard; a remote scheduler serves its own")
    # dask's log records (and what Python cannot raise in dask's clean-up) go to OUT/ensemble.log, held in
    # memory until the folder exists: this command reports faults itself, in one line. After a fault (Ctrl-C, a
    # lost scheduler) they keep going there until the process ends: a cluster interrupted while it started is
    # cleaned up at exit, and logs as it goes.
    dask_log = DaskLog()
    restore = route_dask_logs(dask_log)
    hook, sys.unraisablehook = sys.unraisablehook, dask_log.unraisable
    ens = _run(spec, outdir, scheduler, workers, timeout, (tls_ca_file, tls_cert, tls_key), overwrite, dashboard,
               progress, dask_log)
    restore()
    sys.unraisablehook = hook
    dask_log.close()
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


def _run(spec, outdir, scheduler, workers, timeout, tls, overwrite, dashboard, progress, dask_log):
    """Check the spec, connect, run; returns the finished :class:`Ensemble`."""
    from pathlib import Path

    from dnarod.workflows.ensemble.cluster import available_cores, connect, tls_security
    from dnarod.workflows.ensemble.ensemble import LOG_FILE, Ensemble

    ens = Ensemble.from_toml(spec, outdir, overwrite=overwrite)
    # certificates given here (the rest from dask's configuration); a tls:// address without them looks there only
    security = tls_security(*tls) if any(t is not None for t in tls) else None
    client = connect(scheduler, timeout, security) if scheduler else None    # a wrong address fails here, in one line
    try:
        ens.prepare()
        dask_log.open(Path(outdir) / LOG_FILE)
        done = len(ens.members) - len(ens.pending())
        where = f"scheduler {scheduler}" if scheduler else "this process (no dask)" if workers == 0 else \
            f"a local cluster of {workers or available_cores()} workers"
        click.echo(f"ensemble {ens.spec.name!r}: {len(ens.members)} members ({done} already finished) -> {outdir} "
                   f"on {where}", err=True)
        ens.run(client=client, workers=workers, progress=progress, dashboard=dashboard)
    finally:
        if client is not None:
            try:
                client.close()
            except Exception:  # noqa: BLE001 -- a lost scheduler: already reported
                pass
    return ens
