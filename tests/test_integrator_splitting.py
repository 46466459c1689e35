"""The symplectic splitting and BAOAB (design A4 b, A6 items 6-7), and numba == numpy."""
import warnings

import numpy as np
import pytest

from dnarod.core.errors import DnarodError, SimulationError
from dnarod.engines.lax import BoundaryConditions, SplittingIntegrator, integrate_exact, omega_max
from dnarod.physics.modes import normal_modes
from dnarod.engines.lax.splitting import RigidState, maxwell_state
from dnarod.physics.testsystems import TwistedRod, dna_like_rod


@pytest.fixture(scope="module")
def rod20():
    model = dna_like_rod(20)
    return model, maxwell_state(model, 300.0, seed=11)


def test_momentum_and_angular_momentum_conserved_to_roundoff(rod20):
    model, st = rod20
    P0, L0 = st.total_momentum()
    integ = SplittingIntegrator(model, 0.05, st)
    scaleP = np.abs(st.momenta).sum()
    scaleL = np.abs(np.cross(st.positions, st.momenta)).sum() + np.abs(st.angular_momenta).sum()
    for _ in range(10):
        integ.step(200)
        P, L = integ.state.total_momentum()
        assert np.abs(P - P0).max() < 1e-10 * scaleP
        assert np.abs(L - L0).max() < 1e-10 * scaleL
    F = integ.state.frames
    assert np.abs(np.swapaxes(F, 1, 2) @ F - np.eye(3)).max() < 1e-12


def test_second_order_convergence_to_dop853(rod20):
    model, st = rod20
    T = 2.0
    v, w = st.velocities(model.mass, model.inertia)
    ref = integrate_exact(model, T, v, w, rtol=1e-12, atol=1e-12, n_frames=2).trajectory
    errs = []
    dts = [0.1, 0.05, 0.025, 0.0125]
    for dt in dts:
        integ = SplittingIntegrator(model, dt, st, check_stability=False)
        integ.step(int(round(T / dt)))
        errs.append(np.abs(integ.state.positions - ref.positions[-1]).max()
                    + model.ds * np.abs(integ.state.frames - ref.frames[-1]).max())
    order = np.polyfit(np.log(dts), np.log(errs), 1)[0]
    print("errors", errs, "order", order)
    assert abs(order - 2.0) < 0.1, (errs, order)


def test_no_energy_drift(rod20):
    model, st = rod20
    integ = SplittingIntegrator(model, 0.05, st)
    E = [integ.total_energy()]
    for _ in range(200):
        integ.step(100)   # 1 ns in total
        E.append(integ.total_energy())
    E = np.array(E)
    kt = 2.494
    assert np.abs(E - E[0]).max() < 0.5 * kt          # bounded error, O(dt^2)
    slope = np.polyfit(np.arange(E.size) * 5.0, E, 1)[0]  # kJ/mol per ps
    print("max |E-E0|/kT", np.abs(E - E[0]).max() / kt, "drift kT/ns", slope * 1000 / kt)
    assert abs(slope) * 1000.0 / kt < 0.05               # < 0.05 kT/ns


def test_stability_threshold_twisted_rod():
    tr = TwistedRod.from_forcefield("dna-default", 16)
    model = tr.model()
    w_an = tr.omega_max()
    assert abs(omega_max(model) - w_an) < 1e-6
    dt_crit = 2.0 / w_an
    rng = np.random.default_rng(0)
    st = RigidState.from_model(model, 1e-4 * rng.standard_normal((16, 3)), 1e-4 * rng.standard_normal((16, 3)))
    stable = SplittingIntegrator(model, 0.97 * dt_crit, st)
    E0 = stable.total_energy()
    stable.step(3000)
    assert abs(stable.total_energy() - E0) < 10 * E0
    with pytest.raises(SimulationError, match="stability limit"):
        SplittingIntegrator(model, 1.03 * dt_crit, st)
    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        unstable = SplittingIntegrator(model, 1.03 * dt_crit, st, allow_unstable=True)
    assert any("stability limit" in str(r.message) for r in rec)
    with pytest.raises(SimulationError) as exc:
        unstable.step(3000)
    assert exc.value.step is not None and exc.value.step < 3000 and exc.value.node is not None


def test_stability_threshold_dna_like_rod(rod20):
    """The free 20-node DNA-like rod: stable at 0.97 dt_crit, blows up at 1.03 dt_crit."""
    model, _ = rod20
    w = omega_max(model)
    wm, _ = normal_modes(model)
    assert abs(w - wm[-1]) < 1e-6
    rng = np.random.default_rng(1)
    st = RigidState.from_model(model, 1e-3 * rng.standard_normal((20, 3)))
    a = SplittingIntegrator(model, 0.97 * 2 / w, st)
    a.step(3000)
    assert a.kinetic_energy() < 1.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        b = SplittingIntegrator(model, 1.03 * 2 / w, st, allow_unstable=True)
    with pytest.raises(SimulationError):
        b.step(3000)


