"""Nucleotide-like ligands (cAMP in 1CGP) vs modified nucleotides inside a chain (5CM, 8OG)."""
from pathlib import Path

import numpy as np
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.structure import model_from_structure
from dnarod.structure.analysis import analyze_structure
from dnarod.structure.reader import read_structure
from dnarod.structure.selection import choose_duplex

DATA = Path(__file__).resolve().parents[1] / "data" / "structures"
LINES = (DATA / "355D.pdb").read_text().splitlines(keepends=True)
CAMP = [ln[:72].rstrip() + "\n" for ln in (DATA / "1CGP.pdb").read_text().splitlines()
        if ln.startswith("HETATM") and ln[17:20] == "CMP" and ln[21] == "A"]


def _xyz(line):
    return np.array([float(line[30:38]), float(line[38:46]), float(line[46:54])])


def _atom_line(template, name, xyz, element):
    """A HETATM line with the template's residue fields, a new atom name and position (PDB columns)."""
    return (f"HETATM{template[6:11]} {name:<4}{template[16:30]}{xyz[0]:8.3f}{xyz[1]:8.3f}{xyz[2]:8.3f}"
            f"{template[54:66]}          {element:>2}\n")


def _with_cmp(chain_terminated):
    """355D with cAMP appended to chain A: after chain A's TER (a non-polymer entity), or without TER."""
    last_a = max(k for k, ln in enumerate(LINES) if ln.startswith("ATOM") and ln[21] == "A")
    cmp_lines = [ln[:21] + "A" + " 101" + ln[26:] for ln in CAMP]
    rest = LINES[last_a + 1:]
    if chain_terminated:
        ter = rest.index(next(ln for ln in rest if ln.startswith("TER")))
        return "".join(LINES[:last_a + 1] + rest[:ter + 1] + cmp_lines + rest[ter + 1:])
    return "".join(LINES[:last_a + 1] + cmp_lines + [ln for ln in rest if not (ln.startswith("TER") and ln[21] == "A")])


def _modified(res_edits):
    """355D with residues renamed to a modified nucleotide (HETATM) and the extra atom added.

    ``res_edits``: {(chain, number): (new name, added atom name, element, bond length A, ring atoms)}; the new
    atom sits in the base plane on the line from the centroid of ``ring atoms`` through the first of them.
    """
    out = []
    by_res = {}
    for ln in LINES:
        if ln.startswith(("ATOM", "HETATM")):
            by_res.setdefault((ln[21], int(ln[22:26])), []).append(ln)
    done = set()
    for ln in LINES:
        key = (ln[21], int(ln[22:26])) if ln.startswith(("ATOM", "HETATM")) else None
        if key in res_edits:
            name, atom, el, bond, ring = res_edits[key]
            out.append("HETATM" + ln[6:17] + f"{name:>3}" + ln[20:])
            if key not in done and ln is by_res[key][-1]:
                xyz = {r[12:16].strip(): _xyz(r) for r in by_res[key]}
                anchor = xyz[ring[0]]
                u = anchor - np.mean([xyz[a] for a in ring], axis=0)
                out.append(_atom_line(out[-1], atom, anchor + bond * u / np.linalg.norm(u), el))
                done.add(key)
        else:
            out.append(ln)
    return "".join(out)


def test_1cgp_camp_is_a_ligand_not_an_unpaired_nucleotide():
    a = analyze_structure(DATA / "1CGP.pdb")
    assert not any(nt.resname == "CMP" for nt in a.structure.nucleotides)
    assert not any("CMP" in line for line in a.skipped if line.startswith("unpaired"))
    lig = [line for line in a.skipped if "nucleotide-like ligand" in line]
    assert lig == ["ignored 2 nucleotide-like ligands not linked into a DNA/RNA chain (CMP A:1, CMP B:2)"]
    rep = choose_duplex(a).report()
    assert "2 nucleotide-like ligands" in rep and "(CMP A:1, CMP B:2)" in rep
    assert a.duplexes[0].n_bp == 30


def test_synthetic_camp_ligand_with_and_without_ter():
    ref = analyze_structure(DATA / "355D.pdb")
    for terminated in (True, False):
        a = analyze_structure(text=_with_cmp(terminated))
        assert [nt.rid for nt in a.structure.nucleotides] == [nt.rid for nt in ref.structure.nucleotides]
        assert any("(CMP A:101)" in line for line in a.skipped)
        assert not any(line.startswith("unpaired") for line in a.skipped)
        assert np.allclose(a.duplexes[0].step_params, ref.duplexes[0].step_params, atol=1e-12)


def test_linked_cmp_inside_a_chain_is_kept_as_a_nucleotide():
    """Classification is by linkage, not by name: a CMP residue bonded O3'-P into the chain stays a nucleotide."""
    text = _modified({("A", 6): ("CMP", "C8X", "C", 0.0, ("N9", "C8", "N7", "C5", "C4"))})
    text = "".join(ln for ln in text.splitlines(keepends=True) if " C8X" not in ln)  # rename only
    st = read_structure(text=text)
    nt = [x for x in st.nucleotides if x.rid == "A:6"][0]
    assert nt.resname == "CMP" and nt.base == "A" and nt.modified


def test_modified_nucleotides_in_the_chain_map_to_their_parent():
    """5-methyl-C (5CM, methyl C5A added) and 8-oxo-G (8OG, O8 added) keep the helix and its parameters."""
    ref = analyze_structure(DATA / "355D.pdb").duplexes[0]
    edits = {("A", 3): ("5CM", "C5A", "C", 1.50, ("C5", "N1", "C2", "N3", "C4", "C6")),
             ("B", 22): ("8OG", "O8", "O", 1.23, ("C8", "N9", "N7", "C5", "C4"))}
    text = _modified(edits)
    a = analyze_structure(text=text)
    assert len(a.duplexes) == 1
    d = a.duplexes[0]
    assert d.n_bp == 12 and [nt.rid for nt in d.strand1] == [nt.rid for nt in ref.strand1]
    assert np.allclose(d.step_params, ref.step_params, atol=1e-12)  # frames are fitted on ring atoms only
    assert np.allclose(d.bp_params, ref.bp_params, atol=1e-12)
    mods = {nt.rid: (nt.resname, nt.base) for nt in d.strand1 + d.strand2 if nt.modified}
    assert mods == {"A:3": ("5CM", "C"), "B:22": ("8OG", "G")}
    assert "C5A" in [x for x in d.strand1 if x.rid == "A:3"][0].atoms
    assert d.bp_labels[2] == "c-g" and all(lab.isupper() for k, lab in enumerate(d.bp_labels) if k != 2)
    note = "modified nucleotides modelled as their parent base: A:3 5CM->C, B:22 8OG->G"
    assert f"duplex 1: {note}" in a.skipped
    assert not any(line.startswith("unpaired") or "nucleotide-like" in line for line in a.skipped)
    sel = choose_duplex(a)
    assert note in sel.report()


def test_modified_nucleotides_model_and_cli(tmp_path):
    edits = {("A", 3): ("5CM", "C5A", "C", 1.50, ("C5", "N1", "C2", "N3", "C4", "C6"))}
    p = tmp_path / "m.pdb"
    p.write_text(_modified(edits))
    m = model_from_structure(p)
    ref = model_from_structure(DATA / "355D.pdb")
    assert m.sequence == ref.sequence == "CGCGAATTCGCG"
    assert np.allclose(m.positions, ref.positions, atol=1e-12)
    r = CliRunner().invoke(main, ["steps", str(p)])
    assert r.exit_code == 0 and "A:3 5CM->C" in r.output
