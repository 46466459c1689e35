"""Special cases of Sections IV-V: static rod, heavy top, body in fluid, Kirchhoff rod, planar rod, space curve."""
import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dnarod.core.errors import DnarodError
from dnarod.physics.lax import U_matrix, component_rhs, smk_rhs
from dnarod.physics.lax.cases import (HeavyTop, arclength, KirchhoffBody, KirchhoffRod, StaticRod, curvature_torsion,
                              frenet_step_matrix, planar_embed, planar_rhs, printed_tetrad_step_matrix,
                              tetrad_step_matrix)
from dnarod.core.rotations import check_frames
from dnarod.core.strains import chain_from_strains, strains

RNG = np.random.default_rng(2024)


def spd(n, seed, diag=2.0):
    r = np.random.default_rng(seed).normal(size=(n, n))
    return r @ r.T / n + diag * np.eye(n)


def rel_spread(x):
    x = np.asarray(x)
    return np.abs(x - x[0]).max() / np.abs(x[0])


# ------------------------------------------------------------------------------------------- Case 1: static rod

@pytest.mark.parametrize("reading", ["R1", "midpoint"])
def test_static_rod_map_solves_the_static_smk_equations(reading):
    K = spd(6, 1)
    K[:3, 3:] += 0.3 * np.random.default_rng(1).normal(size=(3, 3))   # non-symmetric B
    K[3:, :3] = K[:3, 3:].T
    xi0 = np.array([0.1, -0.2, 1.8, 0.05, 0.0, 1.0])
    ds = 0.1
    rod = StaticRod(K, xi0, ds=ds, reading=reading)
    Om, Ga, M, P = rod.shoot([0.3, 0.1, 1.7], [0.02, -0.03, 1.01], 30)
    assert np.abs(Om).max() < 10                                     # a tame stretch of rod
    z = np.zeros_like(Om)
    # static (3.13c,d): with zero velocities and momenta, d/dt p and d/dt m vanish (open chain, last row unused)
    _, _, dp, dm = smk_rhs(Ga, Om, z, z, z, z, P, M, ds, reading=reading, periodic=False)
    assert np.abs(dp[:-1]).max() < 1e-12 * np.abs(P).max() / ds
    assert np.abs(dm[:-1]).max() < 1e-12 * np.abs(M).max() / ds
    # constitutive law (4.3c,d) with B^T, misprint 13
    A, B, C = K[:3, :3], K[:3, 3:], K[3:, 3:]
    dO, dG = Om - xi0[:3], Ga - xi0[3:]
    assert np.allclose(M, dO @ A.T + dG @ B.T) and np.allclose(P, dO @ B + dG @ C.T)


def _static_continuum(K, xi0, y0, s_end):
    """Reference: continuum static rod M' = M x Omega + P x Gamma, P' = P x Omega (independent code)."""
    Kinv = np.linalg.inv(K)

    def f(s, y):
        xi = Kinv @ y + xi0
        return np.concatenate([np.cross(y[:3], xi[:3]) + np.cross(y[3:], xi[3:]), np.cross(y[3:], xi[:3])])
    return solve_ivp(f, (0, s_end), y0, method="DOP853", rtol=1e-12, atol=1e-13).y[:, -1]


def test_static_rod_converges_to_continuum_and_midpoint_keeps_casimirs():
    K = spd(6, 2)
    xi0 = np.array([0.4, 0.0, 1.5, 0.0, 0.0, 1.0])
    Om0, Ga0 = np.array([0.7, -0.2, 1.4]), np.array([0.05, 0.02, 1.03])
    L = 3.0
    rod = StaticRod(K, xi0, 0.1)
    M0, P0 = rod.stresses(Om0, Ga0)
    ref = _static_continuum(K, xi0, np.concatenate([M0, P0]), L)
    orders = {}
    for reading in ("R1", "midpoint"):
        err = []
        for n in (60, 120):
            Om, Ga, M, P = StaticRod(K, xi0, L / n, reading).shoot(Om0, Ga0, n)
            err.append(np.abs(np.concatenate([M[-1], P[-1]]) - ref).max())
        orders[reading] = np.log2(err[0] / err[1])
    # both readings evaluate the U-fields at node k, so both are first order (measured 1.09 and 1.00)
    assert 0.85 < orders["R1"] < 1.2 and 0.85 < orders["midpoint"] < 1.2, orders
    # exact discrete Casimirs of the midpoint map over many steps; R1 drifts
    Om, Ga, M, P = StaticRod(K, xi0, 0.05, "midpoint").shoot(Om0, Ga0, 4000)
    cas = StaticRod.casimirs(M, P)
    assert rel_spread(cas[:, 0]) < 1e-12
    assert np.abs(cas[:, 1] - cas[0, 1]).max() < 1e-12 * np.abs(M).max() * np.abs(P).max()
    Om, Ga, M, P = StaticRod(K, xi0, 0.05, "R1").shoot(Om0, Ga0, 400)
    assert rel_spread(StaticRod.casimirs(M, P)[:, 0]) > 1e-6


