"""Pairing helpers built on 3DNA's rules: helix-context pairs, multiplets, explicit pairs, classes.

The pairs themselves and their ordering into helices follow 3DNA's ``find_pair``
(:mod:`dnarod.structure.findpair`). This module adds what dnarod does beyond those rules, each
reported in a note naming the residues:

* :func:`fill_helix_gaps`: a base pair inside a helix that misses 3DNA's N/O contact
  criterion (no base N/O atoms within 4.0 A, e.g. 1KX5 I:53/J:-53 at 4.2 A) but passes all
  its other criteria and stacks between paired neighbours is kept (3DNA would leave the two
  bases unpaired and step across them);
* :func:`multiplets`: base triples and G-tetrads (a G-quadruplex is refused);
* :func:`check_duplicated`: a base whose best partner has a copy in the same place (a
  duplicated strand or unresolved altloc) is refused;
* :func:`explicit_pairs`, :func:`classify_pair`, :func:`backbone_links` (unpaired nucleotides a
  step crosses, for the gap column).

Units: nm.
"""
from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from dnarod.core.errors import StructureError
from dnarod.structure.findpair import HELIX_BREAK, MAX_DV, check_pair
from dnarod.structure.reader import BACKBONE, COMPLEMENT

LINK = 0.25             # nm, O3'-P bond cut-off
OVERLAP = 0.10          # nm: two bases with origins this close overlap (atoms closer than 1 A)
HOOGSTEEN_CONTACT = 0.33  # nm: an N7...N/O hydrogen bond, with no N1 contact, marks a Hoogsteen pair
MAX_GAP = 3             # unpaired nucleotides a helix-context pair run or a flagged gap may span on a strand
MAX_HBOND = 0.40        # nm: 3DNA's hb_dist1, the N/O contact the helix-context pairs miss
MAX_ANGLE = 65.0        # degrees: 3DNA's max_plane_angle, also the stacking test of helix-context pairs
__all__ = ["HELIX_BREAK", "MAX_GAP", "backbone_links", "check_duplicated", "classify_pair", "explicit_pairs",
           "fill_helix_gaps", "is_mismatch", "multiplets"]


def _base_polar_atoms(nt):
    return np.array([xyz for name, xyz in nt.atoms.items()
                     if name not in BACKBONE and "'" not in name and name[:1] in ("N", "O")]).reshape(-1, 3)


def check_duplicated(nucleotides, bases, found, candidates, source="<structure>"):
    """Refuse a base whose chosen partner has a copy in the same place (a duplicated strand or altloc).

    Raises
    ------
    StructureError
        Naming the base and its two would-be partners.
    """
    origins = np.array([b.origin for b in bases])
    partners = {}
    for (i, j) in candidates:
        partners.setdefault(i, []).append(j)
        partners.setdefault(j, []).append(i)
    for i, j, _ in found:
        for a, b in ((i, j), (j, i)):
            for k in partners.get(a, ()):
                if k != b and np.linalg.norm(origins[k] - origins[b]) < OVERLAP:
                    na, nb, nk = nucleotides[a], nucleotides[b], nucleotides[k]
                    raise StructureError(
                        f"{source}: {na.label} is paired twice: with {nb.label} and with {nk.label}, which occupy "
                        f"the same place (a duplicated strand or unresolved altloc?); remove one copy or give the "
                        f"pairs explicitly")


def _pair_axis(frames, origins, a, b):
    """Approximate base-pair origin (nm) and helix axis of bases ``a`` (strand I) and ``b``."""
    za, zb = frames[a][:, 2], frames[b][:, 2]
    z = za - zb if za @ zb < 0 else za + zb
    return 0.5 * (origins[a] + origins[b]), z / np.linalg.norm(z)


