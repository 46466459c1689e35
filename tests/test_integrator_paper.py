"""The paper's printed (3.13) against the exact system: O(ds) distance and linear instability (design A3, C4)."""
import numpy as np
import pytest

from dnarod.core.errors import DnarodError
from dnarod.engines.lax.paper_scheme import distance_to_exact, growth_rate, integrate_paper
from dnarod.physics.testsystems import TwistedRod

TAU0 = 1.81446558193  # dna-default intrinsic twist, 1/nm


@pytest.fixture(scope="module")
def dna_ring():
    return TwistedRod.from_forcefield("dna-default", 12).model()


def test_paper_scheme_grows_exact_does_not(dna_ring):
    rate_paper = growth_rate(dna_ring, "paper")
    rate_exact = growth_rate(dna_ring, "exact")
    print("growth rates (1/ps): paper", rate_paper, "exact", rate_exact)
    assert rate_paper > 1.0
    assert abs(rate_exact) < 1e-6


def test_paper_scheme_is_order_ds_from_exact():
    L = 32 * 0.34

    def make(n):
        ds = L / n
        return TwistedRod.from_forcefield("dna-default", n, ds=ds, theta0=2 * np.arctan(0.5 * ds * TAU0),
                                          mass=650 / 0.34 * ds, J1=117 / 0.34 * ds, J3=234 / 0.34 * ds).model()

    d = distance_to_exact(make, (32, 64, 128))
    print("distance", d["distance"], "order", d["order"])
    assert np.all(np.abs(d["order"] - 1.0) < 0.15)
    assert np.all(np.diff(d["distance"], axis=0) < 0)


def test_integrating_paper_scheme_blows_up(dna_ring):
    rng = np.random.default_rng(0)
    t, E, ok = integrate_paper(dna_ring, 2.0, omega=1e-3 * rng.standard_normal((12, 3)), n_frames=5)
    assert E[-1] > 100 * E[0] or not ok


def test_needs_periodic_chain():
    from dnarod.physics.testsystems import dna_like_rod

    with pytest.raises(DnarodError, match="circular"):
        growth_rate(dna_like_rod(6))
