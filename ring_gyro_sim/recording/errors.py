"""Errors raised by the recording layer."""

from ring_gyro_sim.core.errors import RingGyroError


class RecordingError(RingGyroError, RuntimeError):
    """A recording cannot be written or read; the message names the file and the reason."""
