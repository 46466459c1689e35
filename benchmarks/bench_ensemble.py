"""Benchmark: ensembles on dask.distributed.

1. Speed-up: 8 members of a 200-bp OpenMM run (the automatic platform, one thread: OpenMM's Reference
   platform since round 11, ``--platform CPU`` for the CPU platform with one thread; clamped and pulled,
   forces 0.5-4 pN) on a 2-worker ``LocalCluster`` against the same 8 members one after another
   in this process (the worker function itself, same one-thread settings). Target >= 1.8x on 2
   cores. The cluster is started and every process (this one and each worker) is warmed up by one
   tiny member (imports, numba compilation) before the clocks; both are reported separately. Each
   member's own wall and CPU time (its ``result.json``) is kept for both sides, so a side that is
   slower per member shows where. Members are 20 ns (~9 s each on Reference; at 2 ns, 0.8 s each, the
   scheduling dominates). On the CPU platform with one thread a member took 3.1 s of wall (2.5 s CPU) one
   after another on the otherwise idle machine and 1.2 s (1.2 s CPU) with both workers busy (2026-12-07;
   cause not proven), which inflates the CPU platform's "speed-up" to 4x; Reference shows no such effect.
2. Scheduling overhead per member: ``--overhead-members`` members of the "null" protocol (no
   simulation: each writes its member.json, log and result.json) on the same cluster; wall time
   per member (target < 0.5 s).
3. Client memory: the same null ensemble with 100 and with 1,000 members, each in a fresh
   process whose scheduler and workers run in subprocesses (dask's ``SubprocessCluster``), so
   only the client is measured: peak of its Python allocations (tracemalloc, which also slows
   it) and the growth of its resident set during ``run`` (target: flat).

Usage: ``python benchmarks/bench_ensemble.py [--time-ns T] [--json OUT]``. Prints a table and
writes JSON (default ``benchmarks/results/bench_ensemble.json``). Wall and CPU times are both
given; the machine load (1-minute load average) is recorded before and after each part.
"""
from __future__ import annotations

import os

os.environ.setdefault("OPENMM_CPU_THREADS", "1")   # the sequential baseline runs OpenMM on one thread too
os.environ.setdefault("NUMBA_NUM_THREADS", "1")

import argparse  # noqa: E402
import json  # noqa: E402
import math  # noqa: E402
import platform  # noqa: E402
import resource  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
import tempfile  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SEQ200 = "GATTACAG" * 25


def load():
    return round(os.getloadavg()[0], 2)


def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def warm_up():
    """One tiny OpenMM member in this process (imports, numba compilation, OpenMM plugins)."""
    import tempfile

    from dnarod.workflows.ensemble import parse_spec, run_member

    m = next(parse_spec({"base": {"source": "ACGTACGTACGT", "time_ns": 0.002, "clamp_first": True,
                                  "force_pN": 1.0}}).members())
    with tempfile.TemporaryDirectory() as d:
        assert run_member(m.id, m.settings, d)["status"] == "ok"
    return True


def _member_times(outdir, members):
    """Each member's (wall_s, cpu_s) from its result.json."""
    from dnarod.workflows.ensemble.member import member_dir, read_result

    return [[round(float(r["wall_s"]), 3), round(float(r["cpu_s"]), 3)]
            for r in (read_result(member_dir(outdir, m.id)) for m in members)]


