"""Pairing and ordering: several duplexes, overhangs, mismatches, nicks, pair classes."""
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.core.forcefield import load_forcefield
from dnarod.structure.analysis import analyze_structure
from dnarod.structure.rebuild import rebuild_coordinates, write_pdb

DATA = Path(__file__).resolve().parents[1] / "data"
PDB355 = DATA / "structures" / "355D.pdb"
ATOMS = [ln for ln in PDB355.read_text().splitlines(keepends=True) if ln.startswith("ATOM")]


def test_two_duplexes_ordered_and_numbered(tmp_path):
    moved = []
    for ln in ATOMS:
        ch = {"A": "C", "B": "D"}[ln[21]]
        moved.append(ln[:21] + ch + ln[22:30] + f"{float(ln[30:38]) + 60.0:8.3f}" + ln[38:])
    p = tmp_path / "two.pdb"
    p.write_text("".join(moved + ATOMS))  # the moved copy comes first in the file
    ana = analyze_structure(p)
    assert [d.n_bp for d in ana.duplexes] == [12, 12]
    assert ana.duplexes[0].strand1[0].rid == "C:1" and ana.duplexes[1].strand1[0].rid == "A:1"
    assert np.allclose(ana.duplexes[0].step_params, ana.duplexes[1].step_params, atol=1e-9)
    out = tmp_path / "s.csv"
    res = CliRunner().invoke(main, ["steps", str(p), "--csv", str(out)])
    assert res.exit_code == 0
    steps = [ln.split(",")[0] for ln in out.read_text().splitlines()[1:]]
    assert steps == [str(k) for k in range(1, 23)]  # 11 steps per duplex, numbered along strand I


def test_overhangs_reported(tmp_path):
    keep = [ln for ln in ATOMS if not (ln[21] == "B" and int(ln[22:26]) in (23, 24))]
    p = tmp_path / "overhang.pdb"
    p.write_text("".join(keep))
    ana = analyze_structure(p)
    d = ana.duplexes[0]
    assert d.n_bp == 10 and d.strand1[0].rid == "A:3"
    assert any("unpaired" in s and "chain A: 1(C) 2(G)" in s for s in ana.skipped)
    full = analyze_structure(PDB355).duplexes[0]
    assert np.allclose(d.step_params, full.step_params[2:], atol=1e-12)


def test_mismatch_and_nick_in_rebuilt_duplex(tmp_path):
    ff = load_forcefield("dna-default")
    m = ff.model_from_sequence("GATCCGTAGCAT")
    seq2 = "CTAGTCATCGTA"  # complement of strand I except position 5 (C-T mismatch)
    xyz, atoms = rebuild_coordinates(m.frames, m.positions, m.sequence, sequence2=seq2)
    write_pdb(tmp_path / "mm.pdb", xyz, atoms)
    d = analyze_structure(tmp_path / "mm.pdb").duplexes[0]
    assert d.n_bp == 12 and d.bp_labels[4] == "C-T" and d.names[4] == "non-WC"
    assert d.names[:4] == ["WC"] * 4
    # nick strand I between residues 6 and 7 (no phosphate on 7, residues 7..12 in chain E): one duplex,
    # chained through strand II
    lines = (tmp_path / "mm.pdb").read_text().splitlines(keepends=True)
    nicked = [ln[:21] + "E" + ln[22:] if ln.startswith("ATOM") and ln[21] == "A" and int(ln[22:26]) > 6 else ln
              for ln in lines
              if not (ln.startswith("ATOM") and ln[21] == "A" and int(ln[22:26]) == 7 and ln[12:16].strip() in
                      ("P", "OP1", "OP2"))]
    (tmp_path / "nick.pdb").write_text("".join(nicked))
    ana = analyze_structure(tmp_path / "nick.pdb")
    assert [x.n_bp for x in ana.duplexes] == [12]
    assert np.allclose(ana.duplexes[0].step_params, d.step_params, atol=1e-9)
