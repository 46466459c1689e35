"""Generators (3.1), the 4x4 pair (3.3)-(3.7), the Lax residual (3.8), the obstruction, Appendix A
(design B2, B3, B5)."""
import itertools

import numpy as np
import pytest

from dnarod.core.errors import DnarodError
from dnarod.physics.lax import (D_FLIP, XMINUS, XPLUS, J, K, U_matrix, V_matrix, appendix_pair, appendix_residual,
                        appendix_to_paper, commutator, complexify, component_rhs, lax_pair, lax_residual, realify,
                        so4_coefficients, so4_matrix, so4_to_fields, symmetric_obstruction,
                        xpm_coefficients)
from dnarod.physics.lax.generators import LEVI_CIVITA, antisymmetric_part, symmetric_part
from dnarod.core.rotations import hat

# The paper's printed matrices (3.1a,b), typed in independently of the closed forms in the package.
J_PRINTED = np.array([
    [[0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 0]],
    [[0, 0, 1, 0], [0, 0, 0, 0], [-1, 0, 0, 0], [0, 0, 0, 0]],
    [[0, -1, 0, 0], [1, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, 0]]], dtype=float)
K_PRINTED = np.array([
    [[0, 0, 0, -1], [0, 0, 0, 0], [0, 0, 0, 0], [1, 0, 0, 0]],
    [[0, 0, 0, 0], [0, 0, 0, -1], [0, 0, 0, 0], [0, 1, 0, 0]],
    [[0, 0, 0, 0], [0, 0, 0, 0], [0, 0, 0, -1], [0, 0, 1, 0]]], dtype=float)


def rand_fields(n=5, seed=0):
    rng = np.random.default_rng(seed)
    return [rng.normal(size=(n, 3)) for _ in range(8)]


def test_generators_are_the_printed_matrices():
    assert np.array_equal(J, J_PRINTED)
    assert np.array_equal(K, K_PRINTED)


def test_commutation_relations_3_1c():
    for a, b in itertools.product(range(3), repeat=2):
        eJ = np.einsum("c,cij->ij", LEVI_CIVITA[a, b], J)
        eK = np.einsum("c,cij->ij", LEVI_CIVITA[a, b], K)
        assert np.array_equal(commutator(J[a], J[b]), eJ)
        assert np.array_equal(commutator(J[a], K[b]), eK)
        assert np.array_equal(commutator(K[a], K[b]), eJ)
        # closed form K_a K_b = -delta_ab E44 - E_ab
        E = np.zeros((4, 4))
        E[a, b] = 1
        assert np.array_equal(K[a] @ K[b], -(a == b) * np.diag([0, 0, 0, 1.0]) - E)
        # X+ and X- are two commuting copies of so(3)
        assert np.allclose(commutator(XPLUS[a], XMINUS[b]), 0)
        assert np.allclose(commutator(XPLUS[a], XPLUS[b]), np.einsum("c,cij->ij", LEVI_CIVITA[a, b], XPLUS))
        assert np.allclose(commutator(XMINUS[a], XMINUS[b]), np.einsum("c,cij->ij", LEVI_CIVITA[a, b], XMINUS))
        # conjugation by diag(1,1,1,-1)
        assert np.array_equal(D_FLIP @ J[a] @ D_FLIP, J[a])
        assert np.array_equal(D_FLIP @ K[a] @ D_FLIP, -K[a])


def test_omega_dot_J_is_cross_product_and_projection_inverts():
    rng = np.random.default_rng(1)
    w, v, k = rng.normal(size=(3, 3))
    W = np.einsum("a,aij->ij", w, J)
    assert np.allclose(W[:3, :3] @ v, np.cross(w, v))
    assert np.allclose(W[:3, :3], hat(w))
    X = so4_matrix(w + 1j * v, k)
    assert np.allclose(X, np.einsum("a,aij->ij", w + 1j * v, J) + np.einsum("a,aij->ij", k, K))
    S = rng.normal(size=(4, 4))
    j2, k2 = so4_coefficients(X + (S + S.T))      # the symmetric part does not contribute
    assert np.allclose(j2, w + 1j * v) and np.allclose(k2, k)
    # X+/- decomposition
    plus, minus = xpm_coefficients(w + 1j * v, k)
    assert np.allclose(np.einsum("a,aij->ij", plus, XPLUS) + np.einsum("a,aij->ij", minus, XMINUS), X)
    # trace form
    assert np.allclose([-0.5 * np.trace(J[a] @ X) for a in range(3)], w + 1j * v)


