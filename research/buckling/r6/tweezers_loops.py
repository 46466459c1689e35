"""End loops (:func:`dnarod.workflows.protocols.measure.plectoneme_end_loops`) of a tweezers member's poses kept by
premembers.py (every 4th sample). Usage: python tweezers_loops.py POSES_NPZ [...]
(round 6's fixed detector distances, 25 nm and 6 nm, as in its report.)
"""
import sys

import numpy as np

from dnarod.workflows.protocols.measure import plectoneme_end_loops

for f in sys.argv[1:]:
    pos = np.load(f)["pos"]
    n = np.array([plectoneme_end_loops(p, 0.34, False, 25.0, 6.0)[0] for p in pos])
    half = len(n) // 2
    print(f, len(n), "poses; end loops histogram", np.bincount(n).tolist(), "mean", round(n.mean(), 3),
          "halves", round(n[:half].mean(), 3), round(n[half:].mean(), 3))
