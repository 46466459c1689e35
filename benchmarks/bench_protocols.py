"""Cost of tweezers protocol members: wall/CPU time per member, ns/day, measured autocorrelation times.

One magnetic-tweezers member (rotation clamp, 1 pN, 0 and +turns) per chain length, OpenMM CPU engine with
WCA + Debye-Hueckel, auto friction (critical damping of the slowest bending mode). Prints a table and writes
``benchmarks/results/protocols.json``. The cost of a 1 kbp hat curve is extrapolated from the measured ns/day
and the measured extension autocorrelation time (samples needed for +-3 % extension: see the printed model).

    python benchmarks/bench_protocols.py [--lengths 100,200,400] [--time-ns 1.0]
"""
from __future__ import annotations

import argparse
import json
import os
import platform
import tempfile
import time
from pathlib import Path

import numpy as np


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--lengths", default="100,200,400")
    ap.add_argument("--time-ns", type=float, default=1.0)
    ap.add_argument("--force", type=float, default=1.0)
    a = ap.parse_args()
    from dnarod.workflows.protocols.tweezers import run_member

    rows = []
    root = Path(tempfile.mkdtemp(prefix="bench_protocols_"))
    for n in [int(x) for x in a.lengths.split(",")]:
        for turns in (0.0, round(0.04 * n / 10.5, 2)):
            r = run_member(dict(n_bp=n, force_pN=a.force, turns=turns, time_ns=a.time_ns, seed=1),
                           root / f"{n}_{turns}")
            d = np.genfromtxt(root / f"{n}_{turns}" / "samples.csv", delimiter=",", names=True)
            sd = float(np.std(d["extension_nm"], ddof=1))
            tau = r["extension_nm_tau_ps"] or float("nan")
            # production needed for a +-3 % (1 SE) extension: N_eff = (sd / (0.03 <x>))^2, time = 2 tau N_eff
            need_ps = 2 * tau * (sd / (0.03 * r["extension_nm"])) ** 2
            rows.append(dict(n_bp=n, turns=turns, force_pN=a.force, wall_s=r["wall_s"], cpu_s=r["cpu_s"],
                             simulated_ns=r["n_steps"] * r["dt_ps"] / 1000, ns_per_day=r["ns_per_day"],
                             dt_ps=r["dt_ps"], friction_per_ps=r["friction_per_ps"],
                             tau_bend_estimate_ps=r["tau_bend_estimate_ps"], extension_tau_ps=tau,
                             torque_tau_ps=r["twist_torque_pN_nm_tau_ps"], extension_sd_nm=sd,
                             relative_extension=r["relative_extension"], production_for_3pct_ns=need_ps / 1000,
                             plectoneme_fraction=r["plectoneme_fraction"]))
            q = rows[-1]
            print(f"{n:5d} bp turns {turns:5.2f}: wall {q['wall_s']:6.1f} s cpu {q['cpu_s']:6.1f} s "
                  f"({q['simulated_ns']:.2f} ns, {q['ns_per_day']:.0f} ns/day), friction "
                  f"{q['friction_per_ps']:.2e}/ps, tau_ext {tau:.0f} ps (estimate tau_1 "
                  f"{q['tau_bend_estimate_ps']:.0f} ps), x/L {q['relative_extension']:.3f}, needs "
                  f"{q['production_for_3pct_ns']:.2f} ns for 3 %", flush=True)
    out = Path(__file__).resolve().parent / "results" / "protocols.json"
    out.parent.mkdir(exist_ok=True)
    doc = dict(host=platform.node(), cpus=os.cpu_count(), date=time.strftime("%Y-%m-%d %H:%M"), rows=rows,
               note="one member per row, sequential; machine shared (see cpu_s vs wall_s)")
    out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
