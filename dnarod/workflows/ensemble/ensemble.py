"""The :class:`Ensemble`: a spec's members, their folder, running them on dask, and their results.

Folder layout (``outdir``)::

    ensemble.json           # the spec's fingerprint, members and settings (written first)
    spec.toml               # the spec file as given (from_toml)
    members/<id>/           # one run directory per member (see dnarod.workflows.ensemble.member)
    results.parquet, results.csv, plot_<axis>.png, summary.json
    ensemble.log            # dask's own log records (and a local cluster's worker processes' stderr)

Running again with the same spec resumes: finished members are skipped, partial ones resume
from their checkpoints. A folder made by another spec is refused unless ``overwrite``.
"""
from __future__ import annotations

import contextlib
import hashlib
import json
import shutil
import time
import uuid
from pathlib import Path

from dnarod.core.errors import DnarodError
from dnarod.core.extras import require
from dnarod.core.io import REPLACEMENT_PREFIX, check_output_folder, write_text_atomic
from dnarod.workflows.ensemble.member import is_finished, member_dir, read_result, run_member
from dnarod.core.io import RESULT
from dnarod.workflows.ensemble.protocol import protocol_keys, resolve_protocol
from dnarod.workflows.ensemble.results import CSV, SUMMARY, TABLE, collect_rows, plot_axes, rows_to_table, write_summary, write_table
from dnarod.workflows.ensemble.schema import SpecError
from dnarod.workflows.ensemble.spec import EnsembleSpec, check_members, load_spec, parse_spec

MANIFEST = "ensemble.json"
#: Where dask's log records go while the ensemble runs (never to the terminal).
LOG_FILE = "ensemble.log"
#: What an overwrite removes (only what an ensemble writes).
_OURS = ("members", MANIFEST, "spec.toml", TABLE, CSV, SUMMARY, LOG_FILE)


