"""Monte Carlo engine on the 1-kbp magnetic-tweezers points: extension and torque with calibrated errors, and
their CPU cost, beside the MD engine's cost for the same errors.

Set-up (as the tweezers protocol, :func:`dnarod.workflows.protocols.tweezers.build_member`): ``dna-default``,
1000 bp, 1 pN, 300 K, default non-bonded terms at 0.15 M, node 0 clamped at the surface, the last node pulled
along +z under the bead plane (walls), rotation clamp (250 kJ/mol) on the last node whose target carries the turns.
Turns are Delta Lk counted from the torque-free state at 300 K, as the protocol counts them; the 0 K offset
(:func:`dnarod.physics.loads.torque_free_offset`) is reported beside them (``turns_0K = dlk + offset``).

Each point: one :class:`~dnarod.engines.mc.MCEngine`, the first from the protocol's start pose (the static
equilibrium under the loads), each next one from the previous point's final pose with the turn difference added as
twist spread along the chain (a turn sweep; points are run in ``--order``, so that the point at the buckling
transition starts from a plectoneme). Sweeps until both targets are met (relative extension error <=
``--target-ext``, torque error <= ``--target-torque`` pN nm, neither series flagged short) or the point's CPU budget
is spent. One sample per sweep: the extension ``z_last - z_0`` (x/L with L = ds (n - 1)) and the tail-torque
estimate of the clamp torque (:meth:`MCEngine.tail_torque_z`, height-weighted); means and errors from
:func:`dnarod.analysis.statistics.mean_and_error` (transient cut, autocorrelation time, ``short`` flag). CPU seconds
are the process's own (numba runs single-threaded), equilibration included.

``--ladder LO HI STEP``: the points with Delta Lk in [LO, HI] are sampled together by one replica-exchange ladder
(:class:`dnarod.engines.mc.ladder.TurnLadder`) with rungs ``LO, LO + STEP, .., HI`` (which must hold them), after
the other points, from a plectoneme (1000 sweeps of one engine at HI from the last point's final pose; the
straight, overwound chain is metastable there), its pose turned to every rung: a sweep of every rung and
a swap attempt of neighbours (alternating parity) per round, a sample of the requested rungs per round, until every
requested rung meets both targets or ``--ladder-budget`` CPU seconds are spent. Past buckling the plectoneme's size
relaxes slowly within one chain, but configurations pass between rungs whose turns suit them. The ladder's CPU
seconds are those of all its rungs, counted once in the total.

    nice -n 10 python benchmarks/bench_mc.py --dlk 0 2 4 3 --budget 300 --ladder 2.6 4.2 0.2

MD cost for the same errors: the extension's spread and integrated autocorrelation time of the nearest rung of the
earlier replica-exchange MD run ``research/hat_curve/results/hat_1kbp_r12.json`` (labelled as such: not this run), with
the MD engine's speed (CPU-s per simulated ns of one 1-kbp member) measured in this run (``--md-seconds``, 0 to
skip), give ``2 tau (sd / target)^2`` ns and their CPU cost.

    nice -n 10 python benchmarks/bench_mc.py --dlk 0 2 4 3 --budget 300

``--hat`` runs the 26 rungs of the 1-kbp hat curve of the hat-curve study (the turns of ``hat_1kbp_r12.json``,
counted there from the intrinsic twist, here converted to turns from the torque-free state) as one
replica-exchange ladder (:class:`dnarod.engines.mc.ladder.TurnLadder`) for
``--hat-budget`` CPU seconds in all, from the protocol's start poses: a sweep of every rung per round, a sample of
every rung per round, swaps of neighbours every ``--exchange-every`` rounds; writes
``benchmarks/results/bench_mc_hat.json`` with each rung's x/L and torque, their errors and flags.

    nice -n 10 python benchmarks/bench_mc.py --hat --hat-budget 1800
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

N_BP = 1000
HAT_R12 = Path(__file__).resolve().parents[1] / "research" / "hat_curve" / "results" / "hat_1kbp_r12.json"


def thermal_offset(n_bp, temperature):
    """Turns from the 0 K intrinsic twist to the torque-free state at ``temperature`` (negative for DNA)."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.physics.loads import torque_free_offset

    return torque_free_offset(load_forcefield("dna-default").model_from_sequence(n_nodes=n_bp), temperature)


