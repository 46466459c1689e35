"""Benchmark: all-atom rebuild with a closed Amber14 backbone, time per base pair against length.

Cases: the ideal intrinsic shape (dna-default) of 12 and 24 bp, the crystal nodes of 355D
(12 bp) and, with ``--large``, the nucleosome 1KX5 (147 bp, crystal nodes) and an ideal 300-bp
duplex. For each: wall and CPU time of :func:`dnarod.structure.allatom.rebuild_allatom`
(placement, hydrogens, the staged restrained minimisation, in overlapping windows past
``WINDOW_CORE + 2 * WINDOW_FLANK`` bp followed by a capped global polish, and the checks), per base
pair, whether the windows were used, the load average before and after, and the measured geometry
(largest bond deviation from Amber14, O3'-P range, closest non-bonded heavy atoms, frame errors).

Usage: ``python benchmarks/bench_rebuild.py [--large] [--cases ideal12,355D,...] [--keep DIR]
[--json OUT]``. Prints a table and writes JSON (default ``benchmarks/results/bench_rebuild.json``);
``--keep DIR`` also writes each rebuilt duplex as ``DIR/<case>.pdb`` (for
``bench_rebuild_md.py --pdb``). The machine is shared: compare figures from the same run only.
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import time
from pathlib import Path

import numpy as np

from dnarod.core.forcefield import load_forcefield
from dnarod.structure import model_from_structure
from dnarod.structure import allatom
from dnarod.structure.allatom import rebuild_allatom

ROOT = Path(__file__).resolve().parents[1]
SMALL = ("ideal12", "ideal24", "355D")
LARGE = ("1KX5", "ideal300")


def _model(case):
    if case.startswith("ideal"):
        n = int(case[5:])
        m = load_forcefield("dna-default").model_from_sequence(("GATCCGTAGCAT" * (n // 12 + 1))[:n])
        return f"ideal {n} bp", m, None, None
    m = model_from_structure(ROOT / "data" / "structures" / f"{case}.pdb")
    return f"{case} crystal", m, np.array(m.metadata["bp_params"]), m.metadata["sequence2"]


def _case(case, keep=None):
    name, m, bp, seq2 = _model(case)
    load0 = os.getloadavg()
    c0 = resource.getrusage(resource.RUSAGE_SELF).ru_utime
    t0 = time.perf_counter()
    res = rebuild_allatom(m.frames, m.positions, m.sequence, bp, seq2)
    wall = time.perf_counter() - t0
    cpu = resource.getrusage(resource.RUSAGE_SELF).ru_utime - c0
    r = res.report
    if keep:
        Path(keep).mkdir(parents=True, exist_ok=True)
        res.write(Path(keep) / f"{case}.pdb")
    row = {"case": name, "n_bp": m.n_nodes, "atoms": res.topology.getNumAtoms(),
           "windows": m.n_nodes > allatom.WINDOW_CORE + 2 * allatom.WINDOW_FLANK, "wall_s": wall, "cpu_s": cpu,
           "wall_per_bp_s": wall / m.n_nodes, "cpu_per_bp_s": cpu / m.n_nodes,
           "max_bond_dev_A": 10 * r.max_bond_deviation, "worst_bond": r.worst_bond,
           "o3p_min_A": 10 * r.o3p_range[0], "o3p_max_A": 10 * r.o3p_range[1],
           "placement_o3p_min_A": 10 * r.placement_o3p_range[0], "placement_o3p_max_A": 10 * r.placement_o3p_range[1],
           "min_nonbonded_A": 10 * r.min_nonbonded, "frame_origin_err_A": 10 * r.frame_origin_error,
           "frame_angle_err_deg": r.frame_angle_error, "max_angle_dev_deg": r.max_angle_deviation,
           "energy_kJ_mol": r.energy, "load_average_before": load0, "load_average_after": os.getloadavg()}
    print(json.dumps(row), flush=True)
    return row


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--large", action="store_true", help="Also the 147-bp nucleosome 1KX5 and an ideal 300 bp.")
    ap.add_argument("--cases", default=None, help=f"Comma-separated subset of {SMALL + LARGE} (ideal<N> for any N).")
    ap.add_argument("--keep", default=None, help="Directory for the rebuilt PDBs.")
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "results" / "bench_rebuild.json"))
    a = ap.parse_args()
    cases = a.cases.split(",") if a.cases else list(SMALL + (LARGE if a.large else ()))
    rows = [_case(c, a.keep) for c in cases]
    cols = ("case", "n_bp", "atoms", "windows", "wall_s", "cpu_s", "wall_per_bp_s", "cpu_per_bp_s", "max_bond_dev_A",
            "o3p_min_A", "o3p_max_A", "min_nonbonded_A", "frame_origin_err_A", "frame_angle_err_deg",
            "max_angle_dev_deg")
    print(" | ".join(cols))
    for r in rows:
        print(" | ".join(f"{r[c]:.3f}" if isinstance(r[c], float) else str(r[c]) for c in cols))
    import openmm

    out = {"machine": platform.platform(), "cpus": os.cpu_count(), "python": platform.python_version(),
           "openmm": openmm.__version__, "openmm_cpu_threads": os.environ.get("OPENMM_CPU_THREADS", "default"),
           "window_core_bp": allatom.WINDOW_CORE, "window_flank_bp": allatom.WINDOW_FLANK,
           "polish_iterations": allatom.POLISH_ITERATIONS, "rows": rows}
    Path(a.json).parent.mkdir(parents=True, exist_ok=True)
    Path(a.json).write_text(json.dumps(out, indent=1))
    print(f"wrote {a.json}")


if __name__ == "__main__":
    main()
