"""Exact equilibrium starts (dnarod.physics.thermal.equilibrium_sample) and the trustworthy statistics of ``analyze``:
lag-1 persistence length headline, slowest bending relaxation time and the short-run warning."""
import json

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.analysis.polymer import (TangentCorrelation, bending_relaxation_time, integrated_autocorrelation_time,
                                     relaxation_warning)
from dnarod.cli.main import main
from dnarod.core.errors import DnarodError
from dnarod.core.forcefield import load_forcefield
from dnarod.physics.thermal import equilibrium_sample, persistence_length
from dnarod.core.units import kT
from dnarod.core.trajectory import Trajectory

FF = load_forcefield("dna-default")


def sample_trajectory(model, n, seed, time_step=1.0):
    poses = [equilibrium_sample(model, 300.0, seed + i) for i in range(n)]
    return Trajectory(np.arange(n) * time_step, np.array([m.positions for m in poses]),
                      np.array([m.frames for m in poses]))


def test_lag1_persistence_length_of_exact_samples_equals_exact_value():
    model = FF.model_from_sequence(n_nodes=301)
    traj = sample_trajectory(model, 60, seed=100)
    r = TangentCorrelation(traj, FF.ds, n_blocks=10).run().results
    exact = persistence_length(model.params, FF.ds, kT(300))
    assert exact == pytest.approx(50.0, abs=0.01)
    se = r.persistence_length_one_step_err
    assert 0 < se < 1.0  # 18000 steps: ~0.4 nm
    assert abs(r.persistence_length_one_step - exact) < 4 * se
    # the same statistic against a wrong reference (a chain with twice the bending stiffness) fails
    stiff = FF.model_from_sequence(n_nodes=301)
    stiff.params.stiffness[:, :3, :3] *= 2.0
    assert abs(persistence_length(stiff.params, FF.ds, kT(300)) - r.persistence_length_one_step) > 20 * se


def test_equilibrium_sample_sequence_model_and_alignment():
    ff = load_forcefield("olson1998")
    model = ff.model_from_sequence("ACGTTGCAAGCTTAGC" * 4)
    s = equilibrium_sample(model, 300.0, seed=3, align=(0, 0, 1))
    e = s.positions[-1] - s.positions[0]
    assert np.allclose(e / np.linalg.norm(e), [0, 0, 1], atol=1e-12)
    assert np.allclose(s.positions[0], model.positions[0])
    # thermal energy: the exact sample carries ~ (6/2) kT per step of Gaussian energy (Haar factor aside)
    energies = [equilibrium_sample(model, 300.0, seed=i).energy() for i in range(40)]
    per_step = np.mean(energies) / model.n_steps / kT(300)
    assert per_step == pytest.approx(3.0, abs=0.15)
    # deterministic for a seed
    assert np.array_equal(equilibrium_sample(model, 300.0, seed=5).positions,
                          equilibrium_sample(model, 300.0, seed=5).positions)


def test_equilibrium_sample_rejects_rings_and_bad_temperature():
    ring = FF.ring(n_nodes=105, delta_linking_number=0)
    with pytest.raises(DnarodError, match="circular"):
        equilibrium_sample(ring, 300.0)
    with pytest.raises(DnarodError, match="positive temperature"):
        equilibrium_sample(FF.model_from_sequence(n_nodes=10), 0.0)


def test_bending_relaxation_time_limits():
    L, lp, T, rho = 102.0, 50.0, 300.0, 650.0 / 0.34
    A = kT(T) * lp
    # strongly overdamped: zeta rho L^4 / (A beta^4), free (4.730) and hinged (pi) ends
    z = 1.0
    assert bending_relaxation_time(L, lp, T, rho, z) == pytest.approx(z * rho * L**4 / (A * 4.730040744862704**4),
                                                                      rel=1e-6)
    assert bending_relaxation_time(L, lp, T, rho, z, ends="hinged") == pytest.approx(
        z * rho * L**4 / (A * np.pi**4), rel=1e-6)
    # underdamped: 2/zeta
    assert bending_relaxation_time(L, lp, T, rho, 1e-6) == pytest.approx(2e6)
    # tension stiffens the mode (shorter time)
    assert bending_relaxation_time(L, lp, T, rho, z, tension=1.0) < bending_relaxation_time(L, lp, T, rho, z)
    assert relaxation_warning(1e3, 1e4) is not None and relaxation_warning(1e5, 1e4) is None


def test_integrated_autocorrelation_time_of_ar1():
    rng = np.random.default_rng(0)
    phi, n = 0.9, 200_000
    x = np.empty(n)
    x[0] = 0
    e = rng.standard_normal(n)
    for i in range(1, n):
        x[i] = phi * x[i - 1] + e[i]
    exact = 0.5 * (1 + phi) / (1 - phi)  # 9.5 samples
    assert integrated_autocorrelation_time(x) == pytest.approx(exact, rel=0.08)
    assert integrated_autocorrelation_time(rng.standard_normal(20000)) == pytest.approx(0.5, abs=0.05)


@pytest.mark.parametrize("run_ps, warns", [(2000.0, True), (2.0e8, False)])
def test_analyze_headlines_lag1_and_warns_on_short_runs(tmp_path, run_ps, warns):
    model = FF.model_from_sequence(n_nodes=301)
    model.save(tmp_path / "final_model.npz")
    n = 80  # 80 independent frames: enough for an unflagged error bar (50 effective samples)
    traj = sample_trajectory(model, n, seed=7, time_step=run_ps / (n - 1))
    traj.metadata = {"temperature_K": 300.0, "friction_per_ps": 1.0}
    traj.save(tmp_path / "run.dtraj")
    res = CliRunner().invoke(main, ["analyze", str(tmp_path / "run.dtraj"), "-o", str(tmp_path / "out"),
                                    "--no-plots"])
    assert res.exit_code == 0, res.output
    assert "persistence length (lag 1)" in res.output
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    tau = s["relaxation"]["tau_ps"]
    assert tau == pytest.approx(3.4e6, rel=0.1)  # 300 bp, zeta = 1/ps: ~3 microseconds
    assert bool(s["warnings"]) is warns
    assert ("warning: the run" in res.output) is warns
