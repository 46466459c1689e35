"""Numba kernels of the core maths: the exact loads of one step (docs/formulation.md §4) and of a chain.

One compiled home for the A2 loads, shared by both engines' fast paths (the Lax-form splitting
kernels in :mod:`dnarod.engines.lax.fast` and the OpenMM ``PythonForce`` in
:mod:`dnarod.engines.openmm.forces`). :func:`dnarod.core.energy.loads` is the numpy reference; tests compare
them. Written with numba because no library provides these Cayley-strain loads, and per-step
numpy (many small temporaries) is an order of magnitude too slow for the engines' targets.
"""
from __future__ import annotations

import numpy as np
from numba import njit

from dnarod.core.rotations import MAX_CAYLEY_ANGLE

#: LLVM fast-math flags: contraction to FMA and reassociation, but NaN and Inf are kept
#: meaningful (no "nnan"/"ninf") so that blow-ups are still detected.
_FM = {"contract", "reassoc", "nsz", "arcp", "afn"}
_DEN_LIMIT = 2.0 * (1.0 + np.cos(MAX_CAYLEY_ANGLE))


@njit(cache=True, inline="always")
def pair_vector(pos, i, j):
    """Separation ``pos[j] - pos[i]`` of two nodes (nm) and its squared length: ``(dx, dy, dz, r2)``."""
    dx = pos[j, 0] - pos[i, 0]
    dy = pos[j, 1] - pos[i, 1]
    dz = pos[j, 2] - pos[i, 2]
    return dx, dy, dz, dx * dx + dy * dy + dz * dz


@njit(cache=True, inline="always", fastmath=_FM)
def lab_stresses(w0, w1, w2, M0, M1, M2, P0, P1, P2, L00, L01, L02, L10, L11, L12, L20, L21, L22):
    """Lab force ``n = L P`` and moment ``m = L T(w)^T M`` of a step (docs/formulation.md §4) from its Cayley
    vector ``w``, body stresses ``M`` (moment) and ``P`` (force) and left frame ``L`` (directors as columns);
    returns ``(n0, n1, n2, m0, m1, m2)``. Scalar arguments, so both the per-step and the lane-blocked kernels
    inline it as straight-line arithmetic."""
    wM = w0 * M0 + w1 * M1 + w2 * M2
    bm0 = M0 + 0.5 * (w1 * M2 - w2 * M1) + 0.25 * w0 * wM
    bm1 = M1 + 0.5 * (w2 * M0 - w0 * M2) + 0.25 * w1 * wM
    bm2 = M2 + 0.5 * (w0 * M1 - w1 * M0) + 0.25 * w2 * wM
    n0 = L00 * P0 + L01 * P1 + L02 * P2
    n1 = L10 * P0 + L11 * P1 + L12 * P2
    n2 = L20 * P0 + L21 * P1 + L22 * P2
    m0 = L00 * bm0 + L01 * bm1 + L02 * bm2
    m1 = L10 * bm0 + L11 * bm1 + L12 * bm2
    m2 = L20 * bm0 + L21 * bm1 + L22 * bm2
    return n0, n1, n2, m0, m1, m2


