"""Export trajectories of node centres and frames for MD tools (mdtraj, MDAnalysis, VMD).

Coarse-grained topology (names, elements, residues, chains and the REMARK that documents
them): :mod:`dnarod.structure.cg_topology` -- beads ``BPC`` (node centre), ``BPX`` (tip of
d1 at ``centre + a d1``), ``BPZ`` (tip of d3), ``a = 1 nm`` by default. The first frame goes to
a PDB file (the topology) and all frames to a DCD file (float32, Angstrom) whose header holds the
true time between frames (written with MDAnalysis, which reads the frame times back equal to the
``.dtraj`` times to the header's float32 precision; mdtraj's DCD reader ignores the header's time
and numbers the frames), and optionally to an XTC file (mdtraj; each frame stores its time, read
back by both mdtraj and MDAnalysis). The frames are recovered from the beads by
:func:`dnarod.structure.cg_topology.frames_from_beads` (``d2 = d3 x d1``), to float32 precision; the ``.dtraj`` file
(:func:`load_dtraj`) holds them as the run stored them.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.trajectory import Trajectory, load_trajectory

from dnarod.structure.cg_topology import bead_positions, cg_pdb_text


def load_dtraj(path):
    """The dnarod loader: a :class:`~dnarod.core.trajectory.Trajectory` with frames bit-exact."""
    return load_trajectory(path)


def mdtraj_topology(n_nodes, residue_names=None, sequence=None):
    """An ``mdtraj.Topology`` with the coarse-grained beads (:mod:`dnarod.structure.cg_topology`)."""
    from dnarod.structure.cg_topology import mdtraj_topology as _top

    return _top(n_nodes, sequence)


def write_dcd(path, xyz_nm, time_ps):
    """Write bead coordinates ``(n_frames, n_atoms, 3)`` nm to a DCD file whose header holds the frame spacing.

    The frame times must be evenly spaced and start at a multiple of the spacing (the DCD header
    stores a start step, a step interval and a time step); MDAnalysis reads ``time = frame * dt``.
    """
    import warnings

    import MDAnalysis as mda
    from MDAnalysis.coordinates.DCD import DCDWriter

    from dnarod.core.units import ANGSTROM_PER_NM

    t = np.asarray(time_ps, float)
    dt = float(t[1] - t[0]) if len(t) > 1 else 1.0
    if len(t) > 1 and (dt <= 0 or not np.allclose(np.diff(t), dt, rtol=1e-9, atol=1e-12)):
        raise DnarodError(f"{path}: the frames are not evenly spaced in time, which DCD cannot store; "
                          f"export to XTC instead")
    istart = int(round(t[0] / dt)) if len(t) > 1 else 0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # MDAnalysis warns about the missing unit cell
        u = mda.Universe.empty(xyz_nm.shape[1], trajectory=True)
        with DCDWriter(str(path), xyz_nm.shape[1], dt=dt, istart=istart, nsavc=1) as w:
            for frame in xyz_nm:
                u.atoms.positions = frame * ANGSTROM_PER_NM
                w.write(u.atoms)


def export_trajectory(traj, pdb_path, dcd_path=None, sequence=None, arm=1.0, xtc_path=None):
    """Write a ``.dtraj`` trajectory (or :class:`Trajectory`) as PDB topology + DCD (+ XTC) frames.

    Parameters
    ----------
    traj : Trajectory or str or Path
    pdb_path : str or Path
        First frame with the topology (CONECT records for the bonds).
    dcd_path : str or Path or None
        All frames with the true frame spacing in the header (skip if None).
    xtc_path : str or Path or None
        All frames with their times (mdtraj XTC, 0.001 nm precision; skip if None).
    sequence : str or None
        Strand I letters for residue names (default: the trajectory's metadata ``sequence``).
    arm : float
        nm.

    Returns
    -------
    mdtraj.Trajectory
    """
    import mdtraj as md

    from dnarod.core.io import atomic_path, write_text_atomic

    if not isinstance(traj, Trajectory):
        traj = load_trajectory(traj)
    if traj.n_frames == 0:
        raise DnarodError("the trajectory has no frames to export")
    n = traj.n_nodes
    seq = sequence if sequence is not None else traj.metadata.get("sequence") or None
    if seq is not None and len(seq) != n:
        seq = None
    top = mdtraj_topology(n, sequence=seq)
    xyz = bead_positions(traj.positions, traj.frames, arm).astype(np.float32)
    t = md.Trajectory(xyz, top, time=traj.time)
    n_atoms = xyz.shape[1]
    if pdb_path is not None:
        text = cg_pdb_text(traj.positions[0], traj.frames[0], seq, arm)
        write_text_atomic(Path(pdb_path), text)
    # The C writers (mdtraj's XTC, MDAnalysis's DCD) may stop early on a full disk without an error: each file is
    # read back (its frame count) before it replaces the old one.
    if xtc_path is not None:
        # mdtraj's XTC writer takes only ASCII paths: an ASCII temporary name, reached by an ASCII path
        needed = xtc_bytes(traj.n_frames, n_atoms)
        with atomic_path(Path(xtc_path), needed=needed, needed_bound=True, ascii=True, suffix=".xtc") as tmp:
            with _c_writer(xtc_path, "xtc", needed):
                t.save_xtc(tmp, force_overwrite=True)
            _check_written(xtc_path, tmp, traj.n_frames, "xtc", needed)
    if dcd_path is not None:
        needed = dcd_bytes(traj.n_frames, n_atoms)
        with atomic_path(Path(dcd_path), needed=needed) as tmp:
            with _c_writer(dcd_path, "dcd", needed):
                write_dcd(tmp, xyz, traj.time)
            _check_written(dcd_path, tmp, traj.n_frames, "dcd", needed)
    return t


class _c_writer:
    """A C writer's error (mdtraj's ``XTC write error: 7``, with no errno) as one line naming ``path``: a full disk
    with its free space, else the writer's words and the free space (a quota or a file-size limit?)."""

    def __init__(self, path, kind, needed):
        self.path, self.kind, self.needed = Path(path), kind, needed

    def __enter__(self):
        return self

    def __exit__(self, typ, exc, tb):
        from dnarod.core.io import WriteError, disk_free, human_bytes, write_failure

        if exc is None or isinstance(exc, DnarodError) or not isinstance(exc, (OSError, RuntimeError, IOError)):
            return False
        err = write_failure(self.path, exc, self.needed, needed_bound=self.kind == "xtc")
        if err is None:
            free = disk_free(self.path.parent)
            what = " ".join(str(exc).split())[:120] or type(exc).__name__
            err = WriteError(f"cannot write {self.path}: the {self.kind.upper()} writer failed ({what}; "
                             f"{human_bytes(free) if free is not None else 'unknown space'} free on its disk: a quota "
                             f"or a file-size limit?); the files written before are kept", self.path, None, free,
                             self.needed)
        raise err from None


