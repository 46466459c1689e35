"""Bad input to the analyses: clear errors naming what is wrong."""
import warnings

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.analysis import StepAnalysis, StiffnessFit, TangentCorrelation
from dnarod.analysis.report import load_input
from dnarod.physics.sampling import sample_chains
from dnarod.cli.main import main
from dnarod.core.errors import DnarodError, GeometryError, StructureError
from dnarod.core.forcefield import load_forcefield
from dnarod.core.units import kT
from dnarod.core.trajectory import Trajectory

FF = load_forcefield("dna-default")


def chains(n_frames=6, n_steps=8, seed=0):
    return sample_chains(FF.step_parameters(n_steps=n_steps), FF.ds, kT(300), n_frames, np.random.default_rng(seed))


def test_nan_frame_is_named():
    t = chains()
    t.positions[3, 5, 1] = np.nan
    with pytest.raises(GeometryError, match=r"frame 3 .*base pair 6: position is not finite"):
        StepAnalysis(t, 0.34)
    t = chains()
    t.frames[2, 4] = np.nan
    with pytest.raises(GeometryError, match=r"frame 2 .*base pair 5: frame is not finite"):
        TangentCorrelation(t, 0.34)


def test_non_orthonormal_frame_is_named():
    t = chains()
    t.frames[1, 2] *= 1.01
    with pytest.raises(GeometryError, match=r"frame 1, base pair 3: frame is not orthonormal"):
        StepAnalysis(t, 0.34)


def test_missing_and_repeated_frames():
    t = chains()
    t = Trajectory([0, 1, 2, 4, 5, 6], t.positions, t.frames)
    with pytest.raises(DnarodError, match=r"frame 3: time jumps from 2 to 4 ps .* frames are missing"):
        StepAnalysis(t, 0.34)
    StepAnalysis(t, 0.34, check_spacing=False).run()  # explicitly allowed
    t2 = Trajectory([0, 1, 1, 2, 3, 4], t.positions, t.frames)
    with pytest.raises(DnarodError, match=r"frame 2: time 1 ps does not increase"):
        StepAnalysis(t2, 0.34)


def test_circular_analysis_of_linear_chain():
    with pytest.raises(GeometryError, match=r"not closed.*linear chain"):
        StepAnalysis(chains(), 0.34, circular=True).run()


def test_sequence_that_does_not_match_the_trajectory():
    with pytest.raises(DnarodError, match=r"sequence .* gives 3 steps but the trajectory has 8"):
        StiffnessFit(chains(), 0.34, sequence="ACGT")


def test_empty_selection_and_too_few_samples():
    with pytest.raises(DnarodError, match="selects no frames"):
        StepAnalysis(chains(), 0.34).run(start=10)
    with pytest.raises(DnarodError, match=r"only 16 samples"):
        StiffnessFit(chains(n_frames=2), 0.34).run()


def test_dtraj_that_does_not_match_its_model(tmp_path):
    t = chains(n_steps=8)
    t.save(tmp_path / "run.dtraj")
    FF.model_from_sequence(n_nodes=12).save(tmp_path / "model.npz")
    with pytest.raises(DnarodError, match=r"9 nodes per frame but its topology .* has 12"):
        load_input(tmp_path / "run.dtraj", tmp_path / "model.npz")


def test_allatom_trajectory_that_does_not_match_its_topology(tmp_path):
    import MDAnalysis as mda

    from dnarod.structure.rebuild import rebuild_coordinates, write_pdb

    model = FF.model_from_sequence("ACGT")
    xyz, atoms = rebuild_coordinates(model.frames, model.positions, "ACGT")
    write_pdb(tmp_path / "small.pdb", xyz, atoms)
    u = mda.Universe(str(tmp_path / "small.pdb"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # no unit cell in the DCD
        with mda.Writer(str(tmp_path / "small.dcd"), u.atoms.n_atoms) as w:
            w.write(u.atoms)
    from dnarod.analysis.allatom import load_allatom

    with pytest.raises(StructureError, match="small.dcd"):
        load_allatom("data/allatom/355D_obc2_top.pdb", tmp_path / "small.dcd")


def test_topology_without_dna(tmp_path):
    from dnarod.analysis.allatom import load_allatom

    lines = [f"HETATM{i + 1:5d}  O   HOH A{i + 1:4d}    {i:8.3f}{0:8.3f}{0:8.3f}  1.00  0.00           O"
             for i in range(3)]
    (tmp_path / "water.pdb").write_text("\n".join(lines) + "\nEND\n")
    with pytest.raises(StructureError, match="no nucleic acid"):
        load_allatom(tmp_path / "water.pdb")


def test_cli_reports_bad_input_in_one_line(tmp_path):
    t = chains()
    t.save(tmp_path / "lin.dtraj")
    res = CliRunner().invoke(main, ["analyze", str(tmp_path / "lin.dtraj"), "--circular", "-o", str(tmp_path / "o")])
    assert res.exit_code == 2
    assert "dnarod: error: circular analysis of a chain that is not closed" in res.output
    assert "Traceback" not in res.output


def test_frame_strains_names_the_frame_with_a_rotation_beyond_pi():
    from dnarod.analysis.steps import frame_strains
    from dnarod.core.errors import GeometryError
    from dnarod.core.forcefield import load_forcefield
    from dnarod.core.rotations import rotation_about_axis

    m = load_forcefield("dna-default").model_from_sequence(n_nodes=6)
    pos = np.repeat(m.positions[None], 4, 0)
    frm = np.repeat(m.frames[None], 4, 0)
    frm[2, 3] = frm[2, 2] @ rotation_about_axis(np.array([1.0, 0.0, 0.0]), np.pi)
    with pytest.raises(GeometryError, match=r"trajectory frame 2: step 3 \(base pairs 3-4\)"):
        frame_strains(pos, frm, m.ds)
    Om, Ga = frame_strains(pos[[0, 1, 3]], frm[[0, 1, 3]], m.ds)
    assert Om.shape == (3, 5, 3) and np.allclose(Om, m.params.Omega0) and np.allclose(Ga, m.params.Gamma0)
