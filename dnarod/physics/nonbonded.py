"""Non-local terms between base pairs far apart along the chain: excluded volume and screened
electrostatics, one interaction site per node (its centre).

* **Excluded volume**: WCA (purely repulsive Lennard-Jones cut at its minimum and shifted),
  ``4 eps [(sigma/r)^12 - (sigma/r)^6] + eps`` for ``r < 2^(1/6) sigma``, ``eps = kT``.
  Default ``sigma = 2.0 nm``, the geometric diameter of B-DNA: 20-22 Angstrom in the table of DNA structural
  parameters at grupo.us.es (citing Dickerson 1992 and Saenger 1984, *Principles of Nucleic Acid Structure*),
  "about 20 Angstrom" in the NCI thesaurus (secondary sources; Saenger's book itself was not read;
  ``data/experimental/dna_diameter.csv``). Not fitted.
* **Electrostatics**: Debye-Hueckel, ``q^2 (e^2/4 pi eps0 eps_r) exp(-r/lambda_D)/r`` between node charges q,
  shifted to zero at the cutoff (default ``DEFAULT_CUTOFF_DEBYE = 12`` Debye lengths); ``eps_r = 78.5`` (water,
  25 C; a textbook value, not re-read); ``lambda_D = 1/sqrt(8 pi l_B N_A I)`` for monovalent salt of ionic
  strength I (mol/L), with the Bjerrum length ``l_B = e^2/(4 pi eps0 eps_r kT)`` (0.71 nm at 300 K, 0.79 nm
  Debye length at 150 mM).
* **Charge: calibrated to the effective diameter** (``charge="calibrated"``, the default). The node charge is
  ``q = nu * ds`` with ``nu`` the far-field line charge of a Poisson-Boltzmann cylinder
  (:func:`pb_far_field_line_charge`: bare charge 2 e per 0.34 nm, radius ``CALIBRATED_RADIUS`` = 1.159 nm,
  monovalent salt; the potential far outside is that of a Debye-Hueckel line charge ``nu`` on the axis, as in
  Stigter's treatment). This is a Stigter-type effective charge, larger than Manning's and salt dependent: the
  screened field of a thick cylinder decays from its surface, so the equivalent axis charge grows as the
  Debye length shrinks. **Calibrated to**: the model's second-virial effective diameter (:func:`effective_diameter`:
  hard rods with the same second virial coefficient as this WCA + shifted Debye-Hueckel pair energy, at the
  default cutoff) is **5.0 nm at 0.15 M, 300 K** with ``nu = CALIBRATED_LINE_CHARGE`` = 8.86 e/nm (3.01 e per bp;
  :func:`calibrated_line_charge`), and the radius is the one whose far-field charge is that at 0.15 M
  (:func:`calibrated_radius`; 1.0 and 1.2 nm give 7.20 and 9.34 e/nm). The 5.0 nm is the hard-cylinder diameter
  "d = 50 A [that] yields the same second virial coefficient as the electrostatic potential obtained by numerical
  solution of the Poisson-Boltzmann equation for 150 mM salt" (Gebe, Allison, Clendenning & Schurr 1995,
  Biophys. J. 68:619-633, doi:10.1016/S0006-3495(95)80223-7, abstract; a computed value, not a measurement),
  the only effective diameter read in a stored source: the measured knotting diameters of Rybenkov, Cozzarelli &
  Vologodskii (1993) and Shaw & Wang (1993) and Stigter's (1977) tabulated values could not be read (the 1997
  NAR abstract of Rybenkov, Vologodskii & Cozzarelli says only that d was determined from knotting probabilities
  under all its ionic conditions). **Predictions**, checked against nothing read: the diameter at other salts
  (README "What is calibrated to what"). One constant charge does not carry across salts: the Poisson-Boltzmann
  charge of the same cylinder is 4.6 / 6.7 / 8.9 / 11.1 / 29 e/nm at 0.05 / 0.1 / 0.15 / 0.2 / 0.5 M, so a
  constant 8.86 e/nm would overstate the diameter at low salt and understate it at high salt (README). Above
  about 1 M the far-field charge grows as ``exp(kappa a)`` (28 e per bp at 1 M, 126 at 2 M): the axis charges
  then act as a soft core at the cylinder's surface (the Debye-Hueckel form is not meant for ``r < a``); runs
  above 1 M were not tested.
  Truncation: at 2.9 e per bp and 0.15 M the diameter is 4.55 / 4.85 / 4.94 / 4.97 nm with cutoffs of 8 / 10 /
  12 / 15 Debye lengths, so the default 12 lies about 0.03-0.04 nm (under 1 %) below the untruncated potential's
  value; the old 5 Debye lengths (a 4.0 nm cutoff at 0.15 M) cannot reach the 5.0 nm target at any charge. The
  calibration is made at the default cutoff, so the truncated model is the one that reproduces 5.0 nm.
* **Charge: Manning** (``charge="manning"``, the default before calibration). Counter-ion condensation
  renormalises the line charge to one elementary charge per Bjerrum length, ``q = ds / l_B`` e per bp (0.48 e
  at 300 K): with charge spacing b = 0.17 nm (two phosphates per 0.34 nm; "for double-stranded DNA, b = 1.7
  A" in a lecture on Manning's theory that cites G. S. Manning, "The molecular theory of polyelectrolyte
  solutions with applications to the electrostatic properties of polynucleotides", Q. Rev. Biophys.
  11:179-246, 1978, read 2026-12 at slideorbit.com; the paper itself was not read) and Manning parameter
  ``xi = l_B / b > 1`` a fraction ``1 - 1/xi`` of the counter-ions condenses (checked against secondary
  sources), leaving ``2/xi = ds / l_B`` e per bp. Its effective diameter is 2.31 nm at 0.15 M with a
  5 Debye-length cutoff (2.52 nm with 12): less than half the Poisson-Boltzmann value. Manning's charge is what
  remains after condensation, not the amplitude of the screened far field of a 2-nm-thick cylinder, which is
  what sets the excluded volume of crossing segments.
* **Exclusions along the chain**: pairs ``|i - j| <= n_exclude`` (chain distance, circular
  chains wrap) do not interact; by default ``n_exclude = ceil(cutoff / ds)``, so nodes that
  are within the cutoff in a straight duplex never interact: their interactions are already
  in the elastic parameters, which are fitted to measured (salt-screened) stiffnesses.

The OpenMM engine's force (a numba Verlet list through ``openmm.PythonForce``) is
:mod:`dnarod.engines.openmm.nonbonded`.
"""
from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numba
import numpy as np

