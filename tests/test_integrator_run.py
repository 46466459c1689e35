"""Running the Lax-form engine: shared trajectory format, energies CSV, checkpoint/resume, failures, CLI."""
import warnings

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.core.errors import SimulationError
from dnarod.core.forcefield import load_forcefield
from dnarod.run.lax import simulate_exact, simulate_langevin, simulate_nve
from dnarod.core.trajectory import Trajectory
from dnarod.physics.testsystems import dna_like_rod


@pytest.fixture(scope="module")
def model():
    return load_forcefield("dna-default").model_from_sequence("ACGTTGCAAGCTTACG")


def test_nve_writes_shared_format(tmp_path, model):
    res = simulate_nve(model, 0.05, 300, temperature=300.0, seed=1, out=tmp_path / "a.dtraj",
                       energy_csv=tmp_path / "a.csv", report_interval=50)
    tr = Trajectory.load(tmp_path / "a.dtraj")
    assert tr.n_frames == 7 and list(tr.step) == [0, 50, 100, 150, 200, 250, 300]
    assert np.allclose(tr.time, 0.05 * tr.step)
    assert np.array_equal(tr.positions[-1], res.state.positions)
    v, w = res.state.velocities(model.mass, model.inertia)
    assert np.array_equal(tr.velocities[-1], v) and np.array_equal(tr.angular_velocities[-1], w)
    csv = np.loadtxt(tmp_path / "a.csv", delimiter=",", skiprows=1)
    assert csv.shape == (7, 9)  # the run layer's header: step .. temperature, elastic, nonbonded, external
    assert np.allclose(csv[:, 2] + csv[:, 3], csv[:, 4])
    assert np.abs(csv[:, 4] - csv[0, 4]).max() < 0.3 * 2.494   # NVE: bounded energy error at dt = 0.05
    assert tr.metadata["engine"] == "lax"


def test_checkpoint_resume_is_seamless(tmp_path, model):
    kw = dict(temperature=300.0, friction=1.0, seed=7, report_interval=20, checkpoint_interval=100)
    full = simulate_langevin(model, 0.05, 400, out=tmp_path / "f.dtraj", energy_csv=tmp_path / "f.csv",
                             checkpoint=tmp_path / "f.npz", **kw)
    part = simulate_langevin(model, 0.05, 200, out=tmp_path / "p.dtraj", energy_csv=tmp_path / "p.csv",
                             checkpoint=tmp_path / "p.npz", **kw)
    # simulate a crash after step 230: the files hold frames past the checkpoint at 200
    simulate_langevin(model, 0.05, 240, out=tmp_path / "junk.dtraj", **kw)
    res = simulate_langevin(model, 0.05, 400, out=tmp_path / "p.dtraj", energy_csv=tmp_path / "p.csv",
                            checkpoint=tmp_path / "p.npz", resume=True, **kw)
    assert res.step == 400 and part.step == 200
    assert np.array_equal(res.state.positions, full.state.positions)
    assert np.array_equal(res.state.angular_momenta, full.state.angular_momenta)
    a, b = Trajectory.load(tmp_path / "f.dtraj"), Trajectory.load(tmp_path / "p.dtraj")
    assert np.array_equal(a.step, b.step) and np.array_equal(a.frames, b.frames)
    assert (tmp_path / "f.csv").read_text() == (tmp_path / "p.csv").read_text()


def test_blow_up_keeps_written_frames(tmp_path):
    model = dna_like_rod(12)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(SimulationError) as exc:
            simulate_nve(model, 1.5, 5000, temperature=300.0, seed=2, out=tmp_path / "b.dtraj",
                         energy_csv=tmp_path / "b.csv", report_interval=1, allow_unstable=True)
    err = exc.value
    assert err.step is not None and err.node is not None and err.term
    assert f"step {err.step}" in str(err)
    tr = Trajectory.load(tmp_path / "b.dtraj")
    assert tr.n_frames == err.step  # every step before the failing one is on disk
    assert np.isfinite(tr.positions).all()


def test_unstable_dt_is_refused(model):
    with pytest.raises(SimulationError, match="stability limit"):
        simulate_nve(model, 0.6, 10)


def test_exact_run_writes_same_format(tmp_path):
    model = dna_like_rod(8)
    res = simulate_exact(model, 2.0, temperature=300.0, seed=3, n_frames=5, out=tmp_path / "e.dtraj",
                         energy_csv=tmp_path / "e.csv")
    tr = Trajectory.load(tmp_path / "e.dtraj")
    assert tr.n_frames == 5 and tr.velocities is not None
    assert np.allclose(tr.positions, res.trajectory.positions)
    csv = np.loadtxt(tmp_path / "e.csv", delimiter=",", skiprows=1)
    assert np.abs(csv[:, 4] - csv[0, 4]).max() < 1e-7 * abs(csv[0, 4])


def test_cli_lax_run(tmp_path):
    """``lax-run`` is ``simulate --engine lax``: same options, a run folder, one line and exit 2 on misuse."""
    from dnarod.cli.main import main

    runner = CliRunner()
    out = tmp_path / "c"
    r = runner.invoke(main, ["lax-run", "ACGTACGTAC", "--time", "0.01", "--dt", "0.05", "--seed", "1", "-o", str(out),
                             "--frame-interval", "2.5", "--no-progress"])
    assert r.exit_code == 0, r.output
    assert "engine: lax  nodes: 10  ensemble: langevin" in r.output and "steps: 200" in r.output
    assert Trajectory.load(out / "trajectory.dtraj").n_frames == 5
    r = runner.invoke(main, ["lax-run", "12", "--friction", "0", "--time", "0.005", "-o", str(tmp_path / "d"),
                             "--no-progress"])
    assert r.exit_code == 0 and "ensemble: nve" in r.output
    r = runner.invoke(main, ["lax-run", "ACGTAC", "--dt", "0.9", "-o", str(tmp_path / "e"), "--no-progress"])
    assert r.exit_code == 2 and "stability limit" in r.output