def run_point(n_bp, force_pN, turns, budget_cpu, seed, target_ext, target_torque, start_pose=None, prev_turns=None,
              check_every=100, min_sweeps=300):
    from dnarod.analysis.statistics import mean_and_error
    from dnarod.core.units import PN
    from dnarod.engines.mc import MCEngine
    from dnarod.engines.mc.ladder import twist_ramp
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.workflows.protocols.tweezers import build_member

    c0 = time.process_time()
    w0 = time.perf_counter()
    mb = build_member(dict(n_bp=n_bp, force_pN=force_pN, turns=turns))
    model = mb["model"]
    if start_pose is not None:
        model = model.with_pose(start_pose[0], twist_ramp(start_pose[1], turns - prev_turns))
    e = MCEngine(model, 300.0, loads=mb["loads"], nonbonded=member_nonbonded(mb["settings"]), seed=seed)
    L = model.ds * (model.n_nodes - 1)
    ext, tq = [], []
    met = False
    est_x = est_t = None
    while True:
        for _ in range(check_every):
            e.advance(1)
            ext.append((e.pos[-1, 2] - e.pos[0, 2]) / L)
            tq.append(e.tail_torque_z(weighted=True) / PN)
        if len(ext) >= min_sweeps:
            est_x, est_t = mean_and_error(ext), mean_and_error(tq)
            met = (est_x.flag is None and est_t.flag is None and est_x.error <= target_ext * est_x.mean
                   and est_t.error <= target_torque)
        if met or time.process_time() - c0 >= budget_cpu:
            break
    if est_x is None:
        est_x, est_t = mean_and_error(ext), mean_and_error(tq)
    cpu = time.process_time() - c0
    return dict(turns=turns, sweeps=e.step, cpu_s=cpu, wall_s=time.perf_counter() - w0, x_over_L=est_x.mean,
                x_err=est_x.error, x_rel_err=est_x.error / est_x.mean, x_tau_sweeps=est_x.tau, x_n_eff=est_x.n_eff,
                x_flag=est_x.flag, x_transient_sweeps=est_x.t0, x_sd=float(np.std(ext[est_x.t0:])),
                torque_pN_nm=est_t.mean, torque_err=est_t.error, torque_tau_sweeps=est_t.tau,
                torque_n_eff=est_t.n_eff, torque_flag=est_t.flag, torque_transient_sweeps=est_t.t0,
                met_targets=bool(met), acceptance=e.acceptance(), cpu_ms_per_sweep=1e3 * cpu / e.step,
                x_quarters=[float(np.mean(q)) for q in np.array_split(ext[est_x.t0:], 4)],
                torque_estimator="tail-rotation identity, height weights (MCEngine.tail_torque_z)"), e.node_pose()


