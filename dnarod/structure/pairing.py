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

from dnarod.core.errors import StructureError
from dnarod.structure.reader import BACKBONE

MAX_ORIGIN = 1.5        # nm
MAX_VERTICAL = 0.25     # nm
MAX_ANGLE = 65.0        # degrees
MIN_GLYCOSIDIC = 0.45   # nm
MAX_HBOND = 0.40        # nm
LINK = 0.25             # nm, O3'-P bond cut-off
OVERLAP = 0.10          # nm: two bases with origins this close overlap (atoms closer than 1 A)
HELIX_BREAK = 0.75      # nm: 3DNA's helix_break, largest origin distance of neighbouring pairs in a helix
HOOGSTEEN_CONTACT = 0.33  # nm: an N7...N/O hydrogen bond, with no N1 contact, marks a Hoogsteen pair
MAX_GAP = 3             # unpaired nucleotides a helix may step across on a strand
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
    notes : list of str
    gaps : list of list of int
        Per step: unpaired nucleotides (indices) between its two pairs (3DNA's helix continues
        across them); empty for a regular step.
    """

    pairs: list
    circular: bool = False
    notes: list = field(default_factory=list)
    gaps: list = field(default_factory=list)


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


def fill_helix_gaps(nucleotides, frames, origins, pairs, source="<structure>"):
    """Pair bases that sit between stacked pairs on both strands (3DNA's helix context).

    A base pair inside a helix sometimes misses the N/O contact criterion (1KX5 I:53/J:-53,
    0.42 nm; a stretched pair in a distorted or thermal structure). If strand I has a run of
    ``k`` unpaired nucleotides between the strand-I bases of two pairs and strand II a run of
    the same length between their strand-II bases (backbone-linked), the runs are paired in
    order when every new pair passes all the pairing criteria except the N/O contact (origins,
    vertical separation, normals, glycosidic distance) and stacks on its neighbours (pair
    origins within 3DNA's ``helix_break`` 0.75 nm, axes within 65 degrees). Iterated until
    nothing changes.

    Returns
    -------
    pairs : list of (int, int)
        ``pairs`` plus the added ones.
    notes : list of str
        One per added pair, naming the residues and their closest N/O contact.
    """
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
            if x3 is None or not run1 or len(run1) > MAX_GAP:
                continue
            y, y3 = partner[x], partner[x3]
            run2, end = run_after(y3)
            if end != y or len(run2) != len(run1):
                continue
            new = list(zip(run1, reversed(run2)))
            ok = all(_pair_geometry(nucleotides[a], nucleotides[b], frames[a], frames[b], origins[a], origins[b],
                                    max_hbond=np.inf) is not None for a, b in new)
            chain = [(x, y)] + new + [(x3, y3)]
            if not ok or not all(_stacks(frames, origins, p, q) for p, q in zip(chain[:-1], chain[1:])):
                continue
            for a, b in new:
                partner[a], partner[b] = b, a
                added.append((min(a, b), max(a, b)))
                notes.append(f"paired {nucleotides[a].rid}/{nucleotides[b].rid} by helix context: stacked between "
                             f"paired neighbours, closest N/O contact "
                             f"{10 * _closest_contact(nucleotides[a], nucleotides[b]):.2f} A (cut-off "
                             f"{10 * MAX_HBOND:.1f} A)")
            changed = True
    return sorted(pairs + added), notes


def multiplets(nucleotides, frames, origins, pairs, source="<structure>"):
    """Bases that pair with more than one base: base triples, G-tetrads, bifurcated pairs.

    Every candidate pair (all criteria of :func:`candidates`) that involves a base of a chosen
    pair and a third base is collected; the connected groups of such bases are the multiplets.

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
    cand = candidates(nucleotides, frames, origins)
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
            if abs(float((origins[b] - o) @ z)) > MAX_VERTICAL / 2:
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


def order_duplexes(nucleotides, origins, pairs, source="<structure>", frames=None):
    """Chain pairs into duplexes ordered 5'->3' along strand I.

    Parameters
    ----------
    nucleotides : list of Nucleotide
    origins : ndarray, shape (n, 3)
        Base origins, nm (used for links without backbone atoms).
    pairs : list of (int, int)
    source : str
    frames : ndarray, shape (n, 3, 3), optional
        Base frames; with them a duplex continues across up to ``MAX_GAP`` unpaired
        nucleotides on each strand when the flanking pairs stack (3DNA's helix definition).

    Returns
    -------
    duplexes : list of Duplex
        ``Duplex.gaps[k]`` lists the unpaired nucleotides (indices) the step from pair ``k`` to
        ``k + 1`` steps across (empty for a regular step).
        Ordered by the file position of strand I's first base.
    skipped : list of str
        Unpaired nucleotides and other notes.
    """
    next3, prev5 = backbone_links(nucleotides, origins)
    partner = {}
    for i, j in pairs:
        partner[i], partner[j] = j, i

    def path(a, b, links=next3):
        """Unpaired nucleotides strictly between ``a`` and ``b`` along ``links`` (None if not reached)."""
        out, k = [], links[a]
        while k is not None and k != b and k not in partner and len(out) < MAX_GAP:
            out.append(k)
            k = links[k]
        return out if k == b else None

    def across_gap(x, y):
        # 3DNA's helix continues across extruded or unpaired bases when the flanking pairs stack;
        # here the strands must also lead there (at most MAX_GAP unpaired nucleotides on each strand).
        for start, links, strand1 in ((x, next3, True), (y, prev5, False)):
            k, skipped = links[start], 0
            while k is not None and k not in partner and skipped < MAX_GAP:
                k, skipped = links[k], skipped + 1
            if k is None or k not in partner or skipped == 0:
                continue
            nxt = (k, partner[k]) if strand1 else (partner[k], k)
            if frames is None or nxt[0] in (x, y) or nxt[1] in (x, y):
                continue
            other = path(nxt[1], y) if strand1 else path(x, nxt[0])
            nicked = (prev5[y] is None or next3[nxt[1]] is None) if strand1 else \
                (next3[x] is None or prev5[nxt[0]] is None)
            if other is None and not nicked:
                continue  # the other strand runs elsewhere (not a nick, not a short gap)
            if _stacks(frames, origins, (x, y), nxt):
                return nxt
        return None

    def succ(node):
        x, y = node
        x3 = next3[x]
        if x3 is not None and x3 in partner and partner[x3] != x:
            return (x3, partner[x3])
        y5 = prev5[y]
        if y5 is not None and y5 in partner and partner[y5] != y:
            return (partner[y5], y5)
        return across_gap(x, y)

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
        gaps = []
        for (x, y), (x2, y2) in zip(kept[:-1], kept[1:]):
            g = (path(x, x2) or []) + (path(y2, y) or [])
            gaps.append(sorted(g))
        for k, g in enumerate(gaps):
            if g:
                notes.append(f"step {k + 1} ({nucleotides[kept[k][0]].rid}/{nucleotides[kept[k][1]].rid} to "
                             f"{nucleotides[kept[k + 1][0]].rid}/{nucleotides[kept[k + 1][1]].rid}) steps across "
                             f"unpaired {' '.join(nucleotides[i].rid for i in g)} (flagged in the gap column)")
        duplexes.append(Duplex(kept, circular=circular, notes=notes, gaps=gaps))
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
