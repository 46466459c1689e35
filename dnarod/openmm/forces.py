"""The SMK step energy as OpenMM forces (design A1, A2, Part C item 5).

Two interchangeable implementations of ``E = sum_k ds H(Omega_k, Gamma_k)`` on the
three-particle nodes of :mod:`dnarod.openmm.particles`:

* :func:`elastic_compound_forces` -- the **portable path**: a ``CustomCompoundBondForce`` over
  the six particles of neighbouring nodes, written with the dot-product form of A1 as a sum of
  six squares (Cholesky factor of the stiffness; see :func:`elastic_expression`), per-bond
  parameters ``dnarod_Pab`` (the scaled Cholesky factor; entries that are zero on every step
  are left out of the expression), ``dnarod_c1..6`` (the factor times the intrinsic strains)
  and the reverse-map scales ``dnarod_ua = 1/(3 l_k)``, ``dnarod_va = 1/(sqrt(3) l_k)``
  (``ub``, ``vb`` for node k+1). Runs on every OpenMM platform. A circular
  chain adds a second force of one bond whose second node is the screw image of node 0,
  ``p -> Q p + t`` (per-bond ``dnarod_Q11..33``, ``dnarod_t1..3``): the directors of the image
  are ``Q d_a(0)`` and its centre ``Q c_0 + t``, exactly as in :mod:`dnarod.strains`.
* :func:`elastic_python_force` -- the **fast CPU path**: an ``openmm.PythonForce`` whose
  callback runs a numba kernel of the analytic loads of A2 (tested equal to
  :func:`dnarod.energy.loads`) and spreads each node's force and torque over its particles
  (:func:`dnarod.openmm.particles.loads_to_particle_forces`).

The two paths give the same energy and the same total force and torque on every node; their
per-particle forces differ only by components along the constraint directions, which the
rigid-body constraints absorb, so the constrained dynamics are identical.
"""
from __future__ import annotations

import numba
import numpy as np
import openmm

from ..errors import ParameterError
from ..kernels import loads_kernel  # noqa: F401 (one compiled home of the A2 loads)
from .particles import SQRT3

#: Force groups used by the engine (energies are attributed per group on a blow-up).
GROUPS = {"elastic": 1, "nonbonded": 2, "external": 3}



def _det(u, v, w):
    """Triple product ``u . (v x w)`` of three vectors named by prefix (components x, y, z)."""
    return (f"({u}x*({v}y*{w}z - {v}z*{w}y) + {u}y*({v}z*{w}x - {v}x*{w}z) + {u}z*({v}x*{w}y - {v}y*{w}x))")


def _dot(u, v):
    return f"({u}x*{v}x + {u}y*{v}y + {u}z*{v}z)"


