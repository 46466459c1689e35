"""The direct Lax-form engine: exact strain-space dynamics and a symplectic Langevin splitting.

* :mod:`.exact`: the exact zero-curvature (Lax) system of docs/formulation.md §6 in strain space, integrated
  with scipy's DOP853 (adaptive, 8th order) for reference runs.
* :mod:`.splitting`: the fixed-step kick-drift-rotor-kick scheme of docs/formulation.md §7 and its BAOAB
  Langevin form, with the stable-step estimate ``dt_crit = 2 / omega_max``.
* :mod:`.fast`, :mod:`.fast_blocked`: numba kernels of the splitting (loads and update fused in
  one sweep per step; the blocked one is the default), tested equal to the numpy reference.
* :mod:`.modes`: Hessian and normal modes from force differences.
* :mod:`.paper_scheme`: the paper's printed (3.13) right-hand side, kept for comparison only.
* :mod:`.engine`: :class:`LaxEngine`, the engine the run layer drives (:mod:`dnarod.run`; Python runs that
  write ``.dtraj`` files: :mod:`dnarod.run.lax`).
"""
from dnarod.engines.lax.boundary import BoundaryConditions
from dnarod.engines.lax.exact import ExactSystem, integrate_exact, strain_rates
from dnarod.engines.lax.engine import LaxEngine
from dnarod.engines.lax.splitting import RigidState, SplittingIntegrator, maxwell_state, omega_max

__all__ = [
    "BoundaryConditions", "ExactSystem", "integrate_exact", "strain_rates",
    "RigidState", "SplittingIntegrator", "maxwell_state", "omega_max",
    "LaxEngine",
]
