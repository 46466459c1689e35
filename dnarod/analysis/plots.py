"""Plots of the analyses (matplotlib, Agg backend; PNG files written atomically).

* :func:`plot_strain_distributions`: histograms of the six strains of one step type, with
  the Gaussian of the fitted (Haar-reweighted) mean and covariance.
* :func:`plot_tangent_correlation`: ``C(n)`` with block error bars on a log scale, the fitted
  exponential and, if given, the exact prediction.
"""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from dnarod.core.io import atomic_path  # noqa: E402

LABELS = (r"$\Omega_1$ (1/nm)", r"$\Omega_2$ (1/nm)", r"$\Omega_3$ (1/nm)", r"$\Gamma_1$", r"$\Gamma_2$",
          r"$\Gamma_3$")


def _save(fig, path):
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)
    plt.close(fig)


def plot_strain_distributions(xi, path, mean=None, cov=None, title="strain distributions"):
    """Histograms of strain samples.

    Parameters
    ----------
    xi : ndarray, shape (n, 6)
        Samples (Omega 1/nm, Gamma).
    path : str or Path
        PNG file.
    mean, cov : ndarray (6,), (6, 6), optional
        A Gaussian to overlay (its marginals).
    """
    xi = np.asarray(xi, float)
    fig, axes = plt.subplots(2, 3, figsize=(11, 6))
    for i, ax in enumerate(axes.flat):
        ax.hist(xi[:, i], bins=min(60, max(10, len(xi) // 20)), density=True, color="#7aa6c2", alpha=0.8,
                label="samples")
        if mean is not None and cov is not None:
            s = np.sqrt(cov[i, i])
            x = np.linspace(mean[i] - 4 * s, mean[i] + 4 * s, 200)
            ax.plot(x, np.exp(-0.5 * ((x - mean[i]) / s) ** 2) / (s * np.sqrt(2 * np.pi)), "k-", lw=1.2,
                    label="reweighted Gaussian fit")
        ax.set_xlabel(LABELS[i])
    axes.flat[0].legend(fontsize=8)
    fig.suptitle(title)
    fig.tight_layout()
    _save(fig, path)


def plot_tangent_correlation(lags, correlation, error, ds, path, persistence_length=None, exact=None,
                             title="tangent correlation"):
    """``<d3(k)·d3(k+n)>`` against contour distance ``n ds`` (log scale).

    Parameters
    ----------
    lags : ndarray (m,)
    correlation, error : ndarray (m,)
    ds : float
        nm.
    path : str or Path
    persistence_length : float, optional
        Fitted, nm: draws ``exp(-s / l_p)``.
    exact : ndarray (m,), optional
        Exact prediction (e.g. :func:`dnarod.physics.thermal.tangent_correlation`).
    """
    s = np.asarray(lags) * ds
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    C = np.asarray(correlation, float)
    pos = C > 0
    ax.errorbar(s[pos], C[pos], yerr=None if error is None else np.asarray(error)[pos], fmt="o", ms=3,
                capsize=2, label="trajectory")
    if persistence_length is not None and np.isfinite(persistence_length):
        ax.plot(s, np.exp(-s / persistence_length), "k-", lw=1, label=f"fit: $l_p$ = {persistence_length:.1f} nm")
    if exact is not None:
        ax.plot(s, exact, "r--", lw=1, label="exact (force field)")
    ax.set_yscale("log")
    ax.set_xlabel("contour distance n ds (nm)")
    ax.set_ylabel(r"$\langle d_3(k)\cdot d_3(k+n)\rangle$")
    ax.set_title(title)
    ax.legend(fontsize=8)
    fig.tight_layout()
    _save(fig, path)


def plot_step_parameters(mean, std, names, path, title="step parameters"):
    """Mean step parameters (Angstrom, degrees) along the chain with their standard deviation."""
    labels = ("shift (A)", "slide (A)", "rise (A)", "tilt (deg)", "roll (deg)", "twist (deg)")
    k = np.arange(len(names))
    fig, axes = plt.subplots(2, 3, figsize=(11, 6), sharex=True)
    for i, ax in enumerate(axes.flat):
        ax.errorbar(k, mean[:, i], yerr=std[:, i], fmt="o-", ms=3, capsize=2)
        ax.set_ylabel(labels[i])
    for ax in axes[1]:
        ax.set_xlabel("step")
        if len(names) <= 30 and names[0] != "*":
            ax.set_xticks(k)
            ax.set_xticklabels(names, rotation=90, fontsize=7)
    fig.suptitle(title)
    fig.tight_layout()
    _save(fig, path)


def new_figure(ncols=1, nrows=1, width=6.0, height=4.0):
    """A matplotlib figure and its (nrows, ncols) axes array (Agg backend, no display)."""
    fig, axes = plt.subplots(nrows, ncols, figsize=(width * ncols, height * nrows), squeeze=False)
    return fig, axes


def save_figure(fig, out_dir, name):
    """Write ``fig`` to ``out_dir/name`` (PNG, 110 dpi) atomically and close it; returns ``name``."""
    fig.tight_layout()
    _save(fig, f"{out_dir}/{name}")
    return name
