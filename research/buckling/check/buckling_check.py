"""The buckling check: buckling and the plectonemic plateau of a chain in magnetic tweezers against Marko's
two-phase model with the model's own A, C and plectoneme twist stiffness P.

Research code (``research/buckling/check``; until 2026-12-07 it was ``dnarod.validate.buckling``, check ``buckling``
of ``dnarod validate``). It runs on the product's public API: tweezers members
(:func:`dnarod.workflows.protocols.tweezers.run_member`, from the static pose or from a given pose), ring members
(:func:`dnarod.workflows.protocols.rings.run_ring_member`) and the theory of
:mod:`dnarod.physics.theory.supercoil`. Command: ``python research/buckling/check/run_buckling.py OUT [--quick] [KEY=VALUE
...]``.

System: an open ``dna-default`` chain in magnetic tweezers at constant force (node 0 clamped, rotation clamp and
force on the last node, surface and bead walls; :mod:`dnarod.workflows.protocols.tweezers`), OpenMM engine, WCA +
Debye-Hueckel at 0.15 M. Members at one pre-buckling number of turns and at two numbers of turns past
buckling; and one closed ring (:mod:`dnarod.workflows.protocols.rings`) that measures the model's P.

Linking differences are relative to the relaxed chain at the run's temperature
(:func:`dnarod.physics.thermal.relaxed_ribbon_twist`: the mean ribbon twist of the free steps, 0.27 turns below the T = 0
sum of intrinsic twist angles for 600 bp), both for the tweezers chain (``delta_lk_thermal``) and for the ring
that gives P.

Theory (:func:`dnarod.physics.theory.supercoil.marko_two_phase`; J. F. Marko, Phys. Rev. E 76:021926, 2007):
plateau torque ``tau* = sqrt(2 kT g / (1/P - 1/C_s))`` (also the torque at buckling), buckling point
``ΔLk_b = tau* L / (2 pi kT C_s)`` and extension slope past buckling, with A the model's exact persistence
length, ``g`` the exact worm-like-chain free energy per length at this force and A
(:func:`~dnarod.physics.theory.supercoil.wlc_free_energy_exact`; Marko's leading ``f - sqrt(kT f/A)`` is 2.9 %
low at 1 pN and puts tau* 1.5 % low), C_s the Moroz-Nelson effective twist stiffness of the model's bare C at
this force (as in check ``torsion``; the exact extended phase under torque, the Moroz-Nelson eigenvalue problem
solved numerically, differs from it by 0.15 % in tau*) and P the plectoneme twist stiffness, which the
two-phase model takes as a parameter: it is set by the plectoneme's bending, twist and self-repulsion, i.e. by
the model's A, C and effective diameter at this salt
(:func:`~dnarod.physics.theory.supercoil.effective_diameter`, reported). It is measured from the same model in
the other plectonemic geometry, closed rings, where the twist carries the torque (``tau = kT C Ω_tw``; checked
against the twisting moment of the steps: 600-bp rings at ΔLk -4.885 / +5.115 give P 17.24 +- 0.28 /
16.99 +- 0.31 nm from the moment and 17.22 / 17.43 from the writhe, so neither the estimator nor the handedness
matters). **P is the bulk superhelix's**: a single ring's ``C (1 - Wr/ΔLk)`` is not, because its two end loops
take a linking difference of their own (little writhe for their length): it reads 19.7, 18.0, 17.2 nm at sigma
-0.051, -0.068, -0.086 (600 bp) and 14.35 nm for 1200 bp at sigma -0.086 (twisting moment), and the single
600-bp ring puts tau* at 11.47 pN nm against a measured plateau of 10.33 +- 0.27. The check therefore runs two
rings at the same sigma, of n and 2n bp (600 and 1200 in the full form, ΔLk -5 and -10), and takes
``P_b = C (1 - ΔWr / ΔΔLk)`` (:func:`~dnarod.physics.theory.supercoil.plectoneme_P_from_ring_pair`): the loops
cancel if both rings have the same loops (measured with Manning's charge: P_b 12.09 +- 0.70 nm, tau* 9.26 +-
0.31). A long ring that branches has more end loops: the check counts them per sample (``end_loops`` of the ring
members) and fails when the two rings' means differ (premise below). With the calibrated charge (d_eff 5.00 nm,
round 6) it does: at sigma -0.0875 the 600-bp ring (40 ns after 36 ns) has 1.96 end loops on average (2 in 96 %
of samples) and writhe fraction 0.695 (single-ring P 29.9 +- 0.5 nm), the 1200-bp ring (100 ns after 100 ns)
2.64 (3 in 56 %, 4 in 4 %; the loops are hairpin tips: nodes 20 nm either side are 7.6 nm apart against
30.6 at random nodes) and 0.735, so the pair's P_b = 22.2 +- 0.6 nm is biased upwards; counting the loops
(:func:`~dnarod.physics.theory.supercoil.plectoneme_P_from_rings_with_loops`, reported, not gating) gives
18.2 +- 1.1 nm and tau* 11.9 pN nm (pair 13.6, single ring 16.8). A shorter pair, 400/800 bp at sigma -0.0787
(40 ns after 16 ns / 100 ns after 65 ns), does not branch (1.84 / 1.94 end loops, at most 2 in any sample; the
difference 0.104 is just over ``LOOP_TOL``): P_b 19.3 +- 0.8 nm, loops counted 18.5 +- 0.9 (agreeing with the
600/1200 estimate), tau* 12.3 +- 0.3 -- 2.5 pN nm below the measured plateau, so with the calibrated charge the
check would fail on the Marko comparison too (cause not settled: the ring's linking density, 0.135 rad/nm, is
below the coexistence 0.154; the 2.57-turn twins are not settled). (The tweezers plectoneme has one end loop and a junction; in the two-phase model with a constant
loop cost they shift the buckling point, not the plateau, which is set by the bulk phases alone.)

Pass, each with the measured standard errors (``Z_TOL`` = 3 of them) and nothing else:

0. the post-buckling members are equilibrated: the means of extension and torque over the two halves of their
   production agree within ``Z_TOL`` SE, and (``bracket``, the full form) each member run from the straight
   start (too little plectoneme: its torque relaxes from above) and from a larger plectoneme (``bracket_start
   = "above"``: the final pose of a source member at 95 % of the largest sigma, the extra turns taken out as
   twist, :data:`ABOVE_SIGMA`) agrees with its twin in torque, extension and writhe within ``Z_TOL`` SE; the
   twins are then pooled, their error scaled up by the Birge ratio where they scatter more than their errors.
   (``bracket_start = "grown"``, a plectoneme grown 20 ns at 0.3 pN, was the bracket before round 7: at 1200
   bp such a start still had less plectoneme than at equilibrium, so it approached from the same side as the
   straight start);
   with the ring pair, both rings are settled (no drift of Wr between the halves of their production, ``Z_TOL``
   SE) and have the same mean number of plectoneme end loops within ``LOOP_TOL`` (0.1;
   :func:`dnarod.workflows.protocols.measure.plectoneme_end_loops`, recorded per sample by the ring members): a ring that
   branches has more end loops than the pair formula cancels (:func:`ring_pair_premise`);
1. both post-buckling members are plectonemic (detector of :mod:`dnarod.workflows.protocols.measure`);
2. their torques agree (the plateau is flat): ``|Δtau| <= Z_TOL SE``;
3. the extension falls between them by more than ``Z_TOL SE``;
4. the pre-buckling torque follows ``kT C_eff 2 pi ΔLk/L`` (Moroz-Nelson C_eff) within ``Z_TOL SE`` +
   ``LINEAR_ALLOWANCE`` (as before: a finite chain with clamped ends against the long-chain expansion);
5. the plateau torque equals Marko's ``tau*`` for this finite chain within ``Z_TOL`` times the combined
   standard error (the plateau's and tau*'s from the error of P) plus the two-phase model's truncation,
   estimated as the change of tau* between the first-order C_s that Marko uses and the third-order Moroz-Nelson
   C_s (``theory_truncation_pN_nm``, reported). "For this finite chain": the chain holds one plectoneme, free to
   sit anywhere along the extended part, so each member's torque stands ``kT / (L_s (Omega_p - Omega_s))`` above
   the bulk ``tau*`` (:func:`~dnarod.physics.theory.supercoil.plectoneme_position_torque_shift`, L_s = x/zeta;
   0.35 and 0.59 pN nm at 2.57 and 3.59 turns here); the error-weighted mean residual is compared. The plain
   difference (plateau - tau*) is reported beside it (``plain_difference_pN_nm``, ``plain_passed``).

**Round 7** (``research/buckling/r7``; the defaults are the form run there): the round-6 plateau (14.7-14.9 pN
nm) was measured on a plectoneme still growing: a 1200-bp member from the grown start loses extension and gains
writhe through 200 ns while its torque falls, and a larger plectoneme (a 7.19-turn pose turned back to 5.13
turns) reads 10.5 pN nm against 14.0. With twins from the straight start and from a larger plectoneme (the
"above" bracket), members analysed from Chodera's equilibration start on the extension (``equilibration_start``:
73 / 0 / 35 / 23 ns of the 300 discarded), the 400/800-bp pair (seed 7: P_b 19.77 +- 0.72 nm, both rings 2.00
end loops with the round-7 detector) and 300-ns production: **passed**; plateau 13.43 / 14.09 pN nm at 2.57 /
3.59 turns (twins 13.16 / 13.79 and 13.98 / 14.20), Marko 12.53 +- 0.30 (+ the position shifts), mean residual
0.84 against a tolerance of 1.09; the plain difference 1.36 would fail. Cost 5.1 k CPU-s (1.4 core-hours): each
300-ns twin 787-1115 CPU-s, the source 308, the pre-buckling member 191, the rings 135 and 684.

Turns: pre-buckling 0.01 Lk0 (below Marko's ΔLk_b ~ 0.018 Lk0), post-buckling 0.045 and 0.063 Lk0, about 40 %
and 70 % of the way from buckling to the fully plectonemic chain (~0.09 Lk0 at 1 pN).

Statistics: the plectoneme's length fluctuates slowly (tens of ns) and the torque follows it (600 bp, 1 pN,
2.57 turns: -0.086 pN nm per nm of plectoneme, the two-phase model's fixed-Lk value being -0.078), a
small-amplitude mode under fast noise that the autocorrelation-time window misses; member errors are blocked
(:func:`block_standard_error`). The full form runs 400 ns of production per member (each twin at 2.57 turns:
747-752 s CPU); with 150 ns the 2.57-turn twins disagreed (not settled), with 400 ns they agree
(10.34 +- 0.28 and 10.32 +- 0.38 pN nm; Manning's charge). With the calibrated charge (round 6, a reduced full
form: 200-ns twins, 600/1200-bp rings, the long one after 100 ns; ``research/buckling/r6``) the check fails:
plateau 14.71 +- 0.37 / 14.91 +- 0.38 pN nm at 2.57 / 3.59 turns (flat), the 2.57-turn twins disagree (13.25 +-
0.61 vs 15.50 +- 0.45, z 3.0; one plectoneme each, its end loop mid-chain in one and near the bead in the
other), the 1200-bp ring branches (premise), Marko 13.55 +- 0.24 with the biased pair P_b. Cost there (CPU
time, load average 8-16): 600-bp twin 397-538 CPU-s per 200 ns (+ 11.5 ns equilibration, + 20 ns at 0.3 pN
for the grown start), 1200-bp ring 1012 CPU-s per 200 ns, 600-bp ring 168 CPU-s per 76 ns.

Members: :func:`member_plan` lists the members the check runs with given options (folders, settings, seeds);
members run in advance with exactly those settings (e.g. in two processes, ``research/buckling/r6/premembers.py``)
into the member root are reused. Without ``member_root`` the members live in ``<report folder>/buckling_members``
(:data:`MEMBER_FOLDER`), so running the check again into the same report folder (``run_buckling.py SAME``) reuses the
finished members and resumes an interrupted one from its checkpoint. The pre-buckling member has no plectoneme
and runs ``PRE_TIME_NS`` (100 ns, ~40 slowest bending relaxation times) in the full form.

The buckling point (pre-buckling linear law met by the plateau torque) and the extension slope are reported
beside Marko's values but not tested: the two-phase model leaves out the plectoneme end loop, which shifts
buckling and takes length in short chains (see the README for the measured numbers). ``c_override`` replaces the
model's C in the theory, in C_s and in P (both ring formulas scale with C; the tests show the check failing
with C halved);
``P_nm``/``P_err_nm`` skip the rings; ``ring_pair=False`` (the quick form) takes P from the single ring (which
overstates it, above).
"""
from __future__ import annotations

