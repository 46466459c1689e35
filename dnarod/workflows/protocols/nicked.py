"""Nicked-ring members: the writhe distribution of a ring whose linking number is free, sampled with the model.

A nick (one step without twist stiffness) cannot change the linking number in this model: a step's rotation
cannot pass 180 degrees (the Cayley strains diverge there), so a ring with one twist-free step still has a
fixed Lk, and its axis writhe stays tied to the twist of the intact steps. What a real nick does is make
``Lk`` free, and then the twist of the intact steps and the shape of the axis are independent (the model's
bending is isotropic and twist couples only to stretch), so ``<ΔLk²> = <ΔTw²> + Var(Wr*)`` with ``Tw`` the sum of
the steps' Cayley twist angles, known exactly (:func:`dnarod.physics.theory.supercoil.twist_variance_exact`),
and ``Wr* = Lk - Tw`` (:func:`step_twist_sum`; column ``Wr_star``) of a ring free to writhe.

That writhe variance is sampled here with the model (OpenMM engine, its excluded volume and electrostatics) in
a ring whose twist is made soft at every step: the stiffness of each step is replaced by the Schur complement
on the five non-twist strains (so the joint distribution of bending, shear and stretch, hence of the axis, is
exactly the model's) plus a decoupled twist stiffness ``K_33 / softening``. The soft twist still ties
``Wr*`` to the fixed Lk, through a factor ``p_Tw(Lk - Wr*)`` on its density (``p_Tw`` the density of the
soft chain's total twist: Gaussian, variance and mean from the exact step distribution); the samples are
reweighted by ``1 / p_Tw(Lk - Wr*)``, which removes it exactly. With the default softening (16: twist s.d.
~0.26 rad per step) the reweighting changes the variance by 1 % at 200 bp and 8-20 % at 600 bp (reported);
softening 4 and 16 agree at 200 bp.

Units: nm, turns, ps.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.physics.nonbonded import DEFAULT_CHARGE, DEFAULT_CUTOFF_DEBYE
from dnarod.core.parameters import StepParameters
from dnarod.core.units import kT
from dnarod.core.strains import strains
from dnarod.analysis.polymer import integrated_autocorrelation_time
from dnarod.physics.writhe import twist, writhe
from dnarod.core.forcefield import load_forcefield
from dnarod.core.io import jsonable
from dnarod.physics.thermal import persistence_length, sample_step_strains
from dnarod.analysis.statistics import jackknife, split_blocks

COLUMNS = ("time_ps", "Wr_star", "Wr_axis", "Wr", "Tw", "Lk", "step_twist", "radius_of_gyration_nm")
#: Base pairs per vertex of the smoothed axis whose writhe is the shape writhe (one helical turn).
AXIS_BLOCK = 10


def smoothed_axis(positions, block=AXIS_BLOCK):
    """The ring's axis as the polygon through the centres of consecutive blocks of ``block`` nodes, shape (m, 3).

    The polygon through the node centres carries the shear of every step (edges tilted by ~0.16 rad from d3 at
    random): local wiggles whose writhe adds to the writhe variance and is compensated by the ribbon twist in
    Lk = Tw + Wr. Blocks remove them but, on short rings, also lose writhe: at 200 bp the 20-vertex polygon
    has about half of the ring's writhe variance (harmonic ring with stiff shear: 0.00089 vs 0.00154 through
    every node); at 600 bp (60 vertices) it agrees with ``Wr_star``. Reported for comparison; the nicked-ring
    check uses ``Wr_star`` (:func:`step_twist_sum`).
    """
    n = len(positions)
    m = max(4, int(round(n / block)))
    return np.array([positions[idx].mean(axis=0) for idx in np.array_split(np.arange(n), m)])
DEFAULT_SOFTENING = 16.0


def _settings(s):
    from dnarod.engines.openmm.platforms import member_platform  # loads OpenMM

    out = dict(n_bp=300, forcefield="dna-default", time_ns=4.0, equilibration_ns=None, temperature_K=300.0,
               salt_M=0.15, seed=1, friction_per_ps=None, sample_ps=None, platform=None, threads=None,
               electrostatics=True, excluded_volume=True, charge=DEFAULT_CHARGE, cutoff_debye=DEFAULT_CUTOFF_DEBYE,
               softening=DEFAULT_SOFTENING)
    unknown = set(s) - set(out)
    if unknown:
        raise DnarodError(f"unknown nicked-ring setting(s) {sorted(unknown)}; known: {sorted(out)}")
    out.update({k: v for k, v in s.items() if v is not None})
    if not (float(out["softening"]) >= 1.0):
        raise DnarodError(f"softening {out['softening']}: give a factor >= 1 by which the twist stiffness is divided")
    out.update(member_platform(out["platform"], out["threads"], "auto"))  # the platform it runs on, in its key
    return out


def soft_twist_model(model, softening, temperature=300.0, n_samples=200_000, seed=0):
    """The model with every step's twist made soft and decoupled, the non-twist marginal kept exactly.

    The Cayley twist angle ``2 atan(ds Omega_3 / 2)`` is concave in Omega_3, so a soft twist lowers the mean
    twist angle of a step; the intrinsic Omega_3 is raised (three Newton steps on the sampled mean, exact
    step distribution) so that each step's mean twist angle stays the model's, and with it the relaxed twist
    of the ring.

    Parameters
    ----------
    model : RodModel
    softening : float
        The twist stiffness (after taking out its coupling) is divided by this.

    Returns
    -------
    RodModel
        Same pose, masses and closure; stiffness per step ``[[S, 0], [0, K_33/softening]]`` with S the Schur
        complement of K_33 on the other five strains.
    """
    K = np.array(model.params.stiffness, float)
    Kn = np.zeros_like(K)
    other = [0, 1, 3, 4, 5]
    for k in range(len(K)):
        b = K[k][np.ix_(other, other)]
        c = K[k][other, 2]
        Kn[k][np.ix_(other, other)] = b - np.outer(c, c) / K[k][2, 2]
        Kn[k][2, 2] = K[k][2, 2] / float(softening)
    xi0 = np.array(model.params.intrinsic, float)

    rng = np.random.default_rng(seed)
    ds = model.ds
    fixed = {}
    for k in range(len(K)):
        key = (Kn[k].tobytes(), xi0[k].tobytes())
        if key not in fixed:
            target = 2.0 * np.arctan(0.5 * ds * xi0[k, 2])
            x = xi0[k].copy()
            for _ in range(3):
                st = sample_step_strains(Kn[k], x, ds, kT(temperature), n_samples, rng)[:, 2]
                mean = np.mean(2.0 * np.arctan(0.5 * ds * st))
                slope = np.mean(ds / (1.0 + (0.5 * ds * st) ** 2))
                x[2] += (target - mean) / slope
            fixed[key] = x
        xi0[k] = fixed[key]
    params = StepParameters(Kn, xi0, names=model.params.names)
    return dataclasses.replace(model, params=params)


def step_twist_sum(positions, frames, ds, closure):
    """Sum of the Cayley twist angles ``2 atan(ds Omega_3 / 2)`` of a ring's steps (turns).

    ``Lk - step_twist_sum`` is the part of the linking number that is not step twist (``Wr_star``): the
    exact complement of the twist whose variance :func:`dnarod.physics.theory.supercoil.twist_variance_exact`
    gives, so ``ΔLk = Δ(step twist) + ΔWr_star`` with no smoothing choice.
    """
    om, _ = strains(positions, frames, ds, closure)
    return float(np.sum(2.0 * np.arctan(0.5 * ds * om[:, 2])) / (2.0 * np.pi))


def twist_sum_moments(model, temperature, n_samples=400_000, seed=0):
    """Mean and variance (turns, turns²) of the total twist of the model's steps, from the exact step distribution."""
    rng = np.random.default_rng(seed)
    p = model.params
    cache, mean, var = {}, 0.0, 0.0
    for k in range(p.n_steps):
        key = (p.stiffness[k].tobytes(), p.intrinsic[k].tobytes())
        if key not in cache:
            s = sample_step_strains(p.stiffness[k], p.intrinsic[k], model.ds, kT(temperature), n_samples, rng)
            th = 2.0 * np.arctan(0.5 * model.ds * s[:, 2]) / (2 * np.pi)
            cache[key] = (float(th.mean()), float(th.var()))
        mean += cache[key][0]
        var += cache[key][1]
    return mean, var


