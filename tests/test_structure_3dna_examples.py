"""3DNA's own four-way junction example (1EGK) and its three helices, against 3DNA v2.0's output.

``data/structures/3dna_examples/*.out`` are 3DNA's ``analyze`` output (see the README there).
The tests parse them and require the same pairs (chain:residue of strand I and II, in 3DNA's
order), the same pair classes, the same helix partition and step count (3DNA lists a step
row at every helix break and leaves it empty), the same hydrogen-bond lists and every
parameter within 0.02 A and 0.2 degrees.
"""
import csv
import re
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.core.stepparams import to_angstrom_degrees
from dnarod.structure import findpair as fp
from dnarod.structure.analysis import analyze_structure
from dnarod.structure.frames import base_frames, has_base_atoms
from dnarod.structure.reader import read_structure

DATA = Path(__file__).resolve().parents[1] / "data"
EX = DATA / "structures" / "3dna_examples"
TOL = np.array([0.02, 0.02, 0.02, 0.2, 0.2, 0.2])  # Angstrom, degrees
NAMES = ["h1", "h2", "h3", "1egk_ok"]
ROW = re.compile(r"\s*(\d+)\s+\(\s*[\d.]+\)\s+\S*>(\S):(\S+?)_:\[...\](.)(.)(...)(.)(.)\[...\]:(\S+?)_:(\S)<\S*"
                 r"\s+\(\s*[\d.]+\)\s+(\S)")


def parse_out(path):
    """Pairs, helix markers, H-bonds and parameter tables of a 3DNA ``analyze`` output file."""
    lines = Path(path).read_text().splitlines()
    k = next(i for i, ln in enumerate(lines) if ln.startswith("RMSD of the bases"))
    pairs = []
    for ln in lines[k + 3:]:
        m = ROW.match(ln)
        if not m:
            break
        pairs.append({"s1": f"{m.group(2)}:{m.group(3).strip('.')}", "s2": f"{m.group(10)}:{m.group(9).strip('.')}",
                      "sym": m.group(6), "helix_end": m.group(11) == "x"})

    def table(title):
        k = next(i for i, ln in enumerate(lines) if ln.startswith(title))
        rows = []
        for ln in lines[k + 2:]:
            if ln.strip().startswith("~") or ln.startswith("*"):
                break
            parts = ln.split()
            rows.append((parts[1], None if parts[2].startswith("--") else [float(v) for v in parts[2:8]]))
        return rows

    k = next(i for i, ln in enumerate(lines) if ln.startswith("Detailed H-bond"))
    hbonds = []
    for ln in lines[k + 1:]:
        if ln.startswith("*"):
            break
        hb = re.findall(r"(\S+) ([-*]) (\S+)\s+([\d.]+)", ln.split("]", 1)[1])
        hbonds.append(sorted((a, b, t, float(d)) for a, t, b, d in hb))
    return pairs, table("Local base-pair parameters"), table("Local base-pair step parameters"), hbonds


@pytest.fixture(scope="module", params=NAMES)
def case(request):
    name = request.param
    return name, analyze_structure(EX / f"{name}.pdb"), parse_out(EX / f"{name}.out")


def _partition(pairs):
    sizes, n = [], 0
    for p in pairs:
        n += 1
        if p["helix_end"]:
            sizes.append(n)
            n = 0
    return sizes + ([n] if n else [])


def test_pairs_strands_order_and_helices_as_3dna(case):
    name, ana, (pairs, _, steps, _) = case
    assert [d.n_bp for d in ana.duplexes] == _partition(pairs)
    assert [nt.rid for d in ana.duplexes for nt in d.strand1] == [p["s1"] for p in pairs]
    assert [nt.rid for d in ana.duplexes for nt in d.strand2] == [p["s2"] for p in pairs]
    # 3DNA lists one step row per consecutive pair of its listing and leaves the helix breaks empty
    n_steps = sum(d.n_bp - 1 for d in ana.duplexes)
    assert n_steps + len(ana.duplexes) - 1 == len(steps)
    assert n_steps == sum(1 for _, v in steps if v is not None)
    breaks = list(np.cumsum([d.n_bp for d in ana.duplexes])[:-1])
    assert [k + 1 for k, (_, v) in enumerate(steps) if v is None] == breaks


def test_parameters_within_3dna_precision(case):
    name, ana, (_, bp_ref, step_ref, _) = case
    bp = np.vstack([to_angstrom_degrees(d.bp_params) for d in ana.duplexes])
    assert np.all(np.abs(bp - np.array([v for _, v in bp_ref])) <= TOL)
    ours = [row for d in ana.duplexes for row in list(to_angstrom_degrees(d.step_params)) + [None]][:-1]
    assert len(ours) == len(step_ref)
    for k, (row, (label, ref)) in enumerate(zip(ours, step_ref)):
        assert (row is None) == (ref is None), k
        if ref is not None:
            assert np.all(np.abs(row - np.array(ref)) <= TOL), (k + 1, label, row, ref)
    labels = [lab for d in ana.duplexes for lab in d.step_labels + [None]][:-1]
    assert [lab for lab in labels if lab] == [lab for lab, v in step_ref if v is not None]


