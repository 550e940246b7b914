"""A scenario's hidden LEDs in the emulated world: an LED stays dark for a whole LED
sequence with the scenario's probability, as the twin hides it for one observation."""

from __future__ import annotations

import numpy as np

from calib.detection.sequence import SwitchingSequence
from twin.emulators.emulation import HidingLeds
from twin.hal.devices import MarkerLeds
from twin.hal.readings import LedSwitch


class Recording(MarkerLeds):
    def __init__(self) -> None:
        self.states: list[tuple[bool, ...]] = []

    @property
    def child(self) -> str:
        return "child1"

    @property
    def count(self) -> int:
        return 4

    def switch(self, on):
        self.states.append(tuple(on))
        return LedSwitch("child1", 0.0, tuple(on))

    def close(self) -> None:
        pass


PATTERN = SwitchingSequence.binary(4).pattern


def _sequence(leds: HidingLeds) -> np.ndarray:
    """Run one LED sequence; (4,) which LEDs were dark in every frame they were asked on."""
    inner = leds.inner
    assert isinstance(inner, Recording)
    start = len(inner.states)
    for row in PATTERN:
        asked = [bool(b) for b in row]
        event = leds.switch(asked)
        assert event.on == tuple(asked)  # the switch reports what was asked
    shown = np.array(inner.states[start:])
    asked = np.asarray(PATTERN, dtype=bool)
    return ~(shown & asked).any(axis=0)


def test_an_led_is_hidden_for_a_whole_sequence_at_the_scenarios_rate():
    rng = np.random.default_rng(3)
    leds = HidingLeds(Recording(), 0.3, rng)
    hidden = np.array([_sequence(leds) for _ in range(3000)])
    # 12000 LED-sequences at p = 0.3: the std of the fraction is 0.0042; 6 sigma is 0.025.
    assert abs(hidden.mean() - 0.3) < 0.025
    # Within a sequence an LED is either shown whenever asked or never: the draw holds.
    inner = leds.inner
    states = np.array(inner.states).reshape(3000, len(PATTERN), 4)
    asked = np.asarray(PATTERN, dtype=bool)
    shown_when_asked = states & asked
    partial = shown_when_asked.any(axis=1) & ~(shown_when_asked == asked).all(axis=1)
    assert not partial.any()


def test_rates_of_zero_and_one_hide_nothing_and_everything():
    assert not _sequence(HidingLeds(Recording(), 0.0, np.random.default_rng(1))).any()
    assert _sequence(HidingLeds(Recording(), 1.0, np.random.default_rng(1))).all()
