"""All-atom DNA trajectories (any format MDAnalysis reads) to node trajectories.

The duplex and its base pairs are found once, on the topology, by
:func:`dnarod.structure.analysis.analyze_structure`; every frame's base-pair (node) frames
and origins then come from :func:`dnarod.structure.analysis.step_parameters_over_frames`
(standard-base least-squares fits and 3DNA middle frames, vectorised over frames). The result
is a :class:`~dnarod.trajectory.Trajectory` (origins as node positions, nm; pair frames as
node frames) that every analysis of :mod:`dnarod.analysis` reads.
"""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from ..errors import StructureError
from ..trajectory import Trajectory

STRUCTURE_SUFFIXES = {".pdb", ".ent", ".cif", ".mmcif", ".pdbx"}
CHUNK = 500


def _structure_suffix(path):
    suffixes = [s.lower() for s in Path(path).suffixes]
    if suffixes and suffixes[-1] == ".gz":
        suffixes = suffixes[:-1]
    return suffixes[-1] if suffixes else ""


def _universe(topology, trajectory):
    import MDAnalysis as mda

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # MDAnalysis warns about missing elements, box, etc.
        try:
            return mda.Universe(str(topology), str(trajectory)) if trajectory else mda.Universe(str(topology))
        except Exception as exc:  # MDAnalysis raises many exception types for unreadable or mismatched input
            what = f"{trajectory} with topology {topology}" if trajectory else str(topology)
            msg = " ".join(str(exc).split())
            raise StructureError(f"cannot read {what}: {msg}. The trajectory must have the topology's atoms in "
                                 f"the same order") from None


def load_allatom(topology, trajectory=None, duplex=0, start=None, stop=None, step=None):
    """Node trajectory of one duplex of an all-atom trajectory.

    Parameters
    ----------
    topology : str or Path
        Topology: PDB/mmCIF (read with gemmi for pairing), or any MDAnalysis topology
        (PSF, PRMTOP, GRO, TPR, ...; its first frame is written as PDB for pairing).
    trajectory : str or Path, optional
        DCD, XTC, TRR, NetCDF, multi-model PDB, ...; default the topology's own frames.
    duplex : int
        Which duplex (0-based, as found by the pairing).
    start, stop, step : int, optional
        Frame selection.

    Returns
    -------
    traj : Trajectory
        Node positions (base-pair origins, nm) and frames; ``metadata`` holds ``sequence``
        (strand I), ``step_labels``, ``source`` files and ``duplex``.
    duplex : DuplexAnalysis
        The duplex found on the topology.

    Raises
    ------
    StructureError
        Unreadable files, atom counts or names that differ between topology and trajectory,
        no DNA in the topology, no duplex, non-finite coordinates (naming the frame).
    """
    from ..structure.analysis import analyze_structure, step_parameters_over_frames
    from ..structure.reader import OLD_NAMES

    topology = Path(topology)
    if not topology.exists():
        raise StructureError(f"{topology}: no such topology file")
    if trajectory is not None and not Path(trajectory).exists():
        raise StructureError(f"{trajectory}: no such trajectory file")
    u = _universe(topology, trajectory)
    if _structure_suffix(topology) in STRUCTURE_SUFFIXES:
        ana = analyze_structure(topology)
    else:
        import tempfile

        import MDAnalysis as mda

        with tempfile.TemporaryDirectory() as tmp, warnings.catch_warnings():
            warnings.simplefilter("ignore")
            u.trajectory[0]
            ref = Path(tmp) / "first_frame.pdb"
            with mda.Writer(str(ref), multiframe=False) as w:
                w.write(u.atoms)
            ana = analyze_structure(ref)
    if not 0 <= duplex < len(ana.duplexes):
        raise StructureError(f"{topology}: duplex {duplex} does not exist ({len(ana.duplexes)} found, 0-based)")
    d = ana.duplexes[duplex]
    if d.n_bp < 2:
        raise StructureError(f"{topology}: duplex {duplex} has {d.n_bp} base pair; need at least 2")
    if u.atoms.n_atoms != ana.structure.n_atoms:
        raise StructureError(f"{trajectory or topology}: frames have {u.atoms.n_atoms} atoms but the structure read "
                             f"from {topology} has {ana.structure.n_atoms}; the trajectory does not match its topology")
    names = [str(a).strip().replace("*", "'").upper() for a in u.atoms.names]
    for nt in d.strand1 + d.strand2:
        for a, i in nt.atom_index.items():
            if names[i] != a.upper() and OLD_NAMES.get(names[i]) != a:
                raise StructureError(f"{trajectory or topology}: atom {i} is {names[i]} in the trajectory's "
                                     f"topology but {a} of {nt.label} in {topology}; the atom order does not match")
    idx = np.arange(len(u.trajectory))[slice(start, stop, step)]
    if idx.size == 0:
        raise StructureError(f"{trajectory or topology}: the frame selection {start}:{stop}:{step} is empty "
                             f"({len(u.trajectory)} frames)")
    times, origins, frames = [], [], []
    for c0 in range(0, idx.size, CHUNK):
        sel = idx[c0:c0 + CHUNK]
        X, t = [], []
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # MDAnalysis DCDReader timestep-copy notice
            for ts in u.trajectory[sel]:
                X.append(0.1 * ts.positions.astype(float))  # Angstrom -> nm
                t.append(ts.time)
        X = np.array(X)
        bad = ~np.isfinite(X).all(axis=(1, 2))
        if bad.any():
            f = int(sel[np.argmax(bad)])
            raise StructureError(f"{trajectory or topology}: frame {f} has non-finite coordinates")
        _, _, mid, morg = step_parameters_over_frames(d, X)
        frames.append(mid)
        origins.append(morg)
        times.append(t)
    meta = {"sequence": d.sequence, "step_labels": d.step_labels, "topology": str(topology),
            "trajectory": None if trajectory is None else str(trajectory), "duplex": int(duplex),
            "source": "all-atom", "circular": bool(getattr(d, "circular", False))}
    traj = Trajectory(np.concatenate(times), np.concatenate(origins), np.concatenate(frames), step=idx,
                      metadata=meta)
    return traj, d
