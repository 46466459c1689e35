"""The exact strain-space (Lax-form) system: kinematics, balance laws, DOP853 runs (design A3, A6 items 4-5)."""
import numpy as np
import pytest
from scipy.linalg import expm

from dnarod.core.energy import loads
from dnarod.core.errors import DnarodError
from dnarod.core.forcefield import load_forcefield
from dnarod.engines.lax import BoundaryConditions, integrate_exact
from dnarod.engines.lax.exact import body_loads, lax_matrices, strain_rates
from dnarod.core.rotations import hat, rotation_about_axis
from dnarod.core.strains import strains
from dnarod.physics.testsystems import dna_like_rod


def _perturbed_model(circular, seed=0, n=12):
    ff = load_forcefield("dna-default")
    m = ff.model_from_sequence(n_nodes=n, circular=circular)
    rng = np.random.default_rng(seed)
    ax = rng.standard_normal((n, 3))
    ax /= np.linalg.norm(ax, axis=1)[:, None]
    frm = rotation_about_axis(ax, 0.3 * rng.standard_normal(n)) @ m.frames
    return m.with_pose(m.positions + 0.05 * rng.standard_normal((n, 3)), frm), rng


def _motion(model, rng):
    """A prescribed smooth motion: L_k(t) = L_k exp(t hat(w_k) + t^2 hat(a_k)), r_k(t) = r_k + t v_k + t^2 c_k."""
    n = model.n_nodes
    w, a, v, c = (rng.standard_normal((4, n, 3)) * np.array([0.7, 0.3, 0.5, 0.2])[:, None, None])

    def pose(t):
        L = np.array([model.frames[k] @ expm(t * hat(w[k]) + t * t * hat(a[k])) for k in range(n)])
        return model.positions + t * v + t * t * c, L

    return pose, w, np.einsum("kji,kj->ki", model.frames, v)


def _d_dt(f, h=1e-3):
    """Fourth-order central difference at t = 0."""
    return (-f(2 * h) + 8 * f(h) - 8 * f(-h) + f(-2 * h)) / (12 * h)


@pytest.mark.parametrize("circular", [False, True])
def test_strain_rates_match_finite_differences(circular):
    model, rng = _perturbed_model(circular)
    pose, omega, gamma = _motion(model, rng)
    ds = model.ds
    dOm_fd = _d_dt(lambda t: strains(*pose(t), ds, model.closure)[0])
    dGa_fd = _d_dt(lambda t: strains(*pose(t), ds, model.closure)[1])
    Om, Ga = model.strains()
    dOm, dGa = strain_rates(Om, Ga, omega, gamma, ds, circular)
    assert np.abs(dOm - dOm_fd).max() / np.abs(dOm_fd).max() < 1e-8
    assert np.abs(dGa - dGa_fd).max() / np.abs(dGa_fd).max() < 1e-8


@pytest.mark.parametrize("circular", [False, True])
def test_lax_identity_column_and_row_conventions(circular):
    model, rng = _perturbed_model(circular, seed=3)
    pose, omega, gamma = _motion(model, rng)
    zero = np.zeros_like(omega)

    def U_of(t):
        return lax_matrices(*pose(t), zero, zero, model.closure)[0]

    U, V = lax_matrices(model.positions, model.frames, gamma, omega, model.closure)
    Vn = np.roll(V, -1, axis=0)[: U.shape[0]]
    Vk = V[: U.shape[0]]
    dU = _d_dt(U_of)
    # column / body convention: dU_k/dt = U_k V_{k+1} - V_k U_k
    assert np.abs(dU - (U @ Vn - Vk @ U)).max() < 1e-9 * np.abs(dU).max()
    # the paper's row convention Phi(k) = g_k^-1: U^p = U^-1, V^p = -V, dU^p/dt = V^p_{k+1} U^p - U^p V^p_k
    Up_dot = _d_dt(lambda t: np.linalg.inv(U_of(t)))
    Up, Vpn, Vpk = np.linalg.inv(U), -Vn, -Vk
    assert np.abs(Up_dot - (Vpn @ Up - Up @ Vpk)).max() < 1e-9 * np.abs(Up_dot).max()
    # and Phi = g^-1 obeys d Phi/dt = V^p Phi
    Phi_dot = _d_dt(lambda t: np.linalg.inv(_g(*pose(t))))
    assert np.abs(Phi_dot - (-V) @ np.linalg.inv(_g(model.positions,
                                                    model.frames))).max() < 1e-9 * np.abs(Phi_dot).max()


def _g(positions, frames):
    g = np.zeros((positions.shape[0], 4, 4))
    g[:, :3, :3], g[:, :3, 3], g[:, 3, 3] = frames, positions, 1.0
    return g


@pytest.mark.parametrize("circular", [False, True])
def test_body_loads_equal_lab_loads(circular):
    model, _ = _perturbed_model(circular, seed=5)
    E, F, tau = loads(model.positions, model.frames, model.params, model.ds, model.closure)
    Om, Ga = model.strains()
    f, t, E2 = body_loads(Om, Ga, model.params, model.ds, model.n_nodes, circular)
    assert abs(E - E2) < 1e-12 * E
    assert np.allclose(f, np.einsum("kji,kj->ki", model.frames, F), rtol=0, atol=1e-12 * np.abs(F).max())
    assert np.allclose(t, np.einsum("kji,kj->ki", model.frames, tau), rtol=0, atol=1e-12 * np.abs(tau).max())


def _thermal(model, seed=1):
    from dnarod.engines.lax.splitting import maxwell_state

    st = maxwell_state(model, 300.0, seed)
    return st.velocities(model.mass, model.inertia)