def run_ladder(n_bp, force_pN, rungs, points, budget_cpu, seed, target_ext, target_torque, start_pose, prev_turns,
               start_sweeps=1000, check_every=100, min_rounds=500):
    """One turn ladder (module docstring) sampling ``points`` (turns, each one of ``rungs``); returns rows.

    The rungs start from a plectoneme: ``start_sweeps`` sweeps of one engine at the top rung from ``start_pose``
    (the straight, overwound chain is metastable there and buckles within a few hundred sweeps), its final pose
    then turned to every rung. Started straight, the ladder stays in the metastable straight branch for longer
    than its error bars can tell (measured: x/L 0.80 and 18 pN nm at Delta Lk 3 after 1000 rounds)."""
    from dnarod.analysis.statistics import mean_and_error
    from dnarod.core.units import PN
    from dnarod.engines.mc import MCEngine
    from dnarod.engines.mc.ladder import TurnLadder, twist_ramp
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.workflows.protocols.tweezers import build_member

    c0 = time.process_time()
    w0 = time.perf_counter()
    idx = [int(np.argmin(np.abs(rungs - t))) for t in points]
    if any(abs(rungs[i] - t) > 1e-9 for i, t in zip(idx, points)):
        raise SystemExit(f"ladder rungs {rungs.tolist()} do not hold the points {points}")
    top = float(rungs[-1])
    mb = build_member(dict(n_bp=n_bp, force_pN=force_pN, turns=top))
    model = mb["model"]
    if start_pose is not None:
        model = model.with_pose(start_pose[0], twist_ramp(start_pose[1], top - prev_turns))
    e = MCEngine(model, 300.0, loads=mb["loads"], nonbonded=member_nonbonded(mb["settings"]), seed=seed)
    e.advance(start_sweeps)
    start_pose, prev_turns = e.node_pose(), top
    engines = []
    for i, t in enumerate(rungs):
        mb = build_member(dict(n_bp=n_bp, force_pN=force_pN, turns=float(t)))
        model = mb["model"].with_pose(start_pose[0], twist_ramp(start_pose[1], float(t) - prev_turns))
        engines.append(MCEngine(model, 300.0, loads=mb["loads"], nonbonded=member_nonbonded(mb["settings"]),
                                seed=seed + 17 * (i + 1)))
    lad = TurnLadder(engines, rungs, seed=seed)
    L = engines[0].model.ds * (n_bp - 1)
    ext = {i: [] for i in idx}
    tq = {i: [] for i in idx}
    rounds = 0
    met = False
    est = {}
    while True:
        for _ in range(check_every):
            lad.advance(1)
            lad.exchange()
            rounds += 1
            for i in idx:
                e = engines[i]
                ext[i].append((e.pos[-1, 2] - e.pos[0, 2]) / L)
                tq[i].append(e.tail_torque_z(weighted=True) / PN)
        if rounds >= min_rounds:
            est = {i: (mean_and_error(ext[i]), mean_and_error(tq[i])) for i in idx}
            met = all(ex.flag is None and et.flag is None and ex.error <= target_ext * ex.mean
                      and et.error <= target_torque for ex, et in est.values())
        if met or time.process_time() - c0 >= budget_cpu:
            break
    if not est:
        est = {i: (mean_and_error(ext[i]), mean_and_error(tq[i])) for i in idx}
    cpu = time.process_time() - c0
    rows = []
    for i, t in zip(idx, points):
        ex, et = est[i]
        e = engines[i]
        rows.append(dict(turns=float(t), sweeps=rounds, cpu_s=cpu, wall_s=time.perf_counter() - w0,
                         x_over_L=ex.mean, x_err=ex.error, x_rel_err=ex.error / ex.mean, x_tau_sweeps=ex.tau,
                         x_n_eff=ex.n_eff, x_flag=ex.flag, x_transient_sweeps=ex.t0,
                         x_sd=float(np.std(ext[i][ex.t0:])), torque_pN_nm=et.mean, torque_err=et.error,
                         torque_tau_sweeps=et.tau, torque_n_eff=et.n_eff, torque_flag=et.flag,
                         torque_transient_sweeps=et.t0, met_targets=bool(met), acceptance=e.acceptance(),
                         cpu_ms_per_sweep=1e3 * cpu / (rounds * len(rungs)),
                         x_quarters=[float(np.mean(q)) for q in np.array_split(ext[i][ex.t0:], 4)],
                         torque_estimator="tail-rotation identity, height weights (MCEngine.tail_torque_z)",
                         ladder=dict(rungs=rungs.tolist(), rounds=rounds, cpu_s_all_rungs=cpu,
                                     swap_acceptance=lad.acceptance().tolist(),
                                     note="sweeps = rounds (one sweep of every rung each); cpu_s is the whole "
                                          "ladder's, shared by its points")))
    return rows


