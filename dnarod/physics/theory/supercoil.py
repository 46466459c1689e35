"""Supercoiling theory with the model's own parameters: Marko's two-phase model, the plectoneme twist stiffness,
the nicked-ring linking-number variance and the model's effective diameter.

Units: nm, pN, pN nm, turns; ``kt`` in pN nm (4.14 at 300 K).

**Two-phase model** (J. F. Marko, Phys. Rev. E 76:021926, 2007). A stretched chain at force f with linking
difference ΔLk is split into an extended phase (free energy per length ``-g(f) + kT C_s Ω²/2``, Ω the excess
twist rate in rad/nm, ``g = f - sqrt(kT f / A)`` the leading high-force free energy of the stretched worm-like
chain and ``C_s`` the effective twist persistence length under tension) and a plectonemic phase (free energy per
length ``kT P Ω²/2``, no extension). ``P`` is the plectoneme's effective twist stiffness, a parameter of the
model (it is set by the bending, twist and self-repulsion of the interwound superhelix, i.e. by A, C and the
effective diameter; the two-phase model does not derive it). Coexistence (common tangent in Ω) gives

* torque ``tau* = sqrt(2 kT g / (1/P - 1/C_s))``, the same at the buckling point and all along the plateau
  (``g`` exact by default: :func:`wlc_free_energy_exact`; Marko's leading ``f - sqrt(kT f/A)`` is 3 % low at
  1 pN for A = 50 nm, which puts tau* 1.5 % low);
* extended / plectonemic twist rates ``Ω_s = tau*/(kT C_s)``, ``Ω_p = tau*/(kT P)``;
* buckling linking difference ``ΔLk_b = Ω_s L / 2 pi`` (the end of the linear torque-turns regime);
* extension slope past buckling ``dz/dΔLk = -2 pi zeta / (Ω_p - Ω_s)`` (nm per turn), ``zeta = 1 -
  sqrt(kT/(4 A f))`` the relative extension of the extended phase.

The model leaves out the plectoneme end loop (a constant nucleation free energy: it shifts the buckling point to
higher ΔLk and causes the torque overshoot at buckling, but not the plateau torque) and the entropy of several
plectonemes (which makes the torque rise slowly past buckling in long chains): the plateau torque is its
firmest prediction.

**Plectonemes in closed rings.** In the plectonemic phase the twist carries the torque,
``tau = kT C Ω_tw = kT P Ω``, so a fraction ``P / C`` of the linking difference is twist and
``Wr / ΔLk = 1 - P / C`` (rings: no tension, the bare C). Conversely a measured writhe fraction gives the
model's P: ``P = C (1 - Wr/ΔLk)``.

**Nicked rings.** With a nick (one step without twist stiffness) the twist of the intact steps and the shape of
the axis are independent (bending isotropic, no twist-bend coupling: true of ``dna-default``), so ``<ΔLk²> =
<ΔTw²> + <Wr²>``; the twist part is exactly ``L / (4 pi² C)`` (turns²) to leading order in the Cayley twist,
and ``ΔG = (K RT / N) ΔLk²`` with ``K = N / (2 <ΔLk²>)`` for a ring of N bp.
"""
from __future__ import annotations

import math
import dataclasses

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.physics.thermal import relaxed_ribbon_twist as thermal_relaxed_twist  # noqa: F401  (the ring checks' Tw0 at T)
from dnarod.physics.thermal import sample_step_strains, persistence_length
from dnarod.core.units import kT
from dnarod.core.forcefield import load_forcefield
from dnarod.physics.nonbonded import member_nonbonded, effective_diameter as nb_effective_diameter
from dnarod.physics.theory.torsion import bare_twist_persistence

TWO_PI = 2.0 * math.pi


def wlc_free_energy_per_length(force_pN, A_nm, kt):
    """``g(f) = f - sqrt(kT f / A)`` (pN): the leading high-force term of :func:`wlc_free_energy_exact`."""
    f = np.asarray(force_pN, float)
    return f - np.sqrt(kt * f / A_nm)


