"""Non-local terms: cell-list kernel vs all-pairs reference, gradients, physical constants."""
import numpy as np
import pytest

from dnarod.core.errors import GeometryError, ParameterError
from dnarod.core.forcefield import load_forcefield
from dnarod.engines.openmm.nonbonded import NonbondedCallback
from dnarod.physics.nonbonded import NonbondedSettings, nonbonded_reference
from dnarod.engines.openmm.system import build_system


def random_walk(n, step=0.34, seed=0):
    """A compact random chain (many non-excluded pairs inside the cutoffs)."""
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    d *= step / np.linalg.norm(d, axis=1, keepdims=True)
    return np.cumsum(d, axis=0) + rng.uniform(-5, 5, size=3)


def test_debye_and_bjerrum_lengths():
    v = NonbondedSettings(salt=0.15).resolve(0.34, 298.15)
    # l_B = 0.7 nm in water at 25 C; Debye length 0.304/sqrt(I[M]) nm (e.g. Israelachvili).
    assert v["bjerrum"] == pytest.approx(0.7135, rel=2e-3)
    assert v["debye_length"] == pytest.approx(0.304 / np.sqrt(0.15), rel=5e-3)
    assert v["n_exclude"] == int(np.ceil(v["cutoff"] / 0.34))
    assert v["cutoff"] == pytest.approx(12.0 * v["debye_length"], rel=1e-12)
    with pytest.raises(ParameterError, match="salt"):
        NonbondedSettings(salt=-1).resolve(0.34, 300)


def test_charge_models():
    from dnarod.physics.nonbonded import CALIBRATED_LINE_CHARGE

    cal = NonbondedSettings(salt=0.15).resolve(0.34, 300.0)
    # at the calibration salt the Poisson-Boltzmann far-field charge of the calibrated cylinder is the calibrated
    # line charge (radius given to 1 pm: 0.03 % in charge, 0.0005 nm in diameter)
    assert (cal["charge"], cal["charge_model"]) == (pytest.approx(CALIBRATED_LINE_CHARGE * 0.34, rel=5e-4),
                                                    "calibrated")
    assert NonbondedSettings(charge="calibrated").resolve(0.17, 300.0)["charge"] == pytest.approx(0.5 * cal["charge"])
    q = [NonbondedSettings(salt=c).resolve(0.34, 300.0)["charge"] for c in (0.01, 0.05, 0.15, 0.5)]
    assert q[0] < q[1] < q[2] < q[3]  # a thick cylinder's equivalent axis charge grows as the screening shortens
    # Manning: one elementary charge per Bjerrum length of chain (0.48 e per bp at 300 K); None keeps that meaning
    for q in ("manning", " Manning", None):
        v = NonbondedSettings(charge=q).resolve(0.34, 300.0)
        assert v["charge"] == pytest.approx(0.34 / v["bjerrum"], rel=1e-12) and v["charge_model"] == "manning"
    assert NonbondedSettings(charge=1.25).resolve(0.34, 300.0)["charge"] == 1.25
    for bad in ("stigter", -1.0, float("nan"), [1.0]):
        with pytest.raises(ParameterError, match="charge"):
            NonbondedSettings(charge=bad).resolve(0.34, 300.0)


@pytest.mark.parametrize("circular", [False, True])
@pytest.mark.parametrize("salt", [0.15, 0.02])
@pytest.mark.parametrize("spread", [False, True])
def test_cell_list_equals_all_pairs(circular, salt, spread):
    c = random_walk(400, seed=1 if circular else 2)
    if spread:  # a huge bounding box: the kernel switches from the dense grid to spatial hashing
        c[200:] += [3e4, -2e4, 1e4]
    v = NonbondedSettings(salt=salt, n_exclude=3).resolve(0.34, 300.0)
    cb = NonbondedCallback(len(c), circular, v)
    ew, ed, F = cb.evaluate(c)
    ew0, ed0, F0 = nonbonded_reference(c, circular, v)
    assert ew0 > 0 and ed0 > 0  # the test geometry exercises both terms
    assert ew == pytest.approx(ew0, rel=1e-12) and ed == pytest.approx(ed0, rel=1e-12)
    assert np.abs(F - F0).max() <= 1e-10 * np.abs(F0).max()


def test_forces_are_the_gradient():
    c = random_walk(120, seed=4)
    v = NonbondedSettings(n_exclude=3).resolve(0.34, 300.0)
    cb = NonbondedCallback(len(c), False, v)
    _, _, F = cb.evaluate(c)
    rng = np.random.default_rng(5)
    h = 1e-6
    for _ in range(3):
        d = rng.normal(size=c.shape)
        Ep = sum(cb.evaluate(c + h * d)[:2])
        Em = sum(cb.evaluate(c - h * d)[:2])
        assert (Ep - Em) / (2 * h) == pytest.approx(-np.sum(F * d), rel=1e-6)


