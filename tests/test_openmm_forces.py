"""OpenMM engine: rigid three-particle nodes and the step energy (portable and fast paths).

References: dnarod.core.energy.energy / loads (analytic A2, verified against finite differences in
the core tests), the particle geometry's exact inertia, and finite differences here.
"""
import numpy as np
import openmm
import pytest

from dnarod.core.energy import energy, loads
from dnarod.core.errors import ParameterError
from dnarod.core.forcefield import load_forcefield
from dnarod.core.model import RodModel
from dnarod.engines.openmm import particles as P
from dnarod.engines.openmm.forces import (add_closure_image, elastic_compound_forces, elastic_particle_kernel,
                                  elastic_python_force)
from dnarod.core.parameters import StepParameters
from dnarod.core.rotations import cayley, rotation_about_axis
from dnarod.core.strains import Closure


def random_spd(rng, n):
    A = rng.normal(size=(n, 6, 6))
    K = np.einsum("kij,klj->kil", A, A) * 20 + np.eye(6) * 50
    return K


def perturbed(model, rng, scale=0.05, rot=0.1, closure=None, params=None):
    pos = model.positions + scale * rng.normal(size=model.positions.shape)
    frm = cayley(rot * rng.normal(size=(model.n_nodes, 3))) @ model.frames
    return RodModel(pos, frm, params or model.params, model.ds, model.mass, model.inertia,
                    closure=closure if closure is not None else model.closure)


@pytest.fixture(scope="module")
def ff():
    return load_forcefield("dna-default")


@pytest.fixture(scope="module")
def open_full(ff):
    """An open 9-node chain with a different random full SPD 6x6 K and intrinsic strains per step."""
    rng = np.random.default_rng(7)
    base = ff.model_from_sequence("ACGTTGCAG")
    xi0 = base.params.intrinsic + 0.1 * rng.normal(size=base.params.intrinsic.shape)
    params = StepParameters(random_spd(rng, base.n_steps), xi0)
    return perturbed(base, rng, params=params)


@pytest.fixture(scope="module")
def circular(ff):
    rng = np.random.default_rng(3)
    base = ff.model_from_sequence("ACGTTGCAGT", circular=True)
    axis = np.array([0.3, 0.2, 1.0]) / np.linalg.norm([0.3, 0.2, 1.0])
    closure = Closure(rotation_about_axis(axis, 0.7), np.array([0.1, -0.2, 3.3]))
    return perturbed(base, rng, closure=closure)


@pytest.fixture(scope="module")
def circular_full(ff):
    """A circular chain with a random full SPD K and intrinsic strains per step, closed by a general screw."""
    rng = np.random.default_rng(11)
    base = ff.model_from_sequence("ACGTTGCAGT", circular=True)
    xi0 = base.params.intrinsic + 0.1 * rng.normal(size=base.params.intrinsic.shape)
    params = StepParameters(random_spd(rng, base.n_steps), xi0)
    axis = np.array([-0.5, 0.4, 1.0]) / np.linalg.norm([-0.5, 0.4, 1.0])
    closure = Closure(rotation_about_axis(axis, 0.9), np.array([0.3, 0.1, 3.1]))
    return perturbed(base, rng, closure=closure, params=params)


@pytest.fixture(scope="module")
def ring_full():
    """A plain ring (identity closure) with the sequence-dependent olson1998 K (21 entries), supercoiled by
    Delta Lk = +2."""
    rng = np.random.default_rng(13)
    base = load_forcefield("olson1998").ring("ACGTTGCAGTCATGCA", delta_linking_number=2)
    return perturbed(base, rng, scale=0.02, rot=0.05)


@pytest.fixture(scope="module")
def open_sized(open_full):
    """``open_full`` with nodes of different sizes (triangle radius varies from node to node)."""
    scale = 1.0 + 0.3 * np.sin(np.arange(open_full.n_nodes))
    return RodModel(open_full.positions, open_full.frames, open_full.params, open_full.ds, open_full.mass,
                    open_full.inertia * scale[:, None], closure=None)


