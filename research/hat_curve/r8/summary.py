"""Summary of a bracketed hat curve (``dnarod protocol hat --start bracket``; ``research/hat_curve/r8/run.sh``).

Per turn value: the outward and inward members (x/L, block and tau-based standard errors, integrated
autocorrelation time of the extension, the production's quarters), the bracketed point of ``curve.csv``
(midpoint, its error covering half the gap, relative error, the gap in standard errors) and whether it reaches the
issue's target (relative error of the extension <= ``--target``); the command's wall and CPU time from
``/usr/bin/time -v`` and the load average during the run. Prints a table, writes JSON.

    python research/hat_curve/r8/summary.py runs/hat_r8 --out research/hat_curve/results/hat_1kbp_r8.json \
        --figure research/hat_curve/figures/hat_1kbp_1pN_bracket.png
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[3] / "benchmarks"))  # bench_hat_1kbp
from bench_hat_1kbp import analyse_curve  # noqa: E402


def _time_v(path):
    """Wall (s), user+sys CPU (s) and maximum resident set (kB) of a ``/usr/bin/time -v`` report."""
    out = {}
    for line in Path(path).read_text().splitlines():
        k, _, v = line.strip().rpartition(": ")
        if k == "User time (seconds)":
            out["user_s"] = float(v)
        elif k == "System time (seconds)":
            out["sys_s"] = float(v)
        elif k.startswith("Elapsed (wall clock) time"):
            parts = [float(x) for x in v.split(":")]
            out["wall_s"] = sum(p * 60 ** i for i, p in enumerate(reversed(parts)))
        elif k == "Maximum resident set size (kbytes)":
            out["max_rss_kB"] = int(v)
    if "user_s" in out:
        out["cpu_s"] = out["user_s"] + out["sys_s"]
    return out


def run_costs(root):
    """``(command, load)`` of a run.sh folder: the ``/usr/bin/time -v`` figures of ``time.txt`` (empty dict if
    absent) and the min/max/mean of the 1-minute load averages in ``load.log`` (None if absent)."""
    root = Path(root)
    load = [float(line.split()[1]) for line in (root / "load.log").read_text().splitlines()] \
        if (root / "load.log").exists() else []
    cmd = _time_v(root / "time.txt") if (root / "time.txt").exists() else {}
    return cmd, (dict(min=min(load), max=max(load), mean=sum(load) / len(load)) if load else None)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", help="the run folder of run.sh (curve/, time.txt, load.log)")
    ap.add_argument("--target", type=float, default=0.03)
    ap.add_argument("--out", default="research/hat_curve/results/hat_1kbp_r8.json")
    ap.add_argument("--figure", default=None, help="PNG: the bracketed curve, both directions and Marko's line")
    a = ap.parse_args(argv)
    root = Path(a.root)
    rows, total = analyse_curve(root / "curve", a.target)
    by = {(r["folder"].split("_")[0], round(r["turns"], 6)): r for r in rows}
    points = []
    cfile = root / "curve" / "curve.csv"
    curve = list(csv.DictReader(cfile.open())) if cfile.exists() else []
    for c in curve:
        t = round(float(c["turns"]), 6)
        o, i = by.get(("out", t)), by.get(("in", t))
        rel = float(c["relative_extension_rel_err"])
        points.append(dict(turns=t, x_over_L=float(c["relative_extension"]), err=float(c["relative_extension_err"]),
                           rel_err=rel, half_gap_rel=float(c["relative_extension_half_gap_rel"]),
                           gap_z=float(c["relative_extension_gap_z"]) if c.get("relative_extension_gap_z") else None,
                           meets_target=rel <= a.target, Wr=float(c["Wr"]),
                           plectoneme_fraction=float(c["plectoneme_fraction"]),
                           out=o, inn=i))
    cmd, load = run_costs(root)
    res = dict(folder=str(root), target=a.target, command=cmd, load_average_1min=load, members=total,
        points=points, points_meeting_target=sum(p["meets_target"] for p in points), n_points=len(points))
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(res, indent=1) + "\n")
    print(f"{'turns':>6} {'x/L out':>8} {'se':>6} {'tau ns':>6} {'x/L in':>8} {'se':>6} {'tau ns':>6} {'x/L':>7} "
          f"{'err':>6} {'rel':>6} {'gap z':>6} {'Wr':>6}  quarters out | in")
    for p in points:
        o, i = p["out"] or {}, p["inn"] or {}
        q = lambda r: " ".join(f"{v:.3f}" for v in r.get("quarters_x_over_L", []))
        print(f"{p['turns']:6.1f} {o.get('x_over_L', float('nan')):8.3f} {o.get('se_block', float('nan')):6.3f} "
              f"{o.get('tau_int_extension_ns', float('nan')):6.1f} {i.get('x_over_L', float('nan')):8.3f} "
              f"{i.get('se_block', float('nan')):6.3f} {i.get('tau_int_extension_ns', float('nan')):6.1f} "
              f"{p['x_over_L']:7.3f} {p['err']:6.3f} {p['rel_err']:6.3f} {p['gap_z'] or float('nan'):6.2f} "
              f"{p['Wr']:6.2f}  {q(o)} | {q(i)}")
    print(f"{res['points_meeting_target']} of {len(points)} points within {a.target:.0%}; command: "
          f"{cmd.get('wall_s', float('nan')):.0f} s wall, {cmd.get('cpu_s', float('nan')):.0f} s CPU; members "
          f"{total['member_cpu_s']:.0f} CPU-s, {total['simulated_ns']:.0f} ns simulated; load "
          f"{res['load_average_1min']}")
    if a.figure:
        figure(points, Path(a.figure), a.target)
    return res


def figure(points, path, target):
    """The bracketed points (midpoint, error covering the gap), the outward and inward members and Marko's
    two-phase line with the model's parameters; below, the relative error and half-gap against the target."""
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "r6"))
    from compare import marko_figure

    fig, ax, _ = marko_figure()
    a = ax[0]
    t = [p["turns"] for p in points]
    for key, mk, lab, dx in (("out", "^", "outward member (from the smaller turn value)", -0.06),
                             ("inn", "v", "inward member (from the larger turn value)", 0.06)):
        rs = [(p["turns"] + dx, p[key]["x_over_L"], p[key]["se_block"]) for p in points if p.get(key)]
        if rs:
            a.errorbar(*zip(*rs), fmt=mk, ms=4, capsize=2, alpha=0.6, label=lab)
    a.errorbar(t, [p["x_over_L"] for p in points], yerr=[p["err"] for p in points], fmt="ko-", ms=4, capsize=3,
               label="bracketed point: midpoint, error covering the gap")
    a.set_ylabel("extension / contour length")
    a.set_title("1 kbp at 1 pN, dna-default, 0.15 M (calibrated charge), 300 K: --start bracket", fontsize=9)
    a.legend(fontsize=7, loc="lower center")
    b = ax[1]
    b.plot(t, [100 * p["rel_err"] for p in points], "ko-", ms=4, label="error / x")
    b.plot(t, [100 * p["half_gap_rel"] for p in points], "s:", color="C3", ms=3, label="half gap / x")
    b.axhline(100 * target, color="0.5", lw=0.8, ls="--")
    b.set(ylabel="% of x", xlabel="turns")
    b.legend(fontsize=7)
    from dnarod.analysis.plots import save_figure  # atomic PNG, 110 dpi

    path.parent.mkdir(parents=True, exist_ok=True)
    print(f"wrote {path.parent / save_figure(fig, path.parent, path.name)}")


if __name__ == "__main__":
    main()
