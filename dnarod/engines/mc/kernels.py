"""Numba kernels of the Monte Carlo engine: energies of the exact model, a bounding-sphere tree, and the move loop.

Why our own kernels: no library samples SE(3)^N rods with the exact SMK (Cayley-strain) energy; the energy
of a move must be computed locally (only the steps, node pairs and wall contacts it changes) in compiled code.

Energy
------
The state is the pose (positions ``pos`` (n, 3) nm, frames ``frm`` (n, 3, 3), directors as columns). The energy
is the sum of

* the elastic energy of every step, ``ds H`` (:func:`step_energy`, the arithmetic of
  :func:`dnarod.core.kernels.step_loads`);
* the non-bonded pairs (WCA + shifted Debye-Hueckel between node centres, chain separation > ``n_ex``, the
  functional form of :func:`dnarod.engines.openmm.nonbonded.pair_kernel`);
* the loads of each node (:func:`node_loads`): dead pulling force ``-F . r``, trap, rotation clamp
  ``k (3 - tr(T^T L)) / 2``, dead torque ``-|tau| phi`` (phi the unwrapped swing-twist angle about the torque
  axis, as :class:`dnarod.engines.openmm.loads.TorqueCallback`);
* the tweezers walls of :mod:`dnarod.engines.openmm.walls`: the surface plane under the three particles of nodes
  ``skip .. n-1`` (:func:`surface_energy`) and the bead plane through the last node's centre above the first
  particle of nodes ``0 .. n-1-skip`` (:func:`bead_term`).

Moves
-----
One call of :func:`sweep` attempts ``n_moves`` moves, types drawn with fixed probabilities:

0. *node*: one free node translated (uniform in a cube) and rotated (Cayley map of a vector uniform in a ball)
   about its centre;
1. *crankshaft*: nodes ``i+1 .. j-1`` rotated rigidly about the axis through nodes i and j (ends fixed);
2. *pivot*: the tail ``k .. n-1`` (or the head ``0 .. k``) of an open chain rotated rigidly about node k's centre
   about a random axis (the whole chain: any angle);
3. *hinge pair* ("constrained pivot", the move of PolyMC's ``MCS_PivCon``, Skoruppa and Carlon): nodes
   ``a .. b`` rotated rigidly about node a's centre and the rest of the chain, ``b+1 .. n-1``, translated with
   node b, so that only steps ``a-1`` and ``b`` bend: the far end moves without turning (a rotation-clamped bead
   keeps its orientation), which is what relaxes the extension of a chain held at both ends by a surface and a bead;
4. *twist*: the frames of nodes ``a .. b`` turned by one angle about their own d3 (positions fixed);
5. *end twist*: the same for a segment that ends at one end of an open chain (the last ``l`` nodes or the first),
   which changes the twist of one step and the end's orientation: with a rotation-clamped end, this is what moves
   the chain's total twist against the clamp;
6. *slide*: nodes ``a .. b`` translated rigidly (uniform in a cube), which stretches or shears only steps a-1 and
   b; a slide of a segment that holds an end changes one step only, hence the chain's total length: the extensible
   rod's stretch mode, which moves of rigid rotations leave alone and single-node moves relax only diffusively
   (in a time growing as the square of the chain's length).

Segment lengths are drawn log-uniformly (every length scale equally often) independently of the state, and every
proposal is symmetric with respect to the invariant (Haar x Lebesgue) measure of SE(3)^n (the inverse move has the
same probability). Acceptance is Metropolis in two stages (delayed acceptance, Christen and Fox 2005, J. Comput.
Graph. Stat. 14:795): first ``min(1, exp(-dE_local/kT))`` with the elastic, load and wall terms, then, only for a
move that passed, ``min(1, exp(-dE_nb/kT))`` with the non-bonded pairs, the expensive part; the product of the two
satisfies detailed balance with respect to ``exp(-E/kT)`` exactly, and the pairs of a move rejected by its local
terms are never evaluated. Amplitudes depend only on the move type and the segment length's octave
(:func:`length_bin`).

A move is a partition of the chain into at most :data:`MAX_SEG` index segments, each carried by one *motion*
(fixed; rotation about an axis through a point; translation along the arc of a point rotating about an axis;
straight translation with a turn about the node's own centre; body twist). Only steps between segments of
different motions, wall contacts of moved nodes (or of all nodes when the bead plane moves), and pairs of nodes
in differently moving segments change their energy.

Bounding-sphere tree
--------------------
Leaves hold :data:`LEAF` consecutive nodes; the tree is complete over a power of two of leaves (implicit binary
heap: node t has children 2t, 2t+1, root 1), each node a sphere enclosing its nodes' centres. The pairs a move
changes are found by a dual-tree descent restricted to the index ranges of two segments; a pair of tree nodes is
skipped when every pair of nodes in it is excluded along the chain, or when their spheres, each grown by a bound
on its nodes' displacement (:func:`disp_bound`), are farther apart than the cut-off. The walls are found by a
descent on the z extent of the spheres. For a stretched chain both cost O(log n) per move instead of O(moved
nodes); after an accepted move the spheres of the leaves it touched and their ancestors are recomputed.

Topology (when the excluded volume is on)
-----------------------------------------
A move is rejected if a moved node comes within ``r_hc`` of a node it interacts with (chain separation > n_ex),
where ``r_hc`` is the distance at which the WCA energy exceeds :data:`HARD_CORE_KT` kT (its Boltzmann factor
underflows double precision, so nothing is lost) at the end of the move *or at any point of its continuous path*:
the relative path of two nodes is an arc of a rotation (rigid and hinge-pair moves) or a straight line (node
moves), whose distance of closest approach is computed exactly (:func:`arc_min2`). Chords of changed steps stay
below ``l_max < r_hc`` (the chords a move changes are longest at one end of its path). Then no segment of the
chain passes through another non-excluded one during the move (two crossing segments of chords <= l_max would
bring two of their end nodes within l_max), so linking numbers and knot types are kept, whatever the size of the
move.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

from dnarod.core.kernels import _DEN_LIMIT, pair_vector, step_loads

#: WCA energy (kT) beyond which a pair is a hard-core overlap: exp(-700) underflows to 1e-304.
HARD_CORE_KT = 700.0
_SQ3H = 0.8660254037844386

# float parameter pack
F_DS, F_KT, F_EPS, F_S2, F_RCWCA, F_ADH, F_KAPPA, F_RCDH, F_SHIFT, F_CUT, F_RHC, F_LMAX, F_WZ0, F_WK, F_PRAD = range(15)
N_F = 15
# int parameter pack
I_N, I_CIRC, I_NEX, I_NB, I_EV, I_WALLS, I_SKIP, I_LEAF, I_AXI, I_IDCLOS, I_P = range(11)
N_I = 11
# move types
MT_NODE, MT_CRANK, MT_PIVOT, MT_HINGE, MT_TWIST, MT_ENDTWIST, MT_SLIDE = range(7)
N_TYPES = 7
#: Amplitude bins per move type: octaves of the segment length (bin b holds lengths 2^b .. 2^(b+1) - 1).
N_BINS = 24
# motion kinds
K_FIXED, K_ROT, K_TRANSARC, K_LINEAR, K_TWIST = range(5)
#: Most segments (and motions, fixed included) of one move.
MAX_SEG = 5
MAX_MOT = 3
#: Nodes per leaf of the bounding-sphere tree.
LEAF = 8
_STACK = 256

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


@njit(cache=True)
def segment_length(s, lmax):
    """A segment length in 1..lmax, log-uniformly distributed."""
    ln = int(math.exp(rng_uniform(s) * math.log(lmax + 1.0)))
    if ln > lmax:
        ln = lmax
    if ln < 1:
        ln = 1
    return ln


@njit(cache=True, inline="always")
def length_bin(ln):
    """Octave of a segment length (0 for 1, 1 for 2-3, 2 for 4-7, ...)."""
    b = 0
    while ln > 1 and b < N_BINS - 1:
        ln >>= 1
        b += 1
    return b


# --- elastic energy --------------------------------------------------------------------------------------------------


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


# --- non-bonded ------------------------------------------------------------------------------------------------------


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
def pair_force_over_r(r2, fp):
    """``-dE/dr / r`` of a pair at squared distance r2 (kJ/mol/nm^2): the force on j from i is this times
    ``r_j - r_i``."""
    cut = fp[F_CUT]
    if r2 >= cut * cut:
        return 0.0
    r = math.sqrt(r2)
    f = 0.0
    if r < fp[F_RCWCA]:
        s6 = (fp[F_S2] / r2) ** 3
        f += 24.0 * fp[F_EPS] * (2.0 * s6 * s6 - s6) / r2
    if r < fp[F_RCDH]:
        f += fp[F_ADH] * math.exp(-fp[F_KAPPA] * r) * (fp[F_KAPPA] * r + 1.0) / (r2 * r)
    return f


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


# --- bounding-sphere tree --------------------------------------------------------------------------------------------


def tree_ranges(n, leaf=LEAF):
    """Index ranges of the tree nodes: ``(P, lo (2P,), hi (2P,))`` with P leaves (a power of two); an empty node
    has lo > hi."""
    nl = max(1, -(-n // leaf))
    P = 1
    while P < nl:
        P *= 2
    lo = np.full(2 * P, 1, np.int64)
    hi = np.zeros(2 * P, np.int64)
    for b in range(P):
        a = b * leaf
        if a < n:
            lo[P + b] = a
            hi[P + b] = min(n, a + leaf) - 1
    for t in range(P - 1, 0, -1):
        l_, r_ = 2 * t, 2 * t + 1
        if lo[l_] <= hi[l_]:
            lo[t] = lo[l_]
            hi[t] = hi[r_] if lo[r_] <= hi[r_] else hi[l_]
    return P, lo, hi


@njit(cache=True, inline="always")
def _leaf_sphere(pos, t, tlo, thi, tcen, trad):
    lo = tlo[t]
    hi = thi[t]
    if lo > hi:
        trad[t] = -1.0
        return
    cx = 0.0
    cy = 0.0
    cz = 0.0
    for i in range(lo, hi + 1):
        cx += pos[i, 0]
        cy += pos[i, 1]
        cz += pos[i, 2]
    inv = 1.0 / (hi - lo + 1)
    cx *= inv
    cy *= inv
    cz *= inv
    rr = 0.0
    for i in range(lo, hi + 1):
        dx = pos[i, 0] - cx
        dy = pos[i, 1] - cy
        dz = pos[i, 2] - cz
        d2 = dx * dx + dy * dy + dz * dz
        if d2 > rr:
            rr = d2
    tcen[t, 0] = cx
    tcen[t, 1] = cy
    tcen[t, 2] = cz
    trad[t] = math.sqrt(rr) * (1.0 + 1e-12) + 1e-12


@njit(cache=True, inline="always")
def _merge_sphere(t, tcen, trad):
    a = 2 * t
    b = 2 * t + 1
    ra = trad[a]
    rb = trad[b]
    if rb < 0.0 or ra < 0.0:
        s = a if rb < 0.0 else b
        tcen[t, 0] = tcen[s, 0]
        tcen[t, 1] = tcen[s, 1]
        tcen[t, 2] = tcen[s, 2]
        trad[t] = trad[s]
        return
    dx = tcen[b, 0] - tcen[a, 0]
    dy = tcen[b, 1] - tcen[a, 1]
    dz = tcen[b, 2] - tcen[a, 2]
    d = math.sqrt(dx * dx + dy * dy + dz * dz)
    if d + rb <= ra:
        s = a
    elif d + ra <= rb:
        s = b
    else:
        R = 0.5 * (d + ra + rb)
        f = (R - ra) / d
        tcen[t, 0] = tcen[a, 0] + f * dx
        tcen[t, 1] = tcen[a, 1] + f * dy
        tcen[t, 2] = tcen[a, 2] + f * dz
        trad[t] = R * (1.0 + 1e-12)
        return
    tcen[t, 0] = tcen[s, 0]
    tcen[t, 1] = tcen[s, 1]
    tcen[t, 2] = tcen[s, 2]
    trad[t] = trad[s]


@njit(cache=True)
def tree_build(pos, P, tlo, thi, tcen, trad):
    """All spheres from the positions."""
    for t in range(P, 2 * P):
        _leaf_sphere(pos, t, tlo, thi, tcen, trad)
    for t in range(P - 1, 0, -1):
        _merge_sphere(t, tcen, trad)


@njit(cache=True)
def tree_update(pos, i_lo, i_hi, leaf, P, tlo, thi, tcen, trad):
    """Spheres of the leaves holding nodes i_lo..i_hi and of their ancestors."""
    a = P + i_lo // leaf
    b = P + i_hi // leaf
    for t in range(a, b + 1):
        _leaf_sphere(pos, t, tlo, thi, tcen, trad)
    a >>= 1
    b >>= 1
    while a >= 1:
        for t in range(a, b + 1):
            _merge_sphere(t, tcen, trad)
        a >>= 1
        b >>= 1


# --- motions ---------------------------------------------------------------------------------------------------------
# motion m (0 .. MAX_MOT-1; m = 0 is always the fixed one): mkind (M,), mR (M, 3, 3) rotation of positions about mc
# (kind ROT) or of frames (ROT, LINEAR), mc (M, 3) centre, mt (M, 3) translation (TRANSARC, LINEAR), mu (M, 3) axis and
# mth (M,) angle of the path's rotation (ROT, TRANSARC; TWIST: the twist angle), mq (M, 3) the point whose arc the
# translation follows (TRANSARC), mb (M,) displacement bound factor 2|sin(th/2)| (ROT) or |t| (TRANSARC, LINEAR).


@njit(cache=True, inline="always")
def move_point(m, x0, x1, x2, mkind, mR, mc, mt):
    k = mkind[m]
    if k == K_ROT:
        p0 = x0 - mc[m, 0]
        p1 = x1 - mc[m, 1]
        p2 = x2 - mc[m, 2]
        return (mc[m, 0] + mR[m, 0, 0] * p0 + mR[m, 0, 1] * p1 + mR[m, 0, 2] * p2,
                mc[m, 1] + mR[m, 1, 0] * p0 + mR[m, 1, 1] * p1 + mR[m, 1, 2] * p2,
                mc[m, 2] + mR[m, 2, 0] * p0 + mR[m, 2, 1] * p1 + mR[m, 2, 2] * p2)
    if k == K_TRANSARC or k == K_LINEAR:
        return x0 + mt[m, 0], x1 + mt[m, 1], x2 + mt[m, 2]
    return x0, x1, x2


@njit(cache=True, inline="always")
def move_frame(m, L, mkind, mR, mth, out):
    """New frame of a node with frame L under motion m, into out (3, 3)."""
    k = mkind[m]
    if k == K_ROT or k == K_LINEAR:
        for a in range(3):
            for b in range(3):
                out[a, b] = mR[m, a, 0] * L[0, b] + mR[m, a, 1] * L[1, b] + mR[m, a, 2] * L[2, b]
    elif k == K_TWIST:
        c = math.cos(mth[m])
        s = math.sin(mth[m])
        for a in range(3):
            out[a, 0] = c * L[a, 0] + s * L[a, 1]
            out[a, 1] = -s * L[a, 0] + c * L[a, 1]
            out[a, 2] = L[a, 2]
    else:
        for a in range(3):
            for b in range(3):
                out[a, b] = L[a, b]


@njit(cache=True, inline="always")
def disp_bound(m, x0, x1, x2, r, mkind, mc, mu, mb):
    """Largest displacement, along the move's path, of any point within r of (x0, x1, x2) under motion m (nm): for
    a rotation ``2 |sin(th/2)|`` times the largest distance from the axis."""
    k = mkind[m]
    if k == K_ROT:
        d0 = x0 - mc[m, 0]
        d1 = x1 - mc[m, 1]
        d2 = x2 - mc[m, 2]
        pr = d0 * mu[m, 0] + d1 * mu[m, 1] + d2 * mu[m, 2]
        return mb[m] * (math.sqrt(max(0.0, d0 * d0 + d1 * d1 + d2 * d2 - pr * pr)) + r)
    if k == K_TRANSARC or k == K_LINEAR:
        return mb[m]
    return 0.0


@njit(cache=True, inline="always")
def rel_bound(m1, a0, a1, a2, ra, m2, b0, b1, b2, rb, mkind, mc, mu, mq, mb):
    """Bound on the change, along the move's path, of the vector between a point within ra of a (motion m1) and a
    point within rb of b (motion m2) (nm). A rotation and the translation that follows its point q move relative
    to each other as a rotation about the axis through q."""
    k1 = mkind[m1]
    k2 = mkind[m2]
    if k1 == K_ROT and k2 == K_TRANSARC:
        d0 = a0 - mq[m2, 0]
        d1 = a1 - mq[m2, 1]
        d2 = a2 - mq[m2, 2]
        pr = d0 * mu[m1, 0] + d1 * mu[m1, 1] + d2 * mu[m1, 2]
        return mb[m1] * (math.sqrt(max(0.0, d0 * d0 + d1 * d1 + d2 * d2 - pr * pr)) + ra)
    if k2 == K_ROT and k1 == K_TRANSARC:
        d0 = b0 - mq[m1, 0]
        d1 = b1 - mq[m1, 1]
        d2 = b2 - mq[m1, 2]
        pr = d0 * mu[m2, 0] + d1 * mu[m2, 1] + d2 * mu[m2, 2]
        return mb[m2] * (math.sqrt(max(0.0, d0 * d0 + d1 * d1 + d2 * d2 - pr * pr)) + rb)
    return disp_bound(m1, a0, a1, a2, ra, mkind, mc, mu, mb) + disp_bound(m2, b0, b1, b2, rb, mkind, mc, mu, mb)


@njit(cache=True, inline="always")
def arc_min2(a0, a1, a2, b0, b1, b2, u0, u1, u2, th):
    """``min |R_u(phi) a - b|^2`` over phi between 0 and th (|th| <= pi), R_u(phi) the rotation about the unit u."""
    ap = a0 * u0 + a1 * u1 + a2 * u2
    bp = b0 * u0 + b1 * u1 + b2 * u2
    x0 = a0 - ap * u0
    x1 = a1 - ap * u1
    x2 = a2 - ap * u2
    y0 = b0 - bp * u0
    y1 = b1 - bp * u1
    y2 = b2 - bp * u2
    base = (ap - bp) * (ap - bp) + x0 * x0 + x1 * x1 + x2 * x2 + y0 * y0 + y1 * y1 + y2 * y2
    A = x0 * y0 + x1 * y1 + x2 * y2
    B = (u1 * x2 - u2 * x1) * y0 + (u2 * x0 - u0 * x2) * y1 + (u0 * x1 - u1 * x0) * y2
    fmax = max(A, A * math.cos(th) + B * math.sin(th))
    ps = math.atan2(B, A)
    lo = min(0.0, th)
    hi = max(0.0, th)
    if lo <= ps <= hi:
        fmax = math.sqrt(A * A + B * B)
    d2 = base - 2.0 * fmax
    return d2 if d2 > 0.0 else 0.0


@njit(cache=True)
def path_min2(m1, x, m2, y, mkind, mc, mt, mu, mth, mq):
    """Squared distance of closest approach, along the move's path, of a node at x (3,) carried by motion m1 and
    one at y carried by m2 (one of them fixed, or a rotation and the translation that follows it); -1 for a pair
    of motions no move produces."""
    k1 = mkind[m1]
    k2 = mkind[m2]
    if k1 == K_FIXED or k1 == K_TWIST:
        m1, m2 = m2, m1
        k1, k2 = k2, k1
        x, y = y, x
    if k2 == K_FIXED or k2 == K_TWIST:
        if k1 == K_ROT:
            return arc_min2(x[0] - mc[m1, 0], x[1] - mc[m1, 1], x[2] - mc[m1, 2], y[0] - mc[m1, 0],
                            y[1] - mc[m1, 1], y[2] - mc[m1, 2], mu[m1, 0], mu[m1, 1], mu[m1, 2], mth[m1])
        if k1 == K_TRANSARC:
            a0 = mq[m1, 0] - mc[m1, 0]
            a1 = mq[m1, 1] - mc[m1, 1]
            a2 = mq[m1, 2] - mc[m1, 2]
            return arc_min2(a0, a1, a2, y[0] - x[0] + a0, y[1] - x[1] + a1, y[2] - x[2] + a2, mu[m1, 0], mu[m1, 1],
                            mu[m1, 2], mth[m1])
        if k1 == K_LINEAR:
            d0 = x[0] - y[0]
            d1 = x[1] - y[1]
            d2 = x[2] - y[2]
            tt = mt[m1, 0] * mt[m1, 0] + mt[m1, 1] * mt[m1, 1] + mt[m1, 2] * mt[m1, 2]
            s = 0.0
            if tt > 0.0:
                s = -(d0 * mt[m1, 0] + d1 * mt[m1, 1] + d2 * mt[m1, 2]) / tt
                s = min(1.0, max(0.0, s))
            d0 += s * mt[m1, 0]
            d1 += s * mt[m1, 1]
            d2 += s * mt[m1, 2]
            return d0 * d0 + d1 * d1 + d2 * d2
        return -1.0
    if k1 == K_TRANSARC and k2 == K_ROT:
        m1, m2 = m2, m1
        k1, k2 = k2, k1
        x, y = y, x
    if k1 == K_ROT and k2 == K_TRANSARC:
        # the tail follows the arc of q about the rotation's own axis: relative path R(phi) (x - q) vs (y - q)
        return arc_min2(x[0] - mq[m2, 0], x[1] - mq[m2, 1], x[2] - mq[m2, 2], y[0] - mq[m2, 0], y[1] - mq[m2, 1],
                        y[2] - mq[m2, 2], mu[m1, 0], mu[m1, 1], mu[m1, 2], mth[m1])
    return -1.0


@njit(cache=True)
def nonbonded_delta(pos, nseg, slo, shi, smid, mkind, mR, mc, mt, mu, mth, mq, mb, tlo, thi, tcen, trad, ip, fp,
                    stack):
    """Non-bonded energy change (kJ/mol) of a move (segments and motions as in :func:`sweep`); ``inf`` if two
    interacting nodes come within the hard core at its end or along its path (module docstring)."""
    n = pos.shape[0]
    circ = ip[I_CIRC] == 1
    nex = ip[I_NEX]
    ev = ip[I_EV] == 1
    P = ip[I_P]
    cut = fp[F_CUT]
    cut2 = cut * cut
    rhc = fp[F_RHC]
    rhc2 = rhc * rhc
    x = np.empty(3)
    y = np.empty(3)
    dE = 0.0
    for s1 in range(nseg):
        m1 = smid[s1]
        for s2 in range(s1 + 1, nseg):
            m2 = smid[s2]
            if m1 == m2:
                continue
            k1 = mkind[m1]
            k2 = mkind[m2]
            if (k1 == K_FIXED or k1 == K_TWIST) and (k2 == K_FIXED or k2 == K_TWIST):
                continue
            sp = 1
            stack[0, 0] = 1
            stack[0, 1] = 1
            while sp > 0:
                sp -= 1
                ta = stack[sp, 0]
                tb = stack[sp, 1]
                alo = max(tlo[ta], slo[s1])
                ahi = min(thi[ta], shi[s1])
                if alo > ahi:
                    continue
                blo = max(tlo[tb], slo[s2])
                bhi = min(thi[tb], shi[s2])
                if blo > bhi:
                    continue
                # segments are ordered along the chain: every j - i lies in [blo - ahi, bhi - alo]
                if bhi - alo <= nex or (circ and blo - ahi >= n - nex):
                    continue
                ra = trad[ta]
                rb = trad[tb]
                dx = tcen[tb, 0] - tcen[ta, 0]
                dy = tcen[tb, 1] - tcen[ta, 1]
                dz = tcen[tb, 2] - tcen[ta, 2]
                gap = math.sqrt(dx * dx + dy * dy + dz * dz) - ra - rb
                if gap < cut:
                    pass  # interacting before the move
                else:
                    # after the move: the spheres move rigidly with their segments' motions
                    a0, a1, a2 = move_point(m1, tcen[ta, 0], tcen[ta, 1], tcen[ta, 2], mkind, mR, mc, mt)
                    b0, b1, b2 = move_point(m2, tcen[tb, 0], tcen[tb, 1], tcen[tb, 2], mkind, mR, mc, mt)
                    if math.sqrt((b0 - a0) ** 2 + (b1 - a1) ** 2 + (b2 - a2) ** 2) - ra - rb >= cut:
                        # on the way: within the displacement bounds, against the hard core only
                        if not ev:
                            continue
                        if gap - rel_bound(m1, tcen[ta, 0], tcen[ta, 1], tcen[ta, 2], ra, m2, tcen[tb, 0],
                                           tcen[tb, 1], tcen[tb, 2], rb, mkind, mc, mu, mq, mb) >= rhc:
                            continue
                la = ta >= P
                lb = tb >= P
                if la and lb:
                    nb0, nb1, nb2 = move_point(m2, tcen[tb, 0], tcen[tb, 1], tcen[tb, 2], mkind, mR, mc, mt)
                    for i in range(alo, ahi + 1):
                        x[0] = pos[i, 0]
                        x[1] = pos[i, 1]
                        x[2] = pos[i, 2]
                        yi0, yi1, yi2 = move_point(m1, x[0], x[1], x[2], mkind, mR, mc, mt)
                        # node i against leaf b's sphere, before, after and (hard core) on the way
                        gi = math.sqrt((tcen[tb, 0] - x[0]) ** 2 + (tcen[tb, 1] - x[1]) ** 2
                                       + (tcen[tb, 2] - x[2]) ** 2) - rb
                        # bound on the change of the vector from i to any node of b along the path
                        relmax = rel_bound(m1, x[0], x[1], x[2], 0.0, m2, tcen[tb, 0], tcen[tb, 1], tcen[tb, 2], rb,
                                           mkind, mc, mu, mq, mb) if ev else 0.0
                        if gi >= cut and math.sqrt((nb0 - yi0) ** 2 + (nb1 - yi1) ** 2 + (nb2 - yi2) ** 2) - rb >= cut:
                            if not ev or gi - relmax >= rhc:
                                continue
                        reach2 = (rhc + relmax) ** 2
                        j0 = max(blo, i + nex + 1)
                        j1 = min(bhi, i + n - nex - 1) if circ else bhi
                        for j in range(j0, j1 + 1):
                            y[0] = pos[j, 0]
                            y[1] = pos[j, 1]
                            y[2] = pos[j, 2]
                            d0 = (y[0] - x[0]) ** 2 + (y[1] - x[1]) ** 2 + (y[2] - x[2]) ** 2
                            yj0, yj1, yj2 = move_point(m2, y[0], y[1], y[2], mkind, mR, mc, mt)
                            d1 = (yj0 - yi0) ** 2 + (yj1 - yi1) ** 2 + (yj2 - yi2) ** 2
                            if ev:
                                if d1 < rhc2:
                                    return np.inf
                                # the relative path is an arc (or a line) whose points lie within its chord of the
                                # start, itself within relmax
                                if d0 < reach2:
                                    rel = math.sqrt((yj0 - yi0 - y[0] + x[0]) ** 2 + (yj1 - yi1 - y[1] + x[1]) ** 2
                                                    + (yj2 - yi2 - y[2] + x[2]) ** 2)
                                    if math.sqrt(d0) - rel < rhc:
                                        pm = path_min2(m1, x, m2, y, mkind, mc, mt, mu, mth, mq)
                                        if pm < rhc2:
                                            return np.inf
                            if d0 < cut2:
                                dE -= pair_energy(d0, fp)
                            if d1 < cut2:
                                dE += pair_energy(d1, fp)
                elif lb or (not la and ra >= rb):
                    stack[sp, 0] = 2 * ta
                    stack[sp, 1] = tb
                    stack[sp + 1, 0] = 2 * ta + 1
                    stack[sp + 1, 1] = tb
                    sp += 2
                else:
                    stack[sp, 0] = ta
                    stack[sp, 1] = 2 * tb
                    stack[sp + 1, 0] = ta
                    stack[sp + 1, 1] = 2 * tb + 1
                    sp += 2
    return dE


# --- external energy -------------------------------------------------------------------------------------------------
# per-node load tables: force (n, 3); trap_k (n,), trap_c (n, 3); rc_k (n,), rc_T (n, 3, 3); tq_mag (n,),
# tq_axis (n, 3), tq_ref (n, 3, 3), tq_last (n,), tq_phi (n,); radius (n,) particle circumradius (walls)


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


@njit(cache=True)
def node_loads(k, r, L, force, trap_k, trap_c, rc_k, rc_T, tq_mag, tq_axis, tq_ref, tq_last, tq_phi):
    """Load energy (kJ/mol) of node k at pose (r (3,), L (3, 3)) (the walls are separate). A dead torque contributes
    ``-|tau| phi`` with phi continued from the node's current unwrapped angle."""
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
    return E


