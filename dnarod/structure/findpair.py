"""Base pairs and helices by 3DNA's ``find_pair`` rules.

The rules are those of 3DNA (Lu & Olson 2003, Nucleic Acids Res. 31:5108; Lu & Olson 2008,
Nat. Protoc. 3:1213) with the defaults of its parameter file ``misc_3dna.par``; they are
re-implemented here from their description (no 3DNA code is used) and checked against 3DNA's
own output tables (``data/structures/3dna_examples``, ``data/reference/3dna``).

Pair criteria (:func:`check_pair`), lengths in Angstrom:

* base origins at most ``max_dorg`` = 15 apart; vertical separation ``d_v`` (origin
  difference along the mean base normal) at most ``max_dv`` = 2.5; angle between the base
  normals (folded into 0..90 degrees) at most ``max_plane_angle`` = 65; glycosidic atoms
  (RN9/YN1) at least ``min_dNN`` = 4.5 apart;
* the two bases do not overlap: the polygons of their ring atoms, each ring atom replaced by
  its first exocyclic (non-hydrogen) neighbour where it has one, projected on the mean base
  plane, share less than 0.01 A^2;
* at least ``min_base_hb`` = 1 pair of base N/O atoms ``hb_lower`` = 1.8 to ``hb_dist1`` =
  4.0 apart (never two atoms of the phosphate/O3'/O4'/O5'/N7 group).

Quality (lower is better): ``d_org + 2 d_v + angle/20``, minus 2 for a Watson-Crick pair
(complementary letters, relative x/y/z directions of a WC pair, |shear| <= 1.8, |stretch| <=
2, |opening| <= 60), minus 1 per "good" hydrogen bond (a donor-acceptor pair 2.5-3.5 A
apart after each atom keeps its best partner), at most minus 3. Pairs are found by rounds of
mutual best choices among the bases not yet paired, until a round adds none
(:func:`find_best_pairs`).

Helices (:func:`assemble_helices`): the pair origins (mid-points of the two base origins)
are chained by proximity: a pair's neighbours are its nearest pair and the nearest pair on
the other side along the pair's normal, both within ``helix_break`` = 7.5 A; a pair with no
neighbour within 7.5 A is isolated, one with a neighbour on one side only ends a helix.
Helices are walked from their end pairs in pair order. In each helix the two bases of every
pair are then assigned to strand I/II so that strand I runs 5'->3' (O3'(i)-P(i+1) within
2.5 A) and consecutive pairs keep Watson-Crick-like relative orientations; an antiparallel
helix gets as strand I the strand whose 5' end comes first in the file.

Internal units: nm for coordinates (the thresholds above are converted at this edge).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from dnarod.core.stepparams import step_parameters

MAX_DORG = 1.5          # nm (15 A)
MAX_DV = 0.25           # nm (2.5 A)
MAX_PLANE_ANGLE = 65.0  # degrees
MIN_DNN = 0.45          # nm (4.5 A)
HB_LOWER = 0.18         # nm (1.8 A)
HB_DIST1 = 0.40         # nm (4.0 A)
HELIX_BREAK = 0.75      # nm (7.5 A)
O3P_UPPER = 0.25        # nm (2.5 A): O3'(i)-P(j) taken as a backbone link
OVERLAP_AREA = 0.01     # A^2: two bases sharing at least this projected ring area are stacked, not paired
END_STACK_XANG = 125.0  # degrees: x axes of two WC pairs further apart than this are not a regular step
WC_BONUS = 2.0          # A, subtracted from the quality of a Watson-Crick pair
GOOD_HB = (2.5, 3.5)    # A: donor-acceptor distance range of a "good" hydrogen bond
HB_SECOND_PASS = 3.2    # A: 3DNA v2.0 also keeps a bond up to this long that shares an atom with a longer located one
WC_LETTERS = {"AT", "AU", "TA", "UA", "GC", "IC", "CG", "CI"}

RING_ORDER = ("C4", "N3", "C2", "N1", "C6", "C5", "N7", "C8", "N9")
PURINES = ("A", "G", "I")
#: Atoms that never form an H-bond with each other (phosphate oxygens, O3', O4', O5', N7).
NO_HB_GROUP = {"OP1", "OP2", "O1P", "O2P", "O3'", "O4'", "O5'", "N7"}
#: Donor (D) / acceptor (A) / either (X) character of base and backbone atoms.
BACKBONE_DA = {"OP1": "A", "OP2": "A", "O1P": "A", "O2P": "A", "O5'": "A", "O4'": "A", "O3'": "A", "O2'": "X"}
BASE_DA = {
    "A": {"N9": "?", "N7": "A", "N6": "D", "N1": "A", "N3": "A"},
    "C": {"N1": "?", "O2": "A", "N3": "A", "N4": "D"},
    "G": {"N9": "?", "N7": "A", "O6": "A", "N1": "D", "N2": "D", "N3": "A"},
    "I": {"N9": "?", "N7": "A", "O6": "A", "N1": "D", "N3": "A"},
    "T": {"N1": "?", "O2": "A", "N3": "D", "O4": "A"},
    "U": {"N1": "?", "O2": "A", "N3": "D", "O4": "A"},
}
DA_PAIRS = {"AD", "AX", "XD", "XX", "DA", "DX", "XA"}
COVALENT_RADIUS = {"C": 0.0762, "N": 0.0689, "O": 0.0646, "P": 0.1000, "S": 0.1105, "H": 0.0352}  # nm
BOND_FACTOR = 1.15


def _element(name):
    """Element of a (normalised, hydrogen-free) nucleotide atom name: its first letter."""
    return name.lstrip("0123456789")[:1]


def is_base_atom(name):
    """True for base atoms named like ``N1``, ``O6``, ``C7`` (one letter other than H/P and digits)."""
    return name == "C5M" or (len(name) >= 2 and name[0] not in "HP" and name[0].isalpha()
                             and name[1:].isdigit() and "'" not in name)


@dataclass
class BaseData:
    """What the pairing rules need of one nucleotide (nm)."""

    letter: str
    purine: bool
    frame: np.ndarray
    origin: np.ndarray
    glycosidic: np.ndarray
    o3: np.ndarray | None
    p: np.ndarray | None
    names: list
    xyz: np.ndarray
    polar: np.ndarray            # indices of N/O atoms (H-bond capable)
    base_polar: np.ndarray       # indices of N/O base atoms
    polygon: np.ndarray          # (k, 3) first-shell ring polygon


def _first_shell_polygon(names, xyz, purine):
    """Ring atoms in 3DNA's order, each replaced by its first bonded non-ring heavy atom (file order)."""
    ring = [a for a in (RING_ORDER if purine else RING_ORDER[:6]) if a in names]
    pos = {n: k for k, n in enumerate(names)}
    ring_idx = [pos[a] for a in ring]
    rad = np.array([COVALENT_RADIUS.get(_element(n), 0.1666) for n in names])  # unknown elements: 3DNA's 1.666 A
    other = np.ones(len(names), dtype=bool)
    other[ring_idx] = False
    other &= np.array([_element(n) != "H" for n in names], dtype=bool)
    out = []
    for i in ring_idx:
        bonded = other & (np.linalg.norm(xyz - xyz[i], axis=1) <= BOND_FACTOR * (rad + rad[i]))
        j = np.flatnonzero(bonded)  # ascending atom order, as a sorted connection table
        out.append(xyz[j[0]] if j.size else xyz[i])
    return np.array(out).reshape(-1, 3)


