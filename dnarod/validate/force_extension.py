"""Check ``force_extension`` (slow, not in ``--quick``): a 1 kbp chain against the extensible WLC.

A free open ``dna-default`` chain of ``n_bp`` base pairs, started straight at its intrinsic shape,
is pulled by opposite constant forces F on its two end nodes (along the initial axis), with
Langevin dynamics in the Lax-form engine (BAOAB splitting, numba kernel). The mean projected
end-to-end extension ``<(r_N-1 - r_0) . z> / L0`` (``L0 = (n_bp - 1) ds``) of the second part of
the run (the first part is discarded as equilibration) is compared with the extensible worm-like
chain (:func:`dnarod.physics.theory.wlc.extensible_wlc_extension`, Bouchiat et al. 1999 interpolation with
``l = x/L - F/S``) with the model's **own** parameters:

* persistence length: the exact discrete value :func:`dnarod.physics.thermal.persistence_length`;
* stretch modulus: ``S = 1 / (K^-1)_66`` (axial compliance with every other stress zero, i.e.
  twist, bend and shear free), converted to pN.

Tolerance: ``|x/L - x_WLC/L| <= Z_TOL * SE + ALLOWANCE`` at every force, with the block-jackknife
standard error SE and a fixed allowance for what separates this model from the reference (finite
length ``L0/lp ~ 7``, shear, discreteness).

Experiment: the same measured x/L are also compared with the relative extensions implied by the persistence
lengths measured in single-molecule force-extension experiments at ``experiment_salt_M`` (Wang et al. 1997;
Wenner et al. 2002; :func:`dnarod.physics.experiments.wlc_extension_band`, extensible WLC with the model's
stretch modulus): a force passes if x/L lies inside that interval widened by the same ``Z_TOL * SE +
ALLOWANCE``. The measured force-extension points themselves could not be read (``data/README.md``).

Convergence: the slow modes of a 340 nm chain at 0.1 pN have periods of tens of ns, longer than
affordable runs, so every force is run from **two starts** on opposite sides of the answer: the
straight intrinsic shape (too extended) and a coil drawn from the exact force-free equilibrium
(i.i.d. steps with the density of docs/formulation.md §8, rejection-sampled), rotated so that its
end-to-end vector lies along the force (too short at high forces). A force point passes only if
the two runs agree within ``Z_TOL`` combined standard errors (equilibrated) **and** their mean
agrees with the WLC.
"""
from __future__ import annotations

import time

import numpy as np

from dnarod.core.units import PN
from dnarod.analysis.plots import new_figure, save_figure
from dnarod.analysis.statistics import jackknife, split_blocks

NAME = "force_extension"
Z_TOL = 3.0
ALLOWANCE = 0.02
DEFAULT_FORCES_PN = (0.1, 0.3, 1.0, 3.0, 10.0)


def model_constants(model, temperature):
    """``(lp nm, S pN, kT pN nm, L0 nm)`` of a uniform model at ``temperature`` K."""
    from dnarod.physics.thermal import persistence_length
    from dnarod.core.units import kT

    kt = kT(temperature)
    lp = persistence_length(model.params, model.ds, kt)
    K = model.params.stiffness[0]
    S = 1.0 / np.linalg.inv(K)[5, 5] / PN
    L0 = model.ds * float(np.sum(model.params.Gamma0[:, 2]))
    return float(lp), float(S), kt / PN, L0


def equilibrium_coil(model, temperature, seed):
    """A pose drawn from the exact force-free equilibrium of an open chain, end-to-end vector along z.

    :func:`dnarod.physics.thermal.equilibrium_sample` (the one home of the sampler) with ``align = z``.
    """
    from dnarod.physics.thermal import equilibrium_sample

    return equilibrium_sample(model, temperature, seed, align=(0.0, 0.0, 1.0))


