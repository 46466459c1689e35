"""dnarod.physics.modes: the banded Hessian and omega_max against dense, independent references."""
import numpy as np
import pytest
import scipy.linalg

from dnarod.physics import modes
from dnarod.core.energy import energy as elastic_energy
from dnarod.core.energy import loads as numpy_loads
from dnarod.core.forcefield import load_forcefield
from dnarod.physics.loads import Clamp, PullingForce, RotationClamp, Torque, Trap, resolve_loads
from dnarod.core.rotations import rotation_about_axis
from dnarod.physics.testsystems import TwistedRod


@pytest.fixture(scope="module")
def ff():
    return load_forcefield("dna-default")


def _perturb(pos, frm, k, a, h):
    p, f = pos.copy(), frm.copy()
    if a < 3:
        p[k, a] += h
    else:
        f[k] = rotation_about_axis(np.eye(3)[a - 3], h) @ f[k]
    return p, f


def dense_reference(model, loads=(), pos=None, frm=None, h=1e-5):
    """Dense lab-chart Hessian from the numpy loads (dnarod.core.energy) + ResolvedLoads, one dof at a time,
    and the generalised eigenvalues with the mass matrix over the free dofs."""
    pos = model.positions if pos is None else pos
    frm = model.frames if frm is None else frm
    rl = resolve_loads(loads, model, pos, frm)
    n = model.n_nodes
    H = np.empty((6 * n, 6 * n))
    for dof in range(6 * n):
        k, a = divmod(dof, 6)
        cols = []
        for s in (h, -h):
            p, f = _perturb(pos, frm, k, a, s)
            _, F, t = numpy_loads(p, f, model.params, model.ds, model.closure)
            _, Fe, te = rl.evaluate(p, f)
            cols.append(-np.concatenate([F + Fe, t + te], 1).ravel())
        H[:, dof] = (cols[0] - cols[1]) / (2 * h)
    H = 0.5 * (H + H.T)
    keep = np.repeat(~rl.clamped, 6)
    M = modes.mass_matrix(model, frm).toarray()
    lam = scipy.linalg.eigh(H[np.ix_(keep, keep)], M[np.ix_(keep, keep)], eigvals_only=True)
    return H, lam


CASES = {
    "open": (dict(n_nodes=12), ()),
    "open sequence": (dict(sequence="GCGAATTCGCGATC"), ()),
    "ring 11": (dict(n_nodes=11, circular=True), ()),
    "ring 12": (dict(n_nodes=12, circular=True), ()),
    "clamped ends": (dict(sequence="GATTACAGATTACA"), (Clamp(0), Clamp(-1))),
    "interior clamp, trap, rotation clamp": (dict(n_nodes=10), (Clamp(4), Trap(0, 5000.0),
                                                                RotationClamp(-1, 800.0))),
    "ring with trap": (dict(n_nodes=10, circular=True), (Trap(3, 3000.0), Clamp(7))),
}


@pytest.mark.parametrize("name", list(CASES))
def test_omega_max_equals_dense_eigvalsh(ff, name):
    kw, loads = CASES[name]
    m = ff.model_from_sequence(**kw)
    _, lam = dense_reference(m, loads)
    w_dense = np.sqrt(lam.max())
    assert modes.omega_max(m, loads) == pytest.approx(w_dense, rel=1e-8)
    # the whole spectrum of the sparse Hessian too
    w, _ = modes.normal_modes(m, loads)
    lam_sparse = np.sign(w) * w**2
    assert np.abs(np.sort(lam_sparse) - np.sort(lam)).max() < 1e-8 * lam.max()


def test_omega_max_screw_closure_equals_exact_dispersion():
    tr = TwistedRod.from_forcefield("dna-default", 16)
    assert abs(modes.omega_max(tr.model()) - tr.omega_max()) < 1e-8 * tr.omega_max()


def test_hessian_is_the_chart_second_derivative_of_the_energy(ff):
    """At a stressed (non-equilibrium) pose the symmetrised load differences equal the second differences of
    the energy in the chart (dr, L -> exp(hat(dtheta)) L): the chart term hat(tau)/2 is exactly the
    antisymmetric part that symmetrising removes."""
    m = ff.model_from_sequence("GCGATC")
    rng = np.random.default_rng(2)
    pos = m.positions + 0.03 * rng.standard_normal(m.positions.shape)
    frm = np.array([rotation_about_axis(v / np.linalg.norm(v), 0.1) @ f
                    for v, f in zip(rng.standard_normal((m.n_nodes, 3)), m.frames)])
    loads = (Trap(0, 500.0, centre=pos[0] + 0.05), RotationClamp(-1, 300.0, frame=np.eye(3)))
    rl = resolve_loads(loads, m, pos, frm)
    H = modes.hessian(m, loads, pos, frm).toarray()

    def E(p, f):
        return elastic_energy(p, f, m.params, m.ds) + rl.evaluate(p, f)[0]

    def chart(q):  # (dr, dtheta) per node -> pose (dr + r, exp(hat(dtheta)) L)
        f = frm.copy()
        for k in range(m.n_nodes):
            a = np.linalg.norm(q[k, 3:])
            if a > 0:
                f[k] = rotation_about_axis(q[k, 3:] / a, a) @ frm[k]
        return pos + q[:, :3], f

    h = 1e-4
    n6 = 6 * m.n_nodes
    Hf = np.empty((n6, n6))
    for i in range(n6):
        for j in range(i, n6):
            vals = []
            for si, sj in ((h, h), (h, -h), (-h, h), (-h, -h)):
                q = np.zeros((m.n_nodes, 6))
                q[i // 6, i % 6] += si
                q[j // 6, j % 6] += sj
                vals.append(E(*chart(q)))
            Hf[i, j] = Hf[j, i] = (vals[0] - vals[1] - vals[2] + vals[3]) / (4 * h * h)
    assert np.abs(H - Hf).max() < 2e-5 * np.abs(Hf).max()


def test_default_time_step_and_splitting_use_modes(ff):
    from dnarod.engines.lax import SplittingIntegrator, omega_max

    m = ff.model_from_sequence(n_nodes=30)
    dt, w = modes.default_time_step(m)
    assert dt == pytest.approx(modes.DEFAULT_OMEGA_DT / w, rel=1e-15)
    assert omega_max(m) == pytest.approx(w, rel=1e-9)
    assert SplittingIntegrator(m, dt).omega_max == pytest.approx(w, rel=1e-9)


def test_dead_loads_add_no_stiffness(ff):
    m = ff.model_from_sequence(n_nodes=9)
    H0 = modes.hessian(m, (Clamp(0),)).toarray()
    H1 = modes.hessian(m, (Clamp(0), PullingForce(-1, [1.0, 2.0, 3.0]), Torque(-1, [0, 0, 2.0]))).toarray()
    assert np.abs(H1 - H0).max() == 0.0
