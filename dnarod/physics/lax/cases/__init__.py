"""The special cases of the paper's Sections IV-V as small usable models with their conserved quantities.

* :class:`StaticRod` -- static discrete rod (4.1)/(4.3) as a shooting map (Case 1, Subcase 1.1);
* :class:`HeavyTop` -- (4.5) read as the heavy top, Lagrange and Kowalewski integrals (Subcase 1.2);
* :class:`KirchhoffBody` -- rigid body in an ideal fluid, (5.1), with its Casimirs (Case 2);
* :class:`KirchhoffRod` -- discrete Kirchhoff rod (6.2) with the inextensibility constraint (Case 3);
* :func:`planar_rhs` -- the planar rod (7.1) (Case 4);
* :func:`curvature_torsion` and the tetrad matrices (8.1)-(8.3) (Case 5).
"""
from dnarod.physics.lax.cases.curve import (arclength, curvature_torsion, frenet_step_matrix,
                                            printed_tetrad_step_matrix, tetrad_step_matrix,
                    tetrad_velocity_matrix)
from dnarod.physics.lax.cases.fluid import KirchhoffBody
from dnarod.physics.lax.cases.kirchhoff_rod import KirchhoffRod
from dnarod.physics.lax.cases.planar import PLANAR_U, PLANAR_V, planar_embed, planar_rhs
from dnarod.physics.lax.cases.static import StaticRod, static_stress_step
from dnarod.physics.lax.cases.top import HeavyTop

__all__ = [
    "StaticRod", "static_stress_step", "HeavyTop", "KirchhoffBody", "KirchhoffRod", "planar_rhs", "planar_embed",
    "PLANAR_U", "PLANAR_V", "arclength", "curvature_torsion", "tetrad_step_matrix", "tetrad_velocity_matrix",
    "printed_tetrad_step_matrix", "frenet_step_matrix",
]
