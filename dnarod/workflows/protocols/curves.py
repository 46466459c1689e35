"""Protocol curves: run a protocol's members (an ensemble over its axes) and write ``curve.csv`` + ``curve.png``.

Members run on :class:`dnarod.workflows.ensemble.Ensemble` (dask ``LocalCluster``; ``workers=0`` runs them one after
the other in this process, which the tests use). Bad input is refused before anything runs, with one line
(:class:`~dnarod.core.errors.DnarodError`). Finished members are reused (same settings -> same folder).
"""
from __future__ import annotations

import csv
import io
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.workflows.protocols.settings import expand_members, member_name

#: Start modes of the rotation-clamp protocols (see :func:`run_protocol`).
STARTS = ("static", "exchange")

@dataclass
class Curve:
    """A protocol's result: ``rows`` (one dict per member, sorted along the x axis) and written ``files``."""

    kind: str
    rows: list[dict[str, Any]]
    files: dict[str, Path] = field(default_factory=dict)


# one keyword per option of the `dnarod protocol` commands
def run_protocol(kind: str, axes: dict[str, list[Any]], base: dict[str, Any], outdir: str | Path, workers: int = 2,
                 progress: bool = True, client: Any = None, plots: bool = True, start: str = "static",
                 overwrite: bool = False, exchange_ps: float | None = None) -> Curve:
    """Run a protocol over its axes and write its curve.

    Parameters
    ----------
    kind : {"force_extension", "magnetic_tweezers", "torque_turns", "rings"}
    axes : dict
        Axis name -> list of values (``force_pN``, ``turns``, ``delta_lk``, ``seed``); crossed.
    base : dict
        Settings shared by all members (ensemble keys: ``source``, ``time_ns``, ``equilibration_ns``,
        ``temperature_K``, ``salt_M``, ``rotation_clamp_kJ_mol``, ...).
    outdir : path
    workers : int
        Dask local workers; 0 runs the members serially in this process.
    start : {"static", "exchange"}
        "static": every member starts from the static pose under its loads (independent members, one dask task
        each). "exchange" (hat and torque-turns): the turn values of each force are the rungs of one
        replica-exchange ladder (:mod:`dnarod.workflows.protocols.exchange`: swaps between neighbouring rungs with
        the turn difference carried as twist, Metropolis-accepted), run as ``workers`` dask actors; rungs in
        ``members/exchange_*``, the ladder's acceptance and round trips in ``ladders/*/exchange.json``. Near
        buckling a long chain keeps the state it starts in (straight or plectonemic) for longer than a member
        runs; exchange lets configurations change state through neighbouring rungs. (A member that continues
        another member's final pose: :func:`dnarod.workflows.protocols.tweezers.run_member` with ``start_pose``.)
    exchange_ps : float, optional
        With ``start="exchange"``: time between exchange attempts, ps (default
        :data:`dnarod.workflows.protocols.exchange.EXCHANGE_PS`).
    overwrite : bool
        Run into ``outdir`` although it holds this protocol run made with other settings (or another protocol;
        :mod:`dnarod.workflows.protocols.folder`). Without it such a folder is refused, as is any other non-empty folder
        that is not a protocol's; the same settings reuse the finished members (more axis values extend the
        curve). While the protocol runs, ``outdir`` is locked against a second writer
        (:func:`dnarod.core.io.folder_lock`).

    Returns
    -------
    Curve

    Raises
    ------
    DnarodError
        Bad settings, a folder of another protocol run or of something else, a folder in use (before any member
        runs), or a failed member.
    """
    import json

    from dnarod.core.io import check_output_folder, folder_lock, jsonable, staged_folder
    from dnarod.workflows.protocols import ensemble_hooks as hooks
    from dnarod.workflows.protocols.folder import (PROTOCOL_FILES, PROTOCOL_MARKERS, check_protocol_folder,
                                                   replaces_other_settings, write_protocol_record)

    proto = hooks.protocol_of(kind)
    if isinstance(workers, bool) or not isinstance(workers, int) or workers < 0:
        raise DnarodError(f"workers {workers!r}: give a number of dask workers >= 0 (0: one after another in this "
                          f"process)")
    if start not in STARTS:
        raise DnarodError(f"start {start!r}: choose 'static' (every member from the static pose) or 'exchange' "
                          f"(the turn values of each force as the rungs of one replica-exchange ladder)")
    if start == "exchange" or exchange_ps is not None:
        from dnarod.workflows.protocols.exchange import check_exchange

        check_exchange(kind, start, axes, exchange_ps)
    if not isinstance(outdir, (str, Path)) or not str(outdir).strip():
        raise DnarodError(f"output folder {outdir!r}: give a folder path (-o DIR)")
    # the settings every member shares, as given (protocol.json; the defaults below are the protocol's own)
    shared = jsonable(dict(base, start=start))
    if exchange_ps is not None:  # (absent otherwise: the records of earlier runs stay valid)
        shared["exchange_ps"] = float(exchange_ps)
    base = dict(base)
    if kind in ("magnetic_tweezers", "torque_turns"):
        base.setdefault("rotation_clamp_kJ_mol", 250.0)
    if kind == "rings":
        base["ring"] = True  # the ensemble's model check builds a closed ring for delta_lk
    members = expand_members(kind, axes, base)
    outdir = Path(outdir)
    check_output_folder(outdir, PROTOCOL_MARKERS, "protocol")
    check_protocol_folder(outdir, kind, shared, overwrite)
    with folder_lock(outdir):
        check_protocol_folder(outdir, kind, shared, overwrite)  # again: another process may have written it since
        if overwrite and replaces_other_settings(outdir, kind, shared):
            # made beside the old run (kept there if stopped: the same command continues it) and put in place when
            # its curve is written: until then the old run stays as it was
            import hashlib

            tag = hashlib.sha256(json.dumps([kind, shared], sort_keys=True).encode()).hexdigest()[:16]
            with staged_folder(outdir, PROTOCOL_FILES, what="protocol run", resume_name=tag) as work:
                curve = _run_members(kind, axes, base, members, work, workers, progress, client, plots, start, proto,
                                     exchange_ps)
                write_protocol_record(work, kind, shared)
            curve.files = {k: outdir / Path(v).name for k, v in curve.files.items()}
            return curve
        curve = _run_members(kind, axes, base, members, outdir, workers, progress, client, plots, start, proto,
                             exchange_ps)
        write_protocol_record(outdir, kind, shared)
    return curve


