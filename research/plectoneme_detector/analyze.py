"""The plectoneme detector on the poses kept by ``run_members.py``: old fixed distances against the rule.

Usage: python analyze.py ROOT

For every ``ROOT/<name>.poses.npz``: the mean plectoneme fraction, length / L and end-loop count with the earlier
fixed distances (25 nm, 6 nm) and with :func:`dnarod.workflows.protocols.measure.detector_distances` of the member's own
non-bonded terms; for tweezers members the fraction implied by the extension, ``1 - x / (zeta L)`` (zeta: the
mean relative extension of the pre-buckling member of the same charge); and the distribution of each node's
distance to its nearest node 25 nm or more along the chain (its peak: the superhelix's strand separation).
"""
import json
import sys
from pathlib import Path

import numpy as np
from scipy.spatial import cKDTree

from dnarod.physics.nonbonded import member_nonbonded
from dnarod.workflows.protocols.measure import detector_distances, plectoneme_end_loops, plectoneme_state
from dnarod.physics.theory.supercoil import effective_diameter

root = Path(sys.argv[1])
DS = 0.34


def nearest_far(X, circular, sep_nm=25.0, rmax=25.0):
    """Distance (nm) from each node to its nearest node at least ``sep_nm`` along the chain (inf beyond rmax)."""
    n = len(X)
    best = np.full(n, np.inf)
    pr = cKDTree(X).query_pairs(rmax, output_type="ndarray")
    if len(pr):
        i, j = pr.min(1), pr.max(1)
        sep = np.minimum(j - i, n - (j - i)) if circular else j - i
        k = sep >= int(np.ceil(sep_nm / DS))
        r = np.linalg.norm(X[i[k]] - X[j[k]], axis=1)
        np.minimum.at(best, i[k], r)
        np.minimum.at(best, j[k], r)
    return best


def _mirror(X, c, kmax, circular, window=30):
    """Distance from node ``c + k`` to the nearest of ``c - k +- window``, k = 1 .. kmax - 1 (``c``: a loop tip)."""
    n = len(X)
    k = np.arange(1, kmax)
    w = np.arange(-window, window + 1)
    a = (c + k[:, None]) % n if circular else np.minimum(c + k[:, None], n - 1)
    b = c - k[:, None] + w[None, :]
    b = b % n if circular else np.clip(b, 0, n - 1)
    return k, np.linalg.norm(X[a] - X[b], axis=2).min(axis=1)


