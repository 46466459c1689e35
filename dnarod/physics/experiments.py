"""Measured DNA values bundled in ``data/experimental/`` (the one home of the experimental tables), in MD units.

The tables are in the experimentalist's units (pN, nm, Angstrom, pN nm, pN nm^2, deg, mol/L) with their sources;
this module reads them and converts at this edge with :mod:`dnarod.core.units` (forces in kJ/mol/nm, torques and
energies in kJ/mol, torsional rigidities in kJ/mol nm, lengths in nm, angles in rad). Every value was read in a
stored copy of its source (``data/README.md`` says where); quantities that could not be read are listed in
:data:`MISSING` and the functions for them return an empty list rather than a remembered number.

Used by the protocol plots (:mod:`dnarod.workflows.protocols.curves`) and by the "vs experiment" validation
(:mod:`dnarod.validate.experiment`); other checks can call the ``*_reference`` functions.
"""
from __future__ import annotations

import csv
import dataclasses
from dataclasses import dataclass
from pathlib import Path
import re

import numpy as np

from dnarod.core.units import NM_PER_ANGSTROM, PN, kT, AVOGADRO
from dnarod.core.forcefield import data_dir

#: Quantities the issue asks for that could not be read in any stored source (so nothing is bundled for them),
#: or of which only a weaker form could be read (the entry says what is still missing).
MISSING = {
    "force_extension_points": "the individual force-extension points of Wang et al. (1997) and Bouchiat et al. "
                              "(1999), Wang's fitted stretch modulus (the stored abstract breaks off at 'approximately "
                              "110...') and Bouchiat's fitted persistence length (only an extensible-WLC curve drawn "
                              "over lambda-DNA data at 100 mM Na+ could be read, force_extension_curves.csv, and, "
                              "secondary, the ranges of measured stretch moduli an MD study tabulates, "
                              "elastic_constant_ranges.csv)",
    "buckling_torque": "buckling torques, post-buckling torque plateaus, buckling turns and extension-vs-turns slopes "
                       "past buckling of Mosconi et al. (2009), Forth et al. (2008), Lipfert et al. (2010/2011/2014), "
                       "Brutzer et al. (2010) and the magnetic-torque-tweezers data set of Data in Brief "
                       "(PMC7154992): the stored copies show abstracts and figure captions without numbers (only "
                       "the B->P structural-transition torque at 45 pN could be read, structural_transitions.csv)",
    "writhe_fraction": "the measured writhe fraction of Boles, White & Cozzarelli (1990) and Vologodskii et al. with "
                       "its superhelical density and uncertainty (only a review's 'usually ~70%' could be read, "
                       "ring_writhe_fraction.csv)",
    "supercoiling_free_energy": "Depew & Wang's (1975) own value of the coefficient K of dG = (K R T / N) dLk^2 and "
                                "an uncertainty and ionic conditions for K (Horowitz & Wang 1984's abstract gives "
                                "N K 'nearly a constant', about 1150 RT x bp, above 2000 bp without them, "
                                "supercoiling.csv; Rybenkov et al. 1997 and Shurdov & Gruzdev 1989 give only lower "
                                "bounds on its change with salt)",
    "effective_diameter": "the measured (knotting) effective diameters of Rybenkov, Cozzarelli & Vologodskii (1993) "
                          "and Shaw & Wang (1993) and Stigter's (1977) values vs salt (searched again; "
                          "only the computed Poisson-Boltzmann second-virial diameter of Gebe et al. 1995, 5 nm at "
                          "150 mM, could be read: the model's charge is calibrated to it, so no salt dependence "
                          "is checked)",
}