def _run_members(kind, axes, base, members, outdir, workers, progress, client, plots, start, proto, exchange_ps=None):
    """The members of :func:`run_protocol` (run or reused) and the curve written from them."""
    if start == "exchange":
        from dnarod.workflows.protocols.exchange import run_ladders

        rows = run_ladders(kind, axes, members, outdir, workers, progress, client, exchange_ps)
    elif workers:
        rows = _run_ensemble(kind, axes, base, outdir, proto, workers, progress, client)
    else:
        rows = []
        for i, m in enumerate(members):
            mdir = outdir / "members" / member_name(m, axes)
            row = proto.execute(m, mdir)
            rows.append(dict(row, **{k: m[k] for k in axes}))
    return write_curve(kind, rows, base, outdir, plots)


def write_curve(kind: str, rows: list[dict[str, Any]], base: dict[str, Any], outdir: str | Path,
                plots: bool = True) -> Curve:
    """Write a protocol's curve from its member rows: ``outdir/curve.csv`` (and ``curve.png``).

    The rows are sorted along the protocol's x axis and put on the model's zero at the run's temperature
    (:func:`_thermal_corrections`; rings also get ``Tw_minus_Tw0``), in place. :func:`run_protocol` ends with it;
    members run another way (e.g. chained from each other's final poses with
    :func:`dnarod.workflows.protocols.tweezers.run_member`) are written into a curve the same way.

    Parameters
    ----------
    kind : {"force_extension", "magnetic_tweezers", "torque_turns", "rings"}
    rows : list of dict
        One member's result each (:func:`dnarod.workflows.protocols.tweezers.summarize` or a ring member's row),
        with the axis values.
    base : dict
        The settings the members share (``source``, ``forcefield``, ``temperature_K``): the model whose thermal
        zero the corrections use.
    outdir : path
    plots : bool

    Returns
    -------
    Curve
    """
    from dnarod.workflows.protocols.ensemble_hooks import protocol_of

    outdir = Path(outdir)
    x = protocol_of(kind).plot.x
    rows.sort(key=lambda r: (r.get(x) if r.get(x) is not None else 0.0))  # type: ignore[arg-type, return-value]
    for r in rows:
        if kind == "rings" and "Tw" in r:
            r["Tw_minus_Tw0"] = r["Tw"] - r["intrinsic_turns"]
    _thermal_corrections(kind, base, rows)
    curve = Curve(kind, rows)
    curve.files["csv"] = _write_csv(rows, outdir / "curve.csv")
    if plots:
        curve.files["png"] = plot_curve(kind, rows, outdir / "curve.png")
    return curve


