"""The 12 component equations (3.9) and the s-discrete SMK (3.13), tested against the matrix Lax residual.

The reference is always the projection of dU~/dt - (V~^1 U~ - U~ V~) built from the 4x4 matrices
(never the printed formulas): random non-symmetric data, all powers of lam nonzero.
"""
import numpy as np
import pytest

from dnarod.core.errors import DnarodError
from dnarod.physics.lax import appendix_rhs, component_rhs, lax_residual, smk_rhs, so4_to_fields, symmetric_obstruction
from dnarod.physics.lax.generators import LEVI_CIVITA, antisymmetric_part, symmetric_part
from dnarod.core.rotations import rotation_about_axis

# entries (a+1, a+2), 0-based, for a = 0, 1, 2
JROWS, JCOLS = [1, 2, 0], [2, 0, 1]


def rand_fields(n=6, seed=0, scale=1.0):
    rng = np.random.default_rng(seed)
    return [scale * rng.normal(size=(n, 3)) for _ in range(8)]


@pytest.mark.parametrize("lam", [0.37, 0.9, 1.6])
@pytest.mark.parametrize("periodic", [True, False])
def test_midpoint_reading_kills_the_so4_projection(lam, periodic):
    f = rand_fields(7, seed=int(10 * lam))
    ds = 0.29
    d = component_rhs(*f, lam, ds, reading="midpoint", periodic=periodic)
    R = lax_residual(*f, *d, lam, ds, periodic=periodic)
    scale = np.abs(R).max()
    assert np.abs(antisymmetric_part(R)).max() < 1e-14 * max(scale, 1) * 100
    # what remains is exactly the symmetric obstruction
    assert np.allclose(R, -0.5 * ds * symmetric_obstruction(*f, lam, ds, periodic=periodic), atol=1e-13)
    # and the 12 projected component residuals vanish, each separately
    for res in so4_to_fields(R / ds, lam):
        assert np.abs(res).max() < 1e-12


@pytest.mark.parametrize("lam", [0.37, 0.9, 1.6])
@pytest.mark.parametrize("periodic", [True, False])
def test_R1_reading_kills_entries_a1a2_and_a4(lam, periodic):
    f = rand_fields(7, seed=int(100 * lam))
    ds = 0.41
    d = component_rhs(*f, lam, ds, reading="R1", periodic=periodic)
    R = lax_residual(*f, *d, lam, ds, periodic=periodic)
    assert np.abs(R[:, JROWS, JCOLS]).max() < 1e-13
    assert np.abs(R[:, :3, 3]).max() < 1e-13
    # R1 = midpoint - (matching entry of Sym(Res)): the antisymmetric part is minus the symmetric one
    S, A = symmetric_part(R), antisymmetric_part(R)
    assert np.allclose(A[:, JROWS, JCOLS], -S[:, JROWS, JCOLS], atol=1e-13)
    assert np.abs(A[:, JROWS, JCOLS]).max() > 1e-3      # R1 differs from the so(4) projection
    # the readings differ by O(V_{k+1} - V_k): identical when V does not depend on k
    fc = f[:4] + [np.broadcast_to(x[0], x.shape) for x in f[4:]]
    for a, b in zip(component_rhs(*fc, lam, ds, "R1"), component_rhs(*fc, lam, ds, "midpoint")):
        assert np.allclose(a, b, atol=1e-13)


@pytest.mark.parametrize("reading", ["R1", "midpoint"])
def test_smk_is_the_lambda_to_zero_limit(reading):
    f = rand_fields(5, seed=3)
    ds = 0.34
    d0 = smk_rhs(*f, ds, reading=reading)
    assert all(x.shape == (5, 3) for x in d0)
    for lam in (1e-3, 1e-4):
        dl = component_rhs(*f, lam, ds, reading=reading)
        for a, b in zip(d0, dl):
            assert np.abs(a - b).max() < 10 * lam ** 2 * (1 + np.abs(a).max())
    # and at lam = 0 the J_a projection (Omega equation) is exact from the matrices
    d = smk_rhs(*f, ds, reading=reading)
    R = lax_residual(*f, *d, 0.0, ds)
    if reading == "R1":
        assert np.abs(R[:, JROWS, JCOLS]).max() < 1e-13
    else:
        assert np.abs(antisymmetric_part(R)).max() < 1e-13


