"""All-atom DNA from base-pair (node) frames and a sequence.

As 3DNA's ``rebuild``: each base pair's two base frames follow from the pair frame and the
six base-pair parameters (:func:`dnarod.structure.bpparams.base_frames_from_pair`); each
base is the standard base of Olson et al. (2001) placed in its frame, so fitting the bases
of the rebuilt file returns the input frames exactly (to the PDB's 0.001 A rounding). The
sugar-phosphate backbone of every nucleotide is the B-DNA fibre model of Chandrasekaran &
Arnott (3DNA fibre structure 4, ``data/structures/fiber_models/str04``), carried rigidly
with its base; it is exact for ideal B-DNA steps and approximate (stretched O3'-P links)
elsewhere, as in 3DNA.

Units: nm inside; PDB files in Angstrom (written through gemmi). Strand I is chain A,
residues 1..n 5'->3'; strand II is chain B, residues n+1..2n 5'->3' (pairing residue n..1).
5'-terminal residues carry no phosphate (P, OP1, OP2), as usual in MD force fields.
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from dnarod.core.errors import StructureError
from dnarod.core.io import atomic_path
from dnarod.structure._data import data_file
from dnarod.structure.bpparams import base_frames_from_pair
from dnarod.structure.frames import kabsch, standard_bases
from dnarod.structure.reader import COMPLEMENT, read_structure

BACKBONE_ORDER = ("P", "OP1", "OP2", "O5'", "C5'", "C4'", "O4'", "C3'", "O3'", "C2'", "C1'")
TEMPLATE = "str04"


@lru_cache(maxsize=None)
def nucleotide_template(letter):
    """Atom names and coordinates (nm) of a B-DNA nucleotide in its base frame.

    Backbone and sugar from the fibre model, base atoms from the standard base.

    Returns
    -------
    names : tuple of str
    xyz : ndarray, shape (n_atoms, 3)
        nm, in the base frame.
    """
    std, ring = standard_bases()
    nt = read_structure(data_file("structures", "fiber_models", TEMPLATE, f"{letter}.pdb")).nucleotides[0]
    ref = np.array([std[letter][a] for a in ring[letter]])
    R, o, _ = kabsch(ref, np.array([nt.atoms[a] for a in ring[letter]]))
    names, xyz = [], []
    for a in BACKBONE_ORDER:
        names.append(a)
        xyz.append(R.T @ (nt.atoms[a] - o))
    for a, v in std[letter].items():
        if a != "C1'":
            names.append(a)
            xyz.append(v)
    return tuple(names), np.array(xyz)


@lru_cache(maxsize=1)
def fibre_pair_parameters():
    """Base-pair parameters of the B-DNA fibre model (A-T pair of fibre structure 4), nm and rad.

    Strand II of a fibre is the image of strand I under the dyad about the x axis; these
    parameters (propeller about -15 degrees) are the rebuild's default.

    Returns
    -------
    ndarray, shape (6,)
    """
    from dnarod.structure.bpparams import pair_parameters
    from dnarod.structure.frames import base_frames

    nts = [read_structure(data_file("structures", "fiber_models", TEMPLATE, f"{b}.pdb")).nucleotides[0]
           for b in ("A", "T")]
    F, O, _ = base_frames(nts)
    dyad = np.diag([1.0, -1.0, -1.0])
    return pair_parameters(F[0], O[0], dyad @ F[1], dyad @ O[1])[0]


def _check_sequence(sequence, n, what):
    seq = "".join(str(sequence).split()).upper()
    for i, ch in enumerate(seq):
        if ch not in "ACGT":
            raise StructureError(f"{what}: letter {ch!r} at position {i + 1} is not A, C, G or T")
    if len(seq) != n:
        raise StructureError(f"{what}: {len(seq)} letters for {n} base pairs")
    return seq


def rebuild_coordinates(bp_frames, bp_origins, sequence, bp_params=None, sequence2=None):
    """Heavy-atom coordinates of a duplex, vectorised over leading (trajectory) axes.

    Parameters
    ----------
    bp_frames : ndarray, shape (..., n, 3, 3)
        Base-pair (node) frames.
    bp_origins : ndarray, shape (..., n, 3)
        nm.
    sequence : str
        Strand I, 5'->3', n letters (A, C, G, T).
    bp_params : ndarray, shape (..., n, 6) or (n, 6), optional
        shear, stretch, stagger (nm); buckle, propeller, opening (rad). Default: the B-DNA
        fibre's (:func:`fibre_pair_parameters`).
    sequence2 : str, optional
        Strand II bases pairing strand I positions 1..n (default: Watson-Crick complement).

    Returns
    -------
    xyz : ndarray, shape (..., n_atoms, 3)
        nm.
    atoms : list of (chain, residue number, residue name, atom name, element)
    """
    F = np.asarray(bp_frames, float)
    O = np.asarray(bp_origins, float)
    n = F.shape[-3]
    if F.shape[-2:] != (3, 3) or O.shape[-1] != 3 or O.shape[-2] != n or n < 1:
        raise StructureError(f"bp_frames (..., n, 3, 3) and bp_origins (..., n, 3) expected, got {F.shape}, {O.shape}")
    seq1 = _check_sequence(sequence, n, "sequence")
    seq2 = _check_sequence(sequence2, n, "sequence2") if sequence2 else "".join(COMPLEMENT[c] for c in seq1)
    p = fibre_pair_parameters() if bp_params is None else np.asarray(bp_params, float)
    try:
        p = np.broadcast_to(p, F.shape[:-2] + (6,))
    except ValueError:
        raise StructureError(f"bp_params: shape {p.shape} does not match {n} base pairs (need (n, 6))") from None
    if not (np.isfinite(F).all() and np.isfinite(O).all() and np.isfinite(p).all()):
        raise StructureError("rebuild: frames, origins or base-pair parameters contain NaN/inf")
    L1, o1, L2, o2 = base_frames_from_pair(F, O, p)
    blocks, atoms = [], []
    residues = [("A", k + 1, seq1[k], L1[..., k, :, :], o1[..., k, :], k == 0) for k in range(n)]
    residues += [("B", n + 1 + m, seq2[n - 1 - m], L2[..., n - 1 - m, :, :], o2[..., n - 1 - m, :], m == 0)
                 for m in range(n)]
    for chain, num, letter, L, o, five_prime in residues:
        names, local = nucleotide_template(letter)
        keep = [i for i, a in enumerate(names) if not (five_prime and a in ("P", "OP1", "OP2"))]
        blocks.append(np.einsum("...ij,kj->...ki", L, local[keep]) + o[..., None, :])
        atoms += [(chain, num, "D" + letter, names[i], names[i][0]) for i in keep]
    return np.concatenate(blocks, axis=-2), atoms


def pdb_string(xyz, atoms, remark=None):
    """PDB text (Angstrom) of one or more frames via gemmi; several frames become MODELs.

    Parameters
    ----------
    xyz : ndarray, shape (n_atoms, 3) or (n_frames, n_atoms, 3)
        nm.
    atoms : list of (chain, residue number, residue name, atom name, element)
    """
    import gemmi

    X = np.asarray(xyz, float)
    X = X[None] if X.ndim == 2 else X
    st = gemmi.Structure()
    for f in range(X.shape[0]):
        model = gemmi.Model(f + 1)
        chains, res = {}, None
        for (chain, num, rname, aname, el), v in zip(atoms, 10.0 * X[f]):
            if chain not in chains:
                model.add_chain(gemmi.Chain(chain))
                chains[chain] = model[len(model) - 1]
            ch = chains[chain]
            if res is None or res[0] != (chain, num):
                r = gemmi.Residue()
                r.name, r.seqid, r.het_flag = rname, gemmi.SeqId(int(num), " "), "A"
                r.entity_type = gemmi.EntityType.Polymer
                ch.add_residue(r)
                res = ((chain, num), ch[len(ch) - 1])
            a = gemmi.Atom()
            a.name, a.element, a.occ, a.b_iso = aname, gemmi.Element(el), 1.0, 0.0
            a.pos = gemmi.Position(*map(float, v))
            res[1].add_atom(a)
        st.add_model(model)
    st.setup_entities()
    opt = gemmi.PdbWriteOptions()
    opt.cryst1_record = False
    text = st.make_pdb_string(opt)
    if remark:
        text = "".join(f"REMARK   1 {line}\n" for line in remark.splitlines()) + text
    return text


def write_pdb(path, xyz, atoms, remark=None):
    """Write :func:`pdb_string` to ``path`` atomically."""
    text = pdb_string(xyz, atoms, remark)
    with atomic_path(path) as tmp:
        with open(tmp, "w") as fh:
            fh.write(text)


def base_pair_frames(model):
    """Base-pair frames of the bases a model's nodes stand for: the node frames, turned back by 180
    degrees about y where the structure builder reversed them (left-handed pairs,
    ``metadata["bp_reversed"]``).

    Returns
    -------
    ndarray, shape (n, 3, 3)
    """
    flags = model.metadata.get("bp_reversed") if model.metadata else None
    F = np.asarray(model.frames, float)
    if not flags:
        return F
    flags = np.asarray(flags, dtype=bool)
    if flags.shape != (F.shape[0],):
        raise StructureError(f"model metadata bp_reversed has {flags.size} entries for {F.shape[0]} nodes")
    return np.where(flags[:, None, None], F @ np.diag([-1.0, 1.0, -1.0]), F)


def rebuild_model(model, path=None, bp_params=None):
    """All-atom PDB of a :class:`~dnarod.core.model.RodModel` (its nodes are base-pair frames).

    Parameters
    ----------
    model : RodModel
        Needs ``sequence``. Base-pair parameters come from ``bp_params`` or else from
        ``model.metadata["bp_params"]`` (nm, rad; stored by the structure builder), else the
        B-DNA fibre's.
    path : str or Path, optional
        Output PDB file (written atomically).

    Returns
    -------
    xyz : ndarray, shape (n_atoms, 3)
        nm.
    atoms : list
    """
    if not model.sequence:
        raise StructureError("rebuild: the model has no sequence; build it from a sequence or a structure")
    if bp_params is None and "bp_params" in model.metadata:
        bp_params = np.asarray(model.metadata["bp_params"], float)
    xyz, atoms = rebuild_coordinates(base_pair_frames(model), model.positions, model.sequence, bp_params,
                                     model.metadata.get("sequence2"))
    if path is not None:
        write_pdb(path, xyz, atoms, remark=f"rebuilt by dnarod from {model.n_nodes} base-pair frames")
    return xyz, atoms
