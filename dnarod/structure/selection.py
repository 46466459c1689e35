"""Which duplex of a structure a model is built from, and what is left out.

A structure file may hold several duplexes, protein, ions, ligands and water. Every command
that turns a structure into a model takes one duplex (``--duplex N``, 1-based on the command
line, 0-based in the Python API; default the longest) and says so: :func:`choose_duplex`
returns a :class:`DuplexSelection` whose :meth:`~DuplexSelection.report` names the duplex
taken and everything dropped (other duplexes, protein, ions/ligands, water, unpaired
nucleotides), for the CLI to print and for the model's metadata.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dnarod.core.errors import StructureError


@dataclass
class DuplexSelection:
    """The duplex taken from a structure.

    Attributes
    ----------
    index : int
        0-based index of the duplex among ``analysis.duplexes``.
    duplex : DuplexAnalysis
    n_duplexes : int
    source : str
    dropped : list of str
        What the model leaves out, one item per kind.
    """

    index: int
    duplex: object
    n_duplexes: int
    source: str
    dropped: list = field(default_factory=list)

    def describe(self):
        """``duplex 1 of 2 (147 bp, strand I I:-73..I:73)``."""
        d = self.duplex
        return (f"duplex {self.index + 1} of {self.n_duplexes} ({d.n_bp} bp, strand I "
                f"{d.strand1[0].rid}..{d.strand1[-1].rid}, strand II {d.strand2[0].rid}..{d.strand2[-1].rid})")

    def report(self):
        """One line: the duplex taken, what was dropped and which modified nucleotides it models as parents."""
        drop = "; ".join(self.dropped) if self.dropped else "nothing"
        d = self.duplex
        mod = [f"{nt.rid} {nt.resname}->{nt.base}" for nt in list(d.strand1) + list(d.strand2) if nt.modified]
        kept = f"; modified nucleotides modelled as their parent base: {', '.join(mod)}" if mod else ""
        rev = np.asarray(getattr(d, "bp_reversed", np.zeros(0, dtype=bool)), dtype=bool)
        if rev.any():
            ids = [f"{d.strand1[k].rid}/{d.strand2[k].rid}" for k in np.flatnonzero(rev)]
            kept += (f"; left-handed (Z-DNA) pairs {ids[0]}..{ids[-1]} ({rev.sum()} of {d.n_bp}): their node frames "
                     f"are 3DNA's reversed base-pair frames, so the model runs along the helix with positive rise "
                     f"and negative twist there")
        return f"{self.source}: took {self.describe()}; dropped: {drop}{kept}"


def _dropped(analysis, index):
    out = []
    for k, d in enumerate(analysis.duplexes):
        if k != index:
            out.append(f"duplex {k + 1} ({d.n_bp} bp, {d.strand1[0].rid}..{d.strand1[-1].rid})")
    for line in analysis.structure.skipped:
        if line.startswith("ignored "):
            out.append(line[len("ignored "):])
        elif "ignored on request" in line or "skipped" in line:
            out.append(line)
    for line in analysis.skipped:
        if line.startswith("unpaired nucleotides"):
            out.append(line)
    return out


def choose_duplex(analysis, duplex=None):
    """The duplex to model: index ``duplex`` (0-based) or, by default, the longest.

    Parameters
    ----------
    analysis : StructureAnalysis
    duplex : int, optional
        0-based index (the CLI's ``--duplex N`` is ``N - 1``).

    Returns
    -------
    DuplexSelection

    Raises
    ------
    StructureError
        If the index does not exist or the duplex has fewer than 2 base pairs.
    """
    dups = analysis.duplexes
    if duplex is None:
        duplex = int(np.argmax([d.n_bp for d in dups]))
    duplex = int(duplex)
    if not 0 <= duplex < len(dups):
        raise StructureError(f"{analysis.source}: duplex {duplex + 1} does not exist; found {len(dups)} "
                             f"({', '.join(str(d.n_bp) + ' bp' for d in dups)}), numbered from 1 on the command "
                             f"line (--duplex N), from 0 in the Python API")
    d = dups[duplex]
    if d.n_bp < 2:
        raise StructureError(f"{analysis.source}: duplex {duplex + 1} has {d.n_bp} base pair; a model needs at "
                             f"least 2 (choose another with --duplex N)")
    return DuplexSelection(duplex, d, len(dups), str(analysis.source), _dropped(analysis, duplex))