@dataclass(frozen=True)
class Measurement:
    """One measured value in MD units.

    Attributes
    ----------
    quantity : str
        What was measured (e.g. ``"persistence_length"``, ``"effective_torsional_persistence"``).
    value : float
        The value in ``unit``.
    uncertainty : float or None
        Stated uncertainty (same unit), None if the source states none.
    unit : str
        MD unit of ``value`` (``"nm"``, ``"kJ/mol nm"``, ``"1"`` for ratios).
    force : float or None
        Stretching force of the measurement, kJ/mol/nm (None if not applicable or not stated).
    salt_M : float or None
        Monovalent salt concentration, mol/L (None if not monovalent or not stated).
    approximate : bool
        The source states the value as approximate ("about", "approximately").
    source, conditions, url, verification : str
        Citation, conditions as stated, the page read, and how it was read.
    value_max : float or None
        Upper end when the source states a range (``value`` is then the lower end).
    """

    quantity: str
    value: float
    uncertainty: float | None
    unit: str
    force: float | None
    salt_M: float | None
    approximate: bool
    source: str
    conditions: str
    url: str
    verification: str
    value_max: float | None = None

    @property
    def force_pN(self):
        """The force in pN (None if not stated)."""
        return None if self.force is None else self.force / PN


def experimental_dir():
    """``data/experimental`` of the bundled data directory."""
    return Path(data_dir()) / "experimental"


def read_table(name):
    """Rows (dicts of strings) of ``data/experimental/NAME``; ``#`` comment lines skipped; [] if absent."""
    p = experimental_dir() / name
    if not p.exists():
        return []
    lines = [ln for ln in p.read_text().splitlines() if ln.strip() and not ln.lstrip().startswith("#")]
    return list(csv.DictReader(lines))


def _f(s):
    s = (s or "").strip()
    return float(s) if s else None


def _m(row, quantity, value, unit, uncertainty=None, force_pN=None, salt_M=None, approximate=False, value_max=None):
    return Measurement(quantity=quantity, value=float(value), uncertainty=uncertainty, unit=unit,
                       force=None if force_pN is None else float(force_pN) * PN, salt_M=salt_M,
                       approximate=bool(approximate), source=row.get("source", ""),
                       conditions=row.get("conditions", row.get("salt", "")), url=row.get("url", ""),
                       verification=row.get("verification", ""), value_max=value_max)


def cite_short(source):
    """Short label of a ``source`` string: ``"Wang et al. 1997"``, or the journal reference when no year/author."""
    year = re.search(r"\b(?:19|20)\d\d\b", source)
    name = re.match(r"([A-Z][\w'-]+)(?: & ([A-Z][\w'-]+))?(,| et al)?", source)
    if year and name:
        who = f"{name.group(1)} & {name.group(2)}" if name.group(2) else name.group(1)
        return f"{who}{' et al.' if name.group(3) else ''} {year.group(0)}"
    doi = re.search(r", ([^,]+?)(?: \(doi|$)", source)
    return doi.group(1) if doi else source[:40]


def persistence_lengths(monovalent_only=True):
    """Bending persistence lengths (nm) fitted to measured force-extension curves, with their salt.

    ``monovalent_only`` drops the multivalent-cation value of Wang et al. (1997).
    """
    out = []
    for r in read_table("force_extension_parameters.csv"):
        salt = _f(r.get("salt_M"))
        if monovalent_only and salt is None:
            continue
        out.append(_m(r, "persistence_length", r["persistence_length_nm"], "nm", _f(r.get("uncertainty_nm")),
                      salt_M=salt, approximate="approximate" in r.get("conditions", "")))
    return out


def persistence_length_band(salt_M):
    """Measured bending persistence-length interval (nm) at monovalent salt ``salt_M`` (mol/L).

    The persistence length falls with salt (Wenner et al. 2002), so at ``salt_M`` it lies between the smallest
    value measured at a salt >= ``salt_M`` and the largest measured at a salt <= ``salt_M``: the spread of
    the measurements that bracket it. Returns ``(low, high, measurements used)``; raises ValueError if
    ``salt_M`` is outside the measured range.
    """
    ms = persistence_lengths()
    salts = [m.salt_M for m in ms]
    if not ms or not (min(salts) <= salt_M <= max(salts)):
        raise ValueError(f"salt {salt_M} M is outside the measured range "
                         f"{min(salts) if ms else '?'}-{max(salts) if ms else '?'} M")
    above = [m for m in ms if m.salt_M >= salt_M]
    below = [m for m in ms if m.salt_M <= salt_M]
    lo, hi = min(m.value for m in above), max(m.value for m in below)
    return float(min(lo, hi)), float(max(lo, hi)), sorted(set(above) | set(below), key=lambda m: m.salt_M)


