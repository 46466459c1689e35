import sys
import numpy as np
from numba import njit

@njit(cache=True)
def flag(z, nex, r0, out):
    n = z.shape[0]
    d = np.zeros(n + 1)
    for i in range(n):
        for j in range(i + nex + 1, n):
            if abs(z[i] - z[j]) < r0:
                d[i] += 1.0
                d[j] -= 1.0
    c = 0.0
    for k in range(n - 1):
        c += d[k]
        out[k] = c

D = np.load(sys.argv[1])
prof, Z, d3z, nex = D["prof"], D["z"], D["d3z"], int(D["nex"])
valid = np.isfinite(prof[0]); P = np.where(valid, prof, 0.0)
u = P[:, valid].mean(1)
print("uniform sd %.2f mean %.2f" % (u.std(), u.mean()))
n = Z.shape[1]
for nexx in [nex, 40, 60]:
  for r0 in [2.0, 4.0, 6.0, 9.45]:
    C = np.empty((len(Z), n - 1))
    for s in range(len(Z)):
        flag(Z[s], nexx, r0, C[s])
    for thr in [-2, 0.8, 0.9]:
        al = np.minimum(d3z[:, :-1], d3z[:, 1:]) > thr
        W = (C == 0) * valid * al
        nw = W.sum(1)
        est = np.where(nw > 0, (W * P).sum(1) / np.maximum(nw, 1), u)
        print(f"nex {nexx} r0 {r0} d3z>{thr}: sd {est.std():.2f} mean {est.mean():.2f} frac {(nw / valid.sum()).mean():.2f} none {(nw == 0).mean():.3f}")
