"""SIMD-friendly numba kernel of the splitting integrator: blocks of nodes in structure-of-arrays scratch.

The scalar kernel of :mod:`.fast` keeps each node's arithmetic in a dependency chain (the five
free-rotor sub-flows are sequential), so it is latency bound. Here the chain is swept in blocks of
``BLOCK`` nodes: each block's poses, momenta and parameters are copied into small scratch arrays
with one row per quantity, and every formula is a loop over the lanes of the block, which LLVM
vectorises (AVX2/AVX-512). Per time step and block:

1. step loads of the block's steps (the exact A2 loads, same arithmetic as :func:`dnarod.core.kernels.step_loads`);
2. node loads = own step + previous step (carried across blocks) + end loads;
3. kick (finish step i), kick (start step i+1), drift, free rotor (and BAOAB's O step).

The free-rotor sines and cosines use branch-free polynomials: a short one when every sub-step
angle of the block is below 0.25 rad (the thermal case), a longer one with two angle doublings up
to ``ROTOR_ANGLE_MAX``; ``|pi|`` is invariant under the rotor, so one bound per block decides,
and a block beyond it takes the scalar libm path. All three agree with libm to rounding. Circular chains
compute their closing step first (it needs node 0 before node 0 moves).
"""
from __future__ import annotations

import numpy as np
from numba import njit

from dnarod.core.kernels import _DEN_LIMIT, _FM, lab_stresses
from dnarod.core.kernels import step_loads as _step_loads
from dnarod.engines.lax.fast import _MOM2, _rotor_node

#: Nodes per block (a compile-time constant of the kernel). Measured at 1000 nodes on this project's
#: AVX-512 machine: 8 lanes 1.37e7, 16 lanes 1.67e7, 32 lanes 1.84e7, 64 lanes 1.90e7 node-steps/s.
BLOCK = 64
#: Largest free-rotor angle per sub-step (rad) for the polynomial sine/cosine (|x|/4 < 0.8).
ROTOR_ANGLE_MAX = 3.2


@njit(cache=True, inline="always", fastmath=_FM)
def _sincos_poly(x):
    """sin(x), cos(x) for |x| < 3.2: Taylor polynomials at x/4 (truncation < 1e-18), two doublings."""
    y = 0.25 * x
    y2 = y * y
    s = y * (1.0 + y2 * (-1.0 / 6 + y2 * (1.0 / 120 + y2 * (-1.0 / 5040 + y2 * (1.0 / 362880 + y2 * (
        -1.0 / 39916800 + y2 * (1.0 / 6227020800 + y2 * (-1.0 / 1307674368000 + y2 * (1.0 / 355687428096000)))))))))
    c = 1.0 + y2 * (-0.5 + y2 * (1.0 / 24 + y2 * (-1.0 / 720 + y2 * (1.0 / 40320 + y2 * (
        -1.0 / 3628800 + y2 * (1.0 / 479001600 + y2 * (-1.0 / 87178291200 + y2 * (1.0 / 20922789888000))))))))
    s, c = 2.0 * s * c, (c - s) * (c + s)
    return 2.0 * s * c, (c - s) * (c + s)


@njit(cache=True, inline="always", fastmath=_FM)
def _sincos_short(x):
    """sin(x), cos(x) for |x| < 0.25 (thermal rotor angles): Taylor to x^11 / x^12, truncation < 1e-16 relative."""
    x2 = x * x
    s = x * (1.0 + x2 * (-1.0 / 6 + x2 * (1.0 / 120 + x2 * (-1.0 / 5040 + x2 * (1.0 / 362880 + x2 * (
        -1.0 / 39916800))))))
    c = 1.0 + x2 * (-0.5 + x2 * (1.0 / 24 + x2 * (-1.0 / 720 + x2 * (1.0 / 40320 + x2 * (
        -1.0 / 3628800 + x2 * (1.0 / 479001600))))))
    return s, c