def elastic_expression(used, image=False):
    """The energy expression of one step (Cholesky form).

    With ``K = R^T R`` (R upper triangular) the step energy ``ds/2 u^T K u`` is
    ``v1^2 + ... + v6^2``, ``v_a = sqrt(ds/2) sum_{b >= a} R_ab u_b``: each strain enters
    only the rows ``a <= b``, so the rotation strains (the largest subexpressions, first in the
    strain order) are copied 1, 2 and 3 times instead of 6 in the expanded quadratic form, and
    Lepton (OpenMM's expression compiler, which substitutes every ';' definition and
    differentiates the whole tree with respect to the 18 coordinates) has several times fewer
    operations to build (``benchmarks/bench_portable.py``). The strains are written without
    cross products of directors: with the node vectors ``p = 2 x1 - x2 - x3 = 3 l d1``,
    ``q = x2 - x3 = sqrt(3) l d2`` (node a; ``r``, ``s`` for node b),
    ``d32 - d23 = (d1a + d1b).(d2a x d2b)`` and ``d13 - d31 = det(d1a, d1b, d2a + d2b)``
    (one triple product each), ``G3 = det(d1a, d2a, e)`` and
    ``1 + tr(R) = (1 + d11)(1 + d22) - d12 d21`` (Binet-Cauchy, ``d33 = d11 d22 - d12 d21``).
    Per-bond constants: ``dnarod_P_ab = sqrt(ds/2) R_ab (2/ds`` for rotation, ``1/ds`` for
    translation strains), ``dnarod_c_a = sqrt(ds/2) (R xi0)_a`` and the scales ``ua, va, ub,
    vb = 1/(3 l), 1/(sqrt(3) l)``.

    Parameters
    ----------
    used : list of (int, int)
        Entries ``(a, b)``, ``a <= b`` (0-based, strain order of
        :class:`~dnarod.parameters.StepParameters`) of R included in the expression.
    image : bool
        The second node is the screw image ``p -> Q p + t`` of the first node of the chain
        (per-bond ``dnarod_Q11..33``, ``dnarod_t1..3``).

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
        w = [f"dnarod_P{a + 1}{b + 1}*wt{b + 1}" for b in rows[a] if b < 3]
        g = [f"dnarod_P{a + 1}{b + 1}*gt{b - 2}" for b in rows[a] if b >= 3]
        parts = (["(" + " + ".join(w) + ")/D"] if w else []) + g
        lines.append(f"v{a + 1} = " + " + ".join(parts) + f" - dnarod_c{a + 1}")
        squares.append(f"v{a + 1}^2")
    lines.insert(0, " + ".join(squares) if squares else "0")
    # 2 (d32 - d23) = 2 va vb (ua p + ub r).(q x s),  2 (d13 - d31) = 2 ua ub det(p, r, va q + vb s)
    lines += ["wt1 = dnarod_va*dnarod_vb*" + _det("m", "q", "s"),
              "wt2 = dnarod_ua*dnarod_ub*" + _det("p", "r", "n"),
              "wt3 = d21 - d12", "D = (1 + d11)*(1 + d22) - d12*d21",
              f"d11 = dnarod_ua*dnarod_ub*{_dot('p', 'r')}", f"d22 = dnarod_va*dnarod_vb*{_dot('q', 's')}",
              f"d12 = dnarod_ua*dnarod_vb*{_dot('p', 's')}", f"d21 = dnarod_va*dnarod_ub*{_dot('q', 'r')}",
              f"gt1 = dnarod_ua*{_dot('p', 'e')}", f"gt2 = dnarod_va*{_dot('q', 'e')}",
              f"gt3 = dnarod_ua*dnarod_va*{_det('p', 'q', 'e')}"]
    lines += [f"m{c} = dnarod_ua*p{c} + dnarod_ub*r{c}" for c in "xyz"]
    lines += [f"n{c} = dnarod_va*q{c} + dnarod_vb*s{c}" for c in "xyz"]
    lines += [f"e{c} = (cb{c} - {c}1 - {c}2 - {c}3)/3" for c in "xyz"]
    lines += [f"p{c} = 2*{c}1 - {c}2 - {c}3" for c in "xyz"] + [f"q{c} = {c}2 - {c}3" for c in "xyz"]
    if image:
        for i, c in enumerate("xyz"):
            Q = [f"dnarod_Q{i + 1}{j + 1}" for j in range(3)]
            lines.append(f"r{c} = {Q[0]}*rrx + {Q[1]}*rry + {Q[2]}*rrz")
            lines.append(f"s{c} = {Q[0]}*ssx + {Q[1]}*ssy + {Q[2]}*ssz")
            lines.append(f"cb{c} = {Q[0]}*(x4 + x5 + x6) + {Q[1]}*(y4 + y5 + y6) + {Q[2]}*(z4 + z5 + z6) "
                         f"+ 3*dnarod_t{i + 1}")
        lines += [f"rr{c} = 2*{c}4 - {c}5 - {c}6" for c in "xyz"] + [f"ss{c} = {c}5 - {c}6" for c in "xyz"]
    else:
        lines += [f"cb{c} = {c}4 + {c}5 + {c}6" for c in "xyz"]
        lines += [f"r{c} = 2*{c}4 - {c}5 - {c}6" for c in "xyz"] + [f"s{c} = {c}5 - {c}6" for c in "xyz"]
    return "; ".join(lines)


def cholesky_parameters(stiffness, intrinsic, ds):
    """Per-step constants of :func:`elastic_expression`: ``P`` (n, 6, 6) and ``c`` (n, 6).

    Raises
    ------
    ParameterError
        If a step's stiffness is not symmetric positive definite (naming the step).
    """
    K = np.asarray(stiffness, float)
    R = np.empty_like(K)
    for k in range(K.shape[0]):
        try:
            R[k] = np.linalg.cholesky(0.5 * (K[k] + K[k].T)).T
        except np.linalg.LinAlgError:
            raise ParameterError(f"step {k}: the stiffness matrix is not positive definite; the portable path "
                                 f"needs K = R^T R (fix the parameter set)") from None
    h = np.sqrt(0.5 * ds)
    col = np.array([2 / ds] * 3 + [1 / ds] * 3)
    P = h * R * col[None, None, :]
    c = h * np.einsum("kab,kb->ka", R, np.asarray(intrinsic, float))
    return P, c


def used_stiffness_pairs(stiffness, steps=None):
    """Upper-triangle stiffness entries that are non-zero on at least one step."""
    K = np.asarray(stiffness)[steps] if steps is not None else np.asarray(stiffness)
    return [(i, j) for i in range(6) for j in range(i, 6) if np.any(K[:, i, j] != 0)]


#: Largest number of Cholesky entries kept in one force by default (21: never split). Lepton's work
#: grows faster than linearly with the expression, so one force per factor row compiles faster
#: (full K, 100 nodes, Reference: Context 1.69 -> 1.05 CPU-s; Lepton alone 1.18 -> 0.40 s), but
#: the rows no longer share subexpressions and a step costs 3.5x more (0.185 -> 0.645 ms), so the
#: split is an option (``split=True``), not the default.
MAX_ENTRIES_PER_FORCE = 21


def elastic_compound_forces(model, radius, split=None):
    """The portable path: CustomCompoundBondForce(s) carrying the step energy.

    Parameters
    ----------
    model : RodModel
    radius : ndarray, shape (n_nodes,)
        Triangle circumradius of every node, nm.
    split : bool or None
        One force per row of the Cholesky factor (``v_a^2``; faster to compile, slower to
        run); ``None``: split when more than :data:`MAX_ENTRIES_PER_FORCE` entries are used.

    Returns
    -------
    list of openmm.CustomCompoundBondForce
        For an open chain one force (or one per factor row); a circular chain adds the same for
        its closing step. All in force group ``GROUPS["elastic"]``.
    """
    n = model.n_nodes
    P, c = cholesky_parameters(model.params.stiffness, model.params.intrinsic, model.ds)
    inner = np.arange(n - 1)
    forces = []
    blocks = [(inner, False)] + ([(np.array([n - 1]), True)] if model.closure is not None else [])
    for steps, image in blocks:
        if steps.size == 0:
            continue
        used = used_stiffness_pairs(P, steps)  # entries of the Cholesky factor (zero pattern of K, no fill-in)
        do_split = len(used) > MAX_ENTRIES_PER_FORCE if split is None else bool(split)
        all_rows = sorted({a for a, _ in used})
        for rows in ([[a] for a in all_rows] if do_split else [all_rows]):
            pairs = [(a, b) for a, b in used if a in rows]
            f = openmm.CustomCompoundBondForce(6, elastic_expression(pairs, image))
            names = [f"dnarod_P{a + 1}{b + 1}" for a, b in pairs] + [f"dnarod_c{a + 1}" for a in rows]
            names += ["dnarod_ua", "dnarod_va", "dnarod_ub", "dnarod_vb"]
            if image:
                names += [f"dnarod_Q{r}{c_}" for r in (1, 2, 3) for c_ in (1, 2, 3)] + ["dnarod_t1", "dnarod_t2",
                                                                                        "dnarod_t3"]
            for name in names:
                f.addPerBondParameter(name)
            for k in steps:
                k1 = (k + 1) % n
                vals = [P[k, a, b] for a, b in pairs] + [c[k, a] for a in rows]
                vals += [1 / (3 * radius[k]), 1 / (SQRT3 * radius[k]), 1 / (3 * radius[k1]),
                         1 / (SQRT3 * radius[k1])]
                if image:
                    vals += list(model.closure.Q.reshape(-1)) + list(model.closure.t)
                f.addBond([3 * k, 3 * k + 1, 3 * k + 2, 3 * k1, 3 * k1 + 1, 3 * k1 + 2], [float(v) for v in vals])
            f.setForceGroup(GROUPS["elastic"])
            f.setName("dnarod elastic (portable)" + (" closure" if image else "")
                      + (f" row {rows[0] + 1}" if do_split else ""))
            forces.append(f)
    return forces


# ----------------------------------------------------------------------------------------
# Fast path: numba kernel of the analytic loads (design A2)
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

    With ``nonbonded`` (a :class:`dnarod.openmm.nonbonded.NonbondedCallback`) the same callback
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
    f = openmm.PythonForce(callback if callback is not None else ElasticCallback(model, radius))
    f.setForceGroup(GROUPS["elastic"])
    fused = callback is not None and callback.nonbonded is not None
    f.setName("dnarod elastic + nonbonded (fast)" if fused else "dnarod elastic (fast)")
    return f
