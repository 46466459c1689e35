"""Left-handed DNA in 3DNA's convention: the ideal Z fibre and a B-Z junction.

The Z-DNA fibre is built from 3DNA's own repeat unit of fibre model 15 (``data/structures/
fiber_models/str15``, poly d(GC):poly d(GC), Chandrasekaran & Arnott), repeated by the screw
its README gives: twist -60 degrees and rise 7.25 A per dinucleotide. 3DNA reports Z-DNA with
positive rise and negative twist (Lu & Olson 2003): with its reversed base-pair frames the two
steps of a repeat compose to exactly that screw. A B-Z junction is built by continuing strand
I of the Z fibre with B-DNA placed by a chosen junction step; 3DNA's junction rule must give
that step back.
"""
import csv
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.core.conversion import strains_to_step_parameters
from dnarod.core.stepparams import from_angstrom_degrees, step_parameters, step_transform, to_angstrom_degrees
from dnarod.structure.analysis import analyze_structure, step_parameters_over_frames
from dnarod.structure.bpparams import pair_parameters
from dnarod.structure.builders import model_from_structure
from dnarod.structure.conventions import REVERSE
from dnarod.structure.frames import base_frames
from dnarod.structure.rebuild import pdb_string, rebuild_coordinates, rebuild_model

DATA = Path(__file__).resolve().parents[1] / "data"
STR15 = DATA / "structures" / "fiber_models" / "str15"
TWIST, RISE = -60.0, 7.25  # degrees, A per repeat: 3DNA fibre README, structure 15 (Z-DNA)


def _unit(name):
    out = []
    for ln in (STR15 / name).read_text().splitlines():
        if ln.startswith("ATOM"):
            xyz = np.array([float(ln[30:38]), float(ln[38:46]), float(ln[46:54])])
            out.append((ln[12:16].strip(), ln[17:20].strip(), int(ln[22:26]), xyz))
    return out


def _screw(x, k):
    t = np.radians(TWIST * k)
    c, s = np.cos(t), np.sin(t)
    return np.array([c * x[0] - s * x[1], s * x[0] + c * x[1], x[2] + RISE * k])


def z_fibre(n_units=5):
    """PDB text of a Z-DNA fibre of ``2 n_units`` base pairs (strand I chain A, strand II chain B)."""
    lines = []

    def add(chain, resnum, resname, atom, x):
        lines.append(f"ATOM  {len(lines) + 1:5d} {atom:<4s} {'D' + resname:>3s} {chain}{resnum:4d}    "
                     f"{x[0]:8.3f}{x[1]:8.3f}{x[2]:8.3f}  1.00  0.00           {atom[0]}")

    for chain, unit, units in (("A", _unit("S1.pdb"), reversed(range(n_units))),  # strand I runs down the axis
                               ("B", _unit("S2.pdb"), range(n_units))):           # strand II (dyad image) up
        r = 0
        for k in units:
            for num in (1, 2):
                r += 1
                for atom, resname, rnum, x in unit:
                    if rnum == num:
                        add(chain, r, resname, atom, _screw(x, k))
    return "\n".join(lines) + "\nEND\n"


JUNCTION = (0.0, -1.0, 3.4, 0.0, -7.0, -17.0)  # A, degrees: a B-Z junction step like 3DNA's in the issue


def bz_junction(n_units=3, b_seq="ATGCAT"):
    """Z fibre continued along strand I by B-DNA (chains C/D) placed by ``JUNCTION`` from the last Z pair."""
    ztxt = z_fibre(n_units)
    z = analyze_structure(text=ztxt).duplexes[0]
    M, o = z.bp_frames[-1], z.bp_origins[-1]  # 3DNA's reversed frame of the last Z pair: z along strand I
    F, O = [], []
    for p in [JUNCTION] + [(0.0, 0.0, 3.38, 0.0, 0.0, 36.0)] * (len(b_seq) - 1):
        R, t = step_transform(from_angstrom_degrees(np.array(p)))
        o, M = o + M @ t, M @ R
        F.append(M)
        O.append(o)
    xyz, atoms = rebuild_coordinates(np.array(F), np.array(O), b_seq)
    atoms = [("C" if a[0] == "A" else "D", *a[1:]) for a in atoms]
    blines = [ln for ln in pdb_string(xyz, atoms).splitlines() if ln.startswith("ATOM")]
    return "\n".join([ln for ln in ztxt.splitlines() if ln.startswith("ATOM")] + blines) + "\nEND\n"


