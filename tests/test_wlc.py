"""Worm-like-chain references against published numbers and internal consistency."""
import numpy as np
import pytest

from dnarod.physics.theory.wlc import bouchiat_force, extensible_wlc_extension, marko_siggia_force, odijk_extension


def test_odijk_reference_numbers():
    # lumicks-pylake 1.8.0 test values (data/physical/wlc_formulas.md section 3): Lp 50 nm, L 16 um, S 1500 pN
    x = 16.0 * odijk_extension(np.array([0.1, 0.2, 0.3]), 50.0, 1500.0, 4.11)
    assert np.allclose(x, [8.74792941, 10.8733908, 11.81559925], rtol=1e-8)


def test_bouchiat_limits_and_inverse():
    kt, lp = 4.11, 50.0
    assert bouchiat_force(0.0, lp, kt) == 0.0
    # small extension: linear response F = 3 kT l / (2 lp) (Gaussian chain); the correction starts at l^2
    assert bouchiat_force(1e-6, lp, kt) == pytest.approx(1.5 * kt / lp * 1e-6, rel=1e-5)
    # the correction is negative and below 15% of Marko-Siggia everywhere (measured maximum 14.3% at l ~ 0.5)
    l = np.linspace(0.05, 0.97, 50)
    assert np.all((r := bouchiat_force(l, lp, kt) / marko_siggia_force(l, lp, kt) - 1) < 0) and np.all(r > -0.15)
    # inverse: inextensible limit (huge S) recovers l
    for F in (0.1, 1.0, 10.0):
        lx = extensible_wlc_extension(F, lp, 1e15, kt)
        assert bouchiat_force(lx, lp, kt) == pytest.approx(F, rel=1e-10)
    # at high force the Odijk form and the Bouchiat form agree (within the 1e-3 of its validity)
    assert extensible_wlc_extension(10.0, lp, 1100.0, kt) == pytest.approx(odijk_extension(10.0, lp, 1100.0, kt),
                                                                           abs=3e-3)
