"""Writing images as PNG files (OpenCV; no MuJoCo, so image tools need no OpenGL)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray


def save_png(image: NDArray[np.uint8] | NDArray[np.uint16], path: str | Path) -> Path:
    """Write an (H, W, 3) RGB or (H, W) grey image (8 or 16 bits) as PNG; return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    img = np.asarray(image)
    if img.ndim == 3:
        img = img[:, :, ::-1]
    if not cv2.imwrite(str(path), np.ascontiguousarray(img)):
        raise OSError(f"could not write {path}")
    return path
