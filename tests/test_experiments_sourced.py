"""The values compiled in ../shared/data/reference/physical/measured_values_sourced.md, copied to data/experimental with
where each was read, and what check ``experiment`` does with them: gated where the model speaks to them (Bryant's
single-tension C(0) fits as C_eff), reported beside the model's own number, or listed as outside its reach with why."""
import pytest

from dnarod.core.units import PN
from dnarod.physics import experiments as ex
from dnarod.validate.experiment import OUTSIDE_MODEL, check_experiment


def test_sourced_values_with_provenance():
    got = {m.quantity: m for m in ex.sourced_mechanics()}
    assert got["twist_bend_coupling_G"].value == 40.0 and got["twist_bend_coupling_G"].uncertainty == 10.0
    assert got["effective_torsional_stiffness_salt_relative_change"].value == pytest.approx(-0.10)
    assert got["anharmonic_twist_b_over_a"].value == 4.5
    assert got["twist_stretch_coupling_g"].value / PN == pytest.approx(-100.0)
    assert got["stretch_modulus_S"].value / PN == pytest.approx(1100.0)
    for m in got.values():  # each says where it was read, with the quote
        assert "read in" in m.verification and '"' in m.verification and m.source
    fits = sorted((round(m.force_pN), round(m.value / PN)) for m in ex.torsional_rigidities() if m.force is not None)
    assert (45, 410) in fits and (15, 430) in fits and (15, 440) in fits


def test_check_gates_lists_and_reports(tmp_path):
    r = check_experiment(tmp_path, plots=False, d_override=5.0)
    assert r["passed"]
    gated = {(round(t["force_pN"]), round(t["measured_nm"], 1)) for t in r["effective_torsional_stiffness"]}
    assert (6, 103.0) in gated and any(f == 45 for f, _ in gated)  # Kriegel 6.5 pN and Bryant's 45-pN fit
    outside = {o["quantity"]: o for o in r["outside_model"]}
    for q in ("overwinding_transition_torque", "overstretching", "anharmonic_twist_b_over_a",
              "effective_torsional_stiffness_salt_relative_change", "twist_bend_coupling_G",
              "persistence_length_vs_salt"):
        assert q in outside and outside[q]["why"] == OUTSIDE_MODEL[q]
    assert outside["overwinding_transition_torque"]["measured"] == pytest.approx(34.0)
    assert "P-DNA" in outside["overwinding_transition_torque"]["why"]
    assert outside["twist_bend_coupling_G"]["model"] == 0.0 and outside["twist_bend_coupling_G"]["z"] == 4.0
    assert any("twist-bend coupling" in d for d in r["disagreements"])  # reported, not gating
    rep = {o["quantity"]: o for o in r["sourced_reported"]}
    assert rep["twist_stretch_coupling_g"]["model"] == pytest.approx(r["model_twist_stretch_pN_nm"])
    assert any("Outside the model's reach" in n for n in r["notes"])
    # a model far off the single-tension fits fails the gate (C_eff at 15 and 45 pN within 10 %)
    bad = check_experiment(tmp_path / "bad", plots=False, d_override=5.0, c_override=80.0)
    assert not bad["passed"]
    assert not all(t["passed"] for t in bad["effective_torsional_stiffness"] if round(t["force_pN"]) == 45)
