"""Move mixes at a buckled point: sweeps per CPU-s, extension MSD per CPU-s at fixed lags, tau_x."""
import json
import sys
import time

import numpy as np

from common import engine
from dnarod.analysis.statistics import mean_and_error

CONFIGS = {
    "default": {},
    "hinge": dict(moves={"node": 0.15, "crankshaft": 0.2, "hinge": 0.4, "twist": 0.1, "end_twist": 0.05,
                         "slide": 0.1}),
    "crank": dict(moves={"node": 0.15, "crankshaft": 0.45, "hinge": 0.2, "twist": 0.05, "end_twist": 0.05,
                         "slide": 0.1}),
    "twist": dict(moves={"node": 0.2, "crankshaft": 0.2, "hinge": 0.15, "twist": 0.25, "end_twist": 0.1,
                         "slide": 0.1}),
    "twist2": dict(moves={"node": 0.15, "crankshaft": 0.15, "hinge": 0.15, "twist": 0.3, "end_twist": 0.15,
                          "slide": 0.1}),
    "endtwist": dict(moves={"node": 0.2, "crankshaft": 0.2, "hinge": 0.15, "twist": 0.1, "end_twist": 0.25,
                            "slide": 0.1}),
    "seg100": dict(max_segment=100),
    "seg300": dict(max_segment=300),
}
lk = float(sys.argv[1])
name = sys.argv[2]
budget = float(sys.argv[3])
seed = int(sys.argv[4]) if len(sys.argv) > 4 else 7
p = np.load(f"pose{int(lk)}.npz")
e = engine(lk, (p["pos"], p["frm"]), lk, seed=seed, **CONFIGS[name])
e.advance(200)
L = e.model.ds * (e.model.n_nodes - 1)
x = []
c0 = time.process_time()
while time.process_time() - c0 < budget:
    e.advance(10)
    x.append((e.pos[-1, 2] - e.pos[0, 2]) / L)
cpu = time.process_time() - c0
x = np.repeat(np.array(x), 1)
sw = 10 * len(x)
cps = cpu / sw
out = dict(lk=lk, name=name, sweeps=sw, cpu=cpu, sweeps_per_cpu_s=sw / cpu, mean=float(x.mean()), sd=float(x.std()))
for lag in (1, 5, 20):
    d = x[lag:] - x[:-lag]
    out[f"msd_per_cpus_lag{10 * lag}"] = float(np.mean(d * d) / (2 * 10 * lag * cps))
est = mean_and_error(x)
out.update(tau_sweeps=10 * est.tau, rel_err=est.error / est.mean, flag=est.flag, acc=e.acceptance())
print(json.dumps(out), flush=True)
