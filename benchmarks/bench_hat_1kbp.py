"""Cost of a 1-kbp hat curve: per-member cost, equilibration and autocorrelation time of the extension, and the
extrapolated cost of a 12-turn curve with the extension to a target precision.

Runs (or reuses) 1000-bp tweezers members at 0.5 pN from the protocol's static start, with a long production that
includes the relaxation (``equilibration_ns`` small on purpose), then analyses ``samples.csv``: the extension in
windows (when it stops drifting), its integrated autocorrelation time and standard deviation after a cut, and the
simulated time a member needs for a standard error of ``target`` (relative, of the extension; and absolute, of
x/L). Prints a table and writes ``benchmarks/results/hat_1kbp.json``.

    python benchmarks/bench_hat_1kbp.py --turns 0,6 --time 40 [--root DIR]
    python benchmarks/bench_hat_1kbp.py --turns 0,6 --cut 10,40 --dirs runs/bench_hat_1kbp/kbp_0.0,runs/bench_hat_1kbp/kbp_6.0_long

``--curve DIR`` analyses a finished ``dnarod protocol hat ... -o DIR`` instead (every member): cost, the
integrated autocorrelation times of extension and writhe, the standard error of the extension (block and
tau-based) relative to its value, the production in quarters (drift) and the curve's span and total CPU time;
writes ``benchmarks/results/hat_1kbp_curve.json`` (the hat-curve study's recorded runs are in
``research/hat_curve/results/``).

    python benchmarks/bench_hat_1kbp.py --curve runs/hat_1kbp_1pN

It reads both layouts: members of the ensemble (``DIR/ensemble/members``) and of a turn sweep
(``research/turn_sweeps/turn_sweep.py``, or ``--start exchange``: ``DIR/members``, whose start time is taken as the result's time less its wall time).

    python benchmarks/bench_hat_1kbp.py --curve runs/hat1k_sweep --out benchmarks/results/hat_1kbp_sweep.json

``--extend DIR[,DIR...]`` continues finished members of a sweep at their own turns (their final pose, a settle of
``--settle`` ns, then ``--time`` ns), in ``--root``/<name>, and analyses them (finished continuations are reused);
writes ``benchmarks/results/hat_1kbp_extend.json``.

    python benchmarks/bench_hat_1kbp.py --extend runs/hat1k_sweep/members/force_pN+1_turns+4,runs/hat1k_sweepin/members/force_pN+1_turns+4 --settle 100 --time 40 --root runs/hat1k_cont
"""
from __future__ import annotations

import argparse
import json
import os
import time
from pathlib import Path

import numpy as np


def analyse(member_dir, cut_ns, windows=(0, 2, 5, 10, 20, 30, 40, 50, 60, 70, 1e9)):
    from dnarod.analysis.polymer import integrated_autocorrelation_time

    res = json.loads((Path(member_dir) / "protocol_result.json").read_text())["result"]
    d = np.genfromtxt(Path(member_dir) / "samples.csv", delimiter=",", names=True)
    L = res["contour_length_nm"]
    x, t = d["extension_nm"] / L, d["time_ps"] / 1000.0
    win = []
    for a, b in zip(windows[:-1], windows[1:]):
        m = (t >= a) & (t < b)
        if m.any():
            win.append(dict(from_ns=a, to_ns=float(min(b, t[-1])), x_over_L=float(x[m].mean()),
                            plectoneme_fraction=float(d["plectoneme_fraction"][m].mean())))
    m = t >= cut_ns
    y = x[m]
    dt = float(t[1] - t[0])
    tau = float(integrated_autocorrelation_time(y)) * dt
    return dict(turns=res["turns"], force_pN=res["force_pN"], n_bp=res["n_bp"], wall_s=res["wall_s"], cpu_s=res["cpu_s"],
                simulated_ns=res["n_steps"] * res["dt_ps"] / 1000.0, ns_per_day_wall=res["ns_per_day"],
                ns_per_day_cpu=res["n_steps"] * res["dt_ps"] / 1000.0 / res["cpu_s"] * 86400.0,
                elastic_path=res.get("elastic_path"), friction_per_ps=res["friction_per_ps"],
                tau_bend_estimate_ns=res["tau_bend_estimate_ps"] / 1000.0, windows=win, cut_ns=cut_ns,
                x_over_L=float(y.mean()), sd_x_over_L=float(y.std()), tau_int_extension_ns=tau,
                n_effective=float((t[m][-1] - t[m][0]) / (2 * tau)))


