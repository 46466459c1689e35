"""Benchmark: structures to base-pair frames and parameters.

1. The 147-bp nucleosome 1KX5 (13,607 atoms, protein and water): PDB file -> base frames ->
   pairs -> base-pair frames -> base-pair and step parameters (target < 1 s).
2. An all-atom trajectory of a 24-bp duplex, 1,000 frames, synthesised by rebuilding atoms
   from randomly perturbed base-pair frames and written as a DCD: step parameters of every
   frame, vectorised over frames (target < 10 s), with and without reading the DCD, and a
   frame-by-frame loop of the same computation for the ratio.

Usage: ``python benchmarks/bench_structure.py [--json OUT] [--frames N]``. Prints a table and
writes JSON (default ``benchmarks/results/bench_structure.json``).
"""
from __future__ import annotations

import argparse
import json
import platform
import tempfile
import time
import warnings
from pathlib import Path

import numpy as np

from dnarod.core.forcefield import load_forcefield
from dnarod.core.rotations import rotation_about_axis
from dnarod.structure.analysis import analyze_structure, step_parameters_over_frames
from dnarod.structure.trajectory import read_duplex_trajectory
from dnarod.structure.rebuild import rebuild_coordinates, write_pdb

ROOT = Path(__file__).resolve().parents[1]


def best_of(fn, repeats):
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t)
    return min(times), float(np.median(times)), out


def synthetic_trajectory(n_frames, n_bp=24, seed=0):
    """Atoms of a 24-bp duplex for n_frames perturbed copies of the dna-default intrinsic shape."""
    rng = np.random.default_rng(seed)
    seq = "".join(rng.choice(list("ACGT"), n_bp))
    m = load_forcefield("dna-default").model_from_sequence(seq)
    axes = rng.normal(size=(n_frames, n_bp, 3))
    R = rotation_about_axis(axes / np.linalg.norm(axes, axis=-1)[..., None],
                            np.radians(4.0) * rng.normal(size=(n_frames, n_bp)))
    F = R @ m.frames
    O = m.positions + 0.02 * rng.normal(size=(n_frames, n_bp, 3))
    X, atoms = rebuild_coordinates(F, O, seq)
    return X, atoms, F, O


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", default=str(ROOT / "benchmarks" / "results" / "bench_structure.json"))
    ap.add_argument("--frames", type=int, default=1000)
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    rows = []

    pdb = ROOT / "data" / "structures" / "1KX5.pdb"
    analyze_structure(pdb)  # warm caches (standard bases, residue names)
    tmin, tmed, ana = best_of(lambda: analyze_structure(pdb), args.repeats)
    rows.append(dict(case="1KX5 PDB -> frames, pairs, bp + step parameters", size=f"{ana.duplexes[0].n_bp} bp",
                     best_s=tmin, median_s=tmed, target_s=1.0))

    import MDAnalysis as mda

    # MDAnalysis warns about the (absent) unit cell of the DCD and a future reader change
    warnings.filterwarnings("ignore", message=".*(DCDReader|No dimensions).*")

    X, atoms, F, O = synthetic_trajectory(args.frames)
    with tempfile.TemporaryDirectory() as tmp:
        top, dcd = Path(tmp) / "top.pdb", Path(tmp) / "traj.dcd"
        write_pdb(top, X[0], atoms)
        u = mda.Universe(str(top))
        with mda.Writer(str(dcd), u.atoms.n_atoms) as w:
            for f in range(args.frames):
                u.atoms.positions = 10.0 * X[f]
                w.write(u.atoms)
        d = analyze_structure(top).duplexes[0]
        tmin, tmed, (sp, *_) = best_of(lambda: step_parameters_over_frames(d, X), args.repeats)
        rows.append(dict(case="24-bp trajectory: step parameters, vectorised (in memory)",
                         size=f"{args.frames} frames x {X.shape[1]} atoms", best_s=tmin, median_s=tmed, target_s=10.0))
        def read_all():
            r = read_duplex_trajectory(top, dcd)
            return r.duplex, r.step_params, r.pair_params

        tmin, tmed, (_, sp2, _) = best_of(read_all, max(1, args.repeats // 2))
        rows.append(dict(case="24-bp trajectory: read DCD + pair + step parameters",
                         size=f"{args.frames} frames", best_s=tmin, median_s=tmed, target_s=10.0))
        n_loop = min(args.frames, 100)
        tmin, tmed, _ = best_of(lambda: [step_parameters_over_frames(d, X[f:f + 1]) for f in range(n_loop)], 1)
        rows.append(dict(case=f"24-bp trajectory: frame-by-frame loop (scaled from {n_loop} frames)",
                         size=f"{args.frames} frames", best_s=tmin * args.frames / n_loop,
                         median_s=tmed * args.frames / n_loop, target_s=None))
    from dnarod.core.stepparams import step_parameters

    err = float(np.abs(sp - step_parameters(F[:, :-1], O[:, :-1], F[:, 1:], O[:, 1:])).max())
    err_dcd = float(np.abs(sp2 - sp).max())
    print(f"{'case':62s} {'size':>28s} {'best s':>9s} {'median s':>9s} {'target s':>9s}")
    for r in rows:
        tgt = "" if r["target_s"] is None else f"{r['target_s']:.1f}"
        print(f"{r['case']:62s} {r['size']:>28s} {r['best_s']:9.4f} {r['median_s']:9.4f} {tgt:>9s}")
    ratio = rows[3]["median_s"] / rows[1]["median_s"]
    print(f"vectorised vs frame-by-frame speed-up: {ratio:.0f}x")
    print(f"check: max |step params from atoms - from the frames| = {err:.2e} (in memory), "
          f"{err_dcd:.2e} (through float32 DCD) [nm, rad]")
    out = dict(benchmark="structure", python=platform.python_version(), machine=platform.machine(), rows=rows,
               speedup_vectorised=ratio, max_error_in_memory=err, max_error_dcd=err_dcd)
    Path(args.json).parent.mkdir(parents=True, exist_ok=True)
    from dnarod.core.io import write_text_atomic

    write_text_atomic(args.json, json.dumps(out, indent=2))
    print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
