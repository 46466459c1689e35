"""Replica exchange along the turns (``dnarod.workflows.protocols.exchange``, ``protocol hat --start exchange``).

References: the exchange map's algebra (involution, lab angular velocity kept, the sweep's twist ramp), the
swap energy against a fresh simulation of the target rung, the untouched trajectory after a trial, resume from a
checkpoint equal to the uninterrupted run, the same result on one or two groups, and the rungs' equilibrium
against independent members of the same settings.
"""
import json

import numpy as np
import pytest

from dnarod.workflows.protocols import ensemble_hooks as hooks
from dnarod.workflows.protocols import exchange as ex

BASE = dict(source="40", force_pN=1.0, time_ns=0.2, equilibration_ns=0.05, temperature_K=300.0, salt_M=0.15,
            seed=3, rotation_clamp_kJ_mol=250.0)


def _settings(turns, **kw):
    return [hooks.MAGNETIC_TWEEZERS.member_settings(dict(BASE, turns=t, **kw)) for t in turns]


def _random_frames(rng, n):
    from scipy.spatial.transform import Rotation

    return Rotation.random(n, random_state=rng).as_matrix()


def test_twist_move_is_an_involution_that_keeps_lab_angular_velocity():
    from dnarod.workflows.protocols.poses import add_turns

    rng = np.random.default_rng(1)
    F = _random_frames(rng, 9)
    W = rng.normal(size=(9, 3))
    F2, W2 = ex.twist_move(F, W, 0.37)
    np.testing.assert_allclose(F2, add_turns(np.zeros((9, 3)), F, 0.37)[1], atol=1e-15)
    # lab angular velocity R Omega unchanged; d3 and Omega_3 unchanged; |Omega| kept (I1 = I2: same kinetic energy)
    np.testing.assert_allclose(np.einsum("kab,kb->ka", F2, W2), np.einsum("kab,kb->ka", F, W), atol=1e-13)
    np.testing.assert_allclose(F2[:, :, 2], F[:, :, 2], atol=1e-15)
    np.testing.assert_allclose(W2[:, 2], W[:, 2])
    np.testing.assert_allclose(np.linalg.norm(W2, axis=1), np.linalg.norm(W, axis=1))
    # node k turned by 2 pi d k/(n-1) about its d3: the last node by the whole increment
    c = float(F[-1][:, 0] @ F2[-1][:, 0])
    assert c == pytest.approx(np.cos(2 * np.pi * 0.37))
    F3, W3 = ex.twist_move(F2, W2, -0.37)
    np.testing.assert_allclose(F3, F, atol=1e-14)
    np.testing.assert_allclose(W3, W, atol=1e-14)


def test_swap_energy_equals_a_fresh_simulation_of_the_target_rung():
    from dnarod.workflows.protocols.tweezers import _member_simulation

    g = ex.ReplicaGroup(_settings([0.0, 0.3]), [0, 1])
    g.advance(200)
    r = g.replicas[0]
    dE = r.trial(1)
    c, f = r.sim.node_pose()
    e_here = r.sim.energies()["potential"]
    f2, _ = ex.twist_move(f, np.zeros((len(f), 3)), 0.3)
    m1 = g.members[1]
    fresh = _member_simulation(m1, m1["model"].with_pose(c, f2), dt=g.dt)
    e_there = fresh.energies()["potential"]
    assert abs(dE) > 1.0  # the twist ramp costs energy: the comparison is not 0 = 0
    assert dE == pytest.approx(e_there - e_here, rel=1e-9, abs=1e-9)


def test_trial_leaves_the_trajectory_bit_for_bit():
    a = ex.ReplicaGroup(_settings([0.0, 0.3]), [0, 1])
    b = ex.ReplicaGroup(_settings([0.0, 0.3]), [0, 1])
    for g in (a, b):
        g.advance(50)
    a.trials([(0, 1)])
    a.sample()
    for g in (a, b):
        g.advance(50)
    for rid in (0, 1):
        pa, fa = a.replicas[rid].sim.node_pose()
        pb, fb = b.replicas[rid].sim.node_pose()
        assert np.array_equal(pa, pb) and np.array_equal(fa, fb)


