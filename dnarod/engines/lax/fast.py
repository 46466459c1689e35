"""Numba kernel of the splitting integrator: loads and update fused into one sweep per time step.

Why our own kernel: no maintained library integrates SE(3)^N rods with the exact Cayley-strain
loads of docs/formulation.md §4, and per-step numpy (many small temporaries) runs an order of magnitude
slower than the target. Each time step is one pass over the chain: step k's stresses are
computed from the current pose, node k's loads are then complete, so its momenta are kicked
(second half of the previous step, first half of this one) and it is drifted and rotated at
once, while it is still in cache. The arithmetic is the same as :class:`.splitting.NumpyKernel`
(which uses :func:`dnarod.core.energy.loads`), and the tests check the two agree to 1e-12.

Circular chains: node 0 is needed by the closing step, so its update is deferred to the end of
the sweep.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from dnarod.core.kernels import _FM
from dnarod.core.kernels import chain_loads
from dnarod.core.kernels import step_loads as _step_loads
from dnarod.engines.lax.splitting_limits import MOMENTUM_LIMIT

_MOM2 = MOMENTUM_LIMIT**2



@njit(cache=True, inline="always", fastmath=_FM)
def _sincos(x):
    """sin(x), cos(x): Taylor polynomials (truncation < 1e-19) for |x| < 0.8, libm beyond.

    Rotor angles per sub-step are |h pi_a / J_a| <~ 0.3 rad at useful time steps, where the
    polynomials are both exact to rounding and three times cheaper than two libm calls."""
    if abs(x) < 0.8:
        x2 = x * x
        s = x * (1.0 + x2 * (-1.0 / 6 + x2 * (1.0 / 120 + x2 * (-1.0 / 5040 + x2 * (1.0 / 362880 + x2 * (
            -1.0 / 39916800 + x2 * (1.0 / 6227020800 + x2 * (-1.0 / 1307674368000 + x2 * (
                1.0 / 355687428096000)))))))))
        c = 1.0 + x2 * (-0.5 + x2 * (1.0 / 24 + x2 * (-1.0 / 720 + x2 * (1.0 / 40320 + x2 * (
            -1.0 / 3628800 + x2 * (1.0 / 479001600 + x2 * (-1.0 / 87178291200 + x2 * (
                1.0 / 20922789888000 + x2 * (-1.0 / 6402373705728000)))))))))
        return s, c
    return np.sin(x), np.cos(x)


@njit(cache=True, inline="always", fastmath=_FM)
def _sub(xb0, xb1, xb2, xd0, xd1, xd2, pb, pd, phi):
    """Exact free-rotor sub-flow by angle phi about body axis a: rotates frame columns b, d and
    body momenta pi_b, pi_d (b, d the two other axes, cyclic)."""
    s, c = _sincos(phi)
    return (c * xb0 + s * xd0, c * xb1 + s * xd1, c * xb2 + s * xd2,
            c * xd0 - s * xb0, c * xd1 - s * xb1, c * xd2 - s * xb2,
            c * pb + s * pd, c * pd - s * pb)


@njit(cache=True, inline="always", fastmath=_FM)
def _rotor_node(frm, pi, invJ, k, h):
    """Free-rotor flow of node k for time h: R1(h/2) R2(h/2) R3(h) R2(h/2) R1(h/2), in registers."""
    f00, f01, f02 = frm[k, 0, 0], frm[k, 0, 1], frm[k, 0, 2]
    f10, f11, f12 = frm[k, 1, 0], frm[k, 1, 1], frm[k, 1, 2]
    f20, f21, f22 = frm[k, 2, 0], frm[k, 2, 1], frm[k, 2, 2]
    p0, p1, p2 = pi[k, 0], pi[k, 1], pi[k, 2]
    j0, j1, j2 = invJ[k, 0], invJ[k, 1], invJ[k, 2]
    hh = 0.5 * h
    # R1(h/2): axis 0 rotates columns 1, 2
    f01, f11, f21, f02, f12, f22, p1, p2 = _sub(f01, f11, f21, f02, f12, f22, p1, p2, hh * p0 * j0)
    # R2(h/2): axis 1 rotates columns 2, 0
    f02, f12, f22, f00, f10, f20, p2, p0 = _sub(f02, f12, f22, f00, f10, f20, p2, p0, hh * p1 * j1)
    # R3(h): axis 2 rotates columns 0, 1
    f00, f10, f20, f01, f11, f21, p0, p1 = _sub(f00, f10, f20, f01, f11, f21, p0, p1, h * p2 * j2)
    f02, f12, f22, f00, f10, f20, p2, p0 = _sub(f02, f12, f22, f00, f10, f20, p2, p0, hh * p1 * j1)
    f01, f11, f21, f02, f12, f22, p1, p2 = _sub(f01, f11, f21, f02, f12, f22, p1, p2, hh * p0 * j0)
    frm[k, 0, 0], frm[k, 0, 1], frm[k, 0, 2] = f00, f01, f02
    frm[k, 1, 0], frm[k, 1, 1], frm[k, 1, 2] = f10, f11, f12
    frm[k, 2, 0], frm[k, 2, 1], frm[k, 2, 2] = f20, f21, f22
    pi[k, 0], pi[k, 1], pi[k, 2] = p0, p1, p2


@njit(cache=True, inline="always")
def _momentum_ok(P, pi, k):
    """False if a momentum of node k is NaN, infinite or beyond MOMENTUM_LIMIT (a blow-up)."""
    p2 = P[k, 0] * P[k, 0] + P[k, 1] * P[k, 1] + P[k, 2] * P[k, 2]
    l2 = pi[k, 0] * pi[k, 0] + pi[k, 1] * pi[k, 1] + pi[k, 2] * pi[k, 2]
    return p2 < _MOM2 and l2 < _MOM2


@njit(cache=True, inline="always", fastmath=_FM)
def _kick(P, pi, frm, F, tau, k, h):
    """Half kick of node k: lab momentum by h F, body angular momentum by h L^T tau."""
    for a in range(3):
        P[k, a] += h * F[k, a]
    for a in range(3):
        pi[k, a] += h * (frm[k, 0, a] * tau[k, 0] + frm[k, 1, a] * tau[k, 1] + frm[k, 2, a] * tau[k, 2])


@njit(cache=True, inline="always", fastmath=_FM)
def _advance(pos, frm, P, pi, inv_m, invJ, k, dt, langevin, c, sigP, sigpi, noise, i):
    """Drift and free rotor of node k (NVE), or A O A of BAOAB (Langevin)."""
    if not langevin:
        for a in range(3):
            pos[k, a] += dt * P[k, a] * inv_m[k]
        _rotor_node(frm, pi, invJ, k, dt)
    else:
        h = 0.5 * dt
        for a in range(3):
            pos[k, a] += h * P[k, a] * inv_m[k]
        _rotor_node(frm, pi, invJ, k, h)
        for a in range(3):
            P[k, a] = c * P[k, a] + sigP[k] * noise[i, a, k]
            pi[k, a] = c * pi[k, a] + sigpi[k, a] * noise[i, 3 + a, k]
        for a in range(3):
            pos[k, a] += h * P[k, a] * inv_m[k]
        _rotor_node(frm, pi, invJ, k, h)


@njit(cache=True, fastmath=_FM)
def compute_loads(pos, frm, K, xi0, ds, circular, Q, tvec, Fext, tauext, free, F, tau):
    """Energy and lab loads (in place into F, tau) of a pose; returns (E, bad_step or -1)."""
    n = pos.shape[0]
    for k in range(n):
        for a in range(3):
            F[k, a] = Fext[k, a]
            tau[k, a] = tauext[k, a]
    E, bad = chain_loads(pos, frm, K, xi0, ds, Q, tvec, circular, F, tau)
    if bad >= 0:
        return E, bad
    for k in range(n):
        for a in range(3):
            F[k, a] *= free[k]
            tau[k, a] *= free[k]
    return E, -1


@njit(cache=True, fastmath=_FM)
def run_steps(pos, frm, P, pi, F, tau, inv_m, invJ, free, Fext, tauext, K, xi0, ds, circular, Q, tvec,
              dt, n_steps, langevin, c, sigP, sigpi, noise):
    """Advance n_steps steps in place. F, tau hold the loads of the current pose on entry and exit.

    Returns (status, step index, node, energy): status 0 ok; 1 a step rotation at/beyond the Cayley
    limit or non-finite (node = left node of that step); 2 momentum non-finite or beyond
    MOMENTUM_LIMIT at that node.
    """
    n = pos.shape[0]
    m = K.shape[0]
    h = 0.5 * dt
    out = np.empty(13)
    E = np.nan
    if n_steps <= 0:
        return 0, 0, -1, E
    # first half-kick and drift of step 0
    for k in range(n):
        _kick(P, pi, frm, F, tau, k, h)
        _advance(pos, frm, P, pi, inv_m, invJ, k, dt, langevin, c, sigP, sigpi, noise, 0)
    cF = np.zeros(3)
    cT = np.zeros(3)
    for i in range(n_steps):
        last = i == n_steps - 1
        E = 0.0
        for a in range(3):
            cF[a] = 0.0
            cT[a] = 0.0
        for k in range(n):
            for a in range(3):
                F[k, a] = Fext[k, a] + cF[a]
                tau[k, a] = tauext[k, a] + cT[a]
                cF[a] = 0.0
                cT[a] = 0.0
            if k < m:
                img = circular and k == n - 1
                j = 0 if img else k + 1
                if not _step_loads(pos, frm, K, xi0, ds, k, img, j, Q, tvec, out):
                    return 1, i, k, E
                E += out[12]
                for a in range(3):
                    F[k, a] += out[a]
                    tau[k, a] += out[3 + a]
                if img:
                    for a in range(3):
                        F[0, a] += Q[0, a] * out[6] + Q[1, a] * out[7] + Q[2, a] * out[8]
                        tau[0, a] += Q[0, a] * out[9] + Q[1, a] * out[10] + Q[2, a] * out[11]
                else:
                    for a in range(3):
                        cF[a] = out[6 + a]
                        cT[a] = out[9 + a]
            for a in range(3):
                F[k, a] *= free[k]
                tau[k, a] *= free[k]
            if circular and k == 0:
                continue  # node 0 is finished after the closing step
            # node k's loads are complete: finish step i, start step i + 1
            _kick(P, pi, frm, F, tau, k, h)
            if not _momentum_ok(P, pi, k):
                return 2, i, k, E
            if not last:
                _kick(P, pi, frm, F, tau, k, h)
                _advance(pos, frm, P, pi, inv_m, invJ, k, dt, langevin, c, sigP, sigpi, noise, i + 1)
        if circular:
            _kick(P, pi, frm, F, tau, 0, h)
            if not _momentum_ok(P, pi, 0):
                return 2, i, 0, E
            if not last:
                _kick(P, pi, frm, F, tau, 0, h)
                _advance(pos, frm, P, pi, inv_m, invJ, 0, dt, langevin, c, sigP, sigpi, noise, i + 1)
    return 0, n_steps, -1, E
