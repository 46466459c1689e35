"""Reading: residue names, atom names, altlocs, models, hydrogens; bad inputs; mangled text."""
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from dnarod.cli.main import main
from dnarod.core.errors import DnarodError, StructureError
from dnarod.structure.analysis import analyze_structure
from dnarod.structure.reader import normalise_residue_name, read_structure

DATA = Path(__file__).resolve().parents[1] / "data"
PDB355 = DATA / "structures" / "355D.pdb"
LINES = PDB355.read_text().splitlines(keepends=True)
ATOMS = [ln for ln in LINES if ln.startswith("ATOM")]


def _write(tmp_path, lines, name="bad.pdb"):
    p = tmp_path / name
    p.write_text("".join(lines))
    return p


def _res(line):
    return line[21], int(line[22:26]), line[12:16].strip()


def test_residue_name_normalisation():
    assert normalise_residue_name("DA") == ("A", False)
    assert normalise_residue_name("  A") == ("A", False)
    assert normalise_residue_name("ADE") == ("A", False)
    assert normalise_residue_name("DA5") == ("A", False)
    assert normalise_residue_name("DT3") == ("T", False)
    assert normalise_residue_name("RU5") == ("U", False)
    assert normalise_residue_name("5CM") == ("C", True)  # from 3DNA's baselist
    assert normalise_residue_name("1MA") == ("A", True)
    assert normalise_residue_name("XYZ") is None
    assert normalise_residue_name("XYZ", {"XYZ": "C"}) == ("C", True)


def test_old_atom_names_and_modified_base():
    st = read_structure(DATA / "structures" / "355D.pdb")  # O5*, C1*, O1P
    atoms = st.nucleotides[1].atoms
    assert {"O5'", "C1'", "OP1", "OP2"} <= set(atoms) and not any("*" in a for a in atoms)
    m = read_structure(DATA / "structures" / "329D.pdb")
    mod = [nt for nt in m.nucleotides if nt.modified]
    assert mod and all(nt.resname == "5CM" and nt.base == "C" and nt.letter == "c" for nt in mod)
    assert "C7" not in mod[0].atoms or mod[0].base == "T"


def test_hydrogens_water_ignored_same_result(tmp_path):
    extra = []
    for ln in ATOMS[:40]:
        extra.append(ln)
        if ln[12:16].strip() == "C1*":  # a hydrogen on C1', as MD files have
            h = ln[:12] + " H1*" + ln[16:30] + f"{float(ln[30:38]) + 1.0:8.3f}" + ln[38:76] + " H\n"
            extra.append(h)
    water = "HETATM 9999  O   HOH C 100       1.000   2.000   3.000  1.00 10.00           O\n"
    text = "".join(extra + ATOMS[40:]) + water
    a = analyze_structure(text=text)
    b = analyze_structure(PDB355)
    assert np.allclose(a.duplexes[0].bp_params, b.duplexes[0].bp_params)
    assert any("hydrogen" in s for s in a.skipped) and any("water" in s for s in a.skipped)


def _shifted(line, dx, altloc, occ):
    x = float(line[30:38]) + dx
    return line[:16] + altloc + line[17:30] + f"{x:8.3f}" + line[38:54] + f"{occ:6.2f}" + line[60:]


def test_altlocs_choose_most_occupied_or_requested(tmp_path):
    out = []
    for ln in ATOMS:
        if _res(ln)[:2] == ("A", 5):
            out += [_shifted(ln, 0.0, "A", 0.7), _shifted(ln, 0.5, "B", 0.3)]
        else:
            out.append(ln)
    p = _write(tmp_path, out)
    ref = read_structure(PDB355).nucleotides[4].atoms["N1"]
    auto = read_structure(p).nucleotides[4].atoms["N1"]
    chosen_b = read_structure(p, altloc="B").nucleotides[4].atoms["N1"]
    assert np.allclose(auto, ref) and np.allclose(chosen_b - ref, [0.05, 0, 0], atol=1e-9)


def test_models_choose_one(tmp_path):
    body = [ln for ln in ATOMS]
    moved = [ln[:30] + f"{float(ln[30:38]) + 10.0:8.3f}" + ln[38:] for ln in ATOMS]
    p = _write(tmp_path, ["MODEL        1\n"] + body + ["ENDMDL\n", "MODEL        2\n"] + moved + ["ENDMDL\n", "END\n"])
    a = analyze_structure(p)
    b = analyze_structure(p, model=2)
    assert a.structure.n_models == 2
    assert np.allclose(b.duplexes[0].bp_origins - a.duplexes[0].bp_origins, [1.0, 0, 0], atol=1e-9)
    with pytest.raises(StructureError, match="model 3 does not exist"):
        read_structure(p, model=3)


def test_gzipped_pdb(tmp_path):
    import gzip

    with gzip.open(tmp_path / "355D.pdb.gz", "wt") as fh:
        fh.write(PDB355.read_text())
    a = analyze_structure(tmp_path / "355D.pdb.gz")
    assert np.allclose(a.duplexes[0].step_params, analyze_structure(PDB355).duplexes[0].step_params)


