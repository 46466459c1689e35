"""What every worker process of a local cluster does as it starts (a dask preload, see
:func:`dnarod.workflows.ensemble.cluster.local_cluster`).

* The HTTP server dask starts beside each worker (its dashboard and metrics) is stopped, unless the
  cluster was asked for a dashboard (``DNAROD_DASK_HTTP=1``): a local ensemble serves nothing over HTTP.
* SIGINT is ignored: Ctrl-C in a terminal reaches every process of the foreground group; the command
  itself stops the ensemble and closes the cluster, so the workers need not (and print no
  ``KeyboardInterrupt`` tracebacks).
* With ``DNAROD_DASK_LOG=PATH``, the process's stderr (dask's log records, warnings) is appended to that
  file: also for a worker the nanny restarts after the cluster started.

The settings come from the environment the cluster gives its workers; a worker inside the
command's own process (not a spawned one) is left alone apart from its HTTP server.
"""
from __future__ import annotations

import multiprocessing
import os
import signal

#: Environment variables read here.
ENV_LOG, ENV_HTTP = "DNAROD_DASK_LOG", "DNAROD_DASK_HTTP"


def dask_setup(worker):
    """Run by dask in each worker once it has started (``preload``)."""
    if os.environ.get(ENV_HTTP, "0") != "1":
        http = getattr(worker, "http_server", None)
        if http is not None:
            http.stop()
    if multiprocessing.parent_process() is None:
        return                          # not a spawned worker process: its signals and stderr are not ours
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:                  # not the main thread
        pass
    log = os.environ.get(ENV_LOG)
    if log:
        try:
            fd = os.open(log, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o644)
        except OSError:
            return
        os.dup2(fd, 2)
        os.close(fd)
