"""Timings of the trajectory analyses (prints a table, writes benchmarks/results/bench_analysis.json).

Usage: python benchmarks/bench_analysis.py
"""
from __future__ import annotations

import json
import time
from pathlib import Path

import numpy as np

from dnarod.analysis import LinkingNumber, StepAnalysis, StiffnessFit, TangentCorrelation
from dnarod.physics.sampling import sample_chains
from dnarod.physics.writhe import writhe
from dnarod.core.forcefield import load_forcefield
from dnarod.core.units import kT


def timed(fn, repeat=3):
    best = np.inf
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def main():
    ff = load_forcefield("dna-default")
    rows = []
    for n_frames, n_nodes in ((1000, 50), (200, 500)):
        traj = sample_chains(ff.step_parameters(n_steps=n_nodes - 1), ff.ds, kT(300), n_frames,
                             np.random.default_rng(0))
        for name, fn in (("StepAnalysis", lambda: StepAnalysis(traj, ff.ds).run()),
                         ("StiffnessFit", lambda: StiffnessFit(traj, ff.ds).run()),
                         ("TangentCorrelation", lambda: TangentCorrelation(traj, ff.ds).run())):
            t = timed(fn)
            rows.append(dict(analysis=name, frames=n_frames, nodes=n_nodes, seconds=t,
                             us_per_step=1e6 * t / (n_frames * (n_nodes - 1))))
    for n in (100, 400, 1000):
        s = np.linspace(0, 2 * np.pi, n, endpoint=False)
        P = np.stack([np.cos(s), np.sin(s), 0.2 * np.sin(3 * s)], 1)
        t = timed(lambda: writhe(P))
        rows.append(dict(analysis="writhe", frames=1, nodes=n, seconds=t, us_per_step=1e6 * t / n))
    s = np.linspace(0, 2 * np.pi, 200, endpoint=False)
    from dnarod.core.trajectory import Trajectory
    P = 10 * np.stack([np.cos(s), np.sin(s), 0 * s], 1)
    T = np.stack([-np.sin(s), np.cos(s), 0 * s], 1)
    N = -P / 10
    F = np.stack([N, np.cross(T, N), T], axis=-1)
    ring = Trajectory(np.arange(10.0), np.repeat(P[None], 10, 0), np.repeat(F[None], 10, 0))
    t = timed(lambda: LinkingNumber(ring).run(), repeat=1)
    rows.append(dict(analysis="LinkingNumber", frames=10, nodes=200, seconds=t, us_per_step=1e6 * t / 2000))
    print(f"{'analysis':20s} {'frames':>7s} {'nodes':>6s} {'seconds':>9s} {'us/step':>9s}")
    for r in rows:
        print(f"{r['analysis']:20s} {r['frames']:7d} {r['nodes']:6d} {r['seconds']:9.3f} {r['us_per_step']:9.2f}")
    out = Path(__file__).resolve().parent / "results" / "bench_analysis.json"
    out.parent.mkdir(exist_ok=True)
    out.write_text(json.dumps(rows, indent=2) + "\n")


if __name__ == "__main__":
    main()