@njit(cache=True, inline="always", fastmath=_FM)
def step_loads(pos, frm, K, xi0, ds, k, j_is_image, j, Q, tvec, out):
    """Loads of step k on its left node (out[0:3] force, out[3:6] torque) and right node
    (out[6:9], out[9:12], in the right node's lab frame before the closure map), and its energy
    (out[12]). Returns False if the step rotation is at/beyond the Cayley limit or not finite.
    Scalar code only (no temporaries), so it compiles to straight-line arithmetic."""
    if j_is_image:
        x0 = tvec[0] + Q[0, 0] * pos[0, 0] + Q[0, 1] * pos[0, 1] + Q[0, 2] * pos[0, 2]
        x1 = tvec[1] + Q[1, 0] * pos[0, 0] + Q[1, 1] * pos[0, 1] + Q[1, 2] * pos[0, 2]
        x2 = tvec[2] + Q[2, 0] * pos[0, 0] + Q[2, 1] * pos[0, 1] + Q[2, 2] * pos[0, 2]
        # R = L_k^T Q L_0 = (Q^T L_k)^T L_0
        a00 = Q[0, 0] * frm[k, 0, 0] + Q[1, 0] * frm[k, 1, 0] + Q[2, 0] * frm[k, 2, 0]
        a10 = Q[0, 1] * frm[k, 0, 0] + Q[1, 1] * frm[k, 1, 0] + Q[2, 1] * frm[k, 2, 0]
        a20 = Q[0, 2] * frm[k, 0, 0] + Q[1, 2] * frm[k, 1, 0] + Q[2, 2] * frm[k, 2, 0]
        a01 = Q[0, 0] * frm[k, 0, 1] + Q[1, 0] * frm[k, 1, 1] + Q[2, 0] * frm[k, 2, 1]
        a11 = Q[0, 1] * frm[k, 0, 1] + Q[1, 1] * frm[k, 1, 1] + Q[2, 1] * frm[k, 2, 1]
        a21 = Q[0, 2] * frm[k, 0, 1] + Q[1, 2] * frm[k, 1, 1] + Q[2, 2] * frm[k, 2, 1]
        a02 = Q[0, 0] * frm[k, 0, 2] + Q[1, 0] * frm[k, 1, 2] + Q[2, 0] * frm[k, 2, 2]
        a12 = Q[0, 1] * frm[k, 0, 2] + Q[1, 1] * frm[k, 1, 2] + Q[2, 1] * frm[k, 2, 2]
        a22 = Q[0, 2] * frm[k, 0, 2] + Q[1, 2] * frm[k, 1, 2] + Q[2, 2] * frm[k, 2, 2]
    else:
        x0 = pos[j, 0]
        x1 = pos[j, 1]
        x2 = pos[j, 2]
        a00 = frm[k, 0, 0]
        a10 = frm[k, 1, 0]
        a20 = frm[k, 2, 0]
        a01 = frm[k, 0, 1]
        a11 = frm[k, 1, 1]
        a21 = frm[k, 2, 1]
        a02 = frm[k, 0, 2]
        a12 = frm[k, 1, 2]
        a22 = frm[k, 2, 2]
    # R_ab = (column a of the left frame, possibly Q^T-mapped) . (column b of frame j)
    R00 = a00 * frm[j, 0, 0] + a10 * frm[j, 1, 0] + a20 * frm[j, 2, 0]
    R01 = a00 * frm[j, 0, 1] + a10 * frm[j, 1, 1] + a20 * frm[j, 2, 1]
    R02 = a00 * frm[j, 0, 2] + a10 * frm[j, 1, 2] + a20 * frm[j, 2, 2]
    R10 = a01 * frm[j, 0, 0] + a11 * frm[j, 1, 0] + a21 * frm[j, 2, 0]
    R11 = a01 * frm[j, 0, 1] + a11 * frm[j, 1, 1] + a21 * frm[j, 2, 1]
    R12 = a01 * frm[j, 0, 2] + a11 * frm[j, 1, 2] + a21 * frm[j, 2, 2]
    R20 = a02 * frm[j, 0, 0] + a12 * frm[j, 1, 0] + a22 * frm[j, 2, 0]
    R21 = a02 * frm[j, 0, 1] + a12 * frm[j, 1, 1] + a22 * frm[j, 2, 1]
    R22 = a02 * frm[j, 0, 2] + a12 * frm[j, 1, 2] + a22 * frm[j, 2, 2]
    den = 1.0 + R00 + R11 + R22
    if not den > _DEN_LIMIT:
        return False
    iden = 2.0 / den
    w0 = (R21 - R12) * iden
    w1 = (R02 - R20) * iden
    w2 = (R10 - R01) * iden
    e0 = x0 - pos[k, 0]
    e1 = x1 - pos[k, 1]
    e2 = x2 - pos[k, 2]
    L00 = frm[k, 0, 0]
    L01 = frm[k, 0, 1]
    L02 = frm[k, 0, 2]
    L10 = frm[k, 1, 0]
    L11 = frm[k, 1, 1]
    L12 = frm[k, 1, 2]
    L20 = frm[k, 2, 0]
    L21 = frm[k, 2, 1]
    L22 = frm[k, 2, 2]
    inv = 1.0 / ds
    d0 = w0 * inv - xi0[k, 0]
    d1 = w1 * inv - xi0[k, 1]
    d2 = w2 * inv - xi0[k, 2]
    d3 = (L00 * e0 + L10 * e1 + L20 * e2) * inv - xi0[k, 3]
    d4 = (L01 * e0 + L11 * e1 + L21 * e2) * inv - xi0[k, 4]
    d5 = (L02 * e0 + L12 * e1 + L22 * e2) * inv - xi0[k, 5]
    Kk = K[k]
    M0 = Kk[0, 0] * d0 + Kk[0, 1] * d1 + Kk[0, 2] * d2 + Kk[0, 3] * d3 + Kk[0, 4] * d4 + Kk[0, 5] * d5
    M1 = Kk[1, 0] * d0 + Kk[1, 1] * d1 + Kk[1, 2] * d2 + Kk[1, 3] * d3 + Kk[1, 4] * d4 + Kk[1, 5] * d5
    M2 = Kk[2, 0] * d0 + Kk[2, 1] * d1 + Kk[2, 2] * d2 + Kk[2, 3] * d3 + Kk[2, 4] * d4 + Kk[2, 5] * d5
    P0 = Kk[3, 0] * d0 + Kk[3, 1] * d1 + Kk[3, 2] * d2 + Kk[3, 3] * d3 + Kk[3, 4] * d4 + Kk[3, 5] * d5
    P1 = Kk[4, 0] * d0 + Kk[4, 1] * d1 + Kk[4, 2] * d2 + Kk[4, 3] * d3 + Kk[4, 4] * d4 + Kk[4, 5] * d5
    P2 = Kk[5, 0] * d0 + Kk[5, 1] * d1 + Kk[5, 2] * d2 + Kk[5, 3] * d3 + Kk[5, 4] * d4 + Kk[5, 5] * d5
    H = d0 * M0 + d1 * M1 + d2 * M2 + d3 * P0 + d4 * P1 + d5 * P2
    n0, n1, n2, m0, m1, m2 = lab_stresses(w0, w1, w2, M0, M1, M2, P0, P1, P2,
                                          L00, L01, L02, L10, L11, L12, L20, L21, L22)
    out[0] = n0
    out[1] = n1
    out[2] = n2
    out[3] = m0 + e1 * n2 - e2 * n1
    out[4] = m1 + e2 * n0 - e0 * n2
    out[5] = m2 + e0 * n1 - e1 * n0
    out[6] = -n0
    out[7] = -n1
    out[8] = -n2
    out[9] = -m0
    out[10] = -m1
    out[11] = -m2
    out[12] = 0.5 * ds * H
    return True