@njit(cache=True, inline="always", fastmath=_FM)
def _rotor_lanes(S, nb, h, short):
    """Free-rotor flow for time h of lanes 0..nb-1. Rows of S: frame 0-8 (3 i + a), pi 9-11, 1/J 12-14."""
    for sub in range(5):
        if sub == 0 or sub == 4:
            a, b, d, f = 0, 1, 2, 0.5
        elif sub == 1 or sub == 3:
            a, b, d, f = 1, 2, 0, 0.5
        else:
            a, b, d, f = 2, 0, 1, 1.0
        for l in range(nb):
            phi = f * h * S[9 + a, l] * S[12 + a, l]
            if short:
                s, c = _sincos_short(phi)
            else:
                s, c = _sincos_poly(phi)
            x0 = S[b, l]
            y0 = S[d, l]
            x1 = S[3 + b, l]
            y1 = S[3 + d, l]
            x2 = S[6 + b, l]
            y2 = S[6 + d, l]
            S[b, l] = c * x0 + s * y0
            S[d, l] = c * y0 - s * x0
            S[3 + b, l] = c * x1 + s * y1
            S[3 + d, l] = c * y1 - s * x1
            S[6 + b, l] = c * x2 + s * y2
            S[6 + d, l] = c * y2 - s * x2
            pb = S[9 + b, l]
            pd = S[9 + d, l]
            S[9 + b, l] = c * pb + s * pd
            S[9 + d, l] = c * pd - s * pb


