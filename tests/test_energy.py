"""Strains, energy and analytic loads (design A2, A5 i, A6 items 2-3)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dnarod.core.energy import energy, loads
from dnarod.core.parameters import StepParameters
from dnarod.core.rotations import cayley, rotation_about_axis
from dnarod.core.strains import Closure, chain_from_strains, strains

from conftest import random_chain


def fd_loads(pos, frm, params, ds, closure=None, h=1e-4):
    """Richardson-extrapolated central differences of the energy (an independent reference)."""
    def E(p, f):
        return energy(p, f, params, ds, closure)

    def central(fun, h):
        return (fun(h) - fun(-h)) / (2 * h)

    F = np.zeros_like(pos)
    T = np.zeros_like(pos)
    for i in range(pos.shape[0]):
        for a in range(3):
            e = np.eye(3)[a]

            def shift(s):
                p = pos.copy()
                p[i] += s * e
                return E(p, frm)

            def turn(s):
                f = frm.copy()
                f[i] = rotation_about_axis(e, s) @ frm[i]
                return E(pos, f)

            F[i, a] = -(4 * central(shift, h / 2) - central(shift, h)) / 3
            T[i, a] = -(4 * central(turn, h / 2) - central(turn, h)) / 3
    return F, T


def test_loads_match_finite_differences(chain):
    pos, frm, params, ds = chain
    E, F, T = loads(pos, frm, params, ds)
    assert E == pytest.approx(energy(pos, frm, params, ds), rel=1e-14)
    Fn, Tn = fd_loads(pos, frm, params, ds)
    assert np.abs(F - Fn).max() / np.abs(F).max() < 1e-7
    assert np.abs(T - Tn).max() / np.abs(T).max() < 1e-7


def test_total_force_and_torque_vanish(chain):
    pos, frm, params, ds = chain
    _, F, T = loads(pos, frm, params, ds)
    scale = np.abs(F).max() * (1 + np.abs(pos).max())
    assert np.abs(F.sum(axis=0)).max() < 1e-12 * scale
    assert np.abs((T + np.cross(pos, F)).sum(axis=0)).max() < 1e-12 * scale


def test_circular_screw_closure_loads_match_finite_differences():
    pos, frm, params, ds = random_chain(7, n=7, circular=True)
    closure = Closure(Rotation.random(random_state=11).as_matrix(), np.array([0.3, -0.2, 1.1]))
    E, F, T = loads(pos, frm, params, ds, closure)
    Fn, Tn = fd_loads(pos, frm, params, ds, closure)
    assert np.abs(F - Fn).max() / np.abs(F).max() < 1e-7
    assert np.abs(T - Tn).max() / np.abs(T).max() < 1e-7


def test_circular_plain_ring_conserves_total_torque():
    pos, frm, params, ds = random_chain(8, n=6, circular=True)
    _, F, T = loads(pos, frm, params, ds, Closure.identity())
    scale = np.abs(F).max() * (1 + np.abs(pos).max())
    assert np.abs(F.sum(axis=0)).max() < 1e-12 * scale
    assert np.abs((T + np.cross(pos, F)).sum(axis=0)).max() < 1e-12 * scale


def helix_closed_form(Omega0, Gamma0, ds, n):
    """Design A5 i: nodes of the uniform helix, built without the strain map."""
    W = np.linalg.norm(Omega0)
    nvec = Omega0 / W
    theta = 2 * np.arctan(ds * W / 2)
    b = ds * Gamma0
    h = b @ nvec
    bperp = b - h * nvec
    p = 0.5 * (bperp + np.cross(nvec, bperp) / np.tan(theta / 2))
    frames = rotation_about_axis(np.tile(nvec, (n, 1)), theta * np.arange(n))
    pos = p + np.arange(n)[:, None] * h * nvec - frames @ p
    radius = np.linalg.norm(np.cross(Gamma0, Omega0)) * np.sqrt(1 + ds**2 * W**2 / 4) / W**2
    return pos, frames, theta, h, radius, p, nvec


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_helix_closed_form_has_intrinsic_strains_and_zero_loads(seed):
    rng = np.random.default_rng(seed)
    ds = 0.34
    Omega0 = rng.normal(0, 0.5, 3) + [0, 0, 1.8]
    Gamma0 = rng.normal(0, 0.2, 3) + [0, 0, 1.0]
    pos, frm, theta, h, radius, p, nvec = helix_closed_form(Omega0, Gamma0, ds, 25)
    Om, Ga = strains(pos, frm, ds)
    assert np.abs(Om - Omega0).max() < 1e-10
    assert np.abs(Ga - Gamma0).max() < 1e-10
    # every node is at the helix radius from the axis through p along n
    rel = pos - p
    dist = np.linalg.norm(rel - np.outer(rel @ nvec, nvec), axis=1)
    assert np.allclose(dist, radius, rtol=1e-10)
    X = rng.normal(size=(6, 6))
    params = StepParameters.uniform(X @ X.T + 6 * np.eye(6), np.concatenate([Omega0, Gamma0]), 24)
    E, F, T = loads(pos, frm, params, ds)
    assert abs(E) < 1e-18
    assert np.abs(F).max() < 1e-10 and np.abs(T).max() < 1e-10


def test_chain_from_strains_is_the_inverse(chain):
    pos, frm, params, ds = chain
    Om, Ga = strains(pos, frm, ds)
    p2, f2 = chain_from_strains(Om, Ga, ds, pos[0], frm[0])
    assert np.abs(p2 - pos).max() < 1e-12 and np.abs(f2 - frm).max() < 1e-12
    assert np.allclose(cayley(ds * Om), np.swapaxes(frm[:-1], 1, 2) @ frm[1:], atol=1e-13)


def test_strains_vectorised_over_frames_equal_per_frame_loop():
    """Leading (trajectory-frame) axes give the same strains as a loop (open and screw-closed)."""
    chains = [random_chain(s, n=6) for s in range(4)]
    pos = np.stack([c[0] for c in chains])
    frm = np.stack([c[1] for c in chains])
    closure = Closure(Rotation.random(random_state=3).as_matrix(), np.array([0.1, 0.2, 0.3]))
    for cl in (None, closure):
        Om, Ga = strains(pos, frm, 0.34, cl)
        for i in range(4):
            o, g = strains(pos[i], frm[i], 0.34, cl)
            assert np.allclose(Om[i], o, rtol=1e-13, atol=1e-13) and np.allclose(Ga[i], g, rtol=1e-13, atol=1e-13)
