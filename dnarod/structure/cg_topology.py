"""The coarse-grained topology of exported rod trajectories, named so MD tools read it sensibly.

One residue per base pair (node), three beads per residue:

========  ================================  ===========================================
bead      position                          meaning
========  ================================  ===========================================
``BPC``   node centre                       base-pair origin
``BPX``   centre + a d1 (a = 1 nm)          tip of d1 (toward the major groove)
``BPZ``   centre + a d3                     tip of d3 (along the helix, 5'->3' strand I)
========  ================================  ===========================================

d2 = d3 x d1. The bead names collide with no PDB atom name of proteins or nucleic acids and
the element is ``VS`` (virtual site; mdtraj's ``virtual`` element; MDAnalysis reads it as an
unknown element and leaves the element empty), so no tool mistakes a bead for a carbon or a
C-alpha. Residue names are the DNA residue of the strand-I base of the pair (``DA`` = A-T,
``DC`` = C-G, ``DG`` = G-C, ``DT`` = T-A; strand II is the complement in dnarod's models),
so ``select_atoms("nucleic")`` in MDAnalysis and ``top.select("dna")``-style selections find
them; ``DN`` when the model has no sequence. Bonds (CONECT): ``BPC-BPX``, ``BPC-BPZ`` and
``BPC(k)-BPC(k+1)``. Residue numbers run 1..9999 in a chain; longer chains continue in the
next chain ID (A-Z, a-z, 0-9; node k is chain ``k // 9999``, residue ``k % 9999 + 1``), so
the numbers stay valid PDB for up to 619,938 base pairs; atom serial numbers beyond 99,999
use the hybrid-36 encoding (as gemmi and MDAnalysis read it). The mapping is written as
REMARK 250 lines at the top of every exported PDB.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.docs import fill_doc
from dnarod.core.trajectory import Trajectory
from dnarod.core.io import ascii_alias

BEADS = ("BPC", "BPX", "BPZ")
ELEMENT = "VS"
PER_CHAIN = 9999
CHAIN_IDS = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789"
RESIDUE = {"A": "DA", "C": "DC", "G": "DG", "T": "DT"}
UNKNOWN = "DN"
MARKER = "dnarod coarse-grained rod"

REMARK = (
    f"{MARKER}: one residue per base pair, three beads (element {ELEMENT}, virtual site)",
    "BPC = base-pair centre; BPX = centre + ARM d1 (major groove); BPZ = centre + ARM d3 (helix axis)",
    "d2 = d3 x d1. Residue DA/DC/DG/DT = strand-I base of the pair (strand II complementary); DN = no sequence",
    "chains hold 9999 residues each (node k: chain k // 9999, residue k % 9999 + 1); serials > 99999 hybrid-36",
    "exact float64 frames: the run's trajectory.dtraj (dnarod analyze RUNDIR/trajectory.dtraj)",
)


def residue_names(sequence, n_nodes):
    """Residue name per node: the DNA residue of the strand-I base, ``DN`` without a sequence."""
    if sequence is None or len(sequence) != n_nodes:
        return [UNKNOWN] * n_nodes
    return [RESIDUE.get(c.upper(), UNKNOWN) for c in sequence]


def chain_and_number(k):
    """(chain ID, residue number) of node ``k`` (0-based)."""
    c = k // PER_CHAIN
    if c >= len(CHAIN_IDS):
        raise DnarodError(f"base pair {k + 1}: more than {PER_CHAIN * len(CHAIN_IDS)} base pairs do not fit PDB chain "
                          f"IDs; export the frames with the .dtraj trajectory instead")
    return CHAIN_IDS[c], k % PER_CHAIN + 1


def hy36(value, width=5):
    """Hybrid-36 encoding of an integer in ``width`` characters (decimal while it fits).

    The scheme of Grosse-Kunstleve et al. (cctbx, "hybrid-36"), used by PDB writers for
    serial numbers past 99,999: after the decimal range come upper-case base-36 numbers
    starting at ``A0000``, then lower-case ones. Written here because it is ten lines and the
    writers that have it (gemmi) do not write this topology's CONECT records.
    """
    digits = "0123456789ABCDEFGHIJKLMNOPQRSTUVWXYZ"
    if value < 10 ** width:
        return f"{value:>{width}d}"
    value -= 10 ** width
    for first, base in ((10, digits), (10, digits.lower())):
        span = 26 * 36 ** (width - 1)
        if value < span:
            v, out = value + first * 36 ** (width - 1), ""
            for _ in range(width):
                v, r = divmod(v, 36)
                out = base[r] + out
            return out
        value -= span
    raise DnarodError(f"atom serial {value} is too large for hybrid-36 in {width} characters")


@fill_doc
def cg_pdb_text(positions, frames, sequence=None, arm=1.0, remark_extra=()):
    """PDB text (Angstrom) of one frame of the coarse-grained topology, with REMARK and CONECT.

    Parameters
    ----------
    %(pose)s
    sequence : str, optional
        Strand I letters.
    arm : float
        Tip distance, nm.
    """
    pos = np.asarray(positions, float)
    frm = np.asarray(frames, float)
    n = pos.shape[0]
    beads = np.stack([pos, pos + arm * frm[:, :, 0], pos + arm * frm[:, :, 2]], axis=1) * 10.0
    names = residue_names(sequence, n)
    lines = [f"REMARK 250 {line.replace('ARM', f'{arm:g} nm')}" for line in REMARK]
    lines += [f"REMARK 250 {line}" for line in remark_extra]
    serial = 0
    prev_chain = None
    for k in range(n):
        ch, num = chain_and_number(k)
        if prev_chain is not None and ch != prev_chain:
            lines.append("TER")
        prev_chain = ch
        for b, name in enumerate(BEADS):
            serial += 1
            x, y, z = beads[k, b]
            lines.append(f"ATOM  {hy36(serial)} {name:<4s} {names[k]:>3s} {ch}{num:>4d}    "
                         f"{x:8.3f}{y:8.3f}{z:8.3f}  1.00  0.00          {ELEMENT:>2s}")
    lines.append("TER")
    for k in range(n):
        c = 3 * k + 1
        partners = [c + 1, c + 2] + ([c + 3] if k + 1 < n else [])
        lines.append("CONECT" + "".join(hy36(v) for v in [c] + partners))
    lines.append("END")
    return "\n".join(lines) + "\n"


def mdtraj_topology(n_nodes, sequence=None):
    """The same topology as an ``mdtraj.Topology`` (for writing DCD/XTC frames through mdtraj)."""
    import mdtraj as md

    top = md.Topology()
    names = residue_names(sequence, n_nodes)
    chains, prev = {}, None
    for k in range(n_nodes):
        ch, num = chain_and_number(k)
        if ch not in chains:
            chains[ch] = top.add_chain()
        res = top.add_residue(names[k], chains[ch], resSeq=num)
        atoms = [top.add_atom(name, md.element.virtual, res) for name in BEADS]
        top.add_bond(atoms[0], atoms[1])
        top.add_bond(atoms[0], atoms[2])
        if prev is not None:
            top.add_bond(prev, atoms[0])
        prev = atoms[0]
    return top


def is_cg_export(path):
    """True if ``path`` is a PDB written by :func:`cg_pdb_text` (its REMARK or its bead names)."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(8192).decode("ascii", "replace")
    except OSError:
        return False
    if MARKER in head:
        return True
    atoms = [ln[12:16].strip() for ln in head.splitlines() if ln.startswith(("ATOM", "HETATM"))]
    return bool(atoms) and set(atoms) <= set(BEADS) | {"CA", "D1", "D3"} and ("BPC" in atoms or "D1" in atoms)


