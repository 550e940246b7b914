"""JPEG quality against the LED centroids: what the emulated cameras' MJPEG encoding does
to the positions the detector finds, and what it costs.

Run: ``.venv/bin/python benchmarks/bench_jpeg_centroids.py [--groups N] [--repeats N]``

Frames as :class:`twin.emulators.led_frames.GeometricLedFrames` draws them: a plain
background of 20 DN with 2 DN of Gaussian noise, each LED a pixel-integrated Gaussian spot
of 200 DN peak and sigma 0.95 px (an LED of the smoke scenario's cam1 at about 4.7 m) at a
random sub-pixel place. Each group of four LEDs runs the binary switching sequence (6
frames); every frame is encoded by :func:`twin.emulators.camera.encode_jpeg` (the
MJPEG server's encoder) at each quality, decoded with ``cv2.imdecode`` and the LEDs are
found by :func:`calib.detection.detect_leds`. The baseline is the same noisy frames without
encoding (lossless, as PNG would be), so every quality is compared on the very same noise.

Columns:

- ``bias``: RMS over the LED places of the mean error (over the noise repeats) against the
  true place, px per coordinate: the systematic error at a place (the detector's own, from
  the pixel grid and its window, plus the encoding's).
- ``shift``: RMS over the places of the mean change against the baseline's position from
  the same noisy frames, px per coordinate: the systematic part of what JPEG adds.
- ``std``: standard deviation of the error over the noise repeats (pooled over places), px
  per coordinate: the detector's noise, and the encoding's part of it.
- ``pred``: the detector's own predicted sigma (mean).
- ``found``: share of the LEDs found; ``wrong``: share found more than 1 px from the truth
  (a wrong match; left out of bias, shift and std).
- ``encode``: ms to encode one 320 x 240 frame; ``kB``: its size.

Result (x86_64, 2 CPUs, OpenCV 5.0.0; 60 groups x 4 LEDs x 8 repeats = 1920 detections
per row, 34 s)::

     quality   bias px   shift px     std px    pred px   found   wrong  encode ms      kB
    lossless    0.0080          -     0.0220     0.0218  100.0%    0.0%          -       -
          50    0.1844     0.1834     0.0575     0.0118   34.6%    0.0%       0.10     1.4
          75    0.1382     0.1381     0.0425     0.0298   16.5%    2.2%       0.09     2.6
          90    0.0150     0.0129     0.0306     0.0173   99.1%    0.0%       0.13     8.0
          95    0.0088     0.0047     0.0236     0.0214  100.0%    0.0%       0.16    15.6
         100    0.0080     0.0016     0.0224     0.0223  100.0%    0.0%       0.25    35.3

At 75 and below the encoding smooths the 2 DN noise of the flat background away, so the
noise the detector estimates from the dark frames is too small (0.5 to 0.85 DN instead of
2), and the block artefacts around a spot make it look PARTIAL or AMBIGUOUS: most LEDs
are lost and a few found at a wrong place. At 90 one LED in a hundred is still lost.

The emulator's default quality is 95 (:data:`twin.emulators.camera.DEFAULT_QUALITY`): it
loses no LED, and the systematic shift it adds (0.005 px) is a fifth of the detector's own
noise on the same spots (0.022 px, which it raises by 7 %); quality 100 would cut the
shift to 0.002 px for 2.3 times the bytes. Encoding costs 0.16 ms per frame.
"""

from __future__ import annotations

import argparse
import os
import platform
import time
import warnings

import cv2
import numpy as np

from calib.detection import SwitchingSequence, detect_leds
from twin.emulators.camera import encode_jpeg
from twin.emulators.led_frames import gaussian_spot

QUALITIES = (50, 75, 90, 95, 100)
SIZE = (128, 96)  # (width, height) of the accuracy frames, px: JPEG works on 8 x 8 blocks
BACKGROUND = 20.0
NOISE_DN = 2.0
PEAK_DN = 200.0
SIGMA_PX = 0.95
N_LEDS = 4
WRONG_PX = 1.0  # a position further than this from the truth is a wrong match, not an error


def places(rng: np.random.Generator) -> np.ndarray:
    """(N_LEDS, 2) random sub-pixel places, one per quadrant, away from the border."""
    w, h = SIZE
    corners = np.array([[0, 0], [w / 2, 0], [0, h / 2], [w / 2, h / 2]])
    return corners + 12.0 + rng.uniform(0, 1, (N_LEDS, 2)) * (np.array([w, h]) / 2 - 24.0)


def frames(pixels: np.ndarray, pattern: np.ndarray, rng: np.random.Generator) -> list[np.ndarray]:
    """The uint8 frames of one sequence, with fresh noise."""
    w, h = SIZE
    out = []
    for row in pattern:
        image = np.full((h, w), BACKGROUND)
        for k in np.flatnonzero(row):
            gaussian_spot(image, pixels[k], SIGMA_PX, PEAK_DN)
        image += NOISE_DN * rng.standard_normal(image.shape)
        out.append(np.clip(np.rint(image), 0, 255).astype(np.uint8))
    return out


def through_jpeg(image: np.ndarray, quality: int) -> np.ndarray:
    return cv2.imdecode(np.frombuffer(encode_jpeg(image, quality), np.uint8), cv2.IMREAD_GRAYSCALE)