def reference_context(model, forces):
    """A Reference Context of the nodes' particles (and, for a circular model, node 0's screw image after them)."""
    r = P.triangle_radius(model.mass, model.inertia)
    system = openmm.System()
    for m in np.repeat(model.mass / 3, 3):
        system.addParticle(m)
    x = P.particle_positions(model.positions, model.frames, r)
    if model.closure is not None and any(isinstance(f, openmm.CustomCompoundBondForce) for f in forces):
        if add_closure_image(system, model):  # 0 for a plain ring: node 0 is its own image
            assert system.getNumParticles() == 3 * model.n_nodes + 3
            x = np.vstack([x, P.closure_image_positions(x, model.closure)])
    for f in forces:
        system.addForce(f)
    ctx = openmm.Context(system, openmm.VerletIntegrator(0.001), openmm.Platform.getPlatformByName("Reference"))
    ctx.setPositions(x)
    return ctx


def state_loads(ctx):
    """Energy and node loads; only the nodes' particles (a closure image's forces are already on node 0)."""
    st = ctx.getState(getEnergy=True, getForces=True, getPositions=True)
    system = ctx.getSystem()
    n3 = sum(not system.isVirtualSite(i) for i in range(system.getNumParticles()))
    p = st.getPositions(asNumpy=True)._value[:n3]
    F, tau = P.particle_forces_to_loads(p, st.getForces(asNumpy=True)._value[:n3])
    return st.getPotentialEnergy()._value, F, tau


def portable_context(model):
    """A Reference Context with the portable forces of ``model`` (default split)."""
    return reference_context(model, elastic_compound_forces(model, P.triangle_radius(model.mass, model.inertia)))


@pytest.fixture(scope="module")
def portable_open(open_full):
    return portable_context(open_full)


@pytest.fixture(scope="module")
def portable_circular(circular):
    return portable_context(circular)


@pytest.fixture(scope="module")
def portable_circular_full(circular_full):
    return portable_context(circular_full)


@pytest.fixture(scope="module")
def portable_ring_full(ring_full):
    return portable_context(ring_full)


@pytest.fixture(scope="module")
def portable_open_sized(open_sized):
    return portable_context(open_sized)


# --- particles -------------------------------------------------------------------------
def test_triangle_has_the_model_inertia_and_centre(ff):
    m = ff.model_from_sequence("ACGTA")
    r = P.triangle_radius(m.mass, m.inertia)
    assert r == pytest.approx(0.6, rel=1e-12)
    p = P.particle_positions(m.positions, m.frames, r).reshape(-1, 3, 3)
    for k in range(m.n_nodes):
        x = p[k] - m.positions[k]
        assert np.allclose(x.mean(0), 0, atol=1e-14)
        I_lab = (m.mass[k] / 3) * (np.sum(x * x) * np.eye(3) - x.T @ x)
        I_body = m.frames[k].T @ I_lab @ m.frames[k]
        assert np.allclose(I_body, np.diag(m.inertia[k]), rtol=1e-12, atol=1e-10)


def test_pose_and_velocity_round_trip():
    rng = np.random.default_rng(0)
    n = 6
    c = rng.normal(size=(n, 3))
    f = cayley(rng.normal(size=(n, 3)))
    r = rng.uniform(0.3, 0.9, n)
    p = P.particle_positions(c, f, r)
    c2, f2 = P.node_poses(p)
    assert np.allclose(c2, c, atol=1e-14) and np.allclose(f2, f, atol=1e-13)
    v, w = rng.normal(size=(n, 3)), rng.normal(size=(n, 3))
    u = P.particle_velocities(f, r, v, w)
    # rigid: every pair distance is constant to first order, (p_i - p_j).(u_i - u_j) = 0
    pp, uu = p.reshape(n, 3, 3), u.reshape(n, 3, 3)
    assert np.allclose(np.einsum("kc,kc->k", pp[:, 0] - pp[:, 1], uu[:, 0] - uu[:, 1]), 0, atol=1e-12)
    v2, w2 = P.node_velocities(p, u)
    assert np.allclose(v2, v, atol=1e-13) and np.allclose(w2, w, atol=1e-12)
    # kinetic energy of the particles = node kinetic energy with J = m l^2 (1/2, 1/2, 1)
    m = rng.uniform(100, 900, n)
    J = m[:, None] * r[:, None] ** 2 * np.array([0.5, 0.5, 1.0])
    ke_p = 0.5 * np.sum(np.repeat(m / 3, 3)[:, None] * u**2)
    ke_n = 0.5 * np.sum(m[:, None] * v**2) + 0.5 * np.sum(J * w**2)
    assert ke_p == pytest.approx(ke_n, rel=1e-12)


