"""Base reference frames by least-squares fit of the standard bases (Tsukuba convention).

Olson et al. (2001), J. Mol. Biol. 313:229: each base's frame is the rigid-body transform
that best superimposes (least squares over the ring atoms) the idealised standard base,
given in its own frame, on the observed base. The standard coordinates are 3DNA's
(``data/standard_bases/standard_base_coordinates_3dna.csv``). The fit is the SVD
(Kabsch) solution, vectorised over any leading axes (frames of a trajectory, bases).

Units: nm. Frames have the axes x, y, z as columns; ``observed = origin + frame @ standard``.
"""
from __future__ import annotations

import csv
from functools import lru_cache

import numpy as np

from dnarod.core.errors import StructureError
from dnarod.structure._data import data_file

RING_ATOMS = {
    "purine": ("C4", "N3", "C2", "N1", "C6", "C5", "N7", "C8", "N9"),
    "pyrimidine": ("C4", "N3", "C2", "N1", "C6", "C5"),
}
# Inosine has no standard base file here; its ring atoms coincide with guanine's.
FIT_BASE = {"A": "A", "G": "G", "I": "G", "C": "C", "T": "T", "U": "U"}
MIN_RING_ATOMS = 3


@lru_cache(maxsize=1)
def standard_bases():
    """Standard base atoms: ``{letter: {atom: xyz (3,) nm}}`` and ring-atom lists.

    Returns
    -------
    atoms : dict
        Letter -> atom name -> ndarray (3,), nm, in the base frame.
    ring : dict
        Letter -> tuple of ring atom names used in the fit (3DNA's order).
    """
    atoms, ring = {}, {}
    with open(data_file("standard_bases", "standard_base_coordinates_3dna.csv")) as fh:
        for row in csv.DictReader(fh):
            name = "C7" if row["atom"] == "C5M" else row["atom"]
            xyz = 0.1 * np.array([float(row["x_A"]), float(row["y_A"]), float(row["z_A"])])
            atoms.setdefault(row["base"], {})[name] = xyz
            if row["ring_atom"] == "1":
                ring.setdefault(row["base"], []).append(name)
    return atoms, {k: tuple(v) for k, v in ring.items()}


def kabsch(reference, observed):
    """Least-squares rigid fit ``observed ~ origin + R @ reference``, vectorised.

    Parameters
    ----------
    reference : ndarray, shape (k, 3) or (..., k, 3)
        Model coordinates (the standard base in its frame), nm.
    observed : ndarray, shape (..., k, 3)
        Observed coordinates, nm.

    Returns
    -------
    R : ndarray, shape (..., 3, 3)
        Proper rotation (the base frame, axes as columns).
    origin : ndarray, shape (..., 3)
        nm.
    rmsd : ndarray, shape (...)
        Root-mean-square deviation of the fitted atoms, nm.
    """
    ref = np.asarray(reference, float)
    obs = np.asarray(observed, float)
    rc = ref.mean(axis=-2)
    oc = obs.mean(axis=-2)
    P = ref - rc[..., None, :]
    Q = obs - oc[..., None, :]
    H = np.einsum("...ki,...kj->...ij", P, Q)  # sum_k p_k q_k^T
    U, _, Vt = np.linalg.svd(H)
    V = np.swapaxes(Vt, -1, -2)
    d = np.sign(np.linalg.det(V @ np.swapaxes(U, -1, -2)))
    d = np.where(d == 0, 1.0, d)
    D = np.zeros(d.shape + (3, 3))
    D[..., 0, 0] = 1.0
    D[..., 1, 1] = 1.0
    D[..., 2, 2] = d
    R = V @ D @ np.swapaxes(U, -1, -2)
    origin = oc - np.einsum("...ij,...j->...i", R, rc)
    fit = np.einsum("...ij,...kj->...ki", R, ref if ref.ndim > 2 else ref[None]) + origin[..., None, :]
    rmsd = np.sqrt(np.mean(np.sum((fit - obs) ** 2, axis=-1), axis=-1))
    return R, origin, rmsd


def has_base_atoms(nucleotide):
    """True if any ring atom of the nucleotide's standard base is present."""
    _, ring = standard_bases()
    letter = FIT_BASE.get(nucleotide.base)
    return letter is not None and any(a in nucleotide.atoms for a in ring[letter])


def ring_atoms_present(nucleotide, source="<structure>"):
    """Ring atom names of a nucleotide used for its fit (at least three, not collinear).

    Raises
    ------
    StructureError
        If fewer than three ring atoms of its standard base are present.
    """
    std, ring = standard_bases()
    letter = FIT_BASE.get(nucleotide.base)
    if letter is None:
        raise StructureError(f"{source}: {nucleotide.label}: no standard base for parent {nucleotide.base!r}")
    names = [a for a in ring[letter] if a in nucleotide.atoms]
    if len(names) < MIN_RING_ATOMS:
        missing = [a for a in ring[letter] if a not in nucleotide.atoms]
        raise StructureError(f"{source}: {nucleotide.label}: too few base ring atoms to fit a frame "
                             f"({len(names)} of {len(ring[letter])}; missing {', '.join(missing)}); "
                             f"need at least {MIN_RING_ATOMS}. Complete the base or remove the residue")
    return letter, tuple(names)


def base_frames(nucleotides, source="<structure>"):
    """Fit the standard base to every nucleotide.

    Parameters
    ----------
    nucleotides : list of Nucleotide
    source : str
        File name for messages.

    Returns
    -------
    frames : ndarray, shape (n, 3, 3)
    origins : ndarray, shape (n, 3)
        nm.
    rmsd : ndarray, shape (n,)
        nm.
    """
    std, _ = standard_bases()
    n = len(nucleotides)
    frames = np.zeros((n, 3, 3))
    origins = np.zeros((n, 3))
    rmsd = np.zeros(n)
    groups = {}
    for i, nt in enumerate(nucleotides):
        groups.setdefault(ring_atoms_present(nt, source), []).append(i)
    for (letter, names), idx in groups.items():
        ref = np.array([std[letter][a] for a in names])
        obs = np.array([[nucleotides[i].atoms[a] for a in names] for i in idx])
        R, o, r = kabsch(ref, obs)
        frames[idx], origins[idx], rmsd[idx] = R, o, r
    bad = np.flatnonzero(rmsd > 0.1)
    if bad.size:
        nt = nucleotides[bad[0]]
        raise StructureError(f"{source}: {nt.label}: the base does not fit its standard geometry "
                             f"(ring RMSD {10 * rmsd[bad[0]]:.2f} A); check its atoms and residue name")
    return frames, origins, rmsd
