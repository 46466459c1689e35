"""Check ``nicked_ring``: the supercoiling free energy of nicked rings, ``ΔG = (K RT / N) ΔLk²``, from ``<ΔLk²>``.

A nicked ring's linking number is free and its twist and axis shape are independent, so ``<ΔLk²> = <ΔTw²> +
<ΔWr*²>`` and ``K = N / (2 <ΔLk²>)``, with the split ``Lk = Tw + Wr*`` made exactly: ``Tw`` the sum of the
steps' Cayley twist angles and ``Wr* = Lk - Tw`` (:func:`dnarod.workflows.protocols.nicked.step_twist_sum`).

* Twist part: exact from the model's step distribution (
  :func:`~dnarod.physics.theory.supercoil.twist_variance_exact`), beside the continuum ``L / (4 pi² C)``.
* ``Wr*`` part, **model**: the variance of ``Wr*`` of the model's ring free to writhe, sampled with OpenMM
  (excluded volume and Debye-Hueckel at the chosen salt) by :func:`dnarod.workflows.protocols.nicked.run_nicked_member`
  (soft twist, exactly reweighted), with a block-jackknife error. ``Wr*`` needs no smoothing and carries no
  shear wiggles; it is close to the writhe of the curve the frames' tangents d3 trace.
* Reference: the Vologodskii-type Monte Carlo of a worm-like ring (:mod:`dnarod.validate.wlc_ring_mc`) with the
  model's persistence length A and its effective diameter at this salt
  (:func:`~dnarod.physics.theory.supercoil.effective_diameter`), same length, segments of ``segment_nm``
  (1.7 nm up to 300 bp, else 3.4 nm). Optionally (``harmonic_samples``) the harmonic ensemble of the model's
  own relaxed ring (:mod:`dnarod.validate.ring_harmonic`), reported, not gating (it is the small-ring limit and
  leaves out the anharmonic part).

Pass: model and reference agree within ``Z_TOL`` combined standard errors plus ``DISCRETE_ALLOWANCE`` (relative):
the reference's own dependence on its segment length, measured at 68 nm (200 bp, 8000-16000 samples):
0.00161 ± 0.00006, 0.00175 ± 0.00007, 0.00202 ± 0.00010 at 3.4, 1.7, 0.85 nm (research/supercoiling_checks/notes.md,
"The MC's discretisation").

Why ``Wr*`` and not the writhe of the axis smoothed over 10-bp blocks (
:func:`dnarod.workflows.protocols.nicked.smoothed_axis`, still reported as ``model_wr2_axis``): that polygon, 20
vertices at 200 bp, misses about half of
the ring's writhe.

The free energy coefficient K is reported at the sampled size (model) and, from the exact twist part and the
reference writhe, at ``full_n_bp`` (default 3000 bp), beside the measured Depew-Wang / Horowitz-Wang K when one
is tabulated (:func:`dnarod.physics.experiments.supercoiling_free_energy_reference`: Horowitz & Wang's (1984)
N K "nearly a constant", about 1150 RT x bp, for rings longer than 2000 bp; ``measured_K`` is None when none is).
``a_override`` gives the reference a wrong persistence length (the tests show the check failing).
"""
from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from dnarod.validate._common import ring_writhe_plot, save_ring_writhe_plot
from dnarod.workflows.protocols.nicked import run_nicked_member
from dnarod.physics.theory.supercoil import depew_wang_K, ring_constants, twist_variance_exact, twist_variance_linear
from dnarod.validate.wlc_ring_mc import sample_ring_writhe
from dnarod.analysis.polymer import integrated_autocorrelation_time
from dnarod.physics import experiments as ex
from dnarod.validate.ring_harmonic import gaussian_writhe_samples

NAME = "nicked_ring"
Z_TOL = 3.0
DISCRETE_ALLOWANCE = 0.15


