"""The SMK step energy as OpenMM forces (docs/formulation.md §2-4, §7).

Two interchangeable implementations of ``E = sum_k ds H(Omega_k, Gamma_k)`` on the
three-particle nodes of :mod:`dnarod.engines.openmm.particles`:

* :func:`elastic_compound_forces` -- the **portable path**: ``CustomCompoundBondForce`` forces over
  the six particles of neighbouring nodes, written with the dot-product form of A1 as a sum of
  six squares (Cholesky factor of the stiffness; see :func:`elastic_expression`), per-bond
  parameters ``dnarod_Pab`` (the scaled Cholesky factor with the node scales folded in; entries
  that are zero on every step are left out of the expression), ``dnarod_c1..6`` (the factor
  times the intrinsic strains) and ``dnarod_alpha``, ``dnarod_beta`` (and ``dnarod_rho`` when
  the nodes differ in size). Runs on every OpenMM platform. A large factor is split into one
  force per row (faster to compile). The closing step of a circular chain is one more bond of
  the same forces whose second node is the screw image of node 0, ``p -> Q p + t``: three
  massless ``SymmetrySite`` particles after the nodes' particles (:func:`add_closure_image`),
  whose directors are ``Q d_a(0)`` and centre ``Q c_0 + t``, exactly as in :mod:`dnarod.core.strains`.
* :func:`elastic_python_force` -- the **fast CPU path**: an ``openmm.PythonForce`` whose
  callback runs a numba kernel of the analytic loads of A2 (tested equal to
  :func:`dnarod.core.energy.loads`) and spreads each node's force and torque over its particles
  (:func:`dnarod.engines.openmm.particles.loads_to_particle_forces`).

The two paths give the same energy and the same total force and torque on every node; their
per-particle forces differ only by components along the constraint directions, which the
rigid-body constraints absorb, so the constrained dynamics are identical.
"""
from __future__ import annotations

import gc

import numba
import numpy as np

import openmm

from dnarod.core.errors import ParameterError
from dnarod.core.kernels import loads_kernel
from dnarod.engines.openmm.particles import SQRT3

class _CollectorPaused:
    """Calls ``callback(state)`` with the cyclic garbage collector paused (picklable, as OpenMM may serialize
    the force with its System)."""

    def __init__(self, callback):
        self.callback = callback

    def __call__(self, state):
        enabled = gc.isenabled()
        gc.disable()
        try:
            return self.callback(state)
        finally:
            if enabled:
                gc.enable()


def python_force(callback):
    """An ``openmm.PythonForce`` calling ``callback(state)`` with Python's cyclic garbage collector paused.

    OpenMM calls the callback from inside a force evaluation; a collection that ran there could destroy another
    simulation's Context (left in a reference cycle) in the middle of this one's evaluation, which crashes the
    process. Pausing the collector for the duration of the call (it resumes at once after) removes that class of
    crash at the cost of two C calls per evaluation.
    """
    return openmm.PythonForce(_CollectorPaused(callback))


#: Force groups used by the engine (energies are attributed per group on a blow-up).
GROUPS = {"elastic": 1, "nonbonded": 2, "external": 3}



def _det(u, v, w):
    """Triple product ``u . (v x w)`` of three vectors named by prefix (components x, y, z)."""
    return (f"({u}x*({v}y*{w}z - {v}z*{w}y) + {u}y*({v}z*{w}x - {v}x*{w}z) + {u}z*({v}x*{w}y - {v}y*{w}x))")


def _dot(u, v):
    return f"({u}x*{v}x + {u}y*{v}y + {u}z*{v}z)"


