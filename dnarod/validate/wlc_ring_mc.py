"""Reference simulation: the writhe distribution of a worm-like ring with a hard-core diameter (Monte Carlo).

The classic method of the supercoiling literature (Vologodskii, Anshelevich, Lukashin & Frank-Kamenetskii,
"Statistical mechanics of supercoils and the torsional stiffness of the DNA double helix", 1979: abstract read,
journal details from memory, Nature 280:294):
a closed chain of M straight segments of length b, bending energy ``g (1 - cos theta)`` at each vertex with
``g`` set so that ``<cos theta> = coth g - 1/g = exp(-b/A)`` (persistence length A exactly), segments closer
than the diameter d (chain separation > ``exclude`` segments) forbidden, sampled by Metropolis crankshaft
moves (a sub-chain rotated rigidly about the line through its two end vertices, which keeps the closure and
the segment lengths). Written here because none of the project's dependencies samples worm-like rings; it shares nothing
with the rod model but A and d, so it is an independent reference for the model's ring writhe.

Strand passage is forbidden as in Vologodskii's simulations: a move whose result has a knot determinant
(|Alexander polynomial at t = -1| of the xy projection) other than 1 is rejected, so the ring stays unknotted
like the rod model's (whose dynamics cannot pass the chain through itself). Without this, a large crankshaft
move could carry a segment through another: a 600-bp ring at ΔLk = -2.9 with d = 2.13 nm knotted after ~2500
sweeps and its mean writhe jumped from -2.3 to -3.1 (writhe fraction 0.90 instead of 0.80). The few knots with
determinant 1 (none below 10 crossings in the standard tables) are not distinguished from the unknot.

Soft pair energy (``pair``): instead of the hard core, the model's own non-bonded energy (WCA + shifted screened
Coulomb between interaction sites spaced along the segments, the model's node spacing, cutoff and chain-distance
exclusion; :func:`pair_parameters`) enters the Metropolis test: a screened-Coulomb ring without an effective
diameter, so nothing of the model's energy is mapped. A crankshaft move rotates segments ``i .. j-1`` rigidly
(both end vertices lie on the axis), so only their pairs with the unmoved segments change energy.

Units: nm, turns.
"""
from __future__ import annotations

import math

import numpy as np


def bending_coefficient(b_nm, A_nm):
    """``g`` (kT) with ``coth g - 1/g = exp(-b/A)``."""
    from scipy.optimize import brentq

    target = math.exp(-b_nm / A_nm)
    return float(brentq(lambda g: 1.0 / math.tanh(g) - 1.0 / g - target, 1e-6, 1e6))


