"""Fault injection: full disks at every stage, unusual paths for every command that writes, and silent nonsense.

A full disk is simulated in-process (:class:`DiskFull`: every file opened for writing under a folder fails with
ENOSPC once a byte budget is spent, part of the last write landing first, as on a real disk) and, where the
machine allows user namespaces, on a real tmpfs of a few hundred kB (``unshare -rm``, ``test_real_full_disk``).
C writers that bypass Python's files (mdtraj's XTC, MDAnalysis's DCD, pyarrow) are made to fail the way they fail
on a full disk (an error code, or a short file and no error). Every fault must give one line on stderr naming the
file, exit status 2, leave no temporary file and change nothing written before (checksums), and a run must
still resume. The table of faults is docs/faults.md.
"""
from __future__ import annotations

import builtins
import errno
import hashlib
import io
import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import dnarod.core.io as dio
from dnarod.cli.main import main
from dnarod.core.errors import ParameterError

SEQ = "ACGTACGTACGTACGTACGT"
#: A 20-node Lax-form run of ~190 steps, 40 frames, a checkpoint every 10 frames (bit-exact resume).
RUN = ["--engine", "lax", "--time", "0.02", "--frame-interval", "0.5", "--seed", "7", "--no-progress"]
ODD = "ün dir/räum run"  # a space and non-ASCII letters in the folder and the run's name


# ----------------------------------------------------------------------------------------------------------
# helpers
# ----------------------------------------------------------------------------------------------------------
class _Budget:
    def __init__(self, budget, match):
        self.left = int(budget)
        self.match = match
        self.tripped = False


class _Budgeted:
    """A file object whose writes spend a shared byte budget; past it the write lands partly and raises ENOSPC."""

    def __init__(self, fh, state):
        self._fh, self._state = fh, state

    def write(self, data):
        st = self._state
        n = len(data)
        if n <= st.left:
            st.left -= n
            return self._fh.write(data)
        self._fh.write(data[:st.left])
        st.left, st.tripped = 0, True
        raise OSError(errno.ENOSPC, "No space left on device")

    def writelines(self, lines):
        for line in lines:
            self.write(line)

    def __getattr__(self, name):
        return getattr(self._fh, name)

    def __iter__(self):
        return iter(self._fh)

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self._fh.close()


class DiskFull:
    """Files opened for writing under ``root`` (whose name contains ``match``, if given) share ``budget`` bytes;
    the write that overruns it fails with ENOSPC. ``dnarod.core.io.disk_free`` reports a roomy disk until then and
    what is left (0 B) after, so messages and pre-checks see what a real disk would show."""

    def __init__(self, monkeypatch, root, budget, match=None):
        self.state = st = _Budget(budget, match)
        root = os.path.realpath(root)
        real_open = builtins.open

        def watched(path):
            try:
                p = os.path.realpath(os.fspath(path))
            except TypeError:
                return False
            return p.startswith(root + os.sep) and (match is None or match in os.path.basename(p))

        def fake_open(file, mode="r", *a, **k):
            fh = real_open(file, mode, *a, **k)
            if isinstance(file, int) or not any(c in mode for c in "wax+") or not watched(file):
                return fh
            return _Budgeted(fh, st)

        monkeypatch.setattr(builtins, "open", fake_open)
        monkeypatch.setattr(io, "open", fake_open)
        monkeypatch.setattr(dio, "disk_free", lambda path: st.left if st.tripped else 10**12)


def checksums(folder):
    """Relative path -> sha256 of every file under ``folder`` (hidden ones included), the lock file excepted."""
    out = {}
    for p in sorted(Path(folder).rglob("*")):
        if p.is_file() and p.name != dio.LOCK_NAME:
            out[str(p.relative_to(folder))] = hashlib.sha256(p.read_bytes()).hexdigest()
    return out


def leftovers(folder):
    """Temporary files and stage folders left under ``folder`` (must be none after a failure)."""
    return [str(p) for p in Path(folder).rglob("*")
            if ".tmp" in p.name or p.name.startswith((dio.STAGE_PREFIX, ".dnarod-replaced-"))]


def cli(args, env=None):
    r = CliRunner().invoke(main, [str(a) for a in args], env=env)
    return r


def refused(r, *words, after=0):
    """One line on stderr (after ``after`` lines of progress), exit status 2, nothing on stdout, and ``words`` in
    the line."""
    assert r.exit_code == 2, (r.exit_code, r.output, r.exception)
    lines = r.stderr.strip().splitlines()
    assert len(lines) == after + 1, r.stderr
    err = lines[-1]
    assert err.startswith("dnarod: error: "), err
    assert "Traceback" not in r.output
    for w in words:
        assert w in err, (w, err)
    return err