def wlc_extension_band(forces_pN, salt_M, stretch_modulus_pN, temperature):
    """Relative extension x/L (extensible WLC, Bouchiat interpolation) implied by the measured persistence
    lengths at ``salt_M``: ``(low, high)`` arrays over ``forces_pN`` (pN) with the model's stretch modulus (pN)
    and kT at ``temperature`` (K). Not measured points: those could not be read (:data:`MISSING`)."""
    from dnarod.physics.theory.wlc import extensible_wlc_extension  # loads scipy.optimize

    lo, hi, _ = persistence_length_band(salt_M)
    F = np.atleast_1d(np.asarray(forces_pN, float))
    ktp = kT(temperature) / PN
    return (np.asarray(extensible_wlc_extension(F, lo, stretch_modulus_pN, ktp)),
            np.asarray(extensible_wlc_extension(F, hi, stretch_modulus_pN, ktp)))


def torsional_rigidities():
    """Measured torsional rigidities C (kJ/mol nm) with their force (Bryant et al. 2003); ``15-45`` pN -> None."""
    out = []
    for r in read_table("torsional_stiffness.csv"):
        try:
            f = float(r["force_pN"])
        except ValueError:
            f = None
        unc = _f(r.get("uncertainty_pN_nm2"))
        out.append(_m(r, "torsional_rigidity", float(r["C_pN_nm2"]) * PN, "kJ/mol nm",
                      None if unc is None else unc * PN, force_pN=f))
    return out


def effective_torsional_persistence(temperature=298.15):
    """Measured effective torsional persistence lengths C_eff (nm) at a force.

    Magnetic-torque-tweezers values are stated in nm; rotor-bead rigidities (pN nm^2) are divided by kT at
    ``temperature`` (K): the captions read do not state the experiments' temperature, so the conversion is
    the caller's choice and is written into ``conditions``.
    """
    out = []
    for r in read_table("effective_torsional_stiffness.csv"):
        salts = [float(s) for s in r.get("salt_M_values", "").split(";") if s.strip()]
        out.append(_m(r, "effective_torsional_persistence", r["C_eff_nm"], "nm", _f(r.get("uncertainty_nm")),
                      force_pN=r["force_pN"], salt_M=min(salts) if salts else None))
    kt = kT(temperature)
    for m in torsional_rigidities():
        if m.force is None:
            continue
        out.append(Measurement(quantity="effective_torsional_persistence", value=m.value / kt,
                               uncertainty=None if m.uncertainty is None else m.uncertainty / kt, unit="nm",
                               force=m.force, salt_M=None, approximate=False, source=m.source,
                               conditions=f"{m.conditions}; converted with kT at {temperature:g} K", url=m.url,
                               verification=m.verification))
    return out


def buckling_reference():
    """What was read about buckling (:data:`MISSING` lists the torques that could not be read)."""
    return [_m(r, r["quantity"], r["value"], "1" if r["unit"] == "ratio" else r["unit"],
               approximate=r.get("approximate") == "yes") for r in read_table("buckling.csv")]