def found(stack: list[np.ndarray], seq: SwitchingSequence) -> tuple[np.ndarray, np.ndarray]:
    """(N_LEDS, 2) positions (NaN where not found) and (N_LEDS,) predicted sigma."""
    result = detect_leds(stack, seq)
    pix = np.full((N_LEDS, 2), np.nan)
    sig = np.full(N_LEDS, np.nan)
    for d in result.leds:
        if d.pixel is not None:
            pix[d.led] = d.pixel
            sig[d.led] = d.sigma_px
    return pix, sig


def accuracy(groups: int, repeats: int, seed: int = 0) -> dict[object, dict[str, float]]:
    seq = SwitchingSequence.binary(N_LEDS)
    rng = np.random.default_rng(seed)
    kinds: list[object] = ["lossless", *QUALITIES]
    # err[kind]: (groups, repeats, N_LEDS, 2) error against the truth.
    err = {k: np.full((groups, repeats, N_LEDS, 2), np.nan) for k in kinds}
    sig = {k: np.full((groups, repeats, N_LEDS), np.nan) for k in kinds}
    for g in range(groups):
        truth = places(rng)
        for r in range(repeats):
            raw = frames(truth, seq.pattern, rng)
            for kind in kinds:
                stack = raw if kind == "lossless" else [through_jpeg(f, int(kind)) for f in raw]
                pix, s = found(stack, seq)
                err[kind][g, r] = pix - truth
                sig[kind][g, r] = s
    with np.errstate(invalid="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # places never found: NaN
        return _rows(err, sig, kinds, repeats)


def _rows(
    err: dict[object, np.ndarray], sig: dict[object, np.ndarray], kinds: list[object], repeats: int
) -> dict[object, dict[str, float]]:
    rows = {}
    base_mean = np.nanmean(err["lossless"], axis=1)  # (groups, N_LEDS, 2)
    for kind in kinds:
        e = err[kind].copy()
        wrong = np.hypot(e[..., 0], e[..., 1]) > WRONG_PX
        found_share = float(np.mean(np.isfinite(e[..., 0])))
        e[wrong] = np.nan
        mean = np.nanmean(e, axis=1)
        rows[kind] = {
            "bias": float(np.sqrt(np.nanmean(mean**2))),
            "shift": float(np.sqrt(np.nanmean((mean - base_mean) ** 2))),
            "std": float(np.sqrt(np.nanmean((e - mean[:, None]) ** 2) * repeats / (repeats - 1))),
            "pred": float(np.nanmean(sig[kind])),
            "found": found_share,
            "wrong": float(np.mean(wrong)),
        }
    return rows


def encode_cost(frames_n: int = 200) -> dict[int, tuple[float, float]]:
    """{quality: (ms per 320 x 240 frame, kB)} on an emulator-like frame."""
    rng = np.random.default_rng(1)
    image = np.full((240, 320), BACKGROUND)
    for _ in range(8):
        gaussian_spot(image, rng.uniform([10, 10], [310, 230]), SIGMA_PX, PEAK_DN)
    image = np.clip(np.rint(image + NOISE_DN * rng.standard_normal(image.shape)), 0, 255)
    image = image.astype(np.uint8)
    out = {}
    for q in QUALITIES:
        encode_jpeg(image, q)
        t0 = time.perf_counter()
        for _ in range(frames_n):
            data = encode_jpeg(image, q)
        out[q] = (1e3 * (time.perf_counter() - t0) / frames_n, len(data) / 1e3)
    return out


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--groups", type=int, default=60, help="groups of 4 LED places")
    parser.add_argument("--repeats", type=int, default=8, help="noise repeats per place")
    args = parser.parse_args()
    print(f"{platform.machine()}, {os.cpu_count()} CPUs, OpenCV {cv2.__version__}")
    print(
        f"{args.groups} groups x {N_LEDS} LEDs x {args.repeats} repeats; spot sigma {SIGMA_PX} px, "
        f"peak {PEAK_DN} DN, noise {NOISE_DN} DN"
    )
    t0 = time.perf_counter()
    rows = accuracy(args.groups, args.repeats)
    cost = encode_cost()
    header = (
        f"{'quality':>8} {'bias px':>9} {'shift px':>10} {'std px':>10} {'pred px':>10} "
        f"{'found':>7} {'wrong':>7} {'encode ms':>10} {'kB':>7}"
    )
    print(header)
    for kind, row in rows.items():
        ms, kb = cost.get(kind, (None, None)) if isinstance(kind, int) else (None, None)
        shift = "-" if kind == "lossless" else f"{row['shift']:.4f}"
        print(
            f"{kind!s:>8} {row['bias']:9.4f} {shift:>10} {row['std']:10.4f} {row['pred']:10.4f} "
            f"{100 * row['found']:6.1f}% {100 * row['wrong']:6.1f}% "
            f"{'-' if ms is None else f'{ms:.2f}':>10} {'-' if kb is None else f'{kb:.1f}':>7}"
        )
    print(f"({time.perf_counter() - t0:.1f} s)")


if __name__ == "__main__":
    main()