def speedup(time_ns, workdir, platform_name=None):
    from distributed import Client

    from dnarod.workflows.ensemble import Ensemble, local_cluster, run_member

    base = {"source": SEQ200, "engine": "openmm", "time_ns": time_ns, "clamp_first": True, "frame_interval_ps": 2.0}
    if platform_name:
        base["platform"] = platform_name
    doc = {"base": base, "axes": {"force_pN": [0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0]}}
    out = {"members": 8, "n_bp": 200, "time_ns_per_member": time_ns, "platform": platform_name or "automatic",
           "load_before": load()}
    ens = Ensemble.from_dict(doc, workdir / "seq")
    ens.prepare()
    warm_up()
    t, c = time.perf_counter(), time.process_time()
    for m in ens.members:
        rec = run_member(m.id, m.settings, str(workdir / "seq"), None, ens.spec.analysis)
        assert rec["status"] == "ok", rec
    out["sequential_wall_s"] = time.perf_counter() - t
    out["sequential_cpu_s"] = time.process_time() - c
    out["sequential_member_wall_cpu_s"] = _member_times(workdir / "seq", ens.members)
    t = time.perf_counter()
    cluster = local_cluster(2)
    client = Client(cluster, set_as_default=False)
    out["cluster_startup_s"] = time.perf_counter() - t
    t = time.perf_counter()
    client.run(warm_up)                    # the same warm-up on every worker
    out["worker_warm_up_s"] = time.perf_counter() - t
    try:
        par = Ensemble.from_dict(doc, workdir / "par")
        t = time.perf_counter()
        par.run(client=client, progress=False)
        out["parallel_wall_s"] = time.perf_counter() - t
        out["parallel_member_cpu_s"] = par.summary["member_cpu_s_total"]
        out["parallel_member_wall_cpu_s"] = _member_times(workdir / "par", par.members)
        assert par.summary["status"] == {"ok": 8}, par.summary
        out["tables_equal"] = bool(par.results().equals(ens.results()))
    finally:
        client.close()
        cluster.close()
    out["speedup"] = out["sequential_wall_s"] / out["parallel_wall_s"]
    out["load_after"] = load()
    return out


def overhead(n, workdir):
    from distributed import Client

    from dnarod.workflows.ensemble import Ensemble, local_cluster

    cluster = local_cluster(2)
    client = Client(cluster, set_as_default=False)
    client.run(lambda: __import__("dnarod.workflows.ensemble.member"))
    try:
        doc = {"base": {"source": "ACGTACGTACGT"}, "axes": {"force_pN": {"linspace": [0.0, 1.0, n]}},
               "ensemble": {"protocol": "null"}}
        out = {"members": n, "load_before": load()}
        ens = Ensemble.from_dict(doc, workdir / f"null{n}")
        t = time.perf_counter()
        ens.run(client=client, progress=False)
        out["wall_s"] = time.perf_counter() - t
        out["per_member_s"] = out["wall_s"] / n
        out["worker_s_per_member"] = 2 * out["wall_s"] / n
        out["member_wall_s_mean"] = ens.summary["member_wall_s_total"] / n
        out["load_after"] = load()
        return out
    finally:
        client.close()
        cluster.close()


MEMORY_CHILD = r"""
import json, os, resource, sys, time, tracemalloc
from distributed import Client
from distributed.deploy.subprocess import SubprocessCluster
from dnarod.workflows.ensemble import WORKER_ENV, Ensemble
n, out = int(sys.argv[1]), sys.argv[2]
# scheduler and workers in their own processes: what is measured here is the client alone
cluster = SubprocessCluster(n_workers=2, threads_per_worker=1, dashboard_address=None,
                            worker_kwargs={"env": dict(WORKER_ENV)})
client = Client(cluster, set_as_default=False)
client.run(lambda: __import__("dnarod.workflows.ensemble.member"))
def rss():
    with open("/proc/self/status") as fh:
        return next(int(l.split()[1]) for l in fh if l.startswith("VmRSS")) * 1024
doc = {"base": {"source": "ACGTACGTACGT"}, "axes": {"force_pN": {"linspace": [0.0, 1.0, n]}},
       "ensemble": {"protocol": "null"}}
import matplotlib.pyplot, pyarrow.parquet, pyarrow.csv   # imported before the baseline
r0 = rss()
tracemalloc.start()
ens = Ensemble.from_dict(doc, out)
t = time.perf_counter()
ens.run(client=client, progress=False)
wall = time.perf_counter() - t
cur, peak = tracemalloc.get_traced_memory()
tracemalloc.stop()
print(json.dumps({"members": n, "tracemalloc_peak_bytes": peak, "tracemalloc_end_bytes": cur,
                  "rss_growth_bytes": rss() - r0,
                  "rss_peak_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024, "wall_s": wall}))
client.close(); cluster.close()
"""


