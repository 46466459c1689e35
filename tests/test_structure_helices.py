"""Helices as 3DNA defines them: stretched pairs kept, helices across extruded bases, ambiguous pairing.

3DNA's rules (Lu & Olson 2003, Nucleic Acids Res. 31:5108; Lu & Olson 2008, Nat. Protoc. 3:1213;
defaults of 3DNA's misc_3dna.par): pairing is purely geometric; neighbouring pairs belong to one
helix when their origins are within ``helix_break`` = 7.5 A; the step between two pairs of a
helix is computed between those pairs whatever lies between them.
"""
import csv
from pathlib import Path

import gemmi
import numpy as np
import pytest
from click.testing import CliRunner
from scipy.optimize import minimize

from dnarod.cli.main import main
from dnarod.core.errors import StructureError
from dnarod.core.forcefield import load_forcefield
from dnarod.structure.analysis import analyze_structure
from dnarod.structure.frames import standard_bases
from dnarod.structure.pairing import HELIX_BREAK
from dnarod.structure.reader import BACKBONE
from dnarod.structure.rebuild import pdb_string, rebuild_coordinates

DATA = Path(__file__).resolve().parents[1] / "data"
KX5 = DATA / "structures" / "1KX5.pdb"


def _stretch_1kx5(path, k=70, shift_nm=0.25):
    """1KX5 with the strand-I base of pair k moved away from its partner along the pair's y axis."""
    d = analyze_structure(KX5).duplexes[0]
    rid, y = d.strand1[k].rid, d.bp_frames[k][:, 1]
    st = gemmi.read_structure(str(KX5))
    for ch in st[0]:
        for r in ch:
            if f"{ch.name}:{r.seqid.num}" == rid:
                for at in r:
                    n = at.name.replace("*", "'")
                    if "'" not in n and n not in BACKBONE:
                        at.pos = gemmi.Position(*(np.array(at.pos.tolist()) + 10 * shift_nm * y))
    st.setup_entities()
    st.write_pdb(str(path))
    return d, rid


def test_stretched_nucleosome_pair_keeps_one_helix(tmp_path):
    p = tmp_path / "stretched.pdb"
    ref, rid = _stretch_1kx5(p)
    ana = analyze_structure(p)
    assert [d.n_bp for d in ana.duplexes] == [147]
    note = [s for s in ana.skipped if s.startswith(f"paired {rid}/")]
    assert note and "helix context" in note[0]
    contact = float(note[0].split("contact ")[1].split(" A")[0])
    assert contact > 4.0  # past 3DNA's N/O contact cut-off: only the helix context keeps it
    d = ana.duplexes[0]
    assert np.abs(d.step_params[:, :3] - ref.step_params[:, :3]).max() > 0.1  # it did move (slide, > 1 A)
    assert abs(10 * (d.bp_params[70, 1] - ref.bp_params[70, 1]) - 2.5) < 0.3  # stretch +2.5 A
    out = tmp_path / "steps.csv"
    res = CliRunner().invoke(main, ["steps", str(p), "--csv", str(out)])
    assert res.exit_code == 0, res.output
    rows = list(csv.DictReader(open(out)))
    assert [int(r["step"]) for r in rows] == list(range(1, 147)) and all(r["gap"] == "" for r in rows)


def _ideal(n=12):
    m = load_forcefield("dna-default").model_from_sequence("GATCCGTAGCAT"[:n])
    xyz, atoms = rebuild_coordinates(m.frames, m.positions, m.sequence)
    return m, xyz, list(atoms)


def _extrude(xyz, atoms, after, before, out_nm=1.5, axis=None):
    """Insert an extruded copy of residue ``before`` between residues ``after`` and ``before``
    (backbone-linked through O3'-P) and renumber; returns new xyz, atoms."""
    def key(a):
        return (a[0], a[1])
    idx_after = [i for i, a in enumerate(atoms) if key(a) == after]
    idx_before = [i for i, a in enumerate(atoms) if key(a) == before]
    o3 = xyz[[i for i in idx_after if atoms[i][3] == "O3'"][0]]
    p_next = xyz[[i for i in idx_before if atoms[i][3] == "P"][0]]
    u = (p_next - o3) / np.linalg.norm(p_next - o3)
    new_xyz, new_atoms = [], []
    for i in idx_before:
        ch, num, rn, an, el = atoms[i]
        if an in ("P", "OP1", "OP2", "O3'"):
            v = {"P": o3 - 0.12 * u, "OP1": o3 - 0.12 * u + [0.1, 0.1, 0], "OP2": o3 - 0.12 * u - [0.1, 0.1, 0],
                 "O3'": p_next + 0.15 * u}[an]
        else:
            v = xyz[i] + out_nm * axis
        new_xyz.append(v)
        new_atoms.append((ch, num, rn, an, el))
    ch0, n0 = before
    ren = [(a[0], a[1] + 1 if a[0] == ch0 and a[1] >= n0 else a[1], *a[2:]) for a in atoms]
    k = idx_before[0]
    return (np.concatenate([xyz[:k], new_xyz, xyz[k:]]), ren[:k] + new_atoms + ren[k:])


