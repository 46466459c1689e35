"""Polymer observables: tangent correlations and persistence length, end-to-end distance,
and for closed (circular) chains the linking number, twist and writhe.

Tangent correlation ``C(n) = <d3(k) . d3(k+n)>`` is averaged over frames and positions k;
for an open chain in equilibrium it is exactly ``(<R>^n)_33`` (design A5 iii) and for an
axisymmetric step ``c^n``, so the discrete persistence length is ``l_p = -ds / ln c``; it is
fitted as ``ln C(n) = -n ds / l_p`` by least squares through the origin. Error bars are
block averages over frames (``n_blocks`` contiguous blocks).

Units: nm, dimensionless correlations; Lk, Tw, Wr in turns.
"""
from __future__ import annotations

import numpy as np

from ..errors import DnarodError, GeometryError
from .base import AnalysisBase, block_estimates, check_closed, closure_of, standard_error
from .writhe import linking_number, twist, writhe


def tangent_correlation_frames(d3, n_max, circular=False):
    """Per-frame tangent correlation ``C_f(n) = mean_k d3(k) . d3(k+n)``.

    Parameters
    ----------
    d3 : ndarray, shape (n_frames, n_nodes, 3)
        Unit tangents (third directors).
    n_max : int
        Largest lag (< n_nodes for an open chain).
    circular : bool
        Use all n_nodes pairs at every lag (indices mod n_nodes).

    Returns
    -------
    ndarray, shape (n_frames, n_max + 1)
    """
    nf, n, _ = d3.shape
    out = np.empty((nf, n_max + 1))
    for lag in range(n_max + 1):
        other = np.roll(d3, -lag, axis=1) if circular else d3[:, lag:]
        first = d3 if circular else d3[:, :n - lag]
        out[:, lag] = np.einsum("fki,fki->fk", first, other).mean(axis=1)
    return out


def fit_persistence_length(correlation, ds, min_correlation=0.1):
    """Least-squares ``ln C(n) = -n ds / l_p`` through the origin over lags 1.. with C > ``min_correlation``.

    Returns
    -------
    lp : float
        nm (``inf`` for a rigid chain, NaN if no lag is usable).
    n_fit : int
        Number of lags used.
    """
    C = np.asarray(correlation, float)
    lags = np.arange(len(C))
    use = (lags >= 1) & (C > min_correlation)
    # Only the leading run of usable lags: past the first drop below the threshold the data are noise.
    if use[1:].size and not use[1:].all():
        first_bad = int(np.argmin(use[1:])) + 1
        use[first_bad:] = False
    if not use.any():
        return np.nan, 0
    n = lags[use]
    slope = np.sum(n * np.log(C[use])) / np.sum(n * n)
    lp = np.inf if slope >= 0 else -ds / slope
    return float(lp), int(use.sum())


class TangentCorrelation(AnalysisBase):
    """Tangent correlation ``<d3(k) . d3(k+n)>`` and the persistence length.

    Parameters
    ----------
    trajectory : Trajectory
    ds : float
        Contour length per step, nm (the model's reference arc length).
    n_max : int, optional
        Largest lag (default: n_nodes - 1 - 2 exclude_ends, at most 200).
    exclude_ends : int
        Nodes left out at each end.
    n_blocks : int
    circular : bool
        Lags wrap around a closed chain (no persistence-length fit).
    min_correlation : float
        Lags with C(n) below this are not fitted.

    Results
    -------
    lags : ndarray (n_max + 1,)
    correlation, correlation_err : ndarray (n_max + 1,)
    persistence_length, persistence_length_err : float
        nm (fit), block standard error.
    persistence_length_one_step : float
        ``-ds / ln C(1)``, nm.
    n_fit : int
    """

    def __init__(self, trajectory, ds, n_max=None, exclude_ends=0, n_blocks=10, circular=False,
                 min_correlation=0.1, check_spacing=True):
        super().__init__(trajectory, check_spacing=check_spacing)
        if not (np.isfinite(ds) and ds > 0):
            raise DnarodError(f"ds must be a positive length (nm), got {ds}")
        self.ds = float(ds)
        self.exclude_ends = int(exclude_ends)
        n_used = trajectory.n_nodes - 2 * self.exclude_ends
        if n_used < 2:
            raise DnarodError(f"exclude_ends={exclude_ends} leaves {n_used} of {trajectory.n_nodes} nodes")
        limit = n_used - 1 if not circular else n_used // 2
        self.n_max = min(limit, 200) if n_max is None else int(n_max)
        if not 1 <= self.n_max <= limit:
            raise DnarodError(f"n_max must be between 1 and {limit} for {n_used} nodes, got {n_max}")
        self.circular = bool(circular)
        self.n_blocks = int(n_blocks)
        self.min_correlation = float(min_correlation)

    def _compute(self, positions, frames, time):
        e = self.exclude_ends
        d3 = frames[:, e:frames.shape[1] - e, :, 2]
        self.results.per_frame = tangent_correlation_frames(d3, self.n_max, self.circular)

    def _conclude(self):
        r = self.results
        C = r.per_frame
        r.lags = np.arange(self.n_max + 1)
        r.correlation = C.mean(axis=0)
        blocks = block_estimates(C, self.n_blocks)
        r.correlation_blocks = blocks
        r.correlation_err = standard_error(blocks)
        c1 = r.correlation[1]
        r.persistence_length_one_step = float(-self.ds / np.log(c1)) if 0 < c1 < 1 else np.nan
        if self.circular:
            r.persistence_length, r.n_fit, r.persistence_length_err = np.nan, 0, np.nan
            return
        r.persistence_length, r.n_fit = fit_persistence_length(r.correlation, self.ds, self.min_correlation)
        lp_blocks = np.array([fit_persistence_length(b, self.ds, self.min_correlation)[0] for b in blocks])
        r.persistence_length_blocks = lp_blocks
        r.persistence_length_err = float(standard_error(lp_blocks[:, None])[0]) if np.isfinite(lp_blocks).all() \
            else np.nan


