"""Per-step elastic parameters of the rod: stiffness K = [[A, B], [B^T, C]] and intrinsic strains.

Units (OpenMM MD units): A in kJ/mol nm (bend and twist stiffness), B in kJ/mol (coupling),
C in kJ/mol/nm (shear and stretch stiffness); intrinsic Omega0 in 1/nm (Cayley), Gamma0
dimensionless. The energy of step k is ``ds * H_k`` with ``H = 1/2 dxi^T K dxi``,
``xi = (Omega, Gamma)``.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dnarod.core.errors import ParameterError

STRAIN_NAMES = ("Omega1", "Omega2", "Omega3", "Gamma1", "Gamma2", "Gamma3")


def check_stiffness(K, name="stiffness"):
    """Check a 6x6 stiffness matrix: finite, symmetric and positive definite.

    Parameters
    ----------
    K : array_like, shape (6, 6)
    name : str
        Name of the entry, used in error messages.

    Returns
    -------
    ndarray, shape (6, 6)

    Raises
    ------
    ParameterError
    """
    K = np.asarray(K, dtype=float)
    if K.shape != (6, 6):
        raise ParameterError(f"{name}: stiffness must be 6x6 [[A, B], [B^T, C]], got shape {K.shape}")
    if not np.isfinite(K).all():
        raise ParameterError(f"{name}: stiffness has non-finite entries")
    scale = np.abs(K).max()
    asym = np.abs(K - K.T).max()
    if asym > 1e-9 * max(scale, 1.0):
        i, j = np.unravel_index(np.argmax(np.abs(K - K.T)), K.shape)
        raise ParameterError(
            f"{name}: stiffness is not symmetric (K[{i},{j}] = {K[i, j]:g} but K[{j},{i}] = {K[j, i]:g}); "
            f"give the full symmetric 6x6 matrix"
        )
    eig = np.linalg.eigvalsh(0.5 * (K + K.T))
    if eig[0] <= 0:
        raise ParameterError(
            f"{name}: stiffness is not positive definite (smallest eigenvalue {eig[0]:g}); the rod would "
            f"have no stable rest state. Check signs and units of the couplings"
        )
    return 0.5 * (K + K.T)


@dataclass
class StepParameters:
    """Elastic parameters of every step of a chain.

    Parameters
    ----------
    stiffness : ndarray, shape (n_steps, 6, 6)
        K = [[A, B], [B^T, C]] per step (see module docstring for units).
    intrinsic : ndarray, shape (n_steps, 6)
        Intrinsic strains (Omega0 in 1/nm, Gamma0 dimensionless).
    names : list of str, optional
        Step labels (for example ``"AC"``), used in messages and analysis.
    """

    stiffness: np.ndarray
    intrinsic: np.ndarray
    names: list = field(default=None)

    def __post_init__(self):
        K = np.asarray(self.stiffness, dtype=float)
        xi0 = np.asarray(self.intrinsic, dtype=float)
        if K.ndim == 2:
            K = K[None]
        if xi0.ndim == 1:
            xi0 = xi0[None]
        if K.ndim != 3 or K.shape[1:] != (6, 6):
            raise ParameterError(f"stiffness must have shape (n_steps, 6, 6), got {K.shape}")
        if xi0.shape != (K.shape[0], 6):
            raise ParameterError(f"intrinsic strains must have shape ({K.shape[0]}, 6), got {xi0.shape}")
        names = list(self.names) if self.names is not None else [f"step {k + 1}" for k in range(K.shape[0])]
        if len(names) != K.shape[0]:
            raise ParameterError(f"got {len(names)} step names for {K.shape[0]} steps")
        # each distinct matrix is checked once, at its first step (a sequence model has <= 16 of them)
        _, first, inverse = np.unique(K.reshape(K.shape[0], 36), axis=0, return_index=True, return_inverse=True)
        checked = np.empty((len(first), 6, 6))
        for u in np.argsort(first):
            k = int(first[u])
            checked[u] = check_stiffness(K[k], name=f"step {k + 1} ({names[k]})")
        K = checked[inverse.reshape(-1)]
        if not np.isfinite(xi0).all():
            k = int(np.argwhere(~np.isfinite(xi0))[0, 0])
            raise ParameterError(f"step {k + 1} ({names[k]}): intrinsic strain is not finite")
        self.stiffness, self.intrinsic, self.names = K, xi0, names

    @property
    def n_steps(self):
        return self.stiffness.shape[0]

    @property
    def A(self):
        """Bend-twist block, shape (n_steps, 3, 3), kJ/mol nm."""
        return self.stiffness[:, :3, :3]

    @property
    def B(self):
        """Coupling block, shape (n_steps, 3, 3), kJ/mol."""
        return self.stiffness[:, :3, 3:]

    @property
    def C(self):
        """Shear-stretch block, shape (n_steps, 3, 3), kJ/mol/nm."""
        return self.stiffness[:, 3:, 3:]

    @property
    def Omega0(self):
        """Intrinsic bend-twist strains, shape (n_steps, 3), 1/nm."""
        return self.intrinsic[:, :3]

    @property
    def Gamma0(self):
        """Intrinsic shear-stretch strains, shape (n_steps, 3)."""
        return self.intrinsic[:, 3:]

    def __getitem__(self, index):
        idx = np.arange(self.n_steps)[index]
        idx = np.atleast_1d(idx)
        return StepParameters(self.stiffness[idx], self.intrinsic[idx], [self.names[i] for i in idx])

    @staticmethod
    def uniform(stiffness, intrinsic, n_steps, name="uniform"):
        """The same parameters repeated for ``n_steps`` steps."""
        K = np.broadcast_to(np.asarray(stiffness, float), (n_steps, 6, 6)).copy()
        xi0 = np.broadcast_to(np.asarray(intrinsic, float), (n_steps, 6)).copy()
        return StepParameters(K, xi0, [name] * n_steps)

    @staticmethod
    def concatenate(parts):
        """Join parameter sets step-wise."""
        return StepParameters(
            np.concatenate([p.stiffness for p in parts]),
            np.concatenate([p.intrinsic for p in parts]),
            sum((list(p.names) for p in parts), []),
        )
