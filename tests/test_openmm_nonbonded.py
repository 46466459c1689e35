"""Non-local terms: cell-list kernel vs all-pairs reference, gradients, physical constants."""
import numpy as np
import pytest

from dnarod.errors import GeometryError, ParameterError
from dnarod.forcefield import load_forcefield
from dnarod.openmm.nonbonded import NonbondedSettings, NonbondedCallback, nonbonded_reference
from dnarod.openmm.system import build_system


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
    assert v["charge"] == pytest.approx(0.34 / v["bjerrum"], rel=1e-12)
    assert v["n_exclude"] == int(np.ceil(v["cutoff"] / 0.34))
    with pytest.raises(ParameterError, match="salt"):
        NonbondedSettings(salt=-1).resolve(0.34, 300)


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
    m = ff.model_from_sequence("A" * 30)
    pos = m.positions.copy()
    pos[20] = pos[2] + [0.3, 0.0, 0.0]  # far along the chain, 0.3 nm apart in space
    bad = m.with_pose(pos, m.frames)
    with pytest.raises(GeometryError, match=r"nodes [12] and 20 overlap"):
        build_system(bad)
    pos[20] = pos[2]  # coincident centres: rejected even without excluded volume
    with pytest.raises(GeometryError, match="overlap"):
        build_system(m.with_pose(pos, m.frames), nonbonded=False)
