"""Misuse classes of output folders, locks and bounds, each fixed in the API that has the concept: a report
folder replaced without --overwrite, output written into any non-empty folder, protocol and report folders without
the lock of run folders, the protocol settings check only on the command line, the protocols' clamp stiffness unbounded,
``simulate`` without ``--charge``/``--cutoff-debye``, and lock files left behind. Refusals use the shared
``assert_refused`` (one stderr line, exit status 2, nothing on stdout, no file changed)."""
import json
import os
import re
import socket
from pathlib import Path

import pytest
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.core.io import LOCK_NAME, folder_lock

SEQ = "ACGTTGCAAC"
LAX = ["--engine", "lax", "--time", "0.001", "--no-progress", "--seed", "3", "--frame-interval", "0.2"]
HAT = ["protocol", "hat", "--turns", "0", "--source", "40", "--time", "0.001", "--workers", "0"]


@pytest.fixture
def work(tmp_path):
    """A project folder (files and a .git folder, no dnarod output), a finished validation report, a protocol
    folder and a spec file; nothing has run."""
    (tmp_path / "proj" / ".git").mkdir(parents=True)
    (tmp_path / "proj" / "notes.txt").write_text("my notes\n")
    rep = tmp_path / "rep"
    rep.mkdir()
    (rep / "results.json").write_text(json.dumps({"checks": {"helix": {"passed": True, "plots": []}}}) + "\n")
    (rep / "report.md").write_text("# dnarod validation report\n")
    (tmp_path / "pl").mkdir()
    (tmp_path / "spec.toml").write_text('[base]\nsource = "ACGTACGTAC"\ntime_ns = 0.001\nengine = "lax"\n'
                                        'excluded_volume = false\nelectrostatics = false\n')
    (tmp_path / "tweezers.toml").write_text('[ensemble]\nprotocol = "magnetic-tweezers"\n[base]\nsource = "40"\n'
                                            'time_ns = 0.001\nforce_pN = 1\nrotation_clamp_kJ_mol = 1e7\n'
                                            '[axes]\nturns = [0, 0.5]\n')
    (tmp_path / "hot.toml").write_text((tmp_path / "spec.toml").read_text() + "temperature_K = 1e9\n")
    return tmp_path


def _hold(folder):
    def setup(w):
        cm = folder_lock(w / folder)
        cm.__enter__()
        return cm
    return setup