def printed_3_9(Gamma, Omega, p, m, gamma, omega, P, M, lam, ds, fix_index=True):
    """The paper's (3.9a-d) typed as printed (LHS = 0 solved for d/dt), Levi-Civita and a+1, a+2 forms.

    Only the repeated free index of (3.9a) is fixed (misprint 4); the sign misprints 5-7 are kept.
    """
    eps = LEVI_CIVITA
    nx = lambda x: np.roll(x, -1, axis=0)  # noqa: E731  superscript 1
    s1 = lambda x: np.roll(x, -1, axis=1)  # noqa: E731  component a+1
    s2 = lambda x: np.roll(x, -2, axis=1)  # noqa: E731  component a+2
    dG = ((nx(gamma) - gamma) / ds + np.einsum("abc,ka,kb->kc", eps, Gamma, nx(omega))
          + np.einsum("abc,ka,kb->kc", eps, Omega, gamma)
          + lam ** 2 * (np.einsum("abc,ka,kb->kc", eps, M, p) - np.einsum("abc,ka,kb->kc", eps, m, nx(P))))
    dO = ((nx(omega) - omega) / ds + (s1(Omega) * s2(nx(omega)) - s1(omega) * s2(Omega))
          + lam ** 2 * (s1(P) * s2(p) - s1(p) * s2(nx(P)))
          - lam ** 4 * (s1(Gamma) * s2(gamma) - s1(nx(gamma)) * s2(Gamma))
          - lam ** 6 * (s1(nx(M)) * s2(m) - s1(m) * s2(M)))
    dp = ((nx(P) - P) / ds + (s1(p) * s2(nx(omega)) - s1(omega) * s2(p)) - (s1(P) * s2(Omega) - s1(Omega) * s2(nx(P)))
          + lam ** 4 * (s1(M) * s2(Gamma) - s1(nx(Gamma)) * s2(M) + s1(m) * s2(gamma) - s1(nx(gamma)) * s2(m)))
    dm = (nx(M) - M) / ds + sum(np.einsum("abc,ka,kb->kc", eps, x, y)
                                for x, y in ((p, gamma), (Gamma, nx(P)), (Omega, M), (m, nx(omega))))
    return dG, dO, dp, dm


def test_printed_3_13_with_index_fix_is_R1_but_printed_3_9_has_sign_misprints():
    f = rand_fields(6, seed=11)
    ds = 0.3
    # lam = 0: printed (3.13b,c,d) and fixed (3.13a) are the R1 reading
    for a, b in zip(printed_3_9(*f, 0.0, ds), smk_rhs(*f, ds, reading="R1")):
        assert np.allclose(a, b, atol=1e-13)
    # lam != 0: (3.9a) and (3.9d) agree, (3.9b) and (3.9c) do not (misprints 5, 6, 7)
    lam = 0.8
    pr = printed_3_9(*f, lam, ds)
    ok = component_rhs(*f, lam, ds, reading="R1")
    assert np.allclose(pr[0], ok[0], atol=1e-13) and np.allclose(pr[3], ok[3], atol=1e-13)
    assert np.abs(pr[1] - ok[1]).max() > 0.1 and np.abs(pr[2] - ok[2]).max() > 0.1
    R = lax_residual(*f, *pr, lam, ds)
    assert np.abs(R[:, JROWS, JCOLS]).max() > 1e-2      # the matrix test catches them


def test_midpoint_is_rotation_covariant_R1_is_not():
    f = rand_fields(5, seed=12)
    ds, lam = 0.25, 0.7
    axis = np.array([0.3, -0.5, 0.8])
    Q = rotation_about_axis(axis / np.linalg.norm(axis), 1.1)
    fq = [x @ Q.T for x in f]
    for reading, covariant in (("midpoint", True), ("R1", False)):
        d = component_rhs(*f, lam, ds, reading=reading)
        dq = component_rhs(*fq, lam, ds, reading=reading)
        err = max(np.abs(a @ Q.T - b).max() for a, b in zip(d, dq))
        assert (err < 1e-12) == covariant, (reading, err)


def test_open_chain_uses_zero_beyond_last_node():
    f = rand_fields(4, seed=13)
    ds = 0.5
    z = [np.zeros((1, 3))] * 8
    ext = [np.concatenate([x, zz]) for x, zz in zip(f, z)]
    for reading in ("R1", "midpoint"):
        a = smk_rhs(*f, ds, reading=reading, periodic=False)
        b = smk_rhs(*ext, ds, reading=reading, periodic=False)
        for x, y in zip(a, b):
            assert np.allclose(x, y[:-1])


