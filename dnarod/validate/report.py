"""Writing the validation report folder: ``results.json``, ``report.md`` (plots are written by the checks).

``results.json`` has exactly the form ``{"checks": {NAME: {"passed": true|false, ...}}}``; the other
entries of a check are its measured values and tolerances (JSON numbers; non-finite values as
strings). All files are written atomically.
"""
from __future__ import annotations

import datetime
import json
import os
import platform

from dnarod.core.io import write_text_atomic
from dnarod.validate._common import jsonable


#: The report's own files (the plots are the checks'; ``results.json`` lists them).
REPORT_FILES = ("results.json", "report.md")


def old_report(out_dir):
    """``(name of a report file in out_dir or None, plots the earlier results.json lists)``."""
    present = [f for f in REPORT_FILES if os.path.exists(os.path.join(out_dir, f))]
    plots = []
    try:
        with open(os.path.join(out_dir, "results.json")) as fh:
            old = json.load(fh)
        plots = [str(p) for r in old["checks"].values() for p in (r.get("plots") or [])]
    except (OSError, ValueError, KeyError, TypeError, AttributeError):
        pass
    return (present[0] if present else None), plots


def _fmt(x, spec=".3g"):
    try:
        return format(float(x), spec)
    except (TypeError, ValueError):
        return str(x)