def analyse_curve(outdir, target=0.03):
    """Per-member statistics and the whole-curve cost of a finished protocol folder (see the module docstring)."""
    import datetime as _dt

    from dnarod.analysis.polymer import integrated_autocorrelation_time

    rows, starts, ends = [], [], []
    found = sorted(Path(outdir).glob("ensemble/members/*/protocol_result.json")) \
        + sorted(Path(outdir).glob("members/*/protocol_result.json"))  # a turn sweep (--start sweep)
    for rj in found:
        mdir = rj.parent
        res = json.loads(rj.read_text())["result"]
        d = np.genfromtxt(mdir / "samples.csv", delimiter=",", names=True)
        L = res["contour_length_nm"]
        x, t = d["extension_nm"] / L, d["time_ps"] / 1000.0
        dt = float(t[1] - t[0])
        tau_x = float(integrated_autocorrelation_time(x)) * dt
        tau_wr = float(integrated_autocorrelation_time(d["Wr"])) * dt
        se_tau = float(x.std(ddof=1) * np.sqrt(2.0 * tau_x / dt / len(x)))
        se_block = float(res["relative_extension_err"])
        q = [float(v.mean()) for v in np.array_split(x, 4)]
        h1, h2 = np.array_split(x, 2)
        se_half = se_tau * np.sqrt(2.0)  # SE of a half's mean
        if (mdir / "member.log").exists():
            for line in (mdir / "member.log").read_text().splitlines():
                if " start: " in line:
                    starts.append(_dt.datetime.strptime(line[:19], "%Y-%m-%d %H:%M:%S").timestamp())
        else:  # a sweep's member (no ensemble log): its result's time less its wall time
            starts.append(rj.stat().st_mtime - float(res["wall_s"]))
        ends.append(rj.stat().st_mtime)
        rows.append(dict(folder=mdir.name, turns=res["turns"], previous_turns=res.get("previous_turns"), start=res.get("start"),
                         force_pN=res["force_pN"], n_bp=res["n_bp"], wall_s=res["wall_s"],
                         cpu_s=res["cpu_s"], simulated_ns=res["n_steps"] * res["dt_ps"] / 1000.0,
                         equilibration_ns=res["equilibration_ps"] / 1000.0, production_ns=res["production_ps"] / 1000.0,
                         ns_per_cpu_day=res["n_steps"] * res["dt_ps"] / 1000.0 / res["cpu_s"] * 86400.0,
                         friction_per_ps=res["friction_per_ps"], sample_ps=res["sample_ps"],
                         x_over_L=float(x.mean()), sd_x_over_L=float(x.std(ddof=1)),
                         se_block=se_block, se_tau=se_tau, se_rel=max(se_block, se_tau) / float(x.mean()),
                         tau_int_extension_ns=tau_x, tau_int_wr_ns=tau_wr,
                         n_effective=float(len(x) * dt / (2.0 * tau_x)), quarters_x_over_L=q,
                         drift_z=float((h2.mean() - h1.mean()) / (np.sqrt(2.0) * se_half)),
                         Wr=res["Wr"], delta_lk=res["delta_lk"], plectoneme_fraction=res["plectoneme_fraction"],
                         twist_torque_pN_nm=res["twist_torque_pN_nm"], lk_slips=res["lk_slips"],
                         production_ns_for_target=2 * tau_x * (float(x.std(ddof=1)) / (target * float(x.mean()))) ** 2))
    rows.sort(key=lambda r: r["turns"])
    span = (max(ends) - min(starts)) if rows else 0.0
    total = dict(members=len(rows), member_cpu_s=sum(r["cpu_s"] for r in rows),
                 member_wall_s=sum(r["wall_s"] for r in rows), simulated_ns=sum(r["simulated_ns"] for r in rows),
                 span_wall_s=span, max_se_rel=max(r["se_rel"] for r in rows) if rows else None,
                 members_meeting_target=sum(r["se_rel"] <= target for r in rows))
    return rows, total