@pytest.fixture(scope="module")
def reference(tmp_path_factory):
    """A complete run of :data:`RUN` (the bit-exact target of every resumed run)."""
    out = tmp_path_factory.mktemp("ref") / "run"
    r = cli(["simulate", SEQ, *RUN, "-o", out])
    assert r.exit_code == 0, r.output
    return out


def _frames(run):
    from dnarod.core.trajectory import load_trajectory

    t = load_trajectory(Path(run) / "trajectory.dtraj")
    return t.step, t.positions, t.frames


def _same_run(a, b):
    sa, pa, fa = _frames(a)
    sb, pb, fb = _frames(b)
    assert np.array_equal(sa, sb) and np.array_equal(pa, pb) and np.array_equal(fa, fb)
    ea = (Path(a) / "energies.csv").read_text()
    eb = (Path(b) / "energies.csv").read_text()
    assert ea == eb


# ----------------------------------------------------------------------------------------------------------
# the one mechanism (dnarod.core.io): every errno, encodings, long names
# ----------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("code, words", [
    (errno.ENOSPC, ["no space left", "free", "about 12 B needed"]),
    (errno.EDQUOT, ["quota", "free"]),
    (errno.EFBIG, ["file too large"]),
    (errno.EROFS, ["read-only", "choose a folder you can write"]),
    (errno.EACCES, ["permission denied"]),
])
def test_write_errors_become_one_line_naming_the_file(tmp_path, code, words):
    target = tmp_path / "ün dir" / "out.json"
    target.parent.mkdir()
    target.write_text("old")
    with pytest.raises(dio.WriteError) as exc:
        with dio.atomic_path(target, needed=12) as tmp:
            Path(tmp).write_text("new, half written")
            raise OSError(code, os.strerror(code))
    msg = str(exc.value)
    assert msg.startswith(f"cannot write {target}: ") and "\n" not in msg
    for w in words:
        assert w in msg, (w, msg)
    assert target.read_text() == "old" and leftovers(tmp_path) == []


def test_unencodable_path_and_c_writer_error_on_a_full_disk(tmp_path, monkeypatch):
    target = tmp_path / "x.xtc"
    with pytest.raises(dio.WriteError, match="could not take the characters of the path"):
        with dio.atomic_path(target):
            "ü".encode("ascii")
    monkeypatch.setattr(dio, "disk_free", lambda p: 0)  # a C writer's bare error on a full disk
    with pytest.raises(dio.WriteError, match=r"x.xtc: no space left on its disk \(0 B free"):
        with dio.atomic_path(target):
            raise RuntimeError("XTC write error: 7")
    monkeypatch.setattr(dio, "disk_free", lambda p: 10**12)  # the same error with room left: not a disk fault
    with pytest.raises(RuntimeError, match="XTC write error"):
        with dio.atomic_path(target):
            raise RuntimeError("XTC write error: 7")
    assert leftovers(tmp_path) == []


def test_temporary_names_fit_255_bytes_and_ascii_paths_reach_the_folder(tmp_path):
    long = "ä" * 120 + ".csv"  # 244 bytes: legal, and its temporary name must be too
    with dio.atomic_path(tmp_path / long) as tmp:
        assert len(os.path.basename(tmp).encode()) <= 255
        Path(tmp).write_text("x")
    assert (tmp_path / long).read_text() == "x"
    odd = tmp_path / "ün dir"
    with dio.atomic_path(odd / "f.xtc", ascii=True, suffix=".xtc") as tmp:
        assert tmp.isascii() and tmp.endswith(".xtc")
        with builtins.open(tmp, "w") as fh:  # the path a C writer gets reaches the non-ASCII folder
            fh.write("ok")
    assert (odd / "f.xtc").read_text() == "ok" and leftovers(tmp_path) == []


def test_check_free_space_refuses_before_work(tmp_path, monkeypatch):
    monkeypatch.setattr(dio, "disk_free", lambda p: 1000)
    with pytest.raises(dio.WriteError, match=r"this run needs about 2 kB in .*, but its disk has 1 kB free"):
        dio.check_free_space(tmp_path, 2000, "this run")
    dio.check_free_space(tmp_path, 500, "this run")


