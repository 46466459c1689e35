"""Per-frame observables of tweezers chains and rings: extension, end rotation, clamp torque, Tw, Wr, Lk and a
plectoneme detector.

Conventions (open chains in tweezers): node 0 is fixed at the surface, the pulling force and the rotation
clamp act on the last node, both along the lab z axis.

* **Extension**: ``z_last - z_0``, nm.
* **End rotation** (turns): rotation of the last node's frame about z since the start, unwrapped between
  samples (samples must be closer than half a turn apart).
* **Clamp torque** (pN nm): the z component of the torque the rotation clamp ``E = k (1 - cos theta)``
  exerts on the last node, ``k sin(theta) n_z`` (theta, n: angle and axis of the rotation from the node's
  frame to the clamp target). In equilibrium its mean is the torque the DNA exerts on the bead.
* **Tw, Wr, Lk** (turns) of an open chain closed along z: :func:`dnarod.physics.observables.twist_writhe_open`
  (the one home of Tw, Wr and Lk and their end closure). ``Lk - Lk0`` is the number of turns applied.
* **Plectoneme detector** (:func:`plectoneme_state`): a node is *in a plectoneme* if some node at least
  ``min_separation_nm`` away along the chain is closer than ``contact_distance_nm`` in space (a
  self-contact of the interwound superhelix; a stretched or coiled chain has essentially none at these
  distances). The plectoneme fraction is the fraction of such nodes; the plectoneme length is the span of
  the largest cluster of them (gaps up to twice the minimum separation, the end loop, are bridged); a
  frame is *plectonemic* when the fraction is at least ``min_fraction`` (0.05).
  **The distances follow the model's non-bonded terms** (:func:`detector_distances`): the contact distance is
  ``CONTACT_PER_DIAMETER = 2.6`` effective diameters of the model's pair energy at its salt and temperature
  (:func:`dnarod.physics.theory.supercoil.effective_diameter`), the minimum separation ``max(25 nm, 2 x``
  contact distance). Why: the superhelix's two strands sit about one effective diameter apart (the distance from
  a node to its nearest node 25 nm or more along the chain peaks at 1.0-1.35 d_eff for both charge models), so
  the contact distance scales with d_eff; 2.6 d_eff is the reach the earlier fixed 6 nm had for Manning's charge,
  so the detector reaches as far into the superhelix at either charge (13.0 nm, separation 26 nm, for the
  calibrated charge at 0.15 M) and counts a tweezers plectoneme with most of its end loop, as the extension does.
  Past ``min_separation_nm = 2 x`` the contact distance a chain comes back within the contact distance only
  through a loop, so a stretched chain reads no contact and a free coil's random self-approaches stay rare (more
  for long coils: a few per cent of the samples of a 1-kbp free coil are flagged). Without non-bonded terms the
  WCA diameter stands for d_eff. An explicit ``contact_distance_nm`` / ``min_separation_nm`` is used as given.
  The members, free-coil samples and tables behind the rule: ``research/plectoneme_detector`` in the repository.

Units: nm, turns, pN nm.
"""
from __future__ import annotations

import numpy as np

from dnarod.core.units import PN, kT
from dnarod.core.docs import fill_doc
from dnarod.physics.nonbonded import NonbondedSettings
from dnarod.physics.theory.supercoil import effective_diameter
from dnarod.core.strains import strains
from dnarod.physics.thermal import sample_step_strains

Z = np.array([0.0, 0.0, 1.0])


def rotation_about_z(frame_now, frame_ref):
    """Angle (rad, in (-pi, pi]) of the rotation ``frame_now frame_ref^T`` about z (swing-twist decomposition).

    Parameters
    ----------
    frame_now, frame_ref : ndarray, shape (..., 3, 3)

    Returns
    -------
    ndarray, shape (...)
    """
    R = np.asarray(frame_now) @ np.swapaxes(np.asarray(frame_ref), -1, -2)
    return 2.0 * np.arctan2(R[..., 1, 0] - R[..., 0, 1], 1.0 + np.trace(R, axis1=-2, axis2=-1))