# ------------------------------------------------------------------------------------------- Subcase 1.2: heavy top

def test_heavy_top_generic_energy_and_casimirs():
    top = HeavyTop(spd(3, 5), chi=(0.1, -0.2, 0.9), Omega0=(0.2, 0.0, -0.1))
    s, y = top.integrate(RNG.normal(size=6), 300.0)
    assert rel_spread(top.energy(y)) < 1e-9
    cas = top.casimirs(y)
    assert rel_spread(cas[:, 0]) < 1e-9 and rel_spread(cas[:, 1]) < 1e-9


def test_lagrange_and_kowalewski_tops_have_their_extra_integrals():
    y0 = np.array([0.7, -0.4, 1.1, 0.3, 0.8, -0.5])
    lag = HeavyTop.lagrange(1.3, 0.7, c=0.9)
    s, y = lag.integrate(y0, 300.0)
    assert rel_spread(lag.lagrange_integral(y)) < 1e-9 and rel_spread(lag.energy(y)) < 1e-9
    kow = HeavyTop.kowalewski(0.8, c=1.2)
    s, y = kow.integrate(y0, 300.0)
    K = kow.kowalewski_integral(y)
    assert rel_spread(K) < 1e-9 and rel_spread(kow.energy(y)) < 1e-9
    assert np.ptp(y[:, 2]) > 0.1            # M3 is not conserved here: the integral is not trivial
    # a non-Kowalewski ratio breaks the integral (shows the check can fail)
    other = HeavyTop(np.diag([1.6, 0.8, 1.5]), chi=(0, 0, 1.2))
    s, y = other.integrate(y0, 100.0)
    Om = y[:, :3] @ np.linalg.inv(other.A).T
    z = np.abs((Om[:, 2] + 1j * Om[:, 0]) ** 2 - (1.2 / 0.8) * (y[:, 5] + 1j * y[:, 3])) ** 2
    assert rel_spread(z) > 1e-2
    with pytest.raises(DnarodError, match="kowalewski"):
        lag.kowalewski_integral(y0)


def test_discrete_top_converges_to_continuous_top():
    top = HeavyTop(np.diag([1.0, 1.4, 0.8]))
    y0 = np.array([0.5, 0.2, -0.3, 0.1, 0.4, 0.9])
    ref = top.integrate(y0, 2.0, n_out=2)[1][-1]
    for reading, order in (("R1", 1), ("midpoint", 1)):
        err = []
        for n in (100, 200):
            M, P = y0[:3], y0[3:]
            for _ in range(n):
                M, P = top.discrete_step(M, P, 2.0 / n, reading)
            err.append(np.abs(np.concatenate([M, P]) - ref).max())
        assert abs(np.log2(err[0] / err[1]) - order) < 0.2, (reading, err)


# ------------------------------------------------------------------------------------------- Case 2: body in fluid

