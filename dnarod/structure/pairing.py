"""Geometric base pairing and ordering of base pairs into duplexes.

Pairing follows the criteria of 3DNA's ``find_pair`` (Lu & Olson 2003, defaults of its
``misc_3dna.par``): two bases pair if their origins are within 1.5 nm, their vertical
separation along the mean normal is at most 0.25 nm, their normals differ by at most 65
degrees, the glycosidic N atoms (N9/N1) are at least 0.45 nm apart, and at least one
N/O...N/O base-base contact is within 0.4 nm. Each base takes its best partner (lowest
``d_org + 2 d_v + angle/20``, in Angstrom and degrees); pairs are the mutual best choices.
This is written here because gemmi/MDAnalysis/mdtraj do not detect base pairs with the
3DNA criteria that the reference tables were made with.

Ordering: pairs are chained through the backbone (O3'(i)-P(i+1) bonds, or consecutive
residues of a chain when the backbone is missing) along strand I, or along strand II where
strand I is nicked or bulged. Each chain of pairs is a duplex; strand I is the strand whose
5' end comes first in the file (3DNA's choice for the reference structures). Unpaired
nucleotides (overhangs, bulges, loops) are reported, not silently dropped.

Units: nm.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from ..errors import StructureError
from .reader import BACKBONE

MAX_ORIGIN = 1.5        # nm
MAX_VERTICAL = 0.25     # nm
MAX_ANGLE = 65.0        # degrees
MIN_GLYCOSIDIC = 0.45   # nm
MAX_HBOND = 0.40        # nm
LINK = 0.25             # nm, O3'-P bond cut-off
OVERLAP = 0.10          # nm: two bases with origins this close overlap (atoms closer than 1 A)
COMPLEMENT = {"A": "T", "T": "A", "G": "C", "C": "G", "U": "A", "I": "C"}


@dataclass
class Duplex:
    """An ordered run of base pairs.

    Attributes
    ----------
    pairs : list of (int, int)
        Nucleotide indices (strand I, strand II), 5'->3' along strand I.
    circular : bool
        True if the pairs close into a ring (the ring is opened at the first pair).
    """

    pairs: list
    circular: bool = False
    notes: list = field(default_factory=list)


def _glycosidic(nt):
    name = "N9" if nt.base in ("A", "G", "I") else "N1"
    return nt.atoms.get(name)


def _base_polar_atoms(nt):
    return np.array([xyz for name, xyz in nt.atoms.items()
                     if name not in BACKBONE and "'" not in name and name[:1] in ("N", "O")]).reshape(-1, 3)


def _pair_geometry(ni, nj, Fi, Fj, oi, oj, pi=None, pj=None, max_hbond=MAX_HBOND):
    """Score of a candidate pair (Angstrom/degrees, lower is better) or None if it fails a criterion."""
    d = oj - oi
    if np.linalg.norm(d) > MAX_ORIGIN:
        return None
    zi, zj = Fi[:, 2], Fj[:, 2]
    c = float(zi @ zj)
    angle = np.degrees(np.arccos(min(1.0, abs(c))))
    if angle > MAX_ANGLE:
        return None
    zm = zi + np.sign(c or 1.0) * zj
    zm /= np.linalg.norm(zm)
    dv = abs(float(d @ zm))
    if dv > MAX_VERTICAL:
        return None
    gi, gj = _glycosidic(ni), _glycosidic(nj)
    if gi is not None and gj is not None and np.linalg.norm(gi - gj) < MIN_GLYCOSIDIC:
        return None
    pi = _base_polar_atoms(ni) if pi is None else pi
    pj = _base_polar_atoms(nj) if pj is None else pj
    if len(pi) == 0 or len(pj) == 0:
        return None
    if not (np.linalg.norm(pi[:, None, :] - pj[None, :, :], axis=-1) <= max_hbond).any():
        return None
    return 10 * np.linalg.norm(d) + 20 * dv + angle / 20.0


def candidates(nucleotides, frames, origins):
    """All base pairs passing the geometric criteria.

    Returns
    -------
    dict
        ``(i, j) -> score`` for ``i < j`` (Angstrom/degree units, lower is better).
    """
    tree = cKDTree(origins)
    polar = [_base_polar_atoms(nt) for nt in nucleotides]
    out = {}
    for i, j in sorted(tree.query_pairs(MAX_ORIGIN)):
        score = _pair_geometry(nucleotides[i], nucleotides[j], frames[i], frames[j], origins[i], origins[j],
                               polar[i], polar[j])
        if score is not None:
            out[(i, j)] = score
    return out


def find_pairs(nucleotides, frames, origins, source="<structure>"):
    """Mutual-best base pairs.

    Parameters
    ----------
    nucleotides : list of Nucleotide
    frames : ndarray, shape (n, 3, 3)
        Base frames.
    origins : ndarray, shape (n, 3)
        Base origins, nm.
    source : str

    Returns
    -------
    list of (int, int)
        Unordered pairs ``(i, j)``, ``i < j``.

    Raises
    ------
    StructureError
        If a base would be paired twice: two candidate partners occupying the same place.
    """
    cand = candidates(nucleotides, frames, origins)
    best = {}
    for (i, j), s in cand.items():
        for a, b in ((i, j), (j, i)):
            if a not in best or s < best[a][1]:
                best[a] = (b, s)
    pairs = sorted((i, j) for i, (j, _) in best.items() if i < j and best.get(j, (None,))[0] == i)
    partners = {}
    for (i, j) in cand:
        partners.setdefault(i, []).append(j)
        partners.setdefault(j, []).append(i)
    for i, j in pairs:
        for a, b in ((i, j), (j, i)):
            for k in partners[a]:
                if k != b and np.linalg.norm(origins[k] - origins[b]) < OVERLAP:
                    na, nb, nk = nucleotides[a], nucleotides[b], nucleotides[k]
                    raise StructureError(
                        f"{source}: {na.label} is paired twice: with {nb.label} and with {nk.label}, which occupy "
                        f"the same place (a duplicated strand or unresolved altloc?); remove one copy or give the "
                        f"pairs explicitly")
    return pairs


def fill_helix_gaps(nucleotides, frames, origins, pairs, source="<structure>"):
    """Pair two unpaired bases that sit between consecutive pairs on both strands.

    A base pair inside a helix sometimes misses the N/O contact criterion only just (1KX5
    I:53/J:-53, 0.42 nm; 3DNA 2.0 left it out, 3DNA 2.4 pairs it). If nucleotide ``a`` lies
    between the strand-I bases of two pairs and ``b`` between their strand-II bases, ``a`` and
    ``b`` are paired when they pass every criterion with the contact cut-off relaxed to 0.45 nm.

    Returns
    -------
    pairs : list of (int, int)
        ``pairs`` plus the added ones.
    notes : list of str
    """
    next3, prev5 = backbone_links(nucleotides, origins)
    partner = {}
    for i, j in pairs:
        partner[i], partner[j] = j, i
    added, notes = [], []
    for a in range(len(nucleotides)):
        x, x3 = prev5[a], next3[a]
        if a in partner or x is None or x3 is None or x not in partner or x3 not in partner:
            continue
        y, y3 = partner[x], partner[x3]
        b = prev5[y]
        if b is None or b in partner or next3[y3] != b or b == a:
            continue
        if _pair_geometry(nucleotides[a], nucleotides[b], frames[a], frames[b], origins[a], origins[b],
                          max_hbond=MAX_HBOND + 0.05) is None:
            continue
        partner[a], partner[b] = b, a
        added.append((min(a, b), max(a, b)))
        notes.append(f"paired {nucleotides[a].rid}/{nucleotides[b].rid} by helix context (their closest N/O "
                     f"contact is over {10 * MAX_HBOND:.1f} A)")
    return sorted(pairs + added), notes


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


def order_duplexes(nucleotides, origins, pairs, source="<structure>"):
    """Chain pairs into duplexes ordered 5'->3' along strand I.

    Parameters
    ----------
    nucleotides : list of Nucleotide
    origins : ndarray, shape (n, 3)
        Base origins, nm (used for links without backbone atoms).
    pairs : list of (int, int)
    source : str

    Returns
    -------
    duplexes : list of Duplex
        Ordered by the file position of strand I's first base.
    skipped : list of str
        Unpaired nucleotides and other notes.
    """
    next3, prev5 = backbone_links(nucleotides, origins)
    partner = {}
    for i, j in pairs:
        partner[i], partner[j] = j, i

    def succ(node):
        x, y = node
        x3 = next3[x]
        if x3 is not None and x3 in partner and partner[x3] != x:
            return (x3, partner[x3])
        y5 = prev5[y]
        if y5 is not None and y5 in partner and partner[y5] != y:
            return (partner[y5], y5)
        return None

    nodes = [(i, j) for i, j in pairs] + [(j, i) for i, j in pairs]
    nxt = {nd: succ(nd) for nd in nodes}
    n_pred = {nd: 0 for nd in nodes}
    for nd, s in nxt.items():
        if s is not None:
            n_pred[s] += 1
    walks = []
    visited = set()

    def walk(start):
        out, nd = [], start
        while nd is not None and nd not in visited:
            visited.add(nd)
            out.append(nd)
            nd = nxt[nd]
        return out, nd == start

    for nd in sorted(nodes, key=lambda t: (t[0], t[1])):
        if n_pred[nd] == 0 and nd not in visited:
            walks.append(walk(nd))
    for nd in sorted(nodes, key=lambda t: (t[0], t[1])):
        if nd not in visited:  # rings of pairs (circular DNA)
            walks.append(walk(nd))
    walks.sort(key=lambda w: (w[0][0][0], -len(w[0])))
    claimed, duplexes = set(), []
    for w, circular in walks:
        kept = [nd for nd in w if frozenset(nd) not in claimed]
        if not kept:
            continue
        for nd in kept:
            claimed.add(frozenset(nd))
        notes = []
        if len(kept) < len(w):
            notes.append("part of this duplex was already assigned (branched pairing)")
        if circular:
            notes.append(f"circular: the ring of pairs is opened at {nucleotides[kept[0][0]].rid}")
        duplexes.append(Duplex(kept, circular=circular, notes=notes))
    paired = set(partner)
    unpaired = [nt for k, nt in enumerate(nucleotides) if k not in paired]
    skipped = []
    if unpaired:
        by_chain = {}
        for nt in unpaired:
            by_chain.setdefault(nt.chain, []).append(f"{nt.number}{nt.icode}({nt.resname})")
        for ch, items in by_chain.items():
            skipped.append(f"unpaired nucleotides (overhang, bulge, loop or single strand) in chain {ch}: "
                           f"{' '.join(items)}")
    return duplexes, skipped


def classify_pair(letter1, letter2, params):
    """Name of a base pair from its letters and parameters (nm, rad).

    ``"WC"`` (Watson-Crick: complementary, |shear| < 0.18 nm, |stretch| < 0.2 nm,
    |opening| < 60 deg), ``"wobble"`` (G-T/G-U with 0.1 < |shear| < 0.3 nm), else
    ``"non-WC"`` (mismatches, Hoogsteen and other geometries).
    """
    a, b = letter1.upper(), letter2.upper()
    shear, stretch, opening = params[0], params[1], params[5]
    if COMPLEMENT.get(a) == b or (a, b) in (("A", "U"), ("U", "A")):
        if abs(shear) < 0.18 and abs(stretch) < 0.2 and abs(np.degrees(opening)) < 60:
            return "WC"
    if {a, b} in ({"G", "T"}, {"G", "U"}) and 0.1 < abs(shear) < 0.3:
        return "wobble"
    return "non-WC"