def load_cg_trajectory(pdb_path, trajectory_path=None, arm=1.0):
    """Node centres and frames from an exported coarse-grained PDB (+ DCD/XTC), float32 precision.

    Returns
    -------
    dnarod.core.trajectory.Trajectory
        Frames re-orthonormalised from the beads (``d2 = d3 x d1``).
    """
    import mdtraj as md



    with ascii_alias(pdb_path, trajectory_path) as (pdb, trj):  # mdtraj's C readers take only ASCII paths
        t = md.load(trj, top=pdb) if trj else md.load(pdb)
    if t.n_atoms % 3:
        raise DnarodError(f"{pdb_path}: {t.n_atoms} atoms is not three beads per node; not a dnarod export")
    c, f = frames_from_beads(t.xyz.astype(float))
    return Trajectory(np.asarray(t.time, float), c, f, metadata={"source": str(trajectory_path or pdb_path)})


def bead_positions(positions, frames, arm=1.0):
    """Bead coordinates ``(n_frames, 3 n_nodes, 3)`` nm from centres and frames.

    Parameters
    ----------
    positions : ndarray, shape (n_frames, n_nodes, 3)
    frames : ndarray, shape (n_frames, n_nodes, 3, 3)
    arm : float
        Director tip distance, nm.
    """
    pos = np.asarray(positions, float)
    frm = np.asarray(frames, float)
    out = np.stack([pos, pos + arm * frm[..., :, 0], pos + arm * frm[..., :, 2]], axis=-2)
    return out.reshape(pos.shape[0], -1, 3)


def frames_from_beads(xyz):
    """Centres and orthonormal frames from bead coordinates ``(n_frames, 3 n_nodes, 3)``."""
    b = np.asarray(xyz, float).reshape(xyz.shape[0], -1, 3, 3)
    c = b[:, :, 0]
    d1 = b[:, :, 1] - c
    d1 /= np.linalg.norm(d1, axis=-1, keepdims=True)
    d3 = b[:, :, 2] - c
    d3 -= np.einsum("fki,fki->fk", d3, d1)[..., None] * d1
    d3 /= np.linalg.norm(d3, axis=-1, keepdims=True)
    d2 = np.cross(d3, d1)
    return c, np.stack([d1, d2, d3], axis=-1)