def wlc_free_energy_exact(force_pN, A_nm, kt, l_max=160):
    """``g(f)`` (pN): minus the free energy per length of a long stretched worm-like chain, exactly.

    ``g = -kT E0`` with ``E0`` the lowest eigenvalue of the tangent's transfer operator
    ``-(1/2A) nabla² - (f/kT) cos theta`` on the unit sphere (the chain's free energy is ``L kT E0`` for
    ``L >> A``, relative to the unstretched chain: ``g(0) = 0``), diagonalised in the orthonormal Legendre
    basis, where ``cos theta`` couples ``l`` and ``l + 1`` with ``(l + 1) / sqrt((2l + 1)(2l + 3))``. So
    ``g(f) = int_0^f z(f') df'`` with ``z`` the exact inextensible worm-like-chain extension per length.
    Limits (tests): ``A f² / (3 kT)`` at low force; ``f - sqrt(kT f/A) + kT/(4A) + O(f^-1/2)`` at high
    force, the leading two terms being Marko's ``g`` (:func:`wlc_free_energy_per_length`), which is 3 %
    low at 1 pN for A = 50 nm. Written here (a tridiagonal eigenvalue, ``scipy.linalg.eigvalsh_tridiagonal``)
    because no kept library offers the worm-like chain's free energy; ``l_max`` = 160 is converged to 1e-12
    below ``f A / kT`` ~ 1e3.
    """
    from scipy.linalg import eigvalsh_tridiagonal

    b = float(force_pN) / kt
    lv = np.arange(l_max + 1, dtype=float)
    off = -b * (lv[:-1] + 1.0) / np.sqrt((2 * lv[:-1] + 1.0) * (2 * lv[:-1] + 3.0))
    e0 = eigvalsh_tridiagonal(lv * (lv + 1.0) / (2.0 * A_nm), off, select="i", select_range=(0, 0))[0]
    return -kt * float(e0)


def wlc_extension_exact(force_pN, A_nm, kt, h=1e-4):
    """Relative extension ``z = dg/df`` of the long inextensible worm-like chain (central difference)."""
    f = float(force_pN)
    h = min(h, 0.5 * f) if f > 0 else h
    return (wlc_free_energy_exact(f + h, A_nm, kt) - wlc_free_energy_exact(max(f - h, 0.0), A_nm, kt)) / (
        f + h - max(f - h, 0.0))


def extended_fraction(force_pN, A_nm, kt):
    """Relative extension ``zeta = 1 - sqrt(kT / (4 A f))`` of the extended phase (inextensible, high force)."""
    return 1.0 - 0.5 * np.sqrt(kt / (A_nm * np.asarray(force_pN, float)))


def marko_two_phase(A_nm, C_s_nm, P_nm, force_pN, kt, L_nm, exact_wlc=True):
    """Marko's two-phase predictions for a chain of contour length L (see the module docstring).

    ``exact_wlc`` (default) takes the extended phase's ``g`` and relative extension ``zeta`` from the exact
    worm-like chain (:func:`wlc_free_energy_exact`, :func:`wlc_extension_exact`) instead of Marko's leading
    high-force terms (``exact_wlc=False``); at 1 pN and A = 50 nm g is 0.7333 instead of 0.7122 pN and the
    plateau torque 1.5 % higher.

    Parameters
    ----------
    A_nm, C_s_nm, P_nm : float
        Bending persistence length, effective twist persistence length at this force (e.g. Moroz-Nelson),
        plectoneme twist stiffness; nm. ``P < C_s`` is required (else there is no buckling).
    force_pN : float
    kt : float
        pN nm.
    L_nm : float

    Returns
    -------
    dict
        ``torque_pN_nm`` (buckling and plateau), ``omega_s``/``omega_p`` (rad/nm), ``buckling_delta_lk``,
        ``plectonemic_delta_lk`` (whole chain plectonemic), ``extension_slope_nm_per_turn``, ``g_pN``,
        ``zeta``.
    """
    if not (0 < P_nm < C_s_nm):
        raise DnarodError(f"two-phase model: the plectoneme twist stiffness P = {P_nm:.3g} nm must lie between 0 "
                          f"and C_s = {C_s_nm:.3g} nm (else the chain never buckles)")
    if exact_wlc:
        g, zeta = wlc_free_energy_exact(force_pN, A_nm, kt), wlc_extension_exact(force_pN, A_nm, kt)
    else:
        g, zeta = float(wlc_free_energy_per_length(force_pN, A_nm, kt)), float(extended_fraction(force_pN, A_nm, kt))
    tau = math.sqrt(2.0 * kt * g / (1.0 / P_nm - 1.0 / C_s_nm))
    om_s, om_p = tau / (kt * C_s_nm), tau / (kt * P_nm)
    return dict(torque_pN_nm=tau, omega_s=om_s, omega_p=om_p, buckling_delta_lk=om_s * L_nm / TWO_PI,
                plectonemic_delta_lk=om_p * L_nm / TWO_PI, extension_slope_nm_per_turn=-TWO_PI * zeta / (om_p - om_s),
                g_pN=g, zeta=zeta)


