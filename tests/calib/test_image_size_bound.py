"""Image sizes beyond any sensor are rejected before they reach OpenCV's 32-bit sizes."""

from __future__ import annotations

import pytest

from calib.checks import MAX_IMAGE_SIDE_PX, check_image_size


def test_the_largest_side_is_accepted() -> None:
    assert check_image_size((MAX_IMAGE_SIDE_PX, 1)) == (MAX_IMAGE_SIDE_PX, 1)


@pytest.mark.parametrize("size", [(MAX_IMAGE_SIDE_PX + 1, 240), (320, 2**31), (2**63, 2**63)])
def test_larger_sides_are_a_value_error(size) -> None:
    with pytest.raises(ValueError, match=rf"at most {MAX_IMAGE_SIDE_PX} px a side, got"):
        check_image_size(size)


def test_a_size_beyond_floats_is_a_value_error() -> None:
    with pytest.raises(ValueError, match=r"image_size must be \(width, height\)"):
        check_image_size((float("inf"), 240))
