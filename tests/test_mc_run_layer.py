"""RunSpec(engine="mc") through the run layer: folder, energies CSV, observables, resume, CLI."""
import json

import numpy as np
import pytest

from dnarod.core.errors import ParameterError
from dnarod.physics.loads import Clamp, PullingForce, RotationClamp
from dnarod.run import RunSpec, run
from dnarod.core.units import PN


def _spec(**kw):
    loads = (Clamp(0), PullingForce(-1, [0.0, 0.0, 2.0 * PN]), RotationClamp(-1, 250.0))
    base = dict(source=40, engine="mc", time_ns=0.1, frame_interval_ps=10.0, loads=loads, seed=3, export=False)
    base.update(kw)
    return RunSpec(**base)


def test_mc_run_and_resume(tmp_path):
    res = run(_spec(), tmp_path / "r", progress=False)
    assert res.summary["steps"] == 100 and res.summary["engine"] == "mc"
    rows = (tmp_path / "r" / "energies.csv").read_text().splitlines()
    head = rows[0].split(",")
    assert "extension_nm" in head and "clamp_torque_pN_nm" in head
    assert len(rows) == 1 + 11
    meta = json.loads((tmp_path / "r" / "run.json").read_text())
    assert meta["dt_ps"] == 1.0
    # resume to 200 sweeps gives the same end state as one run of 200 sweeps
    run(_spec(time_ns=0.2), tmp_path / "r", resume=True, progress=False)
    run(_spec(time_ns=0.2), tmp_path / "s", progress=False)
    from dnarod.core.model import RodModel

    a = RodModel.load(tmp_path / "r" / "final_model.npz")
    b = RodModel.load(tmp_path / "s" / "final_model.npz")
    assert np.array_equal(a.positions, b.positions)


def test_mc_spec_refusals():
    with pytest.raises(ParameterError, match="temperature > 0"):
        _spec(temperature=0.0).check()
    with pytest.raises(ParameterError, match="no time step"):
        _spec(dt=0.01).check()
    with pytest.raises(ParameterError, match="platform"):
        _spec(platform="CUDA").check()


def test_mc_cli_simulate(tmp_path):
    """`dnarod simulate --engine mc` runs a tweezers chain and reports sweeps and acceptance."""
    from click.testing import CliRunner

    from dnarod.cli.main import main as cli

    out = tmp_path / "cli"
    r = CliRunner().invoke(cli, ["simulate", "30", "--engine", "mc", "--time", "0.05", "--frame-interval", "10",
                                 "--pull", "2", "--clamp-first", "--rotation-clamp", "250", "--seed", "2",
                                 "--no-export", "--no-progress", "-o", str(out)])
    assert r.exit_code == 0, r.output
    assert "Monte Carlo sweeps: 50" in r.output and "acceptance" in r.output
    assert (out / "checkpoint.npz").exists() and (out / "trajectory.dtraj").exists()


def test_mc_member_sampling_resumes_bit_for_bit(tmp_path):
    """A tweezers member sampled by the Monte Carlo engine through dnarod.run.sampling (the protocols' sampling
    path): interrupted after its checkpoint and resumed, it gives the samples of an uninterrupted run."""
    from dnarod.engines.mc import MCEngine
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.run.sampling import SampleReporter, run_sampling
    from dnarod.workflows.protocols.tweezers import build_member

    mb = build_member(dict(n_bp=40, force_pN=2.0, turns=0.3))

    def engine():
        return MCEngine(mb["model"], 300.0, loads=mb["loads"], nonbonded=member_nonbonded(mb["settings"]), seed=4)

    def observe(pos, frm, step):
        return {"extension_nm": pos[-1, 2] - pos[0, 2]}

    def sampler(n):
        return SampleReporter(["extension_nm"], 5, observe, start=20, n_samples=n)

    full = run_sampling(engine(), sampler(12))["samples"]
    ck = tmp_path / "member.npz"
    run_sampling(engine(), sampler(6), ck, extra={"k": 1})  # a run of another schedule leaves its checkpoint
    with pytest.raises(ParameterError, match="another schedule"):
        run_sampling(engine(), sampler(12), ck, extra={"k": 1})
    # the same schedule, interrupted: run 6 samples' worth, then resume to 12
    ck2 = tmp_path / "member2.npz"
    e1 = engine()
    s1 = sampler(12)
    from dnarod.run.loop import run_engine

    run_engine(e1, s1.start + 6 * s1.interval, [s1], ck2, 0, checkpoint_extra={"k": 1}, report_start=False)
    resumed = run_sampling(engine(), sampler(12), ck2, extra={"k": 1})
    assert resumed["resumed_from"] == s1.start + 6 * s1.interval
    assert np.array_equal(resumed["samples"]["extension_nm"], full["extension_nm"])


def test_analyze_of_a_monte_carlo_run_uses_no_relaxation_time(tmp_path):
    """A Monte Carlo trajectory's frames are sweeps: `analyze` states its error from their autocorrelation and
    does not compare the run with the modes' relaxation time in ps (which would be a wrong warning)."""
    import json

    from click.testing import CliRunner

    from dnarod.cli.main import main as cli

    out = tmp_path / "free"
    r = CliRunner().invoke(cli, ["simulate", "30", "--engine", "mc", "--time", "0.2", "--equilibrium", "--seed", "3",
                                 "--no-export", "--no-progress", "-o", str(out)])
    assert r.exit_code == 0, r.output
    r = CliRunner().invoke(cli, ["analyze", str(out / "trajectory.dtraj"), "-o", str(tmp_path / "an"), "--no-plots"])
    assert r.exit_code == 0, r.output
    rel = json.loads((tmp_path / "an" / "summary.json").read_text())["relaxation"]
    assert rel["tau_ps"] is None and "Monte Carlo" in rel["note"]
    assert "slowest bending relaxation time tau_1" not in r.output