def plectoneme_position_torque_shift(kt, extended_length_nm, omega_p, omega_s):
    """Torque above the two-phase plateau of a finite chain with one plectoneme (pN nm): ``kT / (L_s (Omega_p -
    Omega_s))``.

    The plectoneme can sit anywhere along the extended part, a positional entropy ``kT ln(L_s / b)`` that the
    bulk two-phase model leaves out (the extension of the model by positional and length entropies: Segers,
    Skoruppa, Schiessel & Carlon, arXiv:2410.23145, 2024). Minimising ``L_s phi_s(tau) + L_p phi_p(tau) - kT
    ln(L_s / b)`` over ``L_s`` at fixed linking number gives ``phi_s - phi_p = kT / L_s``; near the plateau
    ``phi_s - phi_p = (tau - tau*) (Omega_p - Omega_s)`` (``d phi / d tau = -Omega``), so the torque stands
    ``kT / (L_s (Omega_p - Omega_s))`` above ``tau*``, more as the extended part shortens (``b`` drops out).

    Parameters
    ----------
    kt : float
        pN nm.
    extended_length_nm : float or ndarray
        Contour length of the extended phase, nm (e.g. extension / zeta).
    omega_p, omega_s : float
        Linking densities of the two phases at the plateau, rad/nm (:func:`marko_two_phase`).

    Returns
    -------
    float or ndarray
        pN nm.
    """
    if not omega_p > omega_s:
        raise DnarodError("the plectonemic phase must hold the higher linking density")
    return float(kt) / (np.asarray(extended_length_nm, float) * (float(omega_p) - float(omega_s)))


def plectoneme_P_from_writhe_fraction(writhe_fraction, C_nm):
    """The plectoneme twist stiffness P (nm) implied by a plectonemic ring's writhe fraction: ``C (1 - Wr/ΔLk)``."""
    return float(C_nm) * (1.0 - float(writhe_fraction))


def plectoneme_P_from_ring_pair(wr_1, dlk_1, wr_2, dlk_2, C_nm, wr_err_1=0.0, wr_err_2=0.0):
    """The bulk plectoneme twist stiffness P (nm) from two plectonemic rings: ``C (1 - ΔWr / ΔΔLk)``.

    A plectonemic ring of contour length L is a superhelix of length ``L - 2 l`` plus two end loops; the loops
    take a linking difference ``2 lambda`` of their own (little writhe for their length), so
    ``2 pi ΔLk = 2 lambda + Ω_b (L - 2 l)`` with the bulk density ``Ω_b = tau / (kT P_b)``, and the single ring's
    ``C (1 - Wr/ΔLk)`` is ``P_b (1 + |delta| / (2 pi ΔLk))`` with ``delta = 2 lambda - 2 l Ω_b``: it overstates
    P_b by a share that falls as 1/ΔLk. Two rings at the same torque (the same linking density sigma, lengths
    L and 2L) have the same loops, so the difference of their writhes is the bulk's alone:
    ``Wr_2 - Wr_1 = (1 - P_b/C)(ΔLk_2 - ΔLk_1)``. (The twist carries the torque in both, ``tau = kT C Ω_tw``.)

    Parameters
    ----------
    wr_1, dlk_1, wr_2, dlk_2 : float
        Mean writhe and linking difference (relative to the relaxed twist at T) of the two rings, turns.
    C_nm : float
    wr_err_1, wr_err_2 : float
        Standard errors of the writhes.

    Returns
    -------
    tuple of float
        ``(P_b, standard_error)``, nm.
    """
    d = float(dlk_2) - float(dlk_1)
    if abs(d) < 0.5:
        raise DnarodError(f"ring pair: the linking differences {dlk_1:.3g} and {dlk_2:.3g} are too close to separate "
                          f"the bulk from the end loops; use rings of two lengths at the same sigma")
    f = (float(wr_2) - float(wr_1)) / d
    return float(C_nm) * (1.0 - f), float(C_nm) * float(np.hypot(wr_err_1, wr_err_2)) / abs(d)


def writhe_fraction_from_P(P_nm, C_nm):
    """Writhe fraction ``1 - P/C`` of a plectonemic ring."""
    return 1.0 - float(P_nm) / float(C_nm)


def twist_variance_linear(L_nm, C_nm):
    """``<ΔTw²> = L / (4 pi² C)`` (turns²) of a free (nicked) chain of contour length L."""
    return float(L_nm) / (4.0 * math.pi ** 2 * float(C_nm))


def twist_variance_exact(model, temperature, n_samples=400_000, seed=0, steps=None):
    """``<ΔTw²>`` (turns²) of the steps of a free chain from the model's exact step distribution.

    Each step's twist angle is ``2 atan(ds Omega_3 / 2)`` (the Cayley twist); steps of a free chain are
    independent (:func:`dnarod.physics.thermal.sample_step_strains`), so the variance is the sum of the per-step
    variances (sampled, ``n_samples`` per distinct step type; relative error ~ sqrt(2/n_samples)).

    Parameters
    ----------
    model : RodModel
    temperature : float
        K.
    steps : array_like of int, optional
        Steps to include (default all).
    """
    rng = np.random.default_rng(seed)
    p = model.params
    idx = np.arange(p.n_steps) if steps is None else np.asarray(steps, int)
    cache, total = {}, 0.0
    for k in idx:
        key = (p.stiffness[k].tobytes(), p.intrinsic[k].tobytes())
        if key not in cache:
            s = sample_step_strains(p.stiffness[k], p.intrinsic[k], model.ds, kT(temperature), n_samples, rng)
            th = 2.0 * np.arctan(0.5 * model.ds * s[:, 2])
            cache[key] = float(np.var(th)) / TWO_PI ** 2
        total += cache[key]
    return total


