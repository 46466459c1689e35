"""dnarod models from structures and from sequences.

:func:`model_from_structure`: one node per base pair of a duplex, at the base-pair frame
origin with the base-pair frame as its directors (d1 = x toward the major groove, d2 = y
toward strand I, d3 = z along the helix), step parameters from a force field for the
detected strand-I sequence, ds, node masses and inertias from the same force field. The
pose is the structure's; the intrinsic shape is the force field's (``intrinsic="sequence"``,
the default) or the structure's own (``intrinsic="structure"``).

:func:`model_from_sequence`: the force field's intrinsic shape
(:meth:`dnarod.core.forcefield.ForceField.model_from_sequence`).

Both return a :class:`~dnarod.core.model.RodModel`, saved and loaded with ``RodModel.save`` /
``RodModel.load`` (``.npz``, format "dnarod-model"). The structure builder records in
``metadata``: the source file, model, duplex, residue ids of both strands, strand II
letters (``sequence2``) and the base-pair parameters of the fitted bases (``bp_params``, nm
and rad) so that :func:`dnarod.structure.rebuild.rebuild_model` puts the bases back where
they were. A left-handed (Z-DNA) pair's node frame is 3DNA's reversed base-pair frame (x and
z negated, so that d3 runs along the helix and the model's strains reproduce 3DNA's steps);
``metadata["bp_reversed"]`` lists those nodes for the rebuild.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import StructureError
from dnarod.core.model import RodModel
from dnarod.structure.analysis import analyze_structure
from dnarod.structure.selection import choose_duplex

INTRINSIC = ("sequence", "structure")


def _forcefield(forcefield):
    from dnarod.core.forcefield import ForceField, load_forcefield

    return forcefield if isinstance(forcefield, ForceField) else load_forcefield(forcefield)


def select_duplex(analysis, duplex=None):
    """``(index, DuplexAnalysis)`` of :func:`dnarod.structure.selection.choose_duplex` (0-based)."""
    sel = choose_duplex(analysis, duplex)
    return sel.index, sel.duplex


def model_from_structure(path=None, forcefield="dna-default", duplex=None, model=1, altloc=None, analysis=None,
                         intrinsic="sequence", **read_options):
    """A RodModel whose nodes are the base pairs of a duplex of a structure file.

    Parameters
    ----------
    path : str or Path
        PDB or mmCIF file.
    forcefield : str, Path or ForceField
        Parameter set: stiffness, ds, masses and (with ``intrinsic="sequence"``) the intrinsic
        shape of the detected sequence (default ``"dna-default"``).
    duplex : int, optional
        Which duplex (0-based, in :func:`analyze_structure` order); default the longest.
    model, altloc, read_options
        Passed to :func:`analyze_structure`.
    analysis : StructureAnalysis, optional
        A ready analysis instead of reading ``path``.
    intrinsic : {"sequence", "structure"}
        ``"sequence"`` (default): the force field's intrinsic strains for the sequence.
        ``"structure"``: the structure's own step strains (:func:`dnarod.core.strains.strains` of the
        base-pair frames with the force field's ds) become the intrinsic shape, so the model's
        zero-energy shape is the input's (a protein-bent DNA keeps its bend); the stiffness is
        still the force field's.

    Returns
    -------
    RodModel
        positions (n, 3) nm at the base-pair origins, frames (n, 3, 3) the base-pair frames.
        ``metadata["selection"]`` is the one-line report of the duplex taken and what was
        dropped (:meth:`~dnarod.structure.selection.DuplexSelection.report`).
    """
    from dnarod.core.parameters import StepParameters
    from dnarod.core.strains import strains

    if intrinsic not in INTRINSIC:
        raise StructureError(f"intrinsic={intrinsic!r}: use 'sequence' (the force field's shape for the sequence) "
                             f"or 'structure' (the input's own step parameters)")
    ana = analysis if analysis is not None else analyze_structure(path, model=model, altloc=altloc, **read_options)
    sel = choose_duplex(ana, duplex)
    k, d = sel.index, sel.duplex
    ff = _forcefield(forcefield)
    seq = d.sequence
    if any(c not in "ACGT" for c in seq):
        raise StructureError(f"{ana.source}: duplex {k + 1} strand I {seq!r} has bases other than A, C, G, T "
                             f"(RNA or inosine); the DNA force fields cannot parametrise it")
    params = ff.step_parameters(seq)
    from dnarod.structure.analysis import check_node_steps

    check_node_steps(d)
    if intrinsic == "structure":
        Om, Ga = strains(d.bp_origins, d.bp_frames, ff.ds)
        params = StepParameters(params.stiffness, np.hstack([Om, Ga]), params.names)
    n = d.n_bp
    from dnarod.structure.conventions import reverse_pair_parameters

    bp_phys = reverse_pair_parameters(d.bp_params) if d.frames_reversed else d.bp_params
    meta = {
        "source": str(ana.source), "model": ana.structure.model, "duplex": k, "forcefield": ff.name,
        "strand1": [nt.rid for nt in d.strand1], "strand2": [nt.rid for nt in d.strand2],
        "sequence2": "".join(nt.base for nt in d.strand2) if all(nt.base in "ACGT" for nt in d.strand2) else None,
        "bp_params": bp_phys.tolist(), "pair_names": list(d.names), "intrinsic": intrinsic,
        "selection": sel.report(), "gaps": list(d.gaps),
    }
    if d.bp_reversed.any():
        meta["bp_reversed"] = [bool(v) for v in d.bp_reversed]
    return RodModel(d.bp_origins.copy(), d.bp_frames.copy(), params, ff.ds, np.full(n, ff.node_mass),
                    np.tile(ff.node_inertia, (n, 1)), sequence=seq, metadata=meta)


def model_from_sequence(sequence, forcefield="dna-default", circular=False):
    """The force field's intrinsic shape for a sequence (strand I, 5'->3').

    Returns
    -------
    RodModel
    """
    return _forcefield(forcefield).model_from_sequence(sequence, circular=circular)
