"""The run layer: both engines through one ``run()``, resume bit-for-bit, exported times, storage format."""
import json
import warnings

import numpy as np
import pytest

from dnarod.core.errors import ParameterError
from dnarod.core.forcefield import load_forcefield
from dnarod.physics.loads import PullingForce
from dnarod.run import ENERGY_COLUMNS, RunSpec, load_energies, run
from dnarod.core.trajectory import HEADER_SIZE, MAGIC, bytes_per_node_frame, load_trajectory

SEQ = "ACGTTGCAACGTTGCA"
BASE = dict(source=SEQ, excluded_volume=False, electrostatics=False, platform="Reference", dt=0.02,
            frame_interval_ps=0.2, checkpoint_interval_ps=0.8, seed=5)


@pytest.mark.parametrize("engine", ["openmm", "lax"])
def test_resume_is_bit_for_bit(tmp_path, engine):
    spec = RunSpec(engine=engine, time_ns=0.004, temperature=300.0, friction=1.0, velocities=True, **BASE)
    platform = dict(platform=None) if engine == "lax" else {}
    spec = spec.replace(**platform)
    run(spec, tmp_path / "full", progress=False)
    half = run(spec.replace(time_ns=0.002), tmp_path / "part", progress=False)
    assert half.summary["steps"] == 100 and half.resumed_from is None
    res = run(spec, tmp_path / "part", resume=True, progress=False)
    assert res.resumed_from == 100 and res.summary["steps"] == 200
    a, b = (load_trajectory(tmp_path / d / "trajectory.dtraj") for d in ("full", "part"))
    assert list(b.step) == list(range(0, 201, 10))
    for name in ("positions", "frames", "velocities", "angular_velocities"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert (tmp_path / "full" / "energies.csv").read_bytes() == (tmp_path / "part" / "energies.csv").read_bytes()
    meta = json.loads((tmp_path / "part" / "run.json").read_text())
    assert [s["to_step"] for s in meta["segments"]] == [100, 200]


def test_both_engines_give_the_same_loaded_nve_run(tmp_path):
    """A chain pulled at both ends, NVE from rest: OpenMM (Reference, constrained particles) and the
    Lax-form splitting integrate the same equations, through the same run layer and reporters."""
    ff = load_forcefield("dna-default")
    m = ff.model_from_sequence(SEQ)
    axis = m.positions[-1] - m.positions[0]
    axis /= np.linalg.norm(axis)
    loads = (PullingForce(-1, 30.0 * axis), PullingForce(0, -30.0 * axis))
    out = {}
    for engine in ("openmm", "lax"):
        spec = RunSpec(engine=engine, time_ns=0.002, temperature=0.0, friction=0.0, loads=loads,
                       **{**BASE, "platform": "Reference" if engine == "openmm" else None})
        res = run(spec, tmp_path / engine, progress=False)
        out[engine] = (load_trajectory(res.files["trajectory"]), load_energies(res.files["energies"]))
    (ta, ea), (tb, eb) = out["openmm"], out["lax"]
    assert np.array_equal(ta.step, tb.step) and ta.n_frames == 11
    moved = np.abs(ta.positions[-1] - ta.positions[0]).max()
    assert moved > 0.04  # nm: the ends really moved
    # measured 4.8e-7 nm at 2 ps (float32 storage, OpenMM's constraint tolerance); before OpenMM's
    # start at rest took off the half kick, the two differed by 3e-4 nm (a first-order start)
    assert np.abs(ta.positions - tb.positions).max() < 2e-6
    assert np.abs(ta.frames - tb.frames).max() < 2e-6
    for col in ("elastic_kJ_mol", "external_kJ_mol", "kinetic_kJ_mol"):
        assert np.allclose(ea[col], eb[col], rtol=1e-4, atol=1e-4), col
    assert list(ea) == ENERGY_COLUMNS[:len(ea)] + list(ea)[len(ENERGY_COLUMNS):]


def test_exported_times_read_back_by_mdanalysis_and_mdtraj(tmp_path):
    import MDAnalysis as mda
    import mdtraj as md

    spec = RunSpec(engine="lax", time_ns=0.003, frame_interval_ps=0.37,  # the default export: PDB + DCD + XTC
                   **{k: v for k, v in BASE.items() if k not in ("platform", "frame_interval_ps")})
    res = run(spec, tmp_path / "r", progress=False)
    tr = load_trajectory(res.files["trajectory"])
    assert tr.n_frames > 5 and tr.time[1] == pytest.approx(0.36, rel=1e-12)  # 18 steps of 0.02 ps
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        u = mda.Universe(str(res.files["pdb"]), str(res.files["dcd"]))
        t_dcd = np.array([ts.time for ts in u.trajectory])
        u = mda.Universe(str(res.files["pdb"]), str(res.files["xtc"]))
        t_xtc_mda = np.array([ts.time for ts in u.trajectory])
    t_xtc_md = md.load(str(res.files["xtc"]), top=str(res.files["pdb"])).time
    # DCD stores the frame spacing as a float32 in AKMA units, XTC each time as float32
    for t in (t_dcd, t_xtc_mda, t_xtc_md):
        assert len(t) == tr.n_frames
        assert np.allclose(t, tr.time, rtol=1e-6, atol=1e-9), (t, tr.time)


def test_trajectory_size_and_old_float64_files(tmp_path):
    spec = RunSpec(engine="lax", time_ns=0.002, export=False,
                   **{k: v for k, v in BASE.items() if k != "platform"})
    res = run(spec, tmp_path / "r", progress=False)
    path = res.files["trajectory"]
    tr = load_trajectory(path)
    n = tr.n_nodes
    assert bytes_per_node_frame() == 48 and bytes_per_node_frame(velocities=True) == 72
    assert path.stat().st_size == HEADER_SIZE + tr.n_frames * (16 + 48 * n)
    assert tr.velocities is None  # velocities only when asked
    # a version-1 file (all float64, written by earlier dnarod) still reads
    old = tmp_path / "old.dtraj"
    header = dict(format="dnarod-trajectory", version=1, n_nodes=n, velocities=False, metadata={"x": 1})
    rec = np.concatenate([np.array([7.0, 0.35]), tr.positions[1].ravel(), tr.frames[1].ravel()])
    old.write_bytes((MAGIC + json.dumps(header).encode()).ljust(HEADER_SIZE - 1) + b"\n" + rec.astype("<f8").tobytes())
    back = load_trajectory(old)
    assert back.step.tolist() == [7] and back.time.tolist() == [0.35] and back.metadata == {"x": 1}
    assert np.array_equal(back.positions[0], tr.positions[1]) and np.array_equal(back.frames[0], tr.frames[1])


def test_zero_temperature_and_checks_through_the_api(tmp_path):
    from dnarod.engines.openmm.simulation import RodSimulation

    m = load_forcefield("dna-default").model_from_sequence(SEQ)
    sim = RodSimulation.create(m, temperature=0)  # at rest; non-bonded scales from the reference temperature
    sim.advance(3)
    e = sim.energies()
    assert e["kinetic"] == pytest.approx(0.0, abs=1e-6) and np.isfinite(e["nonbonded"])
    with pytest.raises(ParameterError, match="--friction -1"):
        run(RunSpec(source=SEQ, friction=-1), tmp_path / "x")
    with pytest.raises(ParameterError, match="--time 0"):
        run(RunSpec(source=SEQ, time_ns=0), tmp_path / "x")
    assert not (tmp_path / "x").exists()
    spec = RunSpec(engine="lax", time_ns=0.002, export=False, **{k: v for k, v in BASE.items() if k != "platform"})
    run(spec, tmp_path / "r", progress=False)
    done = run(spec, tmp_path / "r", resume=True, progress=False)
    assert done.summary["already_done"] and "nothing to do" in done.summary["message"]


def test_equilibrium_start_of_a_pulled_chain_points_along_the_force():
    """start='equilibrium' turns the exact sample so that its end-to-end vector follows the pull."""
    from dnarod.run.api import source_model, start_model

    spec = RunSpec(source="ACGT" * 15, engine="lax", excluded_volume=False, electrostatics=False,
                   start="equilibrium")
    model = source_model(spec)
    for direction in ([1.0, 0, 0], [0, -1.0, 0], [0, 0.6, -0.8]):
        f = 10.0 * np.asarray(direction)
        pulled = spec.replace(loads=(PullingForce(model.n_nodes - 1, f),))
        m = start_model(pulled, model, seed=5)
        e = m.positions[-1] - m.positions[0]
        assert np.dot(e, f) / (np.linalg.norm(e) * np.linalg.norm(f)) > 1 - 1e-9
        assert np.allclose(m.positions[0], model.positions[0])
    free = start_model(spec, model, seed=5)  # no pull: node 0 keeps the model's pose
    assert np.allclose(free.frames[0], model.frames[0])


@pytest.mark.parametrize("engine", ["openmm", "lax"])
def test_run_killed_after_its_last_checkpoint_gets_its_final_model_on_resume(tmp_path, engine):
    """A process killed between the run's last checkpoint and ``final_model.npz`` (an ensemble member whose
    worker died there): the resume finds the run complete and writes the end state from the checkpoint, so the
    member can be reduced."""
    from dnarod.core.model import RodModel

    base = dict(BASE, platform=None) if engine == "lax" else BASE
    spec = RunSpec(engine=engine, time_ns=0.002, temperature=300.0, friction=1.0, export=False, **base)
    run(spec, tmp_path / "r", progress=False)
    final = tmp_path / "r" / "final_model.npz"
    want = RodModel.load(final)
    final.unlink()
    done = run(spec, tmp_path / "r", resume=True, progress=False)
    assert done.summary["already_done"]
    got = RodModel.load(final)
    assert np.array_equal(got.positions, want.positions) and np.array_equal(got.frames, want.frames)


def _interrupt_at(monkeypatch, step):
    """Make the run's engine send this process a Ctrl-C (SIGINT) once it has advanced to or past ``step`` (in one
    advance, or inside one batch of reports: then at the batch's end); returns a dict whose ``"sent"`` is the
    step it was sent at."""
    import os
    import signal

    import dnarod.run.api as api

    make = api.make_engine
    sent = {}

    def make_interrupted(*a, **k):
        eng = make(*a, **k)
        advance = eng.advance

        def interrupt():
            if "sent" not in sent and eng.step >= step:
                sent["sent"] = eng.step
                os.kill(os.getpid(), signal.SIGINT)

        def advance_then_interrupt(n):
            advance(n)
            interrupt()

        eng.advance = advance_then_interrupt
        if hasattr(eng, "advance_reports"):
            reports = eng.advance_reports

            def reports_then_interrupt(*a, **k):
                out = reports(*a, **k)
                interrupt()
                return out

            eng.advance_reports = reports_then_interrupt
        return eng

    monkeypatch.setattr(api, "make_engine", make_interrupted)
    return sent


@pytest.mark.parametrize("engine", ["openmm", "lax"])
def test_ctrl_c_checkpoints_and_resume_is_bit_for_bit(tmp_path, engine, monkeypatch):
    """By default checkpoints follow wall time (none in a short run but the last); a Ctrl-C stops the loop at
    the step it reached, writes a checkpoint there and raises KeyboardInterrupt; the resumed run is the
    uninterrupted one, bit for bit."""
    base = {k: v for k, v in BASE.items() if k != "checkpoint_interval_ps"}
    spec = RunSpec(engine=engine, time_ns=0.004, temperature=300.0, friction=1.0, velocities=True, export=False,
                   **{**base, "platform": None if engine == "lax" else "Reference"})
    assert spec.checkpoint_interval_ps is None and spec.checkpoint_wall_s > 0
    run(spec, tmp_path / "full", progress=False)
    import dnarod.engines.openmm.simulation as sim_mod

    with monkeypatch.context() as mp:
        # batches: the first report alone (step 10), then 4 reports (40 steps): they end at 50, 90, ...
        mp.setattr(sim_mod.RodSimulation, "MAX_BATCH_REPORTS", 4)
        sent = _interrupt_at(mp, 70)  # reports every 10 steps: the loop stops at the report step it reached
        with pytest.raises(KeyboardInterrupt):
            run(spec, tmp_path / "part", progress=False)
    from dnarod.core.io import read_checkpoint
    from dnarod.run.api import CHECKPOINT_FORMATS

    stop = sent["sent"]
    assert stop == (70 if engine == "lax" else 90)  # OpenMM's compiled path reads reports in batches
    meta, _ = read_checkpoint(tmp_path / "part" / "checkpoint.npz", CHECKPOINT_FORMATS[engine], ())
    assert meta["step"] == stop
    assert load_trajectory(tmp_path / "part" / "trajectory.dtraj").step[-1] == stop
    res = run(spec, tmp_path / "part", resume=True, progress=False)
    assert res.resumed_from == stop and res.summary["steps"] == 200
    a, b = (load_trajectory(tmp_path / d / "trajectory.dtraj") for d in ("full", "part"))
    assert list(b.step) == list(range(0, 201, 10))
    for name in ("positions", "frames", "velocities", "angular_velocities"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    assert (tmp_path / "full" / "energies.csv").read_bytes() == (tmp_path / "part" / "energies.csv").read_bytes()


def test_checkpoints_by_wall_time(tmp_path):
    """The wall-time schedule: with a tiny interval a checkpoint follows every report, with 0 only the last;
    an explicit checkpoint_interval (steps) overrides it; each checkpoint resumes to the same run."""
    import time

    from dnarod.engines.lax.engine import LaxEngine
    from dnarod.run import simulate_engine

    m = load_forcefield("dna-default").model_from_sequence(SEQ)
    new = lambda: LaxEngine(m, 0.02, 300.0, 1.0, 5, (), None, None)  # noqa: E731
    counts = {}
    for name, kw in (("tiny", dict(checkpoint_wall_s=1e-9)), ("end", dict(checkpoint_wall_s=0)),
                     ("default", {}), ("steps", dict(checkpoint_interval=30, checkpoint_wall_s=1e-9))):
        out = simulate_engine(new(), 100, tmp_path / name, frame_interval=10, **kw)
        counts[name] = out["checkpoints"]
    # 10 reports after the start: 9 in-between checkpoints and the last; steps 30, 60, 90 and the last
    assert counts == {"tiny": 10, "end": 1, "default": 1, "steps": 4}

    # a run slower than its wall interval: checkpoints in between, each at a report step
    class Slow(LaxEngine):
        def advance(self, n):
            super().advance(n)
            time.sleep(0.02)

    saved = []
    eng = Slow(m, 0.02, 300.0, 1.0, 5, (), None, None)
    save = eng.save_checkpoint
    eng.save_checkpoint = lambda path, extra=None: (saved.append(eng.step), save(path, extra=extra))
    simulate_engine(eng, 100, tmp_path / "slow", frame_interval=10, checkpoint_wall_s=0.05)
    assert 2 <= len(saved) <= 6 and saved[-1] == 100 and all(s % 10 == 0 for s in saved)
    # without reporters the loop advances in chunks sized by the measured rate to the next checkpoint
    from dnarod.run.loop import run_engine

    class SlowSteps(LaxEngine):
        def advance(self, n):
            super().advance(n)
            time.sleep(0.001 * n)

    out = run_engine(SlowSteps(m, 0.02, 300.0, 1.0, 5, (), None, None), 200, (), tmp_path / "c.npz",
                     checkpoint_wall_s=0.05)
    assert out["steps"] == 200 and 2 <= out["checkpoints"] <= 8
    with pytest.raises(ParameterError, match="--checkpoint-wall"):
        RunSpec(source=SEQ, checkpoint_wall_s=-1).check()


class _OneAtATime:
    """A reporter that takes no batches: the run loop then advances and reports one report at a time."""

    supports_batch = False

    def __init__(self, interval):
        self.interval = interval
        self.steps = []

    def describeNextReport(self, engine):  # noqa: N802 - OpenMM reporter protocol
        return self.interval - engine.step % self.interval

    def due(self, step):
        return step % self.interval == 0

    def report(self, engine, snap):
        self.steps.append(snap.step)

    def flush(self):
        pass

    def close(self):
        pass


@pytest.mark.parametrize("loads", ["none", "rotating clamp"])
def test_batched_reports_equal_reports_one_at_a_time(tmp_path, loads):
    """The run loop reads the compiled engine's reports in batches (one call of the integrator for many reports)
    when every reporter takes them; trajectory (with velocities) and energies are the same bytes as reporting
    one report at a time, with loads that turn in time (rotation clamp, per-report update) and without, across
    a step-scheduled checkpoint and a run length that is not a multiple of the interval."""
    from dnarod.engines.openmm.simulation import RodSimulation
    from dnarod.physics.loads import tweezers
    from dnarod.run.loop import run_engine
    from dnarod.run.reporters import DtrajReporter, EnergyReporter

    model = load_forcefield("dna-default").model_from_sequence("ACGT" * 8)
    extra = tweezers(model, force_pN=2.0, rotation_clamp=250.0, turns=0.5) if loads != "none" else []
    outs = []
    for batched in (True, False):
        sim = RodSimulation.create(model, temperature=300.0, elastic="plugin", seed=4, platform="CPU", loads=extra)
        assert sim.supports_report_batches()
        calls = []
        orig = sim.advance_reports
        sim.advance_reports = lambda *a, **k: calls.append(a) or orig(*a, **k)
        d = tmp_path / f"{loads}-{batched}"
        d.mkdir()
        reps = [DtrajReporter(d / "t.dtraj", model.n_nodes, 6, velocities=True), EnergyReporter(d / "e.csv", 6)]
        plain = [] if batched else [_OneAtATime(6)]
        out = run_engine(sim, 1000, reps + plain, d / "c.npz", checkpoint_interval=240, duration_ps=1000 * sim.dt)
        for r in reps:
            r.close()
        assert bool(calls) == batched and out["checkpoints"] == 1 + 1000 // 240
        if batched:
            assert max(c[0] for c in calls) > 1  # several reports per call
        else:
            assert plain[0].steps == list(range(0, 1000, 6))
        outs.append(((d / "t.dtraj").read_bytes(), (d / "e.csv").read_bytes(), sim.node_state()))
    assert outs[0][0] == outs[1][0] and outs[0][1] == outs[1][1]
    for a, b in zip(outs[0][2], outs[1][2]):
        assert np.array_equal(a, b)
    tr = load_trajectory(tmp_path / f"{loads}-True" / "t.dtraj")
    assert list(tr.step) == list(range(0, 1000, 6))


def test_batches_of_reports_are_bounded_in_time(tmp_path, monkeypatch):
    """Checkpoints, the progress bar and Ctrl-C act between batches, so a batch is sized to last about
    BATCH_WALL_S: the first report alone, then as many as fit (here, with a bound far below one report's time,
    one at a time)."""
    import dnarod.run.loop as loop
    from dnarod.engines.openmm.simulation import RodSimulation
    from dnarod.run.reporters import DtrajReporter

    model = load_forcefield("dna-default").model_from_sequence("ACGT" * 4)
    sizes = {}
    for bound in (1e-9, 60.0):
        monkeypatch.setattr(loop, "BATCH_WALL_S", bound)
        sim = RodSimulation.create(model, temperature=300.0, elastic="plugin", seed=2, platform="CPU")
        calls = []
        orig = sim.advance_reports
        sim.advance_reports = lambda k, *a, **kw: calls.append(k) or orig(k, *a, **kw)
        rep = DtrajReporter(tmp_path / f"{bound}.dtraj", model.n_nodes, 5)
        loop.run_engine(sim, 500, [rep])
        rep.close()
        sizes[bound] = calls
    assert sizes[1e-9] == [1] * 100
    assert sizes[60.0][0] == 1 and max(sizes[60.0]) == RodSimulation.MAX_BATCH_REPORTS
