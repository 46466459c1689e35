"""Plain against height-weighted tail-torque averages on the same run (one engine from a buckled pose, or the
300-bp, 1 pN, 1.5-turn chain from its start): means, errors, autocorrelation times; and the clamp's own torque.
Usage: torque_pair.py 4 BUDGET_CPU_S SEED   or   torque_pair.py 300bp N_SWEEPS SEED"""
import sys
import time

import numpy as np

from common import engine
from dnarod.analysis.statistics import mean_and_error
from dnarod.core.units import PN

what, amount, seed = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
if what == "300bp":
    from dnarod.engines.mc import MCEngine
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.workflows.protocols.tweezers import build_member

    mb = build_member(dict(n_bp=300, force_pN=1.0, turns=1.5))
    e = MCEngine(mb["model"], 300.0, loads=mb["loads"], nonbonded=member_nonbonded(mb["settings"]), seed=seed)
    e.advance(4000)
else:
    lk = float(what)
    p = np.load(f"pose{int(lk)}.npz")
    e = engine(lk, (p["pos"], p["frm"]), lk, seed=seed)
    e.advance(300)
cl, pl, wt = [], [], []
c0 = time.process_time()
while (len(cl) < amount) if what == "300bp" else (time.process_time() - c0 < amount):
    e.advance(1)
    cl.append(e.clamp_torque_z() / PN)
    pl.append(e.tail_torque_z(weighted=False) / PN)
    wt.append(e.tail_torque_z(weighted=True) / PN)
cl, pl, wt = map(np.array, (cl, pl, wt))
print(what, "samples", len(cl), "cpu", round(time.process_time() - c0, 1))
for name, s in (("clamp", cl), ("plain", pl), ("weighted", wt), ("weighted - plain", wt - pl),
                ("plain - clamp", pl - cl), ("weighted - clamp", wt - cl)):
    est = mean_and_error(s)
    print(f"{name:17s} {est.mean:8.3f} +- {est.error:.3f}  tau {est.tau:6.1f}  sd {s[est.t0:].std():6.2f}  "
          f"{'FLAG' if est.flag else ''}")
