"""Polymer observables: tangent correlations and persistence length, end-to-end distance,
and for closed (circular) chains the linking number, twist and writhe.

Tangent correlation ``C(n) = <d3(k)·d3(k+n)>`` is averaged over frames and positions k;
for an open chain in equilibrium it is exactly ``(<R>^n)_33`` (docs/formulation.md §8) and for an
axisymmetric step ``c^n``, so the discrete persistence length is ``l_p = -ds / ln c``; it is
fitted as ``ln C(n) = -n ds / l_p`` by least squares through the origin. Error bars of the means over frames come
from their autocorrelation, the start's transient dropped (:func:`dnarod.analysis.statistics.estimate`); those of
the long-lag fit from ``n_blocks`` contiguous blocks. Modes slower than a run do not show in any error bar computed
from it: :func:`lag1_slow_modes` adds their share to the lag-1 value's error from the chain's normal modes.

Units: nm, dimensionless correlations; Lk, Tw, Wr in turns.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import DnarodError, GeometryError
from dnarod.analysis.base import AnalysisBase, block_estimates, check_closed, closure_of, standard_error
from dnarod.physics.writhe import linking_number, twist, writhe


def tangent_correlation_frames(d3, n_max, circular=False):
    """Per-frame tangent correlation ``C_f(n) = mean_k d3(k)·d3(k+n)``.

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
    """Tangent correlation ``<d3(k)·d3(k+n)>`` and the persistence length.

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
    persistence_length_one_step, persistence_length_one_step_err : float
        ``-ds / ln C(1)``, nm, and its standard error from the autocorrelation of the per-frame ``C(1)``
        (:func:`dnarod.analysis.statistics.estimate`). This lag-1 estimate is exact for a uniform chain
        (docs/formulation.md §8), but a run's value still carries the modes slower than the run: their share of
        the error and the bias of a start that was not an equilibrium sample are :func:`lag1_slow_modes`'s.
    persistence_length_one_step_estimate, lag1_estimate : Estimate
        The full estimates (transient dropped, n_eff, tau, flag) of lp and of ``C(1)``.
    dropped_frames : int
        Frames dropped at the start as transient (all lags).
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
        from dnarod.analysis.statistics import estimate, function_estimate

        r = self.results
        C = r.per_frame
        r.lags = np.arange(self.n_max + 1)
        # the headline, lag 1: the mean of the per-frame values with an autocorrelation error, the start's
        # transient dropped (dnarod.analysis.statistics.estimate); the same frames for every lag
        c1 = estimate(C[:, 1], what="lag-1 tangent correlation")
        t0 = c1.n_dropped
        r.lag1_estimate = c1
        r.dropped_frames = t0
        Ck = C[t0:]
        r.correlation = Ck.mean(axis=0)
        r.correlation_err = np.array([estimate(Ck[:, j], transient=False).error for j in range(Ck.shape[1])])
        r.correlation_err[1] = c1.error
        lp1 = function_estimate(c1, lambda c: -self.ds / np.log(c) if 0 < c < 1 else np.nan)
        r.persistence_length_one_step_estimate = lp1
        r.persistence_length_one_step = lp1.mean
        r.persistence_length_one_step_err = lp1.error
        blocks = block_estimates(Ck, self.n_blocks)
        r.correlation_blocks = blocks
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
        from dnarod.analysis.statistics import estimate

        r = self.results
        d = r.distance
        e = estimate(d, what="end-to-end distance")
        r.mean_estimate = e
        r.mean, r.mean_err = e.mean, e.error
        e2 = estimate(d * d, what="squared end-to-end distance")
        r.mean_square, r.mean_square_err = e2.mean, e2.error


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


#: ``beta_1 L`` of the slowest bending mode of a free-free beam (first root of ``cos x cosh x = 1``).
FREE_FREE_BETA1_L = 4.730040744862704
#: Runs shorter than this many slowest bending relaxation times get a warning from ``analyze``.
RELAXATION_TIMES_REQUIRED = 5.0


def bending_relaxation_time(contour_length, persistence_length, temperature, mass_per_length, friction,
                            tension=0.0, ends="free"):
    """Relaxation time (ps) of the slowest bending mode of a chain under Langevin dynamics.

    The long-wavelength bending of the rod is an Euler-Bernoulli beam, ``rho y_tt + gamma y_t
    = -A y_ssss + F y_ss + noise``, with bending stiffness ``A = kT l_p`` (kJ/mol nm), linear mass
    density ``rho = m/ds`` (amu/nm) and tension F. dnarod's Langevin thermostat (OpenMM's
    ``LangevinMiddleIntegrator`` and the Lax-form BAOAB) applies one collision rate ``zeta``
    (``friction``, 1/ps) to every particle, so the drag per unit length is ``gamma = zeta rho``:
    each mode q is a damped oscillator ``x'' + zeta x' + omega_q^2 x = noise`` with
    ``omega_q^2 = (A q^4 + F q^2)/rho``. Its slowest decay rate is
    ``lambda = zeta/2 - sqrt(zeta^2/4 - omega^2)`` (overdamped, ``zeta > 2 omega``) or ``zeta/2``
    (underdamped); the time returned is ``1/lambda``. Overdamped and without tension this is

        ``tau_1 = zeta rho L^4 / (A (beta_1 L)^4)``,

    with ``beta_1 L = pi`` for hinged ends (the form ``gamma rho L^4/(A pi^4)``, gamma the collision
    rate) and ``beta_1 L = 4.730`` for free ends (an open chain; 5.14 times shorter).

    Parameters
    ----------
    contour_length : float
        L, nm.
    persistence_length : float
        Bending persistence length, nm.
    temperature : float
        K.
    mass_per_length : float
        rho, amu/nm.
    friction : float
        Collision rate zeta, 1/ps.
    tension : float
        F, kJ/mol/nm.
    ends : {"free", "hinged"}

    Returns
    -------
    float
        ps (``inf`` without friction: nothing relaxes the mode but the dynamics itself).
    """
    from dnarod.core.units import kT

    if ends not in ("free", "hinged"):
        raise DnarodError(f"ends must be 'free' or 'hinged', got {ends!r}")
    q = (FREE_FREE_BETA1_L if ends == "free" else np.pi) / float(contour_length)
    A = kT(temperature) * float(persistence_length)
    w2 = (A * q ** 4 + float(tension) * q * q) / float(mass_per_length)
    z = float(friction)
    if z <= 0:
        return float("inf")
    disc = 0.25 * z * z - w2
    # ``z/2 - sqrt(z^2/4 - w^2)`` loses digits when strongly overdamped: use ``w^2 / (z/2 + sqrt(.))``.
    lam = w2 / (0.5 * z + np.sqrt(disc)) if disc > 0 else 0.5 * z
    return float(1.0 / lam)


def relaxation_warning(run_time, tau, n_required=RELAXATION_TIMES_REQUIRED, slow_error_nm=None):
    """One-line warning if ``run_time`` (ps) is shorter than ``n_required`` relaxation times ``tau`` (ps); else None.
    ``slow_error_nm``: the share of the modes slower than the run in the lag-1 persistence length's error."""
    if not np.isfinite(tau) or run_time >= n_required * tau:
        return None
    share = (f"; the lag-1 persistence length's error includes their share, +-{slow_error_nm:.2f} nm, from the "
             f"normal modes" if slow_error_nm is not None else "")
    return (f"the run ({run_time:.4g} ps) is {run_time / tau:.3g} of the slowest bending relaxation time "
            f"tau_1 = {tau:.4g} ps (fewer than {n_required:g}): modes slower than the run hardly move in it, so no "
            f"error bar computed from its frames sees them{share}; long-lag tangent correlations and the long-lag "
            f"persistence-length fit are not converged")