def buckling_torque_reference(quantity="buckling_torque", force_pN=None, salt_M=None, force_tol_pN=0.05,
                              salt_tol_M=0.05):
    """Measured torques at buckling (``quantity="buckling_torque"``) or on the post-buckling plateau
    (``"postbuckling_torque_plateau"``), kJ/mol, from ``buckling.csv`` rows with ``torque_pN_nm`` (and
    ``uncertainty_pN_nm``, ``force_pN``, ``salt_M``), optionally only those within ``force_tol_pN`` of
    ``force_pN`` and ``salt_tol_M`` of ``salt_M``.

    Empty today: no such number could be read in any stored source (:data:`MISSING` ``"buckling_torque"``).
    A buckling check compares its measured torque ``tau`` (kJ/mol) with each row: ``|tau - m.value| <=
    3 sqrt(SE^2 + m.uncertainty^2)`` plus the two-phase theory's stated accuracy, and lists the quantity as not
    compared while this returns nothing.
    """
    out = []
    for r in read_table("buckling.csv"):
        if r.get("quantity") != quantity or not (r.get("torque_pN_nm") or "").strip():
            continue
        f, salt = _f(r.get("force_pN")), _f(r.get("salt_M"))
        if force_pN is not None and (f is None or abs(f - force_pN) > force_tol_pN):
            continue
        if salt_M is not None and (salt is None or abs(salt - salt_M) > salt_tol_M):
            continue
        unc = _f(r.get("uncertainty_pN_nm"))
        out.append(_m(r, quantity, float(r["torque_pN_nm"]) * PN, "kJ/mol", None if unc is None else unc * PN,
                      force_pN=f, salt_M=salt, approximate=r.get("approximate") == "yes"))
    return out


def structural_transition_torques():
    """Torques (kJ/mol) at which stretched, twisted B-DNA converts to another form (``structural_transitions.csv``):
    the B->P transition of overwound DNA, 34 +- 2 pN nm at 45 pN (Bryant et al. 2003), and the secondary "about
    -10 pN nm" for unwinding a random sequence under physiological conditions (Kwon et al. 2015, quoting its
    references; force not stated, ``approximate``). Beyond such torques an elastic B-DNA model does not represent
    DNA; the values are limits, not buckling torques."""
    out = []
    for r in read_table("structural_transitions.csv"):
        unc = _f(r.get("uncertainty_pN_nm"))
        out.append(_m(r, r["quantity"], float(r["torque_pN_nm"]) * PN, "kJ/mol", None if unc is None else unc * PN,
                      force_pN=_f(r.get("force_pN")), salt_M=_f(r.get("salt_M")),
                      approximate=r.get("approximate") == "yes"))
    return out


#: MD conversion of the units of ``sourced_mechanics.csv``: (factor, MD unit).
_SOURCED_UNITS = {"nm": (1.0, "nm"), "1": (1.0, "1"), "pN": (PN, "kJ/mol/nm"), "pN nm": (PN, "kJ/mol")}


def sourced_mechanics(quantity=None):
    """The values of ``sourced_mechanics.csv`` (compiled with the page and quote each was read in), in MD units:
    the low-force salt dependence of C_eff (Kriegel et al. 2017), the twist-bend coupling G fitted to torque data
    (Nomidis et al. 2017), Bryant et al.'s (2003) anharmonic twist fit b/a, the twist-stretch coupling below 30 pN
    attributed to Gross et al. (2011) (secondary) and the stretch modulus attributed to Wang et al. (1997) (weak).
    ``verification`` holds the label (P-abs, P-fig, S, T, weak), where it was read and the verbatim quote; a force or
    salt stated as a bound (``<3``) is kept in ``conditions`` only."""
    out = []
    for r in read_table("sourced_mechanics.csv"):
        if quantity is not None and r["quantity"] != quantity:
            continue
        f, unit = _SOURCED_UNITS[r["unit"]]
        unc = _f(r.get("uncertainty"))
        try:
            force = float(r["force_pN"])
        except (TypeError, ValueError):
            force = None
        row = dict(r, verification=f"item {r['item']} ({r['label']}); read in {r['where']}: \"{r['quote']}\" "
                                   f"({r['verification']})")
        out.append(_m(row, r["quantity"], float(r["value"]) * f, unit, None if unc is None else unc * f,
                      force_pN=force, salt_M=_f(r.get("salt_M")), approximate=r.get("approximate") == "yes"))
    return out


@dataclass(frozen=True)
class WLCCurve:
    """Extensible worm-like-chain curve a source draws with its measured force-extension data.

    Attributes
    ----------
    persistence_length : float
        nm.
    stretch_modulus : float
        kJ/mol/nm (a force); ``stretch_modulus_pN`` gives pN.
    rise : float
        Contour length per base pair, nm.
    salt_M : float or None
        Monovalent salt, mol/L.
    source, conditions, url, verification : str
    """

    persistence_length: float
    stretch_modulus: float
    rise: float
    salt_M: float | None
    source: str
    conditions: str
    url: str
    verification: str

    @property
    def stretch_modulus_pN(self):
        """The stretch modulus in pN."""
        return self.stretch_modulus / PN