def elastic_expression(used, uniform=False):
    """The energy expression of one step (Cholesky form, node scales folded into the per-bond constants).

    With ``K = R^T R`` (R the upper-triangular Cholesky factor, strains taken in
    :data:`STRAIN_ORDER`) the step energy ``ds/2 u^T K u`` is ``v1^2 + ... + v6^2``,
    ``v_a = sqrt(ds/2) sum_b R_ab u_b``: each strain enters only the rows that need it, so the
    rotation strains (the largest subexpressions, first in the order) are copied 1, 2 and 3 times
    instead of 6 in the expanded quadratic form, and Lepton (OpenMM's expression compiler, which
    substitutes every ';' definition and differentiates the whole tree with respect to the 18
    coordinates) has several times fewer operations to build (docs/platforms.md).

    The strains are written in the unnormalised node vectors ``p = 2 x1 - x2 - x3 = 3 l d1``,
    ``q = x2 - x3 = sqrt(3) l d2`` (node a; ``r``, ``s`` for node b) and the centre difference
    ``E = 3 (c_b - c_a)``, without director cross products, and every node scale is moved out
    of the coordinate subexpressions into the per-bond constants (fewer operations in every
    copy and every derivative):

    * ``1 + tr(R) = (1 + d11)(1 + d22) - d12 d21`` (Binet-Cauchy, ``d33 = d11 d22 - d12 d21``)
      ``= ua ub va vb Dt``, ``Dt = (alpha + p.r)(beta + q.s) - (p.s)(q.r)``,
      ``alpha = 1/(ua ub)``, ``beta = 1/(va vb)``;
    * ``d32 - d23 = (d1a + d1b).(d2a x d2b) ~ W1 = det(p + rho r, q, s)``,
      ``d13 - d31 = det(d1a, d1b, d2a + d2b) ~ W2 = det(p, r, q + rho s)``,
      ``d21 - d12 ~ W3 = q.r - p.s`` (``rho = l_a / l_b``, left out when all nodes are alike);
    * ``Gamma ~ (p.E, q.E, det(p, q, E))``.

    Here ``ua, va = 1/(3 l_a), 1/(sqrt(3) l_a)`` (``ub``, ``vb`` for node b). The factors that
    turn ``W_b/Dt`` and the ``Gamma`` terms into strains are folded into the per-bond
    ``dnarod_P_ab`` (see :func:`portable_parameters`); ``dnarod_c_a = sqrt(ds/2) (R xi0)_a``.

    Parameters
    ----------
    used : list of (int, int)
        Entries ``(row, strain)`` (0-based; strain order of
        :class:`~dnarod.core.parameters.StepParameters`) of the folded factor included.
    uniform : bool
        All nodes have the same triangle radius (``rho = 1`` left out).

    Returns
    -------
    str
        An OpenMM expression in the coordinates of particles 1-6.
    """
    rows = {}
    for a, b in used:
        rows.setdefault(a, []).append(b)
    lines, squares = [], []
    for a in sorted(rows):
        w = [f"dnarod_P{a + 1}{b + 1}*W{b + 1}" for b in sorted(rows[a]) if b < 3]
        g = [f"dnarod_P{a + 1}{b + 1}*G{b - 2}" for b in sorted(rows[a]) if b >= 3]
        parts = (["(" + " + ".join(w) + ")/Dt"] if w else []) + g
        lines.append(f"v{a + 1} = " + " + ".join(parts) + f" - dnarod_c{a + 1}")
        squares.append(f"v{a + 1}^2")
    lines.insert(0, " + ".join(squares) if squares else "0")
    rho = "" if uniform else "dnarod_rho*"
    lines += ["W1 = " + _det("h", "q", "s"), "W2 = " + _det("p", "r", "k"),
              f"W3 = {_dot('q', 'r')} - {_dot('p', 's')}",
              f"Dt = (dnarod_alpha + {_dot('p', 'r')})*(dnarod_beta + {_dot('q', 's')}) - {_dot('p', 's')}*{_dot('q', 'r')}",
              f"G1 = {_dot('p', 'E')}", f"G2 = {_dot('q', 'E')}", "G3 = " + _det("p", "q", "E")]
    lines += [f"h{c} = p{c} + {rho}r{c}" for c in "xyz"] + [f"k{c} = q{c} + {rho}s{c}" for c in "xyz"]
    lines += [f"E{c} = cb{c} - {c}1 - {c}2 - {c}3" for c in "xyz"]
    lines += [f"p{c} = 2*{c}1 - {c}2 - {c}3" for c in "xyz"] + [f"q{c} = {c}2 - {c}3" for c in "xyz"]
    lines += [f"cb{c} = {c}4 + {c}5 + {c}6" for c in "xyz"]
    lines += [f"r{c} = 2*{c}4 - {c}5 - {c}6" for c in "xyz"] + [f"s{c} = {c}5 - {c}6" for c in "xyz"]
    return "; ".join(lines)