@pytest.mark.parametrize("lam", [0.0, 0.9])
def test_kirchhoff_body_invariants_and_lax_traces(lam):
    body = KirchhoffBody(spd(6, 7, diag=1.0), lam=lam)
    t, y = body.integrate(RNG.normal(size=6), 200.0)
    assert rel_spread(body.energy(y)) < 1e-9
    cas = body.casimirs(y)
    assert rel_spread(cas[:, 0]) < 1e-9 and np.abs(cas[:, 1] - cas[0, 1]).max() < 1e-9 * np.abs(y).max() ** 2
    if lam:
        # the Lax matrix U = -i lam (p.J + lam^2 m.K): tr U^2 and tr U^4 are conserved (exact Lax dU/dt = [V, U])
        z = np.zeros((len(y), 3))
        U = U_matrix(z, z, y[:, :3], y[:, 3:], lam)
        tr2 = np.einsum("kii->k", U @ U).real
        tr4 = np.einsum("kii->k", U @ U @ U @ U).real
        assert rel_spread(tr2) < 1e-9 and rel_spread(tr4) < 1e-9
        p, m = y[0, :3], y[0, 3:]
        assert np.isclose(tr2[0], 2 * lam ** 2 * (p @ p + lam ** 4 * m @ m))
        assert np.isclose(tr4[0] - tr2[0] ** 2 / 4,
                          lam ** 4 * np.sum((p + lam ** 2 * m) ** 2) * np.sum((p - lam ** 2 * m) ** 2))


def test_kirchhoff_body_is_3_9_without_k_dependence():
    body = KirchhoffBody(spd(6, 8, diag=1.0), lam=0.7)
    y = RNG.normal(size=6)
    gamma, omega = body.velocities(y)
    z = np.zeros((1, 3))
    for reading in ("R1", "midpoint"):
        dG, dO, dp, dm = component_rhs(z, z, y[None, :3], y[None, 3:], gamma[None], omega[None], z, z, 0.7, 0.1,
                                       reading=reading)
        assert np.allclose(dG, 0) and np.allclose(dO, 0)
        assert np.allclose(np.concatenate([dp[0], dm[0]]), body.rhs(0, y), atol=1e-14)


# ------------------------------------------------------------------------------------------- Case 3: Kirchhoff rod

def _ring(n, ds):
    s = np.arange(n) * ds
    ph = 2 * np.pi * s / (n * ds)
    return np.stack([0.8 + 0.3 * np.cos(ph), 0.5 * np.sin(ph), 1.5 + 0.2 * np.cos(2 * ph)], 1)


@pytest.mark.parametrize("reading,periodic", [("R1", True), ("R1", False), ("midpoint", False)])
def test_kirchhoff_rod_keeps_the_inextensibility_constraint(reading, periodic):
    n, ds = 8, 0.34
    rod = KirchhoffRod(A=[1.0, 1.2, 0.8], inertia=[0.3, 0.3, 0.5], rho=1.0, ds=ds, Omega0=(0.1, 0, 1.0),
                       reading=reading, periodic=periodic)
    Omega, m = _ring(n, ds), 0.05 * RNG.normal(size=(n, 3))
    p = rod.consistent_momenta(Omega, m)
    y0 = rod.join(Omega, m, p)
    gamma = p / rod.rho
    scale = np.abs(gamma).max() / ds
    assert np.abs(rod.constraint(y0)).max() < 1e-12 * scale
    # the multiplier makes the constraint rate vanish: central difference along the flow (c is bilinear -> exact)
    f = rod.rhs(0.0, y0)
    h = 1e-3
    cdot = (rod.constraint(y0 + h * f) - rod.constraint(y0 - h * f)) / (2 * h)
    assert np.abs(cdot).max() < 1e-9 * np.abs(f).max() / ds
    # the evolution is smk_rhs with that P (and Gamma = chi stays fixed)
    P = rod.multiplier(y0)
    G, O, pp, mm, g, w, _, M = rod.fields(y0)
    _, dO, dp, dm = smk_rhs(G, O, pp, mm, g, w, P, M, ds, reading=reading, periodic=periodic)
    assert np.allclose(f, np.concatenate([dO.ravel(), dm.ravel(), dp.ravel()]))
    # integrate (short: the paper's forward-forward pairing is unstable, design C4)
    t, Y = rod.integrate(y0, 0.2, n_out=11)
    assert np.abs(Y[-1] - y0).max() > 1e-3
    worst = max(np.abs(rod.constraint(yy)).max() / (np.abs(rod.split(yy)[2]).max() / ds) for yy in Y)
    assert worst < 1e-9


