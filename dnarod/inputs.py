"""What the CLI commands accept as a model: a structure, a saved model, a sequence or a node count."""
from __future__ import annotations

from pathlib import Path

from .errors import ParameterError

def load_model(source, forcefield="dna-default", circular=False, ring=False, delta_lk=0):
    """A :class:`~dnarod.model.RodModel` from a command-line SOURCE.

    Parameters
    ----------
    source : str
        A PDB/mmCIF file (its longest duplex; nodes at the base-pair frames), a saved model
        ``.npz``, a DNA sequence (strand I, 5'->3'), or a node count (uniform force fields).
    forcefield : str
        Bundled name or ``.toml`` path, used for structures, sequences and node counts.
    circular : bool
        Periodic chain (screw-closed intrinsic helix) from a sequence or node count.
    ring : bool
        Closed planar ring from a sequence or node count (:meth:`ForceField.ring`).
    delta_lk : int
        With ``ring``: linking number relative to the relaxed ring.

    Raises
    ------
    ParameterError
        A missing file or options that do not apply to the source.
    """
    from .forcefield import load_forcefield
    from .model import RodModel

    from .structure.trajectory import is_structure_file

    p = Path(source)
    if is_structure_file(p) or p.suffix.lower() == ".npz" or p.is_file():
        if not p.is_file():
            raise ParameterError(f"{source}: file not found")
        if circular or ring or delta_lk:
            raise ParameterError("--circular/--ring/--delta-lk apply to a sequence; a file holds its own chain")
        if not is_structure_file(p):
            return RodModel.load(p)
        from .structure import model_from_structure

        return model_from_structure(p, forcefield=forcefield)
    if delta_lk and not ring:
        raise ParameterError("--delta-lk needs --ring")
    if circular and ring:
        raise ParameterError("choose --circular (periodic helix) or --ring (closed ring), not both")
    ff = load_forcefield(forcefield)
    kw = dict(n_nodes=int(source)) if source.isdigit() else dict(sequence=source)
    if ring:
        return ff.ring(**kw, delta_linking_number=delta_lk)
    return ff.model_from_sequence(**kw, circular=circular)
