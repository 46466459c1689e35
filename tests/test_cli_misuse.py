"""Every misuse of the command line: one line on stderr naming the option or file, exit status 2,
nothing on stdout, and every file that existed before left byte-for-byte unchanged."""
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.cli.main import main

ROOT = Path(__file__).resolve().parent.parent
PDB = ROOT / "data" / "structures" / "355D.pdb"
SEQ = "ACGTTGCAAC"
QUICK = ["--time", "0.002", "--no-progress", "--seed", "3", "--frame-interval", "0.2"]


@pytest.fixture(scope="module")
def base(tmp_path_factory):
    """A finished OpenMM run, a finished analysis of it and a model file, made once."""
    d = tmp_path_factory.mktemp("base")
    r = CliRunner().invoke(main, ["simulate", SEQ, "-o", str(d / "run"), *QUICK])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["analyze", str(d / "run" / "trajectory.dtraj"), "-o", str(d / "ana"), "--no-plots"])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(main, ["build", str(PDB), "-o", str(d / "model.npz")])
    assert r.exit_code == 0, r.output
    return d


@pytest.fixture
def work(base, tmp_path):
    for name in ("run", "ana"):
        shutil.copytree(base / name, tmp_path / name)
    shutil.copy(base / "model.npz", tmp_path / "model.npz")
    (tmp_path / "afile").write_text("a regular file\n")
    (tmp_path / "bad.fa").write_text(">seq\nACGTACGT\nACGXT\n")
    junk = np.random.default_rng(1).integers(0, 256, 3000, dtype=np.uint8).tobytes()
    (tmp_path / "binary.bin").write_bytes(junk)
    (tmp_path / "binary.toml").write_bytes(junk)
    (tmp_path / "bad.dcd").write_bytes(junk)
    (tmp_path / "empty.npz").write_bytes(b"")
    (tmp_path / "trunc.npz").write_bytes((tmp_path / "model.npz").read_bytes()[:300])
    (tmp_path / "exists.pdb").write_text("REMARK mine\n")
    return tmp_path


def _snapshot(folder):
    return {p: p.read_bytes() for p in sorted(Path(folder).rglob("*")) if p.is_file()}


def _corrupt_checkpoint(w):
    p = w / "run" / "checkpoint.npz"
    p.write_bytes(p.read_bytes()[:200])


def _foreign_checkpoint(w):
    np.savez(w / "run" / "checkpoint.npz", something=np.arange(3))


def _lax_checkpoint(w):
    r = CliRunner().invoke(main, ["simulate", SEQ, "--engine", "lax", "-o", str(w / "lax"), *QUICK])
    assert r.exit_code == 0, r.output
    shutil.copy(w / "lax" / "checkpoint.npz", w / "run" / "checkpoint.npz")


TWIST = ["--pull", "5", "--clamp-first", "--rotation-clamp", "200", "--turns", "1", "--engine", "lax"]


def _turning_run(w):
    r = CliRunner().invoke(main, ["simulate", SEQ, "-o", str(w / "tw"), *QUICK, *TWIST])
    assert r.exit_code == 0, r.output


def _no_checkpoint(w):
    (w / "run" / "checkpoint.npz").unlink()


RESUME = ["simulate", SEQ, "-o", "{w}/run", "--resume", "--time", "0.004", "--no-progress", "--frame-interval",
          "0.2"]

