"""Derivation of the ``dna-default`` parameter set from cited physical targets.

The numbers in ``forcefields/dna-default.toml`` are produced by :func:`derive` and a test
re-derives them. Targets (sources in ``data/physical/dna_elasticity_reference_values.csv``):

* helical repeat 10.5 bp/turn and rise 0.34 nm per bp;
* bending persistence length 50 nm **as measured in the discrete model**: ``-ds/ln<R33>``
  with the exact Haar-weighted step density (docs/formulation.md §8), solved for A1;
* torsional persistence length 100 nm: effective twist modulus ``A3 sec^4(theta0/2)`` =
  100 nm kT (the Cayley chart's Jacobian at the intrinsic twist, docs/formulation.md §2);
* twist-stretch coupling g = -90 pN nm in angle coordinates: ``B33 = g cos^2(theta0/2)``;
* stretch modulus 1100 pN with twist free: ``C3 - B33^2/A3 = 1100 pN``;
* shear stiffness from Olson et al. (1998) PNAS 95:11163: the mean over the 16 step types
  of the marginal shift and slide stiffnesses ``1/(F^-1)_ii`` (kT/Angstrom^2), converted
  as ``C1 = C2 = 100 ds kT <F>``;
* node: 650 amu per base pair (sodium salt, about 650 Da/bp); inertia of the rigid
  equilateral triangle used by the OpenMM engine with circumradius 0.6 nm
  (``J = m l^2 (1/2, 1/2, 1)``), close to a 2.0 x 0.5 nm slab of 650 amu about the helix
  axis (230 amu nm^2).
"""
from __future__ import annotations

import csv

import numpy as np
from scipy.optimize import brentq

from dnarod.core.forcefield import data_dir
from dnarod.core.parameters import StepParameters
from dnarod.physics.thermal import persistence_length
from dnarod.core.units import kT as kT_of
from dnarod.core.units import PN

TARGETS = dict(
    temperature=300.0, bp_per_turn=10.5, rise=0.34, bending_persistence=50.0, torsional_persistence=100.0,
    stretch_modulus_pN=1100.0, twist_stretch_pN_nm=-90.0, node_mass=650.0, triangle_radius=0.6,
)


def olson_mean_shear_stiffness():
    """Mean marginal shift/slide stiffness of Olson 1998 (16 steps), kT/Angstrom^2."""
    order = ["shift", "slide", "rise", "tilt", "roll", "twist"]
    mats = {}
    with open(data_dir() / "elastic" / "olson1998" / "olson1998_pdna_force_constants_16.csv", newline="") as fh:
        for row in csv.DictReader(fh):
            mats.setdefault(row["step"], np.zeros((6, 6)))[order.index(row["row"])] = [float(row[c]) for c in order]
    vals = [1.0 / np.diag(np.linalg.inv(F))[:2] for F in mats.values()]
    return float(np.mean(vals))


def derive(targets=TARGETS):
    """Compute the dna-default numbers.

    Returns
    -------
    dict
        ``ds`` (nm), ``Omega0`` (1/nm), ``Gamma0``, ``A`` (kJ/mol nm), ``B`` (kJ/mol),
        ``C`` (kJ/mol/nm), ``mass`` (amu), ``inertia`` (amu nm^2).
    """
    t = targets
    kt = kT_of(t["temperature"])
    ds = t["rise"]
    theta0 = 2 * np.pi / t["bp_per_turn"]
    c2 = np.cos(theta0 / 2) ** 2
    Omega0 = np.array([0.0, 0.0, 2.0 / ds * np.tan(theta0 / 2)])
    Gamma0 = np.array([0.0, 0.0, 1.0])
    A3 = t["torsional_persistence"] * kt * c2**2
    B33 = t["twist_stretch_pN_nm"] * PN * c2
    C3 = t["stretch_modulus_pN"] * PN + B33**2 / A3
    C1 = 100.0 * ds * kt * olson_mean_shear_stiffness()

    def stiffness(A1):
        K = np.diag([A1, A1, A3, C1, C1, C3])
        K[2, 5] = K[5, 2] = B33
        return K

    def lp_error(A1):
        p = StepParameters(stiffness(A1), np.concatenate([Omega0, Gamma0]))
        return persistence_length(p, ds, kt) - t["bending_persistence"]

    guess = t["bending_persistence"] * kt * c2
    A1 = brentq(lp_error, 0.5 * guess, 2.0 * guess, xtol=1e-12, rtol=1e-14)
    K = stiffness(A1)
    m, l = t["node_mass"], t["triangle_radius"]
    return dict(ds=ds, Omega0=Omega0, Gamma0=Gamma0, A=K[:3, :3], B=K[:3, 3:], C=K[3:, 3:],
                mass=m, inertia=m * l**2 * np.array([0.5, 0.5, 1.0]))
