"""Writhe, twist and linking number of closed polygonal curves and ribbons.

Written here because no maintained Python package computes the writhe of a polygon and the
twist of a discrete ribbon for arbitrary frames (the field's tools, e.g. WrLINE, are
stand-alone scripts).

* Gauss double integral over two straight segments: exactly the signed solid angle of the
  parallelogram ``{b(t) - a(s)}`` seen from the origin (Klenin & Langowski 2000,
  Biopolymers 54:307, for polygons). It is evaluated as two triangles with the
  Van Oosterom & Strackee (1983) formula ``tan(Omega/2) = a.(b x c) / (|a||b||c| + ...)``,
  which uses ``atan2`` and stays accurate for nearly flat or nearly degenerate quadrilaterals
  where Klenin-Langowski's sum of four ``arcsin`` loses half the digits.
* Writhe of a closed polygon: ``Wr = (1/4 pi) sum_{i != j} Omega_ij`` over non-adjacent
  edge pairs (adjacent and identical edges contribute zero).
* Linking number of two closed polygons: ``Lk = (1/4 pi) sum_{i, j} Omega_ij``; an integer.
* Twist of a polygonal ribbon (vertices ``r_k``, ribbon vectors ``u_k``, linear in between):
  the rotation of the ribbon vector about the edge along each edge plus its rotation about
  the new edge, relative to parallel transport, at each vertex; then ``Lk(C, C + eps u) =
  Tw + Wr`` exactly (Calugareanu-White) for small ``eps``.

Shapes: points ``(n, 3)``; all functions are vectorised over edge pairs (memory O(chunk x n)).
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import GeometryError

_CHUNK = 256


def _numba_pair_sum():
    """The compiled pair sum (numba, cached on first use); same formula as the numpy path."""
    global _NUMBA_PAIR_SUM
    if _NUMBA_PAIR_SUM is None:
        from numba import njit

        @njit(cache=True, fastmath=False)
        def tri(ax, ay, az, bx, by, bz, cx, cy, cz, na, nb, nc):
            num = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx)
            den = (na * nb * nc + (ax * bx + ay * by + az * bz) * nc + (ax * cx + ay * cy + az * cz) * nb
                   + (bx * cx + by * cy + bz * cz) * na)
            return 2.0 * np.arctan2(num, den)

        @njit(cache=True, fastmath=False)
        def pair_sum(A, A2, B, B2, mode):
            # mode 0: all pairs (linking number); mode 1: i < j non-adjacent pairs of one closed polygon
            n, m = A.shape[0], B.shape[0]
            total = 0.0
            for i in range(n):
                j0 = i + 2 if mode == 1 else 0
                for j in range(j0, m):
                    if mode == 1 and i == 0 and j == m - 1:
                        continue
                    ax, ay, az = B[j, 0] - A[i, 0], B[j, 1] - A[i, 1], B[j, 2] - A[i, 2]
                    bx, by, bz = B2[j, 0] - A[i, 0], B2[j, 1] - A[i, 1], B2[j, 2] - A[i, 2]
                    cx, cy, cz = B2[j, 0] - A2[i, 0], B2[j, 1] - A2[i, 1], B2[j, 2] - A2[i, 2]
                    dx, dy, dz = B[j, 0] - A2[i, 0], B[j, 1] - A2[i, 1], B[j, 2] - A2[i, 2]
                    na = np.sqrt(ax * ax + ay * ay + az * az)
                    nb = np.sqrt(bx * bx + by * by + bz * bz)
                    nc = np.sqrt(cx * cx + cy * cy + cz * cz)
                    nd = np.sqrt(dx * dx + dy * dy + dz * dz)
                    total -= (tri(ax, ay, az, bx, by, bz, cx, cy, cz, na, nb, nc)
                              + tri(ax, ay, az, cx, cy, cz, dx, dy, dz, na, nc, nd))
            return total

        _NUMBA_PAIR_SUM = pair_sum
    return _NUMBA_PAIR_SUM


_NUMBA_PAIR_SUM = None


def _dot(a, b):
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def _triple(a, b, c):
    """a . (b x c) with explicit components (faster than np.cross on large broadcast arrays)."""
    return (a[..., 0] * (b[..., 1] * c[..., 2] - b[..., 2] * c[..., 1])
            + a[..., 1] * (b[..., 2] * c[..., 0] - b[..., 0] * c[..., 2])
            + a[..., 2] * (b[..., 0] * c[..., 1] - b[..., 1] * c[..., 0]))


def _triangle_solid_angle(a, b, c, na=None, nb=None, nc=None):
    """Signed solid angle of the triangle with vertices a, b, c (vectors from the observer), (...,)."""
    na = np.sqrt(_dot(a, a)) if na is None else na
    nb = np.sqrt(_dot(b, b)) if nb is None else nb
    nc = np.sqrt(_dot(c, c)) if nc is None else nc
    num = _triple(a, b, c)
    den = na * nb * nc + _dot(a, b) * nc + _dot(a, c) * nb + _dot(b, c) * na
    return 2.0 * np.arctan2(num, den)


def segment_solid_angle(p1, p2, p3, p4):
    """Gauss integral of segments ``p1->p2`` and ``p3->p4`` times 4 pi (signed solid angle).

    ``(1/4pi) int int (r1 - r2).(dr1 x dr2)/|r1 - r2|^3`` with r1 on the first segment and r2
    on the second equals this value over 4 pi. Arrays broadcast; shape (..., 3) each.
    """
    a = p3 - p1
    b = p4 - p1
    c = p4 - p2
    d = p3 - p2
    na, nb, nc, nd = (np.sqrt(_dot(v, v)) for v in (a, b, c, d))
    # The parallelogram a, b, c, d is traversed against the Gauss integrand's orientation: minus sign.
    return -(_triangle_solid_angle(a, b, c, na, nb, nc) + _triangle_solid_angle(a, c, d, na, nc, nd))


def _check_closed_polygon(points, what):
    P = np.asarray(points, float)
    if P.ndim != 2 or P.shape[1] != 3 or P.shape[0] < 3:
        raise GeometryError(f"{what}: a closed polygon needs shape (n >= 3, 3), got {P.shape}")
    if not np.isfinite(P).all():
        raise GeometryError(f"{what}: non-finite coordinates")
    return P


def _pair_sum(A, A2, B, B2, mask_fn=None):
    """Sum of segment solid angles over all pairs (rows of A, rows of B), chunked over A.

    ``mask_fn(i, j)`` (index arrays, broadcast) selects the pairs to include.
    """
    total = 0.0
    jj = np.arange(len(B))
    for i0 in range(0, len(A), _CHUNK):
        i = np.arange(i0, min(i0 + _CHUNK, len(A)))
        om = segment_solid_angle(A[i, None], A2[i, None], B[None], B2[None])
        if mask_fn is not None:
            om = np.where(mask_fn(i[:, None], jj[None, :]), om, 0.0)
        total += om.sum()
    return total


def writhe(points, fast=True):
    """Writhe of the closed polygon through ``points`` (n, 3) (edge n-1 joins the last point to the first).

    ``fast`` uses the numba kernel; ``False`` the vectorised numpy reference (same formula).
    """
    P = _check_closed_polygon(points, "writhe")
    n = len(P)
    Q = np.roll(P, -1, axis=0)
    if fast:
        return 2.0 * _numba_pair_sum()(P, Q, P, Q, 1) / (4.0 * np.pi)
    # Pairs i < j that are not adjacent (j != i+1, and not (i=0, j=n-1)); the sum is symmetric.
    def mask(i, j):
        return (j > i + 1) & ~((i == 0) & (j == n - 1))
    with np.errstate(invalid="ignore", divide="ignore"):
        total = _pair_sum(P, Q, P, Q, mask)
    return 2.0 * total / (4.0 * np.pi)


def linking_number(points1, points2, fast=True):
    """Gauss linking number of two closed polygons (float; an integer for disjoint curves).

    ``fast`` uses the numba kernel; ``False`` the vectorised numpy reference (same formula).
    """
    A = _check_closed_polygon(points1, "linking number, curve 1")
    B = _check_closed_polygon(points2, "linking number, curve 2")
    if fast:
        return _numba_pair_sum()(A, np.roll(A, -1, axis=0), B, np.roll(B, -1, axis=0), 0) / (4.0 * np.pi)
    return _pair_sum(A, np.roll(A, -1, axis=0), B, np.roll(B, -1, axis=0)) / (4.0 * np.pi)


def _signed_angle(u, v, axis):
    """Angle from u to v about the unit ``axis`` (u, v perpendicular to it), (...,)."""
    return np.arctan2(np.einsum("...i,...i->...", np.cross(u, v), axis), np.einsum("...i,...i->...", u, v))


def _perp(u, t):
    p = u - np.einsum("...i,...i->...", u, t)[..., None] * t
    return p


def _transport(v, t0, t1):
    """Parallel transport of v (perpendicular to t0) to perpendicular to t1: the minimal rotation t0 -> t1."""
    c = np.einsum("...i,...i->...", t0, t1)
    ax = np.cross(t0, t1)
    # Rodrigues with the unnormalised axis: R v = v c + (ax x v) + ax (ax.v) / (1 + c)
    return (v * c[..., None] + np.cross(ax, v)
            + ax * (np.einsum("...i,...i->...", ax, v) / (1.0 + c))[..., None])


def twist(points, ribbon):
    """Total twist (in turns) of the closed polygonal ribbon ``(points, ribbon)``.

    Parameters
    ----------
    points : ndarray, shape (n, 3)
        Vertices of the closed centreline, nm.
    ribbon : ndarray, shape (n, 3)
        Ribbon vector at each vertex (need not be unit nor perpendicular to the edges, but
        not parallel to an adjacent edge); it varies linearly along each edge.

    Returns
    -------
    float
        ``Tw`` such that ``Lk = Tw + Wr``.
    """
    P = _check_closed_polygon(points, "twist")
    U = np.asarray(ribbon, float)
    if U.shape != P.shape:
        raise GeometryError(f"twist: ribbon must have the shape of the points {P.shape}, got {U.shape}")
    e = np.roll(P, -1, axis=0) - P
    le = np.linalg.norm(e, axis=1)
    if (le == 0).any():
        k = int(np.argmin(le))
        raise GeometryError(f"twist: edge {k} has zero length (vertices {k} and {(k + 1) % len(P)} coincide)")
    t = e / le[:, None]
    U_next = np.roll(U, -1, axis=0)
    a0 = _perp(U, t)         # ribbon at the start of edge k, perpendicular to t_k
    a1 = _perp(U_next, t)    # ... at its end
    bad = np.minimum(np.linalg.norm(a0, axis=1), np.linalg.norm(a1, axis=1)) < 1e-9 * np.linalg.norm(U, axis=1).max()
    if bad.any():
        k = int(np.argmax(bad))
        raise GeometryError(f"twist: the ribbon vector is parallel to edge {k}; the twist is undefined there")
    along = _signed_angle(a0, a1, t)
    # At vertex k+1 the edge turns from t_k to t_{k+1}: transport a1_k and compare with a0_{k+1}.
    t_next = np.roll(t, -1, axis=0)
    moved = _transport(a1, t, t_next)
    corner = _signed_angle(moved, np.roll(a0, -1, axis=0), t_next)
    return float((along.sum() + corner.sum()) / (2.0 * np.pi))