def integrated_autocorrelation_time(x, c=5.0):
    """Integrated autocorrelation time of a series, in samples, with Sokal's automatic window.

    ``tau_int = 1/2 + sum_{t=1}^{W} rho(t)`` with the smallest window ``W >= c tau_int(W)``
    (A. Sokal, *Monte Carlo methods in statistical mechanics*, 1996, sec. 3); the
    autocorrelation ``rho`` is computed by FFT. The effective number of independent samples is
    ``n / (2 tau_int)``.

    Parameters
    ----------
    x : array_like, shape (n,)
    c : float
        Window factor.

    Returns
    -------
    float
        Samples (>= 0.5); NaN for fewer than 4 samples or a constant series.
    """
    x = np.asarray(x, float)
    n = len(x)
    if n < 4:
        return float("nan")
    y = x - x.mean()
    v = float(y @ y) / n
    if v <= 0:
        return float("nan")
    f = np.fft.rfft(y, 2 * n)
    acf = np.fft.irfft(f * np.conj(f))[:n] / (n * v)
    taus = 2.0 * np.cumsum(acf) - 1.0  # 1 + 2 sum_{t>=1} rho(t), i.e. 2 tau_int at window t
    for W in range(1, n):
        if W >= c * 0.5 * taus[W]:
            return float(max(0.5 * taus[W], 0.5))
    return float(max(0.5 * taus[-1], 0.5))


#: Modes whose squared amplitude decorrelates more slowly than this fraction of the run are counted by
#: :func:`lag1_slow_modes` (faster ones show in the run's own autocorrelation error).
SLOW_MODE_FRACTION = 0.05


def _mean_variance_factor(tau, T):
    """Variance of the time average over ``T`` of a stationary process with autocorrelation ``exp(-t/tau)``, in units
    of its variance: ``2 r - 2 r^2 (1 - exp(-1/r))``, ``r = tau/T`` (1 for a frozen process, ``2 tau/T`` for a fast
    one)."""
    r = np.asarray(tau, float) / float(T)
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        out = 2.0 * r - 2.0 * r * r * (-np.expm1(-1.0 / r))
    return np.where(np.isfinite(r), np.clip(out, 0.0, 1.0), 1.0)


