"""Exception hierarchy of ring_gyro_sim.

Every error raised on purpose by the package derives from :class:`RingGyroError` and also from
the closest builtin, so callers may catch either.
"""


class RingGyroError(Exception):
    """Base class of every ring_gyro_sim error."""


class ParameterError(RingGyroError, ValueError):
    """A parameter is invalid; the message names the field and the reason."""


class InputError(RingGyroError, ValueError):
    """A run-time input (shock, drive change, base acceleration) is invalid."""


class SimulationError(RingGyroError, RuntimeError):
    """The simulation cannot continue (contact, pull-in, numerical failure)."""
