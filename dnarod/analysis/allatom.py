"""All-atom DNA trajectories (any format MDAnalysis reads) to node trajectories.

Reading, pairing and base-pair frames are :func:`dnarod.structure.trajectory.read_duplex_trajectory`;
this wraps the result as a :class:`~dnarod.core.trajectory.Trajectory` (base-pair origins as node
positions, nm; pair frames as node frames) that every analysis of :mod:`dnarod.analysis` reads.
"""
from __future__ import annotations

from dnarod.structure.trajectory import ALLATOM_SOURCE, read_duplex_trajectory
from dnarod.core.docs import fill_doc
from dnarod.core.trajectory import Trajectory


@fill_doc(allatom_source=ALLATOM_SOURCE)
def load_allatom(topology, trajectory=None, duplex=0, start=None, stop=None, step=None):
    """Node trajectory of one duplex of an all-atom trajectory.

    Parameters
    ----------
    %(allatom_source)s

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
    r = read_duplex_trajectory(topology, trajectory, duplex, start, stop, step)
    d = r.duplex
    meta = {"sequence": d.sequence, "step_labels": d.step_labels, "topology": str(topology),
            "trajectory": None if trajectory is None else str(trajectory), "duplex": int(duplex),
            "source": "all-atom", "circular": bool(getattr(d, "circular", False))}
    traj = Trajectory(r.time, r.bp_origins, r.bp_frames, step=r.frame_index, metadata=meta)
    return traj, d