def _frames_in(tmp, kind):
    """Frames a written XTC or DCD file holds, -1 if its last frame cannot be read (a file cut short); what the C
    readers print on fd 2 is dropped. XTC: the frame count from the frame headers, then the last frame decoded
    (one frame in memory); DCD: fixed-size records, the count from the file size."""
    import os

    saved = os.dup(2)
    try:
        with open(os.devnull, "w") as null:
            os.dup2(null.fileno(), 2)
        try:
            if kind == "xtc":
                from mdtraj.formats import XTCTrajectoryFile

                with XTCTrajectoryFile(str(tmp)) as f:
                    n = len(f)
                    if n:
                        f.seek(n - 1)
                        if len(f.read(1)[0]) != 1:
                            return -1
                    return n
            from MDAnalysis.lib.formats.libdcd import DCDFile

            with DCDFile(str(tmp)) as f:
                return int(f.n_frames)
        except Exception:  # noqa: BLE001 - a truncated or unreadable file holds no complete frame set
            return -1
    finally:
        os.dup2(saved, 2)
        os.close(saved)


def _check_written(path, tmp, n_frames, kind, needed):
    """Refuse a file its C writer left short (one line naming ``path``: a full disk with the free space, else
    the frames it holds)."""
    from dnarod.core.io import WriteError, disk_free, human_bytes, write_failure

    got = _frames_in(tmp, kind)
    if got == n_frames:
        return
    free = disk_free(Path(path).parent)
    if free is not None and free < needed:
        import errno

        raise write_failure(path, OSError(errno.ENOSPC, "No space left on device"), needed, needed_bound=kind == "xtc")
    held = f"{got} of its {n_frames} frames" if got >= 0 else f"none of its {n_frames} frames readably"
    raise WriteError(f"cannot write {path}: the {kind.upper()} writer stopped early (the file held {held}; "
                     f"{human_bytes(free) if free is not None else 'unknown space'} free on its disk; a quota or a "
                     f"file-size limit?); the files written before are kept", Path(path), None, free, needed)


def dcd_bytes(n_frames, n_atoms):
    """Size of the DCD file :func:`write_dcd` writes (``n_frames`` frames of ``n_atoms`` atoms), bytes: a 356-byte
    header, then per frame a unit-cell record (56 bytes) and three float32 records of x, y, z."""
    return 356 + n_frames * (56 + 3 * (4 * n_atoms + 8))


def xtc_bytes(n_frames, n_atoms):
    """Upper estimate of an XTC file's size (``n_frames`` frames, ``n_atoms`` atoms), bytes: the compressed
    coordinates take at most the 12 bytes of three float32 per atom, plus a 92-byte frame header."""
    return n_frames * (92 + 12 * n_atoms)
