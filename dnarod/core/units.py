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
NM_PER_ANGSTROM = 0.1  # nm per Angstrom (PDB, DCD, 3DNA lengths)
ANGSTROM_PER_NM = 10.0  # Angstrom per nm


def md_value(quantity):
    """The value of an ``openmm.unit.Quantity`` in OpenMM's MD units (nm, ps, kJ/mol, ...); plain numbers pass."""
    if hasattr(quantity, "value_in_unit_system"):
        from openmm import unit

        return quantity.value_in_unit_system(unit.md_unit_system)
    return quantity


def kT(temperature):
    """Thermal energy at ``temperature`` (K), kJ/mol."""
    return BOLTZMANN * float(temperature)
