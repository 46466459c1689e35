"""The non-bonded charge model and cutoff as a recorded, checked choice: run fingerprints and resume, protocol
members' results, the protocol command's ``--charge`` / ``--cutoff-debye``, and the validation report's labels."""
import json

import pytest
from click.testing import CliRunner

from dnarod.cli.main import main
from dnarod.core.errors import ParameterError
from dnarod.physics.nonbonded import NonbondedSettings, member_nonbonded, nonbonded_record
from dnarod.run import RunSpec, run
from dnarod.run.spec import compare_fingerprints, fingerprint

SEQ = "ACGTTGCAACGTTGCA"
QUICK = dict(source=SEQ, platform="Reference", dt=0.02, frame_interval_ps=0.2, checkpoint_interval_ps=0.8, seed=5,
             export=False)


def _fp(**kw):
    from dnarod.run.api import source_model

    spec = RunSpec(**{**QUICK, **kw}).check()
    return fingerprint(spec, source_model(spec), 0.02, 5)["nonbonded"]


def test_run_fingerprint_records_the_charge_and_cutoff():
    cal, man = _fp(), _fp(charge="manning", cutoff_debye=5.0)
    assert cal["charge_model"] == "calibrated" and cal["charge_e_per_node"] == pytest.approx(3.01, abs=0.01)
    assert cal["cutoff_debye"] == 12.0 and cal["cutoff_nm"] == pytest.approx(12 * 0.7879, abs=1e-3)
    assert man["charge_model"] == "manning" and man["charge_e_per_node"] == pytest.approx(0.48, abs=0.01)
    assert man["cutoff_debye"] == 5.0 and man["cutoff_nm"] == pytest.approx(5 * 0.7879, abs=1e-3)
    # "calibrated" spelled out is the default, not another run
    assert _fp(charge="calibrated", cutoff_debye=12.0) == cal
    with pytest.raises(ParameterError, match="non-bonded settings"):
        compare_fingerprints({"nonbonded": cal}, {"nonbonded": man}, "run.json")
    # without electrostatics there is no charge to record (and an old folder of that kind resumes as before)
    off = _fp(electrostatics=False)
    assert "charge_model" not in off
    compare_fingerprints({"nonbonded": dict(excluded_volume=True, electrostatics=False, salt_mol_L=0.15)},
                         {"nonbonded": off}, "run.json")


def test_a_run_folder_without_the_charge_is_refused_on_resume(tmp_path):
    spec = RunSpec(**QUICK, time_ns=0.002)
    run(spec, tmp_path / "r", progress=False)
    meta = json.loads((tmp_path / "r" / "run.json").read_text())
    nb = meta["fingerprint"]["nonbonded"]
    assert nb["charge_model"] == "calibrated" and nb["cutoff_debye"] == 12.0  # recorded in run.json
    assert run(spec.replace(time_ns=0.004), tmp_path / "r", resume=True, progress=False).resumed_from == 100
    with pytest.raises(ParameterError, match="non-bonded settings"):  # the same folder with another charge
        run(spec.replace(time_ns=0.006, charge="manning"), tmp_path / "r", resume=True, progress=False)
    # a folder written before the charge was recorded: which charge it ran with is unknown -> one clear refusal
    for k in ("charge_model", "charge_e_per_node", "cutoff_debye", "cutoff_nm"):
        nb.pop(k)
    (tmp_path / "r" / "run.json").write_text(json.dumps(meta))
    before = (tmp_path / "r" / "checkpoint.npz").read_bytes()
    with pytest.raises(ParameterError, match="does not record the non-bonded charge") as e:
        run(spec.replace(time_ns=0.006), tmp_path / "r", resume=True, progress=False)
    assert "\n" not in str(e.value) and "new run" in str(e.value)
    assert (tmp_path / "r" / "checkpoint.npz").read_bytes() == before  # nothing changed


@pytest.mark.parametrize("kw, words", [
    (dict(charge="debye"), "nonbonded charge"),
    (dict(charge=-1.0), ">= 0"),
    (dict(cutoff_debye=float("nan")), "--cutoff-debye"),
    (dict(cutoff_debye=-2.0), "--cutoff-debye"),
    (dict(cutoff_debye=2.0), "inside the 2.24-nm contact"),
    (dict(charge="manning", electrostatics=False), "electrostatics, which are off"),
])
def test_run_spec_refuses_a_bad_charge_or_cutoff(kw, words):
    with pytest.raises(ParameterError, match=words):
        RunSpec(**{**QUICK, **kw}).check()