def pull(n_bp, force_pn, temperature, dt, friction, t_equil, t_prod, sample_every, seed, start="straight"):
    """One pulling run along z from ``start`` ("straight" or "coil"); returns the projected extension (nm) series."""
    from dnarod.core.forcefield import load_forcefield
    from dnarod.engines.lax import BoundaryConditions, SplittingIntegrator
    from dnarod.engines.lax.engine import LaxEngine
    from dnarod.engines.lax.splitting import maxwell_state
    from dnarod.run.sampling import SampleReporter, run_sampling

    model = load_forcefield("dna-default").model_from_sequence(n_nodes=n_bp)
    if start == "coil":
        model = equilibrium_coil(model, temperature, seed + 1000)
    axis = np.array([0.0, 0.0, 1.0])
    f = force_pn * PN * axis
    bc = BoundaryConditions(forces={0: -f, n_bp - 1: f})
    integ = SplittingIntegrator(model, dt, state=maxwell_state(model, temperature, seed=seed), boundary=bc,
                                temperature=temperature, friction=friction, seed=seed + 1, check_stability=False)
    stride = max(1, int(round(sample_every / dt)))
    n_samp = int(round(t_prod / (stride * dt)))
    sampler = SampleReporter(("extension_nm",), stride, lambda p, f, snap: {"extension_nm": (p[-1] - p[0]) @ axis},
                             start=stride * -(-int(round(t_equil / dt)) // stride), n_samples=n_samp)
    return run_sampling(LaxEngine.wrap(integ, temperature, friction, seed + 1), sampler)["samples"]["extension_nm"]


def _pull_star(args):
    return pull(*args)


def string_friction(force_pn, model):
    """Collision rate (1/ps) that critically damps the slowest transverse mode of the pulled chain.

    The chain under tension F is a string: its lowest mode has ``omega = (pi/L0) sqrt(F/rho)`` with
    ``rho = m/ds``. A friction ``gamma = 2 omega`` relaxes it in ~1/omega, the fastest possible;
    a larger friction overdamps it (time gamma/omega^2), a smaller one leaves it unthermostatted
    (time 2/gamma). Clipped to [1e-4, 2e-3] 1/ps.
    """
    L0 = model.ds * (model.n_nodes - 1)
    rho = model.mass[0] / model.ds
    return float(np.clip(2.0 * np.pi / L0 * np.sqrt(force_pn * PN / rho), 1e-4, 2e-3))


def check_force_extension(out_dir, quick=False, n_bp=1000, forces_pn=DEFAULT_FORCES_PN, temperature=300.0, dt=0.2,
                          friction=None, t_equil=20000.0, t_prod=60000.0, sample_every=20.0, seed=11,
                          lp_override=None, workers=2, plots=True, experiment_salt_M=0.15):
    """Run the check (times in ps).

    ``friction`` (1/ps): ``None`` for :func:`string_friction` per force. ``dt = 0.2 ps`` is
    ``omega_max dt = 0.91`` (stable below 2); BAOAB samples harmonic configurations exactly at any
    stable step, and the extension is set by the soft bending modes (``omega dt << 1``).
    ``lp_override`` replaces the model's persistence length in the reference curve (the tests use a
    wrong value to show the check fails); ``workers`` processes run the runs in parallel.
    """
    from concurrent.futures import ProcessPoolExecutor

    from dnarod.core.forcefield import load_forcefield
    from dnarod.physics.theory.wlc import extensible_wlc_extension

    t0 = time.perf_counter()
    model = load_forcefield("dna-default").model_from_sequence(n_nodes=n_bp)
    lp, S, kt_pn, L0 = model_constants(model, temperature)
    lp_ref = lp if lp_override is None else float(lp_override)
    starts = ("straight", "coil")
    gammas = [string_friction(F, model) if friction is None else float(friction) for F in forces_pn]
    jobs = [(n_bp, F, temperature, dt, g, t_equil, t_prod, sample_every, seed + 7 * i, st)
            for i, (F, g) in enumerate(zip(forces_pn, gammas)) for st in starts]
    if workers and workers > 1 and len(jobs) > 1:
        import multiprocessing as mp

        with ProcessPoolExecutor(max_workers=workers, mp_context=mp.get_context("fork")) as ex:
            series = list(ex.map(_pull_star, jobs))
    else:
        series = [pull(*j) for j in jobs]
    from dnarod.physics.experiments import wlc_extension_band

    x_lo, x_hi = wlc_extension_band(forces_pn, experiment_salt_M, S, temperature)
    rows = []
    ok = True
    def mean_se(x):
        v, e = jackknife(lambda bl: np.mean(np.concatenate([b[0] for b in bl])), split_blocks([x], 20))
        return float(v), float(e)

    for i, F in enumerate(forces_pn):
        xs = [series[len(starts) * i + j] / L0 for j in range(len(starts))]
        (v1, e1), (v2, e2) = mean_se(xs[0]), mean_se(xs[1])
        val, se = 0.5 * (v1 + v2), 0.5 * np.hypot(e1, e2)
        ref = float(extensible_wlc_extension(F, lp_ref, S, kt_pn))
        tol = Z_TOL * se + ALLOWANCE
        converged = bool(abs(v1 - v2) <= Z_TOL * np.hypot(e1, e2))
        in_band = bool(x_lo[i] - tol <= val <= x_hi[i] + tol)
        passed = bool(converged and abs(val - ref) <= tol and in_band)
        ok = ok and passed
        rows.append(dict(force_pN=F, friction_per_ps=gammas[i], relative_extension=val, standard_error=se, wlc=ref,
                         difference=val - ref,
                         tolerance=tol, from_straight=v1, from_straight_se=e1, from_coil=v2, from_coil_se=e2,
                         starts_agree=converged, experiment_low=float(x_lo[i]), experiment_high=float(x_hi[i]),
                         within_experiment=in_band, passed=passed))
    res = dict(model=f"dna-default open chain, {n_bp} bp, two starts per force (straight; equilibrium coil)",
               temperature_K=temperature,
               engine="Lax-form BAOAB splitting (numba)", dt_ps=dt,
               friction="per force, critical damping of the slowest string mode" if friction is None else friction,
               equilibration_ps_per_force=t_equil, production_ps_per_force=t_prod, contour_length_nm=L0,
               persistence_length_nm=lp, persistence_length_used_nm=lp_ref, stretch_modulus_pN=S, kT_pN_nm=kt_pn,
               z_tolerance=Z_TOL, absolute_allowance=ALLOWANCE, forces=rows, experiment_salt_M=experiment_salt_M,
               passed=bool(ok))
    if plots:
        res["plots"] = [_plot(out_dir, rows, lp_ref, S, kt_pn, experiment_salt_M, temperature)]
    res["runtime_s"] = time.perf_counter() - t0
    return res


def _plot(out_dir, rows, lp, S, kt, salt_M=0.15, temperature=300.0):
    from dnarod.physics.experiments import persistence_length_band, wlc_extension_band
    from dnarod.physics.theory.wlc import extensible_wlc_extension

    fig, ax = new_figure(1, 1, width=6.0, height=4.2)
    a = ax[0, 0]
    F = np.logspace(np.log10(min(r["force_pN"] for r in rows)) - 0.2, np.log10(max(r["force_pN"] for r in rows)) + 0.1, 80)
    lo, hi = wlc_extension_band(F, salt_M, S, temperature)
    lp_lo, lp_hi, _ = persistence_length_band(salt_M)
    a.fill_between(F, lo, hi, color="0.85", zorder=0,
                   label=f"WLC with measured lp {lp_lo:g}-{lp_hi:g} nm ({1000 * salt_M:g} mM Na+; data/experimental)")
    a.semilogx(F, extensible_wlc_extension(F, lp, S, kt), "k-", label=f"extensible WLC (lp {lp:.1f} nm, S {S:.0f} pN)")
    f = np.array([r["force_pN"] for r in rows])
    a.errorbar(f * 0.97, [r["from_straight"] for r in rows], yerr=[r["from_straight_se"] for r in rows], fmt="v",
               capsize=3, label="Langevin, straight start")
    a.errorbar(f * 1.03, [r["from_coil"] for r in rows], yerr=[r["from_coil_se"] for r in rows], fmt="^",
               capsize=3, label="Langevin, equilibrium-coil start")
    a.set_xlabel("force (pN)")
    a.set_ylabel("extension / contour length")
    a.legend(fontsize=8)
    return save_figure(fig, out_dir, "force_extension.png")