# (id, arguments ({w}: the work folder), words the message must contain, set-up)
CASES = [
    ("simulate-out-under-file", ["simulate", SEQ, "-o", "{w}/afile/x", *QUICK], ["afile", "regular file"], None),
    ("simulate-out-is-file", ["simulate", SEQ, "-o", "{w}/afile", *QUICK], ["afile", "regular file"], None),
    ("lax-run-out-under-file", ["lax-run", SEQ, "-o", "{w}/afile/x", *QUICK], ["afile", "regular file"], None),
    ("analyze-out-under-file", ["analyze", "{w}/run/trajectory.dtraj", "-o", "{w}/afile/x"], ["afile", "regular file"],
     None),
    ("build-out-under-file", ["build", str(PDB), "-o", "{w}/afile/x.npz"], ["afile", "regular file"], None),
    ("rebuild-out-under-file", ["rebuild", "{w}/model.npz", "-o", "{w}/afile/x.pdb"], ["afile", "regular file"], None),
    ("steps-csv-under-file", ["steps", str(PDB), "--csv", "{w}/afile/x.csv"], ["afile", "regular file"], None),
    ("validate-out-under-file", ["validate", "--only", "helix", "-o", "{w}/afile/x"], ["afile", "regular file"],
     None),
    ("friction-negative-openmm", ["simulate", SEQ, "--friction", "-1", "-o", "{w}/n", *QUICK], ["--friction -1"],
     None),
    ("friction-negative-lax", ["lax-run", SEQ, "--friction", "-1", "-o", "{w}/n", *QUICK], ["--friction -1"], None),
    ("time-zero", ["simulate", SEQ, "-o", "{w}/n", "--time", "0", "--no-progress"], ["--time 0", "positive"], None),
    ("time-negative", ["simulate", SEQ, "-o", "{w}/n", "--time", "-1", "--no-progress"], ["--time -1", "positive"],
     None),
    ("frame-interval-zero", ["simulate", SEQ, "-o", "{w}/n", *QUICK, "--frame-interval", "0"], ["--frame-interval 0"],
     None),
    ("checkpoint-interval-negative", ["simulate", SEQ, "-o", "{w}/n", "--checkpoint-interval", "-1", *QUICK],
     ["--checkpoint-interval"], None),
    ("temperature-negative", ["simulate", SEQ, "-o", "{w}/n", "-T", "-5", *QUICK], ["--temperature -5"], None),
    ("dt-above-stability-limit", ["simulate", SEQ, "-o", "{w}/n", "--dt", "5", *QUICK], ["stability limit"], None),
    ("tiny-ring", ["simulate", "ACGTA", "--ring", "-o", "{w}/n", *QUICK], ["5-node ring", "kT", "at least"], None),
    ("not-a-sequence", ["simulate", "ACGU", "-o", "{w}/n", *QUICK], ["ACGU", "not a file, a DNA sequence"], None),
    ("missing-structure-file", ["simulate", "{w}/nope.pdb", "-o", "{w}/n", *QUICK], ["nope.pdb", "not found"], None),
    ("bad-fasta-letter", ["simulate", "{w}/bad.fa", "-o", "{w}/n", *QUICK], ["bad.fa", "line 3", "'X'"], None),
    ("duplex-zero-simulate", ["simulate", str(PDB), "--duplex", "0", "-o", "{w}/n", *QUICK], ["--duplex 0", "from 1"],
     None),
    ("duplex-zero-analyze", ["analyze", str(PDB), "--duplex", "0", "-o", "{w}/n"], ["--duplex 0", "from 1"], None),
    ("duplex-on-sequence", ["simulate", SEQ, "--duplex", "1", "-o", "{w}/n", *QUICK], ["--duplex", "structure"],
     None),
    ("delta-lk-without-ring", ["simulate", SEQ, "--delta-lk", "1", "-o", "{w}/n", *QUICK], ["--delta-lk", "--ring"],
     None),
    ("turns-without-clamp", ["simulate", SEQ, "--turns", "2", "-o", "{w}/n", *QUICK], ["--turns", "--rotation-clamp"],
     None),
    ("pull-on-ring", ["simulate", "ACGT" * 10, "--ring", "--pull", "2", "-o", "{w}/n", *QUICK],
     ["--pull", "open chain"], None),
    ("pull-overstretching", ["simulate", SEQ, "--pull", "80", "-o", "{w}/n", *QUICK], ["--pull 80", "overstretch"],
     None),
    ("torque-on-free-chain", ["simulate", SEQ, "--torque", "10", "-o", "{w}/n", *QUICK], ["--torque 10", "equilibrium"],
     None),
    ("bad-trap", ["simulate", SEQ, "--trap", "x", "-o", "{w}/n", *QUICK], ["--trap", "NODE:STIFFNESS"], None),
    ("trap-node-missing", ["simulate", SEQ, "--trap", "99:5", "-o", "{w}/n", *QUICK], ["--trap", "base pair 99"], None),
    ("lax-with-excluded-volume", ["simulate", SEQ, "--engine", "lax", "--excluded-volume", "-o", "{w}/n", *QUICK],
     ["lax engine", "excluded volume"], None),
    ("minimize-and-equilibrium", ["simulate", SEQ, "--minimize", "--equilibrium", "-o", "{w}/n", *QUICK],
     ["--minimize", "--equilibrium"], None),
    ("existing-run-without-overwrite", ["simulate", SEQ, "-o", "{w}/run", *QUICK], ["already holds a run", "--resume",
                                                                                   "--overwrite"], None),
    ("lax-run-onto-existing-run", ["lax-run", SEQ, "-o", "{w}/run", *QUICK], ["already holds a run"], None),
    ("resume-and-overwrite", ["simulate", SEQ, "-o", "{w}/run", "--resume", "--overwrite", *QUICK], ["not both"],
     None),
    ("resume-without-run", ["simulate", SEQ, "-o", "{w}/empty", "--resume", *QUICK], ["cannot resume", "run.json"],
     None),
    ("resume-other-temperature", RESUME + ["-T", "310"], ["cannot resume", "temperature", "300", "310"], None),
    ("resume-other-sequence", ["simulate", "ACGTTGCAAG", *RESUME[2:]],
     ["cannot resume", "sequence", "ACGTTGCAAC", "ACGTTGCAAG"], None),
    ("resume-other-seed", RESUME + ["--seed", "4"], ["cannot resume", "seed"], None),
    ("resume-other-friction", RESUME + ["--friction", "2"], ["cannot resume", "friction"], None),
    ("resume-other-dt", RESUME + ["--dt", "0.05"], ["cannot resume", "time step"], None),
    ("resume-other-engine", RESUME + ["--engine", "lax"], ["cannot resume", "engine"], None),
    ("resume-other-loads", RESUME + ["--pull", "3"], ["cannot resume", "loads"], None),
    ("resume-corrupt-checkpoint", RESUME, ["checkpoint.npz", "not a readable"], _corrupt_checkpoint),
    ("resume-foreign-npz", RESUME, ["checkpoint.npz", "not a readable"], _foreign_checkpoint),
    ("resume-other-engine-checkpoint", RESUME, ["checkpoint.npz", "dnarod-lax-checkpoint"], _lax_checkpoint),
    ("resume-missing-checkpoint", RESUME, ["checkpoint.npz", "does not exist"], _no_checkpoint),
    ("resume-turning-clamp-other-time", ["simulate", SEQ, "-o", "{w}/tw", "--resume", *QUICK[2:], "--time", "0.004",
                                         *TWIST], ["cannot resume", "total time (--time)", "--turns"], _turning_run),
    ("analyze-existing-report", ["analyze", "{w}/run/trajectory.dtraj", "-o", "{w}/ana"],
     ["already holds an analysis report", "--overwrite"], None),
]

