"""oxDNA topologies, configurations and trajectories as base-pair nodes.

File formats (oxDNA documentation, lorenzo-rovigatti.github.io/oxDNA, "Configuration and
topology files"):

* **classic topology**: a header ``N_nucleotides N_strands``, then one line per nucleotide
  ``strand base n3 n5`` (1-based strand index, base letter, 0-based index of the 3' and the 5'
  neighbour, -1 for none); nucleotides of a strand are listed 3' -> 5'.
* **new topology** (oxDNA >= 3.6): a header ``N_nucleotides N_strands 5->3``, then one line per
  strand: its sequence 5' -> 3' and optional ``key=value`` fields (``circular=true``, ``type=DNA``);
  nucleotides are numbered in that order.
* **configuration**: ``t = T``, ``b = Lx Ly Lz``, ``E = Etot U K``, then one line per
  nucleotide: centre of mass ``r``, backbone-base versor ``a1``, base normal ``a3``, velocity,
  angular velocity (15 numbers; trailing ones may be missing). A trajectory is configurations
  one after the other.

Units: oxDNA length unit 0.8518 nm, time unit 3.03 ps (oxDNA documentation, "Units").

Mapping to dnarod's base-pair frame (stated here; an approximation of 3DNA's frame because
oxDNA has no atoms): the hydrogen-bonding site of a nucleotide is ``r + 0.4 a1`` (oxDNA1 and
oxDNA2); the node centre is the midpoint of the two paired sites; ``d3`` is
``a3(I) - a3(II)`` normalised and oriented 5' -> 3' along strand I; ``d2`` points toward
strand I, ``a1(II) - a1(I)`` made orthogonal to ``d3``; ``d1 = d2 x d3`` (toward the major
groove). Pairs: a nucleotide pairs with the complementary nucleotide of another strand
position whose hydrogen-bonding site is nearest (within 0.35 nm) and whose ``a1`` is
antiparallel (mutual choices). The nodes are the longest run of consecutive pairs along a
strand (strand I: the first strand of that run), like one duplex of a structure file.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from dnarod.core.errors import StructureError
from dnarod.structure.reader import COMPLEMENT

LENGTH_NM = 0.8518      # oxDNA length unit, nm
TIME_PS = 3.03          # oxDNA time unit, ps
HB_SITE = 0.4           # hydrogen-bonding site along a1, oxDNA length units
MAX_SITE_DISTANCE = 0.35  # nm between paired hydrogen-bonding sites


def read_topology(path):
    """Strands of an oxDNA topology (classic or new format).

    Returns
    -------
    bases : list of str
        Base letter per nucleotide (file index order).
    next3 : list of int or None
        Index of the 3' neighbour of each nucleotide.
    strand : list of int
        0-based strand of each nucleotide.
    """
    path = Path(path)
    try:
        lines = [ln.split("#")[0].strip() for ln in path.read_text().splitlines()]
    except (OSError, UnicodeDecodeError) as exc:
        raise StructureError(f"{path}: cannot read the oxDNA topology ({exc})") from None
    lines = [ln for ln in lines if ln]
    if not lines:
        raise StructureError(f"{path}: empty oxDNA topology")
    head = lines[0].split()
    try:
        n, ns = int(head[0]), int(head[1])
    except (ValueError, IndexError):
        raise StructureError(f"{path}, line 1: expected 'N_nucleotides N_strands' (oxDNA topology), got "
                             f"{lines[0]!r}") from None
    bases, next3, strand = [], [], []
    if len(head) > 2 and head[2] == "5->3":  # new format: one strand per line, 5'->3'
        for s, ln in enumerate(lines[1:1 + ns]):
            seq = ln.split()[0].upper()
            circular = "circular=true" in ln.lower()
            start = len(bases)
            for k, c in enumerate(seq):
                bases.append(c)
                strand.append(s)
                next3.append(start + k + 1 if k + 1 < len(seq) else (start if circular else None))
    else:  # classic: strand base n3 n5, listed 3'->5'
        for k, ln in enumerate(lines[1:1 + n]):
            p = ln.split()
            try:
                s, b, n3 = int(p[0]) - 1, p[1].upper(), int(p[2])
            except (ValueError, IndexError):
                raise StructureError(f"{path}, line {k + 2}: expected 'strand base n3 n5', got {ln!r}") from None
            bases.append(b)
            strand.append(s)
            next3.append(n3 if n3 >= 0 else None)
    if len(bases) != n:
        raise StructureError(f"{path}: the header says {n} nucleotides, the file lists {len(bases)}")
    return bases, next3, strand


def read_configurations(path, n):
    """All configurations of an oxDNA configuration or trajectory file.

    Returns
    -------
    time : ndarray (n_frames,)
        oxDNA time units.
    r, a1, a3 : ndarray (n_frames, n, 3)
        Centres (oxDNA length units) and versors.
    """
    path = Path(path)
    times, frames = [], []
    try:
        fh = open(path, errors="replace")  # a binary file then fails the format checks, naming the line
    except OSError as exc:
        raise StructureError(f"{path}: cannot read ({exc})") from None
    with fh:
        lineno = 0
        while True:
            head = [fh.readline() for _ in range(3)]
            lineno += 3
            if not head[0]:
                break
            if not head[0].startswith("t") or "=" not in head[0]:
                raise StructureError(f"{path}, line {lineno - 2}: expected 't = TIME' (an oxDNA configuration), "
                                     f"got {head[0].strip()!r}")
            times.append(float(head[0].split("=")[1]))
            rows = []
            for _ in range(n):
                ln = fh.readline()
                lineno += 1
                vals = ln.split()
                if len(vals) < 9:
                    raise StructureError(f"{path}, line {lineno}: expected 'r a1 a3 [v L]' (9-15 numbers) for "
                                         f"a nucleotide, got {ln.strip()!r} (fewer nucleotides than the topology?)")
                rows.append([float(v) for v in vals[:9]])
            frames.append(rows)
    if not frames:
        raise StructureError(f"{path}: no configuration found")
    X = np.array(frames)
    if not np.isfinite(X).all():
        raise StructureError(f"{path}: non-finite numbers in a configuration")
    return np.array(times), X[..., 0:3], X[..., 3:6], X[..., 6:9]


def _pairs(bases, strand, site, a1):
    """Mutual nearest complementary partners (indices) on the first configuration."""
    from scipy.spatial import cKDTree

    tree = cKDTree(site)
    best = {}
    for i in range(len(bases)):
        for d, j in zip(*tree.query(site[i], k=min(6, len(bases)))):
            if j == i or d > MAX_SITE_DISTANCE / LENGTH_NM or COMPLEMENT.get(bases[i]) != bases[j]:
                continue
            if a1[i] @ a1[j] > -0.5:
                continue
            best[i] = j
            break
    return {i: j for i, j in best.items() if best.get(j) == i}


def duplex_nodes(bases, next3, strand, r, a1, a3):
    """Base-pair node frames of the longest run of consecutive pairs.

    Parameters
    ----------
    r, a1, a3 : ndarray, shape (n_frames, n, 3)
        oxDNA units and versors.

    Returns
    -------
    positions : ndarray (n_frames, n_bp, 3)
        nm.
    frames : ndarray (n_frames, n_bp, 3, 3)
    sequence : str
        Strand I bases 5'->3'.
    pairs : list of (int, int)
        oxDNA nucleotide indices (strand I, strand II).
    """
    site = r + HB_SITE * a1
    partner = _pairs(bases, strand, site[0], a1[0])
    if not partner:
        raise StructureError("oxDNA configuration: no base pairs found (single strands?); dnarod needs a duplex")
    prev5 = {j: i for i, j in enumerate(next3) if j is not None}
    runs, seen = [], set()
    for i in sorted(partner):
        if i in seen or (prev5.get(i) in partner and next3[partner[i]] == partner.get(prev5.get(i))):
            continue  # not the 5' start of a run
        run, k = [], i
        while k is not None and k in partner and k not in seen:
            if run and next3[partner[k]] != partner[run[-1]]:
                break
            run.append(k)
            seen.add(k)
            k = next3[k]
        runs.append(run)
    run = max(runs, key=len)
    if len(run) < 2:
        raise StructureError("oxDNA configuration: no two consecutive base pairs; dnarod needs a duplex")
    i1 = np.array(run)
    i2 = np.array([partner[k] for k in run])
    o = 0.5 * (site[:, i1] + site[:, i2]) * LENGTH_NM
    z = a3[:, i1] - a3[:, i2]
    z /= np.linalg.norm(z, axis=-1, keepdims=True)
    direction = np.einsum("fki,fki->f", z[:, :-1], o[:, 1:] - o[:, :-1])  # orient z 5'->3' along strand I
    z *= np.where(direction < 0, -1.0, 1.0)[:, None, None]
    y = a1[:, i2] - a1[:, i1]
    y -= np.einsum("fki,fki->fk", y, z)[..., None] * z
    y /= np.linalg.norm(y, axis=-1, keepdims=True)
    x = np.cross(y, z)
    return o, np.stack([x, y, z], axis=-1), "".join(bases[k] for k in run), list(zip(run, i2.tolist()))


def read_oxdna(topology, configuration):
    """An oxDNA topology + configuration/trajectory as a dnarod :class:`~dnarod.core.trajectory.Trajectory`.

    Parameters
    ----------
    topology : str or Path
        oxDNA topology (classic or new format).
    configuration : str or Path
        Configuration or trajectory file.

    Returns
    -------
    Trajectory
        Node centres (nm) and base-pair frames per frame; time in ps; metadata ``sequence``,
        ``source`` and the oxDNA indices of the pairs.
    """
    from dnarod.core.trajectory import Trajectory

    bases, next3, strand = read_topology(topology)
    t, r, a1, a3 = read_configurations(configuration, len(bases))
    pos, frm, seq, pairs = duplex_nodes(bases, next3, strand, r, a1, a3)
    return Trajectory(t * TIME_PS, pos, frm, metadata={
        "sequence": seq, "source": f"oxDNA {topology} + {configuration}", "oxdna_pairs": [list(p) for p in pairs]})


def write_oxdna(topology, configuration, positions, frames, sequence, new_format=False, time=0.0, box=100.0):
    """Write a duplex as an oxDNA topology + configuration (the inverse of :func:`read_oxdna`'s mapping).

    Parameters
    ----------
    positions : ndarray (n, 3) or (n_frames, n, 3)
        Node centres, nm.
    frames : ndarray (n, 3, 3) or (n_frames, n, 3, 3)
    sequence : str
        Strand I, 5'->3'.
    new_format : bool
        New (5'->3' per strand) or classic topology.
    """
    P = np.asarray(positions, float)
    F = np.asarray(frames, float)
    if P.ndim == 2:
        P, F = P[None], F[None]
    n = P.shape[1]
    seq2 = "".join(COMPLEMENT[c] for c in reversed(sequence))  # strand II 5'->3'
    # strand I nucleotide k: a1 = -d2 (toward strand II), a3 = d3; strand II: a1 = d2, a3 = -d3
    a1_1, a3_1 = -F[..., 1], F[..., 2]
    a1_2, a3_2 = F[..., 1][:, ::-1], -F[..., 2][:, ::-1]
    o = P / LENGTH_NM
    r1 = o - HB_SITE * a1_1
    r2 = o[:, ::-1] - HB_SITE * a1_2
    # order in the file: strand I then strand II, each 5'->3' (new) or 3'->5' (classic)
    r_all = np.concatenate([r1, r2], axis=1)
    a1_all = np.concatenate([a1_1, a1_2], axis=1)
    a3_all = np.concatenate([a3_1, a3_2], axis=1)
    order = np.arange(2 * n)
    if new_format:
        top = [f"{2 * n} 2 5->3", f"{sequence} type=DNA circular=false", f"{seq2} type=DNA circular=false"]
    else:
        order = np.concatenate([np.arange(n)[::-1], n + np.arange(n)[::-1]])  # 3'->5' per strand
        pos_of = {int(g): k for k, g in enumerate(order)}
        top = [f"{2 * n} 2"]
        letters = sequence + seq2
        for k, g in enumerate(order):
            s = 1 if g < n else 2
            last = n - 1 if g < n else 2 * n - 1
            first = 0 if g < n else n
            n3 = pos_of[g + 1] if g < last else -1
            n5 = pos_of[g - 1] if g > first else -1
            top.append(f"{s} {letters[g]} {n3} {n5}")
    from dnarod.core.io import write_text_atomic

    write_text_atomic(topology, "\n".join(top) + "\n")
    out = []
    for f in range(P.shape[0]):
        out += [f"t = {time + f:g}", f"b = {box:g} {box:g} {box:g}", "E = 0 0 0"]
        for g in order:
            vals = list(r_all[f, g]) + list(a1_all[f, g]) + list(a3_all[f, g]) + [0.0] * 6
            out.append(" ".join(f"{v:.10f}" for v in vals))
    write_text_atomic(configuration, "\n".join(out) + "\n")


def looks_like_oxdna_topology(path):
    """True if ``path`` starts like an oxDNA topology (``N Ns`` or ``N Ns 5->3``)."""
    try:
        with open(path) as fh:
            head = fh.readline().split()
    except (OSError, UnicodeDecodeError):
        return False
    return 2 <= len(head) <= 3 and all(h.isdigit() for h in head[:2]) and (len(head) == 2 or head[2] == "5->3")
