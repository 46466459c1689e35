"""Static solver: the cantilever solved by both engines, zero gradient by finite differences of the energy,
small-load linear response, traps and rotation clamps, misuse."""
import numpy as np
import pytest

from dnarod.core.energy import energy as elastic_energy
from dnarod.core.errors import DnarodError
from dnarod.core.forcefield import load_forcefield
from dnarod.physics.loads import Clamp, PullingForce, RotationClamp, Torque, Trap, resolve_loads
from dnarod.core.rotations import rotation_about_axis
from dnarod.engines.openmm.simulation import static_load_fn
from dnarod.physics.statics import solve_static


@pytest.fixture(scope="module")
def cantilever():
    m = load_forcefield("dna-default").model_from_sequence("GCGAATTCGCGA")
    return m, (Clamp(0), PullingForce(-1, [3.0, 1.0, 2.0]), Torque(-1, [0.0, 0.5, 2.0]))


def test_cantilever_both_engines_agree(cantilever):
    m, loads = cantilever
    ml, il = solve_static(m, loads)
    mo, io = solve_static(m, loads, load_fn=static_load_fn(m, loads))
    assert il["converged"] and io["converged"]
    assert il["relative_gradient"] <= 1e-8 and io["relative_gradient"] <= 1e-8
    disp = np.abs(ml.positions - m.positions).max()
    assert disp > 0.1   # a real deflection (nm)
    # measured: 1.5e-15 relative
    assert np.abs(ml.positions - mo.positions).max() < 1e-8 * disp
    assert np.abs(ml.frames - mo.frames).max() < 1e-8
    assert np.abs(ml.positions[0] - m.positions[0]).max() == 0.0   # the clamp holds


def test_equilibrium_has_zero_energy_gradient_by_finite_differences(cantilever):
    """Independent of the analytic loads: central differences of elastic energy - F.r vanish at the solution."""
    m, loads = cantilever
    loads = loads[:2]   # a dead torque has no potential
    ms, info = solve_static(m, loads)
    F = loads[1].force
    pos, frm = ms.positions, ms.frames

    def E(p, f):
        return elastic_energy(p, f, m.params, m.ds) - F @ p[-1]

    h = 1e-5
    g = np.zeros((m.n_nodes, 6))
    for k in range(1, m.n_nodes):
        for a in range(6):
            vals = []
            for s in (h, -h):
                p, f = pos.copy(), frm.copy()
                if a < 3:
                    p[k, a] += s
                else:
                    f[k] = rotation_about_axis(np.eye(3)[a - 3], s) @ f[k]
                vals.append(E(p, f))
            g[k, a] = (vals[0] - vals[1]) / (2 * h)
    scale = np.linalg.norm(F)
    assert np.abs(g[:, :3]).max() < 1e-7 * scale
    assert np.abs(g[:, 3:]).max() < 1e-7 * scale * m.ds
    # and the initial pose was far from equilibrium
    assert info["iterations"] >= 3


def test_small_load_linear_response(cantilever):
    """For a small end force the displacement is K^-1 f, with K the (independent, dense) stiffness matrix from
    differences of the numpy loads at the unloaded pose; the difference is second order in the force."""
    m, _ = cantilever
    f = np.array([1e-3, -2e-3, 1e-3])
    ms, _ = solve_static(m, (Clamp(0), PullingForce(-1, f)))
    n = m.n_nodes
    h = 1e-5
    K = np.empty((6 * (n - 1), 6 * (n - 1)))
    for c in range(6 * (n - 1)):
        k, a = divmod(c, 6)
        cols = []
        for s in (h, -h):
            p, fr = m.positions.copy(), m.frames.copy()
            if a < 3:
                p[k + 1, a] += s
            else:
                fr[k + 1] = rotation_about_axis(np.eye(3)[a - 3], s) @ fr[k + 1]
            _, F, tau = m.loads(p, fr)
            cols.append(-np.concatenate([F, tau], 1)[1:].ravel())
        K[:, c] = (cols[0] - cols[1]) / (2 * h)
    rhs = np.zeros(6 * (n - 1))
    rhs[-6:-3] = f
    u = np.linalg.solve(0.5 * (K + K.T), rhs).reshape(n - 1, 6)
    du = ms.positions[1:] - m.positions[1:]
    assert np.abs(du - u[:, :3]).max() < 1e-3 * np.abs(u[:, :3]).max()


def test_trap_and_rotation_clamp_equilibrium():
    m = load_forcefield("dna-default").model_from_sequence(n_nodes=15)
    target = m.positions[-1] + [0.3, -0.2, 0.4]
    loads = (Clamp(0), Trap(-1, 50.0, centre=target), RotationClamp(-1, 500.0))
    ms, info = solve_static(m, loads, angles=[0.5])
    assert info["converged"] and info["relative_gradient"] <= 1e-8
    rl = resolve_loads(loads, m)
    _, F, tau = ms.loads()
    _, Fe, te = rl.evaluate(ms.positions, ms.frames, [0.5])
    assert np.abs((F + Fe)[1:]).max() <= 1e-8 * info["load_scale"]
    assert np.abs((tau + te)[1:]).max() <= 1e-8 * info["load_scale"] * m.ds


def test_misuse():
    m = load_forcefield("dna-default").model_from_sequence(n_nodes=8)
    with pytest.raises(DnarodError, match="no static equilibrium"):
        solve_static(m, (PullingForce(-1, [0, 0, 1.0]),))
    with pytest.raises(DnarodError, match="gtol"):
        solve_static(m, (Clamp(0),), gtol=0)


def test_ring_with_a_trap_relaxes_and_the_trap_ends_unloaded():
    """A free ring with one trap: at equilibrium the trap force vanishes (nothing else pulls), and the relative
    gradient is measured against the loads of the start (the scale does not collapse with the trap force)."""
    ff = load_forcefield("dna-default")
    r = ff.ring(n_nodes=60)
    rng = np.random.default_rng(0)
    p = r.positions + 0.05 * rng.standard_normal(r.positions.shape)
    centre = r.positions[0] + [1.0, 0.0, 0.0]
    ms, info = solve_static(r, (Trap(0, 100.0, centre=centre),), positions=p)
    assert info["converged"] and info["load_scale"] > 50.0
    assert np.abs(ms.positions[0] - centre).max() < 1e-9
    _, F, tau = ms.loads()
    assert np.abs(F).max() < 1e-8 * info["load_scale"]
