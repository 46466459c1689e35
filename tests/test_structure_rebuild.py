"""Rebuild all-atom PDBs from node frames; read them back; OpenMM and MDAnalysis read them."""
from pathlib import Path

import numpy as np
import pytest

from dnarod.core.errors import StructureError
from dnarod.core.forcefield import load_forcefield
from dnarod.core.rotations import rotation_about_axis
from dnarod.core.stepparams import from_angstrom_degrees, step_transform
from dnarod.structure.analysis import analyze_structure
from dnarod.structure.bpparams import base_frames_from_pair, pair_parameters
from dnarod.structure.rebuild import fibre_pair_parameters, rebuild_coordinates, write_pdb

DATA = Path(__file__).resolve().parents[1] / "data"


def _angle_deg(A, B):
    R = np.swapaxes(A, -1, -2) @ B
    return np.degrees(np.arccos(np.clip((np.trace(R, axis1=-2, axis2=-1) - 1) / 2, -1, 1)))


def _random_rotations(rng, n, scale):
    axes = rng.normal(size=(n, 3))
    return rotation_about_axis(axes / np.linalg.norm(axes, axis=1)[:, None], scale * rng.normal(size=n))


def test_pair_parameters_inverse_exact():
    rng = np.random.default_rng(3)
    n = 50
    F = _random_rotations(rng, n, 2.0)
    o = rng.normal(size=(n, 3))
    p = np.column_stack([0.05 * rng.normal(size=(n, 3)), np.radians(20) * rng.normal(size=(n, 3))])
    L1, o1, L2, o2 = base_frames_from_pair(F, o, p)
    q, mid, morg = pair_parameters(L1, o1, L2, o2)
    assert np.allclose(q, p, atol=1e-12) and np.allclose(mid, F, atol=1e-12) and np.allclose(morg, o, atol=1e-12)


@pytest.mark.parametrize("pdb", ["355D", "2D94"])
def test_rebuild_then_read_gives_same_frames(tmp_path, pdb):
    d = analyze_structure(DATA / "structures" / f"{pdb}.pdb").duplexes[0]
    xyz, atoms = rebuild_coordinates(d.bp_frames, d.bp_origins, d.sequence, d.bp_params)
    out = tmp_path / "rebuilt.pdb"
    write_pdb(out, xyz, atoms)
    e = analyze_structure(out).duplexes[0]
    assert e.n_bp == d.n_bp and e.sequence == d.sequence
    assert np.abs(e.bp_origins - d.bp_origins).max() < 1e-3  # nm
    assert _angle_deg(e.bp_frames, d.bp_frames).max() < 0.1  # degrees
    assert np.abs(e.bp_params - d.bp_params).max() < 2e-3


def test_rebuild_random_model_round_trip(tmp_path):
    """A perturbed 30-bp chain with random base-pair parameters survives PDB writing and reading."""
    rng = np.random.default_rng(7)
    m = load_forcefield("dna-default").model_from_sequence("".join(rng.choice(list("ACGT"), 30)))
    F = _random_rotations(rng, 30, np.radians(4)) @ m.frames
    o = m.positions + 0.02 * rng.normal(size=(30, 3))
    bp = np.column_stack([0.03 * rng.normal(size=(30, 3)), np.radians(8) * rng.normal(size=(30, 3))])
    xyz, atoms = rebuild_coordinates(F, o, m.sequence, bp)
    write_pdb(tmp_path / "m.pdb", xyz, atoms)
    e = analyze_structure(tmp_path / "m.pdb").duplexes[0]
    assert e.sequence == m.sequence
    assert np.abs(e.bp_origins - o).max() < 1e-3 and _angle_deg(e.bp_frames, F).max() < 0.1
    assert np.abs(e.bp_params - bp).max() < 2e-3


def test_fibre_backbone_closes_for_fibre_geometry():
    """With the B-DNA fibre's own step and pair geometry the O3'-P links are chemical bonds (1.5-1.7 A)."""
    p = fibre_pair_parameters()
    assert -16 < np.degrees(p[4]) < -14  # propeller of the B-DNA fibre model
    step = from_angstrom_degrees([-0.005, 0.454, 3.358, 0.002, 1.708, 35.961])  # fibre str04 step
    R, t = step_transform(step)
    F, o = [np.eye(3)], [np.zeros(3)]
    for _ in range(7):
        o.append(o[-1] + F[-1] @ t)
        F.append(F[-1] @ R)
    xyz, atoms = rebuild_coordinates(np.array(F), np.array(o), "ACGTTGCA")
    idx = {(c, n, a): i for i, (c, n, _, a, _) in enumerate(atoms)}
    links = [(c, k) for c, ks in (("A", range(1, 8)), ("B", range(9, 16))) for k in ks]
    d = [10 * np.linalg.norm(xyz[idx[(c, k, "O3'")]] - xyz[idx[(c, k + 1, "P")]]) for c, k in links]
    assert 1.5 < min(d) and max(d) < 1.7


def test_rebuild_vectorised_over_frames():
    m = load_forcefield("dna-default").model_from_sequence("ACGTAC")
    F = np.stack([m.frames, m.frames @ rotation_about_axis(np.array([0, 0, 1.0]), 0.1)])
    O = np.stack([m.positions, m.positions + 1.0])
    X, atoms = rebuild_coordinates(F, O, m.sequence)
    X0, _ = rebuild_coordinates(F[0], O[0], m.sequence)
    X1, _ = rebuild_coordinates(F[1], O[1], m.sequence)
    assert X.shape == (2, len(atoms), 3) and np.allclose(X[0], X0) and np.allclose(X[1], X1)


def test_rebuilt_pdb_readable_by_openmm_and_mdanalysis(tmp_path):
    import MDAnalysis as mda
    from openmm.app import PDBFile

    m = load_forcefield("dna-default").model_from_sequence("CGCGAATTCGCG")
    xyz, atoms = rebuild_coordinates(m.frames, m.positions, m.sequence)
    out = tmp_path / "b.pdb"
    write_pdb(out, xyz, atoms)
    pdb = PDBFile(str(out))
    assert pdb.topology.getNumAtoms() == len(atoms) and pdb.topology.getNumResidues() == 24
    assert pdb.topology.getNumChains() == 2
    pos = np.array([[v.x, v.y, v.z] for v in pdb.getPositions()])  # nm
    assert np.abs(pos - xyz).max() < 1e-3
    assert [r.name for r in pdb.topology.residues()][:3] == ["DC", "DG", "DC"]
    u = mda.Universe(str(out))
    assert u.atoms.n_atoms == len(atoms) and u.residues.n_residues == 24
    assert np.abs(u.atoms.positions / 10.0 - xyz).max() < 1e-3
    assert "P" not in [a.name for a in u.residues[0].atoms]  # 5' end without phosphate


def test_rebuild_bad_inputs():
    m = load_forcefield("dna-default").model_from_sequence("ACGT")
    with pytest.raises(StructureError, match="letter 'X' at position 2"):
        rebuild_coordinates(m.frames, m.positions, "AXGT")
    with pytest.raises(StructureError, match="3 letters for 4 base pairs"):
        rebuild_coordinates(m.frames, m.positions, "ACG")
    bad = m.positions.copy()
    bad[1, 0] = np.nan
    with pytest.raises(StructureError, match="NaN"):
        rebuild_coordinates(m.frames, bad, "ACGT")
