"""Hessian, normal modes and the fastest frequency omega_max of a rod pose, with its loads.

Coordinates (6 per node): the lab translation ``dr_k`` (nm) and the rotation vector ``dtheta_k`` of
``L_k -> exp(hat(dtheta_k)) L_k`` (rad). This is a chart of SE(3)^n around the pose; the Hessian of
the energy in it is symmetric at any pose (the antisymmetric part ``hat(tau)/2`` of the derivative
of the lab torques is the chart's second-order term, so symmetrising the derivative of the loads
gives the chart Hessian exactly).

How: central differences of the analytic loads. Default: each step's 12x12 block from its own loads
(:func:`dnarod.core.kernels.step_loads`, 24 evaluations per step in one numba loop), plus traps (``k I``)
and rotation clamps (differences of their torque). For another engine's loads (``load_fn``, e.g.
the OpenMM forces in the ``dispersion`` check), nodes three apart (further on a ring where needed)
are perturbed together: 6 x 3 colours x 2 signs = 36 whole-chain evaluations. The step,
``1e-5 ds`` (translations) and ``1e-5 rad`` (rotations), gives a relative error of about 1e-10
(tests: dense differences of the numpy loads, second differences of the energy).

Mass weighting: ``q = (sqrt(m_k) dr_k, sqrt(J_k) * dphi_k)`` with ``dphi_k = L_k^T dtheta_k`` the body
rotation vector, so that the kinetic energy is ``|dq/dt|^2 / 2`` and the mode frequencies are the
square roots of the eigenvalues of the mass-weighted Hessian.

omega_max: ``omega_max^2`` is the largest eigenvalue, found by bisection on positive definiteness of
``sigma I - H_w`` (a block Cholesky factorisation that stops at the first non-positive pivot;
Sylvester's law of inertia), between the largest diagonal element (a Rayleigh quotient, a lower
bound) and the Gershgorin bound. Each factorisation costs O(n) (block bandwidth 1; 2 on a ring,
whose nodes are interleaved 0, n-1, 1, n-2, ... so that ring neighbours are at most two apart),
and bisection from a bracket of 1% (the largest eigenvalue of dense 16-node windows around the
stiffest nodes is a lower bound by interlacing) to a relative 1e-9 in omega^2 takes about 25 of them
(a failing one stops early).
This is exact to the tolerance, with no Krylov convergence issue at the clustered band edge of a
long chain (which made Lanczos slow). The 6x6-block Cholesky is hand-written (numba) because
LAPACK's banded ``pbtrf`` (scipy ``cholesky_banded``) cannot stop at the first failing pivot and
was slower in a measurement here (0.08-0.4 s vs 0.03 s for 1e5 nodes).

Boundary conditions: clamped nodes (:class:`dnarod.physics.loads.Clamp`) are removed (Dirichlet); traps and
rotation clamps add their stiffness; a circular chain couples node n-1 to node 0 through its
closure. Dead forces and torques have no stiffness in the lab chart.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from dnarod.core.errors import DnarodError
from dnarod.core.kernels import step_loads
from dnarod.core.errors import ParameterError
from dnarod.core.units import PN
from dnarod.physics.loads import RotationClamp, Trap, resolve_loads, rotation_clamp_load
from dnarod.core.rotations import rotation_about_axis

__all__ = ["hessian", "hessian_blocks", "omega_max", "normal_modes", "mass_matrix", "default_time_step",
           "DEFAULT_OMEGA_DT", "HessianBlocks"]

#: Default time step of both engines: omega_max * dt (docs/formulation.md §7; <= 0.25-0.5 for accuracy, the
#: leapfrog/velocity-Verlet stability limit is 2).
DEFAULT_OMEGA_DT = 0.4
#: Largest accepted omega_max * dt (90% of the leapfrog limit 2); the default is dnarod.physics.modes.DEFAULT_OMEGA_DT.
MAX_OMEGA_DT = 1.8
#: Relative finite-difference step (translations ``REL_STEP * ds`` nm, rotations ``REL_STEP`` rad).
REL_STEP = 1e-5


class HessianBlocks:
    """A block-tridiagonal (block-cyclic on a ring) symmetric Hessian.

    Attributes
    ----------
    diag : ndarray, shape (n, 6, 6)
        ``H[k, k]``.
    off : ndarray, shape (n, 6, 6)
        ``H[k, k+1]`` (``off[n-1] = H[n-1, 0]`` on a ring, zero on an open chain).
    circular : bool
    free : ndarray of bool, shape (n,)
        False for clamped nodes (their rows and columns are zero).
    mass_weighted : bool
    """

    def __init__(self, diag, off, circular, free, mass_weighted, asymmetry=None):
        self.diag, self.off, self.circular, self.free, self.mass_weighted = diag, off, circular, free, mass_weighted
        #: max |H - H^T| / max |H| of the raw differences (coloured path only), before symmetrisation
        self.asymmetry = asymmetry

    @property
    def n_nodes(self):
        return self.diag.shape[0]

    def to_sparse(self, free_only=False):
        """scipy.sparse CSR matrix (6n, 6n) (or of the free dofs only)."""
        import scipy.sparse as sp

        n = self.n_nodes
        rows, cols, vals = [], [], []
        a = np.arange(6)
        base = 6 * np.arange(n)
        R = (base[:, None, None] + a[None, :, None]) * np.ones((1, 1, 6), int)
        C = (base[:, None, None] + a[None, None, :]) * np.ones((1, 6, 1), int)
        rows.append(R.ravel()), cols.append(C.ravel()), vals.append(self.diag.ravel())
        m = n if self.circular else n - 1
        if m > 0:
            nxt = (np.arange(m) + 1) % n
            Ro = (base[:m, None, None] + a[None, :, None]) * np.ones((1, 1, 6), int)
            Co = (base[nxt][:, None, None] + a[None, None, :]) * np.ones((1, 6, 1), int)
            rows += [Ro.ravel(), Co.ravel()]
            cols += [Co.ravel(), Ro.ravel()]
            vals += [self.off[:m].ravel(), self.off[:m].ravel()]
        H = sp.coo_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))),
                          shape=(6 * n, 6 * n)).tocsr()
        if free_only:
            keep = np.repeat(self.free, 6)
            H = H[keep][:, keep]
        return H

    def block_rows(self):
        """Lower block rows ``BR[P, p - d] = H[perm[P], perm[P - d]]`` (n, p+1, 6, 6), p = 1 (open) or 2
        (ring, nodes interleaved 0, n-1, 1, n-2, ...), and the node order ``perm``."""
        n = self.n_nodes
        if not self.circular:
            BR = np.empty((n, 2, 6, 6))
            BR[0, 0] = 0.0
            BR[1:, 0] = np.swapaxes(self.off[:-1], 1, 2)
            BR[:, 1] = self.diag
            return BR, np.arange(n)
        perm = np.empty(n, int)
        perm[0::2] = np.arange((n + 1) // 2)
        perm[1::2] = n - 1 - np.arange(n // 2)
        BR = np.zeros((n, 3, 6, 6))
        for d in (2, 1):
            u = perm
            v = np.roll(perm, d)
            fwd = (u + 1) % n == v
            bwd = (v + 1) % n == u
            fwd[:d] = bwd[:d] = False
            BR[fwd, 2 - d] = self.off[u[fwd]]
            BR[bwd, 2 - d] += np.swapaxes(self.off[v[bwd]], 1, 2)
        BR[:, 2] = self.diag[perm]
        return BR, perm

@njit(cache=True)
def _rotate_lab(frm, P, node, b, phi):
    """P[node] = Rot(e_b, phi) @ frm[node] (rotation about lab axis b)."""
    c = np.cos(phi)
    s = np.sin(phi)
    b1 = (b + 1) % 3
    b2 = (b + 2) % 3
    for col in range(3):
        x1 = frm[node, b1, col]
        x2 = frm[node, b2, col]
        P[node, b, col] = frm[node, b, col]
        P[node, b1, col] = c * x1 - s * x2
        P[node, b2, col] = s * x1 + c * x2


@njit(cache=True)
def _step_hessians(pos, frm, K, xi0, ds, Q, t, circular, h_t, h_r, Hd, Ho):
    """Lab-chart Hessian blocks from central differences of each step's loads (docs/formulation.md §4).

    Hd (n, 6, 6) += H[k, k]; Ho (n, 6, 6) += H[k, k+1] (symmetrised, ring closure included).
    Returns -1 or the first step at/beyond the Cayley limit.
    """
    n = pos.shape[0]
    m = n if circular else n - 1
    out_p = np.empty(13)
    out_m = np.empty(13)
    P = pos.copy()
    Fm = frm.copy()
    G = np.empty((12, 12))
    for k in range(m):
        img = circular and k == n - 1
        j = 0 if img else k + 1
        for col in range(12):
            node = k if col < 6 else j
            a = col % 6
            h = h_t if a < 3 else h_r
            for sgn in range(2):
                dv = h if sgn == 0 else -h
                if a < 3:
                    P[node, a] = pos[node, a] + dv
                else:
                    _rotate_lab(frm, Fm, node, a - 3, dv)
                ok = step_loads(P, Fm, K, xi0, ds, k, img, j, Q, t, out_p if sgn == 0 else out_m)
                if not ok:
                    return k
                # restore
                if a < 3:
                    P[node, a] = pos[node, a]
                else:
                    for r in range(3):
                        for c in range(3):
                            Fm[node, r, c] = frm[node, r, c]
            for r in range(12):
                G[r, col] = -(out_p[r] - out_m[r]) / (2.0 * h)
        if img:  # the right node's loads act on node 0 through Q^T
            for c in range(12):
                for blk in range(2):
                    v0 = G[6 + 3 * blk, c]
                    v1 = G[7 + 3 * blk, c]
                    v2 = G[8 + 3 * blk, c]
                    for r in range(3):
                        G[6 + 3 * blk + r, c] = Q[0, r] * v0 + Q[1, r] * v1 + Q[2, r] * v2
        for r in range(6):
            for c in range(6):
                Hd[k, r, c] += 0.5 * (G[r, c] + G[c, r])
                Hd[j, r, c] += 0.5 * (G[6 + r, 6 + c] + G[6 + c, 6 + r])
                Ho[k, r, c] += 0.5 * (G[r, 6 + c] + G[6 + c, r])
    return -1


@njit(cache=True, fastmath={"contract"})
def _block_cholesky_ok(BR, sigma, L):
    """True if ``sigma I - H`` is positive definite; H symmetric block-banded with 6x6 lower blocks
    ``BR[i, p - d] = H[i, i - d]`` (d = 0..p). Stops at the first non-positive pivot. L: workspace like BR."""
    n = BR.shape[0]
    p = BR.shape[1] - 1
    S = np.empty((6, 6))
    for i in range(n):
        for d in range(min(i, p), -1, -1):
            j = i - d
            for r in range(6):
                for c in range(6):
                    S[r, c] = -BR[i, p - d, r, c]
            if d == 0:
                for r in range(6):
                    S[r, r] += sigma
            for k in range(max(0, i - p), j):
                a = p - (i - k)
                b = p - (j - k)
                for r in range(6):
                    for c in range(6):
                        acc = 0.0
                        for q in range(6):
                            acc += L[i, a, r, q] * L[j, b, c, q]
                        S[r, c] -= acc
            if d == 0:
                for c in range(6):
                    v = S[c, c]
                    for q in range(c):
                        v -= L[i, p, c, q] * L[i, p, c, q]
                    if not v > 0.0:
                        return False
                    v = np.sqrt(v)
                    L[i, p, c, c] = v
                    for r in range(c + 1, 6):
                        w = S[r, c]
                        for q in range(c):
                            w -= L[i, p, r, q] * L[i, p, c, q]
                        L[i, p, r, c] = w / v
                    for r in range(c):
                        L[i, p, r, c] = 0.0
            else:
                # L[i, j] = S L[j, j]^-T
                for r in range(6):
                    for c in range(6):
                        w = S[r, c]
                        for q in range(c):
                            w -= L[i, p - d, r, q] * L[j, p, c, q]
                        L[i, p - d, r, c] = w / L[j, p, c, c]
    return True


def _frames_rotated(frames, idx, vecs):
    """``exp(hat(v)) L`` for the nodes ``idx`` (lab rotation vectors v, (m, 3))."""
    ang = np.linalg.norm(vecs, axis=1)
    axis = vecs / np.where(ang > 0, ang, 1.0)[:, None]
    axis[ang == 0] = (0.0, 0.0, 1.0)
    return rotation_about_axis(axis, ang) @ frames[idx]


def _colours(n, circular):
    """Colour of each node so that nodes of one colour are at least 3 apart (along the ring if circular)."""
    if not circular or n % 3 == 0:
        return np.arange(n) % 3
    col = np.full(n, -1)
    for k in range(n):
        used = {col[(k + d) % n] for d in (-2, -1, 1, 2) if col[(k + d) % n] >= 0}
        col[k] = min(c for c in range(6) if c not in used)
    return col


def _elastic_load_fn(model):
    from dnarod.core.kernels import loads_kernel

    K = np.ascontiguousarray(model.params.stiffness, float)
    xi0 = np.ascontiguousarray(model.params.intrinsic, float)
    circ = model.closure is not None
    Q = np.ascontiguousarray(model.closure.Q, float) if circ else np.eye(3)
    t = np.ascontiguousarray(model.closure.t, float) if circ else np.zeros(3)

    def fn(pos, frm):
        F = np.zeros(pos.shape)
        tau = np.zeros(pos.shape)
        E = loads_kernel(np.ascontiguousarray(pos), np.ascontiguousarray(frm), K, xi0, model.ds, Q, t, circ, F, tau)
        if not np.isfinite(E):
            from dnarod.core.errors import GeometryError

            raise GeometryError("a step rotation is at or beyond 180 deg; the Hessian is undefined at this pose")
        return F, tau

    return fn


def total_load_fn(model, loads=(), angles=None, resolved=None):
    """``fn(positions, frames) -> (F, tau)``: elastic plus external lab loads (kJ/mol/nm, kJ/mol)."""
    el = _elastic_load_fn(model)
    rl = resolve_loads(loads, model) if resolved is None else resolved
    if rl.empty:
        return el

    def fn(pos, frm):
        F, tau = el(pos, frm)
        _, Fe, te = rl.evaluate(pos, frm, angles)
        return F + Fe, tau + te

    return fn


def hessian_blocks(model, loads=(), positions=None, frames=None, mass_weighted=True, load_fn=None, angles=None,
                   rel_step=REL_STEP):
    """The Hessian as blocks (see :class:`HessianBlocks`).

    Parameters
    ----------
    model : RodModel
    loads : sequence of :mod:`dnarod.physics.loads` dataclasses
    positions, frames : ndarray, optional
        Pose (nm; directors as columns); default the model's.
    mass_weighted : bool
        Mass-weighted coordinates (units 1/ps^2) or lab ``(dr, dtheta)`` (kJ/mol per nm^2, nm rad, rad^2).
    load_fn : callable, optional
        ``fn(positions, frames) -> (F, tau)`` lab loads to differentiate (default: the exact elastic
        loads plus ``loads``); e.g. an engine's own forces.
    angles : sequence of float, optional
        Rotation clamp target angles, rad.
    rel_step : float
        Finite-difference step relative to ds (translations) and 1 rad (rotations).

    Returns
    -------
    HessianBlocks
    """
    pos = np.ascontiguousarray(model.positions if positions is None else positions, float)
    frm = np.ascontiguousarray(model.frames if frames is None else frames, float)
    n = pos.shape[0]
    circular = model.closure is not None
    if circular and n < 3:
        raise DnarodError(f"a circular chain needs at least 3 nodes for its Hessian, got {n}")
    rl = resolve_loads(loads, model, pos, frm)
    ht, hr = rel_step * model.ds, rel_step
    asym = None
    if load_fn is None:
        diag = np.zeros((n, 6, 6))
        off = np.zeros((n, 6, 6))
        K = np.ascontiguousarray(model.params.stiffness, float)
        xi0 = np.ascontiguousarray(model.params.intrinsic, float)
        Q = np.ascontiguousarray(model.closure.Q, float) if circular else np.eye(3)
        t = np.ascontiguousarray(model.closure.t, float) if circular else np.zeros(3)
        bad = _step_hessians(pos, frm, K, xi0, model.ds, Q, t, circular, ht, hr, diag, off)
        if bad >= 0:
            from dnarod.core.errors import GeometryError, step_name

            raise GeometryError(f"{step_name(bad, n)}: the rotation between its base pairs is at or beyond "
                                f"180 deg; the Hessian is undefined at this pose")
        _add_external(diag, rl, frm, angles, hr)
    else:
        diag, off, asym = _coloured_hessian(pos, frm, circular, load_fn, ht, hr)
    free = ~rl.clamped
    m = n if circular else n - 1
    nxt = (np.arange(m) + 1) % n
    if (~free).any():
        diag[~free] = 0.0
        off[~free] = 0.0
        prev_clamped = np.zeros(n, bool)
        prev_clamped[:m] = ~free[nxt]
        off[prev_clamped] = 0.0
    if mass_weighted:
        # B_k = blockdiag(I / sqrt(m_k), L_k diag(1/sqrt(J_k))): H_w[j, k] = B_j^T H[j, k] B_k
        B = np.zeros((n, 6, 6))
        B[:, :3, :3] = np.eye(3) / np.sqrt(model.mass)[:, None, None]
        B[:, 3:, 3:] = frm / np.sqrt(model.inertia)[:, None, :]
        BT = np.swapaxes(B, 1, 2)
        diag = BT @ diag @ B
        Bn = np.zeros_like(B)
        Bn[:m] = B[nxt]
        off = BT @ off @ Bn
        diag = 0.5 * (diag + np.swapaxes(diag, 1, 2))
    return HessianBlocks(diag, off, circular, free, mass_weighted, asym)


def _add_external(diag, rl, frm, angles, hr):
    """Add the stiffness of traps (``k I``) and rotation clamps (central differences of their torque)."""

    for k, kk, _ in rl.traps:
        diag[k, :3, :3] += kk * np.eye(3)
    for i, rc in enumerate(rl.rotation_clamps):
        T = rc.target(0.0 if angles is None else angles[i])
        G = np.empty((3, 3))
        for b in range(3):
            e = np.zeros(3)
            e[b] = 1.0
            tp = rotation_clamp_load(rotation_about_axis(e, hr) @ frm[rc.node], T, rc.k)[1]
            tm = rotation_clamp_load(rotation_about_axis(e, -hr) @ frm[rc.node], T, rc.k)[1]
            G[:, b] = -(tp - tm) / (2 * hr)
        diag[rc.node, 3:, 3:] += 0.5 * (G + G.T)


def _coloured_hessian(pos, frm, circular, fn, ht, hr):
    """Lab-chart Hessian blocks of an arbitrary load function by coloured central differences."""
    n = pos.shape[0]
    col = _colours(n, circular)
    H_self = np.zeros((n, 6, 6))
    H_next = np.zeros((n, 6, 6))   # H[j, j+1]
    H_prev = np.zeros((n, 6, 6))   # H[j, j-1]
    nodes = np.arange(n)
    for c in range(col.max() + 1):
        idx = np.flatnonzero(col == c)
        src = np.full(n, -1)
        rel = np.zeros(n, int)
        for d in (-1, 0, 1):
            nb = nodes + d
            if circular:
                nb = nb % n
            ok = (nb >= 0) & (nb < n)
            hit = np.zeros(n, bool)
            hit[ok] = col[nb[ok]] == c
            src[hit] = nb[hit]
            rel[hit] = d
        has = src >= 0
        for a in range(6):
            res = []
            for sgn in (1.0, -1.0):
                p2, f2 = pos.copy(), frm.copy()
                if a < 3:
                    p2[idx, a] += sgn * ht
                else:
                    e = np.zeros((len(idx), 3))
                    e[:, a - 3] = sgn * hr
                    f2[idx] = _frames_rotated(frm, idx, e)
                res.append(fn(p2, f2))
            h = ht if a < 3 else hr
            g = -np.concatenate([res[0][0] - res[1][0], res[0][1] - res[1][1]], axis=1)[has] / (2 * h)
            j = nodes[has]
            for d, target in ((0, H_self), (1, H_next), (-1, H_prev)):
                sel = rel[has] == d
                target[j[sel], :, a] = g[sel]
    diag = 0.5 * (H_self + np.swapaxes(H_self, 1, 2))
    off = np.zeros((n, 6, 6))
    m = n if circular else n - 1
    nxt = (np.arange(m) + 1) % n
    off[:m] = 0.5 * (H_next[:m] + np.swapaxes(H_prev[nxt], 1, 2))
    scale = max(np.abs(H_self).max(), np.abs(H_next).max(), 1e-300)
    asym = max(np.abs(H_self - np.swapaxes(H_self, 1, 2)).max(),
               np.abs(H_next[:m] - np.swapaxes(H_prev[nxt], 1, 2)).max() if m else 0.0) / scale
    return diag, off, float(asym)


def hessian(model, loads=(), positions=None, frames=None, mass_weighted=False, free_only=False, **kw):
    """Sparse symmetric Hessian (6n, 6n) (scipy CSR), block-banded (see :func:`hessian_blocks`).

    Lab coordinates ``(dr_k, dtheta_k)`` per node (kJ/mol/nm^2, kJ/mol/nm, kJ/mol/rad^2), or mass-weighted
    (1/ps^2) with ``mass_weighted=True``. Clamped nodes have zero rows and columns (removed with
    ``free_only``).
    """
    return hessian_blocks(model, loads, positions, frames, mass_weighted, **kw).to_sparse(free_only)


def mass_matrix(model, frames=None):
    """Sparse block-diagonal mass matrix (6n, 6n) in lab coordinates: ``m_k I`` and ``L_k diag(J_k) L_k^T``."""
    import scipy.sparse as sp

    frm = model.frames if frames is None else np.asarray(frames, float)
    n = frm.shape[0]
    blocks = np.zeros((n, 6, 6))
    blocks[:, :3, :3] = model.mass[:, None, None] * np.eye(3)
    blocks[:, 3:, 3:] = np.einsum("kab,kb,kcb->kac", frm, model.inertia, frm)
    return sp.block_diag(list(blocks), format="csr")


def _max_eigenvalue(blocks, rtol):
    D, O = blocks.diag, blocks.off
    lo = max(float(np.diagonal(D, axis1=1, axis2=2).max()), 0.0)   # largest diagonal (Rayleigh quotient)
    # Gershgorin: |row| of H[k, k], H[k, k+1] = off[k] and H[k, k-1] = off[k-1]^T
    absO = np.abs(O)
    rows = np.abs(D).sum(axis=2) + absO.sum(axis=2)
    prev = absO.sum(axis=1)                                          # column sums of off[k] -> rows of node k+1
    if blocks.circular:
        rows += np.roll(prev, 1, axis=0)
    else:
        rows[1:] += prev[:-1]
    BR, _ = blocks.block_rows()
    gersh = float(rows.max()) * (1.0 + 1e-12)
    if gersh <= 0:
        return 0.0
    L = np.empty_like(BR)
    # A tighter bracket: the largest eigenvalue of principal sub-blocks (windows of nodes around the
    # stiffest ones) is a lower bound (Cauchy interlacing) within ~1% of the chain's band edge.
    lo = max(lo, _window_lower_bound(blocks))
    hi = gersh
    gap = 1e-2 * lo
    while lo > 0 and lo + gap < gersh:
        if _block_cholesky_ok(BR, lo + gap, L):
            hi = lo + gap
            break
        lo, gap = lo + gap, 4 * gap
    while hi - lo > rtol * hi:
        mid = 0.5 * (lo + hi)
        if _block_cholesky_ok(BR, mid, L):
            hi = mid
        else:
            lo = mid
    return 0.5 * (lo + hi)


def _window_lower_bound(blocks, width=16, n_windows=3):
    """Largest eigenvalue of dense principal sub-blocks of ``width`` nodes around the nodes with the largest
    diagonal entries: a lower bound of the largest eigenvalue (interlacing)."""
    n = blocks.n_nodes
    w = min(width, n - 1 if blocks.circular else n)   # a window of a ring must not close on itself
    dmax = np.diagonal(blocks.diag, axis1=1, axis2=2).max(axis=1)
    best = 0.0
    starts = set()
    for k in np.argsort(dmax)[::-1][:n_windows]:
        starts.add(int(min(max(k - w // 2, 0), n - w)))
    for s0 in starts:
        H = np.zeros((6 * w, 6 * w))
        for i in range(w):
            H[6 * i:6 * i + 6, 6 * i:6 * i + 6] = blocks.diag[s0 + i]
            if i + 1 < w:
                H[6 * i:6 * i + 6, 6 * i + 6:6 * i + 12] = blocks.off[s0 + i]
                H[6 * i + 6:6 * i + 12, 6 * i:6 * i + 6] = blocks.off[s0 + i].T
        best = max(best, float(np.linalg.eigvalsh(H)[-1]))
    return best


def omega_max(model, loads=(), positions=None, frames=None, rtol=1e-9, load_fn=None, angles=None):
    """Largest normal-mode angular frequency of a pose with its loads, rad/ps.

    ``omega_max^2`` is the largest eigenvalue of the mass-weighted Hessian (see the module docstring),
    found by bisection on the Cholesky factorisability of ``sigma I - H_w`` to relative ``rtol`` in
    ``omega^2``; exact to that tolerance (plus the ~1e-10 finite-difference error of the Hessian).

    Parameters
    ----------
    model : RodModel
    loads : sequence of :mod:`dnarod.physics.loads` dataclasses
        Clamps remove nodes; traps and rotation clamps add stiffness.
    positions, frames : ndarray, optional
        Pose (default: the model's).
    rtol : float
        Relative bisection tolerance on ``omega_max^2``.
    load_fn, angles :
        See :func:`hessian_blocks`.

    Returns
    -------
    float
        rad/ps.
    """
    B = hessian_blocks(model, loads, positions, frames, True, load_fn=load_fn, angles=angles)
    return float(np.sqrt(max(_max_eigenvalue(B, rtol), 0.0)))


def default_time_step(model, loads=(), positions=None, frames=None, omega_dt=DEFAULT_OMEGA_DT):
    """Default time step of both engines, ``omega_dt / omega_max`` ps, and omega_max (rad/ps)."""
    w = omega_max(model, loads, positions, frames)
    if not w > 0:
        raise DnarodError("the model has no vibration (omega_max = 0); give the time step explicitly")
    return omega_dt / w, w


def normal_modes(model, loads=(), k=None, positions=None, frames=None, load_fn=None, angles=None):
    """Normal-mode angular frequencies and mode shapes of a pose with its loads.

    Parameters
    ----------
    model : RodModel
    loads : sequence of :mod:`dnarod.physics.loads` dataclasses
    k : int, optional
        Number of lowest modes (sparse shift-invert Lanczos, scipy ``eigsh``); default all (dense).
    positions, frames, load_fn, angles :
        See :func:`hessian_blocks`.

    Returns
    -------
    omega : ndarray, shape (m,)
        rad/ps, ascending; negative eigenvalues (unstable directions) give ``-sqrt|lambda|``.
    modes : ndarray, shape (m, n, 6)
        Lab displacements ``(dr nm, dtheta rad)`` per node, M-orthonormal (``x^T M x = 1``, amu nm^2);
        zero on clamped nodes.
    """
    B = hessian_blocks(model, loads, positions, frames, True, load_fn=load_fn, angles=angles)
    Hf = B.to_sparse(free_only=True)
    nf = Hf.shape[0]
    if k is None or k >= nf - 1:
        import scipy.linalg

        w2, vec = scipy.linalg.eigh(Hf.toarray())
    else:
        from scipy.sparse.linalg import eigsh

        shift = -1e-3 * max(float(np.abs(Hf.diagonal()).max()), 1e-300)
        w2, vec = eigsh(Hf.tocsc(), k=int(k), sigma=shift, which="LM")
        order = np.argsort(w2)
        w2, vec = w2[order], vec[:, order]
    pos_frm = model.frames if frames is None else np.asarray(frames, float)
    n = B.n_nodes
    q = np.zeros((vec.shape[1], n, 6))
    q[:, B.free, :] = vec.T.reshape(vec.shape[1], -1, 6)
    # back to lab displacements: dr = q / sqrt(m), dtheta = L (q_rot / sqrt(J))
    modes = np.empty_like(q)
    modes[:, :, :3] = q[:, :, :3] / np.sqrt(model.mass)[None, :, None]
    modes[:, :, 3:] = np.einsum("kab,mkb->mka", pos_frm, q[:, :, 3:] / np.sqrt(model.inertia)[None])
    return np.sign(w2) * np.sqrt(np.abs(w2)), modes


#: Largest ratio of the fastest mode with the loads to the free model's before a load's stiffness is refused:
#: 10 means a time step 10 times shorter (and a run 10 times longer) than the chain itself needs.
MAX_LOAD_OMEGA_RATIO = 10.0


#: How :func:`check_load_stiffness` names a stiff load by default: the ``dnarod simulate`` options.
STIFFNESS_OPTIONS = {"Trap": "--trap", "RotationClamp": "--rotation-clamp"}


def check_load_stiffness(model, loads, names=None, omega=None):
    """Refuse a trap or rotation clamp so stiff that its own vibration, not the chain's, sets the time step.

    The one bound on load stiffness (``dnarod simulate --trap/--rotation-clamp``, ensemble members, the protocols'
    ``--clamp-k``): the fastest normal mode with the loads (:func:`dnarod.physics.modes.omega_max`) may be at most
    :data:`MAX_LOAD_OMEGA_RATIO` times the fastest mode without the traps and rotation clamps. A stiffer load
    holds no better; the run would only be that many times longer. The message names the load and the largest
    stiffness within the ratio (the mode frequency grows as the square root of the stiffness).

    Parameters
    ----------
    model : RodModel
        The pose the loads act on.
    loads : sequence of load dataclasses
    names : dict, optional
        Load class name -> how to name it in the message (default :data:`STIFFNESS_OPTIONS`); a trap is shown as
        ``NAME NODE:K`` (K in pN/nm), a rotation clamp as ``NAME K`` (K in kJ/mol).
    omega : float, optional
        The fastest mode with the loads, rad/ps, if already known.

    Raises
    ------
    ParameterError
        One line naming the load, its stiffness and the largest accepted.
    """
    names = {**STIFFNESS_OPTIONS, **(names or {})}
    loads = tuple(loads)
    stiff = [ld for ld in loads if isinstance(ld, (Trap, RotationClamp))]
    if not stiff:
        return
    omega = float(omega_max(model, loads)) if omega is None else float(omega)
    free = float(omega_max(model, tuple(ld for ld in loads if not any(ld is s for s in stiff))))
    ratio = omega / free
    if not ratio > MAX_LOAD_OMEGA_RATIO:
        return
    parts = []
    for ld in stiff:
        if isinstance(ld, Trap):
            k = float(ld.k) / PN
            parts.append(f"{names['Trap']} {ld.node + 1 if ld.node >= 0 else ld.node}:{k:g} (pN/nm; use at most "
                         f"{k * (MAX_LOAD_OMEGA_RATIO / ratio) ** 2:.3g})")
        else:
            k = float(ld.k)
            parts.append(f"{names['RotationClamp']} {k:g} (kJ/mol; use at most "
                         f"{k * (MAX_LOAD_OMEGA_RATIO / ratio) ** 2:.3g})")
    raise ParameterError(f"{', '.join(parts)}: so stiff that its vibration ({omega:.3g} rad/ps) is {ratio:.3g} times "
                         f"the chain's fastest mode ({free:.3g} rad/ps) and sets the time step; a stiffer load holds "
                         f"no better, the run only gets longer")