def _stacks(frames, origins, p, q):
    """True if pair ``q`` stacks on pair ``p`` in 3DNA's helix sense: pair origins within
    ``HELIX_BREAK`` and helix axes within ``MAX_ANGLE`` of each other."""
    op, zp = _pair_axis(frames, origins, *p)
    oq, zq = _pair_axis(frames, origins, *q)
    return (np.linalg.norm(oq - op) <= HELIX_BREAK
            and np.degrees(np.arccos(min(1.0, abs(float(zp @ zq))))) <= MAX_ANGLE)


def _closest_contact(ni, nj):
    pi, pj = _base_polar_atoms(ni), _base_polar_atoms(nj)
    if len(pi) == 0 or len(pj) == 0:
        return float("inf")
    return float(np.linalg.norm(pi[:, None, :] - pj[None, :, :], axis=-1).min())


def fill_helix_gaps(nucleotides, bases, pairs, source="<structure>"):
    """Pairs of bases that sit between stacked pairs on both strands (helix context).

    A base pair inside a helix sometimes misses 3DNA's N/O contact criterion (1KX5
    I:53/J:-53, 4.2 A; a stretched pair in a distorted or thermal structure). If strand I has
    a run of ``k`` <= ``MAX_GAP`` unpaired nucleotides between the strand-I bases of two pairs
    and strand II a run of the same length between their strand-II bases (backbone-linked),
    the runs are paired in order when every new pair passes all of 3DNA's pair criteria
    except the N/O contact (origins, vertical separation, normals, glycosidic distance, no
    ring overlap) and stacks on its neighbours (pair origins within 3DNA's ``helix_break``
    0.75 nm, normals within 65 degrees). Iterated until nothing changes. 3DNA itself would
    leave these bases unpaired (its helix steps across them); the note says so.

    Parameters
    ----------
    nucleotides : list of Nucleotide
    bases : list of BaseData
        :func:`dnarod.structure.findpair.base_data`.
    pairs : list of (int, int)

    Returns
    -------
    added : list of (int, int)
        The new pairs, ``i < j``.
    notes : list of str
        One per added pair, naming the residues and their closest N/O contact.
    """
    frames = np.array([b.frame for b in bases])
    origins = np.array([b.origin for b in bases])
    next3, prev5 = backbone_links(nucleotides, origins)
    partner = {}
    for i, j in pairs:
        partner[i], partner[j] = j, i
    added, notes = [], []

    def run_after(x, limit=MAX_GAP):
        out, k = [], next3[x]
        while k is not None and k not in partner and len(out) <= limit:
            out.append(k)
            k = next3[k]
        return out, k

    changed = True
    while changed:
        changed = False
        for x in range(len(nucleotides)):
            if x not in partner or next3[x] is None or next3[x] in partner:
                continue
            run1, x3 = run_after(x)
            if x3 is None or not run1 or len(run1) > MAX_GAP or x3 not in partner:
                continue
            y, y3 = partner[x], partner[x3]
            run2, end = run_after(y3)
            if end != y or len(run2) != len(run1):
                continue
            new = list(zip(run1, reversed(run2)))
            ok = all(check_pair(bases[a], bases[b], need_hbond=False) is not None for a, b in new)
            chain = [(x, y)] + new + [(x3, y3)]
            if not ok or not all(_stacks(frames, origins, p, q) for p, q in zip(chain[:-1], chain[1:])):
                continue
            for a, b in new:
                partner[a], partner[b] = b, a
                added.append((min(a, b), max(a, b)))
                notes.append(f"paired {nucleotides[a].rid}/{nucleotides[b].rid} by helix context: stacked between "
                             f"paired neighbours, closest N/O contact "
                             f"{10 * _closest_contact(nucleotides[a], nucleotides[b]):.2f} A (cut-off "
                             f"{10 * MAX_HBOND:.1f} A); 3DNA's rules leave it unpaired and step across it")
            changed = True
    return added, notes