def unwrap_turns(angles):
    """Unwrapped cumulative rotation (turns) from a series of angles in (-pi, pi] (rad), shape (n,)."""
    return np.unwrap(np.asarray(angles, float)) / (2.0 * np.pi)


def clamp_torque_z(frame, target, k):
    """z torque (pN nm) of the clamp ``E = k (1 - cos theta)`` (k kJ/mol) on a node with ``frame`` (..., 3, 3)."""
    R = np.asarray(target) @ np.swapaxes(np.asarray(frame), -1, -2)  # lab rotation from the node to the target
    ax = 0.5 * np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0], R[..., 1, 0] - R[..., 0, 1]], -1)
    # ax = sin(theta) n, so k sin(theta) n_z = k ax_z
    return k * ax[..., 2] / PN


#: Contact distance of the plectoneme detector in effective diameters of the model's pair energy (module docstring).
CONTACT_PER_DIAMETER = 2.6
#: Smallest chain separation of a self-contact, nm (raised to twice the contact distance where that is longer).
MIN_SEPARATION_NM = 25.0


def detector_distances(nonbonded=None, temperature=300.0, ds=0.34):
    """``(min_separation_nm, contact_distance_nm)`` of the plectoneme detector for a model's non-bonded terms.

    The contact distance is ``CONTACT_PER_DIAMETER`` times the effective diameter of the pair energy
    (:func:`dnarod.physics.theory.supercoil.effective_diameter`, cached per settings; the WCA diameter when both
    terms are off), the minimum separation ``max(MIN_SEPARATION_NM, 2 x contact)`` (module docstring).

    Parameters
    ----------
    nonbonded : NonbondedSettings, optional
        The model's non-local terms (default: ``NonbondedSettings()``, the calibrated charge at 0.15 M).
    temperature : float
        K.
    ds : float
        nm per base pair.

    Returns
    -------
    tuple of float
        nm, nm.
    """
    nb = NonbondedSettings() if nonbonded is None else nonbonded
    d = effective_diameter(nb, float(ds), float(temperature), n_h=80, n_gamma=8, n_offset=2) \
        if (nb.excluded_volume or nb.electrostatics) else 0.0
    contact = CONTACT_PER_DIAMETER * (d if d > 0 else float(nb.diameter))
    return max(MIN_SEPARATION_NM, 2.0 * contact), contact


#: The chain the self-contact detectors read.
_CONTACT_CHAIN = """\
positions : ndarray, shape (n, 3)
    nm.
ds : float
    nm per step."""


def _distances(min_separation_nm, contact_distance_nm, ds):
    """The detector's distances: the explicit ones, the rest from :func:`detector_distances` (default model)."""
    if min_separation_nm is None or contact_distance_nm is None:
        sep, con = detector_distances(ds=ds) if contact_distance_nm is None else \
            (max(MIN_SEPARATION_NM, 2.0 * float(contact_distance_nm)), float(contact_distance_nm))
        return (sep if min_separation_nm is None else float(min_separation_nm)), con
    return float(min_separation_nm), float(contact_distance_nm)


def _far_contacts(positions, ds, min_separation_nm, contact_distance_nm, circular):
    """Self-contacts of one pose: node pairs ``(i, j)``, ``i < j``, closer than ``contact_distance_nm`` in space
    and at least ``min_separation_nm`` apart along the chain (the shorter way round for a ring); two int arrays."""
    from scipy.spatial import cKDTree

    P = np.asarray(positions, float)
    n = len(P)
    pairs = cKDTree(P).query_pairs(contact_distance_nm, output_type="ndarray")
    if not len(pairs):
        return np.empty(0, int), np.empty(0, int)
    i, j = pairs.min(axis=1), pairs.max(axis=1)
    sep = np.minimum(j - i, n - (j - i)) if circular else j - i
    keep = sep >= int(np.ceil(min_separation_nm / ds))
    return i[keep], j[keep]