def lag1_slow_modes(model, temperature, friction, t_start_ps, t_end_ps, equilibrium_start, exclude_ends=0,
                    max_modes=512):
    """What the modes slower than a run do to its lag-1 tangent correlation: their share of the error of the run's
    mean and, for a start that was not an equilibrium sample, their bias.

    The free chain's bending modes (normal modes of its intrinsic pose, :mod:`dnarod.physics.relaxation`) each hold
    the same share of the bending: a mode of angular frequency omega and amplitude a has bending energy
    ``omega^2 a^2/2`` with mean kT/2, so the sum of squared bend angles it contributes is ``(ds/lp) omega^2 a^2/kT``
    whatever the mode. The per-frame lag-1 correlation ``C(1) = 1 - sum_k theta_k^2/(2M)`` therefore takes from each
    of the ``2 M`` bending modes of M steps the same share of its exact mean deficit ``1 - <C(1)>`` and of its exact
    frame-to-frame variance (:func:`dnarod.physics.thermal.lag1_moments`; the steps are independent). The squared
    amplitude of a mode relaxing at rate lambda decorrelates in ``1/(2 lambda)``, so over a run of duration T its
    share of the variance of the run's mean is ``var_share h(1/(2 lambda), T)`` (:func:`_mean_variance_factor`):
    the whole share for a mode frozen over the run, a fraction ``1/(lambda T)`` for a fast one. The modes slower
    than :data:`SLOW_MODE_FRACTION` of the run are summed here (faster ones show in the run's own autocorrelation
    error); a straight start has their amplitudes at 0, so their deficit ``mu_share exp(-2 lambda t)`` is missing
    from ``1 - C(1)`` at time t: the bias of the run's mean, averaged over the frames kept.

    Parameters
    ----------
    model : RodModel
        The chain (an open chain; its intrinsic pose is used).
    temperature : float
        K.
    friction : float
        Langevin collision rate of the run, 1/ps.
    t_start_ps, t_end_ps : float
        Time of the first and last frame averaged, counted from the run's start (ps).
    equilibrium_start : bool
        The run began from an exact equilibrium sample (``start="equilibrium"``): no bias.
    exclude_ends : int
        Steps left out at each end by the analysis.
    max_modes : int
        Most modes computed.

    Returns
    -------
    dict
        ``variance_c1`` (added variance of the mean C(1)), ``bias_c1`` (expected C(1) excess of the run's mean),
        ``n_slow_modes``, ``tau_slowest_ps`` (the slowest mode's amplitude relaxation time), ``run_over_tau``,
        ``friction_per_ps``.
    """
    from dnarod.core.strains import chain_from_strains
    from dnarod.core.units import kT
    from dnarod.physics.relaxation import relaxation_times
    from dnarod.physics.thermal import lag1_moments

    if model.closure is not None:
        raise DnarodError("lag1_slow_modes is for open chains")
    p = model.params
    xi0 = p.intrinsic
    pos, frm = chain_from_strains(xi0[:, :3], xi0[:, 3:], model.ds)
    straight = model.with_pose(pos, frm)
    mu, var = lag1_moments(p, model.ds, kT(temperature))
    e = int(exclude_ends)
    sel = slice(e, p.n_steps - e) if e else slice(None)
    M = len(mu[sel])
    n_modes = 2 * M
    var_share = float(var[sel].sum()) / M ** 2 / n_modes
    mu_share = float(1.0 - mu[sel].mean()) / n_modes
    T = max(float(t_end_ps) - float(t_start_ps), 1e-12)
    k = 16
    while True:
        r = relaxation_times(straight, (), friction, k=min(k, 6 * model.n_nodes - 7), temperature=temperature)
        tau2 = 0.5 * r["tau_ps"]  # squared amplitudes decorrelate twice as fast
        if tau2[-1] < SLOW_MODE_FRACTION * T or k >= max_modes or len(tau2) < k:
            break
        k *= 2
    slow = tau2 >= SLOW_MODE_FRACTION * T
    variance = var_share * float(_mean_variance_factor(tau2[slow], T).sum())
    bias = 0.0
    if not equilibrium_start:
        lam2 = 1.0 / np.where(np.isfinite(tau2), tau2, np.inf)  # 2 lambda
        with np.errstate(divide="ignore", invalid="ignore"):
            avg = np.where(lam2 > 0, (np.exp(-lam2 * t_start_ps) - np.exp(-lam2 * t_end_ps)) / (lam2 * T), 1.0)
        bias = mu_share * float(avg.sum())
    return dict(variance_c1=variance, bias_c1=bias, n_slow_modes=int(slow.sum()), tau_slowest_ps=r["tau_slowest_ps"],
                run_over_tau=T / r["tau_slowest_ps"], friction_per_ps=float(friction), modes_computed=len(tau2))
