"""Check ``thermal``: Langevin runs reproduce the exact equilibrium of the free open chain (docs/formulation.md §8).

A free open ``dna-default`` chain is run with Langevin dynamics in the Lax-form engine (BAOAB
splitting) and in the OpenMM engine (``LangevinMiddleIntegrator``, CPU platform, no non-bonded
terms). From the sampled frames the check measures, with block-jackknife standard errors
(consecutive time blocks), and compares with the exact answers:

* the reweighted covariance identity ``<dxi dxi^T W>/<W> = kT (ds K)^-1`` with
  ``W = (1 + ds^2 |Omega|^2 / 4)^2`` (all 21 independent entries; the plain covariance
  ``<dxi dxi^T>`` is reported too, it differs at O(kT));
* the tangent correlations ``<d3(k)·d3(k+n)> = (<R>^n)_33`` for n = 1..n_max
  (:func:`dnarod.physics.thermal.tangent_correlation`);
* the discrete persistence length ``-ds / ln <d3(k) . d3(k+1)>`` against
  :func:`dnarod.physics.thermal.persistence_length`;
* the kinetic temperature, 6 degrees of freedom per node.

A quantity passes if ``|measured - exact| <= Z_TOL`` standard errors (40 blocks). With Student-t
errors of 39 degrees of freedom, Z_TOL = 4.5 keeps the chance of a false failure among the ~33
comparisons of one engine near 0.2 %. The friction (0.2/ps) is low so that the long bending
modes of the free chain relax in ~10 ps, well inside one block.
"""
from __future__ import annotations

import time

import numpy as np

from dnarod.analysis.plots import new_figure, save_figure
from dnarod.analysis.statistics import jackknife, split_blocks

NAME = "thermal"
Z_TOL = 4.5
N_BLOCKS = 40


def default_model(n_nodes):
    from dnarod.core.forcefield import load_forcefield

    return load_forcefield("dna-default").model_from_sequence(n_nodes=n_nodes)


def frame_statistics(model, positions, frames, n_max):
    """Per-frame sums of the sampled quantities.

    Returns
    -------
    dict of ndarray
        ``XW`` (n_frames, 6, 6) sum over steps of ``W dxi dxi^T``; ``X`` the same without W;
        ``W`` (n_frames,) sum of W; ``corr`` (n_frames, n_max) mean over k of ``d3(k).d3(k+n)``.
    """
    from dnarod.analysis.polymer import tangent_correlation_frames
    from dnarod.analysis.stiffness import haar_weight
    from dnarod.core.strains import strains

    Om, Ga = strains(positions, frames, model.ds, model.closure)  # (n_frames, n_steps, 3)
    d = np.concatenate([Om, Ga], axis=-1) - model.params.intrinsic
    W = haar_weight(Om, model.ds)
    XW = np.einsum("fk,fki,fkj->fij", W, d, d)
    X = np.einsum("fki,fkj->fij", d, d)
    Wsum = W.sum(axis=1)
    corr = tangent_correlation_frames(np.asarray(frames)[..., 2], n_max)[:, 1:]
    return dict(XW=XW, X=X, W=Wsum, corr=corr)


def sample_lax(model, temperature, dt, friction, n_samples, stride, seed, n_equil):
    """Positions, frames (n_samples, n, ...) and kinetic temperatures (n_samples,) from the Lax-form BAOAB engine."""
    from dnarod.engines.lax import SplittingIntegrator
    from dnarod.engines.lax.engine import LaxEngine
    from dnarod.engines.lax.splitting import maxwell_state

    integ = SplittingIntegrator(model, dt, state=maxwell_state(model, temperature, seed=seed),
                                temperature=temperature, friction=friction, seed=seed + 1)
    return _sample(LaxEngine.wrap(integ, temperature, friction, seed), n_samples, stride, n_equil)


