"""Check ``experiment`` (quick, no simulation): the ``dna-default`` model's elastic response against measured DNA.

The model's own numbers are exact (no sampling): its bending persistence length (the discrete chain's exact
value, :func:`dnarod.physics.thermal.persistence_length`), its bare torsional persistence length C
(:func:`dnarod.validate.torsion.bare_twist_persistence`) and its effective torsional stiffness under tension
``C_eff(F)`` from the Moroz-Nelson expansion with those A and C (:func:`dnarod.validate.torsion.moroz_nelson`;
check ``torsion`` measures that the simulated chain follows it). The measured values are read by
:mod:`dnarod.physics.experiments` from ``data/experimental/`` (sources in ``data/README.md``).

Comparisons (each passes only inside its tolerance; the overall check passes if all do):

1. **Bending persistence length** vs the persistence lengths fitted to single-molecule force-extension curves
   (Wang et al. 1997; Wenner et al. 2002) that bracket the salt ``salt_M``
   (:func:`~dnarod.physics.experiments.persistence_length_band`): pass if the model's lp lies inside the
   measured interval (the tolerance is the experimental spread; the papers' abstracts state no errors). The
   relative extensions x/L that the measured interval implies at ``forces_pN`` (extensible WLC, Bouchiat
   interpolation, the model's stretch modulus) are reported beside the model's own.
2. **Effective torsional stiffness** C_eff(F) at the force of each measurement (magnetic torque tweezers at
   6.5 pN, NAR 45:5920; rotor-bead tweezers at 15 pN, Bryant et al. 2003, converted with kT at
   ``temperature``): pass if ``|model - measured| <= Z_TOL sigma_measured + THEORY_ALLOWANCE C_model``, the
   allowance being the Moroz-Nelson accuracy for a finite chain used by check ``torsion``.
3. **Bare torsional persistence length** C vs the measured microscopic values (Bryant et al. 2003 rotor-bead
   rigidities, Moroz & Nelson 1997/1998 fits): pass if inside ``[min(value - sigma), max(value + sigma)]``
   over the measurements (their spread plus their stated errors).

4. **Writhe fraction** Wr/ΔLk of a supercoiled ring, when a model value is given (``writhe_fraction_model``;
   :func:`dnarod.validate.run_validation` passes the one check ``plectonemes`` measured in the same run) vs the
   "usually ~70%" that a review quotes (Witz & Stasiak 2010; no superhelical density, salt or error stated):
   pass if ``|model - 0.7| <= Z_TOL SE_model + WRITHE_ROUNDING``, the allowance being the precision of a value
   quoted as a round percentage (:func:`compare_writhe_fraction`).
5. **Effective diameter** (gating by default): the model's second-virial effective diameter at ``salt_M``
   (:func:`dnarod.physics.theory.supercoil.effective_diameter` of the default non-bonded terms: WCA 2 nm + shifted
   Debye-Hückel with the calibrated Poisson-Boltzmann far-field charge, ``dnarod.engines.openmm.nonbonded``) vs the
   hard-cylinder diameter with the same second virial coefficient as the Poisson-Boltzmann potential at 150 mM, 5.0 nm
   (Gebe et al. 1995, Biophys J abstract: a computed value, not a measurement; ``dna_diameter.csv``): pass if
   ``|model - reference| <= DIAMETER_PRECISION_NM + DIAMETER_QUADRATURE_NM`` (the reference's precision, "50 Å"
   read as rounded to 10 Å, plus the measured quadrature error of the model's value;
   :func:`compare_effective_diameter`). The model's charge is calibrated to this value at 0.15 M, so there the
   comparison checks that the calibration holds (it fails with Manning's charge, 2.5 nm, or with half or twice
   the calibrated charge); at other salts no value was read and the diameter is reported only.
   ``gate_effective_diameter=False`` reports without gating.

6. **Reported, not gating** (the sources state no uncertainty, so no tolerance can be set): the model's stretch
   modulus and x/L at ``forces_pN`` beside the extensible-WLC curve (lp 50 nm, S 1000 pN) that a source draws over
   lambda-DNA data at 100 mM Na+ (PMC33432 Fig. 2; :func:`compare_force_extension_curve`), and the model's bare C
   beside the C = 3.0e-19 erg cm that Frank-Kamenetskii et al. (1985) fitted to Horowitz & Wang's topoisomer
   variances (:func:`compare_topoisomer_fit`); the model's lp, C and helical repeat beside the worm-like-chain
   fit to measured cyclization j-factors (a = 48.5 nm, C = 2.4e-19 erg cm, 10.49 bp per turn; figure caption on the
   PubMed page of PMID 15778443; :func:`compare_cyclization_fit`); and the model's S, kT C and g/kT placed inside or
   outside the ranges of measured values that an MD study tabulates (**secondary**: PNAS 114:7049 (2017) Table 1;
   two stretch-modulus rows 1450-1750 and 649-1401 pN whose distinguishing label is lost in the stored text,
   C 386-448 pN nm^2, g/kT -39 to -17; :func:`compare_elastic_ranges`); and the model's C, twist-only N K and
   helical repeat beside the Horowitz & Wang (1984) abstract (2.9e-19 erg cm; N K = 3900 RT bp for 200-bp rings,
   whose writhe they take as vanishing; 10.54 bp for 210-bp rings; :func:`compare_horowitz_wang`). Their N K ~ 1150
   RT bp of rings longer than 2000 bp is quoted by check ``nicked_ring`` beside the model's K at 3000 bp.

Not compared, because no value could be read (:data:`dnarod.physics.experiments.MISSING`): buckling torques
and post-buckling plateaus, Depew & Wang's own K and an uncertainty or ionic conditions for K, measured (knotting)
effective diameters and the primary writhe-fraction measurements. ``lp_override`` / ``c_override`` / ``d_override``
replace the model's values (the tests show the check failing with wrong ones).
"""
from __future__ import annotations