def test_kirchhoff_rod_bad_input():
    with pytest.raises(DnarodError, match="inertia"):
        KirchhoffRod(A=[1, 1, 1], inertia=[1, -1, 1], rho=1.0, ds=0.3)
    with pytest.raises(DnarodError, match="rho"):
        KirchhoffRod(A=[1, 1, 1], inertia=[1, 1, 1], rho=0.0, ds=0.3)
    rod = KirchhoffRod(A=[1, 1, 1], inertia=[1, 1, 1], rho=1.0, ds=0.3)
    with pytest.raises(DnarodError, match="y"):
        rod.rhs(0.0, np.zeros(10))


# ------------------------------------------------------------------------------------------- Case 4: planar rod

@pytest.mark.parametrize("reading", ["R1", "midpoint"])
def test_planar_rod_is_3_13_restricted(reading):
    u, v = RNG.normal(size=(6, 6)), RNG.normal(size=(6, 6))
    full = smk_rhs(*planar_embed(u, v), 0.3, reading=reading)
    dG, dO, dp, dm = full
    # the six discarded components vanish identically
    for x in (dO[:, 0], dO[:, 1], dm[:, 0], dm[:, 1], dG[:, 2], dp[:, 2]):
        assert np.abs(x).max() < 1e-14
    want = np.stack([dO[:, 2], dG[:, 0], dG[:, 1], dm[:, 2], dp[:, 0], dp[:, 1]], 1)
    assert np.allclose(planar_rhs(u, v, 0.3, reading=reading), want, atol=1e-13)


def test_printed_7_1f_differs_at_order_ds():
    errs = []
    for n in (50, 100, 200):
        ds = 2.0 / n
        s = np.arange(n) * ds
        ph = np.pi * s
        u = np.stack([np.cos(ph + a) for a in range(6)], 1)
        v = np.stack([np.sin(ph + 0.5 * a) for a in range(6)], 1)
        d = planar_rhs(u, v, ds) - planar_rhs(u, v, ds, reading="printed")
        assert np.abs(d[:, :5]).max() == 0
        errs.append(np.abs(d[:, 5]).max())
    assert errs[0] > 1e-3
    assert np.allclose(np.log2(np.array(errs[:-1]) / errs[1:]), 1.0, atol=0.1)


# ------------------------------------------------------------------------------------------- Case 5: space curve

def _helix_frames(kappa, tau, h, n):
    """Right-handed frames (d1, d2, d3) = (-b, n, t) of the helix with curvature kappa, torsion tau."""
    c2 = 1.0 / (kappa ** 2 + tau ** 2)
    a, b = kappa * c2, tau * c2
    c = np.sqrt(a * a + b * b)
    sig = np.arange(n) * h
    phi = sig / c
    r = np.stack([a * np.cos(phi), a * np.sin(phi), b * phi], 1)
    t = np.stack([-a * np.sin(phi), a * np.cos(phi), np.full_like(phi, b)], 1) / c
    nn = np.stack([-np.cos(phi), -np.sin(phi), np.zeros_like(phi)], 1)
    bb = np.cross(t, nn)
    return r, np.stack([-bb, nn, t], axis=2)


def test_curvature_and_torsion_signs_on_a_helix():
    kappa, tau = 8 / 17, 2 / 17
    errs = []
    for h in (0.2, 0.1):
        r, F = _helix_frames(kappa, tau, h, 12)
        check_frames(F)
        assert np.all(np.linalg.det(F) > 0)
        Om, Ga = strains(r, F, h)
        assert np.abs(Om[:, 1]).max() < 1e-12
        k, t = curvature_torsion(Om, Ga)
        assert np.all(k > 0) and np.all(t > 0)                 # the printed (8.2b) gives the wrong signs
        errs.append(max(np.abs(k - kappa).max() / kappa, np.abs(t - tau).max() / tau))
    assert errs[0] < 3e-3 and 3.5 < errs[0] / errs[1] < 4.5   # O(h^2) from the discrete strains