def _thermal_corrections(kind, base, rows):
    """Put the curve's torques and linking differences on the model's zero at its temperature, in place.

    ``twist_torque_pN_nm`` becomes the twisting moment less what it reads on a chain under no torque
    (:func:`dnarod.workflows.protocols.measure.twisting_moment_offset`, about -1.2 pN nm for ``dna-default`` at 300 K;
    the raw mean stays in ``twist_torque_pN_nm_raw``), and ``delta_lk_thermal`` is ``Lk`` less the relaxed linking
    number at T (tweezers: :func:`dnarod.physics.loads.torque_free_offset`, from which members count their turns,
    so it equals their ``delta_lk``; rings: the relaxed ring's twist at T, ``relaxed_twist_thermal``). The clamp
    torque needs no correction. Members keep their own raw results.
    """
    from dnarod.core.forcefield import load_forcefield
    from dnarod.physics.loads import intrinsic_turns, torque_free_offset
    from dnarod.workflows.protocols.measure import twisting_moment_offset

    if not rows:
        return
    ff = load_forcefield(base.get("forcefield", "dna-default"))
    src = str(base.get("source", "")).strip()
    seq, n_nodes = (None, int(src)) if src.isdigit() else (src, None)
    T = float(base.get("temperature_K") or 300.0)
    if kind == "rings":
        for r in rows:
            if r.get("relaxed_twist_thermal") is not None and r.get("Lk") is not None:
                r["delta_lk_thermal"] = r["Lk"] - r["relaxed_twist_thermal"]
        return
    model = ff.model_from_sequence(seq, n_nodes=n_nodes)
    # the torque-free linking number at T: the one tweezers members count their turns from (exact, no error)
    lk_T, lk_T_se = intrinsic_turns(model) + torque_free_offset(model, T), 0.0
    off, off_se = twisting_moment_offset(model, T) if kind != "force_extension" else (None, None)
    for r in rows:
        if r.get("Lk") is not None:
            r["delta_lk_thermal"] = r["Lk"] - lk_T
            r["relaxed_twist_thermal"], r["relaxed_twist_thermal_err"] = lk_T, lk_T_se
        if off is not None and r.get("twist_torque_pN_nm") is not None:
            r["twist_torque_pN_nm_raw"] = r["twist_torque_pN_nm"]
            r["twist_torque_pN_nm"] = r["twist_torque_pN_nm"] - off
            r["twist_torque_offset_pN_nm"], r["twist_torque_offset_err_pN_nm"] = off, off_se
            if r.get("twist_torque_pN_nm_err") is not None:
                r["twist_torque_pN_nm_err"] = float(np.hypot(r["twist_torque_pN_nm_err"], off_se))  # type: ignore[arg-type]  # set with off


def _run_ensemble(kind, axes, base, outdir, proto, workers, progress, client):
    """Run the members through :mod:`dnarod.workflows.ensemble`; returns their observables rows (settings merged)."""
    from dnarod.workflows.ensemble import Ensemble

    doc = {"ensemble": {"name": kind, "protocol": proto.name},
           "base": {k: v for k, v in base.items()},
           "axes": {k: list(np.atleast_1d(v).tolist()) for k, v in axes.items()}}
    ens = Ensemble.from_dict(doc, outdir / "ensemble", overwrite=False)
    ens.run(client=client, workers=workers, progress=progress)
    rows = []
    from dnarod.workflows.ensemble.member import member_dir, read_result

    for m in ens.members:
        r = read_result(member_dir(ens.outdir, m.id)) or {}
        if r.get("status") != "ok":
            raise DnarodError(f"member {m.index} ({', '.join(f'{k}={m.settings.get(k)}' for k in axes)}) failed: "
                              f"{r.get('error', 'no result')}; see {member_dir(ens.outdir, m.id)}/member.log")
        rows.append(dict(r["observables"], **{k: m.settings.get(k) for k in axes}))
    return rows


