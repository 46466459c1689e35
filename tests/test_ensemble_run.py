"""Ensembles on a dask LocalCluster: results, idempotence, failed members, a killed worker, a killed command."""
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import cloudpickle
import numpy as np
import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.workflows.ensemble import Ensemble, local_cluster, run_member
from dnarod.core.trajectory import load_trajectory

cloudpickle.register_pickle_by_value(sys.modules[__name__])   # workers get this module's protocols by value

#: A tiny deterministic member: 12-node rod, Lax engine (bit-exact resume), clamped and pulled.
LAX = {"source": "12", "engine": "lax", "excluded_volume": False, "electrostatics": False, "clamp_first": True,
       "frame_interval_ps": 1.0, "checkpoint_interval_ps": 10.0, "time_ns": 0.05, "temperature_K": 300.0}


@pytest.fixture(scope="module")
def client():
    from distributed import Client

    cluster = local_cluster(2)
    c = Client(cluster, set_as_default=False)
    yield c
    c.close()
    cluster.close()


def _rows(path):
    return pq.read_table(path).to_pylist()


def test_worker_environment(client):
    env = client.run(lambda: {k: os.environ.get(k) for k in ("OPENMM_CPU_THREADS", "NUMBA_NUM_THREADS",
                                                               "OMP_NUM_THREADS")})
    assert len(env) == 2
    assert all(v == {"OPENMM_CPU_THREADS": "1", "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
               for v in env.values())
    assert all(w["nthreads"] == 1 for w in client.scheduler_info()["workers"].values())


def test_null_members_table_and_rerun_skips(client, tmp_path):
    doc = {"base": {"source": "ACGTACGTACGT", "time_ns": 0.01, "rotation_clamp_kJ_mol": 100.0},
           "axes": {"force_pN": [1, 2, 4], "turns": [0, 3]}, "ensemble": {"protocol": "null"}}
    ens = Ensemble.from_dict(doc, tmp_path / "e").run(client=client, progress=False)
    rows = _rows(tmp_path / "e" / "results.parquet")
    assert [r["index"] for r in rows] == list(range(6))
    assert [(r["force_pN"], r["turns"]) for r in rows] == [(f, t) for f in (1.0, 2.0, 4.0) for t in (0.0, 3.0)]
    assert all(r["status"] == "ok" and r["echo_force_pN"] == r["force_pN"] and r["echo_turns"] == r["turns"]
               for r in rows)
    assert [r["member"] for r in rows] == [m.id for m in ens.members]
    csv_lines = (tmp_path / "e" / "results.csv").read_text().splitlines()
    assert len(csv_lines) == 7 and csv_lines[0].startswith('"member","index","force_pN","turns"')
    assert ens.summary["status"] == {"ok": 6} and ens.summary["n_members"] == 6
    assert sorted(p.name for p in (tmp_path / "e").glob("plot_*.png")) == ["plot_force_pN.png", "plot_turns.png"]
    stamps = {p: p.stat().st_mtime_ns for p in (tmp_path / "e" / "members").glob("*/result.json")}
    assert len(stamps) == 6
    again = Ensemble.from_dict(doc, tmp_path / "e")
    assert again.pending() == []
    again.run(client=client, progress=False)
    assert {p: p.stat().st_mtime_ns for p in stamps} == stamps        # nothing redone
    assert _rows(tmp_path / "e" / "results.parquet") == rows
    inproc = Ensemble.from_dict(doc, tmp_path / "in-process").run(workers=0, progress=False)   # no dask
    assert inproc.results().equals(again.results()) and inproc.summary["workers"] == 0


def _fail_on_force_2(settings, member_dir, analysis):
    if settings["force_pN"] == 2.0:
        raise RuntimeError("this member cannot run:\n force 2 pN")
    return {"double": 2 * settings["force_pN"]}


class Flaky:
    execute = staticmethod(_fail_on_force_2)


def test_failed_member_is_reported_and_others_finish(client, tmp_path):
    doc = {"base": {"source": "ACGTACGTACGT"}, "axes": {"force_pN": [1, 2, 3]}}
    ens = Ensemble.from_dict(doc, tmp_path / "e", protocol=Flaky()).run(client=client, progress=False)
    rows = _rows(tmp_path / "e" / "results.parquet")
    assert [r["status"] for r in rows] == ["ok", "failed", "ok"]
    assert rows[1]["error"] == "this member cannot run: force 2 pN" and rows[1]["double"] is None
    assert [rows[0]["double"], rows[2]["double"]] == [2.0, 6.0]
    assert ens.summary["failed"] == [{"member": ens.members[1].id, "index": 1,
                                      "error": "this member cannot run: force 2 pN"}]
    log = (tmp_path / "e" / "members" / ens.members[1].id / "member.log").read_text()
    assert "Traceback" in log and "RuntimeError" in log
    assert [m.index for m in ens.pending()] == [1]                    # a failed member is retried next time


def test_real_members_on_cluster_equal_sequential(client, tmp_path):
    doc = {"base": dict(LAX), "axes": {"force_pN": [1.0, 5.0]},
           "analysis": {"discard_ns": 0.01, "blocks": 5}}
    ens = Ensemble.from_dict(doc, tmp_path / "dask").run(client=client, progress=False)
    # the same members one after another in this process, through the worker function itself
    for m in ens.members:
        rec = run_member(m.id, m.settings, str(tmp_path / "seq"), None, ens.spec.analysis)
        assert rec["status"] == "ok", rec
    seq = Ensemble.from_dict(doc, tmp_path / "seq").results()
    par = ens.results()
    assert seq.equals(par) and par.num_rows == 2
    rows = par.to_pylist()
    assert all(r["status"] == "ok" for r in rows)
    # the observables are real: mean of the CSV column recomputed here from the member's files
    m0 = ens.members[0]
    e = np.genfromtxt(tmp_path / "dask" / "members" / m0.id / "energies.csv", delimiter=",", names=True)
    keep = e["time_ps"] >= 10.0
    assert rows[0]["potential_kJ_mol"] == pytest.approx(e["potential_kJ_mol"][keep].mean(), rel=1e-12)
    # the measured temperature does not overwrite the temperature setting
    assert rows[0]["temperature_K"] == 300.0
    assert rows[0]["kinetic_temperature_K"] == pytest.approx(e["temperature_K"][keep].mean(), rel=1e-12)
    tr = load_trajectory(tmp_path / "dask" / "members" / m0.id / "trajectory.dtraj")
    sel = tr.time >= 10.0
    d = np.linalg.norm(tr.positions[sel, -1] - tr.positions[sel, 0], axis=1)
    assert rows[0]["end_to_end_nm"] == pytest.approx(d.mean(), rel=1e-12)
    c1 = np.einsum("fki,fki->fk", tr.frames[sel, :-1, :, 2], tr.frames[sel, 1:, :, 2]).mean()
    assert rows[0]["persistence_length_nm"] == pytest.approx(-0.34 / np.log(c1), rel=1e-9)
    # a pulled chain is longer at 5 pN than at 1 pN
    assert rows[1]["end_to_end_nm"] > rows[0]["end_to_end_nm"]


def _pid_from_log(path, attempt=1):
    if not path.exists():
        return None
    m = re.search(rf"start: attempt {attempt} on \S+ pid (\d+)", path.read_text())
    return int(m.group(1)) if m else None


def test_killed_worker_resumes_from_checkpoint(client, tmp_path):
    base = dict(LAX, time_ns=3.0, frame_interval_ps=2.0, checkpoint_interval_ps=50.0)
    doc = {"base": base, "axes": {"force_pN": [3.0]}, "analysis": {"blocks": 5}}
    ref = Ensemble.from_dict(doc, tmp_path / "ref").run(client=client, progress=False)
    ens = Ensemble.from_dict(doc, tmp_path / "kill")
    mdir = tmp_path / "kill" / "members" / ens.members[0].id
    th = threading.Thread(target=ens.run, kwargs=dict(client=client, progress=False))
    th.start()
    deadline = time.time() + 60
    while time.time() < deadline and not ((mdir / "checkpoint.npz").exists() and _pid_from_log(mdir / "member.log")):
        time.sleep(0.02)
    pid = _pid_from_log(mdir / "member.log")
    assert pid is not None and not (mdir / "result.json").exists(), "the member finished before it could be killed"
    os.kill(pid, signal.SIGKILL)
    th.join(120)
    assert not th.is_alive()
    rec = json.loads((mdir / "result.json").read_text())
    assert rec["status"] == "ok" and rec["attempts"] == 2 and rec["resumed_from"] > 0 and rec["pid"] != pid
    assert "resume from" in (mdir / "member.log").read_text()
    tr = load_trajectory(mdir / "trajectory.dtraj")
    steps = np.diff(tr.step)
    assert (steps == steps[0]).all() and steps[0] > 0                 # no gap, no duplicate
    rtr = load_trajectory(tmp_path / "ref" / "members" / ens.members[0].id / "trajectory.dtraj")
    np.testing.assert_array_equal(tr.step, rtr.step)
    np.testing.assert_array_equal(tr.positions, rtr.positions)         # bit-for-bit the uninterrupted run
    assert ens.results().equals(ref.results())


def test_killed_command_rerun_finishes_without_redoing(client, tmp_path):
    spec = tmp_path / "s.toml"
    spec.write_text(
        "[base]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in dict(LAX, time_ns=0.6).items()) +
        '[axes]\nforce_pN = [1.0, 2.0, 3.0, 4.0]\n[ensemble]\nname = "fx"\n')
    out = tmp_path / "out"
    args = ["ensemble", str(spec), "-o", str(out), "--no-progress"]
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).parents[1]))
    # the command with its own local cluster, killed (with the cluster) once a member has finished
    p = subprocess.Popen([sys.executable, "-c", "from dnarod.cli.main import main; main()", *args, "--workers", "2"],
                         start_new_session=True, stdout=subprocess.PIPE, stderr=subprocess.PIPE, env=env)
    deadline = time.time() + 120
    done = []
    while time.time() < deadline and not done and p.poll() is None:
        done = [r for r in out.glob("members/*/result.json") if json.loads(r.read_text())["status"] == "ok"]
        time.sleep(0.05)
    os.killpg(p.pid, signal.SIGKILL)
    p.wait()
    assert done, p.stderr.read().decode()[-2000:]
    finished = {r.parent.name: (r.stat().st_mtime_ns, r.read_bytes())
                for r in out.glob("members/*/result.json") if json.loads(r.read_text())["status"] == "ok"}
    assert 1 <= len(finished) < 4
    assert not (out / "results.parquet").exists()
    # the same command again (here pointed at a running scheduler): finishes the rest only
    r = CliRunner().invoke(main, [*args, "--scheduler", client.scheduler.address])
    assert r.exit_code == 0, r.output
    assert f"4 members ({len(finished)} already finished)" in r.output
    for mid, (stamp, content) in finished.items():
        res = out / "members" / mid / "result.json"
        assert (res.stat().st_mtime_ns, res.read_bytes()) == (stamp, content)   # not redone
    rows = _rows(out / "results.parquet")
    assert len(rows) == 4 and all(r["status"] == "ok" for r in rows)
    # equal to an uninterrupted run of the same members
    ens = Ensemble.from_toml(spec, tmp_path / "ref")
    for m in ens.members:
        run_member(m.id, m.settings, str(tmp_path / "ref"), None, ens.spec.analysis)
    assert ens.results().equals(pq.read_table(out / "results.parquet"))