@pytest.fixture(scope="module")
def zdna():
    return analyze_structure(text=z_fibre(5))


@pytest.fixture(scope="module")
def bz():
    return analyze_structure(text=bz_junction())


def test_z_fibre_reads_left_handed_with_positive_rise(zdna):
    assert [d.n_bp for d in zdna.duplexes] == [10]
    d = zdna.duplexes[0]
    assert d.bp_labels == ["G-C", "C-G"] * 5 and d.names == ["WC"] * 10
    assert d.frames_reversed and d.bp_reversed.all()
    sp = to_angstrom_degrees(d.step_params)
    assert (sp[:, 2] > 3.4).all() and (sp[:, 5] < 0).all()
    # the two steps of every repeat compose to the fibre's screw: -60 degrees about the helix axis, +7.25 A along it
    for k in range(0, 8, 2):
        R1, t1 = step_transform(d.step_params[k])
        R2, t2 = step_transform(d.step_params[k + 1])
        R, t = R1 @ R2, t1 + R1 @ t2
        ang = np.degrees(np.arccos((np.trace(R) - 1) / 2))
        axis = np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
        axis /= np.linalg.norm(axis)
        if axis[2] < 0:
            axis, ang = -axis, -ang
        assert abs(ang - TWIST) < 0.05 and abs(10 * (t @ axis) - RISE) < 0.01
    # GpC and CpG alternate, as in Z-DNA (twist about -51 and -9 degrees, slide about -2 and +6 A)
    assert np.allclose(sp[0::2], sp[0], atol=0.02) and np.allclose(sp[1::2], sp[1], atol=0.02)
    assert sp[0, 5] < -45 and -15 < sp[1, 5] < 0 and sp[0, 1] < 0 < sp[1, 1]
    assert any("left-handed (Z-DNA)" in s for s in zdna.skipped)


def test_z_reversal_is_a_half_turn_about_y(zdna):
    """Without the reversal the same frames give the sign-flipped steps (rise about -3.6 A, twist positive): the
    reported frames are the fitted ones turned by 180 degrees about their y axis."""
    d = zdna.duplexes[0]
    nts = d.strand1 + d.strand2
    F, O, _ = base_frames(nts)
    n = d.n_bp
    bp, mid, morg = pair_parameters(F[:n], O[:n], F[n:], O[n:])
    assert np.allclose(d.bp_frames, mid @ REVERSE, atol=1e-12)
    raw = step_parameters(mid[:-1], morg[:-1], mid[1:], morg[1:])
    assert np.allclose(raw * [-1, 1, -1, -1, 1, -1], d.step_params, atol=1e-10)
    assert np.allclose(bp * [-1, 1, -1, -1, 1, -1], d.bp_params, atol=1e-10)
    assert (raw[:, 2] < 0).all() and (raw[:, 5] > 0).all()


def test_bz_junction_step_as_3dna_computes_it(bz):
    assert [d.n_bp for d in bz.duplexes] == [12]  # one helix across the junction
    d = bz.duplexes[0]
    assert [nt.rid for nt in d.strand1] == [f"A:{k}" for k in range(1, 7)] + [f"C:{k}" for k in range(1, 7)]
    assert not d.frames_reversed
    sp = to_angstrom_degrees(d.step_params)
    zref = to_angstrom_degrees(analyze_structure(text=z_fibre(3)).duplexes[0].step_params)
    assert np.allclose(sp[:5], zref, atol=0.01)  # Z steps: both frames reversed for each
    assert np.allclose(sp[5], JUNCTION, atol=[0.01, 0.01, 0.01, 0.05, 0.05, 0.05])  # the junction step
    assert np.allclose(sp[6:], [0.0, 0.0, 3.38, 0.0, 0.0, 36.0], atol=[0.01, 0.01, 0.01, 0.05, 0.05, 0.05])
    assert d.step_flips.tolist() == [[True, True]] * 5 + [[True, False]] + [[False, False]] * 5
    assert d.bp_reversed.tolist() == [True] * 6 + [False] * 6
    notes = bz.skipped
    assert "duplex 1: left-handed (Z) steps 1-5: both base-pair frames reversed for these steps (3DNA's " \
           "convention: positive rise, negative twist)" in notes
    assert any(s.startswith("duplex 1: step 6 (A:6/B:1 to C:1/D:12) is a B-Z junction") for s in notes)


