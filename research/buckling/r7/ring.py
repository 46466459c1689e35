"""python ring.py FOLDER n_bp delta_lk time_ns seed"""
import json, sys, time
from pathlib import Path
from dnarod.workflows.protocols.rings import run_ring_member
folder, n_bp, dlk, tns, seed = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
s = dict(n_bp=n_bp, delta_lk=dlk, time_ns=tns, seed=seed, temperature_K=300.0)
t0, c0 = time.perf_counter(), time.process_time()
r = run_ring_member(s, Path(folder))
with open(folder + ".log", "a") as f:
    f.write(f"done wall {time.perf_counter()-t0:.0f} cpu {time.process_time()-c0:.0f} {json.dumps({k: v for k, v in r.items() if isinstance(v, (int, float, str))})}\n")