def _spec_overstretching(w):
    (w / "f80.toml").write_text('[ensemble]\nname = "x"\n[base]\nsource = "ACGTACGTAC"\nforce_pN = 80\n')
    # a sweep whose second member alone is out of range: refused before the first member runs
    (w / "salt_sweep.toml").write_text('[ensemble]\nname = "x"\n[base]\nsource = "ACGTACGTAC"\ntime_ns = 0.001\n'
                                       '[axes]\nsalt_M = [0.15, 100]\n')
    (w / "force_sweep.toml").write_text('[ensemble]\nname = "x"\n[base]\nsource = "ACGTACGTAC"\ntime_ns = 0.001\n'
                                        '[axes]\nforce_pN = [1, 80]\n')


DTRAJ = "{w}/run/trajectory.dtraj"
PROTO = ["--source", "40", "--time", "0.001", "--workers", "0", "-o", "{w}/n"]
# Held-out style cases, one per class: usage errors (click's own), out-of-range and non-finite numbers, huge
# sizes, unreadable/empty/truncated/binary/wrong-format files, conflicting options, outputs that exist.
CASES += [
    ("usage-not-a-number", ["simulate", SEQ, "--time", "abc", "-o", "{w}/n"], ["--time", "not a valid float"], None),
    ("usage-unknown-command", ["bogus"], ["No such command", "bogus"], None),
    ("usage-unknown-option", ["protocol", "hat", "--bogus", "--turns", "0", "-o", "{w}/n"], ["--bogus"], None),
    ("usage-missing-argument", ["simulate", "-o", "{w}/n"], ["Missing argument", "SOURCE"], None),
    ("time-huge", ["simulate", SEQ, "-o", "{w}/n", *QUICK, "--time", "1e300"], ["--time", "steps, more than"], None),
    ("dt-tiny", ["simulate", SEQ, "-o", "{w}/n", *QUICK, "--dt", "1e-30"], ["--dt", "steps, more than"], None),
    ("time-nan", ["simulate", SEQ, "-o", "{w}/n", *QUICK, "--time", "nan"], ["--time nan"], None),
    ("salt-zero", ["simulate", SEQ, "-o", "{w}/n", *QUICK, "--salt", "0"], ["--salt 0"], None),
    ("threads-huge", ["simulate", SEQ, "-o", "{w}/n", *QUICK, "--threads", "100000"], ["--threads 100000"], None),
    ("node-count-huge", ["simulate", "1000000000000", "-o", "{w}/n", *QUICK], ["nodes is more than"], None),
    ("ring-delta-lk-huge", ["simulate", "ACGT" * 10, "--ring", "--delta-lk", "100000", "-o", "{w}/n", *QUICK],
     ["--delta-lk", "sigma"], None),
    ("verlet-with-friction", ["simulate", SEQ, "--integrator", "verlet", "--friction", "5", "-o", "{w}/n", *QUICK],
     ["--integrator verlet", "--friction 5"], None),
    ("platform-unknown", ["simulate", SEQ, "--platform", "Foo", "-o", "{w}/n", *QUICK], ["--platform Foo",
                                                                                         "not installed"], None),
    ("platform-wrong-case", ["simulate", SEQ, "--platform", "cpu", "-o", "{w}/n", *QUICK], ["did you mean CPU"], None),
    ("out-empty", ["simulate", SEQ, "-o", "", *QUICK], ["output folder", "-o"], None),
    ("source-empty-npz", ["simulate", "{w}/empty.npz", "-o", "{w}/n", *QUICK], ["empty.npz", "cannot read"], None),
    ("source-truncated-npz", ["simulate", "{w}/trunc.npz", "-o", "{w}/n", *QUICK], ["trunc.npz", "cannot read"],
     None),
    ("forcefield-binary", ["simulate", SEQ, "-f", "{w}/binary.toml", "-o", "{w}/n", *QUICK], ["binary.toml"], None),
    ("forcefields-binary", ["forcefields", "{w}/binary.toml"], ["binary.toml", "cannot read"], None),
    ("steps-binary-pairs-file", ["steps", str(PDB), "--pairs", "{w}/binary.bin"], ["binary.bin", "line"], None),
    ("steps-csv-empty-name", ["steps", str(PDB), "--csv", ""], ["--csv", "file name"], None),
    ("steps-altloc-absent", ["steps", str(PDB), "--altloc", "ZZ"], ["altloc 'ZZ'", "does not occur"], None),
    ("build-sequence-space", ["build", "--sequence", "AC GT", "-o", "{w}/m.npz"], ["--sequence", "' '"], None),
    ("build-onto-existing", ["build", "--sequence", "ACGTACGT", "-o", "{w}/model.npz"], ["exists", "--overwrite"],
     None),
    ("build-wrong-suffix", ["build", "--sequence", "ACGTACGT", "-o", "{w}/m.pdb"], ["-o", ".npz"], None),
    ("rebuild-wrong-suffix", ["rebuild", "{w}/model.npz", "-o", "{w}/x.xyz", "--no-minimize"], ["-o", ".pdb"], None),
    ("rebuild-onto-existing", ["rebuild", "{w}/model.npz", "-o", "{w}/exists.pdb", "--no-minimize"],
     ["exists", "--overwrite"], None),
    ("rebuild-truncated-model", ["rebuild", "{w}/trunc.npz", "-o", "{w}/x.pdb", "--no-minimize"],
     ["trunc.npz", "cannot read"], None),
    ("analyze-binary-dcd", ["analyze", "{w}/bad.dcd", "-t", "{w}/run/trajectory.pdb", "-o", "{w}/n", "--no-plots"],
     ["bad.dcd", "not a DCD file"], None),
    ("analyze-step-zero", ["analyze", DTRAJ, "--step", "0", "-o", "{w}/n", "--no-plots"], ["--step 0"], None),
    ("analyze-one-block", ["analyze", DTRAJ, "--blocks", "1", "-o", "{w}/n", "--no-plots"], ["--blocks 1"], None),
    ("analyze-stop-negative", ["analyze", DTRAJ, "--stop", "-1", "-o", "{w}/n", "--no-plots"], ["--stop -1"], None),
    ("analyze-temperature-zero", ["analyze", DTRAJ, "--temperature", "0", "-o", "{w}/n", "--no-plots"],
     ["--temperature 0"], None),
    ("analyze-exclude-all-steps", ["analyze", DTRAJ, "--exclude-ends", "100", "-o", "{w}/n", "--no-plots"],
     ["--exclude-ends 100", "no steps"], None),
    ("ensemble-timeout-nan", ["ensemble", str(ROOT / "examples" / "force_extension.toml"), "-o", "{w}/n",
                              "--scheduler", "tcp://127.0.0.1:1", "--timeout", "nan"], ["--timeout nan"], None),
    ("ensemble-scheduler-malformed", ["ensemble", str(ROOT / "examples" / "force_extension.toml"), "-o", "{w}/n",
                                      "--scheduler", "garbage"], ["--scheduler garbage", "tcp://HOST:PORT"], None),
    ("ensemble-force-overstretching", ["ensemble", "{w}/f80.toml", "-o", "{w}/n", "--workers", "0"],
     ["--pull 80", "overstretch"], _spec_overstretching),
    ("ensemble-sweep-one-salt-out-of-range", ["ensemble", "{w}/salt_sweep.toml", "-o", "{w}/n", "--workers", "0"],
     ["member 1", "--salt 100", "at most 6"], _spec_overstretching),
    ("ensemble-sweep-one-force-overstretching", ["ensemble", "{w}/force_sweep.toml", "-o", "{w}/n", "--workers", "0"],
     ["member 1", "80 pN", "overstretches"], _spec_overstretching),
    ("protocol-salt-huge", ["protocol", "rings", "--delta-lk", "0", *PROTO, "--salt", "100"],
     ["--salt", "at most 6"], None),
    ("protocol-time-negative", ["protocol", "hat", "--turns", "0", *PROTO, "--time", "-1"], ["time_ns", "> 0"], None),
    ("protocol-force-nan", ["protocol", "force-extension", "--force", "nan", *PROTO], ["--force", "finite"], None),
    ("protocol-force-empty-entry", ["protocol", "force-extension", "--force", "1,,2", *PROTO], ["--force", "empty entry"],
     None),
    ("protocol-delta-lk-inf", ["protocol", "rings", "--delta-lk", "inf", *PROTO], ["--delta-lk", "finite"], None),
    ("protocol-seed-negative", ["protocol", "hat", "--turns", "0", *PROTO, "--seed", "-1"], ["seed"], None),
    ("protocol-temperature-negative", ["protocol", "hat", "--turns", "0", *PROTO, "--temperature", "-1"],
     ["temperature_K"], None),
    ("protocol-workers-negative", ["protocol", "hat", "--turns", "0", *PROTO, "--workers", "-1"], ["--workers -1"],
     None),
    ("torque-with-zero-pull", ["simulate", SEQ, "-o", "{w}/n", *QUICK, "--pull", "0", "--torque", "5"],
     ["--torque 5", "--pull absent or 0"], None),
    ("protocol-ring-too-small", ["protocol", "rings", "--delta-lk", "0", *PROTO, "--source", "5"],
     ["5-node ring", "kT of elastic energy per step"], None),
    ("protocol-into-run-folder", ["protocol", "hat", "--turns", "0", *PROTO, "-o", "{w}/run"],
     ["not a protocol folder"], None),
]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_misuse_is_one_line_exit_2_and_changes_nothing(work, case, assert_refused):
    _, args, words, setup = case
    if setup is not None:
        setup(work)
    assert_refused(work, args, words)


