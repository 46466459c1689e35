"""The numba path of :class:`.splitting.SplittingIntegrator`: loads and steps through the kernels of
:mod:`.fast` (one sweep per step) or :mod:`.fast_blocked` (blocks of nodes, the default)."""
from __future__ import annotations

import numpy as np

from dnarod.core.errors import GeometryError, step_name
from dnarod.engines.lax.fast import compute_loads, run_steps
from dnarod.engines.lax.fast_blocked import run_steps_blocked


class NumbaKernel:
    """The fast path of :class:`.splitting.SplittingIntegrator` (same interface as ``NumpyKernel``)."""

    def __init__(self, model, ext_force, ext_torque, free, blocked=True):
        self.blocked = blocked
        self.model = model
        self.F_ext = np.ascontiguousarray(ext_force, float)
        self.tau_ext = np.ascontiguousarray(ext_torque, float)
        self.free = np.ascontiguousarray(free, float)
        self.K = np.ascontiguousarray(model.params.stiffness)
        self.xi0 = np.ascontiguousarray(model.params.intrinsic)
        cl = model.closure
        self.circular = cl is not None
        self.Q = np.eye(3) if cl is None else np.ascontiguousarray(cl.Q)
        self.t = np.zeros(3) if cl is None else np.ascontiguousarray(cl.t)
        self._dummy_noise = np.zeros((1, 6, 1))
        # distinct parameter sets of the steps (uniform rod: 1; dinucleotide model: <= 16)
        flat = np.concatenate([self.K.reshape(self.K.shape[0], 36), self.xi0], axis=1)
        table, idx = np.unique(flat, axis=0, return_inverse=True)
        self.ktab = np.ascontiguousarray(table.T)
        self.kidx = np.ascontiguousarray(idx.reshape(-1), dtype=np.int64)

    def loads(self, state):
        n = state.positions.shape[0]
        F = np.empty((n, 3))
        tau = np.empty((n, 3))
        E, bad = compute_loads(state.positions, state.frames, self.K, self.xi0, self.model.ds, self.circular,
                               self.Q, self.t, self.F_ext, self.tau_ext, self.free, F, tau)
        if bad >= 0:
            raise GeometryError(f"{step_name(bad, n)}: the rotation between its base pairs is at or beyond "
                                f"180 deg (or not finite)")
        return E, F, tau

    def run(self, state, F, tau, dt, n_steps, inv_m, inv_J, c=None, sig_P=None, sig_pi=None, noise=None):
        langevin = noise is not None
        n = state.positions.shape[0]
        if not langevin:
            c, sig_P, sig_pi, noise = 1.0, np.zeros(n), np.zeros((n, 3)), self._dummy_noise
        for name in ("positions", "frames", "momenta", "angular_momenta"):
            arr = getattr(state, name)
            if not arr.flags.c_contiguous:
                setattr(state, name, np.ascontiguousarray(arr))
        if self.blocked:
            kernel = run_steps_blocked
        else:
            kernel = run_steps
        return kernel(state.positions, state.frames, state.momenta, state.angular_momenta, F, tau,
                         np.ascontiguousarray(inv_m), np.ascontiguousarray(inv_J), self.free, self.F_ext,
                         self.tau_ext, self.K, self.xi0, self.model.ds, self.circular, self.Q, self.t, float(dt),
                         int(n_steps), langevin, float(c), np.ascontiguousarray(sig_P),
                         np.ascontiguousarray(sig_pi), noise, *((self.ktab, self.kidx) if self.blocked else ()))