def base_data(nucleotides, frames, origins):
    """Per-nucleotide data for the pairing rules.

    Parameters
    ----------
    nucleotides : list of Nucleotide
    frames : ndarray, shape (n, 3, 3)
    origins : ndarray, shape (n, 3)
        nm.

    Returns
    -------
    list of BaseData
    """
    out = []
    for nt, F, o in zip(nucleotides, frames, origins):
        names = list(nt.atoms)
        xyz = np.array([nt.atoms[a] for a in names])
        purine = nt.base in PURINES
        gly = nt.atoms.get("N9" if purine else "N1")
        if gly is None:  # 3DNA falls back to the base atom nearest C1'
            c1 = nt.atoms.get("C1'")
            cands = [a for a in names if is_base_atom(a)]
            gly = (min((nt.atoms[a] for a in cands), key=lambda v: np.linalg.norm(v - c1))
                   if c1 is not None and cands else o)
        polar = np.array([k for k, a in enumerate(names) if _element(a) in ("N", "O")], dtype=int)
        base_polar = np.array([k for k in polar if is_base_atom(names[k])], dtype=int)
        out.append(BaseData(nt.base, purine, F, o, np.asarray(gly), nt.atoms.get("O3'"), nt.atoms.get("P"),
                            names, xyz, polar, base_polar, _first_shell_polygon(names, xyz, purine)))
    return out


# ----------------------------------------------------------------------------------------------------------
# polygon overlap (projected ring areas)

def _clip(poly, a, b):
    """Part of polygon ``poly`` (k, 2) left of the directed line a->b (Sutherland-Hodgman)."""
    out = []
    n = len(poly)
    for k in range(n):
        p, q = poly[k], poly[(k + 1) % n]
        sp = (b[0] - a[0]) * (p[1] - a[1]) - (b[1] - a[1]) * (p[0] - a[0])
        sq = (b[0] - a[0]) * (q[1] - a[1]) - (b[1] - a[1]) * (q[0] - a[0])
        if sp >= 0:
            out.append(p)
        if (sp >= 0) != (sq >= 0):
            t = sp / (sp - sq)
            out.append(p + t * (q - p))
    return out


def _area(poly):
    """Signed (counter-clockwise positive) area of a plane polygon."""
    n = len(poly)
    if n < 3:
        return 0.0
    s = 0.0
    for k in range(n):
        p, q = poly[k], poly[(k + 1) % n]
        s += p[0] * q[1] - q[0] * p[1]
    return 0.5 * float(s)


