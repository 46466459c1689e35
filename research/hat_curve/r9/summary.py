"""Summary of a replica-exchange hat curve (``dnarod protocol hat --start exchange``; ``research/hat_curve/r9/run.sh``).

Per rung: x/L with its block and tau-based standard errors (the larger is the point's error), the integrated
autocorrelation time of the rung's extension series (swaps included), the production's quarters, how many replicas
visited the rung, the acceptance of its two exchange pairs, and the round-8 bracketed point at the same turns
(``research/hat_curve/results/hat_1kbp_r8.json``) with the difference in combined errors; the ladder's round trips; the
command's wall and CPU time from ``/usr/bin/time -v`` and the load average during the run. Prints a table, writes
JSON and, with ``--figure``, the curve beside round 8's and Marko's line.

    python research/hat_curve/r9/summary.py runs/hat_r9 --out research/hat_curve/results/hat_1kbp_r9.json \
        --figure research/hat_curve/figures/hat_1kbp_1pN_exchange.png

Other runs' points (a results JSON of this script or of ``r8/summary.py``) are compared with
``--compare LABEL=PATH`` (repeatable; default ``r8=research/hat_curve/results/hat_1kbp_r8.json``): each point then carries
``LABEL_x_over_L``, ``LABEL_err`` and ``z_vs_LABEL``. Round 10:

    python research/hat_curve/r9/summary.py runs/hat_r10 --out research/hat_curve/results/hat_1kbp_r10.json \
        --compare r8=research/hat_curve/results/hat_1kbp_r8.json --compare r9=research/hat_curve/results/hat_1kbp_r9.json \
        --title "exchange, round 10" --figure research/hat_curve/figures/hat_1kbp_1pN_exchange_r10.png

Round 11 (``research/hat_curve/r11/run.sh``):

    python research/hat_curve/r9/summary.py runs/hat_r11 --out research/hat_curve/results/hat_1kbp_r11.json \
        --compare r8=research/hat_curve/results/hat_1kbp_r8.json --compare r10=research/hat_curve/results/hat_1kbp_r10.json \
        --title "exchange, round 11" --figure research/hat_curve/figures/hat_1kbp_1pN_exchange_r11.png
"""
from __future__ import annotations

import argparse
import csv
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[2] / "benchmarks"))  # bench_hat_1kbp
sys.path.insert(0, str(HERE.parent / "r8"))
from bench_hat_1kbp import analyse_curve  # noqa: E402
from summary import run_costs  # noqa: E402  (r8's /usr/bin/time -v and load.log reader)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", help="the run folder of run.sh (curve/, time.txt, load.log)")
    ap.add_argument("--target", type=float, default=0.03)
    ap.add_argument("--out", default="research/hat_curve/results/hat_1kbp_r9.json")
    ap.add_argument("--compare", action="append", default=None, metavar="LABEL=PATH",
                    help="another run's results JSON (default r8=research/hat_curve/results/hat_1kbp_r8.json)")
    ap.add_argument("--title", default="--start exchange", help="the figure's title after the system")
    ap.add_argument("--figure", default=None)
    a = ap.parse_args(argv)
    root = Path(a.root)
    rows, total = analyse_curve(root / "curve", a.target)
    ladder = json.loads(next((root / "curve" / "ladders").glob("*/exchange.json")).read_text())
    ladder.pop("key", None)
    others = {}
    for spec in a.compare or ["r8=research/hat_curve/results/hat_1kbp_r8.json"]:
        label, _, path = spec.partition("=")
        if not label or not Path(path).is_file():
            ap.error(f"--compare {spec}: give LABEL=PATH of an existing results JSON")
        others[label] = {round(p["turns"], 6): p for p in json.loads(Path(path).read_text())["points"]}
    curve = {round(float(c["turns"]), 6): c for c in csv.DictReader((root / "curve" / "curve.csv").open())}
    points = []
    for r in rows:
        t = round(r["turns"], 6)
        res = json.loads((root / "curve" / "members" / r["folder"] / "protocol_result.json").read_text())["result"]
        err = max(r["se_block"], r["se_tau"])
        p = dict(turns=t, x_over_L=r["x_over_L"], err=err, rel_err=err / r["x_over_L"],
                 meets_target=err / r["x_over_L"] <= a.target, se_block=r["se_block"], se_tau=r["se_tau"],
                 tau_int_extension_ns=r["tau_int_extension_ns"], quarters_x_over_L=r["quarters_x_over_L"],
                 drift_z=r["drift_z"], Wr=r["Wr"], plectoneme_fraction=r["plectoneme_fraction"],
                 twist_torque_pN_nm=float(curve[t]["twist_torque_pN_nm"]) if t in curve else None,
                 replicas_visited=res.get("exchange_replicas_visited"),
                 acceptance_down=res.get("exchange_acceptance_down"), acceptance_up=res.get("exchange_acceptance_up"),
                 start=res.get("start"), lk_slips=r["lk_slips"])
        for label, pts in others.items():
            if t in pts:
                q = pts[t]
                p.update({f"{label}_x_over_L": q["x_over_L"], f"{label}_err": q["err"],
                          f"z_vs_{label}": (r["x_over_L"] - q["x_over_L"]) / float(np.hypot(err, q["err"]))})
                if "out" in q or "inn" in q:  # a bracketed point: its two members
                    p.update({f"{label}_out": (q.get("out") or {}).get("x_over_L"),
                              f"{label}_in": (q.get("inn") or {}).get("x_over_L")})
        points.append(p)
    cmd, load = run_costs(root)
    res = dict(folder=str(root), target=a.target, command=cmd, load_average_1min=load, ladder=ladder,
        simulated_ns=total["simulated_ns"], points=points,
        points_meeting_target=sum(p["meets_target"] for p in points), n_points=len(points))
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(res, indent=1) + "\n")
    print(f"{'turns':>6} {'x/L':>7} {'err':>6} {'rel':>6} {'tau ns':>6} {'reps':>4} {'acc-':>5} {'acc+':>5} "
          f"{'Wr':>6}" + "".join(f" {lb + ' x/L':>8} {lb + ' err':>7} {'z':>5}" for lb in others) + "  quarters")
    f = lambda v, w=5, d=2: f"{v:{w}.{d}f}" if v is not None else " " * (w - 1) + "-"
    for p in points:
        print(f"{p['turns']:6.1f} {p['x_over_L']:7.3f} {p['err']:6.3f} {p['rel_err']:6.3f} "
              f"{p['tau_int_extension_ns']:6.1f} {p['replicas_visited'] or 0:4d} {f(p['acceptance_down'])} "
              f"{f(p['acceptance_up'])} {p['Wr']:6.2f}"
              + "".join(f" {f(p.get(lb + '_x_over_L'), 8, 3)} {f(p.get(lb + '_err'), 7, 3)} {f(p.get('z_vs_' + lb))}"
                        for lb in others)
              + f"  {' '.join(f'{v:.3f}' for v in p['quarters_x_over_L'])}")
    print(f"{res['points_meeting_target']} of {len(points)} points within {a.target:.0%}; command: "
          f"{cmd.get('wall_s', float('nan')):.0f} s wall, {cmd.get('cpu_s', float('nan')):.0f} s CPU; "
          f"{total['simulated_ns']:.0f} ns simulated; round trips {ladder['round_trips_total']}; load "
          f"{res['load_average_1min']}")
    if a.figure:
        figure(points, Path(a.figure), a.target, list(others), a.title)
    return res