@pytest.mark.parametrize("var", ["DNAROD_PLUGIN", "DNAROD_DEVICE_KERNELS"])
def test_misspelt_switch_is_refused(work, monkeypatch, var):
    """An on/off environment switch with another value than 0/1 is one line, exit 2 (not silently "on")."""
    from dnarod.engines.openmm import plugin

    monkeypatch.setenv(var, "banana")
    monkeypatch.setattr(plugin, "_STATUS", None)
    monkeypatch.setattr(plugin, "_DEVICE", {})
    args = ["simulate", SEQ, "-o", str(work / "n"), *QUICK]
    if var == "DNAROD_DEVICE_KERNELS":
        args += ["--platform", "OpenCL"]
    r = CliRunner().invoke(main, args)
    if var == "DNAROD_DEVICE_KERNELS" and "banana" not in r.stderr:
        pytest.skip(f"no OpenCL platform or plugin here: {r.stderr.strip()[:200]}")
    assert r.exit_code == 2, (r.output, r.exception)
    err = r.stderr.strip()
    assert "\n" not in err and f"{var}='banana'" in err, err
    assert not (work / "n").exists() or not any((work / "n").iterdir())


def test_long_sequence_and_sequence_files_are_sequences(tmp_path):
    """A 300-letter sequence is a sequence, not a file name; FASTA and plain-text files are read."""
    rng = np.random.default_rng(0)
    seq = "".join(rng.choice(list("ACGT"), 300))
    r = CliRunner().invoke(main, ["lax-run", seq, "-o", str(tmp_path / "a"), *QUICK, "--no-export"])
    assert r.exit_code == 0, r.output
    from dnarod.core.model import RodModel

    assert RodModel.load(tmp_path / "a" / "final_model.npz").sequence == seq
    (tmp_path / "s.fasta").write_text(">x test\n" + seq[:150] + "\n" + seq[150:].lower() + "\n>second\nACGT\n")
    (tmp_path / "s.txt").write_text(seq[:40] + "\n")
    for name, expect in (("s.fasta", seq), ("s.txt", seq[:40])):
        r = CliRunner().invoke(main, ["lax-run", str(tmp_path / name), "-o", str(tmp_path / name[:-4]), *QUICK,
                                      "--no-export"])
        assert r.exit_code == 0, r.output
        assert RodModel.load(tmp_path / name[:-4] / "final_model.npz").sequence == expect


