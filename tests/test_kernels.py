"""The compiled A2 loads (dnarod.core.kernels) against the numpy reference dnarod.core.energy.loads."""
import numpy as np
from scipy.spatial.transform import Rotation

from dnarod.core.energy import loads
from dnarod.core.kernels import loads_kernel
from dnarod.core.rotations import rotation_about_axis
from dnarod.core.strains import Closure

from conftest import random_chain


def _kernel(pos, frm, params, ds, closure):
    F = np.zeros_like(pos)
    T = np.zeros_like(pos)
    Q, t = (closure.Q, closure.t) if closure is not None else (np.eye(3), np.zeros(3))
    E = loads_kernel(pos, frm, params.stiffness, params.intrinsic, ds, Q, t, closure is not None, F, T)
    return E, F, T


def test_kernel_equals_numpy_reference_open_and_circular():
    for seed, circular in ((0, False), (1, False), (2, True)):
        pos, frm, params, ds = random_chain(seed, n=9, circular=circular)
        closure = Closure(Rotation.random(random_state=seed).as_matrix(), np.array([0.2, 0.1,
                                                                                    0.9])) if circular else None
        E0, F0, T0 = loads(pos, frm, params, ds, closure)
        E1, F1, T1 = _kernel(pos, frm, params, ds, closure)
        assert abs(E1 - E0) <= 1e-12 * abs(E0)
        assert np.abs(F1 - F0).max() <= 1e-12 * np.abs(F0).max()
        assert np.abs(T1 - T0).max() <= 1e-12 * np.abs(T0).max()


def test_kernel_returns_nan_at_the_cayley_limit():
    pos, frm, params, ds = random_chain(3, n=5)
    frm = frm.copy()
    frm[2] = frm[1] @ rotation_about_axis(np.array([1.0, 0.0, 0.0]), np.pi)
    assert np.isnan(_kernel(pos, frm, params, ds, None)[0])
