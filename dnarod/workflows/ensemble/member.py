"""Running one member on a worker: skip if finished, resume if partial, reduce, record.

A member's directory ``ENSEMBLE/members/<id>/`` is a normal run directory (``run.json``,
``trajectory.dtraj``, ``energies.csv``, ``checkpoint.npz``, ``final_model.npz``) plus

* ``member.json``: the member's id and settings (written before the run starts);
* ``member.log``: its log (appended by every attempt: start, resume step, errors, timing);
* ``result.json``: written atomically last: ``status`` ("ok" or "failed"), the reduced
  observables or the error, wall and CPU time, attempts.

A finished member (``result.json`` with status "ok") is skipped; a partial one resumes from its
checkpoint through the run layer's checks (``run(..., resume=True)``), so a worker killed
mid-member only costs the steps since the last checkpoint, and the trajectory has no gap or
duplicate. A lock file (``fcntl.flock``) keeps two attempts of one member from running at once.
"""
from __future__ import annotations

import contextlib
import json
import logging
import os
import socket
import time
import traceback
import warnings
from pathlib import Path

from dnarod.core.io import LOG, MEMBER, RESULT, write_text_atomic


def member_dir(outdir, mid):
    """``outdir/members/<id>``."""
    return Path(outdir) / "members" / mid


def read_result(mdir):
    """The member's ``result.json`` as a dict, or None if absent or unreadable."""
    p = Path(mdir) / RESULT
    try:
        return json.loads(p.read_text())
    except (OSError, ValueError):
        return None


def is_finished(mdir, mid=None):
    r = read_result(mdir)
    return bool(r) and r.get("status") == "ok" and (mid is None or r.get("id") == mid)


class _LogFile(logging.FileHandler):
    """``member.log``: a record that cannot be written (a full disk) is dropped, not printed with a traceback on
    the worker's stderr (the member's failure is recorded in its result)."""

    def handleError(self, record):  # noqa: N802 - logging's name
        pass


@contextlib.contextmanager
def _member_log(mdir, mid):
    """A logger writing to ``mdir/member.log`` (the run layer's ``dnarod`` log records included)."""
    handler = _LogFile(Path(mdir) / LOG)
    handler.setFormatter(logging.Formatter("%(asctime)s %(levelname)s %(name)s: %(message)s"))
    log = logging.getLogger(f"dnarod.workflows.ensemble.member.{mid}")
    log.setLevel(logging.INFO)
    root = logging.getLogger("dnarod")
    old = root.level
    root.setLevel(min(old or logging.INFO, logging.INFO))
    root.addHandler(handler)
    log.addHandler(handler)
    log.propagate = False
    try:
        yield log
    finally:
        log.removeHandler(handler)
        root.removeHandler(handler)
        root.setLevel(old)
        handler.close()


@contextlib.contextmanager
def _locked(mdir):
    """Exclusive lock on ``mdir/.lock`` (released by the OS if the process dies)."""
    import fcntl

    fh = open(Path(mdir) / ".lock", "w")
    try:
        fcntl.flock(fh, fcntl.LOCK_EX)
        yield
    finally:
        fcntl.flock(fh, fcntl.LOCK_UN)
        fh.close()


def _one_line(exc):
    text = f"{type(exc).__name__}: {exc}" if not str(exc).strip() else str(exc).strip()
    return " ".join(text.split())


