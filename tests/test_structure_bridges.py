"""Structure-shaped models (1CGP), the coarse-grained export's topology, and the oxDNA bridge."""
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.core.forcefield import load_forcefield
from dnarod.core.rotations import cayley
from dnarod.core.stepparams import step_parameters
from dnarod.structure import model_from_structure
from dnarod.structure.cg_topology import cg_pdb_text, chain_and_number, hy36
from dnarod.structure.oxdna import read_oxdna, write_oxdna
from dnarod.core.trajectory import Trajectory

DATA = Path(__file__).resolve().parents[1] / "data" / "structures"


def _roll(m):
    return np.degrees(step_parameters(m.frames[:-1], m.positions[:-1], m.frames[1:], m.positions[1:])[:, 4])


@pytest.mark.parametrize("intrinsic, kept", [("structure", True), ("sequence", False)])
def test_1cgp_cap_kinks_kept_with_intrinsic_structure(intrinsic, kept):
    from dnarod.engines.openmm.simulation import RodSimulation

    ff = load_forcefield("dna-default")
    m = model_from_structure(DATA / "1CGP.pdb", forcefield=ff, intrinsic=intrinsic)
    assert m.metadata["intrinsic"] == intrinsic and "amino acid" in m.metadata["selection"]
    roll0 = _roll(m)
    assert roll0[9] > 35 and roll0[19] > 25  # the two CAP kinks (3DNA: roll ~39 and ~29 deg)
    sim = RodSimulation.create(m, platform="CPU")
    sim.minimize()
    roll = _roll(sim.current_model())
    if kept:
        assert np.abs(roll - roll0).max() < 0.5
        assert np.allclose(m.params.stiffness, ff.step_parameters(m.sequence).stiffness)  # stiffness from --forcefield
    else:
        assert roll[9] < 10 and roll[19] < 10  # the sequence's intrinsic shape straightens the kinks


def test_cli_build_intrinsic_structure(tmp_path):
    out = tmp_path / "cap.npz"
    r = CliRunner().invoke(main, ["build", str(DATA / "1CGP.pdb"), "--intrinsic", "structure", "-o", str(out)])
    assert r.exit_code == 0, r.output
    from dnarod.core.model import RodModel

    m = RodModel.load(out)
    assert abs(m.energy()) < 1e-9  # the structure is its own zero-energy shape
    r = CliRunner().invoke(main, ["build", "--sequence", "ACGT", "--intrinsic", "structure", "-o", str(out)])
    assert r.exit_code == 2 and "need a structure INPUT" in r.output


def test_cg_export_names_and_tools(tmp_path):
    import MDAnalysis as mda
    import mdtraj as md

    from dnarod.structure.export import export_trajectory

    ff = load_forcefield("dna-default")
    m = ff.model_from_sequence("ACGTTGCA")
    tr = Trajectory(np.arange(3.0) * 2.5, np.repeat(m.positions[None], 3, 0), np.repeat(m.frames[None], 3, 0),
                    metadata={"sequence": m.sequence})
    export_trajectory(tr, tmp_path / "t.pdb", tmp_path / "t.dcd")
    text = (tmp_path / "t.pdb").read_text()
    assert text.startswith("REMARK 250 dnarod coarse-grained rod") and "BPC = base-pair centre" in text
    u = mda.Universe(str(tmp_path / "t.pdb"), str(tmp_path / "t.dcd"))
    assert u.select_atoms("nucleic").n_atoms == 24 and u.select_atoms("name BPC").n_atoms == 8
    assert u.select_atoms("protein").n_atoms == 0 and set(u.atoms.names) == {"BPC", "BPX", "BPZ"}
    assert list(u.residues.resnames[:4]) == ["DA", "DC", "DG", "DT"]
    t = md.load(str(tmp_path / "t.dcd"), top=str(tmp_path / "t.pdb"))
    assert {a.element.symbol for a in t.topology.atoms} == {"VS"} and t.topology.n_bonds == 2 * 8 + 7
    # analyze on the exported PDB + DCD works (float32 frames) and matches the exact trajectory
    from dnarod.structure.trajectory import read_node_trajectory

    back = read_node_trajectory(tmp_path / "t.dcd", tmp_path / "t.pdb")
    assert np.abs(back.frames - tr.frames).max() < 1e-5 and np.abs(back.positions - tr.positions).max() < 1e-4