@njit(cache=True, inline="always")
def surface_energy(k, z, L20, L21, l, ip, fp):
    """Surface-wall energy (kJ/mol) of node k's three particles (centre height z, frame entries L[2, 0], L[2, 1],
    circumradius l)."""
    if ip[I_WALLS] != 1 or k < ip[I_SKIP]:
        return 0.0
    z0 = fp[F_WZ0]
    E = 0.0
    for p in range(3):
        if p == 0:
            zp = z + l * L20
        elif p == 1:
            zp = z + l * (-0.5 * L20 + _SQ3H * L21)
        else:
            zp = z + l * (-0.5 * L20 - _SQ3H * L21)
        d = zp - z0
        if d < 0.0:
            E += 0.5 * fp[F_WK] * d * d
    return E


@njit(cache=True, inline="always")
def bead_term(k, zfirst, zc, n, ip, fp):
    """Bead-wall energy of node k's first particle at height zfirst below the last node's centre zc."""
    if ip[I_WALLS] != 1 or k >= n - ip[I_SKIP]:
        return 0.0
    d = zfirst - zc
    return 0.5 * fp[F_WK] * d * d if d > 0.0 else 0.0


@njit(cache=True)
def wall_energies(pos, frm, radius, ip, fp, esurf, ebead):
    """Per-node surface and bead wall energies into esurf, ebead (n,); returns their total (kJ/mol)."""
    n = pos.shape[0]
    zc = pos[n - 1, 2]
    E = 0.0
    for k in range(n):
        esurf[k] = surface_energy(k, pos[k, 2], frm[k, 2, 0], frm[k, 2, 1], radius[k], ip, fp)
        ebead[k] = bead_term(k, pos[k, 2] + radius[k] * frm[k, 2, 0], zc, n, ip, fp)
        E += esurf[k] + ebead[k]
    return E