def test_bz_model_round_trip_and_runnable(bz, tmp_path):
    """A model built from the junction has node frames along the helix: its strains give back every step of the
    table, it rebuilds to the same steps, and the run checks accept its start pose."""
    from dnarod.run.api import check_start_pose

    d = bz.duplexes[0]
    m = model_from_structure(analysis=bz, intrinsic="structure")
    back = strains_to_step_parameters(m.params.intrinsic, m.ds)
    assert np.allclose(back, to_angstrom_degrees(d.step_params), atol=1e-6)
    assert "left-handed (Z-DNA) pairs A:1/B:6..A:6/B:1 (6 of 12)" in m.metadata["selection"]
    assert m.metadata["bp_reversed"] == [True] * 6 + [False] * 6
    check_start_pose(m, 300.0)  # the junction is a modest step, not a half turn
    xyz, atoms = rebuild_model(m)
    again = analyze_structure(text=pdb_string(xyz, atoms)).duplexes[0]
    assert np.allclose(to_angstrom_degrees(again.step_params), to_angstrom_degrees(d.step_params),
                       atol=[0.01, 0.01, 0.01, 0.05, 0.05, 0.05])
    p = tmp_path / "bz.pdb"
    p.write_text(bz_junction())
    res = CliRunner().invoke(main, ["build", str(p), "--intrinsic", "structure", "-o", str(tmp_path / "m.npz")])
    assert res.exit_code == 0, res.output
    assert "left-handed (Z-DNA) pairs" in res.output


def test_z_trajectory_keeps_the_convention(zdna):
    d = zdna.duplexes[0]
    coords = np.zeros((1, zdna.structure.n_atoms, 3))
    for nt in zdna.structure.nucleotides:
        for a, i in nt.atom_index.items():
            coords[0, i] = nt.atoms[a]
    sp, bp, frames, origins = step_parameters_over_frames(d, np.repeat(coords, 2, axis=0))
    assert np.allclose(sp[1], d.step_params, atol=1e-12) and np.allclose(bp[0], d.bp_params, atol=1e-12)
    assert np.allclose(frames[0], d.bp_frames, atol=1e-12)


def test_cli_steps_of_z_dna(tmp_path):
    p = tmp_path / "z.pdb"
    p.write_text(z_fibre(4))
    out = tmp_path / "s.csv"
    res = CliRunner().invoke(main, ["steps", str(p), "--csv", str(out)])
    assert res.exit_code == 0, res.output
    rows = list(csv.DictReader(open(out)))
    assert [int(r["step"]) for r in rows] == list(range(1, 8))
    assert all(float(r["rise_A"]) > 3.4 and float(r["twist_deg"]) < 0 for r in rows)
    assert all(float(r["Gamma3"]) > 0 for r in rows)  # strains along the helix too
    assert "left-handed (Z-DNA)" in res.output



def test_run_check_numbers_steps_from_one_without_a_wrong_hint():
    """The start-pose check of a run names a kinked step as the steps table does (from 1) and does not suggest a
    longer chain, which would not remove the kink."""
    from dnarod.core.errors import ParameterError
    from dnarod.core.rotations import rotation_about_axis
    from dnarod.run.api import check_start_pose

    m = model_from_structure(DATA / "structures" / "355D.pdb")
    R = rotation_about_axis(m.frames[5][:, 0], np.radians(160.0))
    p5 = m.positions[5].copy()
    m.positions[6:] = p5 + (m.positions[6:] - p5) @ R.T
    m.frames[6:] = R @ m.frames[6:]
    with pytest.raises(ParameterError) as exc:
        check_start_pose(m, 300.0)
    msg = str(exc.value)
    assert msg.startswith("step 6 (base pairs 6-7) of this 12-node chain")
    assert "use a longer chain" not in msg and "not cured by a longer chain" in msg