class Ensemble:
    """Many runs from one spec, executed on dask.distributed.

    Parameters
    ----------
    spec : EnsembleSpec
    outdir : path
        The ensemble folder.
    protocol : object, str or None
        Overrides the spec's protocol (see :mod:`dnarod.workflows.ensemble.protocol`).
    overwrite : bool
        Replace a folder made by another spec.
    spec_text : str, optional
        The TOML text, kept as ``spec.toml``.
    check : bool
        Check force fields, sequences and run settings on the client first.

    Examples
    --------
    The small spec beside ``examples/force_extension.toml``, its members run one after another in this process:

    >>> ens = Ensemble.from_toml("examples/quick_ensemble.toml", "quick_fx")
    >>> _ = ens.run(workers=0, progress=False)     # .run(): a LocalCluster, one worker per core
    >>> ens.results().num_rows                     # a pyarrow.Table, one row per member
    2
    """

    def __init__(self, spec: EnsembleSpec, outdir, protocol=None, overwrite=False, spec_text=None, check=True):
        self.spec = spec
        self.outdir = Path(outdir)
        self.protocol_arg = protocol if protocol is not None else spec.protocol
        self.protocol = resolve_protocol(self.protocol_arg)
        self.overwrite = bool(overwrite)
        self.spec_text = spec_text
        self.members = list(spec.members())
        ids = [m.id for m in self.members]
        if len(set(ids)) != len(ids):
            raise SpecError("two members have identical settings; make the axis values distinct")
        if check:
            check_members(self.members)
            self._check_runspecs()
        self.summary = None

    # ---------------------------------------------------------------------------------------
    @classmethod
    def from_toml(cls, path, outdir, protocol=None, overwrite=False, check=True):
        """An ensemble from a TOML spec file (see :mod:`dnarod.workflows.ensemble.spec`)."""
        p = Path(path)
        keys = None
        proto = protocol
        if proto is None and p.is_file():
            import tomllib

            try:
                proto = tomllib.loads(p.read_text()).get("ensemble", {}).get("protocol")
            except (tomllib.TOMLDecodeError, UnicodeDecodeError, AttributeError):
                proto = None
        if proto is not None:
            keys = protocol_keys(resolve_protocol(proto))
        spec = load_spec(p, protocol_keys=keys)
        return cls(spec, outdir, protocol=protocol, overwrite=overwrite, spec_text=p.read_text(), check=check)

    @classmethod
    def from_dict(cls, doc, outdir, base_dir=".", protocol=None, overwrite=False, check=True):
        """An ensemble from a spec dict (the tables of the TOML file)."""
        proto = protocol if protocol is not None else doc.get("ensemble", {}).get("protocol")
        keys = protocol_keys(resolve_protocol(proto)) if proto is not None else None
        return cls(parse_spec(doc, base_dir=base_dir, protocol_keys=keys), outdir, protocol=protocol,
                   overwrite=overwrite, check=check)

    # ---------------------------------------------------------------------------------------
    @property
    def fingerprint(self):
        """SHA-256 of the member ids (in order), the analysis settings and the protocol's name."""
        doc = {"members": [m.id for m in self.members], "analysis": self.spec.analysis,
               "protocol": _protocol_name(self.protocol_arg)}
        return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()

    def _check_runspecs(self):
        """Build and check the RunSpec of every distinct member (client side), so a sweep with one bad value
        (a salt, force or time outside the run layer's ranges) is refused before any member runs. Members that
        differ only in their seed (replicas) share one check."""
        if hasattr(self.protocol, "execute"):
            # a protocol that runs its members itself may check their settings: before any member runs
            check = getattr(self.protocol, "check", None)
            if callable(check):
                self._check_each(check)
            return
        if not hasattr(self.protocol, "build"):
            return
        from dnarod.run import RunSpec
        from dnarod.run.api import preflight
        from dnarod.workflows.ensemble.protocol import build_runspec
        from dnarod.workflows.ensemble.schema import RUN_KEYS

        seen, models = set(), {}
        for m in self.members:
            s = m.settings
            key = json.dumps({k: v for k, v in s.items() if k not in ("seed", "sequence_name")}, sort_keys=True,
                             default=str)
            if key in seen:
                continue
            seen.add(key)
            try:
                # the default build loads each source once for all members (a sweep of one structure)
                spec = (build_runspec(s, model_cache=models) if self.protocol.build is build_runspec
                        else self.protocol.build(s))
                if hasattr(spec, "check"):
                    spec.check()
                if isinstance(spec, RunSpec):
                    # what the run layer refuses before it writes (dt above the stability limit, more than
                    # 10^12 steps, an equilibrium start of a ring, a too-stiff load): refused here, not as a
                    # failed member after the others ran
                    key = (spec.source, spec.forcefield, bool(spec.circular), bool(spec.ring), spec.delta_lk) \
                        if isinstance(spec.source, str) else None
                    model = preflight(spec, models.get(key) if key is not None else None)
                    if key is not None:
                        models[key] = model
                discard = self.spec.analysis.get("discard_ns", 0.0)
                if discard and discard >= s.get("time_ns", RUN_KEYS["time_ns"].default):
                    raise SpecError(f"[analysis] discard_ns = {discard:g} leaves nothing of the "
                                    f"{s.get('time_ns', RUN_KEYS['time_ns'].default):g} ns run; give a discard_ns "
                                    f"below time_ns")
            except SpecError:
                raise
            except DnarodError as exc:        # the run layer refuses these settings
                raise SpecError(f"member {m.index} ({m.id}): {' '.join(str(exc).split())}") from None

    def _check_each(self, check):
        """``check(settings)`` for every distinct member (seed and label aside), one line naming the member."""
        seen = set()
        for m in self.members:
            key = json.dumps({k: v for k, v in m.settings.items() if k not in ("seed", "sequence_name")},
                             sort_keys=True, default=str)
            if key in seen:
                continue
            seen.add(key)
            try:
                check(m.settings)
            except SpecError:
                raise
            except DnarodError as exc:
                raise SpecError(f"member {m.index} ({m.id}): {' '.join(str(exc).split())}") from None

    def prepare(self):
        """Create or check the folder: same spec resumes, another spec is refused unless ``overwrite``."""
        out = self.outdir
        man = out / MANIFEST
        if man.exists() and getattr(self, "_replaces", None) is None:
            try:
                old = json.loads(man.read_text())
            except ValueError:
                old = {}
            if old.get("fingerprint") != self.fingerprint:
                stage = out / f"{REPLACEMENT_PREFIX}{self.fingerprint[:16]}"
                if not self.overwrite:
                    n_done = sum(1 for d in (out / "members").glob("*") if (d / RESULT).exists()) \
                        if (out / "members").is_dir() else 0
                    going = (f"; a replacement by this spec was begun in {stage.name}: --overwrite continues it"
                             if stage.is_dir() else "")
                    raise SpecError(f"{out}: holds ensemble {old.get('name', '?')!r} made by another spec "
                                    f"({old.get('n_members', '?')} members, {n_done} with results); use another -o "
                                    f"folder, or --overwrite to replace it{going}")
                # overwrite: the new ensemble is made beside the old one (a hidden folder in out, named by the new
                # spec, so that running the command again continues it) and replaces it when every member has
                # finished (write_results); until then the old ensemble stays as it was
                self._replaces = out
                self.outdir = out = stage
                man = out / MANIFEST
        elif getattr(self, "_replaces", None) is None:
            try:
                check_output_folder(out, (MANIFEST,), "ensemble")
            except DnarodError as exc:
                raise SpecError(str(exc)) from None
        out.mkdir(parents=True, exist_ok=True)
        if not man.exists():
            if self.spec_text is not None:
                write_text_atomic(out / "spec.toml", self.spec_text)
            write_text_atomic(man, json.dumps({
                "name": self.spec.name, "fingerprint": self.fingerprint, "n_members": len(self.members),
                "axes": self.spec.axes, "base": self.spec.base, "analysis": self.spec.analysis,
                "protocol": _protocol_name(self.protocol_arg),
                "members": [{"id": m.id, "index": m.index} for m in self.members]}, indent=1) + "\n")
        return self

    def pending(self):
        """Members without a finished result."""
        return [m for m in self.members if not is_finished(member_dir(self.outdir, m.id), m.id)]

    # ---------------------------------------------------------------------------------------
    def run(self, client=None, scheduler=None, workers=None, progress=True, timeout=10.0, window=None,
            dashboard=False, security=None):
        """Run every unfinished member on dask and write the results; returns ``self``.

        Parameters
        ----------
        client : distributed.Client, optional
            Use this client (left open). Default: ``scheduler`` or a new ``LocalCluster``.
        scheduler : str, optional
            Address of a running dask scheduler (``tcp://HOST:PORT``, or ``tls://HOST:PORT`` with
            ``security``).
        workers : int, optional
            Local cluster size (default: the cores); ``0`` runs the members one after another in
            this process, without dask (debugging, or machines where worker processes cannot start).
        progress : bool
            One tqdm bar over members.
        timeout : float
            Seconds to wait for ``scheduler`` to answer.
        window : int, optional
            Members in flight at once (default ``max(32, 4 x worker threads)``); keeps the
            client's memory independent of the ensemble's size.
        dashboard : bool
            Serve the local cluster's dask dashboard on 127.0.0.1 (needs bokeh); each member is a task
            ``dnarod-member-<id>-...`` there. Without it a local cluster serves nothing over HTTP.
        security : distributed.security.Security, optional
            TLS certificates for ``scheduler``
            (:func:`dnarod.workflows.ensemble.cluster.tls_security`).

        Dask's own log records go to ``OUT/ensemble.log`` while the ensemble runs, not to the terminal;
        a lost scheduler raises :class:`~dnarod.workflows.ensemble.cluster.SchedulerError` (one line).
        """
        from concurrent.futures import CancelledError

        as_completed = require("distributed", "ensemble").as_completed
        from tqdm.auto import tqdm

        from distributed.comm.core import CommClosedError

        from dnarod.workflows.ensemble.cluster import SchedulerError, client_for, dask_logs

        self.prepare()
        logs = contextlib.ExitStack()
        logs.enter_context(dask_logs(self.outdir / LOG_FILE))
        t0 = time.perf_counter()
        todo = self.pending()
        n_total = len(self.members)
        bar = tqdm(total=n_total, initial=n_total - len(todo), desc=self.spec.name, unit="member",
                   disable=not progress, dynamic_ncols=True)
        failed = []
        info = {}
        proto = self.protocol       # the object: workers need no registry

        def finished(m, rec):
            if rec.get("status") != "ok":
                failed.append(m.id)
                bar.write(f"member {m.index} ({m.id}) failed: {rec.get('error')}")
                bar.set_postfix(failed=len(failed))
            bar.update(1)

        try:
            if not todo:
                self.summary = self.write_results(wall_s=time.perf_counter() - t0)
                return self
            if workers == 0 and client is None and not scheduler:
                for m in todo:
                    finished(m, run_member(m.id, m.settings, str(self.outdir.resolve()), proto, self.spec.analysis))
                self.summary = self.write_results(wall_s=time.perf_counter() - t0, scheduler=None, workers=0)
                return self
            with client_for(client, scheduler, workers, timeout, dashboard, security, self.outdir / LOG_FILE) as c:
                if dashboard or scheduler:
                    bar.write(f"dask dashboard: {c.dashboard_link}")
                info = {"scheduler": c.scheduler.address, "workers": len(c.scheduler_info().get("workers", {}))}
                token = uuid.uuid4().hex[:8]
                it = iter(todo)
                by_future = {}

                def submit(k):
                    new = []
                    while len(new) < k:
                        m = next(it, None)
                        if m is None:
                            break
                        f = c.submit(run_member, m.id, m.settings, str(self.outdir.resolve()), proto,
                                     self.spec.analysis, key=f"dnarod-member-{m.id}-{token}", pure=False)
                        by_future[f.key] = m
                        new.append(f)
                    return new

                ac = as_completed(submit(window or self._window(c)), loop=c.loop)
                for fut in ac:
                    m = by_future.pop(fut.key)
                    try:
                        rec = fut.result()
                    except (CancelledError, CommClosedError) as exc:   # the scheduler went away: stop, resumable
                        raise SchedulerError(f"lost the connection to the dask scheduler {info['scheduler']} "
                                             f"({type(exc).__name__}); run the same command again: finished "
                                             f"members are kept and partial ones resume") from None
                    except Exception as exc:  # noqa: BLE001 -- a lost member (KilledWorker...) is recorded
                        rec = self._record_lost(m, exc)
                    fut.release()
                    finished(m, rec)
                    for f in submit((window or self._window(c)) - len(by_future)):
                        ac.add(f)
        except CommClosedError as exc:        # the scheduler went away outside a result (submitting, closing)
            raise SchedulerError(f"lost the connection to the dask scheduler {info.get('scheduler', scheduler)} "
                                 f"({_one_line(exc)}); run the same command again: finished members are kept and "
                                 f"partial ones resume") from None
        finally:
            bar.close()
            logs.close()
        self.summary = self.write_results(wall_s=time.perf_counter() - t0, **info)
        return self

    def _window(self, c):
        try:
            threads = sum(w.get("nthreads", 1) for w in c.scheduler_info()["workers"].values())
        except Exception:  # noqa: BLE001
            threads = 1
        return max(32, 4 * threads)

    def _record_lost(self, m, exc):
        """A member whose task itself failed (its workers died): record it unless it finished anyway."""
        mdir = member_dir(self.outdir, m.id)
        done = read_result(mdir)
        if done and done.get("status") == "ok":
            return done
        msg = " ".join(str(exc).split()) or type(exc).__name__
        rec = {"id": m.id, "settings": m.settings, "status": "failed", "error_type": type(exc).__name__,
               "error": f"{type(exc).__name__}: {msg[:300]}"}
        mdir.mkdir(parents=True, exist_ok=True)
        write_text_atomic(mdir / RESULT, json.dumps(rec, indent=1, default=str) + "\n")
        return rec

    # ---------------------------------------------------------------------------------------
    def results(self):
        """The results table (:class:`pyarrow.Table`): one row per member, settings then observables."""
        rows = collect_rows(self.outdir, self.members)
        return rows_to_table(rows, self._setting_keys())

    def _setting_keys(self):
        keys = []
        for m in self.members:
            for k in m.settings:
                if k not in keys:
                    keys.append(k)
        return [k for k in self.spec.axes if k in keys] + [k for k in keys if k not in self.spec.axes]

    def write_results(self, **extra):
        """Write the table, the plots and ``summary.json`` from the members' results; returns the summary."""
        if getattr(self, "_replaces", None) is None:
            return self._write_results(**extra)
        try:
            return self._write_results(**extra)
        except DnarodError as exc:  # name the files by their place in the ensemble folder; the old one is kept
            from dnarod.core.io import _rewrite_message

            _rewrite_message(exc, self.outdir, self._replaces,
                             f" (the earlier ensemble in {self._replaces} is unchanged; the same command with "
                             f"--overwrite continues the replacement kept in {self.outdir.name})")
            raise

    def _write_results(self, **extra):
        rows = collect_rows(self.outdir, self.members)
        table = rows_to_table(rows, self._setting_keys())
        tpath, cpath = write_table(table, self.outdir)
        plots = plot_axes(rows, self.spec.axes, self.outdir, self._setting_keys())
        status = {}
        wall = cpu = 0.0
        for m in self.members:
            r = read_result(member_dir(self.outdir, m.id)) or {}
            status[r.get("status", "pending")] = status.get(r.get("status", "pending"), 0) + 1
            wall += float(r.get("wall_s", 0.0) or 0.0)
            cpu += float(r.get("cpu_s", 0.0) or 0.0)
        failed = [{"member": r["member"], "index": r["index"], "error": r["error"]} for r in rows
                  if r["status"] == "failed"]
        info = {"name": self.spec.name, "description": self.spec.description, "fingerprint": self.fingerprint,
                "n_members": len(self.members), "status": status, "failed": failed, "axes": self.spec.axes,
                "base": self.spec.base, "analysis": self.spec.analysis,
                "protocol": _protocol_name(self.protocol_arg),
                "member_wall_s_total": wall, "member_cpu_s_total": cpu, **extra,
                "files": {"table": str(tpath), "csv": str(cpath), "plots": [str(p) for p in plots]}}
        write_summary(self.outdir, info)
        if getattr(self, "_replaces", None) is not None and not self.pending():
            info = self._replace_old(info)
        return info

    def _replace_old(self, info):
        """Put the finished replacement (``--overwrite``) in place of the old ensemble: the old ensemble's files go
        to a hidden folder, the new ones are renamed into the ensemble folder (renames: no data is written), the
        hidden folders are removed."""
        import os
        import tempfile

        final, stage = self._replaces, self.outdir
        trash = Path(tempfile.mkdtemp(prefix=".dnarod-replaced-", dir=final))
        for p in [*(final / n for n in _OURS), *final.glob("plot_*.png")]:
            if p.exists() or p.is_symlink():
                os.replace(p, trash / p.name)
        for p in stage.iterdir():
            os.replace(p, final / p.name)
        shutil.rmtree(trash, ignore_errors=True)
        for p in [stage, *final.glob(f"{REPLACEMENT_PREFIX}*")]:  # this one and any left by replacements not finished
            shutil.rmtree(p, ignore_errors=True)
        self.outdir, self._replaces = final, None
        fix = lambda x: str(x).replace(str(stage), str(final))  # noqa: E731
        info["files"] = {"table": fix(info["files"]["table"]), "csv": fix(info["files"]["csv"]),
                         "plots": [fix(x) for x in info["files"]["plots"]]}
        write_summary(final, info)
        return info


def _one_line(exc):
    msg = " ".join(str(exc).split()) or type(exc).__name__
    return msg if len(msg) <= 200 else msg[:200] + "..."


def _protocol_name(p):
    if p is None or isinstance(p, str):
        return p
    mod = getattr(p, "__module__", None) or getattr(p, "__name__", "")
    return f"{mod}:{getattr(p, '__qualname__', type(p).__qualname__)}"
