"""Base-pair and step parameters against 3DNA's own tables (355D, 2D94), and 1KX5 pairing."""
import csv
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.core.conversion import strains_to_step_parameters
from dnarod.core.stepparams import to_angstrom_degrees
from dnarod.core.strains import strains
from dnarod.structure.analysis import analyze_structure

DATA = Path(__file__).resolve().parents[1] / "data"
REFS = {"355D": "355D_3dna-v2.0", "2D94": "2D94_3dna-v1.4.0"}
BP_COLS = ["shear_A", "stretch_A", "stagger_A", "buckle_deg", "propeller_deg", "opening_deg"]
STEP_COLS = ["shift_A", "slide_A", "rise_A", "tilt_deg", "roll_deg", "twist_deg"]
TOL = np.array([0.02, 0.02, 0.02, 0.2, 0.2, 0.2])  # Angstrom, degrees


def _table(name):
    with open(DATA / "reference" / "3dna" / name) as fh:
        return list(csv.DictReader(fh))


@pytest.fixture(scope="module", params=sorted(REFS))
def case(request):
    pdb = request.param
    return pdb, analyze_structure(DATA / "structures" / f"{pdb}.pdb"), _table(f"{REFS[pdb]}_bp.csv"), \
        _table(f"{REFS[pdb]}_step.csv")


def test_pairs_and_order_match_3dna(case):
    _, ana, bp_ref, step_ref = case
    assert len(ana.duplexes) == 1
    d = ana.duplexes[0]
    assert d.bp_labels == [r["bp"] for r in bp_ref]
    assert [nt.rid for nt in d.strand1] == [f"{r['chain1']}:{r['resnum1']}" for r in bp_ref]
    assert [nt.rid for nt in d.strand2] == [f"{r['chain2']}:{r['resnum2']}" for r in bp_ref]
    assert d.step_labels == [r["step"] for r in step_ref]
    assert d.names == ["WC"] * d.n_bp


def test_bp_parameters_match_3dna(case):
    _, ana, bp_ref, _ = case
    ours = to_angstrom_degrees(ana.duplexes[0].bp_params)
    ref = np.array([[float(r[c]) for c in BP_COLS] for r in bp_ref])
    err = np.abs(ours - ref)
    assert (err <= TOL).all(), err.max(axis=0)


def test_step_parameters_match_3dna(case):
    _, ana, _, step_ref = case
    ours = to_angstrom_degrees(ana.duplexes[0].step_params)
    ref = np.array([[float(r[c]) for c in STEP_COLS] for r in step_ref])
    err = np.abs(ours - ref)
    assert (err <= TOL).all(), err.max(axis=0)


def test_bp_frames_are_rotations(case):
    _, ana, _, _ = case
    F = ana.duplexes[0].bp_frames
    assert np.allclose(np.swapaxes(F, -1, -2) @ F, np.eye(3), atol=1e-12)
    assert np.allclose(np.linalg.det(F), 1.0)


@pytest.mark.parametrize("pdb", sorted(REFS))
def test_cli_steps_csv_matches_3dna_and_strains(tmp_path, pdb):
    out = tmp_path / "steps.csv"
    res = CliRunner().invoke(main, ["steps", str(DATA / "structures" / f"{pdb}.pdb"), "--csv", str(out)])
    assert res.exit_code == 0, res.output
    rows = list(csv.DictReader(open(out)))
    assert list(rows[0]) == ["step", "bp1", "bp2", "shift_A", "slide_A", "rise_A", "tilt_deg", "roll_deg",
                             "twist_deg", "Omega1_per_nm", "Omega2_per_nm", "Omega3_per_nm", "Gamma1", "Gamma2",
                             "Gamma3", "gap"]
    ref = _table(f"{REFS[pdb]}_step.csv")
    assert [int(r["step"]) for r in rows] == list(range(1, len(ref) + 1))
    assert [f"{r['bp1']}/{r['bp2']}" for r in rows] == [
        f"{a['bp']}/{b['bp']}" for a, b in zip(_table(f"{REFS[pdb]}_bp.csv")[:-1], _table(f"{REFS[pdb]}_bp.csv")[1:])]
    ours = np.array([[float(r[c]) for c in STEP_COLS] for r in rows])
    want = np.array([[float(r[c]) for c in STEP_COLS] for r in ref])
    assert (np.abs(ours - want) <= TOL).all()
    # the strains are dnarod's map with ds = 0.34 nm: mapping them back gives the same step parameters
    xi = np.array([[float(r[c]) for c in ("Omega1_per_nm", "Omega2_per_nm", "Omega3_per_nm", "Gamma1", "Gamma2",
                                          "Gamma3")] for r in rows])
    back = strains_to_step_parameters(xi, 0.34)
    assert np.abs(back - ours).max() < 1e-3
    d = analyze_structure(DATA / "structures" / f"{pdb}.pdb").duplexes[0]
    Om, Ga = strains(d.bp_origins, d.bp_frames, 0.34)
    assert np.allclose(xi, np.hstack([Om, Ga]), atol=2e-6)