def headline(name, r):
    """``(measured, tolerance)`` one-line strings for the summary table."""
    if "error" in r:
        return f"error: {r['error']}", "-"
    if "headline" in r:  # a check may state its own summary line
        return str(r["headline"]), str(r.get("headline_tolerance", "-"))
    try:
        if name == "engines":
            o, s = r["openmm"], r["lax_splitting"]
            return (f"OpenMM order {_fmt(o['order_positions'], '.2f')}, |dr| {_fmt(o['max_position_difference_nm'][-1])} nm "
                    f"at dt {r['dt_ps'][-1]} ps (half-step start: order {_fmt(r['openmm_half_step']['order_positions'], '.2f')}, "
                    f"{_fmt(r['openmm_half_step']['max_position_difference_nm'][-1])} nm); Lax splitting order "
                    f"{_fmt(s['order_positions'], '.2f')}",
                    f"order {r['order_min']}-{r['order_max']}, |dr| < {r['small_dt_position_tol_nm']:g} nm")
        if name == "thermal":
            eng = [e for e in ("lax", "openmm") if e in r]
            parts = [f"{e}: max|z| {_fmt(r[e]['max_abs_z'], '.2f')}, lp {_fmt(r[e]['persistence_length']['measured_nm'], '.2f')}"
                     f"+-{_fmt(r[e]['persistence_length']['standard_error_nm'], '.2f')} nm, T "
                     f"{_fmt(r[e]['kinetic_temperature']['measured_K'], '.1f')}+-"
                     f"{_fmt(r[e]['kinetic_temperature']['standard_error_K'], '.1f')} K" for e in eng]
            lp = r[eng[0]]["persistence_length"]["exact_nm"] if eng else float("nan")
            return "; ".join(parts) + f" (exact lp {_fmt(lp, '.2f')} nm)", f"|z| <= {r['z_tolerance']}"
        if name == "dispersion":
            e = max(r[k]["max_frequency_error"] for k in ("openmm_fast", "openmm_portable"))
            return (f"max |omega - exact| {_fmt(e)} rad/ps (omega_max {_fmt(r['omega_max_exact'], '.4f')})",
                    f"< {r['frequency_tol_rad_per_ps']:g} rad/ps")
        if name == "helix":
            f = max(v for s in r["systems"].values() for k, v in s.items() if k.endswith("max_force"))
            t = max(v for s in r["systems"].values() for k, v in s.items() if k.endswith("max_torque"))
            d = max(v for s in r["systems"].values() for k, v in s.items() if k.endswith("drift_nm"))
            return (f"max |F| {_fmt(f)} kJ/mol/nm, |tau| {_fmt(t)} kJ/mol, drift {_fmt(d)} nm in {r['run_time_ps']} ps",
                    f"|F| < {r['force_tol_kJmol_nm']:g}, |tau| < {r['torque_tol_kJmol']:g}, drift < {r['drift_tol_nm']:g} nm")
        if name == "paper_scheme":
            o = ", ".join(_fmt(v, ".2f") for v in r["observed_order_last_pair"].values())
            return (f"orders (Gamma, Omega, p, m) {o}; growth rate {_fmt(r['growth_rate_per_ps'], '.3f')}/ps "
                    f"(exact {_fmt(r['exact_growth_rate_per_ps'], '.1e')}/ps)",
                    f"order {r['order_min']}-{r['order_max']}, rate > {r['unstable_rate_min_per_ps']:g}/ps, "
                    f"exact < {r['exact_rate_max_per_ps']:g}/ps")
        if name == "force_extension":
            rows = r["forces"]
            worst = max(rows, key=lambda q: abs(q["difference"]) - q["tolerance"])
            return (f"x/L - WLC from {_fmt(min(q['difference'] for q in rows), '.3f')} to "
                    f"{_fmt(max(q['difference'] for q in rows), '.3f')} (worst at {worst['force_pN']} pN: "
                    f"{_fmt(worst['difference'], '.3f')} vs tol {_fmt(worst['tolerance'], '.3f')})",
                    f"|diff| <= {r['z_tolerance']} SE + {r['absolute_allowance']}")
        if name == "torsion":
            sl, fl = r["slope"], r["fluctuation"]
            return (f"C_eff slope {_fmt(sl['C_eff_nm'], '.1f')}+-{_fmt(sl['standard_error_nm'], '.1f')} nm, "
                    f"fluctuations {_fmt(fl['C_eff_nm'], '.1f')}+-{_fmt(fl['standard_error_nm'], '.1f')} nm, "
                    f"Moroz-Nelson {_fmt(r['moroz_nelson_C_eff_nm'], '.1f')} nm",
                    f"agree within {r['z_tolerance']} SE; theory {r['z_tolerance']} SE + "
                    f"{100 * r['theory_allowance_relative']:.0f}%")
        if name == "plectonemes":
            return (f"writhe fraction {_fmt(r['model_writhe_fraction'], '.3f')}+-{_fmt(r['model_writhe_fraction_err'], '.3f')}"
                    f" at sigma {_fmt(r['sigma'], '.4f')} vs worm-like ring MC {_fmt(r['reference_writhe_fraction'], '.3f')}"
                    f"+-{_fmt(r['reference_writhe_fraction_err'], '.3f')} (A {_fmt(r['reference_persistence_length_nm'], '.1f')},"
                    f" C {_fmt(r['reference_twist_persistence_nm'], '.1f')}, the model's pair energy: "
                    f"{r['nonbonded']['charge_model']} {_fmt(r['nonbonded']['charge_e_per_node'], '.2f')} e/bp, cutoff "
                    f"{_fmt(r['nonbonded']['cutoff_debye'], '.0f')} Debye lengths); hard core d_eff "
                    f"{_fmt(r['effective_diameter_nm'], '.2f')} nm: {_fmt(r['hard_core_writhe_fraction'], '.3f')}"
                    f"+-{_fmt(r['hard_core_writhe_fraction_err'], '.3f')};"
                    f" ΔLk {_fmt(r['delta_lk'], '.3f')} relative to the relaxed twist at T"
                    + (f"; planar vs writhed start: ΔWr {_fmt(r['bracket']['difference'], '.3f')}"
                       f"+-{_fmt(r['bracket']['standard_error'], '.3f')}" if r.get("bracket") else ""),
                    f"{r['z_tolerance']} SE (= {_fmt(r['tolerance'], '.3f')})")
        if name == "nicked_ring":
            f = r.get("full") or {}
            h = r.get("harmonic") or {}
            return (f"Var(Wr*) {_fmt(r['model_wr_star_var'], '.5f')}+-{_fmt(r['model_wr_star_var_err'], '.5f')} (Wr* = Lk -"
                    f" step twist) vs worm-like ring MC {_fmt(r['reference_wr2'], '.5f')}+-{_fmt(r['reference_wr2_err'], '.5f')}"
                    f" ({_fmt(r['reference_segment_nm'], '.2f')}-nm segments)"
                    + (f", harmonic ring {_fmt(h['wr2'], '.5f')}+-{_fmt(h['wr2_err'], '.5f')}" if h else "")
                    + f"; <ΔTw²> {_fmt(r['twist_variance_exact_turns2'], '.4f')} (continuum "
                    f"{_fmt(r['twist_variance_continuum_turns2'], '.4f')}); K {_fmt(r['K_sampled_size'], '.0f')}+-"
                    f"{_fmt(r['K_sampled_size_err'], '.0f')} at this size"
                    + (f"; {f['n_bp']} bp (exact twist + MC writhe): K {_fmt(f['K'], '.0f')}+-{_fmt(f['K_err'], '.0f')}"
                       if f else "")
                    + f" (measured K: {'none read' if r.get('measured_K') is None else _fmt(r['measured_K'], '.0f')})",
                    f"{r['z_tolerance']} SE + {100 * r['discrete_allowance_relative']:.0f}% (= {_fmt(r['tolerance'], '.5f')})")
    except (KeyError, TypeError, ValueError, IndexError):
        pass
    return "see results.json", "-"


