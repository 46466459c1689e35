"""Benchmark: the run layer's own cost at 1 kbp, against the engine's bare step, interleaved.

One child process per (tree, repeat), trees alternating (this tree, and with ``--old-tree DIR`` a
checkout of an older commit whose ``dnarod/_plugin`` holds the same compiled plugin). Each child
builds the ``dnarod simulate`` default run of a 1,000-bp duplex (``RunSpec(source="ACGT" * 250,
time_ns=T)``: OpenMM engine, automatic platform, default elastic path (the compiled plugin), a frame and
an energies row every 1 ps, the default checkpoint schedule, export to PDB + DCD + XTC, progress bar
on) and then, ``--pairs`` times, alternately

* ``bare`` -- the same engine (:func:`dnarod.run.api.make_engine` with the run's time step and seed)
  advanced over the run's number of steps in one ``engine.advance(n)`` call, no reporters;
* ``run``  -- :func:`dnarod.run.run` of the spec into a fresh folder; the loop's own wall and CPU time
  (``summary['wall_s']``, ``summary['cpu_s']``, what ``ns_per_day`` is computed from), the end-of-run
  export timed apart (wrapping :func:`dnarod.structure.export.export_trajectory`), and the whole call.

Figures: wall and CPU seconds per step of both, their ratio ``run / bare`` (the issue's "whole step
at most 10 % above the bare step"), the export time, and the number of checkpoints written. The
machine is shared: compare only figures of one invocation, CPU beside wall.

Usage::

    python benchmarks/bench_run_overhead.py [--time-ns 2] [--pairs 2] [--repeats 2] [--old-tree DIR]
        [--plugin] [--json benchmarks/results/run_layer_overhead.json]

``--plugin`` also runs the 10^4-node plugin benchmark (``bench_plugin.sizes([10000], ...)``: the callback and
plugin paths, elastic only and full model) ``--plugin-repeats`` times under each tree, interleaved.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ.setdefault("NUMBA_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import _harness as H  # noqa: E402

_TREE_PRELUDE = """
import sys
tree = {tree!r}
if tree:
    # import dnarod from another checkout (an editable install's finder would redirect to this tree)
    sys.meta_path[:] = [f for f in sys.meta_path if 'editable' not in type(f).__module__]
    sys.path.insert(0, tree)
