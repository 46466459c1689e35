"""The ensemble's outputs: one table of members (Parquet and CSV), plots against each axis, summary.json.

Table columns: ``member`` (id), ``index``, every setting (units in the names), ``status``,
``error``, then the observables (``X`` and ``X_err``). Timing stays out of the table (it lives in
each ``result.json`` and in ``summary.json``), so the table of a resumed or interrupted run is
identical to an uninterrupted one's.
"""
from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from dnarod.core.extras import require
from dnarod.core.io import atomic_path, write_text_atomic
from dnarod.workflows.ensemble.member import member_dir, read_result

TABLE = "results.parquet"
CSV = "results.csv"
SUMMARY = "summary.json"


def collect_rows(outdir, members):
    """One dict per member from its ``result.json`` (status "pending" if it has none)."""
    rows = []
    for m in members:
        r = read_result(member_dir(outdir, m.id)) or {}
        if r.get("id") not in (None, m.id):
            r = {}
        row = {"member": m.id, "index": m.index, **m.settings, "status": r.get("status", "pending"),
               "error": r.get("error", "")}
        taken = set(row)
        for k, v in (r.get("observables", {}) if r.get("status") == "ok" else {}).items():
            # an observable (and its _err) never overwrites a setting or a bookkeeping column
            base = k[:-4] if k.endswith("_err") else k
            row[f"measured_{k}" if base in taken else k] = v
        rows.append(row)
    return rows


def _columns(rows, setting_keys):
    first = ["member", "index"] + list(setting_keys) + ["status", "error"]
    obs = []
    for r in rows:
        for k in r:
            if k not in first and k not in obs:
                obs.append(k)
    return first + obs


def rows_to_table(rows, setting_keys):
    """A :class:`pyarrow.Table` of the rows (missing values null; types inferred per column)."""
    pa = require("pyarrow", "ensemble")
    cols = _columns(rows, setting_keys)
    data = {}
    for c in cols:
        vals = [r.get(c) for r in rows]
        kinds = {type(v) for v in vals if v is not None}
        if kinds and kinds <= {int, float} and float in kinds:
            vals = [None if v is None else float(v) for v in vals]
        elif len(kinds) > 1:
            vals = [None if v is None else str(v) for v in vals]
        data[c] = vals
    return pa.table(data)


def write_table(table, outdir):
    """Write ``results.parquet`` and ``results.csv`` atomically; returns their paths."""
    pacsv = require("pyarrow.csv", "ensemble")
    pq = require("pyarrow.parquet", "ensemble")

    outdir = Path(outdir)
    with atomic_path(outdir / TABLE) as tmp:
        pq.write_table(table, tmp)
    with atomic_path(outdir / CSV) as tmp:
        pacsv.write_csv(table, tmp)
    return outdir / TABLE, outdir / CSV


#: Observables plotted first when present (others follow, up to ``MAX_PANELS``).
PREFERRED = ["extension_nm", "end_to_end_nm", "clamp_torque_pN_nm", "lk", "measured_turns", "turns",
             "persistence_length_nm", "twist_turns", "writhe_turns", "linking_turns", "potential_kJ_mol",
             "elastic_kJ_mol", "kinetic_temperature_K"]
MAX_PANELS = 9


def plot_axes(rows, axes, outdir, setting_keys=()):
    """One PNG per numeric axis: each observable against the axis (mean over the other axes' seeds).

    Members that differ in other axes are separate lines; replicas (``seed``) are averaged, the
    error bar the larger of their combined block errors (``sqrt(sum err^2) / n``) and their
    spread (``std / sqrt(n)``). Returns the written paths.
    """
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    ok = [r for r in rows if r.get("status") == "ok"]
    if not ok:
        return []
    settings = set(axes) | set(setting_keys) | {"member", "index", "status", "error"}
    floats = [k for k in ok[0] if k not in settings and not k.endswith("_err") and isinstance(ok[0][k], float)]
    obs = [k for k in PREFERRED if k in floats] + [k for k in floats if k not in PREFERRED]
    obs = obs[:MAX_PANELS]
    if not obs:
        return []
    paths = []
    for axis in axes:
        if axis == "seed" or not all(isinstance(r.get(axis), (int, float)) and not isinstance(r.get(axis), bool)
                                     for r in ok):
            continue
        others = [a for a in axes if a not in (axis, "seed", "sequence_name")]
        lines = {}
        for r in ok:
            key = tuple((a, r.get(a)) for a in others)
            lines.setdefault(key, {}).setdefault(r[axis], []).append(r)
        ncol = min(3, len(obs))
        nrow = math.ceil(len(obs) / ncol)
        fig, axs = plt.subplots(nrow, ncol, figsize=(4.2 * ncol, 3.2 * nrow), squeeze=False)
        for ax, name in zip(axs.flat, obs):
            for key, pts in lines.items():
                xs = sorted(pts)
                ys, es = [], []
                for x in xs:
                    v = [p.get(name) for p in pts[x] if isinstance(p.get(name), float)]
                    e = [p.get(name + "_err") for p in pts[x] if isinstance(p.get(name + "_err"), float)]
                    ys.append(np.mean(v) if v else np.nan)
                    err = math.sqrt(sum(x * x for x in e)) / len(e) if e and len(e) == len(v) else np.nan
                    if len(v) >= 2:   # replicas: their spread, if larger than the block errors say
                        err = np.nanmax([err, np.std(v, ddof=1) / math.sqrt(len(v))])
                    es.append(err)
                label = ", ".join(f"{a}={_fmt(v)}" for a, v in key) or None
                ax.errorbar(xs, ys, yerr=np.nan_to_num(es), marker="o", ms=3, capsize=2, label=label)
            ax.set_xlabel(axis)
            ax.set_ylabel(name)
            if name in ("force_pN",) or axis in ("force_pN", "salt_M") and min(r[axis] for r in ok) > 0:
                ax.set_xscale("log")
        for ax in list(axs.flat)[len(obs):]:
            ax.set_visible(False)
        if 1 < len(lines) <= 8:
            axs.flat[0].legend(fontsize=7)
        # fixed margins: tight_layout costs more than the drawing itself
        fig.subplots_adjust(left=0.09, right=0.98, bottom=0.1, top=0.95, wspace=0.42, hspace=0.45)
        path = Path(outdir) / f"plot_{axis}.png"
        with atomic_path(path) as tmp:
            fig.savefig(tmp, dpi=100, format="png")
        plt.close(fig)
        paths.append(path)
    return paths


def _fmt(v):
    return f"{v:.4g}" if isinstance(v, float) else str(v)[:16]


def write_summary(outdir, info):
    """``summary.json`` (atomic)."""
    write_text_atomic(Path(outdir) / SUMMARY, json.dumps(info, indent=1, default=str) + "\n")
    return Path(outdir) / SUMMARY
