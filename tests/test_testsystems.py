"""Analytic test systems (design A5 i-ii): helix closed form and the twisted-rod dispersion."""
import numpy as np
import pytest

from dnarod.core.errors import ParameterError
from dnarod.engines.lax import omega_max
from dnarod.physics.modes import normal_modes
from dnarod.physics.testsystems import TwistedRod, UniformHelix


@pytest.mark.parametrize("Om, Ga", [([0.3, -0.5, 1.8], [0.1, 0.05, 1.0]), ([0.0, 0.9, 0.4], [0.2, -0.1, 0.9])])
def test_helix_closed_form(Om, Ga):
    h = UniformHelix(Om, Ga, 0.34, 30)
    r, R = h.closed_form()
    model = h.model()
    assert np.abs(r - model.positions).max() < 1e-10
    assert np.abs(R - model.frames).max() < 1e-12
    Omega, Gamma = model.strains()
    assert np.abs(Omega - Om).max() < 1e-10 and np.abs(Gamma - Ga).max() < 1e-10
    E, F, tau = model.loads()
    assert abs(E) < 1e-20 and np.abs(F).max() < 1e-10 and np.abs(tau).max() < 1e-10
    # every node is at the helix radius from the axis through p along n
    n = h.axis
    b = h.ds * np.asarray(Ga)
    bp = b - (b @ n) * n
    p = 0.5 * (bp + np.cross(n, bp) / np.tan(h.rotation_per_step / 2))
    d = r - p
    dist = np.linalg.norm(d - np.outer(d @ n, n), axis=1)
    assert np.abs(dist - h.radius).max() < 1e-12
    assert abs(h.pitch - 2 * np.pi * h.rise_per_step / h.rotation_per_step) < 1e-15


def test_helix_needs_curvature():
    with pytest.raises(ParameterError, match="nonzero Omega0"):
        UniformHelix([0, 0, 0], [0, 0, 1], 0.34, 5)


@pytest.mark.parametrize("rod", [
    TwistedRod(16),                                         # closure rotation alpha != 0 mod 2 pi
    TwistedRod(20, theta0=2 * np.pi / 10),                  # alpha = 0
    TwistedRod.from_forcefield("dna-default", 16),          # with twist-stretch coupling B33
    TwistedRod(12, A1=50.0, A3=300.0, C1=900.0, C3=400.0, J1=80.0, J3=160.0, mass=300.0, theta0=0.9),
], ids=["alpha", "ring", "dna-default", "other"])
def test_hessian_spectrum_equals_dispersion(rod):
    w_num, _ = normal_modes(rod.model())
    w_an = rod.all_frequencies()
    assert np.abs(np.sort(np.abs(w_num)) - w_an).max() < 1e-6
    assert abs(omega_max(rod.model()) - rod.omega_max()) < 1e-6


def test_dispersion_long_wave_limits():
    rod = TwistedRod(400)
    d = rod.dispersion()
    j = 1
    q = d["q_axial"][j]
    sec = 1 / np.cos(rod.theta0 / 2)
    rho, I3 = rod.mass / rod.ds, rod.J3 / rod.ds
    assert abs(d["stretch"][j] / q - np.sqrt(rod.C3 / rho)) < 1e-4 * np.sqrt(rod.C3 / rho)
    assert abs(d["twist"][j] / q - np.sqrt(rod.A3 * sec**4 / I3)) < 1e-4 * np.sqrt(rod.A3 * sec**4 / I3)
    # Timoshenko shear gap at q = 0
    gap = TwistedRod(20, theta0=2 * np.pi / 10).dispersion()["bend_shear_high"][0]
    assert abs(gap - np.sqrt(rod.C1 * rod.ds / rod.J1)) < 1e-12