import time

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.analysis.plots import new_figure, save_figure

#: Folder of the members in the report folder when no ``member_root`` is given (reused by a rerun).
MEMBER_FOLDER = "buckling_members"

NAME = "buckling"
TWO_PI_ = 2.0 * np.pi
Z_TOL = 3.0
LINEAR_ALLOWANCE = 0.15


#: Fewest blocks :func:`block_standard_error` uses (the error of a standard error from nb blocks is
#: ~1/sqrt(2(nb - 1)): 19 % at 15 blocks).
MIN_BLOCKS = 15

#: The "above" bracket's source member: turns ``ABOVE_SIGMA`` times Lk0 (95 % of the largest sigma a member
#: accepts; at least ``ABOVE_MIN_FACTOR`` times the larger post-buckling value), run ``ABOVE_NS`` of production from
#: the straight start; its plectoneme is larger than either post-buckling member's at equilibrium, so their twins
#: started from its pose (the extra turns taken out as twist) approach equilibrium from the other side than the
#: straight start. Measured (round 7, 1 pN): a plectoneme that is too large shrinks within the twin's equilibration
#: (600 bp: the pose of 40 ns at 4.60 turns, Wr 3.39, turned back to 3.594 turns read Wr 2.62 in the first 50 ns of
#: production, below the straight start's), so the source needs a wide margin; 1200 bp: the pose at 7.19 turns
#: turned back to 5.13 read 10.5 pN nm and Wr 4.08 in the first 24 ns against 14.0 and 3.42 from the grown start.
ABOVE_SIGMA = 0.095
ABOVE_MIN_FACTOR = 1.3
ABOVE_NS = 60.0

#: What the quick form (400 bp, 2-ns members) gates on, and why not on the rest.
QUICK_SCOPE = ("quick form: gates on the pre-buckling torque law (Moroz-Nelson C_eff), on both post-buckling members "
               "being plectonemic and on the extension falling between them; the plateau's flatness, Marko's "
               "plateau torque and the equilibration tests are reported, not gated: 2-ns members are far from the "
               "plectoneme's equilibrium (its length relaxes over ~10^2 ns at 600 bp; the full form runs 300-ns "
               "twins)")