def free_writhe_moments(wr, lk, tw_mean, tw_var, n_blocks=10):
    """Reweighted ``<Wr>`` and ``<Wr²>`` of the free ring, with block-jackknife standard errors.

    Weights ``exp((lk - tw_mean - Wr)² / (2 tw_var))`` undo the Gaussian factor ``p_Tw(lk - Wr)``.

    Returns
    -------
    dict
        ``mean``, ``mean_err``, ``second_moment``, ``second_moment_err``, ``variance`` (about the mean),
        ``unweighted_second_moment``, ``weight_spread`` (max/min weight).
    """
    wr = np.asarray(wr, float)
    a = (lk - tw_mean - wr) ** 2 / (2.0 * tw_var)
    w = np.exp(a - a.max())

    def est(blocks):
        ww = np.concatenate([b[0] for b in blocks])
        x = np.concatenate([b[1] for b in blocks])
        m1 = np.sum(ww * x) / np.sum(ww)
        m2 = np.sum(ww * x * x) / np.sum(ww)
        return np.array([m1, m2, m2 - m1 * m1])

    blocks = split_blocks((w, wr), n_blocks)
    full, se = jackknife(est, blocks)
    return dict(mean=float(full[0]), mean_err=float(se[0]), second_moment=float(full[1]),
                second_moment_err=float(se[1]), variance=float(full[2]), variance_err=float(se[2]),
                unweighted_second_moment=float(np.mean(wr * wr)), weight_spread=float(w.max() / w.min()))