PROJ = ["proj", "not empty", ".git, notes.txt", "choose a new or empty -o folder"]
CASES = [
    # 1. a finished report is replaced only with --overwrite
    ("validate-over-a-report", ["validate", "--only", "helix", "-o", "{w}/rep"],
     ["rep already holds a validation report (results.json)", "--overwrite"], None),
    # 2. any command that writes a folder refuses a non-empty folder that is not of its kind
    ("simulate-into-project", ["simulate", SEQ, "-o", "{w}/proj", *LAX], ["not a run folder", *PROJ], None),
    ("lax-run-overwrite-into-project", ["lax-run", SEQ, "-o", "{w}/proj", "--overwrite", *LAX[2:]],
     ["not a run folder", *PROJ], None),
    ("simulate-into-root", ["simulate", SEQ, "-o", "/", *LAX], ["/: not a run folder and not empty"], None),
    ("simulate-into-report", ["simulate", SEQ, "-o", "{w}/rep", *LAX], ["not a run folder", "report.md"], None),
    ("protocol-into-project", [*HAT, "-o", "{w}/proj"], ["not a protocol folder", *PROJ], None),
    ("protocol-overwrite-into-report", [*HAT, "-o", "{w}/rep", "--overwrite"], ["not a protocol folder",
                                                                               "results.json"], None),
    ("validate-into-project", ["validate", "--only", "helix", "-o", "{w}/proj"],
     ["not a validation report folder", *PROJ], None),
    ("ensemble-into-project", ["ensemble", "{w}/spec.toml", "-o", "{w}/proj", "--workers", "0"],
     ["not an ensemble folder", *PROJ], None),
    ("analyze-into-project", ["analyze", "{w}/t.dtraj", "-o", "{w}/proj"], ["not an analysis report folder", *PROJ],
     None),
    # 3. protocol and report folders are locked as run folders are
    ("protocol-folder-in-use", [*HAT, "-o", "{w}/pl"], ["pl is in use by another dnarod process (pid"],
     _hold("pl")),
    ("validate-folder-in-use", ["validate", "--only", "helix", "-o", "{w}/pl"],
     ["report folder", "pl is in use by another dnarod process"], _hold("pl")),
    # 5. the protocols' clamp has the bound of every other load
    ("protocol-clamp-k-too-stiff", [*HAT, "-o", "{w}/n", "--clamp-k", "1e7"],
     ["--clamp-k (rotation_clamp_kJ_mol) 1e+07", "use at most", "sets the time step"], None),
    ("ensemble-protocol-clamp-too-stiff", ["ensemble", "{w}/tweezers.toml", "-o", "{w}/n", "--workers", "0"],
     ["member 0", "rotation_clamp_kJ_mol 1e+07", "use at most"], None),
    # 6. simulate --charge / --cutoff-debye, checked as the protocols check them
    ("simulate-charge-unknown", ["simulate", SEQ, "-o", "{w}/n", "--time", "0.001", "--charge", "debye"],
     ["--charge 'debye'", "calibrated", "manning"], None),
    ("simulate-cutoff-inside-contact", ["simulate", SEQ, "-o", "{w}/n", "--time", "0.001", "--cutoff-debye", "1"],
     ["--cutoff-debye 1:", "inside the", "contact"], None),
    ("simulate-cutoff-nan", ["simulate", SEQ, "-o", "{w}/n", "--time", "0.001", "--cutoff-debye", "nan"],
     ["--cutoff-debye nan", "positive, finite"], None),
    # found by the misuse probe: --cutoff-debye 1e300 overflowed OpenMM's neighbour grid (a traceback)
    ("simulate-cutoff-1e300", ["simulate", SEQ, "-o", "{w}/n", "--time", "0.001", "--cutoff-debye", "1e300"],
     ["--cutoff-debye 1e+300", "more than 50 Debye lengths"], None),
    ("protocol-cutoff-51", [*HAT, "-o", "{w}/n", "--cutoff-debye", "51"], ["--cutoff-debye 51", "more than 50"],
     None),
    ("lax-run-charge", ["lax-run", SEQ, "-o", "{w}/n", *LAX[2:], "--charge", "manning"],
     ["--charge", "the lax engine has none"], None),
    # found by the misuse probe: a temperature far above the solvent's range ran and blew up at the first step
    ("simulate-temperature-1e9", ["lax-run", SEQ, "-o", "{w}/n", *LAX[2:], "-T", "1e9"],
     ["--temperature 1e+09", "from 0 to 373.15 K"], None),
    ("ensemble-temperature-1e9", ["ensemble", "{w}/hot.toml", "-o", "{w}/n", "--workers", "0"],
     ["member 0", "1e+09", "373.15 K"], None),
    ("protocol-temperature-400", [*HAT, "-o", "{w}/n", "--temperature", "400"],
     ["--temperature (temperature_K)", "at most 373.15 K", "got 400"], None),
    ("simulate-charge-no-electrostatics", ["simulate", SEQ, "-o", "{w}/n", "--time", "0.001", "--charge", "manning",
                                           "--no-electrostatics"], ["--charge", "which are off"], None),
]


@pytest.mark.parametrize("case", CASES, ids=[c[0] for c in CASES])
def test_misuse_class_is_one_line_exit_2_and_changes_nothing(work, case, assert_refused):
    _, args, words, setup = case
    if "{w}/t.dtraj" in args:
        _write_dtraj(work / "t.dtraj")
    assert_refused.case(work, args, words, setup)


def _write_dtraj(path):
    import numpy as np

    from dnarod.structure.inputs import load_model
    from dnarod.core.trajectory import Trajectory

    m = load_model("ACGTACGTAC")
    Trajectory([0.0, 1.0], np.repeat(m.positions[None], 2, 0), np.repeat(m.frames[None], 2, 0), [0, 10]).save(path)


