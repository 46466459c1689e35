"""dnarod models from structures and from sequences.

:func:`model_from_structure`: one node per base pair of a duplex, at the base-pair frame
origin with the base-pair frame as its directors (d1 = x toward the major groove, d2 = y
toward strand I, d3 = z along the helix), step parameters from a force field for the
detected strand-I sequence, ds, node masses and inertias from the same force field. The
pose is the structure's; the intrinsic shape is the force field's.

:func:`model_from_sequence`: the force field's intrinsic shape
(:meth:`dnarod.forcefield.ForceField.model_from_sequence`).

Both return a :class:`~dnarod.model.RodModel`, saved and loaded with ``RodModel.save`` /
``RodModel.load`` (``.npz``, format "dnarod-model"). The structure builder records in
``metadata``: the source file, model, duplex, residue ids of both strands, strand II
letters (``sequence2``) and the base-pair parameters (``bp_params``, nm and rad) so that
:func:`dnarod.structure.rebuild.rebuild_model` puts the bases back where they were.
"""
from __future__ import annotations

import numpy as np

from ..errors import StructureError
from ..model import RodModel
from .analysis import analyze_structure


def _forcefield(forcefield):
    from ..forcefield import ForceField, load_forcefield

    return forcefield if isinstance(forcefield, ForceField) else load_forcefield(forcefield)


def select_duplex(analysis, duplex=None):
    """The duplex to model: index ``duplex`` (0-based) or, by default, the longest.

    Raises
    ------
    StructureError
        If the index does not exist or the duplex has fewer than 2 base pairs.
    """
    dups = analysis.duplexes
    if duplex is None:
        duplex = int(np.argmax([d.n_bp for d in dups]))
    if not 0 <= duplex < len(dups):
        raise StructureError(f"{analysis.source}: duplex {duplex + 1} does not exist; found {len(dups)} "
                             f"({', '.join(str(d.n_bp) + ' bp' for d in dups)}), numbered from 1 "
                             f"(from 0 in the Python API)")
    d = dups[duplex]
    if d.n_bp < 2:
        raise StructureError(f"{analysis.source}: duplex {duplex} has {d.n_bp} base pair; a model needs at least 2")
    return duplex, d


def model_from_structure(path=None, forcefield="dna-default", duplex=None, model=1, altloc=None, analysis=None,
                         **read_options):
    """A RodModel whose nodes are the base pairs of a duplex of a structure file.

    Parameters
    ----------
    path : str or Path
        PDB or mmCIF file.
    forcefield : str, Path or ForceField
        Parameter set for the detected sequence (default ``"dna-default"``).
    duplex : int, optional
        Which duplex (0-based, in :func:`analyze_structure` order); default the longest.
    model, altloc, read_options
        Passed to :func:`analyze_structure`.
    analysis : StructureAnalysis, optional
        A ready analysis instead of reading ``path``.

    Returns
    -------
    RodModel
        positions (n, 3) nm at the base-pair origins, frames (n, 3, 3) the base-pair frames.
    """
    ana = analysis if analysis is not None else analyze_structure(path, model=model, altloc=altloc, **read_options)
    k, d = select_duplex(ana, duplex)
    ff = _forcefield(forcefield)
    seq = d.sequence
    if any(c not in "ACGT" for c in seq):
        raise StructureError(f"{ana.source}: duplex {k} strand I {seq!r} has bases other than A, C, G, T "
                             f"(RNA or inosine); the DNA force fields cannot parametrise it")
    params = ff.step_parameters(seq)
    n = d.n_bp
    meta = {
        "source": str(ana.source), "model": ana.structure.model, "duplex": k, "forcefield": ff.name,
        "strand1": [nt.rid for nt in d.strand1], "strand2": [nt.rid for nt in d.strand2],
        "sequence2": "".join(nt.base for nt in d.strand2) if all(nt.base in "ACGT" for nt in d.strand2) else None,
        "bp_params": d.bp_params.tolist(), "pair_names": list(d.names),
    }
    return RodModel(d.bp_origins.copy(), d.bp_frames.copy(), params, ff.ds, np.full(n, ff.node_mass),
                    np.tile(ff.node_inertia, (n, 1)), sequence=seq, metadata=meta)


def model_from_sequence(sequence, forcefield="dna-default", circular=False):
    """The force field's intrinsic shape for a sequence (strand I, 5'->3').

    Returns
    -------
    RodModel
    """
    return _forcefield(forcefield).model_from_sequence(sequence, circular=circular)
