"""The DOP853 driver shared by the ODE special cases."""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from dnarod.core.errors import DnarodError, SimulationError


def dop853(rhs, y0, t_end, n_out, rtol, atol, what):
    """Integrate ``y' = rhs(t, y)`` from 0 to ``t_end`` with scipy's DOP853.

    Returns
    -------
    t : ndarray, shape (n_out,)
    y : ndarray, shape (n_out, len(y0))

    Raises
    ------
    SimulationError
        If the integrator fails (the message names ``what``).
    """
    t_eval = np.linspace(0.0, float(t_end), int(n_out))
    sol = solve_ivp(rhs, (0.0, float(t_end)), y0, method="DOP853", rtol=rtol, atol=atol, t_eval=t_eval)
    if not sol.success:
        raise SimulationError(f"{what} integration failed: {sol.message}", term="integrator")
    return sol.t, sol.y.T


class SixStateODE:
    """Base of the special cases whose state is two 3-vectors ``y = (a, b)``, shape (..., 6), integrated with
    :func:`dop853`. A subclass gives ``rhs(t, y)``, ``STATE`` (how a message names the pair, e.g. ``"(p, m)"``) and
    ``NAME`` (how a failed integration names the system)."""

    STATE = "(a, b)"
    NAME = "ODE"

    def rhs(self, t, y):
        """d/dt y for scipy; y shape (6,)."""
        raise NotImplementedError

    def _split(self, y):
        y = np.asarray(y, dtype=float)
        if y.shape[-1] != 6:
            raise DnarodError(f"y: expected state (..., 6) = {self.STATE}, got shape {y.shape}")
        return y[..., :3], y[..., 3:]

    def integrate(self, y0, end, n_out=201, rtol=1e-12, atol=1e-12):
        """Integrate from 0 to ``end`` (time, or arc length for a top) with DOP853.

        Returns
        -------
        t : ndarray, shape (n_out,)
        y : ndarray, shape (n_out, 6)
        """
        y0 = np.asarray(y0, dtype=float)
        self._split(y0)
        return dop853(self.rhs, y0, end, n_out, rtol, atol, self.NAME)