class EndToEnd(AnalysisBase):
    """End-to-end distance ``|r_last - r_first|`` of an open chain.

    Results
    -------
    distance : ndarray (n_frames,)
        nm.
    mean, mean_err : float
        nm.
    mean_square, mean_square_err : float
        nm^2.
    """

    def __init__(self, trajectory, n_blocks=10, check_spacing=True):
        super().__init__(trajectory, check_spacing=check_spacing)
        self.n_blocks = int(n_blocks)

    def _compute(self, positions, frames, time):
        self.results.distance = np.linalg.norm(positions[:, -1] - positions[:, 0], axis=-1)

    def _conclude(self):
        r = self.results
        d = r.distance
        r.mean = float(d.mean())
        r.mean_err = float(standard_error(block_estimates(d, self.n_blocks)))
        r.mean_square = float((d * d).mean())
        r.mean_square_err = float(standard_error(block_estimates(d * d, self.n_blocks)))


class LinkingNumber(AnalysisBase):
    """Linking number, twist and writhe of a closed chain, per frame, with ``Lk = Tw + Wr`` checked.

    The centreline is the closed polygon of the node positions; the ribbon vector is each
    node's d1. ``Wr`` is the polygon's exact writhe, ``Tw`` the discrete ribbon twist and
    ``Lk`` the Gauss linking number of the centreline with the ribbon edge (offset ``eps d1``),
    computed independently; it is an integer for a closed ribbon.

    Parameters
    ----------
    trajectory : Trajectory
        A ring: node N-1 joins node 0.
    closure : Closure, optional
        Must be the identity (a ring in space); a screw closure is a periodic chain whose
        linking number is not defined.
    offset : float, optional
        Ribbon offset ``eps`` (nm); default a tenth of the shortest step.
    tolerance : float
        Allowed ``|Lk - (Tw + Wr)|`` and distance of Lk from an integer.

    Results
    -------
    twist, writhe, linking : ndarray (n_frames,)
    linking_integer : ndarray of int (n_frames,)
    max_identity_error : float
        ``max |Lk - Tw - Wr|``.
    max_integer_error : float
    passed : bool
    """

    def __init__(self, trajectory, closure=None, offset=None, tolerance=1e-6, check_spacing=True):
        super().__init__(trajectory, check_spacing=check_spacing)
        if trajectory.n_nodes < 3:
            raise DnarodError(f"a ring needs at least 3 nodes, got {trajectory.n_nodes}")
        self.closure = closure_of(True, closure)
        if not (np.allclose(self.closure.Q, np.eye(3), atol=1e-12) and np.allclose(self.closure.t, 0, atol=1e-12)):
            raise GeometryError("linking number needs a ring closed in space (identity closure); this chain has a "
                                "screw closure (a periodic chain), whose linking number is not defined")
        self.offset = offset
        self.tolerance = float(tolerance)

    def _compute(self, positions, frames, time):
        check_closed(positions, self.closure)
        nf = positions.shape[0]
        tw, wr, lk = np.empty(nf), np.empty(nf), np.empty(nf)
        for f in range(nf):
            P = positions[f]
            U = frames[f, :, :, 0]
            edges = np.linalg.norm(np.roll(P, -1, axis=0) - P, axis=1)
            eps = 0.1 * edges.min() if self.offset is None else float(self.offset)
            try:
                tw[f] = twist(P, U)
            except GeometryError as exc:
                raise GeometryError(f"trajectory frame {f}: {exc}") from None
            wr[f] = writhe(P)
            lk[f] = linking_number(P, P + eps * U)
        r = self.results
        r.twist, r.writhe, r.linking = tw, wr, lk

    def _conclude(self):
        r = self.results
        r.linking_integer = np.rint(r.linking).astype(int)
        r.max_identity_error = float(np.abs(r.linking - r.twist - r.writhe).max())
        r.max_integer_error = float(np.abs(r.linking - r.linking_integer).max())
        r.passed = bool(r.max_identity_error < self.tolerance and r.max_integer_error < self.tolerance)
        r.mean_twist, r.mean_writhe = float(r.twist.mean()), float(r.writhe.mean())
