"""The non-local terms of :mod:`dnarod.physics.nonbonded` as an OpenMM force.

The kernel is a numba Verlet neighbour list with a skin (:class:`VerletList`: pairs within
``cutoff + skin``, rebuilt by a cell list -- dense grid, or spatial hashing for any chain
extent, no box needed -- only when a node has moved half the skin), run through
``openmm.PythonForce``: a ``CustomNonbondedForce`` needs a box and, on the CPU
platform, a per-particle flag to act on one site per node, which the prototype measured 50x
slower than the bonded terms at 10^4 nodes.
"""
from __future__ import annotations

import math

import numba
import numpy as np

from dnarod.core.kernels import pair_vector
from dnarod.engines.openmm.forces import GROUPS, python_force
from dnarod.physics.nonbonded import DEFAULT_SKIN, _separation

@numba.njit(cache=True)
def build_pairs(c, rlist, circular, n_ex, pi, pj):
    """Node pairs ``(i, j)`` with centres closer than ``rlist`` and chain separation > ``n_ex``.

    Writes up to ``len(pi)`` pairs into ``pi``, ``pj`` and returns the number of pairs found
    (call again with larger arrays if it exceeds their length). Cell list with cells of size
    ``rlist``: a dense grid over the bounding box (counting sort, the cell itself and a half
    shell of 13 neighbour cells, pairs emitted in cell order for memory locality) when it has
    at most ~8n cells, else spatial hashing of the cells (any extent).
    """
    n = c.shape[0]
    cap = pi.shape[0]
    m = 0
    if rlist <= 0.0 or n < 2:
        return 0
    r2max = rlist * rlist
    lo = np.empty(3)
    hi = np.empty(3)
    for a in range(3):
        lo[a] = c[0, a]
        hi[a] = c[0, a]
    for i in range(n):
        for a in range(3):
            v = c[i, a]
            if v < lo[a]:
                lo[a] = v
            if v > hi[a]:
                hi[a] = v
    dims = np.empty(3, dtype=np.int64)
    total = 1.0
    for a in range(3):
        dims[a] = np.int64((hi[a] - lo[a]) / rlist) + 1
        total *= dims[a]
    if total <= 8.0 * n + 1000.0:
        nx, ny, nz = dims[0], dims[1], dims[2]
        ncell = nx * ny * nz
        cell = np.empty(n, dtype=np.int64)
        count = np.zeros(ncell + 1, dtype=np.int64)
        for i in range(n):
            ix = min(np.int64((c[i, 0] - lo[0]) / rlist), nx - 1)
            iy = min(np.int64((c[i, 1] - lo[1]) / rlist), ny - 1)
            iz = min(np.int64((c[i, 2] - lo[2]) / rlist), nz - 1)
            cell[i] = (ix * ny + iy) * nz + iz
            count[cell[i] + 1] += 1
        for k in range(ncell):
            count[k + 1] += count[k]
        order = np.empty(n, dtype=np.int64)
        fill = count[:-1].copy()
        for i in range(n):
            order[fill[cell[i]]] = i
            fill[cell[i]] += 1
        buf = np.empty(n, dtype=np.int64)
        for ix in range(nx):
            for iy in range(ny):
                for iz in range(nz):
                    a = (ix * ny + iy) * nz + iz
                    a0, a1 = count[a], count[a + 1]
                    if a0 == a1:
                        continue
                    nbuf = 0
                    for dx in range(0, 2):
                        for dy in range(-1, 2):
                            for dz in range(-1, 2):
                                if dx == 0 and (dy < 0 or (dy == 0 and dz <= 0)):
                                    continue
                                jx, jy, jz = ix + dx, iy + dy, iz + dz
                                if jx >= nx or jy < 0 or jy >= ny or jz < 0 or jz >= nz:
                                    continue
                                b = (jx * ny + jy) * nz + jz
                                for q in range(count[b], count[b + 1]):
                                    buf[nbuf] = order[q]
                                    nbuf += 1
                    for p in range(a0, a1):
                        i = order[p]
                        m_own = a1 - p - 1
                        for t in range(m_own + nbuf):
                            j = order[p + 1 + t] if t < m_own else buf[t - m_own]
                            if _separation(i, j, n, circular) <= n_ex:
                                continue
                            rx = c[j, 0] - c[i, 0]
                            ry = c[j, 1] - c[i, 1]
                            rz = c[j, 2] - c[i, 2]
                            if rx * rx + ry * ry + rz * rz >= r2max:
                                continue
                            if m < cap:
                                pi[m] = i
                                pj[m] = j
                            m += 1
        return m
    # Spatial hashing fallback (very spread-out configurations).
    nb = 1
    while nb < 2 * n:
        nb *= 2
    mask = nb - 1
    cellc = np.empty((n, 3), dtype=np.int64)
    head = -np.ones(nb, dtype=np.int64)
    nxt = np.empty(n, dtype=np.int64)
    for i in range(n):
        for a in range(3):
            cellc[i, a] = np.int64(math.floor(c[i, a] / rlist))
        h = ((cellc[i, 0] * 73856093) ^ (cellc[i, 1] * 19349663) ^ (cellc[i, 2] * 83492791)) & mask
        nxt[i] = head[h]
        head[h] = i
    # Each node visits its own cell (partners j > i) and a half shell of 13 neighbour cells (all
    # partners), keeping only bucket members whose cell is the target (buckets can collide).
    for i in range(n):
        cx, cy, cz = cellc[i, 0], cellc[i, 1], cellc[i, 2]
        for dx in range(0, 2):
            for dy in range(-1, 2):
                for dz in range(-1, 2):
                    if dx == 0 and (dy < 0 or (dy == 0 and dz < 0)):
                        continue
                    own = dx == 0 and dy == 0 and dz == 0
                    tx, ty, tz = cx + dx, cy + dy, cz + dz
                    h = ((tx * 73856093) ^ (ty * 19349663) ^ (tz * 83492791)) & mask
                    j = head[h]
                    while j >= 0:
                        if (cellc[j, 0] == tx and cellc[j, 1] == ty and cellc[j, 2] == tz and (j > i or not own)
                                and _separation(i, j, n, circular) > n_ex):
                            rx = c[j, 0] - c[i, 0]
                            ry = c[j, 1] - c[i, 1]
                            rz = c[j, 2] - c[i, 2]
                            if rx * rx + ry * ry + rz * rz < r2max:
                                if m < cap:
                                    pi[m] = i
                                    pj[m] = j
                                m += 1
                        j = nxt[j]
    return m


