"""Member from another member's final pose: python twp.py FOLDER n_bp turns time_ns seed SRC_FOLDER SRC_TURNS"""
import json, sys, time
from pathlib import Path
import numpy as np
from dnarod.workflows.protocols.tweezers import run_member
folder, n_bp, turns, tns, seed, src, src_turns = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5]), sys.argv[6], float(sys.argv[7])
z = np.load(Path(src) / "final_pose.npz")
s = dict(n_bp=n_bp, force_pN=1.0, turns=round(turns, 4), time_ns=tns, temperature_K=300.0, seed=seed, previous_turns=src_turns)
t0, c0 = time.perf_counter(), time.process_time()
log = Path(folder + ".log"); last = [0.0]
def progress(i, n):
    if time.perf_counter() - last[0] > 120:
        last[0] = time.perf_counter()
        with open(log, "a") as f:
            f.write(f"{time.strftime('%H:%M:%S')} sample {i}/{n} wall {time.perf_counter()-t0:.0f} cpu {time.process_time()-c0:.0f}\n")
r = run_member(s, Path(folder), progress=progress, start_pose=(z["positions"], z["frames"]))
with open(log, "a") as f:
    f.write(f"done wall {time.perf_counter()-t0:.0f} cpu {time.process_time()-c0:.0f} {json.dumps({k: v for k, v in r.items() if isinstance(v, (int, float, str))})}\n")