# ----------------------------------------------------------------------------------------------------------
# simulate: the run stream, checkpoints, exports, --overwrite
# ----------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("checkpoints", [["--checkpoint-interval", "2"], []], ids=["after-a-checkpoint", "before-any"])
def test_full_disk_mid_run_then_resume_is_bit_exact(tmp_path, monkeypatch, reference, checkpoints):
    """A full disk in the middle of a run: one line naming the file; --resume then finishes the run bit for bit, from
    its last checkpoint or, stopped before the first one (checkpoints by wall time), from its start."""
    out = tmp_path / ODD
    disk = DiskFull(monkeypatch, tmp_path, budget=60_000 if checkpoints else 20_000)
    r = cli(["simulate", SEQ, *RUN, *checkpoints, "-o", out])
    err = refused(r, "cannot write", "no space left on its disk (0 B free", "needed", "--resume")
    assert str(out) in err and disk.state.tripped
    assert leftovers(tmp_path) == []
    monkeypatch.undo()
    r = cli(["simulate", SEQ, *RUN, *checkpoints, "-o", out, "--resume"])
    assert r.exit_code == 0, r.output
    _same_run(out, reference)
    assert {p.name for p in out.iterdir()} >= {"trajectory.xtc", "trajectory.dcd", "trajectory.pdb"}


def test_full_disk_at_a_checkpoint_keeps_the_previous_one(tmp_path, monkeypatch, reference):
    out = tmp_path / "run"
    size = (reference / "checkpoint.npz").stat().st_size
    DiskFull(monkeypatch, tmp_path, budget=int(1.5 * size), match="checkpoint.npz")  # the 2nd checkpoint fails
    r = cli(["simulate", SEQ, *RUN, "--checkpoint-interval", "2", "-o", out])
    refused(r, f"cannot write {out}/checkpoint.npz: no space left", "--resume")
    assert leftovers(tmp_path) == []
    monkeypatch.undo()
    from dnarod.core.io import read_checkpoint

    meta, _ = read_checkpoint(out / "checkpoint.npz", "dnarod-lax-checkpoint", ())
    assert meta["step"] > 0  # the first checkpoint, intact
    assert cli(["simulate", SEQ, *RUN, "--checkpoint-interval", "2", "-o", out, "--resume"]).exit_code == 0
    _same_run(out, reference)


def test_full_disk_during_the_export_then_resume_or_export_remakes_it(tmp_path, monkeypatch, reference):
    out = tmp_path / ODD
    DiskFull(monkeypatch, tmp_path, budget=0, match="trajectory.pdb")
    r = cli(["simulate", SEQ, *RUN, "-o", out])
    refused(r, f"cannot write {out}/trajectory.pdb", "the run itself is complete", "dnarod export")
    assert leftovers(tmp_path) == [] and not (out / "trajectory.pdb").exists()
    before = checksums(out)
    monkeypatch.undo()
    r = cli(["simulate", SEQ, *RUN, "-o", out, "--resume"])
    assert r.exit_code == 0 and "remade its exports (trajectory.pdb, trajectory.dcd, trajectory.xtc)" in r.output
    after = checksums(out)
    assert all(after[k] == v for k, v in before.items() if k not in ("run.json",))  # the run itself is unchanged
    _same_run(out, reference)
    r = cli(["simulate", SEQ, *RUN, "-o", out, "--resume"])
    assert "nothing to do" in r.output  # up to date now
    (out / "trajectory.dcd").unlink()
    r = cli(["export", out])
    assert r.exit_code == 0 and "trajectory.dcd" in r.output and (out / "trajectory.dcd").exists()
    refused(cli(["export", tmp_path / "nowhere"]), "does not exist")


def _xtc_frames(path):
    from dnarod.structure.cg_topology import load_cg_trajectory

    return load_cg_trajectory(Path(path).with_suffix(".pdb"), path).n_frames  # the reader takes any path too


def test_c_writers_that_fail_or_stop_short_on_a_full_disk(tmp_path, monkeypatch, reference):
    import mdtraj.formats
    from mdtraj.formats import XTCTrajectoryFile

    import dnarod.structure.export as ex

    run = tmp_path / "run"
    shutil.copytree(reference, run)
    before = checksums(run)
    real_write = XTCTrajectoryFile.write
    monkeypatch.setattr(dio, "disk_free", lambda p: 0)

    def writer(write):  # mdtraj's XTC writer, its write replaced
        return type("XTC", (XTCTrajectoryFile,), {"write": write})

    def error_7(self, xyz, *a, **k):  # mdtraj on a full disk: part of the file, then an error
        real_write(self, xyz[:1], *a, **{kk: v[:1] for kk, v in k.items()})
        raise RuntimeError("XTC write error: 7")

    monkeypatch.setattr(mdtraj.formats, "XTCTrajectoryFile", writer(error_7))
    refused(cli(["export", run]), f"cannot write {run}/trajectory.xtc: no space left on its disk (0 B free")
    assert checksums(run) == before and leftovers(tmp_path) == []

    def short(self, xyz, *a, **k):  # ... or a short file and no error at all
        h = len(xyz) // 2
        real_write(self, xyz[:h], *a, **{kk: v[:h] for kk, v in k.items()})

    monkeypatch.setattr(mdtraj.formats, "XTCTrajectoryFile", writer(short))
    refused(cli(["export", run]), "trajectory.xtc: no space left", "up to")
    assert checksums(run) == before and leftovers(tmp_path) == []
    monkeypatch.setattr(mdtraj.formats, "XTCTrajectoryFile", XTCTrajectoryFile)
    real_dcd = ex._DCDFrames.write
    monkeypatch.setattr(ex._DCDFrames, "write", lambda self, xyz: real_dcd(self, xyz[:3]))
    monkeypatch.setattr(dio, "disk_free", lambda p: 10**12)  # room left: a quota or a file-size limit
    refused(cli(["export", run]), f"cannot write {run}/trajectory.dcd: the DCD writer stopped early", "3 of its")
    assert leftovers(tmp_path) == []
    assert _xtc_frames(run / "trajectory.xtc") == _frames(run)[0].size


