"""All-atom trajectories (any format MDAnalysis reads) to base-pair frames and parameters.

The one reader of all-atom trajectories: the duplex and its base pairs are found once, on the
topology, by :func:`dnarod.structure.analysis.analyze_structure`; every frame's base-pair frames
and parameters then come from :func:`dnarod.structure.analysis.step_parameters_over_frames`
(standard-base least-squares fits, vectorised over frames), read in chunks.
"""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from pathlib import Path
import tempfile

import numpy as np

from dnarod.core.errors import StructureError
from dnarod.core.docs import fill_doc
from dnarod.structure.analysis import analyze_structure, step_parameters_over_frames
from dnarod.structure.reader import OLD_NAMES
from dnarod.structure.cg_topology import is_cg_export, load_cg_trajectory
from dnarod.structure.oxdna import looks_like_oxdna_topology, read_oxdna

STRUCTURE_SUFFIXES = {".pdb", ".ent", ".cif", ".mmcif", ".pdbx"}
CHUNK = 500


@dataclass
class DuplexTrajectory:
    """One duplex over the frames of an all-atom trajectory.

    Attributes
    ----------
    duplex : DuplexAnalysis
        Found on the topology.
    frame_index : ndarray (n_frames,) int
        Trajectory frames read.
    time : ndarray (n_frames,)
        ps.
    step_params : ndarray (n_frames, n_bp - 1, 6)
        shift, slide, rise (nm); tilt, roll, twist (rad).
    pair_params : ndarray (n_frames, n_bp, 6)
        shear, stretch, stagger (nm); buckle, propeller, opening (rad).
    bp_frames : ndarray (n_frames, n_bp, 3, 3)
    bp_origins : ndarray (n_frames, n_bp, 3)
        nm.
    """

    duplex: object
    frame_index: np.ndarray
    time: np.ndarray
    step_params: np.ndarray
    pair_params: np.ndarray
    bp_frames: np.ndarray
    bp_origins: np.ndarray


def _structure_suffix(path):
    suffixes = [s.lower() for s in Path(path).suffixes]
    if suffixes and suffixes[-1] == ".gz":
        suffixes = suffixes[:-1]
    return suffixes[-1] if suffixes else ""


def is_structure_file(path):
    """True for a PDB/mmCIF file name (optionally gzipped), which dnarod reads with gemmi."""
    return _structure_suffix(path) in STRUCTURE_SUFFIXES


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


#: The all-atom sources :func:`read_duplex_trajectory` (and :func:`dnarod.analysis.allatom.load_allatom`) read.
ALLATOM_SOURCE = """\
topology : str or Path
    PDB/mmCIF (read with gemmi for pairing), or any MDAnalysis topology (PSF, PRMTOP, GRO,
    TPR, ...; its first frame is written as PDB for pairing).
trajectory : str or Path, optional
    DCD, XTC, TRR, NetCDF, multi-model PDB, ...; default the topology's own frames.
duplex : int
    Which duplex (0-based, as found by the pairing).
start, stop, step : int, optional
    Frame selection."""


@fill_doc(allatom_source=ALLATOM_SOURCE)
def read_duplex_trajectory(topology, trajectory=None, duplex=0, start=None, stop=None, step=None, model=1):
    """Base-pair frames and parameters of one duplex in every selected frame.

    Parameters
    ----------
    %(allatom_source)s
    model : int
        Model of a PDB/mmCIF topology used for pairing.

    Returns
    -------
    DuplexTrajectory

    Raises
    ------
    StructureError
        Unreadable files, atom counts or names that differ between topology and trajectory,
        no DNA in the topology, no duplex, non-finite coordinates (naming the frame).
    """
    topology = Path(topology)
    if not topology.exists():
        raise StructureError(f"{topology}: no such topology file")
    topology = Path(topology)
    if not topology.exists():
        raise StructureError(f"{topology}: no such topology file")
    if trajectory is not None and not Path(trajectory).exists():
        raise StructureError(f"{trajectory}: no such trajectory file")

    if is_cg_export(topology):
        raise StructureError(f"{topology}: a dnarod coarse-grained export (beads BPC/BPX/BPZ), not an all-atom "
                             f"structure; read it with dnarod.structure.cg_topology.load_cg_trajectory, or analyse "
                             f"the run's exact trajectory.dtraj (dnarod analyze RUNDIR/trajectory.dtraj)")
    u = _universe(topology, trajectory)
    if is_structure_file(topology):
        ana = analyze_structure(topology, model=model)
    else:
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
    times, sp, bp, origins, frames = [], [], [], [], []
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
        s, b, mid, morg = step_parameters_over_frames(d, X)
        sp.append(s)
        bp.append(b)
        frames.append(mid)
        origins.append(morg)
        times.append(t)
    return DuplexTrajectory(d, idx, np.concatenate(times), np.concatenate(sp), np.concatenate(bp),
                            np.concatenate(frames), np.concatenate(origins))


def read_node_trajectory(path, topology=None):
    """Node trajectories that are not all-atom: an oxDNA trajectory or a dnarod coarse-grained export.

    Parameters
    ----------
    path : str or Path
        oxDNA configuration/trajectory (with ``topology`` an oxDNA topology), or an exported
        coarse-grained PDB/DCD/XTC (with ``topology`` its PDB, or the PDB alone).
    topology : str or Path, optional

    Returns
    -------
    dnarod.core.trajectory.Trajectory or None
        None if the input is neither (an all-atom trajectory).
    """
    if topology is not None and looks_like_oxdna_topology(topology):
        return read_oxdna(topology, path)
    if topology is not None and is_cg_export(topology):
        return load_cg_trajectory(topology, path)
    if topology is None and is_cg_export(path):
        return load_cg_trajectory(path)
    return None
