"""Writing images as PNG files (OpenCV; no MuJoCo, so image tools need no OpenGL)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

from twin.outputs import write_bytes_atomic


def save_png(image: NDArray[np.uint8] | NDArray[np.uint16], path: str | Path) -> Path:
    """Write an (H, W, 3) RGB or (H, W) grey image (8 or 16 bits) as PNG, whatever the
    file's name says, atomically (:func:`twin.outputs.write_bytes_atomic`); return the path."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    img = np.asarray(image)
    if img.ndim == 3:
        img = img[:, :, ::-1]
    ok, data = cv2.imencode(".png", np.ascontiguousarray(img))
    if not ok:
        raise OSError(f"could not encode {path} as PNG")
    return write_bytes_atomic(path, data.tobytes())