def test_non_ascii_and_space_paths_for_simulate_and_export(tmp_path):
    out = tmp_path / ODD
    for engine in ("lax", "openmm"):
        r = cli(["simulate", SEQ, "--engine", engine, "--time", "0.005", "--no-progress", "-o", out / engine])
        assert r.exit_code == 0, r.output
        n = _frames(out / engine)[0].size
        assert _xtc_frames(out / engine / "trajectory.xtc") == n
        from MDAnalysis.lib.formats.libdcd import DCDFile

        with DCDFile(str(out / engine / "trajectory.dcd")) as f:
            assert f.n_frames == n
    assert cli(["export", out / "lax", "--no-xtc"]).exit_code == 0
    assert leftovers(tmp_path) == []


def test_simulate_overwrite_is_atomic(tmp_path, monkeypatch, reference):
    out = tmp_path / ODD
    shutil.copytree(reference, out)
    before = checksums(out)
    DiskFull(monkeypatch, tmp_path, budget=20_000)
    r = cli(["simulate", SEQ, *RUN[:-3], "--seed", "8", "--no-progress", "-o", out, "--overwrite"])
    err = refused(r, f"cannot write {out}/", f"the earlier run in {out} is unchanged")
    assert dio.STAGE_PREFIX not in err
    assert checksums(out) == before and leftovers(tmp_path) == []
    monkeypatch.undo()
    r = cli(["simulate", SEQ, *RUN[:-3], "--seed", "8", "--no-progress", "--no-xtc", "-o", out, "--overwrite"])
    assert r.exit_code == 0, r.output
    assert json.loads((out / "run.json").read_text())["seed"] == 8
    assert not (out / "trajectory.xtc").exists()  # the old run's export does not survive as a stale file
    assert leftovers(tmp_path) == []


def test_a_stage_left_by_a_killed_overwrite_is_removed_by_the_next_writer(tmp_path, reference):
    out = tmp_path / "run"
    shutil.copytree(reference, out)
    (out / f"{dio.STAGE_PREFIX}abc").mkdir()
    (out / f"{dio.STAGE_PREFIX}abc" / "trajectory.dtraj").write_bytes(b"partial")
    assert cli(["export", out]).exit_code == 0  # the next command that locks the folder
    assert leftovers(tmp_path) == []


def test_the_run_refuses_up_front_when_the_disk_cannot_hold_it(tmp_path, monkeypatch):
    monkeypatch.setattr(dio, "disk_free", lambda p: 50_000)
    r = cli(["simulate", SEQ, *RUN, "-o", tmp_path / "run"])
    refused(r, "this run needs about", "but its disk has 50 kB free")
    assert not (tmp_path / "run").exists() or not any((tmp_path / "run").iterdir())


# ----------------------------------------------------------------------------------------------------------
# analyze: report files, --overwrite, a single frame, few frames
# ----------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("match", ["step_parameters.csv", "stiffness.toml", "summary.json", "tangent_correlation.png"])
def test_full_disk_while_writing_the_analysis(tmp_path, monkeypatch, reference, match):
    traj = reference / "trajectory.dtraj"
    run_before = checksums(reference)
    out = tmp_path / ODD
    DiskFull(monkeypatch, tmp_path, budget=0, match=match)
    refused(cli(["analyze", traj, "-o", out]), f"cannot write {out}/{match}: no space left")
    assert leftovers(tmp_path) == [] and checksums(reference) == run_before


def test_analyze_overwrite_is_atomic_and_never_prints_nan(tmp_path, monkeypatch, reference):
    traj = reference / "trajectory.dtraj"
    out = tmp_path / ODD
    r = cli(["analyze", traj, "-o", out, "--no-plots"])
    assert r.exit_code == 0, r.output
    assert "nan" not in r.output.lower()
    before = checksums(out)
    DiskFull(monkeypatch, tmp_path, budget=0, match="stiffness_table.csv")
    r = cli(["analyze", traj, "-o", out, "--overwrite", "--stop", "20"])
    refused(r, f"cannot write {out}/stiffness_table.csv", f"the earlier analysis report in {out} is unchanged")
    assert checksums(out) == before and leftovers(tmp_path) == []
    monkeypatch.undo()
    r = cli(["analyze", traj, "-o", out, "--overwrite", "--stop", "4"])
    assert r.exit_code == 0 and "+- nan" not in r.output and "no error bar: 4 frame" in r.output
    assert "too short for an error bar" in r.output
    assert json.loads((out / "summary.json").read_text())["n_frames"] == 4


