"""The pipeline: structure file -> nucleotides -> base frames -> pairs -> helices -> parameters.

Pairs and helices follow 3DNA's ``find_pair`` rules (:mod:`dnarod.structure.findpair`), the
base-pair and step parameters 3DNA's ``analyze`` conventions, including its reversed frames
for left-handed DNA and B-Z junctions (:mod:`dnarod.structure.conventions`); see
``docs/structure_3dna.md``. Where dnarod goes beyond 3DNA's rules (a pair kept by its helix
context although no N/O contact is within 4 A), a note names the residues.

:func:`analyze_structure` returns, per helix (a "duplex"), the base-pair frames (dnarod's
node frames: d1 = x toward the major groove, d2 = y toward strand I, d3 = z along the helix;
for left-handed steps these are 3DNA's reversed frames, so d3 always runs along strand I
5'->3'), their origins, the six base-pair parameters and the six step parameters (3DNA
convention, from :mod:`dnarod.core.stepparams`). :func:`step_parameters_over_frames` repeats the
frame and parameter computation for many coordinate frames of the same system, vectorised
over frames.

Steps are numbered from 1 along strand I, continuing across duplexes, in every table and
message (the numbers of ``dnarod steps``).

Units: nm and rad (convert with :func:`dnarod.core.stepparams.to_angstrom_degrees`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dnarod.core.errors import StructureError
from dnarod.core.stepparams import step_parameters
from dnarod.structure import conventions as cv
from dnarod.structure.bpparams import flip_strand2, pair_parameters
from dnarod.structure.findpair import PairCheck, assemble_helices, base_data, candidate_pairs, check_pair, find_best_pairs
from dnarod.structure.frames import base_frames, has_base_atoms, kabsch, ring_atoms_present, standard_bases
from dnarod.structure.pairing import (MAX_GAP, backbone_links, check_duplicated, classify_pair, explicit_pairs, fill_helix_gaps,
                      is_mismatch, multiplets)
from dnarod.structure.reader import read_structure


@dataclass
class DuplexAnalysis:
    """One helix of a structure (3DNA's helix; called a duplex in dnarod).

    Attributes
    ----------
    strand1, strand2 : list of Nucleotide
        Paired nucleotides, 5'->3' along strand I (so strand II runs 3'->5').
    names : list of str
        Pair class per base pair ("WC", "wobble", "Hoogsteen", "non-WC").
    bp_frames : ndarray, shape (n_bp, 3, 3)
        Node frames: 3DNA's base-pair frames, reversed (x and z negated) where 3DNA reverses
        them for a left-handed step, so that z runs along the helix.
    bp_origins : ndarray, shape (n_bp, 3)
        nm.
    bp_params : ndarray, shape (n_bp, 6)
        shear, stretch, stagger (nm); buckle, propeller, opening (rad), as 3DNA reports them.
    step_params : ndarray, shape (n_bp - 1, 6)
        shift, slide, rise (nm); tilt, roll, twist (rad), as 3DNA reports them.
    circular : bool
    notes : list of str
        Steps across unpaired bases, non-Watson-Crick pairs, left-handed steps, circularity.
    gaps : list of str
        Per step: residue ids of the unpaired nucleotides the step crosses ("" for a regular
        step). Such a step is computed between the flanking pairs, as 3DNA does.
    bp_reversed : ndarray of bool, shape (n_bp,)
        ``bp_frames[k]`` is the base-pair frame of the fitted bases rotated by 180 degrees
        about its y axis (a left-handed pair, 3DNA's reversed frame).
    frames_reversed : bool
        3DNA's whole-structure rule reversed every frame (a left-handed structure); the
        base-pair parameters are then those of the reversed frames.
    step_flips : ndarray of bool, shape (n_bp - 1, 2)
        Which frames of each step 3DNA reverses for that step (relative to its base-pair
        frames): both for a Z step, one for a B-Z junction.
    first_step : int
        Number (1-based, as in ``dnarod steps``) of this duplex's first step.
    """

    strand1: list
    strand2: list
    names: list
    bp_frames: np.ndarray
    bp_origins: np.ndarray
    bp_params: np.ndarray
    step_params: np.ndarray
    circular: bool = False
    notes: list = field(default_factory=list)
    gaps: list = field(default_factory=list)
    bp_reversed: np.ndarray = None
    frames_reversed: bool = False
    step_flips: np.ndarray = None
    first_step: int = 1

    def __post_init__(self):
        n = len(self.strand1)
        if self.bp_reversed is None:
            self.bp_reversed = np.zeros(n, dtype=bool)
        if self.step_flips is None:
            self.step_flips = np.zeros((max(n - 1, 0), 2), dtype=bool)

    @property
    def n_bp(self):
        return len(self.strand1)

    @property
    def bp_labels(self):
        """``["C-G", ...]``: strand I letter, strand II letter (lower case = modified base)."""
        return [f"{a.letter}-{b.letter}" for a, b in zip(self.strand1, self.strand2)]

    @property
    def sequence(self):
        """Strand I parent bases, 5'->3' (upper case)."""
        return "".join(nt.base for nt in self.strand1)

    @property
    def step_labels(self):
        """3DNA step names ``XY/X'Y'`` (strand I 5'->3' / strand II 5'->3')."""
        s1 = [nt.letter for nt in self.strand1]
        s2 = [nt.letter for nt in self.strand2]
        return [f"{s1[k]}{s1[k + 1]}/{s2[k + 1]}{s2[k]}" for k in range(self.n_bp - 1)]

    def step_name(self, k):
        """``step 5 (A:5/B:20 to A:6/B:19)``: step ``k`` (0-based in this duplex) as every output numbers it."""
        a, b = self.strand1, self.strand2
        return (f"step {self.first_step + k} ({a[k].rid}/{b[k].rid} to {a[k + 1].rid}/{b[k + 1].rid})")


@dataclass
class StructureAnalysis:
    """Result of :func:`analyze_structure`.

    Attributes
    ----------
    structure : NucleicStructure
    duplexes : list of DuplexAnalysis
    skipped : list of str
        Everything ignored (water, protein, unpaired nucleotides, ...) and the notes.
    """

    structure: object
    duplexes: list
    skipped: list

    @property
    def source(self):
        return self.structure.source


def unstacked_steps(duplex):
    """Steps (0-based in the duplex) whose node frames turn by 80 % of a half turn or more: not a stacked
    step (a pair with parallel base normals, a helix turning back), beyond what the rod's strains describe."""
    from dnarod.core.rotations import MAX_CAYLEY_ANGLE

    F = duplex.bp_frames
    if len(F) < 2:
        return []
    R = np.swapaxes(F[:-1], -1, -2) @ F[1:]
    ang = np.arccos(np.clip((np.trace(R, axis1=-2, axis2=-1) - 1) / 2, -1, 1))
    return [int(k) for k in np.flatnonzero(ang >= 0.8 * MAX_CAYLEY_ANGLE)]


def describe_unstacked(duplex, k):
    """The line naming an unstacked step: ``NAME: the base-pair frames turn by A deg (tilt T, roll R, twist W deg)``,
    NAME as the duplex's ``step_name(k)`` gives it."""
    F = duplex.bp_frames
    R = F[k].T @ F[k + 1]
    ang = np.degrees(np.arccos(np.clip((np.trace(R) - 1) / 2, -1, 1)))
    p = np.degrees(duplex.step_params[k, 3:])
    return (f"{duplex.step_name(k)}: the base-pair frames turn by {ang:.0f} deg (tilt {p[0]:.0f}, roll {p[1]:.0f}, "
            f"twist {p[2]:.0f} deg)")


def check_node_steps(duplex):
    """Refuse a duplex for a rod model if a step of its node frames is not a stacked step.

    Raises
    ------
    StructureError
        Naming the step as every output numbers it and its residues.
    """
    bad = unstacked_steps(duplex)
    if bad:
        raise StructureError(f"{describe_unstacked(duplex, bad[0])}, beyond what the rod's strains describe; this "
                             f"is not a stacked step (check its pairs with 'dnarod pairs', give the pairs with "
                             f"--pairs, or take another duplex with --duplex N)")


def _ranges(idx):
    """``[(a, b), ...]`` runs of consecutive integers in a sorted list, for messages."""
    out = []
    for k in idx:
        if out and k == out[-1][1] + 1:
            out[-1][1] = k
        else:
            out.append([k, k])
    return ", ".join(f"{a}" if a == b else f"{a}-{b}" for a, b in out)


def _pair_list(nts, bases, pairs, source):
    """Pairs ``[(i, j, PairCheck)]`` in 3DNA's order and the notes on them."""
    notes = []
    if pairs is not None:
        out = []
        for i, j in explicit_pairs(nts, pairs, source):
            c = check_pair(bases[i], bases[j], need_hbond=False)
            out.append((i, j, c if c is not None else PairCheck(np.inf, -1, 0, 0, 0, 0, -1.0)))
        return out, notes
    cand = candidate_pairs(bases)
    found = find_best_pairs(len(nts), cand)
    check_duplicated(nts, bases, found, cand, source)
    idx = sorted((min(i, j), max(i, j)) for i, j, _ in found)
    extra, ctx_notes = fill_helix_gaps(nts, bases, idx, source)
    notes += ctx_notes
    for i, j in extra:
        found.append((i, j, check_pair(bases[i], bases[j], need_hbond=False)))
    notes += multiplets(nts, bases, cand, sorted(idx + extra), source)
    return found, notes


def _gaps(next3, helix_pairs, paired):
    """Per step of a helix: unpaired nucleotides between its two pairs on either strand, and whether
    each strand is linked (directly or across such nucleotides) from one pair to the next."""

    def path(a, b):
        out, k = [], next3[a]
        while k is not None and k != b and k not in paired and len(out) < MAX_GAP:
            out.append(k)
            k = next3[k]
        return out if k == b else []

    gaps, linked = [], []
    for (x, y), (x2, y2) in zip(helix_pairs[:-1], helix_pairs[1:]):
        gaps.append(sorted(path(x, x2) + path(y2, y)))
        linked.append((next3[x] == x2 or bool(path(x, x2)), next3[y2] == y or bool(path(y2, y))))
    return gaps, linked


def analyze_structure(path=None, text=None, model=1, altloc=None, pairs=None, extra_residues=None,
                      ignore_residues=()):
    """Read a structure and compute its base-pair frames and parameters.

    Parameters
    ----------
    path, text, model, altloc, extra_residues, ignore_residues
        As :func:`dnarod.structure.reader.read_structure`.
    pairs : list of (str, str), optional
        Explicit pairs as residue ids (``[("A:1", "B:24"), ...]``) instead of geometric pairing;
        they are ordered into helices by the same rules.

    Returns
    -------
    StructureAnalysis

    Raises
    ------
    StructureError
        Bad input (see the reader), a base without enough ring atoms, no base pairs (single
        strand), a base paired twice.
    """
    st = read_structure(path, text, model=model, altloc=altloc, extra_residues=extra_residues,
                        ignore_residues=ignore_residues)
    nts, no_base = [], []
    for nt in st.nucleotides:  # a backbone without any base atom (disordered base) is skipped, not fitted
        (nts if has_base_atoms(nt) else no_base).append(nt)
    for k, nt in enumerate(nts):
        nt.index = k
    if not nts:
        raise StructureError(f"{st.source}: no nucleotide has base atoms to fit a frame")
    if no_base:
        st.skipped.append(f"no base atoms (disordered base?): {' '.join(nt.rid for nt in no_base)}")
    frames, origins, _ = base_frames(nts, st.source)
    bases = base_data(nts, frames, origins)
    found, notes = _pair_list(nts, bases, pairs, st.source)
    if not found:
        chains = {}
        for nt in nts:
            chains[nt.chain] = chains.get(nt.chain, 0) + 1
        desc = ", ".join(f"chain {c} ({n} nt)" for c, n in chains.items())
        raise StructureError(f"{st.source}: no base pairs found among {len(nts)} nucleotides in {desc}: a single "
                             f"strand? dnarod needs a double-stranded region")
    helices = assemble_helices(bases, found)
    duplexes = _duplexes(nts, frames, origins, helices)
    for k, d in enumerate(duplexes):
        notes += [f"duplex {k + 1}: {n}" for n in d.notes]
    alt = [f"{nt.rid} ({nt.altloc} of {''.join(nt.altlocs)})" for d in duplexes for nt in d.strand1 + d.strand2
           if nt.altlocs and nt.altloc not in ("A", "1") and ("A" in nt.altlocs or "1" in nt.altlocs)]
    if alt:
        notes.append(f"alternate locations: dnarod kept the most occupied conformer of {', '.join(alt)}; 3DNA keeps "
                     f"altloc A (its alt_list 'A1'), so its parameters there may differ: pass --altloc A to read "
                     f"them as 3DNA does")
    outside = [f"{nt.rid} {nt.resname}->{nt.base}" for nt in nts if nt.modified
               and not any(nt is x for d in duplexes for x in d.strand1 + d.strand2)]
    if outside:
        notes.append(f"modified nucleotides outside the duplexes (parent base): {', '.join(outside)}")
    paired = {nt.index for d in duplexes for nt in d.strand1 + d.strand2}
    unpaired = [nt for k, nt in enumerate(nts) if k not in paired]
    if unpaired:
        by_chain = {}
        for nt in unpaired:
            by_chain.setdefault(nt.chain, []).append(f"{nt.number}{nt.icode}({nt.resname})")
        for ch, items in by_chain.items():
            notes.append(f"unpaired nucleotides (overhang, bulge, loop or single strand) in chain {ch}: "
                         f"{' '.join(items)}")
    return StructureAnalysis(st, duplexes, list(st.skipped) + notes)


def _duplexes(nts, frames, origins, helices):
    """DuplexAnalysis per helix, with 3DNA's parameters and reversed frames."""
    allp = [p for h in helices for p in h.pairs]
    i1 = np.array([a for a, _ in allp])
    i2 = np.array([b for _, b in allp])
    F1, O1, O2 = frames[i1], origins[i1], origins[i2]
    F2f = flip_strand2(frames[i2], F1)
    anti = np.einsum("ij,ij->i", F1[:, :, 2], frames[i2][:, :, 2]) < 0
    bp, mid, morg = pair_parameters(F1, O1, frames[i2], O2)
    letters = [nts[a].base + nts[b].base for a, b in allp]
    wc = cv.wc_info(bp, F1, F2f, anti, letters)
    lengths = [len(h.pairs) for h in helices]
    global_rev = bool(cv.global_z_reversal(F1, O1, F2f, O2, wc, cv.helix_markers(lengths)))
    if global_rev:
        bp = cv.reverse_pair_parameters(bp)
        mid = mid @ cv.REVERSE
    sp, flips, junction = cv.step_parameters_3dna(mid, morg)
    bounds = np.cumsum([0] + lengths)
    segments = list(zip(bounds[:-1], bounds[1:]))
    rev, disagree = cv.node_reversal(flips, segments)
    nodes = cv.reverse_frames(mid, rev)
    paired = set(i1) | set(i2)
    next3, _ = backbone_links(nts, origins)
    out, first = [], 1
    for h, (a, b) in zip(helices, segments):
        s1 = [nts[k] for k in i1[a:b]]
        s2 = [nts[k] for k in i2[a:b]]
        names = [classify_pair(x.base, y.base, p, x, y) for x, y, p in zip(s1, s2, bp[a:b])]
        gaps, linked = _gaps(next3, h.pairs, paired)
        d = DuplexAnalysis(s1, s2, names, nodes[a:b], morg[a:b], bp[a:b], sp[a:b - 1], h.circular, [],
                           [" ".join(nts[i].rid for i in g) for g in gaps], rev[a:b] ^ global_rev, global_rev,
                           flips[a:b - 1], first)
        d.notes = _notes(d, h, gaps, linked, junction[a:b - 1], [k - a for k in disagree if a <= k < b - 1], nts)
        first += max(d.n_bp - 1, 0)
        out.append(d)
    return out


def _notes(d, h, gaps, linked, junction, disagree, nts):
    notes = []
    if h.circular:
        notes.append(f"circular: the ring of pairs is opened at {d.strand1[0].rid}")
    for k, g in enumerate(gaps):
        if g:
            notes.append(f"{d.step_name(k)} steps across unpaired {' '.join(nts[i].rid for i in g)} (flagged in "
                         f"the gap column)")
    far = [k for k, (a, b) in enumerate(linked) if not (a or b)]
    if far:
        notes.append(f"{'; '.join(d.step_name(k) for k in far)}: the two pairs are not linked along either strand; "
                     f"3DNA's helix continues by stacking geometry (pair origins within 7.5 A)")
    for s, what in ((0, "I"), (1, "II")):
        cut = [d.first_step + k for k, lk in enumerate(linked) if not lk[s] and lk[1 - s]]
        if cut:
            notes.append(f"strand {what} is not continuous (a nick, gap or change of chain) at step"
                         f"{'s' if len(cut) > 1 else ''} {_ranges(cut)}; the helix continues by stacking geometry")
    if h.parallel:
        notes.append("parallel strands (strand II runs 5'->3' with strand I)")
    if h.weird:
        notes.append("a strand changes direction inside the helix")
    odd = [f"{a.rid}/{b.rid} {a.letter}-{b.letter} ({'mismatch, ' if is_mismatch(a.base, b.base) else ''}{n})"
           for a, b, n in zip(d.strand1, d.strand2, d.names) if n != "WC"]
    if odd:
        notes.append(f"pairs that are not Watson-Crick (kept in the helix, check them): {'; '.join(odd)}")
    if d.frames_reversed:
        notes.append("left-handed (Z-DNA): 3DNA's base-pair frames reversed (x and z negated) for the whole "
                     "structure, so rise is positive and twist negative; shear, stagger, buckle and opening are "
                     "those of the reversed frames")
    zsteps = [k for k in range(d.n_bp - 1) if d.step_flips[k].all()]
    if zsteps:
        notes.append(f"left-handed (Z) steps {_ranges([d.first_step + k for k in zsteps])}: both base-pair frames "
                     f"reversed for these steps (3DNA's convention: positive rise, negative twist)")
    for k in (k for k, j in enumerate(junction) if j):
        side = "second" if d.step_flips[k, 1] else "first"
        notes.append(f"{d.step_name(k)} is a B-Z junction (right- to left-handed pair): the {side} pair's frame "
                     f"is reversed for this step, as 3DNA computes it")
    for k in disagree:
        pair = [m for m in (k, k + 1) if d.bp_reversed[m] != (d.frames_reversed ^ bool(d.step_flips[k, m - k]))]
        who = " and ".join(f"{d.strand1[m].rid}/{d.strand2[m].rid}" for m in pair)
        notes.append(f"{d.step_name(k)}: 3DNA reverses the frame of {who} for a neighbouring step but not for this "
                     f"one; the node frames (strains, models) keep it reversed, so this step of a model differs "
                     f"from the table")
    mod = [f"{nt.rid} {nt.resname}->{nt.base}" for nt in d.strand1 + d.strand2 if nt.modified]
    if mod:
        notes.append(f"modified nucleotides modelled as their parent base: {', '.join(mod)}")
    return notes


def _ring_index_groups(duplex):
    """Group the bases of a duplex by (standard letter, ring atoms): atom-index arrays per group."""
    groups = {}
    for strand, nts in ((0, duplex.strand1), (1, duplex.strand2)):
        for k, nt in enumerate(nts):
            letter, names = ring_atoms_present(nt)
            g = groups.setdefault((letter, names), ([], []))
            g[0].append((strand, k))
            g[1].append([nt.atom_index[a] for a in names])
    return groups


def step_parameters_over_frames(duplex, coordinates):
    """Base-pair frames and step parameters of one duplex for many coordinate frames.

    The pairing of ``duplex`` (from :func:`analyze_structure` on a reference frame) is kept;
    base frames, pair frames and step parameters are recomputed for every frame, vectorised.
    The reference frame's choice of reversed (left-handed) frames is kept too, so that a
    thermal fluctuation does not flip a step's sign from one frame to the next.

    Parameters
    ----------
    duplex : DuplexAnalysis
    coordinates : ndarray, shape (n_frames, n_atoms, 3)
        nm, atoms in the order of the structure file the duplex was read from
        (``NucleicStructure.n_atoms`` atoms, hydrogens/water/protein included).

    Returns
    -------
    step_params : ndarray, shape (n_frames, n_bp - 1, 6)
        nm, rad.
    bp_params : ndarray, shape (n_frames, n_bp, 6)
    bp_frames : ndarray, shape (n_frames, n_bp, 3, 3)
        Node frames (as ``duplex.bp_frames``).
    bp_origins : ndarray, shape (n_frames, n_bp, 3)
    """
    X = np.asarray(coordinates, float)
    if X.ndim != 3 or X.shape[-1] != 3:
        raise StructureError(f"coordinates must have shape (n_frames, n_atoms, 3), got {X.shape}")
    std, _ = standard_bases()
    nf, n = X.shape[0], duplex.n_bp
    F = np.zeros((2, nf, n, 3, 3))
    O = np.zeros((2, nf, n, 3))
    for (letter, names), (where, idx) in _ring_index_groups(duplex).items():
        idx = np.asarray(idx)
        if idx.max() >= X.shape[1]:
            raise StructureError(f"coordinates have {X.shape[1]} atoms but the structure needs atom index "
                                 f"{idx.max()}; use coordinates of the same system in the same atom order")
        ref = np.array([std[letter][a] for a in names])
        R, o, _ = kabsch(ref, X[:, idx])
        s, k = np.array(where).T
        F[s, :, k] = np.swapaxes(R, 0, 1)
        O[s, :, k] = np.swapaxes(o, 0, 1)
    bp, mid, morg = pair_parameters(F[0], O[0], F[1], O[1])
    if duplex.frames_reversed:
        bp = cv.reverse_pair_parameters(bp)
        mid = mid @ cv.REVERSE
    flips = duplex.step_flips
    A = cv.reverse_frames(mid[:, :-1], flips[:, 0])
    B = cv.reverse_frames(mid[:, 1:], flips[:, 1])
    sp = step_parameters(A, morg[:, :-1], B, morg[:, 1:])
    nodes = cv.reverse_frames(mid, duplex.bp_reversed ^ duplex.frames_reversed)
    return sp, bp, nodes, morg
