"""The DOP853 driver shared by the ODE special cases."""
from __future__ import annotations

import numpy as np
from scipy.integrate import solve_ivp

from dnarod.core.errors import SimulationError


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
