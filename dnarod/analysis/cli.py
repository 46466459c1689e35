"""``dnarod analyze``: step parameters, strains, stiffness, persistence length, Lk/Tw/Wr of a trajectory.

Input is a dnarod ``.dtraj`` trajectory (model from ``--topology MODEL.npz``, or the
``final_model.npz`` written beside it by ``dnarod simulate``) or an all-atom trajectory in any
format MDAnalysis reads (``--topology`` PDB/PSF/PRMTOP/...; a PDB/mmCIF alone is analysed as
its own frames). Outputs in ``--out``: CSV tables, the fitted stiffness as force-field TOML
files, PNG plots and ``summary.json``.
"""
from __future__ import annotations

import csv
import json
from pathlib import Path

import click
import numpy as np

from ..errors import DnarodError, StructureError



def _write_rows(path, rows):
    from ..io_utils import atomic_path

    if not rows:
        return
    with atomic_path(path) as tmp, open(tmp, "w", newline="") as fh:
        w = csv.DictWriter(fh, fieldnames=list(rows[0]))
        w.writeheader()
        w.writerows(rows)


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, np.ndarray):
        return _jsonable(x.tolist())
    if isinstance(x, (np.floating, float)):
        return None if not np.isfinite(x) else float(x)
    if isinstance(x, (np.integer,)):
        return int(x)
    if isinstance(x, np.bool_):
        return bool(x)
    return x


def load_input(path, topology=None, duplex=0, start=None, stop=None, step=None):
    """Read the input trajectory.

    Returns
    -------
    traj : Trajectory
    model : RodModel or None
        The dnarod model (``--topology`` or ``final_model.npz`` next to a ``.dtraj``).
    kind : str
        ``"dnarod"`` or ``"all-atom"``.
    """
    from ..model import RodModel
    from ..trajectory import Trajectory

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
    from ..structure.trajectory import is_structure_file, read_node_trajectory
    from .allatom import load_allatom

    nodes = read_node_trajectory(path, topology)  # oxDNA (--topology X.top) or a dnarod CG export (PDB/DCD)
    if nodes is not None:
        return nodes[slice(start, stop, step)], None, "dnarod"

    if topology is None:
        if not is_structure_file(path):
            raise StructureError(f"{path}: an all-atom trajectory needs --topology (PDB, PSF, PRMTOP, GRO, ...)")
        traj, _ = load_allatom(path, None, duplex, start, stop, step)
    else:
        traj, _ = load_allatom(topology, path, duplex, start, stop, step)
    return traj, None, "all-atom"


def exact_tangent_correlation(params, ds, kt, n_max, exclude_ends=0):
    """Exact ``<d3(k) . d3(k+n)>`` of a free open chain in equilibrium, averaged over the start node k
    exactly as :class:`~dnarod.analysis.polymer.TangentCorrelation` averages (design A5 iii:
    ``<d3(k) . d3(k+n)> = (<R_k> ... <R_{k+n-1}>)_33``).

    Returns
    -------
    ndarray, shape (n_max + 1,)
    """
    from ..thermal import mean_rotation

    Rm = mean_rotation(params, ds, kt)
    e = int(exclude_ends)
    n_nodes = len(Rm) + 1 - 2 * e
    out = np.ones(n_max + 1)
    P = np.broadcast_to(np.eye(3), (n_nodes, 3, 3)).copy()  # products starting at node e + k
    for n in range(1, n_max + 1):
        k = np.arange(n_nodes - n)
        P = P[:n_nodes - n] @ Rm[e + k + n - 1]
        out[n] = P[:, 2, 2].mean()
    return out