@pytest.mark.parametrize("branch", ["stretch", "twist"])
def test_single_mode_frequency_is_leapfrog_frequency(branch):
    """A single normal mode oscillates at (2/dt) asin(omega dt/2) (design A6 item 7)."""
    tr = TwistedRod(16)
    model = tr.model()
    d = tr.dispersion()
    j = 5
    w = d[branch][j]
    q = d["q_axial"][j]
    s = np.arange(16) * model.ds
    dt = 0.2
    amp = 1e-6
    v = np.zeros((16, 3))
    om = np.zeros((16, 3))
    shape = np.cos(q * s)
    if branch == "stretch":
        pos = model.positions.copy()
        pos[:, 2] += amp * shape
        st = RigidState(pos, model.frames.copy(), np.zeros((16, 3)), np.zeros((16, 3)))
        coord = lambda state: (state.positions[:, 2] - model.positions[:, 2] - (state.positions[:, 2] - model.positions[:, 2]).mean()) @ shape
    else:
        from dnarod.core.rotations import rotation_about_axis
        R = rotation_about_axis(np.tile([0, 0, 1.0], (16, 1)), amp * shape)
        st = RigidState(model.positions.copy(), R @ model.frames, v, om)
        ref = model.frames
        # rotation angle of each frame about the rod axis, relative to the intrinsic frames
        coord = lambda state: np.arctan2(np.einsum("ki,ki->k", state.frames[:, :, 0], ref[:, :, 1]),
                                         np.einsum("ki,ki->k", state.frames[:, :, 0], ref[:, :, 0])) @ shape
    integ = SplittingIntegrator(model, dt, st)
    x = [coord(integ.state)]
    for _ in range(400):
        integ.step(1)
        x.append(coord(integ.state))
    x = np.array(x)
    # the exact leapfrog recurrence x_{n+1} + x_{n-1} = 2 cos(theta) x_n
    c = np.sum(x[1:-1] * (x[2:] + x[:-2])) / (2 * np.sum(x[1:-1] ** 2))
    w_obs = np.arccos(c) / dt
    w_leap = 2.0 / dt * np.arcsin(w * dt / 2)
    print(branch, w, w_obs, w_leap, abs(w_obs - w_leap) / w_leap)
    assert abs(w_obs - w_leap) / w_leap < 1e-8
    assert abs(w_leap - w) / w > 1e-4   # the test resolves the leapfrog shift


CASES = ["open", "open_2blocks_plus1", "circular", "langevin", "clamped_loads", "sequence"]


@pytest.mark.parametrize("kernel", ["blocked", "scalar"])
@pytest.mark.parametrize("case", CASES)
def test_numba_equals_numpy_reference(case, kernel):
    from dnarod.core.forcefield import load_forcefield
    from dnarod.engines.lax.fast_blocked import BLOCK

    # chains that cross block boundaries: 1.5 blocks, and 2 blocks + 1 node
    n = 2 * BLOCK + 1 if case == "open_2blocks_plus1" else BLOCK + BLOCK // 2
    if case == "sequence":                # sequence-dependent parameters (many step types)
        model = load_forcefield("olson1998").model_from_sequence(("ACGTTGCAAGCTTACGGATCCATG" * 8)[:n])
    else:
        model = load_forcefield("dna-default").model_from_sequence(n_nodes=n, circular=(case == "circular"))
    kw, bc = {}, None
    if case == "langevin":
        kw = dict(temperature=300.0, friction=2.0, seed=5)
    if case == "clamped_loads":
        bc = BoundaryConditions(clamped=(0,), forces={n - 1: [1.0, -2.0, 30.0]}, torques={n - 1: [0.5, 0, 3.0]})
    st = maxwell_state(model, 300.0, seed=2, boundary=bc)
    rng = np.random.default_rng(3)
    st.positions[1:] += 0.02 * rng.standard_normal((n - 1, 3))   # a strained pose: real forces
    a = SplittingIntegrator(model, 0.05, st, boundary=bc, fast=False, **kw)
    b = SplittingIntegrator(model, 0.05, st, boundary=bc, fast=kernel, **kw)
    assert abs(a.potential_energy - b.potential_energy) <= 1e-12 * abs(a.potential_energy)
    assert np.abs(a.F - b.F).max() <= 1e-12 * np.abs(a.F).max()
    a.step(50)
    b.step(50)
    for name in ("positions", "frames", "momenta", "angular_momenta"):
        x, y = getattr(a.state, name), getattr(b.state, name)
        assert np.abs(x - y).max() <= 1e-12 * np.abs(x).max(), name
    assert abs(a.total_energy() - b.total_energy()) <= 1e-12 * abs(a.total_energy())


