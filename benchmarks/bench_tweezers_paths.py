"""One tweezers member on the compiled plugin and on the callback path, one after the other (same settings, seed).

The walls are created with the simulation (``RodSimulation.create(extra_forces=...)``), so the member can use the
plugin. Prints wall and CPU time per path and writes ``benchmarks/results/tweezers_paths.json``.

    python benchmarks/bench_tweezers_paths.py [--n-bp 300] [--time 0.5]
"""
from __future__ import annotations

import argparse
import json
import os
import tempfile
import time
from pathlib import Path


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--n-bp", type=int, default=300)
    ap.add_argument("--time", type=float, default=0.5, help="ns of production (plus 0.1 ns equilibration)")
    ap.add_argument("--out", default="benchmarks/results/tweezers_paths.json")
    a = ap.parse_args(argv)
    from dnarod.workflows.protocols.tweezers import run_member

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for path in ("auto", "fast"):
            r = run_member(dict(n_bp=a.n_bp, force_pN=1.0, turns=0.5, time_ns=a.time, equilibration_ns=0.1,
                                elastic=path, seed=3), Path(tmp) / path)
            rows.append(dict(requested=path, elastic_path=r["elastic_path"], wall_s=r["wall_s"], cpu_s=r["cpu_s"],
                             ns_per_day=r["ns_per_day"], twist_torque_pN_nm=r["twist_torque_pN_nm"],
                             relative_extension=r["relative_extension"]))
    out = dict(date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), load_average=os.getloadavg(), n_bp=a.n_bp,
               production_ns=a.time, rows=rows, cpu_ratio_callback_over_plugin=rows[1]["cpu_s"] / rows[0]["cpu_s"])
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(out, indent=1) + "\n")
    for r in rows:
        print(f"{r['elastic_path']:8s} wall {r['wall_s']:7.1f} s  CPU {r['cpu_s']:7.1f} s  "
              f"{r['ns_per_day']:8.0f} ns/day")
    print(f"CPU ratio callback/plugin: {out['cpu_ratio_callback_over_plugin']:.1f} "
          f"(load average {out['load_average'][0]:.1f})")


if __name__ == "__main__":
    main()
