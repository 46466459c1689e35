"""Monte Carlo engine on the 1-kbp magnetic-tweezers points: extension and torque with calibrated errors, and
their CPU cost.

Set-up (as the tweezers protocol, :func:`dnarod.protocols.tweezers.build_member`): ``dna-default``, 1000 bp, 1 pN,
300 K, default non-bonded terms at 0.15 M (WCA 2 nm + calibrated Debye-Hueckel, 12 Debye lengths), node 0 clamped
at the surface, the last node pulled along +z under the bead plane, rotation clamp (250 kJ/mol) on the last node
whose target carries the turns. Turns are given as Delta Lk counted from the torque-free state at 300 K:
``turns = dlk - (lk0 - Lk_T)`` with ``Lk_T`` the relaxed ribbon twist at T (:func:`dnarod.thermal.relaxed_ribbon_twist`).

Each point: MC from the protocol's start pose (the static equilibrium under the loads), sweeps until its CPU
budget is spent or both targets are met (relative extension error <= ``--target-ext``, torque error <=
``--target-torque`` pN nm), with the transient cut by :func:`dnarod.analysis.statistics.mean_and_error`. One
sample per sweep: extension ``z_last - z_0`` (nm; x/L with L = ds (n - 1)) and the rotation clamp's torque about z
(pN nm). Prints a table; writes ``benchmarks/results/bench_mc.json`` (or ``--json``). CPU seconds are the
process's own (one core: numba runs single-threaded here). MD figures for comparison are read from the earlier
replica-exchange run ``benchmarks/results/hat_1kbp_r12.json`` (a different run, labelled so).

    python benchmarks/bench_mc.py --dlk 0 2 3 4 --budget 75
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _harness import RESULTS, write_results  # noqa: E402


def thermal_offset(n_bp, temperature):
    from dnarod.core.forcefield import load_forcefield
    from dnarod.workflows.protocols.tweezers import intrinsic_turns
    from dnarod.thermal import relaxed_ribbon_twist

    model = load_forcefield("dna-default").model_from_sequence(n_nodes=n_bp)
    lk_t, se = relaxed_ribbon_twist(model, temperature)
    return intrinsic_turns(model) - lk_t, se


def run_point(n_bp, force_pN, turns, budget_cpu, seed, target_ext, target_torque, check_every=500, moves=None,
              eq_sweeps=500):
    from dnarod.analysis.statistics import mean_and_error
    from dnarod.engines.mc import MCEngine
    from dnarod.physics.loads import rotation_clamp_load
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.workflows.protocols.tweezers import build_member
    from dnarod.core.units import PN

    c0 = time.process_time()
    w0 = time.perf_counter()
    mb = build_member(dict(n_bp=n_bp, force_pN=force_pN, turns=turns))
    model = mb["model"]
    e = MCEngine(model, 300.0, loads=mb["loads"], nonbonded=member_nonbonded(mb["settings"]), seed=seed, moves=moves)
    L = model.ds * (model.n_nodes - 1)
    k_c = e.rc_k[-1]
    e.advance(eq_sweeps)
    ext, tq = [], []
    done = False
    est_x = est_t = None
    while not done:
        for _ in range(check_every):
            e.advance(1)
            ext.append(e.pos[-1, 2] - e.pos[0, 2])
            tq.append(rotation_clamp_load(e.frm[-1], e.rc_T[-1], k_c)[1][2] / PN)
        est_x = mean_and_error(np.asarray(ext) / L)
        est_t = mean_and_error(np.asarray(tq))
        spent = time.process_time() - c0
        met = (est_x.flag is None and est_t.flag is None and est_x.error <= target_ext * est_x.mean
               and est_t.error <= target_torque)
        done = met or spent >= budget_cpu
    return dict(turns=turns, sweeps=e.step, cpu_s=time.process_time() - c0, wall_s=time.perf_counter() - w0,
                x_over_L=est_x.mean, x_err=est_x.error, x_rel_err=est_x.error / est_x.mean, x_tau_sweeps=est_x.tau,
                x_n_eff=est_x.n_eff, x_flag=est_x.flag, x_t0=est_x.t0,
                torque_pN_nm=est_t.mean, torque_err=est_t.error, torque_tau_sweeps=est_t.tau,
                torque_n_eff=est_t.n_eff, torque_flag=est_t.flag, met_targets=bool(met),
                acceptance=e.acceptance(), amplitudes=e.amplitudes(), moves=e.moves,
                cpu_s_per_sweep=(time.process_time() - c0) / e.step)


def md_reference(turns_list):
    p = RESULTS / "hat_1kbp_r12.json"
    if not p.exists():
        return None
    d = json.loads(p.read_text())
    pts = {round(q["turns"], 2): q for q in d["points"]}
    out = {}
    for t in turns_list:
        near = min(pts, key=lambda x: abs(x - t))
        q = pts[near]
        out[t] = dict(md_turns=near, x_over_L=q["x_over_L"], err=q["err"], twist_torque_pN_nm=q["twist_torque_pN_nm"],
                      tau_int_extension_ns=q["tau_int_extension_ns"])
    return dict(source=str(p.relative_to(RESULTS.parents[1])), cpu_s_total=d["command"]["cpu_s"],
                rungs=len(d["points"]), target=d["target"], points=out)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-bp", type=int, default=1000)
    ap.add_argument("--force", type=float, default=1.0)
    ap.add_argument("--dlk", type=float, nargs="+", default=[0.0, 2.0, 3.0, 4.0])
    ap.add_argument("--budget", type=float, default=75.0, help="CPU seconds per point at most")
    ap.add_argument("--target-ext", type=float, default=0.01)
    ap.add_argument("--target-torque", type=float, default=0.3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--json", default=str(RESULTS / "bench_mc.json"))
    a = ap.parse_args(argv)
    off, off_se = thermal_offset(a.n_bp, 300.0)
    rows = []
    for dlk in a.dlk:
        turns = dlk - off
        r = run_point(a.n_bp, a.force, turns, a.budget, a.seed, a.target_ext, a.target_torque)
        r["delta_lk"] = dlk
        rows.append(r)
        print(f"dLk {dlk:+.1f} (turns {turns:+.3f}): x/L {r['x_over_L']:.4f} +- {r['x_err']:.4f} "
              f"({100 * r['x_rel_err']:.2f} %, tau {r['x_tau_sweeps']:.0f} sw, {r['x_flag']}), torque "
              f"{r['torque_pN_nm']:+.2f} +- {r['torque_err']:.2f} pN nm (tau {r['torque_tau_sweeps']:.1f} sw), "
              f"{r['sweeps']} sweeps, {r['cpu_s']:.1f} CPU-s, met={r['met_targets']}", flush=True)
    md = md_reference([r["turns"] for r in rows])
    print()
    print(f"{'dLk':>4} {'turns':>7} {'x/L':>8} {'err%':>6} {'tau_x':>6} {'torque':>8} {'err':>5} {'sweeps':>7} "
          f"{'CPU-s':>7} {'met':>4} | {'MD x/L (r12)':>12} {'MD err':>7}")
    for r in rows:
        m = md["points"][r["turns"]] if md else None
        print(f"{r['delta_lk']:4.1f} {r['turns']:7.3f} {r['x_over_L']:8.4f} {100 * r['x_rel_err']:6.2f} "
              f"{r['x_tau_sweeps']:6.0f} {r['torque_pN_nm']:8.2f} {r['torque_err']:5.2f} {r['sweeps']:7d} "
              f"{r['cpu_s']:7.1f} {str(r['met_targets']):>4} | "
              + (f"{m['x_over_L']:12.4f} {m['err']:7.4f} (turns {m['md_turns']:+.1f})" if m else ""))
    total = sum(r["cpu_s"] for r in rows)
    print(f"total CPU {total:.1f} s; targets +-{100 * a.target_ext:g} % extension, +-{a.target_torque:g} pN nm torque")
    write_results(a.json, "bench_mc", **dict(n_bp=a.n_bp, force_pN=a.force, temperature_K=300.0, thermal_offset_turns=off,
                            thermal_offset_se=off_se, budget_cpu_s_per_point=a.budget, targets=dict(
                                extension_rel=a.target_ext, torque_pN_nm=a.target_torque),
                            points=rows, total_cpu_s=total,
                            md_reference_earlier_run=md))


if __name__ == "__main__":
    main()
