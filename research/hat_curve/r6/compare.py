"""The two directions of the 1-kbp hat curve at 1 pN (outward and inward turn sweeps) side by side.

For each finished member of ``ROOT/sweep`` and ``ROOT/sweep-in`` (made by ``research/hat_curve/r6/run.sh``): its
statistics from :func:`bench_hat_1kbp.analyse_curve` (x/L, block and tau_int standard errors, tau_int of extension
and writhe, quarters of the production, drift z, wall and CPU seconds); at every turn value both directions
finished, the difference ``out - in`` in x/L, relative to their mean and in units of the combined standard error;
the cost of each command (``/usr/bin/time -v``: wall, user + system CPU of the command and its dask workers) and the
load average over its run (``load.log``). Draws both directions with Marko's two-phase line (model parameters,
long-chain extension) in ``--figure`` and writes ``--out`` (JSON).

    python research/hat_curve/r6/compare.py runs/hat_r6 --out research/hat_curve/results/hat_1kbp_r6.json \
        --figure research/hat_curve/figures/hat_1kbp_1pN_both.png
"""
from __future__ import annotations

import argparse
import json
import re
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "benchmarks"))  # bench_hat_1kbp


def command_cost(path):
    """Wall and CPU seconds of a command from ``/usr/bin/time -v`` output (None if absent)."""
    p = Path(path)
    if not p.exists():
        return None
    t = p.read_text()
    if "User time" not in t:  # still running
        return None
    user = float(re.search(r"User time \(seconds\): ([\d.]+)", t).group(1))
    sys_ = float(re.search(r"System time \(seconds\): ([\d.]+)", t).group(1))
    wall = re.search(r"Elapsed \(wall clock\) time \(h:mm:ss or m:ss\): ([\d:.]+)", t).group(1)
    parts = [float(x) for x in wall.split(":")]
    wall_s = sum(v * 60 ** i for i, v in enumerate(reversed(parts)))
    return dict(wall_s=wall_s, cpu_s=user + sys_, core_hours=(user + sys_) / 3600.0)


def load_window(root, start, end):
    """Min, mean, max of the 1-min load average logged between two ``HH:MM:SS`` times (UTC)."""
    vals = []
    log = Path(root) / "load.log"
    if not log.exists():
        return None
    for line in log.read_text().splitlines():
        hms, l1 = line.split()[:2]
        if start <= hms <= end:
            vals.append(float(l1))
    return dict(min=min(vals), mean=float(np.mean(vals)), max=max(vals), n=len(vals)) if vals else None


def times(root):
    """``{direction: (start HH:MM:SS, end HH:MM:SS or None)}`` from ``times.log``."""
    out = {}
    log = Path(root) / "times.log"
    for line in (log.read_text().splitlines() if log.exists() else []):
        stamp, what, d = line.split()[:3]
        hms = stamp.split("T")[1]
        out.setdefault(d, [None, None])[0 if what == "start" else 1] = hms
    return out


def marko_line(turns, force_pN=1.0, n_bp=1000):
    """Marko's two-phase x/L against turns (the model's A, C_s(F), P; long-chain extension; see turn_sweep.py)."""
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "turn_sweeps"))  # research/turn_sweeps
    from turn_sweep import buckling_estimate
    from dnarod.core.units import kT
    from dnarod.core.units import PN
    from dnarod.physics.theory.supercoil import marko_two_phase

    e = buckling_estimate(str(n_bp), force_pN, 300.0)
    from dnarod.core.forcefield import load_forcefield

    L = load_forcefield("dna-default").model_from_sequence(n_nodes=n_bp).ds * (n_bp - 1)
    th = marko_two_phase(e["A_nm"], e["C_s_nm"], e["P_nm"], force_pN, kT(300.0) / PN, L)
    dlk = np.asarray(turns) + e["thermal_offset_turns"]
    x = th["zeta"] + th["extension_slope_nm_per_turn"] / L * np.clip(np.abs(dlk) - th["buckling_delta_lk"], 0, None)
    return np.clip(x, 0, None), e, th


