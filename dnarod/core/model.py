"""The rod model: nodes (rigid base pairs), steps, parameters, masses and inertias.

A :class:`RodModel` is the object both engines simulate and the analyses read. It holds
one pose (positions and frames) plus everything constant: arc length per step, the
per-step :class:`~dnarod.core.parameters.StepParameters`, per-node mass and principal inertia,
and, for a circular chain, the screw :class:`~dnarod.core.strains.Closure`.

Units: nm, amu, amu nm^2, kJ/mol. Shapes: positions ``(n_nodes, 3)``, frames
``(n_nodes, 3, 3)`` with directors d1, d2, d3 as columns.
"""
from __future__ import annotations

import hashlib
import json
import zipfile
from dataclasses import dataclass, field, replace

import numpy as np

from dnarod.core import energy as _energy
from dnarod.core.errors import GeometryError, ParameterError, base_pair
from dnarod.core.parameters import StepParameters
from dnarod.core.rotations import check_frames
from dnarod.core.strains import Closure, chain_from_strains, strains


@dataclass
class RodModel:
    """A discrete shearable, extensible rod (one node per base pair).

    Parameters
    ----------
    positions : ndarray, shape (n_nodes, 3)
        Node centres (centres of mass), nm.
    frames : ndarray, shape (n_nodes, 3, 3)
        Node orientations, directors as columns.
    params : StepParameters
        ``n_nodes - 1`` steps (open chain) or ``n_nodes`` steps (circular).
    ds : float
        Reference arc length per step, nm.
    mass : ndarray, shape (n_nodes,)
        Node masses, amu.
    inertia : ndarray, shape (n_nodes, 3)
        Principal moments of inertia about d1, d2, d3, amu nm^2.
    closure : Closure or None
        Screw closure; ``None`` for an open chain.
    sequence : str or None
        Strand I, 5'->3' (one letter per node), if the model is DNA.
    """

    positions: np.ndarray
    frames: np.ndarray
    params: StepParameters
    ds: float
    mass: np.ndarray
    inertia: np.ndarray
    closure: Closure | None = None
    sequence: str | None = None
    metadata: dict = field(default_factory=dict)

    def __post_init__(self):
        self.positions = np.asarray(self.positions, dtype=float)
        if self.positions.ndim != 2 or self.positions.shape[1] != 3:
            raise GeometryError(f"positions must have shape (n_nodes, 3), got {self.positions.shape}")
        n = self.positions.shape[0]
        if n < 2:
            raise GeometryError(f"a rod needs at least 2 nodes, got {n}")
        if not np.isfinite(self.positions).all():
            k = int(np.argwhere(~np.isfinite(self.positions))[0, 0])
            raise GeometryError(f"{base_pair(k)}: position is not finite")
        self.frames = check_frames(self.frames)
        if self.frames.shape[0] != n:
            raise GeometryError(f"{n} positions but {self.frames.shape[0]} frames")
        if not (np.isfinite(self.ds) and self.ds > 0):
            raise ParameterError(f"ds must be a positive length in nm, got {self.ds}")
        self.ds = float(self.ds)
        n_steps = n if self.closure is not None else n - 1
        if self.params.n_steps != n_steps:
            kind = "circular" if self.closure is not None else "open"
            raise ParameterError(
                f"an {kind} chain of {n} nodes has {n_steps} steps, but the parameters have {self.params.n_steps}"
            )
        self.mass = np.broadcast_to(np.asarray(self.mass, dtype=float), (n,)).copy()
        self.inertia = np.broadcast_to(np.asarray(self.inertia, dtype=float), (n, 3)).copy()
        for name, arr in (("mass", self.mass), ("inertia", self.inertia)):
            bad = ~(np.isfinite(arr) & (arr > 0))
            if bad.any():
                k = int(np.argwhere(bad)[0, 0])
                raise ParameterError(f"{base_pair(k)}: {name} must be positive and finite, got {arr[k]}")
        if self.sequence is not None and len(self.sequence) != n:
            raise ParameterError(f"sequence has {len(self.sequence)} letters for {n} nodes")
        # Fail early on poses the strain map cannot represent (rotation >= pi between neighbours).
        strains(self.positions, self.frames, self.ds, self.closure)

    # --- sizes -------------------------------------------------------------------------
    @property
    def n_nodes(self):
        return self.positions.shape[0]

    @property
    def n_steps(self):
        return self.params.n_steps

    @property
    def circular(self):
        return self.closure is not None

    # --- physics -----------------------------------------------------------------------
    def strains(self, positions=None, frames=None):
        """Strains ``(Omega, Gamma)``, each shape (n_steps, 3), of this pose or of a given one."""
        return strains(self._pos(positions), self._frm(frames), self.ds, self.closure)

    def energy(self, positions=None, frames=None):
        """Elastic energy, kJ/mol."""
        return _energy.energy(self._pos(positions), self._frm(frames), self.params, self.ds, self.closure)

    def loads(self, positions=None, frames=None):
        """``(E, F, tau)``: energy (kJ/mol), lab forces (n_nodes, 3) and torques (n_nodes, 3)."""
        return _energy.loads(self._pos(positions), self._frm(frames), self.params, self.ds, self.closure)

    def with_pose(self, positions, frames):
        """A copy of the model with another pose (validated)."""
        return replace(self, positions=np.array(positions, float), frames=np.array(frames, float))

    def _pos(self, p):
        return self.positions if p is None else np.asarray(p, float)

    def _frm(self, f):
        return self.frames if f is None else np.asarray(f, float)

    # --- builders ----------------------------------------------------------------------
    @classmethod
    def from_strains(cls, Omega, Gamma, params, ds, mass, inertia, r0=None, frame0=None, sequence=None):
        """An open chain whose pose has the given strains (exact inverse of the strain map)."""
        pos, frm = chain_from_strains(Omega, Gamma, ds, r0, frame0)
        return cls(pos, frm, params, ds, mass, inertia, sequence=sequence)

    @classmethod
    def intrinsic(cls, params, ds, mass, inertia, sequence=None, r0=None, frame0=None):
        """An open chain at its intrinsic (zero-force) shape."""
        return cls.from_strains(params.Omega0, params.Gamma0, params, ds, mass, inertia, r0, frame0, sequence)

    @classmethod
    def ring(cls, params, ds, mass, inertia, linking_number, rise=None, sequence=None):
        """A planar circular ring (identity closure) with a given integer linking number.

        Nodes lie on a circle whose chords all have length ``rise``; each node's d3 points along
        its outgoing chord (no shear), d1 starts on the inward normal and turns uniformly about d3
        by ``2 pi Lk / n`` per step. The centreline is planar, so its writhe is 0 and
        ``Lk = Tw = linking_number``. A DNA ring at its relaxed linking number has
        ``Lk = round(n theta0 / 2 pi)``; the difference is the supercoiling.

        Parameters
        ----------
        params : StepParameters
            ``n_nodes`` steps (the last joins node n-1 to node 0).
        ds : float
            nm.
        mass : array (n,), amu;  inertia : array (n, 3), amu nm^2
        linking_number : int
        rise : float, optional
            Chord length, nm (default ``ds`` times the mean intrinsic Gamma3).
        sequence : str, optional

        Returns
        -------
        RodModel
        """
        n = params.n_steps
        if n < 3:
            raise ParameterError(f"a ring needs at least 3 nodes, got {n}")
        if int(linking_number) != linking_number:
            raise ParameterError(f"linking_number must be an integer for a closed ring, got {linking_number}")
        b = ds * float(np.mean(params.Gamma0[:, 2])) if rise is None else float(rise)
        radius = b / (2.0 * np.sin(np.pi / n))
        alpha = 2.0 * np.pi * np.arange(n) / n
        pos = radius * np.stack([np.cos(alpha), np.sin(alpha), np.zeros(n)], axis=1)
        d3 = np.roll(pos, -1, axis=0) - pos
        d3 /= np.linalg.norm(d3, axis=1)[:, None]
        normal = -np.stack([np.cos(alpha + np.pi / n), np.sin(alpha + np.pi / n), np.zeros(n)], axis=1)
        phi = 2.0 * np.pi * int(linking_number) * np.arange(n) / n
        binormal = np.cross(d3, normal)
        d1 = np.cos(phi)[:, None] * normal + np.sin(phi)[:, None] * binormal
        d2 = np.cross(d3, d1)
        frames = np.stack([d1, d2, d3], axis=2)
        return cls(pos, frames, params, ds, mass, inertia, closure=Closure.identity(), sequence=sequence,
                   metadata={"linking_number": int(linking_number)})

    # --- file format ---------------------------------------------------------------------
    def save(self, path):
        """Write the model to a ``.npz`` file (format documented in README, "Model files").

        Arrays: ``positions`` (nm), ``frames``, ``stiffness``, ``intrinsic``, ``mass`` (amu),
        ``inertia`` (amu nm^2), ``closure_Q``/``closure_t`` (circular only); ``meta`` is a JSON
        string with ``ds``, ``sequence``, ``step_names``, ``format`` and ``metadata``.
        The file is written atomically (temporary file, then rename).
        """
        from dnarod.core.io import atomic_path

        meta = dict(format="dnarod-model", version=1, ds=self.ds, sequence=self.sequence,
                    step_names=list(self.params.names), metadata=self.metadata)
        arrays = dict(positions=self.positions, frames=self.frames, stiffness=self.params.stiffness,
                      intrinsic=self.params.intrinsic, mass=self.mass, inertia=self.inertia,
                      meta=np.array(json.dumps(meta)))
        if self.closure is not None:
            arrays.update(closure_Q=self.closure.Q, closure_t=self.closure.t)
        with atomic_path(path) as tmp:
            with open(tmp, "wb") as fh:
                np.savez(fh, **arrays)

    @classmethod
    def load(cls, path):
        """Read a model written by :meth:`save`."""
        from dnarod.core.io import file_kind

        kind = file_kind(path)
        if kind is not None and kind not in ("a zip/.npz archive", "an empty file"):
            # numpy would try to unpickle it and suggest allow_pickle=True: say what the file is instead
            raise ParameterError(f"{path}: cannot read dnarod model file (it is {kind}, not an .npz archive); give "
                                 f"a .npz written by `dnarod build` or a run's final_model.npz")
        try:
            with np.load(path, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                if meta.get("format") != "dnarod-model":
                    raise ParameterError(f"{path}: not a dnarod model file (format={meta.get('format')!r})")
                closure = Closure(z["closure_Q"], z["closure_t"]) if "closure_Q" in z else None
                params = StepParameters(z["stiffness"], z["intrinsic"], meta["step_names"])
                return cls(z["positions"], z["frames"], params, meta["ds"], z["mass"], z["inertia"],
                           closure=closure, sequence=meta.get("sequence"), metadata=meta.get("metadata", {}))
        except (OSError, KeyError, ValueError, EOFError, zipfile.BadZipFile) as exc:
            if isinstance(exc, ParameterError):
                raise
            raise ParameterError(f"{path}: cannot read dnarod model file ({exc or type(exc).__name__}); give a "
                                 f".npz written by `dnarod build` or a run's final_model.npz") from None


def model_fingerprint(model, pose=True):
    """SHA-256 of everything that defines the mechanical system: sizes, sequence, parameters,
    masses, inertias, closure, and (with ``pose``) the pose."""
    h = hashlib.sha256()
    h.update(f"{model.n_nodes}|{model.sequence or ''}|{float(model.ds)!r}".encode())
    arrays = [model.params.stiffness, model.params.intrinsic, model.mass, model.inertia]
    if pose:
        arrays += [model.positions, model.frames]
    for a in arrays:
        h.update(np.ascontiguousarray(a, float).tobytes())
    if model.closure is not None:
        h.update(np.ascontiguousarray(model.closure.Q, float).tobytes())
        h.update(np.ascontiguousarray(model.closure.t, float).tobytes())
    return h.hexdigest()