def _scalars(d, prefix=""):
    """Flatten scalar (and short list) entries of a nested dict for the per-check listing."""
    out = []
    for k, v in d.items():
        if k in ("passed", "plots", "notes", "traceback", "runtime_s"):
            continue
        key = f"{prefix}{k}"
        if isinstance(v, dict):
            out += _scalars(v, key + ".")
        elif isinstance(v, list) and len(v) <= 8 and all(not isinstance(x, (dict, list)) for x in v):
            out.append((key, "[" + ", ".join(_fmt(x) if not isinstance(x, str) else x for x in v) + "]"))
        elif isinstance(v, list):
            out.append((key, f"({len(v)} entries, see results.json)"))
        else:
            out.append((key, v if isinstance(v, str) else _fmt(v, ".6g")))
    return out


def summary_table(results):
    """Plain-text table: check, PASS/FAIL, runtime, measured headline."""
    lines = [f"{'check':16s} {'result':6s} {'time (s)':>9s}  measured"]
    for name, r in results["checks"].items():
        measured, _ = headline(name, r)
        lines.append(f"{name:16s} {'PASS' if r['passed'] else 'FAIL':6s} {r.get('runtime_s', float('nan')):9.1f}  {measured}")
    return "\n".join(lines)


def write_report(out_dir, results, quick=False, runtime_s=None):
    """Write ``results.json`` and ``report.md`` into ``out_dir``; returns the JSON-safe results."""
    import numpy as np

    try:
        import openmm

        omm = openmm.__version__
    except ImportError:  # pragma: no cover - OpenMM is a dependency
        omm = "not installed"
    res = jsonable(results)
    write_text_atomic(os.path.join(out_dir, "results.json"), json.dumps(res, indent=1) + "\n")
    checks = res["checks"]
    all_ok = all(r["passed"] for r in checks.values())
    now = datetime.datetime.now(datetime.timezone.utc).strftime("%Y-%m-%d %H:%M UTC")
    md = [f"# dnarod validation report ({'quick' if quick else 'full'})", "",
          f"- date: {now}", f"- result: **{'all checks passed' if all_ok else 'SOME CHECKS FAILED'}** "
          f"({sum(r['passed'] for r in checks.values())}/{len(checks)} passed)",
          f"- total runtime: {runtime_s:.1f} s" if runtime_s is not None else "- total runtime: n/a",
          f"- machine: {platform.platform()}, {os.cpu_count()} CPUs, Python {platform.python_version()}, "
          f"numpy {np.__version__}, OpenMM {omm}", "",
          "| check | result | runtime (s) | measured | tolerance |", "|---|---|---|---|---|"]
    for name, r in checks.items():
        m, t = headline(name, r)
        m, t = m.replace("|", "\\|"), t.replace("|", "\\|")
        md.append(f"| {name} | {'PASS' if r['passed'] else '**FAIL**'} | {r.get('runtime_s', float('nan')):.1f} | {m} | {t} |")
    for name, r in checks.items():
        md += ["", f"## {name}: {'PASS' if r['passed'] else 'FAIL'}", ""]
        m, t = headline(name, r)
        md += [f"Measured: {m}.", "", f"Tolerance: {t}.", ""]
        for note in r.get("notes", []):
            md.append(f"> {note}")
            md.append("")
        if "error" in r:
            md += ["```", r.get("traceback", r["error"]).rstrip(), "```", ""]
        for p in r.get("plots", []):
            md += [f"![{name}]({p})", ""]
        md.append("<details><summary>all numbers</summary>\n")
        md += [f"- `{k}`: {v}" for k, v in _scalars(r)]
        md.append("\n</details>")
    write_text_atomic(os.path.join(out_dir, "report.md"), "\n".join(md) + "\n")
    return res