def test_loads_spread_over_particles_give_the_totals():
    rng = np.random.default_rng(1)
    c, f = rng.normal(size=(5, 3)), cayley(rng.normal(size=(5, 3)))
    p = P.particle_positions(c, f, 0.6)
    F, tau = rng.normal(size=(5, 3)), rng.normal(size=(5, 3))
    F2, tau2 = P.particle_forces_to_loads(p, P.loads_to_particle_forces(p, F, tau))
    assert np.allclose(F2, F, atol=1e-13) and np.allclose(tau2, tau, atol=1e-13)


def test_unrealisable_inertia_is_rejected():
    with pytest.raises(ParameterError, match="base pair 2: inertia"):
        P.triangle_radius([650, 650], [[117, 117, 234], [117, 117, 300]])
    with pytest.raises(ParameterError, match="J1 == J2"):
        P.triangle_radius([650], [[100, 117, 217]])


# --- fast kernel ---------------------------------------------------------------------------
@pytest.mark.parametrize("which", ["open_full", "circular"])
def test_numba_kernel_equals_analytic_loads(which, request):
    m = request.getfixturevalue(which)
    r = P.triangle_radius(m.mass, m.inertia)
    E, F, tau = loads(m.positions, m.frames, m.params, m.ds, m.closure)
    p = P.particle_positions(m.positions, m.frames, r)
    out = np.zeros_like(p)
    Q = m.closure.Q if m.closure else np.eye(3)
    t = m.closure.t if m.closure else np.zeros(3)
    E2 = elastic_particle_kernel(p, r, m.params.stiffness, m.params.intrinsic, m.ds, Q, t, m.closure is not None, out)
    F2, tau2 = P.particle_forces_to_loads(p, out)
    assert E2 == pytest.approx(E, rel=1e-13)
    assert np.abs(F2 - F).max() <= 1e-11 * np.abs(F).max()
    assert np.abs(tau2 - tau).max() <= 1e-11 * np.abs(tau).max()


# --- portable path on the Reference platform ----------------------------------------------
PORTABLE = {"open_full": "portable_open", "circular": "portable_circular", "circular_full": "portable_circular_full",
            "ring_full": "portable_ring_full", "open_sized": "portable_open_sized"}


@pytest.mark.parametrize("which", list(PORTABLE))
def test_portable_energy_and_loads_equal_numpy(which, request):
    m = request.getfixturevalue(which)
    ctx = request.getfixturevalue(PORTABLE[which])
    E, F, tau = loads(m.positions, m.frames, m.params, m.ds, m.closure)
    E_mm, F_mm, tau_mm = state_loads(ctx)
    assert abs(E_mm - energy(m.positions, m.frames, m.params, m.ds, m.closure)) <= 1e-10 * abs(E)
    assert np.abs(F_mm - F).max() <= 1e-10 * np.abs(F).max()
    assert np.abs(tau_mm - tau).max() <= 1e-10 * np.abs(tau).max()


def test_portable_forces_are_the_gradient(open_full, portable_open):
    """Finite differences of the OpenMM energy along random particle displacements."""
    ctx = portable_open
    st = ctx.getState(getPositions=True, getForces=True)
    p0 = st.getPositions(asNumpy=True)._value.copy()
    f0 = st.getForces(asNumpy=True)._value
    rng = np.random.default_rng(2)
    h = 1e-5
    for _ in range(3):
        d = rng.normal(size=p0.shape)
        ctx.setPositions(p0 + h * d)
        Ep = ctx.getState(getEnergy=True).getPotentialEnergy()._value
        ctx.setPositions(p0 - h * d)
        Em = ctx.getState(getEnergy=True).getPotentialEnergy()._value
        assert (Ep - Em) / (2 * h) == pytest.approx(-np.sum(f0 * d), rel=1e-6)
    ctx.setPositions(p0)


