"""Per-step tail-torque values, heights and tangents at a buckled pose, saved for scan_w.py (usage: LK N_SAMPLES)."""
import sys
import time

import numpy as np
from common import engine
from dnarod.core.units import PN
from dnarod.engines.mc.kernels import height_clear_steps as clear_steps


lk = float(sys.argv[1]) if len(sys.argv) > 1 else 4.0
p = np.load(f"pose{int(lk)}.npz")
e = engine(lk, (p["pos"], p["frm"]), lk, tune_sweeps=200)
e.advance(200)
nex = int(e.ip[2]); cut = float(e.fp[9])
print("nex", nex, "cut", cut)
prof, clear, d3z = [], [], []
w = np.empty(e.model.n_nodes - 1)
c0 = time.process_time()
for s in range(int(sys.argv[2]) if len(sys.argv) > 2 else 400):
    e.advance(1)
    pr = e.tail_torque_z(profile=True) / PN
    clear_steps(e.pos[:, 2].copy(), nex, cut, w)
    prof.append(pr); clear.append(e.pos[:, 2].copy()); d3z.append(e.frm[:, 2, 2].copy())
print("cpu", time.process_time() - c0)
prof = np.array(prof); clear = np.array(clear); d3z = np.array(d3z)
np.savez(f"prof{int(lk)}.npz", prof=prof, z=clear, d3z=d3z, nex=nex, cut=cut)
