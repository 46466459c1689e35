"""The validation suite (``dnarod validate``): results.json structure, every check passes on the real
system and fails when fed a deliberately wrong reference (issue 6 item 1).

Fast versions of every check run here (smaller systems, shorter runs); the full-size statistical
runs are marked slow.
"""
import json

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod import validate as V
from dnarod.core.parameters import StepParameters
from dnarod.physics.testsystems import TwistedRod

# Small, fast settings of every check (the real physics, smaller systems / shorter runs).
FAST = {
    "engines": dict(t_end=0.5, dts=[0.02, 0.01, 0.005, 0.0025]),
    "thermal": dict(n_nodes=16, engines=("lax",), n_samples=2400),
    "dispersion": dict(n_nodes=6),
    "helix": dict(t_run=0.2),
    "paper_scheme": dict(n_nodes=16, t_run=0.5),
    "force_extension": dict(n_bp=100, forces_pn=(10.0,), friction=0.05, t_equil=300.0, t_prod=1500.0, workers=1),
}


def _check(name, tmp_path, **extra):
    opts = dict(FAST[name], **extra)
    return V.check_function(name)(tmp_path, quick=True, **opts)


@pytest.fixture(scope="module")
def suite(tmp_path_factory):
    """The fast subset through run_validation (writes the report folder)."""
    out = tmp_path_factory.mktemp("validation")
    names = ["helix", "dispersion", "paper_scheme", "thermal"]
    res = V.run_validation(out, quick=True, checks=names, options={n: FAST[n] for n in names})
    return out, res


def test_results_json_structure(suite):
    out, res = suite
    data = json.loads((out / "results.json").read_text())
    assert list(data) == ["checks"]
    assert data == res
    assert list(data["checks"]) == ["helix", "dispersion", "paper_scheme", "thermal"]
    for name, r in data["checks"].items():
        assert isinstance(r["passed"], bool), name
        assert r["runtime_s"] > 0
    report = (out / "report.md").read_text()
    assert "| dispersion | PASS |" in report
    for png in ("dispersion.png", "paper_scheme.png", "thermal.png"):
        assert (out / png).stat().st_size > 1000
        assert f"]({png})" in report


def test_fast_subset_passes_with_real_numbers(suite):
    _, res = suite
    c = res["checks"]
    assert all(r["passed"] for r in c.values()), {n: r.get("error") for n, r in c.items()}
    # dispersion: the OpenMM Hessian spectrum equals the exact table (design A6 item 7: 1e-6 rad/ps)
    assert c["dispersion"]["openmm_portable"]["max_frequency_error"] < 1e-6
    # paper scheme: first order, unstable, exact system neutral
    assert all(0.8 < o < 1.25 for o in c["paper_scheme"]["observed_order_last_pair"].values())
    assert c["paper_scheme"]["growth_rate_per_ps"] > 1.0
    assert abs(c["paper_scheme"]["exact_growth_rate_per_ps"]) < 1e-6
    # thermal: exact discrete persistence length of dna-default is 50 nm
    lp = c["thermal"]["lax"]["persistence_length"]
    assert abs(lp["exact_nm"] - 50.0) < 1e-6
    assert abs(lp["measured_nm"] - lp["exact_nm"]) < 4.5 * lp["standard_error_nm"]


def test_engines_lax_splitting_and_half_step_openmm_converge_at_second_order(tmp_path):
    r = _check("engines", tmp_path, plots=False)
    for name in ("lax_splitting", "openmm_half_step"):
        assert 1.8 < r[name]["order_positions"] < 2.2, name
        assert r[name]["max_position_difference_nm"][-1] < 1e-6, name
        assert r[name]["relative_angular_momentum_difference"] < 1e-8, name
    assert r["lax_splitting_passed"] and r["openmm_half_step_passed"]


def test_engines_check_passes_through_the_public_openmm_api(tmp_path):
    """RodSimulation.create(initial_velocities=...) must start the leapfrog half a step back (order 2, not 1)."""
    r = _check("engines", tmp_path, plots=False)
    assert 1.8 < r["openmm"]["order_positions"] < 2.2
    assert r["openmm"]["max_position_difference_nm"][-1] < 1e-6
    assert r["conventions"]["inertia_relative_difference"] < 1e-12
    assert r["passed"]