def test_analyze_refuses_a_single_frame(tmp_path, reference):
    root = Path(__file__).resolve().parents[1]
    for args in ([reference / "trajectory.dtraj", "--stop", "1"], [root / "data" / "structures" / "1KX5.pdb"]):
        r = cli(["analyze", *args, "-o", tmp_path / "a"])
        refused(r, "a single frame", "`dnarod steps")
        assert not (tmp_path / "a" / "stiffness.toml").exists()


# ----------------------------------------------------------------------------------------------------------
# ensemble tables, protocol curves, validation reports (and their --overwrite)
# ----------------------------------------------------------------------------------------------------------
def _ensemble_spec(path, forces):
    path.write_text(textwrap.dedent(f"""
        [ensemble]
        name = "faults"
        protocol = "null"
        [base]
        source = "ACGTACGTACGT"
        time_ns = 0.01
        [axes]
        force_pN = {list(forces)}
    """))
    return path


def test_full_disk_while_writing_the_ensemble_table(tmp_path, monkeypatch):
    import pyarrow.parquet as pq

    spec = _ensemble_spec(tmp_path / "spec ü.toml", [1, 2])
    out = tmp_path / ODD
    r = cli(["ensemble", spec, "-o", out, "--workers", "0", "--no-progress"])
    assert r.exit_code == 0, r.output
    before = checksums(out)
    real = pq.write_table

    def full(table, where, **kw):  # pyarrow writes natively: part of the file, then errno 28
        Path(where).write_bytes(b"PAR1")
        raise OSError(errno.ENOSPC, "Error writing bytes to file. Detail: [errno 28] No space left on device")

    monkeypatch.setattr(pq, "write_table", full)
    monkeypatch.setattr(dio, "disk_free", lambda p: 0)
    refused(cli(["ensemble", spec, "-o", out, "--workers", "0", "--no-progress"]),
            f"cannot write {out}/results.parquet: no space left on its disk (0 B free", after=1)
    assert checksums(out) == before and leftovers(tmp_path) == []
    monkeypatch.setattr(pq, "write_table", real)


def test_ensemble_overwrite_is_atomic_and_resumable(tmp_path, monkeypatch):
    out = tmp_path / ODD
    assert cli(["ensemble", _ensemble_spec(tmp_path / "a.toml", [1, 2]), "-o", out, "--workers", "0",
                "--no-progress"]).exit_code == 0
    before = checksums(out)
    spec_b = _ensemble_spec(tmp_path / "b.toml", [3, 4, 5])
    DiskFull(monkeypatch, tmp_path, budget=0, match="summary.json")
    r = cli(["ensemble", spec_b, "-o", out, "--workers", "0", "--no-progress", "--overwrite"])
    refused(r, f"cannot write {out}/summary.json: no space left", "the earlier ensemble", "--overwrite continues",
            after=1)
    assert {k: v for k, v in checksums(out).items() if not k.startswith(dio.REPLACEMENT_PREFIX)} == before
    monkeypatch.undo()
    r = cli(["ensemble", spec_b, "-o", out, "--workers", "0", "--no-progress"])
    refused(r, "made by another spec", "--overwrite continues it")
    r = cli(["ensemble", spec_b, "-o", out, "--workers", "0", "--no-progress", "--overwrite"])
    assert r.exit_code == 0, r.output
    assert "members: 3" in r.output and "(3 already finished)" in r.stderr  # the replacement's members reused
    import pyarrow.parquet as pq

    assert [row["force_pN"] for row in pq.read_table(out / "results.parquet").to_pylist()] == [3.0, 4.0, 5.0]
    assert not list(out.glob(".dnarod-*"))
    assert str(out) in json.loads((out / "summary.json").read_text())["files"]["table"]


PROTO = ["--source", "40", "--time", "0.001", "--workers", "0"]


