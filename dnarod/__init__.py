"""dnarod: coarse-grained DNA as a discrete shearable, extensible elastic rod.

Each base pair is a rigid node (position, frame); consecutive nodes interact through the
SMK elastic energy of Shi, McClain & Hearst (2001) in exact Cayley strains. See README.
"""
from dnarod.core.jit import ensure_numba_cache as _ensure_numba_cache

_ensure_numba_cache()  # before the first kernel is defined: numba caches them once per install

from dnarod.core.errors import DnarodError, GeometryError, ParameterError, SimulationError, StructureError
from dnarod.core.model import RodModel
from dnarod.core.parameters import StepParameters
from dnarod.core.strains import Closure, chain_from_strains, strains

__version__ = "0.1.0"

__all__ = [
    "DnarodError", "GeometryError", "ParameterError", "SimulationError", "StructureError",
    "RodModel", "StepParameters", "Closure", "strains", "chain_from_strains", "__version__",
]