def loop_share(X, centres, separation_nm):
    """Share of a ring's nodes in its end loops, by geometry: from each loop's tip (``centres``) the nodes ``c + k``
    and the nearest of ``c - k +- 30`` move apart and come together again; the loop ends at the first ``k`` past
    their largest distance where they are within ``separation_nm`` (the two strands of the superhelix)."""
    n = len(X)
    tot = 0
    for c in np.rint(centres).astype(int):
        k, g = _mirror(X, c, n // 2, True)
        top = int(np.argmax(g[:len(k) // 2]))
        closed = np.flatnonzero(g[top:] <= separation_nm)
        tot += 2 * (k[top + closed[0]] if len(closed) else n // 2)
    return min(tot / n, 1.0)


def open_plectoneme_share(X, centres, separation_nm):
    """``(whole, interwound)``: shares of an open chain's nodes in its plectoneme(s), by geometry. From each loop
    tip the mirror nodes (as :func:`loop_share`) close to within ``separation_nm`` after the loop and stay close
    along the superhelix; the last ``k`` where they are that close is the plectoneme's base (the tails then part).
    Whole: 2 x base; interwound: 2 x (base - loop end)."""
    n = len(X)
    whole = inter = 0
    for c in np.rint(centres).astype(int):
        kmax = min(c, n - 1 - c)
        if kmax < 3:
            continue
        k, g = _mirror(X, c, kmax, False)
        top = int(np.argmax(g[:max(1, len(k) // 2)]))
        close = np.flatnonzero(g[top:] <= separation_nm)
        if not len(close):
            continue
        end, base = k[top + close[0]], k[top + close[-1]]
        whole += 2 * base
        inter += 2 * (base - end)
    return min(whole / n, 1.0), min(inter / n, 1.0)


rows = {}
for f in sorted(root.glob("*.poses.npz")):
    name = f.name[:-len(".poses.npz")]
    d = np.load(f)
    P = d["positions"].astype(float)
    kind = str(d["kind"])
    settings = json.loads(str(d["settings"]))
    circ = kind == "ring"
    full = dict(excluded_volume=True, electrostatics=True, salt_M=0.15, temperature_K=300.0, **settings)
    nb = member_nonbonded(full)
    rule = detector_distances(nb, 300.0, DS)
    row = dict(kind=kind, n_poses=len(P), d_eff_nm=effective_diameter(nb, DS, 300.0, n_h=80, n_gamma=8, n_offset=2),
               rule_min_separation_nm=rule[0], rule_contact_nm=rule[1])
    for label, (sep, con) in (("fixed", (25.0, 6.0)), ("rule", rule)):
        st = np.array([plectoneme_state(p, DS, sep, con, circular=circ)[:3] for p in P], float)
        loops = np.array([plectoneme_end_loops(p, DS, circular=circ, min_separation_nm=sep,
                                               contact_distance_nm=con)[0] for p in P])
        h = len(P) // 2
        row[label] = dict(fraction=float(st[:, 0].mean()), fraction_halves=[float(st[:h, 0].mean()),
                                                                            float(st[h:, 0].mean())],
                          length_over_L=float(st[:, 1].mean() / (len(P[0]) * DS)),
                          plectonemic_share=float(st[:, 2].mean()), end_loops=float(loops.mean()))
    dn = np.concatenate([nearest_far(p, circ) for p in P])
    fin = dn[np.isfinite(dn)]
    hist, edges = np.histogram(fin[fin < 12.0], bins=np.arange(0.0, 12.01, 0.25))
    row["strand_separation_peak_nm"] = float(edges[np.argmax(hist)] + 0.125)
    if not (fin < 12.0).any():
        row["strand_separation_peak_nm"] = None
    row["nearest_far_quantiles_nm"] = {q: float(np.percentile(fin, q)) for q in (5, 10, 25)} if len(fin) else None
    peak = row["strand_separation_peak_nm"]
    if peak:  # by geometry, loop tips from the rule's end-loop counter, strands within 1.5 / 2 x the peak
        for f in (1.5, 2.0):
            tips = [plectoneme_end_loops(p, DS, circular=circ, min_separation_nm=rule[0],
                                         contact_distance_nm=rule[1])[1] for p in P[::4]]
            if circ:
                sh = [loop_share(p, t, f * peak) for p, t in zip(P[::4], tips)]
                row[f"all_but_end_loops_{f:g}_peak"] = 1.0 - float(np.mean(sh))
            else:
                sh = np.array([open_plectoneme_share(p, t, f * peak) for p, t in zip(P[::4], tips)])
                row[f"plectoneme_geometric_{f:g}_peak"] = float(sh[:, 0].mean())
                row[f"interwound_geometric_{f:g}_peak"] = float(sh[:, 1].mean())
    if kind == "tweezers":
        x = P[:, -1, 2] - P[:, 0, 2]
        row["x_over_L"] = float(x.mean() / (len(P[0]) * DS))
        row["x_over_L_halves"] = [float(x[:len(x) // 2].mean() / (len(P[0]) * DS)),
                                  float(x[len(x) // 2:].mean() / (len(P[0]) * DS))]
    rows[name] = row
for name, row in rows.items():
    if row["kind"] == "tweezers" and "pre" not in name:
        pre = rows[name.split("_")[0] + "_pre" + ("_manning" if name.endswith("_manning") else "")]
        row["zeta"] = pre["x_over_L"]
        row["implied_by_extension"] = 1.0 - row["x_over_L"] / pre["x_over_L"]
for name, row in rows.items():
    pk = row["strand_separation_peak_nm"]
    print(f"{name}: d_eff {row['d_eff_nm']:.2f} nm, rule ({row['rule_min_separation_nm']:.1f}, "
          f"{row['rule_contact_nm']:.2f}) nm, strand-separation peak " + (f"{pk:.2f} nm" if pk else "none")
          + (f", x/L {row['x_over_L']:.3f}" if "x_over_L" in row else "")
          + (f", implied {row['implied_by_extension']:.3f}" if "implied_by_extension" in row else "")
          + (f", all but end loops {row['all_but_end_loops_1.5_peak']:.3f} / {row['all_but_end_loops_2_peak']:.3f}"
             if "all_but_end_loops_2_peak" in row else "")
          + (f", geometric: plectoneme {row['plectoneme_geometric_1.5_peak']:.3f} / "
             f"{row['plectoneme_geometric_2_peak']:.3f}, interwound {row['interwound_geometric_1.5_peak']:.3f} / "
             f"{row['interwound_geometric_2_peak']:.3f}" if "plectoneme_geometric_2_peak" in row else ""))
    for label in ("fixed", "rule"):
        r = row[label]
        print(f"   {label:5s} fraction {r['fraction']:.3f} (halves {r['fraction_halves'][0]:.3f} "
              f"{r['fraction_halves'][1]:.3f}), length/L {r['length_over_L']:.3f}, plectonemic "
              f"{r['plectonemic_share']:.2f}, end loops {r['end_loops']:.2f}")
(root / "analysis.json").write_text(json.dumps(rows, indent=1) + "\n")