def _kernels():
    from numba import njit

    from dnarod.physics.writhe import _numba_pair_sum

    pair_sum = _numba_pair_sum()

    @njit(cache=False)
    def ring_writhe(P, Q):
        M = P.shape[0]
        for k in range(M):
            Q[k, 0], Q[k, 1], Q[k, 2] = P[(k + 1) % M, 0], P[(k + 1) % M, 1], P[(k + 1) % M, 2]
        return 2.0 * pair_sum(P, Q, P, Q, 1) / (4.0 * np.pi)

    @njit(cache=True)
    def seg_dist2(P, a0, a1, b0, b1):
        # squared distance between segments P[a0]-P[a1] and P[b0]-P[b1] (clamped closest points), scalar code
        d1x, d1y, d1z = P[a1, 0] - P[a0, 0], P[a1, 1] - P[a0, 1], P[a1, 2] - P[a0, 2]
        d2x, d2y, d2z = P[b1, 0] - P[b0, 0], P[b1, 1] - P[b0, 1], P[b1, 2] - P[b0, 2]
        rx, ry, rz = P[a0, 0] - P[b0, 0], P[a0, 1] - P[b0, 1], P[a0, 2] - P[b0, 2]
        a = d1x * d1x + d1y * d1y + d1z * d1z
        e = d2x * d2x + d2y * d2y + d2z * d2z
        f = d2x * rx + d2y * ry + d2z * rz
        c = d1x * rx + d1y * ry + d1z * rz
        b = d1x * d2x + d1y * d2y + d1z * d2z
        den = a * e - b * b
        s = 0.0
        if den > 1e-12:
            s = min(max((b * f - c * e) / den, 0.0), 1.0)
        t = (b * s + f) / e
        if t < 0.0:
            t = 0.0
            s = min(max(-c / a, 0.0), 1.0)
        elif t > 1.0:
            t = 1.0
            s = min(max((b - c) / a, 0.0), 1.0)
        dx = rx + d1x * s - d2x * t
        dy = ry + d1y * s - d2y * t
        dz = rz + d1z * s - d2z * t
        return dx * dx + dy * dy + dz * dz

    @njit(cache=True)
    def vertex_cos(pos, k, M):
        a = pos[k] - pos[(k - 1) % M]
        b = pos[(k + 1) % M] - pos[k]
        return (a @ b) / math.sqrt((a @ a) * (b @ b))

    @njit(cache=True)
    def knot_determinant(P):
        # |Alexander polynomial at t = -1| of the closed polygon P from its projection on the xy plane: 1 for
        # the unknot (and for a few rare knots), 3 for the trefoil, 5 for the figure-eight, ...
        M = P.shape[0]
        cu = np.empty(M * M)  # position along the curve of each under-passage
        co = np.empty(M * M)  # ... of its over-passage
        n = 0
        for a in range(M):
            a1 = (a + 1) % M
            ax, ay = P[a1, 0] - P[a, 0], P[a1, 1] - P[a, 1]
            for b in range(a + 2, M):
                if a == 0 and b == M - 1:
                    continue
                b1 = (b + 1) % M
                bx, by = P[b1, 0] - P[b, 0], P[b1, 1] - P[b, 1]
                den = ax * by - ay * bx
                if den == 0.0:
                    continue
                rx, ry = P[b, 0] - P[a, 0], P[b, 1] - P[a, 1]
                ta = (rx * by - ry * bx) / den
                tb = (rx * ay - ry * ax) / den
                if ta <= 0.0 or ta >= 1.0 or tb <= 0.0 or tb >= 1.0:
                    continue
                za = P[a, 2] + ta * (P[a1, 2] - P[a, 2])
                zb = P[b, 2] + tb * (P[b1, 2] - P[b, 2])
                if za < zb:
                    cu[n], co[n] = a + ta, b + tb
                else:
                    cu[n], co[n] = b + tb, a + ta
                n += 1
        if n < 3:
            return 1
        order = np.argsort(cu[:n])
        u = cu[:n][order]
        o = co[:n][order]
        A = np.zeros((n, n))
        for q in range(n):  # arc q runs from under-passage q to under-passage q + 1
            k = 0
            while k < n and u[k] <= o[q]:
                k += 1
            over = (k - 1) % n
            A[q, over] += 2.0
            A[q, (q - 1) % n] -= 1.0
            A[q, q] -= 1.0
        return int(round(abs(np.linalg.det(A[:n - 1, :n - 1]))))

    @njit(cache=False)
    def cross_energy(P, i, length, nbp):
        # soft pair energy (kT) between the sites of segments i .. i+length-1 and those of the other segments;
        # nbp = (eps, sigma, rc_wca, a_dh, kappa, rc_dh, n_sub, n_exclude) in kT and nm, sites n_sub per segment
        M = P.shape[0]
        eps, sig, rc_wca, a_dh, kappa, rc_dh = nbp[0], nbp[1], nbp[2], nbp[3], nbp[4], nbp[5]
        n_sub, nex = int(nbp[6]), int(nbp[7])
        N = M * n_sub
        rc = max(rc_wca, rc_dh)
        rc2, rw2, s2 = rc * rc, rc_wca * rc_wca, sig * sig
        shift = a_dh * math.exp(-kappa * rc_dh) / rc_dh if rc_dh > 0.0 else 0.0
        j = (i + length) % M
        e = 0.0
        for m in range(length):
            a = (i + m) % M
            a1 = (a + 1) % M
            for q in range(M - length):
                bq = (j + q) % M
                sep = abs(a - bq)
                sep = min(sep, M - sep)
                if sep * n_sub + n_sub - 1 <= nex:
                    continue  # every site pair of the two segments is excluded along the chain
                b1 = (bq + 1) % M
                if seg_dist2(P, a, a1, bq, b1) >= rc2:
                    continue
                for s in range(n_sub):
                    fs = s / n_sub
                    ax = P[a, 0] + fs * (P[a1, 0] - P[a, 0])
                    ay = P[a, 1] + fs * (P[a1, 1] - P[a, 1])
                    az = P[a, 2] + fs * (P[a1, 2] - P[a, 2])
                    ia = a * n_sub + s
                    for t in range(n_sub):
                        ib = bq * n_sub + t
                        d = abs(ia - ib)
                        if min(d, N - d) <= nex:
                            continue
                        ft = t / n_sub
                        dx = P[bq, 0] + ft * (P[b1, 0] - P[bq, 0]) - ax
                        dy = P[bq, 1] + ft * (P[b1, 1] - P[bq, 1]) - ay
                        dz = P[bq, 2] + ft * (P[b1, 2] - P[bq, 2]) - az
                        r2 = dx * dx + dy * dy + dz * dz
                        if r2 >= rc2:
                            continue
                        if r2 < rw2:
                            s6 = (s2 / r2) ** 3
                            e += 4.0 * eps * (s6 * s6 - s6) + eps
                        if r2 < rc_dh * rc_dh:
                            r = math.sqrt(r2)
                            e += a_dh * math.exp(-kappa * r) / r - shift
        return e

    @njit(cache=False)
    def sweep(pos, g, d2, exclude, n_moves, phi_max, seed_state, tw_coeff, dlk, wr_now, nbp):
        # tw_coeff > 0: a twist energy tw_coeff (dlk - Wr)^2 (kT) with the twist integrated out (fixed Lk);
        # nbp[6] > 0: the soft pair energy of cross_energy instead of (or besides) the hard core d2
        M = pos.shape[0]
        np.random.seed(seed_state)
        acc = 0
        new = np.empty_like(pos)
        Q = np.empty_like(pos)
        wr_cur = wr_now
        soft = nbp[6] > 0.0
        for _ in range(n_moves):
            i = np.random.randint(M)
            length = 2 + np.random.randint(M - 3)  # vertices i+1 .. i+length-1 move; j = i + length
            j = (i + length) % M
            phi = (2.0 * np.random.random() - 1.0) * phi_max
            axis = pos[j] - pos[i]
            axis = axis / math.sqrt(axis @ axis)
            c, s = math.cos(phi), math.sin(phi)
            e_old = g * (2.0 - vertex_cos(pos, i, M) - vertex_cos(pos, j, M))
            if soft:
                e_old += cross_energy(pos, i, length, nbp)
            ux, uy, uz = axis[0], axis[1], axis[2]
            for m in range(1, length):
                k = (i + m) % M
                vx, vy, vz = pos[k, 0] - pos[i, 0], pos[k, 1] - pos[i, 1], pos[k, 2] - pos[i, 2]
                # Rodrigues rotation about the axis through pos[i]
                dot = (ux * vx + uy * vy + uz * vz) * (1.0 - c)
                new[k, 0], new[k, 1], new[k, 2] = pos[k, 0], pos[k, 1], pos[k, 2]
                pos[k, 0] = pos[i, 0] + vx * c + (uy * vz - uz * vy) * s + ux * dot
                pos[k, 1] = pos[i, 1] + vy * c + (uz * vx - ux * vz) * s + uy * dot
                pos[k, 2] = pos[i, 2] + vz * c + (ux * vy - uy * vx) * s + uz * dot
            e_new = g * (2.0 - vertex_cos(pos, i, M) - vertex_cos(pos, j, M))
            if soft:
                e_new += cross_energy(pos, i, length, nbp)
            ok = True
            de = e_new - e_old
            if tw_coeff <= 0.0 and de > 0.0 and np.random.random() >= math.exp(-de):
                ok = False
            if ok and d2 > 0.0:
                # moved segments (i .. j-1) against unmoved segments (j .. i-1)
                for m in range(length):
                    a = (i + m) % M
                    for q in range(M - length):
                        bq = (j + q) % M
                        sep = abs(a - bq)
                        sep = min(sep, M - sep)
                        if sep <= exclude:
                            continue
                        if seg_dist2(pos, a, (a + 1) % M, bq, (bq + 1) % M) < d2:
                            ok = False
                            break
                    if not ok:
                        break
            wr_new = wr_cur
            if ok and tw_coeff > 0.0:
                wr_new = ring_writhe(pos, Q)
                de += tw_coeff * ((dlk - wr_new) ** 2 - (dlk - wr_cur) ** 2)
                if de > 0.0 and np.random.random() >= math.exp(-de):
                    ok = False
            if ok and knot_determinant(pos) != 1:
                ok = False  # the move passed the chain through itself: keep the unknot (as the rod model does)
            if ok:
                acc += 1
                wr_cur = wr_new
            else:  # restore the old positions
                for m in range(1, length):
                    k = (i + m) % M
                    pos[k, 0], pos[k, 1], pos[k, 2] = new[k, 0], new[k, 1], new[k, 2]
        return acc, wr_cur

    return sweep, knot_determinant, cross_energy