def test_dop853_energy_momentum_conservation_short():
    """Momentum, angular momentum and frame orthogonality of the DOP853 run (10 ps)."""
    model = dna_like_rod(20)
    v, w = _thermal(model)
    res = integrate_exact(model, 10.0, v, w, rtol=1e-10, atol=1e-10, n_frames=11)
    E = res.energy
    assert np.abs(E - E[0]).max() / E[0] < 1e-7
    assert np.abs(res.momentum - res.momentum[0]).max() < 1e-9 * np.abs(model.mass).sum()
    assert np.abs(res.angular_momentum - res.angular_momentum[0]).max() < 1e-8 * model.mass.sum()
    # poses stay proper rotations and the trajectory has the velocities of the shared format
    assert np.abs(np.swapaxes(res.trajectory.frames, -1, -2) @ res.trajectory.frames - np.eye(3)).max() < 1e-9
    assert res.trajectory.velocities.shape == (11, 20, 3)


def test_dop853_energy_error_100ps():
    """A6 item 5 as specified: rtol = atol = 1e-10, 100 ps, relative energy error < 1e-7 (~5 s)."""
    model = dna_like_rod(20)
    v, w = _thermal(model)
    res = integrate_exact(model, 100.0, v, w, rtol=1e-10, atol=1e-10, n_frames=21)
    assert np.abs(res.energy - res.energy[0]).max() / res.energy[0] < 1e-7


def test_exact_reproduces_node_dynamics_of_splitting_at_small_dt():
    """Strain space (exact) and particle space (splitting, dt -> 0) give the same motion."""
    from dnarod.engines.lax import SplittingIntegrator
    from dnarod.engines.lax.splitting import RigidState

    model = dna_like_rod(10, seed=2)
    v, w = _thermal(model, 4)
    res = integrate_exact(model, 1.0, v, w, n_frames=2)
    integ = SplittingIntegrator(model, 0.0025, RigidState.from_model(model, v, w), check_stability=False)
    integ.step(400)
    # second-order splitting at omega dt ~ 0.01: positions agree to ~1e-6 nm
    assert np.abs(integ.state.positions - res.trajectory.positions[-1]).max() < 2e-5
    assert np.abs(integ.state.frames - res.trajectory.frames[-1]).max() < 2e-5


def test_clamped_end_and_end_force():
    model = dna_like_rod(12, seed=1)
    n = model.n_nodes
    bc = BoundaryConditions(clamped=(0,), forces={n - 1: [5.0, 0.0, 20.0]})
    res = integrate_exact(model, 5.0, boundary=bc, n_frames=6)
    tr = res.trajectory
    assert np.abs(tr.positions[:, 0] - model.positions[0]).max() < 1e-12
    assert np.abs(tr.frames[:, 0] - model.frames[0]).max() < 1e-12
    assert np.abs(tr.positions[-1, -1] - model.positions[-1]).max() > 1e-3   # the force moved the free end
    # energy includes the work potential of the dead load and is conserved
    assert np.abs(res.energy - res.energy[0]).max() < 1e-7 * max(1.0, np.abs(res.energy).max())
    # both ends clamped: the interior still moves, the ends do not
    bc2 = BoundaryConditions(clamped=(0, -1))
    v = np.zeros((n, 3))
    v[1:-1] = 0.3
    res2 = integrate_exact(model, 2.0, velocities=v, boundary=bc2, n_frames=3)
    assert np.abs(res2.trajectory.positions[:, -1] - model.positions[-1]).max() < 1e-9
    assert np.abs(res2.trajectory.frames[:, -1] - model.frames[-1]).max() < 1e-9


def test_exact_and_splitting_agree_with_clamp_and_end_loads():
    from dnarod.engines.lax import SplittingIntegrator

    model = dna_like_rod(8, seed=7)
    bc = BoundaryConditions(clamped=(0,), forces={7: [0.0, 3.0, 10.0]}, torques={7: [0.0, 0.0, 4.0]})
    res = integrate_exact(model, 1.0, boundary=bc, n_frames=2)
    integ = SplittingIntegrator(model, 0.002, boundary=bc, check_stability=False)
    integ.step(500)
    assert np.abs(integ.state.positions - res.trajectory.positions[-1]).max() < 1e-5
    assert np.abs(integ.state.positions[-1] - model.positions[-1]).max() > 1e-3


@pytest.mark.parametrize("bc, circular, match", [
    (BoundaryConditions(clamped=(0,)), True, "circular chain has no ends"),
    (BoundaryConditions(clamped=(3,)), False, "only the ends"),
    (BoundaryConditions(clamped=(0,), forces={0: [1, 0, 0]}), False, "absorbed by the clamp"),
    (BoundaryConditions(forces={40: [1, 0, 0]}), False, "does not exist"),
    (BoundaryConditions(torques={1: [np.nan, 0, 0]}), False, "3 finite numbers"),
])
def test_inconsistent_boundary_conditions(bc, circular, match):
    ff = load_forcefield("dna-default")
    model = ff.model_from_sequence(n_nodes=10, circular=circular)
    with pytest.raises(DnarodError, match=match):
        integrate_exact(model, 1.0, boundary=bc)


def test_clamped_node_with_velocity_is_rejected():
    model = dna_like_rod(6)
    v = np.zeros((6, 3))
    v[0, 0] = 1.0
    with pytest.raises(DnarodError, match="node 0 is clamped"):
        integrate_exact(model, 1.0, velocities=v, boundary=BoundaryConditions(clamped=(0,)))