@pytest.mark.parametrize("pdb", sorted(REFS))
def test_cli_pairs_csv_matches_3dna(tmp_path, pdb):
    out = tmp_path / "pairs.csv"
    res = CliRunner().invoke(main, ["pairs", str(DATA / "structures" / f"{pdb}.pdb"), "--csv", str(out)])
    assert res.exit_code == 0, res.output
    rows = list(csv.DictReader(open(out)))
    assert list(rows[0]) == ["bp", "name"] + BP_COLS
    ref = _table(f"{REFS[pdb]}_bp.csv")
    assert [r["name"] for r in rows] == [r["bp"] for r in ref]
    assert [int(r["bp"]) for r in rows] == list(range(1, len(ref) + 1))
    err = np.abs(np.array([[float(r[c]) for c in BP_COLS] for r in rows])
                 - np.array([[float(r[c]) for c in BP_COLS] for r in ref]))
    assert (err <= TOL).all()


def test_cli_tables_are_readable():
    res = CliRunner().invoke(main, ["steps", str(DATA / "structures" / "355D.pdb")])
    assert res.exit_code == 0
    lines = res.output.splitlines()
    assert lines[0].startswith("# ") and "355D.pdb" in lines[0]
    body = [ln for ln in lines if not ln.startswith("#")]
    assert body[0].split()[:4] == ["step", "bp1", "bp2", "shift_A"] and len(body) == 12
    assert body[1].split()[:3] == ["1", "C-G", "G-C"] and body[1].split()[8] == "32.73"
    res = CliRunner().invoke(main, ["pairs", str(DATA / "structures" / "2D94.pdb")])
    assert res.exit_code == 0
    body = [ln for ln in res.output.splitlines() if not ln.startswith("#")]
    assert body[1].split() == ["1", "G-C", "-0.47", "-0.15", "-0.02", "-5.47", "-6.79", "-2.87", "A:1/B:8", "WC"]


def test_nucleosome_1kx5_one_duplex_of_147_bp():
    """3DNA 2.4.2 finds 147 bp in 1KX5 (old atom names O5*, C1*), strand I chain I from -73."""
    ana = analyze_structure(DATA / "structures" / "1KX5.pdb")
    assert [d.n_bp for d in ana.duplexes] == [147]
    d = ana.duplexes[0]
    assert (d.strand1[0].rid, d.strand2[0].rid, d.strand1[-1].rid, d.strand2[-1].rid) == ("I:-73", "J:73", "I:73",
                                                                                          "J:-73")
    assert d.names.count("WC") >= 140
    sp = to_angstrom_degrees(d.step_params)
    assert 3.2 < sp[:, 2].mean() < 3.5 and 33 < sp[:, 5].mean() < 37  # 10.2 bp/turn superhelical DNA
    assert any("I:53/J:-53" in s for s in ana.skipped)


def test_cap_complex_1cgp_skips_protein_and_ligands():
    ana = analyze_structure(DATA / "structures" / "1CGP.pdb")
    assert [d.n_bp for d in ana.duplexes] == [30]
    assert any("amino acid" in s for s in ana.skipped)
    assert any("unpaired" in s and "16(G)" in s for s in ana.skipped)