import time

import numpy as np

NAME = "experiment"
Z_TOL = 3.0
THEORY_ALLOWANCE = 0.10
DEFAULT_FORCES_PN = (0.1, 0.3, 1.0, 3.0, 10.0)
#: Allowance of the writhe-fraction comparison: the value read is "~70%", a round percentage (+-5 points).
WRITHE_ROUNDING = 0.05
#: Precision of the effective-diameter reference, nm: stated as "d = 50 A" without error or decimal, read as rounded
#: to the nearest 10 Angstrom (+-5 A).
DIAMETER_PRECISION_NM = 0.5
#: Quadrature allowance of the model's effective diameter, nm: at 0.15 M the grids (angles, offsets, distances)
#: (10, 2, 120), (12, 2, 200) and (16, 3, 160, the default of
#: :func:`dnarod.physics.theory.supercoil.effective_diameter`) agree to 1e-4 nm (README "What is calibrated to
#: what"); 0.01 nm is allowed.
DIAMETER_QUADRATURE_NM = 0.01


def compare_writhe_fraction(f_model, f_model_se, description=""):
    """Model writhe fraction ``Wr/ΔLk`` (ratio, with standard error) vs the value read
    (:func:`dnarod.physics.experiments.writhe_fraction_reference`).

    Returns a dict (``model``, ``model_se``, ``measured``, ``tolerance``, ``difference``, ``passed``, source
    fields) or None when no value is tabulated. Pass: ``|model - measured| <= Z_TOL * SE + WRITHE_ROUNDING``
    (+ ``Z_TOL`` times the source's uncertainty when it states one).
    """
    from dnarod.physics import experiments as ex

    refs = ex.writhe_fraction_reference()
    if not refs:
        return None
    m = refs[0]
    tol = Z_TOL * float(f_model_se) + WRITHE_ROUNDING + Z_TOL * (m.uncertainty or 0.0)
    diff = float(f_model) - m.value
    return dict(model=float(f_model), model_se=float(f_model_se), model_description=description, measured=m.value,
                measured_uncertainty=m.uncertainty, approximate=m.approximate, difference=diff, tolerance=tol,
                source=ex.cite_short(m.source), conditions=m.conditions, url=m.url, passed=bool(abs(diff) <= tol))


def compare_effective_diameter(d_model_nm, salt_M):
    """Model effective diameter (nm, second-virial definition) at ``salt_M`` (mol/L) vs the computed
    Poisson-Boltzmann second-virial diameter read for that salt
    (:func:`dnarod.physics.experiments.effective_diameter_second_virial_reference`).

    Returns a dict (``model_nm``, ``reference_nm``, ``tolerance_nm``, ``ratio``, ``agrees``, source fields) or None
    when no reference exists at this salt. Agree: ``|model - reference| <= DIAMETER_PRECISION_NM +
    DIAMETER_QUADRATURE_NM``.
    """
    from dnarod.physics import experiments as ex

    refs = [m for m in ex.effective_diameter_second_virial_reference()
            if m.salt_M is not None and abs(m.salt_M - salt_M) < 1e-9]
    if not refs:
        return None
    m = refs[0]
    tol = DIAMETER_PRECISION_NM + DIAMETER_QUADRATURE_NM
    return dict(model_nm=float(d_model_nm), reference_nm=m.value, salt_M=salt_M, tolerance_nm=tol,
                ratio=float(d_model_nm) / m.value, difference_nm=float(d_model_nm) - m.value,
                kind="computed (Poisson-Boltzmann second virial), not measured; the model's charge is calibrated to it",
                source=ex.cite_short(m.source),
                conditions=m.conditions, url=m.url, agrees=bool(abs(float(d_model_nm) - m.value) <= tol))