@fill_doc(contact_chain=_CONTACT_CHAIN)
def plectoneme_state(positions, ds, min_separation_nm=None, contact_distance_nm=None, min_fraction=0.05,
                     circular=False, return_mask=False):
    """Self-contact plectoneme detector for one pose (see the module docstring).

    Parameters
    ----------
    %(contact_chain)s
    min_separation_nm, contact_distance_nm : float, optional
        nm; by default those of :func:`detector_distances` for the default model (calibrated charge, 0.15 M,
        300 K); a member passes its own model's. Only ``contact_distance_nm`` given: the minimum separation is
        ``max(25, 2 x contact)``.
    circular : bool
        Chain separations wrap around (rings).

    Returns
    -------
    fraction : float
        Fraction of nodes in a self-contact.
    length_nm : float
        Span of the largest cluster of contact nodes (ds per node), nm.
    plectonemic : bool
    mask : ndarray of bool, shape (n,)
        Only with ``return_mask``: nodes in a self-contact.
    """
    min_separation_nm, contact_distance_nm = _distances(min_separation_nm, contact_distance_nm, ds)
    n = len(positions)
    sep_min = int(np.ceil(min_separation_nm / ds))
    i, j = _far_contacts(positions, ds, min_separation_nm, contact_distance_nm, circular)
    inside = np.zeros(n, bool)
    inside[i] = True
    inside[j] = True
    frac = float(inside.mean())
    # plectoneme length: contact nodes grouped into clusters, bridging gaps up to 2 sep_min nodes (the end
    # loop of a plectoneme has no partner at sep_min or more); the largest cluster's span
    idx = np.flatnonzero(inside)
    best = 0
    if len(idx):
        if circular:
            idx = np.concatenate([idx, idx + n])
        start = prev = idx[0]
        for i in idx[1:]:
            if i - prev > 2 * sep_min:
                best = max(best, prev - start + 1)
                start = i
            prev = i
        best = min(max(best, prev - start + 1), n)
    if return_mask:
        return frac, float(best * ds), bool(frac >= min_fraction), inside
    return frac, float(best * ds), bool(frac >= min_fraction)


def twisting_moment(positions, frames, params, ds, exclude=None):
    """Mean twisting moment (pN nm) carried by the steps: a low-noise torque estimator.

    Per step, the body stress conjugate to the Cayley twist, ``m3 = (K dxi)_3``, times
    ``dOmega3/dtheta = sec^2(theta/2)/ds`` per unit ds, is the moment about d3 for a twist rotation
    theta; in a straight (unbuckled) stretch of chain with d3 along z it is the torque transmitted
    along z, which in equilibrium equals the torque on the clamp. Averaged over the steps outside a
    plectoneme (``exclude``: boolean per node, True inside), it estimates the clamp torque with about
    ``n_steps`` times less variance than the clamp angle.

    Parameters
    ----------
    positions, frames : (n, 3), (n, 3, 3)
    params : StepParameters
    ds : float
    exclude : ndarray of bool, shape (n,), optional

    Returns
    -------
    float
        pN nm (NaN if every step is excluded).
    """
    Om, Ga = strains(positions, frames, ds)
    dxi = np.concatenate([Om, Ga], axis=1) - params.intrinsic
    m3 = np.einsum("kj,kj->k", params.stiffness[:, 2, :], dxi)
    m3 = m3 * (1.0 + 0.25 * (ds * Om[:, 2]) ** 2)
    # the projection of d3 on z tells which steps are straight along z
    d3z = np.asarray(frames)[:-1, 2, 2]
    use = d3z > 0.9
    if exclude is not None:
        ex = np.asarray(exclude, bool)
        use &= ~(ex[:-1] | ex[1:])
    return float(m3[use].mean() / PN) if use.any() else float("nan")


