"""Shared fixtures: random heterogeneous chains (design A6 item 3)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dnarod.parameters import StepParameters
from dnarod.strains import chain_from_strains


def random_chain(seed, n=8, ds=0.34, twist=0.6, circular=False):
    """A random heterogeneous chain: intrinsic twist ``twist`` rad/step plus random bend and shear,
    its own random SPD 6x6 stiffness per step, and a pose with step rotations up to ~1.6 rad."""
    rng = np.random.default_rng(seed)
    m = n if circular else n - 1
    Omega = rng.normal(0.0, 0.6, (n - 1, 3))
    Omega[:, 2] += 2.0 / ds * np.tan(twist / 2)
    Gamma = rng.normal(0.0, 0.15, (n - 1, 3)) + [0.0, 0.0, 1.0]
    frame0 = Rotation.random(random_state=seed).as_matrix()
    pos, frm = chain_from_strains(Omega, Gamma, ds, r0=rng.normal(size=3), frame0=frame0)
    K = []
    for _ in range(m):
        X = rng.normal(size=(6, 6))
        K.append(100.0 * (X @ X.T + 2.0 * np.eye(6)))
    xi0 = rng.normal(0.0, 0.3, (m, 6))
    xi0[:, 2] += 2.0 / ds * np.tan(twist / 2)
    xi0[:, 5] += 1.0
    return pos, frm, StepParameters(np.array(K), xi0), ds


@pytest.fixture(params=[0, 1, 2, 3, 4])
def chain(request):
    return random_chain(request.param)