def multiplets(nucleotides, bases, cand, pairs, source="<structure>"):
    """Bases that pair with more than one base: base triples, G-tetrads, bifurcated pairs.

    Every candidate pair (3DNA's criteria, ``cand`` from
    :func:`dnarod.structure.findpair.candidate_pairs`) that involves a base of a chosen pair
    and a third base in the plane of that pair is collected; the connected groups of such
    bases are the multiplets.

    Returns
    -------
    notes : list of str
        One per multiplet, naming its residues.

    Raises
    ------
    StructureError
        For a G-tetrad (four guanines each pairing with two others, as in G-quadruplexes):
        dnarod's pairing would build a wrong double helix out of it.
    """
    frames = np.array([b.frame for b in bases])
    origins = np.array([b.origin for b in bases])
    chosen = {frozenset(p) for p in pairs}
    partner = {}
    for i, j in pairs:
        partner[i], partner[j] = j, i
    next3, prev5 = backbone_links(nucleotides, origins)

    def neighbours(k):
        return {m for m in (next3[k], prev5[k]) if m is not None}

    adj = {}
    for (i, j) in cand:
        if frozenset((i, j)) in chosen:
            continue
        for a, b in ((i, j), (j, i)):  # b would be a third base on the pair of a
            if a not in partner:
                continue
            pair = (a, partner[a])
            near = neighbours(a) | neighbours(partner[a])
            if b in near or (b in partner and partner[b] in near):
                continue  # a cross-strand contact with a stacked neighbour pair, not a multiplet
            o, z = _pair_axis(frames, origins, *pair)
            if abs(float((origins[b] - o) @ z)) > MAX_DV / 2:
                continue  # not in the plane of the pair
            adj.setdefault(a, set()).add(b)
            adj.setdefault(b, set()).add(a)
    seen, groups = set(), []
    for start in sorted(adj):
        if start in seen:
            continue
        stack, comp = [start], set()
        while stack:
            k = stack.pop()
            if k in comp:
                continue
            comp.add(k)
            stack.extend(adj.get(k, ()))
            if k in partner:
                stack.append(partner[k])
        seen |= comp
        groups.append(sorted(comp))
    notes = []
    for g in groups:
        ids = " ".join(nucleotides[k].rid for k in g)
        letters = "".join(nucleotides[k].base for k in g)
        ring = all(len(adj.get(k, ())) + (k in partner) >= 2 for k in g)
        if len(g) >= 4 and set(letters) == {"G"} and ring:
            raise StructureError(f"{source}: G-tetrad {ids}: each guanine pairs with two others (a G-quadruplex); "
                                 f"dnarod models double helices only. Give the pairs explicitly (--pairs) to force "
                                 f"a duplex, or remove the quadruplex")
        kind = "base triple (triplex or major-groove base?)" if len(g) == 3 else f"{len(g)}-base multiplet"
        notes.append(f"{kind}: {ids} ({letters}) pair with more than one base; the helix keeps the pairs "
                     f"{', '.join(f'{nucleotides[a].rid}/{nucleotides[b].rid}' for a, b in pairs if a in g and b in g) or 'none of them'}, "
                     f"the other contacts are left out")
    return notes


def explicit_pairs(nucleotides, pairs, source="<structure>"):
    """Validate user-given pairs ``[("A:1", "B:24"), ...]`` and return nucleotide indices.

    Raises
    ------
    StructureError
        For an unknown residue id or a residue paired twice.
    """
    by_id = {nt.rid: nt.index for nt in nucleotides}
    out, used = [], {}
    for a, b in pairs:
        idx = []
        for r in (a, b):
            r = str(r).strip()
            if r not in by_id:
                raise StructureError(f"{source}: pair ({a}, {b}): no nucleotide {r!r} (chain:number, e.g. A:1); "
                                     f"nucleotides are {nucleotides[0].rid}..{nucleotides[-1].rid}")
            if r in used:
                raise StructureError(f"{source}: {nucleotides[by_id[r]].label} is paired twice: in ({used[r][0]}, "
                                     f"{used[r][1]}) and ({a}, {b})")
            idx.append(by_id[r])
        if idx[0] == idx[1]:
            raise StructureError(f"{source}: pair ({a}, {b}) pairs a base with itself")
        used[str(a).strip()] = used[str(b).strip()] = (a, b)
        out.append((min(idx), max(idx)))
    return out


