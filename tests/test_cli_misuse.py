"""Every misuse of the command line: one line on stderr naming the option or file, exit status 2,
nothing on stdout, and every file that existed before left byte-for-byte unchanged."""
import shutil
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from dnarod.cli import main

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
    ("trap-node-missing", ["simulate", SEQ, "--trap", "99:5", "-o", "{w}/n", *QUICK], ["--trap", "node 99"], None),
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


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_misuse_is_one_line_exit_2_and_changes_nothing(work, case):
    _, args, words, setup = case
    if setup is not None:
        setup(work)
    before = _snapshot(work)
    args = [a.replace("{w}", str(work)) for a in args]
    r = CliRunner().invoke(main, args)
    assert r.exit_code == 2, (r.output, r.exception)
    assert r.stdout == ""
    err = r.stderr.strip()
    assert "\n" not in err and err.startswith("dnarod: error: "), err
    for w in words:
        assert w in err, (w, err)
    after = _snapshot(work)
    for p, data in before.items():
        assert after.get(p) == data, f"{p} changed"
    assert not (work / "n").exists() or not any((work / "n").iterdir())


def test_long_sequence_and_sequence_files_are_sequences(tmp_path):
    """A 300-letter sequence is a sequence, not a file name; FASTA and plain-text files are read."""
    rng = np.random.default_rng(0)
    seq = "".join(rng.choice(list("ACGT"), 300))
    r = CliRunner().invoke(main, ["lax-run", seq, "-o", str(tmp_path / "a"), *QUICK, "--no-export"])
    assert r.exit_code == 0, r.output
    from dnarod.model import RodModel

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