def _fan_triangle(poly, i):
    """Triangle ``(poly[0], poly[i], poly[i + 1])`` of a polygon's fan, counter-clockwise, and its signed area."""
    t = np.array([poly[0], poly[i], poly[i + 1]])
    s = _area(t)
    return (t[::-1] if s < 0 else t), s


def polygon_overlap_area(a, b):
    """Area shared by two plane polygons (any shape; the winding-number product integral).

    Each polygon is split into the signed triangles of a fan from its first vertex; the overlap
    is the sum over triangle pairs of the signed areas of their (convex) intersections.

    Parameters
    ----------
    a, b : ndarray, shape (k, 2)

    Returns
    -------
    float
        Area in the squared units of the input.
    """
    if len(a) < 3 or len(b) < 3:
        return 0.0
    lo = np.maximum(a.min(axis=0), b.min(axis=0))
    hi = np.minimum(a.max(axis=0), b.max(axis=0))
    if (lo >= hi).any():  # bounding boxes apart
        return 0.0
    total = 0.0
    for i in range(1, len(a) - 1):
        ta, sa = _fan_triangle(a, i)
        if sa == 0.0:
            continue
        for j in range(1, len(b) - 1):
            tb, sb = _fan_triangle(b, j)
            if sb == 0.0:
                continue
            poly = [p for p in ta]
            for k in range(3):
                poly = _clip(poly, tb[k], tb[(k + 1) % 3])
                if len(poly) < 3:
                    break
            total += np.sign(sa) * np.sign(sb) * _area(poly)
    return abs(total)


