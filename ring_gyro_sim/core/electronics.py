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
Sense electronics of the gyroscope: pick-off, charge amplifier, demodulator, low-pass, rate.

(Skeleton: the signal chain is being written; the output types are fixed.)
"""

from dataclasses import dataclass

import numpy as np

__all__ = ['DEMOD_CHANNELS', 'DemodSamples', 'RateSamples']

DEMOD_CHANNELS = ('sense_i', 'sense_q', 'drive_i', 'drive_q')
"""Channels of ``~/demodulator`` after ``t`` (V, low-passed, at every internal sample)."""


@dataclass(frozen=True)
class RateSamples:
    """
    The rate output of one block (``~/rate``).

    Attributes
    ----------
    t : ndarray, shape (M,)
        Sample times, s (every ``output.rate / gyro.output_rate``-th internal sample).
    rate : ndarray, shape (M,)
        Measured angular rate about z, rad/s (in-phase channel / scale factor).
    quadrature : ndarray, shape (M,)
        The quadrature channel in the same units, rad/s.

    """

    t: np.ndarray
    rate: np.ndarray
    quadrature: np.ndarray

    def __len__(self) -> int:
        return int(self.t.size)


@dataclass(frozen=True)
class DemodSamples:
    """
    The demodulator's low-passed outputs at every internal sample (``~/demodulator``).

    Attributes
    ----------
    t : ndarray, shape (K,)
        Sample times, s (those of the block).
    values : ndarray, shape (K, len(DEMOD_CHANNELS))
        ``sense_i, sense_q, drive_i, drive_q``, V.

    """

    t: np.ndarray
    values: np.ndarray

    def __len__(self) -> int:
        return int(self.t.size)
