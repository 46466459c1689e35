"""Values read from secondary sources (data/experimental/): the worm-like-chain fit to cyclization j-factors
(figure caption on the PubMed page of PMID 15778443) and the secondary ranges of measured elastic constants in PNAS
114:7049 (2017) Table 1. The loader returns exactly the numbers read (in MD units), and check ``experiment`` reports the
model beside them (no gating: the sources state no uncertainty)."""
import pytest

from dnarod.physics import experiments as ex
from dnarod.core.units import AVOGADRO, PN


def test_cyclization_fit_read_as_stated():
    r = ex.cyclization_fit_reference()
    # "The best fit (solid line) corresponds to a = 48.5 nm, gamma = 10.49 bp/(helix turn), and C = 2.4e-19 erg cm."
    a, h, c = r["persistence_length"], r["helical_repeat"], r["torsional_rigidity"]
    assert (a.value, a.unit, a.uncertainty, a.salt_M) == (48.5, "nm", None, None)
    assert (h.value, h.unit) == (10.49, "bp per turn")
    c_si = 2.4e-19 * 1e-7 * 1e-2  # erg cm -> J m
    assert c.value == pytest.approx(c_si * 1e9 * AVOGADRO / 1000.0, rel=1e-12)
    assert c.value == pytest.approx(240.0 * PN, rel=1e-12) and c.unit == "kJ/mol nm"  # 240 pN nm^2
    assert all("15778443" in m.url and "not shown" in m.source for m in r.values())


def test_secondary_elastic_ranges_read_as_stated():
    rows = ex.elastic_constant_ranges()
    got = [(m.quantity, m.value, m.value_max, m.unit) for m in rows]
    # PNAS 114:7049 Table 1, "dsDNA (exp. work)": '1,450 to 1,750 (32, 33)', '649 to 1,401 (5, 6, 42-44)' (both rows
    # labelled 'S, pN'), '386 to 448 (5, 45-47)' (C, pN nm^2), '-17 to -39 (2, 5, 32, 33, 41, 46)' (g/kBT)
    assert got == [("stretch_modulus_range", pytest.approx(1450 * PN), pytest.approx(1750 * PN), "kJ/mol/nm"),
                   ("stretch_modulus_range", pytest.approx(649 * PN), pytest.approx(1401 * PN), "kJ/mol/nm"),
                   ("torsional_rigidity_range", pytest.approx(386 * PN), pytest.approx(448 * PN), "kJ/mol nm"),
                   ("twist_stretch_coupling_range", -39.0, -17.0, "1")]
    assert all(m.uncertainty is None and "PMC5502642" in m.url and "secondary" in m.source for m in rows)
    assert "table refs 5, 6, 42-44" in rows[1].conditions
    assert [m.quantity for m in ex.elastic_constant_ranges("torsional_rigidity_range")] == ["torsional_rigidity_range"]


def test_model_helix_constants_are_the_dna_default_targets():
    from dnarod.physics.dna_default import TARGETS
    from dnarod.validate.experiment import model_helix_constants

    repeat, g, ds = model_helix_constants()
    assert repeat == pytest.approx(TARGETS["bp_per_turn"], rel=1e-9)
    assert g == pytest.approx(TARGETS["twist_stretch_pN_nm"], rel=1e-9)
    assert ds == pytest.approx(TARGETS["rise"], rel=1e-12)


def test_reported_comparisons_use_the_numbers_read_and_follow_the_model():
    from dnarod.core.units import kT
    from dnarod.validate.experiment import compare_cyclization_fit, compare_elastic_ranges

    kt = kT(300.0)
    cyc = compare_cyclization_fit(50.0, 98.25, 10.5, 300.0)
    assert cyc["reference_persistence_length_nm"] == 48.5 and cyc["reference_helical_repeat_bp"] == 10.49
    assert cyc["reference_twist_persistence_nm"] == pytest.approx(240.0 * PN / kt, rel=1e-12)  # 57.9 nm at 300 K
    assert cyc["twist_persistence_ratio"] == pytest.approx(98.25 / (240.0 * PN / kt), rel=1e-12)
    assert "reported" in cyc["kind"]
    rows = compare_elastic_ranges(1100.0, 98.25, -90.0, 300.0)
    by = [(r["quantity"], r["low"], r["high"], r["inside"]) for r in rows]
    assert by[0] == ("stretch_modulus_range", pytest.approx(1450.0), pytest.approx(1750.0), False)
    assert by[1] == ("stretch_modulus_range", pytest.approx(649.0), pytest.approx(1401.0), True)
    assert by[2][:3] == ("torsional_rigidity_range", pytest.approx(386.0), pytest.approx(448.0)) and by[2][3]
    assert by[3] == ("twist_stretch_coupling_range", -39.0, -17.0, True)
    assert rows[2]["model"] == pytest.approx(98.25 * kt / PN, rel=1e-12)  # kT C in pN nm^2
    # the reported placement follows the model's values
    wrong = compare_elastic_ranges(500.0, 60.0, -300.0, 300.0)
    assert [r["inside"] for r in wrong] == [False, False, False, False]
    assert [r["inside"] for r in compare_elastic_ranges(1500.0, 98.25, -90.0, 300.0)][:2] == [True, False]


