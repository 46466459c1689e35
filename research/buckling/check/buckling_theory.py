"""Two-phase theory used only by the buckling study (moved out of ``dnarod.physics.theory.supercoil``).

* :func:`two_phase_from_plectoneme_eos`: Marko's coexistence with a measured plectoneme equation of state;
* :func:`ring_pair_bulk_torque`: the bulk plectoneme's linking density and torque from a ring pair;
* :func:`plectoneme_P_from_rings_with_loops`: the bulk P from two rings with different numbers of end loops.

Units: nm, pN, pN nm, turns; ``kt`` in pN nm. The rest of the theory (Marko's two-phase model, the ring pair's
P_b, the position-entropy shift, the effective diameter) is the product's:
:mod:`dnarod.physics.theory.supercoil`.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import DnarodError
from dnarod.physics.theory.supercoil import (TWO_PI, extended_fraction, wlc_extension_exact,  # noqa: F401
                                             wlc_free_energy_exact, wlc_free_energy_per_length)


def two_phase_from_plectoneme_eos(omega_p, tau_p, A_nm, C_s_nm, force_pN, kt, L_nm, exact_wlc=True):
    """Marko's two-phase coexistence with a measured plectoneme equation of state instead of a constant P.

    Marko's constant P makes the plectonemic phase's torque linear in its linking density,
    ``tau = kT P Omega``. The coexistence condition itself does not need that: in the torque ensemble the
    phases' free energies per length are ``phi_s(tau) = -g - tau²/(2 kT C_s)`` (extended) and
    ``phi_p(tau) = -int_0^tau Omega_p(tau') dtau'`` (plectonemic, relative to the free chain at zero torque,
    ``Omega_p(tau)`` the inverse of the equation of state), and the plateau torque is where they are equal:

        ``int_0^tau* Omega_p(tau') dtau' = g + tau*² / (2 kT C_s)``.

    With ``Omega_p = tau / (kT P)`` this is :func:`~dnarod.physics.theory.supercoil.marko_two_phase`'s ``tau* = sqrt(2 kT g / (1/P - 1/C_s))``;
    a plectonemic phase that is stiffer at low linking density than at the coexistence density (a twisted coil
    before it interwinds) raises tau*. ``Omega_p(tau)`` is the monotone cubic (PCHIP) through (0, 0) and the
    measured points, continued past the last point with that point's secant ``tau/Omega`` (constant P).

    Parameters
    ----------
    omega_p, tau_p : array_like, shape (n,)
        Measured bulk plectoneme points: linking density (rad/nm) and torque (pN nm), e.g. from ring pairs
        (:func:`ring_pair_bulk_torque`). Both must increase together.
    A_nm, C_s_nm, force_pN, kt, L_nm, exact_wlc
        As in :func:`~dnarod.physics.theory.supercoil.marko_two_phase`.

    Returns
    -------
    dict
        As :func:`~dnarod.physics.theory.supercoil.marko_two_phase` (``torque_pN_nm``, ``omega_s``, ``omega_p``, ``buckling_delta_lk``,
        ``plectonemic_delta_lk``, ``extension_slope_nm_per_turn``, ``g_pN``, ``zeta``) plus ``P_secant_nm``,
        the plectoneme's ``tau*/(kT Omega_p)`` at coexistence, and ``extrapolated`` (True if tau* lies past the
        last measured point).
    """
    from scipy.interpolate import PchipInterpolator
    from scipy.optimize import brentq

    om, ta = np.asarray(omega_p, float), np.asarray(tau_p, float)
    order = np.argsort(ta)
    om, ta = om[order], ta[order]
    if len(ta) < 1 or np.any(ta <= 0) or np.any(om <= 0) or np.any(np.diff(ta) <= 0) or np.any(np.diff(om) <= 0):
        raise DnarodError("two-phase model: the plectoneme points must have positive torques and linking densities "
                          "that increase together (a plectoneme twisted harder carries more torque)")
    if exact_wlc:
        g, zeta = wlc_free_energy_exact(force_pN, A_nm, kt), wlc_extension_exact(force_pN, A_nm, kt)
    else:
        g, zeta = float(wlc_free_energy_per_length(force_pN, A_nm, kt)), float(extended_fraction(force_pN, A_nm, kt))
    curve = PchipInterpolator(np.r_[0.0, ta], np.r_[0.0, om])
    integral = curve.antiderivative()
    P_last = ta[-1] / (kt * om[-1])

    def omega(t):
        return float(curve(t)) if t <= ta[-1] else t / (kt * P_last)

    def cumulative(t):
        if t <= ta[-1]:
            return float(integral(t))
        return float(integral(ta[-1])) + (t * t - ta[-1] ** 2) / (2.0 * kt * P_last)

    def h(t):
        return cumulative(t) - g - t * t / (2.0 * kt * C_s_nm)

    if not (0 < P_last < C_s_nm):
        raise DnarodError(f"two-phase model: the last plectoneme point's P = {P_last:.3g} nm must lie between 0 and "
                          f"C_s = {C_s_nm:.3g} nm (else the chain never buckles)")
    hi = ta[-1]
    while h(hi) < 0:
        hi *= 2.0
    tau = brentq(h, 1e-9, hi, xtol=1e-10)
    om_s, om_p = tau / (kt * C_s_nm), omega(tau)
    return dict(torque_pN_nm=tau, omega_s=om_s, omega_p=om_p, buckling_delta_lk=om_s * L_nm / TWO_PI,
                plectonemic_delta_lk=om_p * L_nm / TWO_PI, extension_slope_nm_per_turn=-TWO_PI * zeta / (om_p - om_s),
                g_pN=g, zeta=zeta, P_secant_nm=tau / (kt * om_p), extrapolated=bool(tau > ta[-1]))


def ring_pair_bulk_torque(wr_1, dlk_1, L_1, wr_2, dlk_2, L_2, C_nm, kt, wr_err_1=0.0, wr_err_2=0.0):
    """The bulk plectoneme's linking density and torque from two rings at the same sigma (lengths L_1 < L_2).

    The twist carries the torque, ``tau = kT C Omega_tw``; the end loops are the same in both rings
    (:func:`~dnarod.physics.theory.supercoil.plectoneme_P_from_ring_pair`), so the extra length ``L_2 - L_1`` is bulk, with linking density
    ``Omega = 2 pi (ΔLk_2 - ΔLk_1) / (L_2 - L_1)`` and torque ``kT C 2 pi (ΔTw_2 - ΔTw_1) / (L_2 - L_1)``,
    ``ΔTw = ΔLk - Wr``. At low sigma (a twisted coil, no plectoneme) the same difference removes the rings'
    finite-size share.

    Parameters
    ----------
    wr_1, dlk_1, wr_2, dlk_2 : float
        Mean writhe and linking difference relative to the relaxed twist at T (turns).
    L_1, L_2 : float
        Contour lengths, nm.
    C_nm, kt : float
        Bare twist persistence length (nm), kT (pN nm).

    Returns
    -------
    tuple of float
        ``(omega_rad_per_nm, torque_pN_nm, torque_standard_error)``.
    """
    dL = float(L_2) - float(L_1)
    if dL <= 0:
        raise DnarodError("ring pair: the second ring must be the longer")
    om = TWO_PI * (float(dlk_2) - float(dlk_1)) / dL
    dtw = (float(dlk_2) - float(wr_2)) - (float(dlk_1) - float(wr_1))
    k = kt * float(C_nm) * TWO_PI / dL
    return abs(om), abs(k * dtw), k * float(np.hypot(wr_err_1, wr_err_2))


def plectoneme_P_from_rings_with_loops(wr_1, dlk_1, loops_1, wr_2, dlk_2, loops_2, C_nm, wr_err_1=0.0,
                                       wr_err_2=0.0):
    """Bulk P (nm) from two plectonemic rings with different mean numbers of end loops (a ring that branches).

    The model of :func:`~dnarod.physics.theory.supercoil.plectoneme_P_from_ring_pair` with the end loops counted instead of assumed equal: each
    end loop, wherever it is, lowers the ring's writhe by the same ``mu`` (turns; its linking taken as twist,
    less its own writhe) and a branch junction costs nothing, so ``Wr_i = (1 - P_b/C) ΔLk_i - n_i mu sign(ΔLk)``
    for ring i with ``n_i`` end loops on average. Two rings give ``P_b`` and ``mu``; with ``n_1 = n_2`` this is
    the pair formula. An estimate under that assumption (not tested against rings of known loops), used by
    the buckling check as a diagnostic only.

    Parameters
    ----------
    wr_1, dlk_1, loops_1, wr_2, dlk_2, loops_2 : float
        Mean writhe, linking difference relative to the relaxed twist at T (turns) and mean number of end loops
        (:func:`dnarod.workflows.protocols.measure.plectoneme_end_loops`) of each ring.
    C_nm : float
    wr_err_1, wr_err_2 : float
        Standard errors of the writhes (the loop counts are taken as exact).

    Returns
    -------
    tuple of float
        ``(P_b, standard_error, mu)``: nm, nm, turns per end loop.
    """
    s = np.sign(float(dlk_2))
    M = np.array([[float(dlk_1), -float(loops_1) * s], [float(dlk_2), -float(loops_2) * s]])
    if abs(np.linalg.det(M)) < 1e-9 * max(1.0, np.abs(M).max() ** 2):
        raise DnarodError("ring pair: the two rings have the same loops per linking difference; the loops and the "
                          "bulk cannot be separated")
    Minv = np.linalg.inv(M)
    f, mu = Minv @ np.array([float(wr_1), float(wr_2)])
    f_err = float(np.hypot(Minv[0, 0] * wr_err_1, Minv[0, 1] * wr_err_2))
    return float(C_nm) * (1.0 - f), float(C_nm) * f_err, float(mu)