def needed_ns(a, target_rel, target_abs):
    """Production (ns) for SE(x/L) <= target_rel * x/L and for SE(x/L) <= target_abs (SE = sd sqrt(2 tau / T))."""
    rel = 2 * a["tau_int_extension_ns"] * (a["sd_x_over_L"] / (target_rel * a["x_over_L"])) ** 2
    ab = 2 * a["tau_int_extension_ns"] * (a["sd_x_over_L"] / target_abs) ** 2
    return rel, ab


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--turns", default="0,6")
    ap.add_argument("--force", type=float, default=0.5)
    ap.add_argument("--time", type=float, default=40.0, help="ns per member (relaxation included)")
    ap.add_argument("--cut", default="10,10", help="ns discarded per member (same order as --turns)")
    ap.add_argument("--root", default="runs/bench_hat_1kbp")
    ap.add_argument("--post-equilibration", type=float, default=None,
                    help="ns of equilibration to assume for post-buckling members (default: the cut)")
    ap.add_argument("--curve-members", type=int, default=12)
    ap.add_argument("--target", type=float, default=0.03)
    ap.add_argument("--out", default="benchmarks/results/hat_1kbp.json")
    ap.add_argument("--curve", default=None, help="a finished `dnarod protocol hat` folder: analyse its members")
    ap.add_argument("--figure", default=None,
                    help="with --curve: also write the curve's CSV + PNG (the protocol's own writer and plot) from "
                         "the finished members to FIGURE.csv / FIGURE.png (for a curve still running or stopped)")
    ap.add_argument("--extend", default=None, help="comma-separated finished sweep members to continue at their turns")
    ap.add_argument("--settle", type=float, default=100.0, help="with --extend: settle before the production, ns")
    ap.add_argument("--dirs", default=None, help="comma-separated finished member folders to analyse instead of "
                                                  "running (same order as --turns/--cut)")
    a = ap.parse_args(argv)
    if a.curve:
        return main_curve(a)
    if a.extend:
        return main_extend(a)
    from dnarod.workflows.protocols.tweezers import run_member

    turns = [float(t) for t in a.turns.split(",")]
    cuts = [float(c) for c in a.cut.split(",")]
    rows = []
    dirs = a.dirs.split(",") if a.dirs else [None] * len(turns)
    for t, cut, given in zip(turns, cuts, dirs):
        d = Path(given) if given else Path(a.root) / f"kbp_{t}"
        if not given:
            run_member(dict(n_bp=1000, force_pN=a.force, turns=t, time_ns=a.time, equilibration_ns=0.2, seed=11,
                            sample_ps=20.0), d)
        r = analyse(d, cut)
        r["production_ns_rel"], r["production_ns_abs"] = needed_ns(r, a.target, a.target)
        rows.append(r)
    # extrapolation: half the members pre-buckling (like turns[0]), half post-buckling (like turns[-1])
    pre, post = rows[0], rows[-1]
    half = a.curve_members / 2
    ext = {}
    for kind in ("rel", "abs"):
        eq_post = post["cut_ns"] if a.post_equilibration is None else a.post_equilibration
        total = half * (pre["cut_ns"] + pre[f"production_ns_{kind}"]) + half * (eq_post + post[f"production_ns_{kind}"])
        ext[kind] = dict(total_simulated_ns=total,
                         hours_2_dedicated_cores=total / (2 * np.mean([r["ns_per_day_cpu"] for r in rows])) * 24,
                         hours_2_workers_as_measured=total / (2 * np.mean([r["ns_per_day_wall"] for r in rows])) * 24)
    out = dict(date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), load_average=os.getloadavg(), members=rows,
               target=a.target, curve_members=a.curve_members, extrapolation=ext,
               post_equilibration_ns=a.post_equilibration,
               note="post-buckling equilibration from the static start is a lower bound if the windows still drift")
    Path(a.out).parent.mkdir(parents=True, exist_ok=True)
    Path(a.out).write_text(json.dumps(out, indent=1) + "\n")
    print(f"{'turns':>6} {'wall s':>8} {'cpu s':>8} {'ns/day wall':>12} {'ns/day cpu':>11} {'x/L':>6} {'sd':>6} "
          f"{'tau_int ns':>10} {'prod rel':>9} {'prod abs':>9}")
    for r in rows:
        print(f"{r['turns']:6.1f} {r['wall_s']:8.0f} {r['cpu_s']:8.0f} {r['ns_per_day_wall']:12.0f} "
              f"{r['ns_per_day_cpu']:11.0f} {r['x_over_L']:6.3f} {r['sd_x_over_L']:6.3f} {r['tau_int_extension_ns']:10.2f} "
              f"{r['production_ns_rel']:9.0f} {r['production_ns_abs']:9.0f}")
        print("       windows:", ", ".join(f"{w['from_ns']:g}-{w['to_ns']:.0f} ns {w['x_over_L']:.3f}" for w in r["windows"]))
    for k, e in ext.items():
        print(f"12-member curve, SE {'relative' if k == 'rel' else 'absolute'} {a.target}: {e['total_simulated_ns']:.0f} ns "
              f"simulated, {e['hours_2_dedicated_cores']:.2f} h on 2 dedicated cores, "
              f"{e['hours_2_workers_as_measured']:.2f} h at the measured (shared) speed")


