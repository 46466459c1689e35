"""What a 1-kbp replica-exchange replica costs per simulated ns on OpenMM's CPU platform (``Threads=1``, the
protocol's choice so far) and on the Reference platform, in the same process, with the exchange loop's own pattern:
rounds of ``advance`` (one exchange interval), the bead-rotation read (``follow``) and one trial energy.

Each platform runs the same members (1000 bp, 1 pN, WCA + Debye-Hueckel at 0.15 M, compiled plugin where built):
one straight (0 turns) and one plectonemic (+3.6 turns, grown for ``--grow-ns`` at 0.3 pN: a member at that force
whose final pose the +3.6-turn member starts from),
from the same pose and seed. Reported per platform and member: wall and CPU seconds (user and system apart) per
simulated ns, voluntary and involuntary context switches per round, and the potential energy of the start pose on
both platforms (they must agree: the same System). The CPU platform runs its integrator on a worker thread even
with ``Threads=1`` and hands every step between threads; the Reference platform runs in the calling thread.
Prints a table and writes ``benchmarks/results/exchange_platform.json``.

    python benchmarks/bench_exchange_platform.py [--rounds 150] [--grow-ns 5] [--repeats 2]
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import time
from pathlib import Path


def _usage():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return dict(user=r.ru_utime, sys=r.ru_stime, vcs=r.ru_nvcsw, ivcs=r.ru_nivcsw, wall=time.perf_counter())


def _measure(member, platform, rounds, dt, exchange_ps):
    from dnarod.workflows.protocols.exchange import _Replica, ladder_dt  # noqa: F401 - the loop's own replica

    m = {**member, "settings": {**member["settings"], "platform": platform,
                                "threads": 1 if platform == "CPU" else None}}
    rung = dict(turns=m["turns"], ref_frame=m["ref_frame"], clamp_target=m["clamp_target"])
    rep = _Replica(0, 0, m, [rung, rung], dt)
    e0 = rep._potential()
    n = max(1, int(round(exchange_ps / rep.sim.dt)))
    rep.sim.advance(n)  # warm-up (kernels compiled, first neighbour list)
    u0 = _usage()
    for _ in range(rounds):
        rep.sim.advance(n)
        rep.follow()
        rep.trial(1)
    u1 = _usage()
    ns = rounds * n * rep.sim.dt / 1000.0
    d = {k: u1[k] - u0[k] for k in u0}
    return dict(platform=platform, platform_used=rep.sim.context.getPlatform().getName(),
                elastic_path=rep.sim.rs.elastic, start_energy_kJ_mol=e0, dt_ps=rep.sim.dt, steps_per_round=n,
                simulated_ns=ns, wall_s_per_ns=d["wall"] / ns, cpu_s_per_ns=(d["user"] + d["sys"]) / ns,
                user_s_per_ns=d["user"] / ns, sys_s_per_ns=d["sys"] / ns, voluntary_cs_per_round=d["vcs"] / rounds,
                involuntary_cs_per_round=d["ivcs"] / rounds)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-bp", type=int, default=1000)
    ap.add_argument("--rounds", type=int, default=150, help="exchange rounds per measurement")
    ap.add_argument("--exchange-ps", type=float, default=20.0)
    ap.add_argument("--grow-ns", type=float, default=5.0, help="ns at 0.3 pN to grow the +3.6-turn plectoneme")
    ap.add_argument("--repeats", type=int, default=2, help="alternating CPU/Reference measurements per member")
    ap.add_argument("--out", default="benchmarks/results/exchange_platform.json")
    a = ap.parse_args(argv)
    import tempfile

    from dnarod.workflows.protocols.exchange import ladder_dt
    from dnarod.workflows.protocols.poses import FINAL_POSE, load_pose
    from dnarod.workflows.protocols.tweezers import build_member, run_member

    base = dict(n_bp=a.n_bp, force_pN=1.0, time_ns=1.0, equilibration_ns=0.0, seed=7)
    members = {"straight 0 turns": build_member({**base, "turns": 0.0})}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:  # the plectoneme grown at 0.3 pN (same turns), then its pose
        run_member({**base, "turns": 3.6, "force_pN": 0.3, "equilibration_ns": a.grow_ns, "time_ns": 0.001}, tmp)
        pose = load_pose(Path(tmp) / FINAL_POSE)
    members["plectoneme +3.6 turns"] = build_member({**base, "turns": 3.6, "previous_turns": 3.6}, start_pose=pose)
    grow_s = time.perf_counter() - t0
    dt = ladder_dt(list(members.values()))
    rows = []
    for name, m in members.items():
        for rep in range(a.repeats):
            for platform in ("CPU", "Reference"):
                r = _measure(m, platform, a.rounds, dt, a.exchange_ps)
                r.update(member=name, repeat=rep)
                rows.append(r)
                print(f"{name:22s} {platform:9s} ({r['elastic_path']:6s}) wall {r['wall_s_per_ns']:6.2f} s/ns  "
                      f"CPU {r['cpu_s_per_ns']:6.2f} s/ns (sys {r['sys_s_per_ns']:5.2f})  "
                      f"cs/round {r['voluntary_cs_per_round']:8.0f} + {r['involuntary_cs_per_round']:5.0f}  "
                      f"E0 {r['start_energy_kJ_mol']:.6f}", flush=True)
    ratios = {}
    for name in members:
        cpu = [r["cpu_s_per_ns"] for r in rows if r["member"] == name and r["platform"] == "CPU"]
        ref = [r["cpu_s_per_ns"] for r in rows if r["member"] == name and r["platform"] == "Reference"]
        wc = [r["wall_s_per_ns"] for r in rows if r["member"] == name and r["platform"] == "CPU"]
        wr = [r["wall_s_per_ns"] for r in rows if r["member"] == name and r["platform"] == "Reference"]
        ratios[name] = dict(cpu_over_reference_cpu_s=sum(cpu) / sum(ref), cpu_over_reference_wall_s=sum(wc) / sum(wr))
        print(f"{name:22s} CPU-platform / Reference: CPU time {ratios[name]['cpu_over_reference_cpu_s']:.2f}x, "
              f"wall {ratios[name]['cpu_over_reference_wall_s']:.2f}x")
    out = dict(date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), load_average=os.getloadavg(), n_bp=a.n_bp,
               rounds=a.rounds, exchange_ps=a.exchange_ps, grow_ns=a.grow_ns, grow_wall_s=grow_s, rows=rows,
               ratios=ratios)
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(a.out).with_suffix(".json.tmp")
    tmp.write_text(json.dumps(out, indent=1) + "\n")
    os.replace(tmp, a.out)


if __name__ == "__main__":
    main()