def test_helix_continues_across_extruded_bases(tmp_path):
    m, xyz, atoms = _ideal()
    # one base extruded on each strand at the step between pairs 6 and 7 (as at a B-Z junction)
    x = m.frames[6][:, 0]
    xyz2, atoms2 = _extrude(xyz, atoms, ("A", 6), ("A", 7), axis=x)
    xyz2, atoms2 = _extrude(xyz2, atoms2, ("B", 18), ("B", 19), axis=x)  # strand II: pair 7 is B:18, pair 6 B:19
    p = tmp_path / "extruded.pdb"
    p.write_text(pdb_string(xyz2, atoms2))
    ana = analyze_structure(p)
    assert [d.n_bp for d in ana.duplexes] == [12]
    d = ana.duplexes[0]
    assert d.gaps[5] == "A:7 B:19" and all(g == "" for k, g in enumerate(d.gaps) if k != 5)
    ref = analyze_structure(text=pdb_string(xyz, atoms)).duplexes[0]
    assert np.allclose(d.step_params, ref.step_params, atol=1e-6)  # the gap step is the flanking pairs' step
    assert any("steps across unpaired A:7 B:19" in s for s in ana.skipped)
    out = tmp_path / "steps.csv"
    assert CliRunner().invoke(main, ["steps", str(p), "--csv", str(out)]).exit_code == 0
    rows = list(csv.DictReader(open(out)))
    assert len(rows) == 11 and rows[5]["gap"] == "A:7;B:19" and rows[4]["gap"] == ""


@pytest.mark.parametrize("shift, n_duplexes", [(0.3, 1), (0.6, 2)])
def test_helix_break_distance(tmp_path, shift, n_duplexes):
    """3DNA's helix_break: flanking pairs farther apart than 7.5 A end the helix."""
    m, xyz, atoms = _ideal()
    z = m.frames[6][:, 2]
    moved = np.array([(a[0] == "A" and a[1] >= 7) or (a[0] == "B" and a[1] <= 18) for a in atoms])
    xyz = xyz + shift * moved[:, None] * z
    x = m.frames[6][:, 0]
    xyz2, atoms2 = _extrude(xyz, atoms, ("A", 6), ("A", 7), axis=x)
    xyz2, atoms2 = _extrude(xyz2, atoms2, ("B", 18), ("B", 19), axis=x)
    ana = analyze_structure(text=pdb_string(xyz2, atoms2))
    dist = np.linalg.norm(m.positions[6] + shift * z - m.positions[5])
    assert (dist <= HELIX_BREAK) == (n_duplexes == 1)
    assert len(ana.duplexes) == n_duplexes


def test_single_strand_bulge_flagged(tmp_path):
    m, xyz, atoms = _ideal()
    xyz2, atoms2 = _extrude(xyz, atoms, ("A", 3), ("A", 4), axis=m.frames[3][:, 0])
    ana = analyze_structure(text=pdb_string(xyz2, atoms2))
    d = ana.duplexes[0]
    assert d.n_bp == 12 and d.gaps[2] == "A:4"


def _g_quadruplex(n_tetrads=3, rise=0.34, twist=30.0):
    """Stacked G-tetrads from the standard guanine (Hoogsteen N1...O6 and N2...N7 at 2.9 A)."""
    std, _ = standard_bases()
    g = {k: v for k, v in std["G"].items()}
    names = list(g)
    X = np.array([g[a] for a in names])

    def rot(t):
        c, s = np.cos(t), np.sin(t)
        return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])

    def place(c, k):
        return (X - c) @ rot(np.pi / 2 * k).T + c

    def cost(c2):
        c = np.array([c2[0], c2[1], 0.0])
        a, b = place(c, 0), place(c, 1)
        i = {n: k for k, n in enumerate(names)}
        return ((np.linalg.norm(a[i["N1"]] - b[i["O6"]]) - 0.29) ** 2
                + (np.linalg.norm(a[i["N2"]] - b[i["N7"]]) - 0.29) ** 2)

    c = minimize(cost, [0.3, -0.3]).x
    assert cost(c) < 1e-4
    c = np.array([c[0], c[1], 0.0])
    xyz, atoms = [], []
    for k in range(4):  # chain by chain (one strand per chain)
        for t in range(n_tetrads):
            R = rot(np.radians(twist * t))
            for a, v in zip(names, place(c, k)):
                xyz.append(R @ (v - c) + [0, 0, rise * t])
                atoms.append(("ABCD"[k], t + 1, "DG", a, a[0]))
    return np.array(xyz), atoms