def force_extension_curves():
    """Extensible-WLC curves drawn with measured force-extension data (``force_extension_curves.csv``): lp 50 nm,
    0.34 nm/bp, S 1000 pN over lambda-DNA at 100 mM Na+ (PMC33432, Fig. 2). Curve parameters, not stated as a fit
    and without uncertainty: for drawing and reporting, not for a pass/fail tolerance."""
    return [WLCCurve(persistence_length=float(r["persistence_length_nm"]),
                     stretch_modulus=float(r["stretch_modulus_pN"]) * PN,
                     rise=float(r["contour_length_per_bp_nm"]), salt_M=_f(r.get("salt_M")), source=r["source"],
                     conditions=r.get("conditions", ""), url=r.get("url", ""), verification=r.get("verification", ""))
            for r in read_table("force_extension_curves.csv")]


def writhe_fraction_reference():
    """Writhe fraction Wr/dLk of supercoiled closed circular DNA (``ring_writhe_fraction.csv``; ratio, unit ``"1"``).

    One secondary value could be read: "usually ~70%" (Witz & Stasiak 2010, a review quoting its own references;
    no superhelical density, salt or uncertainty stated, so ``uncertainty`` and ``salt_M`` are None and
    ``approximate`` is True). The primary measurements remain in :data:`MISSING`.
    """
    return [_m(r, "writhe_fraction", r["writhe_fraction"], "1", uncertainty=_f(r.get("uncertainty")),
               salt_M=_f(r.get("salt_M")), approximate=r.get("approximate") == "yes")
            for r in read_table("ring_writhe_fraction.csv")]


def writhe_variance_reference():
    """Ratio var(Wr) / var(Lk) of relaxed circular DNA (about 0.5; ``supercoiling.csv``)."""
    return [_m(r, r["quantity"], r["value"], "1", approximate=r.get("approximate") == "yes")
            for r in read_table("supercoiling.csv") if r["quantity"] == "writhe_variance_over_linking_variance"]


def supercoiling_free_energy_reference():
    """The coefficient K of ``dG = (K RT / N) dLk^2`` of long rings (``supercoiling.csv`` rows
    ``supercoiling_free_energy_K``; dimensionless, unit ``"1"``, i.e. ``N K`` of ``dG = K dLk^2`` in RT bp): Horowitz
    & Wang (1984, abstract): for rings longer than 2000 bp "the product NK is nearly a constant", about 1150 RT x bp
    (``approximate``; no uncertainty, ionic conditions or temperature stated). Depew & Wang's (1975) own value could
    not be read (:data:`MISSING`)."""
    out = []
    for r in read_table("supercoiling.csv"):
        if r["quantity"] == "supercoiling_free_energy_K":
            assert r["unit"] == "RT bp", r["unit"]
            out.append(_m(r, r["quantity"], r["value"], "1", approximate=r.get("approximate") == "yes"))
    return out


def horowitz_wang_reference():
    """The other numbers of the Horowitz & Wang (1984) abstract (``supercoiling.csv``): ``"NK_200bp"``, N K of a
    200-bp ring in RT bp (3900; unit ``"1"``), ``"torsional_rigidity"`` (kJ/mol nm; 2.9e-19 erg cm, computed by the
    authors assuming the writhe contribution vanishes at 200 bp) and ``"helical_repeat_210bp"`` (10.54 bp per turn,
    measured on 210-bp rings). Empty dict if absent. No uncertainty or ionic conditions stated."""
    out = {}
    for r in read_table("supercoiling.csv"):
        q = r["quantity"]
        if q == "supercoiling_free_energy_NK_200bp":
            assert r["unit"] == "RT bp", r["unit"]
            out["NK_200bp"] = _m(r, q, r["value"], "1")
        elif q == "torsional_rigidity_from_small_ring_topoisomers":
            assert r["unit"] == "erg cm", r["unit"]
            out["torsional_rigidity"] = _m(r, q, float(r["value"]) * _erg_cm_to_md(), "kJ/mol nm")
        elif q == "helical_repeat_210bp_rings":
            assert r["unit"] == "bp per turn", r["unit"]
            out["helical_repeat_210bp"] = _m(r, q, r["value"], "bp per turn")
    return out