@pytest.mark.parametrize("spin", [[600.0, -300.0, 800.0], [4e3, -2e3, 6e3]], ids=["doubling", "libm"])
def test_blocked_kernel_large_rotor_angles(spin):
    """Rotor angles beyond the short polynomial (bound 0.25 rad: doubled polynomial) and beyond
    3.2 rad (libm fallback) give the numpy reference's result."""
    model = dna_like_rod(20)
    st = RigidState.from_model(model)
    st.angular_momenta[5] = spin     # angle bound 0.1 |pi| / 117: 0.9 and 6.4 rad
    a = SplittingIntegrator(model, 0.1, st, fast=False, check_stability=False)
    b = SplittingIntegrator(model, 0.1, st, fast=True, check_stability=False)
    a.step(2)
    b.step(2)
    assert np.abs(a.state.frames - b.state.frames).max() < 1e-12
    assert np.abs(a.state.angular_momenta - b.state.angular_momenta).max() < 1e-12 * np.abs(spin).max()


def test_langevin_kinetic_temperature():
    """BAOAB thermostat: mean kinetic energy (3 kT per node) within 5% (fast statistical check)."""
    model = dna_like_rod(20, seed=3)
    integ = SplittingIntegrator(model, 0.05, maxwell_state(model, 300.0, seed=1), temperature=300.0, friction=2.0, seed=9)
    integ.step(1000)
    ke = []
    for _ in range(400):
        integ.step(25)
        ke.append(integ.kinetic_energy())
    expected = 3 * 20 * 0.00831446261815324 * 300.0
    assert abs(np.mean(ke) / expected - 1) < 0.05


def test_nan_mid_run_names_step_and_node(rod20):
    model, st = rod20
    integ = SplittingIntegrator(model, 0.05, st)
    integ.step(10)
    integ.state.momenta[7, 1] = np.nan
    with pytest.raises(SimulationError) as exc:
        integ.step(10)
    assert exc.value.step == 11
    assert exc.value.node in (6, 7)
    assert "step 11" in str(exc.value) and f"base pair {exc.value.node + 1}" in str(exc.value)


def test_bad_parameters():
    model = dna_like_rod(6)
    with pytest.raises(DnarodError, match="positive"):
        SplittingIntegrator(model, -0.1)
    with pytest.raises(DnarodError, match="both temperature"):
        SplittingIntegrator(model, 0.05, temperature=300.0)
    st = RigidState.from_model(model)
    st.angular_momenta[5, 2] = 1.0
    with pytest.raises(DnarodError, match="node 5 is clamped"):
        SplittingIntegrator(model, 0.05, st, boundary=BoundaryConditions(clamped=(-1,)))
    with pytest.raises(DnarodError, match="fast must be"):
        SplittingIntegrator(model, 0.05, fast="gpu")


def test_langevin_tangent_correlation_matches_exact_thermal_answer():
    """BAOAB samples the Haar-measure equilibrium: <d3(k).d3(k+n)> equals the exact A5 iii quadrature
    (fast version: 8-node chain, 500 ps; tolerance ~5 standard errors)."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.physics.testsystems import thermal_tangent_correlation

    model = load_forcefield("dna-default").model_from_sequence(n_nodes=8)
    integ = SplittingIntegrator(model, 0.05, maxwell_state(model, 300.0, seed=1), temperature=300.0, friction=1.0,
                                seed=2)
    integ.step(4000)
    samples = []
    for _ in range(10000):
        integ.step(10)
        d3 = integ.state.frames[:, :, 2]
        samples.append([np.mean(np.einsum("ki,ki->k", d3[:-n], d3[n:])) for n in (1, 2)])
    obs = np.mean(samples, axis=0)
    exact = np.asarray(thermal_tangent_correlation(model.params[:1], model.ds, 300.0, 2))[1:3]
    ratio = (1 - obs) / (1 - exact)
    print("(1 - <d3.d3>) observed / exact:", ratio)
    assert np.all(np.abs(ratio - 1) < 0.03)


def test_kernel_sine_cosine_polynomials_match_libm():
    """The rotor's polynomial sin/cos equal numpy's to a few ulp over their whole ranges."""
    from dnarod.engines.lax.fast import _sincos
    from dnarod.engines.lax.fast_blocked import ROTOR_ANGLE_MAX, _sincos_poly, _sincos_short

    for fn, lim in ((_sincos_short, 0.25), (_sincos_poly, ROTOR_ANGLE_MAX), (_sincos, 5.0)):
        x = np.linspace(-lim, lim, 20001)
        s, c = np.array([fn(v) for v in x]).T
        assert np.abs(s - np.sin(x)).max() < 1e-15 and np.abs(c - np.cos(x)).max() < 1e-15, fn  # a few ulp
