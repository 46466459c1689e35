"""Benchmark: the run layer (``dnarod simulate``) of both engines.

* time to the first step: wall time of ``dnarod simulate SEQ.fa --engine E`` for a run of one
  time step on a 20,000-node random dna-default sequence, in a fresh process (imports, model,
  omega_max, engine set-up, first step, checkpoint, final model), and the run's own set-up
  figures from ``run.json``;
* trajectory size: bytes per node-frame of the ``.dtraj`` written (float32, with and without
  velocities) against the older float64 format;
* run-loop overhead: ns/day of a 1,000-node Lax-form run through ``dnarod.run.run`` (a frame and
  an energy row every 1 ps, checkpoints every 10 ps) against the bare ``engine.advance``.

Usage: ``python benchmarks/bench_run.py [--nodes 20000] [--json OUT]``. Wall and CPU times are
given side by side (the machine is shared).
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def first_step(n_nodes, engine, workdir):
    rng = np.random.default_rng(1)
    fa = Path(workdir) / f"seq{n_nodes}.fa"
    fa.write_text(">random\n" + "".join(rng.choice(list("ACGT"), n_nodes)) + "\n")
    out = Path(workdir) / f"first_{engine}"
    cmd = [str(Path(sys.executable).parent / "dnarod"), "simulate", str(fa), "--engine", engine, "--time", "0.0001",
           "-o", str(out), "--no-progress", "--no-export", "--seed", "1"]
    cpu0, t0 = _children_cpu(), time.perf_counter()
    p = subprocess.run(cmd, capture_output=True, text=True)
    wall, cpu = time.perf_counter() - t0, _children_cpu() - cpu0
    if p.returncode != 0:
        return dict(engine=engine, n_nodes=n_nodes, error=p.stderr.strip().splitlines()[-1])
    meta = json.loads((out / "run.json").read_text())
    return dict(engine=engine, n_nodes=n_nodes, wall_s=wall, cpu_s=cpu, steps=meta["segments"][-1]["to_step"],
                loop_wall_s=meta["segments"][-1]["wall_s"])


def sizes(workdir):
    from dnarod.run import RunSpec, run
    from dnarod.core.trajectory import HEADER_SIZE

    out = {}
    for vel in (False, True):
        spec = RunSpec(source="ACGT" * 50, engine="lax", time_ns=0.02, excluded_volume=False, electrostatics=False,
                       seed=1, velocities=vel, export=False)
        res = run(spec, Path(workdir) / f"size_{vel}", progress=False)
        from dnarod.core.trajectory import load_trajectory

        tr = load_trajectory(res.files["trajectory"])
        size = res.files["trajectory"].stat().st_size - HEADER_SIZE - 16 * tr.n_frames  # minus step and time
        out["with_velocities" if vel else "positions_frames"] = size / (tr.n_frames * tr.n_nodes)
    out["float64_v1_positions_frames"] = 12 * 8
    out["float64_v1_with_velocities"] = 18 * 8
    return out


def loop_overhead(workdir, n_nodes=1000, time_ns=0.05):
    from dnarod.run import RunSpec, run
    from dnarod.run.api import make_engine, source_model

    rng = np.random.default_rng(2)
    spec = RunSpec(source="".join(rng.choice(list("ACGT"), n_nodes)), engine="lax", time_ns=time_ns,
                   excluded_volume=False, electrostatics=False, seed=1, export=False)
    res = run(spec, Path(workdir) / "loop", progress=False)
    s = res.summary
    model = source_model(spec)
    eng = make_engine(spec, model, s["dt_ps"], 1, s["omega_max"])
    eng.advance(10)
    t, c = time.perf_counter(), time.process_time()
    eng.advance(s["steps"])
    wall, cpu = time.perf_counter() - t, time.process_time() - c
    bare = s["steps"] * s["dt_ps"] * 1e-3 / wall * 86400
    return dict(n_nodes=n_nodes, steps=s["steps"], ns_per_day_run=s["ns_per_day"], cpu_s_run=s["cpu_s"],
                wall_s_run=s["wall_s"], ns_per_day_bare=bare, wall_s_bare=wall, cpu_s_bare=cpu,
                run_over_bare=s["ns_per_day"] / bare)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--nodes", type=int, default=20000)
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "results" / "bench_run.json"))
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as d:
        firsts = [first_step(args.nodes, e, d) for e in ("lax", "openmm")]
        size = sizes(d)
        loop = loop_overhead(d)
    print(f"time to the first step, {args.nodes} nodes, fresh process (imports, model, omega_max, set-up, one step, "
          f"checkpoint, final model):")
    for f in firsts:
        if "error" in f:
            print(f"  {f['engine']:>6}: error {f['error']}")
        else:
            print(f"  {f['engine']:>6}: wall {f['wall_s']:.2f} s, CPU {f['cpu_s']:.2f} s ({f['steps']} step(s); "
                  f"run loop {f['loop_wall_s']:.3f} s)")
    print(f"trajectory bytes per node-frame: {size['positions_frames']:.0f} (float32), "
          f"{size['with_velocities']:.0f} with velocities; float64 (format 1): {size['float64_v1_positions_frames']}, "
          f"{size['float64_v1_with_velocities']}")
    print(f"run loop, {loop['n_nodes']} nodes, Lax engine, frame + energies every 1 ps: {loop['ns_per_day_run']:.4g} "
          f"ns/day (wall {loop['wall_s_run']:.2f} s, CPU {loop['cpu_s_run']:.2f} s) against bare advance "
          f"{loop['ns_per_day_bare']:.4g} ns/day (wall {loop['wall_s_bare']:.2f} s, CPU {loop['cpu_s_bare']:.2f} s): "
          f"ratio {loop['run_over_bare']:.3f}")
    out = dict(benchmark="bench_run", machine=platform.platform(), cpu_count=os.cpu_count(),
               python=platform.python_version(), first_step=firsts, bytes_per_node_frame=size, loop=loop)
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    Path(args.json).write_text(json.dumps(out, indent=2))
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
