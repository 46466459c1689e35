"""Tweezers observables: extension, applied turns, clamp torque and Lk against exact values."""
from types import SimpleNamespace

import numpy as np
import pytest

from dnarod.core.forcefield import load_forcefield
from dnarod.physics.loads import Clamp, PullingForce, RotationClamp, Trap
from dnarod.physics.observables import LK_MAX_NODES, csv_observables, open_twist
from dnarod.core.rotations import rotation_about_axis
from dnarod.core.units import PN


@pytest.fixture(scope="module")
def ff():
    return load_forcefield("dna-default")


def snap(pos, frm, t=0.0):
    return SimpleNamespace(state=(pos, frm, None, None), time_ps=t, step=0, engine="lax")


def test_columns_follow_the_loads(ff):
    m = ff.model_from_sequence(n_nodes=20)
    assert csv_observables(m, ()).columns == []
    assert csv_observables(m, (Clamp(0), PullingForce(-1, [0, 0, 5.0]))).columns == ["extension_nm"]
    obs = csv_observables(m, (Clamp(0), PullingForce(-1, [0, 0, 5.0]), RotationClamp(-1, 100.0, turns=2)),
                          duration_ps=10.0)
    assert obs.columns == ["extension_nm", "turns", "clamp_torque_pN_nm", "lk"]
    assert csv_observables(ff.ring(n_nodes=42), ()).columns == ["lk"]
    assert LK_MAX_NODES >= 1000


def test_extension_turns_and_torque_exact(ff):
    m = ff.model_from_sequence(n_nodes=20)
    a = np.array([0.0, 0.6, 0.8])
    k = 150.0
    obs = csv_observables(m, (Trap(0, 10.0), PullingForce(-1, 7.0 * a), RotationClamp(-1, k, axis=a, turns=1.5)),
                          duration_ps=30.0)
    pos, frm = m.positions.copy(), m.frames.copy()
    alpha = 0.3   # the node lags its target by alpha about the clamp axis
    t = 10.0      # target at 1.5 * 10/30 = 0.5 turns
    frm[-1] = rotation_about_axis(a, 2 * np.pi * 0.5 - alpha) @ m.frames[-1]
    r = obs(snap(pos, frm, t))
    assert r["extension_nm"] == pytest.approx((pos[-1] - pos[0]) @ a, rel=1e-14)
    assert r["turns"] == pytest.approx(0.5, rel=1e-14)
    # E = k (1 - cos theta): the torque about the axis is k sin(alpha), driving the node forward
    assert r["clamp_torque_pN_nm"] == pytest.approx(k * np.sin(alpha) / PN, rel=1e-10)


def test_ring_lk_is_the_built_linking_number(ff):
    for dlk in (-2, 0, 3):
        ring = ff.ring(n_nodes=60, delta_linking_number=dlk)
        obs = csv_observables(ring, ())
        lk = obs(snap(ring.positions, ring.frames))["lk"]
        assert lk == pytest.approx(ring.metadata["linking_number"], abs=1e-9)


def test_open_chain_lk_follows_the_turns_of_the_held_end(ff):
    m = ff.model_from_sequence(n_nodes=40)
    a = m.positions[-1] - m.positions[0]
    a /= np.linalg.norm(a)
    obs = csv_observables(m, (Clamp(0), PullingForce(-1, 5.0 * a), RotationClamp(-1, 100.0)))
    lk0 = obs(snap(m.positions, m.frames))["lk"]
    # equals the total twist of the chain plus the writhe of the closed construct; turning the end node
    # about the axis by phi changes it by phi / 2 pi
    for phi in (0.4, 2.0):
        frm = m.frames.copy()
        frm[-1] = rotation_about_axis(a, phi) @ frm[-1]
        lk = obs(snap(m.positions, frm))["lk"]
        tw_change = open_twist(m.positions, frm[:, :, 0]) - open_twist(m.positions, m.frames[:, :, 0])
        assert lk - lk0 == pytest.approx(tw_change, abs=1e-12)
        assert tw_change == pytest.approx(phi / (2 * np.pi), abs=0.02)
    # a rigid rotation of the whole construct changes nothing
    R = rotation_about_axis(np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5]), 0.8)
    obs_r = csv_observables(m.with_pose(m.positions @ R.T, R @ m.frames),
                            (Clamp(0), PullingForce(-1, 5.0 * (R @ a)), RotationClamp(-1, 100.0)))
    assert obs_r(snap(m.positions @ R.T, R @ m.frames))["lk"] == pytest.approx(lk0, abs=1e-9)


def test_open_chain_lk_is_one_construction_for_any_pull_axis():
    """Tw, Wr and Lk of an open chain have one home (physics.observables): rotating the chain and its pull axis
    together changes neither, and turning the last node about the axis by phi changes Lk by phi/2pi."""
    from dnarod.core.rotations import rotation_about_axis
    from dnarod.physics.observables import _to_axis_frame, twist_writhe_open

    m = load_forcefield("dna-default").model_from_sequence(n_nodes=40)
    rng = np.random.default_rng(3)
    pos = m.positions + rng.normal(scale=0.05, size=m.positions.shape)
    frm = m.frames
    tw, wr = twist_writhe_open(pos, frm)
    axis = np.array([0.3, -0.4, 0.866])
    axis /= np.linalg.norm(axis)
    R = _to_axis_frame(axis).T  # z -> axis
    assert np.allclose(R @ [0, 0, 1.0], axis)
    tw2, wr2 = twist_writhe_open(pos @ R.T, R @ frm, axis)
    assert abs(tw2 - tw) < 1e-9 and abs(wr2 - wr) < 1e-9
    phi = 0.7
    frm3 = frm.copy()
    frm3[-1] = rotation_about_axis(np.array([0.0, 0.0, 1.0]), phi) @ frm[-1]
    lk3 = sum(twist_writhe_open(pos, frm3))
    assert abs(lk3 - (tw + wr) - phi / (2 * np.pi)) < 1e-9