def topoisomer_variance_fit_reference():
    """Torsional rigidity C (kJ/mol nm) and bending persistence length (nm) that Frank-Kamenetskii et al. (1985)
    fitted to the chain-length dependence of Horowitz & Wang's (1984) topoisomer variances <dLk^2> of small rings
    (``supercoiling.csv``; C = 3.0e-19 erg cm, a = 500 Angstrom; secondary to Horowitz & Wang, ionic conditions not
    stated). Returns ``{"torsional_rigidity": Measurement, "persistence_length": Measurement}`` (empty if absent).
    C / kT is the torsional persistence length at the caller's temperature."""
    erg_cm = _erg_cm_to_md()
    out = {}
    for r in read_table("supercoiling.csv"):
        if r["quantity"] == "torsional_rigidity_fit_to_topoisomer_variance":
            assert r["unit"] == "erg cm", r["unit"]
            out["torsional_rigidity"] = _m(r, r["quantity"], float(r["value"]) * erg_cm, "kJ/mol nm")
        elif r["quantity"] == "bending_persistence_fit_to_topoisomer_variance":
            assert r["unit"] == "Angstrom", r["unit"]
            out["persistence_length"] = _m(r, r["quantity"], float(r["value"]) * NM_PER_ANGSTROM, "nm")
    return out


def supercoiling_free_energy_ionic_variation():
    """Lower bound on how much the supercoiling free energy changes with NaCl/MgCl2 (Rybenkov et al. 1997:
    "changed >1.5-fold"; a ratio, ``value`` 1.5 is a lower bound). Not a value of K."""
    return [_m(r, r["quantity"], r["value"], "1", approximate=r.get("approximate") == "yes")
            for r in read_table("supercoiling.csv")
            if r["quantity"] == "supercoiling_free_energy_ionic_variation_min_ratio"]


def dna_diameter_reference():
    """Geometric diameter (nm) and the effective-thickness statement read (``dna_diameter.csv``)."""
    out = []
    for r in read_table("dna_diameter.csv"):
        out.append(_m(r, r["quantity"], r["value"], "1" if r["unit"] == "ratio" else r["unit"],
                      approximate=r.get("approximate") == "yes", value_max=_f(r.get("value_max"))))
    return out


def effective_diameter_reference():
    """Measured salt-dependent effective diameters (knotting: Rybenkov, Cozzarelli & Vologodskii 1993; Shaw & Wang
    1993): empty, none could be read (:data:`MISSING`; the computed value the model is calibrated to is
    :func:`effective_diameter_second_virial_reference`)."""
    return [m for m in dna_diameter_reference() if m.quantity == "effective_diameter"]


def effective_diameter_second_virial_reference():
    """Computed effective diameters (nm) with the model's definition -- hard rods with the same second virial
    coefficient as the electrostatic potential -- read in a stored source: 5.0 nm at 0.15 M from the
    Poisson-Boltzmann potential (Gebe et al. 1995, Biophys J abstract, ``dna_diameter.csv``), with its salt
    (mol/L). The model's Debye-Hückel line charge is calibrated to it (``dnarod.physics.nonbonded.CALIBRATION``)."""
    out = []
    for r in read_table("dna_diameter.csv"):
        if r["quantity"] != "effective_diameter_second_virial_pb":
            continue
        to_nm = NM_PER_ANGSTROM if r["unit"] == "Angstrom" else 1.0  # the abstract states 50 Angstrom
        out.append(_m(r, r["quantity"], float(r["value"]) * to_nm, "nm", salt_M=_f(r.get("salt_M")),
                      approximate=r.get("approximate") == "yes"))
    return out


