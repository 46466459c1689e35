"""Per-step-type strain statistics and stiffness estimates (all-atom MD in, rod parameters out).

The configuration measure of the rod is Haar on SE(3) per node, so in Cayley strains the
equilibrium density of a step is (docs/formulation.md §8)::

    p(xi) ~ exp(-ds H(xi) / kT) (1 + ds^2 |Omega|^2 / 4)^-2,     xi = (Omega, Gamma)

and reweighting each sample by ``W = (1 + ds^2 |Omega|^2 / 4)^2`` makes the Gaussian exact::

    <xi W>/<W> = xi0,     <(xi - xi0)(xi - xi0)^T W>/<W> = kT (ds K)^-1

so the estimate is ``K = kT (ds Cov_W)^-1`` with the reweighted mean as ``xi0``. The plain
(unweighted) moments are reported too; they are biased at O(kT).

The identity is exact for a free open chain (steps independent). Pooling several step types
("*") mixes their intrinsic shapes into the covariance; the per-type fits do not. Steps are
typed along strand I (``XY``); complementary steps (``XY`` and ``Y'X'``) are not merged. For a
ring the closure couples the steps and the estimate is approximate.

Error bars come from block averaging over frames: the estimates of ``n_blocks`` contiguous
blocks, standard error ``std / sqrt(n_blocks)``.

Units: Omega 1/nm, Gamma dimensionless, K in kJ/mol units per length (A kJ/mol nm, B kJ/mol,
C kJ/mol/nm), kT kJ/mol.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError, ParameterError
from dnarod.core.forcefield import write_forcefield
from dnarod.core.parameters import STRAIN_NAMES, StepParameters
from dnarod.core.units import kT as thermal_kT
from dnarod.analysis.base import AnalysisBase, closure_of
from dnarod.analysis.steps import frame_strains, step_names

MIN_SAMPLES = 30


def haar_weight(Omega, ds):
    """Reweighting factor ``W = (1 + ds^2 |Omega|^2 / 4)^2``; shape of ``Omega`` without its last axis."""
    w2 = ds * ds * np.einsum("...i,...i->...", Omega, Omega)
    return (1.0 + 0.25 * w2) ** 2


def weighted_moments(xi, weights=None):
    """Weighted mean (6,) and covariance (6, 6) of samples ``xi`` (n, 6) (unweighted if ``weights`` is None)."""
    xi = np.asarray(xi, float)
    W = np.ones(len(xi)) if weights is None else np.asarray(weights, float)
    mean = W @ xi / W.sum()
    d = xi - mean
    cov = np.einsum("n,ni,nj->ij", W, d, d) / W.sum()
    return mean, cov


def stiffness_from_samples(xi, ds, kt, reweight=True):
    """Intrinsic strains and stiffness from equilibrium samples of one step type.

    Parameters
    ----------
    xi : ndarray, shape (n, 6)
        Samples ``(Omega, Gamma)``.
    ds : float
        nm.
    kt : float
        kJ/mol.
    reweight : bool
        Apply the Haar reweighting (exact); ``False`` gives the naive Gaussian estimate.

    Returns
    -------
    mean : ndarray (6,)
    cov : ndarray (6, 6)
    K : ndarray (6, 6)
        ``kT (ds cov)^-1``.
    """
    xi = np.asarray(xi, float)
    if xi.ndim != 2 or xi.shape[1] != 6:
        raise DnarodError(f"strain samples must have shape (n, 6), got {xi.shape}")
    W = haar_weight(xi[:, :3], ds) if reweight else None
    mean, cov = weighted_moments(xi, W)
    ev = np.linalg.eigvalsh(cov)
    if ev[0] <= 1e-14 * max(ev[-1], 1e-300):
        raise DnarodError(f"strain covariance of {len(xi)} samples is singular (eigenvalues {ev[0]:.3g} .. "
                          f"{ev[-1]:.3g}): the trajectory does not sample all six strains (frozen "
                          f"degrees of freedom or too few frames)")
    K = kt * np.linalg.inv(ds * cov)
    return mean, cov, 0.5 * (K + K.T)


class StiffnessFit(AnalysisBase):
    """Per-step-type means, covariances and stiffness estimates from a trajectory.

    Parameters
    ----------
    trajectory : Trajectory
    ds : float
        Reference arc length per step (nm); the strains and the stiffness refer to it.
    temperature : float
        K.
    sequence : str, optional
        Strand I, 5'->3'; steps are grouped by dinucleotide. Without it all steps form one
        type ``"*"``.
    exclude_ends : int
        Leave out this many steps at each end of an open chain (frayed ends of MD duplexes).
    circular : bool
    closure : Closure, optional
    n_blocks : int
        Blocks (contiguous in time) for the error bars.
    check_spacing : bool

    Results
    -------
    types : dict
        Per step type (and ``"*"`` for all steps pooled): ``n_samples``, ``mean`` (6,),
        ``cov`` (6, 6), ``stiffness`` (6, 6) with the Haar reweighting; ``mean_naive``,
        ``cov_naive``, ``stiffness_naive`` without; ``*_err`` block standard errors.
    skipped_types : dict
        Step types with too few samples for a fit (name -> reason).
    kT : float
        kJ/mol.
    """

    def __init__(self, trajectory, ds, temperature=300.0, sequence=None, exclude_ends=0, circular=False,
                 closure=None, n_blocks=10, check_spacing=True):
        super().__init__(trajectory, check_spacing=check_spacing)
        if not (np.isfinite(ds) and ds > 0):
            raise DnarodError(f"ds must be a positive length (nm), got {ds}")
        if not (np.isfinite(temperature) and temperature > 0):
            raise DnarodError(f"temperature must be positive (K), got {temperature}")
        self.ds = float(ds)
        self.temperature = float(temperature)
        self.closure = closure_of(circular, closure)
        n_steps = trajectory.n_nodes if self.closure is not None else trajectory.n_nodes - 1
        self.names = step_names(n_steps, sequence, self.closure is not None)
        self.exclude_ends = int(exclude_ends)
        keep = np.arange(n_steps)
        if self.closure is None and self.exclude_ends:
            keep = keep[self.exclude_ends:n_steps - self.exclude_ends]
        if keep.size == 0:
            raise DnarodError(f"exclude_ends={exclude_ends} leaves no steps of {n_steps}")
        self.keep = keep
        self.n_blocks = int(n_blocks)

    def _compute(self, positions, frames, time):
        Om, Ga = frame_strains(positions, frames, self.ds, self.closure)
        self.results.xi = np.concatenate([Om, Ga], axis=-1)  # (n_frames, n_steps, 6)

    def _conclude(self):
        r = self.results
        kt = thermal_kT(self.temperature)
        r.kT = kt
        xi = r.xi
        nf = xi.shape[0]
        groups = {}
        for k in self.keep:
            groups.setdefault(self.names[k], []).append(k)
        if len(groups) > 1 or "*" not in groups:
            groups["*"] = list(self.keep)
        nb = min(self.n_blocks, nf)
        blocks = np.array_split(np.arange(nf), nb) if nb >= 2 else []
        r.types = {}
        r.skipped_types = {}
        for name, steps in sorted(groups.items(), key=lambda g: g[0] != "*"):
            samples = xi[:, steps].reshape(-1, 6)
            try:
                if len(samples) < MIN_SAMPLES:
                    label = "all step types pooled" if name == "*" else f"step type {name}"
                    raise DnarodError(f"{label}: only {len(samples)} samples ({nf} frames x {len(steps)} "
                                      f"steps); need at least {MIN_SAMPLES} for a 6x6 covariance: analyse more "
                                      f"frames (a single structure is one frame)")
                fits = {rw: stiffness_from_samples(samples, self.ds, kt, reweight=rw) for rw in (True, False)}
            except DnarodError as exc:
                if name == "*":  # the pooled fit is required; a single rare step type is only skipped
                    msg = str(exc)
                    raise DnarodError(msg if msg.startswith("all step types") else f"step type {name}: {msg}") \
                        from None
                r.skipped_types[name] = str(exc)
                continue
            out = {"n_samples": len(samples), "steps": [int(s) for s in steps]}
            for tag, rw in (("", True), ("_naive", False)):
                mean, cov, K = fits[rw]
                out.update({f"mean{tag}": mean, f"cov{tag}": cov, f"stiffness{tag}": K})
                est = []
                for b in blocks:
                    bs = xi[b][:, steps].reshape(-1, 6)
                    if len(bs) >= MIN_SAMPLES:
                        try:
                            est.append(stiffness_from_samples(bs, self.ds, kt, reweight=rw))
                        except DnarodError:
                            pass
                if len(est) >= 2:
                    n = len(est)
                    for j, key in enumerate(("mean", "cov", "stiffness")):
                        arr = np.array([e[j] for e in est])
                        out[f"{key}{tag}_err"] = arr.std(axis=0, ddof=1) / np.sqrt(n)
                else:
                    for key, shape in (("mean", (6,)), ("cov", (6, 6)), ("stiffness", (6, 6))):
                        out[f"{key}{tag}_err"] = np.full(shape, np.nan)
            r.types[name] = out

    # --- outputs ---------------------------------------------------------------------
    def step_parameters(self, name="*"):
        """The fit of one step type as :class:`~dnarod.core.parameters.StepParameters` (one step)."""
        t = self._type(name)
        return StepParameters(t["stiffness"], t["mean"], [name])

    def _type(self, name):
        if "types" not in self.results:
            raise DnarodError("run() the stiffness fit first")
        if name not in self.results.types:
            raise DnarodError(f"no step type {name!r}; fitted: {sorted(self.results.types)}")
        return self.results.types[name]

    def write_forcefield(self, path, name="*", ff_name="fitted", node_mass=650.0,
                         node_inertia=(117.0, 117.0, 234.0), description=None, sources=()):
        """Write one step type as a ``kind = "uniform"`` force field that
        :func:`dnarod.core.forcefield.load_forcefield` reads.

        Parameters
        ----------
        path : str or Path
        name : str
            Step type (``"*"``: all steps pooled).
        ff_name : str
        node_mass : float
            amu.
        node_inertia : (3,)
            amu nm^2.
        """
        t = self._type(name)
        desc = description or (f"Stiffness fitted by dnarod analyze from {t['n_samples']} samples of step type "
                               f"{name} (Haar-reweighted covariance, K = kT (ds Cov_W)^-1)")
        src = list(sources) + [f"kT = {self.results.kT:.6g} kJ/mol at {self.temperature:g} K; ds = {self.ds:g} nm"]
        write_forcefield(path, ff_name, {"*": (t["stiffness"], t["mean"])}, self.ds, node_mass, node_inertia,
                         self.temperature, desc, src,
                         header="dnarod force field written by dnarod.analysis.stiffness.StiffnessFit.write_forcefield")

    def write_sequence_forcefield(self, path, ff_name="fitted-sequence", node_mass=650.0,
                                  node_inertia=(117.0, 117.0, 234.0)):
        """Write every dinucleotide type's fit as a ``kind = "sequence-cayley"`` force field.

        Parameters
        ----------
        path : str or Path
            The ``.toml`` file to write.

        Returns
        -------
        Path of the TOML file.
        """
        self._type("*")
        types = {n: t for n, t in self.results.types.items() if n != "*"}
        if not types or any(len(n) != 2 or not set(n) <= set("ACGT") for n in types):
            raise ParameterError("a sequence force field needs dinucleotide step types; fit with a sequence")
        write_forcefield(path, ff_name, {n: (t["stiffness"], t["mean"]) for n, t in types.items()}, self.ds,
                         node_mass, node_inertia, self.temperature,
                         f"Sequence-dependent stiffness fitted by dnarod analyze ({len(types)} step types)",
                         [f"kT = {self.results.kT:.6g} kJ/mol at {self.temperature:g} K"],
                         header="Per-step-type Haar-reweighted stiffness fits (dnarod.analysis.stiffness)")
        return Path(path)

    def table_rows(self):
        """Long table of every type's mean and stiffness with errors: list of dicts (for CSV)."""
        rows = []
        for name, t in self.results.types.items():
            for i, a in enumerate(STRAIN_NAMES):
                rows.append({"step_type": name, "quantity": "mean", "row": a, "col": "",
                             "value": float(t["mean"][i]), "error": float(t["mean_err"][i]),
                             "naive": float(t["mean_naive"][i]), "n_samples": t["n_samples"]})
            for i, a in enumerate(STRAIN_NAMES):
                for j, b in enumerate(STRAIN_NAMES):
                    rows.append({"step_type": name, "quantity": "stiffness", "row": a, "col": b,
                                 "value": float(t["stiffness"][i, j]), "error": float(t["stiffness_err"][i, j]),
                                 "naive": float(t["stiffness_naive"][i, j]), "n_samples": t["n_samples"]})
        return rows