@njit(cache=True, inline="always")
def _mid_of(k, nseg, slo, shi, smid):
    for s in range(nseg):
        if slo[s] <= k <= shi[s]:
            return smid[s]
    return 0


@njit(cache=True)
def wall_delta(pos, frm, radius, nseg, slo, shi, smid, mkind, mR, mc, mt, mth, esurf, ebead, tlo, thi, tcen, trad,
               ip, fp, stack, wnode, wsurf, wbead, Lt):
    """Wall energy change (kJ/mol) of a move and the number of nodes whose wall energies it changes (their index,
    new surface and bead energies into wnode, wsurf, wbead)."""
    n = pos.shape[0]
    P = ip[I_P]
    z0 = fp[F_WZ0]
    pr = fp[F_PRAD]
    mbd = _mid_of(n - 1, nseg, slo, shi, smid)
    zc_old = pos[n - 1, 2]
    zc_new = move_point(mbd, pos[n - 1, 0], pos[n - 1, 1], pos[n - 1, 2], mkind, mR, mc, mt)[2]
    bead_moved = zc_new != zc_old
    zlow = min(zc_old, zc_new)
    dE = 0.0
    nw = 0
    for s in range(nseg):
        m = smid[s]
        moved = mkind[m] != K_FIXED
        if not moved and not bead_moved:
            continue
        lo_s = slo[s]
        hi_s = shi[s]
        sp = 1
        stack[0, 0] = 1
        while sp > 0:
            sp -= 1
            t = stack[sp, 0]
            lo = max(tlo[t], lo_s)
            hi = min(thi[t], hi_s)
            if lo > hi:
                continue
            r = trad[t]
            cz = tcen[t, 2]
            if moved:
                # old sphere against the old planes, or the moved sphere (rigidly carried) against the new ones
                near = (cz - r - pr < z0) or (cz + r + pr > zc_old)
                if not near:
                    nz = move_point(m, tcen[t, 0], tcen[t, 1], cz, mkind, mR, mc, mt)[2]
                    near = (nz - r - pr < z0) or (nz + r + pr > zc_new)
            else:
                near = cz + r + pr > zlow
            if not near:
                continue
            if t >= P:
                for i in range(lo, hi + 1):
                    if moved:
                        y0, y1, y2 = move_point(m, pos[i, 0], pos[i, 1], pos[i, 2], mkind, mR, mc, mt)
                        move_frame(m, frm[i], mkind, mR, mth, Lt)
                        es = surface_energy(i, y2, Lt[2, 0], Lt[2, 1], radius[i], ip, fp)
                        eb = bead_term(i, y2 + radius[i] * Lt[2, 0], zc_new, n, ip, fp)
                    else:
                        es = esurf[i]
                        eb = bead_term(i, pos[i, 2] + radius[i] * frm[i, 2, 0], zc_new, n, ip, fp)
                    if es != esurf[i] or eb != ebead[i]:
                        dE += es + eb - esurf[i] - ebead[i]
                        wnode[nw] = i
                        wsurf[nw] = es
                        wbead[nw] = eb
                        nw += 1
            else:
                stack[sp, 0] = 2 * t
                stack[sp + 1, 0] = 2 * t + 1
                sp += 2
    return dE, nw


