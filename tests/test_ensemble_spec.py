"""Ensemble specs: expansion into members, stable ids, and refusal of bad input (one line, exit 2)."""
import itertools
import json
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.workflows.ensemble import Ensemble, SpecError, load_spec, member_id, parse_spec, slurm_cluster
from dnarod.workflows.ensemble.cluster import SchedulerError, connect

SEQ = "ACGTACGTACGT"


def spec(**tables):
    doc = {"base": {"source": SEQ, "time_ns": 0.01}}
    for k, v in tables.items():
        doc.setdefault(k, {}).update(v)
    return doc


def test_cross_product_order_and_replica_seeds():
    s = parse_spec(spec(axes={"force_pN": [1, 2, 3], "salt_M": [0.1, 0.2]}, ensemble={"replicas": 2},
                        base={"seed": 7}))
    ms = list(s.members())
    assert len(s) == len(ms) == 12
    expect = [(f, c, 7 + r) for f, c in itertools.product([1.0, 2.0, 3.0], [0.1, 0.2]) for r in range(2)]
    assert [(m.settings["force_pN"], m.settings["salt_M"], m.settings["seed"]) for m in ms] == expect
    assert [m.index for m in ms] == list(range(12))
    assert s.axes == ["force_pN", "salt_M", "seed"]
    assert all(m.settings["source"] == SEQ and m.settings["time_ns"] == 0.01 for m in ms)
    assert len({m.id for m in ms}) == 12


def test_zip_and_zip_groups():
    s = parse_spec(spec(axes={"force_pN": [1, 2, 3], "turns": [0, 5, 10], "salt_M": [0.1, 0.2]},
                        base={"rotation_clamp_kJ_mol": 100.0}, ensemble={"zip": [["force_pN", "turns"]]}))
    got = [(m.settings["force_pN"], m.settings["turns"], m.settings["salt_M"]) for m in s.members()]
    assert got == [(f, t, c) for f, t in [(1, 0), (2, 5), (3, 10)] for c in (0.1, 0.2)]
    z = parse_spec(spec(axes={"force_pN": [1, 2], "temperature_K": [280, 300]}, ensemble={"combine": "zip"}))
    assert [(m.settings["force_pN"], m.settings["temperature_K"]) for m in z.members()] == [(1, 280), (2, 300)]
    with pytest.raises(SpecError, match="equal lengths.*force_pN: 3, turns: 2"):
        parse_spec(spec(axes={"force_pN": [1, 2, 3], "turns": [0, 1]}, ensemble={"combine": "zip"}))


def test_ranges_and_fasta(tmp_path):
    s = parse_spec(spec(axes={"force_pN": {"logspace": [0.1, 10.0, 5]}}))
    np.testing.assert_allclose([m.settings["force_pN"] for m in s.members()], np.geomspace(0.1, 10, 5), rtol=1e-11)
    s = parse_spec(spec(axes={"temperature_K": {"linspace": [280, 320, 3]}}))
    assert [m.settings["temperature_K"] for m in s.members()] == [280.0, 300.0, 320.0]
    (tmp_path / "s.fa").write_text(">one first\nACGT\nACGT\n\n>two\nggccggcc\n")
    doc = {"base": {"time_ns": 0.01}, "axes": {"fasta": "s.fa", "force_pN": [1, 2]}}
    ms = list(parse_spec(doc, base_dir=tmp_path).members())
    assert [(m.settings["sequence_name"], m.settings["source"], m.settings["force_pN"]) for m in ms] == \
        [("one", "ACGTACGT", 1.0), ("one", "ACGTACGT", 2.0), ("two", "GGCCGGCC", 1.0), ("two", "GGCCGGCC", 2.0)]