def sample_openmm(model, temperature, dt, friction, n_samples, stride, seed, n_equil):
    """The same from the OpenMM engine (LangevinMiddleIntegrator, CPU platform, elastic forces only)."""
    from dnarod.engines.openmm.simulation import RodSimulation

    sim = RodSimulation.create(model, integrator="langevin", temperature=temperature, dt=dt, friction=friction,
                               platform="CPU", nonbonded=False, seed=seed, threads=1)
    return _sample(sim, n_samples, stride, n_equil)


def _sample(engine, n_samples, stride, n_equil):
    """Equilibrate (``n_equil`` steps, rounded up to whole strides), then record (positions, frames, kinetic
    temperature) every ``stride`` steps, through the run layer (:func:`dnarod.run.sampling.run_sampling`)."""
    from dnarod.run.sampling import SampleReporter, run_sampling

    def observe(pos, frm, snapshot):
        return {"positions": pos, "frames": frm, "temperature": snapshot.energies["temperature"]}

    start = stride * -(-int(n_equil) // stride)
    sampler = SampleReporter(("positions", "frames", "temperature"), stride, observe, start=start,
                             n_samples=n_samples)
    s = run_sampling(engine, sampler)["samples"]
    return s["positions"], s["frames"], s["temperature"]


def analyse(model, positions, frames, tkin, temperature, n_max, stiffness_scale=1.0):
    """Compare samples with the exact equilibrium; returns the metrics dict.

    ``stiffness_scale`` multiplies the stiffness used for the *expected* values (1 = the model's own;
    any other value must fail -- used by the tests).
    """
    from dnarod.core.parameters import StepParameters
    from dnarod.physics.thermal import persistence_length, tangent_correlation
    from dnarod.core.units import kT

    kt = kT(temperature)
    ds = model.ds
    p = model.params
    ref_params = StepParameters(p.stiffness * stiffness_scale, p.intrinsic, p.names)
    K = ref_params.stiffness[0]
    if not np.allclose(ref_params.stiffness, K) or not np.allclose(p.intrinsic, p.intrinsic[0]):
        raise ValueError("the thermal check needs a uniform chain (one step type)")
    st = frame_statistics(model, positions, frames, n_max)
    blocks = split_blocks([st["XW"], st["X"], st["W"], st["corr"], tkin], N_BLOCKS)
    m = model.n_steps

    def cov_w(bl):
        return sum(b[0].sum(0) for b in bl) / sum(b[2].sum() for b in bl)

    def cov_plain(bl):
        return sum(b[1].sum(0) for b in bl) / (m * sum(len(b[1]) for b in bl))

    def corr(bl):
        return sum(b[3].sum(0) for b in bl) / sum(len(b[3]) for b in bl)

    def lp(bl):
        return -ds / np.log(corr(bl)[0])

    def temp(bl):
        return sum(b[4].sum() for b in bl) / sum(len(b[4]) for b in bl)

    expected_cov = kt * np.linalg.inv(ds * K)
    iu = np.triu_indices(6)
    out = {}
    for name, est in (("reweighted_covariance", cov_w), ("plain_covariance", cov_plain)):
        val, se = jackknife(est, blocks)
        z = (val - expected_cov)[iu] / np.where(se[iu] > 0, se[iu], np.inf)
        out[name] = dict(measured_diagonal=np.diag(val), expected_diagonal=np.diag(expected_cov),
                         standard_error_diagonal=np.diag(se),
                         relative_error_diagonal=np.diag(val) / np.diag(expected_cov) - 1,
                         max_abs_z_21_entries=float(np.abs(z).max()))
    c_val, c_se = jackknife(corr, blocks)
    c_exact = tangent_correlation(ref_params, ds, kt, n_max)[1:]
    zc = (c_val - c_exact) / c_se
    out["tangent_correlation"] = dict(n=np.arange(1, n_max + 1), measured=c_val, exact=c_exact,
                                      standard_error=c_se, max_abs_z=float(np.abs(zc).max()))
    l_val, l_se = jackknife(lp, blocks)
    l_exact = persistence_length(ref_params, ds, kt)
    out["persistence_length"] = dict(measured_nm=float(l_val), exact_nm=float(l_exact), standard_error_nm=float(l_se),
                                     z=float((l_val - l_exact) / l_se))
    t_val, t_se = jackknife(temp, blocks)
    out["kinetic_temperature"] = dict(measured_K=float(t_val), expected_K=float(temperature),
                                      standard_error_K=float(t_se), z=float((t_val - temperature) / t_se))
    zs = [out["reweighted_covariance"]["max_abs_z_21_entries"], out["tangent_correlation"]["max_abs_z"],
          abs(out["persistence_length"]["z"]), abs(out["kinetic_temperature"]["z"])]
    out["max_abs_z"] = float(max(zs))
    out["passed"] = bool(max(zs) <= Z_TOL)
    out["n_frames"] = int(len(positions))
    return out


def check_thermal(out_dir, quick=False, n_nodes=None, temperature=300.0, engines=None, stiffness_scale=1.0,
                  n_samples=None, seed=7, plots=True):
    """Run the check.

    Parameters
    ----------
    quick : bool
        Fewer samples (same statistics, larger error bars).
    engines : sequence of {"lax", "openmm"}, optional
        Default both.
    stiffness_scale : float
        Scale of the stiffness in the expected values (1 for the real check; the tests use another
        value to show the check fails).
    """
    t0 = time.perf_counter()
    n_nodes = n_nodes or (24 if quick else 40)
    model = default_model(n_nodes)
    engines = engines or ("lax", "openmm")
    dt, friction, stride, n_max = 0.02, 0.2, 25, 10
    if n_samples is None:
        n_samples = 4000 if quick else 16000
    res = dict(model=f"dna-default free open chain, {n_nodes} nodes", temperature_K=temperature, dt_ps=dt,
               friction_per_ps=friction, sample_stride_steps=stride, n_samples=n_samples, n_blocks=N_BLOCKS,
               z_tolerance=Z_TOL, stiffness_scale_of_expected_values=stiffness_scale)
    samplers = dict(lax=sample_lax, openmm=sample_openmm)
    ok = True
    for eng in engines:
        te = time.perf_counter()
        pos, frm, tk = samplers[eng](model, temperature, dt, friction, n_samples, stride, seed, n_equil=5000)
        r = analyse(model, pos, frm, tk, temperature, n_max, stiffness_scale)
        r["simulated_ps"] = n_samples * stride * dt
        r["runtime_s"] = time.perf_counter() - te
        res[eng] = r
        ok = ok and r["passed"]
    res["passed"] = bool(ok)
    if plots:
        res["plots"] = [_plot(out_dir, res, engines)]
    res["runtime_s"] = time.perf_counter() - t0
    return res


def _plot(out_dir, res, engines):
    fig, ax = new_figure(2, 1, width=5.0, height=3.8)
    a = ax[0, 0]
    for eng in engines:
        c = res[eng]["tangent_correlation"]
        a.errorbar(c["n"], c["measured"], yerr=c["standard_error"], fmt="o", ms=3, capsize=2, label=f"{eng} Langevin")
    a.plot(c["n"], c["exact"], "k-", lw=1, label="exact (<R>^n)_33")
    a.set_xlabel("n (steps)")
    a.set_ylabel("<d3(k) . d3(k+n)>")
    a.legend(fontsize=8)
    a = ax[0, 1]
    labels = ["W1", "W2", "W3", "G1", "G2", "G3"]
    x = np.arange(6)
    for j, eng in enumerate(engines):
        r = res[eng]["reweighted_covariance"]
        a.errorbar(x + 0.15 * j, r["relative_error_diagonal"],
                   yerr=r["standard_error_diagonal"] / r["expected_diagonal"], fmt="o", capsize=2,
                   label=f"{eng}: reweighted")
        q = res[eng]["plain_covariance"]
        a.plot(x + 0.15 * j + 0.05, q["relative_error_diagonal"], "x", label=f"{eng}: plain")
    a.axhline(0, color="k", lw=0.8)
    a.set_xticks(x, labels)
    a.set_ylabel("variance / (kT (ds K)^-1) - 1")
    a.legend(fontsize=7)
    return save_figure(fig, out_dir, "thermal.png")