def compare_force_extension_curve(lp_model_nm, s_model_pN, forces_pN, temperature):
    """Model relative extension x/L (extensible WLC with the model's lp, nm, and S, pN) at ``forces_pN`` beside the
    curve a source draws over measured lambda-DNA data (:func:`dnarod.physics.experiments.force_extension_curves`),
    reported only: the curve's parameters carry no uncertainty. Returns a dict or None when none is tabulated."""
    from dnarod.physics import experiments as ex
    from dnarod.core.units import kT
    from dnarod.core.units import PN
    from dnarod.physics.theory.wlc import extensible_wlc_extension

    curves = ex.force_extension_curves()
    if not curves:
        return None
    c = curves[0]
    kt_pn = kT(temperature) / PN
    F = np.asarray(forces_pN, float)
    xm = np.asarray(extensible_wlc_extension(F, lp_model_nm, s_model_pN, kt_pn))
    xc = np.asarray(extensible_wlc_extension(F, c.persistence_length, c.stretch_modulus_pN, kt_pn))
    return dict(curve_persistence_length_nm=c.persistence_length, curve_stretch_modulus_pN=c.stretch_modulus_pN,
                salt_M=c.salt_M, model_stretch_modulus_pN=float(s_model_pN),
                stretch_modulus_ratio=float(s_model_pN) / c.stretch_modulus_pN,
                relative_extension=[dict(force_pN=float(f), model=float(a), curve=float(b), difference=float(a - b))
                                    for f, a, b in zip(F, xm, xc)],
                max_abs_difference=float(np.max(np.abs(xm - xc))), kind="reported (curve parameters, no uncertainty)",
                source=c.source, conditions=c.conditions, url=c.url)


def compare_topoisomer_fit(c_model_nm, temperature):
    """Model bare torsional persistence length C (nm) beside C / kT of the rigidity Frank-Kamenetskii et al. (1985)
    fitted to Horowitz & Wang's topoisomer variances
    (:func:`~dnarod.physics.experiments.topoisomer_variance_fit_reference`), reported only (no uncertainty stated).
    Returns a dict or None."""
    from dnarod.physics import experiments as ex
    from dnarod.core.units import kT

    ref = ex.topoisomer_variance_fit_reference()
    if "torsional_rigidity" not in ref:
        return None
    m = ref["torsional_rigidity"]
    c_ref = m.value / kT(temperature)
    lp = ref.get("persistence_length")
    return dict(model_nm=float(c_model_nm), reference_nm=float(c_ref), conversion_temperature_K=temperature,
                ratio=float(c_model_nm) / c_ref, reference_persistence_length_nm=None if lp is None else lp.value,
                kind="reported (a fit to topoisomer variances, secondary to Horowitz & Wang 1984; no uncertainty)",
                source=m.source, url=m.url)


def compare_cyclization_fit(lp_model_nm, c_model_nm, repeat_model_bp, temperature):
    """Model bending persistence length (nm), bare torsional persistence length C (nm) and helical repeat (bp per
    turn) beside the worm-like-chain parameters fitted to measured cyclization j-factors
    (:func:`dnarod.physics.experiments.cyclization_fit_reference`; C / kT at ``temperature``, K), reported only
    (the caption read states no uncertainty). Returns a dict or None when none is tabulated."""
    from dnarod.physics import experiments as ex
    from dnarod.core.units import kT

    ref = ex.cyclization_fit_reference()
    if not {"persistence_length", "torsional_rigidity", "helical_repeat"} <= set(ref):
        return None
    a, c, h = ref["persistence_length"], ref["torsional_rigidity"], ref["helical_repeat"]
    c_ref = c.value / kT(temperature)
    return dict(model_persistence_length_nm=float(lp_model_nm), reference_persistence_length_nm=a.value,
                persistence_length_ratio=float(lp_model_nm) / a.value, model_twist_persistence_nm=float(c_model_nm),
                reference_twist_persistence_nm=float(c_ref), twist_persistence_ratio=float(c_model_nm) / c_ref,
                conversion_temperature_K=temperature, model_helical_repeat_bp=float(repeat_model_bp),
                reference_helical_repeat_bp=h.value, kind="reported (a fit to cyclization j-factors; no uncertainty, "
                "buffer or salt stated)", source="PMID 15778443 (figure caption)", conditions=a.conditions, url=a.url)


def compare_horowitz_wang(c_model_nm, ds_nm, repeat_model_bp, temperature):
    """The model beside the Horowitz & Wang (1984) abstract
    (:func:`~dnarod.physics.experiments.horowitz_wang_reference`,
    :func:`~dnarod.physics.experiments.supercoiling_free_energy_reference`), reported
    only (no uncertainty stated): bare C (nm) vs their 2.9e-19 erg cm / kT; the twist-only ``N K = N / (2
    <dTw^2>) = 2 pi^2 C / ds`` (bp; continuum twist variance ``L / (4 pi^2 C)``, exact for the uniform chain to the
    Cayley-angle correction) vs their N K = 3900 RT bp of 200-bp rings, where they take the writhe contribution as
    vanishing (so the twist-only value is the like-for-like one); the helical repeat vs their 10.54 bp of 210-bp
    rings. The long-ring N K ~ 1150 needs the writhe variance and is compared by check ``nicked_ring`` (model K at
    ``full_n_bp``). Returns a dict or None when nothing is tabulated."""
    from dnarod.physics import experiments as ex
    from dnarod.core.units import kT

    hw = ex.horowitz_wang_reference()
    if not {"NK_200bp", "torsional_rigidity", "helical_repeat_210bp"} <= set(hw):
        return None
    c_ref = hw["torsional_rigidity"].value / kT(temperature)
    nk_twist = 2.0 * np.pi ** 2 * float(c_model_nm) / float(ds_nm)
    long = ex.supercoiling_free_energy_reference()
    return dict(model_twist_persistence_nm=float(c_model_nm), reference_twist_persistence_nm=float(c_ref),
                twist_persistence_ratio=float(c_model_nm) / c_ref, conversion_temperature_K=temperature,
                model_NK_twist_only_bp=nk_twist, reference_NK_200bp=hw["NK_200bp"].value,
                NK_200bp_ratio=nk_twist / hw["NK_200bp"].value,
                model_helical_repeat_bp=float(repeat_model_bp),
                reference_helical_repeat_bp=hw["helical_repeat_210bp"].value,
                reference_NK_long_rings=long[0].value if long else None,
                kind="reported (abstract values, no uncertainty or ionic conditions stated)",
                source=ex.cite_short(hw["NK_200bp"].source), url=hw["NK_200bp"].url)


