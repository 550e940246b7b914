"""Instrument models: the total station, its inclination sensor, and the marker assembly."""
