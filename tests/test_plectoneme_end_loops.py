"""The plectoneme end-loop counter (the rings' ``end_loops`` column) on synthetic shapes: rings of n hairpin arms,
an open hairpin, a straight chain and a plain circle."""
import numpy as np
import pytest

from dnarod.workflows.protocols.measure import plectoneme_end_loops

DS = 0.34


def _resample(waypoints, ds=DS, closed=True):
    """Points every ``ds`` nm along the polygon through ``waypoints`` (closed: back to the first)."""
    w = np.asarray(waypoints, float)
    if closed:
        w = np.vstack([w, w[:1]])
    seg = np.linalg.norm(np.diff(w, axis=0), axis=1)
    s = np.concatenate([[0.0], np.cumsum(seg)])
    t = np.arange(0.0, s[-1] - (0.5 * ds if closed else -1e-9), ds)
    return np.stack([np.interp(t, s, w[:, k]) for k in range(3)], axis=1)


def star(arms, arm_nm=60.0, half_gap=2.0, hub=12.0, phase=0.0):
    """A closed chain made of ``arms`` hairpins (two duplexes 2 half_gap apart) radiating from a hub."""
    pts = []
    for k in range(arms):
        a = phase + 2 * np.pi * k / arms
        u, v = np.array([np.cos(a), np.sin(a), 0.0]), np.array([-np.sin(a), np.cos(a), 0.0])
        pts += [hub * u - half_gap * v, (hub + arm_nm) * u - half_gap * v, (hub + arm_nm) * u + half_gap * v,
                hub * u + half_gap * v]
    return _resample(pts)


@pytest.mark.parametrize("arms", [2, 3, 4])
def test_end_loops_of_a_ring_count_its_arms(arms):
    P = star(arms)
    n, where = plectoneme_end_loops(P, DS, circular=True)
    assert n == arms
    # each loop sits at the tip of an arm: the node farthest from the hub
    r = np.linalg.norm(P[:, :2], axis=1)
    for c in where:
        assert r[int(round(c)) % len(P)] > 12.0 + 55.0
    # the answer does not depend on where the ring's node 0 is
    assert plectoneme_end_loops(np.roll(P, 97, axis=0), DS, circular=True)[0] == arms


def test_end_loops_of_an_open_chain_and_of_no_plectoneme():
    hairpin = _resample([[0, 0, 0], [0, 0, 80.0], [4.0, 0, 80.0], [4.0, 0, 0], [40.0, 0, 0]], closed=False)
    n, where = plectoneme_end_loops(hairpin, DS)
    assert n == 1 and abs(where[0] - np.argmax(hairpin[:, 2] + 0.01 * hairpin[:, 0])) < 10
    straight = _resample([[0, 0, 0], [0, 0, 150.0]], closed=False)
    assert plectoneme_end_loops(straight, DS)[0] == 0
    circle = np.stack([np.cos(t := np.linspace(0, 2 * np.pi, 600, endpoint=False)), np.sin(t), 0 * t], 1) * 32.5
    assert plectoneme_end_loops(circle, DS, circular=True)[0] == 0

