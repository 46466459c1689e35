"""Monte Carlo engine of the exact rod model (equilibrium sampling; run-layer engine ``"mc"``)."""
from dnarod.engines.mc.engine import MCEngine

__all__ = ["MCEngine"]
