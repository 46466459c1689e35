"""Figure research/buckling/figures/buckling_600bp_1pN.png from the long members and rings (run from runs/)."""
import json, sys
import numpy as np
import matplotlib
matplotlib.use("Agg")
import matplotlib.pyplot as plt
from dnarod.physics.theory.supercoil import marko_two_phase
kt, cs, L = 4.1419464, 84.27, 203.66
off = -1.2156
fig, ax = plt.subplots(1, 2, figsize=(9, 3.6))
for f, lab, c in (("t257_s.npz", "straight start", "C0"), ("t257_g.npz", "grown-plectoneme start", "C1")):
    d = np.load(f); n = int(d["n"]); t = d["time_ps"][:n] / 1000; tau = d["twist_torque_pN_nm"][:n] - off
    w = 125
    tm = [t[i:i + w].mean() for i in range(0, n - w + 1, w)]; tw = [tau[i:i + w].mean() for i in range(0, n - w + 1, w)]
    ax[0].plot(tm, tw, "o-", color=c, ms=3, label=f"{lab}: {tau.mean():.2f} pN nm")
res = json.load(open("rings.json"))
for P, ls, lab in ((res["P_single"], "--", "single 600-bp ring P"), (res["P_bulk"], "-", "bulk P_b (600/1200-bp ring pair)")):
    ax[0].axhline(marko_two_phase(50.0, cs, P, 1.0, kt, L)["torque_pN_nm"], color="C3", ls=ls,
                  label=f"Marko, {lab} {P:.1f} nm")
ax[0].set_xlabel("time (ns)"); ax[0].set_ylabel("torque, 25-ns means (pN nm)")
ax[0].set_title("600 bp, 1 pN, 2.57 turns", fontsize=9); ax[0].legend(fontsize=6.5)
x = np.array(res["inv_theta"]); y = np.array(res["P"]); e = np.array(res["P_err"])
ax[1].errorbar(x, y, yerr=e, fmt="s", capsize=3, label="600-bp rings: C(1 - Wr/ΔLk)")
if res.get("x1200") is not None:
    ax[1].errorbar([res["x1200"]], [res["P1200"]], yerr=[res["P1200_err"]], fmt="D", color="C2", capsize=3,
                   label="1200-bp ring, sigma -0.086 (moment)")
xx = np.linspace(0, max(x) * 1.05, 50)
ax[1].plot(xx, res["fit"][0] + res["fit"][1] * xx, "k:", label=f"fit P_b(1 + |delta|/2piΔLk): P_b {res['fit'][0]:.1f}")
ax[1].errorbar([0], [res["P_bulk"]], yerr=[res["P_bulk_err"]], fmt="o", color="C3", capsize=3, label="ring pair P_b = C(1 - dWr/dDLk)")
ax[1].set_xlabel("1 / (2 pi |ΔLk|)"); ax[1].set_ylabel("P (nm)"); ax[1].legend(fontsize=6.5)
fig.tight_layout(); fig.savefig(sys.argv[1], dpi=130)
