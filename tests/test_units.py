"""dnarod's unit factors against OpenMM's unit system (an independent implementation)."""
import numpy as np
import pytest
from openmm import unit

from dnarod.core import units
from dnarod.physics.thermal import kinetic_temperature, node_kinetic_energy


def test_constants_match_openmm_units():
    md_force = unit.kilojoule_per_mole / unit.nanometer
    assert units.PN == pytest.approx((1 * unit.piconewton * unit.AVOGADRO_CONSTANT_NA).value_in_unit(md_force),
                                     rel=1e-12)
    assert units.BOLTZMANN == pytest.approx(
        unit.MOLAR_GAS_CONSTANT_R.value_in_unit(unit.kilojoule_per_mole / unit.kelvin), rel=1e-9)
    assert units.PA == pytest.approx((1 * unit.pascal * unit.AVOGADRO_CONSTANT_NA * unit.nanometer**3)
                                     .value_in_unit(unit.kilojoule_per_mole), rel=1e-12)
    assert units.KG_PER_M3 == pytest.approx((1 * unit.kilogram / unit.meter**3 * unit.AVOGADRO_CONSTANT_NA)
                                            .value_in_unit(unit.amu / unit.nanometer**3), rel=1e-9)


def test_node_kinetic_energy_and_temperature():
    rng = np.random.default_rng(0)
    m = rng.uniform(1, 3, 5)
    J = rng.uniform(1, 3, (5, 3))
    v, w = rng.normal(size=(2, 4, 5, 3))  # 4 frames
    ke = node_kinetic_energy(m, J, v, w)
    loop = [sum(0.5 * m[k] * v[f, k] @ v[f, k] + 0.5 * J[k] @ w[f, k] ** 2 for k in range(5)) for f in range(4)]
    assert np.allclose(ke, loop, rtol=1e-14)
    # equipartition: kT/2 per degree of freedom
    assert kinetic_temperature(30 * units.BOLTZMANN * 300 / 2, 30) == pytest.approx(300.0, rel=1e-14)
    assert kinetic_temperature(1.0, 0) == 0.0
