"""Reading a written figure back: its PNG's pixels, and the matplotlib figure it came from.

A figure is checked against what it was asked to draw, not by its file's size: the PNG's
pixel size is the figure's drawn extent at the DPI it was saved with, the colours of its
markers are there, and the artists hold the data they were given.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pytest
from matplotlib import colors, rcParams
from matplotlib.figure import Figure

import twin.montecarlo.figures
import twin.report.figures
from twin.report.figures import DPI


def read_png(path: str | Path) -> np.ndarray:
    """(H, W, 3) RGB pixels of a PNG file."""
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    assert img is not None, f"{path} is not an image"
    return img[:, :, ::-1]


def pixels_of(img: np.ndarray, colour: str, tol: int = 2) -> int:
    """How many pixels have ``colour`` (any matplotlib colour), within ``tol`` levels."""
    rgb = np.round(np.array(colors.to_rgb(colour)) * 255)
    return int(np.all(np.abs(img.astype(int) - rgb) <= tol, axis=2).sum())


def tight_size_px(fig: Figure) -> tuple[float, float]:
    """(width, height) in pixels at DPI of the figure's drawn extent, with matplotlib's
    padding: what ``savefig(bbox_inches="tight")`` writes."""
    box = fig.get_tightbbox(fig.canvas.get_renderer())
    box = box.padded(rcParams["savefig.pad_inches"])
    return box.width * DPI, box.height * DPI


@dataclass
class Saved:
    """A figure as it was saved: the Figure, its drawn size in pixels at DPI, the file."""

    figure: Figure
    size_px: tuple[float, float]
    path: Path

    def check_png(self) -> np.ndarray:
        """The PNG's pixels, checked to be the drawn figure at DPI; returns them."""
        img = read_png(self.path)
        height, width = img.shape[:2]
        want_w, want_h = self.size_px
        # Text extents at the saving DPI differ from the screen's by a pixel or so.
        assert abs(width - want_w) <= 0.01 * want_w + 2, (width, want_w)
        assert abs(height - want_h) <= 0.01 * want_h + 2, (height, want_h)
        return img

    def texts(self) -> list[str]:
        """Every text of the figure: titles, labels, annotations, notes on the axes."""
        out = [t.get_text() for t in self.figure.findobj(lambda a: hasattr(a, "get_text"))]
        return [t for t in out if t]

    def lines(self, label: str | None = None) -> list:
        """The figure's Line2D artists, those with ``label`` when given."""
        found = [ln for ax in self.figure.axes for ln in ax.get_lines()]
        return [ln for ln in found if label is None or ln.get_label() == label]


@pytest.fixture
def saved(monkeypatch) -> dict[str, Saved]:
    """Every figure written during the test, by file name."""
    out: dict[str, Saved] = {}
    real = twin.report.figures.save_figure

    def spy(fig: Figure, path: str | Path) -> Path:
        written = real(fig, path)
        out[Path(path).name] = Saved(fig, tight_size_px(fig), written)
        return written

    monkeypatch.setattr(twin.report.figures, "save_figure", spy)
    monkeypatch.setattr(twin.montecarlo.figures, "save_figure", spy)
    return out
