"""``dnarod analyze`` end to end on dnarod trajectories (open and circular) and the bundled all-atom one."""
import json
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.physics.sampling import sample_chains
from dnarod.cli.main import main
from dnarod.core.forcefield import load_forcefield
from dnarod.physics.thermal import persistence_length
from dnarod.core.units import kT

DATA = Path(__file__).resolve().parent.parent / "data" / "allatom"


def run_cli(args):
    res = CliRunner().invoke(main, ["analyze", *map(str, args)])
    assert res.exit_code == 0, res.output
    return res


def test_analyze_dtraj_with_model(tmp_path):
    ff = load_forcefield("dna-default")
    model = ff.model_from_sequence(n_nodes=31)
    model.save(tmp_path / "final_model.npz")
    traj = sample_chains(model.params, ff.ds, kT(300), 400, np.random.default_rng(9))
    traj.metadata = {"temperature_K": 300.0}
    traj.save(tmp_path / "run.dtraj")
    res = run_cli([tmp_path / "run.dtraj", "-o", tmp_path / "out"])
    assert "400 frames, 31 nodes" in res.output
    out = tmp_path / "out"
    s = json.loads((out / "summary.json").read_text())
    for f in s["files"].values():
        assert (out / f).stat().st_size > 0, f
    lp = s["persistence_length_nm"]
    exact = persistence_length(model.params, ff.ds, kT(300))
    assert lp["exact_one_step"] == pytest.approx(exact, rel=1e-6)  # the model file was picked up
    assert abs(lp["fit"] - exact) < 4.5 * lp["error"]
    fitted = load_forcefield(out / "stiffness.toml")
    K = ff.table["*"][0]
    rel = np.abs(np.diag(fitted.table["*"][0]) / np.diag(K) - 1)
    assert rel.max() < 0.08  # 12000 samples: ~2-3 % statistical error per diagonal entry
    rows = (out / "step_parameters.csv").read_text().splitlines()
    assert len(rows) == 1 + 400 * 30
    ee = s["end_to_end_nm"]
    assert 0 < ee["mean"] < ee["contour_nm"] and ee["error"] > 0


def test_analyze_ring(tmp_path):
    from test_analysis_linking import ring_trajectory

    ring = ring_trajectory(84, 8, 3, seed=1)
    ring.save(tmp_path / "ring.dtraj")
    run_cli([tmp_path / "ring.dtraj", "--circular", "-o", tmp_path / "out", "--no-plots"])
    s = json.loads((tmp_path / "out" / "summary.json").read_text())
    assert s["linking"]["Lk"] == [8, 8, 8]
    assert s["linking"]["check_Lk_equals_Tw_plus_Wr"] is True
    assert s["circular"] is True and "end_to_end_nm" not in s


def test_analyze_bundled_allatom(tmp_path):
    res = run_cli([DATA / "355D_obc2_100ps.dcd", "--topology", DATA / "355D_obc2_top.pdb", "-o", tmp_path / "aa"])
    assert "sequence CGCGAATTCGCG" in res.output
    s = json.loads((tmp_path / "aa" / "summary.json").read_text())
    assert 3.2 < s["mean_step_parameters"]["rise_A"] < 3.5
    assert 30 < s["mean_step_parameters"]["twist_deg"] < 38
    # all-atom MD in, coarse-grained parameters out: both force-field files load and build the duplex
    uni = load_forcefield(tmp_path / "aa" / "stiffness.toml")
    assert uni.model_from_sequence("CGCGAATTCGCG").n_nodes == 12
    seqff = load_forcefield(tmp_path / "aa" / s["files"]["sequence_forcefield"])
    assert seqff.model_from_sequence("CGCGAATTCGCG").params.names[4] == "AA"
