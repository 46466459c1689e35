"""Numba kernels of the Monte Carlo engine: energies of the exact model and the move loop.

Why our own kernels: no library samples SE(3)^N rods with the exact SMK (Cayley-strain) energy; the energy
of a move must be computed locally (only the steps and node pairs it changes) in compiled code to be useful.

The state is the pose (positions ``pos`` (n, 3) nm, frames ``frm`` (n, 3, 3), directors as columns). The energy
is the sum of

* the elastic energy of every step, ``ds H`` (:func:`step_energy`, the arithmetic of
  :func:`dnarod.kernels.step_loads`);
* the non-bonded pairs (WCA + shifted Debye-Hueckel between node centres, chain separation > ``n_ex``, the
  functional form of :func:`dnarod.openmm.nonbonded.pair_kernel`);
* the external energy of each node (:func:`node_external`): dead pulling force ``-F . r``, trap, rotation clamp
  ``k (3 - tr(T^T L)) / 2``, dead torque ``-|tau| phi`` (phi the unwrapped swing-twist angle about the torque
  axis, as :class:`dnarod.openmm.loads.TorqueCallback`), and the tweezers surface wall on the node's three
  particles (:mod:`dnarod.openmm.walls`);
* the tweezers bead wall between the first particle of every node and the last node's centre.

Moves (one call of :func:`sweep` attempts ``n_moves`` of them, types drawn with the probabilities ``p``):

0. *node*: one free node translated (uniform in a cube) and rotated (Cayley map of a vector uniform in a ball)
   about its centre;
1. *crankshaft*: nodes ``i+1 .. j-1`` rotated rigidly about the axis through nodes i and j (ends fixed);
2. *pivot*: the tail ``k .. n-1`` (or the head ``0 .. k``) of an open chain rotated rigidly about node k's centre
   (k = 0 or n-1: the whole chain, by any angle);
3. *twist*: the frames of nodes ``a .. b`` turned by one angle about their own d3 (positions fixed).

Every proposal is symmetric with respect to the invariant (Haar x Lebesgue) measure of SE(3)^n, and rotation
amplitudes are capped by a quantity the move leaves invariant (the largest distance of a moved node from the
rotation axis or point), so Metropolis acceptance ``min(1, exp(-dE/kT))`` samples ``exp(-E/kT)`` exactly.

Topology (when the excluded volume is on): a move is rejected if a moved node comes within ``r_hc`` of a node it
interacts with (chain separation > ``n_ex``), where ``r_hc`` is the distance at which the WCA energy exceeds
:data:`HARD_CORE_KT` kT (its Boltzmann factor underflows double precision, so nothing is lost), or if it makes a
step's chord longer than ``l_max``; and no node moves along a path longer than ``delta_max = 2 (r_hc - l_max)``.
Then no segment of the chain passes through another non-excluded segment during the move (a point of the moved
polyline that touched the fixed one half-way would be within ``delta_max / 2`` of it at the start or the end,
while every such distance is at least ``r_hc - l_max``), so linking numbers and knot types are kept.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from dnarod.core.kernels import _DEN_LIMIT

#: WCA energy (kT) beyond which a pair is a hard-core overlap: exp(-700) underflows to 1e-304.
HARD_CORE_KT = 700.0
_SQ3H = 0.8660254037844386

# --- random numbers: xoshiro256+ (state: 4 uint64), saved in checkpoints ---------------------------------------------


@njit(cache=True, inline="always")
def _rotl(x, k):
    return (x << np.uint64(k)) | (x >> np.uint64(64 - k))


@njit(cache=True)
def rng_uniform(s):
    """A double in [0, 1) from the xoshiro256+ state ``s`` (uint64 (4,)), advancing it."""
    result = s[0] + s[3]
    t = s[1] << np.uint64(17)
    s[2] ^= s[0]
    s[3] ^= s[1]
    s[1] ^= s[2]
    s[0] ^= s[3]
    s[2] ^= t
    s[3] = _rotl(s[3], 45)
    return float(result >> np.uint64(11)) * (1.0 / 9007199254740992.0)


def rng_seed(seed):
    """xoshiro256+ state (uint64 (4,)) from an integer seed (splitmix64 expansion)."""
    x = int(seed) & 0xFFFFFFFFFFFFFFFF
    out = np.empty(4, np.uint64)
    for i in range(4):
        x = (x + 0x9E3779B97F4A7C15) & 0xFFFFFFFFFFFFFFFF
        z = x
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & 0xFFFFFFFFFFFFFFFF
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & 0xFFFFFFFFFFFFFFFF
        out[i] = z ^ (z >> 31)
    return out


@njit(cache=True)
def _unit_vector(s, out):
    z = 2.0 * rng_uniform(s) - 1.0
    ph = 2.0 * math.pi * rng_uniform(s)
    r = math.sqrt(max(0.0, 1.0 - z * z))
    out[0] = r * math.cos(ph)
    out[1] = r * math.sin(ph)
    out[2] = z


@njit(cache=True)
def _rotation(axis0, axis1, axis2, ang, R):
    """Rotation matrix by ``ang`` rad about the unit axis (Rodrigues)."""
    c = math.cos(ang)
    s = math.sin(ang)
    t = 1.0 - c
    R[0, 0] = c + t * axis0 * axis0
    R[0, 1] = t * axis0 * axis1 - s * axis2
    R[0, 2] = t * axis0 * axis2 + s * axis1
    R[1, 0] = t * axis1 * axis0 + s * axis2
    R[1, 1] = c + t * axis1 * axis1
    R[1, 2] = t * axis1 * axis2 - s * axis0
    R[2, 0] = t * axis2 * axis0 - s * axis1
    R[2, 1] = t * axis2 * axis1 + s * axis0
    R[2, 2] = c + t * axis2 * axis2


# --- elastic energy ----------------------------------------------------------------------------------------------------


@njit(cache=True, inline="always")
def step_energy(rl, Ll, rr, Lr, K, xi, ds):
    """``ds H`` (kJ/mol) of one step from its left pose (rl (3,), Ll (3, 3)) to its right pose; ``inf`` at or
    beyond the Cayley limit. K (6, 6), xi (6,) intrinsic strains."""
    R00 = Ll[0, 0] * Lr[0, 0] + Ll[1, 0] * Lr[1, 0] + Ll[2, 0] * Lr[2, 0]
    R01 = Ll[0, 0] * Lr[0, 1] + Ll[1, 0] * Lr[1, 1] + Ll[2, 0] * Lr[2, 1]
    R02 = Ll[0, 0] * Lr[0, 2] + Ll[1, 0] * Lr[1, 2] + Ll[2, 0] * Lr[2, 2]
    R10 = Ll[0, 1] * Lr[0, 0] + Ll[1, 1] * Lr[1, 0] + Ll[2, 1] * Lr[2, 0]
    R11 = Ll[0, 1] * Lr[0, 1] + Ll[1, 1] * Lr[1, 1] + Ll[2, 1] * Lr[2, 1]
    R12 = Ll[0, 1] * Lr[0, 2] + Ll[1, 1] * Lr[1, 2] + Ll[2, 1] * Lr[2, 2]
    R20 = Ll[0, 2] * Lr[0, 0] + Ll[1, 2] * Lr[1, 0] + Ll[2, 2] * Lr[2, 0]
    R21 = Ll[0, 2] * Lr[0, 1] + Ll[1, 2] * Lr[1, 1] + Ll[2, 2] * Lr[2, 1]
    R22 = Ll[0, 2] * Lr[0, 2] + Ll[1, 2] * Lr[1, 2] + Ll[2, 2] * Lr[2, 2]
    den = 1.0 + R00 + R11 + R22
    if not den > _DEN_LIMIT:
        return np.inf
    iden = 2.0 / den
    inv = 1.0 / ds
    e0 = rr[0] - rl[0]
    e1 = rr[1] - rl[1]
    e2 = rr[2] - rl[2]
    d0 = (R21 - R12) * iden * inv - xi[0]
    d1 = (R02 - R20) * iden * inv - xi[1]
    d2 = (R10 - R01) * iden * inv - xi[2]
    d3 = (Ll[0, 0] * e0 + Ll[1, 0] * e1 + Ll[2, 0] * e2) * inv - xi[3]
    d4 = (Ll[0, 1] * e0 + Ll[1, 1] * e1 + Ll[2, 1] * e2) * inv - xi[4]
    d5 = (Ll[0, 2] * e0 + Ll[1, 2] * e1 + Ll[2, 2] * e2) * inv - xi[5]
    H = 0.0
    for a in range(6):
        da = d0 if a == 0 else (d1 if a == 1 else (d2 if a == 2 else (d3 if a == 3 else (d4 if a == 4 else d5))))
        H += da * (K[a, 0] * d0 + K[a, 1] * d1 + K[a, 2] * d2 + K[a, 3] * d3 + K[a, 4] * d4 + K[a, 5] * d5)
    return 0.5 * ds * H


@njit(cache=True)
def _image(r0, L0, Qc, tc, rimg, Limg):
    for a in range(3):
        rimg[a] = tc[a] + Qc[a, 0] * r0[0] + Qc[a, 1] * r0[1] + Qc[a, 2] * r0[2]
        for b in range(3):
            Limg[a, b] = Qc[a, 0] * L0[0, b] + Qc[a, 1] * L0[1, b] + Qc[a, 2] * L0[2, b]


@njit(cache=True)
def elastic_energies(pos, frm, K, xi0, ds, circular, Qc, tc, out):
    """Energy of every step into ``out`` (m,); returns the total (inf if a step is at the Cayley limit)."""
    n = pos.shape[0]
    m = n if circular else n - 1
    rimg = np.empty(3)
    Limg = np.empty((3, 3))
    tot = 0.0
    for k in range(m):
        if circular and k == n - 1:
            _image(pos[0], frm[0], Qc, tc, rimg, Limg)
            e = step_energy(pos[k], frm[k], rimg, Limg, K[k], xi0[k], ds)
        else:
            e = step_energy(pos[k], frm[k], pos[k + 1], frm[k + 1], K[k], xi0[k], ds)
        out[k] = e
        tot += e
    return tot


# --- non-bonded ----------------------------------------------------------------------------------------------------------
# fp layout (floats): see :func:`pack_floats` in engine.py
F_DS, F_KT, F_EPS, F_S2, F_RCWCA, F_ADH, F_KAPPA, F_RCDH, F_SHIFT, F_CUT, F_RHC, F_LMAX, F_DMAX, F_WZ0, F_WK = range(15)
# ip layout (ints)
I_N, I_CIRC, I_NEX, I_NB, I_EV, I_WALLS, I_SKIP, I_BS, I_AXI, I_IDCLOS = range(10)


@njit(cache=True, inline="always")
def pair_energy(r2, fp):
    """WCA + shifted Debye-Hueckel of a pair at squared distance r2 (nm^2), kJ/mol."""
    cut = fp[F_CUT]
    if r2 >= cut * cut:
        return 0.0
    r = math.sqrt(r2)
    e = 0.0
    if r < fp[F_RCWCA]:
        s6 = (fp[F_S2] / r2) ** 3
        e += 4.0 * fp[F_EPS] * (s6 * s6 - s6) + fp[F_EPS]
    if r < fp[F_RCDH]:
        e += fp[F_ADH] * math.exp(-fp[F_KAPPA] * r) / r - fp[F_SHIFT]
    return e


@njit(cache=True, inline="always")
def separation(i, j, n, circular):
    sep = j - i if j > i else i - j
    if circular and n - sep < sep:
        sep = n - sep
    return sep


@njit(cache=True)
def nonbonded_total(pos, ip, fp):
    """All-pairs non-bonded energy (kJ/mol) and the smallest distance of an interacting pair (nm)."""
    n = pos.shape[0]
    circ = ip[I_CIRC] == 1
    nex = ip[I_NEX]
    cut2 = fp[F_CUT] * fp[F_CUT]
    E = 0.0
    dmin2 = np.inf
    for i in range(n):
        for j in range(i + nex + 1, n):
            if circ and n - (j - i) <= nex:
                continue
            dx = pos[j, 0] - pos[i, 0]
            dy = pos[j, 1] - pos[i, 1]
            dz = pos[j, 2] - pos[i, 2]
            r2 = dx * dx + dy * dy + dz * dz
            if r2 < dmin2:
                dmin2 = r2
            if r2 < cut2:
                E += pair_energy(r2, fp)
    return E, math.sqrt(dmin2)


@njit(cache=True)
def update_blocks(pos, b0, b1, bs, bc, br):
    """Bounding spheres (centre bc (nb, 3), radius br (nb,)) of blocks b0..b1 of ``bs`` consecutive nodes."""
    n = pos.shape[0]
    for b in range(b0, b1 + 1):
        lo = b * bs
        hi = min(n, lo + bs)
        mid = (lo + hi - 1) // 2
        for a in range(3):
            bc[b, a] = pos[mid, a]
        rr = 0.0
        for i in range(lo, hi):
            dx = pos[i, 0] - bc[b, 0]
            dy = pos[i, 1] - bc[b, 1]
            dz = pos[i, 2] - bc[b, 2]
            d2 = dx * dx + dy * dy + dz * dz
            if d2 > rr:
                rr = d2
        br[b] = math.sqrt(rr)


@njit(cache=True)
def nonbonded_delta(pos, newpos, mv, nmv, moved, delta, bc, br, ip, fp):
    """Non-bonded energy change (kJ/mol) of moving nodes ``mv[:nmv]`` to ``newpos[:nmv]`` (every node moves by at
    most ``delta`` nm); ``inf`` if a moved node comes within the hard core of a node it interacts with.
    ``moved`` (n,) bool marks the moved nodes. Pairs are found through the block bounding spheres."""
    n = pos.shape[0]
    bs = ip[I_BS]
    nb = bc.shape[0]
    circ = ip[I_CIRC] == 1
    nex = ip[I_NEX]
    ev = ip[I_EV] == 1
    rhc2 = fp[F_RHC] * fp[F_RHC]
    reach = fp[F_CUT] + delta
    dE = 0.0
    s = 0
    while s < nmv:
        b1 = mv[s] // bs
        e = s
        while e < nmv and mv[e] // bs == b1:
            e += 1
        # moved nodes mv[s:e] lie in block b1
        for b2 in range(nb):
            dx = bc[b2, 0] - bc[b1, 0]
            dy = bc[b2, 1] - bc[b1, 1]
            dz = bc[b2, 2] - bc[b1, 2]
            lim = reach + br[b1] + br[b2]
            if dx * dx + dy * dy + dz * dz > lim * lim:
                continue
            lo = b2 * bs
            hi = min(n, lo + bs)
            for t in range(s, e):
                i = mv[t]
                # interacting partners j: nex < |i - j| (and, on a ring, |i - j| < n - nex): two index intervals
                for half in range(2):
                    if half == 0:
                        ja = lo
                        jb = min(hi, i - nex)
                        if circ:
                            ja = max(lo, i - n + nex + 1)
                    else:
                        ja = max(lo, i + nex + 1)
                        jb = hi
                        if circ:
                            jb = min(hi, i + n - nex)
                    for j in range(ja, jb):
                        if moved[j]:
                            continue
                        ax = pos[j, 0] - newpos[t, 0]
                        ay = pos[j, 1] - newpos[t, 1]
                        az = pos[j, 2] - newpos[t, 2]
                        r2n = ax * ax + ay * ay + az * az
                        if ev and r2n < rhc2:
                            return np.inf
                        ox = pos[j, 0] - pos[i, 0]
                        oy = pos[j, 1] - pos[i, 1]
                        oz = pos[j, 2] - pos[i, 2]
                        dE += pair_energy(r2n, fp) - pair_energy(ox * ox + oy * oy + oz * oz, fp)
        s = e
    return dE


# --- external energy --------------------------------------------------------------------------------------------------
# per-node load tables: force (n, 3); trap_k (n,), trap_c (n, 3); rc_k (n,), rc_T (n, 3, 3); tq_mag (n,),
# tq_axis (n, 3), tq_ref (n, 3, 3), tq_last (n,), tq_phi (n,); radius (n,)


@njit(cache=True, inline="always")
def swing_twist_angle(L, ref, ax):
    """Twist angle (rad, in (-pi, pi]) about the unit lab axis ``ax`` of the rotation ``L ref^T``."""
    R00 = L[0, 0] * ref[0, 0] + L[0, 1] * ref[0, 1] + L[0, 2] * ref[0, 2]
    R11 = L[1, 0] * ref[1, 0] + L[1, 1] * ref[1, 1] + L[1, 2] * ref[1, 2]
    R22 = L[2, 0] * ref[2, 0] + L[2, 1] * ref[2, 1] + L[2, 2] * ref[2, 2]
    R21 = L[2, 0] * ref[1, 0] + L[2, 1] * ref[1, 1] + L[2, 2] * ref[1, 2]
    R12 = L[1, 0] * ref[2, 0] + L[1, 1] * ref[2, 1] + L[1, 2] * ref[2, 2]
    R02 = L[0, 0] * ref[2, 0] + L[0, 1] * ref[2, 1] + L[0, 2] * ref[2, 2]
    R20 = L[2, 0] * ref[0, 0] + L[2, 1] * ref[0, 1] + L[2, 2] * ref[0, 2]
    R10 = L[1, 0] * ref[0, 0] + L[1, 1] * ref[0, 1] + L[1, 2] * ref[0, 2]
    R01 = L[0, 0] * ref[1, 0] + L[0, 1] * ref[1, 1] + L[0, 2] * ref[1, 2]
    v = (R21 - R12) * ax[0] + (R02 - R20) * ax[1] + (R10 - R01) * ax[2]
    return 2.0 * math.atan2(v, 1.0 + R00 + R11 + R22)


@njit(cache=True, inline="always")
def wrap_pi(d):
    return (d + math.pi) % (2.0 * math.pi) - math.pi


@njit(cache=True, inline="always")
def node_external(k, r, L, n, force, trap_k, trap_c, rc_k, rc_T, tq_mag, tq_axis, tq_ref, tq_last, tq_phi,
                  radius, ip, fp):
    """External energy (kJ/mol) of node k at pose (r (3,), L (3, 3)): loads and the surface wall (the bead wall is
    separate: :func:`bead_energy`). A dead torque contributes ``-|tau| phi`` with phi continued from the node's
    current unwrapped angle."""
    E = -(force[k, 0] * r[0] + force[k, 1] * r[1] + force[k, 2] * r[2])
    if trap_k[k] > 0.0:
        dx = r[0] - trap_c[k, 0]
        dy = r[1] - trap_c[k, 1]
        dz = r[2] - trap_c[k, 2]
        E += 0.5 * trap_k[k] * (dx * dx + dy * dy + dz * dz)
    if rc_k[k] > 0.0:
        tr = 0.0
        for a in range(3):
            for b in range(3):
                tr += rc_T[k, a, b] * L[a, b]
        E += 0.5 * rc_k[k] * (3.0 - tr)
    if tq_mag[k] > 0.0:
        ang = swing_twist_angle(L, tq_ref[k], tq_axis[k])
        E -= tq_mag[k] * (tq_phi[k] + wrap_pi(ang - tq_last[k]))
    if ip[I_WALLS] == 1 and k >= ip[I_SKIP]:
        z0 = fp[F_WZ0]
        l = radius[k]
        zc = r[2]
        for p in range(3):
            if p == 0:
                z = zc + l * L[2, 0]
            elif p == 1:
                z = zc + l * (-0.5 * L[2, 0] + _SQ3H * L[2, 1])
            else:
                z = zc + l * (-0.5 * L[2, 0] - _SQ3H * L[2, 1])
            d = z - z0
            if d < 0.0:
                E += 0.5 * fp[F_WK] * d * d
    return E


@njit(cache=True, inline="always")
def bead_term(k, zfirst, zc, n, ip, fp):
    """Bead-wall energy of node k's first particle at height zfirst below the last node's centre zc."""
    if k >= n - ip[I_SKIP]:
        return 0.0
    d = zfirst - zc
    return 0.5 * fp[F_WK] * d * d if d > 0.0 else 0.0


@njit(cache=True)
def bead_energy(pos, frm, radius, ip, fp):
    """The whole bead wall (kJ/mol)."""
    n = pos.shape[0]
    if ip[I_WALLS] != 1:
        return 0.0
    zc = pos[n - 1, 2]
    E = 0.0
    for k in range(n):
        E += bead_term(k, pos[k, 2] + radius[k] * frm[k, 2, 0], zc, n, ip, fp)
    return E


# --- the move loop ------------------------------------------------------------------------------------------------------


@njit(cache=True)
def _segment_length(s, lmax):
    """A segment length in 1..lmax, log-uniformly distributed."""
    ln = 1 + int(math.exp(rng_uniform(s) * math.log(lmax + 1.0)) - 1.0)
    if ln > lmax:
        ln = lmax
    if ln < 1:
        ln = 1
    return ln


@njit(cache=True)
def sweep(pos, frm, K, xi0, Qc, tc, movable, ext, force, trap_k, trap_c, rc_k, rc_T, tq_mag, tq_axis, tq_ref,
          tq_last, tq_phi, radius, ip, fp, estep, enode, bc, br, rng, n_moves, p_cum, amp, lmax, counts, energy,
          work_i, work_f):
    """Attempt ``n_moves`` Monte Carlo moves (module docstring); the state arrays are updated in place.

    Parameters (beyond the pose and the load tables)
    ----------
    ext : (n,) int8, 0 for a node without external energy, 1 with a position-only one (force, trap), 2 with a
        frame-dependent one (rotation clamp, torque); the walls are handled separately
    estep : (m,) energy of every step;  enode : (n,) external energy of every node (both kept current)
    bc, br : block bounding spheres (kept current)
    rng : uint64 (4,) xoshiro256+ state
    p_cum : (4,) cumulative probabilities of the move types 0..3
    amp : (6,) amplitudes: node translation (nm, half cube side), node rotation (rad, Cayley ball radius),
        crankshaft, pivot and twist angles (rad)
    lmax : (4,) int, largest segment (nodes) of moves 1..3
    counts : (4, 2) int64, attempted and accepted moves per type (incremented)
    energy : (3,) elastic, non-bonded, external running totals (kJ/mol, incremented by accepted changes)
    work_i : (3 n + 8,) int64 and work_f : (n + 2, 8) float64 scratch

    Returns
    -------
    int
        0, or -1 if a non-finite energy was accepted (never expected).
    """
    n = pos.shape[0]
    circ = ip[I_CIRC] == 1
    m = n if circ else n - 1
    ds = fp[F_DS]
    beta = 1.0 / fp[F_KT]
    has_nb = ip[I_NB] == 1
    walls = ip[I_WALLS] == 1
    ev = ip[I_EV] == 1
    axi = ip[I_AXI] == 1
    idclos = ip[I_IDCLOS] == 1
    lmax2 = fp[F_LMAX] * fp[F_LMAX]
    dmax = fp[F_DMAX]
    mv = work_i[0:n]
    where = work_i[n:2 * n]
    steps = work_i[2 * n:3 * n + 8]
    newpos = work_f[:, 0:3]
    newenode = work_f[:, 3]
    newstep = work_f[:, 4]
    zfirst = work_f[:, 5]
    moved = np.zeros(n, np.bool_)
    newfrm = np.empty((n, 3, 3))
    R = np.empty((3, 3))
    u = np.empty(3)
    rimg = np.empty(3)
    Limg = np.empty((3, 3))
    rl = np.empty(3)
    Ll = np.empty((3, 3))
    rr = np.empty(3)
    Lr = np.empty((3, 3))
    Lt = np.empty((3, 3))
    for it in range(n_moves):
        x = rng_uniform(rng)
        mt = 0
        while mt < 3 and x >= p_cum[mt]:
            mt += 1
        counts[mt, 0] += 1
        nmv = 0
        rigid = True
        delta = 0.0
        ok = True
        cx = 0.0
        cy = 0.0
        cz = 0.0
        cph = 1.0
        sph = 0.0
        # ---- propose: moved nodes mv[:nmv]; rigid moves: x -> R (x - c) + c + shift; twist: L -> L Rz(phi) -------
        if mt == 0:
            k = int(rng_uniform(rng) * n)
            if not movable[k]:
                continue
            mv[0] = k
            nmv = 1
            while True:
                for a in range(3):
                    u[a] = 2.0 * rng_uniform(rng) - 1.0
                if u[0] * u[0] + u[1] * u[1] + u[2] * u[2] <= 1.0:
                    break
            w0 = amp[1] * u[0]
            w1 = amp[1] * u[1]
            w2 = amp[1] * u[2]
            q = 1.0 + 0.25 * (w0 * w0 + w1 * w1 + w2 * w2)
            R[0, 0] = 1.0 - 0.5 * (w1 * w1 + w2 * w2) / q
            R[1, 1] = 1.0 - 0.5 * (w0 * w0 + w2 * w2) / q
            R[2, 2] = 1.0 - 0.5 * (w0 * w0 + w1 * w1) / q
            R[0, 1] = (-w2 + 0.5 * w0 * w1) / q
            R[1, 0] = (w2 + 0.5 * w0 * w1) / q
            R[0, 2] = (w1 + 0.5 * w0 * w2) / q
            R[2, 0] = (-w1 + 0.5 * w0 * w2) / q
            R[1, 2] = (-w0 + 0.5 * w1 * w2) / q
            R[2, 1] = (w0 + 0.5 * w1 * w2) / q
            d2 = 0.0
            for a in range(3):
                dd = amp[0] * (2.0 * rng_uniform(rng) - 1.0)
                newpos[0, a] = pos[k, a] + dd
                d2 += dd * dd
            delta = math.sqrt(d2)
        elif mt == 1 or mt == 2:
            if mt == 1:
                ln = _segment_length(rng, min(lmax[1], n - 2))
                if circ:
                    i0 = int(rng_uniform(rng) * n)
                    j0 = (i0 + ln + 1) % n
                    if not idclos and i0 + ln + 1 >= n:
                        continue
                else:
                    if ln > n - 2:
                        continue
                    i0 = int(rng_uniform(rng) * (n - 1 - ln))
                    j0 = i0 + ln + 1
                for t in range(ln):
                    mv[t] = (i0 + 1 + t) % n
                nmv = ln
                ax0 = pos[j0, 0] - pos[i0, 0]
                ax1 = pos[j0, 1] - pos[i0, 1]
                ax2 = pos[j0, 2] - pos[i0, 2]
                an = math.sqrt(ax0 * ax0 + ax1 * ax1 + ax2 * ax2)
                if an == 0.0:
                    continue
                ax0 /= an
                ax1 /= an
                ax2 /= an
                cx = pos[i0, 0]
                cy = pos[i0, 1]
                cz = pos[i0, 2]
                amax = amp[2]
            else:
                if circ:
                    continue
                kp = int(rng_uniform(rng) * n)
                if rng_uniform(rng) < 0.5:
                    # the tail kp .. n-1 (node kp turns about its own centre; the hinge is step kp-1)
                    nmv = n - kp
                    if nmv > lmax[2]:
                        continue
                    for t in range(nmv):
                        mv[t] = kp + t
                else:
                    # the head kp .. 0 (the hinge is step kp)
                    nmv = kp + 1
                    if nmv > lmax[2]:
                        continue
                    for t in range(nmv):
                        mv[t] = kp - t
                _unit_vector(rng, u)
                ax0 = u[0]
                ax1 = u[1]
                ax2 = u[2]
                cx = pos[kp, 0]
                cy = pos[kp, 1]
                cz = pos[kp, 2]
                amax = amp[3]
            rho2 = 0.0
            for t in range(nmv):
                i = mv[t]
                if not movable[i]:
                    ok = False
                    break
                px = pos[i, 0] - cx
                py = pos[i, 1] - cy
                pz = pos[i, 2] - cz
                d2 = px * px + py * py + pz * pz
                if mt == 1:
                    pr = px * ax0 + py * ax1 + pz * ax2
                    d2 -= pr * pr
                if d2 > rho2:
                    rho2 = d2
            if not ok:
                continue
            rho = math.sqrt(rho2)
            if nmv == n:
                # the whole chain turned rigidly: no step changes and no part passes another, any angle will do
                amax = math.pi
            elif ev and rho * amax > dmax:
                amax = dmax / rho
            ang = amax * (2.0 * rng_uniform(rng) - 1.0)
            delta = rho * abs(ang)
            _rotation(ax0, ax1, ax2, ang, R)
            for t in range(nmv):
                i = mv[t]
                px = pos[i, 0] - cx
                py = pos[i, 1] - cy
                pz = pos[i, 2] - cz
                newpos[t, 0] = cx + R[0, 0] * px + R[0, 1] * py + R[0, 2] * pz
                newpos[t, 1] = cy + R[1, 0] * px + R[1, 1] * py + R[1, 2] * pz
                newpos[t, 2] = cz + R[2, 0] * px + R[2, 1] * py + R[2, 2] * pz
        else:
            ln = _segment_length(rng, min(lmax[3], n))
            if circ:
                a0 = int(rng_uniform(rng) * n)
                if not idclos and a0 + ln > n:
                    continue
            else:
                a0 = int(rng_uniform(rng) * (n - ln + 1))
            ang = amp[4] * (2.0 * rng_uniform(rng) - 1.0)
            cph = math.cos(ang)
            sph = math.sin(ang)
            nmv = ln
            rigid = False
            for t in range(ln):
                i = (a0 + t) % n
                mv[t] = i
                if not movable[i]:
                    ok = False
                    break
                newpos[t, 0] = pos[i, 0]
                newpos[t, 1] = pos[i, 1]
                newpos[t, 2] = pos[i, 2]
            if not ok:
                continue
        # ---- energy change ------------------------------------------------------------------------------------------
        for t in range(nmv):
            i = mv[t]
            moved[i] = True
            where[i] = t
        same = rigid or (axi and mt == 3)
        ns = 0
        for t in range(nmv):
            i = mv[t]
            kl = i - 1 if i > 0 else (n - 1 if circ else -1)
            if kl >= 0 and not moved[kl]:
                steps[ns] = kl
                ns += 1
            if i < m and (not same or not moved[(i + 1) % n]):
                steps[ns] = i
                ns += 1
        dE_el = 0.0
        for q_ in range(ns):
            k = steps[q_]
            jn = (k + 1) % n
            for side in range(2):
                node = k if side == 0 else jn
                rv = rl if side == 0 else rr
                Lv = Ll if side == 0 else Lr
                if moved[node]:
                    t = where[node]
                    for a in range(3):
                        rv[a] = newpos[t, a]
                    if mt == 3:
                        for a in range(3):
                            Lv[a, 0] = cph * frm[node, a, 0] + sph * frm[node, a, 1]
                            Lv[a, 1] = -sph * frm[node, a, 0] + cph * frm[node, a, 1]
                            Lv[a, 2] = frm[node, a, 2]
                    else:
                        for a in range(3):
                            for b in range(3):
                                Lv[a, b] = R[a, 0] * frm[node, 0, b] + R[a, 1] * frm[node, 1, b] + R[a, 2] * frm[node, 2, b]
                else:
                    for a in range(3):
                        rv[a] = pos[node, a]
                        for b in range(3):
                            Lv[a, b] = frm[node, a, b]
            if circ and k == n - 1:
                _image(rr, Lr, Qc, tc, rimg, Limg)
                for a in range(3):
                    rr[a] = rimg[a]
                    for b in range(3):
                        Lr[a, b] = Limg[a, b]
            if ev:
                ch2 = (rr[0] - rl[0]) ** 2 + (rr[1] - rl[1]) ** 2 + (rr[2] - rl[2]) ** 2
                if ch2 > lmax2:
                    ok = False
                    break
            e = step_energy(rl, Ll, rr, Lr, K[k], xi0[k], ds)
            newstep[q_] = e
            dE_el += e - estep[k]
        if not ok or not (dE_el < np.inf):
            for t in range(nmv):
                moved[mv[t]] = False
            continue
        # external energy of the moved nodes: loads and the surface wall
        dE_ext = 0.0
        for t in range(nmv):
            i = mv[t]
            if ext[i] == 0 and not walls:
                newenode[t] = 0.0
                continue
            if ext[i] == 2 or walls:
                if mt == 3:
                    for a in range(3):
                        Lt[a, 0] = cph * frm[i, a, 0] + sph * frm[i, a, 1]
                        Lt[a, 1] = -sph * frm[i, a, 0] + cph * frm[i, a, 1]
                        Lt[a, 2] = frm[i, a, 2]
                elif ext[i] == 2:
                    for a in range(3):
                        for b in range(3):
                            Lt[a, b] = R[a, 0] * frm[i, 0, b] + R[a, 1] * frm[i, 1, b] + R[a, 2] * frm[i, 2, b]
                else:  # only the z row is needed (walls)
                    for b in range(3):
                        Lt[2, b] = R[2, 0] * frm[i, 0, b] + R[2, 1] * frm[i, 1, b] + R[2, 2] * frm[i, 2, b]
            e = node_external(i, newpos[t], Lt, n, force, trap_k, trap_c, rc_k, rc_T, tq_mag, tq_axis, tq_ref,
                              tq_last, tq_phi, radius, ip, fp)
            newenode[t] = e
            dE_ext += e - enode[i]
            if walls:
                # bead wall term of this node's first particle, here against the old bead height (fixed below)
                zfirst[t] = newpos[t, 2] + radius[i] * Lt[2, 0]
        if walls:
            zc_old = pos[n - 1, 2]
            if moved[n - 1]:
                zc_new = newpos[where[n - 1], 2]
                for k in range(n):
                    if moved[k]:
                        continue
                    zf = pos[k, 2] + radius[k] * frm[k, 2, 0]
                    dE_ext += bead_term(k, zf, zc_new, n, ip, fp) - bead_term(k, zf, zc_old, n, ip, fp)
            else:
                zc_new = zc_old
            for t in range(nmv):
                i = mv[t]
                dE_ext += (bead_term(i, zfirst[t], zc_new, n, ip, fp)
                           - bead_term(i, pos[i, 2] + radius[i] * frm[i, 2, 0], zc_old, n, ip, fp))
        dE_nb = 0.0
        if has_nb and rigid:
            dE_nb = nonbonded_delta(pos, newpos, mv, nmv, moved, delta, bc, br, ip, fp)
        for t in range(nmv):
            moved[mv[t]] = False
        dE = dE_el + dE_ext + dE_nb
        if not (dE < np.inf):
            continue
        if dE > 0.0 and rng_uniform(rng) >= math.exp(-beta * dE):
            continue
        # ---- accept ----------------------------------------------------------------------------------------------------
        counts[mt, 1] += 1
        energy[0] += dE_el
        energy[1] += dE_nb
        energy[2] += dE_ext
        for q_ in range(ns):
            estep[steps[q_]] = newstep[q_]
        for t in range(nmv):
            i = mv[t]
            if mt == 3:
                for a in range(3):
                    f0 = frm[i, a, 0]
                    f1 = frm[i, a, 1]
                    frm[i, a, 0] = cph * f0 + sph * f1
                    frm[i, a, 1] = -sph * f0 + cph * f1
            else:
                for b in range(3):
                    f0 = frm[i, 0, b]
                    f1 = frm[i, 1, b]
                    f2 = frm[i, 2, b]
                    frm[i, 0, b] = R[0, 0] * f0 + R[0, 1] * f1 + R[0, 2] * f2
                    frm[i, 1, b] = R[1, 0] * f0 + R[1, 1] * f1 + R[1, 2] * f2
                    frm[i, 2, b] = R[2, 0] * f0 + R[2, 1] * f1 + R[2, 2] * f2
                pos[i, 0] = newpos[t, 0]
                pos[i, 1] = newpos[t, 1]
                pos[i, 2] = newpos[t, 2]
            if tq_mag[i] > 0.0:
                ang2 = swing_twist_angle(frm[i], tq_ref[i], tq_axis[i])
                tq_phi[i] += wrap_pi(ang2 - tq_last[i])
                tq_last[i] = ang2
            enode[i] = newenode[t]
        if has_nb and rigid:
            bsz = ip[I_BS]
            lo_b = mv[0] // bsz
            hi_b = mv[nmv - 1] // bsz
            if lo_b > hi_b:
                lo_b, hi_b = hi_b, lo_b
            if circ and nmv > 1 and abs(mv[nmv - 1] - mv[0]) != nmv - 1:  # wraps past node 0
                update_blocks(pos, 0, bc.shape[0] - 1, bsz, bc, br)
            else:
                update_blocks(pos, lo_b, hi_b, bsz, bc, br)
        if not (energy[0] + energy[1] + energy[2] < np.inf):
            return -1
    return 0
