"""Run one tweezers member: python tw.py FOLDER n_bp turns time_ns seed [grown]"""
import json, sys, time
from pathlib import Path
from dnarod.workflows.protocols.tweezers import run_member
sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "turn_sweeps"))  # research/turn_sweeps
from turn_sweep import run_grown_member
folder, n_bp, turns, time_ns, seed = sys.argv[1], int(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]), int(sys.argv[5])
s = dict(n_bp=n_bp, force_pN=1.0, turns=round(turns, 4), time_ns=time_ns, temperature_K=300.0, seed=seed)
grown = "grown" in sys.argv[6:]  # from a plectoneme grown 20 ns at 0.3 pN (the start_force_pN/start_ns of the time)
t0, c0 = time.perf_counter(), time.process_time()
log = Path(folder + ".log")
last = [0.0]
def progress(i, n):
    if time.perf_counter() - last[0] > 120:
        last[0] = time.perf_counter()
        with open(log, "a") as f:
            f.write(f"{time.strftime('%H:%M:%S')} sample {i}/{n} wall {time.perf_counter()-t0:.0f} cpu {time.process_time()-c0:.0f}\n")
r = run_grown_member(s, Path(folder), 0.3, 20.0, progress=progress) if grown else run_member(s, Path(folder), progress=progress)
with open(log, "a") as f:
    f.write(f"done wall {time.perf_counter()-t0:.0f} cpu {time.process_time()-c0:.0f} {json.dumps({k: v for k, v in r.items() if isinstance(v, (int, float, str))})}\n")