@pytest.mark.parametrize("reading", ["R1", "midpoint"])
def test_continuum_limit_is_order_ds(reading):
    """Smooth fields: (3.9) -> the continuum equations of design B4 with error O(ds)."""
    lam = 0.6
    L = 2.0

    def fields(s):
        ph = 2 * np.pi * s / L
        c, sn = np.cos, np.sin
        F = [np.stack([a * c(ph + b), a * sn(2 * ph - b), 0.5 + a * c(ph - 2 * b)], 1)
             for a, b in zip((0.3, 0.5, 0.4, 0.2, 0.6, 0.35, 0.45, 0.25), np.arange(8) * 0.7)]
        dF = [np.stack([-a * sn(ph + b), 2 * a * c(2 * ph - b), -a * sn(ph - 2 * b)], 1) * 2 * np.pi / L
              for a, b in zip((0.3, 0.5, 0.4, 0.2, 0.6, 0.35, 0.45, 0.25), np.arange(8) * 0.7)]
        return F, dF

    errs = []
    for n in (40, 80, 160):
        ds = L / n
        s = np.arange(n) * ds
        F, dF = fields(s)
        G, O, p, m, g, w, P, M = F
        dg, dw, dP, dM = dF[4:]
        cr = np.cross
        l2, l4, l6 = lam ** 2, lam ** 4, lam ** 6
        cont = (dg + cr(G, w) + cr(O, g) + l2 * (cr(M, p) + cr(P, m)),
                dw + cr(O, w) + l2 * cr(P, p) + l4 * cr(G, g) + l6 * cr(M, m),
                dP + cr(p, w) + cr(O, P) + l4 * (cr(m, g) + cr(G, M)),
                dM + cr(m, w) + cr(G, P) + cr(O, M) + cr(p, g))
        d = component_rhs(*F, lam, ds, reading=reading)
        errs.append(max(np.abs(a - b).max() for a, b in zip(d, cont)))
    order = np.log2(np.array(errs[:-1]) / np.array(errs[1:]))
    assert np.all((order > 0.9) & (order < 1.1)), (errs, order)


def test_appendix_rhs_is_component_rhs_at_zeta():
    f = rand_fields(4, seed=14)
    for a, b in zip(appendix_rhs(*f, 0.8, 0.2), component_rhs(*f, 0.8, 0.2)):
        assert np.array_equal(a, b)


def test_component_bad_input_names_argument():
    f = rand_fields(3)
    with pytest.raises(DnarodError, match="reading"):
        smk_rhs(*f, 0.1, reading="R2")
    with pytest.raises(DnarodError, match="gamma"):
        smk_rhs(*f[:4], np.zeros(3), *f[5:], 0.1)
    with pytest.raises(DnarodError, match="M: has 2 nodes"):
        smk_rhs(*f[:7], np.zeros((2, 3)), 0.1)
    with pytest.raises(DnarodError, match="ds"):
        smk_rhs(*f, -0.1)
    with pytest.raises(DnarodError, match="ds"):
        smk_rhs(*f, "abc")
    bad = f[5].copy()
    bad[2, 0] = np.inf
    with pytest.raises(DnarodError, match="omega: non-finite value at node 2"):
        smk_rhs(*f[:5], bad, *f[6:], 0.1)
    with pytest.raises(DnarodError, match="lam"):
        component_rhs(*f, float("nan"), 0.1)
    with pytest.raises(DnarodError, match="Gamma"):
        smk_rhs(np.zeros((0, 3)), *f[1:], 0.1)


def test_symbolic_projection_vanishes_identically():
    """sympy: with the package's own formulas fed symbols, the projected residual is identically zero."""
    import sympy as sp  # a test dependency: a missing install must fail, not skip
    from dnarod.physics.lax.components import _midpoint, _r1

    lam, ds = sp.symbols("lam ds", positive=True)
    names = ["G", "O", "p", "m", "g", "w", "P", "M"]
    F = [np.array([[sp.Symbol(f"{nm}{k}{a}") for a in range(3)] for k in range(2)], dtype=object) for nm in names]
    nxt = [np.roll(x, -1, axis=0) for x in F[4:]]

    def mat(lin, rot, ml, mr):
        j = [-(rot[a] + sp.I * lam * ml[a]) for a in range(3)]
        k = [-lam ** 2 * (lin[a] + sp.I * lam * mr[a]) for a in range(3)]
        return sp.Matrix([[0, -j[2], j[1], -k[0]], [j[2], 0, -j[0], -k[1]], [-j[1], j[0], 0, -k[2]],
                          [k[0], k[1], k[2], 0]])

    for reading, fn in (("R1", _r1), ("midpoint", _midpoint)):
        d = fn(*F, *nxt, lam, ds)
        k = 0
        U = mat(*[x[k] for x in F[:4]])
        V = mat(*[x[k] for x in F[4:]])
        V1 = mat(*[x[k + 1] for x in F[4:]])
        dU = mat(*[x[k] for x in d])
        R = sp.expand(dU - (V1 - V) / ds - (V1 * U - U * V))
        if reading == "midpoint":
            assert sp.expand(R - R.T) == sp.zeros(4, 4)
            assert sp.expand(R + (V1 - V) * U / 2 + U * (V1 - V) / 2) == sp.zeros(4, 4)
        else:
            for i, j in ((1, 2), (2, 0), (0, 1), (0, 3), (1, 3), (2, 3)):
                assert R[i, j] == 0
