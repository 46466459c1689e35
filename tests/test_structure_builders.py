"""Models from structures and sequences; saving, loading, rebuilding; trajectories of frames."""
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.core.errors import StructureError
from dnarod.core.forcefield import load_forcefield
from dnarod.core.model import RodModel
from dnarod.core.rotations import rotation_about_axis
from dnarod.core.stepparams import step_parameters
from dnarod.core.strains import strains
from dnarod.structure.analysis import analyze_structure, step_parameters_over_frames
from dnarod.structure.trajectory import read_duplex_trajectory
from dnarod.structure.builders import model_from_sequence, model_from_structure
from dnarod.structure.rebuild import rebuild_coordinates, rebuild_model, write_pdb

DATA = Path(__file__).resolve().parents[1] / "data"
PDB355 = DATA / "structures" / "355D.pdb"


@pytest.mark.parametrize("ff", ["dna-default", "olson1998"])
def test_model_from_structure(tmp_path, ff):
    m = model_from_structure(PDB355, forcefield=ff)
    d = analyze_structure(PDB355).duplexes[0]
    field = load_forcefield(ff)
    assert m.sequence == "CGCGAATTCGCG" and m.n_nodes == 12 and m.ds == field.ds
    assert np.array_equal(m.positions, d.bp_origins) and np.array_equal(m.frames, d.bp_frames)
    ref = field.step_parameters("CGCGAATTCGCG")
    assert np.array_equal(m.params.stiffness, ref.stiffness) and np.array_equal(m.params.intrinsic, ref.intrinsic)
    assert np.allclose(m.mass, field.node_mass) and np.allclose(m.inertia, field.node_inertia)
    Om, Ga = m.strains()
    Om2, Ga2 = strains(d.bp_origins, d.bp_frames, field.ds)
    assert np.allclose(Om, Om2) and np.allclose(Ga, Ga2)
    m.save(tmp_path / "m.npz")
    back = RodModel.load(tmp_path / "m.npz")
    assert np.array_equal(back.frames, m.frames) and back.sequence == m.sequence
    assert back.metadata["strand1"][0] == "A:1" and back.metadata["strand2"][0] == "B:24"
    assert np.isclose(back.energy(), m.energy())


def test_model_from_sequence_is_forcefield_intrinsic():
    m = model_from_sequence("ACGTTGCA", "olson1998")
    ref = load_forcefield("olson1998").model_from_sequence("ACGTTGCA")
    assert np.allclose(m.positions, ref.positions) and np.isclose(m.energy(), 0.0, atol=1e-9)


def test_structure_model_rebuild_reproduces_frames(tmp_path):
    m = model_from_structure(DATA / "structures" / "2D94.pdb")
    rebuild_model(m, tmp_path / "r.pdb")
    d = analyze_structure(tmp_path / "r.pdb").duplexes[0]
    assert np.abs(d.bp_origins - m.positions).max() < 1e-3
    assert np.abs(d.bp_params - np.array(m.metadata["bp_params"])).max() < 2e-3
    assert np.abs(step_parameters(d.bp_frames[:-1], d.bp_origins[:-1], d.bp_frames[1:], d.bp_origins[1:])
                  - step_parameters(m.frames[:-1], m.positions[:-1], m.frames[1:], m.positions[1:])).max() < 2e-3


def test_cli_build_and_rebuild(tmp_path):
    r = CliRunner()
    res = r.invoke(main, ["build", str(PDB355), "-o", str(tmp_path / "a.npz"), "--forcefield", "olson1998"])
    assert res.exit_code == 0, res.output
    assert RodModel.load(tmp_path / "a.npz").n_nodes == 12
    res = r.invoke(main, ["build", "--sequence", "ACGTAC", "-o", str(tmp_path / "b.npz")])
    assert res.exit_code == 0, res.output
    res = r.invoke(main, ["rebuild", str(tmp_path / "b.npz"), "-o", str(tmp_path / "b.pdb")])
    assert res.exit_code == 0, res.output
    m = RodModel.load(tmp_path / "b.npz")
    d = analyze_structure(tmp_path / "b.pdb").duplexes[0]
    # the rebuild keeps base-pair origins within 0.05 A (its own checked tolerance; 0.015 A measured here)
    assert d.sequence == "ACGTAC" and np.abs(d.bp_origins - m.positions).max() < 5e-3
    res = r.invoke(main, ["build", "-o", str(tmp_path / "c.npz")])
    assert res.exit_code == 2 and "INPUT" in res.output
    res = r.invoke(main, ["build", str(PDB355), "--duplex", "3", "-o", str(tmp_path / "c.npz")])
    assert res.exit_code == 2 and "duplex 3 does not exist" in res.output


def test_step_parameters_over_frames_matches_direct(tmp_path):
    """Frames -> atoms (rebuild) -> frames (vectorised fit) -> step parameters, against the frames' own."""
    rng = np.random.default_rng(11)
    m = load_forcefield("dna-default").model_from_sequence("GATTACAGATTACA")
    nf = 20
    axes = rng.normal(size=(nf, 14, 3))
    R = rotation_about_axis(axes / np.linalg.norm(axes, axis=-1)[..., None], np.radians(5) * rng.normal(size=(nf, 14)))
    F = R @ m.frames
    O = m.positions + 0.03 * rng.normal(size=(nf, 14, 3))
    X, atoms = rebuild_coordinates(F, O, m.sequence)
    write_pdb(tmp_path / "top.pdb", X[0], atoms)
    d = analyze_structure(tmp_path / "top.pdb").duplexes[0]
    sp, bp, mid, morg = step_parameters_over_frames(d, X)
    want = step_parameters(F[:, :-1], O[:, :-1], F[:, 1:], O[:, 1:])
    assert sp.shape == (nf, 13, 6) and np.abs(sp - want).max() < 1e-9
    assert np.allclose(morg, O, atol=1e-9)
    # the same through a multi-model PDB read by MDAnalysis
    write_pdb(tmp_path / "traj.pdb", X, atoms)
    r = read_duplex_trajectory(tmp_path / "top.pdb", tmp_path / "traj.pdb")
    sp2 = r.step_params
    assert sp2.shape == (nf, 13, 6) and np.abs(sp2 - want).max() < 2e-3  # PDB rounds to 1e-4 nm
    with pytest.raises(StructureError, match="coordinates have 5 atoms"):
        step_parameters_over_frames(d, X[:, :5])