def md_speed(seconds, seed=1):
    """CPU seconds per simulated ns of one 1-kbp tweezers member with the MD engine (measured here), or None."""
    if not seconds:
        return None
    from dnarod.workflows.protocols.tweezers import _member_simulation, build_member

    mb = build_member(dict(n_bp=N_BP, force_pN=1.0, turns=0.0, seed=seed))
    sim = _member_simulation(mb, mb["model"])
    sim.advance(200)
    c0 = time.process_time()
    steps = 0
    while time.process_time() - c0 < seconds:
        sim.advance(500)
        steps += 500
    cpu = time.process_time() - c0
    return dict(cpu_s_per_ns=cpu / (steps * sim.dt * 1e-3), dt_ps=sim.dt, steps=steps, cpu_s=cpu,
                platform=sim.platform_name, elastic_path=sim.rs.elastic)


def md_reference(turns_0k, target_ext, speed):
    """MD cost for the extension target at the rung of hat_1kbp_r12.json nearest each point (an earlier run)."""
    p = HAT_R12
    if not p.exists():
        return None
    d = json.loads(p.read_text())
    ns_per_rung = d["ladder"]["simulated_ns_per_rung"]
    pts = {round(q["turns"], 2): q for q in d["points"]}
    out = {}
    for t in turns_0k:
        near = min(pts, key=lambda x: abs(x - t))
        q = pts[near]
        tau = q["tau_int_extension_ns"]
        n_eff = ns_per_rung / (2.0 * tau)
        sd = q["se_tau"] * np.sqrt(n_eff)  # spread of x/L recovered from the tau-based error
        need_ns = 2.0 * tau * (sd / (target_ext * q["x_over_L"])) ** 2
        out[f"{t:+.3f}"] = dict(md_rung_turns=near, x_over_L=q["x_over_L"], err=q["err"], tau_int_ns=tau, sd=sd,
                               ns_for_target=need_ns,
                               cpu_s_for_target=need_ns * speed["cpu_s_per_ns"] if speed else None)
    return dict(source=str(p.relative_to(RESULTS.parents[1])), note="spread and autocorrelation time from an "
                "earlier MD run (replica exchange along the turns, 26 rungs); MD speed measured in this run",
                ns_per_rung=ns_per_rung, points=out)