#: Production (ns) of each post-buckling member in the full form (round 7: the straight and "above" twins agree and
#: pass the drift test at 300 ns after Chodera's equilibration start; 1.4 core-hours for the whole check).
FULL_TIME_NS = 300.0

#: Production (ns) of the pre-buckling member in the full form (shorter than the post-buckling members': it has
#: no plectoneme; 600 bp at 1 pN: slowest bending relaxation time ~2.3 ns).
PRE_TIME_NS = 100.0


def block_standard_error(x, min_blocks=MIN_BLOCKS):
    """Standard error of the mean of a correlated series by blocking (Flyvbjerg & Petersen, J. Chem. Phys. 91,
    461, 1989): the largest standard error of the block means over block lengths 1, 2, 4, ... samples that
    leave at least ``min_blocks`` blocks.

    Why not the integrated autocorrelation time: the torque and extension of a buckled member carry a slow,
    small-amplitude mode (the plectoneme's length, tens of ns) under fast noise; Sokal's automatic window
    stops on the fast part and misses it. Measured at 2.57 turns, 600 bp, 1 pN, 400 ns: the blocked error
    of the twisting moment grows from 0.13 (single samples) to 0.28-0.38 pN nm (25.6-ns blocks) while the
    autocorrelation-time estimate reads 0.20-0.24. Taking the largest level keeps the estimate from
    falling back below the slow mode's share (a plain plateau pick is noisy at 15 blocks). Blocking in turn
    underestimates a series only a few correlation times long (no block is longer than n/min_blocks), where
    the autocorrelation-time estimate does better: the larger of the two is returned.

    Parameters
    ----------
    x : array_like, shape (n,)
    min_blocks : int

    Returns
    -------
    float
        Same unit as ``x``; NaN with fewer than 4 samples.
    """
    from dnarod.analysis.polymer import integrated_autocorrelation_time

    x = np.asarray(x, float)
    best, b = float("nan"), 1
    if len(x) >= 4 and np.ptp(x) > 0:
        tau = integrated_autocorrelation_time(x)
        tau = tau if np.isfinite(tau) and tau > 0.5 else 0.5
        best = float(x.std(ddof=1) * np.sqrt(2.0 * tau / len(x)))
    while len(x) // b >= min_blocks:
        nb = len(x) // b
        m = x[: nb * b].reshape(nb, b).mean(axis=1)
        se = float(m.std(ddof=1) / np.sqrt(nb))
        best = se if not np.isfinite(best) else max(best, se)
        b *= 2
    return best


def equilibration_start(x, n_candidates=40, max_fraction=0.5):
    """First sample of the equilibrated part of a series (Chodera's rule: the start that maximises the effective
    number of independent samples left, ``(n - t0) / g(t0)``, with ``g = 2 tau_int`` the statistical
    inefficiency of ``x[t0:]``; J. D. Chodera, J. Chem. Theory Comput. 12:1799, 2016).

    Written here on :func:`dnarod.analysis.polymer.integrated_autocorrelation_time` (Sokal's window) rather than
    taken from pymbar's ``timeseries.detect_equilibration``, which would add pymbar and numexpr as dependencies
    and prints a banner on import, for ten lines. Candidates are ``n_candidates`` evenly spaced starts in the first
    ``max_fraction`` of the series (at least half of it is kept).

    Parameters
    ----------
    x : array_like, shape (n,)

    Returns
    -------
    int
        Index of the first kept sample (0 for fewer than 8 samples).
    """
    from dnarod.analysis.polymer import integrated_autocorrelation_time

    x = np.asarray(x, float)
    n = len(x)
    if n < 8:
        return 0
    best, t_best = -1.0, 0
    for t0 in np.unique(np.linspace(0, int(max_fraction * n), n_candidates).astype(int)):
        tau = integrated_autocorrelation_time(x[t0:])
        g = 2.0 * tau if np.isfinite(tau) and tau > 0.5 else 1.0
        if (n - t0) / g > best:
            best, t_best = (n - t0) / g, int(t0)
    return t_best


def drift_z(samples_csv, column, min_blocks=8, start=0):
    """z-score of the difference between the means of the two halves of a member's samples (blocked errors,
    :func:`block_standard_error` with ``min_blocks`` per half)."""
    d = np.genfromtxt(samples_csv, delimiter=",", names=True)
    halves = np.array_split(np.asarray(d[column], float)[int(start):], 2)
    se = [block_standard_error(h, min_blocks) for h in halves]
    return float((halves[1].mean() - halves[0].mean()) / np.hypot(*se))


def plectoneme_twist_stiffness(ring_row, C_nm, intrinsic_turns, relaxed_twist_err=0.0):
    """P (nm) and its standard error from a plectonemic ring member's writhe fraction, ``P = C (1 - Wr/ΔLk)``.

    ``ΔLk = Lk - intrinsic_turns``, the relaxed ring's mean twist at the run's temperature
    (:func:`dnarod.physics.thermal.relaxed_ribbon_twist`; turns).
    """
    d = ring_row["Lk"] - intrinsic_turns
    f = ring_row["Wr"] / d
    f_err = float(np.hypot(ring_row["Wr_err"], f * relaxed_twist_err) / abs(d))
    return C_nm * (1.0 - f), C_nm * f_err, f, f_err


#: Largest difference of the two rings' mean numbers of plectoneme end loops for the ring pair to cancel them
#: (calibrated charge: an end loop lowers the writhe by 0.25-0.30 turns, from the loop-counted pair formula on the
#: 400/800 and 600/1200-bp pairs, so 0.1 loop moves P_b by 0.6-0.9 nm, about one standard error).
LOOP_TOL = 0.1


def ring_series(member_dir, column):
    """One column of a ring member's ``samples.csv`` (ndarray, shape (n_samples,)); None if not recorded."""
    from pathlib import Path

    d = np.genfromtxt(Path(member_dir) / "samples.csv", delimiter=",", names=True)
    return np.asarray(d[column], float) if column in d.dtype.names else None


def ring_pair_premise(short_dir, long_dir, loop_tol=None, z_tol=Z_TOL):
    """Whether two ring members can give the bulk P
    (:func:`~dnarod.physics.theory.supercoil.plectoneme_P_from_ring_pair`): both settled (the
    means of Wr over the halves of each production agree within ``z_tol`` blocked SE) and with the same
    number of plectoneme end loops on average (``|<n_long> - <n_short>| <= loop_tol``, :data:`LOOP_TOL`; the
    per-sample count :func:`dnarod.workflows.protocols.measure.plectoneme_end_loops`, column ``end_loops``). A ring
    that branches has more end loops than the pair formula cancels.

    Returns
    -------
    dict
        ``end_loops`` (mean per ring), ``end_loop_histograms`` (samples with 0, 1, 2, ... loops),
        ``loop_difference``, ``wr_drift_z`` (per ring), ``settled``, ``same_loops`` and ``passed``;
        ``same_loops`` is False with a ``reason`` when a ring has no ``end_loops`` column.
    """
    loop_tol = LOOP_TOL if loop_tol is None else float(loop_tol)
    loops = [ring_series(d, "end_loops") for d in (short_dir, long_dir)]
    z = [drift_z(f"{d}/samples.csv", "Wr") for d in (short_dir, long_dir)]
    settled = bool(all(abs(v) <= z_tol for v in z))
    out = dict(wr_drift_z=z, settled=settled, loop_tolerance=loop_tol)
    if any(x is None for x in loops):
        out.update(end_loops=None, end_loop_histograms=None, loop_difference=None, same_loops=False,
                   reason="end loops not recorded (ring members run before the end_loops column existed)")
    else:
        m = [float(x.mean()) for x in loops]
        out.update(end_loops=m, end_loop_histograms=[np.bincount(x.astype(int)).tolist() for x in loops],
                   loop_difference=m[1] - m[0], same_loops=bool(abs(m[1] - m[0]) <= loop_tol))
    out["passed"] = bool(settled and out["same_loops"])
    return out


