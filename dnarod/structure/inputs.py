"""What the commands accept as a model: a structure, a saved model, a sequence (or a sequence file) or a node count."""
from __future__ import annotations

import re
from pathlib import Path

from dnarod.core.errors import ParameterError

#: Letters of a DNA sequence given on the command line or in a sequence file (strand I, 5'->3').
SEQUENCE_RE = re.compile(r"[ACGTacgt]+")
#: Suffixes of plain sequence files (FASTA or bare letters).
SEQUENCE_SUFFIXES = {".fa", ".fasta", ".fna", ".seq", ".txt"}
#: Most nodes a model may have (10^8 nodes take ~20 GB for the pose alone).
MAX_NODES = 10**8


def read_sequence_file(path):
    """The DNA sequence in a FASTA file (first record) or a plain-text file of letters.

    Whitespace and line breaks are ignored; FASTA header lines (``>``) and comment lines
    (``;``) are skipped; only the first FASTA record is read.

    Raises
    ------
    ParameterError
        No sequence, or letters other than A, C, G, T (naming the first one and its line).
    """
    path = Path(path)
    try:
        lines = path.read_text().splitlines()
    except (OSError, UnicodeDecodeError) as exc:
        raise ParameterError(f"{path}: cannot read the sequence file ({exc})") from None
    seq = []
    seen_header = False
    for i, line in enumerate(lines, 1):
        s = line.strip()
        if s.startswith(">"):
            if seen_header and seq:
                break  # first record only
            seen_header = True
            continue
        if not s or s.startswith(";"):
            continue
        s = "".join(s.split())
        bad = re.search(r"[^ACGTacgt]", s)
        if bad:
            raise ParameterError(f"{path}, line {i}: {bad.group()!r} is not a DNA base (A, C, G, T); "
                                 f"give a FASTA or plain-text file of the strand-I sequence")
        seq.append(s.upper())
    if not seq:
        raise ParameterError(f"{path}: no sequence found (expected FASTA or plain A/C/G/T letters)")
    return "".join(seq)


def _is_file(p):
    try:
        return p.is_file()
    except OSError:  # e.g. a name longer than the file system allows: not a file
        return False


def _check_ring_twist(relaxed, delta_lk):
    """Refuse a linking difference whose twist per step leaves the rod model's Cayley chart (beyond it the
    twist would wrap around by whole turns and the ring would silently hold another linking number)."""
    import numpy as np

    from dnarod.physics.loads import intrinsic_turns
    from dnarod.core.rotations import MAX_CAYLEY_ANGLE

    lk0 = float(intrinsic_turns(relaxed))
    n = relaxed.n_nodes
    per_step = 2 * np.pi * abs(lk0 + delta_lk) / n
    if per_step > 0.8 * MAX_CAYLEY_ANGLE:
        most = int(0.8 * MAX_CAYLEY_ANGLE * n / (2 * np.pi) - abs(lk0))
        raise ParameterError(f"--delta-lk {delta_lk}: sigma = {delta_lk / lk0:+.3g} (Lk0 = {lk0:.1f}) twists each of the "
                             f"{n} steps by {np.degrees(per_step):.0f} deg, beyond the rod model's range "
                             f"({np.degrees(0.8 * MAX_CAYLEY_ANGLE):.0f} deg); use |delta-lk| <= {max(most, 0)} "
                             f"(real DNA denatures beyond |sigma| ~ 0.1)")