@numba.njit(cache=True)
def pair_kernel(c, pi, pj, m, eps, sigma, rc_wca, a_dh, kappa, rc_dh, F, spread=False):
    """WCA + shifted Debye-Hueckel over the first ``m`` listed pairs; adds forces to F.

    ``F`` is (n, 3) node forces, or with ``spread`` (3n, 3) particle forces (each node's force
    shared equally by its three particles). Pairs beyond the cutoffs (the skin of a Verlet
    list) contribute nothing. Returns ``(E_wca, E_dh)`` in kJ/mol.
    """
    rc = max(rc_wca, rc_dh)
    rc2 = rc * rc
    shift_dh = a_dh * math.exp(-kappa * rc_dh) / rc_dh if rc_dh > 0 else 0.0
    s2 = sigma * sigma
    ewca = 0.0
    edh = 0.0
    for t in range(m):
        i = pi[t]
        j = pj[t]
        rx, ry, rz, r2 = pair_vector(c, i, j)
        if r2 >= rc2:
            continue
        r = math.sqrt(r2)
        fr = 0.0  # -dE/dr
        if r < rc_wca:
            s6 = (s2 / r2) ** 3
            ewca += 4.0 * eps * (s6 * s6 - s6) + eps
            fr += 24.0 * eps * (2.0 * s6 * s6 - s6) / r
        if r < rc_dh:
            ex = a_dh * math.exp(-kappa * r) / r
            edh += ex - shift_dh
            fr += ex * (kappa + 1.0 / r)
        g = fr / r
        if spread:
            g3 = g / 3.0
            for q in range(3):
                F[3 * i + q, 0] -= g3 * rx
                F[3 * i + q, 1] -= g3 * ry
                F[3 * i + q, 2] -= g3 * rz
                F[3 * j + q, 0] += g3 * rx
                F[3 * j + q, 1] += g3 * ry
                F[3 * j + q, 2] += g3 * rz
        else:
            F[i, 0] -= g * rx
            F[i, 1] -= g * ry
            F[i, 2] -= g * rz
            F[j, 0] += g * rx
            F[j, 1] += g * ry
            F[j, 2] += g * rz
    return ewca, edh


