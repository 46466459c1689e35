"""Run a ring member keeping every pose the plectoneme detector sees: python ring_poses.py FOLDER n_bp delta_lk time_ns seed
(the member's settings and samples are those of a plain run; the poses go to FOLDER.poses.npz)."""
import sys, time
from pathlib import Path
import numpy as np
import dnarod.workflows.protocols.measure as measure
from dnarod.workflows.protocols.rings import run_ring_member
folder, n_bp, dlk, tns, seed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
poses, orig = [], measure.plectoneme_state
def wrapped(positions, ds, *a, **k):
    poses.append(np.asarray(positions, np.float32))
    return orig(positions, ds, *a, **k)
measure.plectoneme_state = wrapped
t0, c0 = time.perf_counter(), time.process_time()
r = run_ring_member(dict(n_bp=n_bp, delta_lk=dlk, time_ns=tns, seed=seed, temperature_K=300.0), Path(folder))
np.savez_compressed(folder + ".poses.npz", pos=np.array(poses), every=1)
with open(folder + ".log", "a") as f:
    f.write(f"done wall {time.perf_counter()-t0:.0f} cpu {time.process_time()-c0:.0f} Wr {r['Wr']}\n")
