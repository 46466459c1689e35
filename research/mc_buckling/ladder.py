"""Turn ladder near buckling (torques: height-weighted tq, plain tq_plain; runs a-c wrote the then-default
weighted average as tq): per-rung extension series and, for pooling, every sample's reduced potential in
every rung after the twist-ramp map (positions unchanged, so only elastic, clamp and wall terms change)."""
import sys
import time

import numpy as np

from common import engine
from dnarod.core.units import PN
from dnarod.engines.mc.ladder import TurnLadder, twist_ramp

lo, hi, step = float(sys.argv[1]), float(sys.argv[2]), float(sys.argv[3])
budget = float(sys.argv[4])
xe = int(sys.argv[5])          # exchange every xe rounds
tag = sys.argv[6]
seed = int(sys.argv[7]) if len(sys.argv) > 7 else 0
posefile = sys.argv[8] if len(sys.argv) > 8 else "pose4.npz"
with_u = len(sys.argv) <= 9 or sys.argv[9] != "nou"
turns = np.round(np.arange(lo, hi + 1e-9, step), 6)
p = np.load(posefile)
pt = 4.0 if "4" in posefile else 3.0
engines = [engine(t, (p["pos"], p["frm"]), pt, seed=11 + i + 100 * seed) for i, t in enumerate(turns)]
lad = TurnLadder(engines, turns, seed=5 + seed)
L = engines[0].model.ds * 999
kt = engines[0].fp[1]
K = len(turns)
X, TQ, TP, U, LAB = [], [], [], [], []
c0 = time.process_time()
r = 0
while time.process_time() - c0 < budget:
    lad.advance(1)
    r += 1
    X.append([(e.pos[-1, 2] - e.pos[0, 2]) / L for e in engines])
    TQ.append([e.tail_torque_z(weighted=True) / PN for e in engines])
    TP.append([e.tail_torque_z(weighted=False) / PN for e in engines])
    u = np.zeros((K, K))
    for i, e in enumerate(engines if with_u else []):
        for k, ek in enumerate(engines):
            u[i, k] = ek.potential_local(e.pos, twist_ramp(e.frm, turns[k] - turns[i])) / kt
    U.append(u)
    LAB.append(lad.labels.copy())
    if r % xe == 0:
        lad.exchange()
cpu = time.process_time() - c0
np.savez(f"ladder_{tag}.npz", turns=turns, x=np.array(X), tq=np.array(TQ), tq_plain=np.array(TP), u=np.array(U), labels=np.array(LAB),
         cpu=cpu, swap=lad.acceptance())
print(tag, "rounds", r, "cpu", cpu, "swap", np.round(lad.acceptance(), 2), flush=True)