def overlap_area(bi, bj, oave, zave):
    """Projected overlap (A^2) of the first-shell ring polygons of two bases on the plane normal to zave."""
    z = zave / np.linalg.norm(zave)
    ref = np.array([1.0, 0.0, 0.0]) if abs(z[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = np.cross(z, ref)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    P = np.stack([x, y], axis=1)
    return 100.0 * polygon_overlap_area((bi.polygon - oave) @ P, (bj.polygon - oave) @ P)


# ----------------------------------------------------------------------------------------------------------
# hydrogen bonds

def _donor_acceptor(li, lj, a1, a2):
    """'-' for a donor-acceptor pair of the six standard bases (and backbone O), '*' otherwise."""
    if li.upper() not in BASE_DA or lj.upper() not in BASE_DA:
        return "*"
    ia = BACKBONE_DA.get(a1) or BASE_DA[li.upper()].get(a1)
    ja = BACKBONE_DA.get(a2) or BASE_DA[lj.upper()].get(a2)
    if ia and ja and ia + ja in DA_PAIRS:
        return "-"
    return "*"


def _good_hb_atoms(a1, a2):
    return not (a1 in NO_HB_GROUP and a2 in NO_HB_GROUP)


def hydrogen_bonds(bi, bj):
    """3DNA's H-bond list between two nucleotides: ``[(atom_i, atom_j, distance_A, type)]``.

    All N/O atom pairs 1.8-4.0 A apart (not both in the phosphate/O3'/O4'/O5'/N7 group);
    each atom keeps its shortest mutual partner (conflicting contacts dropped); a contact up
    to ``HB_SECOND_PASS`` = 3.2 A long that shares an atom with a longer kept bond is kept too
    (the lists of 3DNA v2.0's output, ``data/structures/3dna_examples/*.out``, need this); a
    list with a donor-acceptor bond 2.5-3.5 A long drops bonds longer than 3.6 A and
    donor-donor / acceptor-acceptor bonds outside 2.6-3.2 A that are not an atom's best
    contact. Type ``'-'`` is a donor-acceptor pair, ``'*'`` another.
    """
    cand = []
    for m in bi.polar:
        for n in bj.polar:
            d = np.linalg.norm(bi.xyz[m] - bj.xyz[n])
            if HB_LOWER <= d <= HB_DIST1 and _good_hb_atoms(bi.names[m], bj.names[n]):
                cand.append([bi.names[m], bj.names[n], 10.0 * d])
    nh = len(cand)
    if nh == 0:
        return []
    dist = [c[2] for c in cand]
    matched = [False] * nh
    m_done, it = 0, 0
    while True:  # each atom keeps its nearest mutual partner
        if it >= nh:
            break
        if matched[it]:
            it += 1
            continue
        best = [it, it]
        dmin = [dist[it], dist[it]]
        for n in range(nh):
            if n == it or matched[n]:
                continue
            if cand[n][0] == cand[it][0] and dist[n] < dmin[0]:
                best[0], dmin[0] = n, dist[n]
            if cand[n][1] == cand[it][1] and dist[n] < dmin[1]:
                best[1], dmin[1] = n, dist[n]
        if best[0] == best[1]:
            k = best[0]
            dist[k] = -dist[k]
            it = 0
            for n in range(nh):
                if matched[n]:
                    continue
                if cand[n][0] == cand[k][0] or cand[n][1] == cand[k][1]:
                    matched[n] = True
                    m_done += 1
            if m_done >= nh:
                break
        else:
            it += 1
    lkg = []
    for k in range(nh):
        i1 = i2 = 0
        if dist[k] < 0:
            i1 = i2 = 9
        else:
            for m in range(nh):
                if m != k and dist[m] < 0:
                    if cand[m][0] == cand[k][0]:
                        i1 = 1
                    if cand[m][1] == cand[k][1]:
                        i2 = 1
        lkg.append(i1 + i2)
    if HB_SECOND_PASS > 0:  # 3DNA v2.0: a bond shorter than a located bond it shares an atom with is kept too
        add = []
        for m in range(nh):
            if dist[m] > 0:
                continue
            for n in range(nh):
                if dist[n] < 0 or n in add or dist[n] > -dist[m] or not 10 * HB_LOWER <= dist[n] <= HB_SECOND_PASS:
                    continue
                if cand[n][0] == cand[m][0] or cand[n][1] == cand[m][1]:
                    add.append(n)
        for n in add:
            dist[n] = -dist[n]
    types = [" "] * nh
    good = 0
    for k in range(nh):
        if dist[k] > 0:
            continue
        types[k] = _donor_acceptor(bi.letter, bj.letter, cand[k][0], cand[k][1])
        dist[k] = -dist[k]
        if types[k] == "-" and GOOD_HB[0] <= dist[k] <= GOOD_HB[1]:
            good += 1
    if good:
        for k in range(nh):
            if types[k] == " ":
                continue
            if dist[k] > 3.6 or (types[k] == "*" and lkg[k] != 18 and not 2.6 <= dist[k] <= 3.2):
                types[k] = " "
    return [(cand[k][0], cand[k][1], dist[k], types[k]) for k in range(nh) if types[k] != " "]


def hb_quality(bi, bj):
    """3DNA's H-bond adjustment of the pair quality: -1 per good bond, -3 for two or more (A)."""
    good = sum(1 for _, _, d, t in hydrogen_bonds(bi, bj)
               if t == "-" and GOOD_HB[0] <= round(d, 2) <= GOOD_HB[1])  # 3DNA reads them back at 0.01 A
    return -3.0 if good >= 2 else -float(good)


# ----------------------------------------------------------------------------------------------------------
# pair check

@dataclass
class PairCheck:
    """A pair passing 3DNA's criteria (lengths in A, angle in degrees).

    Attributes
    ----------
    score : float
        Quality, lower is better.
    bpid : int
        2 Watson-Crick, 1 Watson-Crick geometry, -1 other.
    dorg, dv, angle, dnn : float
    dir_z : float
        Dot product of the two base normals (negative: antiparallel, as in a WC pair).
    """

    score: float
    bpid: int
    dorg: float
    dv: float
    angle: float
    dnn: float
    dir_z: float


def check_wc_wobble(letters, shear_A, stretch_A, opening_deg):
    """3DNA's class of a pair whose base axes have Watson-Crick directions (x alike, y and z
    opposite): 2 (Watson-Crick: complementary letters, |shear| <= 1.8 A, |stretch| <= 2 A,
    |opening| <= 60 deg), else 1 (WC geometry).

    3DNA v2.0 (the version of the tables in ``data/``, whose pair symbols ``*--`` show it)
    calls every such pair WC geometry; v2.3 and later only those with 1.8 <= |shear| <= 2.8 A.
    """
    if (letters.upper() in WC_LETTERS and abs(shear_A) <= 1.8 and abs(stretch_A) <= 2.0
            and abs(opening_deg) <= 60):
        return 2
    return 1


def _pair_params_A(bi, bj):
    """Base-pair parameters (A, deg) with base i as strand I, base j as strand II."""
    L2 = bj.frame.copy()
    if bi.frame[:, 2] @ bj.frame[:, 2] < 0:
        L2[:, 1:] *= -1
    p = step_parameters(L2, bj.origin, bi.frame, bi.origin)
    return 10.0 * p[:3], np.degrees(p[3:])


def check_pair(bi, bj, need_hbond=True):
    """3DNA's pair criteria for two bases; ``None`` if they do not pair.

    Parameters
    ----------
    bi, bj : BaseData
    need_hbond : bool
        False: every criterion but the N/O contact (used to flag helix-context pairs).

    Returns
    -------
    PairCheck or None
    """
    d = bj.origin - bi.origin
    dorg = float(np.linalg.norm(d))
    if dorg > MAX_DORG:
        return None
    zi, zj = bi.frame[:, 2], bj.frame[:, 2]
    dir_z = float(zi @ zj)
    zave = zi + zj if dir_z > 0 else zi - zj
    zave = zave / np.linalg.norm(zave)
    dv = abs(float(d @ zave))
    angle = 90.0 - abs(np.degrees(np.arccos(np.clip(dir_z, -1.0, 1.0))) - 90.0)
    dnn = float(np.linalg.norm(bj.glycosidic - bi.glycosidic))
    if dv > MAX_DV or angle > MAX_PLANE_ANGLE or dnn < MIN_DNN:
        return None
    if overlap_area(bi, bj, 0.5 * (bi.origin + bj.origin), zave) >= OVERLAP_AREA:
        return None
    if need_hbond:
        if not len(bi.base_polar) or not len(bj.base_polar):
            return None
        D = np.linalg.norm(bi.xyz[bi.base_polar][:, None, :] - bj.xyz[bj.base_polar][None, :, :], axis=-1)
        ok = (D >= HB_LOWER) & (D <= HB_DIST1)
        ok &= ~np.array([[a in NO_HB_GROUP and b in NO_HB_GROUP for b in (bj.names[k] for k in bj.base_polar)]
                         for a in (bi.names[k] for k in bi.base_polar)], dtype=bool).reshape(ok.shape)
        if not ok.any():
            return None
    score = 10.0 * dorg + 20.0 * dv + angle / 20.0
    dir_x = float(bi.frame[:, 0] @ bj.frame[:, 0])
    dir_y = float(bi.frame[:, 1] @ bj.frame[:, 1])
    bpid = -1
    if dir_x > 0 and dir_y < 0 and dir_z < 0:  # Watson-Crick axis directions
        t, r = _pair_params_A(bi, bj)
        bpid = check_wc_wobble(bi.letter + bj.letter, t[0], t[1], r[2])
        if bpid == 2:
            score -= WC_BONUS
    if need_hbond:
        score += hb_quality(bi, bj)
    return PairCheck(score, bpid, 10 * dorg, 10 * dv, angle, 10 * dnn, dir_z)


def candidate_pairs(bases):
    """Every pair passing :func:`check_pair`: ``{(i, j): PairCheck}`` with ``i < j``."""
    origins = np.array([b.origin for b in bases])
    out = {}
    for i, j in sorted(cKDTree(origins).query_pairs(MAX_DORG)):
        c = check_pair(bases[i], bases[j])
        if c is not None:
            out[(i, j)] = c
    return out


def find_best_pairs(n, candidates):
    """3DNA's best-pair search: rounds of mutual best choices among unpaired bases.

    Parameters
    ----------
    n : int
        Number of bases.
    candidates : dict
        ``{(i, j): PairCheck}`` from :func:`candidate_pairs`.

    Returns
    -------
    list of (int, int, PairCheck)
        ``(i, j, check)`` in the order found, ``i`` the base whose search found the pair.
    """
    part = [[] for _ in range(n)]
    for (i, j), c in sorted(candidates.items()):
        part[i].append((j, c))
        part[j].append((i, c))
    for lst in part:
        lst.sort(key=lambda t: t[0])
    matched = [False] * n

    def best(i):
        bj, bc = None, None
        for j, c in part[i]:
            if matched[j]:
                continue
            if bc is None or c.score < bc.score:
                bj, bc = j, c
        return bj, bc

    pairs = []
    while True:
        added = False
        for i in range(n):
            if matched[i]:
                continue
            j, c = best(i)
            if j is None:
                continue
            if best(j)[0] == i:
                matched[i] = matched[j] = True
                pairs.append((i, j, c))
                added = True
        if not added:
            break
    return pairs


# ----------------------------------------------------------------------------------------------------------
# helices

def _linked(bases, i, j):
    """1 if O3'(i)-P(j) is a backbone link, -1 if O3'(j)-P(i), 0 otherwise (3DNA's is_linked)."""
    a, b = bases[i], bases[j]
    if a.o3 is not None and b.p is not None and np.linalg.norm(a.o3 - b.p) <= O3P_UPPER:
        return 1
    if b.o3 is not None and a.p is not None and np.linalg.norm(b.o3 - a.p) <= O3P_UPPER:
        return -1
    return 0


def _o3_dist(bases, i, j):
    a, b = bases[i], bases[j]
    if a.o3 is None or b.o3 is None:
        return -1.0
    return float(np.linalg.norm(a.o3 - b.o3))


@dataclass
class Helix:
    """A helix in 3DNA's sense.

    Attributes
    ----------
    pairs : list of (int, int)
        Base indices (strand I, strand II), in helix order.
    bpids : list of int
        3DNA pair class per pair (2 WC, 1 WC geometry, -1 other).
    broken : bool
        Some consecutive pairs are not backbone-linked on a strand.
    parallel : bool
    weird : bool
        A strand changes direction inside the helix.
    zdna : bool
        Every step reads as left-handed with WC-geometry pairs (3DNA's Z-DNA label).
    circular : bool
        Every pair has neighbours on both sides (a closed ring of pairs).
    """

    pairs: list
    bpids: list
    broken: bool = False
    parallel: bool = False
    weird: bool = False
    zdna: bool = False
    circular: bool = False


class _Pairs:
    """Base-pair records with 3DNA's per-pair data: bases (i, j), bpid, origin, base axes."""

    def __init__(self, bases, pair_list):
        self.bases = bases
        self.ij = [[i, j] for i, j, _ in pair_list]
        self.bpid = [c.bpid for _, _, c in pair_list]
        self.org = np.array([0.5 * (bases[i].origin + bases[j].origin) for i, j, _ in pair_list]).reshape(-1, 3)
        # axes[k, s] = frame (columns x, y, z) of base s (0: i, 1: j) of pair k
        self.axes = np.array([[bases[i].frame, bases[j].frame] for i, j, _ in pair_list]).reshape(-1, 2, 3, 3)
        self.swapped = [False] * len(pair_list)

    def ij_of(self, m):
        i, j = self.ij[m]
        return (j, i) if self.swapped[m] else (i, j)

    def axes_of(self, m):
        """(strand I base frame, strand II base frame) of pair m with the current swap."""
        a = self.axes[m]
        return (a[1], a[0]) if self.swapped[m] else (a[0], a[1])


def _bp_context(P):
    """Neighbour pairs and helix end pairs (3DNA's bp_context)."""
    n = len(P.ij)
    order = [[0, 0, 0] for _ in range(n)]  # [middle flag (-1), neighbour 1, neighbour 2], 0-based+1 (0: none)
    ends = []
    d_last = None
    for i in range(n):
        zi, zj = P.axes[i, 0][:, 2], P.axes[i, 1][:, 2]
        d_last = float(zi @ zj)
        zave = zi - zj if d_last <= 0 else zi + zj
        zave /= np.linalg.norm(zave)
        dist = np.linalg.norm(P.org[i] - P.org, axis=1)
        dist[i] = np.inf
        idx = [k for k in np.argsort(dist, kind="stable")[:8] if np.isfinite(dist[k])]
        dmin = [float(dist[k]) for k in idx]
        if len(idx) < 2:
            continue
        if dmin[0] > HELIX_BREAK:
            ends.append([i + 1, 0, 0])
            continue
        d = float(zave @ (P.org[i] - P.org[idx[0]]))
        if len(idx) >= 3 and dmin[1] <= HELIX_BREAK and dmin[2] <= HELIX_BREAK:
            d2 = float(zave @ (P.org[i] - P.org[idx[1]]))
            d3 = float(zave @ (P.org[i] - P.org[idx[2]]))
            if d * d2 < 0 and d * d3 < 0 and abs(d2) > abs(d3):
                idx[1], idx[2] = idx[2], idx[1]
                dmin[1], dmin[2] = dmin[2], dmin[1]
        found = False
        for k in range(1, len(idx)):
            if dmin[k] > HELIX_BREAK:
                break
            d2 = float(zave @ (P.org[i] - P.org[idx[k]]))
            if d * d2 < 0:
                order[i] = [-1, idx[0] + 1, idx[k] + 1]
                found = True
                break
        if not found:
            end = [i + 1, idx[0] + 1, 0]
            order[i][1] = idx[0] + 1
            t2 = P.org[idx[1]] - P.org[idx[0]]
            d2 = float(zave @ t2)
            if d * d2 < 0 and np.linalg.norm(t2) <= HELIX_BREAK:
                end[2] = idx[1] + 1
                order[i][2] = idx[1] + 1
            ends.append(end)
    if not ends:
        ends.append([1, 0, 0])
        if n > 2 and all(o[0] == -1 for o in order):  # circular
            m = min(order[0][1], order[0][2])
            ends[0][1] = m
            ends[0][2] = order[m - 1][2] if order[m - 1][1] == 1 else order[m - 1][1]
        elif n == 2:
            if d_last is not None and d_last <= HELIX_BREAK:
                ends[0][1] = 2
                ends.append([2, 1, 0])
            else:
                ends.append([2, 0, 0])
    return order, ends


def _locate_helices(n, order, ends):
    """Walk helices from their end pairs (3DNA's locate_helix); 1-based pair numbers in, 0-based out."""
    matched = [False] * (n + 1)
    bp_idx = []
    helices = []
    start = 0
    for e in ends:
        if len(bp_idx) >= n:
            break
        present = [k for k in e if k]
        if sum(matched[k] for k in present) == len(present):
            continue
        for k in e:
            if k and not matched[k] and len(bp_idx) < n:
                bp_idx.append(k)
                matched[k] = True
        for _ in range(n):
            k = bp_idx[-1]
            k2, k3 = order[k - 1][1], order[k - 1][2]
            if order[k - 1][0] != -1:  # end point
                if k2 and not matched[k2] and not k3:
                    bp_idx.append(k2)
                    matched[k2] = True
                break
            m = matched[k2] + matched[k3]
            if m in (0, 2):
                break
            prev = bp_idx[-2] if len(bp_idx) >= 2 else None
            if k2 == prev:
                bp_idx.append(k3)
                matched[k3] = True
            elif k3 == prev:
                bp_idx.append(k2)
                matched[k2] = True
            else:
                break
        helices.append(list(range(start, len(bp_idx))))
        start = len(bp_idx)
    if len(bp_idx) < n:  # left-over pairs go into the last region, as 3DNA does
        rest = [k for k in range(1, n + 1) if not matched[k]]
        if helices and start == len(bp_idx):
            helices.append([])
        helices[-1].extend(range(len(bp_idx), len(bp_idx) + len(rest)))
        bp_idx.extend(rest)
    return [[bp_idx[p] - 1 for p in h] for h in helices if h]


def _wc_zdir(P, m, n, m_swap=None, n_swap=None):
    def zdir(k, flip):
        a1, a2 = P.axes_of(k)
        if flip:
            a1, a2 = a2, a1
        v = a1[:, 2] - a2[:, 2]
        return v / np.linalg.norm(v)
    return float(zdir(m, False) @ zdir(n, bool(n_swap)))


def _wc_xang(P, m, n):
    dm = P.axes[m, 0][:, 0] + P.axes[m, 1][:, 0]
    dn = P.axes[n, 0][:, 0] + P.axes[n, 1][:, 0]
    c = dm @ dn / (np.linalg.norm(dm) * np.linalg.norm(dn))
    return float(np.degrees(np.arccos(np.clip(c, -1, 1))))


def _wc_bporien(P, m, n):
    if P.bpid[m] > 0 and P.bpid[n] > 0:
        i1, j1 = P.ij_of(m)
        i2, j2 = P.ij_of(n)
        b = P.bases
        if _wc_xang(P, m, n) > END_STACK_XANG or _linked(b, i1, i2) or _linked(b, j1, j2):
            return False
        if _wc_zdir(P, m, n) < 0 and _wc_zdir(P, m, n, n_swap=True) > 0:
            return True
    return False


def _check_o3dist(P, m, n):
    b = P.bases
    i1, j1 = P.ij_of(m)
    i2, j2 = P.ij_of(n)
    a, c = _o3_dist(b, i1, i2), _o3_dist(b, i1, j2)
    e, f = _o3_dist(b, j1, i2), _o3_dist(b, j1, j2)
    return a > 0 and c > 0 and a > c and e > 0 and f > 0 and f > e


def _check_schain(P, m, n):
    b = P.bases
    i1, j1 = P.ij_of(m)
    i2, j2 = P.ij_of(n)
    return (not _linked(b, i1, i2) and not _linked(b, j1, j2)
            and bool(_linked(b, i1, j2) or _linked(b, j1, i2)))


def _check_others(P, m, n):
    b = P.bases
    i1, j1 = P.ij_of(m)
    i2, j2 = P.ij_of(n)
    if _linked(b, i1, i2) or _linked(b, j1, j2) or _linked(b, i1, j2) or _linked(b, j1, i2):
        return False
    m1, m2 = P.axes_of(m)
    n1, n2 = P.axes_of(n)
    def dots(A, B):
        return np.einsum("ij,ij->j", A, B)  # x, y, z axis dots
    a1, a2, r1, r2 = dots(m1, n1), dots(m2, n2), dots(m1, n2), dots(m2, n1)
    i1ok, i2ok, j1ok, j2ok = (bool((v > 0).all()) for v in (a1, a2, r1, r2))
    if i1ok and i2ok:
        return False
    if not i1ok and not i2ok:
        return j1ok or j2ok
    def ang(v):
        return float(np.degrees(np.arccos(np.clip(v, -1, 1))).sum())
    d = [ang(a1), ang(a2), ang(r1), ang(r2)]
    if i1ok and j1ok:
        return d[0] > d[2]
    if i1ok and j2ok:
        return d[0] > d[3]
    if i2ok and j1ok:
        return d[1] > d[2]
    if i2ok and j2ok:
        return d[1] > d[3]
    return False


def _first_step(P, h):
    if len(h) < 2:
        return h
    for _attempt in range(2):  # as given, then reversed; unlinked both ways: as given
        i1, _ = P.ij_of(h[0])
        i2, _ = P.ij_of(h[1])
        k = _linked(P.bases, i1, i2)
        if k == -1:
            P.swapped[h[0]] = not P.swapped[h[0]]
        if k != 0:
            return h
        h = h[::-1]
    return h


def _direction(P, h):
    b = P.bases
    d = [0] * 7
    for m, n in zip(h[:-1], h[1:]):
        i1, j1 = P.ij_of(m)
        i2, j2 = P.ij_of(n)
        k = _linked(b, i1, i2)
        d[1 if k == 1 else 2 if k == -1 else 3] += 1
        k = _linked(b, j1, j2)
        d[4 if k == 1 else 5 if k == -1 else 6] += 1
    return d


def _check_direction(P, h, flags):
    d = _direction(P, h)
    if (d[1] and d[2]) or (d[4] and d[5]):
        flags["weird"] = True
        return h, d
    if d[1] + d[2] + d[4] + d[5] == 0:
        return h, d
    i1, j1 = P.ij_of(h[0])
    i2, j2 = P.ij_of(h[-1])
    if d[3] or d[6]:
        flags["broken"] = True
    if d[1] and not d[2]:
        if not d[4] and d[5]:  # antiparallel: strand I starts with the earlier residue
            if i1 > j2:
                for m in h:
                    P.swapped[m] = not P.swapped[m]
                h = h[::-1]
        elif d[4] and not d[5]:
            flags["parallel"] = True
            if i1 > j1:
                for m in h:
                    P.swapped[m] = not P.swapped[m]
    return h, d


def _check_strand2(P, h, flags, d):
    b = P.bases
    if not flags["weird"]:
        if d[1] + d[2] + d[4] + d[5] == 0:
            return h
        flags.update(broken=False, parallel=False, weird=False)
        for m, n in zip(h[:-1], h[1:]):
            if _wc_bporien(P, m, n):
                continue
            i1, j1 = P.ij_of(m)
            i2, j2 = P.ij_of(n)
            if (not _linked(b, i1, i2) and not _linked(b, j1, j2)
                    and (_linked(b, i1, j2) == 1 or (_linked(b, i1, j2) and _linked(b, j1, i2)))):
                P.swapped[n] = not P.swapped[n]
    else:
        flags["weird"] = False
        anti = d[1] > d[2] and d[4] < d[5]
        para = d[1] > d[2] and d[4] > d[5]
        for m, n in zip(h[:-1], h[1:]):
            i1, j1 = P.ij_of(m)
            i2, j2 = P.ij_of(n)
            k = _linked(b, j1, j2)
            if not _linked(b, i1, i2) and ((anti and k == 1) or (para and k == -1)):
                P.swapped[n] = not P.swapped[n]
            i2, j2 = P.ij_of(n)
            if not _linked(b, i1, i2) and not _linked(b, j1, j2):
                if (anti and _linked(b, j1, i2) == 1) or (para and _linked(b, i1, j2) == -1):
                    P.swapped[m] = not P.swapped[m]
                elif (anti and _linked(b, i1, j2) == 1) or (para and _linked(b, j1, i2) == -1):
                    P.swapped[n] = not P.swapped[n]
    h, _ = _check_direction(P, h, flags)
    return h


def _five2three(P, helices):
    """Strand I 5'->3' and consistent pair orientations in each helix (3DNA's five2three)."""
    b = P.bases
    for h in helices:  # an O3'(i)-P(i) "link" inside a residue: 3DNA leaves the order as it is
        for m in h:
            i = P.ij[m][0]
            if b[i].o3 is not None and b[i].p is not None and np.linalg.norm(b[i].o3 - b[i].p) <= O3P_UPPER:
                return [(h, {"broken": False, "parallel": False, "weird": False}) for h in helices]
    out = []
    for h in helices:
        h = _first_step(P, h)
        for m, n in zip(h[:-1], h[1:]):
            if (_wc_bporien(P, m, n) or _check_o3dist(P, m, n) or _check_schain(P, m, n)
                    or _check_others(P, m, n)):
                P.swapped[n] = not P.swapped[n]
            i1, _ = P.ij_of(m)
            i2, _ = P.ij_of(n)
            if _linked(b, i1, i2) == -1:
                P.swapped[n] = not P.swapped[n]
        for m, n in zip(h[:-1], h[1:]):
            if _wc_bporien(P, m, n):
                P.swapped[m] = not P.swapped[m]
        flags = {"broken": False, "parallel": False, "weird": False}
        h, d = _check_direction(P, h, flags)
        h = _check_strand2(P, h, flags, d)
        out.append((h, flags))
    return out


def _is_zdna(P, h):
    """3DNA's Z-DNA label: every pair of the helix WC-like with the next pair below its strand-I normal."""
    if len(h) <= 1:
        return False
    t = None
    for k, m in enumerate(h):
        if k < len(h) - 1:
            t = P.org[h[k + 1]] - P.org[m]
        z1 = P.axes_of(m)[0][:, 2]
        if not (t @ z1 < 0 and P.bpid[m] > 0):
            return False
    return True


def assemble_helices(bases, pair_list):
    """Order base pairs into helices by 3DNA's rules.

    Parameters
    ----------
    bases : list of BaseData
    pair_list : list of (int, int, PairCheck)
        Pairs in the order found (:func:`find_best_pairs`).

    Returns
    -------
    list of Helix
        In 3DNA's order.
    """
    if not pair_list:
        return []
    P = _Pairs(bases, pair_list)
    order, ends = _bp_context(P)
    helices = _locate_helices(len(pair_list), order, ends)
    circular = len(pair_list) > 2 and all(o[0] == -1 for o in order)
    out = []
    for h, flags in _five2three(P, helices):
        hx = Helix([P.ij_of(m) for m in h], [P.bpid[m] for m in h], circular=circular and len(h) == len(pair_list),
                   **flags)
        if not (flags["broken"] or flags["parallel"] or flags["weird"]):
            hx.zdna = _is_zdna(P, h)
        out.append(hx)
    return out
