"""The pipeline: structure file -> nucleotides -> base frames -> pairs -> duplexes -> parameters.

:func:`analyze_structure` returns, per duplex, the base-pair frames (dnarod's node frames:
d1 = x toward the major groove, d2 = y toward strand I, d3 = z along the helix), their
origins, the six base-pair parameters and the six step parameters (3DNA convention, from
:mod:`dnarod.core.stepparams`). :func:`step_parameters_over_frames` repeats the frame and
parameter computation for many coordinate frames of the same system, vectorised over frames.

Units: nm and rad (convert with :func:`dnarod.core.stepparams.to_angstrom_degrees`).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dnarod.core.errors import StructureError
from dnarod.core.stepparams import step_parameters
from dnarod.structure.bpparams import pair_parameters
from dnarod.structure.frames import base_frames, has_base_atoms, kabsch, ring_atoms_present, standard_bases
from dnarod.structure.pairing import classify_pair, explicit_pairs, fill_helix_gaps, find_pairs, is_mismatch, multiplets, order_duplexes
from dnarod.structure.reader import read_structure


@dataclass
class DuplexAnalysis:
    """One duplex of a structure.

    Attributes
    ----------
    strand1, strand2 : list of Nucleotide
        Paired nucleotides, 5'->3' along strand I (so strand II runs 3'->5').
    names : list of str
        Pair class per base pair ("WC", "wobble", "non-WC").
    bp_frames : ndarray, shape (n_bp, 3, 3)
    bp_origins : ndarray, shape (n_bp, 3)
        nm.
    bp_params : ndarray, shape (n_bp, 6)
        shear, stretch, stagger (nm); buckle, propeller, opening (rad).
    step_params : ndarray, shape (n_bp - 1, 6)
        shift, slide, rise (nm); tilt, roll, twist (rad).
    circular : bool
    notes : list of str
        Steps across unpaired bases, non-Watson-Crick pairs, circularity.
    gaps : list of str
        Per step: residue ids of the unpaired nucleotides the step crosses ("" for a regular
        step). Such a step is computed between the flanking pairs, as 3DNA does.
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


@dataclass
class StructureAnalysis:
    """Result of :func:`analyze_structure`.

    Attributes
    ----------
    structure : NucleicStructure
    duplexes : list of DuplexAnalysis
    skipped : list of str
        Everything ignored (water, protein, unpaired nucleotides, ...).
    """

    structure: object
    duplexes: list
    skipped: list

    @property
    def source(self):
        return self.structure.source


def analyze_structure(path=None, text=None, model=1, altloc=None, pairs=None, extra_residues=None,
                      ignore_residues=()):
    """Read a structure and compute its base-pair frames and parameters.

    Parameters
    ----------
    path, text, model, altloc, extra_residues, ignore_residues
        As :func:`dnarod.structure.reader.read_structure`.
    pairs : list of (str, str), optional
        Explicit pairs as residue ids (``[("A:1", "B:24"), ...]``) instead of geometric pairing.

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
    if pairs is None:
        pair_idx = find_pairs(nts, frames, origins, st.source)
        pair_idx, gap_notes = fill_helix_gaps(nts, frames, origins, pair_idx, st.source)
        gap_notes += multiplets(nts, frames, origins, pair_idx, st.source)
    else:
        pair_idx, gap_notes = explicit_pairs(nts, pairs, st.source), []
    if not pair_idx:
        chains = {}
        for nt in nts:
            chains[nt.chain] = chains.get(nt.chain, 0) + 1
        desc = ", ".join(f"chain {c} ({n} nt)" for c, n in chains.items())
        raise StructureError(f"{st.source}: no base pairs found among {len(nts)} nucleotides in {desc}: a single "
                             f"strand? dnarod needs a double-stranded region")
    ordered, skipped = order_duplexes(nts, origins, pair_idx, st.source, frames=frames)
    duplexes = []
    for dup in ordered:
        i1 = np.array([a for a, _ in dup.pairs])
        i2 = np.array([b for _, b in dup.pairs])
        bp, mid, morg = pair_parameters(frames[i1], origins[i1], frames[i2], origins[i2])
        sp = step_parameters(mid[:-1], morg[:-1], mid[1:], morg[1:])
        s1 = [nts[k] for k in i1]
        s2 = [nts[k] for k in i2]
        names = [classify_pair(a.base, b.base, p, a, b) for a, b, p in zip(s1, s2, bp)]
        notes = list(dup.notes)
        odd = [f"{a.rid}/{b.rid} {a.letter}-{b.letter} ({'mismatch, ' if is_mismatch(a.base, b.base) else ''}{n})"
               for a, b, n in zip(s1, s2, names) if n != "WC"]
        if odd:
            notes.append(f"pairs that are not Watson-Crick (kept in the helix, check them): {'; '.join(odd)}")
        mod = [f"{nt.rid} {nt.resname}->{nt.base}" for nt in s1 + s2 if nt.modified]
        if mod:
            notes.append(f"modified nucleotides modelled as their parent base: {', '.join(mod)}")
        gaps = [" ".join(nts[i].rid for i in g) for g in (dup.gaps or [[]] * (len(s1) - 1))]
        duplexes.append(DuplexAnalysis(s1, s2, names, mid, morg, bp, sp, dup.circular, notes, gaps))
    for k, d in enumerate(duplexes):
        gap_notes += [f"duplex {k + 1}: {n}" for n in d.notes]
    outside = [f"{nt.rid} {nt.resname}->{nt.base}" for nt in nts if nt.modified
               and not any(nt is x for d in duplexes for x in d.strand1 + d.strand2)]
    if outside:
        gap_notes.append(f"modified nucleotides outside the duplexes (parent base): {', '.join(outside)}")
    return StructureAnalysis(st, duplexes, list(st.skipped) + gap_notes + skipped)


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
    sp = step_parameters(mid[:, :-1], morg[:, :-1], mid[:, 1:], morg[:, 1:])
    return sp, bp, mid, morg
