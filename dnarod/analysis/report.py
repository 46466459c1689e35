"""The analysis report of a trajectory (the API of ``dnarod analyze``): step parameters, strains,
stiffness, persistence length, Lk/Tw/Wr, written to a report folder.

Input is a dnarod ``.dtraj`` trajectory (model from ``topology=MODEL.npz``, or the
``final_model.npz`` written beside it by ``dnarod simulate``) or an all-atom trajectory in any
format MDAnalysis reads (a topology PDB/PSF/PRMTOP/...; a PDB/mmCIF alone is analysed as its
own frames). Outputs: CSV tables, the fitted stiffness as force-field TOML files, PNG plots and
``summary.json`` (:data:`REPORT_FILES`); an existing report is replaced only with ``overwrite``,
which first removes the report's own files (no stale plot survives).
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError, StructureError, positive_number
from dnarod.core.io import jsonable

#: Files ``analyze`` may write in its report folder (``overwrite`` removes exactly these).
REPORT_FILES = ("summary.json", "step_parameters.csv", "step_parameters_mean.csv", "stiffness_table.csv",
                "stiffness.toml", "sequence_stiffness.toml", "tangent_correlation.csv", "end_to_end.csv",
                "linking.csv", "strain_distributions.png", "tangent_correlation.png", "step_parameters.png")


def prepare_report_folder(out, overwrite=False):
    """Create the report folder; refuse to replace an earlier report unless ``overwrite`` (then remove it).

    Raises
    ------
    DnarodError
        ``out`` (or a parent) is a regular file, it holds a report and ``overwrite`` is false, or it is not empty
        and holds no report (``-o ~``, a run folder; :func:`dnarod.core.io.check_output_folder`).
    """
    from dnarod.core.io import check_dir_path, check_output_folder, ensure_dir

    out = check_dir_path(Path(out), what="report folder")
    check_output_folder(out, REPORT_FILES, "analysis report", what="report folder")
    present = [out / f for f in REPORT_FILES if (out / f).exists()]
    if present and not overwrite:
        raise DnarodError(f"{out} already holds an analysis report ({present[0].name}); pass --overwrite to replace "
                          f"it or choose another folder with -o")
    ensure_dir(out, what="report folder")
    return out, present


def _write_rows(path, rows):
    from dnarod.core.io import atomic_path

    if not rows:
        return
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def load_input(path, topology=None, duplex=1, start=None, stop=None, step=None):
    """Read the input trajectory (``duplex``: which duplex of an all-atom system, from 1).

    Returns
    -------
    traj : Trajectory
    model : RodModel or None
        The dnarod model (``--topology`` or ``final_model.npz`` next to a ``.dtraj``).
    kind : str
        ``"dnarod"`` or ``"all-atom"``.
    """
    from dnarod.core.model import RodModel
    from dnarod.core.trajectory import Trajectory

    path = Path(path)
    if not path.exists():
        raise DnarodError(f"{path}: no such file")
    if path.suffix == ".dtraj":
        traj = Trajectory.load(path)
        model = None
        top = Path(topology) if topology else (path.parent / "final_model.npz")
        if topology or top.exists():
            if top.suffix != ".npz":
                raise DnarodError(f"{top}: the topology of a .dtraj trajectory is a dnarod model file (.npz)")
            model = RodModel.load(top)
            if model.n_nodes != traj.n_nodes:
                raise DnarodError(f"{path} has {traj.n_nodes} nodes per frame but its topology {top} has "
                                  f"{model.n_nodes}: the trajectory does not match its topology")
        traj = traj[slice(start, stop, step)]
        return traj, model, "dnarod"
    from dnarod.structure.trajectory import is_structure_file, read_node_trajectory
    from dnarod.analysis.allatom import load_allatom

    _check_magic(path)
    try:
        with _c_stderr_held():
            nodes = read_node_trajectory(path, topology)  # oxDNA (--topology X.top) or a dnarod CG export (PDB/DCD)
    except DnarodError:
        raise
    except (OSError, ValueError, EOFError, IndexError, KeyError, UnicodeDecodeError) as exc:
        raise StructureError(_unreadable(path, topology, exc)) from None
    if nodes is not None:
        return nodes[slice(start, stop, step)], None, "dnarod"
    duplex = int(duplex)
    if duplex < 1:
        raise DnarodError(f"--duplex {duplex}: duplexes are numbered from 1 (see `dnarod pairs TOPOLOGY`)")
    duplex -= 1
    if topology is None and not is_structure_file(path):
        raise StructureError(f"{path}: an all-atom trajectory needs --topology (PDB, PSF, PRMTOP, GRO, ...)")
    try:
        with _c_stderr_held():
            if topology is None:
                traj, _ = load_allatom(path, None, duplex, start, stop, step)
            else:
                traj, _ = load_allatom(topology, path, duplex, start, stop, step)
    except DnarodError:
        raise
    except (OSError, ValueError, EOFError, IndexError, KeyError, UnicodeDecodeError) as exc:
        raise StructureError(_unreadable(path, topology, exc)) from None
    return traj, None, "all-atom"


class _c_stderr_held:
    """Hold back what C readers (MDAnalysis's dcdplugin) print straight to file descriptors 1 and 2: replayed
    after a successful read, dropped when the read fails (the error is then one line of ours)."""

    def __enter__(self):
        import os
        import sys
        import tempfile

        self.held = []
        for fd in (1, 2):
            try:
                (sys.stdout if fd == 1 else sys.stderr).flush()
                saved = os.dup(fd)
            except (OSError, ValueError, AttributeError):
                continue
            tmp = tempfile.TemporaryFile()
            os.dup2(tmp.fileno(), fd)
            self.held.append((fd, saved, tmp))
        return self

    def __exit__(self, kind, exc, tb):
        import os

        for fd, saved, tmp in self.held:
            os.dup2(saved, fd)
            os.close(saved)
            if kind is None:
                tmp.seek(0)
                data = tmp.read()
                if data:
                    os.write(fd, data)
            tmp.close()
        return False


def _check_magic(path):
    """Refuse a DCD or XTC file whose first bytes are not the format's, before a C reader prints its own
    complaint on stderr (DCD: a Fortran record of 84 bytes holding "CORD"; XTC: the magic number 1995)."""
    suffix = path.suffix.lower()
    if suffix not in (".dcd", ".xtc"):
        return
    with open(path, "rb") as fh:
        head = fh.read(8)
    if suffix == ".dcd":
        ok = len(head) == 8 and head[4:8] == b"CORD" and int.from_bytes(head[:4], "little") in (84, 84 << 24)
    else:
        ok = len(head) >= 4 and int.from_bytes(head[:4], "big") == 1995
    if not ok:
        kind = "empty" if not head else f"not a {suffix[1:].upper()} file (its first bytes are not the format's)"
        raise StructureError(f"{path}: {kind}; give a complete trajectory written by OpenMM, mdtraj, MDAnalysis or "
                             f"`dnarod simulate --export`")


def _unreadable(path, topology, exc):
    """One line for a trajectory or topology file its reader (MDAnalysis, mdtraj) could not read."""
    what = " ".join(str(exc).split())[:160] or type(exc).__name__
    top = f" with topology {topology}" if topology else ""
    return (f"{path}{top}: cannot read it as a trajectory ({what}); check that the file is complete and matches "
            f"its --topology")


def _check_arguments(input_path, temperature, start, stop, step, exclude_ends, n_blocks, duplex):
    """Refuse bad analysis arguments with one line naming the option, before anything is read or written."""
    if not isinstance(input_path, (str, Path)) or not str(input_path).strip():
        raise DnarodError(f"INPUT {input_path!r}: give a trajectory or structure file")

    def integer(opt, v, ok, what):
        if v is None:
            return
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not ok(int(v)):
            raise DnarodError(f"{opt} {v!r}: must be {what}")

    integer("--start", start, lambda k: k >= 0, "a frame number >= 0 (frames count from 0)")
    integer("--stop", stop, lambda k: k >= 1, "a frame number >= 1 (the analysis stops before it)")
    integer("--step", step, lambda k: k >= 1, "an integer >= 1 (every STEP-th frame)")
    integer("--exclude-ends", exclude_ends, lambda k: k >= 0, "an integer >= 0 (steps left out at each end)")
    integer("--blocks", n_blocks, lambda k: k >= 2, "an integer >= 2 (blocks for the error bars)")
    integer("--duplex", duplex, lambda k: k >= 1, "an integer >= 1 (duplexes are numbered from 1, see `dnarod pairs`)")
    if start is not None and stop is not None and stop <= start:
        raise DnarodError(f"--start {start} --stop {stop}: no frame left; --stop must be above --start")
    if temperature is not None and positive_number(temperature) is None:
        raise DnarodError(f"--temperature {temperature}: must be a positive temperature in K")


def analyze(input_path, topology=None, forcefield=None, out=None, circular=False, temperature=None,
            start=None, stop=None, step=None, exclude_ends=None, n_blocks=10, allow_gaps=False, duplex=1,
            plots=True, echo=print, overwrite=False):
    """Run every analysis on a trajectory and write the report folder (the API of ``dnarod analyze``).

    ``duplex`` numbers the duplexes of an all-atom system from 1; ``overwrite`` replaces an earlier
    report in ``out`` (default ``INPUT_analysis/``).

    Returns
    -------
    dict
        The summary written to ``OUT/summary.json``.
    """
    from dnarod.core.forcefield import load_forcefield

    _check_arguments(input_path, temperature, start, stop, step, exclude_ends, n_blocks, duplex)
    out = Path(out) if out else Path(input_path).with_name(Path(input_path).stem + "_analysis")
    out, stale = prepare_report_folder(out, overwrite)
    traj, model, kind = load_input(input_path, topology, duplex, start, stop, step)
    ff = load_forcefield(forcefield or "dna-default")
    # refused here, before the old report's files go and before anything is printed
    if traj.n_frames == 0 and start is None and stop is None and step is None:
        raise DnarodError(f"{input_path}: holds no complete frame (an empty or truncated trajectory, or a run "
                          f"stopped before its first frame); analyse a trajectory with frames")
    if traj.n_frames == 0:
        raise DnarodError(f"{input_path}: no frame left with --start {start} --stop {stop} --step {step}; widen the "
                          f"range")
    closed = bool(circular or traj.metadata.get("circular") or (model is not None and model.closure is not None))
    n_steps = traj.n_nodes - 1
    ends_asked = (1 if kind == "all-atom" else 0) if exclude_ends is None else int(exclude_ends)
    if not closed and n_steps - 2 * ends_asked < 1:
        default = " (the default for all-atom input)" if exclude_ends is None else ""
        raise DnarodError(f"--exclude-ends {ends_asked}{default} leaves no steps of {n_steps}; use at most "
                          f"{max((n_steps - 1) // 2, 0)}")
    closure = model.closure if model is not None else None
    circular = circular or bool(traj.metadata.get("circular"))
    if circular and closure is None:
        from dnarod.core.strains import Closure
        closure = Closure.identity()
    seq = (model.sequence if model is not None else None) or traj.metadata.get("sequence") or None
    if seq is not None and len(seq) != traj.n_nodes:
        seq = None
    if seq is not None and set(seq.upper()) - set("ACGT"):
        bad = sorted(set(seq.upper()) - set("ACGT"))
        raise DnarodError(f"{input_path}: strand I {seq[:40]}{'...' if len(seq) > 40 else ''} has bases other than "
                          f"A, C, G, T ({', '.join(bad)}: RNA or unmapped modified bases); the step analysis and its "
                          f"force-field comparison are for DNA duplexes")
    if traj.n_frames == 1:  # a fit, a persistence length and their error bars from one frame would be noise
        sel = "" if start is None and stop is None and step is None else " left by --start/--stop/--step"
        raise DnarodError(f"{input_path}: a single frame{sel} (one structure): the stiffness, the persistence length "
                          f"and their error bars need a trajectory of many frames; `dnarod steps {input_path}` gives "
                          f"the step parameters of one structure")
    from dnarod.analysis.stiffness import MIN_SAMPLES

    n_used = n_steps + (1 if closed else 0) - (0 if closed else 2 * ends_asked)
    if traj.n_frames * n_used < MIN_SAMPLES:  # refused before any file of the report is written
        raise DnarodError(f"{input_path}: {traj.n_frames} frame(s) x {n_used} steps = {traj.n_frames * n_used} "
                          f"step samples; the stiffness fit needs at least {MIN_SAMPLES}: analyse more frames (a "
                          f"single structure is one frame; `dnarod steps` gives its step parameters)")
    import contextlib

    from dnarod.core.io import folder_lock, staged_folder

    with contextlib.ExitStack() as stack:
        stack.enter_context(folder_lock(out, what="report folder"))
        if stale:  # overwrite: the new report is made beside the old one and replaces it only when complete
            work = stack.enter_context(staged_folder(out, REPORT_FILES, what="analysis report"))
        else:
            work = out
        return _report(input_path, traj, model, kind, ff, out, work, temperature, exclude_ends, allow_gaps,
                       circular, closed, closure, n_steps, n_blocks, forcefield, plots, echo)


def _report(input_path, traj, model, kind, ff, final_out, out, temperature, exclude_ends, allow_gaps, circular,
            closed, closure, n_steps, n_blocks, forcefield, plots, echo):
    """Write the report of :func:`analyze` into ``out`` (``final_out`` itself, or the folder a replacement of
    the report in ``final_out`` is built in); returns the summary."""
    from dnarod.analysis.polymer import EndToEnd, LinkingNumber, TangentCorrelation
    from dnarod.analysis.steps import StepAnalysis
    from dnarod.analysis.stiffness import StiffnessFit
    from dnarod.core.stepparams import to_angstrom_degrees
    from dnarod.core.units import kT as thermal_kT
    from dnarod.physics.thermal import exact_tangent_correlation

    is_ring = closure is not None
    ds = model.ds if model is not None else ff.ds
    seq = (model.sequence if model is not None else None) or traj.metadata.get("sequence") or None
    if seq is not None and len(seq) != traj.n_nodes:
        seq = None
    T = float(temperature or traj.metadata.get("temperature_K") or ff.temperature)
    ends = (1 if kind == "all-atom" else 0) if exclude_ends is None else int(exclude_ends)
    if is_ring:
        ends = 0
    check = not allow_gaps
    summary = {"input": str(input_path), "kind": kind, "n_frames": traj.n_frames, "n_nodes": traj.n_nodes,
               "sequence": seq, "ds_nm": ds, "temperature_K": T, "circular": is_ring, "exclude_ends": ends,
               "forcefield": ff.name, "model": "from topology" if model is not None else None, "files": {}}
    echo(f"{input_path}: {kind} trajectory, {traj.n_frames} frames, {traj.n_nodes} nodes"
         + (f", sequence {seq[:40]}{'...' if len(seq) > 40 else ''}" if seq else ""))

    steps = StepAnalysis(traj, ds, sequence=seq, closure=closure, check_spacing=check).run()
    steps.write_csv(out / "step_parameters.csv")
    rows = steps.summary_rows()
    _write_rows(out / "step_parameters_mean.csv", rows)
    m = len(steps.names)
    keep = slice(ends, m - ends) if ends and not is_ring else slice(None)
    mean_ad = to_angstrom_degrees(steps.results.step_parameters[:, keep].reshape(-1, 6)).mean(axis=0)
    summary["mean_step_parameters"] = dict(zip(["shift_A", "slide_A", "rise_A", "tilt_deg", "roll_deg", "twist_deg"],
                                               mean_ad))
    summary["files"].update(step_parameters="step_parameters.csv", step_parameters_mean="step_parameters_mean.csv")

    fit = StiffnessFit(traj, ds, T, sequence=seq, exclude_ends=ends, closure=closure, n_blocks=n_blocks,
                       check_spacing=check).run()
    _write_rows(out / "stiffness_table.csv", fit.table_rows())
    fit.write_forcefield(out / "stiffness.toml", "*", ff_name=f"fitted-{Path(input_path).stem}",
                         node_mass=ff.node_mass, node_inertia=ff.node_inertia,
                         sources=[f"dnarod analyze {Path(input_path).name}"])
    pooled = fit.results.types["*"]
    summary["stiffness"] = {"file": "stiffness.toml", "n_samples": pooled["n_samples"],
                            "intrinsic": pooled["mean"], "stiffness": pooled["stiffness"],
                            "stiffness_err": pooled["stiffness_err"],
                            "units": "Omega 1/nm, Gamma 1; A kJ/mol nm, B kJ/mol, C kJ/mol/nm",
                            "note": "all steps pooled; with a sequence the per-step-type fits are in "
                                    "stiffness_table.csv and sequence_stiffness.toml",
                            "skipped_step_types": fit.results.skipped_types}
    summary["files"].update(stiffness_table="stiffness_table.csv", stiffness="stiffness.toml")
    types = [t for t in fit.results.types if t != "*"]
    if types and all(len(t) == 2 for t in types):
        p = fit.write_sequence_forcefield(out / "sequence_stiffness.toml", ff_name="fitted-sequence",
                                          node_mass=ff.node_mass, node_inertia=ff.node_inertia)
        summary["files"]["sequence_forcefield"] = str(p.relative_to(out))

    tc = TangentCorrelation(traj, ds, exclude_ends=ends, n_blocks=n_blocks, circular=is_ring,
                            check_spacing=check).run()
    r = tc.results
    params = model.params if model is not None else None
    exact = None
    if not is_ring:
        if params is None and forcefield is not None:
            try:
                params = ff.step_parameters(seq, n_steps=traj.n_nodes - 1)
            except DnarodError:
                params = None
        if params is not None:
            exact = exact_tangent_correlation(params, ds, thermal_kT(T), tc.n_max, ends)
    _write_rows(out / "tangent_correlation.csv",
                [{"lag": int(n), "s_nm": float(n * ds), "correlation": float(r.correlation[n]),
                  "error": float(r.correlation_err[n]),
                  **({"exact": float(exact[n])} if exact is not None else {})} for n in r.lags])
    lp1 = r.persistence_length_one_step_estimate
    dt_frame = float(np.median(np.diff(traj.time))) if traj.n_frames > 1 else float("nan")
    summary["persistence_length_nm"] = {"one_step": r.persistence_length_one_step,
                                        "one_step_error": r.persistence_length_one_step_err,
                                        "one_step_error_run": lp1.error,
                                        "one_step_error_slow_modes": 0.0,
                                        "transient_dropped_frames": r.dropped_frames,
                                        "transient_dropped_ps": (float(traj.time[r.dropped_frames] - traj.time[0])
                                                                 if traj.n_frames > 1 else 0.0),
                                        "frames_averaged": lp1.n_samples, "n_effective": lp1.n_eff,
                                        "autocorrelation_time_ps": lp1.tau * dt_frame, "flag": lp1.flag,
                                        "fit": r.persistence_length, "error": r.persistence_length_err,
                                        "n_lags_fitted": r.n_fit,
                                        "headline": "one_step (lag 1): mean over the frames after the start's "
                                                    "transient; its error from their autocorrelation plus the share "
                                                    "of the modes slower than the run (normal modes); the long-lag "
                                                    "fit needs runs much longer than the slowest bending relaxation "
                                                    "time"}
    summary["warnings"] = [lp1.flag] if lp1.flag else []
    if not is_ring and model is not None and kind != "all-atom":
        rel = _relaxation(traj, model, T, tc, ends, Path(input_path))
        summary["relaxation"] = rel
        lp_rec = summary["persistence_length_nm"]
        if rel.get("lag1_error_slow_modes_nm") is not None:
            lp_rec["one_step_error_slow_modes"] = rel["lag1_error_slow_modes_nm"]
            lp_rec["one_step_error"] = float(np.hypot(lp1.error, rel["lag1_error_slow_modes_nm"]))
            lp_rec["start_bias_expected_nm"] = rel["lag1_start_bias_nm"]
        for key in ("warning", "start_warning"):
            if rel.get(key):
                summary["warnings"].append(rel[key])
    if exact is not None and len(exact) > 1:
        summary["persistence_length_nm"]["exact_one_step"] = float(-ds / np.log(exact[1]))
    summary["files"]["tangent_correlation"] = "tangent_correlation.csv"
    if not is_ring:
        ee = EndToEnd(traj, n_blocks=n_blocks, check_spacing=check).run()
        summary["end_to_end_nm"] = {"mean": ee.results.mean, "error": ee.results.mean_err,
                                    "mean_square_nm2": ee.results.mean_square,
                                    "mean_square_error": ee.results.mean_square_err,
                                    "contour_nm": (traj.n_nodes - 1) * ds}
        _write_rows(out / "end_to_end.csv", [{"frame": int(f), "time_ps": float(t), "distance_nm": float(d)}
                                             for f, t, d in zip(ee.frame_indices, ee.times, ee.results.distance)])
        summary["files"]["end_to_end"] = "end_to_end.csv"
    elif np.allclose(closure.Q, np.eye(3)) and np.allclose(closure.t, 0):
        lk = LinkingNumber(traj, closure=closure, check_spacing=check).run()
        L = lk.results
        summary["linking"] = {"Lk": L.linking_integer, "mean_twist": L.mean_twist, "mean_writhe": L.mean_writhe,
                              "max_identity_error": L.max_identity_error, "max_integer_error": L.max_integer_error,
                              "check_Lk_equals_Tw_plus_Wr": L.passed}
        _write_rows(out / "linking.csv", [{"frame": int(f), "time_ps": float(t), "Tw": float(a), "Wr": float(b),
                                           "Lk": float(c)} for f, t, a, b, c in
                                          zip(lk.frame_indices, lk.times, L.twist, L.writhe, L.linking)])
        summary["files"]["linking"] = "linking.csv"
        echo(f"linking number {sorted(set(L.linking_integer.tolist()))}, <Tw> = {L.mean_twist:.4f}, "
             f"<Wr> = {L.mean_writhe:.4f}, Lk = Tw + Wr to {L.max_identity_error:.1e}")
    else:
        summary["linking"] = "not defined: the chain has a screw closure (a periodic chain, not a ring in space)"

    if plots:
        from dnarod.analysis.plots import plot_step_parameters, plot_strain_distributions, plot_tangent_correlation

        xi = fit.results.xi[:, fit.keep].reshape(-1, 6)
        plot_strain_distributions(xi, out / "strain_distributions.png", pooled["mean"], pooled["cov"],
                                  title=f"strains of {Path(input_path).name} (all steps pooled)")
        plot_tangent_correlation(r.lags, r.correlation, r.correlation_err, ds, out / "tangent_correlation.png",
                                 None if is_ring else r.persistence_length, exact,
                                 title=f"tangent correlation, {Path(input_path).name}")
        plot_step_parameters(to_angstrom_degrees(steps.results.mean_step_parameters),
                             to_angstrom_degrees(steps.results.std_step_parameters), steps.names,
                             out / "step_parameters.png", title=f"step parameters, {Path(input_path).name}")
        summary["files"].update(plot_strains="strain_distributions.png", plot_tangent="tangent_correlation.png",
                                plot_steps="step_parameters.png")
    from dnarod.core.io import write_text_atomic

    write_text_atomic(out / "summary.json", json.dumps(jsonable(summary), indent=2) + "\n")
    lp = summary["persistence_length_nm"]
    line = f"mean rise {mean_ad[2]:.3f} A, twist {mean_ad[5]:.2f} deg"
    no_bar = f" (no error bar: {traj.n_frames} frame(s) are too few for an autocorrelation or block estimate)"
    if lp["one_step"] is not None and np.isfinite(lp["one_step"] or np.nan):
        line += f"; persistence length (lag 1) {_pm(lp['one_step'], lp['one_step_error'], '.2f', no_bar)}"
        if lp.get("exact_one_step") is not None:
            line += f" (model exact {lp['exact_one_step']:.2f} nm)"
        if lp.get("transient_dropped_frames"):
            line += (f"; the first {lp['transient_dropped_frames']} frames ({lp['transient_dropped_ps']:.4g} ps) "
                     f"dropped as the start's transient")
    echo(line)
    if lp["fit"] is not None and np.isfinite(lp["fit"] or np.nan):
        echo(f"long-lag fit {_pm(lp['fit'], lp['error'], '.1f', no_bar)} ({lp['n_lags_fitted']} lags; converged only "
             f"for runs of many slowest bending relaxation times"
             + (f", here {summary['relaxation']['run_over_tau']:.3g} of them)"
                if summary.get("relaxation", {}).get("run_over_tau") is not None else ")"))
    for w in summary["warnings"]:
        echo(f"warning: {w}")
    echo(f"wrote {final_out}/ (summary.json, CSV tables, stiffness.toml{', plots' if plots else ''})")
    return summary


def _run_record(input_path):
    """``(start, loads, engine)`` of the run that wrote ``input_path`` (its ``run.json`` beside it), or Nones."""
    f = Path(input_path).parent / "run.json"
    try:
        spec = json.loads(f.read_text()).get("spec", {})
    except (OSError, ValueError, AttributeError):
        return None, None, None
    return spec.get("start"), spec.get("loads"), spec.get("engine")


def _pm(value, err, fmt, no_bar, unit="nm"):
    """``"value +- err unit"``, or the value, unit and ``no_bar`` when the error bar could not be estimated (never
    "+- nan")."""
    if err is not None and np.isfinite(err):
        return f"{value:{fmt}} +- {err:{fmt}} {unit}"
    return f"{value:{fmt}} {unit}{no_bar}"


def _relaxation(traj, model, temperature, tc, exclude_ends, input_path):
    """Slowest relaxation time of the analysed chain (its normal modes at the run's friction), the share of the modes
    slower than the run in the lag-1 persistence length's error, the bias a start that was not an equilibrium
    sample leaves in it, and the run-length warnings (summary entry)."""
    from dnarod.analysis.polymer import RELAXATION_TIMES_REQUIRED, lag1_slow_modes, relaxation_warning

    r = tc.results
    lp = r.persistence_length_one_step
    friction = traj.metadata.get("friction_per_ps")
    run_time = float(traj.time[-1] - traj.time[0]) if traj.n_frames > 1 else 0.0
    start, loads, engine = _run_record(input_path)
    out = {"method": "normal modes of the chain's intrinsic pose (dnarod.physics.relaxation) at the run's friction; "
                     "slow-mode share and start bias of the lag-1 value: dnarod.analysis.polymer.lag1_slow_modes",
           "contour_length_nm": model.ds * (traj.n_nodes - 1), "run_time_ps": run_time,
           "required_relaxation_times": RELAXATION_TIMES_REQUIRED, "start": start}
    if friction is None or not np.isfinite(lp or np.nan):
        out["tau_ps"] = None
        out["note"] = "no friction in the trajectory metadata: relaxation time not estimated"
        return out
    if engine == "mc":
        out["tau_ps"] = None
        out["note"] = ("a Monte Carlo run: its frames are sweeps, not time, so the modes' relaxation times do not "
                       "apply; the error comes from the frames' autocorrelation alone")
        return out
    if float(friction) <= 0:
        out["tau_ps"] = None
        out["note"] = ("a constant-energy (NVE) run: its modes exchange energy only through anharmonic couplings; "
                       "relaxation times and the slow modes' share of the error are not estimated")
        return out
    if loads:
        out["tau_ps"] = None
        out["note"] = "a loaded chain: the free chain's modes do not describe it; slow-mode terms not estimated"
        return out
    t0 = r.dropped_frames
    sm = lag1_slow_modes(model, temperature, float(friction), float(traj.time[t0]), float(traj.time[-1]),
                         equilibrium_start=(start == "equilibrium"), exclude_ends=exclude_ends)
    c1 = r.lag1_estimate.mean
    dlp = model.ds / (c1 * np.log(c1) ** 2)  # d(-ds/ln c)/dc
    tau = sm["tau_slowest_ps"]
    err_slow = float(np.sqrt(sm["variance_c1"]) * dlp)
    bias = float(sm["bias_c1"] * dlp)
    out.update(friction_per_ps=float(friction), tau_ps=tau, run_over_tau=run_time / tau if np.isfinite(tau) else 0.0,
               n_slow_modes=sm["n_slow_modes"], lag1_error_slow_modes_nm=err_slow, lag1_start_bias_nm=bias,
               warning=relaxation_warning(run_time, tau, slow_error_nm=err_slow))
    total = float(np.hypot(r.persistence_length_one_step_err, err_slow))
    if start != "equilibrium" and abs(bias) > total:
        how = f"the start ({start})" if start else "a start that was not an equilibrium sample (the run's start is " \
                                                   "not recorded: no run.json beside the trajectory)"
        out["start_warning"] = (f"not equilibrated: {how} leaves the slowest modes unrelaxed, and over the frames "
                                f"averaged they bias the lag-1 persistence length by {bias:+.2f} nm (expected from "
                                f"the normal modes), more than its error +-{total:.2f} nm; start from an "
                                f"equilibrium sample (simulate --equilibrium) or run much longer than the slowest "
                                f"relaxation time {tau:.3g} ps")
    return out