def test_move_there_and_back_restores_the_state_and_follows_the_bead():
    g = ex.ReplicaGroup(_settings([0.0, 0.3]), [0, 1])
    g.advance(100)
    r = g.replicas[0]
    c, f, v, w = r.sim.node_state()
    turns_before = r.turns_acc
    r.move(1)
    assert r.label == 1
    c1, f1, v1, w1 = r.sim.node_state()
    np.testing.assert_allclose(c1, c, atol=1e-12)
    np.testing.assert_allclose(v1, v, atol=1e-9)
    # the bead turned by 0.3 turns with its rung: its offset from the rung's turns is unchanged
    assert r.turns_acc == pytest.approx(turns_before, abs=1e-9)
    assert g.sample()[1]["end_turns"] == pytest.approx(0.3 + turns_before, abs=0.02)
    r.move(0)
    c2, f2, v2, w2 = r.sim.node_state()
    np.testing.assert_allclose(f2, f, atol=1e-12)
    np.testing.assert_allclose(w2, w, atol=1e-9)


def test_accept_rule():
    assert ex._accept(-3.0, 0.999)
    assert ex._accept(1.0, np.exp(-1.0) - 1e-9)
    assert not ex._accept(1.0, np.exp(-1.0) + 1e-9)


def _ladder(tmp_path, name, turns=(-0.2, 0.0, 0.2), **kw):
    d = tmp_path / name
    return d, ex.run_ladder(_settings(list(turns)), d / "ladder", [str(d / f"m{i}") for i in range(len(turns))],
                            progress=False, **kw)


def test_ladder_writes_rungs_and_resumes_exactly(tmp_path, monkeypatch):
    da, ra = _ladder(tmp_path, "a", exchange_ps=10.0)
    summ = json.loads((da / "ladder" / ex.RESULT).read_text())
    assert summ["rungs"] == [-0.2, 0.0, 0.2] and sum(summ["attempts"]) > 10
    assert 0 < sum(summ["accepts"]) <= sum(summ["attempts"])
    for i, r in enumerate(ra):
        assert r["turns"] == [-0.2, 0.0, 0.2][i]
        assert r["n_samples"] >= 4 and (da / f"m{i}" / "samples.csv").exists()
        assert (da / f"m{i}" / "final_pose.npz").exists()
        assert "replica exchange" in r["start"]
    assert ra[0]["exchange_acceptance_down"] is None and ra[0]["exchange_acceptance_up"] is not None
    assert not (da / "ladder" / ex.CHECKPOINT).exists()
    # the end turns follow each rung (the clamp holds the bead there), swaps or not
    for i, t in enumerate([-0.2, 0.0, 0.2]):
        assert ra[i]["end_turns"] == pytest.approx(t, abs=0.05)
    # interrupted after a few samples (checkpoints every round), then run again: the same samples
    calls = {"n": 0}
    real = ex.ReplicaGroup.sample

    def failing(self):
        calls["n"] += 1
        if calls["n"] == 4:
            raise RuntimeError("interrupted")
        return real(self)

    monkeypatch.setattr(ex.ReplicaGroup, "sample", failing)
    with pytest.raises(RuntimeError):
        _ladder(tmp_path, "b", exchange_ps=10.0, checkpoint_wall_s=0.0)
    db = tmp_path / "b"
    assert (db / "ladder" / ex.CHECKPOINT).exists()
    monkeypatch.setattr(ex.ReplicaGroup, "sample", real)
    _, rb = _ladder(tmp_path, "b", exchange_ps=10.0, checkpoint_wall_s=0.0)
    for i in range(3):
        assert (db / f"m{i}" / "samples.csv").read_text() == (da / f"m{i}" / "samples.csv").read_text()
    sb = json.loads((db / "ladder" / ex.RESULT).read_text())
    assert sb["accepts"] == summ["accepts"] and sb["label_of_replica"] == summ["label_of_replica"]
    # a finished ladder is reused; other settings in its folder are refused
    _, rc = _ladder(tmp_path, "b", exchange_ps=10.0, checkpoint_wall_s=0.0)
    assert rc[1]["extension_nm"] == rb[1]["extension_nm"]


def test_checkpoint_of_other_settings_refused(tmp_path, monkeypatch):
    from dnarod.core.errors import DnarodError

    real = ex.ReplicaGroup.sample
    monkeypatch.setattr(ex.ReplicaGroup, "sample", lambda self: (_ for _ in ()).throw(RuntimeError("stop")))
    with pytest.raises(RuntimeError):
        _ladder(tmp_path, "c", exchange_ps=10.0, checkpoint_wall_s=0.0)
    monkeypatch.setattr(ex.ReplicaGroup, "sample", real)
    with pytest.raises(DnarodError, match="other settings"):
        _ladder(tmp_path, "c", exchange_ps=15.0)