_SWEEP = None
_KNOT = None
_CROSS = None


def pair_parameters(nonbonded, ds, temperature, b_nm):
    """The soft pair energy of :func:`sample_ring_writhe` from the model's non-bonded settings.

    Parameters
    ----------
    nonbonded : dnarod.physics.nonbonded.NonbondedSettings
    ds : float
        The model's node spacing, nm: each segment of length ``b_nm`` carries ``round(b_nm / ds)`` interaction sites
        spaced evenly along it (spacing ``ds`` when ``b_nm`` is a multiple of it).
    temperature : float
        K.
    b_nm : float
        Segment length, nm.

    Returns
    -------
    numpy.ndarray
        ``(eps, sigma, rc_wca, a_dh, kappa, rc_dh, n_sub, n_exclude)``: WCA depth and Debye-Hueckel prefactor in kT
        (kT nm), lengths in nm, sites per segment, chain-distance exclusion in sites (the model's own, from
        :meth:`~dnarod.physics.nonbonded.NonbondedSettings.resolve`).
    """
    from dnarod.core.units import kT

    nb = nonbonded.resolve(ds, temperature)
    kt = kT(temperature)
    n_sub = max(1, int(round(b_nm / ds)))
    return np.array([nb["eps"] / kt, nb["sigma"], nb["rc_wca"], nb["a_dh"] / kt, nb["kappa"], nb["rc_dh"],
                     float(n_sub), float(nb["n_exclude"])])