from dnarod.core.errors import ParameterError, DnarodError
from dnarod.core.units import kT as kT_of

ONE_4PI_EPS0 = 138.935457833  # kJ/mol nm / e^2


AVOGADRO_PER_NM3_PER_M = 0.602214076  # (1 mol/L) in 1/nm^3


#: Verlet-list skin, nm: a thermal node (dna-default, 300 K, friction 1/ps) moves skin/2 = 0.5 nm
#: in roughly 10^2 steps, while the list grows by ((rc + skin)/rc)^3 ~ 1.35x at 150 mM (12 Debye lengths).
DEFAULT_SKIN = 1.0


#: Default Debye-Hueckel cutoff, Debye lengths: truncates the calibrated effective diameter by ~1 % (module docstring).
DEFAULT_CUTOFF_DEBYE = 12.0


#: Longest accepted Debye-Hueckel cutoff, Debye lengths: the screened repulsion there is e^-50 = 2e-22 of its value
#: at one Debye length, so a longer cutoff changes nothing but the cost (1e300 overflowed OpenMM's neighbour grid).
MAX_CUTOFF_DEBYE = 50.0


#: Calibrated effective line charge at the calibration salt, e/nm: with node charges ``CALIBRATED_LINE_CHARGE * ds``
#: the model's second-virial effective diameter (:func:`effective_diameter`, WCA sigma 2 nm, cutoff
#: ``DEFAULT_CUTOFF_DEBYE``) is ``CALIBRATION["diameter_nm"]`` at ``CALIBRATION["salt_M"]`` and
#: ``CALIBRATION["temperature_K"]`` (:func:`calibrated_line_charge` recomputes it). At other salts the default
#: charge follows the Poisson-Boltzmann far field of a cylinder of radius ``CALIBRATED_RADIUS``.
CALIBRATED_LINE_CHARGE = 8.86


#: What the calibrated charge reproduces (Gebe et al. 1995, Biophys. J. 68:619, abstract: a Poisson-Boltzmann
#: second-virial hard-cylinder diameter, computed, not measured; ``data/experimental/dna_diameter.csv``).
CALIBRATION = dict(diameter_nm=5.0, salt_M=0.15, temperature_K=300.0, ds_nm=0.34, sigma_nm=2.0,
                   cutoff_debye=DEFAULT_CUTOFF_DEBYE)


#: Named charge models accepted by ``NonbondedSettings.charge``.
CHARGE_MODELS = ("calibrated", "manning")