def test_mmcif_reads_like_pdb(tmp_path):
    import gemmi

    s = gemmi.read_structure(str(PDB355))
    s.setup_entities()
    p = tmp_path / "355D.cif"
    s.make_mmcif_document().write_file(str(p))
    a = analyze_structure(p)
    b = analyze_structure(PDB355)
    assert np.allclose(a.duplexes[0].step_params, b.duplexes[0].step_params, atol=1e-9)


# --- bad inputs: each a clear StructureError naming file (and chain/residue), and CLI exit 2 -------------

def _bad_inputs(tmp_path):
    cases = {}
    cases["empty"] = (_write(tmp_path, [], "empty.pdb"), ["empty"])
    cut = "".join(LINES)
    cut = cut[:cut.index("ATOM    300")] + "ATOM    300  C4 "
    (tmp_path / "truncated.pdb").write_text(cut)
    cases["truncated"] = (tmp_path / "truncated.pdb", ["truncated"])
    rng = np.random.default_rng(1)
    (tmp_path / "garbage.pdb").write_bytes(bytes(rng.integers(0, 256, 3000, dtype=np.uint8)))
    cases["binary"] = (tmp_path / "garbage.pdb", ["binary"])
    prot = [ln for ln in (DATA / "structures" / "1CGP.pdb").read_text().splitlines(keepends=True)
            if ln.startswith("ATOM") and ln[21] == "A" and ln[17:20] != "CMP"]
    cases["no nucleic acid"] = (_write(tmp_path, prot, "protein.pdb"), ["no nucleic acid"])
    cases["single strand"] = (_write(tmp_path, [ln for ln in ATOMS if ln[21] == "A"], "single.pdb"),
                              ["no base pairs", "chain A"])
    few = [ln for ln in ATOMS if not (_res(ln)[:2] == ("A", 5) and _res(ln)[2] in ("C2", "N3", "C4", "C5", "C6",
                                                                                     "N7", "C8"))]
    cases["few ring atoms"] = (_write(tmp_path, few, "few.pdb"), ["too few base ring atoms", "chain A residue 5"])
    unk = [ln[:17] + "XYZ" + ln[20:] if _res(ln)[:2] == ("A", 6) else ln for ln in ATOMS]
    cases["unknown residue"] = (_write(tmp_path, unk, "unknown.pdb"), ["unknown residue", "chain A residue 6"])
    dup = []
    for ln in ATOMS:
        dup.append(ln)
        if _res(ln) == ("A", 7, "N3"):
            dup.append(ln)
    cases["duplicate atom"] = (_write(tmp_path, dup, "dup.pdb"), ["duplicate atom N3", "chain A residue 7"])
    alt = []
    for ln in ATOMS:
        if _res(ln) == ("B", 20, "C2"):
            alt += [_shifted(ln, 0.0, "A", 1.0), _shifted(ln, 0.3, "B", 1.0)]
        else:
            alt.append(ln)
    cases["conflicting altlocs"] = (_write(tmp_path, alt, "alt.pdb"), ["conflicting altlocs", "chain B residue 20"])
    copy = [ln[:21] + "C" + ln[22:] for ln in ATOMS if ln[21] == "B"]
    cases["paired twice"] = (_write(tmp_path, ATOMS + copy, "twice.pdb"), ["paired twice", "chain A residue"])
    return cases


BAD = ["empty", "truncated", "binary", "no nucleic acid", "single strand", "few ring atoms", "unknown residue",
       "duplicate atom", "conflicting altlocs", "paired twice"]


@pytest.mark.parametrize("kind", BAD)
def test_bad_input_clear_error(tmp_path, kind):
    path, words = _bad_inputs(tmp_path)[kind]
    with pytest.raises(StructureError) as exc:
        analyze_structure(path)
    msg = str(exc.value)
    assert str(path) in msg
    for w in words:
        assert w in msg, msg
    for cmd in ("steps", "pairs"):
        res = CliRunner().invoke(main, [cmd, str(path)])
        assert res.exit_code == 2, (cmd, res.output)
        assert "dnarod: error:" in res.output and str(path) in res.output and "Traceback" not in res.output


def test_explicit_pairs_paired_twice_and_unknown(tmp_path):
    with pytest.raises(StructureError, match=r"chain A residue 1 \(C\) is paired twice"):
        analyze_structure(PDB355, pairs=[("A:1", "B:24"), ("A:1", "B:23")])
    with pytest.raises(StructureError, match="no nucleotide 'Q:9'"):
        analyze_structure(PDB355, pairs=[("Q:9", "B:24")])
    f = tmp_path / "pairs.txt"
    f.write_text("A:1 B:24\nA:2 B:24\n")
    res = CliRunner().invoke(main, ["pairs", str(PDB355), "--pairs", str(f)])
    assert res.exit_code == 2 and "paired twice" in res.output
    f.write_text("# explicit\nA:1 B:24\nA:2 B:23\nA:3 B:22\n")
    ana = analyze_structure(PDB355, pairs=[("A:1", "B:24"), ("A:2", "B:23"), ("A:3", "B:22")])
    geo = analyze_structure(PDB355).duplexes[0]
    assert np.allclose(ana.duplexes[0].step_params, geo.step_params[:2])