def sample_ring_writhe(length_nm, A_nm, diameter_nm, b_nm=3.4, n_samples=2000, sweeps_between=1,
                       equilibration_sweeps=200, exclude=None, phi_max=1.0, seed=0, C_nm=None, delta_lk=0.0,
                       pair=None):
    """Writhe samples of the worm-like ring (see the module docstring).

    Parameters
    ----------
    length_nm, A_nm, diameter_nm : float
        Contour length, persistence length, hard-core diameter (nm); ``diameter_nm = 0`` for a phantom ring.
    b_nm : float
        Segment length (M = round(L/b) segments).
    n_samples : int
    sweeps_between : int
        Sweeps (M moves each) between samples.
    exclude : int or None
        Segments this close along the chain are not tested for overlap (default: those within 2 d along the chain,
        at least 1).
    C_nm, delta_lk : float, optional
        With ``C_nm``: a closed ring of fixed linking difference ``delta_lk`` (turns), its twist integrated out
        (Gaussian, ``E_tw = 2 pi² kT C (ΔLk - Wr)² / L``), as in Vologodskii's simulations of supercoiled rings;
        without: the nicked ring (writhe free).
    pair : numpy.ndarray, optional
        A soft pair energy instead of the hard core (:func:`pair_parameters`: the model's own WCA + screened
        Coulomb between sites spaced along the segments, with its cutoff and chain-distance exclusion; give
        ``diameter_nm = 0``). Metropolis on bending + pair (+ twist) energy; about 10x slower than the hard core.

    Returns
    -------
    dict
        ``wr`` (n_samples,), ``radius_of_gyration_nm`` (n_samples,, of the vertices), ``segments``, ``bending_coefficient``, ``acceptance``.
    """
    global _SWEEP, _KNOT, _CROSS
    from dnarod.physics.writhe import writhe

    if _SWEEP is None:
        _SWEEP, _KNOT, _CROSS = _kernels()
    M = int(round(length_nm / b_nm))
    b = length_nm / M
    g = bending_coefficient(b, A_nm)
    ex = max(1, int(math.ceil(2.0 * diameter_nm / b))) if exclude is None else int(exclude)
    R = b / (2.0 * math.sin(math.pi / M))
    t = 2.0 * np.pi * np.arange(M) / M
    pos = np.stack([R * np.cos(t), R * np.sin(t), np.zeros(M)], axis=1)
    rng = np.random.default_rng(seed)
    d2 = float(diameter_nm) ** 2
    tc = 0.0 if C_nm is None else 2.0 * math.pi ** 2 * float(C_nm) / float(length_nm)
    dlk = float(delta_lk)
    if pair is None:
        nbp = np.zeros(8)
    else:
        nbp = np.array(pair, float)
        if nbp.shape != (8,) or round(length_nm / b_nm) * nbp[6] <= 2 * nbp[7] + 1:
            raise ValueError("pair: 8 numbers of pair_parameters, on a ring longer than twice the exclusion")
    _, w = _SWEEP(pos, g, d2, ex, equilibration_sweeps * M, phi_max, int(rng.integers(2**31)), tc, dlk, 0.0, nbp)
    wr = np.empty(n_samples)
    rg = np.empty(n_samples)
    acc = 0
    for k in range(n_samples):
        a, w = _SWEEP(pos, g, d2, ex, sweeps_between * M, phi_max, int(rng.integers(2**31)), tc, dlk, w, nbp)
        acc += a
        wr[k] = writhe(pos)
        rg[k] = math.sqrt(float(((pos - pos.mean(axis=0)) ** 2).sum(axis=1).mean()))
    return dict(wr=wr, radius_of_gyration_nm=rg, segments=M, segment_nm=b, bending_coefficient=g, exclude=ex,
                acceptance=acc / (n_samples * sweeps_between * M))
