"""Benchmark: the quick ``plectonemes`` ring with the calibrated non-bonded terms and with the terms before the
calibration, in one process.

Runs :func:`dnarod.validate.plectonemes.check_plectonemes` (quick form: 400 bp, ΔLk -2, 3 ns after five bending
relaxation times, seed 5, 0.15 M, 300 K) twice, each ring in a fresh folder: ``calibrated`` with the default
:class:`~dnarod.physics.nonbonded.NonbondedSettings` (Poisson-Boltzmann far-field charge calibrated to the 5.0 nm
effective diameter, cutoff 12 Debye lengths) and ``manning5`` with Manning's charge and a 5-Debye-length cutoff
(the defaults before the calibration; a settings subclass with those defaults replaces the class in
``dnarod.engines.openmm.nonbonded`` for that run, so every part of the check -- ring member and effective diameter --
sees them; the engine modules are imported first so that their own reference stays the real class, and a
settings object of the real class reaches the engine unchanged). Prints the writhe fractions of the
model and of its worm-like-ring reference, the plectoneme fraction and the ring member's CPU and wall time, and
writes JSON.

Usage: ``python benchmarks/bench_ring_charge.py [--json OUT]``.
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import tempfile
import time
from pathlib import Path

import _harness as H

KEYS = ("effective_diameter_nm", "model_writhe", "model_writhe_err", "model_writhe_fraction",
        "model_writhe_fraction_err", "model_plectoneme_fraction", "model_writhe_tau_ps", "reference_writhe_fraction",
        "reference_writhe_fraction_err", "tolerance", "passed", "model_wall_s", "model_cpu_s")


def run(mode, root):
    import dnarod.physics.nonbonded as nbm
    import dnarod.engines.openmm.simulation  # noqa: F401  (bind the real class in modules that import it at load time)
    import dnarod.engines.openmm.system  # noqa: F401
    from dnarod.validate import plectonemes
    from dnarod.physics.theory import supercoil as supercoil_theory

    real = nbm.NonbondedSettings
    if mode == "manning5":
        @dataclasses.dataclass
        class Legacy(real):
            charge: object = "manning"
            cutoff_debye: float = 5.0

        nbm.NonbondedSettings = Legacy
    try:
        supercoil_theory._DEFF_CACHE.clear()
        t, c = time.perf_counter(), time.process_time()
        r = plectonemes.check_plectonemes(root, quick=True, plots=False, member_root=Path(root) / mode)
        out = {k: r[k] for k in KEYS}
        out.update(check_wall_s=time.perf_counter() - t, check_cpu_s=time.process_time() - c,
                   load_average_end=os.getloadavg())
        return out
    finally:
        nbm.NonbondedSettings = real


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--json", default=str(H.RESULTS / "bench_ring_charge.json"))
    args = ap.parse_args()
    load = [os.getloadavg()]
    res = {}
    with tempfile.TemporaryDirectory(prefix="bench_ring_charge_") as root:
        for mode in ("manning5", "calibrated"):
            res[mode] = run(mode, root)
    load.append(os.getloadavg())
    print("quick plectonemes ring (400 bp, dLk -2, 3 ns, seed 5, 0.15 M, 300 K), one process")
    print(f"{'terms':>10} {'d_eff nm':>8} {'Wr/dLk':>15} {'reference':>15} {'plectoneme':>10} {'member CPU s':>12} "
          f"{'member wall s':>13}")
    for k, r in res.items():
        print(f"{k:>10} {r['effective_diameter_nm']:>8.3f} {r['model_writhe_fraction']:>8.3f} ± "
              f"{r['model_writhe_fraction_err']:.3f} {r['reference_writhe_fraction']:>8.3f} ± "
              f"{r['reference_writhe_fraction_err']:.3f} {r['model_plectoneme_fraction']:>10.3f} "
              f"{r['model_cpu_s']:>12.1f} {r['model_wall_s']:>13.1f}")
    H.write_results(args.json, "bench_ring_charge", load_average_start_end=load, runs=res,
                    cpu_ratio_calibrated_over_manning5=(res["calibrated"]["model_cpu_s"]
                                                        / res["manning5"]["model_cpu_s"]))


if __name__ == "__main__":
    main()