def load_model(source, forcefield="dna-default", circular=False, ring=False, delta_lk=0, duplex=None,
               intrinsic="sequence"):
    """A :class:`~dnarod.core.model.RodModel` from a command-line SOURCE.

    Parameters
    ----------
    source : str, Path, int or RodModel
        A PDB/mmCIF file (a duplex of it; nodes at the base-pair frames), a saved model
        ``.npz``, a FASTA or plain-text sequence file (``.fa``, ``.fasta``, ``.fna``, ``.seq``,
        ``.txt``), a DNA sequence of any length (strand I, 5'->3'), a node count (uniform force
        fields), or a model (returned as is).
    forcefield : str
        Bundled name or ``.toml`` path, used for structures, sequences and node counts.
    circular : bool
        Periodic chain (screw-closed intrinsic helix) from a sequence or node count.
    ring : bool
        Closed planar ring from a sequence or node count (:meth:`~dnarod.core.forcefield.ForceField.ring`).
    delta_lk : int
        With ``ring``: linking number relative to the relaxed ring.
    duplex : int, optional
        Which duplex of a structure, 1-based (default the longest).
    intrinsic : {"sequence", "structure"}
        Intrinsic shape of a structure's model: the force field's for its sequence (default) or
        the structure's own step parameters (stiffness still from ``forcefield``).

    Raises
    ------
    ParameterError
        A missing file, an unreadable source or options that do not apply to the source.
    """
    from dnarod.core.forcefield import load_forcefield
    from dnarod.core.model import RodModel
    from dnarod.structure.trajectory import is_structure_file

    if isinstance(source, RodModel):
        return source
    if isinstance(source, int) and not isinstance(source, bool):
        source = str(source)
    source = str(source)
    if duplex is not None and (int(duplex) < 1):
        raise ParameterError(f"--duplex {duplex}: duplexes are numbered from 1 (see `dnarod pairs FILE`)")
    if delta_lk and not ring:
        raise ParameterError("--delta-lk needs --ring")
    if circular and ring:
        raise ParameterError("choose --circular (periodic helix) or --ring (closed ring), not both")
    sequence = None
    if SEQUENCE_RE.fullmatch(source) and not _is_file(Path(source)):
        sequence = source.upper()
    elif not source.isdigit():
        p = Path(source)
        suffix = p.suffix.lower()
        if not _is_file(p):
            if is_structure_file(p) or suffix in SEQUENCE_SUFFIXES | {".npz"}:
                raise ParameterError(f"{source}: file not found")
            raise ParameterError(f"{source[:60]}{'...' if len(source) > 60 else ''}: not a file, a DNA sequence "
                                 f"(letters A, C, G, T), a FASTA/text sequence file or a node count")
        if suffix in SEQUENCE_SUFFIXES:
            sequence = read_sequence_file(p)
        else:
            if circular or ring or delta_lk:
                raise ParameterError("--circular/--ring/--delta-lk apply to a sequence; a model or structure file "
                                     "holds its own chain")
            if is_structure_file(p):
                from dnarod.structure import model_from_structure

                return model_from_structure(p, forcefield=forcefield, duplex=None if duplex is None else duplex - 1,
                                            intrinsic=intrinsic)
            if duplex is not None:
                raise ParameterError("--duplex applies to a structure file (PDB/mmCIF)")
            if intrinsic != "sequence":
                raise ParameterError("--intrinsic structure applies to a structure file (PDB/mmCIF)")
            return RodModel.load(p)
    if duplex is not None:
        raise ParameterError("--duplex applies to a structure file (PDB/mmCIF)")
    if intrinsic != "sequence":
        raise ParameterError("--intrinsic structure applies to a structure file (PDB/mmCIF)")
    ff = load_forcefield(forcefield)
    kw = dict(n_nodes=int(source)) if sequence is None else dict(sequence=sequence)
    if kw.get("n_nodes", 2) < 2:
        raise ParameterError(f"node count {source}: a chain needs at least 2 nodes")
    if kw.get("n_nodes", 0) > MAX_NODES or len(sequence or "") > MAX_NODES:
        raise ParameterError(f"{source[:20]}{'...' if len(source) > 20 else ''}: {kw.get('n_nodes') or len(sequence)} "
                             f"nodes is more than {MAX_NODES:.0e}; give a shorter chain")
    if ring:
        if delta_lk:
            _check_ring_twist(ff.ring(**kw), delta_lk)
        return ff.ring(**kw, delta_linking_number=delta_lk)
    return ff.model_from_sequence(**kw, circular=circular)


def protocol_source(source, min_nodes=2, option="--source"):
    """``(sequence, n_nodes)`` of a protocol's source: a node count or a DNA sequence (one of the two is None).

    A protocol builds its chain with the force field from a count or a sequence; a file (structure, model,
    FASTA) is refused with one line saying so, as are other letters, a chain shorter than ``min_nodes`` and
    one longer than :data:`MAX_NODES`.

    Raises
    ------
    ParameterError
    """
    src = "".join(str(source if source is not None else "").split())
    if not src:
        raise ParameterError(f"{option}: give a node count (e.g. 600) or a DNA sequence")
    if src.isdigit():
        n, seq = int(src), None
    elif SEQUENCE_RE.fullmatch(src):
        n, seq = len(src), src.upper()
    else:
        p = Path(str(source).strip())
        looks_like_file = _is_file(p) or "/" in src or p.suffix.lower() in SEQUENCE_SUFFIXES | {
            ".npz", ".pdb", ".cif", ".mmcif", ".ent", ".gz"}
        short = f"{src[:40]}{'...' if len(src) > 40 else ''}"
        if looks_like_file:
            raise ParameterError(f"{option} {short}: a protocol builds its chain from a node count or a DNA sequence, "
                                 f"not from a file; give the sequence itself or a node count (`dnarod simulate` "
                                 f"reads structure, model and sequence files)")
        raise ParameterError(f"{option} {short}: not a node count or a DNA sequence (letters A, C, G, T)")
    if n < min_nodes:
        raise ParameterError(f"{option} {src if seq is None else seq[:20]}: {n} nodes; this protocol needs at least "
                             f"{min_nodes}")
    if n > MAX_NODES:
        raise ParameterError(f"{option} {src[:20]}: {n} nodes is more than {MAX_NODES:.0e}; give a shorter chain")
    return seq, (n if seq is None else None)

