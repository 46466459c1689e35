"""Check ``torsion``: the effective torsional stiffness of a stretched chain, C_eff(F), two ways, against
Moroz & Nelson.

System: an open ``dna-default`` chain in magnetic tweezers (node 0 clamped, force F on the last node along z;
:mod:`dnarod.workflows.protocols.tweezers`), OpenMM engine with excluded volume and Debye-Hueckel at 0.15 M.

1. **Torque-turns slope**: two rotation-clamped members at ``+-turns`` (below buckling); the torque is the
   twisting-moment estimator of :func:`dnarod.workflows.protocols.measure.twisting_moment` and the applied linking
   difference the measured ``Lk - Lk0`` (``Tw + Wr`` with the vertical closure). ``C_slope =
   L d(torque) / (kT 2 pi d(Lk))``.
2. **Twist fluctuations of an (almost) torque-free end**: one member with a weak rotation clamp k_w at zero
   turns, friction critically damping the slowest twist mode (:func:`twist_friction`); the end rotation phi about z has
   ``<dphi^2> = kT / (k_w + kT C_eff / L)``, so ``C_fluct = L (kT / <dphi^2> - k_w) / kT``. Its error comes from the
   measured integrated autocorrelation time of phi^2.
3. **Theory** (the model's own parameters): Moroz & Nelson's high-force expansion (PNAS 94:14418, 1997;
   Macromolecules 31:6333, 1998; third-order form as summarised by Lipfert et al., Nat. Commun. 2:439,
   2011): ``C_eff = C (1 - M/(4 K0) + (M^2 - 2M)/(16 K0^2) - (4M^3 - 16M^2 + 21M)/(256 K0^3))`` with
   ``M = C/A``, ``K0 = sqrt(A F / kT)``, A the model's exact persistence length and C its bare torsional
   persistence length at constant force, ``C = sec^4(theta0/2) / ((K^-1)_33 kT)`` (twist compliance with every
   other stress fixed, converted from the Cayley twist to the rotation angle).

Pass: the two measurements agree within ``Z_TOL`` combined standard errors, and each agrees with the theory
within ``Z_TOL`` standard errors plus ``THEORY_ALLOWANCE`` (relative) for what separates a chain of a few
persistence lengths with clamped end tangents from the long-chain expansion. ``c_override`` replaces the
model's C in the theory (the tests feed a wrong value to show the check fails).
"""
from __future__ import annotations

import time
import tempfile
from pathlib import Path

import numpy as np

from dnarod.physics.theory.torsion import bare_twist_persistence, moroz_nelson, twist_friction
from dnarod.analysis.plots import new_figure, save_figure
from dnarod.core.forcefield import load_forcefield
from dnarod.workflows.protocols.tweezers import run_member
from dnarod.physics.thermal import persistence_length
from dnarod.core.units import kT, PN
from dnarod.analysis.polymer import integrated_autocorrelation_time

NAME = "torsion"
Z_TOL = 3.0
THEORY_ALLOWANCE = 0.10