def test_two_groups_give_the_one_group_result(tmp_path):
    """Replicas split over two dask actors (a LocalCluster) run exactly as in one group in this process."""
    da, ra = _ladder(tmp_path, "one", turns=(-0.2, 0.0, 0.2, 0.35), exchange_ps=10.0)
    db, rb = _ladder(tmp_path, "two", turns=(-0.2, 0.0, 0.2, 0.35), exchange_ps=10.0, workers=2)
    for i in range(4):
        assert (da / f"m{i}" / "samples.csv").read_text() == (db / f"m{i}" / "samples.csv").read_text()
    assert json.loads((db / "ladder" / ex.RESULT).read_text())["groups"] == 2


def _agreement(tmp_path, time_ns, turns):
    """Each rung of a ladder against an independent static member at its turn value (same settings)."""
    from dnarod.workflows.protocols.tweezers import run_member

    _, rungs = _ladder(tmp_path, "lad", turns=turns, exchange_ps=10.0)
    rows = []
    for t, r in zip(turns, rungs):
        s = _settings([t])[0]
        ind = run_member(dict(s, time_ns=time_ns), tmp_path / f"ind{t:+g}")
        for key in ("extension_nm", "twist_torque_pN_nm"):
            # the larger of the block and the autocorrelation-time errors (short runs: blocks of a few tau)
            a, ea = r[key], max(r[key + "_err"], r.get(key + "_err_tau") or 0.0)
            b, eb = ind[key], max(ind[key + "_err"], ind.get(key + "_err_tau") or 0.0)
            rows.append((t, key, (a - b) / np.hypot(ea, eb)))
    return rows


def test_rungs_sample_the_members_equilibrium(tmp_path, monkeypatch):
    """Fast form: three rungs (40 bp, 1 pN, 0.2 ns) against independent members (0.4 ns): extension and twisting
    moment agree within 4 combined standard errors, and the twisting moment follows the turns."""
    monkeypatch.setitem(BASE, "time_ns", 0.2)
    rows = _agreement(tmp_path, 0.4, (-0.3, 0.0, 0.3))
    assert all(abs(z) < 4.0 for _, _, z in rows), rows


@pytest.mark.slow
def test_rungs_sample_the_members_equilibrium_long(tmp_path, monkeypatch):
    """Full form: five rungs of 60 bp at 1 pN up to sigma = 0.09 (4 ns each) against 8-ns independent members (the
    extension's autocorrelation time reaches 0.35 ns there)."""
    monkeypatch.setitem(BASE, "source", "60")
    monkeypatch.setitem(BASE, "time_ns", 4.0)
    monkeypatch.setitem(BASE, "equilibration_ns", 0.5)
    rows = _agreement(tmp_path, 8.0, (-0.5, -0.25, 0.0, 0.25, 0.5))
    assert all(abs(z) < 4.0 for _, _, z in rows), rows


def _model(s):
    from dnarod.workflows.protocols.tweezers import build_member

    return build_member(s)["model"]


def test_twist_ramp_mismatch_is_zero_for_isotropic_steps_only():
    """The exchange map's symmetry check: 0 for the isotropic, straight sets; not for olson1998's anisotropic,
    coupled, intrinsically bent steps; and not for dna-default with one bending stiffness changed."""
    import dataclasses

    iso = _model(_settings([0.0])[0]).params
    assert ex.twist_ramp_mismatch(iso) < 1e-12
    assert ex.twist_ramp_mismatch(_model(_settings([0.0], forcefield="uniform-rod")[0]).params) < 1e-12
    K = np.array(iso.stiffness)
    K[3, 0, 0] *= 1.5
    # entries are relative to each step's largest stiffness (its extension's, 674): 0.04 here
    assert ex.twist_ramp_mismatch(dataclasses.replace(iso, stiffness=K)) > 0.01
    x0 = np.array(iso.intrinsic)
    x0[5, 1] = 0.05  # an intrinsic roll of one step
    assert ex.twist_ramp_mismatch(dataclasses.replace(iso, intrinsic=x0)) > 0.01


def _z(a, b, key):
    ea = max(a[key + "_err"], a.get(key + "_err_tau") or 0.0)
    eb = max(b[key + "_err"], b.get(key + "_err_tau") or 0.0)
    return a[key] - b[key], float(np.hypot(ea, eb))