# --- the move loop ---------------------------------------------------------------------------------------------------


@njit(cache=True)
def _set_rot(m, ax0, ax1, ax2, ang, cx, cy, cz, mkind, mR, mc, mt, mu, mth, mq, mb):
    mkind[m] = K_ROT
    _rotation(ax0, ax1, ax2, ang, mR[m])
    mc[m, 0] = cx
    mc[m, 1] = cy
    mc[m, 2] = cz
    mu[m, 0] = ax0
    mu[m, 1] = ax1
    mu[m, 2] = ax2
    mth[m] = ang
    mb[m] = 2.0 * abs(math.sin(0.5 * ang))
    for a in range(3):
        mt[m, a] = 0.0
        mq[m, a] = 0.0


@njit(cache=True)
def _range_segments(lo, ln, n, circ, mid, slo, shi, smid):
    """Segments of a chain whose nodes lo .. lo+ln-1 (mod n on a ring) move with motion ``mid`` and the rest is fixed
    (motion 0); returns their number."""
    hi = lo + ln - 1
    ns = 0
    if hi < n:
        if lo > 0:
            slo[ns] = 0
            shi[ns] = lo - 1
            smid[ns] = 0
            ns += 1
        slo[ns] = lo
        shi[ns] = hi
        smid[ns] = mid
        ns += 1
        if hi < n - 1:
            slo[ns] = hi + 1
            shi[ns] = n - 1
            smid[ns] = 0
            ns += 1
    else:  # wraps past node 0 (rings only)
        slo[ns] = 0
        shi[ns] = hi - n
        smid[ns] = mid
        ns += 1
        if hi - n + 1 <= lo - 1:
            slo[ns] = hi - n + 1
            shi[ns] = lo - 1
            smid[ns] = 0
            ns += 1
        slo[ns] = lo
        shi[ns] = n - 1
        smid[ns] = mid
        ns += 1
    return ns