def twisting_moment_offset(model, temperature, n_samples=400_000, seed=0):
    """What :func:`twisting_moment` reads on a chain under no torque at all (pN nm), with its standard error.

    A free chain carries no torque, but the mean of the twist stress ``m3 (1 + (ds Omega_3)²/4)`` over the exact
    step distribution is not zero: the steps are distributed with the Haar measure of their rotations, whose
    density in Cayley coordinates falls as ``(1 + |ds Omega|²/4)^-2``, so ``<dE/dOmega_3>`` equals ``kT`` times the
    mean log-derivative of that factor instead of 0 (about -1.6 pN nm for ``dna-default`` at 300 K). The
    estimator's slope (torque per turn) is unaffected; its absolute value is corrected by subtracting this offset
    (to first order: the offset changes with the twist strain by a relative ~1e-3 per pN nm). Computed per
    distinct step from :func:`dnarod.physics.thermal.sample_step_strains` (exact) and averaged over the steps.

    Parameters
    ----------
    model : RodModel
    temperature : float
        K.

    Returns
    -------
    tuple of float
        ``(offset, standard_error)``, pN nm.
    """
    rng = np.random.default_rng(seed)
    p = model.params
    cache, vals, errs = {}, [], []
    for k in range(p.n_steps):
        key = (p.stiffness[k].tobytes(), p.intrinsic[k].tobytes())
        if key not in cache:
            x = sample_step_strains(p.stiffness[k], p.intrinsic[k], model.ds, kT(temperature), int(n_samples), rng)
            m3 = (x - p.intrinsic[k]) @ p.stiffness[k][2] * (1.0 + 0.25 * (model.ds * x[:, 2]) ** 2) / PN
            cache[key] = (float(m3.mean()), float(m3.std(ddof=1) / np.sqrt(len(m3))))
        vals.append(cache[key][0])
        errs.append(cache[key][1])
    return float(np.mean(vals)), float(np.sqrt(np.mean(np.square(errs))))


@fill_doc(contact_chain=_CONTACT_CHAIN)
def plectoneme_end_loops(positions, ds, circular=False, min_separation_nm=None, contact_distance_nm=None,
                         merge_nm=20.0, min_share=0.1):
    """Number of plectoneme end loops (hairpin tips) in one pose, and where they are.

    The self-contacts of :func:`plectoneme_state` (same ``min_separation_nm`` and ``contact_distance_nm``)
    pair the two duplexes of a superhelix arm; the chain between the two nodes of a contact runs out along the
    arm, round its end loop and back, so the midpoint of that stretch (the shorter way round for a ring) is
    the arm's end loop, the same for every contact of the arm. The midpoints are grouped (gaps up to
    ``merge_nm`` of chain bridged); a group holding at least ``min_share`` of the contacts is an end loop.
    An unbranched plectoneme has one end loop in an open chain and two in a closed ring (its two tips); a
    branched one (arms meeting at a junction) has one more per extra arm. Chosen because it needs no
    superhelix axis and reuses the contact definition of the plectoneme detector.

    Parameters
    ----------
    %(contact_chain)s
    circular : bool
        Closed ring (contact midpoints taken the shorter way round).
    min_separation_nm, contact_distance_nm : float, optional
        As in :func:`plectoneme_state` (default: the default model's, :func:`detector_distances`).

    Returns
    -------
    n_loops : int
    centres : ndarray, shape (n_loops,)
        Node index (fractional) of each end loop.
    """
    min_separation_nm, contact_distance_nm = _distances(min_separation_nm, contact_distance_nm, ds)
    n = len(positions)
    i, j = _far_contacts(positions, ds, min_separation_nm, contact_distance_nm, circular)
    d = j - i
    if circular:
        mid = np.where(d <= n - d, i + 0.5 * d, j + 0.5 * (n - d)) % n
    else:
        mid = 0.5 * (i + j)
    mid = np.sort(mid)
    if not len(mid):
        return 0, np.empty(0)
    gap = merge_nm / ds
    groups = np.split(mid, np.flatnonzero(np.diff(mid) > gap) + 1)
    if circular and len(groups) > 1 and mid[0] + n - mid[-1] <= gap:  # a group across the ring's node 0
        groups = [np.concatenate([groups[-1], groups[0] + n])] + groups[1:-1]
    big = [g for g in groups if len(g) >= min_share * len(mid)]
    return len(big), np.array([float(np.median(g)) % n if circular else float(np.median(g)) for g in big])
