"""Measured values drawn beside a protocol's curve, converted to the curve's axes (:mod:`dnarod.physics.experiments`).

Each function draws one reference on a matplotlib axes ``a`` from the curve's rows; a protocol object lists the
ones that apply to it (:mod:`dnarod.workflows.protocols.ensemble_hooks`), so adding a reference is adding a function
here and naming it in the protocol.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.units import PN, kT
from dnarod.physics import experiments as ex


def _kt_pn(rows):
    return kT(float(rows[0].get("temperature_K") or 300.0)) / PN


def twist_slopes(a, rows, rotor_bead):
    """Torque-turns: the pre-buckling slope ``kT C_eff 2 pi turns / L`` of this chain for each measured torsional
    stiffness (rotor-bead measurements with ``rotor_bead``, the others without), labelled with the force it was
    measured at (not necessarily the run's force)."""
    T = float(rows[0].get("temperature_K") or 300.0)
    L = float(rows[0]["contour_length_nm"])
    t = np.array([float(r.get("turns") or 0.0) for r in rows])
    tt = np.linspace(min(t.min(), 0.0), max(t.max(), 0.0), 20)
    run_f = rows[0].get("force_pN")
    for m in ex.effective_torsional_persistence(temperature=T):
        if rotor_bead == ("rotor-bead" in m.conditions):
            a.plot(tt, _kt_pn(rows) * m.value * 2 * np.pi * tt / L, "--", lw=1,
                   label=f"slope, measured C_eff = {m.value:.0f} nm at {m.force_pN:g} pN "
                         f"({ex.cite_short(m.source)}; run at {run_f} pN)")


def rotor_bead_twist_slopes(a, rows):
    """:func:`twist_slopes` of the rotor-bead measurements (``torsional_stiffness.csv``)."""
    twist_slopes(a, rows, True)


def other_twist_slopes(a, rows):
    """:func:`twist_slopes` of the other measurements (``effective_torsional_stiffness.csv``)."""
    twist_slopes(a, rows, False)


def wlc_persistence_lengths(a, rows):
    """Force-extension: the worm-like-chain extension (Bouchiat interpolation, inextensible) with each measured
    persistence length, labelled with its salt, and shaded the band of the persistence lengths that bracket the run's
    salt (:func:`~dnarod.physics.experiments.persistence_length_band`)."""
    from dnarod.physics.theory.wlc import extensible_wlc_extension  # loads scipy.optimize

    kt_pn = _kt_pn(rows)
    F = np.array([float(r["force_pN"]) for r in rows])
    FF = np.logspace(np.log10(F.min()) - 0.1, np.log10(F.max()) + 0.1, 60)
    salt = float(rows[0].get("salt_M") or 0.15)
    for m in ex.persistence_lengths():
        a.plot(FF, extensible_wlc_extension(FF, m.value, 1e12, kt_pn), ":", lw=1,
               label=f"WLC, measured lp {m.value:g} nm at {1000 * m.salt_M:g} mM Na+ ({ex.cite_short(m.source)})")
    try:
        lo, hi, _ = ex.persistence_length_band(salt)
    except ValueError:
        return
    a.fill_between(FF, extensible_wlc_extension(FF, lo, 1e12, kt_pn), extensible_wlc_extension(FF, hi, 1e12, kt_pn),
                   color="0.85", zorder=0, label=f"measured lp {lo:g}-{hi:g} nm bracketing {1000 * salt:g} mM")


def transition_torques(a, rows):
    """Torque-turns: the torque of the B->P structural transition (34 +- 2 pN nm, measured at 45 pN; Bryant et al.
    2003) as a horizontal band, labelled as a limit of B-DNA measured at another force, not a buckling torque."""
    run_f = rows[0].get("force_pN")
    for m in ex.structural_transition_torques():
        tau, sig = m.value / PN, (m.uncertainty or 0.0) / PN
        what = "B->P transition" if tau > 0 else "unwinding transition"
        at = f"at {m.force_pN:g} pN" if m.force_pN is not None else "force not stated"
        if sig > 0:
            a.axhspan(tau - sig, tau + sig, color="0.8", alpha=0.6, zorder=0,
                      label=f"{what} torque {tau:g}+-{sig:g} pN nm {at} ({ex.cite_short(m.source)}; "
                            f"a limit of B-DNA, not buckling; run at {run_f} pN)")
        else:
            a.axhline(tau, color="0.6", ls=":", lw=2, zorder=0,
                      label=f"{what} torque {'~' if m.approximate else ''}{tau:g} pN nm, {at} "
                            f"({ex.cite_short(m.source)}, quoted; a limit of B-DNA, not buckling)")
        lo, hi = a.get_ylim()  # keep each limit in view beside the run's torques
        a.set_ylim(min(lo, 1.15 * (tau - sig)), max(hi, 1.15 * (tau + sig)))


def buckling_torques(a, rows):
    """Torque-turns: measured buckling torques and post-buckling plateaus at the run's force, if any were read."""
    run_f = float(rows[0].get("force_pN") or 0.0)
    for q, mk in (("buckling_torque", "v"), ("postbuckling_torque_plateau", "_")):
        for m in ex.buckling_torque_reference(q, force_pN=run_f):
            a.errorbar([0.0], [m.value / PN], yerr=[(m.uncertainty or 0.0) / PN], fmt=mk, ms=10, capsize=4,
                       label=f"measured {q.replace('_', ' ')} {m.value / PN:g} pN nm at {m.force_pN:g} pN"
                             + (f", {1000 * m.salt_M:g} mM" if m.salt_M is not None else "")
                             + f" ({ex.cite_short(m.source)})")


def _ewlc_label(c):
    return (f"eWLC lp {c.persistence_length:g} nm, S {c.stretch_modulus_pN:g} pN drawn over lambda-DNA data "
            f"at {1000 * c.salt_M:g} mM Na+ ({c.source.split(',')[0]} Fig. 2)")


def ewlc_curves(a, rows):
    """Force-extension: the extensible-WLC curve a source draws over its measured lambda-DNA data (lp 50 nm, S 1000
    pN at 100 mM Na+; :func:`~dnarod.physics.experiments.force_extension_curves`), labelled with its salt."""
    from dnarod.physics.theory.wlc import extensible_wlc_extension  # loads scipy.optimize

    F = np.array(sorted({float(r["force_pN"]) for r in rows if r.get("force_pN") is not None}))
    FF = np.logspace(np.log10(F.min()) - 0.1, np.log10(F.max()) + 0.1, 60)
    for c in ex.force_extension_curves():
        a.plot(FF, extensible_wlc_extension(FF, c.persistence_length, c.stretch_modulus_pN, _kt_pn(rows)), "-.",
               lw=1, color="0.3", label=_ewlc_label(c))


def ewlc_at_zero_turns(a, rows):
    """Hat curves: a diamond at zero turns for the x/L of the curve drawn over lambda-DNA data (100 mM Na+) at the
    run's forces."""
    from dnarod.physics.theory.wlc import extensible_wlc_extension  # loads scipy.optimize

    F = np.array(sorted({float(r["force_pN"]) for r in rows if r.get("force_pN") is not None}))
    for c in ex.force_extension_curves():
        a.plot(np.zeros_like(F), extensible_wlc_extension(F, c.persistence_length, c.stretch_modulus_pN,
                                                          _kt_pn(rows)), "D", mfc="none", color="0.3",
               label=f"x/L at {', '.join(f'{f:g}' for f in F)} pN: " + _ewlc_label(c))


def persistence_length_bar(a, rows):
    """Hat curves: at zero turns a bar spans the relative extension that the measured persistence lengths bracketing
    the run's salt give at the run's force (long-molecule worm-like chain: a chain of a few persistence lengths with
    clamped ends extends further)."""
    T = float(rows[0].get("temperature_K") or 300.0)
    salt = float(rows[0].get("salt_M") or 0.15)
    for f in sorted({float(r["force_pN"]) for r in rows if r.get("force_pN") is not None}):
        try:
            lo, hi = ex.wlc_extension_band([f], salt, 1e12, T)
            lp_lo, lp_hi, _ = ex.persistence_length_band(salt)
        except ValueError:
            continue
        a.errorbar([0.0], [0.5 * (lo[0] + hi[0])], yerr=[[0.5 * (hi[0] - lo[0])]], fmt="none", ecolor="k",
                   capsize=6, lw=2, label=f"x/L at {f:g} pN from measured lp {lp_lo:g}-{lp_hi:g} nm "
                                       f"({1000 * salt:g} mM; long-molecule WLC)")


def writhe_fraction(a, rows):
    """Rings: the line ``Wr = f dLk`` for the writhe fraction read ("usually ~70%", a review quoting its sources; no
    superhelical density or salt stated, the label says so beside the run's salt)."""
    dl = np.array([float(r.get("delta_lk") or 0.0) for r in rows])
    xx = np.linspace(min(dl.min(), 0.0), max(dl.max(), 0.0), 20)
    salt = rows[0].get("salt_M")
    for m in ex.writhe_fraction_reference():
        cond = ("; " + (f"{1000 * m.salt_M:g} mM" if m.salt_M is not None else "salt not stated")
                + ("" if m.uncertainty is None else f"; +-{m.uncertainty:g}"))
        a.plot(xx, m.value * xx, ":", lw=1,
               label=f"Wr = {'~' if m.approximate else ''}{m.value:g} dLk ({ex.cite_short(m.source)}, quoted"
                     f"{cond}; run at {1000 * float(salt or 0.15):g} mM)")