@njit(cache=True)
def sweep(pos, frm, K, xi0, Qc, tc, movable, clamp_prefix, ext_nodes, force, trap_k, trap_c, rc_k, rc_T, tq_mag,
          tq_axis, tq_ref, tq_last, tq_phi, radius, ip, fp, estep, enode, esurf, ebead, tlo, thi, tcen, trad, rng,
          n_moves, p_cum, amp, lmax, counts, energy):
    """Attempt ``n_moves`` Monte Carlo moves (module docstring); the state arrays are updated in place.

    Parameters
    ----------
    pos, frm, K, xi0, Qc, tc, force, trap_k, trap_c, rc_k, rc_T, tq_mag, tq_axis, tq_ref, tq_last, tq_phi, radius, \
ip, fp, n_moves
        The pose and the load tables (:class:`dnarod.engines.mc.engine.MCEngine` builds them).
    movable : ndarray of bool, shape (n,)
    clamp_prefix : ndarray of int, shape (n + 1,)
        Clamped nodes before each index.
    ext_nodes : ndarray of int, shape (n_ext,)
        The nodes with a load.
    estep, enode, esurf, ebead : ndarray
        Energy of every step (m,), load energy of every node (n,), wall energies of every node (n,); kept current.
    tlo, thi, tcen, trad : ndarray
        The bounding-sphere tree (kept current).
    rng : ndarray of uint64, shape (4,)
        xoshiro256+ state.
    p_cum : ndarray, shape (N_TYPES,)
        Cumulative probabilities of the move types.
    amp : ndarray, shape (N_TYPES, N_BINS)
        Amplitudes by type and segment-length octave: rad, except the node move (``amp[0, 0]`` translation
        half-width, nm; ``amp[0, 1]`` Cayley ball radius, rad).
    lmax : ndarray of int, shape (N_TYPES,)
        Largest segment (nodes) of each type.
    counts : ndarray of int64, shape (N_TYPES, N_BINS, 2)
        Attempted and accepted moves (incremented).
    energy : ndarray, shape (3,)
        Elastic, non-bonded, external (loads and walls) running totals (kJ/mol, incremented).

    Returns
    -------
    int
        0, or -1 if a non-finite energy was accepted (never expected), or -2 if a move produced a pair of motions
        the topology check does not know (a bug).
    """
    n = pos.shape[0]
    circ = ip[I_CIRC] == 1
    m_steps = n if circ else n - 1
    ds = fp[F_DS]
    beta = 1.0 / fp[F_KT]
    has_nb = ip[I_NB] == 1
    walls = ip[I_WALLS] == 1
    ev = ip[I_EV] == 1
    axi = ip[I_AXI] == 1
    idclos = ip[I_IDCLOS] == 1
    leaf = ip[I_LEAF]
    lmax2 = fp[F_LMAX] * fp[F_LMAX]
    n_ext = ext_nodes.shape[0]
    n_mov = 0
    for i in range(n):
        if movable[i]:
            n_mov += 1
    movlist = np.empty(max(1, n_mov), np.int64)
    q_ = 0
    for i in range(n):
        if movable[i]:
            movlist[q_] = i
            q_ += 1
    slo = np.zeros(MAX_SEG, np.int64)
    shi = np.zeros(MAX_SEG, np.int64)
    smid = np.zeros(MAX_SEG, np.int64)
    mkind = np.zeros(MAX_MOT, np.int64)
    mR = np.zeros((MAX_MOT, 3, 3))
    mc = np.zeros((MAX_MOT, 3))
    mt = np.zeros((MAX_MOT, 3))
    mu = np.zeros((MAX_MOT, 3))
    mth = np.zeros(MAX_MOT)
    mq = np.zeros((MAX_MOT, 3))
    mb = np.zeros(MAX_MOT)
    stack = np.zeros((_STACK, 2), np.int64)
    wnode = np.zeros(n, np.int64)
    wsurf = np.zeros(n)
    wbead = np.zeros(n)
    steps = np.zeros(n + 4, np.int64)
    newstep = np.zeros(n + 4)
    newext = np.zeros(max(1, n_ext))
    u = np.empty(3)
    rl = np.empty(3)
    Ll = np.empty((3, 3))
    rr = np.empty(3)
    Lr = np.empty((3, 3))
    Lt = np.empty((3, 3))
    rimg = np.empty(3)
    Limg = np.empty((3, 3))
    for it in range(n_moves):
        x = rng_uniform(rng)
        mt_ = 0
        while mt_ < N_TYPES - 1 and x >= p_cum[mt_]:
            mt_ += 1
        mkind[0] = K_FIXED
        nseg = 0
        bin_ = 0
        ok = True
        # ---- propose: segments (slo, shi, smid) and motions 1, 2 ---------------------------------------------
        if mt_ == MT_NODE:
            if n_mov == 0:
                continue
            k = movlist[int(rng_uniform(rng) * n_mov)]
            while True:
                for a in range(3):
                    u[a] = 2.0 * rng_uniform(rng) - 1.0
                if u[0] * u[0] + u[1] * u[1] + u[2] * u[2] <= 1.0:
                    break
            w0 = amp[0, 1] * u[0]
            w1 = amp[0, 1] * u[1]
            w2 = amp[0, 1] * u[2]
            qq = 1.0 + 0.25 * (w0 * w0 + w1 * w1 + w2 * w2)
            mkind[1] = K_LINEAR
            mR[1, 0, 0] = 1.0 - 0.5 * (w1 * w1 + w2 * w2) / qq
            mR[1, 1, 1] = 1.0 - 0.5 * (w0 * w0 + w2 * w2) / qq
            mR[1, 2, 2] = 1.0 - 0.5 * (w0 * w0 + w1 * w1) / qq
            mR[1, 0, 1] = (-w2 + 0.5 * w0 * w1) / qq
            mR[1, 1, 0] = (w2 + 0.5 * w0 * w1) / qq
            mR[1, 0, 2] = (w1 + 0.5 * w0 * w2) / qq
            mR[1, 2, 0] = (-w1 + 0.5 * w0 * w2) / qq
            mR[1, 1, 2] = (-w0 + 0.5 * w1 * w2) / qq
            mR[1, 2, 1] = (w0 + 0.5 * w1 * w2) / qq
            tn = 0.0
            for a in range(3):
                mt[1, a] = amp[0, 0] * (2.0 * rng_uniform(rng) - 1.0)
                tn += mt[1, a] * mt[1, a]
                mc[1, a] = pos[k, a]
            mb[1] = math.sqrt(tn)
            nseg = _range_segments(k, 1, n, circ, 1, slo, shi, smid)
        elif mt_ == MT_CRANK or mt_ == MT_TWIST:
            cap = n - 2 if mt_ == MT_CRANK else n
            if circ and mt_ == MT_TWIST:
                cap = n - 1
            ln = segment_length(rng, min(lmax[mt_], cap))
            if ln < 1 or ln > cap:
                continue
            bin_ = length_bin(ln)
            if circ:
                a0 = int(rng_uniform(rng) * n)
                if mt_ == MT_CRANK:
                    a0 = (a0 + 1) % n  # the moved nodes follow hinge node a0 - 1
                if not idclos and a0 + ln > n:
                    continue
            else:
                if mt_ == MT_CRANK:
                    a0 = 1 + int(rng_uniform(rng) * (n - 1 - ln))
                else:
                    a0 = int(rng_uniform(rng) * (n - ln + 1))
            hi0 = a0 + ln - 1
            if hi0 < n:
                if clamp_prefix[hi0 + 1] - clamp_prefix[a0] > 0:
                    continue
            elif clamp_prefix[n] - clamp_prefix[a0] + clamp_prefix[hi0 - n + 1] > 0:
                continue
            ang = amp[mt_, bin_] * (2.0 * rng_uniform(rng) - 1.0)
            if mt_ == MT_TWIST:
                mkind[1] = K_TWIST
                mth[1] = ang
                mb[1] = 0.0
            else:
                i0 = (a0 - 1) % n
                j0 = (a0 + ln) % n
                ax0 = pos[j0, 0] - pos[i0, 0]
                ax1 = pos[j0, 1] - pos[i0, 1]
                ax2 = pos[j0, 2] - pos[i0, 2]
                an = math.sqrt(ax0 * ax0 + ax1 * ax1 + ax2 * ax2)
                if an == 0.0:
                    continue
                _set_rot(1, ax0 / an, ax1 / an, ax2 / an, ang, pos[i0, 0], pos[i0, 1], pos[i0, 2], mkind, mR, mc,
                         mt, mu, mth, mq, mb)
            nseg = _range_segments(a0, ln, n, circ, 1, slo, shi, smid)
        elif mt_ == MT_SLIDE:
            cap = n - 1
            ln = segment_length(rng, min(lmax[MT_SLIDE], cap))
            bin_ = length_bin(ln)
            if circ:
                a0 = int(rng_uniform(rng) * n)
                if not idclos and a0 + ln > n:
                    continue
            else:
                a0 = int(rng_uniform(rng) * (n - ln + 1))
            hi0 = a0 + ln - 1
            if hi0 < n:
                if clamp_prefix[hi0 + 1] - clamp_prefix[a0] > 0:
                    continue
            elif clamp_prefix[n] - clamp_prefix[a0] + clamp_prefix[hi0 - n + 1] > 0:
                continue
            mkind[1] = K_LINEAR
            tn = 0.0
            for a in range(3):
                for b in range(3):
                    mR[1, a, b] = 1.0 if a == b else 0.0
                mt[1, a] = amp[MT_SLIDE, bin_] * (2.0 * rng_uniform(rng) - 1.0)
                tn += mt[1, a] * mt[1, a]
            mb[1] = math.sqrt(tn)
            nseg = _range_segments(a0, ln, n, circ, 1, slo, shi, smid)
        elif mt_ == MT_ENDTWIST:
            if circ:
                continue
            ln = segment_length(rng, min(lmax[MT_TWIST], n - 1))
            bin_ = length_bin(ln)
            a0 = n - ln if rng_uniform(rng) < 0.5 else 0
            if clamp_prefix[a0 + ln] - clamp_prefix[a0] > 0:
                continue
            mkind[1] = K_TWIST
            mth[1] = amp[MT_ENDTWIST, bin_] * (2.0 * rng_uniform(rng) - 1.0)
            mb[1] = 0.0
            nseg = _range_segments(a0, ln, n, circ, 1, slo, shi, smid)
        elif mt_ == MT_PIVOT:
            if circ:
                continue
            kp = int(rng_uniform(rng) * n)
            if rng_uniform(rng) < 0.5:
                lo = kp
                ln = n - kp
            else:
                lo = 0
                ln = kp + 1
            if ln > lmax[MT_PIVOT] or clamp_prefix[lo + ln] - clamp_prefix[lo] > 0:
                continue
            bin_ = length_bin(ln)
            _unit_vector(rng, u)
            amax = math.pi if ln == n else amp[MT_PIVOT, bin_]
            ang = amax * (2.0 * rng_uniform(rng) - 1.0)
            _set_rot(1, u[0], u[1], u[2], ang, pos[kp, 0], pos[kp, 1], pos[kp, 2], mkind, mR, mc, mt, mu, mth, mq,
                     mb)
            nseg = _range_segments(lo, ln, n, circ, 1, slo, shi, smid)
        else:  # MT_HINGE
            if circ:
                continue
            a0 = int(rng_uniform(rng) * n)
            ln = segment_length(rng, min(lmax[MT_HINGE], n))
            b0 = min(a0 + ln - 1, n - 1)
            if clamp_prefix[n] - clamp_prefix[a0] > 0:
                continue
            bin_ = length_bin(b0 - a0 + 1)
            _unit_vector(rng, u)
            ang = amp[MT_HINGE, bin_] * (2.0 * rng_uniform(rng) - 1.0)
            _set_rot(1, u[0], u[1], u[2], ang, pos[a0, 0], pos[a0, 1], pos[a0, 2], mkind, mR, mc, mt, mu, mth,
                     mq, mb)
            if a0 > 0:
                slo[nseg] = 0
                shi[nseg] = a0 - 1
                smid[nseg] = 0
                nseg += 1
            slo[nseg] = a0
            shi[nseg] = b0
            smid[nseg] = 1
            nseg += 1
            if b0 < n - 1:
                mkind[2] = K_TRANSARC
                qx0, qx1, qx2 = move_point(1, pos[b0, 0], pos[b0, 1], pos[b0, 2], mkind, mR, mc, mt)
                mt[2, 0] = qx0 - pos[b0, 0]
                mt[2, 1] = qx1 - pos[b0, 1]
                mt[2, 2] = qx2 - pos[b0, 2]
                mb[2] = math.sqrt(mt[2, 0] ** 2 + mt[2, 1] ** 2 + mt[2, 2] ** 2)
                for a in range(3):
                    mq[2, a] = pos[b0, a]
                    mc[2, a] = mc[1, a]
                    mu[2, a] = mu[1, a]
                mth[2] = mth[1]
                slo[nseg] = b0 + 1
                shi[nseg] = n - 1
                smid[nseg] = 2
                nseg += 1
        if nseg == 0:
            continue
        counts[mt_, bin_, 0] += 1
        # ---- elastic: the steps between differently moving nodes (all steps of a twisted segment off axisymmetry) --
        ns = 0
        for s in range(nseg):
            if mkind[smid[s]] == K_TWIST and not axi:
                k_first = slo[s] - 1
                if k_first < 0 and (not circ or _mid_of(n - 1, nseg, slo, shi, smid) == smid[s]):
                    k_first = slo[s]  # no step before node 0, or the step n-1 is listed by the wrapped piece
                for k in range(k_first, shi[s] + 1):
                    if k % n < m_steps:
                        steps[ns] = k % n
                        ns += 1
        for s in range(nseg):
            k = shi[s]  # the step from the segment's last node to the next segment's first
            if k >= m_steps:
                continue
            s2 = s + 1 if s + 1 < nseg else 0
            if smid[s] == smid[s2]:
                continue
            if mkind[smid[s]] == K_TWIST and not axi:
                continue  # listed above
            if mkind[smid[s2]] == K_TWIST and not axi and s2 != s:
                # the step into a non-axisymmetric twisted segment is listed above (its first step)
                continue
            steps[ns] = k
            ns += 1
        dE_el = 0.0
        for q_ in range(ns):
            k = steps[q_]
            jn = (k + 1) % n
            mk = _mid_of(k, nseg, slo, shi, smid)
            mj = _mid_of(jn, nseg, slo, shi, smid)
            rl[0], rl[1], rl[2] = move_point(mk, pos[k, 0], pos[k, 1], pos[k, 2], mkind, mR, mc, mt)
            move_frame(mk, frm[k], mkind, mR, mth, Ll)
            rr[0], rr[1], rr[2] = move_point(mj, pos[jn, 0], pos[jn, 1], pos[jn, 2], mkind, mR, mc, mt)
            move_frame(mj, frm[jn], mkind, mR, mth, Lr)
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
            continue
        # ---- loads of the moved nodes ----------------------------------------------------------------------------
        dE_ext = 0.0
        for q_ in range(n_ext):
            k = ext_nodes[q_]
            mk = _mid_of(k, nseg, slo, shi, smid)
            if mkind[mk] == K_FIXED:
                newext[q_] = enode[k]
                continue
            rl[0], rl[1], rl[2] = move_point(mk, pos[k, 0], pos[k, 1], pos[k, 2], mkind, mR, mc, mt)
            move_frame(mk, frm[k], mkind, mR, mth, Lt)
            e = node_loads(k, rl, Lt, force, trap_k, trap_c, rc_k, rc_T, tq_mag, tq_axis, tq_ref, tq_last, tq_phi)
            newext[q_] = e
            dE_ext += e - enode[k]
        nw = 0
        if walls:
            dw, nw = wall_delta(pos, frm, radius, nseg, slo, shi, smid, mkind, mR, mc, mt, mth, esurf, ebead, tlo,
                                thi, tcen, trad, ip, fp, stack, wnode, wsurf, wbead, Lt)
            dE_ext += dw
        # ---- delayed acceptance: first the local terms, then (only if they pass) the non-bonded pairs -------------
        dE1 = dE_el + dE_ext
        if not (dE1 < np.inf):
            continue
        if dE1 > 0.0 and rng_uniform(rng) >= math.exp(-beta * dE1):
            continue
        dE_nb = 0.0
        if has_nb:
            dE_nb = nonbonded_delta(pos, nseg, slo, shi, smid, mkind, mR, mc, mt, mu, mth, mq, mb, tlo, thi, tcen,
                                    trad, ip, fp, stack)
            if not (dE_nb < np.inf):
                continue
            if dE_nb > 0.0 and rng_uniform(rng) >= math.exp(-beta * dE_nb):
                continue
        # ---- accept ------------------------------------------------------------------------------------------------
        counts[mt_, bin_, 1] += 1
        energy[0] += dE_el
        energy[1] += dE_nb
        energy[2] += dE_ext
        for q_ in range(ns):
            estep[steps[q_]] = newstep[q_]
        for q_ in range(nw):
            esurf[wnode[q_]] = wsurf[q_]
            ebead[wnode[q_]] = wbead[q_]
        for s in range(nseg):
            m = smid[s]
            kd = mkind[m]
            if kd == K_FIXED:
                continue
            for i in range(slo[s], shi[s] + 1):
                if kd != K_TWIST:
                    pos[i, 0], pos[i, 1], pos[i, 2] = move_point(m, pos[i, 0], pos[i, 1], pos[i, 2], mkind, mR, mc,
                                                                 mt)
                if kd != K_TRANSARC:
                    move_frame(m, frm[i], mkind, mR, mth, Lt)
                    for a in range(3):
                        for b in range(3):
                            frm[i, a, b] = Lt[a, b]
            if kd != K_TWIST and (has_nb or walls):
                tree_update(pos, slo[s], shi[s], leaf, ip[I_P], tlo, thi, tcen, trad)
        for q_ in range(n_ext):
            k = ext_nodes[q_]
            if mkind[_mid_of(k, nseg, slo, shi, smid)] == K_FIXED:
                continue
            if tq_mag[k] > 0.0:
                ang2 = swing_twist_angle(frm[k], tq_ref[k], tq_axis[k])
                tq_phi[k] += wrap_pi(ang2 - tq_last[k])
                tq_last[k] = ang2
            enode[k] = newext[q_]
        if not (energy[0] + energy[1] + energy[2] < np.inf):
            return -1
    return 0


