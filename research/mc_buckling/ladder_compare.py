"""Per-rung x/L and torques (height-weighted and plain, same samples) of ladder runs; usage: ladder_compare.py NPZ."""
import sys

import numpy as np

from dnarod.analysis.statistics import mean_and_error

D = np.load(sys.argv[1])
for i, t in enumerate(D["turns"]):
    x = mean_and_error(D["x"][:, i])
    w = mean_and_error(D["tq"][:, i])
    line = (f"{t:5.2f} x/L {x.mean:.4f} +- {100 * x.error / x.mean:.2f} % {'F' if x.flag else ' '} | weighted "
            f"{w.mean:6.2f} +- {w.error:.2f} (tau {w.tau:5.1f}) {'F' if w.flag else ' '}")
    if "tq_plain" in D:
        p = mean_and_error(D["tq_plain"][:, i])
        d = mean_and_error(D["tq"][:, i] - D["tq_plain"][:, i])
        line += (f" | plain {p.mean:6.2f} +- {p.error:.2f} (tau {p.tau:5.1f}) {'F' if p.flag else ' '} | w - p "
                 f"{d.mean:+.2f} +- {d.error:.2f}")
    print(line)