def portable_parameters(stiffness, intrinsic, ds, radius_a, radius_b, order=None):
    """Per-step constants of :func:`elastic_expression`: folded factor ``P`` (n, 6, 6) (row, strain),
    ``c`` (n, 6) and ``alpha``, ``beta``, ``rho`` (n,).

    Parameters
    ----------
    stiffness : ndarray, shape (n, 6, 6)
    intrinsic : ndarray, shape (n, 6)
    ds : float
        nm.
    radius_a, radius_b : ndarray, shape (n,)
        Triangle circumradius of the first and second node of each step, nm.
    order : sequence of int, optional
        Strain order of the Cholesky factorisation (default :data:`STRAIN_ORDER`).
    """
    order = STRAIN_ORDER if order is None else order
    P, c = cholesky_parameters(stiffness, intrinsic, ds, order)
    la, lb = np.asarray(radius_a, float), np.asarray(radius_b, float)
    ua, va, ub, vb = 1 / (3 * la), 1 / (SQRT3 * la), 1 / (3 * lb), 1 / (SQRT3 * lb)
    rho = la / lb
    # strain_b = factor_b * (W_b / Dt) for rotations, factor_b * G_b for translations
    factor = np.stack([1 / ub, 1 / vb, rho / (ub * vb), ua / 3, va / 3, ua * va / 3], axis=1)
    return P * factor[:, None, :], c, 1 / (ua * ub), 1 / (va * vb), rho


def cholesky_parameters(stiffness, intrinsic, ds, order=None):
    """Per-step constants of :func:`elastic_expression`: ``P`` (n, 6, 6) and ``c`` (n, 6).

    ``P[k, a, s]`` is row ``a`` of the Cholesky factor of the stiffness with its strains taken in
    ``order`` (a permutation of 0..5, strain order of StepParameters; default the identity),
    indexed by the original strain ``s``: ``v_a = sum_s P[k, a, s] u_s - c[k, a]``.

    Raises
    ------
    ParameterError
        If a step's stiffness is not symmetric positive definite (naming the step).
    """
    K = np.asarray(stiffness, float)
    order = np.arange(6) if order is None else np.asarray(order)
    R = np.zeros_like(K)
    for k in range(K.shape[0]):
        Kk = 0.5 * (K[k] + K[k].T)
        try:
            R[k][:, order] = np.linalg.cholesky(Kk[np.ix_(order, order)]).T
        except np.linalg.LinAlgError:
            raise ParameterError(f"step {k + 1}: the stiffness matrix is not positive definite; the portable path "
                                 f"needs K = R^T R (fix the parameter set)") from None
    h = np.sqrt(0.5 * ds)
    col = np.array([2 / ds] * 3 + [1 / ds] * 3)
    P = h * R * col[None, None, :]
    c = h * np.einsum("kab,kb->ka", R, np.asarray(intrinsic, float))
    return P, c


def used_stiffness_pairs(stiffness, steps=None):
    """Entries ``(row, strain)`` of the (permuted) Cholesky factor that are non-zero on at least one step."""
    K = np.asarray(stiffness)[steps] if steps is not None else np.asarray(stiffness)
    return [(i, j) for i in range(6) for j in range(6) if np.any(K[:, i, j] != 0)]


#: Strain order of the Cholesky factorisation: the rotations first (their subexpressions, with the
#: denominator ``Dt``, are the largest, and a strain enters only the factor rows up to its position),
#: then Gamma3 (a triple product) before the two dot-product strains Gamma1, Gamma2 (fewer Lepton
#: operations than the natural order for a full K).
STRAIN_ORDER = (0, 1, 2, 5, 3, 4)
#: A force whose factor has more entries than this is split into one force per factor row (see
#: :func:`elastic_compound_forces`); dna-default-like stiffness (7 entries) stays in one force.
MAX_ENTRIES_PER_FORCE = 7


