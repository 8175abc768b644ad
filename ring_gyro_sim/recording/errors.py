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

"""Errors raised by the recording layer (all of them :class:`RecordingError`)."""

from ring_gyro_sim.core.errors import RingGyroError


class RecordingError(RingGyroError, RuntimeError):
    """A recording cannot be written or read; the message names the file and the reason."""


class OutputExistsError(RecordingError):
    """The output file exists and replacing it was not asked for (or is never allowed)."""


class OutputBusyError(RecordingError):
    """Another process is writing the file right now (it holds the recorder's lock)."""