def test_engines_fails_when_the_lax_engine_has_another_stiffness(tmp_path):
    from dnarod.validate.engines import default_model

    model = default_model()
    p = model.params
    wrong = model.with_pose(model.positions, model.frames)
    wrong.params = StepParameters(p.stiffness * 1.01, p.intrinsic, p.names)
    r = _check("engines", tmp_path, model=model, lax_model=wrong, plots=False)
    assert not r["passed"] and not r["openmm_half_step_passed"]
    assert r["openmm_half_step"]["max_position_difference_nm"][-1] > 1e-5


def test_thermal_fails_against_a_wrong_stiffness(tmp_path):
    r = _check("thermal", tmp_path, stiffness_scale=1.1, plots=False)
    assert not r["passed"]
    assert r["lax"]["max_abs_z"] > 4.5


def test_dispersion_fails_against_a_wrong_bending_modulus(tmp_path):
    rod = TwistedRod.from_forcefield("dna-default", 6)
    ref = TwistedRod.from_forcefield("dna-default", 6, A1=rod.A1 * 1.001)
    r = _check("dispersion", tmp_path, rod=rod, reference_rod=ref, plots=False)
    assert not r["passed"]
    assert r["openmm_fast"]["max_frequency_error"] > 1e-5


def test_helix_fails_when_the_pose_is_not_intrinsic(tmp_path):
    from dnarod.validate.helix import default_models

    label, model, hx = default_models()[0]
    p = model.params
    shifted = model.with_pose(model.positions, model.frames)
    shifted.params = StepParameters(p.stiffness, p.intrinsic + 1e-3, p.names)
    r = _check("helix", tmp_path, models=[(label, shifted, None)])
    assert not r["passed"]
    assert r["systems"][label]["openmm_portable_max_force"] > 1e-4


def test_paper_scheme_check_fails_for_a_consistent_stable_scheme(tmp_path):
    r = _check("paper_scheme", tmp_path, scheme="exact", plots=False)
    assert not r["passed"] and not r["instability_passed"]


def test_force_extension_high_force_matches_wlc_and_fails_with_a_wrong_lp(tmp_path):
    good = _check("force_extension", tmp_path, plots=False)
    row = good["forces"][0]
    assert good["stretch_modulus_pN"] == pytest.approx(1100.0, rel=1e-6)
    assert good["passed"], row
    bad = _check("force_extension", tmp_path, lp_override=5.0, plots=False)
    assert not bad["passed"]


def test_cli_exit_status_and_summary(tmp_path, monkeypatch):
    from dnarod.cli.main import main

    runner = CliRunner()
    out = tmp_path / "rep"
    res = runner.invoke(main, ["validate", "--only", "paper_scheme", "--out", str(out)])
    assert res.exit_code == 0, res.output
    assert "paper_scheme" in res.output and "PASS" in res.output and "runtime" in res.output
    assert json.loads((out / "results.json").read_text())["checks"]["paper_scheme"]["passed"] is True
    monkeypatch.setattr(V, "check_function", lambda name: (lambda out_dir, quick=False: {"passed": False, "x": 1.0}))
    res = runner.invoke(main, ["validate", "--only", "helix", "--out", str(out), "--overwrite"])
    assert res.exit_code == 1
    assert "FAIL" in res.output
    res = runner.invoke(main, ["validate", "--only", "nonsense", "--out", str(out)])
    assert res.exit_code == 2


def test_a_crashing_check_is_reported_as_failed(tmp_path, monkeypatch):
    def boom(out_dir, quick=False):
        raise RuntimeError("deliberate")

    monkeypatch.setattr(V, "check_function", lambda name: boom)
    res = V.run_validation(tmp_path, checks=["helix"])
    r = res["checks"]["helix"]
    assert r["passed"] is False and "deliberate" in r["error"]
    assert "deliberate" in (tmp_path / "report.md").read_text()


def test_unknown_check_name_is_a_clear_error(tmp_path):
    from dnarod.core.errors import DnarodError

    with pytest.raises(DnarodError, match="unknown validation check 'bogus'"):
        V.run_validation(tmp_path, checks=["bogus"])


@pytest.mark.slow
def test_quick_suite_full_size(tmp_path):
    """``dnarod validate --quick`` as a user runs it (all five checks, both engines in thermal)."""
    res = V.run_validation(tmp_path, quick=True)
    failed = [n for n, r in res["checks"].items() if not r["passed"]]
    assert failed == [], failed
    assert res["checks"]["thermal"]["openmm"]["passed"]
    assert np.isfinite(res["checks"]["thermal"]["openmm"]["kinetic_temperature"]["measured_K"])