def check_nicked_ring(out_dir, quick=False, n_bp=None, time_ns=None, full_n_bp=3000, temperature=300.0,
                      salt_M=0.15, seed=41, a_override=None, mc_samples=None, full_mc_samples=None, plots=True,
                      member_root=None, segment_nm=None, harmonic_samples=None, softening=None, sample_ps=None,
                      nonbonded=None, platform=None, threads=None):
    """Run the check (see the module docstring). ``nonbonded`` (dict with ``charge`` and/or ``cutoff_debye``) runs
    the ring with other non-bonded terms than the defaults (the recorded test member was run with Manning's charge
    and 5 Debye lengths); ``platform`` and ``threads`` choose the member's OpenMM platform (default: the members'
    automatic choice); a member folder run with the same settings is reused."""
    t0 = time.perf_counter()
    n_bp = n_bp or (200 if quick else 600)
    time_ns = time_ns or (30.0 if quick else 400.0)
    mc_samples = mc_samples or 4000
    segment_nm = segment_nm or (1.7 if n_bp <= 300 else 3.4)
    harmonic_samples = (1000 if n_bp <= 300 else 0) if harmonic_samples is None else int(harmonic_samples)
    full_mc_samples = full_mc_samples or (1000 if quick else 5000)
    root = Path(member_root) if member_root else Path(tempfile.mkdtemp(prefix="nicked_", dir=out_dir))
    rc = ring_constants(n_bp, temperature, salt_M, nonbonded=nonbonded)
    ff, ring, L, A, C, d_eff = rc["ff"], rc["ring"], rc["L"], rc["A"], rc["C"], rc["d_eff"]
    A_ref = A if a_override is None else float(a_override)
    md = run_nicked_member(dict(n_bp=n_bp, time_ns=time_ns, seed=seed, temperature_K=temperature, salt_M=salt_M,
                                softening=softening, sample_ps=sample_ps, platform=platform, threads=threads,
                                **dict(nonbonded or {})),
                           root / f"ring{n_bp}")
    mc = sample_ring_writhe(L, A_ref, d_eff, b_nm=segment_nm, n_samples=mc_samples, seed=seed)

    w2 = mc["wr"] ** 2
    tau_mc = max(float(integrated_autocorrelation_time(w2)), 0.5)
    mc_w2, mc_se = float(w2.mean()), float(w2.std(ddof=1) * np.sqrt(2 * tau_mc / len(w2)))
    model_w2, model_err = md["wr_star_var"], md["wr_star_var_err"]
    diff = model_w2 - mc_w2
    se = float(np.hypot(model_err, mc_se))
    tol = Z_TOL * se + DISCRETE_ALLOWANCE * mc_w2
    passed = bool(abs(diff) <= tol)
    tw_exact = twist_variance_exact(ring, temperature)
    tw_lin = twist_variance_linear(L, C)
    lk2_model = tw_exact + model_w2
    lk2_model_err = model_err
    harm = None
    if harmonic_samples:
        hw = gaussian_writhe_samples(ring, harmonic_samples, temperature, seed=seed)["tangent"]
        harm = dict(wr2=float(np.mean(hw ** 2)), wr2_err=float(np.std(hw ** 2, ddof=1) / np.sqrt(len(hw))),
                    samples=int(harmonic_samples))
    K_model = depew_wang_K(n_bp, lk2_model)
    # full size: exact twist + reference writhe (the model's own MD at this size is estimated in cost below)
    full = None
    if full_n_bp:  # full size: exact twist + reference writhe (the model's own MD is out of reach at that size)
        Lf = ring.ds * full_n_bp
        full_ring = ff.ring(n_nodes=full_n_bp, delta_linking_number=0)
        tw_full = twist_variance_exact(full_ring, temperature)
        mcf = sample_ring_writhe(Lf, A_ref, d_eff, b_nm=5.1, n_samples=full_mc_samples, seed=seed + 1)
        wf = mcf["wr"] ** 2
        tau_f = max(float(integrated_autocorrelation_time(wf)), 0.5)
        wr2_full, wr2_full_se = float(wf.mean()), float(wf.std(ddof=1) * np.sqrt(2 * tau_f / len(wf)))
        K_full = depew_wang_K(full_n_bp, tw_full + wr2_full)
        full = dict(n_bp=full_n_bp, twist_variance_turns2=tw_full, reference_wr2=wr2_full,
                    reference_wr2_err=wr2_full_se, K=K_full, K_err=K_full * wr2_full_se / (tw_full + wr2_full),
                    writhe_share=wr2_full / (tw_full + wr2_full), segments=mcf["segments"],
                    segment_nm=mcf["segment_nm"])

    measured = ex.supercoiling_free_energy_reference()  # Horowitz & Wang 1984: N K ~ 1150 RT bp above 2000 bp
    measured_K = measured[0].value if measured else None
    measured_K_source = (ex.cite_short(measured[0].source) if measured
                         else "none read: " + ex.MISSING["supercoiling_free_energy"])
    res = dict(model=f"dna-default ring, {n_bp} bp (L = {L:.1f} nm), {salt_M} M, {temperature} K",
               persistence_length_nm=A, reference_persistence_length_nm=A_ref, twist_persistence_nm=C,
               effective_diameter_nm=d_eff,
               twist_variance_exact_turns2=tw_exact, twist_variance_continuum_turns2=tw_lin,
               model_wr_star_var=model_w2, model_wr_star_var_err=model_err, model_wr_star_mean=md["wr_star_mean"],
               model_wr_star_mean_err=md["wr_star_mean_err"],
               model_wr2_axis=md["wr2_free"], model_wr2_axis_err=md["wr2_free_err"],
               model_wr2_tau_ps=md["wr2_tau_ps"], model_wr_tau_ps=md["wr_tau_ps"], model_n_effective=md["n_effective"],
               model_production_ns=md["production_ps"] / 1000.0, model_wall_s=md["wall_s"], model_cpu_s=md["cpu_s"],
               model_ns_per_day=md["ns_per_day"], model_softening=md["softening"],
               reference_wr2=mc_w2, reference_wr2_err=mc_se, reference_segments=mc["segments"],
               reference_segment_nm=mc["segment_nm"], harmonic=harm,
               difference=diff, standard_error=se, tolerance=tol, z_tolerance=Z_TOL,
               discrete_allowance_relative=DISCRETE_ALLOWANCE,
               K_sampled_size=K_model, K_sampled_size_err=K_model * lk2_model_err / lk2_model,
               writhe_share_sampled_size=model_w2 / lk2_model,
               full=full,
               measured_K=measured_K, measured_K_source=measured_K_source, passed=passed)
    if plots:
        fig, a, d = ring_writhe_plot(mc["wr"], f"WLC ring MC (A {A_ref:.0f}, d {d_eff:.2f} nm)",
                                     root / f"ring{n_bp}" / "samples.csv")
        a.hist(d["Wr_star"] - md["wr_star_mean"], bins=40, density=True, histtype="step",
               label="model Wr* = Lk - step twist (soft twist, unweighted)")
        res["plots"] = save_ring_writhe_plot(fig, a, n_bp, out_dir, "nicked_ring.png")
    res["runtime_s"] = time.perf_counter() - t0
    return res