LEGEND = {"r8": "round 8: bracketed point (error covers the out/in gap)",
          "r9": "round 9: exchange, 0.8-turn pairs in the plateaus",
          "r10": "round 10: exchange, 0.4-turn rungs, CPU platform, 140 ns",
          "r11": "round 11: exchange, Reference platform, 0.4-turn rungs below buckling, 240 ns",
          "r12": "round 12: exchange, 0.2-turn rungs on both plateaus, 210 ns"}


def figure(points, path, target, labels=("r8",), title="--start exchange"):
    """The exchange curve beside the compared runs' points and Marko's two-phase line; below, error / x and
    each pair's acceptance."""
    sys.path.insert(0, str(HERE.parent / "r6"))
    from compare import marko_figure

    fig, ax, _ = marko_figure()
    a = ax[0]
    t = [p["turns"] for p in points]
    for j, (lb, fmt) in enumerate(zip(labels, "sDv^")):
        other = [(p["turns"] + 0.06 * (j + 1), p[lb + "_x_over_L"], p[lb + "_err"]) for p in points
                 if p.get(lb + "_x_over_L") is not None]
        if other:
            a.errorbar(*zip(*other), fmt=fmt, color=f"C{j + 1}", ms=3, capsize=2, alpha=0.7,
                       label=LEGEND.get(lb, lb))
    a.errorbar(t, [p["x_over_L"] for p in points], yerr=[p["err"] for p in points], fmt="ko-", ms=4, capsize=3,
               label="replica exchange along the turns (--start exchange)")
    a.set_ylabel("extension / contour length")
    a.set_title(f"1 kbp at 1 pN, dna-default, 0.15 M (calibrated charge), 300 K: {title}", fontsize=9)
    a.legend(fontsize=7, loc="lower center")
    b = ax[1]
    b.plot(t, [100 * p["rel_err"] for p in points], "ko-", ms=4, label="error / x (%)")
    b.axhline(100 * target, color="0.5", lw=0.8, ls="--")
    mids = [(0.5 * (p["turns"] + q["turns"]), 100 * p["acceptance_up"]) for p, q in zip(points, points[1:])
            if p.get("acceptance_up") is not None]
    b.plot(*zip(*mids), "^:", color="C5", ms=4, label="swap acceptance of the pair (%)")
    b.set(ylabel="%", xlabel="turns")
    b.legend(fontsize=7)
    from dnarod.analysis.plots import save_figure  # atomic PNG, 110 dpi

    path.parent.mkdir(parents=True, exist_ok=True)
    print(f"wrote {path.parent / save_figure(fig, path.parent, path.name)}")


if __name__ == "__main__":
    main()
