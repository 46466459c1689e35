"""Trajectory analysis (the MDAnalysis pattern: build, ``run()`` returns self, read ``.results``).

* :mod:`~dnarod.analysis.steps`: per-frame step parameters and strains (:class:`StepAnalysis`).
* :mod:`~dnarod.analysis.stiffness`: per-step-type means, covariances and the Haar-reweighted
  stiffness estimate (:class:`StiffnessFit`), written as a force field dnarod loads.
* :mod:`~dnarod.analysis.polymer`: tangent correlation and persistence length
  (:class:`TangentCorrelation`), :class:`EndToEnd`, and for rings :class:`LinkingNumber`.
* :mod:`~dnarod.physics.writhe`: writhe, twist and linking number of closed polygons.
* :mod:`~dnarod.analysis.allatom`: all-atom trajectories to node trajectories.
* :mod:`~dnarod.analysis.plots`: figures; :mod:`~dnarod.cli.analyze`: ``dnarod analyze``.
"""
from dnarod.analysis.base import AnalysisBase, Results
from dnarod.analysis.polymer import EndToEnd, LinkingNumber, TangentCorrelation
from dnarod.analysis.steps import StepAnalysis
from dnarod.analysis.stiffness import StiffnessFit

__all__ = ["AnalysisBase", "Results", "StepAnalysis", "StiffnessFit", "TangentCorrelation", "EndToEnd",
           "LinkingNumber"]
