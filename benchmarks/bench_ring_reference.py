"""Benchmark: the ``plectonemes`` check's worm-like-ring reference with a hard core vs with the model's own pair
energy, and what the old diameter allowance measured.

For the quick check's ring (400 bp, ΔLk -1.923 at 300 K, 1500 samples) and with ``--full`` also the full check's
(600 bp, ΔLk -2.885, 4000 samples), at 0.15 M with the default (calibrated) non-bonded terms, A and C of
``dna-default``: the writhe fraction of :func:`dnarod.validate.wlc_ring_mc.sample_ring_writhe` with a hard core of
the effective diameter (5.00 nm) and of the WCA core alone (2.13 nm; the difference of the two was the check's
"diameter systematic" until round 6), with the soft pair energy (WCA + screened Coulomb, the check's reference now)
and with the WCA term alone, and the hard and soft rings with C halved; at 400 bp also the soft ring on 1.7-nm
segments. Prints the fractions with their standard errors (integrated autocorrelation time) and CPU / wall time
per reference, writes JSON.

Usage: ``python benchmarks/bench_ring_reference.py [--full] [--json OUT]``.
"""
from __future__ import annotations

import argparse
import time

import numpy as np

import _harness as H


def _fraction(r, dlk):
    from dnarod.analysis.polymer import integrated_autocorrelation_time

    wr = r["wr"]
    tau = max(float(integrated_autocorrelation_time(wr)), 0.5)
    return float(wr.mean() / dlk), float(wr.std(ddof=1) * np.sqrt(2 * tau / len(wr)) / abs(dlk)), tau


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--full", action="store_true", help="also the 600-bp ring of the full check (~3 min CPU)")
    ap.add_argument("--json", default=str(H.RESULTS / "bench_ring_reference.json"))
    args = ap.parse_args()
    from dnarod.physics.nonbonded import NonbondedSettings, member_nonbonded
    from dnarod.physics.theory.supercoil import effective_diameter, ring_constants
    from dnarod.validate.wlc_ring_mc import pair_parameters, sample_ring_writhe

    rows = []
    cases_of = [(400, -1.923, 1500)] + ([(600, -2.885, 4000)] if args.full else [])
    for n_bp, dlk, ns in cases_of:
        rc = ring_constants(n_bp, 300.0, 0.15)
        L, A, C, d = rc["L"], rc["A"], rc["C"], rc["d_eff"]
        nb = member_nonbonded(dict(excluded_volume=True, electrostatics=True, salt_M=0.15))
        wca = NonbondedSettings(salt=0.15, electrostatics=False)
        dw = effective_diameter(wca, 0.34, 300.0)
        soft, soft_wca = pair_parameters(nb, 0.34, 300.0, 3.4), pair_parameters(wca, 0.34, 300.0, 3.4)
        cases = [(f"hard core d_eff {d:.2f} nm", dict(diameter_nm=d)),
                 (f"hard core d_WCA {dw:.2f} nm", dict(diameter_nm=dw)),
                 ("soft, model pair energy", dict(diameter_nm=0.0, pair=soft)),
                 ("soft, WCA only", dict(diameter_nm=0.0, pair=soft_wca)),
                 ("soft, model pair energy, C/2", dict(diameter_nm=0.0, pair=soft, C_nm=C / 2)),
                 (f"hard core d_eff {d:.2f} nm, C/2", dict(diameter_nm=d, C_nm=C / 2))]
        if n_bp == 400:
            cases.append(("soft, model pair energy, 1.7-nm segments",
                          dict(diameter_nm=0.0, pair=pair_parameters(nb, 0.34, 300.0, 1.7), b_nm=1.7)))
        for label, kw in cases:
            kw = dict(dict(C_nm=C, b_nm=3.4), **kw)
            t0, c0 = time.perf_counter(), time.process_time()
            r = sample_ring_writhe(L, A, n_samples=ns, seed=5, delta_lk=dlk, equilibration_sweeps=300, **kw)
            f, se, tau = _fraction(r, dlk)
            row = dict(n_bp=n_bp, delta_lk=dlk, samples=ns, reference=label, writhe_fraction=f, standard_error=se,
                       tau_samples=tau, acceptance=r["acceptance"], cpu_s=time.process_time() - c0,
                       wall_s=time.perf_counter() - t0)
            rows.append(row)
            print(f"{n_bp:4d} bp  {label:44s} {f:.3f} ± {se:.3f}  CPU {row['cpu_s']:6.1f} s  "
                  f"wall {row['wall_s']:6.1f} s", flush=True)
    H.write_results(args.json, "bench_ring_reference", rows=rows,
                    note="first reference of a process includes numba compilation")


if __name__ == "__main__":
    main()
