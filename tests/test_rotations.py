"""Cayley chart (design A1, A6 item 1)."""
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dnarod.core.errors import GeometryError
from dnarod.core.rotations import axial, cayley, cayley_inverse, cayley_T, check_frames, hat, rotation_about_axis
from dnarod.core.strains import strains, strains_dot_form

from conftest import random_chain


def test_hat_axial_cross():
    rng = np.random.default_rng(0)
    v, x = rng.normal(size=(2, 10, 3))
    assert np.allclose(hat(v) @ x[..., None], np.cross(v, x)[..., None], atol=1e-14)
    assert np.allclose(axial(hat(v)), v, atol=0)


def test_cayley_round_trip_and_angle():
    R = Rotation.random(500, random_state=1)
    angle = R.magnitude()
    keep = angle < np.pi - 1e-3
    M = R.as_matrix()[keep]
    w = cayley_inverse(M)
    assert np.abs(cayley(w) - M).max() < 1e-12
    # |w| = 2 tan(theta/2) along the rotation axis (scipy's rotation vector is independent of our code)
    rv = R.as_rotvec()[keep]
    expected = 2 * np.tan(angle[keep] / 2)[:, None] * rv / angle[keep][:, None]
    assert np.allclose(w, expected, rtol=1e-10, atol=1e-12)


def test_cayley_T_is_derivative():
    """T(w)^T dTheta = dw for a body rotation of the second frame, and T^T = R T."""
    rng = np.random.default_rng(3)
    for w in rng.normal(0, 1.0, (5, 3)):
        R, T = cayley(w), cayley_T(w)
        assert np.allclose(T.T, R @ T, atol=1e-13)
        h = 1e-6
        J = np.empty((3, 3))
        for a in range(3):
            dR = rotation_about_axis(np.eye(3)[a], h)
            J[:, a] = (cayley_inverse(R @ dR) - cayley_inverse(R @ dR.T)) / (2 * h)
        assert np.allclose(J, T.T, atol=1e-8)


def test_dot_product_form_equals_matrix_form(chain):
    pos, frm, _, ds = chain
    Om1, Ga1 = strains(pos, frm, ds)
    Om2, Ga2 = strains_dot_form(pos, frm, ds)
    assert np.abs(Om1 - Om2).max() <= 1e-12 * np.abs(Om1).max()
    assert np.abs(Ga1 - Ga2).max() <= 1e-12 * np.abs(Ga1).max()


def test_rotation_at_pi_is_rejected_naming_the_step():
    pos, frm, _, ds = random_chain(0, n=5)
    frm = frm.copy()
    frm[3] = frm[2] @ rotation_about_axis(np.array([0.0, 0.0, 1.0]), np.pi)
    with pytest.raises(GeometryError, match=r"step 3 \(base pairs 3-4\).*180"):
        strains(pos, frm, ds)


def test_bad_frames_are_named():
    frm = np.tile(np.eye(3), (4, 1, 1))
    bad = frm.copy()
    bad[2] = np.diag([1.0, 1.0, -1.0])
    with pytest.raises(GeometryError, match="base pair 3.*left-handed"):
        check_frames(bad)
    bad = frm.copy()
    bad[1] *= 1.01
    with pytest.raises(GeometryError, match="base pair 2.*not orthonormal"):
        check_frames(bad)
    bad = frm.copy()
    bad[3, 0, 0] = np.nan
    with pytest.raises(GeometryError, match="base pair 4.*non-finite"):
        check_frames(bad)


def test_rotation_about_axis_normalises_and_rejects_zero_axis():
    R = rotation_about_axis(np.array([0.3, -0.5, 0.8]), 0.7)
    assert np.allclose(R @ R.T, np.eye(3), atol=1e-14) and np.isclose(np.linalg.det(R), 1.0)
    assert np.allclose(R, Rotation.from_rotvec(0.7 * np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])).as_matrix())
    with pytest.raises(GeometryError, match="zero length"):
        rotation_about_axis(np.zeros(3), 0.1)