def _bases(path):
    st = read_structure(path)
    nts = [nt for nt in st.nucleotides if has_base_atoms(nt)]
    F, O, _ = base_frames(nts)
    return nts, fp.base_data(nts, F, O)


def test_pair_classes_and_hydrogen_bonds_as_3dna(case):
    """3DNA's class symbols (WC '-', WC geometry, normals antiparallel '-' / parallel '+') and its
    H-bond lists (atoms, donor-acceptor type, length at 0.01 A)."""
    name, ana, (pairs, _, _, hbonds) = case
    nts, bases = _bases(EX / f"{name}.pdb")
    helices = fp.assemble_helices(bases, fp.find_best_pairs(len(bases), fp.candidate_pairs(bases)))
    got = [(b, i, j) for h in helices for (i, j), b in zip(h.pairs, h.bpids)]
    for (bpid, i, j), p, ref in zip(got, pairs, hbonds):
        assert p["sym"][0] == ("-" if bpid == 2 else "*") and p["sym"][1] == ("-" if bpid > 0 else "*")
        z = bases[i].frame[:, 2] @ bases[j].frame[:, 2]
        assert p["sym"][2] == ("-" if z < 0 else "+")
        ours = sorted((a.replace("OP", "O") + "P" if a.startswith("OP") else a,
                       b.replace("OP", "O") + "P" if b.startswith("OP") else b, t, round(d, 2))
                      for a, b, d, t in fp.hydrogen_bonds(bases[i], bases[j]))
        if (name, nts[i].rid) == ("h3", "C:119"):  # N6-O4 3.6003 A: 3DNA v2.0 keeps it at its 3.6 A limit
            ref = [r for r in ref if r[:2] != ("N6", "O4")]
        assert [r[:3] for r in ours] == [r[:3] for r in ref], (nts[i].rid, ours, ref)
        assert np.allclose([r[3] for r in ours], [r[3] for r in ref], atol=0.011)


def test_h2_junction_steps_named_as_the_steps_table():
    """h2 (3DNA: "This structure seems to contain a B-Z junction"): its step 2 runs into a
    pair whose normals are parallel (A+A); 3DNA reverses that pair's frame for the step."""
    ana = analyze_structure(EX / "h2.pdb")
    notes = [s for s in ana.skipped if "B-Z junction" in s]
    assert notes == ["duplex 1: step 2 (B:44/B:40 to C:101/B:39) is a B-Z junction (right- to left-handed pair): "
                     "the second pair's frame is reversed for this step, as 3DNA computes it"]
    d = ana.duplexes[0]
    assert d.step_flips[1].tolist() == [False, True] and not d.step_flips[[0] + list(range(2, 13))].any()
    assert any("step 3 (C:101/B:39 to B:45/B:38): 3DNA reverses the frame of C:101/B:39" in s for s in ana.skipped)
    assert "duplex 1: strand I is not continuous (a nick, gap or change of chain) at steps 2-4; the helix " \
           "continues by stacking geometry" in ana.skipped


def test_cli_steps_numbering_of_the_junction(tmp_path):
    out = tmp_path / "s.csv"
    p = EX / "1egk_ok.pdb"
    res = CliRunner().invoke(main, ["steps", str(p), "--csv", str(out)])
    assert res.exit_code == 0, res.output
    rows = list(csv.DictReader(open(out)))
    assert [int(r["step"]) for r in rows] == list(range(1, 50))  # 18 + 13 + 18 steps, numbered along strand I
    ana = analyze_structure(p)
    assert [d.first_step for d in ana.duplexes] == [1, 19, 32]
    assert "step 20 (B:44/B:40 to C:101/B:39) is a B-Z junction" in res.output  # the note uses the same numbers
    res = CliRunner().invoke(main, ["steps", str(p), "--duplex", "2", "--csv", str(out)])
    assert res.exit_code == 0, res.output
    rows2 = list(csv.DictReader(open(out)))
    assert [int(r["step"]) for r in rows2] == list(range(19, 32))  # a step keeps its number with --duplex
    assert [r["twist_deg"] for r in rows2] == [r["twist_deg"] for r in rows[18:31]]