def test_U_matrix_matches_3_4_and_3_5():
    Gamma, Omega, p, m = rand_fields(4)[:4]
    lam = 0.7
    U = U_matrix(Gamma, Omega, p, m, lam)
    A = -(np.einsum("ka,aij->kij", Omega, J_PRINTED) + lam ** 2 * np.einsum("ka,aij->kij", Gamma, K_PRINTED))
    B = -lam * (np.einsum("ka,aij->kij", p, J_PRINTED) + lam ** 2 * np.einsum("ka,aij->kij", m, K_PRINTED))
    assert np.allclose(U, A + 1j * B, atol=1e-15)
    assert np.allclose(so4_to_fields(U, lam), (Gamma, Omega, p, m))
    V = V_matrix(Gamma, Omega, p, m, lam)          # same ansatz
    assert np.allclose(V, U)


def test_residual_identity_and_symmetric_obstruction():
    f = rand_fields(6, seed=2)
    rng = np.random.default_rng(3)
    d = [rng.normal(size=(6, 3)) for _ in range(4)]
    lam, ds = 0.9, 0.23
    R = lax_residual(*f, *d, lam, ds)
    U = U_matrix(*f[:4], lam)
    V = V_matrix(*f[4:], lam)
    V1 = np.roll(V, -1, axis=0)
    dU = U_matrix(*d, lam)
    Res = dU - (V1 - V) / ds - (V1 @ U - U @ V)
    assert np.allclose(R, ds * Res, atol=1e-13)
    Ut, Vt = lax_pair(*f, lam, ds)
    assert np.allclose(R, ds * dU - (np.roll(Vt, -1, axis=0) @ Ut - Ut @ Vt), atol=1e-13)
    # Sym(Res) = -1/2 {V1 - V, U}, whatever the time derivatives
    obs = symmetric_obstruction(*f, lam, ds)
    assert np.allclose(symmetric_part(R), -0.5 * ds * obs, atol=1e-13)
    assert np.abs(obs).max() > 0.1
    assert np.allclose(obs, np.swapaxes(obs, 1, 2))
    # Antisym(V1 U - U V) = [Vbar, U]
    Vb = 0.5 * (V + V1)
    assert np.allclose(antisymmetric_part(V1 @ U - U @ V), Vb @ U - U @ Vb, atol=1e-13)
    # the obstruction vanishes when V does not depend on k
    f_const = f[:4] + [np.broadcast_to(x[0], x.shape) for x in f[4:]]
    assert np.abs(symmetric_obstruction(*f_const, lam, ds)).max() < 1e-14


def test_open_chain_takes_zero_beyond_last_node():
    f = rand_fields(4, seed=4)
    d = rand_fields(4, seed=5)[:4]
    lam, ds = 0.6, 0.5
    R_open = lax_residual(*f, *d, lam, ds, periodic=False)
    R_per = lax_residual(*f, *d, lam, ds, periodic=True)
    assert np.allclose(R_open[:-1], R_per[:-1])
    Ut, Vt = lax_pair(*f, lam, ds)
    assert np.allclose(R_open[-1], ds * U_matrix(*d, lam)[-1] + Ut[-1] @ Vt[-1])


def test_appendix_A_pair_is_conjugated_real_form():
    f = rand_fields(5, seed=6)
    lam, ds = 0.75, 0.31
    Xt, Yt = appendix_pair(*f, lam, ds)
    Ut, Vt = lax_pair(*f, lam, ds)
    assert Xt.dtype == float and Xt.shape == (5, 8, 8)
    assert np.allclose(appendix_to_paper(Xt), Ut, atol=1e-15)
    assert np.allclose(appendix_to_paper(Yt), Vt, atol=1e-15)
    assert np.allclose(realify(D_FLIP @ Ut @ D_FLIP), Xt, atol=1e-15)
    assert np.allclose(complexify(realify(Ut)), Ut)
    # (A.2e) block by block, from the printed generators
    Gamma, Omega, p, m = f[:4]
    A = -np.einsum("ka,aij->kij", Omega, J_PRINTED) + lam ** 2 * np.einsum("ka,aij->kij", Gamma, K_PRINTED)
    B = lam * (-np.einsum("ka,aij->kij", p, J_PRINTED) + lam ** 2 * np.einsum("ka,aij->kij", m, K_PRINTED))
    assert np.allclose((Xt - np.eye(8)) / ds, np.block([[A, -B], [B, A]]))
    # X is similar to diag(A + iB, A - iB): same spectrum
    ev8 = np.sort_complex(np.linalg.eigvals(Xt[0]))
    ev4 = np.sort_complex(np.concatenate([np.linalg.eigvals(Ut[0]), np.linalg.eigvals(Ut[0].conj())]))
    assert np.allclose(ev8, ev4, atol=1e-12)


