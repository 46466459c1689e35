"""More experimental values (data/experimental/): the B->P transition torque, the extensible-WLC curve drawn over
lambda-DNA data at 100 mM Na+, the fit to Horowitz-Wang topoisomer variances, and the buckling-torque reference
that stays empty until a source stating buckling torques is read. Loader units, plot overlays, the reported
comparisons of check ``experiment``."""
import pytest

from dnarod.physics import experiments as ex
from dnarod.core.units import AVOGADRO, PN


def test_structural_transition_torques_in_md_units():
    m, u = ex.structural_transition_torques()
    # Bryant et al. 2003 Fig. 3a inset: tau_crit,+ = 34 +- 2 pN nm at 45 pN (B->P transition)
    assert m.value == pytest.approx(34.0 * 0.602214076) and m.uncertainty == pytest.approx(2.0 * 0.602214076)
    assert (m.unit, m.force_pN, m.salt_M, m.approximate) == ("kJ/mol", 45.0, None, False)
    assert ex.cite_short(m.source) == "Bryant et al. 2003" and "nature01810_F3" in m.url
    # Kwon et al. 2015 (secondary): unwinding a random sequence at "~-10 pN nm" under physiological conditions
    assert u.value == pytest.approx(-10.0 * 0.602214076) and u.uncertainty is None and u.force is None
    assert u.approximate and u.quantity == "underwinding_transition_torque" and "PMC4457082" in u.url


def test_force_extension_curve_drawn_over_measured_data():
    (c,) = ex.force_extension_curves()
    assert (c.persistence_length, c.rise, c.salt_M) == (50.0, 0.34, 0.100)
    assert c.stretch_modulus_pN == pytest.approx(1000.0) and c.stretch_modulus == pytest.approx(1000.0 * PN)
    assert "PMC33432" in c.url and "not stated as a fit" in c.verification


def test_topoisomer_fit_converted_from_cgs():
    t = ex.topoisomer_variance_fit_reference()
    # 3.0e-19 erg cm = 3.0e-28 J m = 300 pN nm^2 per molecule; times N_A / 1000 -> kJ/mol nm
    c_si = 3.0e-19 * 1e-7 * 1e-2  # J m
    assert t["torsional_rigidity"].value == pytest.approx(c_si * 1e9 * AVOGADRO / 1000.0, rel=1e-12)
    assert t["torsional_rigidity"].value == pytest.approx(300.0 * PN, rel=1e-12)
    assert t["persistence_length"].value == pytest.approx(50.0) and t["persistence_length"].unit == "nm"
    assert "Horowitz & Wang" in t["torsional_rigidity"].source


def test_buckling_torque_reference_is_empty_and_parses_rows_when_present(monkeypatch):
    assert ex.buckling_torque_reference() == [] and ex.buckling_torque_reference("postbuckling_torque_plateau") == []
    assert "buckling_torque" in ex.MISSING and "Mosconi" in ex.MISSING["buckling_torque"]
    real = ex.read_table

    def fake(name):
        rows = real(name)
        if name == "buckling.csv":
            rows = rows + [dict(source="Test & Row 2001 J", quantity="buckling_torque", torque_pN_nm="20",
                                uncertainty_pN_nm="1.5", force_pN="1.0", salt_M="0.15", url="u", verification="v"),
                           dict(source="Test & Row 2001 J", quantity="buckling_torque", torque_pN_nm="30",
                                uncertainty_pN_nm="", force_pN="3.0", salt_M="0.15", url="u", verification="v")]
        return rows

    monkeypatch.setattr(ex, "read_table", fake)
    allm = ex.buckling_torque_reference()
    assert [(m.value, m.force_pN) for m in allm] == [(pytest.approx(20 * PN), 1.0), (pytest.approx(30 * PN), 3.0)]
    (one,) = ex.buckling_torque_reference(force_pN=1.02)
    assert one.uncertainty == pytest.approx(1.5 * PN) and one.unit == "kJ/mol" and one.salt_M == 0.15
    assert ex.buckling_torque_reference(force_pN=2.0) == [] and ex.buckling_torque_reference(salt_M=0.5) == []
    assert ex.buckling_torque_reference(force_pN=3.0)[0].uncertainty is None


