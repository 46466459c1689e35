"""Benchmark: all-atom rebuild with a closed Amber14 backbone, time per base pair.

Cases: the ideal intrinsic shape (dna-default) of 12 and 24 bp, the crystal nodes of 355D
(12 bp) and, with ``--large``, of the nucleosome 1KX5 (147 bp). For each: wall and CPU time of
:func:`dnarod.structure.allatom.rebuild_allatom` (placement, hydrogens, two-stage restrained
minimisation, checks), per base pair, and the measured geometry (largest bond deviation from
Amber14, O3'-P range, closest non-bonded heavy atoms, frame errors).

Usage: ``python benchmarks/bench_rebuild.py [--large] [--json OUT]``. Prints a table and writes
JSON (default ``benchmarks/results/bench_rebuild.json``). The machine is shared: compare
figures from the same run only.
"""
from __future__ import annotations

import argparse
import json
import platform
import resource
import time
from pathlib import Path

import numpy as np

from dnarod.forcefield import load_forcefield
from dnarod.structure import model_from_structure
from dnarod.structure.allatom import rebuild_allatom

ROOT = Path(__file__).resolve().parents[1]


def _case(name, m, bp=None, seq2=None):
    c0 = resource.getrusage(resource.RUSAGE_SELF).ru_utime
    t0 = time.perf_counter()
    res = rebuild_allatom(m.frames, m.positions, m.sequence, bp, seq2)
    wall = time.perf_counter() - t0
    cpu = resource.getrusage(resource.RUSAGE_SELF).ru_utime - c0
    r = res.report
    return {"case": name, "n_bp": m.n_nodes, "atoms": res.topology.getNumAtoms(), "wall_s": wall, "cpu_s": cpu,
            "wall_per_bp_s": wall / m.n_nodes, "cpu_per_bp_s": cpu / m.n_nodes,
            "max_bond_dev_A": 10 * r.max_bond_deviation, "o3p_min_A": 10 * r.o3p_range[0],
            "o3p_max_A": 10 * r.o3p_range[1], "min_nonbonded_A": 10 * r.min_nonbonded,
            "frame_origin_err_A": 10 * r.frame_origin_error, "frame_angle_err_deg": r.frame_angle_error,
            "max_angle_dev_deg": r.max_angle_deviation, "energy_kJ_mol": r.energy}


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--large", action="store_true", help="Also the 147-bp nucleosome 1KX5.")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "results" / "bench_rebuild.json"))
    a = ap.parse_args()
    ff = load_forcefield("dna-default")
    rows = []
    for n in (12, 24):
        rows.append(_case(f"ideal {n} bp", ff.model_from_sequence(("GATCCGTAGCAT" * 2)[:n])))
    structures = ["355D"] + (["1KX5"] if a.large else [])
    for s in structures:
        m = model_from_structure(ROOT / "data" / "structures" / f"{s}.pdb")
        rows.append(_case(f"{s} crystal", m, np.array(m.metadata["bp_params"]), m.metadata["sequence2"]))
    cols = ("case", "n_bp", "atoms", "wall_s", "cpu_s", "wall_per_bp_s", "cpu_per_bp_s", "max_bond_dev_A",
            "o3p_min_A", "o3p_max_A", "min_nonbonded_A", "frame_origin_err_A", "frame_angle_err_deg",
            "max_angle_dev_deg")
    print(" | ".join(cols))
    for r in rows:
        print(" | ".join(f"{r[c]:.3f}" if isinstance(r[c], float) else str(r[c]) for c in cols))
    import openmm

    import os

    out = {"machine": platform.platform(), "python": platform.python_version(), "openmm": openmm.__version__,
           "load_average_at_end": os.getloadavg(), "rows": rows}
    Path(a.json).parent.mkdir(parents=True, exist_ok=True)
    Path(a.json).write_text(json.dumps(out, indent=1))
    print(f"wrote {a.json}")


if __name__ == "__main__":
    main()
