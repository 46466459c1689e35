"""Replica exchange along the turns (``dnarod.protocols.exchange``, ``protocol hat --start exchange``).

References: the exchange map's algebra (involution, lab angular velocity kept, the sweep's twist ramp), the
swap energy against a fresh simulation of the target rung, the untouched trajectory after a trial, resume from a
checkpoint equal to the uninterrupted run, the same result on one or two groups, and the rungs' equilibrium
against independent members of the same settings.
"""
import json

import numpy as np
import pytest

from dnarod.protocols import ensemble_hooks as hooks
from dnarod.protocols import exchange as ex

BASE = dict(source="40", force_pN=1.0, time_ns=0.2, equilibration_ns=0.05, temperature_K=300.0, salt_M=0.15,
            seed=3, rotation_clamp_kJ_mol=250.0)


def _settings(turns, **kw):
    return [hooks.MAGNETIC_TWEEZERS.member_settings(dict(BASE, turns=t, **kw)) for t in turns]


def _random_frames(rng, n):
    from scipy.spatial.transform import Rotation

    return Rotation.random(n, random_state=rng).as_matrix()


def test_twist_move_is_an_involution_that_keeps_lab_angular_velocity():
    from dnarod.protocols.sweep import add_turns

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
    from dnarod.protocols.tweezers import _member_simulation

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
    from dnarod.errors import DnarodError

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
    from dnarod.protocols.tweezers import run_member

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