# --- the clamp torque from the tail-rotation identity ----------------------------------------------------------------


@njit(cache=True)
def nonbonded_pair_sums(pos, tlo, thi, tcen, trad, ip, fp, dA, dF):
    """Every interacting pair (i < j, chain separation > n_ex, closer than the cut-off) adds, over the steps
    k = i .. j-1 it straddles, the z torque ``(r_j x f_j)_z`` and the force ``f_j`` on j (from i): difference arrays
    ``dA`` (n + 1,) and ``dF`` (n + 1, 2) (x and y) to be summed cumulatively. Open chains; found with the tree."""
    nex = ip[I_NEX]
    P = ip[I_P]
    cut = fp[F_CUT]
    cut2 = cut * cut
    stack = np.zeros((_STACK, 2), np.int64)
    sp = 1
    stack[0, 0] = 1
    stack[0, 1] = 1
    while sp > 0:
        sp -= 1
        ta = stack[sp, 0]
        tb = stack[sp, 1]
        if tlo[ta] > thi[ta] or tlo[tb] > thi[tb]:
            continue
        if ta != tb:
            if thi[tb] - tlo[ta] <= nex:
                continue
            dx = tcen[tb, 0] - tcen[ta, 0]
            dy = tcen[tb, 1] - tcen[ta, 1]
            dz = tcen[tb, 2] - tcen[ta, 2]
            lim = cut + trad[ta] + trad[tb]
            if dx * dx + dy * dy + dz * dz >= lim * lim:
                continue
        if ta >= P and tb >= P:
            for i in range(tlo[ta], thi[ta] + 1):
                for j in range(max(tlo[tb], i + nex + 1), thi[tb] + 1):
                    dx, dy, dz, r2 = pair_vector(pos, i, j)
                    if r2 >= cut2:
                        continue
                    g = pair_force_over_r(r2, fp)
                    fx = g * dx
                    fy = g * dy
                    A = pos[j, 0] * fy - pos[j, 1] * fx
                    dA[i] += A
                    dA[j] -= A
                    dF[i, 0] += fx
                    dF[j, 0] -= fx
                    dF[i, 1] += fy
                    dF[j, 1] -= fy
        elif ta == tb:
            stack[sp, 0] = 2 * ta
            stack[sp, 1] = 2 * ta
            stack[sp + 1, 0] = 2 * ta + 1
            stack[sp + 1, 1] = 2 * ta + 1
            stack[sp + 2, 0] = 2 * ta
            stack[sp + 2, 1] = 2 * ta + 1
            sp += 3
        elif tb >= P or (ta < P and trad[ta] >= trad[tb]):
            stack[sp, 0] = 2 * ta
            stack[sp, 1] = tb
            stack[sp + 1, 0] = 2 * ta + 1
            stack[sp + 1, 1] = tb
            sp += 2
        else:
            stack[sp, 0] = ta
            stack[sp, 1] = 2 * tb
            stack[sp + 1, 0] = ta
            stack[sp + 1, 1] = 2 * tb + 1
            sp += 2