def run_member(mid, settings, outdir, protocol=None, analysis=None):
    """Run, resume or skip one member, and return its row (runs on a dask worker).

    Parameters
    ----------
    mid : str
        Member id.
    settings : dict
        Canonical settings.
    outdir : str
        Ensemble folder (shared file system between client and workers).
    protocol : object or str or None
        See :mod:`dnarod.workflows.ensemble.protocol`.
    analysis : dict or None
        ``[analysis]`` settings passed to the reduction.

    Returns
    -------
    dict
        The content of ``result.json``: ``id``, ``status``, ``observables`` or ``error``, timing.
        Errors inside the member are caught and recorded (status "failed"); they do not stop
        other members.
    """
    analysis = dict(analysis or {})
    mdir = member_dir(outdir, mid)
    mdir.mkdir(parents=True, exist_ok=True)
    with _locked(mdir):
        done = read_result(mdir)
        if done and done.get("status") == "ok" and done.get("id") == mid:
            return dict(done, skipped=True)
        prev_attempts = int(done.get("attempts", 0)) if done else 0
        if not (mdir / MEMBER).exists():
            write_text_atomic(mdir / MEMBER, json.dumps({"id": mid, "settings": settings}, indent=1) + "\n")
        t0, c0 = time.perf_counter(), time.process_time()
        attempt = prev_attempts + _count_starts(mdir) + 1
        with _member_log(mdir, mid) as log:
            log.info("start: attempt %d on %s pid %d", attempt, socket.gethostname(), os.getpid())
            record = {"id": mid, "settings": settings, "host": socket.gethostname(), "pid": os.getpid(),
                      "attempts": attempt}
            caught = []
            try:
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    obs, resumed = _attempt(protocol, settings, mdir, analysis, log)
                record.update(status="ok", observables=_scalars(obs), resumed_from=resumed)
                log.info("done: %d observables", len(record["observables"]))
            except Exception as exc:  # noqa: BLE001 -- a failed member is recorded, others go on
                record.update(status="failed", error=_one_line(exc), error_type=type(exc).__name__)
                log.error("failed: %s\n%s", record["error"], traceback.format_exc())
            for w in caught:
                log.warning("%s: %s", w.category.__name__, w.message)
            if caught:
                record["warnings"] = sorted({_one_line(w.message) for w in caught})
            record.update(wall_s=time.perf_counter() - t0, cpu_s=time.process_time() - c0)
            write_text_atomic(mdir / RESULT, json.dumps(record, indent=1, default=_json_default) + "\n")
    return record


def _attempt(protocol, settings, mdir, analysis, log):
    """Run (or resume) and reduce one member; returns (observables, resumed step or None)."""
    from dnarod.workflows.ensemble.protocol import call_hook, resolve_protocol

    proto = resolve_protocol(protocol)
    if hasattr(proto, "execute"):
        return call_hook(proto.execute, settings, mdir, analysis), None
    resumed = _run(proto, settings, mdir, log)
    reduce = getattr(proto, "reduce", None) or resolve_protocol(None).reduce
    return call_hook(reduce, mdir, settings, analysis), resumed


def _count_starts(mdir):
    """Attempts logged without a result (killed workers): lines 'start:' since the last result."""
    p = Path(mdir) / LOG
    if not p.exists():
        return 0
    n = 0
    for line in p.read_text(errors="replace").splitlines():
        if " start: attempt " in line:
            n += 1
        elif " done: " in line or " failed: " in line:
            n = 0
    return n


def _run(proto, settings, mdir, log):
    """Build the member's RunSpec and run it, resuming a partial run; returns the resumed step or None."""
    from dnarod.workflows.ensemble.protocol import _run_api

    _, run = _run_api()
    build = getattr(proto, "build", None) or resolve_build()
    spec = build(settings)
    from dnarod.engines.openmm.platforms import env_threads

    threads = env_threads()
    if getattr(spec, "threads", "absent") is None and threads and spec.engine == "openmm":
        spec = spec.replace(threads=threads)
    has_ckpt = (mdir / "checkpoint.npz").exists()
    started = (mdir / "run.json").exists()
    if has_ckpt:
        log.info("resume from %s", mdir / "checkpoint.npz")
        result = run(spec, mdir, resume=True, overwrite=False, progress=False)
    else:
        if started:
            log.info("run.json without a checkpoint: the earlier attempt died before its first checkpoint; "
                     "starting over")
        result = run(spec, mdir, resume=False, overwrite=started, progress=False)
    resumed = getattr(result, "resumed_from", None)
    log.info("run finished (resumed from step %s)", resumed)
    return resumed


def resolve_build():
    from dnarod.workflows.ensemble.protocol import build_runspec

    return build_runspec


def _scalars(obs):
    if not isinstance(obs, dict):
        raise TypeError(f"the protocol's reduce returned {type(obs).__name__}, not a dict of scalars")
    out = {}
    for k, v in obs.items():
        if hasattr(v, "item") and getattr(v, "ndim", 1) == 0:
            v = v.item()
        if not isinstance(v, (int, float, str, bool)) and v is not None:
            raise TypeError(f"the protocol's reduce returned {k!r} = {type(v).__name__}; expected a scalar")
        out[str(k)] = v
    return out


def _json_default(v):
    if hasattr(v, "item"):
        return v.item()
    return str(v)