@njit(cache=True, inline="always", fastmath=_FM)
def _rotor_block(S, nb, h):
    """Rotor of a block: vector path if every lane's angle bound is below ROTOR_ANGLE_MAX, else libm per lane."""
    amax = 0.0
    for l in range(nb):
        p2 = S[9, l] * S[9, l] + S[10, l] * S[10, l] + S[11, l] * S[11, l]
        jm = max(S[12, l], max(S[13, l], S[14, l]))
        amax = max(amax, p2 * jm * jm)
    if amax * h * h < 0.0625:   # every sub-step angle below 0.25 rad
        _rotor_lanes(S, nb, h, True)
        return
    if amax * h * h < ROTOR_ANGLE_MAX * ROTOR_ANGLE_MAX:
        _rotor_lanes(S, nb, h, False)
        return
    frm = np.empty((1, 3, 3))
    pi = np.empty((1, 3))
    iJ = np.empty((1, 3))
    for l in range(nb):
        for r in range(9):
            frm[0, r // 3, r % 3] = S[r, l]
        for a in range(3):
            pi[0, a] = S[9 + a, l]
            iJ[0, a] = S[12 + a, l]
        _rotor_node(frm, pi, iJ, 0, h)
        for r in range(9):
            S[r, l] = frm[0, r // 3, r % 3]
        for a in range(3):
            S[9 + a, l] = pi[0, a]


@njit(cache=True, inline="always", fastmath=_FM)
def _kick_lane(S, l, h):
    """Half kick of lane ``l`` by ``h`` ps: lab momentum (rows 15-17) by the lab force (rows 21-23), body angular
    momentum (rows 9-11) by the lab torque (rows 24-26) taken into the body frame (frame rows 0-8)."""
    for a in range(3):
        S[15 + a, l] += h * S[21 + a, l]
    t0, t1, t2 = S[24, l], S[25, l], S[26, l]
    S[9, l] += h * (S[0, l] * t0 + S[3, l] * t1 + S[6, l] * t2)
    S[10, l] += h * (S[1, l] * t0 + S[4, l] * t1 + S[7, l] * t2)
    S[11, l] += h * (S[2, l] * t0 + S[5, l] * t1 + S[8, l] * t2)


@njit(cache=True)
def _scatter(Z, FT, pos, frm, P, pi, F, tau):
    """Copy the structure-of-arrays state and loads back into the caller's (n, 3) / (n, 3, 3) arrays."""
    for k in range(pos.shape[0]):
        for a in range(3):
            pos[k, a] = Z[a, k]
            P[k, a] = Z[12 + a, k]
            pi[k, a] = Z[15 + a, k]
            F[k, a] = FT[a, k]
            tau[k, a] = FT[3 + a, k]
        for r in range(9):
            frm[k, r // 3, r % 3] = Z[3 + r, k]


@njit(cache=True, fastmath=_FM)
def run_steps_blocked(pos, frm, P, pi, F, tau, inv_m, invJ, free, Fext, tauext, K, xi0, ds, circular, Q, tvec,
                      dt, n_steps, langevin, c, sigP, sigpi, noise, ktab, kidx):
    """Same contract as :func:`.fast.run_steps`: advance n_steps in place; returns (status, step, node, E).

    ``ktab`` (42, n_types) holds the distinct step parameter sets (K row-major, then xi0) and
    ``kidx`` (n_steps,) the set of each step, so a uniform or dinucleotide-dependent rod reads its
    parameters from a table that stays in cache instead of 42 numbers per step per time step."""
    n = pos.shape[0]
    h = 0.5 * dt
    E = np.nan
    if n_steps <= 0:
        return 0, 0, -1, E
    m = K.shape[0]
    # Structure-of-arrays copies for the whole call (one transpose in, one out): state Z, constants C,
    # loads FT. Block copies from these are contiguous.
    Z = np.empty((18, n))            # r 0-2, L 3-11 (3 i + a), P 12-14, pi 15-17
    C = np.empty((15, n))            # 1/J 0-2, 1/m 3, free 4, F_ext 5-7, tau_ext 8-10, sigP 11, sigpi 12-14
    FT = np.empty((6, n))
    for k in range(n):
        for a in range(3):
            Z[a, k] = pos[k, a]
            Z[12 + a, k] = P[k, a]
            Z[15 + a, k] = pi[k, a]
            C[a, k] = invJ[k, a]
            C[5 + a, k] = Fext[k, a]
            C[8 + a, k] = tauext[k, a]
            C[12 + a, k] = sigpi[k, a] if langevin else 0.0
        for r in range(9):
            Z[3 + r, k] = frm[k, r // 3, r % 3]
        C[3, k] = inv_m[k]
        C[4, k] = free[k]
        C[11, k] = sigP[k] if langevin else 0.0
    pc = np.empty((2, 3))            # closing step of a circular chain: node 0 (index 0), node n-1 (index 1)
    fc = np.empty((2, 3, 3))
    Kc = np.empty((2, 6, 6))
    xc = np.empty((2, 6))
    Kc[1] = K[m - 1]
    xc[1] = xi0[m - 1]
    X = np.empty((12, BLOCK + 1))   # pose of nodes k0..k0+BLOCK: r (3), L (9, row 3 + 3 i + a)
    KS = np.empty((42, BLOCK))      # stiffness (36) and intrinsic strains (6) of the block's steps
    O = np.empty((13, BLOCK))       # step outputs: left F, tau (0-5), right F, tau (6-11), energy (12)
    D = np.empty(BLOCK)             # Cayley denominators
    RF = np.empty((6, BLOCK + 1))   # right-node loads shifted by one lane (lane 0 = carry)
    S = np.empty((32, BLOCK))       # node rows: frame 0-8, pi 9-11, 1/J 12-14, P 15-17, r 18-20,
    #                                 F 21-23, tau 24-26, 1/m 27, free 28, sigP 29
    NZ = np.empty((9, BLOCK))       # Langevin: sigpi (3), noise (6)
    out = np.empty(13)
    cl = np.zeros(12)               # closing-step loads (circular)
    limit = _DEN_LIMIT
    uniform = ktab.shape[1] == 1
    if uniform:  # one parameter set: fill the lanes once
        for r in range(42):
            for l in range(BLOCK):
                KS[r, l] = ktab[r, 0]
    # Pass i computes the loads of the current pose, finishes step i (i >= 0) and starts step i + 1.
    # Pass -1 recomputes the entry loads with this kernel's own arithmetic, so a run split into
    # several calls (or resumed from a checkpoint) is bit-identical to one call.
    for i in range(-1, n_steps):
        finish = i >= 0
        last = i == n_steps - 1
        E = 0.0
        cl[:] = 0.0
        if circular:  # the closing step, before node 0 moves
            for kk, src in ((0, 0), (1, n - 1)):
                for a in range(3):
                    pc[kk, a] = Z[a, src]
                for r in range(9):
                    fc[kk, r // 3, r % 3] = Z[3 + r, src]
            if not _step_loads(pc, fc, Kc, xc, ds, 1, True, 0, Q, tvec, out):
                _scatter(Z, FT, pos, frm, P, pi, F, tau)
                return 1, i, n - 1, E
            E += out[12]
            for a in range(6):
                cl[a] = out[a]
            for a in range(3):
                cl[6 + a] = Q[0, a] * out[6] + Q[1, a] * out[7] + Q[2, a] * out[8]
                cl[9 + a] = Q[0, a] * out[9] + Q[1, a] * out[10] + Q[2, a] * out[11]
        for a in range(6):
            RF[a, 0] = 0.0
        for k0 in range(0, n, BLOCK):
            nb = min(BLOCK, n - k0)
            ns = min(BLOCK, n - 1 - k0)
            ng = min(BLOCK + 1, n - k0)
            # ---- gather poses and parameters
            for r in range(12):
                for l in range(ng):
                    X[r, l] = Z[r, k0 + l]
            if not uniform:
                for l in range(ns):
                    t = kidx[k0 + l]
                    for r in range(42):
                        KS[r, l] = ktab[r, t]
            # ---- phase 1: loads of steps k0..k0+ns-1 (lanes), vectorised
            nbad = 0
            for l in range(ns):
                # R_ab = sum_i L0[i, a] L1[i, b]; L[i, a] is row 3 + 3 i + a
                R00 = X[3, l] * X[3, l + 1] + X[6, l] * X[6, l + 1] + X[9, l] * X[9, l + 1]
                R01 = X[3, l] * X[4, l + 1] + X[6, l] * X[7, l + 1] + X[9, l] * X[10, l + 1]
                R02 = X[3, l] * X[5, l + 1] + X[6, l] * X[8, l + 1] + X[9, l] * X[11, l + 1]
                R10 = X[4, l] * X[3, l + 1] + X[7, l] * X[6, l + 1] + X[10, l] * X[9, l + 1]
                R11 = X[4, l] * X[4, l + 1] + X[7, l] * X[7, l + 1] + X[10, l] * X[10, l + 1]
                R12 = X[4, l] * X[5, l + 1] + X[7, l] * X[8, l + 1] + X[10, l] * X[11, l + 1]
                R20 = X[5, l] * X[3, l + 1] + X[8, l] * X[6, l + 1] + X[11, l] * X[9, l + 1]
                R21 = X[5, l] * X[4, l + 1] + X[8, l] * X[7, l + 1] + X[11, l] * X[10, l + 1]
                R22 = X[5, l] * X[5, l + 1] + X[8, l] * X[8, l + 1] + X[11, l] * X[11, l + 1]
                den = 1.0 + R00 + R11 + R22
                D[l] = den
                nbad += 0 if den > limit else 1
                iden = 2.0 / den
                w0 = (R21 - R12) * iden
                w1 = (R02 - R20) * iden
                w2 = (R10 - R01) * iden
                e0 = X[0, l + 1] - X[0, l]
                e1 = X[1, l + 1] - X[1, l]
                e2 = X[2, l + 1] - X[2, l]
                L00, L01, L02 = X[3, l], X[4, l], X[5, l]
                L10, L11, L12 = X[6, l], X[7, l], X[8, l]
                L20, L21, L22 = X[9, l], X[10, l], X[11, l]
                inv = 1.0 / ds
                d0 = w0 * inv - KS[36, l]
                d1 = w1 * inv - KS[37, l]
                d2 = w2 * inv - KS[38, l]
                d3 = (L00 * e0 + L10 * e1 + L20 * e2) * inv - KS[39, l]
                d4 = (L01 * e0 + L11 * e1 + L21 * e2) * inv - KS[40, l]
                d5 = (L02 * e0 + L12 * e1 + L22 * e2) * inv - KS[41, l]
                M0 = KS[0, l] * d0 + KS[1, l] * d1 + KS[2, l] * d2 + KS[3, l] * d3 + KS[4, l] * d4 + KS[5, l] * d5
                M1 = KS[6, l] * d0 + KS[7, l] * d1 + KS[8, l] * d2 + KS[9, l] * d3 + KS[10, l] * d4 + KS[11, l] * d5
                M2 = KS[12, l] * d0 + KS[13, l] * d1 + KS[14, l] * d2 + KS[15, l] * d3 + KS[16, l] * d4 + KS[17, l] * d5
                P0 = KS[18, l] * d0 + KS[19, l] * d1 + KS[20, l] * d2 + KS[21, l] * d3 + KS[22, l] * d4 + KS[23, l] * d5
                P1 = KS[24, l] * d0 + KS[25, l] * d1 + KS[26, l] * d2 + KS[27, l] * d3 + KS[28, l] * d4 + KS[29, l] * d5
                P2 = KS[30, l] * d0 + KS[31, l] * d1 + KS[32, l] * d2 + KS[33, l] * d3 + KS[34, l] * d4 + KS[35, l] * d5
                H = d0 * M0 + d1 * M1 + d2 * M2 + d3 * P0 + d4 * P1 + d5 * P2
                n0, n1, n2, m0, m1, m2 = lab_stresses(w0, w1, w2, M0, M1, M2, P0, P1, P2,
                                                      L00, L01, L02, L10, L11, L12, L20, L21, L22)
                O[0, l] = n0
                O[1, l] = n1
                O[2, l] = n2
                O[3, l] = m0 + e1 * n2 - e2 * n1
                O[4, l] = m1 + e2 * n0 - e0 * n2
                O[5, l] = m2 + e0 * n1 - e1 * n0
                RF[0, l + 1] = -n0
                RF[1, l + 1] = -n1
                RF[2, l + 1] = -n2
                RF[3, l + 1] = -m0
                RF[4, l + 1] = -m1
                RF[5, l + 1] = -m2
                O[12, l] = 0.5 * ds * H
            if nbad > 0:
                for l in range(ns):
                    if not D[l] > limit:
                        _scatter(Z, FT, pos, frm, P, pi, F, tau)
                        return 1, i, k0 + l, E
            for l in range(ns):
                E += O[12, l]
            for l in range(ns, nb):  # the last node of the chain has no step of its own
                for a in range(6):
                    O[a, l] = 0.0
            # ---- phase 2: node loads and updates of nodes k0..k0+nb-1
            for r in range(9):
                for l in range(nb):
                    S[r, l] = X[3 + r, l]
            for a in range(3):
                for l in range(nb):
                    S[9 + a, l] = Z[15 + a, k0 + l]
                    S[12 + a, l] = C[a, k0 + l]
                    S[15 + a, l] = Z[12 + a, k0 + l]
                    S[18 + a, l] = X[a, l]
                    S[21 + a, l] = C[5 + a, k0 + l]
                    S[24 + a, l] = C[8 + a, k0 + l]
            for l in range(nb):
                S[27, l] = C[3, k0 + l]
                S[28, l] = C[4, k0 + l]
            if langevin and not last:
                inz = i + 1
                for l in range(nb):
                    S[29, l] = C[11, k0 + l]
                for a in range(3):
                    for l in range(nb):
                        NZ[a, l] = C[12 + a, k0 + l]
                for a in range(6):
                    for l in range(nb):
                        NZ[3 + a, l] = noise[inz, a, k0 + l]
            if circular and k0 == 0:
                for a in range(6):
                    S[21 + a, 0] += cl[6 + a]
            if circular and k0 + nb == n:
                for a in range(6):
                    S[21 + a, nb - 1] += cl[a]
            mom = 0.0
            for l in range(nb):
                fr = S[28, l]
                for a in range(6):
                    S[21 + a, l] = (S[21 + a, l] + O[a, l] + RF[a, l]) * fr
            for l in range(nb * finish):
                _kick_lane(S, l, h)  # kick: finish step i
                p2 = S[15, l] * S[15, l] + S[16, l] * S[16, l] + S[17, l] * S[17, l]
                l2 = S[9, l] * S[9, l] + S[10, l] * S[10, l] + S[11, l] * S[11, l]
                mom = max(mom, max(p2, l2)) if (p2 == p2 and l2 == l2) else np.inf
            if not mom < _MOM2:
                for l in range(nb):
                    p2 = S[15, l] * S[15, l] + S[16, l] * S[16, l] + S[17, l] * S[17, l]
                    l2 = S[9, l] * S[9, l] + S[10, l] * S[10, l] + S[11, l] * S[11, l]
                    if not (p2 < _MOM2 and l2 < _MOM2):
                        _scatter(Z, FT, pos, frm, P, pi, F, tau)
                        return 2, i, k0 + l, E
            if not last:
                for l in range(nb):
                    _kick_lane(S, l, h)  # kick: start step i + 1
                if not langevin:
                    for l in range(nb):
                        for a in range(3):
                            S[18 + a, l] += dt * S[15 + a, l] * S[27, l]
                    _rotor_block(S, nb, dt)
                else:
                    for l in range(nb):
                        for a in range(3):
                            S[18 + a, l] += h * S[15 + a, l] * S[27, l]
                    _rotor_block(S, nb, h)
                    for l in range(nb):
                        for a in range(3):
                            S[15 + a, l] = c * S[15 + a, l] + S[29, l] * NZ[3 + a, l]
                            S[9 + a, l] = c * S[9 + a, l] + NZ[a, l] * NZ[6 + a, l]
                    for l in range(nb):
                        for a in range(3):
                            S[18 + a, l] += h * S[15 + a, l] * S[27, l]
                    _rotor_block(S, nb, h)
            # ---- store the block back (contiguous rows)
            for r in range(9):
                for l in range(nb):
                    Z[3 + r, k0 + l] = S[r, l]
            for a in range(3):
                for l in range(nb):
                    Z[15 + a, k0 + l] = S[9 + a, l]
                    Z[12 + a, k0 + l] = S[15 + a, l]
                    Z[a, k0 + l] = S[18 + a, l]
                    FT[a, k0 + l] = S[21 + a, l]
                    FT[3 + a, k0 + l] = S[24 + a, l]
            for a in range(6):
                RF[a, 0] = RF[a, ns] if ns == BLOCK else 0.0
    _scatter(Z, FT, pos, frm, P, pi, F, tau)
    return 0, n_steps, -1, E