@njit(cache=True)
def tail_torque_profile(pos, frm, K, xi0, ds, force, trap_k, trap_c, tq_mag, tq_axis, tlo, thi, tcen, trad, ip,
                        fp, k_first, out):
    """Estimates of the z torque (kJ/mol) the rotation clamps of the tail exert, one per step k >= k_first, into
    out (n - 1,) (NaN before k_first): minus the z torque, about node k+1's centre, of everything else acting on the
    tail (nodes ``k+1`` to ``n-1``) from outside it: step k, the non-bonded pairs across k, the pulling forces,
    traps and dead torques of the tail (the walls exert none: their forces are along z). Open chains."""
    n = pos.shape[0]
    sl = np.zeros(13)
    eye = np.eye(3)
    zero = np.zeros(3)
    dA = np.zeros(n + 1)
    dF = np.zeros((n + 1, 2))
    if ip[I_NB] == 1:
        nonbonded_pair_sums(pos, tlo, thi, tcen, trad, ip, fp, dA, dF)
    # loads of the tail: sum over j > k of (r_j x G_j)_z + tau_j,z and of G_j (x, y), accumulated from the end
    gA = 0.0
    gx = 0.0
    gy = 0.0
    A = 0.0
    Fx = 0.0
    Fy = 0.0
    for k in range(n - 1):
        out[k] = np.nan
    # pair sums over k are prefix sums of the difference arrays
    pA = np.zeros(n)
    pFx = np.zeros(n)
    pFy = np.zeros(n)
    for k in range(n):
        A += dA[k]
        Fx += dF[k, 0]
        Fy += dF[k, 1]
        pA[k] = A
        pFx[k] = Fx
        pFy[k] = Fy
    for k in range(n - 2, -1, -1):
        j = k + 1
        G0 = force[j, 0] - trap_k[j] * (pos[j, 0] - trap_c[j, 0])
        G1 = force[j, 1] - trap_k[j] * (pos[j, 1] - trap_c[j, 1])
        gA += pos[j, 0] * G1 - pos[j, 1] * G0 + tq_mag[j] * tq_axis[j, 2]
        gx += G0
        gy += G1
        if k < k_first:
            continue
        step_loads(pos, frm, K, xi0, ds, k, False, j, eye, zero, sl)
        px = pos[j, 0]
        py = pos[j, 1]
        Z = sl[11] + (pA[k] - (px * pFy[k] - py * pFx[k])) + (gA - (px * gy - py * gx))
        out[k] = -Z



@njit(cache=True)
def height_clear_steps(z, nex, r0, out):
    """Steps no interacting pair straddles at a height difference below ``r0``: ``out[k]`` (n - 1,) is 1.0 if no
    pair ``i <= k < j`` with ``j - i > nex`` has ``|z_i - z_j| < r0`` (nm), else 0.0. A function of the heights
    ``z`` (n,) only, hence unchanged by any rotation about a lab z axis of any part of the chain (the weights of
    :meth:`dnarod.engines.mc.engine.MCEngine.tail_torque_z`). O(n log n + pairs within r0 in height)."""
    n = z.shape[0]
    order = np.argsort(z)
    d = np.zeros(n + 1)
    for a in range(n):
        i = order[a]
        for b in range(a + 1, n):
            j = order[b]
            if z[j] - z[i] >= r0:
                break
            lo = min(i, j)
            hi = max(i, j)
            if hi - lo > nex:
                d[lo] += 1.0
                d[hi] -= 1.0
    c = 0.0
    for k in range(n - 1):
        c += d[k]
        out[k] = 1.0 if c == 0.0 else 0.0