def test_cg_numbering_beyond_pdb_limits():
    assert hy36(99999) == "99999" and hy36(100000) == "A0000" and hy36(100001) == "A0001"
    assert hy36(100000 + 26 * 36 ** 4) == "a0000"
    assert chain_and_number(0) == ("A", 1) and chain_and_number(9998) == ("A", 9999)
    assert chain_and_number(9999) == ("B", 1) and chain_and_number(20000) == ("C", 3)
    n = 34000  # 102,000 beads: serials past 99,999 and residue numbers past 9999
    pos = np.zeros((n, 3))
    pos[:, 2] = 0.34 * np.arange(n)
    frm = np.broadcast_to(np.eye(3), (n, 3, 3))
    lines = cg_pdb_text(pos, frm).splitlines()
    atoms = [ln for ln in lines if ln.startswith("ATOM")]
    assert len(atoms) == 3 * n and max(int(ln[22:26]) for ln in atoms) == 9999
    assert atoms[99999][6:11] == "A0000" and {ln[21] for ln in atoms} == {"A", "B", "C", "D"}
    import gemmi

    st = gemmi.read_pdb_string("\n".join(lines))  # a PDB reader that decodes hybrid-36
    assert st[0].count_atom_sites() == 3 * n


@pytest.mark.parametrize("new_format", [False, True])
def test_oxdna_round_trip(tmp_path, new_format):
    m = model_from_structure(DATA / "355D.pdb")
    rng = np.random.default_rng(5)
    P, F = [], []
    for _ in range(3):  # three "thermal" frames: small random rotations and shifts of each node
        R = cayley(0.05 * rng.standard_normal((m.n_nodes, 3)))
        F.append(m.frames @ R)
        P.append(m.positions + 0.02 * rng.standard_normal((m.n_nodes, 3)))
    P, F = np.array(P), np.array(F)
    top, conf = tmp_path / "d.top", tmp_path / "trajectory.dat"
    write_oxdna(top, conf, P, F, m.sequence, new_format=new_format)
    head = top.read_text().splitlines()[0]
    assert head == ("24 2 5->3" if new_format else "24 2")
    tr = read_oxdna(top, conf)
    assert tr.metadata["sequence"] == m.sequence == "CGCGAATTCGCG"
    assert np.abs(tr.positions - P).max() < 1e-8 and np.abs(tr.frames - F).max() < 1e-8
    assert np.allclose(tr.time, np.arange(3) * 3.03)
    r = CliRunner().invoke(main, ["analyze", str(conf), "--topology", str(top), "--no-plots",
                                  "-o", str(tmp_path / "an")])
    assert r.exit_code == 0, r.output
    assert (tmp_path / "an").is_dir()


def test_cli_simulate_intrinsic_structure_keeps_the_kinks(tmp_path):
    """`simulate --intrinsic structure --minimize` says which duplex it took and what it dropped, and keeps CAP's
    kinks."""
    from dnarod.core.model import RodModel

    out = tmp_path / "cap"
    r = CliRunner().invoke(main, ["simulate", str(DATA / "1CGP.pdb"), "--intrinsic", "structure", "--minimize",
                                  "--time", "0.0005", "-T", "0", "--no-export", "--no-progress", "-o", str(out)])
    assert r.exit_code == 0, r.output
    line = next(s for s in r.stdout.splitlines() if s.startswith("input: "))
    assert "took duplex" in line and "amino acid" in line
    m0 = model_from_structure(DATA / "1CGP.pdb", intrinsic="structure")
    m = RodModel.load(out / "final_model.npz")
    assert np.abs(_roll(m) - _roll(m0)).max() < 0.5
    r = CliRunner().invoke(main, ["simulate", "ACGTACGTAC", "--intrinsic", "structure", "-o", str(tmp_path / "x")])
    assert r.exit_code == 2 and "applies to a structure file" in r.output