def _invoke(args):
    return CliRunner().invoke(main, [str(a) for a in args])


# ---------------------------------------------------------------------------------------------------------
# 1. validate: a report is replaced only with --overwrite
def test_validate_report_is_replaced_only_with_overwrite_and_members_are_kept(tmp_path, monkeypatch):
    """A stub check (no simulation) writes a plot named after its call; the second run is refused without
    --overwrite and changes nothing, with it the report is the new one, the old plot that the new report does not
    list is gone, and a folder of the report's that it does not list is untouched. A non-empty folder that holds
    no report (e.g. only the members of the buckling check, which left the product for research/buckling/check)
    is refused."""
    from dnarod import validate as V

    calls = []

    def stub(out_dir, quick=False):
        calls.append(out_dir)
        name = f"plot{len(calls)}.png"
        (Path(out_dir) / name).write_bytes(b"png")
        return {"passed": True, "value": float(len(calls)), "plots": [name]}

    monkeypatch.setattr(V, "check_function", lambda name: stub)
    out = tmp_path / "rep"
    args = ["validate", "--only", "helix", "-o", out]
    assert _invoke(args).exit_code == 0
    members = out / "members_kept" / "m1"
    members.mkdir(parents=True)
    (members / "result.json").write_text("{}\n")
    first = json.loads((out / "results.json").read_text())
    assert first["checks"]["helix"]["value"] == 1.0 and (out / "plot1.png").exists()
    r = _invoke(args)
    assert r.exit_code == 2 and "--overwrite" in r.stderr and len(calls) == 1, r.output
    r = _invoke([*args, "--overwrite"])
    assert r.exit_code == 0, r.output
    new = json.loads((out / "results.json").read_text())
    assert new["checks"]["helix"]["value"] == 2.0 and new["checks"]["helix"]["plots"] == ["plot2.png"]
    assert not (out / "plot1.png").exists() and (out / "plot2.png").exists()
    assert (members / "result.json").read_text() == "{}\n"
    assert not (out / LOCK_NAME).exists()
    # a folder holding only members of the buckling check (no report): not a report folder, refused
    again = tmp_path / "interrupted"
    (again / "buckling_members" / "m1").mkdir(parents=True)
    r = _invoke(["validate", "--only", "helix", "-o", again])
    assert r.exit_code == 2 and "buckling_members" in r.stderr and len(calls) == 2, r.output
    assert not (again / "results.json").exists()


# ---------------------------------------------------------------------------------------------------------
# 4. the protocol settings check is the API's
def test_protocol_api_refuses_a_folder_of_other_settings(tmp_path):
    """hat_curve into a folder recorded with another time is refused before anything runs, as on the command
    line; another protocol's folder too; a non-protocol folder too."""
    from dnarod.core.errors import DnarodError
    from dnarod.workflows.protocols import hat_curve, torque_turns
    from dnarod.workflows.protocols.folder import write_protocol_record

    out = tmp_path / "hat"
    base = dict(time_ns=0.001)
    shared = dict(base, source="40", start="static", settle_ns=None, settle_buckled_ns=None)
    write_protocol_record(out, "magnetic_tweezers", shared)
    before = sorted(p.name for p in out.iterdir())
    with pytest.raises(DnarodError, match=r"time_ns 0\.001 -> 0\.002.*--overwrite"):
        hat_curve([0], out, source="40", base=dict(time_ns=0.002), workers=0)
    with pytest.raises(DnarodError, match="a magnetic_tweezers run, not torque_turns"):
        torque_turns([0], out, source="40", base=base, workers=0)
    assert sorted(p.name for p in out.iterdir()) == before       # no member ran, no lock left
    (tmp_path / "proj").mkdir()
    (tmp_path / "proj" / "data.csv").write_text("x\n")
    with pytest.raises(DnarodError, match="not a protocol folder and not empty .*data.csv"):
        hat_curve([0], tmp_path / "proj", source="40", base=base, workers=0)