def member_plan(quick=False, n_bp=None, force_pN=1.0, pre_turns=None, post_turns=None, time_ns=None,
                temperature=300.0, seed=31, P_nm=None, ring_n_bp=None, ring_delta_lk=None, ring_time_ns=None,
                ring_seed=5, bracket=None, grown_force_pN=0.3, grown_ns=None, ring_pair=None, ring_pair_time_ns=None,
                nonbonded=None, pre_time_ns=None, ring_pair_equilibration_ns=None, bracket_start="above",
                above_turns=None, above_ns=None, platform=None):
    """The members :func:`check_buckling` runs with these options, in the order it runs them.

    Each entry is a dict: ``kind`` (``"tweezers"``: :func:`dnarod.workflows.protocols.tweezers.run_member`; ``"ring"``:
    :func:`dnarod.workflows.protocols.rings.run_ring_member`), ``folder`` (the member's folder name under the check's member
    root), ``settings`` (the member's settings dict) and ``role`` (``"ring"``, ``"ring_pair"``, ``"pre"``,
    ``"post"``, ``"post_grown"``, ``"above_source"``, ``"post_above"``) with ``index`` (0 pre-buckling, 1 and 2
    post-buckling). A ``"post_above"`` member starts from the final pose of the ``"above_source"`` member named
    by its ``start_from`` (:func:`run_planned`); a ``"post_grown"`` member starts from a plectoneme grown as its
    ``grow`` entry says (:func:`run_grown_member`). Members run in advance with exactly these settings into the
    member root (e.g. in parallel processes) are reused by the check. Same keywords as :func:`check_buckling`;
    ``platform`` (an OpenMM platform name; default the automatic choice) goes into every member's settings, so
    members recorded on one platform are reused only by a check asked to run on it.
    """
    from dnarod.core.forcefield import load_forcefield
    from dnarod.physics.loads import intrinsic_turns

    n_bp = n_bp or (400 if quick else 600)
    lk0 = intrinsic_turns(load_forcefield("dna-default").model_from_sequence(n_nodes=n_bp))
    # pre-buckling below Marko's buckling point (ΔLk_b ~ 0.018 Lk0 here, relative to the relaxed chain at T);
    # post-buckling at ~40 % and ~70 % of the way from buckling to the fully plectonemic chain (~0.09 Lk0), so
    # that both are in the two-phase coexistence the model describes (earlier 0.075/0.098 Lk0: at and beyond
    # the fully plectonemic point)
    pre_turns = 0.01 * lk0 if pre_turns is None else float(pre_turns)
    post_turns = (0.045 * lk0, 0.063 * lk0) if post_turns is None else tuple(post_turns)
    time_ns = time_ns or (2.0 if quick else FULL_TIME_NS)
    # the pre-buckling member has no plectoneme (no slow mode): PRE_TIME_NS is ~40 slowest bending relaxation times
    pre_time_ns = pre_time_ns or min(time_ns, PRE_TIME_NS)
    bracket = (not quick) if bracket is None else bool(bracket)
    grown_ns = grown_ns or (2.0 if quick else 20.0)
    nb = dict(nonbonded or {})  # member settings "charge" / "cutoff_debye" (default: the model's non-bonded terms)
    if platform:
        nb["platform"] = platform
    plan = []
    if P_nm is None:  # the model's plectoneme twist stiffness, from plectonemic rings of the same model
        ring_n_bp = ring_n_bp or 400
        ring_delta_lk = ring_delta_lk or -3
        ring_time_ns = ring_time_ns or (3.0 if quick else 60.0)
        plan.append(dict(kind="ring", role="ring", index=0, folder=f"ring{ring_n_bp}_{ring_delta_lk}",
                         settings=dict(n_bp=ring_n_bp, delta_lk=ring_delta_lk, time_ns=ring_time_ns, seed=ring_seed,
                                       temperature_K=temperature, **nb)))
        if (not quick) if ring_pair is None else bool(ring_pair):
            # the bulk P: a second ring twice as long at the same sigma (the end loops cancel)
            n2, dlk2 = 2 * ring_n_bp, 2 * ring_delta_lk
            plan.append(dict(kind="ring", role="ring_pair", index=1, folder=f"ring{n2}_{dlk2}",
                             settings=dict(n_bp=n2, delta_lk=dlk2, time_ns=ring_pair_time_ns or 2.0 * ring_time_ns,
                                           seed=ring_seed, temperature_K=temperature,
                                           # default: the ring protocol's five slowest bending relaxation times
                                           **({} if ring_pair_equilibration_ns is None
                                              else dict(equilibration_ns=ring_pair_equilibration_ns)), **nb)))
    if bracket_start not in ("above", "grown"):
        raise DnarodError(f"bracket_start {bracket_start!r}: 'above' (from a larger plectoneme) or 'grown' (from a "
                          f"plectoneme grown at a lower force)")
    above = bracket and bracket_start == "above"
    if above:  # one source member with more turns than either post-buckling member: its plectoneme is larger
        from dnarod.physics.loads import MAX_SIGMA

        t_src = round(float(above_turns if above_turns is not None
                            else min(max(ABOVE_SIGMA * lk0, ABOVE_MIN_FACTOR * max(post_turns)), 0.95 * MAX_SIGMA * lk0)), 4)
        src_folder = f"turns{t_src:+.3f}_source"
        plan.append(dict(kind="tweezers", role="above_source", index=3, folder=src_folder,
                         settings=dict(n_bp=n_bp, force_pN=force_pN, turns=t_src,
                                       time_ns=above_ns or (2.0 if quick else ABOVE_NS),
                                       temperature_K=temperature, seed=seed + 3, **nb)))
    for i, t in enumerate((pre_turns, *post_turns)):
        for twin in ((False, True) if bracket and i > 0 else (False,)):
            t = round(float(t), 4)
            extra, role, suffix = {}, ("pre" if i == 0 else "post"), ""
            if twin and above:
                extra, role, suffix = dict(previous_turns=t_src), "post_above", "_above"
            elif twin:
                extra, role, suffix = {}, "post_grown", "_grown"
            e = dict(kind="tweezers", role=role, index=i, folder=f"turns{t:+.3f}" + suffix,
                     settings=dict(n_bp=n_bp, force_pN=force_pN, turns=t, time_ns=pre_time_ns if i == 0 else time_ns,
                                   temperature_K=temperature, seed=seed + i + (10 if twin else 0), **extra, **nb))
            if role == "post_above":
                e["start_from"] = src_folder
            if role == "post_grown":  # grown for grown_ns at grown_force_pN first (:func:`run_grown_member`)
                e["grow"] = dict(force_pN=grown_force_pN, time_ns=grown_ns)
            plan.append(e)
    return plan


