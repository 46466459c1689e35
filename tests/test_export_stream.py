"""The end-of-run export streams the ``.dtraj`` in chunks and writes the same bytes as whole-trajectory writers."""
import warnings

import numpy as np
import pytest

from dnarod.core.errors import DnarodError
from dnarod.core.forcefield import load_forcefield
from dnarod.core.trajectory import TrajectoryWriter, load_trajectory
from dnarod.structure import export
from dnarod.structure.cg_topology import bead_positions, cg_pdb_text, mdtraj_topology


def _dtraj(path, n_frames=11, seq="ACGTTGCAAC", dt=0.37, start=0):
    m = load_forcefield("dna-default").model_from_sequence(seq)
    rng = np.random.default_rng(4)
    with TrajectoryWriter(path, m.n_nodes, metadata={"sequence": seq}) as w:
        for i in range(n_frames):
            rot = np.linalg.qr(rng.normal(size=(m.n_nodes, 3, 3)))[0]
            w.write(start + 10 * i, (start / 10 + i) * dt, m.positions + rng.normal(scale=0.3, size=m.positions.shape),
                    np.einsum("kab,kbc->kac", rot, m.frames))
    return path


def _reference_files(tr, d, arm=1.0):
    """PDB, XTC and DCD written from the whole trajectory in memory (mdtraj's Trajectory.save_xtc and an
    MDAnalysis DCDWriter fed an AtomGroup per frame): what the export wrote before it streamed."""
    import MDAnalysis as mda
    import mdtraj as md
    from MDAnalysis.coordinates.DCD import DCDWriter

    xyz = bead_positions(tr.positions, tr.frames, arm).astype(np.float32)
    (d / "ref.pdb").write_text(cg_pdb_text(tr.positions[0], tr.frames[0], tr.metadata["sequence"], arm))
    md.Trajectory(xyz, mdtraj_topology(tr.n_nodes, tr.metadata["sequence"]), time=tr.time).save_xtc(str(d / "ref.xtc"))
    dt = tr.time[1] - tr.time[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        u = mda.Universe.empty(xyz.shape[1], trajectory=True)
        with DCDWriter(str(d / "ref.dcd"), xyz.shape[1], dt=dt, istart=int(round(tr.time[0] / dt)), nsavc=1) as w:
            for frame in xyz:
                u.atoms.positions = frame * 10.0
                w.write(u.atoms)


@pytest.mark.parametrize("chunk", [3, 512])
def test_streamed_export_writes_the_same_bytes(tmp_path, monkeypatch, chunk):
    monkeypatch.setattr(export, "EXPORT_CHUNK_FRAMES", chunk)
    src = _dtraj(tmp_path / "t.dtraj", start=20)
    tr = load_trajectory(src)
    _reference_files(tr, tmp_path)
    for name, source in (("file", src), ("memory", tr)):
        out = tmp_path / name
        out.mkdir()
        n = export.export_trajectory(source, out / "t.pdb", out / "t.dcd", xtc_path=out / "t.xtc")
        assert n == tr.n_frames == 11
        for ext in ("pdb", "xtc", "dcd"):
            assert (out / f"t.{ext}").read_bytes() == (tmp_path / f"ref.{ext}").read_bytes(), (name, ext)
    assert sorted(p.name for p in (tmp_path / "file").iterdir()) == ["t.dcd", "t.pdb", "t.xtc"]  # no temporaries


def test_beads_in_float32_equal_the_float64_beads_rounded():
    rng = np.random.default_rng(1)
    pos = rng.normal(scale=50.0, size=(4, 7, 3)).astype(np.float32)
    frm = np.linalg.qr(rng.normal(size=(4, 7, 3, 3)))[0].astype(np.float32)
    for arm in (1.0, 0.37):
        want = bead_positions(pos.astype(float), frm.astype(float), arm).astype(np.float32)
        assert np.array_equal(export._beads32(pos, frm, arm), want)


def test_uneven_frame_times_refuse_the_dcd_after_the_xtc(tmp_path):
    src = tmp_path / "t.dtraj"
    _dtraj(src, n_frames=3)
    with TrajectoryWriter(src, 10, resume_step=20) as w:  # a fourth frame after a gap in time
        t = load_trajectory(src)
        w.write(50, 9.0, t.positions[0], t.frames[0])
    with pytest.raises(DnarodError, match="not evenly spaced"):
        export.export_trajectory(src, tmp_path / "t.pdb", tmp_path / "t.dcd", xtc_path=tmp_path / "t.xtc")
    assert (tmp_path / "t.xtc").exists() and not (tmp_path / "t.dcd").exists()
    with pytest.raises(DnarodError, match="no frames"):
        export.export_trajectory(_dtraj(tmp_path / "e.dtraj", n_frames=0), tmp_path / "e.pdb")