def test_analyze_overwrite_removes_its_stale_outputs(work):
    ana = work / "ana"
    (ana / "strain_distributions.png").write_bytes(b"stale")  # a plot a --no-plots rerun would not rewrite
    (ana / "notes.txt").write_text("mine")  # not the report's: kept
    r = CliRunner().invoke(main, ["analyze", str(work / "run" / "trajectory.dtraj"), "-o", str(ana), "--overwrite",
                                  "--no-plots"])
    assert r.exit_code == 0, r.output
    assert not (ana / "strain_distributions.png").exists() and (ana / "notes.txt").read_text() == "mine"
    assert (ana / "summary.json").is_file()


def test_time_already_reached_changes_nothing(work):
    before = _snapshot(work / "run")
    r = CliRunner().invoke(main, ["simulate", SEQ, "-o", str(work / "run"), "--resume", "--time", "0.001",
                                  "--frame-interval", "0.2", "--no-progress"])
    assert r.exit_code == 0, r.output
    assert "already at step" in r.stdout and "nothing to do" in r.stdout
    assert _snapshot(work / "run") == before


def test_resume_says_where_it_resumed_and_lists_every_file(work):
    r = CliRunner().invoke(main, ["simulate", SEQ, "-o", str(work / "run"), "--resume", "--time", "0.004",
                                  "--frame-interval", "0.2", "--no-progress"])
    assert r.exit_code == 0, r.output
    assert r.stdout.startswith("resumed from step ")
    wrote = r.stdout.strip().splitlines()[-1]
    for name in ("run.json", "trajectory.dtraj", "energies.csv", "checkpoint.npz", "final_model.npz",
                 "trajectory.pdb", "trajectory.dcd"):
        assert name in wrote, name


