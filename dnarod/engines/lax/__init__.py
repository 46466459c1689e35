"""The direct Lax-form engine: exact strain-space dynamics and a symplectic Langevin splitting.

* :mod:`.exact`: the exact zero-curvature (Lax) system of design A3 in strain space, integrated
  with scipy's DOP853 (adaptive, 8th order) for reference runs.
* :mod:`.splitting`: the fixed-step kick-drift-rotor-kick scheme of design A4 b and its BAOAB
  Langevin form, with the stable-step estimate ``dt_crit = 2 / omega_max``.
* :mod:`.fast`, :mod:`.fast_blocked`: numba kernels of the splitting (loads and update fused in
  one sweep per step; the blocked one is the default), tested equal to the numpy reference.
* :mod:`.modes`: Hessian and normal modes from force differences.
* :mod:`.paper_scheme`: the paper's printed (3.13) right-hand side, kept for comparison only.
* :mod:`.run`: ``simulate_nve``, ``simulate_langevin``, ``simulate_exact`` writing ``.dtraj``.
"""
from dnarod.engines.lax.boundary import BoundaryConditions
from dnarod.engines.lax.exact import ExactSystem, integrate_exact, strain_rates
from dnarod.engines.lax.run import SimulationResult, simulate_exact, simulate_langevin, simulate_nve
from dnarod.engines.lax.splitting import RigidState, SplittingIntegrator, maxwell_state, omega_max, stable_time_step

__all__ = [
    "BoundaryConditions", "ExactSystem", "integrate_exact", "strain_rates",
    "RigidState", "SplittingIntegrator", "maxwell_state", "omega_max", "stable_time_step",
    "SimulationResult", "simulate_nve", "simulate_langevin", "simulate_exact",
]