@numba.njit(cache=True)
def max_displacement2(c, ref):
    """Largest squared displacement of a node between ``ref`` and ``c`` (both (n, 3))."""
    best = 0.0
    for i in range(c.shape[0]):
        dx = c[i, 0] - ref[i, 0]
        dy = c[i, 1] - ref[i, 1]
        dz = c[i, 2] - ref[i, 2]
        d2 = dx * dx + dy * dy + dz * dz
        if d2 > best:
            best = d2
    return best


class VerletList:
    """Verlet neighbour list with a skin over node centres.

    The list holds every non-excluded pair closer than ``cutoff + skin`` at the last build; it
    is rebuilt (cell list, O(n)) only when some node has moved more than ``skin / 2`` since
    then, so no pair that has come inside the cutoff is missing (two nodes approach by less
    than ``skin``). Between rebuilds a step costs one pass over the listed pairs and an O(n)
    displacement check. A displacement that is not finite forces a rebuild, which puts
    nothing in the list for that node (the engine's blow-up check then reports it).

    Parameters
    ----------
    n_nodes : int
    cutoff : float
        nm.
    skin : float
        nm (``0`` rebuilds at every evaluation).
    circular : bool
    n_exclude : int
        Chain-distance exclusion.
    """

    def __init__(self, n_nodes, cutoff, skin, circular, n_exclude):
        self.n = int(n_nodes)
        self.cutoff = float(cutoff)
        self.skin = float(skin)
        self.circular = bool(circular)
        self.n_exclude = int(n_exclude)
        self.ref = None
        self.pi = np.empty(16 * self.n + 1024, dtype=np.int64)
        self.pj = np.empty_like(self.pi)
        self.m = 0
        self.builds = 0
        self.evaluations = 0

    def update(self, c):
        """Rebuild the list if needed for centres ``c`` (n, 3) nm; returns ``(pi, pj, m)``."""
        self.evaluations += 1
        half = 0.5 * self.skin
        if self.ref is None or self.skin <= 0 or not max_displacement2(c, self.ref) <= half * half:
            rlist = self.cutoff + self.skin
            m = build_pairs(c, rlist, self.circular, self.n_exclude, self.pi, self.pj)
            if m > self.pi.shape[0]:
                self.pi = np.empty(m + m // 4 + 1024, dtype=np.int64)
                self.pj = np.empty_like(self.pi)
                m = build_pairs(c, rlist, self.circular, self.n_exclude, self.pi, self.pj)
            self.m = m
            self.ref = np.array(c, dtype=float, copy=True)
            self.builds += 1
        return self.pi, self.pj, self.m


def nonbonded_kernel(c, circular, n_ex, eps, sigma, rc_wca, a_dh, kappa, rc_dh, cutoff, F):
    """WCA + shifted Debye-Hueckel between node centres ``c`` (n,3), from a fresh cell list
    (no skin); adds forces to F (n,3) and returns ``(E_wca, E_dh)``."""
    vl = VerletList(c.shape[0], cutoff, 0.0, circular, n_ex)
    pi, pj, m = vl.update(np.ascontiguousarray(c, float))
    return pair_kernel(c, pi, pj, m, eps, sigma, rc_wca, a_dh, kappa, rc_dh, F)


@numba.njit(cache=True)
def _centres(p, out):
    n = out.shape[0]
    for k in range(n):
        for a in range(3):
            out[k, a] = (p[3 * k, a] + p[3 * k + 1, a] + p[3 * k + 2, a]) / 3.0


@numba.njit(cache=True)
def _spread(F, out):
    for k in range(F.shape[0]):
        for a in range(3):
            f = F[k, a] / 3.0
            out[3 * k, a] = f
            out[3 * k + 1, a] = f
            out[3 * k + 2, a] = f


class NonbondedCallback:
    """Picklable PythonForce computation of the non-local terms (forces on node centres,
    spread equally over the node's three particles: no torque), through a :class:`VerletList`.

    Parameters
    ----------
    n_nodes : int
    circular : bool
    numbers : dict
        From :meth:`~dnarod.physics.nonbonded.NonbondedSettings.resolve` (``skin`` in nm, default 1.0).
    """

    def __init__(self, n_nodes, circular, numbers):
        self.n = int(n_nodes)
        self.circular = bool(circular)
        self.numbers = dict(numbers)
        self.last = (0.0, 0.0)
        self._setup()

    def _setup(self):
        v = self.numbers
        self.verlet = VerletList(self.n, v["cutoff"], v.get("skin", DEFAULT_SKIN), self.circular, v["n_exclude"])
        self._c = np.empty((self.n, 3))
        self._F = np.zeros((self.n, 3))
        self._out = np.empty((3 * self.n, 3))

    def evaluate(self, centres):
        """``(E_wca, E_dh, F)`` for node centres (n, 3) nm; F kJ/mol/nm, shape (n, 3)."""
        v = self.numbers
        c = np.ascontiguousarray(centres, float)
        pi, pj, m = self.verlet.update(c)
        F = np.zeros((c.shape[0], 3))
        ew, ed = pair_kernel(c, pi, pj, m, v["eps"], v["sigma"], v["rc_wca"], v["a_dh"], v["kappa"], v["rc_dh"], F)
        return ew, ed, F

    def add_to_particles(self, centres, out):
        """Add the forces, spread over each node's three particles, to ``out`` (3n, 3) kJ/mol/nm
        for node centres (n, 3) nm; records and returns the energy (kJ/mol)."""
        v = self.numbers
        pi, pj, m = self.verlet.update(centres)
        ew, ed = pair_kernel(centres, pi, pj, m, v["eps"], v["sigma"], v["rc_wca"], v["a_dh"], v["kappa"], v["rc_dh"],
                             out, True)
        self.last = (ew, ed)
        return ew + ed

    def __call__(self, state):
        v = self.numbers
        p = state.getPositions(asNumpy=True)._value
        c = self._c
        _centres(p, c)
        pi, pj, m = self.verlet.update(c)
        F = self._F
        F[:] = 0.0
        ew, ed = pair_kernel(c, pi, pj, m, v["eps"], v["sigma"], v["rc_wca"], v["a_dh"], v["kappa"], v["rc_dh"], F)
        self.last = (ew, ed)
        out = self._out
        _spread(F, out)
        return ew + ed, out.copy()

    def __getstate__(self):
        return dict(n=self.n, circular=self.circular, numbers=self.numbers, last=self.last)

    def __setstate__(self, d):
        self.__dict__.update(d)
        self._setup()


def nonbonded_force(model, settings, temperature):
    """An ``openmm.PythonForce`` with the non-local terms, or ``None`` if both are off.

    Parameters
    ----------
    model : RodModel
    settings : NonbondedSettings
    temperature : float
        K (sets the WCA energy scale kT and the Bjerrum length).

    Returns
    -------
    (openmm.PythonForce or None, dict)
        The force (group ``GROUPS["nonbonded"]``) and the resolved numbers.
    """
    numbers = settings.resolve(model.ds, temperature)
    if not (settings.excluded_volume or settings.electrostatics):
        return None, numbers
    cb = NonbondedCallback(model.n_nodes, model.closure is not None, numbers)
    f = python_force(cb)
    f.dnarod_callback = cb  # the engine reads the per-term energies of the last evaluation
    f.setForceGroup(GROUPS["nonbonded"])
    f.setName("dnarod nonbonded (WCA + Debye-Hueckel)")
    return f, numbers