def test_full_disk_while_writing_the_protocol_curve_and_atomic_overwrite(tmp_path, monkeypatch):
    out = tmp_path / ODD
    r = cli(["protocol", "force-extension", "--force", "1,2", *PROTO, "-o", out])
    assert r.exit_code == 0, r.output
    before = checksums(out)
    DiskFull(monkeypatch, tmp_path, budget=0, match="curve.csv")
    refused(cli(["protocol", "force-extension", "--force", "1,2", *PROTO, "-o", out]),
            f"cannot write {out}/curve.csv: no space left")
    assert checksums(out) == before
    r = cli(["protocol", "force-extension", "--force", "3", *PROTO, "-o", out, "--temperature", "310",
             "--overwrite"])
    refused(r, "curve.csv: no space left", "the earlier protocol run", "continues the replacement")
    assert {k: v for k, v in checksums(out).items() if not k.startswith(dio.REPLACEMENT_PREFIX)} == before
    monkeypatch.undo()
    r = cli(["protocol", "force-extension", "--force", "3", *PROTO, "-o", out, "--temperature", "310",
             "--overwrite"])
    assert r.exit_code == 0, r.output
    assert json.loads((out / "protocol.json").read_text())["settings"]["temperature_K"] == 310
    assert not list(out.glob(".dnarod-*")) and leftovers(tmp_path) == []


@pytest.fixture
def fake_check(monkeypatch):
    """A validation check that runs in no time and writes a plot, as real checks do."""
    import dnarod.validate as V
    from dnarod.analysis.plots import new_figure, save_figure

    def check(out_dir, quick=False, **kw):
        fig, ax = new_figure()
        ax[0, 0].plot([0, 1], [0, 1])
        return {"passed": True, "x": 1.0, "plots": [save_figure(fig, out_dir, "fake.png")]}

    monkeypatch.setattr(V, "check_function", lambda name: check)


def test_full_disk_while_writing_the_validation_report_and_atomic_overwrite(tmp_path, monkeypatch, fake_check):
    out = tmp_path / ODD
    r = cli(["validate", "--only", "helix", "-o", out])
    assert r.exit_code == 0, r.output
    assert {"report.md", "results.json", "fake.png"} <= {p.name for p in out.iterdir()}
    before = checksums(out)
    DiskFull(monkeypatch, tmp_path, budget=0, match="report.md")
    refused(cli(["validate", "--only", "helix", "-o", out, "--overwrite"]),
            f"cannot write {out}/report.md: no space left", "the earlier validation report", after=2)
    assert checksums(out) == before and leftovers(tmp_path) == []


# ----------------------------------------------------------------------------------------------------------
# every other command that writes: unusual paths, long names, full disks
# ----------------------------------------------------------------------------------------------------------
def test_structure_commands_take_any_legal_path_and_a_full_disk(tmp_path, monkeypatch):
    root = Path(__file__).resolve().parents[1]
    pdb = tmp_path / "ün pdb" / "1 BNA.pdb"
    pdb.parent.mkdir()
    shutil.copy(root / "data" / "structures" / "1BNA.pdb", pdb)
    odd = tmp_path / ODD
    long = "m" * 200 + "ü" * 20  # 240 bytes with the suffix
    cases = [(["steps", pdb, "--csv", odd / "steps.csv"], odd / "steps.csv"),
             (["pairs", pdb, "--csv", odd / "pairs.csv"], odd / "pairs.csv"),
             (["build", pdb, "-o", odd / f"{long}.npz"], odd / f"{long}.npz"),
             (["build", "--sequence", SEQ, "-o", odd / "seq.npz"], odd / "seq.npz"),
             (["rebuild", odd / "seq.npz", "-o", odd / "aa model.pdb", "--no-minimize"], odd / "aa model.pdb")]
    for args, made in cases:
        r = cli(args)
        assert r.exit_code == 0, (args, r.output)
        assert made.exists()
    before = checksums(odd)
    for args, made in cases:
        with monkeypatch.context() as m:
            DiskFull(m, tmp_path, budget=0, match=made.name[:60])  # temporary names cut long names
            refused(cli([*args, "--overwrite"] if args[0] in ("build", "rebuild") else args),
                    f"cannot write {made}: no space left")
    assert checksums(odd) == before and leftovers(tmp_path) == []


# ----------------------------------------------------------------------------------------------------------
# real faults outside the process: a full tmpfs (user namespaces), a file-size limit for the C writers
# ----------------------------------------------------------------------------------------------------------
def _dnarod():
    return str(Path(sys.executable).parent / "dnarod")


def _unshare_ok():
    if shutil.which("unshare") is None:
        return False
    r = subprocess.run(["unshare", "-rm", "sh", "-c", "mount -t tmpfs -o size=64k tmpfs /mnt 2>/dev/null || "
                        "mount -t tmpfs -o size=64k tmpfs /tmp"], capture_output=True)
    return r.returncode == 0