def analyze(input_path, topology=None, forcefield=None, out=None, circular=False, temperature=None,
            start=None, stop=None, step=None, exclude_ends=None, n_blocks=10, allow_gaps=False, duplex=0,
            plots=True, echo=print):
    """Run every analysis on a trajectory and write the report folder (the API of ``dnarod analyze``).

    Returns
    -------
    dict
        The summary written to ``OUT/summary.json``.
    """
    from ..forcefield import load_forcefield
    from ..stepparams import to_angstrom_degrees
    from ..thermal import kT as thermal_kT
    from .polymer import EndToEnd, LinkingNumber, TangentCorrelation
    from .steps import StepAnalysis
    from .stiffness import StiffnessFit

    traj, model, kind = load_input(input_path, topology, duplex, start, stop, step)
    out = Path(out) if out else Path(input_path).with_name(Path(input_path).stem + "_analysis")
    out.mkdir(parents=True, exist_ok=True)
    ff = load_forcefield(forcefield or "dna-default")
    closure = model.closure if model is not None else None
    circular = circular or bool(traj.metadata.get("circular"))
    if circular and closure is None:
        from ..strains import Closure
        closure = Closure.identity()
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
    summary["persistence_length_nm"] = {"fit": r.persistence_length, "error": r.persistence_length_err,
                                        "n_lags_fitted": r.n_fit, "one_step": r.persistence_length_one_step}
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
        from .plots import plot_step_parameters, plot_strain_distributions, plot_tangent_correlation

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
    from ..io_utils import write_text_atomic

    write_text_atomic(out / "summary.json", json.dumps(_jsonable(summary), indent=2) + "\n")
    lp = summary["persistence_length_nm"]
    echo(f"mean rise {mean_ad[2]:.3f} A, twist {mean_ad[5]:.2f} deg; persistence length "
         f"{lp['fit']:.1f} +- {lp['error']:.1f} nm" if lp["fit"] is not None and np.isfinite(lp["fit"] or np.nan)
         else f"mean rise {mean_ad[2]:.3f} A, twist {mean_ad[5]:.2f} deg")
    echo(f"wrote {out}/ (summary.json, CSV tables, stiffness.toml, plots)")
    return summary


@click.command("analyze")
@click.argument("input_path", metavar="INPUT", type=click.Path(dir_okay=False))
@click.option("--topology", "-t", type=click.Path(dir_okay=False),
              help="All-atom topology (PDB, PSF, PRMTOP, GRO, ...) or, for a .dtraj, the dnarod model .npz "
                   "(default: final_model.npz next to it).")
@click.option("--forcefield", "-f", default=None,
              help="Force field (bundled name or .toml): ds and node mass for the fitted stiffness file, and the "
                   "exact tangent correlation to compare with. Default dna-default.")
@click.option("--out", "-o", type=click.Path(file_okay=False), help="Output folder (default INPUT_analysis/).")
@click.option("--circular", is_flag=True, help="The chain is a ring: the last node joins the first; "
                                               "reports Lk, Tw and Wr.")
@click.option("--temperature", type=float, default=None,
              help="K (default: the trajectory's, else the force field's).")
@click.option("--start", type=int, default=None, help="First frame (0-based).")
@click.option("--stop", type=int, default=None, help="Stop before this frame.")
@click.option("--step", type=int, default=None, help="Use every STEP-th frame.")
@click.option("--exclude-ends", type=int, default=None,
              help="Steps/nodes left out at each end (default 1 for all-atom, 0 for dnarod).")
@click.option("--blocks", type=int, default=10, show_default=True, help="Blocks for the error bars.")
@click.option("--allow-gaps", is_flag=True, help="Accept unevenly spaced (missing) frames.")
@click.option("--duplex", type=int, default=0, show_default=True, help="Duplex of an all-atom system (0-based).")
@click.option("--no-plots", is_flag=True, help="Skip the PNG plots.")
def analyze_cmd(input_path, topology, forcefield, out, circular, temperature, start, stop, step, exclude_ends,
                blocks, allow_gaps, duplex, no_plots):
    """Analyse a trajectory: step parameters, strains, stiffness, persistence length, Lk/Tw/Wr.

    INPUT is a dnarod .dtraj trajectory or an all-atom trajectory MDAnalysis reads (with
    --topology), or a PDB/mmCIF file (its models are the frames).
    """
    analyze(input_path, topology, forcefield, out, circular, temperature, start, stop, step, exclude_ends,
            blocks, allow_gaps, duplex, plots=not no_plots, echo=click.echo)