#: The default charge model.
DEFAULT_CHARGE = "calibrated"


#: Bare line charge of B-DNA, e/nm: two phosphates per 0.34-nm base pair (b = 0.17 nm).
BARE_LINE_CHARGE = 2.0 / 0.34


#: Radius of the Poisson-Boltzmann cylinder whose far field gives the default node charges, nm: chosen so that its
#: far-field line charge at ``CALIBRATION`` is ``CALIBRATED_LINE_CHARGE`` (:func:`calibrated_radius`).
CALIBRATED_RADIUS = 1.159


#: Temperature (K) that sets the non-bonded energy scales (the WCA kT, the Bjerrum length) of a run at 0 K (started at
#: rest, or NVE): the potential must not depend on how a run starts, so 0 K means these scales at 300 K.
NONBONDED_REFERENCE_T = 300.0


def scales_temperature(temperature):
    """The temperature (K) the non-bonded terms are evaluated at: the run's, or :data:`NONBONDED_REFERENCE_T` at 0 K
    (the one place this rule is written)."""
    return float(temperature) if temperature and float(temperature) > 0 else NONBONDED_REFERENCE_T


@dataclass
class NonbondedSettings:
    """Settings of the non-local terms.

    Parameters
    ----------
    excluded_volume : bool
        WCA repulsion between node centres.
    electrostatics : bool
        Debye-Hueckel repulsion.
    diameter : float
        WCA sigma, nm.
    salt : float
        Monovalent salt concentration (ionic strength), mol/L.
    charge : {"calibrated", "manning"} or float
        Effective charge per node (base pair), e: ``"calibrated"`` (default) ``ds`` times the Poisson-Boltzmann
        far-field line charge of a cylinder of radius ``CALIBRATED_RADIUS`` at this salt and temperature, with
        which the model's effective diameter is the Poisson-Boltzmann second-virial diameter, 5.0 nm, at 0.15 M
        (module docstring); ``"manning"`` Manning's ``ds / l_B`` (``None`` is read as ``"manning"``, its old
        meaning); a number is used as given at every salt.
    dielectric : float
        Relative permittivity of the solvent.
    cutoff_debye : float
        Debye-Hueckel cutoff in Debye lengths.
    n_exclude : int or None
        Chain-distance exclusion; ``None`` for ``ceil(cutoff / ds)``.
    skin : float
        Verlet-list skin, nm (the list is rebuilt when a node has moved ``skin / 2``; ``0``
        rebuilds it at every evaluation).
    """

    excluded_volume: bool = True
    electrostatics: bool = True
    diameter: float = 2.0
    salt: float = 0.15
    charge: float | str | None = DEFAULT_CHARGE
    dielectric: float = 78.5
    cutoff_debye: float = DEFAULT_CUTOFF_DEBYE
    n_exclude: int | None = None
    skin: float = DEFAULT_SKIN

    @property
    def active(self):
        """Whether any non-bonded term is on (both off: a bare chain, no non-bonded force at all)."""
        return bool(self.excluded_volume or self.electrostatics)

    def resolve(self, ds, temperature):
        """Numbers used by the kernel: dict of eps, sigma, wca cutoff, DH prefactor, kappa, cutoffs."""
        for name in ("diameter", "salt", "dielectric", "cutoff_debye"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ParameterError(f"nonbonded {name} must be positive and finite, got {v}")
        if not (np.isfinite(self.skin) and self.skin >= 0):
            raise ParameterError(f"nonbonded skin must be >= 0 nm and finite, got {self.skin}")
        kt = kT_of(temperature)
        lB = ONE_4PI_EPS0 / (self.dielectric * kt)
        kappa = 1.0 / debye_length(self.salt, temperature, self.dielectric)
        q, model = _node_charge(self.charge, ds, lB, float(self.salt), float(temperature), float(self.dielectric))
        rc_dh = self.cutoff_debye / kappa if self.electrostatics else 0.0
        rc_wca = 2 ** (1 / 6) * self.diameter if self.excluded_volume else 0.0
        cutoff = max(rc_dh, rc_wca)
        # both terms off (a bare chain): nothing interacts, the exclusion is only a number (neighbours are bonded)
        n_ex = (max(int(math.ceil(cutoff / ds)), 1) if self.n_exclude is None else int(self.n_exclude)) if \
            self.active else max(1 if self.n_exclude is None else int(self.n_exclude), 1)
        if n_ex < 1:
            raise ParameterError(f"n_exclude must be at least 1 (neighbours are bonded), got {n_ex}")
        return dict(eps=kt if self.excluded_volume else 0.0, sigma=self.diameter, rc_wca=rc_wca,
                    a_dh=(ONE_4PI_EPS0 / self.dielectric * q * q) if self.electrostatics else 0.0,
                    kappa=kappa, rc_dh=rc_dh, cutoff=cutoff, n_exclude=n_ex, bjerrum=lB,
                    debye_length=1 / kappa, charge=q, charge_model=model, skin=float(self.skin))


def member_nonbonded(settings):
    """The :class:`NonbondedSettings` of a protocol member's settings (keys ``excluded_volume``,
    ``electrostatics``, ``salt_M``, ``charge``, ``cutoff_debye``), checked before anything runs.

    The charge model and the cutoff are settings of the member, so a member folder recorded with other non-bonded
    terms is not taken for this one (the member's cache key is its settings)."""
    nb = NonbondedSettings(excluded_volume=bool(settings["excluded_volume"]),
                           electrostatics=bool(settings["electrostatics"]), salt=float(settings["salt_M"]),
                           charge=settings.get("charge", DEFAULT_CHARGE),
                           cutoff_debye=float(settings.get("cutoff_debye", DEFAULT_CUTOFF_DEBYE)))
    # refuses an unknown charge model or a bad number (the calibrated charge at the calibration point is cached)
    _node_charge(nb.charge, CALIBRATION["ds_nm"], 1.0, CALIBRATION["salt_M"], CALIBRATION["temperature_K"],
                 nb.dielectric)
    check_cutoff_debye(nb.cutoff_debye)
    check_cutoff_holds_contact(nb, float(settings.get("temperature_K", CALIBRATION["temperature_K"])))
    return nb


def check_cutoff_debye(cutoff_debye):
    """Refuse (:class:`ParameterError`, one line starting ``cutoff_debye X:``) a Debye-Hueckel cutoff that is not a
    finite number of Debye lengths in ``(0, MAX_CUTOFF_DEBYE]``."""
    x = float(cutoff_debye)
    if not (math.isfinite(x) and x > 0):
        raise ParameterError(f"cutoff_debye {cutoff_debye}: give a positive, finite number of Debye lengths "
                             f"(default {DEFAULT_CUTOFF_DEBYE:g})")
    if x > MAX_CUTOFF_DEBYE:
        raise ParameterError(f"cutoff_debye {x:g}: more than {MAX_CUTOFF_DEBYE:g} Debye lengths, beyond which the "
                             f"screened repulsion is below e^-{MAX_CUTOFF_DEBYE:g} of its value at one Debye length; a "
                             f"longer cutoff changes nothing but the cost (default {DEFAULT_CUTOFF_DEBYE:g})")


def nonbonded_options(charge, cutoff_debye, salt_M, temperature_K):
    """The command-line options ``--charge`` / ``--cutoff-debye`` as settings (only those given), checked before
    anything runs, with one-line messages in the options' names; the one check of both ``dnarod simulate`` and
    ``dnarod protocol``.

    Parameters
    ----------
    charge : str or None
        A name of :data:`CHARGE_MODELS` (any case).
    cutoff_debye : float or None
        Debye lengths, > 0; must reach past the excluded-volume contact (:func:`check_cutoff_holds_contact`).
    salt_M, temperature_K : float
        mol/L and K of the run (other values than 0 < salt <= 6 M, T > 0 are refused by their own options).

    Returns
    -------
    dict
        ``charge`` (lower case) and/or ``cutoff_debye`` (float), those given.

    Raises
    ------
    DnarodError
    """
    out = {}
    if charge is not None:
        name = str(charge).strip().lower()
        if name not in CHARGE_MODELS:
            raise DnarodError(f"--charge {charge!r}: choose calibrated (Poisson-Boltzmann far-field charge, the "
                              f"default) or manning (0.48 e/bp)")
        out["charge"] = name
    if cutoff_debye is not None:
        try:
            check_cutoff_debye(cutoff_debye)
            if 0 < salt_M <= 6.0 and temperature_K > 0:  # other salts and temperatures are refused by their options
                check_cutoff_holds_contact(NonbondedSettings(salt=salt_M, cutoff_debye=cutoff_debye), temperature_K)
        except DnarodError as exc:
            raise DnarodError(f"--{exc}".replace("cutoff_debye", "cutoff-debye", 1)) from None
        out["cutoff_debye"] = float(cutoff_debye)
    return out


def check_cutoff_holds_contact(nb, temperature):
    """Refuse (:class:`ParameterError`, one line) a Debye-Hueckel cutoff that ends inside the excluded-volume
    contact (the WCA range ``2^(1/6) sigma``, 2.24 nm by default): the screened repulsion would then act only where
    the cores already overlap, i.e. never. Not refused where the contact lies beyond ``DEFAULT_CUTOFF_DEBYE`` Debye
    lengths (high salt): the repulsion is negligible there whatever the cut-off.
    ``nb``: :class:`NonbondedSettings`; ``temperature`` K."""
    if not (nb.electrostatics and nb.excluded_volume):
        return
    if not (np.isfinite(nb.salt) and nb.salt > 0 and np.isfinite(nb.dielectric) and nb.dielectric > 0
            and temperature > 0):
        return  # resolve() names these
    lam = debye_length(nb.salt, temperature, nb.dielectric)
    contact = 2 ** (1 / 6) * float(nb.diameter)
    # at high salt the contact lies beyond the default reach (12 Debye lengths, above ~2.7 M at 0.15-M defaults):
    # the screened repulsion there is below e^-12 of its contact value and the cut-off changes nothing
    if nb.cutoff_debye * lam <= contact and contact / lam < DEFAULT_CUTOFF_DEBYE:
        raise ParameterError(f"cutoff_debye {nb.cutoff_debye:g}: {nb.cutoff_debye:g} Debye lengths are "
                             f"{nb.cutoff_debye * lam:.2f} nm at {nb.salt:g} M, inside the {contact:.2f}-nm contact "
                             f"of the excluded-volume core, so the electrostatics would act only where the cores "
                             f"already repel; give more than "
                             f"{contact / lam:.2f} (default {DEFAULT_CUTOFF_DEBYE:g})")


def debye_length(salt_M, temperature, dielectric=78.5):
    """Debye length (nm) of monovalent salt ``salt_M`` (mol/L) at ``temperature`` (K) in a medium of relative
    permittivity ``dielectric``: ``1/sqrt(8 pi l_B N_A c)``; the one place it is computed."""
    lB = ONE_4PI_EPS0 / (dielectric * kT_of(temperature))
    return 1.0 / math.sqrt(8 * math.pi * lB * AVOGADRO_PER_NM3_PER_M * salt_M)


def nonbonded_record(settings, ds, temperature):
    """What a run or member records of its non-bonded terms (JSON-safe dict; ``None`` when both are off).

    Parameters
    ----------
    settings : NonbondedSettings or None or False
    ds : float
        nm per node.
    temperature : float
        K.

    Returns
    -------
    dict or None
        ``excluded_volume``, ``electrostatics``, ``salt_mol_L``, ``wca_sigma_nm``, ``charge_model``
        (``"calibrated"``, ``"manning"`` or ``"explicit"`` for a number), ``charge_e_per_node``, ``cutoff_debye``,
        ``cutoff_nm``, ``debye_length_nm`` and ``n_exclude`` (nodes); the charge entries are ``None`` without
        electrostatics.
    """
    if not settings or not (settings.excluded_volume or settings.electrostatics):
        return None
    nb = settings.resolve(ds, temperature)
    es = bool(settings.electrostatics)
    return dict(excluded_volume=bool(settings.excluded_volume), electrostatics=es, salt_mol_L=float(settings.salt),
                wca_sigma_nm=float(settings.diameter) if settings.excluded_volume else None,
                charge_model=nb["charge_model"] if es else None, charge_e_per_node=float(nb["charge"]) if es else None,
                cutoff_debye=float(settings.cutoff_debye) if es else None, cutoff_nm=float(nb["rc_dh"]) if es else None,
                debye_length_nm=float(nb["debye_length"]), n_exclude=int(nb["n_exclude"]))


def _node_charge(charge, ds, lB, salt, temperature, dielectric):
    """``(q e per node, charge-model name)`` for ``NonbondedSettings.charge`` (see there)."""
    if charge is None or (isinstance(charge, str) and charge.strip().lower() == "manning"):
        return ds / lB, "manning"
    if isinstance(charge, str):
        if charge.strip().lower() == "calibrated":
            return pb_far_field_line_charge(salt, temperature, dielectric=dielectric) * ds, "calibrated"
        raise ParameterError(f"nonbonded charge must be one of {', '.join(CHARGE_MODELS)} or a number of "
                             f"elementary charges per base pair, got {charge!r}")
    try:
        q = float(charge)
    except (TypeError, ValueError):
        raise ParameterError(f"nonbonded charge must be one of {', '.join(CHARGE_MODELS)} or a number of "
                             f"elementary charges per base pair, got {charge!r}") from None
    if not (np.isfinite(q) and q >= 0):
        raise ParameterError(f"nonbonded charge must be a finite number >= 0 e per base pair, got {charge!r}")
    return q, "explicit"


@functools.lru_cache(maxsize=512)
def pb_far_field_line_charge(salt_M, temperature, radius=CALIBRATED_RADIUS, dielectric=78.5, bare=BARE_LINE_CHARGE):
    """Far-field line charge (e/nm) of a charged cylinder in monovalent salt, from the nonlinear Poisson-Boltzmann
    equation: the ``nu`` with which the reduced potential far from the cylinder is ``2 l_B nu K0(kappa r)``, the
    potential of a Debye-Hueckel line charge ``nu`` on the axis (Stigter's way of carrying the Poisson-Boltzmann
    field into a Debye-Hueckel pair energy).

    Solves ``(1/r) d/dr (r dphi/dr) = kappa^2 sinh(phi)`` (phi = e psi / kT, the sign of the charge taken
    positive) for ``r > radius`` with Gauss's law at the surface, ``dphi/dr = -2 l_B bare / radius``, and
    ``phi = 0`` at ``radius + 25 lambda_D`` (scipy ``solve_bvp`` in ``log r``), and reads ``nu`` at
    ``radius + 5 lambda_D``. Written here because no maintained library solves the cylindrical PB cell; tested
    against the linearised limit ``nu = bare / (kappa a K1(kappa a))``. Results are cached.

    Parameters
    ----------
    salt_M : float
        Monovalent salt, mol/L.
    temperature : float
        K.
    radius : float
        Cylinder radius, nm.
    dielectric : float
        Relative permittivity.
    bare : float
        Bare line charge, e/nm.

    Returns
    -------
    float
        e/nm.
    """
    from scipy.integrate import solve_bvp
    from scipy.special import k0, k1

    if not (salt_M > 0 and temperature > 0 and radius > 0 and dielectric > 0 and bare >= 0):
        raise ParameterError(f"Poisson-Boltzmann charge needs positive salt, temperature, radius and dielectric, got "
                             f"{salt_M} M, {temperature} K, {radius} nm, {dielectric}")
    lB = ONE_4PI_EPS0 / (dielectric * kT_of(temperature))
    kap = 1.0 / debye_length(salt_M, temperature, dielectric)
    if bare == 0:
        return 0.0
    a = float(radius)
    x = np.linspace(math.log(a), math.log(a + 25.0 / kap), 3000)

    def rhs(x, y):
        r = np.exp(x)
        return np.vstack([y[1], kap * kap * r * r * np.sinh(y[0])])

    def bc(ya, yb):
        return np.array([ya[1] + 2.0 * lB * bare, yb[0]])

    lin = 2.0 * lB * bare * k0(kap * np.exp(x)) / (kap * a * k1(kap * a))
    y0 = np.vstack([np.minimum(lin, 10.0), -2.0 * lB * bare * np.ones_like(x)])
    sol = solve_bvp(rhs, bc, x, y0, tol=1e-8, max_nodes=500000)
    if sol.status != 0:
        raise ParameterError(f"Poisson-Boltzmann cylinder did not converge at {salt_M} M, {temperature} K "
                             f"({sol.message}); give the non-bonded charge as a number")
    r = a + 5.0 / kap
    return float(sol.sol(math.log(r))[0] / (2.0 * lB * k0(kap * r)))


def calibrated_radius(line_charge=CALIBRATED_LINE_CHARGE, salt_M=CALIBRATION["salt_M"],
                      temperature=CALIBRATION["temperature_K"]):
    """The cylinder radius (nm) whose Poisson-Boltzmann far-field line charge (:func:`pb_far_field_line_charge`)
    is ``line_charge`` (e/nm) at ``salt_M`` and ``temperature`` (bisection on 0.5-2 nm)."""
    from scipy.optimize import brentq

    def f(a):
        return math.log(pb_far_field_line_charge(salt_M, temperature, radius=a)) - math.log(line_charge)
    return float(brentq(f, 0.5, 2.0, xtol=1e-5))


@numba.njit(cache=True)
def _separation(i, j, n, circular):
    sep = j - i if j > i else i - j
    if circular and n - sep < sep:
        sep = n - sep
    return sep


def pair_energy(r, numbers):
    """WCA + shifted Debye-Hueckel energy (kJ/mol) of node pairs at distances ``r`` (nm, any shape), with the
    numbers of :meth:`NonbondedSettings.resolve` (the same terms as
    :func:`dnarod.engines.openmm.nonbonded.pair_kernel`)."""
    r = np.asarray(r, float)
    eps, sig, kap, rc = numbers["eps"], numbers["sigma"], numbers["kappa"], numbers["rc_dh"]
    with np.errstate(over="ignore", divide="ignore", invalid="ignore"):
        s6 = (sig / r) ** 6
        e = np.where(r < numbers["rc_wca"], 4 * eps * (s6 * s6 - s6) + eps, 0.0)
        shift = numbers["a_dh"] * np.exp(-kap * rc) / rc if rc > 0 else 0.0
        e = e + np.where(r < rc, numbers["a_dh"] * np.exp(-kap * r) / r - shift, 0.0)
    return e


def crossing_diameter(numbers, ds, gamma, kt, n_phase, h):
    """Excluded half-width (nm) of two straight site chains crossing at angle ``gamma`` (rad):
    ``<integral_0^h_max (1 - exp(-U(h)/kT)) dh>`` over the sites' offsets (``n_phase`` per chain), U summed over
    all site pairs with :func:`pair_energy`; ``h`` (nm) is the grid, from 0 to at least the cutoff. Hard rods of
    diameter d give d. Used by :func:`effective_diameter`."""
    rc = numbers["cutoff"]
    sg, cg = np.sin(gamma), np.cos(gamma)
    n1 = int(np.ceil(rc / (ds * sg))) + 1
    phases = (np.arange(n_phase) + 0.5) / n_phase
    acc = 0.0
    for p1 in phases:
        s1 = (np.arange(-n1, n1 + 1) + p1) * ds
        for p2 in phases:
            # sites of chain 2 within rc (in the plane) of site s1 of chain 1 have |s2 - s1 cos g| < rc
            lo = np.floor((s1 * cg - rc) / ds - p2).astype(int)
            cnt = np.ceil((s1 * cg + rc) / ds - p2).astype(int) - lo + 1
            j = np.repeat(lo - np.cumsum(cnt) + cnt, cnt) + np.arange(cnt.sum())
            s2 = (j + p2) * ds
            d2 = (np.repeat(s1, cnt) - s2 * cg) ** 2 + (s2 * sg) ** 2
            d2 = d2[d2 < rc * rc]
            U = np.zeros(h.size)
            for c0 in range(0, d2.size, 20000):
                U += pair_energy(np.sqrt(h[:, None] ** 2 + d2[None, c0:c0 + 20000]), numbers).sum(axis=1)
            acc += np.trapezoid(-np.expm1(-U / kt), h)
    return acc / n_phase ** 2


def effective_diameter(settings, ds, temperature, n_angles=24, n_phase=3, n_h=400, gamma_min=0.05):
    """The model's effective diameter (nm): the diameter of hard rods with the same second virial coefficient.

    Two long straight chains of interaction sites (spacing ``ds`` nm) cross at angle gamma with closest
    distance h; their excluded volume per length squared is ``sin(gamma) <integral (1 - exp(-U(h)/kT)) dh>``
    (U: the summed :func:`pair_energy` of all site pairs; the average runs over the sites' offsets along both
    chains), which for hard rods of diameter d is ``2 d sin(gamma)``. Averaging over isotropic orientations
    (weight ``sin(gamma)``) gives ``d_eff = int sin^2(g) d(g) dg / int sin^2(g) dg`` on ``(0, pi/2)``. This is the
    definition behind the "effective diameter" of charged DNA (the salt-dependent excluded diameter that knotting
    and catenation experiments are interpreted with, and of the Poisson-Boltzmann hard cylinder the default charge
    is calibrated to: 5.0 nm at 0.15 M); it is computed here for the model's own potential. Angles below ``gamma_min``
    (where the pair count grows as 1/sin(gamma)) take ``d(gamma_min)``; their weight is ``gamma_min^3/3`` of ``pi/4``
    (5e-5 for 0.05 rad).

    Parameters
    ----------
    settings : NonbondedSettings
    ds : float
        Site spacing along the chain, nm (0.34 for ``dna-default``).
    temperature : float
        K.
    n_angles, n_phase, n_h, gamma_min : int, int, int, float
        Gauss-Legendre points in gamma on ``(gamma_min, pi/2)``, site offsets per chain, points in h on
        ``[0, cutoff]``, smallest angle (rad).

    Returns
    -------
    float
        Effective diameter, nm.
    """
    nb = settings.resolve(ds, temperature)
    kt = kT_of(temperature)
    rc = nb["cutoff"]
    if rc <= 0:
        return 0.0
    x, w = np.polynomial.legendre.leggauss(n_angles)
    gam = gamma_min + (x + 1.0) * (np.pi / 2 - gamma_min) / 2.0
    wg = w * (np.pi / 2 - gamma_min) / 2.0
    h = np.linspace(0.0, rc, n_h)
    d = np.array([crossing_diameter(nb, ds, g, kt, n_phase, h) for g in gam])
    s2w = np.sin(gam) ** 2
    small = (gamma_min - np.sin(2 * gamma_min) / 2) / 2  # int_0^gamma_min sin^2
    return float((np.sum(wg * s2w * d) + small * d[0]) / (np.sum(wg * s2w) + small))


def nonbonded_reference(centres, circular, numbers):
    """All-pairs numpy evaluation of the same terms (for tests): ``(E_wca, E_dh, F)``."""
    c = np.asarray(centres, float)
    n = c.shape[0]
    i, j = np.triu_indices(n, 1)
    sep = j - i
    if circular:
        sep = np.minimum(sep, n - sep)
    keep = sep > numbers["n_exclude"]
    i, j = i[keep], j[keep]
    rv = c[j] - c[i]
    r = np.linalg.norm(rv, axis=1)
    eps, sig, kap = numbers["eps"], numbers["sigma"], numbers["kappa"]
    w = r < numbers["rc_wca"]
    s6 = (sig / r) ** 6
    ewca = np.where(w, 4 * eps * (s6**2 - s6) + eps, 0.0)
    fw = np.where(w, 24 * eps * (2 * s6**2 - s6) / r, 0.0)
    rc = numbers["rc_dh"]
    d = r < rc
    ex = numbers["a_dh"] * np.exp(-kap * r) / r
    shift = numbers["a_dh"] * np.exp(-kap * rc) / rc if rc > 0 else 0.0
    edh = np.where(d, ex - shift, 0.0)
    fd = np.where(d, ex * (kap + 1 / r), 0.0)
    g = ((fw + fd) / r)[:, None] * rv
    F = np.zeros((n, 3))
    np.add.at(F, i, -g)
    np.add.at(F, j, g)
    return float(ewca.sum()), float(edh.sum()), F


def calibrated_line_charge(diameter_nm=CALIBRATION["diameter_nm"], salt_M=CALIBRATION["salt_M"],
                           temperature=CALIBRATION["temperature_K"], ds=CALIBRATION["ds_nm"],
                           sigma=CALIBRATION["sigma_nm"], cutoff_debye=CALIBRATION["cutoff_debye"], tol_nm=1e-3,
                           **quadrature):
    """The line charge (e/nm) with which :func:`effective_diameter` is ``diameter_nm`` at ``salt_M``.

    The diameter grows by about one Debye length per e-fold of the charge squared (the far field of a screened
    line charge), so the root is found by the secant method in ``log(charge)`` from Manning's charge and twice it
    (a few evaluations of :func:`effective_diameter`, each tens of CPU seconds at 0.15 M).

    Parameters
    ----------
    diameter_nm, salt_M, temperature, ds, sigma, cutoff_debye : float
        Target diameter (nm), salt (mol/L), K, site spacing (nm), WCA sigma (nm), cutoff (Debye lengths).
    tol_nm : float
        Stop when the diameter is within this of the target, nm.
    **quadrature
        Passed to :func:`effective_diameter`.

    Returns
    -------
    float
        e/nm (the node charge is this times ``ds``).
    """
    def d_of(log_nu):
        st = NonbondedSettings(salt=salt_M, diameter=sigma, cutoff_debye=cutoff_debye,
                               charge=float(np.exp(log_nu)) * ds)
        return effective_diameter(st, ds, temperature, **quadrature) - diameter_nm

    lB = ONE_4PI_EPS0 / (NonbondedSettings().dielectric * kT_of(temperature))
    x0, x1 = math.log(1.0 / lB), math.log(2.0 / lB)
    f0, f1 = d_of(x0), d_of(x1)
    for _ in range(30):
        if abs(f1) <= tol_nm:
            return float(np.exp(x1))
        if f1 == f0:
            break
        x0, x1, f0 = x1, x1 - f1 * (x1 - x0) / (f1 - f0), f1
        f1 = d_of(x1)
    if abs(f1) <= tol_nm:
        return float(np.exp(x1))
    raise ParameterError(f"no line charge gives an effective diameter of {diameter_nm} nm at {salt_M} M "
                         f"(last miss {f1:+.3g} nm)")