"""


def _use_tree(tree):
    if tree:
        exec(_TREE_PRELUDE.format(tree=tree), {})


def single(tree, time_ns, pairs, n_bp, profile=None, frame_interval_ps=None):
    """One child: ``pairs`` interleaved (bare, run) measurements; returns a JSON-able dict."""
    _use_tree(tree)
    import dnarod
    import dnarod.structure.export as ex
    from dnarod.run import RunSpec, run
    from dnarod.run.api import choose_dt, default_omega_max, intervals, make_engine, source_model

    export_times = []
    original = ex.export_trajectory

    def timed_export(*a, **k):
        t, c = time.perf_counter(), time.process_time()
        try:
            return original(*a, **k)
        finally:
            export_times.append((time.perf_counter() - t, time.process_time() - c))

    ex.export_trajectory = timed_export
    seq = "ACGT" * (n_bp // 4)
    spec = RunSpec(source=seq, time_ns=time_ns, seed=1)
    if frame_interval_ps is not None:
        spec = spec.replace(frame_interval_ps=frame_interval_ps)
    model = source_model(spec)
    omega = default_omega_max(model, spec.loads)
    dt = choose_dt(spec, model, omega)
    n_steps, fi, ci = intervals(spec, dt)
    out = dict(tree=tree or str(ROOT), dnarod=str(Path(dnarod.__file__).parent), n_bp=n_bp, time_ns=time_ns,
               frame_interval_ps=spec.frame_interval_ps,
               steps=n_steps, dt_ps=dt, frame_interval_steps=fi, checkpoint_interval_steps=ci, pairs=[])
    workdir = tempfile.mkdtemp(prefix="bench_run_overhead_")
    for i in range(pairs):
        rec = {}
        for what in (("bare", "run") if i % 2 == 0 else ("run", "bare")):
            if what == "bare":
                eng = make_engine(spec, model, dt, 1, omega)
                rec["platform"], rec["elastic"] = eng.platform_name, eng.rs.elastic
                t, c = time.perf_counter(), time.process_time()
                eng.advance(n_steps)
                rec["bare_wall_s"], rec["bare_cpu_s"] = time.perf_counter() - t, time.process_time() - c
                del eng
            else:
                saves = []
                folder = Path(workdir) / f"run{i}"
                n_export = len(export_times)
                # count checkpoints: wrap the loop's checkpoint writes through the engine class
                from dnarod.engines.openmm.simulation import RodSimulation
                eng_cls_save = RodSimulation.save_checkpoint

                def counting(self, *a, **k):
                    saves.append(1)
                    return eng_cls_save(self, *a, **k)

                RodSimulation.save_checkpoint = counting
                prof = None
                if profile:
                    import cProfile
                    prof = cProfile.Profile()
                    prof.enable()
                t, c = time.perf_counter(), time.process_time()
                try:
                    res = run(spec, folder, progress=True)
                finally:
                    RodSimulation.save_checkpoint = eng_cls_save
                    if prof is not None:
                        prof.disable()
                        prof.dump_stats(f"{profile}.{i}")
                rec["call_wall_s"], rec["call_cpu_s"] = time.perf_counter() - t, time.process_time() - c
                s = res.summary
                rec["loop_wall_s"], rec["loop_cpu_s"] = s["wall_s"], s["cpu_s"]
                rec["ns_per_day"] = s["ns_per_day"]
                rec["export_wall_s"], rec["export_cpu_s"] = (export_times[-1] if len(export_times) > n_export
                                                             else (0.0, 0.0))
                rec["checkpoints"] = len(saves)
                rec["files"] = sorted(p.name for p in res.files.values())
                shutil.rmtree(folder, ignore_errors=True)  # a 10-ns run's trajectory is 0.5 GB
        rec["ratio_wall"] = rec["loop_wall_s"] / rec["bare_wall_s"]
        rec["ratio_cpu"] = rec["loop_cpu_s"] / rec["bare_cpu_s"]
        out["pairs"].append(rec)
    shutil.rmtree(workdir, ignore_errors=True)
    return out


def _child(tree, args):
    cmd = [sys.executable, str(Path(__file__).resolve()), "--single", "--time-ns", str(args.time_ns),
           "--pairs", str(args.pairs), "--n-bp", str(args.n_bp)]
    if args.frame_interval_ps is not None:
        cmd += ["--frame-interval-ps", str(args.frame_interval_ps)]
    if tree:
        cmd += ["--tree", tree]
    p = subprocess.run(cmd, capture_output=True, text=True)
    if p.returncode != 0:
        return dict(tree=tree, error=(p.stderr.strip().splitlines() or ["failed"])[-1])
    return json.loads(p.stdout.strip().splitlines()[-1])


def _plugin_child(tree, budget):
    """The 10^4-node plugin benchmark (:func:`bench_plugin.sizes` at 10^4 nodes: the callback and plugin paths,
    elastic only and full model, node-steps per CPU-second and per wall second) under ``tree``."""
    code = _TREE_PRELUDE.format(tree=tree) + (
        "import json, sys\n"
        f"sys.path.insert(0, {str(ROOT / 'benchmarks')!r})\n"
        "import bench_plugin\n"
        f"print(json.dumps(bench_plugin.sizes([10000], {float(budget)!r}, 1)[0]))\n")
    t = time.perf_counter()
    p = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    if p.returncode != 0:
        return dict(tree=tree or str(ROOT), error=(p.stderr.strip().splitlines() or ["failed"])[-1])
    return dict(tree=tree or str(ROOT), wall_s=time.perf_counter() - t, **json.loads(p.stdout.strip().splitlines()[-1]))


def _plugin_summary(plugin):
    out = {}
    for tree in dict.fromkeys(p["tree"] for p in plugin):
        rows = [p for p in plugin if p["tree"] == tree and "error" not in p]
        out[tree] = {k: statistics.median(r[k] for r in rows) for k in
                     ("plugin_full_per_cpu_s", "plugin_bonded_per_cpu_s", "plugin_full_per_wall_s",
                      "callback_full_per_cpu_s")} if rows else {}
        out[tree]["n"] = len(rows)
    return out


def _summary(children):
    by = {}
    for ch in children:
        if "error" in ch:
            continue
        by.setdefault(ch["tree"], []).extend(ch["pairs"])
    out = {}
    for tree, pairs in by.items():
        med = lambda k: statistics.median(p[k] for p in pairs)  # noqa: E731
        steps = children[0]["steps"]
        out[tree] = dict(n=len(pairs), ratio_wall_median=med("ratio_wall"), ratio_cpu_median=med("ratio_cpu"),
                         ratio_wall_all=[p["ratio_wall"] for p in pairs], ratio_cpu_all=[p["ratio_cpu"] for p in pairs],
                         bare_wall_ms_per_step=1e3 * med("bare_wall_s") / steps,
                         bare_cpu_ms_per_step=1e3 * med("bare_cpu_s") / steps,
                         loop_wall_ms_per_step=1e3 * med("loop_wall_s") / steps,
                         loop_cpu_ms_per_step=1e3 * med("loop_cpu_s") / steps,
                         export_wall_s=med("export_wall_s"), export_cpu_s=med("export_cpu_s"),
                         call_wall_s=med("call_wall_s"), checkpoints=med("checkpoints"),
                         ns_per_day=med("ns_per_day"))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--time-ns", type=float, default=2.0)
    ap.add_argument("--n-bp", type=int, default=1000)
    ap.add_argument("--frame-interval-ps", type=float, default=None,
                    help="frame (and energies-row) interval, ps (default: simulate's, 1 ps)")
    ap.add_argument("--pairs", type=int, default=2, help="interleaved (bare, run) pairs per child process")
    ap.add_argument("--repeats", type=int, default=2, help="child processes per tree (trees alternate)")
    ap.add_argument("--old-tree", default=None, help="a checkout of an older commit to compare (same plugin build)")
    ap.add_argument("--plugin", action="store_true", help="also the 10^4-node plugin benchmark under each tree")
    ap.add_argument("--plugin-budget", type=float, default=3.0, help="seconds per plugin rate measurement")
    ap.add_argument("--plugin-repeats", type=int, default=4, help="child processes per tree for the plugin benchmark")
    ap.add_argument("--json", default=str(H.RESULTS / "run_layer_overhead.json"))
    ap.add_argument("--single", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--tree", default=None, help=argparse.SUPPRESS)
    ap.add_argument("--profile", default=None, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.single:
        print(json.dumps(single(args.tree, args.time_ns, args.pairs, args.n_bp, args.profile,
                                args.frame_interval_ps)))
        return
    trees = [None] + ([str(Path(args.old_tree).resolve())] if args.old_tree else [])
    load0 = os.getloadavg()
    children, plugin = [], []
    for r in range(args.repeats):
        for tree in (trees if r % 2 == 0 else trees[::-1]):
            ch = _child(tree, args)
            children.append(ch)
            name = "this tree" if tree is None else tree
            if "error" in ch:
                print(f"{name}: error {ch['error']}", file=sys.stderr)
                continue
            for p in ch["pairs"]:
                print(f"{name:>24}: bare {p['bare_wall_s']:.2f} s wall / {p['bare_cpu_s']:.2f} s CPU, run loop "
                      f"{p['loop_wall_s']:.2f} / {p['loop_cpu_s']:.2f} s: ratio wall {p['ratio_wall']:.3f}, CPU "
                      f"{p['ratio_cpu']:.3f}; export {p['export_wall_s']:.2f} s wall / {p['export_cpu_s']:.2f} s CPU; "
                      f"{p['checkpoints']} checkpoints; {p['platform']}/{p['elastic']}", file=sys.stderr)
    if args.plugin:
        for r in range(args.plugin_repeats):
            for tree in (trees if r % 2 == 0 else trees[::-1]):
                plugin.append(p := _plugin_child(tree, args.plugin_budget))
                print(f"plugin benchmark, 10^4 nodes ({tree or 'this tree'}): " + (
                    p["error"] if "error" in p else f"plugin full {p['plugin_full_per_cpu_s']:.4g} node-steps per "
                    f"CPU-s ({p['plugin_full_per_wall_s']:.4g} per wall s), bonded {p['plugin_bonded_per_cpu_s']:.4g}"),
                      file=sys.stderr)
    summary = _summary(children)
    print(f"{args.n_bp} bp, {args.time_ns:g} ns per run ({children[0].get('steps')} steps), medians of "
          f"{args.repeats} x {args.pairs} interleaved pairs:")
    print(f"{'tree':>40} {'bare ms/step':>13} {'run ms/step':>12} {'ratio wall':>10} {'ratio CPU':>9} "
          f"{'export s':>9} {'ckpts':>6}")
    for tree, s in summary.items():
        print(f"{tree:>40} {s['bare_wall_ms_per_step']:>6.4f}/{s['bare_cpu_ms_per_step']:.4f} "
              f"{s['loop_wall_ms_per_step']:>6.4f}/{s['loop_cpu_ms_per_step']:.4f} {s['ratio_wall_median']:>10.3f} "
              f"{s['ratio_cpu_median']:>9.3f} {s['export_wall_s']:>9.2f} {s['checkpoints']:>6g}")
    plugin_summary = _plugin_summary(plugin) if plugin else None
    if plugin:
        print("10^4-node plugin benchmark, medians (node-steps per CPU-second):")
        for tree, s in plugin_summary.items():
            if s.get("n"):
                print(f"{tree:>40} plugin full {s['plugin_full_per_cpu_s']:.4g}, bonded {s['plugin_bonded_per_cpu_s']:.4g} "
                      f"({s['n']} runs)")
    H.write_results(args.json, "run_layer_overhead", command=" ".join(sys.argv), load_average_start=load0,
                    summary=summary, children=children, plugin=plugin,
                    plugin_summary=plugin_summary)


if __name__ == "__main__":
    main()
