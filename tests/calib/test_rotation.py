"""The one home of the rotation helpers: skew matrices and angle wrapping over arrays."""

import math

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from calib.rotation import compose_planar, invert_planar, rot_z, skew, wrap_angle

finite = st.floats(-1e3, 1e3, allow_nan=False)


@given(a=st.tuples(finite, finite, finite), b=st.tuples(finite, finite, finite))
def test_skew_is_the_cross_product(a, b):
    np.testing.assert_allclose(skew(a) @ np.array(b), np.cross(a, b), rtol=1e-12, atol=1e-9)


def test_skew_takes_any_leading_shape():
    v = np.arange(24.0).reshape(2, 4, 3)
    s = skew(v)
    assert s.shape == (2, 4, 3, 3)
    np.testing.assert_array_equal(s[1, 2], skew(v[1, 2]))
    np.testing.assert_array_equal(s, -np.swapaxes(s, -1, -2))


def test_skew_refuses_a_vector_that_is_not_3d():
    with np.testing.assert_raises_regex(ValueError, r"\(\.\.\., 3\)"):
        skew([1.0, 2.0])


@given(angle=st.floats(-1e4, 1e4, allow_nan=False))
def test_a_wrapped_angle_lies_in_range_and_turns_the_same(angle):
    w = wrap_angle(angle)
    assert isinstance(w, float)
    assert -math.pi <= w < math.pi
    assert math.isclose(math.cos(w), math.cos(angle), abs_tol=1e-9)
    assert math.isclose(math.sin(w), math.sin(angle), abs_tol=1e-9)


@given(angles=st.lists(st.floats(-1e4, 1e4, allow_nan=False), min_size=1, max_size=20))
def test_arrays_wrap_bit_for_bit_as_floats(angles):
    wrapped = wrap_angle(np.array(angles))
    assert wrapped.shape == (len(angles),)
    assert [float(w) for w in wrapped] == [wrap_angle(a) for a in angles]


def test_wrapping_known_angles():
    assert wrap_angle(math.pi) == -math.pi
    assert wrap_angle(-math.pi) == -math.pi
    assert wrap_angle(3 * math.pi / 2) == -math.pi / 2
    np.testing.assert_allclose(rot_z(wrap_angle(7.0)), rot_z(7.0), atol=1e-12)


_poses = st.tuples(st.floats(-100.0, 100.0), st.floats(-100.0, 100.0), st.floats(-math.pi, math.pi))


@given(a=_poses, b=_poses, c=_poses)
def test_planar_poses_compose_as_homogeneous_transforms(a, b, c):
    def matrix(p):
        m = np.eye(3)
        m[:2, :2] = rot_z(p[2])[:2, :2]
        m[:2, 2] = p[:2]
        return m

    ab = compose_planar(a, b)
    np.testing.assert_allclose(matrix(ab), matrix(a) @ matrix(b), atol=1e-9)
    np.testing.assert_allclose(
        compose_planar(compose_planar(a, b), c), compose_planar(a, compose_planar(b, c)), atol=1e-9
    )
    np.testing.assert_allclose(compose_planar(invert_planar(a), a), np.zeros(3), atol=1e-9)
    np.testing.assert_allclose(compose_planar(a, invert_planar(a)), np.zeros(3), atol=1e-9)