def run_planned(entry, member_root, progress=None):
    """Run (or reuse) one entry of :func:`member_plan` in ``member_root``; returns the member's result row."""
    from pathlib import Path

    from dnarod.workflows.protocols.rings import run_ring_member
    from dnarod.workflows.protocols.tweezers import run_member

    if entry.get("start_from"):  # from the final pose of an earlier member of the plan (it must have run)
        from dnarod.workflows.protocols.poses import FINAL_POSE, load_pose

        src = Path(member_root) / entry["start_from"] / FINAL_POSE
        if not src.exists():
            raise DnarodError(f"member {entry['folder']} starts from {entry['start_from']}, which has not run "
                              f"(run the plan in order)")
        return run_member(entry["settings"], Path(member_root) / entry["folder"], progress=progress,
                          start_pose=load_pose(src))
    if entry.get("grow"):
        return run_grown_member(entry["settings"], Path(member_root) / entry["folder"], entry["grow"]["force_pN"],
                                entry["grow"]["time_ns"], progress=progress)
    fn = run_ring_member if entry["kind"] == "ring" else run_member
    return fn(entry["settings"], Path(member_root) / entry["folder"], progress=progress)


def run_grown_member(settings, member_dir, grow_force_pN, grow_ns, progress=None):
    """A tweezers member started from a plectoneme grown at a lower force ("from above" the equilibrium).

    First a member of the same settings at ``grow_force_pN`` runs ``grow_ns`` ns (all of it equilibration, a
    few samples; same turns and clamp target, so the same linking number) in ``member_dir/grow``; then the member
    runs from its final pose (:func:`dnarod.workflows.protocols.tweezers.run_member` with ``start_pose`` and
    ``previous_turns`` = its own turns), equilibrating as long as from the static pose (five slowest bending
    relaxation times) unless ``equilibration_ns`` is given. Both are reused when finished.
    """
    from pathlib import Path

    from dnarod.workflows.protocols.poses import FINAL_POSE, load_pose
    from dnarod.workflows.protocols.tweezers import build_member, run_member

    member_dir = Path(member_dir)
    grow = dict(settings, force_pN=float(grow_force_pN), equilibration_ns=float(grow_ns), time_ns=0.001)
    run_member(grow, member_dir / "grow")
    s = dict(settings, previous_turns=float(settings.get("turns") or 0.0))
    if s.get("equilibration_ns") is None:
        s["equilibration_ns"] = build_member(settings)["equilibration_ps"] / 1000.0
    return run_member(s, member_dir, progress=progress, start_pose=load_pose(member_dir / "grow" / FINAL_POSE))