def main(argv=None):
    from bench_hat_1kbp import analyse_curve

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default="runs/hat_r6")
    ap.add_argument("--out", default="research/hat_curve/results/hat_1kbp_r6.json")
    ap.add_argument("--figure", default=None)
    a = ap.parse_args(argv)
    root = Path(a.root)
    tm = times(root)
    res = dict(date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), root=str(root), directions={})
    by = {}
    for d in ("sweep", "sweep-in"):
        if not (root / d).exists():
            continue
        rows, total = analyse_curve(root / d)
        for r in rows:
            rj = root / d / "members" / f"force_pN+1_turns{r['turns']:+g}" / "protocol_result.json"
            if rj.exists():
                r["seed"] = json.loads(rj.read_text())["result"]["seed"]
        start, end = tm.get(d, [None, None])
        res["directions"][d] = dict(members=rows, total=total, command=command_cost(root / f"time_{d}.txt"),
                                    start_utc=start, end_utc=end,
                                    load_average_1min=load_window(root, start, end or "99") if start else None)
        by[d] = {r["turns"]: r for r in rows}
    comp = []
    if len(by) == 2:
        for t in sorted(set(by["sweep"]) & set(by["sweep-in"])):
            o, i = by["sweep"][t], by["sweep-in"][t]
            se_o, se_i = max(o["se_block"], o["se_tau"]), max(i["se_block"], i["se_tau"])
            diff = o["x_over_L"] - i["x_over_L"]
            mean = 0.5 * (o["x_over_L"] + i["x_over_L"])
            comp.append(dict(turns=t, out=o["x_over_L"], se_out=se_o, inward=i["x_over_L"], se_in=se_i, diff=diff,
                             diff_rel=diff / mean, z=diff / np.hypot(se_o, se_i),
                             combined_se_rel=np.hypot(se_o, se_i) / mean,
                             settle_out_ns=o["equilibration_ns"], settle_in_ns=i["equilibration_ns"],
                             wr_out=o["Wr"], wr_in=i["Wr"], plect_out=o["plectoneme_fraction"],
                             plect_in=i["plectoneme_fraction"], drift_z_out=o["drift_z"], drift_z_in=i["drift_z"]))
    res["comparison"] = comp
    res["within_3_percent"] = sum(abs(c["diff_rel"]) <= 0.03 for c in comp)
    _, est, th = marko_line([0.0])
    res["marko"] = dict(estimate=est, torque_pN_nm=th["torque_pN_nm"], zeta=th["zeta"],
                        buckling_delta_lk=th["buckling_delta_lk"], plectonemic_delta_lk=th["plectonemic_delta_lk"],
                        extension_slope_nm_per_turn=th["extension_slope_nm_per_turn"])
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(res, indent=1, default=float) + "\n")
    for d, v in res["directions"].items():
        c = v["command"] or {}
        print(f"{d}: {len(v['members'])} members, members {v['total']['member_cpu_s']:.0f} CPU-s / "
              f"{v['total']['member_wall_s']:.0f} s wall; command {c.get('wall_s', float('nan')):.0f} s wall, "
              f"{c.get('cpu_s', float('nan')):.0f} CPU-s ({c.get('core_hours', float('nan')):.2f} core-h); "
              f"{v['start_utc']}-{v['end_utc']}, load {v['load_average_1min']}")
        for r in v["members"]:
            frm = "head" if r.get("previous_turns") is None else f"{r['previous_turns']:+.1f}"
            print(f"  {r['turns']:+5.1f} from {frm:>5} {r['equilibration_ns']:5.1f}+{r['production_ns']:<4.0f} "
                  f"x/L {r['x_over_L']:.3f} SE/x {100 * r['se_rel']:4.1f}% tau_x {r['tau_int_extension_ns']:4.1f} "
                  f"tau_Wr {r['tau_int_wr_ns']:4.1f} Wr {r['Wr']:+5.2f} plect {r['plectoneme_fraction']:.2f} "
                  f"drift z {r['drift_z']:+4.1f} quarters " + " ".join(f"{q:.3f}" for q in r["quarters_x_over_L"])
                  + f"  CPU {r['cpu_s']:.0f} s wall {r['wall_s']:.0f} s")
    print("turns    out      in       out-in  rel     z     (combined SE/x)")
    for c in comp:
        print(f"{c['turns']:+5.1f}  {c['out']:.3f}±{c['se_out']:.3f}  {c['inward']:.3f}±{c['se_in']:.3f}  "
              f"{c['diff']:+.3f}  {100 * c['diff_rel']:+5.1f}%  {c['z']:+5.1f}  ({100 * c['combined_se_rel']:.1f}%)")
    print(f"within 3 %: {res['within_3_percent']} of {len(comp)}")
    if a.figure:
        figure(res, by, Path(a.figure))
    return res


def marko_figure():
    """A two-panel figure (curve above, differences below, shared turns axis) with Marko's two-phase x/L line
    (:func:`marko_line`) drawn on the upper panel; returns ``(fig, axes, buckling_estimate)``."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(2, 1, figsize=(6.4, 7.0), sharex=True, gridspec_kw=dict(height_ratios=[3, 1.3]))
    tt = np.linspace(-5.2, 4.4, 200)
    x, est, _ = marko_line(tt)
    ax[0].plot(tt, x, "k--", lw=1, label=f"Marko two-phase, model A, C_s {est['C_s_nm']:.0f} nm, P {est['P_nm']:g} "
                                        f"nm (long chain)")
    return fig, ax, est


def figure(res, by, path):
    fig, ax, est = marko_figure()
    a = ax[0]
    for b in (est["turns_lo"], est["turns_hi"]):
        a.axvline(b, color="0.7", lw=0.8, ls=":")
    for d, mk, lab in (("sweep", "o-", "outward sweep (0 → ±)"), ("sweep-in", "s-", "inward sweep (± → 0)")):
        if d not in by:
            continue
        rs = [by[d][t] for t in sorted(by[d])]
        if len(rs) < 12:  # an unfinished sweep: no line across the members it has not run
            mk, lab = mk[0], lab + f", {len(rs)} members finished"
        a.errorbar([r["turns"] for r in rs], [r["x_over_L"] for r in rs],
                   yerr=[max(r["se_block"], r["se_tau"]) for r in rs], fmt=mk, ms=4, capsize=3, label=lab)
    a.set_ylabel("extension / contour length")
    a.set_title("1 kbp at 1 pN, dna-default, 0.15 M (calibrated charge), 300 K", fontsize=9)
    a.legend(fontsize=7, loc="lower center")
    a.text(0.01, 0.98, "dotted: long settle (--settle-buckled) beyond, |ΔLk at T| ≥ 0.8 ΔLk_b", transform=a.transAxes,
           fontsize=6.5, color="0.4", va="top")
    b = ax[1]
    comp = res["comparison"]
    if comp:
        b.errorbar([c["turns"] for c in comp], [100 * c["diff_rel"] for c in comp],
                   yerr=[100 * c["combined_se_rel"] for c in comp], fmt="o", ms=4, capsize=3, color="C3")
    b.axhspan(-3, 3, color="0.9", zorder=0)
    b.axhline(0, color="0.5", lw=0.8)
    b.set_ylabel("(out − in) / x, %")
    b.set_xlabel("turns")
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