@pytest.mark.slow  # three dnarod processes (8 s idle, 13-23 s on the shared machine); the fast versions are in-process
def test_real_full_disk_then_resume(tmp_path):
    """On a real 160 kB tmpfs: a filler takes the space the export needs; one line, exit 2, and once it is removed
    `--resume` remakes the exports."""
    if not _unshare_ok():
        pytest.skip("no user namespaces here to mount a small tmpfs")
    mnt = tmp_path / "mnt"
    mnt.mkdir()
    script = textwrap.dedent(f"""
        set -u
        mount -t tmpfs -o size=160k tmpfs "{mnt}" || exit 99
        cd "{mnt}"
        D="{_dnarod()}"
        "$D" simulate {SEQ} --engine lax --time 0.02 --seed 3 --no-progress -o "ün run" > /dev/null 2>&1 || exit 98
        rm "ün run"/trajectory.pdb "ün run"/trajectory.dcd "ün run"/trajectory.xtc
        python3 -c "import json; p='ün run/run.json'; d=json.load(open(p)); d.pop('export'); json.dump(d, open(p, 'w'))"
        dd if=/dev/zero of=filler bs=1k 2>/dev/null
        "$D" simulate {SEQ} --engine lax --time 0.02 --seed 3 --no-progress -o "ün run" --resume; echo "rc=$?"
        ls -a "ün run"
        rm filler
        "$D" simulate {SEQ} --engine lax --time 0.02 --seed 3 --no-progress -o "ün run" --resume; echo "rc=$?"
        ls -a "ün run"
    """)
    r = subprocess.run(["unshare", "-rm", "bash", "-c", script], capture_output=True, text=True, timeout=120)
    out = r.stdout + r.stderr
    assert r.returncode == 0, out
    first, second = out.split("rc=", 1)[1], out.split("rc=", 2)[2]
    assert first.startswith("2"), out
    assert "dnarod: error: cannot write ün run/trajectory." in out and "no space left on its disk" in out
    assert out.count("dnarod: error:") == 1 and "Traceback" not in out
    listing = first.split("\n", 1)[1]
    assert ".tmp" not in listing.split("rc=")[0]
    assert second.startswith("0") and "remade its exports" in out
    assert all(n in second for n in ("trajectory.pdb", "trajectory.dcd", "trajectory.xtc"))


def test_file_size_limit_on_the_c_writers(tmp_path, reference):
    """A file-size limit (ulimit -f) cuts the C writers' files short without an error: `dnarod export` reads them
    back, refuses with one line and leaves the exports as they were."""
    import resource

    run = tmp_path / ODD
    shutil.copytree(reference, run)
    for n in ("trajectory.dcd", "trajectory.xtc"):
        (run / n).unlink()
    before = checksums(run)

    def limit():
        resource.setrlimit(resource.RLIMIT_FSIZE, (6000, resource.RLIM_INFINITY))

    r = subprocess.run([_dnarod(), "export", str(run)], capture_output=True, text=True, preexec_fn=limit,
                       timeout=120)
    err = r.stderr.strip()
    assert r.returncode == 2 and "\n" not in err and "Traceback" not in err, err
    assert err.startswith(f"dnarod: error: cannot write {run}/trajectory.")
    assert any(w in err for w in ("stopped early", "writer failed", "file too large")), err
    assert checksums(run) == before and leftovers(tmp_path) == []


# ----------------------------------------------------------------------------------------------------------
# no silent nonsense: memory, start poses, numbering, speed, compile
# ----------------------------------------------------------------------------------------------------------
def test_a_model_too_large_for_memory_is_refused_before_any_work(tmp_path, monkeypatch):
    import dnarod.run.resources as res

    with pytest.raises(ParameterError, match=r"a 1000000-node model needs about 3.75 GB .* 1 GB available; use at "
                                             r"most ~214285 nodes"):
        res.check_memory(1_000_000, "lax", available=10**9)
    res.check_memory(1000, "lax", available=10**9)
    monkeypatch.setattr(res, "available_memory", lambda: 10**9)
    r = cli(["simulate", "1000000", "--engine", "lax", "-o", tmp_path / "big"])
    refused(r, "1000000-node model needs about", "available")
    assert not (tmp_path / "big").exists()
    assert res.node_count_hint(SEQ) == 20 and res.node_count_hint("12") == 12 and res.node_count_hint(7) == 7


def test_large_set_up_prints_its_stages():
    import dnarod.run.resources as res

    buf = io.StringIO()
    stage = res.SetupStages(res.LARGE_MODEL, True, stream=buf)
    stage("building the model")
    stage("the fastest normal mode (time step)")
    lines = buf.getvalue().splitlines()
    assert lines[0].startswith(f"dnarod: set-up of {res.LARGE_MODEL} nodes, 0 s: building the model")
    assert len(lines) == 2
    quiet = io.StringIO()
    res.SetupStages(1000, True, stream=quiet)("x")
    assert quiet.getvalue() == ""


