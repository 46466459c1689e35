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

import contextlib
import os
from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.core.trajectory import Trajectory, load_trajectory

from dnarod.structure.cg_topology import cg_pdb_text


def load_dtraj(path):
    """The dnarod loader: a :class:`~dnarod.core.trajectory.Trajectory` with frames bit-exact."""
    return load_trajectory(path)


def mdtraj_topology(n_nodes, residue_names=None, sequence=None):
    """An ``mdtraj.Topology`` with the coarse-grained beads (:mod:`dnarod.structure.cg_topology`)."""
    from dnarod.structure.cg_topology import mdtraj_topology as _top

    return _top(n_nodes, sequence)


def _check_spacing(path, time_ps):
    """The DCD header's (time step ps, start step): the frame times must be evenly spaced."""
    t = np.asarray(time_ps, float)
    dt = float(t[1] - t[0]) if len(t) > 1 else 1.0
    if len(t) > 1 and (dt <= 0 or not np.allclose(np.diff(t), dt, rtol=1e-9, atol=1e-12)):
        raise DnarodError(f"{path}: the frames are not evenly spaced in time, which DCD cannot store; "
                          f"export to XTC instead")
    return dt, int(round(t[0] / dt)) if len(t) > 1 else 0


class _DCDFrames:
    """MDAnalysis's DCD writer fed bead coordinates (nm) frame by frame, through an empty Universe's own time
    step (no per-frame copy of an AtomGroup's time step; the bytes written are the same)."""

    def __init__(self, path, n_atoms, dt, istart):
        import warnings

        import MDAnalysis as mda
        from MDAnalysis.coordinates.DCD import DCDWriter

        self._warnings = warnings.catch_warnings()
        self._warnings.__enter__()
        warnings.simplefilter("ignore")  # MDAnalysis warns about the missing unit cell
        self.u = mda.Universe.empty(n_atoms, trajectory=True)
        self.ts = self.u.trajectory.ts
        self.w = DCDWriter(str(path), n_atoms, dt=dt, istart=istart, nsavc=1)

    def write(self, xyz_nm):
        from dnarod.core.units import ANGSTROM_PER_NM

        for frame in xyz_nm:
            self.ts.positions = frame * ANGSTROM_PER_NM
            self.w.write(self.u)

    def close(self):
        try:
            self.w.close()
        finally:
            self._warnings.__exit__(None, None, None)


def write_dcd(path, xyz_nm, time_ps):
    """Write bead coordinates ``(n_frames, n_atoms, 3)`` nm to a DCD file whose header holds the frame spacing.

    The frame times must be evenly spaced and start at a multiple of the spacing (the DCD header
    stores a start step, a step interval and a time step); MDAnalysis reads ``time = frame * dt``.
    """
    dt, istart = _check_spacing(path, time_ps)
    w = _DCDFrames(path, xyz_nm.shape[1], dt, istart)
    try:
        w.write(xyz_nm)
    finally:
        w.close()


#: Frames converted to bead coordinates at a time by :func:`export_trajectory` (bounds its memory).
EXPORT_CHUNK_FRAMES = 512


def _frame_source(traj):
    """``(n_nodes, time (n_frames,) ps, metadata, chunk)`` of a Trajectory or of a ``.dtraj`` file, whose records
    are read through a memory map; ``chunk(a, b)`` gives the centres ``(b - a, n, 3)`` and frames ``(b - a, n, 3,
    3)`` of frames ``a:b`` as stored (float32 or float64)."""
    if isinstance(traj, Trajectory):
        return traj.n_nodes, traj.time, traj.metadata, lambda a, b: (traj.positions[a:b], traj.frames[a:b])
    from dnarod.core.trajectory import HEADER_SIZE, _read_header, _record_dtype

    path = Path(traj)
    try:
        with open(path, "rb") as fh:
            header = _read_header(fh, path)
        size = path.stat().st_size
    except IsADirectoryError:
        raise DnarodError(f"{path}: is a directory, not a .dtraj trajectory") from None
    except OSError as exc:
        raise DnarodError(f"{path}: cannot read trajectory ({exc.strerror or exc})") from None
    dtype = _record_dtype(header, path)
    n_frames = max(0, size - HEADER_SIZE) // dtype.itemsize  # a trailing partial record is ignored
    rec = (np.memmap(path, dtype=dtype, mode="r", offset=HEADER_SIZE, shape=(n_frames,)) if n_frames
           else np.zeros(0, dtype))
    return (int(header["n_nodes"]), rec["time"].astype(float), header.get("metadata", {}),
            lambda a, b: (rec["positions"][a:b], rec["frames"][a:b]))