def test_polygon_overlap_area_against_a_grid():
    """The ring-overlap criterion's polygon intersection (non-convex polygons) against counting grid points."""
    a = np.array([[0.0, 0.0], [4.0, 0.0], [4.0, 3.0], [2.0, 1.0], [0.0, 3.0]])  # non-convex (notched)
    b = np.array([[1.0, -1.0], [3.5, 0.5], [1.5, 4.0]])
    g = np.linspace(-2, 6, 1601)
    X, Y = np.meshgrid(g, g)
    pts = np.stack([X.ravel(), Y.ravel()], axis=1)

    def inside(poly, p):
        c = np.zeros(len(p), dtype=bool)
        for k in range(len(poly)):
            (x1, y1), (x2, y2) = poly[k], poly[(k + 1) % len(poly)]
            cross = (y1 > p[:, 1]) != (y2 > p[:, 1])
            xint = x1 + (p[:, 1] - y1) * (x2 - x1) / np.where(y2 == y1, 1, y2 - y1)
            c ^= cross & (p[:, 0] < xint)
        return c

    grid = (inside(a, pts) & inside(b, pts)).sum() * (g[1] - g[0]) ** 2
    assert abs(fp.polygon_overlap_area(a, b) - grid) < 0.02
    assert abs(fp.polygon_overlap_area(a[::-1], b) - grid) < 0.02  # orientation does not matter
    assert fp.polygon_overlap_area(a, b + [10.0, 0.0]) == 0.0


def test_1kx5_one_helix_and_what_3dna_rules_alone_give():
    """1KX5: 3DNA's rules pair 146 of the 147 base pairs (I:53/J:-53 has no N/O contact within 4.0 A, as in
    3DNA v2.0's own run) and keep one helix across the gap; dnarod pairs it by its helix context and says so."""
    nts, bases = _bases(DATA / "structures" / "1KX5.pdb")
    found = fp.find_best_pairs(len(bases), fp.candidate_pairs(bases))
    helices = fp.assemble_helices(bases, found)
    assert [len(h.pairs) for h in helices] == [146]
    ids = {(nts[i].rid, nts[j].rid) for h in helices for i, j in h.pairs}
    assert ("I:53", "J:-53") not in ids and ("I:52", "J:-52") in ids and ("I:54", "J:-54") in ids
    ana = analyze_structure(DATA / "structures" / "1KX5.pdb")
    assert [d.n_bp for d in ana.duplexes] == [147] and ana.duplexes[0].step_params.shape == (146, 6)
    note = [s for s in ana.skipped if "I:53/J:-53" in s]
    assert len(note) == 1 and "3DNA's rules leave it unpaired" in note[0] and "4.20 A" in note[0]


def test_unstacked_steps_keep_their_numbers_and_build_refuses_them(tmp_path):
    """h2 steps 11 and 12 run into and out of a pair with parallel base normals (D:139/A:1, A+A): 3DNA's
    numbers, no strains (NaN) and a note in `steps`; `build` refuses the helix naming step 11."""
    p = EX / "h2.pdb"
    out = tmp_path / "s.csv"
    res = CliRunner().invoke(main, ["steps", str(p), "--csv", str(out)])
    assert res.exit_code == 0, res.output
    rows = list(csv.DictReader(open(out)))
    assert [int(r["step"]) for r in rows if r["Omega1_per_nm"] == "nan"] == [11, 12]
    assert float(rows[11]["tilt_deg"]) == pytest.approx(-170.00, abs=0.2)  # 3DNA: -170.00
    assert "note: step 11 (D:138/D:145 to D:139/A:1): the base-pair frames turn by 170 deg" in res.output
    res = CliRunner().invoke(main, ["build", str(p), "-o", str(tmp_path / "m.npz")])
    assert res.exit_code == 2 and "Traceback" not in res.output
    assert "dnarod: error:" in res.output and "step 11 (D:138/D:145 to D:139/A:1)" in res.output


def test_altloc_choice_that_3dna_would_not_make_is_noted(tmp_path):
    """3DNA keeps altloc A (alt_list 'A1'); dnarod keeps the most occupied conformer and says where they differ."""
    lines = (DATA / "structures" / "355D.pdb").read_text().splitlines(keepends=True)
    out = []
    for ln in lines:
        if ln.startswith("ATOM") and ln[21] == "A" and int(ln[22:26]) == 5:
            x = float(ln[30:38])
            out.append(ln[:16] + "A" + ln[17:54] + f"{0.3:6.2f}" + ln[60:])
            out.append(ln[:16] + "B" + ln[17:30] + f"{x + 0.2:8.3f}" + ln[38:54] + f"{0.7:6.2f}" + ln[60:])
        else:
            out.append(ln)
    p = tmp_path / "alt.pdb"
    p.write_text("".join(out))
    ana = analyze_structure(p)
    assert any(s.startswith("alternate locations: dnarod kept the most occupied conformer of A:5 (B of AB)")
               and "--altloc A" in s for s in ana.skipped)
    assert not any("alternate locations" in s for s in analyze_structure(p, altloc="A").skipped)