def plectoneme_geometry_reference(quantity=None):
    """Measured geometry of plectonemic supercoiled DNA (``plectoneme_geometry.csv``): superhelix diameters (nm)
    at 10 and 100 mM Na+ (Hammermann et al. 2000, SANS) and the opening angle (tabulated in degrees, returned in
    rad; Zakharova et al. 2002). ``quantity`` selects one kind (``"superhelix_diameter"``, ``"opening_angle"``)."""
    out = []
    for r in read_table("plectoneme_geometry.csv"):
        if quantity not in (None, r["quantity"]):
            continue
        f, unit = (np.pi / 180.0, "rad") if r["unit"] == "deg" else (1.0, r["unit"])
        unc = _f(r.get("uncertainty"))
        out.append(_m(r, r["quantity"], float(r["value"]) * f, unit, None if unc is None else unc * f,
                      salt_M=_f(r.get("salt_M")), approximate=r.get("approximate") == "yes"))
    return out


def _erg_cm_to_md():
    """1 erg cm per molecule in kJ/mol nm (1e-9 J m = 1e-9 J * 1e9 nm, times Avogadro / 1000)."""
    return 1e-9 * 1e9 * AVOGADRO / 1000.0


def cyclization_fit_reference():
    """Worm-like-chain parameters fitted to measured cyclization j-factors of short DNA fragments
    (``cyclization_fit.csv``; a figure caption on the PubMed page of PMID 15778443, title and authors not shown on the
    page read): bending persistence length a = 48.5 nm, helical repeat 10.49 bp per turn and torsional rigidity
    C = 2.4e-19 erg cm. No uncertainty, buffer, salt or temperature stated.

    Returns ``{"persistence_length": Measurement (nm), "helical_repeat": Measurement (bp per turn),
    "torsional_rigidity": Measurement (kJ/mol nm)}`` (empty if the table is absent). C / kT is the torsional
    persistence length at the caller's temperature.
    """
    out = {}
    for r in read_table("cyclization_fit.csv"):
        q, v = r["quantity"], float(r["value"])
        if q == "bending_persistence_fit_to_cyclization":
            assert r["unit"] == "nm", r["unit"]
            out["persistence_length"] = _m(r, q, v, "nm")
        elif q == "helical_repeat_fit_to_cyclization":
            assert r["unit"] == "bp per turn", r["unit"]
            out["helical_repeat"] = _m(r, q, v, "bp per turn")
        elif q == "torsional_rigidity_fit_to_cyclization":
            assert r["unit"] == "erg cm", r["unit"]
            out["torsional_rigidity"] = _m(r, q, v * _erg_cm_to_md(), "kJ/mol nm")
    return out


def elastic_constant_ranges(quantity=None):
    """Ranges of measured DNA elastic constants tabulated by an MD study beside its own values (**secondary**:
    PNAS 114:7049 (2017) Table 1, column "dsDNA (exp. work)", ``elastic_constant_ranges.csv``; the table's numbered
    references were not resolved). Each Measurement has ``value`` (low end) and ``value_max`` (high end) in MD units:
    ``"stretch_modulus_range"`` in kJ/mol/nm (two rows, both labelled "S, pN" in the stored table; the symbol that
    distinguishes them is lost), ``"torsional_rigidity_range"`` in kJ/mol nm, ``"twist_stretch_coupling_range"`` as
    g/kBT (dimensionless, unit ``"1"``). ``conditions`` carries the table's reference numbers. No uncertainty: a
    range across experiments, for reporting, not for a pass/fail tolerance."""
    scale = {"pN": (PN, "kJ/mol/nm"), "pN nm^2": (PN, "kJ/mol nm"), "g/kBT": (1.0, "1")}
    out = []
    for r in read_table("elastic_constant_ranges.csv"):
        if quantity not in (None, r["quantity"]):
            continue
        f, unit = scale[r["unit"]]
        m = _m(r, r["quantity"], float(r["value"]) * f, unit, value_max=float(r["value_max"]) * f)
        out.append(dataclasses.replace(m, conditions=f"{m.conditions} (table refs {r['table_refs']})"))
    return out