def test_appendix_A_X_is_not_antisymmetric():
    """Misprint 30: X + X^T = [[0, -2B], [2B, 0]], so f_I . f_J = delta_IJ is not preserved by (9.2)."""
    f = rand_fields(3, seed=9)
    Xt, Yt = appendix_pair(*f, 0.9, 0.2)
    for Z, scale in ((Xt - np.eye(8), 0.2), (Yt, 1.0)):
        B = (Z[:, 4:, :4]) / scale
        S = (Z + np.swapaxes(Z, 1, 2)) / scale
        assert np.allclose(S[:, :4, :4], 0) and np.allclose(S[:, 4:, 4:], 0)
        assert np.allclose(S[:, 4:, :4], 2 * B) and np.abs(B).max() > 0.1


@pytest.mark.parametrize("reading", ["R1", "midpoint"])
def test_appendix_A_residual_keeps_block_form_and_vanishes_with_3_9(reading):
    f = rand_fields(5, seed=7)
    lam, ds = 1.1, 0.2
    d = component_rhs(*f, lam, ds, reading=reading)
    R8 = appendix_residual(*f, *d, lam, ds)
    R4 = lax_residual(*f, *d, lam, ds)
    assert np.allclose(R8, realify(D_FLIP @ R4 @ D_FLIP), atol=1e-13)
    assert np.allclose(R8[:, :4, :4], R8[:, 4:, 4:]) and np.allclose(R8[:, :4, 4:], -R8[:, 4:, :4])
    # so(4) part of the upper-left (real) and lower-left (imaginary) blocks
    if reading == "midpoint":
        for blk in (R8[:, :4, :4], R8[:, 4:, :4]):
            assert np.abs(antisymmetric_part(blk)).max() < 1e-13
    else:
        for blk in (R8[:, :4, :4], R8[:, 4:, :4]):
            assert np.abs(blk[:, [1, 2, 0], [2, 0, 1]]).max() < 1e-13
            assert np.abs(blk[:, :3, 3]).max() < 1e-13


def test_appendix_zeta_i_lambda_is_not_3_9():
    """Misprint 12: zeta = i lam does not reduce (A.4) to (3.9)."""
    f = rand_fields(4, seed=8)
    lam, ds = 0.8, 0.3
    d = component_rhs(*f, lam, ds, reading="midpoint")
    R8 = appendix_residual(*f, *d, 1j * lam, ds)
    assert np.abs(antisymmetric_part(R8[:, :4, :4])).max() > 1e-2


def test_pair_bad_input_names_argument():
    f = rand_fields(3)
    with pytest.raises(DnarodError, match="Omega"):
        U_matrix(f[0], np.zeros((3, 2)), f[2], f[3], 0.5)
    with pytest.raises(DnarodError, match="p: has 2 nodes"):
        U_matrix(f[0], f[1], np.zeros((2, 3)), f[3], 0.5)
    bad = f[3].copy()
    bad[1, 2] = np.nan
    with pytest.raises(DnarodError, match="m: non-finite value at node 1"):
        U_matrix(*f[:3], bad, 0.5)
    with pytest.raises(DnarodError, match="ds"):
        lax_pair(*f, 0.5, 0.0)
    with pytest.raises(DnarodError, match="ds"):
        lax_pair(*f, 0.5, float("nan"))
    with pytest.raises(DnarodError, match="lam"):
        lax_pair(*f, float("inf"), 0.1)
    with pytest.raises(DnarodError, match="dm"):
        lax_residual(*f, *f[:3], np.zeros((4, 3)), 0.5, 0.1)
    with pytest.raises(DnarodError, match="lam"):
        so4_to_fields(np.zeros((4, 4)), 0.0)