def test_unknown_residue_can_be_mapped_or_ignored(tmp_path):
    unk = [ln[:17] + "XYZ" + ln[20:] if _res(ln)[:2] == ("A", 6) else ln for ln in ATOMS]
    p = _write(tmp_path, unk)
    a = analyze_structure(p, extra_residues={"XYZ": "A"})
    assert a.duplexes[0].bp_labels[5] == "a-T" and a.duplexes[0].n_bp == 12
    b = analyze_structure(p, ignore_residues=["XYZ"])
    assert sum(d.n_bp for d in b.duplexes) == 11
    res = CliRunner().invoke(main, ["pairs", str(p), "--map", "XYZ=A", "--csv", str(tmp_path / "o.csv")])
    assert res.exit_code == 0, res.output


# --- property-based: mangled PDB text never escapes as anything but a DnarodError ----------------------

SMALL = (DATA / "structures" / "2D94.pdb").read_text().splitlines(keepends=True)
SMALL = [ln for ln in SMALL if ln.startswith(("ATOM", "HETATM", "MODEL", "ENDMDL", "TER", "END"))][:400]


@st.composite
def mangled(draw):
    lines = list(SMALL)
    for _ in range(draw(st.integers(0, 12))):
        op = draw(st.sampled_from(["char", "delete", "duplicate", "truncate", "insert", "swap"]))
        i = draw(st.integers(0, len(lines) - 1))
        ln = lines[i]
        if op == "char" and ln:
            j = draw(st.integers(0, max(0, len(ln) - 1)))
            c = draw(st.characters(min_codepoint=1, max_codepoint=0x2FF))
            lines[i] = ln[:j] + c + ln[j + 1:]
        elif op == "delete":
            del lines[i]
        elif op == "duplicate":
            lines.insert(i, ln)
        elif op == "truncate":
            lines[i] = ln[:draw(st.integers(0, len(ln)))]
        elif op == "insert":
            lines.insert(i, draw(st.text(max_size=90)) + "\n")
        else:
            j = draw(st.integers(0, len(lines) - 1))
            lines[i], lines[j] = lines[j], lines[i]
        if not lines:
            break
    if draw(st.booleans()):
        text = "".join(lines)
        return text[:draw(st.integers(0, len(text)))]
    return "".join(lines)


def _check_mangled(text):
    try:
        ana = analyze_structure(text=text)
    except DnarodError:
        return
    for d in ana.duplexes:
        assert np.isfinite(d.bp_params).all() and np.isfinite(d.step_params).all()


HEALTH = [HealthCheck.too_slow, HealthCheck.data_too_large]


@settings(max_examples=200, deadline=None, suppress_health_check=HEALTH)
@given(mangled())
def test_mangled_pdb_text_only_raises_dnarod_errors(text):
    _check_mangled(text)


@pytest.mark.slow
@settings(max_examples=3000, deadline=None, suppress_health_check=HEALTH)
@given(mangled())
def test_mangled_pdb_text_only_raises_dnarod_errors_long(text):
    _check_mangled(text)


def test_non_ascii_names_are_a_clear_error():
    lines = list(ATOMS)
    lines[25] = lines[25][:25] + "\u00e9" + lines[25][26:]  # residue number field with a non-ASCII letter
    with pytest.raises(StructureError, match="non-ASCII"):
        analyze_structure(text="".join(lines))


def test_split_residue_blocks_are_merged_and_disordered_bases_skipped(tmp_path):
    lines = list(ATOMS)
    i = next(k for k, ln in enumerate(lines) if _res(ln) == ("A", 3, "N1"))
    lines.append(lines.pop(i))  # one atom of A:3 at the end of the file
    a = analyze_structure(text="".join(lines))
    assert np.allclose(a.duplexes[0].bp_params, analyze_structure(PDB355).duplexes[0].bp_params)
    base = {"N1", "C2", "N3", "C4", "C5", "C6", "N7", "C8", "N9", "O2", "O6", "N2", "N4", "N6", "O4", "C7", "C5M"}
    lines = [ln for ln in ATOMS if not (_res(ln)[:2] == ("B", 24) and _res(ln)[2] in base)]
    b = analyze_structure(text="".join(lines))
    assert b.duplexes[0].n_bp == 11 and any("no base atoms" in s and "B:24" in s for s in b.skipped)


def test_conflicting_altlocs_resolved_by_choosing_one(tmp_path):
    path, _ = _bad_inputs(tmp_path)["conflicting altlocs"]
    a = analyze_structure(path, altloc="A")
    b = analyze_structure(PDB355)
    assert np.allclose(a.duplexes[0].bp_params, b.duplexes[0].bp_params)
    res = CliRunner().invoke(main, ["steps", str(path), "--altloc", "B", "--csv", str(tmp_path / "s.csv")])
    assert res.exit_code == 0, res.output