def elastic_compound_forces(model, radius, split=None, order=None, image=None):
    """The portable path: CustomCompoundBondForce(s) carrying the step energy.

    Lepton's work (differentiating each force's expression with respect to its 18 particle
    coordinates, then compiling every derivative with common-subexpression elimination) grows
    faster than linearly with the expression, so a large energy compiles faster as several
    forces: one per row ``v_a^2`` of the Cholesky factor. The rows then no longer share the
    strain subexpressions at run time, so an evaluation of the portable force costs 2-3x more on
    the Reference/CPU platforms (on GPU platforms OpenMM runs all bonded forces in one kernel).
    The closing step of a circular chain is one more bond of the same forces, from node
    ``n - 1`` to the three massless image particles of node 0 (:func:`add_closure_image`), so a
    circular chain compiles the same expressions as an open one. Compile times and costs:
    ``docs/platforms.md``.

    Parameters
    ----------
    model : RodModel
    radius : ndarray, shape (n_nodes,)
        Triangle circumradius of every node, nm.
    split : bool or None
        One force per row of the Cholesky factor; ``None``: split when the factor has more
        than :data:`MAX_ENTRIES_PER_FORCE` entries.
    order : sequence of int, optional
        Strain order of the factorisation (default :data:`STRAIN_ORDER`).
    image : int, optional
        Circular chain: index of the first of the three image particles of node 0 (default
        ``3 n_nodes``, where :func:`add_closure_image` puts them; ``0``, node 0 itself, for the
        identity closure of a plain ring); the System must hold them.

    Returns
    -------
    list of openmm.CustomCompoundBondForce
        All in force group ``GROUPS["elastic"]``.
    """
    n = model.n_nodes
    radius = np.asarray(radius, float)
    circular = model.closure is not None
    steps = np.arange(n if circular else n - 1)
    k1 = (steps + 1) % n
    P, c, alpha, beta, rho = portable_parameters(model.params.stiffness, model.params.intrinsic, model.ds,
                                                 radius[steps], radius[k1], order)
    uniform = bool(np.all(radius == radius[0]))
    second = [[3 * j, 3 * j + 1, 3 * j + 2] for j in k1]
    if circular:  # the closing step's second node is the screw image of node 0
        first = (0 if is_identity(model.closure) else 3 * n) if image is None else int(image)
        second[-1] = [first, first + 1, first + 2]
    forces = []
    if steps.size == 0:
        return forces
    used = used_stiffness_pairs(P)  # entries of the Cholesky factor (zero pattern of K, no fill-in)
    all_rows = sorted({a for a, _ in used})
    do_split = len(used) > MAX_ENTRIES_PER_FORCE if split is None else bool(split)
    row_groups = [[a] for a in all_rows] if do_split else [all_rows]
    for rows in row_groups:
        pairs = [(a, b) for a, b in used if a in rows]
        f = openmm.CustomCompoundBondForce(6, elastic_expression(pairs, uniform))
        names = [f"dnarod_P{a + 1}{b + 1}" for a, b in pairs] + [f"dnarod_c{a + 1}" for a in rows]
        names += ["dnarod_alpha", "dnarod_beta"] + ([] if uniform else ["dnarod_rho"])
        for name in names:
            f.addPerBondParameter(name)
        for k in steps:
            vals = [P[k, a, b] for a, b in pairs] + [c[k, a] for a in rows] + [alpha[k], beta[k]]
            vals += [] if uniform else [rho[k]]
            f.addBond([3 * k, 3 * k + 1, 3 * k + 2] + second[k], [float(v) for v in vals])
        f.setForceGroup(GROUPS["elastic"])
        f.setName("dnarod elastic (portable)"
                  + (f" rows {','.join(str(a + 1) for a in rows)}" if len(row_groups) > 1 else ""))
        forces.append(f)
    return forces


def is_identity(closure):
    """True for the plain ring closure (``Q = I``, ``t = 0`` exactly): node 0 is its own image."""
    return bool(np.array_equal(closure.Q, np.eye(3)) and not np.any(closure.t))