def check_torsion(out_dir, quick=False, n_bp=None, force_pN=3.0, turns=0.6, slope_ns=None, fluct_ns=None,
                  weak_clamp_kJ_mol=1.0, fluct_friction=None, temperature=300.0, seed=21, c_override=None, plots=True,
                  member_root=None):
    """Run the check (see the module docstring); ``quick`` uses a 100 bp chain and short runs."""

    t0 = time.perf_counter()
    n_bp = n_bp or (100 if quick else 300)
    slope_ns = slope_ns or (0.4 if quick else 4.0)
    fluct_ns = fluct_ns or (12.0 if quick else 60.0)
    root = Path(member_root) if member_root else Path(tempfile.mkdtemp(prefix="torsion_", dir=out_dir))
    kt_pn = kT(temperature) / PN
    model = load_forcefield("dna-default").model_from_sequence(n_nodes=n_bp)
    L = model.ds * model.n_steps
    A = persistence_length(model.params, model.ds, kT(temperature))
    C0 = bare_twist_persistence(model, temperature)
    C_ref = C0 if c_override is None else float(c_override)
    theory = float(moroz_nelson(C_ref, A, force_pN, kt_pn))
    base = dict(n_bp=n_bp, force_pN=force_pN, temperature_K=temperature, equilibration_ns=0.2 if quick else 1.0)
    plus = run_member(dict(base, turns=turns, time_ns=slope_ns, seed=seed), root / "plus")
    minus = run_member(dict(base, turns=-turns, time_ns=slope_ns, seed=seed + 1), root / "minus")
    dtau = plus["twist_torque_pN_nm"] - minus["twist_torque_pN_nm"]
    dtau_se = float(np.hypot(plus["twist_torque_pN_nm_err"], minus["twist_torque_pN_nm_err"]))
    dlk = plus["delta_lk"] - minus["delta_lk"]
    c_slope = L * dtau / (kt_pn * 2 * np.pi * dlk)
    c_slope_se = abs(c_slope) * dtau_se / abs(dtau)
    if fluct_friction is None:
        fluct_friction = twist_friction(model, temperature, C0)
    fl = run_member(dict(base, turns=0.0, clamp_k_kJ_mol=weak_clamp_kJ_mol, friction_per_ps=fluct_friction,
                         time_ns=fluct_ns, sample_ps=5.0, seed=seed + 2), root / "fluct")
    d = np.genfromtxt(root / "fluct" / "samples.csv", delimiter=",", names=True)

    phi = (d["end_turns"] - d["end_turns"].mean()) * 2 * np.pi
    var = float(np.mean(phi ** 2))
    tau = integrated_autocorrelation_time(phi ** 2)
    n_eff = len(phi) / (2 * tau)
    var_se = float(np.std(phi ** 2, ddof=1) / np.sqrt(n_eff))
    kw = weak_clamp_kJ_mol
    kt = kT(temperature)
    c_fluct = L * (kt / var - kw) / kt
    c_fluct_se = L * kt / var ** 2 * var_se / kt
    z_agree = abs(c_slope - c_fluct) / np.hypot(c_slope_se, c_fluct_se)
    tol_slope = Z_TOL * c_slope_se + THEORY_ALLOWANCE * theory
    tol_fluct = Z_TOL * c_fluct_se + THEORY_ALLOWANCE * theory
    passed = bool(z_agree <= Z_TOL and abs(c_slope - theory) <= tol_slope and abs(c_fluct - theory) <= tol_fluct)
    res = dict(model=f"dna-default open chain, {n_bp} bp (L = {L:.1f} nm), tweezers at {force_pN} pN, 0.15 M",
               temperature_K=temperature, persistence_length_nm=A, bare_twist_persistence_nm=C0,
               twist_persistence_used_nm=C_ref, moroz_nelson_C_eff_nm=theory,
               slope=dict(turns=turns, torque_plus_pN_nm=plus["twist_torque_pN_nm"],
                          torque_minus_pN_nm=minus["twist_torque_pN_nm"], delta_lk_plus=plus["delta_lk"],
                          delta_lk_minus=minus["delta_lk"], torque_tau_ps=plus["twist_torque_pN_nm_tau_ps"],
                          production_ns=slope_ns, C_eff_nm=c_slope, standard_error_nm=c_slope_se,
                          plectoneme_fraction=max(plus["plectoneme_fraction"], minus["plectoneme_fraction"])),
               fluctuation=dict(weak_clamp_kJ_mol=kw, friction_per_ps=fluct_friction, production_ns=fluct_ns,
                                variance_rad2=var, variance_se=var_se, tau_int_samples=tau, n_effective=n_eff,
                                C_eff_nm=c_fluct, standard_error_nm=c_fluct_se),
               agreement_z=float(z_agree), z_tolerance=Z_TOL, theory_allowance_relative=THEORY_ALLOWANCE,
               slope_tolerance_nm=tol_slope, fluctuation_tolerance_nm=tol_fluct,
               cost=dict(slope_members_wall_s=plus["wall_s"] + minus["wall_s"], fluctuation_wall_s=fl["wall_s"],
                         ns_per_day=fl["ns_per_day"]),
               passed=passed)
    if plots:
        fig, ax = new_figure(1, 1, width=5.5, height=4.0)
        a = ax[0, 0]
        F = np.linspace(0.3, 10, 60)
        a.plot(F, moroz_nelson(C_ref, A, F, kt_pn), "k-", label=f"Moroz-Nelson (A {A:.1f}, C {C_ref:.1f} nm)")
        a.errorbar([force_pN * 0.98], [c_slope], yerr=[c_slope_se], fmt="o", capsize=3, label="torque-turns slope")
        a.errorbar([force_pN * 1.02], [c_fluct], yerr=[c_fluct_se], fmt="s", capsize=3, label="twist fluctuations")
        a.set_xlabel("force (pN)")
        a.set_ylabel("C_eff (nm)")
        a.legend(fontsize=8)
        res["plots"] = [save_figure(fig, out_dir, "torsion.png")]
    res["runtime_s"] = time.perf_counter() - t0
    return res
