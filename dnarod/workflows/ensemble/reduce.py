"""The default reduction of one finished run to a row of observables (runs on the worker).

Every value ``X`` comes with ``X_err``, its standard error from :func:`dnarod.analysis.statistics.estimate` over the
frames after ``discard_ns`` (autocorrelation of the series, the start's remaining transient dropped; ``flags``
names the values whose run is too short for an error bar; the ``blocks`` setting is the number of blocks of the
long-lag persistence-length fit, not used by this row):

* every column of ``energies.csv`` other than ``step`` and ``time_ps`` (energies kJ/mol, the
  kinetic temperature as ``kinetic_temperature_K`` and, when loads define them, extension nm,
  turns, clamp torque pN nm, Lk);
* ``end_to_end_nm`` (open chains), from the trajectory;
* ``persistence_length_nm``: the lag-1 estimate ``-ds / ln <d3(k).d3(k+1)>`` (nm), error
  propagated from the error of the mean correlation;
* ``twist_turns``, ``writhe_turns``, ``linking_turns`` for rings (identity closure).

Plus ``n_frames`` and ``analysed_ns``. The client never loads a trajectory.
"""
from __future__ import annotations

import csv
import math
from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.analysis.polymer import EndToEnd, LinkingNumber, TangentCorrelation
from dnarod.core.model import RodModel
from dnarod.core.trajectory import load_trajectory


#: energies.csv columns renamed in the row (a setting has the plain name).
RENAME = {"temperature_K": "kinetic_temperature_K"}


def mean_err(values, blocks=None, flags=None, what="value"):
    """(mean, standard error) of a 1-D series by :func:`dnarod.analysis.statistics.estimate`; its flag, if any, is
    appended to ``flags`` (``blocks`` is accepted for callers of the block version and not used)."""
    from dnarod.analysis.statistics import estimate

    e = estimate(values, what=what)
    if flags is not None and e.flag:
        flags.append(e.flag)
    return e.mean, e.error


def read_energies(path):
    """Columns of an energies CSV as a dict name -> float array."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    if not rows:
        raise DnarodError(f"{path}: empty energies file")
    head, body = rows[0], [r for r in rows[1:] if len(r) == len(rows[0])]
    data = np.array(body, float) if body else np.empty((0, len(head)))
    return {h: data[:, i] for i, h in enumerate(head)}


def reduce_run(member_dir, settings, analysis):
    """Observables of the run in ``member_dir`` (see the module docstring).

    Parameters
    ----------
    member_dir : path
        A finished run directory (``energies.csv``, ``trajectory.dtraj``, ``final_model.npz``).
    settings : dict
        The member's settings (``ring`` selects the ring observables).
    analysis : dict
        ``discard_ns`` (default 0) and ``blocks`` (default 10).

    Returns
    -------
    dict
        name -> float.
    """
    d = Path(member_dir)
    blocks = int(analysis.get("blocks", 10))
    t0 = 1000.0 * float(analysis.get("discard_ns", 0.0))
    out = {}
    flags = []
    e = read_energies(d / "energies.csv")
    keep = e["time_ps"] >= t0 if "time_ps" in e else slice(None)
    for name, col in e.items():
        if name in ("step", "time_ps"):
            continue
        name = RENAME.get(name, name)
        col = col[keep]
        if col.size:
            out[name], out[name + "_err"] = mean_err(col, flags=flags, what=name)
    traj = load_trajectory(d / "trajectory.dtraj")
    sel = np.nonzero(traj.time >= t0)[0]
    if sel.size == 0:
        raise DnarodError(f"{d}: no frames after discard_ns = {t0 / 1000:g} ns (run length "
                          f"{traj.time[-1] / 1000 if traj.n_frames else 0:g} ns)")
    traj = traj[int(sel[0]):]
    out["n_frames"] = int(traj.n_frames)
    out["analysed_ns"] = float((traj.time[-1] - traj.time[0]) / 1000.0)
    ring = bool(settings.get("ring", False))
    circular = ring or bool(settings.get("circular", False))
    model = RodModel.load(d / "final_model.npz")
    if not circular:
        ee = EndToEnd(traj, n_blocks=blocks).run().results
        out["end_to_end_nm"], out["end_to_end_nm_err"] = ee.mean, ee.mean_err
        if ee.mean_estimate.flag:
            flags.append(ee.mean_estimate.flag)
    # lags wrap around a ring only; a periodic (screw-closed) chain's last and first nodes are not neighbours
    # in one frame, so its lag-1 pairs are the open chain's
    tc = TangentCorrelation(traj, model.ds, n_max=1, n_blocks=blocks, circular=ring).run().results
    c, dc = float(tc.correlation[1]), float(tc.correlation_err[1])
    if tc.lag1_estimate.flag:
        flags.append(tc.lag1_estimate.flag)
    if 0 < c < 1:
        out["persistence_length_nm"] = -model.ds / math.log(c)
        out["persistence_length_nm_err"] = model.ds / (c * math.log(c) ** 2) * dc
    else:
        out["persistence_length_nm"], out["persistence_length_nm_err"] = math.nan, math.nan
    if ring:
        lk = LinkingNumber(traj).run().results
        for name, series in (("twist_turns", lk.twist), ("writhe_turns", lk.writhe), ("linking_turns", lk.linking)):
            out[name], out[name + "_err"] = mean_err(series, flags=flags, what=name)
    out["flags"] = " | ".join(flags) or None
    return out