def test_corrected_8_1a_advances_the_tetrad_and_the_printed_one_does_not():
    n = 6
    errs = {"corrected": [], "printed": []}
    for ds in (0.04, 0.02):
        Om = np.tile([0.7, -0.5, 1.2], (n, 1))
        Ga = np.tile([0.1, 0.05, 1.0], (n, 1))
        r, F = chain_from_strains(Om, Ga, ds)
        rows = np.transpose(F, (0, 2, 1))                      # rows d_a(k)
        lam = 0.6
        for key, fn in (("corrected", tetrad_step_matrix), ("printed", printed_tetrad_step_matrix)):
            T = fn(Om, Ga, lam, ds)
            pred = np.einsum("kab,kbj->kaj", T[:, :3, :3], rows[:-1])
            errs[key].append(np.abs(pred - rows[1:]).max())
            if key == "corrected":
                # row 4 with rhat = lam^2 r is exact (2.6); with the printed rhat = lam^-2 r it is not
                rh = lam ** 2 * r
                pred4 = rh[:-1] + np.einsum("ka,kaj->kj", (T[:, 3, :3] - 0) , rows[:-1]) + 0 * rh[:-1]
                assert np.allclose(pred4, rh[1:], atol=1e-14)
                rh = r / lam ** 2
                pred4 = rh[:-1] + np.einsum("ka,kaj->kj", T[:, 3, :3], rows[:-1])
                assert np.abs(pred4 - rh[1:]).max() > 1e-3
    assert 3.5 < errs["corrected"][0] / errs["corrected"][1] < 4.5       # O(ds^2) per step
    assert 1.8 < errs["printed"][0] / errs["printed"][1] < 2.2           # O(ds): wrong at first order
    # the printed 3x3 block is not antisymmetric
    T = printed_tetrad_step_matrix(Om, Ga, 0.6, 0.1)[0, :3, :3] - np.eye(3)
    assert np.abs(T + T.T).max() > 0.05


def test_frenet_matrix_8_3a_is_the_corrected_8_1a_in_the_b_n_t_basis():
    Om = np.array([[-0.47, 0.0, 0.12], [0.3, 0.0, -0.2]])
    Ga = np.array([[0.0, 0.0, 1.3], [0.0, 0.0, 0.9]])
    lam, ds = 0.7, 0.05
    k, t = curvature_torsion(Om, Ga)
    Pm = np.diag([-1.0, 1, 1, 1])                               # (d1, d2, d3) = (-b, n, t)
    A = Pm @ tetrad_step_matrix(Om, Ga, lam, ds) @ Pm
    assert np.allclose(A, frenet_step_matrix(k, t, lam, Ga[:, 2] * ds), atol=1e-15)


def test_arclength_sums_from_zero():
    Ga = np.array([[0.1, 0.0, 1.0], [0.0, 0.2, 0.9], [0.3, 0.1, 1.2]])
    Om = np.array([[0.5, 0.1, 1.0], [0.2, -0.3, 0.8], [0.0, 0.4, 1.1]])
    r, _ = chain_from_strains(Om, Ga, 0.34)
    chords = np.linalg.norm(np.diff(r, axis=0), axis=1)
    assert np.allclose(arclength(Ga, 0.34), np.concatenate([[0], np.cumsum(chords)]), atol=1e-14)


def test_curve_bad_input():
    with pytest.raises(DnarodError, match="Gamma3"):
        curvature_torsion(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(DnarodError, match="ds_tilde"):
        frenet_step_matrix([1.0], [0.0], 0.5, -1.0)
    with pytest.raises(DnarodError, match="v"):
        planar_rhs(np.zeros((3, 6)), np.zeros((3, 5)), 0.1)
    from dnarod.physics.lax.cases import static_stress_step
    with pytest.raises(DnarodError, match="singular"):
        static_stress_step([-2.0, 1.0, 4.0], [0, 0, 1.0], np.ones(3), np.ones(3), 0.5)   # 1 + ds^3 O1O2O3 = 0
    static_stress_step([-2.0, 1.0, 4.0], [0, 0, 1.0], np.ones(3), np.ones(3), 0.5, reading="midpoint")
    with pytest.raises(DnarodError, match="Gamma"):
        static_stress_step(np.zeros(3), np.zeros(2), np.ones(3), np.ones(3), 0.5)
    with pytest.raises(DnarodError, match="intrinsic"):
        StaticRod(np.eye(6), np.zeros(5), 0.1)
    with pytest.raises(DnarodError, match="A"):
        HeavyTop(-np.eye(3))
    with pytest.raises(DnarodError, match="H"):
        KirchhoffBody(np.zeros((5, 5)))