def test_ids_are_stable_and_canonical():
    a = list(parse_spec(spec(axes={"force_pN": [1, 2]})).members())
    b = list(parse_spec(spec(axes={"force_pN": [1.0, 2.0]})).members())   # int and float spell one value
    assert [m.id for m in a] == [m.id for m in b]
    assert member_id({"b": 1, "a": 2.5}) == member_id({"a": 2.5, "b": 1})   # key order does not matter
    c = list(parse_spec(spec(axes={"force_pN": [1, 2.0000001]})).members())
    assert a[0].id == c[0].id and a[1].id != c[1].id
    # the same settings give the same id in a fresh interpreter (no per-process hash seed)
    code = ("from dnarod.workflows.ensemble import member_id; "
            f"print(member_id({a[1].settings!r}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout.strip()
    assert out == a[1].id and len(out) == 12 and int(out, 16) >= 0


@pytest.mark.parametrize("doc, message", [
    (spec(base={"force": 2.0}), r"\[base\] force: unit missing; write force_pN"),
    (spec(base={"temperature_C": 25.0}),
     r"\[base\] temperature_C: wrong unit; temperature is given in K: write temperature_K"),
    (spec(axes={"force_N": [1e-12]}), r"\[axes\] force_N: wrong unit; force is given in pN: write force_pN"),
    (spec(axes={"salt": [0.1]}), r"\[axes\] salt: unit missing; write salt_M"),
    (spec(base={"temprature_K": 300.0}), r"unknown key 'temprature_K'; did you mean temperature_K\?"),
    (spec(axes={"force_pN": []}), r"\[axes\] force_pN: axis of length zero"),
    (spec(axes={"force_pN": {"linspace": [1, 2, 0]}}), r"axis of length 0"),
    (spec(axes={"force_pN": [1, "two"]}), r"\[axes\] force_pN: expected a number, got 'two'"),
    (spec(base={"time_ns": -1.0}), r"\[base\] time_ns: must be > 0"),
    (spec(base={"engine": "gromacs"}), r"\[base\] engine: must be one of openmm, lax"),
    (spec(axes={"force_pN": [1, 1]}), r"repeated values"),
    (spec(ensemble={"replicas": 2}, axes={"seed": [1, 2]}), r"replicas > 1 with a seed axis"),
    (spec(axes={"time_ns": [1.0]}), r"\[axes\] time_ns is also in \[base\]"),
    ({"base": {"time_ns": 1.0}}, r"\[base\] source is missing"),
    ({"bass": {}}, r"unknown table \[bass\]"),
])
def test_bad_specs_name_the_key(doc, message):
    with pytest.raises(SpecError, match=message):
        parse_spec(doc)


def test_unmappable_sequence_is_refused_before_running(tmp_path):
    with pytest.raises(SpecError, match=r"member 1 \(source ACGXT.*ACGXT"):
        Ensemble.from_dict({"base": {"time_ns": 0.01}, "axes": {"source": ["ACGTA", "ACGXT"]}}, tmp_path / "e")
    assert not (tmp_path / "e").exists()


def _write(tmp_path, text, name="s.toml"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_cli_bad_spec_one_line_exit_2(tmp_path):
    p = _write(tmp_path, f'[base]\nsource = "{SEQ}"\nforce = 3\n')
    r = CliRunner().invoke(main, ["ensemble", str(p), "-o", str(tmp_path / "out")])
    assert r.exit_code == 2
    assert r.output.strip().splitlines() == [f"dnarod: error: {p}: [base] force: unit missing; write force_pN"]
    assert not (tmp_path / "out").exists()
    p2 = _write(tmp_path, "[base\nsource=", "broken.toml")
    r = CliRunner().invoke(main, ["ensemble", str(p2), "-o", str(tmp_path / "out")])
    assert r.exit_code == 2 and len(r.output.strip().splitlines()) == 1 and "not valid TOML" in r.output


def test_folder_of_another_spec_is_refused_unless_overwrite(tmp_path):
    out = tmp_path / "ens"
    a = Ensemble.from_dict(spec(axes={"force_pN": [1, 2]}), out, protocol="null").prepare()
    (out / "members" / a.members[0].id).mkdir(parents=True)
    keep = out / "members" / a.members[0].id / "result.json"
    keep.write_text(json.dumps({"id": a.members[0].id, "status": "ok", "observables": {}}))
    before = {p: p.read_bytes() for p in out.rglob("*") if p.is_file()}
    b = Ensemble.from_dict(spec(axes={"force_pN": [1, 3]}), out, protocol="null")
    with pytest.raises(SpecError, match=r"holds ensemble 'ensemble' made by another spec \(2 members, 1 with "
                                        r"results\); use another -o folder, or --overwrite"):
        b.prepare()
    assert {p: p.read_bytes() for p in out.rglob("*") if p.is_file()} == before      # nothing changed
    Ensemble.from_dict(spec(axes={"force_pN": [1, 2]}), out, protocol="null").prepare()   # same spec: resume
    assert keep.exists()
    c = Ensemble.from_dict(spec(axes={"force_pN": [1, 3]}), out, protocol="null", overwrite=True).prepare()
    assert keep.exists() and c.outdir.parent == out  # built beside the old one, which stays until it is complete
    c.run(workers=0, progress=False)
    assert c.outdir == out and not list(out.glob(".dnarod-*"))
    assert json.loads(keep.read_text()).get("settings") is not None  # member force 1 of the new ensemble, not the old
    other = tmp_path / "other"
    other.mkdir()
    (other / "notes.txt").write_text("mine")
    with pytest.raises(SpecError, match="not an ensemble folder"):
        Ensemble.from_dict(spec(), other, protocol="null", overwrite=True).prepare()
    assert (other / "notes.txt").read_text() == "mine"


def test_scheduler_that_does_not_answer(tmp_path):
    import socket

    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    t0 = time.perf_counter()
    with pytest.raises(SchedulerError, match=rf"--scheduler tcp://127.0.0.1:{port}: nothing listens on port {port} "
                                             r"of 127.0.0.1 \(connection refused\)"):
        connect(f"tcp://127.0.0.1:{port}", timeout=2)
    assert time.perf_counter() - t0 < 20
    p = _write(tmp_path, f'[base]\nsource = "{SEQ}"\ntime_ns = 0.01\n[ensemble]\nprotocol = "null"\n')
    r = CliRunner().invoke(main, ["ensemble", str(p), "-o", str(tmp_path / "o"), "--scheduler",
                                  f"tcp://127.0.0.1:{port}", "--timeout", "2", "--no-progress"])
    assert r.exit_code == 2, r.output
    assert [ln for ln in r.output.splitlines() if ln.startswith("dnarod: error:")] == [
        ln for ln in r.output.splitlines() if "error" in ln]
    assert f"nothing listens on port {port} of 127.0.0.1" in r.output


def test_slurm_cluster_job_script():
    cluster = slurm_cluster(cores=4, memory="8GB", walltime="01:30:00", queue="short", account="lab",
                            job_extra_directives=["--constraint=skylake"])
    try:
        script = cluster.job_script()
    finally:
        cluster.close()
    lines = script.splitlines()
    for want in ("#SBATCH -p short", "#SBATCH -A lab", "#SBATCH --cpus-per-task=4", "#SBATCH --mem=8G",
                 "#SBATCH -t 01:30:00", "#SBATCH --constraint=skylake", "export OPENMM_CPU_THREADS=1",
                 "export NUMBA_NUM_THREADS=1", "export OMP_NUM_THREADS=1"):
        assert want in lines, (want, script)
    worker = [ln for ln in lines if "distributed.cli.dask_worker" in ln]
    assert len(worker) == 1 and "--nthreads 1" in worker[0] and "--nworkers 4" in worker[0]
    assert worker[0].startswith(sys.executable)


def test_example_spec_expands():
    s = load_spec(Path(__file__).parents[1] / "examples" / "force_extension.toml")
    ms = list(s.members())
    assert len(ms) == 16 and s.axes == ["force_pN", "seed"]
    assert len(ms[0].settings["source"]) == 50
    np.testing.assert_allclose(sorted({m.settings["force_pN"] for m in ms}), np.geomspace(0.1, 20, 8), rtol=1e-11)


def test_protocol_hooks_and_keys(tmp_path):
    from dnarod.workflows.ensemble import Key, run_member
    from dnarod.workflows.ensemble.protocol import call_hook

    two = lambda settings, member_dir: ("two", settings, member_dir)                      # noqa: E731
    three = lambda settings, member_dir, analysis: ("three", analysis)                    # noqa: E731
    assert call_hook(two, {"a": 1}, "d", {"blocks": 3}) == ("two", {"a": 1}, "d")
    assert call_hook(three, {"a": 1}, "d", {"blocks": 3}) == ("three", {"blocks": 3})
    from dnarod.workflows.ensemble.protocol import resolve_protocol
    for name in ("force-extension", "magnetic-tweezers", "torque-turns", "rings", "null"):
        assert callable(resolve_protocol(name).execute)
    with pytest.raises(SpecError, match=r"protocol 'nope': not a registered name"):
        resolve_protocol("nope")

    class Proto:                      # a protocol with its own keys and no source
        keys = {"n_bp": int, "equilibration_ns": Key("equilibration_ns", float, None, "ns", ">0")}

        @staticmethod
        def execute(settings, member_dir):
            return {"twice": 2 * settings["n_bp"]}

    ens = Ensemble.from_dict({"base": {"equilibration_ns": 1}, "axes": {"n_bp": [10, 20]}}, tmp_path / "e",
                             protocol=Proto())
    assert [m.settings for m in ens.members] == [{"equilibration_ns": 1.0, "n_bp": 10, "seed": 1},
                                                 {"equilibration_ns": 1.0, "n_bp": 20, "seed": 1}]
    with pytest.raises(SpecError, match=r"\[base\] equilibration_ns: must be > 0"):
        Ensemble.from_dict({"base": {"equilibration_ns": -1.0}}, tmp_path / "f", protocol=Proto())
    ens.prepare()
    rec = run_member(ens.members[1].id, ens.members[1].settings, str(tmp_path / "e"), Proto(), {})
    assert rec["status"] == "ok" and rec["observables"] == {"twice": 40}
    assert ens.results().to_pylist()[1]["twice"] == 40 and ens.results().to_pylist()[0]["status"] == "pending"