def test_protocol_run_records_its_settings_and_leaves_no_lock(tmp_path):
    """A tiny protocol through the API writes protocol.json (the settings the refusal compares) and removes its
    lock; the same call again reuses the member."""
    from dnarod.workflows.protocols import hat_curve

    out = tmp_path / "hat"
    kw = dict(source="40", base=dict(time_ns=0.001, equilibration_ns=0.001), workers=0, progress=False, plots=False)
    c = hat_curve([0], out, **kw)
    rec = json.loads((out / "protocol.json").read_text())
    assert rec["kind"] == "magnetic_tweezers" and rec["settings"]["time_ns"] == 0.001
    assert rec["settings"]["source"] == "40" and rec["settings"]["start"] == "static"
    assert not (out / LOCK_NAME).exists()
    member = next((out / "members").rglob("protocol_result.json"))
    stamp = member.stat().st_mtime_ns
    c2 = hat_curve([0], out, **kw)
    assert member.stat().st_mtime_ns == stamp
    assert c2.rows[0]["relative_extension"] == c.rows[0]["relative_extension"]


# ---------------------------------------------------------------------------------------------------------
# 5. one stiffness rule for simulate and the protocols
def test_clamp_bound_is_the_same_for_simulate_and_protocol(work):
    """The largest accepted clamp stiffness named by `protocol hat --clamp-k` equals the one `simulate
    --rotation-clamp` names for the same chain (40 bp, node 0 clamped): one rule, one number."""
    most = []
    for args in (["simulate", "40", "-o", work / "n", *LAX, "--clamp-first", "--rotation-clamp", "1e7"],
                 [*HAT, "-o", work / "n", "--clamp-k", "1e7"]):
        r = _invoke(args)
        assert r.exit_code == 2, r.output
        most.append(float(re.search(r"use at most ([0-9.e+]+)", r.stderr).group(1)))
    assert most[0] == most[1] and 1e4 < most[0] < 1e7, most
    from dnarod.workflows.protocols.tweezers import DEFAULT_CLAMP_K

    assert DEFAULT_CLAMP_K < most[0]            # the protocols' default clamp is well inside the bound


# ---------------------------------------------------------------------------------------------------------
# 6. simulate --charge: recorded in the fingerprint, a resume with another charge is refused
def test_simulate_charge_is_recorded_and_a_resume_with_another_is_refused(tmp_path):
    out = tmp_path / "r"
    args = ["simulate", "ACGTACGTACGTACGTACGT", "-o", out, "--no-progress", "--seed", "1", "--no-export",
            "--platform", "Reference"]
    r = _invoke([*args, "--time", "0.001", "--charge", "Manning", "--cutoff-debye", "8"])
    assert r.exit_code == 0, r.output
    assert "(manning)" in r.stdout and "(8 Debye lengths)" in r.stdout
    nb = json.loads((out / "run.json").read_text())["fingerprint"]["nonbonded"]
    assert nb["charge_model"] == "manning" and nb["cutoff_debye"] == 8.0
    assert abs(nb["charge_e_per_node"] - 0.48) < 0.01           # Manning's 1/(l_B/b) per bp
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    for other, words in ((["--cutoff-debye", "8"], ["charge_model was manning, now calibrated"]),
                         (["--charge", "manning"], ["cutoff_debye was 8.0, now 12.0"])):
        r = _invoke([*args, "--time", "0.002", "--resume", *other])
        assert r.exit_code == 2 and r.stdout == "", r.output
        assert all(w in r.stderr for w in ["cannot resume", "--charge/--cutoff-debye", *words]), r.stderr
        assert {p.name: p.read_bytes() for p in out.iterdir()} == before
    r = _invoke([*args, "--time", "0.002", "--resume", "--charge", "manning", "--cutoff-debye", "8"])
    assert r.exit_code == 0 and r.stdout.startswith("resumed from step"), r.output


