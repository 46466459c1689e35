"""Add the ``end_loops`` column to a ring member run before ring members recorded it, from the poses that
premembers.py kept (one pose per sample, the very poses the plectoneme detector saw).

Usage: python add_end_loops.py MEMBER_DIR POSES_NPZ

Writes ``samples.csv`` with the extra column and adds ``end_loops`` (mean), ``end_loops_err`` (10 blocks, as
the ring protocol) and the histogram to ``protocol_result.json`` (settings key unchanged), atomically. The
count is :func:`dnarod.workflows.protocols.measure.plectoneme_end_loops`, what ring members recorded in round 6, with that
round's fixed distances (25 nm, 6 nm; the numbers in its report; members now use their own model's, round 7).
"""
import json
import sys
from pathlib import Path

import numpy as np

from dnarod.core.forcefield import load_forcefield
from dnarod.core.io import jsonable, write_text_atomic
from dnarod.workflows.protocols.measure import plectoneme_end_loops

member, poses = Path(sys.argv[1]), np.load(sys.argv[2])
pos = poses["pos"]
assert int(poses["every"]) == 1, "ring poses must be one per sample"
d = np.genfromtxt(member / "samples.csv", delimiter=",", names=True)
if len(d) != len(pos):
    sys.exit(f"{len(d)} samples but {len(pos)} poses")
done = json.loads((member / "protocol_result.json").read_text())
ds = load_forcefield(done["settings"]["forcefield"]).ring(n_nodes=pos.shape[1]).ds
loops = np.array([plectoneme_end_loops(p, ds, True, 25.0, 6.0)[0] for p in pos], float)
names = [n for n in d.dtype.names if n != "end_loops"]
lines = [",".join(names + ["end_loops"])] + [",".join([f"{d[c][i]:.10g}" for c in names] + [f"{loops[i]:.10g}"])
                                              for i in range(len(d))]
write_text_atomic(member / "samples.csv", "\n".join(lines) + "\n")
b = np.array([v.mean() for v in np.array_split(loops, 10)])
res = done["result"]
res.update(end_loops=float(loops.mean()), end_loops_err=float(b.std(ddof=1) / np.sqrt(10)),
           end_loops_histogram=np.bincount(loops.astype(int)).tolist())
write_text_atomic(member / "protocol_result.json", json.dumps(jsonable(done), indent=1) + "\n")
print(member, "end loops mean", loops.mean(), "histogram", np.bincount(loops.astype(int)).tolist())