def test_member_record_and_contact_rule():
    nb = member_nonbonded(dict(excluded_volume=True, electrostatics=True, salt_M=0.15, charge="manning",
                               cutoff_debye=5.0))
    rec = nonbonded_record(nb, 0.34, 300.0)
    assert rec["charge_model"] == "manning" and rec["cutoff_nm"] == pytest.approx(3.94, abs=0.01)
    assert nonbonded_record(NonbondedSettings(excluded_volume=False, electrostatics=False), 0.34, 300.0) is None
    # 2.85 Debye lengths are the 2.245-nm WCA range at 0.15 M: just above passes, just below is refused
    member_nonbonded(dict(excluded_volume=True, electrostatics=True, salt_M=0.15, cutoff_debye=2.86))
    with pytest.raises(ParameterError, match="give more than 2.85"):
        member_nonbonded(dict(excluded_volume=True, electrostatics=True, salt_M=0.15, cutoff_debye=2.84))
    # high salt: the contact lies beyond 12 Debye lengths (above ~2.7 M), where the screened repulsion is below
    # e^-12 of its contact value, so the default cut-off is accepted (protocols run up to 6 M) ...
    for salt in (3.0, 6.0):
        member_nonbonded(dict(excluded_volume=True, electrostatics=True, salt_M=salt))
    # ... while a cut-off that truncates a repulsion that still matters at 1 M is refused
    with pytest.raises(ParameterError, match="inside the 2.24-nm contact"):
        member_nonbonded(dict(excluded_volume=True, electrostatics=True, salt_M=1.0, cutoff_debye=5.0))


PROTO = ["rings", "--delta-lk", "0", "--source", "40", "--time", "0.001", "--equilibration", "0.001",
         "--workers", "0"]


@pytest.mark.parametrize("extra, words", [
    (["--charge", "debye"], ["--charge 'debye'", "calibrated", "manning"]),
    (["--charge", ""], ["--charge ''"]),
    (["--cutoff-debye", "nan"], ["--cutoff-debye nan", "finite"]),
    (["--cutoff-debye", "-3"], ["--cutoff-debye -3", "positive"]),
    (["--cutoff-debye", "0"], ["--cutoff-debye 0"]),
    (["--cutoff-debye", "2"], ["--cutoff-debye 2", "contact", "more than 2.85"]),
    (["--cutoff-debye", "4", "--salt", "1.0"], ["--cutoff-debye 4", "at 1 M", "more than 7.36"]),
])
def test_protocol_refuses_a_bad_charge_or_cutoff(tmp_path, extra, words):
    r = CliRunner().invoke(main, ["protocol", *PROTO, "-o", str(tmp_path / "p"), *extra])
    assert r.exit_code == 2, (r.output, r.exception)
    err = r.stderr.strip()
    assert "\n" not in err and err.startswith("dnarod: error: "), err
    for w in words:
        assert w in err, (w, err)
    assert not (tmp_path / "p").exists() or not any((tmp_path / "p").iterdir())


def test_protocol_runs_members_with_the_chosen_charge(tmp_path):
    r = CliRunner().invoke(main, ["protocol", *PROTO, "-o", str(tmp_path / "p"), "--charge", "Manning",
                                  "--cutoff-debye", "5"])
    assert r.exit_code == 0, (r.output, r.exception)
    (res,) = [json.loads(p.read_text()) for p in (tmp_path / "p").rglob("protocol_result.json")]
    assert res["settings"]["charge"] == "manning" and res["settings"]["cutoff_debye"] == 5.0
    nb = res["result"]["nonbonded"]
    assert nb["charge_model"] == "manning" and nb["charge_e_per_node"] == pytest.approx(0.48, abs=0.01)
    assert nb["cutoff_debye"] == 5.0 and nb["cutoff_nm"] == pytest.approx(3.94, abs=0.01)


def test_protocol_rows_through_the_ensemble_carry_the_nonbonded_record_as_scalars(tmp_path):
    """The ensemble keeps scalars per member: the members' nested non-bonded record becomes
    ``nonbonded_<key>`` columns (a nested dict failed every member of a tweezers or ring curve run on dask)."""
    from dnarod.workflows.ensemble.member import _scalars
    from dnarod.workflows.protocols.ensemble_hooks import MAGNETIC_TWEEZERS, RINGS, flat_row

    assert flat_row({"a": 1.0, "nonbonded": {"charge_model": "calibrated", "cutoff_debye": 12.0}}) == \
        {"a": 1.0, "nonbonded_charge_model": "calibrated", "nonbonded_cutoff_debye": 12.0}
    short = dict(source="40", time_ns=0.002, equilibration_ns=0.001)
    for proto, extra in ((MAGNETIC_TWEEZERS, dict(force_pN=1.0, turns=0.0, rotation_clamp_kJ_mol=1000.0)),
                         (RINGS, dict(delta_lk=0, ring=True))):
        row = _scalars(proto.execute(dict(short, **extra), tmp_path / proto.kind))
        assert row["nonbonded_charge_model"] == "calibrated" and row["nonbonded_cutoff_debye"] == 12.0