def compare_elastic_ranges(s_model_pN, c_model_nm, g_model_pN_nm, temperature):
    """Model stretch modulus S (pN), bare torsional persistence length C (nm, compared as kT C with kT at
    ``temperature``) and twist-stretch coupling g (pN nm, compared as g / kT) against the ranges of measured values
    that PNAS 114:7049 (2017) Table 1 tabulates (**secondary**;
    :func:`~dnarod.physics.experiments.elastic_constant_ranges`). Reported only: a range across experiments carries
    no uncertainty. Returns a list of
    dicts (``quantity``, ``model``, ``low``, ``high``, ``unit``, ``inside``, ...) or None when none is tabulated."""
    from dnarod.physics import experiments as ex
    from dnarod.core.units import kT
    from dnarod.core.units import PN

    kt_pn = kT(temperature) / PN
    model = {"stretch_modulus_range": (float(s_model_pN), 1.0 / PN, "pN"),
             "torsional_rigidity_range": (float(c_model_nm) * kt_pn, 1.0 / PN, "pN nm^2"),
             "twist_stretch_coupling_range": (float(g_model_pN_nm) / kt_pn, 1.0, "g/kBT")}
    rows = []
    for m in ex.elastic_constant_ranges():
        v, f, unit = model[m.quantity]
        lo, hi = m.value * f, m.value_max * f
        rows.append(dict(quantity=m.quantity, model=v, low=float(lo), high=float(hi), unit=unit,
                         inside=bool(lo <= v <= hi), conditions=m.conditions, source=ex.cite_short(m.source),
                         url=m.url, kind="reported (secondary range across experiments; no uncertainty)"))
    return rows or None


