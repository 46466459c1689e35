"""Where members run: a local dask cluster, an existing scheduler, or SLURM through dask-jobqueue.

Every worker is one process with one thread, and the numerical libraries inside it are held to
one thread (:data:`WORKER_ENV`), so N workers use N cores without oversubscription: OpenMM's CPU
platform reads ``OPENMM_CPU_THREADS`` when it loads, numba ``NUMBA_NUM_THREADS``, BLAS the
``*_NUM_THREADS`` variables.
"""
from __future__ import annotations

import contextlib
import os

from dnarod.core.errors import DnarodError

#: Environment of every worker process.
WORKER_ENV = {"OPENMM_CPU_THREADS": "1", "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1",
              "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1", "VECLIB_MAXIMUM_THREADS": "1",
              "NUMEXPR_NUM_THREADS": "1"}


class SchedulerError(DnarodError):
    """A scheduler address that does not answer, or a cluster that cannot start."""


def available_cores():
    """Cores this process may use (its CPU affinity, else ``os.cpu_count()``)."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:
        return os.cpu_count() or 1


#: Most local worker processes per core: each is a Python process with OpenMM loaded (a few hundred MB), so far
#: more than the cores only fills the memory (the same bound as OpenMM's --threads).
MAX_WORKERS_PER_CORE = 4


def check_workers(workers, option="--workers"):
    """Refuse a local worker count that is not an integer >= 0 or above :data:`MAX_WORKERS_PER_CORE` per core
    (one line naming ``option``); returns it. 0 means: no cluster, members one after another."""
    if workers is None:
        return None
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 0:
        raise SchedulerError(f"{option} {workers!r}: give a number of worker processes >= 0 (0: one after another "
                             f"in this process)")
    most = MAX_WORKERS_PER_CORE * available_cores()
    if workers > most:
        raise SchedulerError(f"{option} {workers}: more than {most} local worker processes ({MAX_WORKERS_PER_CORE} "
                             f"per core here) only fill the memory; use at most {most} (the default is one per core)")
    return workers


def local_cluster(workers=None, dashboard=False, **kw):
    """A :class:`distributed.LocalCluster` of ``workers`` processes (default: the cores), one thread each.

    Parameters
    ----------
    workers : int, optional
    dashboard : bool
        Serve the dask dashboard (per-member progress) on port 8787 if bokeh is installed.
    **kw
        Passed to ``LocalCluster``.
    """
    from distributed import LocalCluster

    check_workers(workers)
    n = int(workers or available_cores())
    if dashboard:
        try:
            import bokeh  # noqa: F401
        except ImportError:
            raise SchedulerError("--dashboard needs bokeh (pip install 'bokeh>=3.1')") from None
    if n < 1:
        raise SchedulerError(f"--workers {workers}: need at least 1 worker")
    kw.setdefault("dashboard_address", ":8787" if dashboard else ":0")   # ":0": any free port, no clash
    return LocalCluster(n_workers=n, threads_per_worker=1, processes=True, env=dict(WORKER_ENV),
                        silence_logs=kw.pop("silence_logs", 40), **kw)


def connect(address, timeout=10.0):
    """A :class:`distributed.Client` of the scheduler at ``address``; a clear error within ``timeout`` s.

    Raises
    ------
    SchedulerError
        Nothing answered at ``address`` within ``timeout`` seconds, or the address is malformed.
    """
    from distributed import Client

    try:
        return Client(address, timeout=f"{float(timeout)}s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        msg = " ".join(str(exc).split()) or type(exc).__name__
        if len(msg) > 160:
            msg = msg[:160] + "..."
        raise SchedulerError(f"--scheduler {address}: no dask scheduler answered within {timeout:g} s ({msg}); "
                             f"check the address (tcp://HOST:PORT) and that the scheduler is running") from None


@contextlib.contextmanager
def client_for(client=None, scheduler=None, workers=None, timeout=10.0, dashboard=False):
    """Yield a client: ``client`` as given, one connected to ``scheduler``, or a new local cluster's.

    Clients and clusters made here are closed on exit; a given ``client`` is left open.
    """
    if client is not None:
        yield client
        return
    if scheduler:
        c = connect(scheduler, timeout)
        try:
            yield c
        finally:
            c.close()
        return
    from distributed import Client

    cluster = local_cluster(workers, dashboard=dashboard)
    c = Client(cluster, set_as_default=False)
    try:
        yield c
    finally:
        c.close()
        cluster.close()


def slurm_cluster(cores=1, processes=None, memory="4GB", walltime="04:00:00", queue=None, account=None,
                  job_extra_directives=(), python=None, **kw):
    """A :class:`dask_jobqueue.SLURMCluster` whose jobs run one-thread dnarod workers.

    Each SLURM job gets ``cores`` CPUs and starts ``processes`` worker processes (default one
    per core) of one thread each, with :data:`WORKER_ENV` exported in the job script. Scale it
    with ``cluster.scale(jobs=N)`` or ``cluster.adapt(maximum_jobs=N)`` and pass
    ``distributed.Client(cluster)`` to :meth:`~dnarod.workflows.ensemble.ensemble.Ensemble.run`. The ensemble folder
    must be on a
    file system the compute nodes share.

    Parameters
    ----------
    cores : int
        CPUs per job (``#SBATCH --cpus-per-task``).
    processes : int, optional
        Workers per job (default ``cores``).
    memory : str
        Memory per job (``#SBATCH --mem``).
    walltime : str
        ``HH:MM:SS`` per job (``#SBATCH -t``). Members resume across jobs, so short walltimes only
        cost the steps since a member's last checkpoint.
    queue, account : str, optional
        ``#SBATCH -p`` and ``-A``.
    job_extra_directives : sequence of str
        More ``#SBATCH`` lines, e.g. ``["--constraint=skylake"]``.
    python : str, optional
        Python executable on the nodes (default this one).
    **kw
        Passed to ``SLURMCluster``.

    Returns
    -------
    dask_jobqueue.SLURMCluster
    """
    try:
        from dask_jobqueue import SLURMCluster
    except ImportError:
        raise SchedulerError("SLURM clusters need dask-jobqueue: pip install 'dnarod[cluster]'") from None
    import sys

    processes = int(processes or cores)
    prologue = [f"export {k}={v}" for k, v in WORKER_ENV.items()]
    return SLURMCluster(cores=int(cores), processes=processes, memory=memory, walltime=walltime, queue=queue,
                        account=account, job_extra_directives=list(job_extra_directives),
                        job_script_prologue=prologue + list(kw.pop("job_script_prologue", [])),
                        python=python or sys.executable, **kw)
