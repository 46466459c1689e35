"""All-atom trajectories: rebuilt atoms give the known node frames back; the bundled Amber
trajectory of the Dickerson dodecamer gives B-DNA-like step parameters."""
import warnings
from pathlib import Path

import numpy as np
import pytest

from dnarod.analysis import StepAnalysis, StiffnessFit, TangentCorrelation
from dnarod.analysis.allatom import load_allatom
from dnarod.physics.sampling import sample_chains
from dnarod.core.forcefield import load_forcefield
from dnarod.core.stepparams import to_angstrom_degrees
from dnarod.core.units import kT

DATA = Path(__file__).resolve().parent.parent / "data" / "allatom"
TOP = DATA / "355D_obc2_top.pdb"
DCD = DATA / "355D_obc2_100ps.dcd"


def test_rebuilt_atoms_give_the_frames_back(tmp_path):
    import MDAnalysis as mda

    from dnarod.structure.rebuild import rebuild_coordinates, write_pdb

    ff = load_forcefield("olson1998")
    seq = "GATTACAGC"
    traj = sample_chains(ff.step_parameters(seq), ff.ds, kT(300), 5, np.random.default_rng(3))
    xyz, atoms = rebuild_coordinates(traj.frames, traj.positions, seq)  # (5, n_atoms, 3) nm
    write_pdb(tmp_path / "top.pdb", xyz[0], atoms)
    u = mda.Universe(str(tmp_path / "top.pdb"))
    u.load_new(10.0 * xyz.astype(np.float32), order="fac")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with mda.Writer(str(tmp_path / "traj.dcd"), u.atoms.n_atoms) as w:
            for _ in u.trajectory:
                w.write(u.atoms)
    back, duplex = load_allatom(tmp_path / "top.pdb", tmp_path / "traj.dcd")
    assert duplex.sequence == seq and back.metadata["sequence"] == seq
    assert back.n_frames == 5 and back.n_nodes == len(seq)
    # float32 DCD coordinates (~1e-6 nm): frames and origins come back to that precision.
    assert np.abs(back.frames - traj.frames).max() < 1e-5
    assert np.abs(back.positions - traj.positions).max() < 1e-5
    # and the step parameters equal those of the known frames
    a = StepAnalysis(back, ff.ds, sequence=seq).run().results.step_parameters
    b = StepAnalysis(traj, ff.ds, sequence=seq).run().results.step_parameters
    assert np.abs(a - b).max() < 1e-5


@pytest.fixture(scope="module")
def bundled():
    if not DCD.exists():
        pytest.fail(f"bundled all-atom trajectory missing: run python data/make_allatom.py ({DCD})")
    traj, duplex = load_allatom(TOP, DCD)
    return traj, duplex


def test_bundled_allatom_trajectory_is_b_dna(bundled):
    traj, duplex = bundled
    assert duplex.sequence == "CGCGAATTCGCG"
    assert traj.n_frames >= 90 and traj.n_nodes == 12
    steps = StepAnalysis(traj, 0.34, sequence=duplex.sequence).run()
    p = to_angstrom_degrees(steps.results.step_parameters[:, 1:-1])  # inner steps (frayed ends left out)
    rise, twist = p[..., 2].mean(), p[..., 5].mean()
    assert 3.2 <= rise <= 3.5, rise
    assert 30.0 <= twist <= 38.0, twist
    # fluctuations are thermal, not a broken duplex
    assert p[..., 5].std() < 8.0 and p[..., 2].std() < 0.5


def test_bundled_allatom_stiffness_and_tangent_correlation(bundled):
    traj, duplex = bundled
    fit = StiffnessFit(traj, 0.34, 300.0, sequence=duplex.sequence, exclude_ends=1).run()
    pooled = fit.results.types["*"]
    assert pooled["n_samples"] == traj.n_frames * 9
    assert np.linalg.eigvalsh(pooled["stiffness"]).min() > 0
    # the reweighted intrinsic twist is B-DNA-like: 2 tan(theta/2)/ds with theta 30-38 deg
    theta = np.degrees(2 * np.arctan(0.34 * pooled["mean"][2] / 2))
    assert 30 < theta < 38
    tc = TangentCorrelation(traj, 0.34, exclude_ends=1).run()
    assert np.all(tc.results.correlation[1:] < 1) and tc.results.correlation[1] > 0.9


def test_other_formats_gro_topology_and_xtc_trajectory(bundled, tmp_path):
    """Any MDAnalysis format: the bundled run converted to GRO + XTC gives the same step parameters."""
    import MDAnalysis as mda

    traj, duplex = bundled
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # MDAnalysis notices (DCD timestep copies, no unit cell)
        u = mda.Universe(str(TOP), str(DCD))
        u.atoms.write(str(tmp_path / "top.gro"))
        with mda.Writer(str(tmp_path / "traj.xtc"), u.atoms.n_atoms) as w:
            for _ in u.trajectory[:20]:
                w.write(u.atoms)
    other, d2 = load_allatom(tmp_path / "top.gro", tmp_path / "traj.xtc")
    assert d2.sequence == duplex.sequence and other.n_frames == 20
    a = to_angstrom_degrees(StepAnalysis(other, 0.34).run().results.step_parameters)
    b = to_angstrom_degrees(StepAnalysis(traj[:20], 0.34).run().results.step_parameters)
    # XTC stores 0.01 Angstrom: parameters agree to that precision
    assert np.abs(a[..., :3] - b[..., :3]).max() < 0.05 and np.abs(a[..., 3:] - b[..., 3:]).max() < 0.5