def _rows(kind):
    from dnarod.physics.theory.wlc import extensible_wlc_extension

    if kind == "force_extension":
        return [dict(force_pN=f, relative_extension=float(extensible_wlc_extension(f, 50.0, 1100.0, 4.14)),
                     relative_extension_err=0.005, n_bp=600, temperature_K=300.0, salt_M=0.15)
                for f in (0.1, 1.0, 10.0)]
    return [dict(turns=t, twist_torque_pN_nm=20.0 * t, twist_torque_pN_nm_err=1.0, clamp_torque_pN_nm=20.0 * t,
                 clamp_torque_pN_nm_err=2.0, relative_extension=0.8, relative_extension_err=0.01, force_pN=1.0,
                 contour_length_nm=101.66, n_bp=300, temperature_K=300.0, salt_M=0.15) for t in (-1.0, 0.0, 1.0)]


def _labels_and_texts(plot_labels, tmp_path, kind):
    labels, texts = plot_labels(kind, _rows(kind), tmp_path / f"{kind}.png")
    return " | ".join(labels), texts


def test_plots_draw_the_limits_and_curves(tmp_path, plot_labels):
    fe, _ = _labels_and_texts(plot_labels, tmp_path, "force_extension")
    assert "eWLC lp 50 nm, S 1000 pN drawn over lambda-DNA data at 100 mM Na+ (PMC33432 Fig. 2)" in fe
    hat, texts = _labels_and_texts(plot_labels, tmp_path, "magnetic_tweezers")
    assert "x/L at 1 pN: eWLC lp 50 nm" in hat and any("no measured hat-curve points" in t for t in texts)
    tt, texts = _labels_and_texts(plot_labels, tmp_path, "torque_turns")
    assert "B->P transition torque 34+-2 pN nm at 45 pN (Bryant et al. 2003; a limit of B-DNA, not buckling" in tt
    assert "unwinding transition torque ~-10 pN nm, force not stated (Kwon et al. 2015, quoted" in tt
    assert any("no measured buckling torque or post-buckling plateau" in t for t in texts)
    assert "measured buckling torque" not in tt


def test_torque_plot_draws_a_buckling_torque_at_the_run_force_when_one_is_tabulated(tmp_path, monkeypatch,
                                                                                    plot_labels):
    real = ex.read_table

    def fake(name):
        rows = real(name)
        if name == "buckling.csv":
            rows = rows + [dict(source="Test & Row 2001 J", quantity="buckling_torque", torque_pN_nm="20",
                                uncertainty_pN_nm="1.5", force_pN="1.0", salt_M="0.15"),
                           dict(source="Test & Row 2001 J", quantity="buckling_torque", torque_pN_nm="31",
                                uncertainty_pN_nm="1.5", force_pN="3.0", salt_M="0.15")]
        return rows

    monkeypatch.setattr(ex, "read_table", fake)
    tt, texts = _labels_and_texts(plot_labels, tmp_path, "torque_turns")
    assert "measured buckling torque 20 pN nm at 1 pN, 150 mM (Test & Row 2001)" in tt
    assert "31 pN nm" not in tt  # measured at 3 pN, the run is at 1 pN
    assert not any("no measured buckling torque" in t for t in texts)


def test_experiment_check_reports_the_comparisons_without_stated_uncertainty(tmp_path):
    from dnarod.validate.experiment import (check_experiment, compare_force_extension_curve,
                                            compare_topoisomer_fit)

    r = check_experiment(tmp_path, plots=False, d_override=5.0)  # the calibrated diameter (computing it is slow)
    assert r["passed"]
    fe = r["force_extension_curve"]
    # the model's S (1100 pN) vs the curve's 1000 pN; lp 50 nm in both: x/L agree to 1e-3 up to 10 pN
    assert fe["model_stretch_modulus_pN"] == pytest.approx(1100.0, rel=1e-6)
    assert fe["stretch_modulus_ratio"] == pytest.approx(1.1, rel=1e-6) and fe["max_abs_difference"] < 1.5e-3
    assert "reported" in fe["kind"] and "S 1100 pN vs 1000 pN" in " ".join(r["notes"])
    topo = r["topoisomer_fit"]
    from dnarod.core.units import kT

    assert topo["reference_nm"] == pytest.approx(300.0 * PN / kT(300.0), rel=1e-9)  # 72.4 nm at 300 K
    assert topo["ratio"] == pytest.approx(98.25 / 72.43, rel=2e-3)
    # reported numbers respond to the model's parameters (no pass/fail: the sources state no uncertainty)
    soft = compare_force_extension_curve(50.0, 300.0, [10.0], 300.0)
    assert soft["max_abs_difference"] > 0.02
    assert compare_topoisomer_fit(72.43, 300.0)["ratio"] == pytest.approx(1.0, abs=1e-3)
