"""Rewrite the ``end_loops`` column of ring members with the plectoneme detector's current distances.

Usage: python recount_loops.py MEMBER_FOLDER POSES_NPZ [MEMBER_FOLDER POSES_NPZ ...]

The poses are those the detector saw while the member ran (every sample; ``ring_poses.py`` or
``research/buckling/r6/premembers.py``). Ring members run before the detector's distances followed the model's
non-bonded terms (round 7, :func:`dnarod.workflows.protocols.measure.detector_distances`) counted with the fixed 6-nm contact,
which misses one end loop of a short calibrated-charge plectoneme in a fifth of the samples; the recount uses the
member's own distances. The old column is kept as ``end_loops_6nm``; samples.csv is replaced atomically.
"""
import json
import sys
from pathlib import Path

import numpy as np

from dnarod.core.forcefield import load_forcefield
from dnarod.core.io import write_text_atomic
from dnarod.physics.nonbonded import member_nonbonded
from dnarod.workflows.protocols.measure import detector_distances, plectoneme_end_loops
from dnarod.workflows.protocols.rings import _settings

args = sys.argv[1:]
for member, poses in zip(args[::2], args[1::2]):
    member = Path(member)
    s = _settings(json.loads((member / "protocol_result.json").read_text())["settings"])
    pos = np.load(poses)["pos"]
    ds = load_forcefield(s["forcefield"]).ring(n_nodes=int(s["n_bp"])).ds
    sep, con = detector_distances(member_nonbonded(s), float(s["temperature_K"]), ds)
    lines = (member / "samples.csv").read_text().splitlines()
    head = lines[0].split(",")
    if len(pos) != len(lines) - 1:
        sys.exit(f"{poses}: {len(pos)} poses for {len(lines) - 1} samples")
    loops = [plectoneme_end_loops(p.astype(float), ds, circular=True, min_separation_nm=sep, contact_distance_nm=con)[0]
             for p in pos]
    k = head.index("end_loops")
    if "end_loops_6nm" not in head:
        head.append("end_loops_6nm")
        rows = [r.split(",") + [r.split(",")[k]] for r in lines[1:]]
    else:
        rows = [r.split(",") for r in lines[1:]]
    for r, n in zip(rows, loops):
        r[k] = str(int(n))
    write_text_atomic(member / "samples.csv", "\n".join([",".join(head)] + [",".join(r) for r in rows]) + "\n")
    print(member, f"contact {con:.2f} nm, separation {sep:.1f} nm:", np.bincount(np.asarray(loops, int)).tolist(),
          f"mean {np.mean(loops):.3f}")