@pytest.mark.parametrize("which", list(PORTABLE))
def test_fast_path_equals_portable_path(which, request):
    m = request.getfixturevalue(which)
    ctx = request.getfixturevalue(PORTABLE[which])
    r = P.triangle_radius(m.mass, m.inertia)
    fast = reference_context(m, [elastic_python_force(m, r)])
    E1, F1, t1 = state_loads(ctx)
    E2, F2, t2 = state_loads(fast)
    assert E2 == pytest.approx(E1, rel=1e-12)
    assert np.abs(F2 - F1).max() <= 1e-10 * np.abs(F1).max()
    assert np.abs(t2 - t1).max() <= 1e-10 * np.abs(t1).max()


def test_intrinsic_helix_is_force_free_on_both_paths(open_full, portable_open):
    """Zero energy and loads at the intrinsic shape: heterogeneous full-K chain (portable and fast
    paths, same context reused) and the sequence-dependent olson1998 set (fast path)."""
    m = RodModel.intrinsic(open_full.params, open_full.ds, open_full.mass, open_full.inertia)
    r = P.triangle_radius(m.mass, m.inertia)
    portable_open.setPositions(P.particle_positions(m.positions, m.frames, r))
    olson = load_forcefield("olson1998").model_from_sequence("ACGTTGCATG")
    r_o = P.triangle_radius(olson.mass, olson.inertia)
    cases = [(portable_open, open_full), (reference_context(m, [elastic_python_force(m, r)]), open_full),
             (reference_context(olson, [elastic_python_force(olson, r_o)]), olson)]
    try:
        for ctx, ref in cases:
            E, F, tau = state_loads(ctx)
            # round-off scale: the largest stiffness times a strain error of 1e-14 (the loads of
            # the perturbed chains are of order 1e2-1e3 kJ/mol/nm)
            tol = 1e-14 * np.abs(ref.params.stiffness).max() / ref.ds * 10
            assert abs(E) < tol * 1e-10
            assert np.abs(F).max() < tol and np.abs(tau).max() < tol
    finally:
        portable_open.setPositions(P.particle_positions(open_full.positions, open_full.frames, r))


def test_cpu_fast_path_within_precision(open_full):
    r = P.triangle_radius(open_full.mass, open_full.inertia)
    system = openmm.System()
    for m in np.repeat(open_full.mass / 3, 3):
        system.addParticle(m)
    system.addForce(elastic_python_force(open_full, r))
    ctx = openmm.Context(system, openmm.VerletIntegrator(0.001), openmm.Platform.getPlatformByName("CPU"))
    ctx.setPositions(P.particle_positions(open_full.positions, open_full.frames, r))
    E, F, tau = loads(open_full.positions, open_full.frames, open_full.params, open_full.ds)
    E2, F2, t2 = state_loads(ctx)
    # CPU positions are stored in single precision: relative errors of order 1e-6.
    assert E2 == pytest.approx(E, rel=1e-4)
    assert np.abs(F2 - F).max() <= 1e-3 * np.abs(F).max()
    assert np.abs(t2 - tau).max() <= 1e-3 * np.abs(tau).max()


@pytest.mark.parametrize("which", ["open_full", "circular_full"])
def test_portable_single_force_and_row_split_give_the_same_energy_and_loads(which, request):
    """One force per Cholesky row (the default for a full K; faster to compile) and one force for all rows both
    equal dnarod.core.energy, also for a circular chain closed by a general screw (closing bond to the image sites)."""
    m = request.getfixturevalue(which)
    r = P.triangle_radius(m.mass, m.inertia)
    assert len(elastic_compound_forces(m, r)) == 6
    assert len(elastic_compound_forces(m, r, split=False)) == 1
    E, F, tau = loads(m.positions, m.frames, m.params, m.ds, m.closure)
    for split in (False, True):
        E_mm, F_mm, tau_mm = state_loads(reference_context(m, elastic_compound_forces(m, r, split=split)))
        assert abs(E_mm - E) <= 1e-12 * abs(E)
        assert np.abs(F_mm - F).max() <= 1e-10 * np.abs(F).max()
        assert np.abs(tau_mm - tau).max() <= 1e-10 * np.abs(tau).max()


