# Copyright 2026 ring_gyro_sim developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
Exception hierarchy of ring_gyro_sim.

Every error raised on purpose by the package derives from :class:`RingGyroError` and also from
the closest builtin, so callers may catch either.
"""

__all__ = ['RingGyroError', 'ParameterError', 'InputError', 'SimulationError']


class RingGyroError(Exception):
    """Base class of every ring_gyro_sim error."""


class ParameterError(RingGyroError, ValueError):
    """A parameter is invalid; the message names the field and the reason."""


class InputError(RingGyroError, ValueError):
    """A run-time input (shock, drive change, base acceleration) is invalid."""


class SimulationError(RingGyroError, RuntimeError):
    """The simulation cannot continue (contact, pull-in, numerical failure)."""
