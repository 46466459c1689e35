"""Physical constants and unit factors: the one place dnarod converts units.

Internal units are OpenMM's MD units (nm, ps, kJ/mol, amu, K, rad); these factors convert
at the edges. Values are CODATA 2018 exact or recommended values, the ones OpenMM uses.
"""
AVOGADRO = 6.02214076e23  # 1/mol (exact)
BOLTZMANN = 0.00831446261815324  # kJ/mol/K (k_B N_A, exact)
PN = AVOGADRO * 1e-24  # kJ/mol/nm per pN, and kJ/mol per pN nm (0.602214076)
AMU_KG = 1.66053906660e-27  # kg per amu
PA = AVOGADRO * 1e-30  # kJ/mol/nm^3 per Pa
KG_PER_M3 = 1e-27 / AMU_KG  # amu/nm^3 per kg/m^3