# ---------------------------------------------------------------------------------------------------------
# 7. the lock file: gone after a clean end, a stale one taken over with a notice
def test_run_removes_its_lock_and_takes_over_a_stale_one(tmp_path):
    out = tmp_path / "r"
    r = _invoke(["lax-run", SEQ, "-o", out, *LAX[2:]])
    assert r.exit_code == 0, r.output
    assert not (out / LOCK_NAME).exists()
    dead = _dead_pid()
    (out / LOCK_NAME).write_text(f"{dead} {socket.gethostname()}\n")      # left by a killed run
    r = _invoke(["lax-run", SEQ, "-o", out, "--resume", "--time", "0.002", *LAX[4:]])
    assert r.exit_code == 0, r.output
    notice = [ln for ln in r.stderr.splitlines() if "lock" in ln]
    assert len(notice) == 1 and f"pid {dead} (no longer running)" in notice[0], r.stderr
    assert notice[0].startswith("dnarod: warning: ") and "took over" in notice[0]
    assert not (out / LOCK_NAME).exists()
    # a folder holding nothing but a stale lock counts as empty
    only = tmp_path / "only_lock"
    only.mkdir()
    (only / LOCK_NAME).write_text(f"{dead} {socket.gethostname()}\n")
    r = _invoke(["lax-run", SEQ, "-o", only, *LAX[2:]])
    assert r.exit_code == 0 and (only / "run.json").exists() and not (only / LOCK_NAME).exists(), r.output


def test_lock_is_exclusive_across_processes_and_freed_when_the_holder_dies(tmp_path):
    """A lock held by another live process refuses; once that process is killed (no clean exit: the file stays)
    the lock is free, and the next taker names the dead holder."""
    import subprocess
    import sys
    import warnings

    from dnarod.core.errors import DnarodError

    code = ("import sys, time\nfrom dnarod.core.io import folder_lock\n"
            "with folder_lock(sys.argv[1]):\n    print('held', flush=True)\n    time.sleep(60)\n")
    p = subprocess.Popen([sys.executable, "-c", code, str(tmp_path)], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "held"
        with pytest.raises(DnarodError, match=f"in use by another dnarod process \\(pid {p.pid}\\)"):
            with folder_lock(tmp_path):
                pass
    finally:
        p.kill()
        p.wait()
    assert (tmp_path / LOCK_NAME).exists()                      # killed: no clean exit
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        with folder_lock(tmp_path):
            assert (tmp_path / LOCK_NAME).read_text().split()[0] == str(os.getpid())
    assert len(caught) == 1 and f"pid {p.pid} (no longer running)" in str(caught[0].message)
    assert not (tmp_path / LOCK_NAME).exists()


def _dead_pid():
    """A pid that no process has (a child that has been reaped)."""
    import subprocess
    import sys

    p = subprocess.Popen([sys.executable, "-c", "pass"])
    p.wait()
    return p.pid


def test_temperature_bound_is_liquid_water():
    """373.15 K (100 degC) is accepted by a run and by a protocol's settings, just above it is refused by both."""
    from dnarod.core.errors import DnarodError
    from dnarod.workflows.protocols.settings import _checked_settings
    from dnarod.run import RunSpec

    spec = RunSpec(source=SEQ, engine="lax", excluded_volume=False, electrostatics=False)
    for T in (0.0, 300.0, 373.15):
        spec.replace(temperature=T).check()
        _checked_settings({"temperature_K": T or 1.0}, [], [])
    with pytest.raises(DnarodError, match="from 0 to 373.15 K"):
        spec.replace(temperature=373.16).check()
    with pytest.raises(DnarodError, match="at most 373.15 K"):
        _checked_settings({"temperature_K": 373.16}, [], [])


def test_cutoff_bound_in_the_api():
    """The API (RunSpec, the protocols' member settings) refuses the cutoffs the options refuse; 50 is accepted."""
    from dnarod.core.errors import DnarodError
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.run import RunSpec

    RunSpec(source=SEQ, cutoff_debye=50.0).check()
    settings = dict(excluded_volume=True, electrostatics=True, salt_M=0.15, temperature_K=300.0)
    assert member_nonbonded(dict(settings, cutoff_debye=50.0)).cutoff_debye == 50.0
    for bad in (50.5, 1e300, float("inf"), 0.0):
        with pytest.raises(DnarodError, match="cutoff"):
            RunSpec(source=SEQ, cutoff_debye=bad).check()
        with pytest.raises(DnarodError, match="cutoff_debye"):
            member_nonbonded(dict(settings, cutoff_debye=bad))