def test_a_wrong_acceptance_rule_fails_where_the_twist_map_is_not_a_symmetry(tmp_path, monkeypatch):
    """The acceptance rule itself. On ``dna-default`` in the straight regime the twist ramp is nearly a symmetry of
    the rungs, so almost any rule would pass the tests above. On ``olson1998`` (bending stiffness 251 vs 130 kT,
    roll-twist coupling, intrinsic roll and tilt) the ramp turns each step's bend about d3 by a different angle and
    the rungs' distributions are not images of each other: a 40-bp ladder at 0 and 0.03 turns, swaps every 1 ps and
    a sample right after each round, against independent 2-ns members. The Metropolis rule (35-40 % accepted)
    keeps each rung's twisting moment within 4 SE of its member (measured |z| <= 1.8 over five seeds); accepting
    every swap biases the two rungs apart (the difference between them off by 9 SE)."""
    from dnarod.workflows.protocols.tweezers import run_member

    base = dict(BASE, source="A" * 10 + "CG" * 5 + "A" * 10 + "CA" * 5, forcefield="olson1998", time_ns=1.0,
                equilibration_ns=0.02, sample_ps=1.0, seed=5)
    turns = [0.0, 0.03]
    settings = [hooks.MAGNETIC_TWEEZERS.member_settings(dict(base, turns=t)) for t in turns]
    ind = [run_member(dict(s, time_ns=2.0), tmp_path / f"ind{i}") for i, s in enumerate(settings)]

    def ladder(name):
        d = tmp_path / name
        with pytest.warns(UserWarning, match="not a symmetry"):
            res = ex.run_ladder(settings, d / "ladder", [str(d / f"m{i}") for i in range(2)], exchange_ps=1.0,
                                progress=False)
        summary = json.loads((d / "ladder" / ex.RESULT).read_text())
        assert summary["twist_ramp_mismatch"] > 0.1  # reported beside the acceptance
        return res, summary["acceptance"][0]

    assert ex.twist_ramp_mismatch(_model(settings[0]).params) > 0.1
    key = "twist_torque_pN_nm"
    right, acc = ladder("metropolis")
    assert 0.15 < acc < 0.7, acc  # swaps happen, and are not all accepted
    for r, m in zip(right, ind):
        d, e = _z(r, m, key)
        assert abs(d) < 4.0 * e, (d, e)
    monkeypatch.setattr(ex, "_accept", lambda delta_kT, u: True)
    wrong, acc_w = ladder("always")
    assert acc_w == 1.0
    (d0, e0), (d1, e1) = _z(wrong[0], ind[0], key), _z(wrong[1], ind[1], key)
    assert d1 - d0 > 4.0 * np.hypot(e0, e1), (d0, d1, e0, e1)


@pytest.mark.parametrize("args,words", [
    (["--turns=0", "--start", "exchange"], ["at least two turn values"]),
    (["--turns=0,0", "--start", "exchange"], ["repeat"]),
    (["--turns=0,1", "--start", "exchange", "--exchange-ps", "0"], ["exchange interval", "> 0"]),
    (["--turns=0,1", "--start", "exchange", "--exchange-ps", "nan"], ["exchange interval"]),
    (["--turns=0,1", "--exchange-ps", "20"], ["--start exchange only"]),
    (["--turns=0,1", "--start", "exchange", "--settle", "5"], ["settle"]),
])
def test_exchange_bad_input_one_line(tmp_path, assert_refused, args, words):
    assert_refused(tmp_path, ["protocol", "hat", "--source", "40", "--time", "0.1", "-o", "{w}/n", *args], words)


def test_cli_prints_a_run_warning_when_raised_and_holds_other_warnings(monkeypatch):
    """The exchange's RunWarning reaches stderr while the command runs (it is printed even if the command then
    stops with a refusal), other warnings only after a finished command (a refusal is its one line alone)."""
    import warnings

    import click
    from click.testing import CliRunner

    from dnarod.cli.main import main
    from dnarod.core.errors import DnarodError, RunWarning

    events = []

    @click.command("_warn_probe")
    @click.option("--fail", is_flag=True)
    def probe(fail):
        warnings.warn("a held warning", UserWarning)
        warnings.warn("the ladder is inefficient", RunWarning)
        events.append("after the warnings")
        if fail:
            raise DnarodError("refused input")
        click.echo("done")

    monkeypatch.setitem(main.commands, "_warn_probe", probe)
    ok = CliRunner().invoke(main, ["_warn_probe"])
    assert ok.exit_code == 0, ok.output
    lines = ok.output.splitlines()
    assert lines == ["dnarod: warning: the ladder is inefficient", "done", "dnarod: warning: a held warning"], lines
    bad = CliRunner().invoke(main, ["_warn_probe", "--fail"])
    assert bad.exit_code == 2
    assert bad.output.splitlines() == ["dnarod: warning: the ladder is inefficient", "dnarod: error: refused input"]
    assert events == ["after the warnings"] * 2