def test_experiment_check_reports_the_secondary_values(tmp_path):
    from dnarod.validate.experiment import check_experiment

    r = check_experiment(tmp_path, plots=False, d_override=5.0)  # the calibrated diameter (computing it is slow)
    assert r["passed"]  # reported values do not gate
    cyc = r["cyclization_fit"]
    assert cyc["model_helical_repeat_bp"] == pytest.approx(10.5) and cyc["reference_persistence_length_nm"] == 48.5
    assert cyc["twist_persistence_ratio"] == pytest.approx(1.70, abs=0.01)  # model C 98.3 nm vs 57.9 nm
    assert [q["inside"] for q in r["elastic_constant_ranges"]] == [False, True, True, True]
    notes = " ".join(r["notes"])
    assert r["horowitz_wang"]["NK_200bp_ratio"] == pytest.approx(1.46, abs=0.01)
    assert "twist-only N K 5704 vs 3900 RT bp (200-bp rings)" in notes
    assert "fitted to cyclization j-factors (PMID 15778443)" in notes
    assert "stretch_modulus 1100 pN OUTSIDE the measured range 1450 to 1750" in notes
    # a wrong C moves only the reported numbers, not the verdict of the reported comparisons' rows
    r2 = check_experiment(tmp_path, plots=False, d_override=5.0, c_override=150.0)
    assert not r2["passed"]  # gated elsewhere (bare C outside the measured values)
    assert r2["cyclization_fit"]["twist_persistence_ratio"] == pytest.approx(150.0 / 57.94, rel=1e-3)
    assert not r2["elastic_constant_ranges"][2]["inside"]


def test_horowitz_wang_abstract_read_as_stated():
    # "For DNA rings with length N larger than 2000 bp, K is inversely proportional to N and the product NK is nearly a
    # constant around 1150 RT X bp. ... for a 200 bp ring NK is 3900 RT X bp. ... the torsional rigidity of the DNA
    # double helix is calculated to be 2.9 X 10(-19) erg cm. ... For the 210 bp rings, the repeat is measured to be
    # 10.54 bp."
    (k,) = ex.supercoiling_free_energy_reference()
    assert (k.value, k.unit, k.uncertainty, k.approximate) == (1150.0, "1", None, True)
    assert ex.cite_short(k.source) == "Horowitz & Wang 1984" and "6321743" in k.url
    hw = ex.horowitz_wang_reference()
    assert hw["NK_200bp"].value == 3900.0 and hw["helical_repeat_210bp"].value == 10.54
    assert hw["torsional_rigidity"].value == pytest.approx(2.9e-19 * 1e-7 * 1e-2 * 1e9 * AVOGADRO / 1000.0, rel=1e-12)
    assert hw["torsional_rigidity"].value == pytest.approx(290.0 * PN, rel=1e-12)
    # Shurdov & Gruzdev 1989: K "more than doubled" from 0.3 M to 0.01 M NaCl (a lower bound), beside Rybenkov 1997
    assert [m.value for m in ex.supercoiling_free_energy_ionic_variation()] == [1.5, 2.0]


def test_horowitz_wang_comparison_reports_the_model_beside_the_abstract():
    from dnarod.core.units import kT
    from dnarod.validate.experiment import compare_horowitz_wang

    r = compare_horowitz_wang(98.25, 0.34, 10.5, 300.0)
    assert r["reference_twist_persistence_nm"] == pytest.approx(290.0 * PN / kT(300.0), rel=1e-12)  # 70.0 nm
    # twist-only N K = N / (2 <dTw^2>) with <dTw^2> = L / (4 pi^2 C): 2 pi^2 C / ds
    assert r["model_NK_twist_only_bp"] == pytest.approx(2 * 3.141592653589793 ** 2 * 98.25 / 0.34, rel=1e-12)
    assert r["reference_NK_200bp"] == 3900.0 and r["reference_NK_long_rings"] == 1150.0
    assert r["NK_200bp_ratio"] == pytest.approx(5704.2 / 3900.0, rel=1e-4)
    assert (r["model_helical_repeat_bp"], r["reference_helical_repeat_bp"]) == (10.5, 10.54)
    # follows the model: the C that would give 3900 RT bp twist-only
    c_match = 3900.0 * 0.34 / (2 * 3.141592653589793 ** 2)
    assert compare_horowitz_wang(c_match, 0.34, 10.5, 300.0)["NK_200bp_ratio"] == pytest.approx(1.0, rel=1e-12)
