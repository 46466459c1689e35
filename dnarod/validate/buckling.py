"""Check ``buckling`` (not in ``--quick``): the torque plateau of a buckled, plectonemic chain.

System: an open ``dna-default`` chain in magnetic tweezers at constant force (node 0 clamped, rotation clamp and
force on the last node, surface and bead walls; :mod:`dnarod.protocols.tweezers`), OpenMM engine, WCA +
Debye-Hueckel at 0.15 M. Members at one pre-buckling number of turns and at two numbers of turns past
buckling.

Reference: Marko's two-phase model (J. F. Marko, Phys. Rev. E 76:021926, 2007; abstract): when plectonemic
and extended domains coexist, the torque depends only on the force, not on the linking number, while the
extension keeps falling with the linking number. Measured here: (1) both post-buckling members are
plectonemic (detector of :mod:`dnarod.protocols.measure`), (2) their torques agree within ``Z_TOL``
combined standard errors plus ``PLATEAU_ALLOWANCE`` (pN nm; a finite chain's plectoneme end loop and
tails still take a little twist), (3) their extensions differ (the extension falls with Lk at constant
torque), (4) the pre-buckling torque follows the linear law ``kT C_eff 2 pi dLk / L`` with the Moroz-Nelson
C_eff of check ``torsion`` within ``Z_TOL`` SE + 15 %.

Not compared (no value could be verified this session): Marko's closed-form plateau torque and buckling
point, and the measured buckling torques of Mosconi et al. 2009, Forth et al. 2008 and Lipfert et al. 2010.
Passing pre-buckling turns as ``post_turns`` shows the plateau criterion failing (the tests do).
"""
from __future__ import annotations

import time

import numpy as np

from ._common import new_figure, save_figure

NAME = "buckling"
Z_TOL = 3.0
PLATEAU_ALLOWANCE = 2.0  # pN nm
LINEAR_ALLOWANCE = 0.15


def check_buckling(out_dir, quick=False, n_bp=None, force_pN=1.0, pre_turns=None, post_turns=None, time_ns=None,
                   temperature=300.0, seed=31, plots=True, member_root=None):
    """Run the check (see the module docstring)."""
    import tempfile
    from pathlib import Path

    from ..forcefield import load_forcefield
    from ..protocols.tweezers import intrinsic_turns, run_member
    from ..thermal import kT, persistence_length
    from ..units import PN
    from .torsion import bare_twist_persistence, moroz_nelson

    t0 = time.perf_counter()
    n_bp = n_bp or (200 if quick else 600)
    model = load_forcefield("dna-default").model_from_sequence(n_nodes=n_bp)
    lk0 = intrinsic_turns(model)
    pre_turns = 0.02 * lk0 if pre_turns is None else float(pre_turns)
    post_turns = (0.075 * lk0, 0.098 * lk0) if post_turns is None else tuple(post_turns)
    time_ns = time_ns or (1.0 if quick else 6.0)
    root = Path(member_root) if member_root else Path(tempfile.mkdtemp(prefix="buckling_", dir=out_dir))
    L = model.ds * model.n_steps
    kt_pn = kT(temperature) / PN
    A = persistence_length(model.params, model.ds, kT(temperature))
    c_mn = float(moroz_nelson(bare_twist_persistence(model, temperature), A, force_pN, kt_pn))
    rows = []
    for i, t in enumerate((pre_turns, *post_turns)):
        r = run_member(dict(n_bp=n_bp, force_pN=force_pN, turns=round(float(t), 4), time_ns=time_ns,
                            temperature_K=temperature, seed=seed + i), root / f"turns{t:+.3f}")
        rows.append(r)
    pre, p1, p2 = rows
    lin = kt_pn * c_mn * 2 * np.pi * pre["delta_lk"] / L
    lin_ok = abs(pre["twist_torque_pN_nm"] - lin) <= Z_TOL * pre["twist_torque_pN_nm_err"] + LINEAR_ALLOWANCE * abs(lin)
    plectonemic = bool(p1["plectonemic"] > 0.5 and p2["plectonemic"] > 0.5)
    dtau = p2["twist_torque_pN_nm"] - p1["twist_torque_pN_nm"]
    dtau_se = float(np.hypot(p1["twist_torque_pN_nm_err"], p2["twist_torque_pN_nm_err"]))
    plateau_ok = abs(dtau) <= Z_TOL * dtau_se + PLATEAU_ALLOWANCE
    dx = p2["relative_extension"] - p1["relative_extension"]
    dx_se = float(np.hypot(p1["relative_extension_err"], p2["relative_extension_err"]))
    falls = dx < -Z_TOL * dx_se
    passed = bool(lin_ok and plectonemic and plateau_ok and falls)
    res = dict(model=f"dna-default open chain, {n_bp} bp (L = {L:.1f} nm, Lk0 = {lk0:.2f}), {force_pN} pN, 0.15 M",
               temperature_K=temperature, production_ns_per_member=time_ns,
               members=[{k: r[k] for k in ("turns", "delta_lk", "relative_extension", "relative_extension_err",
                                             "twist_torque_pN_nm", "twist_torque_pN_nm_err", "clamp_torque_pN_nm",
                                             "clamp_torque_pN_nm_err", "Wr", "plectoneme_fraction", "plectonemic",
                                             "lk_slips", "wall_s")} for r in rows],
               pre_buckling=dict(torque_pN_nm=pre["twist_torque_pN_nm"], linear_law_pN_nm=lin,
                                 moroz_nelson_C_eff_nm=c_mn, passed=bool(lin_ok)),
               plateau=dict(torque_difference_pN_nm=dtau, standard_error=dtau_se, allowance_pN_nm=PLATEAU_ALLOWANCE,
                            mean_torque_pN_nm=0.5 * (p1["twist_torque_pN_nm"] + p2["twist_torque_pN_nm"]),
                            both_plectonemic=plectonemic, passed=bool(plateau_ok)),
               extension_drop=dict(difference=dx, standard_error=dx_se, passed=bool(falls)),
               z_tolerance=Z_TOL, passed=passed)
    if plots:
        fig, ax = new_figure(2, 1, width=4.5, height=3.6)
        t = [r["delta_lk"] for r in rows]
        ax[0, 0].errorbar(t, [r["twist_torque_pN_nm"] for r in rows], yerr=[r["twist_torque_pN_nm_err"] for r in rows],
                          fmt="o", capsize=3, label="twisting moment")
        tt = np.linspace(0, max(t), 20)
        ax[0, 0].plot(tt, kt_pn * c_mn * 2 * np.pi * tt / L, "k--", label="linear law, Moroz-Nelson C_eff")
        ax[0, 0].set_xlabel("Lk - Lk0 (turns)")
        ax[0, 0].set_ylabel("torque (pN nm)")
        ax[0, 0].legend(fontsize=7)
        ax[0, 1].errorbar(t, [r["relative_extension"] for r in rows],
                          yerr=[r["relative_extension_err"] for r in rows], fmt="s", capsize=3)
        ax[0, 1].set_xlabel("Lk - Lk0 (turns)")
        ax[0, 1].set_ylabel("extension / L")
        res["plots"] = [save_figure(fig, out_dir, "buckling.png")]
    res["runtime_s"] = time.perf_counter() - t0
    return res
