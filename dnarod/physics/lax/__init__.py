"""The Lax pair of Shi, McClain & Hearst (2001) as a library, with the corrections listed in docs/lax.md.

* :mod:`.generators` -- SO(4) generators J_a, K_a (3.1), X^+/- decomposition, so(4) projections;
* :mod:`.pair` -- the 4x4 complex pair U~ = 1 + ds U, V~ = V (3.3)-(3.7), the exact residual of
  (3.8), the symmetric obstruction {V_{k+1} - V_k, U_k}, and the 8x8 real pair of Appendix A;
* :mod:`.components` -- the 12 component equations (3.9) for any real lam and the s-discrete SMK
  equations (3.13), each in the paper's entrywise reading "R1" (corrected) and the covariant
  "midpoint" reading;
* :mod:`~dnarod.physics.lax.monodromy` -- T(lam) = U~_{N-1}...U~_0 and tr T^n;
* :mod:`.cases` -- the special cases of Sections IV-V.

See docs/lax.md for the corrected equations and the misprint table as implemented.
"""
from dnarod.physics.lax.components import appendix_rhs, component_rhs, smk_rhs
from dnarod.physics.lax.generators import (D_FLIP, XMINUS, XPLUS, J, K, commutator, so4_coefficients, so4_matrix,
                         xpm_coefficients)
from dnarod.physics.lax.monodromy import monodromy, monodromy_from_matrices, spectral_invariants
from dnarod.physics.lax.pair import (U_matrix, V_matrix, appendix_pair, appendix_residual, appendix_to_paper, complexify, lax_pair,
                   lax_residual, realify, so4_to_fields, symmetric_obstruction)

__all__ = [
    "J", "K", "XPLUS", "XMINUS", "D_FLIP", "commutator", "so4_matrix", "so4_coefficients", "xpm_coefficients",
    "U_matrix", "V_matrix", "lax_pair", "lax_residual", "symmetric_obstruction", "so4_to_fields",
    "realify", "complexify", "appendix_pair", "appendix_to_paper", "appendix_residual",
    "component_rhs", "smk_rhs", "appendix_rhs",
    "monodromy", "monodromy_from_matrices", "spectral_invariants",
]