def backbone_links(nucleotides, origins):
    """3' neighbours: ``next3[i] = j`` if O3'(i)-P(j) is a bond, or else if j follows i in the
    same chain with consecutive numbers and stacked bases (origins within 0.8 nm: missing
    backbone atoms, or stretched links in rebuilt models)."""
    n = len(nucleotides)
    next3 = [None] * n
    p_idx = [k for k, nt in enumerate(nucleotides) if "P" in nt.atoms]
    if p_idx:
        tree = cKDTree(np.array([nucleotides[k].atoms["P"] for k in p_idx]))
    for i, nt in enumerate(nucleotides):
        if "O3'" in nt.atoms and p_idx:
            d, k = tree.query(nt.atoms["O3'"])
            if d < LINK and p_idx[k] != i:
                next3[i] = p_idx[k]
                continue
    bonded_to = set(j for j in next3 if j is not None)
    for i, nt in enumerate(nucleotides):
        if next3[i] is None and i + 1 < n and i + 1 not in bonded_to:
            nx = nucleotides[i + 1]
            if (nx.chain == nt.chain and nx.number == nt.number + 1
                    and np.linalg.norm(origins[i + 1] - origins[i]) < 0.8):
                next3[i] = i + 1
    prev5 = [None] * n
    for i, j in enumerate(next3):
        if j is not None and prev5[j] is None:
            prev5[j] = i
    return next3, prev5


def _hoogsteen(nt1, nt2):
    """True if a purine of the pair faces its partner with its N7 (Hoogsteen) edge, not N1."""
    for pur, other in ((nt1, nt2), (nt2, nt1)):
        if pur is None or other is None or pur.base not in ("A", "G", "I"):
            continue
        if "N1" not in pur.atoms or "N7" not in pur.atoms:
            continue
        polar = _base_polar_atoms(other)
        if len(polar) == 0:
            continue
        d1 = np.linalg.norm(polar - pur.atoms["N1"], axis=-1).min()
        d7 = np.linalg.norm(polar - pur.atoms["N7"], axis=-1).min()
        if d7 <= HOOGSTEEN_CONTACT < d1:
            return True
    return False


def classify_pair(letter1, letter2, params, nt1=None, nt2=None):
    """Name of a base pair from its letters and parameters (nm, rad).

    ``"Hoogsteen"`` (given the nucleotides: a purine's N7 edge, not its N1, faces the
    partner), ``"WC"`` (Watson-Crick: complementary, |shear| < 0.18 nm, |stretch| < 0.2 nm,
    |opening| < 60 deg), ``"wobble"`` (G-T/G-U with 0.1 < |shear| < 0.3 nm), else
    ``"non-WC"`` (mismatches and other geometries).
    """
    a, b = letter1.upper(), letter2.upper()
    shear, stretch, opening = params[0], params[1], params[5]
    if _hoogsteen(nt1, nt2):
        return "Hoogsteen"
    if COMPLEMENT.get(a) == b or (a, b) in (("A", "U"), ("U", "A")):
        if abs(shear) < 0.18 and abs(stretch) < 0.2 and abs(np.degrees(opening)) < 60:
            return "WC"
    if {a, b} in ({"G", "T"}, {"G", "U"}) and 0.1 < abs(shear) < 0.3:
        return "wobble"
    return "non-WC"


def is_mismatch(letter1, letter2):
    """True if two parent letters are not a Watson-Crick (or A-U) complement."""
    a, b = letter1.upper(), letter2.upper()
    return not (COMPLEMENT.get(a) == b or (a, b) in (("A", "U"), ("U", "A")))
