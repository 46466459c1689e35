"""Values read in round 6 (data/experimental/): the worm-like-chain fit to cyclization j-factors (figure caption on
the PubMed page of PMID 15778443) and the secondary ranges of measured elastic constants in PNAS 114:7049 (2017)
Table 1. The loader returns exactly the numbers read (in MD units), and check ``experiment`` reports the model beside
them (no gating: the sources state no uncertainty)."""
import pytest

from dnarod.protocols import experiments as ex
from dnarod.units import AVOGADRO, PN


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
    from dnarod.dna_default import TARGETS
    from dnarod.validate.experiment import model_helix_constants

    repeat, g = model_helix_constants()
    assert repeat == pytest.approx(TARGETS["bp_per_turn"], rel=1e-9)
    assert g == pytest.approx(TARGETS["twist_stretch_pN_nm"], rel=1e-9)


def test_reported_comparisons_use_the_numbers_read_and_follow_the_model():
    from dnarod.thermal import kT
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


def test_experiment_check_reports_the_round6_values(tmp_path):
    from dnarod.validate.experiment import check_experiment

    r = check_experiment(tmp_path, plots=False, d_override=5.0)  # the calibrated diameter (computing it is slow)
    assert r["passed"]  # reported values do not gate
    cyc = r["cyclization_fit"]
    assert cyc["model_helical_repeat_bp"] == pytest.approx(10.5) and cyc["reference_persistence_length_nm"] == 48.5
    assert cyc["twist_persistence_ratio"] == pytest.approx(1.70, abs=0.01)  # model C 98.3 nm vs 57.9 nm
    assert [q["inside"] for q in r["elastic_constant_ranges"]] == [False, True, True, True]
    notes = " ".join(r["notes"])
    assert "fitted to cyclization j-factors (PMID 15778443)" in notes
    assert "stretch_modulus 1100 pN OUTSIDE the measured range 1450 to 1750" in notes
    # a wrong C moves only the reported numbers, not the verdict of the reported comparisons' rows
    r2 = check_experiment(tmp_path, plots=False, d_override=5.0, c_override=150.0)
    assert not r2["passed"]  # gated elsewhere (bare C outside the measured values)
    assert r2["cyclization_fit"]["twist_persistence_ratio"] == pytest.approx(150.0 / 57.94, rel=1e-3)
    assert not r2["elastic_constant_ranges"][2]["inside"]
