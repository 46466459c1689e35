"""Per-rung estimates and MBAR pooling (twist-ramp-mapped reduced potentials) of a ladder run; jackknife errors
over contiguous time blocks of all rungs together."""
import sys

import numpy as np
from pymbar import MBAR

from dnarod.analysis.statistics import mean_and_error

D = np.load(sys.argv[1])
targets = [float(t) for t in sys.argv[2].split(",")]
cut = float(sys.argv[3]) if len(sys.argv) > 3 else 0.2
win = float(sys.argv[4]) if len(sys.argv) > 4 else 10.0   # pool rungs within this many turns of the target
turns, x, u, tq = D["turns"], D["x"], D["u"], D["tq"]
R, K = x.shape
r0 = int(cut * R)
print(f"rounds {R}, cpu {float(D['cpu']):.0f}, swap {np.round(D['swap'], 2)}")
for i, t in enumerate(turns):
    est = mean_and_error(x[r0:, i]); et = mean_and_error(tq[r0:, i])
    print(f"rung {t:5.2f}: x/L {est.mean:.4f} +- {100 * est.error / est.mean:.2f} % tau {est.tau:5.1f} "
          f"{'FLAG' if est.flag else ''}  torque {et.mean:6.2f} +- {et.error:.2f} tau {et.tau:.1f}")


def mbar_x(rows, sel, k_t):
    xs = x[rows][:, sel]                    # (r, Ks)
    us = u[rows][:, sel][:, :, sel]         # (r, i, k)
    Ks = len(sel)
    u_kn = np.concatenate([us[:, i, :] for i in range(Ks)], axis=0).T    # (Ks, N)
    a_n = np.concatenate([xs[:, i] for i in range(Ks)])
    m = MBAR(u_kn, np.full(Ks, len(rows)), solver_protocol="robust")
    w = m.W_nk[:, k_t]
    return float(np.sum(w * a_n)), float(1.0 / np.sum(w * w))


B = 10
rows = np.arange(r0, R)
blocks = np.array_split(rows, B)
for t in targets:
    k = int(np.argmin(np.abs(turns - t)))
    sel = [i for i in range(K) if abs(turns[i] - t) <= win + 1e-9]
    kt = sel.index(k)
    full, neff = mbar_x(rows, sel, kt)
    jk = np.array([mbar_x(np.concatenate([b for j, b in enumerate(blocks) if j != q]), sel, kt)[0] for q in range(B)])
    err = np.sqrt((B - 1) / B * np.sum((jk - jk.mean()) ** 2))
    # the same jackknife on the rung alone, for comparison
    jk1 = np.array([x[np.concatenate([b for j, b in enumerate(blocks) if j != q]), k].mean() for q in range(B)])
    err1 = np.sqrt((B - 1) / B * np.sum((jk1 - jk1.mean()) ** 2))
    print(f"target {t}: pooled over {[float(turns[i]) for i in sel]}: x/L {full:.4f} +- {100 * err / full:.2f} % "
          f"(Kish n {neff:.0f}); rung alone {x[rows, k].mean():.4f} +- {100 * err1 / x[rows, k].mean():.2f} % (jackknife)")