def depew_wang_K(n_bp, var_lk):
    """``K = N / (2 <ΔLk²>)`` of ``ΔG = (K RT / N) ΔLk²`` for a ring of N bp."""
    return float(n_bp) / (2.0 * float(var_lk))


def gaussian_unconstrained_variance(var_constrained, var_other):
    """Variance of X when only ``X + Y`` fixed was sampled, Y Gaussian and independent of X.

    Sampling X with ``X + Y = const`` and Y ~ N(·, var_other) independent of X multiplies X's density by a
    Gaussian of variance ``var_other``; for Gaussian X the sampled variance is ``v v_o / (v + v_o)``, so
    ``v = v_c v_o / (v_o - v_c)``. Used to undo the (small) constraint that the soft twist of a sampled ring
    puts on its writhe.
    """
    vc, vo = float(var_constrained), float(var_other)
    if vc >= vo:
        raise DnarodError(f"constrained variance {vc:.3g} >= the constraint's variance {vo:.3g}: the twist is not "
                          f"soft enough to leave the writhe free; soften it further")
    return vc * vo / (vo - vc)


def ring_constants(n_bp, temperature, salt_M, forcefield="dna-default", nonbonded=None):
    """A relaxed ``forcefield`` ring of ``n_bp`` nodes and the constants the ring checks compare with.

    Returns
    -------
    dict
        ``ff`` (the force field), ``ring`` (RodModel, ΔLk = 0), ``L`` (contour length, nm), ``A`` (the exact
        bending persistence length, nm), ``C`` (the bare torsional persistence length, nm) and ``d_eff`` (the
        effective diameter of the model's WCA + Debye-Hückel pair energy at ``salt_M``, nm; ``nonbonded``: a dict
        with ``charge`` and/or ``cutoff_debye`` for other terms than the defaults, as in the members' settings).
    """
    terms = member_nonbonded({"excluded_volume": True, "electrostatics": True, "salt_M": salt_M,
                              **dict(nonbonded or {})})
    ff = load_forcefield(forcefield)
    ring = ff.ring(n_nodes=n_bp, delta_linking_number=0)
    return dict(ff=ff, ring=ring, L=ring.ds * n_bp, A=persistence_length(ring.params, ring.ds, kT(temperature)),
                C=bare_twist_persistence(ff.model_from_sequence(n_nodes=4), temperature),
                d_eff=effective_diameter(terms, ring.ds, temperature))


def effective_diameter(nonbonded, ds, temperature, n_h=160, n_gamma=16, n_offset=3):
    """The model's effective diameter (nm); see :func:`_effective_diameter` (results are cached per settings)."""
    key = (tuple(dataclasses.astuple(nonbonded)), float(ds), float(temperature), int(n_h), int(n_gamma), int(n_offset))
    if key not in _DEFF_CACHE:
        _DEFF_CACHE[key] = _effective_diameter(nonbonded, ds, temperature, n_h, n_gamma, n_offset)
    return _DEFF_CACHE[key]


_DEFF_CACHE = {}


def _effective_diameter(nonbonded, ds, temperature, n_h, n_gamma, n_offset):
    """The model's effective diameter (nm): Onsager's excluded volume of two long straight chains of its nodes,
    computed by :func:`dnarod.physics.nonbonded.effective_diameter` (the one home of this computation; ``n_gamma``
    angles, ``n_offset`` site offsets per chain, ``n_h`` distances).

    Two long rods crossing at angle gamma with closest distance h exclude ``2 L² |sin gamma| d(gamma)``, with
    ``d(gamma) = int_0^inf <1 - exp(-U(h, gamma)/kT)> dh`` (average over the rods' sliding offsets along their
    axes); the effective diameter is its isotropic average ``<|sin g| d(g)> / <|sin g|>`` (weight ``sin² g``):
    the diameter of the hard rods with the same second virial coefficient, the definition of Stigter's effective
    diameter. U is the model's own pair energy (WCA + shifted screened Coulomb with its cutoff, node charges and
    Debye length at this salt).

    Parameters
    ----------
    nonbonded : NonbondedSettings
    ds : float
        nm per base pair.
    temperature : float
        K.

    Returns
    -------
    float
    """
    return float(nb_effective_diameter(nonbonded, ds, temperature, n_angles=n_gamma, n_phase=n_offset, n_h=n_h))