def run_nicked_member(settings, member_dir, progress=None):
    """Run (or reuse) one soft-twist ring; writes ``samples.csv`` and ``protocol_result.json``, returns the row.

    The row has the reweighted free-ring writhe moments of the smoothed axis (``wr2_free``, ``wr2_free_err``;
    :func:`smoothed_axis`) and of the node polygon (``wr2_free_node_polygon``), the unweighted ones,
    the soft chain's total-twist moments, the integrated autocorrelation time of Wr², and the cost.
    """
    # late: a test patches rings.sample_ring
    from dnarod.workflows.protocols.rings import cached_member, sample_ring, write_member

    s = _settings(settings)
    key = jsonable(s)
    cached, done = cached_member(member_dir, key)
    if cached is not None:
        return cached
    ff = load_forcefield(s["forcefield"])
    ring = ff.ring(n_nodes=int(s["n_bp"]), delta_linking_number=0)
    T = float(s["temperature_K"])
    model = soft_twist_model(ring, float(s["softening"]), T)
    tw_mean, tw_var = twist_sum_moments(model, T)
    lp = persistence_length(ring.params, ring.ds, kT(T))

    def record(pos, frm):
        tw_step = step_twist_sum(pos, frm, model.ds, model.closure)
        lk = twist(pos, frm[:, :, 0]) + writhe(pos)  # as sample_ring's Lk (an integer: the ring is closed)
        return {"Wr_axis": writhe(smoothed_axis(pos)), "step_twist": tw_step, "Wr_star": lk - tw_step}

    ckpt = Path(member_dir) / "member_checkpoint.npz"
    out, run = sample_ring(model, s, lp, COLUMNS, record, tau_fraction=0.05, samples_per_ns=400.0,
                           max_sample_ps=100.0, min_samples=20, progress=progress, checkpoint=ckpt)
    stride, dt, n_samp = run.pop("stride"), run["dt_ps"], run["n_samples"]
    lk_int = np.rint(out["Lk"])
    if np.ptp(lk_int) != 0:
        raise DnarodError(f"nicked-ring member: the linking number changed during the run ({sorted(set(lk_int))}); "
                          f"the sampled topology is not fixed")
    lk = float(lk_int[0])
    mom_star = free_writhe_moments(out["Wr_star"], lk, tw_mean, tw_var)
    mom = free_writhe_moments(out["Wr_axis"], lk, tw_mean, tw_var)
    mom_fine = free_writhe_moments(out["Wr"], lk, tw_mean, tw_var)
    dev2 = (out["Wr_star"] - mom_star["mean"]) ** 2
    tau_wr2 = integrated_autocorrelation_time(dev2)
    tau_wr = integrated_autocorrelation_time(out["Wr_star"])
    res = dict(n_bp=model.n_nodes, temperature_K=T, salt_M=float(s["salt_M"]), seed=int(s["seed"]),
               softening=float(s["softening"]), linking_number=lk,
               soft_twist_mean_turns=tw_mean, soft_twist_variance_turns2=tw_var,
               wr_star_var=mom_star["variance"], wr_star_var_err=mom_star["variance_err"],
               wr_star_mean=mom_star["mean"], wr_star_mean_err=mom_star["mean_err"],
               wr_star_var_unweighted=float(np.var(out["Wr_star"])),
               wr2_free=mom["second_moment"], wr2_free_err=mom["second_moment_err"], wr_mean_free=mom["mean"],
               wr_mean_free_err=mom["mean_err"], wr2_unweighted=mom["unweighted_second_moment"],
               weight_spread=mom["weight_spread"], wr2_free_node_polygon=mom_fine["second_moment"],
               wr2_free_node_polygon_err=mom_fine["second_moment_err"],
               wr_tau_ps=float(tau_wr * stride * dt) if np.isfinite(tau_wr) else None,
               wr2_tau_ps=float(tau_wr2 * stride * dt) if np.isfinite(tau_wr2) else None,
               n_effective=float(n_samp / (2 * tau_wr2)) if np.isfinite(tau_wr2) and tau_wr2 > 0 else None,
               radius_of_gyration_nm=float(out["radius_of_gyration_nm"].mean()), **run)
    write_member(member_dir, done, key, COLUMNS, out, res)
    ckpt.unlink(missing_ok=True)
    return jsonable(res)