def test_overlapping_nodes_are_rejected():
    ff = load_forcefield("dna-default")
    m = ff.model_from_sequence("A" * 60)
    pos = m.positions.copy()
    # far along the chain (beyond the default exclusion, 28 bp at 0.15 M), 0.3 nm apart in space
    pos[40] = pos[2] + [0.3, 0.0, 0.0]
    bad = m.with_pose(pos, m.frames)
    with pytest.raises(GeometryError, match=r"nodes [1-4] and 40 overlap"):
        build_system(bad)
    pos[40] = pos[2]  # coincident centres: rejected even without excluded volume
    with pytest.raises(GeometryError, match="overlap"):
        build_system(m.with_pose(pos, m.frames), nonbonded=False)


@pytest.mark.parametrize("gamma", [np.pi / 2, np.pi / 4])
def test_crossing_diameter_of_line_charges_matches_the_continuum_formula(gamma):
    # Two straight lines of charge nu (e/nm) crossing at angle gamma, closest distance h, interact through the
    # Debye-Hueckel energy U/kT = 2 pi nu^2 l_B exp(-kappa h) / (kappa sin gamma) (integrate exp(-kappa r)/r over
    # the plane spanned by the lines, area element ds1 ds2 sin gamma). Sites 0.1 nm apart, no core, cutoff 12
    # Debye lengths (the shift is then e^-12 per pair): the site sum must reproduce it.
    from dnarod.physics.nonbonded import crossing_diameter
    from dnarod.core.units import kT

    ds = 0.1
    nb = NonbondedSettings(salt=0.1, excluded_volume=False, cutoff_debye=12.0, charge=0.2).resolve(ds, 300.0)
    h = np.linspace(0.0, nb["cutoff"], 600)
    d = crossing_diameter(nb, ds, gamma, kT(300.0), 1, h)
    nu, k = nb["charge"] / ds, nb["kappa"]
    U = 2 * np.pi * nu**2 * nb["bjerrum"] * np.exp(-k * h) / (k * np.sin(gamma))
    assert d == pytest.approx(np.trapezoid(-np.expm1(-U), h), rel=3e-3)


def test_poisson_boltzmann_far_field_charge():
    """Linearised limit (small bare charge): nu = bare / (kappa a K1(kappa a)), the Debye-Hueckel cylinder; the
    nonlinear charge is below the linearised one (saturation); the calibrated radius reproduces the constant."""
    from scipy.special import k1

    from dnarod.physics.nonbonded import (BARE_LINE_CHARGE, CALIBRATED_LINE_CHARGE, CALIBRATED_RADIUS,
                                          calibrated_radius, pb_far_field_line_charge)

    for salt, a in ((0.01, 1.0), (0.15, 1.159), (1.0, 0.8)):
        k = NonbondedSettings(salt=salt).resolve(0.34, 300.0)["kappa"]
        small = 1e-3
        assert pb_far_field_line_charge(salt, 300.0, radius=a, bare=small) == pytest.approx(
            small / (k * a * k1(k * a)), rel=1e-4)
        lin = BARE_LINE_CHARGE / (k * a * k1(k * a))
        assert 0 < pb_far_field_line_charge(salt, 300.0, radius=a) < lin
    assert calibrated_radius() == pytest.approx(CALIBRATED_RADIUS, abs=1e-3)
    assert pb_far_field_line_charge(0.15, 300.0) == pytest.approx(CALIBRATED_LINE_CHARGE, rel=5e-4)
    with pytest.raises(ParameterError, match="Poisson-Boltzmann"):
        pb_far_field_line_charge(0.15, 300.0, radius=-1.0)


def test_effective_diameter_of_the_default_potential():
    from dnarod.physics.nonbonded import CALIBRATION, effective_diameter

    sigma = 2.0
    grid = dict(n_angles=12, n_phase=2, n_h=200)  # agrees with finer grids to 1e-4 nm at 0.15 M (README)
    d_wca = effective_diameter(NonbondedSettings(electrostatics=False, diameter=sigma), 0.34, 300.0, **grid)
    # f = 1 - exp(-U/kT) <= 1 and U = 0 beyond the WCA cutoff 2^(1/6) sigma; inside sigma the many overlapping
    # sites make U >> kT
    assert 0.95 * sigma < d_wca < 2 ** (1 / 6) * sigma
    # the calibrated charge reproduces the Poisson-Boltzmann second-virial diameter, 5.0 nm at 0.15 M, 300 K
    d = {c: effective_diameter(NonbondedSettings(salt=c), 0.34, 300.0, **grid) for c in (0.15, 0.5)}
    assert d[0.15] == pytest.approx(CALIBRATION["diameter_nm"], abs=0.03)
    assert d[0.15] > d[0.5] > d_wca
    # Manning's charge with the old 5-Debye-length cutoff (README): 2.31 nm at 0.15 M, capped by that cutoff
    old = NonbondedSettings(salt=0.15, charge="manning", cutoff_debye=5.0)
    assert effective_diameter(old, 0.34, 300.0, **grid) == pytest.approx(2.31, abs=0.02)


@pytest.mark.slow
def test_calibrated_line_charge_is_recomputed():
    from dnarod.physics.nonbonded import CALIBRATED_LINE_CHARGE, calibrated_line_charge

    nu = calibrated_line_charge(tol_nm=0.005)
    assert nu == pytest.approx(CALIBRATED_LINE_CHARGE, rel=0.01)