def _model_with_step(angle_deg, n=24, k=11):
    from dnarod.core.forcefield import load_forcefield
    from dnarod.core.rotations import rotation_about_axis

    m = load_forcefield("dna-default").model_from_sequence(n_nodes=n)
    F = m.frames.copy()
    R = rotation_about_axis(np.array([0.0, 0.0, 1.0]), np.radians(angle_deg))
    F[k + 1:] = F[k + 1:] @ R  # step k (between nodes k and k+1) turns by angle_deg more about d3
    return m.with_pose(m.positions, F)


def test_a_b_z_junction_is_named_as_such_and_numbered_from_1():
    from dnarod.run.api import check_start_pose

    m = _model_with_step(170.0 - 34.3)  # one step turned by ~170 deg (a B-Z junction's flip)
    with pytest.raises(ParameterError) as exc:
        check_start_pose(m, 300.0)
    msg = str(exc.value)
    assert msg.startswith("step 12 (base pairs 12-13) of this 24-node chain rotates by")
    assert "B-Z junction" in msg and "not cured by a longer chain" in msg and "use a longer" not in msg


def test_numbering_is_from_1_in_trap_and_blow_up_messages(tmp_path):
    refused(cli(["simulate", SEQ, "--trap", "0:5", "-o", tmp_path / "n", *RUN]), "numbered from 1")
    refused(cli(["simulate", SEQ, "--trap", "1:5", "--trap", "-20:3", "-o", tmp_path / "n", *RUN]),
            "base pair 1 already has a trap")
    from dnarod.core.errors import base_pair, step_name

    assert base_pair(0) == "base pair 1" and step_name(0) == "step 1 (base pairs 1-2)"
    assert step_name(9, 10) == "step 10 (base pairs 10-1)"


def test_speed_leaves_out_the_first_advance(monkeypatch):
    """A first advance that takes long (the kernels compile) is not in ns/day: only the steps after it count."""
    import time

    from dnarod.run.loop import run_engine

    class Engine:
        dt = 0.01
        step = 0

        def advance(self, n):
            if self.step == 0:
                time.sleep(0.5)
            self.step += n

    out = run_engine(Engine(), 100, reporters=[], checkpoint=None)
    assert out["wall_s"] >= 0.5 and out["timed_wall_s"] < 0.2 and out["timed_steps"] == 0
    from dnarod.run.api import _ns_per_day

    assert _ns_per_day(dict(out, timed_steps=50, timed_wall_s=0.01), 0.01) == pytest.approx(50 * 0.01e-3 / 0.01 * 86400)
    assert _ns_per_day(out, 0.01) == pytest.approx(100 * 0.01e-3 / out["wall_s"] * 86400)


def test_compile_notice_sees_numba_s_disk_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(tmp_path / "cache"))
    (tmp_path / "kmod.py").write_text("from numba import njit\n\n@njit(cache=True)\ndef f(x):\n    return x + 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    import importlib

    from dnarod.core.jit import is_cached

    import numba.core.config as cfg

    monkeypatch.setattr(cfg, "CACHE_DIR", str(tmp_path / "cache"))
    mod = importlib.import_module("kmod")
    assert is_cached(mod.f) is False
    mod.f(1)
    assert is_cached(mod.f) is True
    from dnarod.run.resources import compile_notice

    msg = compile_notice("lax")
    assert msg is None or msg.startswith("compiling kernels (first run after install")


def test_numba_cache_falls_back_to_a_writable_folder(tmp_path, monkeypatch):
    from dnarod.core.jit import ensure_numba_cache

    import numba.core.config as cfg

    blocked = tmp_path / "a file"
    blocked.write_text("not a folder")
    monkeypatch.setattr(cfg, "CACHE_DIR", cfg.CACHE_DIR)  # restored afterwards, as is the environment
    monkeypatch.setenv("NUMBA_CACHE_DIR", "")
    assert ensure_numba_cache(tmp_path / "pkg", tmp_path / "home-cache") is None  # writable: numba's own choice
    folder = ensure_numba_cache(blocked / "pkg", blocked / "home-cache")  # neither can be written
    assert folder is not None and os.environ["NUMBA_CACHE_DIR"] == folder and Path(folder).is_dir()
    assert cfg.CACHE_DIR == folder


def test_member_log_on_a_full_disk_prints_no_traceback(tmp_path, capsys):
    import logging

    from dnarod.workflows.ensemble.member import _LogFile

    h = _LogFile(tmp_path / "member.log")

    class Full:
        def write(self, text):
            raise OSError(errno.ENOSPC, "No space left on device")

        def flush(self):
            pass

    h.stream = Full()
    log = logging.getLogger("dnarod.test.fulldisk")
    log.addHandler(h)
    log.propagate = False
    try:
        log.error("a record the disk cannot take")
    finally:
        log.removeHandler(h)
    assert capsys.readouterr().err == ""