def _beads32(positions, frames, arm):
    """``bead_positions(positions, frames, arm).astype(float32)`` (the same values: sums in float64, rounded once)
    without the float64 stack of all beads."""
    pos = np.asarray(positions, float)
    out = np.empty(pos.shape[:2] + (3, 3), np.float32)
    out[:, :, 0] = pos
    out[:, :, 1] = pos + arm * np.asarray(frames[..., :, 0], float)
    out[:, :, 2] = pos + arm * np.asarray(frames[..., :, 2], float)
    return out.reshape(pos.shape[0], -1, 3)


def export_trajectory(traj, pdb_path, dcd_path=None, sequence=None, arm=1.0, xtc_path=None):
    """Write a ``.dtraj`` trajectory (or :class:`Trajectory`) as PDB topology + DCD (+ XTC) frames.

    The frames are converted and written :data:`EXPORT_CHUNK_FRAMES` at a time (a ``.dtraj`` file is read
    through a memory map), so the memory needed does not grow with the length of the run.

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
    int
        Number of frames written.
    """
    from dnarod.core.io import atomic_path, write_text_atomic

    n, time_ps, metadata, chunk = _frame_source(traj)
    n_frames = len(time_ps)
    if n_frames == 0:
        raise DnarodError("the trajectory has no frames to export")
    seq = sequence if sequence is not None else metadata.get("sequence") or None
    if seq is not None and len(seq) != n:
        seq = None
    if pdb_path is not None:
        pos0, frm0 = chunk(0, 1)
        write_text_atomic(Path(pdb_path), cg_pdb_text(np.asarray(pos0[0], float), np.asarray(frm0[0], float), seq,
                                                      arm))
    spacing = refused = None
    if dcd_path is not None:
        try:
            spacing = _check_spacing(dcd_path, time_ps)
        except DnarodError as exc:
            if xtc_path is None:
                raise
            refused = exc  # the XTC, which holds any times, is still written; then this is raised
    n_atoms = 3 * n
    # The C writers (mdtraj's XTC, MDAnalysis's DCD) may stop early on a full disk without an error: each file is
    # read back (its frame count, then its last frame) before it replaces the old one (_verified); a writer's own
    # error becomes one line naming the file (_c_writer).
    with contextlib.ExitStack() as stack:
        writers = []
        if xtc_path is not None:
            from mdtraj.formats import XTCTrajectoryFile

            xtc_path, needed = Path(xtc_path), xtc_bytes(n_frames, n_atoms)
            # mdtraj's XTC writer takes only ASCII paths and picks the format by the extension
            tmp = stack.enter_context(atomic_path(xtc_path, needed=needed, needed_bound=True, ascii=True,
                                                  suffix=".xtc"))
            stack.enter_context(_verified(xtc_path, tmp, n_frames, "xtc", needed))
            stack.enter_context(_c_writer(xtc_path, "xtc", needed))
            xtc = stack.enter_context(XTCTrajectoryFile(str(tmp), "w", force_overwrite=True))
            # nm, the frames' times and step numbers 0, 1, ...: the bytes of mdtraj's Trajectory.save_xtc
            writers.append((xtc_path, "xtc", needed,
                            lambda a, b, xyz: xtc.write(xyz, time=time_ps[a:b], step=np.arange(a, b))))
        if spacing is not None:
            dcd_path, needed_dcd = Path(dcd_path), dcd_bytes(n_frames, n_atoms)
            tmp_dcd = stack.enter_context(atomic_path(dcd_path, needed=needed_dcd))
            stack.enter_context(_verified(dcd_path, tmp_dcd, n_frames, "dcd", needed_dcd))
            stack.enter_context(_c_writer(dcd_path, "dcd", needed_dcd))
            dcd = _DCDFrames(tmp_dcd, n_atoms, *spacing)
            stack.callback(dcd.close)
            writers.append((dcd_path, "dcd", needed_dcd, lambda a, b, xyz: dcd.write(xyz)))
        for a in range(0, n_frames if writers else 0, EXPORT_CHUNK_FRAMES):
            b = min(n_frames, a + EXPORT_CHUNK_FRAMES)
            xyz = _beads32(*chunk(a, b), arm)
            for path, kind, needed, w in writers:
                with _c_writer(path, kind, needed):
                    w(a, b, xyz)
    if refused is not None:
        raise refused
    return n_frames


@contextlib.contextmanager
def _verified(path, tmp, n_frames, kind, needed):
    """On success, refuse a file its C writer left short (:func:`_check_written`) before it replaces the old one."""
    yield
    _check_written(path, tmp, n_frames, kind, needed)


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