def add_closure_image(system, model):
    """Add the screw image of node 0 to ``system`` for the portable path of a circular chain.

    Three massless particles (indices ``3n, 3n+1, 3n+2`` when added right after the nodes'
    particles), each an OpenMM ``SymmetrySite`` of one particle of node 0: ``Q x + t`` in
    Cartesian coordinates, the closure screw of :class:`dnarod.core.strains.Closure`. The closing
    step's second node is then an ordinary node of :func:`elastic_compound_forces` (its centre
    ``Q c_0 + t``, its directors ``Q d_a(0)``, as in :mod:`dnarod.core.strains`); OpenMM moves the
    sites with node 0 and hands their forces back to it (``Q^T F``).

    Parameters
    ----------
    system : openmm.System
        Holds the ``3 n`` particles of the nodes (node 0 owns particles 0, 1, 2).
    model : RodModel
        Circular (``model.closure`` set).

    Returns
    -------
    int
        Index of the first image particle; ``0`` (node 0 itself, nothing added) for the identity
        closure of a plain ring (:func:`is_identity`).
    """
    if model.closure is None:
        raise ParameterError("add_closure_image needs a circular model (model.closure is None)")
    if is_identity(model.closure):
        return 0
    if not hasattr(openmm, "SymmetrySite"):  # pyproject allows openmm>=8.1; the site came in a later release
        raise ParameterError(f"the portable path of a screw-closed chain needs OpenMM's SymmetrySite, which OpenMM "
                             f"{openmm.__version__} lacks: upgrade openmm or use elastic='fast' / 'plugin'")
    Q = np.asarray(model.closure.Q, float)
    t = openmm.Vec3(*map(float, model.closure.t))
    rows = [openmm.Vec3(*map(float, Q[i])) for i in range(3)]
    first = system.getNumParticles()
    for i in range(3):
        system.addParticle(0.0)
        system.setVirtualSite(first + i, openmm.SymmetrySite(i, rows[0], rows[1], rows[2], t, False))
    return first


# ----------------------------------------------------------------------------------------
# Fast path: numba kernel of the analytic loads (docs/formulation.md §4)
# ----------------------------------------------------------------------------------------
@numba.njit(cache=True)
def _frames_from_particles(p, radius, centres, frames):
    n = radius.shape[0]
    s3 = np.sqrt(3.0)
    for k in range(n):
        for c in range(3):
            a0 = p[3 * k, c]
            a1 = p[3 * k + 1, c]
            a2 = p[3 * k + 2, c]
            centres[k, c] = (a0 + a1 + a2) / 3.0
            frames[k, c, 0] = (2.0 * a0 - a1 - a2) / (3.0 * radius[k])
            frames[k, c, 1] = (a1 - a2) / (s3 * radius[k])
        d1 = frames[k, :, 0]
        d2 = frames[k, :, 1]
        frames[k, 0, 2] = d1[1] * d2[2] - d1[2] * d2[1]
        frames[k, 1, 2] = d1[2] * d2[0] - d1[0] * d2[2]
        frames[k, 2, 2] = d1[0] * d2[1] - d1[1] * d2[0]


@numba.njit(cache=True)
def spread_loads(p, centres, F, tau, out):
    """Particle forces ``F/3 + a x x_i``, ``a = A^{-1} tau`` (see particles.loads_to_particle_forces)."""
    n = centres.shape[0]
    A = np.empty((3, 3))
    x = np.empty((3, 3))
    for k in range(n):
        for i in range(3):
            for c in range(3):
                x[i, c] = p[3 * k + i, c] - centres[k, c]
        for a in range(3):
            for b in range(3):
                A[a, b] = 0.0
        for i in range(3):
            r2 = x[i, 0] ** 2 + x[i, 1] ** 2 + x[i, 2] ** 2
            for a in range(3):
                A[a, a] += r2
                for b in range(3):
                    A[a, b] -= x[i, a] * x[i, b]
        # Solve A a = tau by Cramer's rule (A is symmetric positive definite for a triangle).
        det = (A[0, 0] * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]) - A[0, 1] * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
               + A[0, 2] * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0]))
        t0, t1, t2 = tau[k, 0], tau[k, 1], tau[k, 2]
        a0 = (t0 * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1]) - A[0, 1] * (t1 * A[2, 2] - A[1, 2] * t2)
              + A[0, 2] * (t1 * A[2, 1] - A[1, 1] * t2)) / det
        a1 = (A[0, 0] * (t1 * A[2, 2] - A[1, 2] * t2) - t0 * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
              + A[0, 2] * (A[1, 0] * t2 - t1 * A[2, 0])) / det
        a2 = (A[0, 0] * (A[1, 1] * t2 - t1 * A[2, 1]) - A[0, 1] * (A[1, 0] * t2 - t1 * A[2, 0])
              + t0 * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0])) / det
        for i in range(3):
            out[3 * k + i, 0] = F[k, 0] / 3.0 + a1 * x[i, 2] - a2 * x[i, 1]
            out[3 * k + i, 1] = F[k, 1] / 3.0 + a2 * x[i, 0] - a0 * x[i, 2]
            out[3 * k + i, 2] = F[k, 2] / 3.0 + a0 * x[i, 1] - a1 * x[i, 0]