def check_buckling(out_dir, quick=False, n_bp=None, force_pN=1.0, pre_turns=None, post_turns=None, time_ns=None,
                   temperature=300.0, seed=31, plots=True, member_root=None, c_override=None, P_nm=None,
                   P_err_nm=0.0, ring_n_bp=None, ring_delta_lk=None, ring_time_ns=None, ring_seed=5, bracket=None,
                   grown_force_pN=0.3, grown_ns=None, ring_pair=None, ring_pair_time_ns=None, nonbonded=None,
                   pre_time_ns=None, ring_pair_equilibration_ns=None, bracket_start="above", above_turns=None,
                   above_ns=None, platform=None):
    """Run the check (see the module docstring).

    ``bracket`` (default: the full form) runs each post-buckling member twice, from the straight start and from
    a plectoneme grown for ``grown_ns`` at ``grown_force_pN`` (longer than at the member's force), and requires
    the two to agree; ``time_ns`` is then each member's production after its equilibration. ``nonbonded``
    (dict with ``charge`` and/or ``cutoff_debye``) runs the members and rings with other non-bonded terms than
    the defaults (the recorded test members were run with Manning's charge and 5 Debye lengths). ``platform``
    runs the members on that OpenMM platform (default: the automatic choice; the recorded test members were run on
    the CPU platform with one thread, ``platform="CPU"`` reuses them).
    """
    from pathlib import Path

    from dnarod.core.forcefield import load_forcefield
    from dnarod.physics.loads import intrinsic_turns
    from dnarod.physics.thermal import persistence_length
    from dnarod.core.units import kT
    from dnarod.core.units import PN
    from dnarod.physics.nonbonded import member_nonbonded
    from dnarod.workflows.protocols.measure import twisting_moment_offset
    from dnarod.physics.thermal import relaxed_ribbon_twist
    from dnarod.core.errors import DnarodError
    from dnarod.physics.theory.supercoil import (effective_diameter, marko_two_phase, plectoneme_P_from_ring_pair,
                                                 plectoneme_position_torque_shift)

    from buckling_theory import plectoneme_P_from_rings_with_loops
    from dnarod.physics.theory.torsion import bare_twist_persistence, moroz_nelson

    t0 = time.perf_counter()
    plan = member_plan(quick=quick, n_bp=n_bp, force_pN=force_pN, pre_turns=pre_turns, post_turns=post_turns,
                       time_ns=time_ns, temperature=temperature, seed=seed, P_nm=P_nm, ring_n_bp=ring_n_bp,
                       ring_delta_lk=ring_delta_lk, ring_time_ns=ring_time_ns, ring_seed=ring_seed, bracket=bracket,
                       grown_force_pN=grown_force_pN, grown_ns=grown_ns, ring_pair=ring_pair,
                       ring_pair_time_ns=ring_pair_time_ns, nonbonded=nonbonded, pre_time_ns=pre_time_ns,
                       ring_pair_equilibration_ns=ring_pair_equilibration_ns, bracket_start=bracket_start,
                       above_turns=above_turns, above_ns=above_ns, platform=platform)
    n_bp = n_bp or (400 if quick else 600)
    model = load_forcefield("dna-default").model_from_sequence(n_nodes=n_bp)
    lk0 = intrinsic_turns(model)
    time_ns = time_ns or (2.0 if quick else FULL_TIME_NS)
    bracket = (not quick) if bracket is None else bool(bracket)
    grown_ns = grown_ns or (2.0 if quick else 20.0)
    # the members' folder: given, or one per report folder (a rerun into the same report folder reuses the
    # finished members and resumes an interrupted one from its checkpoint)
    root = Path(member_root) if member_root else Path(out_dir) / MEMBER_FOLDER
    L = model.ds * model.n_steps
    kt_pn = kT(temperature) / PN
    A = persistence_length(model.params, model.ds, kT(temperature))
    C0 = bare_twist_persistence(model, temperature)
    C_th = C0 if c_override is None else float(c_override)
    c_mn = float(moroz_nelson(C_th, A, force_pN, kt_pn))  # the pre-buckling law is theory too: the override applies
    # relaxed linking number of the chain at T (mean ribbon twist of its free steps; below the T = 0 lk0)
    lk0_T, lk0_T_se = relaxed_ribbon_twist(model, temperature)
    nb = dict(nonbonded or {})  # member settings "charge" / "cutoff_debye" (default: the model's non-bonded terms)
    terms = member_nonbonded({"excluded_volume": True, "electrostatics": True, "salt_M": 0.15, **nb})
    ring = ring2 = premise = P_loops = None
    P_single = P_single_err = None
    rings = {e["role"]: e for e in plan if e["kind"] == "ring"}
    if "ring" in rings:  # the model's plectoneme twist stiffness, from a plectonemic ring of the same model
        from dnarod.core.forcefield import load_forcefield as _ff

        ring = run_planned(rings["ring"], root)
        ring_n_bp = ring["n_bp"]
        tw0_T, tw0_T_se = relaxed_ribbon_twist(_ff("dna-default").ring(n_nodes=ring_n_bp), temperature)
        P_nm, P_err_nm, f_wr, f_wr_err = plectoneme_twist_stiffness(ring, C_th, tw0_T, tw0_T_se)
        P_single, P_single_err = P_nm, P_err_nm
        if "ring_pair" in rings:  # the bulk P: a second ring twice as long at the same sigma (the end loops cancel)
            ring2 = run_planned(rings["ring_pair"], root)
            tw0_2, _ = relaxed_ribbon_twist(_ff("dna-default").ring(n_nodes=ring2["n_bp"]), temperature)
            ring, ring2 = (dict(x, Wr_err=block_standard_error(ring_series(root / rings[k]["folder"], "Wr")))
                           for x, k in ((ring, "ring"), (ring2, "ring_pair")))
            P_nm, P_err_nm = plectoneme_P_from_ring_pair(ring["Wr"], ring["Lk"] - tw0_T, ring2["Wr"],
                                                         ring2["Lk"] - tw0_2, C_th, ring["Wr_err"], ring2["Wr_err"])
            premise = ring_pair_premise(root / rings["ring"]["folder"], root / rings["ring_pair"]["folder"])
            if premise["end_loops"] is not None:  # diagnostic: the loops counted instead of assumed equal
                try:
                    P_loops = plectoneme_P_from_rings_with_loops(
                        ring["Wr"], ring["Lk"] - tw0_T, premise["end_loops"][0], ring2["Wr"], ring2["Lk"] - tw0_2,
                        premise["end_loops"][1], C_th, ring["Wr_err"], ring2["Wr_err"])
                except DnarodError:
                    P_loops = None
    rows, drifts, twins = [], [], []

    def member(entry):
        r = dict(run_planned(entry, root))
        csv = root / entry["folder"] / "samples.csv"
        d = np.genfromtxt(csv, delimiter=",", names=True)
        # the equilibrated part of the production: Chodera's start on the extension, the slow coordinate of the
        # plectoneme (a straight start past buckling keeps a high torque and a long extension for tens of ns;
        # the torque's fast noise hides that from its own autocorrelation time)
        t0 = equilibration_start(np.asarray(d["extension_nm"], float))
        r["equilibration_discarded_ns"] = float(d["time_ps"][t0] - d["time_ps"][0]) * 1e-3 if t0 else 0.0
        for q, col in (("twist_torque_pN_nm", "twist_torque_pN_nm"), ("relative_extension", "extension_nm"),
                       ("Wr", "Wr"), ("clamp_torque_pN_nm", "clamp_torque_pN_nm")):
            x = np.asarray(d[col], float)[t0:]
            # blocked standard errors (the member's own 10-block errors miss the slow plectoneme mode)
            scale = r["contour_length_nm"] if q == "relative_extension" else 1.0
            r[q], r[q + "_err"] = float(x.mean()) / scale, block_standard_error(x) / scale
        for q in ("Tw", "Lk", "plectoneme_fraction", "plectonemic"):
            r[q] = float(np.asarray(d[q], float)[t0:].mean())
        start = {"post_grown": "grown", "post_above": "above"}.get(entry["role"], "straight")
        return r, dict(turns=r["turns"], start=start, discarded_ns=r["equilibration_discarded_ns"],
                       extension_z=drift_z(csv, "extension_nm", start=t0),
                       torque_z=drift_z(csv, "twist_torque_pN_nm", start=t0))

    source = None
    for entry in (e for e in plan if e["kind"] == "tweezers"):
        if entry["role"] == "above_source":  # only the start pose of the "above" twins
            source = run_planned(entry, root)
            continue
        r, d = member(entry)
        drifts.append(d)
        if entry["role"] not in ("post_grown", "post_above"):
            rows.append(r)
            continue
        g, dg = r, d
        r = rows[-1]
        dq = {q: (g[q] - r[q], float(np.hypot(g[q + "_err"], r[q + "_err"])))
              for q in ("twist_torque_pN_nm", "relative_extension", "Wr")}
        twins.append(dict(turns=r["turns"], straight=r, other=g, other_start=dg["start"],
                          differences={q: dict(difference=v[0], standard_error=v[1]) for q, v in dq.items()},
                          agree=bool(all(abs(v[0]) <= Z_TOL * v[1] for v in dq.values()))))
    if twins:  # both starts of a member pooled (error-weighted; they agree, or the check fails below)
        pooled = []
        for tw in twins:
            a, b = tw["straight"], tw["other"]
            p = dict(a)
            for q in ("twist_torque_pN_nm", "relative_extension", "Wr", "clamp_torque_pN_nm"):
                wa, wb = a[q + "_err"] ** -2, b[q + "_err"] ** -2
                p[q] = (wa * a[q] + wb * b[q]) / (wa + wb)
                # scaled by the twins' scatter where it exceeds their errors (Birge ratio: the blocked errors of a
                # few hundred ns can miss the plectoneme's slowest modes, and the twins are the only independent
                # replicate)
                err = float(np.hypot(a[q + "_err"], b[q + "_err"]))
                birge = abs(a[q] - b[q]) / err if err > 0 else 1.0
                p[q + "_err"] = (wa + wb) ** -0.5 * max(1.0, birge)
            p["plectonemic"] = min(a["plectonemic"], b["plectonemic"])
            p["plectoneme_fraction"] = 0.5 * (a["plectoneme_fraction"] + b["plectoneme_fraction"])
            p["wall_s"] = a["wall_s"] + b["wall_s"]
            pooled.append(p)
        rows = [rows[0], *pooled]
    # the twisting-moment estimator reads a nonzero torque on a torque-free chain (Haar measure of the step
    # rotations; measure.twisting_moment_offset): subtract it, and carry its error into absolute comparisons
    tq_off, tq_off_se = twisting_moment_offset(model, temperature)
    rows = [dict(r, twist_torque_pN_nm_raw=r["twist_torque_pN_nm"], twist_torque_pN_nm=r["twist_torque_pN_nm"] - tq_off)
            for r in rows]
    for r in rows:  # linking difference relative to the relaxed chain at T
        r["delta_lk_thermal"] = r["Lk"] - lk0_T
    pre, p1, p2 = rows
    lin = kt_pn * c_mn * 2 * np.pi * pre["delta_lk_thermal"] / L
    lin_ok = (abs(pre["twist_torque_pN_nm"] - lin)
              <= Z_TOL * float(np.hypot(pre["twist_torque_pN_nm_err"], tq_off_se)) + LINEAR_ALLOWANCE * abs(lin))
    plectonemic = bool(p1["plectonemic"] > 0.5 and p2["plectonemic"] > 0.5)
    dtau = p2["twist_torque_pN_nm"] - p1["twist_torque_pN_nm"]
    dtau_se = float(np.hypot(p1["twist_torque_pN_nm_err"], p2["twist_torque_pN_nm_err"]))
    plateau_ok = abs(dtau) <= Z_TOL * dtau_se
    dx = p2["relative_extension"] - p1["relative_extension"]
    dx_se = float(np.hypot(p1["relative_extension_err"], p2["relative_extension_err"]))
    falls = dx < -Z_TOL * dx_se
    # Marko's two-phase model with the model's A, C (or the override) and P
    c_s = float(moroz_nelson(C_th, A, force_pN, kt_pn))
    th = marko_two_phase(A, c_s, P_nm, force_pN, kt_pn, L)
    c_s1 = C_th * (1 - C_th / (4 * A) * np.sqrt(kt_pn / (A * force_pN)))  # Marko's first-order C_s
    th1 = marko_two_phase(A, c_s1, P_nm, force_pN, kt_pn, L)
    trunc = abs(th1["torque_pN_nm"] - th["torque_pN_nm"])
    dP = max(float(P_err_nm), 1e-12)
    th_hi = marko_two_phase(A, c_s, min(P_nm + dP, 0.999 * c_s), force_pN, kt_pn, L)["torque_pN_nm"]
    th_lo = marko_two_phase(A, c_s, max(P_nm - dP, 1e-6), force_pN, kt_pn, L)["torque_pN_nm"]
    tau_th_se = 0.5 * abs(th_hi - th_lo)
    w1, w2 = p1["twist_torque_pN_nm_err"] ** -2, p2["twist_torque_pN_nm_err"] ** -2
    tau_pl = (w1 * p1["twist_torque_pN_nm"] + w2 * p2["twist_torque_pN_nm"]) / (w1 + w2)
    tau_pl_se = (w1 + w2) ** -0.5
    marko_se = float(np.sqrt(tau_pl_se ** 2 + tau_th_se ** 2 + tq_off_se ** 2))
    marko_tol = Z_TOL * marko_se + trunc
    # the finite chain holds one plectoneme whose position along the extended part is free: its torque stands
    # kT / (L_s (Omega_p - Omega_s)) above tau* (supercoil_theory.plectoneme_position_torque_shift), L_s the
    # extended contour x / zeta of each member; the comparison is of the error-weighted mean residual
    shifts = [float(plectoneme_position_torque_shift(kt_pn, min(q["relative_extension"] * L / th["zeta"], L),
                                                      th["omega_p"], th["omega_s"])) for q in (p1, p2)]
    resid = (w1 * (p1["twist_torque_pN_nm"] - th["torque_pN_nm"] - shifts[0])
             + w2 * (p2["twist_torque_pN_nm"] - th["torque_pN_nm"] - shifts[1])) / (w1 + w2)
    marko_ok = abs(resid) <= marko_tol
    slope_meas = dx * L / (p2["delta_lk"] - p1["delta_lk"])
    dlk_b_meas = tau_pl * L / (kt_pn * c_mn * 2 * np.pi)
    # equilibrated: no drift between the halves of the post-buckling members' production (plectonemes grow
    # slowly), and with ``bracket`` the straight and grown starts agree
    settled = all(abs(d["extension_z"]) <= Z_TOL and abs(d["torque_z"]) <= Z_TOL for d in drifts[1:])
    settled = settled and all(tw["agree"] for tw in twins)
    # the ring pair: both rings settled (no writhe drift) with the same number of end loops
    premise_ok = premise is None or premise["passed"]
    # the quick form's members (a few ns) are far from the plectoneme's equilibrium (its growth takes ~10^2 ns:
    # QUICK_SCOPE): it gates on what a few ns measure and reports the rest
    gates = dict(linear_law=bool(lin_ok), plectonemic=plectonemic, extension_falls=bool(falls))
    if not quick:
        gates.update(plateau_flat=bool(plateau_ok), marko=bool(marko_ok), settled=bool(settled),
                     ring_pair_premise=bool(premise_ok))
    passed = bool(all(gates.values()))
    res = dict(model=f"dna-default open chain, {n_bp} bp (L = {L:.1f} nm, Lk0 = {lk0:.2f}), {force_pN} pN, 0.15 M",
               temperature_K=temperature, production_ns_per_member=time_ns,
               twisting_moment_offset_pN_nm=tq_off, twisting_moment_offset_se=tq_off_se,
               relaxed_linking_number_T0=lk0, relaxed_linking_number_thermal=lk0_T,
               relaxed_linking_number_thermal_err=lk0_T_se, bracket=bool(bracket),
               bracket_start=(bracket_start if bracket else None),
               grown_start=dict(force_pN=grown_force_pN, time_ns=grown_ns) if bracket and bracket_start == "grown" else None,
               above_source=(dict(turns=source["turns"], time_ns=next(e["settings"]["time_ns"] for e in plan
                                                                      if e["role"] == "above_source"),
                                  Wr=source["Wr"], relative_extension=source["relative_extension"])
                             if source else None),
               brackets=[dict(turns=tw["turns"], differences=tw["differences"], agree=tw["agree"],
                              straight={q: tw["straight"][q] for q in ("twist_torque_pN_nm", "twist_torque_pN_nm_err",
                                                                         "twist_torque_pN_nm_tau_ps",
                                                                         "relative_extension", "relative_extension_err",
                                                                         "extension_nm_tau_ps", "Wr", "Wr_err")},
                              other_start=tw["other_start"],
                              other={q: tw["other"][q] for q in ("twist_torque_pN_nm", "twist_torque_pN_nm_err",
                                                                   "twist_torque_pN_nm_tau_ps",
                                                                   "relative_extension", "relative_extension_err",
                                                                   "extension_nm_tau_ps", "Wr", "Wr_err")})
                         for tw in twins],
               members=[{k: r[k] for k in ("turns", "delta_lk", "delta_lk_thermal", "relative_extension", "relative_extension_err",
                                             "twist_torque_pN_nm", "twist_torque_pN_nm_err", "twist_torque_pN_nm_raw",
                                             "clamp_torque_pN_nm",
                                             "clamp_torque_pN_nm_err", "Wr", "plectoneme_fraction", "plectonemic",
                                             "lk_slips", "wall_s")} for r in rows],
               pre_buckling=dict(torque_pN_nm=pre["twist_torque_pN_nm"], torque_se=pre["twist_torque_pN_nm_err"],
                                 delta_lk_thermal=pre["delta_lk_thermal"], linear_law_pN_nm=lin,
                                 moroz_nelson_C_eff_nm=c_mn, passed=bool(lin_ok)),
               plateau=dict(torque_difference_pN_nm=dtau, standard_error=dtau_se,
                            mean_torque_pN_nm=tau_pl, mean_torque_se=tau_pl_se,
                            both_plectonemic=plectonemic, passed=bool(plateau_ok)),
               extension_drop=dict(difference=dx, standard_error=dx_se, passed=bool(falls)),
               marko=dict(persistence_length_nm=A, twist_persistence_nm=C_th, C_s_nm=c_s, P_nm=P_nm, P_err_nm=P_err_nm,
                          P_source=(("closed rings of " + f"{ring['n_bp']} and {ring2['n_bp']} bp at sigma "
                                     f"{ring['sigma']:+.4f}: P_b = C (1 - ΔWr/ΔΔLk), Wr {ring['Wr']:.3f} and "
                                     f"{ring2['Wr']:.3f}") if ring2 else
                                    ("closed ring " + f"{ring['n_bp']} bp at sigma {ring['sigma']:+.4f}: writhe fraction "
                                     f"{f_wr:.3f} +- {f_wr_err:.3f}") if ring else "given"),
                          P_single_ring_nm=P_single, P_single_ring_err_nm=P_single_err,
                          P_loop_corrected_nm=P_loops[0] if P_loops else None,
                          P_loop_corrected_err_nm=P_loops[1] if P_loops else None,
                          loop_writhe_deficit_turns=P_loops[2] if P_loops else None,
                          torque_loop_corrected_P_pN_nm=(marko_two_phase(A, c_s, P_loops[0], force_pN, kt_pn, L)
                                                         ["torque_pN_nm"] if P_loops and 0 < P_loops[0] < c_s else None),
                          torque_single_ring_P_pN_nm=(marko_two_phase(A, c_s, P_single, force_pN, kt_pn, L)["torque_pN_nm"]
                                                      if P_single is not None and P_single < c_s else None),
                          ring_linking_density_rad_per_nm=(TWO_PI_ * abs(ring["Lk"] - tw0_T) / (ring["n_bp"] * model.ds)
                                                           if ring else None),
                          coexistence_plectoneme_density_rad_per_nm=th["omega_p"],
                          effective_diameter_nm=effective_diameter(terms, model.ds, temperature),
                          torque_pN_nm=th["torque_pN_nm"], torque_se_from_P=tau_th_se, theory_truncation_pN_nm=trunc,
                          measured_plateau_pN_nm=tau_pl, tolerance_pN_nm=marko_tol, passed=bool(marko_ok),
                          position_entropy_shift_pN_nm=shifts, residual_pN_nm=resid,
                          plain_difference_pN_nm=tau_pl - th["torque_pN_nm"],
                          plain_passed=bool(abs(tau_pl - th["torque_pN_nm"]) <= marko_tol),
                          buckling_delta_lk=th["buckling_delta_lk"], buckling_delta_lk_measured=dlk_b_meas,
                          extension_slope_nm_per_turn=th["extension_slope_nm_per_turn"],
                          extension_slope_measured_nm_per_turn=slope_meas,
                          plectonemic_delta_lk=th["plectonemic_delta_lk"]),
               drift=dict(members=drifts, settled=bool(settled)), ring_pair_premise=premise, z_tolerance=Z_TOL,
               gates=gates, scope=QUICK_SCOPE if quick else None,
               pre_buckling_production_ns=next(e["settings"]["time_ns"] for e in plan if e["role"] == "pre"),
               passed=passed)
    res["production_ns_per_member"] = time_ns
    if plots:
        fig, ax = new_figure(2, 1, width=4.5, height=3.6)
        t = [r["delta_lk_thermal"] for r in rows]
        ax[0, 0].errorbar(t, [r["twist_torque_pN_nm"] for r in rows], yerr=[r["twist_torque_pN_nm_err"] for r in rows],
                          fmt="o", capsize=3, label="twisting moment")
        tt = np.linspace(0, max(t), 20)
        ax[0, 0].plot(tt, kt_pn * c_mn * 2 * np.pi * tt / L, "k--", label="linear law, Moroz-Nelson C_eff")
        ax[0, 0].axhline(th["torque_pN_nm"], color="C3", label=f"Marko two-phase (P {P_nm:.1f} nm)")
        ax[0, 0].axhspan(th["torque_pN_nm"] - marko_tol, th["torque_pN_nm"] + marko_tol, color="C3", alpha=0.15)
        ax[0, 0].set_xlabel("Lk - Lk0(T) (turns)")
        ax[0, 0].set_ylabel("torque (pN nm)")
        ax[0, 0].legend(fontsize=7)
        ax[0, 1].errorbar(t, [r["relative_extension"] for r in rows],
                          yerr=[r["relative_extension_err"] for r in rows], fmt="s", capsize=3)
        ax[0, 1].plot([0.0, th["buckling_delta_lk"], th["plectonemic_delta_lk"]], [th["zeta"], th["zeta"], 0.0], "C3-",
                      label="Marko two-phase")
        ax[0, 1].legend(fontsize=7)
        ax[0, 1].set_xlabel("Lk - Lk0(T) (turns)")
        ax[0, 1].set_ylabel("extension / L")
        res["plots"] = [save_figure(fig, out_dir, "buckling.png")]
    res["runtime_s"] = time.perf_counter() - t0
    return res