def _write_csv(rows, path):
    from dnarod.core.io import write_text_atomic

    keys = []
    for r in rows:
        for k in r:
            if k not in keys:
                keys.append(k)
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=keys, extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow({k: ("" if r.get(k) is None else r.get(k)) for k in keys})
    write_text_atomic(path, buf.getvalue())
    return Path(path)


def plot_curve(kind: str, rows: list[dict[str, Any]], path: str | Path) -> Path:
    """Plot a protocol's curve (mean +- block standard error per member) with its measured references beside
    (the protocol object's ``plot`` and ``references``, :mod:`dnarod.workflows.protocols.references`)."""
    from dnarod.analysis.plots import new_figure, save_figure
    from dnarod.workflows.protocols.ensemble_hooks import protocol_of

    proto = protocol_of(kind)
    plot = proto.plot
    fig, ax = new_figure(1, 1, width=6.0, height=5.4)
    a = ax[0, 0]
    x = np.array([float(r.get(plot.x) or 0.0) for r in rows])
    if plot.log_x:
        a.set_xscale("log")
    for yk in plot.ys:
        y = np.array([np.nan if r.get(yk) is None else float(r[yk]) for r in rows])
        e = np.array([np.nan if r.get(yk + "_err") is None else float(r[yk + "_err"]) for r in rows])
        a.errorbar(x, y, yerr=np.where(np.isfinite(e), e, 0.0), fmt="o-", capsize=3, label=f"dnarod: {yk}")
    if rows:
        for draw in proto.references:
            draw(a, rows)
    note = proto.missing_note()
    if note:
        # torque-turns legends fill the top left; the note goes bottom right there
        x0, y0, ha, va = (0.98, 0.03, "right", "bottom") if kind == "torque_turns" else (0.02, 0.97, "left", "top")
        a.text(x0, y0, note, transform=a.transAxes, fontsize=7, color="0.4", va=va, ha=ha)
    a.set_xlabel(plot.x_label)
    a.set_ylabel(plot.y_label)
    if rows:
        r0 = rows[0]
        a.set_title(f"{kind.replace('_', ' ')}: {r0.get('n_bp')} bp"
                    + (f", {r0.get('force_pN')} pN" if kind in ("magnetic_tweezers", "torque_turns") else ""),
                    fontsize=10)
    # below the axes: the measured overlays carry long labels (source and conditions) that would hide the data
    a.legend(fontsize=6.5, loc="upper center", bbox_to_anchor=(0.5, -0.14), frameon=False)
    out = Path(path)
    save_figure(fig, out.parent, out.name)
    return out


def force_extension(forces_pN: list[float], outdir: str | Path, source: str | int = "600", **kw: Any) -> Curve:
    """Force-extension curve (torsionally free bead end): one member per force (pN). See :func:`run_protocol`."""
    return run_protocol("force_extension", {"force_pN": list(forces_pN)}, dict(kw.pop("base", {}), source=str(source)),
                        outdir, **kw)


def hat_curve(turns: list[float], outdir: str | Path, force_pN: float | list[float] = 0.5, source: str | int = "600",
              **kw: Any) -> Curve:
    """Magnetic-tweezers hat curve: extension vs turns at constant force (one or several forces, pN)."""
    return run_protocol("magnetic_tweezers", {"force_pN": list(np.atleast_1d(force_pN)), "turns": list(turns)},
                        dict(kw.pop("base", {}), source=str(source)), outdir, **kw)


def torque_turns(turns: list[float], outdir: str | Path, force_pN: float | list[float] = 1.0,
                 source: str | int = "600", **kw: Any) -> Curve:
    """Torque-turns curve with a rotation clamp at constant force (pN)."""
    return run_protocol("torque_turns", {"force_pN": list(np.atleast_1d(force_pN)), "turns": list(turns)},
                        dict(kw.pop("base", {}), source=str(source)), outdir, **kw)


def ring_supercoiling(delta_lk: list[int], outdir: str | Path, source: str | int = "600", **kw: Any) -> Curve:
    """Closed rings over a list of linking differences: Tw, Wr, writhe fraction, plectonemes."""
    return run_protocol("rings", {"delta_lk": list(delta_lk)}, dict(kw.pop("base", {}), source=str(source)),
                        outdir, **kw)