def run_hat(budget_cpu, exchange_every, seed, force_pN=1.0, n_bp=N_BP):
    """The 26-rung ladder of the hat-curve study (module docstring); returns (rows, ladder info)."""
    from dnarod.analysis.statistics import mean_and_error
    from dnarod.core.units import PN
    from dnarod.engines.mc import MCEngine
    from dnarod.engines.mc.ladder import TurnLadder
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.workflows.protocols.tweezers import build_member

    c0 = time.process_time()
    turns = json.loads(HAT_R12.read_text())["ladder"]["rungs"]  # from the 0 K intrinsic twist
    offset = thermal_offset(n_bp, 300.0)
    engines = []
    for i, t in enumerate(turns):
        mb = build_member(dict(n_bp=n_bp, force_pN=force_pN, turns=t - offset))
        engines.append(MCEngine(mb["model"], 300.0, loads=mb["loads"], nonbonded=member_nonbonded(mb["settings"]),
                                seed=seed + i))
    lad = TurnLadder(engines, turns, seed=seed)
    L = engines[0].model.ds * (n_bp - 1)
    ext = [[] for _ in turns]
    tq = [[] for _ in turns]
    rounds = 0
    while time.process_time() - c0 < budget_cpu:
        lad.advance(1)
        rounds += 1
        for i, e in enumerate(engines):
            ext[i].append((e.pos[-1, 2] - e.pos[0, 2]) / L)
            tq[i].append(e.tail_torque_z() / PN)
        if rounds % exchange_every == 0:
            lad.exchange()
    rows = []
    for i, t in enumerate(turns):
        ex, et = mean_and_error(ext[i]), mean_and_error(tq[i])
        rows.append(dict(turns=t - offset, turns_0K=t, x_over_L=ex.mean, x_err=ex.error, x_rel_err=ex.error / ex.mean,
                         x_tau_sweeps=ex.tau,
                         x_n_eff=ex.n_eff, x_flag=ex.flag, x_transient_sweeps=ex.t0, torque_pN_nm=et.mean,
                         torque_err=et.error, torque_tau_sweeps=et.tau, torque_flag=et.flag,
                         acceptance=engines[i].acceptance()))
    info = dict(rounds=rounds, cpu_s=time.process_time() - c0, exchange_every=exchange_every,
                swap_acceptance=lad.acceptance().tolist(), labels=lad.labels.tolist(),
                cpu_ms_per_sweep=[1e3 * (time.process_time() - c0) / rounds / len(turns)])
    return rows, info


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-bp", type=int, default=N_BP)
    ap.add_argument("--force", type=float, default=1.0)
    ap.add_argument("--dlk", type=float, nargs="+", default=[0.0, 2.0, 4.0, 3.0],
                    help="Delta Lk from the torque-free state, in the order they are run (a turn sweep)")
    ap.add_argument("--budget", type=float, default=300.0, help="CPU seconds per point at most")
    ap.add_argument("--target-ext", type=float, default=0.01)
    ap.add_argument("--target-torque", type=float, default=0.3)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--md-seconds", type=float, default=30.0, help="CPU seconds of MD to measure its speed (0: skip)")
    ap.add_argument("--json", default=str(RESULTS / "bench_mc.json"))
    ap.add_argument("--hat", action="store_true", help="run the 26-rung hat-curve ladder instead")
    ap.add_argument("--hat-budget", type=float, default=1800.0, help="CPU seconds for the whole ladder")
    ap.add_argument("--exchange-every", type=int, default=5)
    ap.add_argument("--ladder", type=float, nargs=3, metavar=("LO", "HI", "STEP"), default=None,
                    help="sample the points with Delta Lk in [LO, HI] by one turn ladder with these rungs")
    ap.add_argument("--ladder-budget", type=float, default=None,
                    help="CPU seconds for the ladder (default: --budget times its points)")
    a = ap.parse_args(argv)
    c_all = time.process_time()
    if a.hat:
        rows, info = run_hat(a.hat_budget, a.exchange_every, a.seed, a.force, a.n_bp)
        print(f"{'turns':>6} {'x/L':>8} {'err%':>6} {'tau':>5} {'flag':>6} {'torque':>8} {'err':>5}")
        for r in rows:
            print(f"{r['turns']:6.2f} {r['x_over_L']:8.4f} {100 * r['x_rel_err']:6.2f} {r['x_tau_sweeps']:5.0f} "
                  f"{str(r['x_flag']):>6} {r['torque_pN_nm']:8.2f} {r['torque_err']:5.2f}")
        print(f"{info['rounds']} rounds, {info['cpu_s']:.0f} CPU-s; swap acceptance "
              + " ".join(f"{x:.2f}" for x in info["swap_acceptance"]))
        write_results(a.json.replace("bench_mc.json", "bench_mc_hat.json"), "bench_mc_hat", n_bp=a.n_bp,
                      force_pN=a.force, rungs=rows,
                      turns_counted_from="the torque-free state at 300 K (turns_0K: from the intrinsic twist, as "
                                         "hat_1kbp_r12.json)",
                      ladder=info, command_cpu_s=time.process_time() - c_all)
        return
    off = thermal_offset(a.n_bp, 300.0)
    print(f"torque-free state at 300 K: {off:+.4f} turns from the intrinsic twist", flush=True)
    rows, pose, prev = [], None, None
    lad_pts = [d for d in a.dlk if a.ladder and a.ladder[0] - 1e-9 <= d <= a.ladder[1] + 1e-9]
    for dlk in a.dlk:
        if dlk in lad_pts:
            continue
        turns = dlk  # the protocol counts turns from the torque-free state
        r, pose_new = run_point(a.n_bp, a.force, turns, a.budget, a.seed, a.target_ext, a.target_torque, pose, prev)
        pose, prev = pose_new, turns
        r["delta_lk"] = dlk
        r["turns_0K"] = dlk + off
        rows.append(r)
        print(f"dLk {dlk:+.1f} (turns {turns:+.3f}): x/L {r['x_over_L']:.4f} +- {r['x_err']:.4f} "
              f"({100 * r['x_rel_err']:.2f} %, tau {r['x_tau_sweeps']:.0f} sweeps, {r['x_flag']}), torque "
              f"{r['torque_pN_nm']:+.2f} +- {r['torque_err']:.2f} pN nm (tau {r['torque_tau_sweeps']:.1f}), "
              f"{r['sweeps']} sweeps, {r['cpu_s']:.1f} CPU-s, met={r['met_targets']}", flush=True)
    ladder_cpu = 0.0
    if lad_pts:
        lo, hi, st = a.ladder
        rungs = np.round(lo + st * np.arange(int(round((hi - lo) / st)) + 1), 9)
        budget = a.ladder_budget if a.ladder_budget is not None else a.budget * len(lad_pts)
        lrows = run_ladder(a.n_bp, a.force, rungs, lad_pts, budget, a.seed, a.target_ext, a.target_torque, pose, prev)
        ladder_cpu = lrows[0]["cpu_s"]
        for r in lrows:
            r["delta_lk"] = r["turns"]
            r["turns_0K"] = r["turns"] + off
            rows.append(r)
            print(f"dLk {r['delta_lk']:+.1f} (ladder of {len(rungs)} rungs): x/L {r['x_over_L']:.4f} +- "
                  f"{r['x_err']:.4f} ({100 * r['x_rel_err']:.2f} %, tau {r['x_tau_sweeps']:.0f} rounds, "
                  f"{r['x_flag']}), torque {r['torque_pN_nm']:+.2f} +- {r['torque_err']:.2f} pN nm (tau "
                  f"{r['torque_tau_sweeps']:.1f}), {r['sweeps']} rounds, {r['cpu_s']:.1f} CPU-s (whole ladder), "
                  f"met={r['met_targets']}", flush=True)
    speed = md_speed(a.md_seconds)
    md = md_reference([r["turns_0K"] for r in rows], a.target_ext, speed)
    print()
    print(f"{'dLk':>4} {'turns':>7} {'x/L':>8} {'err%':>6} {'tau_x':>6} {'torque':>8} {'err':>5} {'sweeps':>7} "
          f"{'CPU-s':>7} {'met':>5} | {'MD rung':>7} {'MD x/L':>7} {'MD CPU-s for target':>20}")
    for r in rows:
        m = md["points"][f"{r['turns_0K']:+.3f}"] if md else None
        md_cost = f"{m['cpu_s_for_target']:20.0f}" if m and m["cpu_s_for_target"] else f"{'-':>20}"
        print(f"{r['delta_lk']:4.1f} {r['turns']:7.3f} {r['x_over_L']:8.4f} {100 * r['x_rel_err']:6.2f} "
              f"{r['x_tau_sweeps']:6.0f} {r['torque_pN_nm']:8.2f} {r['torque_err']:5.2f} {r['sweeps']:7d} "
              f"{r['cpu_s']:7.1f} {str(r['met_targets']):>5} | "
              + (f"{m['md_rung_turns']:+7.1f} {m['x_over_L']:7.4f} {md_cost}" if m else ""))
    total = sum(r["cpu_s"] for r in rows if "ladder" not in r) + ladder_cpu
    print(f"MC total {total:.1f} CPU-s for {len(rows)} points; targets +-{100 * a.target_ext:g} % extension, "
          f"+-{a.target_torque:g} pN nm torque"
          + (f"; MD speed {speed['cpu_s_per_ns']:.1f} CPU-s/ns ({speed['platform']}, {speed['elastic_path']})"
             if speed else ""))
    write_results(a.json, "bench_mc", n_bp=a.n_bp, force_pN=a.force, temperature_K=300.0,
                  turns_offset_0K=off, budget_cpu_s_per_point=a.budget,
                  targets=dict(extension_rel=a.target_ext, torque_pN_nm=a.target_torque), points=rows,
                  ladder=(dict(rungs_lo_hi_step=a.ladder, points=lad_pts) if lad_pts else None),
                  total_mc_cpu_s=total, md_speed_this_run=speed, md_reference_earlier_run=md,
                  command_cpu_s=time.process_time() - c_all)


if __name__ == "__main__":
    main()