@numba.njit(cache=True)
def elastic_particle_kernel_centres(p, radius, K, xi0, ds, Q, t, circular, out, centres):
    """:func:`elastic_particle_kernel` that also returns the node centres in ``centres`` (n, 3)."""
    n = radius.shape[0]
    frames = np.empty((n, 3, 3))
    _frames_from_particles(p, radius, centres, frames)
    F = np.zeros((n, 3))
    tau = np.zeros((n, 3))
    E = loads_kernel(centres, frames, K, xi0, ds, Q, t, circular, F, tau)
    spread_loads(p, centres, F, tau, out)
    return E


@numba.njit(cache=True)
def elastic_particle_kernel(p, radius, K, xi0, ds, Q, t, circular, out):
    """Energy and particle forces of the step energy from particle positions (fast path)."""
    centres = np.empty((radius.shape[0], 3))
    return elastic_particle_kernel_centres(p, radius, K, xi0, ds, Q, t, circular, out, centres)


class ElasticCallback:
    """Picklable PythonForce computation: the step energy through the numba kernel.

    With ``nonbonded`` (a :class:`dnarod.engines.openmm.nonbonded.NonbondedCallback`) the same callback
    also adds the non-local terms from the node centres it has just computed, so one
    ``PythonForce`` (one State hand-over per step) carries both; the per-term energies are
    recorded in ``last_energy`` and ``nonbonded.last``.
    """

    def __init__(self, model, radius, nonbonded=None):
        self.radius = np.ascontiguousarray(radius, dtype=float)
        self.K = np.ascontiguousarray(model.params.stiffness, dtype=float)
        self.xi0 = np.ascontiguousarray(model.params.intrinsic, dtype=float)
        self.ds = float(model.ds)
        self.circular = model.closure is not None
        self.Q = np.eye(3) if model.closure is None else np.ascontiguousarray(model.closure.Q, float)
        self.t = np.zeros(3) if model.closure is None else np.ascontiguousarray(model.closure.t, float)
        self.nonbonded = nonbonded
        self._buffers()
        self.last_energy = 0.0

    def _buffers(self):
        self._out = np.zeros((3 * self.radius.size, 3))
        self._centres = np.zeros((self.radius.size, 3))

    def __call__(self, state):
        p = np.ascontiguousarray(state.getPositions(asNumpy=True)._value, dtype=float)
        out = self._out
        E = elastic_particle_kernel_centres(p, self.radius, self.K, self.xi0, self.ds, self.Q, self.t, self.circular,
                                            out, self._centres)
        self.last_energy = E
        if self.nonbonded is not None:
            E = E + self.nonbonded.add_to_particles(self._centres, out)
        return E, out.copy()

    def __getstate__(self):
        d = dict(self.__dict__)
        d.pop("_out")
        d.pop("_centres")
        return d

    def __setstate__(self, d):
        self.__dict__.update(d)
        self._buffers()


def elastic_python_force(model, radius, callback=None):
    """The fast CPU path: an ``openmm.PythonForce`` evaluating the analytic loads (and, if the
    callback carries them, the non-local terms).

    Parameters
    ----------
    model : RodModel
    radius : ndarray, shape (n_nodes,)
        nm.
    callback : ElasticCallback, optional
        The computation (default: a new one); it records ``last_energy``.

    Returns
    -------
    openmm.PythonForce
        In force group ``GROUPS["elastic"]``.
    """
    if not hasattr(openmm, "PythonForce"):
        raise ParameterError("this OpenMM has no PythonForce (needs OpenMM >= 8.3); use elastic='portable'")
    f = python_force(callback if callback is not None else ElasticCallback(model, radius))
    f.setForceGroup(GROUPS["elastic"])
    fused = callback is not None and callback.nonbonded is not None
    f.setName("dnarod elastic + nonbonded (fast)" if fused else "dnarod elastic (fast)")
    return f