def _fmt(x, spec=".3g"):
    try:
        return format(float(x), spec)
    except (TypeError, ValueError):
        return str(x)


def headline(r):
    """``(measured, tolerance)``: one-line strings summing up a result of :func:`check_buckling` (as the
    validation report's table had them)."""
    pl, mk = r["plateau"], r["marko"]
    return (f"plateau {_fmt(pl['mean_torque_pN_nm'], '.1f')}+-{_fmt(pl['mean_torque_se'], '.1f')} pN nm vs Marko "
            f"two-phase {_fmt(mk['torque_pN_nm'], '.1f')}+-{_fmt(mk['torque_se_from_P'], '.1f')} pN nm (A "
            f"{_fmt(mk['persistence_length_nm'], '.1f')}, C_s {_fmt(mk['C_s_nm'], '.1f')}, {_p_label(mk)} "
            f"{_fmt(mk['P_nm'], '.1f')} nm)"
            + (" + the single plectoneme's position shift "
               + "/".join(_fmt(x, '.2f') for x in mk['position_entropy_shift_pN_nm'])
               + f" pN nm: residual {_fmt(mk['residual_pN_nm'], '.2f')} (plain difference "
               f"{_fmt(mk['plain_difference_pN_nm'], '.2f')})" if mk.get("position_entropy_shift_pN_nm") else "")
            + f"; plateau torques differ by {_fmt(pl['torque_difference_pN_nm'], '.2f')}"
            f"+-{_fmt(pl['standard_error'], '.2f')}; buckling at ΔLk {_fmt(mk['buckling_delta_lk_measured'], '.2f')}"
            f" (Marko {_fmt(mk['buckling_delta_lk'], '.2f')}); slope {_fmt(mk['extension_slope_measured_nm_per_turn'], '.0f')}"
            f" nm/turn (Marko {_fmt(mk['extension_slope_nm_per_turn'], '.0f')}); pre-buckling torque "
            f"{_fmt(r['pre_buckling']['torque_pN_nm'], '.1f')} vs linear law "
            f"{_fmt(r['pre_buckling']['linear_law_pN_nm'], '.1f')} pN nm; drift z (extension, torque) of the "
            f"post-buckling members " + ", ".join(f"({_fmt(d['extension_z'], '.1f')}, {_fmt(d['torque_z'], '.1f')})"
                                                  for d in r["drift"]["members"][1:])
            + ("; straight vs " + (r.get("bracket_start") or "grown") + " start: Δtau " + ", ".join(
                f"{_fmt(b['differences']['twist_torque_pN_nm']['difference'], '.2f')}"
                f"+-{_fmt(b['differences']['twist_torque_pN_nm']['standard_error'], '.2f')}"
                for b in r.get("brackets") or []) if r.get("brackets") else "")
            + f"; P from a ring at {_fmt(mk.get('ring_linking_density_rad_per_nm'), '.3f')} rad/nm "
              f"(coexistence {_fmt(mk.get('coexistence_plectoneme_density_rad_per_nm'), '.3f')})"
            + ("; ring pair: mean end loops "
               + " / ".join(_fmt(x, '.2f') for x in (r['ring_pair_premise']['end_loops'] or [None, None]))
               + ", Wr drift z "
               + ", ".join(_fmt(z, '.1f') for z in r['ring_pair_premise']['wr_drift_z'])
               + f", premise {'met' if r['ring_pair_premise']['passed'] else 'NOT met'}"
               + (f" ({r['ring_pair_premise']['reason']})" if r['ring_pair_premise'].get('reason') else "")
               if r.get("ring_pair_premise") else ""),
            (r["scope"] + "; " if r.get("scope") else "")
            + f"drift |z| <= {r['z_tolerance']}; |residual| <= {r['z_tolerance']} SE + truncation {_fmt(mk['theory_truncation_pN_nm'], '.2f')} "
            f"pN nm (= {_fmt(mk['tolerance_pN_nm'], '.2f')}); |dtau| <= {r['z_tolerance']} SE"
            + ("; failed: " + ", ".join(k for k, v in r["gates"].items() if not v)
               if r.get("gates") and not r["passed"] else ""))


def _p_label(marko):
    """Which plectoneme twist stiffness the buckling check used (from its ``P_source``)."""
    src = str(marko.get("P_source") or "")
    if src.startswith("closed rings of"):
        return "P_b (ring pair)"
    if src.startswith("closed ring"):
        return "P (single ring)"
    return "P (given)"
