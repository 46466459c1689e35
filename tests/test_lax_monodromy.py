"""Monodromy T(lam) and tr T^n: exact conservation under the matrix Lax flow, O(ds) drift under (3.9) (design B8)."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dnarod.core.errors import DnarodError
from dnarod.physics.lax import (V_matrix, component_rhs, lax_pair, monodromy, monodromy_from_matrices,
                        spectral_invariants)

LAM = 0.8
LENGTH = 1.0


def u_fields(s):
    """Smooth periodic U-fields on [0, LENGTH): Gamma, Omega, p, m, each (n, 3)."""
    c, sn = np.cos(2 * np.pi * s / LENGTH), np.sin(2 * np.pi * s / LENGTH)
    Gamma = np.stack([0.1 * sn, 0.2 * c, 1.0 + 0.1 * c], 1)
    Omega = np.stack([0.5 + 0.3 * c, 0.4 * sn, 1.2 + 0.2 * sn * c], 1)
    p = np.stack([0.3 * c, 0.2 + 0.1 * sn, -0.1 * c], 1)
    m = np.stack([0.1 * sn, -0.2 * c, 0.3 + 0.05 * sn], 1)
    return Gamma, Omega, p, m


def v_fields(s, t):
    """Arbitrary smooth periodic V-fields (not constitutive): gamma, omega, P, M, each (n, 3)."""
    ph = 2 * np.pi * s / LENGTH
    gamma = np.stack([0.3 * np.sin(ph + t), 0.2 * np.cos(ph - 0.5 * t), 0.1 + 0.1 * np.sin(2 * ph)], 1)
    omega = np.stack([0.4 * np.cos(ph + 0.3 * t), 0.2 + 0.1 * np.sin(ph), 0.5 * np.cos(ph - t)], 1)
    P = np.stack([0.2 * np.sin(ph - t), 0.3 * np.cos(ph), 0.4 + 0.2 * np.sin(ph + 0.7 * t)], 1)
    M = np.stack([0.1 * np.cos(2 * ph), 0.3 * np.sin(ph + t), -0.2 * np.cos(ph)], 1)
    return gamma, omega, P, M


def test_monodromy_is_ordered_product():
    rng = np.random.default_rng(0)
    f = [rng.normal(size=(3, 3)) for _ in range(4)]
    T = monodromy(*f, LAM, 0.3)
    Ut, _ = lax_pair(*f, *f, LAM, 0.3)
    assert np.allclose(T, Ut[2] @ Ut[1] @ Ut[0], atol=1e-14)
    assert not np.allclose(T, Ut[0] @ Ut[1] @ Ut[2], atol=1e-3)   # order matters
    inv = spectral_invariants(T, 3)
    assert np.allclose(inv, [np.trace(T), np.trace(T @ T), np.trace(T @ T @ T)], atol=1e-12)


def test_invariants_conserved_by_exact_matrix_flow():
    """dU~_k/dt = V~_{k+1} U~_k - U~_k V~_k with arbitrary periodic V: tr T^n constant."""
    n = 12
    ds = LENGTH / n
    s = np.arange(n) * ds
    Ut0, _ = lax_pair(*u_fields(s), *v_fields(s, 0.0), LAM, ds)

    def rhs(t, y):
        Ut = (y[:16 * n] + 1j * y[16 * n:]).reshape(n, 4, 4)
        V = V_matrix(*v_fields(s, t), LAM)
        d = np.roll(V, -1, axis=0) @ Ut - Ut @ V
        return np.concatenate([d.real.ravel(), d.imag.ravel()])

    y0 = np.concatenate([Ut0.real.ravel(), Ut0.imag.ravel()])
    sol = solve_ivp(rhs, (0, 3.0), y0, method="DOP853", rtol=1e-12, atol=1e-13)
    Ut1 = (sol.y[:16 * n, -1] + 1j * sol.y[16 * n:, -1]).reshape(n, 4, 4)
    I0 = spectral_invariants(monodromy_from_matrices(Ut0), 4)
    I1 = spectral_invariants(monodromy_from_matrices(Ut1), 4)
    assert np.abs(Ut1 - Ut0).max() > 0.1          # the matrices really moved
    assert np.abs(I1 - I0).max() / np.abs(I0).max() < 1e-10


def _drift(n, reading):
    ds = LENGTH / n
    s = np.arange(n) * ds
    y0 = np.concatenate([x.ravel() for x in u_fields(s)])

    def rhs(t, y):
        G, O, p, m = y.reshape(4, n, 3)
        d = component_rhs(G, O, p, m, *v_fields(s, t), LAM, ds, reading=reading)
        return np.concatenate([x.ravel() for x in d])

    sol = solve_ivp(rhs, (0, 1.0), y0, method="DOP853", rtol=1e-11, atol=1e-12)
    I0 = spectral_invariants(monodromy(*y0.reshape(4, n, 3), LAM, ds), 3)
    I1 = spectral_invariants(monodromy(*sol.y[:, -1].reshape(4, n, 3), LAM, ds), 3)
    return np.abs(I1 - I0).max() / np.abs(I0).max()


@pytest.mark.parametrize("reading", ["R1", "midpoint"])
def test_invariants_drift_at_order_ds_under_component_equations(reading):
    d = [_drift(n, reading) for n in (32, 64, 128)]
    assert d[0] > 1e-4                                    # not conserved: (3.8) is not exact
    order = np.log2(np.array(d[:-1]) / np.array(d[1:]))
    assert np.all((order > 0.9) & (order < 1.25)), (d, order)   # measured 1.16, 1.08


def test_open_chain_trace_rate():
    """Exact flow, open ends: dT/dt = V~_N T - T V~_0, so d tr T^n/dt = n tr((V~_N - V~_0) T^n)."""
    rng = np.random.default_rng(5)
    n, ds = 5, 0.3
    f = [rng.normal(size=(n + 1, 3)) for _ in range(8)]
    Ut, Vt = lax_pair(*f, LAM, ds)
    Ut, VN = Ut[:n], Vt[n]
    dU = Vt[1:] @ Ut - Ut @ Vt[:n]
    dT = sum(monodromy_from_matrices(np.concatenate([Ut[:k], dU[k:k + 1], Ut[k + 1:]])) for k in range(n))
    T = monodromy_from_matrices(Ut)
    assert np.allclose(dT, VN @ T - T @ Vt[0], atol=1e-12)
    for p in (1, 2, 3):
        rate = sum(np.trace(np.linalg.matrix_power(T, j) @ dT @ np.linalg.matrix_power(T, p - 1 - j)) for j in range(p))
        assert np.isclose(rate, p * np.trace((VN - Vt[0]) @ np.linalg.matrix_power(T, p)))


def test_monodromy_bad_input():
    with pytest.raises(DnarodError, match="Ut"):
        monodromy_from_matrices(np.zeros((3, 4)))
    with pytest.raises(DnarodError, match="T"):
        spectral_invariants(np.zeros((3, 4)))
    with pytest.raises(DnarodError, match="nmax"):
        spectral_invariants(np.eye(4), 0)
    with pytest.raises(DnarodError, match="ds"):
        monodromy(*[np.zeros((2, 3))] * 4, LAM, -1.0)