def model_twist_bend_coupling(temperature, forcefield="dna-default"):
    """Twist-bend coupling G (nm) of a uniform chain of ``forcefield``: the larger bend-twist off-diagonal entry of
    its rotational stiffness with the translations relaxed (:func:`dnarod.physics.thermal.bend_twist_schur`), over
    kT at ``temperature``; 0 for a model whose bending does not couple to twist (``dna-default``)."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.core.units import kT
    from dnarod.physics.thermal import bend_twist_schur

    S = bend_twist_schur(load_forcefield(forcefield).model_from_sequence(n_nodes=4).params.stiffness[0])
    return float(max(abs(S[0, 2]), abs(S[1, 2])) / kT(temperature))


#: Why a measured value is outside what the elastic rod model represents (listed by :func:`sourced_comparisons`).
OUTSIDE_MODEL = {
    "overwinding_transition_torque": "a structural transition (overwound B-DNA becomes P-DNA, the backbones inside and "
                                     "the bases outside); the rod has one B form with a harmonic twist energy, so its "
                                     "torque grows with the turns without limit: torques above it are not DNA's",
    "underwinding_transition_torque": "a structural transition (unwound B-DNA melts or turns into left-handed forms); "
                                      "the rod keeps its B form at any negative torque",
    "overstretching": "a structural transition (S-DNA or strand separation near 65-70 pN, 1.7 times longer, lower at "
                      "low salt); the rod's stretching is harmonic, and dnarod refuses forces above "
                      "dnarod.physics.loads.MAX_FORCE_PN",
    "anharmonic_twist_b_over_a": "the rod's twist energy is harmonic (a constant C); an anharmonic C(dtheta) = a - "
                                 "b dtheta/N is not in the model",
    "effective_torsional_stiffness_salt_relative_change": "the model's elastic constants do not depend on salt and its "
                                                          "non-bonded terms act only between nodes farther apart than "
                                                          "their cutoff, so the C_eff(F) of a stretched, unbuckled "
                                                          "chain is the same at every salt (the model's change: 0)",
    "persistence_length_vs_salt": "the model's bending persistence length does not depend on salt (the electrostatic "
                                  "stiffening is inside the elastic constants, fitted at one salt); it is gated only "
                                  "at the check's salt against the measurements bracketing it",
    "twist_bend_coupling_G": "dna-default has no twist-bend coupling (isotropic bending, G = 0 by construction); the "
                             "value is a fit of the TWLC+G theory to torque data, so it is reported as a difference of "
                             "the force field, not gated",
}


def sourced_comparisons(lp_nm, c_nm, s_pN, g_pN_nm, G_nm, temperature, forces_pN=(0.3, 1.0, 3.0)):
    """The newly sourced values (:func:`dnarod.physics.experiments.sourced_mechanics`, the structural transitions,
    overstretching and the persistence length's salt series) placed against the model: each entry names the
    measured value, where it was read, the model's value where it has one, and whether it is reported or outside
    the model's reach (:data:`OUTSIDE_MODEL` says why). Nothing here gates: none of these states an uncertainty
    but G, which is a theory-dependent fit (the gated comparisons are the check's bending, C_eff and C ones).

    Returns
    -------
    dict
        ``reported`` and ``outside`` (lists of dicts), ``disagreements`` (lines for values the model misses by more
        than ``Z_TOL`` stated uncertainties).
    """
    from dnarod.core.units import PN, kT
    from dnarod.physics import experiments as ex
    from dnarod.physics.theory.torsion import moroz_nelson

    kt_pn = kT(temperature) / PN
    reported, outside, disagreements = [], [], []

    def entry(m, value_md_to_shown, unit, **kw):
        return dict(quantity=m.quantity, measured=m.value * value_md_to_shown,
                    uncertainty=None if m.uncertainty is None else m.uncertainty * value_md_to_shown, unit=unit,
                    conditions=m.conditions, source=ex.cite_short(m.source), where=m.verification, url=m.url, **kw)

    for m in ex.sourced_mechanics():
        q = m.quantity
        if q == "twist_bend_coupling_G":
            z = abs(G_nm - m.value) / m.uncertainty
            outside.append(entry(m, 1.0, "nm", model=G_nm, z=float(z), why=OUTSIDE_MODEL[q]))
            if z > Z_TOL:
                disagreements.append(f"twist-bend coupling G {G_nm:g} nm (dna-default has none) vs {m.value:g}+-"
                                     f"{m.uncertainty:g} nm fitted to torque data ({ex.cite_short(m.source)})")
        elif q == "twist_stretch_coupling_g":
            reported.append(entry(m, 1.0 / PN, "pN nm", model=float(g_pN_nm),
                                  kind="reported: secondary, no uncertainty stated"))
        elif q == "stretch_modulus_S":
            reported.append(entry(m, 1.0 / PN, "pN", model=float(s_pN),
                                  kind="reported: a weak secondary attribution, no uncertainty stated"))
        elif q == "effective_torsional_stiffness_salt_relative_change":
            ceff = [float(moroz_nelson(c_nm, lp_nm, f, kt_pn)) for f in forces_pN]
            outside.append(entry(m, 1.0, "relative", model=0.0, why=OUTSIDE_MODEL[q],
                                 model_C_eff_nm={f"{f:g} pN": c for f, c in zip(forces_pN, ceff)}))
        else:
            outside.append(entry(m, 1.0, "1", model=None, why=OUTSIDE_MODEL.get(q, "not represented by the model")))
    for m in ex.structural_transition_torques():
        outside.append(entry(m, 1.0 / PN, "pN nm", model=None, force_pN=m.force_pN, why=OUTSIDE_MODEL[m.quantity]))
    for r in ex.read_table("overstretching.csv"):
        outside.append(dict(quantity="overstretching", measured=float(r["force_pN"]), uncertainty=None, unit="pN",
                            salt_M=ex._f(r.get("salt_M")), source=ex.cite_short(r["source"]), where=r.get("where"),
                            url=r.get("url"), model=None, why=OUTSIDE_MODEL["overstretching"]))
    series = sorted(ex.persistence_lengths(), key=lambda m: m.salt_M)
    outside.append(dict(quantity="persistence_length_vs_salt", unit="nm", model=float(lp_nm),
                        measured={f"{1000 * m.salt_M:g} mM": m.value for m in series},
                        source="; ".join(sorted({ex.cite_short(m.source) for m in series})),
                        why=OUTSIDE_MODEL["persistence_length_vs_salt"]))
    return dict(reported=reported, outside=outside, disagreements=disagreements)


def model_helix_constants(forcefield="dna-default"):
    """``(helical repeat bp per turn, twist-stretch coupling g pN nm, rise ds nm)`` of a uniform chain of
    ``forcefield``: the
    repeat from the intrinsic twist rate, ``2 pi / theta0`` with ``theta0 = 2 atan(ds Omega0_3 / 2)`` (the Cayley
    chart), and ``g = B33 / cos^2(theta0/2)`` (the inverse of the derivation in :mod:`dnarod.physics.dna_default`)."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.core.units import PN

    model = load_forcefield(forcefield).model_from_sequence(n_nodes=20)
    th0 = 2.0 * np.arctan(0.5 * model.ds * model.params.intrinsic[0, 2])
    g = model.params.stiffness[0][2, 5] / np.cos(0.5 * th0) ** 2 / PN
    return float(2.0 * np.pi / th0), float(g), float(model.ds)


def model_elastic_constants(temperature, forcefield="dna-default"):
    """``(lp nm, C nm, S pN)`` of a uniform chain of ``forcefield`` at ``temperature`` K (exact values)."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.physics.thermal import persistence_length
    from dnarod.core.units import kT
    from dnarod.core.units import PN
    from dnarod.physics.theory.torsion import bare_twist_persistence

    model = load_forcefield(forcefield).model_from_sequence(n_nodes=20)
    lp = persistence_length(model.params, model.ds, kT(temperature))
    C = bare_twist_persistence(model, temperature)
    S = 1.0 / np.linalg.inv(model.params.stiffness[0])[5, 5] / PN
    return float(lp), float(C), float(S)


def check_experiment(out_dir, quick=False, temperature=300.0, salt_M=0.15, forces_pN=DEFAULT_FORCES_PN,
                     forcefield="dna-default", lp_override=None, c_override=None, d_override=None,
                     writhe_fraction_model=None, gate_effective_diameter=True, plots=True, nonbonded=None):
    """Run the check (see the module docstring). ``quick`` changes nothing: the check is exact (no sampling).

    ``writhe_fraction_model``: ``(Wr/ΔLk, standard error, description)`` of a model ring (from check
    ``plectonemes``); without it the writhe fraction is listed as not compared. ``d_override`` (nm) replaces
    the model's effective diameter (computing it takes tens of CPU seconds the first time per process);
    ``nonbonded`` (NonbondedSettings, its salt replaced by ``salt_M``) replaces the default non-bonded terms
    (e.g. ``charge="manning"``).
    """
    from dnarod.physics import experiments as ex
    from dnarod.core.units import kT
    from dnarod.core.units import PN
    from dnarod.physics.theory.wlc import extensible_wlc_extension
    from dnarod.physics.theory.torsion import moroz_nelson

    t0 = time.perf_counter()
    lp0, C0, S = model_elastic_constants(temperature, forcefield)
    lp = lp0 if lp_override is None else float(lp_override)
    C = C0 if c_override is None else float(c_override)
    kt_pn = kT(temperature) / PN

    lo, hi, used = ex.persistence_length_band(salt_M)
    lp_ok = bool(lo <= lp <= hi)
    F = np.asarray(forces_pN, float)
    x_lo, x_hi = ex.wlc_extension_band(F, salt_M, S, temperature)
    x_model = np.asarray(extensible_wlc_extension(F, lp, S, kt_pn))
    bending = dict(model_nm=lp, measured_low_nm=lo, measured_high_nm=hi, salt_M=salt_M,
                   measurements=[dict(value_nm=m.value, salt_M=m.salt_M, source=m.source, url=m.url) for m in used],
                   relative_extension=[dict(force_pN=float(f), model=float(a), measured_low=float(b),
                                            measured_high=float(c)) for f, a, b, c in zip(F, x_model, x_lo, x_hi)],
                   passed=lp_ok)

    torsion_rows = []
    for m in ex.effective_torsional_persistence(temperature=temperature):
        model_c = float(moroz_nelson(C, lp, m.force_pN, kt_pn))
        sigma = m.uncertainty or 0.0
        tol = Z_TOL * sigma + THEORY_ALLOWANCE * model_c
        torsion_rows.append(dict(force_pN=m.force_pN, measured_nm=m.value, measured_sigma_nm=sigma,
                                 model_nm=model_c, difference_nm=model_c - m.value, tolerance_nm=tol,
                                 source=ex.cite_short(m.source), conditions=m.conditions, url=m.url,
                                 passed=bool(abs(model_c - m.value) <= tol)))
    torsion_ok = bool(torsion_rows) and all(r["passed"] for r in torsion_rows)

    bare = []
    for m in ex.torsional_rigidities():
        s = m.uncertainty or 0.0
        bare.append((m.value / kT(temperature), s / kT(temperature), ex.cite_short(m.source)))
    for r in ex.read_table("twist_stiffness_fits.csv"):
        bare.append((float(r["C_nm"]), 0.0, ex.cite_short(r["source"])))
    c_lo = min(v - s for v, s, _ in bare)
    c_hi = max(v + s for v, s, _ in bare)
    bare_ok = bool(c_lo <= C <= c_hi)
    bare_res = dict(model_nm=C, measured_low_nm=c_lo, measured_high_nm=c_hi, conversion_temperature_K=temperature,
                    measurements=[dict(value_nm=v, sigma_nm=s, source=src) for v, s, src in bare], passed=bare_ok)

    from dnarod.core.forcefield import load_forcefield
    from dnarod.physics.nonbonded import NonbondedSettings
    from dnarod.physics.theory.supercoil import effective_diameter

    if d_override is None:
        ds = load_forcefield(forcefield).model_from_sequence(n_nodes=20).ds
        import dataclasses

        nb = NonbondedSettings() if nonbonded is None else nonbonded
        d_model = float(effective_diameter(dataclasses.replace(nb, salt=salt_M), ds, temperature))
    else:
        d_model = float(d_override)
    diameter = compare_effective_diameter(d_model, salt_M)
    writhe = None if writhe_fraction_model is None else compare_writhe_fraction(*writhe_fraction_model)
    fe_curve = compare_force_extension_curve(lp, S, F, temperature)
    topo = compare_topoisomer_fit(C, temperature)
    repeat, g_model, ds_model = model_helix_constants(forcefield)
    cyclization = compare_cyclization_fit(lp, C, repeat, temperature)
    ranges = compare_elastic_ranges(S, C, g_model, temperature)
    hw = compare_horowitz_wang(C, ds_model, repeat, temperature)

    G_model = model_twist_bend_coupling(temperature, forcefield)
    sourced = sourced_comparisons(lp, C, S, g_model, G_model, temperature)

    not_compared = {k: f"no value could be read: {v}" for k, v in ex.MISSING.items()}
    if writhe is None:
        not_compared["writhe_fraction_model"] = ("no model writhe fraction in this run (check plectonemes gives it "
                                                 "when run together with this check)")
    if diameter is None:
        not_compared["effective_diameter_reference"] = f"no effective diameter read for {salt_M} M"
    disagreements = list(sourced["disagreements"])
    if diameter is not None and not diameter["agrees"]:
        disagreements.append(f"effective diameter {d_model:.2f} nm vs {diameter['reference_nm']:g} nm "
                             f"({diameter['kind']}, {1000 * salt_M:g} mM): ratio {diameter['ratio']:.2f}")
    passed = bool(lp_ok and torsion_ok and bare_ok and (writhe is None or writhe["passed"])
                  and (diameter is None or not gate_effective_diameter or diameter["agrees"]))
    # the magnetic-torque-tweezers value (6.5 pN) leads the headline
    mtt = next((r for r in torsion_rows if abs(r["force_pN"] - 6.5) < 1e-9), torsion_rows[0] if torsion_rows else None)
    res = dict(model=f"{forcefield} uniform chain at {temperature} K: lp {lp:.2f} nm, C {C:.2f} nm, S {S:.0f} pN",
               temperature_K=temperature, model_persistence_length_nm=lp0, model_twist_persistence_nm=C0,
               persistence_length_used_nm=lp, twist_persistence_used_nm=C, stretch_modulus_pN=S,
               bending=bending, effective_torsional_stiffness=torsion_rows, bare_torsional_stiffness=bare_res,
               writhe_fraction=writhe, effective_diameter=diameter, force_extension_curve=fe_curve,
               topoisomer_fit=topo, cyclization_fit=cyclization, elastic_constant_ranges=ranges, horowitz_wang=hw,
               model_helical_repeat_bp=repeat, model_twist_stretch_pN_nm=g_model, model_effective_diameter_nm=d_model,
               effective_diameter_gating=bool(gate_effective_diameter), disagreements=disagreements,
               sourced_reported=sourced["reported"], outside_model=sourced["outside"],
               model_twist_bend_coupling_nm=G_model,
               z_tolerance=Z_TOL, theory_allowance_relative=THEORY_ALLOWANCE, writhe_rounding=WRITHE_ROUNDING,
               diameter_tolerance_nm=DIAMETER_PRECISION_NM + DIAMETER_QUADRATURE_NM, not_compared=not_compared,
               notes=["Measured values and where they were read: data/README.md (data/experimental/).",
                      "Not compared (no value could be read): " + "; ".join(ex.MISSING.values()) + ".",
                      "Reported, not gating (no uncertainty stated): "
                      + (f"S {S:.0f} pN vs {fe_curve['curve_stretch_modulus_pN']:g} pN of the eWLC curve drawn over "
                         f"lambda-DNA data at {1000 * fe_curve['salt_M']:g} mM (max |dx/L| "
                         f"{fe_curve['max_abs_difference']:.3f}); " if fe_curve else "")
                      + (f"C {C:.1f} nm vs {topo['reference_nm']:.1f} nm fitted to Horowitz-Wang topoisomer "
                         f"variances (Frank-Kamenetskii et al. 1985, at {temperature:g} K); " if topo else "")
                      + (f"lp {lp:.1f} nm, C {C:.1f} nm, repeat {repeat:.2f} bp vs "
                         f"{cyclization['reference_persistence_length_nm']:g} nm, "
                         f"{cyclization['reference_twist_persistence_nm']:.1f} nm, "
                         f"{cyclization['reference_helical_repeat_bp']:g} bp fitted to cyclization j-factors "
                         f"(PMID 15778443); " if cyclization else "")
                      + (f"C {C:.1f} nm vs {hw['reference_twist_persistence_nm']:.1f} nm, twist-only N K "
                         f"{hw['model_NK_twist_only_bp']:.0f} vs {hw['reference_NK_200bp']:g} RT bp (200-bp rings), "
                         f"repeat {repeat:.2f} vs {hw['reference_helical_repeat_bp']:g} bp (210-bp rings) "
                         f"(Horowitz & Wang 1984; their N K ~ {hw['reference_NK_long_rings']:g} RT bp above 2000 bp is "
                         f"compared by check nicked_ring); " if hw else "")
                      + ("; ".join(f"{q['quantity'].replace('_range', '')} {q['model']:.4g} {q['unit']} "
                                   f"{'inside' if q['inside'] else 'OUTSIDE'} the measured range "
                                   f"{q['low']:.4g} to {q['high']:.4g} (secondary, {q['source']})"
                                   for q in ranges) + "." if ranges else ""),
                      "Outside the model's reach (listed, not compared): "
                      + "; ".join(f"{o['quantity']} ({o['source']}): {o['why']}" for o in sourced["outside"]) + ".",
                      "Effective diameter: the reference is computed (Poisson-Boltzmann), not measured; the model's "
                      "Debye-Hueckel line charge is calibrated to it at 0.15 M (dnarod.engines.openmm.nonbonded), so "
                      "at 0.15 M this checks the calibration ("
                      + ("gating" if gate_effective_diameter else "not gating") + ")."],
               passed=passed)
    res["headline"] = (f"lp {lp:.1f} nm vs measured {lo:g}-{hi:g} nm at {1000 * salt_M:g} mM; "
                       + (f"C_eff({mtt['force_pN']:g} pN) {mtt['model_nm']:.1f} vs {mtt['measured_nm']:g}"
                          f"+-{mtt['measured_sigma_nm']:g} nm; " if mtt else "")
                       + "; ".join(f"C_eff({r['force_pN']:g} pN) {r['model_nm']:.1f} vs {r['measured_nm']:.1f}"
                                   + (f"+-{r['measured_sigma_nm']:.1f} nm" if (r['measured_sigma_nm'] or 0) > 0 else
                                      " nm (fit, no error given)")
                                   for r in torsion_rows if r is not mtt)
                       + f"; C {C:.1f} vs measured {c_lo:.1f}-{c_hi:.1f} nm"
                       + (f"; Wr/dLk {writhe['model']:.3f}+-{writhe['model_se']:.3f} vs ~{writhe['measured']:g}"
                          if writhe else "")
                       + (f"; d_eff {d_model:.2f} vs {diameter['reference_nm']:g} nm (PB, computed): "
                          + ("agrees" if diameter["agrees"] else "DISAGREES") if diameter else ""))
    res["headline_tolerance"] = (f"lp inside the measured interval; |dC_eff| <= {Z_TOL:g} sigma + "
                                 f"{100 * THEORY_ALLOWANCE:.0f}%; C inside measured values +- sigma"
                                 + (f"; |dWr/dLk| <= {Z_TOL:g} SE + {WRITHE_ROUNDING:g}" if writhe else "")
                                 + f"; |d_eff - ref| <= {DIAMETER_PRECISION_NM + DIAMETER_QUADRATURE_NM:g} nm "
                                 + ("(gating)" if gate_effective_diameter else "(reported, not gating)"))
    if plots:
        res["plots"] = [_plot(out_dir, res, F, x_model, x_lo, x_hi, C, lp, kt_pn)]
    res["runtime_s"] = time.perf_counter() - t0
    return res


def _plot(out_dir, res, F, x_model, x_lo, x_hi, C, lp, kt_pn):
    from dnarod.physics.theory.torsion import moroz_nelson
    from dnarod.analysis.plots import new_figure, save_figure

    fig, ax = new_figure(3, 1, width=4.6, height=4.0)
    a = ax[0, 0]
    a.fill_between(F, x_lo, x_hi, color="0.85", label="WLC with the measured lp interval")
    a.semilogx(F, x_model, "ko-", label=f"model (lp {lp:.1f} nm)")
    fe = res.get("force_extension_curve")
    if fe:
        a.semilogx(F, [r["curve"] for r in fe["relative_extension"]], "-.", color="0.4",
                   label=f"eWLC lp {fe['curve_persistence_length_nm']:g} nm, S {fe['curve_stretch_modulus_pN']:g} pN "
                         f"over lambda-DNA data, {1000 * fe['salt_M']:g} mM (reported)")
    a.set_xlabel("force (pN)")
    a.set_ylabel("extension / contour length")
    a.legend(fontsize=7)
    b = ax[0, 1]
    FF = np.linspace(0.5, 20, 80)
    b.plot(FF, moroz_nelson(C, lp, FF, kt_pn), "k-", label=f"model, Moroz-Nelson (C {C:.1f} nm)")
    for r in res["effective_torsional_stiffness"]:
        b.errorbar([r["force_pN"]], [r["measured_nm"]], yerr=[r["measured_sigma_nm"]], fmt="s", capsize=3,
                   label=f"measured ({r['source']})")
    b.set_xlabel("force (pN)")
    b.set_ylabel("C_eff (nm)")
    b.legend(fontsize=7)
    c = ax[0, 2]
    d = res["effective_diameter"]
    salt = res["bending"]["salt_M"]
    c.plot([1000 * salt], [res["model_effective_diameter_nm"]], "ko", ms=4, zorder=3,
           label=f"model {res['model_effective_diameter_nm']:.2f} nm (WCA + DH, second virial; calibrated at 150 mM)")
    if d:
        c.errorbar([1000 * d["salt_M"]], [d["reference_nm"]], yerr=[d["tolerance_nm"]], fmt="s", capsize=3,
                   label=f"PB second virial {d['reference_nm']:g} nm, computed ({d['source']})")
    from dnarod.physics import experiments as ex

    for m in ex.plectoneme_geometry_reference("superhelix_diameter"):
        c.errorbar([1000 * m.salt_M], [m.value], yerr=[m.uncertainty or 0.0], fmt="^", capsize=3, color="0.5",
                   label=f"superhelix diameter {m.value:g} nm, {1000 * m.salt_M:g} mM Na+ ({ex.cite_short(m.source)})")
    w = res.get("writhe_fraction")
    c.set_xscale("log")
    c.set_xlabel("monovalent salt (mM)")
    c.set_ylabel("diameter (nm)")
    c.set_title("effective and superhelix diameters"
                + (f"; Wr/dLk {w['model']:.2f} vs ~{w['measured']:g}" if w else ""), fontsize=9)
    c.legend(fontsize=6)
    return save_figure(fig, out_dir, "experiment.png")