def memory(ns, workdir):
    rows = []
    for n in ns:
        r = subprocess.run([sys.executable, "-c", MEMORY_CHILD, str(n), str(workdir / f"mem{n}")], capture_output=True,
                           text=True, check=True, env=dict(os.environ, PYTHONPATH=str(ROOT)))
        rows.append(json.loads(r.stdout.strip().splitlines()[-1]))
    return rows


def _positive(text):
    v = float(text)
    if not math.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"{text!r}: give a finite time > 0 ns")
    return v


def _platform_names():
    """The OpenMM platforms this installation has (so a misspelt one is refused before any member runs)."""
    import openmm

    return [openmm.Platform.getPlatform(i).getName() for i in range(openmm.Platform.getNumPlatforms())]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--time-ns", type=_positive, default=20.0, help="simulated time per 200-bp member, ns")
    ap.add_argument("--platform", default=None, choices=_platform_names(),
                    help="OpenMM platform of the speed-up members (default: automatic)")
    ap.add_argument("--overhead-members", type=int, default=200)
    ap.add_argument("--memory-members", type=int, nargs="+", default=[10, 100, 1000])
    ap.add_argument("--skip", nargs="*", default=[], choices=["speedup", "overhead", "memory"])
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "results" / "bench_ensemble.json"))
    args = ap.parse_args()
    res = {"machine": {"python": platform.python_version(), "cpus": os.cpu_count(),
                       "affinity": len(os.sched_getaffinity(0)), "platform": platform.platform()},
           "date": time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())}
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        if "speedup" not in args.skip:
            s = res["speedup"] = speedup(args.time_ns, tmp, args.platform)
            print(f"8 x 200-bp members, {args.time_ns:g} ns each, platform {s['platform']} "
                  f"(load {s['load_before']} -> {s['load_after']})")
            print(f"  sequential, one process   wall {s['sequential_wall_s']:8.1f} s   "
                  f"CPU {s['sequential_cpu_s']:8.1f} s")
            print(f"  2-worker LocalCluster     wall {s['parallel_wall_s']:8.1f} s   member CPU "
                  f"{s['parallel_member_cpu_s']:8.1f} s   (cluster start-up {s['cluster_startup_s']:.1f} s, "
                  f"worker warm-up {s['worker_warm_up_s']:.1f} s)")
            print(f"  speed-up {s['speedup']:.2f}x   tables equal: {s['tables_equal']}")
            for side in ("sequential", "parallel"):
                print(f"  {side:10s} per member (wall, CPU) s: "
                      + "  ".join(f"{w:.1f}/{c:.1f}" for w, c in s[f"{side}_member_wall_cpu_s"]))
        if "overhead" not in args.skip:
            o = res["overhead"] = overhead(args.overhead_members, tmp)
            print(f"{o['members']} null members on 2 workers: wall {o['wall_s']:.2f} s -> "
                  f"{o['per_member_s'] * 1000:.1f} ms per member ({o['worker_s_per_member'] * 1000:.1f} worker-ms; "
                  f"inside the member function "
                  f"{o['member_wall_s_mean'] * 1000:.1f} ms) (load {o['load_before']} -> {o['load_after']})")
        if "memory" not in args.skip:
            m = res["memory"] = memory(args.memory_members, tmp)
            print("client memory, null members:  members  tracemalloc peak  RSS growth  wall")
            for r in m:
                print(f"  {r['members']:>30d}  {r['tracemalloc_peak_bytes'] / 2**20:13.2f} MiB  "
                      f"{r['rss_growth_bytes'] / 2**20:8.1f} MiB  {r['wall_s']:6.1f} s")
            if len(m) >= 2:
                a, b = m[0], m[-1]
                per = (b["tracemalloc_peak_bytes"] - a["tracemalloc_peak_bytes"]) / (b["members"] - a["members"])
                res["memory_per_member_bytes"] = per
                print(f"  tracemalloc peak growth per extra member: {per / 1024:.2f} KiB")
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(res, indent=1) + "\n")
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