def test_g_quadruplex_is_an_error_naming_the_tetrad():
    xyz, atoms = _g_quadruplex()
    with pytest.raises(StructureError, match=r"G-tetrad A:\d B:\d C:\d D:\d.*G-quadruplex"):
        analyze_structure(text=pdb_string(xyz, atoms))


def test_hoogsteen_and_mismatch_named(tmp_path):
    m, xyz, atoms = _ideal()
    seq2 = "CTAGTCATCGTA"  # partners of GATCCGTAGCAT position by position; position 5 (C) against T
    xyz, atoms = rebuild_coordinates(m.frames, m.positions, m.sequence, sequence2=seq2)
    # A:2 (A) flipped syn about its glycosidic bond and moved so its N7 faces T's N3 (a Hoogsteen pair)
    def res(ch, n):
        return [i for i, a in enumerate(atoms) if a[0] == ch and a[1] == n]
    ia = res("A", 2)
    names = {atoms[i][3]: i for i in ia}
    c1, n9 = xyz[names["C1'"]], xyz[names["N9"]]
    ax = (n9 - c1) / np.linalg.norm(n9 - c1)
    base = [i for i in ia if atoms[i][3] in standard_bases()[0]["A"] and atoms[i][3] != "C1'"]
    v = xyz[base] - n9
    xyz[base] = n9 + 2 * (v @ ax)[:, None] * ax - v  # rotation by 180 degrees about the axis
    it = {atoms[i][3]: i for i in res("B", 23)}
    d = xyz[it["N3"]] - xyz[names["N7"]]
    xyz[ia] += d - 0.29 * d / np.linalg.norm(d)
    ana = analyze_structure(text=pdb_string(xyz, atoms))
    dup = ana.duplexes[0]
    assert dup.names[1] == "Hoogsteen"
    note = [s for s in ana.skipped if "not Watson-Crick" in s][0]
    assert "A:2/B:23 A-T (Hoogsteen)" in note and "A:5/B:20 C-T (mismatch, non-WC)" in note


def test_duplex_option_and_selection_report(tmp_path):
    atoms = [ln for ln in (DATA / "structures" / "355D.pdb").read_text().splitlines(keepends=True)
             if ln.startswith("ATOM")]
    moved = [ln[:21] + {"A": "C", "B": "D"}[ln[21]] + ln[22:30] + f"{float(ln[30:38]) + 60.0:8.3f}" + ln[38:]
             for ln in atoms]
    keep = [ln for ln in moved if not (ln[21] == "D" and int(ln[22:26]) > 20)]  # second copy: 8 bp
    p = tmp_path / "two.pdb"
    p.write_text("".join(atoms + keep))
    out = tmp_path / "s.csv"
    res = CliRunner().invoke(main, ["steps", str(p), "--duplex", "2", "--csv", str(out)])
    assert res.exit_code == 0, res.output
    rows = list(csv.DictReader(open(out)))
    assert len(rows) == 7 and rows[0]["bp1"] == "A-T"  # C:5..C:12 (AATTCGCG) pair with D:20..D:13
    res = CliRunner().invoke(main, ["pairs", str(p), "--duplex", "3"])
    assert res.exit_code == 2 and "duplex 3 does not exist; found 2 (12 bp, 8 bp)" in res.output
    res = CliRunner().invoke(main, ["build", str(p), "--duplex", "2", "-o", str(tmp_path / "m.npz")])
    assert res.exit_code == 0, res.output
    assert "took duplex 2 of 2 (8 bp" in res.output and "dropped: duplex 1 (12 bp, A:1..A:12)" in res.output
    assert "unpaired nucleotides" in res.output and "chain C: 1(C) 2(G) 3(C) 4(G)" in res.output
    res = CliRunner().invoke(main, ["build", str(DATA / "structures" / "1CGP.pdb"), "-o", str(tmp_path / "c.npz")])
    assert res.exit_code == 0 and "amino acid" in res.output and "took duplex 1 of 1 (30 bp" in res.output
