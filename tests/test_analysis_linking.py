"""Writhe, twist and linking number: Lk = Tw + Wr on analytic closed curves and rings."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dnarod.analysis.polymer import LinkingNumber
from dnarod.physics.writhe import linking_number, twist, writhe
from dnarod.core.errors import GeometryError
from dnarod.core.forcefield import load_forcefield
from dnarod.core.trajectory import Trajectory


def trefoil(s):
    return np.stack([np.sin(s) + 2 * np.sin(2 * s), np.cos(s) - 2 * np.cos(2 * s), -np.sin(3 * s)], 1)


def trefoil_derivative(s):
    return np.stack([np.cos(s) + 4 * np.cos(2 * s), -np.sin(s) + 4 * np.sin(2 * s), -3 * np.cos(3 * s)], 1)


def writhe_klenin_langowski_loop(P):
    """Slow reference: Klenin & Langowski (2000) eq. 13-16 (arcsin form), double loop over edge pairs."""
    n = len(P)
    total = 0.0
    for i in range(n):
        for j in range(n):
            if j in (i, (i + 1) % n, (i - 1) % n):
                continue
            p1, p2, p3, p4 = P[i], P[(i + 1) % n], P[j], P[(j + 1) % n]
            r12, r34 = p2 - p1, p4 - p3
            r13, r14, r23, r24 = p3 - p1, p4 - p1, p3 - p2, p4 - p2
            ns = [np.cross(r13, r14), np.cross(r14, r24), np.cross(r24, r23), np.cross(r23, r13)]
            ns = [v / np.linalg.norm(v) for v in ns]
            om = sum(np.arcsin(np.clip(np.dot(ns[a], ns[(a + 1) % 4]), -1, 1)) for a in range(4))
            total += om * np.sign(np.dot(np.cross(r34, r12), r13))
    return total / (4 * np.pi)


def gauss_midpoint(curve, dcurve, m):
    """Independent reference: midpoint rule for the Gauss writhe integral of a smooth closed curve."""
    s = (np.arange(m) + 0.5) * 2 * np.pi / m
    r, dr = curve(s), dcurve(s) * 2 * np.pi / m
    tot = 0.0
    for i in range(m):
        d = r[i] - r
        nrm = np.linalg.norm(d, axis=1)
        nrm[i] = np.inf
        tot += np.sum(np.einsum("ij,ij->i", d, np.cross(dr[i], dr)) / nrm**3)
    return tot / (4 * np.pi)


def circle_ribbon(n, turns, radius=1.0):
    s = np.linspace(0, 2 * np.pi, n, endpoint=False)
    P = radius * np.stack([np.cos(s), np.sin(s), 0 * s], 1)
    N = -P / radius
    B = np.cross(np.stack([-np.sin(s), np.cos(s), 0 * s], 1), N)
    U = np.cos(turns * s)[:, None] * N + np.sin(turns * s)[:, None] * B
    return P, U


@pytest.mark.parametrize("turns", [0, 1, -3, 10])
def test_circle_writhe_zero_twist_equals_linking(turns):
    P, U = circle_ribbon(120, turns)
    assert abs(writhe(P)) < 1e-12
    assert twist(P, U) == pytest.approx(turns, abs=1e-10)
    assert linking_number(P, P + 1e-3 * U) == pytest.approx(turns, abs=1e-9)


def test_writhe_matches_klenin_langowski_double_loop():
    P = trefoil(np.linspace(0, 2 * np.pi, 40, endpoint=False))
    rng = np.random.default_rng(1)
    P = P + rng.normal(0, 0.05, P.shape)
    assert writhe(P) == pytest.approx(writhe_klenin_langowski_loop(P), abs=1e-9)


def test_writhe_converges_to_gauss_integral_and_flips_under_mirror():
    P = trefoil(np.linspace(0, 2 * np.pi, 600, endpoint=False))
    wr = writhe(P)
    ref = gauss_midpoint(trefoil, trefoil_derivative, 2000)
    assert abs(wr - ref) < 2e-4 and abs(wr) > 3.0  # trefoil writhe ~ -3.354 for this parametrisation
    assert writhe(P * [1, 1, -1]) == pytest.approx(-wr, abs=1e-10)


def test_hopf_link_and_unlinked_rings():
    s = np.linspace(0, 2 * np.pi, 80, endpoint=False)
    a = np.stack([np.cos(s), np.sin(s), 0 * s], 1)
    b = np.stack([1 + np.cos(s), 0 * s, np.sin(s)], 1)
    assert abs(abs(linking_number(a, b)) - 1) < 1e-10
    assert linking_number(a, b) == pytest.approx(linking_number(b, a), abs=1e-10)
    assert abs(linking_number(a, b + [5, 0, 0])) < 1e-10


@pytest.mark.parametrize("extra", [0, 2, -5])
def test_lk_equals_tw_plus_wr_on_twisted_trefoil_ribbon(extra):
    n = 300
    s = np.linspace(0, 2 * np.pi, n, endpoint=False)
    P = trefoil(s)
    T = trefoil_derivative(s)
    T /= np.linalg.norm(T, axis=1)[:, None]
    ref = np.cross(T, [0.3, 0.2, 1.0])
    ref /= np.linalg.norm(ref, axis=1)[:, None]
    other = np.cross(T, ref)
    U = np.cos(extra * s)[:, None] * ref + np.sin(extra * s)[:, None] * other
    lk = linking_number(P, P + 1e-3 * U)
    tw, wr = twist(P, U), writhe(P)
    assert abs(lk - round(lk)) < 1e-8
    assert abs(lk - (tw + wr)) < 1e-8
    assert abs(wr) > 3.0 and abs(tw) > 0.1  # a real check: both terms matter


def ring_trajectory(n_nodes, turns, n_frames, seed, noise=0.03):
    """Rings of n_nodes base pairs (rise 0.34 nm) with ``turns`` helical turns, thermally perturbed."""
    rng = np.random.default_rng(seed)
    R = n_nodes * 0.34 / (2 * np.pi)
    s = np.linspace(0, 2 * np.pi, n_nodes, endpoint=False)
    pos, frm = [], []
    for f in range(n_frames):
        P = R * np.stack([np.cos(s), np.sin(s), 0.3 * np.sin(2 * s + f)], 1) + rng.normal(0, noise, (n_nodes, 3))
        T = np.roll(P, -1, 0) - np.roll(P, 1, 0)
        T /= np.linalg.norm(T, axis=1)[:, None]
        N = np.cross(T, [0, 0, 1.0])
        N /= np.linalg.norm(N, axis=1)[:, None]
        B = np.cross(T, N)
        ang = turns * s + rng.normal(0, 0.05, n_nodes)
        d1 = np.cos(ang)[:, None] * N + np.sin(ang)[:, None] * B
        d2 = np.cross(T, d1)
        F = np.stack([d1, d2, T], axis=-1)
        tilt = Rotation.from_rotvec(rng.normal(0, 0.05, (n_nodes, 3))).as_matrix()
        pos.append(P)
        frm.append(tilt @ F)
    return Trajectory(np.arange(n_frames) * 1.0, np.array(pos), np.array(frm))


def test_linking_number_analysis_on_rings():
    traj = ring_trajectory(105, 10, 4, seed=3)
    lk = LinkingNumber(traj).run()
    r = lk.results
    assert list(r.linking_integer) == [10] * 4
    assert r.max_identity_error < 1e-8 and r.max_integer_error < 1e-8 and r.passed
    assert np.abs(r.writhe).max() > 1e-3  # non-planar: Wr does not vanish, Tw absorbs it
    assert np.allclose(r.twist + r.writhe, 10, atol=1e-8)


def test_linking_number_rejects_screw_closure_ring_model():
    model = load_forcefield("dna-default").model_from_sequence(n_nodes=21, circular=True)
    traj = Trajectory([0.0], model.positions[None], model.frames[None])
    with pytest.raises(GeometryError, match="screw closure"):
        LinkingNumber(traj, closure=model.closure)


def test_numba_and_numpy_pair_sums_agree():
    rng = np.random.default_rng(4)
    P = trefoil(np.linspace(0, 2 * np.pi, 150, endpoint=False)) + rng.normal(0, 0.05, (150, 3))
    U = rng.normal(size=(150, 3))
    assert writhe(P) == pytest.approx(writhe(P, fast=False), abs=1e-11)
    Q = P + 0.05 * U
    assert linking_number(P, Q) == pytest.approx(linking_number(P, Q, fast=False), abs=1e-11)