def main_extend(a):
    """Continue sweep members at their own turns and analyse the continuations (see the module docstring)."""
    from dnarod.workflows.protocols.poses import load_pose
    from dnarod.workflows.protocols.tweezers import run_member

    rows = []
    for src in a.extend.split(","):
        src = Path(src)
        old = json.loads((src / "protocol_result.json").read_text())["result"]
        out = Path(a.root) / ("sweepin" if "sweepin" in str(src) else "sweep")
        s = dict(n_bp=old["n_bp"], force_pN=old["force_pN"], turns=old["turns"], previous_turns=old["turns"],
                 time_ns=a.time, equilibration_ns=a.settle, seed=old["seed"], clamp_k_kJ_mol=250.0, threads=1)
        run_member(s, out, start_pose=load_pose(src / "final_pose.npz"))
        r = analyse(out, 0.0)
        r.update(source=str(src), before_x_over_L=old["relative_extension"], settle_ns=a.settle,
                 quarters_x_over_L=[w for w in _quarters(out)])
        rows.append(r)
    out = dict(date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), load_average=os.getloadavg(), members=rows)
    path = Path(a.out).with_name("hat_1kbp_extend.json")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1) + "\n")
    for r in rows:
        print(f"{r['source']}: before {r['before_x_over_L']:.3f}; +{r['settle_ns']:g} ns settle: x/L {r['x_over_L']:.3f} "
              f"sd {r['sd_x_over_L']:.3f} tau_int {r['tau_int_extension_ns']:.2f} ns, quarters "
              + " ".join(f"{q:.3f}" for q in r["quarters_x_over_L"]) + f"; {r['cpu_s']:.0f} CPU-s, {r['wall_s']:.0f} s wall")
    return out


def _quarters(member_dir):
    res = json.loads((Path(member_dir) / "protocol_result.json").read_text())["result"]
    d = np.genfromtxt(Path(member_dir) / "samples.csv", delimiter=",", names=True)
    return [float(v.mean()) for v in np.array_split(d["extension_nm"] / res["contour_length_nm"], 4)]


def main_curve(a):
    rows, total = analyse_curve(a.curve, a.target)
    out_path = Path(a.out).with_name("hat_1kbp_curve.json") if a.out.endswith("hat_1kbp.json") else Path(a.out)
    out = dict(date=time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime()), load_average=os.getloadavg(),
               folder=str(a.curve), target=a.target, total=total, members=rows)
    out_path.parent.mkdir(parents=True, exist_ok=True)
    out_path.write_text(json.dumps(out, indent=1) + "\n")
    if a.figure:
        from dnarod.workflows.protocols.curves import _write_csv, plot_curve

        obs = []
        for rj in Path(a.curve).glob("ensemble/members/*/result.json"):
            r = json.loads(rj.read_text())
            if r.get("status") == "ok":
                obs.append(dict(r["observables"], force_pN=r["settings"]["force_pN"], turns=r["settings"]["turns"]))
        for rj in Path(a.curve).glob("members/*/protocol_result.json"):  # a turn sweep's finished members
            obs.append(json.loads(rj.read_text())["result"])
        obs.sort(key=lambda r: r["turns"])
        _write_csv(obs, Path(a.figure + ".csv"))
        plot_curve("magnetic_tweezers", obs, Path(a.figure + ".png"))
        print(f"wrote {a.figure}.csv and {a.figure}.png ({len(obs)} finished members)")
    print(f"{'turns':>6} {'from':>5} {'eq+prod ns':>10} {'wall s':>7} {'cpu s':>6} {'ns/CPU-day':>10} {'x/L':>6} {'sd':>6} "
          f"{'SE blk':>7} {'SE tau':>7} {'SE/x':>6} {'tau_x ns':>8} {'tau_Wr ns':>9} {'Wr':>6} {'plect':>5} "
          f"{'drift z':>7}  quarters")
    for r in rows:
        frm = "-" if r.get("previous_turns") is None else f"{r['previous_turns']:+.1f}"
        print(f"{r['turns']:6.1f} {frm:>5} {r['equilibration_ns']:4.0f}+{r['production_ns']:<5.0f} {r['wall_s']:7.0f} "
              f"{r['cpu_s']:6.0f} {r['ns_per_cpu_day']:10.0f} {r['x_over_L']:6.3f} {r['sd_x_over_L']:6.3f} "
              f"{r['se_block']:7.4f} {r['se_tau']:7.4f} {100 * r['se_rel']:5.1f}% {r['tau_int_extension_ns']:8.2f} "
              f"{r['tau_int_wr_ns']:9.2f} {r['Wr']:6.2f} {r['plectoneme_fraction']:5.2f} {r['drift_z']:7.1f}  "
              + " ".join(f"{v:.3f}" for v in r["quarters_x_over_L"]))
    t = total
    print(f"{t['members']} members, {t['simulated_ns']:.0f} ns simulated; member CPU {t['member_cpu_s']:.0f} s = "
          f"{t['member_cpu_s'] / 3600:.2f} core-hours; member wall {t['member_wall_s']:.0f} s; span (first start to "
          f"last finish) {t['span_wall_s']:.0f} s = {t['span_wall_s'] / 3600:.2f} h; SE/x <= {100 * a.target:g}% in "
          f"{t['members_meeting_target']} of {t['members']} (largest {100 * t['max_se_rel']:.1f}%)")
    return out


if __name__ == "__main__":
    main()
