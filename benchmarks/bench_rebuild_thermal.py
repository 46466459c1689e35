"""Benchmark: all-atom rebuild of thermal snapshots of the coarse-grained model (300 K).

For each (sequence, length, seed): a dna-default chain run ``--steps`` steps of
``RodSimulation.create(m, temperature=300, nonbonded=False, seed=seed)`` (OpenMM engine), then
:func:`dnarod.structure.allatom.rebuild_allatom` on the final node frames. Records pass/fail
(the rebuild's own strict checks: every bond within 0.05 A of Amber14, no heavy-atom pair
under 2.2 A, frames within 0.05 A and 1 deg), the largest bond deviation, frame errors and the
wall / CPU time per base pair.

Usage: ``python benchmarks/bench_rebuild_thermal.py [--seeds 1 2 ...] [--steps 400] [--json OUT]``.
The machine is shared: compare figures from the same run only.
"""
from __future__ import annotations

import argparse
import json
import platform
import resource
import time
from pathlib import Path

import numpy as np

from dnarod.core.errors import StructureError
from dnarod.core.forcefield import load_forcefield
from dnarod.structure.allatom import rebuild_allatom

ROOT = Path(__file__).resolve().parents[1]
SEQUENCES = ("GATCCGTAGCATGGCAATTCGCTA", "AAAATTTTCCCCGGGGATATGCGC", "CGCGAATTCGCGCGCGAATTCGCG")


def thermal_snapshot(sequence, seed, steps=400):
    """Node frames (n,3,3) and positions (n,3) nm after ``steps`` steps at 300 K."""
    from dnarod.engines.openmm.simulation import RodSimulation

    m = load_forcefield("dna-default").model_from_sequence(sequence)
    sim = RodSimulation.create(m, temperature=300, nonbonded=False, seed=seed)
    sim.advance(steps)
    c, f, _, _ = sim.node_state()
    return m.with_pose(c, f)


def placed_ring_clash(m):
    """Shortest distance (nm) between base ring atoms of different residues as the frames place them.

    Below 0.22 nm no rebuild can keep the frames within tolerance and avoid the clash.
    """
    from scipy.spatial import cKDTree

    from dnarod.structure.frames import standard_bases
    from dnarod.structure.rebuild import rebuild_coordinates

    _, ring = standard_bases()
    names = {a for r in ring.values() for a in r}
    xyz, atoms = rebuild_coordinates(m.frames, m.positions, m.sequence)
    keep = [i for i, a in enumerate(atoms) if a[3] in names]
    res = np.array([(atoms[i][0], atoms[i][1]) for i in keep], dtype=object)
    best = np.inf
    for i, j in cKDTree(xyz[keep]).query_pairs(0.3):
        if tuple(res[i]) != tuple(res[j]):
            best = min(best, np.linalg.norm(xyz[keep[i]] - xyz[keep[j]]))
    return float(best)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, nargs="+", default=list(range(1, 8)))
    ap.add_argument("--lengths", type=int, nargs="+", default=[10, 16, 24])
    ap.add_argument("--steps", type=int, default=400)
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "results" / "bench_rebuild_thermal.json"))
    a = ap.parse_args()
    rows = []
    k = 0
    for seed in a.seeds:
        for si, seq in enumerate(SEQUENCES):
            n = a.lengths[k % len(a.lengths)]
            k += 1
            m = thermal_snapshot(seq[:n], seed, a.steps)
            c0, t0 = resource.getrusage(resource.RUSAGE_SELF).ru_utime, time.perf_counter()
            row = {"sequence": seq[:n], "n_bp": n, "seed": seed,
                   "placed_ring_min_A": 10 * placed_ring_clash(m)}
            try:
                r = rebuild_allatom(m.frames, m.positions, m.sequence).report
                row.update(ok=True, error="", max_bond_dev_A=10 * r.max_bond_deviation, worst_bond=r.worst_bond,
                           min_nonbonded_A=10 * r.min_nonbonded, frame_origin_err_A=10 * r.frame_origin_error,
                           frame_angle_err_deg=r.frame_angle_error, max_angle_dev_deg=r.max_angle_deviation,
                           o3p_min_A=10 * r.o3p_range[0], o3p_max_A=10 * r.o3p_range[1])
            except StructureError as exc:
                row.update(ok=False, error=str(exc))
            row["wall_per_bp_s"] = (time.perf_counter() - t0) / n
            row["cpu_per_bp_s"] = (resource.getrusage(resource.RUSAGE_SELF).ru_utime - c0) / n
            rows.append(row)
            print(json.dumps(row), flush=True)
    ok = [r for r in rows if r["ok"]]
    summ = {"passed": len(ok), "total": len(rows),
            "worst_bond_dev_A": max((r["max_bond_dev_A"] for r in ok), default=np.nan),
            "worst_frame_origin_err_A": max((r["frame_origin_err_A"] for r in ok), default=np.nan),
            "worst_frame_angle_err_deg": max((r["frame_angle_err_deg"] for r in ok), default=np.nan),
            "min_nonbonded_A": min((r["min_nonbonded_A"] for r in ok), default=np.nan),
            "worst_angle_dev_deg": max((r["max_angle_dev_deg"] for r in ok), default=np.nan),
            "o3p_range_A": [min((r["o3p_min_A"] for r in ok), default=np.nan),
                            max((r["o3p_max_A"] for r in ok), default=np.nan)],
            "refused": [f"{r['sequence']} seed {r['seed']}: {r['error']}" for r in rows if not r["ok"]],
            "mean_wall_per_bp_s": float(np.mean([r["wall_per_bp_s"] for r in rows])),
            "mean_cpu_per_bp_s": float(np.mean([r["cpu_per_bp_s"] for r in rows]))}
    print(json.dumps(summ, indent=1))
    import openmm

    import os

    out = {"machine": platform.platform(), "python": platform.python_version(), "openmm": openmm.__version__,
           "load_average_at_end": os.getloadavg(), "steps": a.steps, "temperature_K": 300, "summary": summ,
           "rows": rows}
    Path(a.json).parent.mkdir(parents=True, exist_ok=True)
    Path(a.json).write_text(json.dumps(out, indent=1))
    print(f"wrote {a.json}")


if __name__ == "__main__":
    main()
