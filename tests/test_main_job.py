"""The README's main job end to end: dnarod simulate on a bundled PDB, then dnarod analyze on the result."""
import json

import numpy as np
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.core.forcefield import data_dir
from dnarod.structure import analyze_structure
from dnarod.core.trajectory import load_trajectory

PDB = data_dir() / "structures" / "355D.pdb"


def test_simulate_pdb_then_analyze(tmp_path):
    run = tmp_path / "run"
    r = CliRunner().invoke(main, ["simulate", str(PDB), "--time", "0.1", "-o", str(run), "--no-progress",
                                  "--seed", "1"])
    assert r.exit_code == 0, r.output
    traj = load_trajectory(run / "trajectory.dtraj")
    d = analyze_structure(PDB).duplexes[0]
    # frame 0 is the crystal structure's base-pair frames (nm), the nodes of the model
    assert traj.n_nodes == 12
    # the .dtraj stores float32: equal to the float64 values rounded to float32
    assert np.array_equal(traj.positions[0], d.bp_origins.astype(np.float32).astype(float))
    assert np.array_equal(traj.frames[0], d.bp_frames.astype(np.float32).astype(float))
    assert traj.n_frames >= 90 and np.isfinite(traj.positions).all()
    r = CliRunner().invoke(main, ["analyze", str(run / "trajectory.dtraj"), "-o", str(tmp_path / "ana")])
    assert r.exit_code == 0, r.output
    summary = json.loads((tmp_path / "ana" / "summary.json").read_text())
    assert summary["n_frames"] == traj.n_frames
    for f in ("step_parameters.csv", "stiffness.toml", "tangent_correlation.png", "strain_distributions.png"):
        assert (tmp_path / "ana" / f).is_file(), f
    # running the same command again refuses to clobber the earlier run (nothing lost)
    r = CliRunner().invoke(main, ["simulate", str(PDB), "--time", "0.1", "-o", str(run), "--no-progress"])
    assert r.exit_code == 2 and "overwrite" in r.output.lower()
    assert load_trajectory(run / "trajectory.dtraj").n_frames == traj.n_frames


def test_simulate_rejects_missing_file_and_circular_structure(tmp_path):
    r = CliRunner().invoke(main, ["simulate", str(tmp_path / "nope.pdb"), "-o", str(tmp_path / "x")])
    assert r.exit_code == 2 and "nope.pdb: file not found" in r.output
    r = CliRunner().invoke(main, ["simulate", str(PDB), "--circular", "-o", str(tmp_path / "x")])
    assert r.exit_code == 2 and "--circular/--ring/--delta-lk apply to a sequence" in r.output


def test_supercoiled_minicircle_keeps_its_linking_number(tmp_path):
    """A 105 bp ring with Lk = 10 - 2: the dynamics conserve the (topological) linking number."""
    from dnarod.analysis import LinkingNumber
    from dnarod.core.model import RodModel

    seq = "ACGTTGCA" * 13 + "A"
    r = CliRunner().invoke(main, ["simulate", seq, "--ring", "--delta-lk", "-2", "--time", "0.05", "-o",
                                  str(tmp_path / "ring"), "--no-progress", "--seed", "2"])
    assert r.exit_code == 0, r.output
    traj = load_trajectory(tmp_path / "ring" / "trajectory.dtraj")
    model = RodModel.load(tmp_path / "ring" / "final_model.npz")
    res = LinkingNumber(traj, closure=model.closure).run().results
    assert set(res.linking_integer) == {8}
    assert res.max_identity_error < 1e-8
    r = CliRunner().invoke(main, ["simulate", seq, "--delta-lk", "1", "-o", str(tmp_path / "x")])
    assert r.exit_code == 2 and "--delta-lk needs --ring" in r.output