API_BAD = [
    dict(time_ns=1e300), dict(seed="x"), dict(seed=1.5), dict(threads="x"), dict(duplex="x"), dict(delta_lk=1.5),
    dict(forcefield=None), dict(elastic="x"), dict(circular="yes"), dict(extra=None), dict(loads="junk"),
]


@pytest.mark.parametrize("bad", API_BAD, ids=[next(iter(b)) + "=" + repr(next(iter(b.values()))) for b in API_BAD])
def test_api_bad_run_arguments_raise_dnarod_errors(tmp_path, bad):
    """run(RunSpec(...)) with a bad argument raises a DnarodError naming it, and writes nothing."""
    from dnarod.core.errors import DnarodError
    from dnarod.run import RunSpec, run

    spec = RunSpec(**{**dict(source=SEQ, engine="lax", time_ns=0.001, excluded_volume=False, electrostatics=False,
                             seed=1), **bad})
    with pytest.raises(DnarodError) as exc:
        run(spec, tmp_path / "r", progress=False)
    name = next(iter(bad)).replace("_ns", "").replace("_", "-")
    assert name.split("-")[0] in str(exc.value) and "\n" not in str(exc.value)
    assert not (tmp_path / "r").exists()


def test_api_bad_outdir_model_and_protocol_values(work):
    from dnarod.analysis.report import analyze
    from dnarod.core.errors import DnarodError
    from dnarod.core.model import RodModel
    from dnarod.workflows.protocols import hat_curve, ring_supercoiling
    from dnarod.run import RunSpec, run

    tmp_path = work / "api"
    tmp_path.mkdir()
    with pytest.raises(DnarodError, match="output folder"):
        run(RunSpec(source=SEQ, engine="lax", excluded_volume=False, electrostatics=False), None)
    for name in ("empty.npz", "trunc.npz"):
        with pytest.raises(DnarodError, match="cannot read dnarod model"):
            RodModel.load(work / name)
    with pytest.raises(DnarodError, match="expected a number"):
        hat_curve("abc", tmp_path / "h", source="40", base=dict(time_ns=0.001), workers=0)
    with pytest.raises(DnarodError, match="unknown key 'tim_ns'"):
        hat_curve([0], tmp_path / "h", source="40", base=dict(tim_ns=0.001), workers=0)
    with pytest.raises(DnarodError, match="delta_lk"):
        ring_supercoiling([0.5], tmp_path / "r", source="40", workers=0)
    with pytest.raises(DnarodError, match="--step 0"):
        analyze(str(work / "run" / "trajectory.dtraj"), out=str(tmp_path / "a"), step=0, plots=False)
    assert not any(tmp_path.iterdir())