@njit(cache=True)
def chain_loads(centres, frames, K, xi0, ds, Q, t, circular, F, tau):
    """Energy and lab loads of every node (docs/formulation.md §4), accumulated into ``F`` and ``tau``.

    Parameters
    ----------
    centres : (n, 3) nm;  frames : (n, 3, 3);  K : (m, 6, 6);  xi0 : (m, 6);  ds : float nm
    Q, t : closure rotation (3, 3) and translation (3,) (ignored unless ``circular``)
    circular : bool
    F, tau : (n, 3) arrays the loads are added to (kJ/mol/nm, kJ/mol)

    Returns
    -------
    E : float
        Energy, kJ/mol (of the steps before a failing one).
    bad : int
        -1, or the first step whose rotation is at or beyond the Cayley limit or not finite.
    """
    n = centres.shape[0]
    m = n if circular else n - 1
    out = np.empty(13)
    E = 0.0
    for k in range(m):
        img = circular and k == n - 1
        j = 0 if img else k + 1
        if not step_loads(centres, frames, K, xi0, ds, k, img, j, Q, t, out):
            return E, k
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
                F[j, a] += out[6 + a]
                tau[j, a] += out[9 + a]
    return E, -1


@njit(cache=True)
def loads_kernel(centres, frames, K, xi0, ds, Q, t, circular, F, tau):
    """As :func:`chain_loads`, returning only the energy: NaN if a step is at the Cayley limit."""
    E, bad = chain_loads(centres, frames, K, xi0, ds, Q, t, circular, F, tau)
    return np.nan if bad >= 0 else E
