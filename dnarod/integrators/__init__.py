"""The direct Lax-form engine: exact strain-space dynamics and a symplectic Langevin splitting.

* :mod:`.exact`: the exact zero-curvature (Lax) system of design A3 in strain space, integrated
  with scipy's DOP853 (adaptive, 8th order) for reference runs.
* :mod:`.splitting`: the fixed-step kick-drift-rotor-kick scheme of design A4 b and its BAOAB
  Langevin form, with the stable-step estimate ``dt_crit = 2 / omega_max``.
* :mod:`.fast`: the numba kernel of the splitting (fused loads + update), tested equal to the
  numpy reference.
* :mod:`.paper_scheme`: the paper's printed (3.13) right-hand side, kept for comparison only.
* :mod:`.run`: ``simulate_nve``, ``simulate_langevin``, ``simulate_exact`` writing ``.dtraj``.
"""
from .boundary import BoundaryConditions
from .exact import ExactSystem, integrate_exact, strain_rates
from .splitting import RigidState, SplittingIntegrator, omega_max, stable_time_step

__all__ = [
    "BoundaryConditions", "ExactSystem", "integrate_exact", "strain_rates",
    "RigidState", "SplittingIntegrator", "omega_max", "stable_time_step",
]
