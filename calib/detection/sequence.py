"""Switching sequences: which LEDs are lit in which frame of a detection sequence.

A child robot switches its LEDs by a known pattern while a fixed camera takes one frame per
row of the pattern. Rows with every LED off are *dark* (reference) frames: their mean is the
LED-off image that the LED-on images are compared with. The other rows are *code* frames;
the on/off column of an LED over the code frames is its *code*, and the detector identifies
each LED by it.

Two constructors give the sequences the project uses:

- :meth:`SwitchingSequence.one_at_a_time`: dark, LED 0, LED 1, ..., dark. Short, and every
  LED is seen against all the others, but each code has a single lit frame: anything small
  and compact that appears in exactly that one frame (a reflection, a glint, a transient
  light) has the same code as the LED, and only the detector's size and shape checks (and
  ambiguity reporting when the LED is there too) protect against it.
- :meth:`SwitchingSequence.binary`: dark, then the fewest code frames (at least 4) that give
  every LED a distinct code of constant weight (each LED lit in exactly half the code
  frames), then dark. A transient present in one frame, or a light present in every code
  frame, matches no code: a false LED needs at least two matching frames and the right
  off frames in between.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass
from math import comb

import numpy as np
from numpy.typing import ArrayLike, NDArray


def _code_str(code: NDArray[np.bool_]) -> str:
    return "".join("1" if b else "0" for b in code)


@dataclass(frozen=True, eq=False)
class SwitchingSequence:
    """The LED switching pattern of one detection sequence.

    Attributes:
        pattern: (n_frames, n_leds) bool, True where an LED is lit in that frame. Rows with
            no LED lit are dark reference frames; there must be at least one. Every LED must
            be lit in at least one frame, and the codes of the LEDs (their columns over the
            non-dark frames) must all differ, or the LEDs cannot be told apart. The array
            is copied and made read-only.
    """

    pattern: NDArray[np.bool_]

    def __post_init__(self) -> None:
        raw = np.asarray(self.pattern)
        if raw.ndim != 2:
            raise ValueError(
                f"pattern must be a 2-D (n_frames, n_leds) array, got shape {raw.shape}"
            )
        if raw.shape[1] == 0:
            raise ValueError(f"pattern must have at least one LED column, got shape {raw.shape}")
        if raw.dtype != np.bool_ and (
            raw.dtype.kind not in "biuf" or not np.isin(raw, (0, 1)).all()
        ):
            raise ValueError(
                f"pattern must hold booleans (or 0/1), got dtype {raw.dtype} with values "
                f"{np.unique(raw)[:5].tolist()}"
            )
        pat = raw.astype(bool).copy()
        dark = ~pat.any(axis=1)
        if not dark.any():
            raise ValueError(
                f"pattern has no dark frame (a row with every LED off) among its {pat.shape[0]}"
                " rows; the LED-off reference image needs at least one"
            )
        never = np.flatnonzero(~pat.any(axis=0))
        if never.size:
            raise ValueError(
                f"LED {int(never[0])} is never lit in the pattern; every LED needs at least "
                "one lit frame"
            )
        codes = pat[~dark]
        for i, j in itertools.combinations(range(pat.shape[1]), 2):
            if np.array_equal(codes[:, i], codes[:, j]):
                raise ValueError(
                    f"LEDs {i} and {j} have the same code {_code_str(codes[:, i])} over the "
                    f"{codes.shape[0]} code frames; they cannot be told apart"
                )
        pat.setflags(write=False)
        object.__setattr__(self, "pattern", pat)

    # -- construction -------------------------------------------------------------------
    @classmethod
    def one_at_a_time(cls, n_leds: int = 4) -> SwitchingSequence:
        """Dark, LED 0, LED 1, ..., LED n-1, dark: ``n_leds + 2`` frames.

        Each LED is lit in exactly one frame, so a compact transient present in that frame
        alone cannot be told from the LED by its code (see the module docstring).
        """
        n = _check_n_leds(n_leds)
        pat = np.zeros((n + 2, n), dtype=bool)
        pat[1 : n + 1] = np.eye(n, dtype=bool)
        return cls(pat)

    @classmethod
    def binary(cls, n_leds: int = 4) -> SwitchingSequence:
        """Dark, the fewest constant-weight code frames, dark.

        The number of code frames is the smallest even m >= 4 with C(m, m/2) >= n_leds
        (4 frames for up to 6 LEDs, 6 for up to 20); every LED is lit in exactly m/2 of
        them. Codes are taken in complementary pairs (1100 with 0011, ...), chosen so that
        two LEDs share as few lit frames as possible; with an even number of LEDs every code
        frame then has half of them lit. A single LED gets dark, lit, lit, dark: every
        frame with it off is a dark frame, and it still needs two matching frames.
        """
        n = _check_n_leds(n_leds)
        if n == 1:
            # A frame with the only LED off is a dark frame: no constant-weight code exists.
            return cls(np.array([[False], [True], [True], [False]]))
        m = 4
        while comb(m, m // 2) < n:
            m += 2
        w = m // 2
        # Words of weight m/2 that light frame 0, each paired with its complement.
        pairs = [
            (word, ~word)
            for word in (np.isin(np.arange(m), idx) for idx in itertools.combinations(range(m), w))
            if word[0]
        ]
        chosen: list[NDArray[np.bool_]] = []
        while len(chosen) < n:

            def worst_overlap(pair: tuple[NDArray[np.bool_], ...]) -> int:
                return max(
                    (int((c & p).sum()) for c in chosen for p in pair),
                    default=0,
                )

            best = min(range(len(pairs)), key=lambda k: worst_overlap(pairs[k]))
            chosen.extend(pairs.pop(best))
        codes = np.array(chosen[:n]).T  # (m, n)
        dark = np.zeros((1, n), dtype=bool)
        return cls(np.vstack([dark, codes, dark]))

    # -- derived quantities -------------------------------------------------------------
    @property
    def n_frames(self) -> int:
        """Number of frames (rows of the pattern)."""
        return int(self.pattern.shape[0])

    @property
    def n_leds(self) -> int:
        """Number of LEDs (columns of the pattern)."""
        return int(self.pattern.shape[1])

    @property
    def dark_frames(self) -> tuple[int, ...]:
        """Indices of the dark reference frames (every LED off)."""
        return tuple(int(i) for i in np.flatnonzero(~self.pattern.any(axis=1)))

    @property
    def code_frames(self) -> tuple[int, ...]:
        """Indices of the frames with at least one LED lit."""
        return tuple(int(i) for i in np.flatnonzero(self.pattern.any(axis=1)))

    def lit_frames(self, led: int) -> tuple[int, ...]:
        """Indices of the frames in which ``led`` is lit."""
        return tuple(int(i) for i in np.flatnonzero(self.pattern[:, self._check_led(led)]))

    def off_code_frames(self, led: int) -> tuple[int, ...]:
        """Indices of the code frames in which ``led`` is off (other LEDs are lit)."""
        col = self.pattern[:, self._check_led(led)]
        return tuple(int(i) for i in np.flatnonzero(~col & self.pattern.any(axis=1)))

    def code(self, led: int) -> str:
        """The LED's code over the code frames as a string of 0 and 1, e.g. "1100"."""
        return _code_str(self.pattern[list(self.code_frames), self._check_led(led)])

    @property
    def codes(self) -> NDArray[np.bool_]:
        """(n_code_frames, n_leds) the pattern restricted to the code frames."""
        return self.pattern[list(self.code_frames)]

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, SwitchingSequence):
            return NotImplemented
        return bool(np.array_equal(self.pattern, other.pattern))

    def __hash__(self) -> int:
        return hash((self.pattern.shape, self.pattern.tobytes()))

    def __repr__(self) -> str:
        rows = " ".join(_code_str(r) for r in self.pattern)
        return f"SwitchingSequence({self.n_frames} frames x {self.n_leds} LEDs: {rows})"

    def _check_led(self, led: int) -> int:
        if not 0 <= int(led) < self.n_leds or int(led) != led:
            raise ValueError(f"LED index must be 0..{self.n_leds - 1}, got {led!r}")
        return int(led)


MAX_LEDS = 64
"""The most LEDs a switching sequence codes: far more than a marker carries (the paper's has
four), and few enough that a sequence's frames stay a short burst."""


def _check_n_leds(n_leds: int) -> int:
    if int(n_leds) != n_leds or not 1 <= n_leds <= MAX_LEDS:
        raise ValueError(f"n_leds must be an integer from 1 to {MAX_LEDS}, got {n_leds!r}")
    return int(n_leds)


def as_sequence(sequence: SwitchingSequence | ArrayLike) -> SwitchingSequence:
    """A SwitchingSequence as is, or one built from a (n_frames, n_leds) pattern."""
    if isinstance(sequence, SwitchingSequence):
        return sequence
    return SwitchingSequence(np.asarray(sequence))