def test_circular_chain_compiles_the_open_expressions_with_the_closing_bond_to_the_image(ff, circular):
    """The closing step is one more bond of the same forces (no second expression to compile), from node n-1
    to the three image particles after the nodes' particles."""
    r = P.triangle_radius(circular.mass, circular.inertia)
    n = circular.n_nodes
    closed = elastic_compound_forces(circular, r)
    m = ff.model_from_sequence("ACGTTGCAGT")
    opened = elastic_compound_forces(m, P.triangle_radius(m.mass, m.inertia))
    assert len(closed) == len(opened) == 1
    assert closed[0].getEnergyFunction() == opened[0].getEnergyFunction()
    assert closed[0].getNumBonds() == n and opened[0].getNumBonds() == n - 1
    assert list(closed[0].getBondParameters(n - 1)[0]) == [3 * n - 3, 3 * n - 2, 3 * n - 1, 3 * n, 3 * n + 1, 3 * n + 2]
    assert list(elastic_compound_forces(circular, r, image=100)[0].getBondParameters(n - 1)[0])[3:] == [100, 101, 102]


def test_plain_ring_closes_on_node_0_itself(ring_full):
    """The identity closure of a ring (any Delta Lk) needs no image particles: the closing bond ends on node 0."""
    r = P.triangle_radius(ring_full.mass, ring_full.inertia)
    n = ring_full.n_nodes
    system = openmm.System()
    assert add_closure_image(system, ring_full) == 0 and system.getNumParticles() == 0
    for f in elastic_compound_forces(ring_full, r):
        assert list(f.getBondParameters(n - 1)[0]) == [3 * n - 3, 3 * n - 2, 3 * n - 1, 0, 1, 2]


def test_closure_image_sites_follow_node_0_by_the_screw(ff, circular):
    """OpenMM places the SymmetrySite particles at Q x + t of node 0's particles (as closure_image_positions)."""
    r = P.triangle_radius(circular.mass, circular.inertia)
    x = P.particle_positions(circular.positions, circular.frames, r)
    system = openmm.System()
    for mass in np.repeat(circular.mass / 3, 3):
        system.addParticle(mass)
    assert add_closure_image(system, circular) == x.shape[0]
    assert [system.getParticleMass(x.shape[0] + i)._value for i in range(3)] == [0.0, 0.0, 0.0]
    ctx = openmm.Context(system, openmm.VerletIntegrator(0.001), openmm.Platform.getPlatformByName("Reference"))
    ctx.setPositions(np.vstack([x, np.zeros((3, 3))]))
    ctx.computeVirtualSites()
    y = ctx.getState(getPositions=True).getPositions(asNumpy=True)._value[-3:]
    want = P.closure_image_positions(x, circular.closure)
    assert np.abs(y - want).max() < 1e-12
    assert np.abs(want - (x[:3] @ circular.closure.Q.T + circular.closure.t)).max() < 1e-15
    with pytest.raises(ParameterError, match="circular"):
        add_closure_image(system, ff.model_from_sequence("ACGT"))


def test_closure_image_without_symmetry_sites_is_one_clear_error(ff, circular, monkeypatch):
    """An OpenMM older than SymmetrySite (the pin allows 8.1): a screw-closed portable system says so."""
    monkeypatch.delattr(openmm, "SymmetrySite")
    with pytest.raises(ParameterError, match="SymmetrySite.*elastic='fast'"):
        add_closure_image(openmm.System(), circular)


def test_portable_expression_keeps_only_the_used_entries(ff):
    """dna-default (diagonal + twist-stretch coupling) stays one force with 7 factor entries (row, strain):
    the strain order (Omega, Gamma3, Gamma1, Gamma2) puts Gamma3 next to Omega3, so the coupling adds no
    fill-in."""
    m = ff.model_from_sequence("ACGTTGCAGT")
    r = P.triangle_radius(m.mass, m.inertia)
    forces = elastic_compound_forces(m, r)
    assert len(forces) == 1
    names = {forces[0].getPerBondParameterName(i) for i in range(forces[0].getNumPerBondParameters())}
    assert sorted(n for n in names if n.startswith("dnarod_P")) == [
        "dnarod_P11", "dnarod_P22", "dnarod_P33", "dnarod_P36", "dnarod_P46", "dnarod_P54", "dnarod_P65"]
