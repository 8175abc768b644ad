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

r"""
How far a rate sample can be trusted, judged from what the sensor itself measures (V1-V6).

A gyroscope's output is a measurement only while its loops hold their operating point. A
10 000 g shock knocks the drive off its backbone and the PLL out of lock for seconds; a
constant covariance on ``~/rate`` then tells an estimator that readings thousands of standard
deviations off are good. :class:`RateValidity` gives each rate sample a variance that says
what it is worth, from the signals real sensor electronics have (their status bits work this
way), never from the true rate:

Not a measurement (V1)
    While the PLL is out of lock (C4), while force-to-rebalance is off (C8b: the drive not
    qualified), while the drive pick-off is more than :data:`DRIVE_TOLERANCE` away from
    what the operating point gives (the AGC's set-point closed loop; open loop the pair's
    linear response to the measured rate, E8), while the drive (the NCO) is detuned from the
    frequency the open-loop sense readout holds its scale factor at by more than
    :data:`DETUNING_TOLERANCE` half-widths of the sense mode (closed loop without
    rebalance: ``core.gyro.channel``), or when the shock detector on the drive
    pick-off fires (its mean over a rate period moved from one period to the next by more
    than :data:`SHOCK_DC_TOLERANCE` of its amplitude: ``core.gyro.channel``), the rate
    output is not a measurement: its
    variance is :data:`NOT_MEASURED_VARIANCE`, finite, so that filters that rotate a
    covariance (``R C R^T``) keep finite numbers and give the sample no weight.

Saturated (V1b)
    A sample that reads the full scale of the output word because the rate behind it is
    beyond it (``gyro.range``, ``core.gyro.electronics`` E15) is not a measurement either:
    it says only that the rate is at least the range. Its reason is ``saturated`` unless a
    loop's state (V1) says more. The clip is memoryless and the readout behind it did not
    saturate, so it starts no settling (V2): the first sample back within the range is a
    measurement again.

Settling (V2)
    When such a state ends, the output stays "not a measurement" for :data:`SETTLE_TIME_CONSTANTS`
    time constants of the rate path, ``1 / (2 pi B)`` with ``B`` the path's bandwidth (E9:
    the rebalance loop's 20 Hz, 40 ms; the open-loop sense mode's 0.12 Hz, 6.5 s): the
    readout has to forget the disturbance it integrated.

Noise and scale factor (V3)
    A measurement has the variance of the white noise through the rate path (E10-E12,
    ``SenseElectronics.rate_variance``), plus the flicker's level (the bias instability B
    in rad/s, squared), plus the scale factor's uncertainty times the reading:
    ``(SCALE_FACTOR_SIGMA Omega_hat)^2``. :data:`SCALE_FACTOR_SIGMA` is the model-based
    readout's accuracy: the largest deviation of its scale factor measured at the shipped
    operating points (+0.25 % open loop at config/gyro.yaml, -0.097 % with rebalance at the
    defaults: doc/gyroscope.md, doc/control.md). With an output word of LSB ``L``
    (``gyro.resolution``) its rounding adds ``L^2 / 12``, the variance of an error uniform
    within ``+-L / 2``.

Transient (V4)
    A disturbance that leaves the loops locked still moves the sense mode: its in-phase and
    quadrature parts ring together. The quadrature channel is not the rate, so its departure
    from what the operating point gives, ``dQ = Q - (q_r Omega_hat + Q_0)`` (``q_r`` the
    quadrature a rate causes, E6b, 0 with rebalance; ``Q_0`` the steady offset, tracked with
    the time constant :data:`QUADRATURE_REFERENCE_S` while the output is a measurement and
    quiet), measures the transient: its envelope ``E`` (a peak detector decaying with the
    rate path's time constant, at least :data:`ENVELOPE_MIN_S`) adds ``E^2`` to the variance.
    After a 10 000 g shock with the loops locked again the in-phase error stays within a few
    times ``E`` (measured: within 2.5 E right after the PLL locks again, within 0.1 E once
    the quadrature force has settled; doc/gyroscope.md).

Validity (V5)
    A sample is *valid* when it is a measurement (V1, V2) and its standard deviation is at most
    :data:`VALID_SIGMA_RATIO` times that of V3 alone; the stated band of its error is
    ``BAND_SIGMAS`` (6) standard deviations.

The variance is capped at :data:`NOT_MEASURED_VARIANCE` (V6).
"""

from dataclasses import dataclass
import math
from typing import Optional

import numpy as np

__all__ = ['BAND_SIGMAS', 'DRIVE_TOLERANCE', 'ENVELOPE_MIN_S', 'NOT_MEASURED_VARIANCE',
           'QUADRATURE_REFERENCE_S', 'REASONS', 'RateValidity', 'SATURATED',
           'SCALE_FACTOR_SIGMA', 'SETTLE_TIME_CONSTANTS', 'VALID_SIGMA_RATIO',
           'ValidityState']

NOT_MEASURED_VARIANCE = 1e6
"""(rad/s)^2 of a sample that is not a measurement, and of the axes the sensor does not
measure (x, y): (1 000 rad/s)^2, beyond any rate the model takes, finite (V1)."""
DRIVE_TOLERANCE = 0.1
"""Largest relative departure of the drive pick-off from its operating point (V1)."""
SETTLE_TIME_CONSTANTS = 5.0
"""Time constants of the rate path a readout needs to forget a disturbance (V2)."""
SCALE_FACTOR_SIGMA = 0.0025
"""Relative standard uncertainty of the model-based scale factor (V3)."""
QUADRATURE_REFERENCE_S = 10.0
"""Time constant of the steady quadrature offset's tracker, s (V4)."""
ENVELOPE_MIN_S = 0.1
"""Shortest decay time of the transient's envelope, s (V4)."""
VALID_SIGMA_RATIO = 3.0
"""A valid sample's standard deviation is at most this many times V3's (V5)."""
BAND_SIGMAS = 6.0
"""The stated band of a sample's error, in its standard deviations (V5)."""
DETUNING_TOLERANCE = 0.25
"""Largest departure of the drive (the NCO) from its steady frequency, in half-widths of the
sense mode, at which the open-loop sense readout is a measurement (V1): measured after a
10 000 g shock at the defaults without rebalance, the reading moves by ~0.26 per Hz of
detuning (31 % at -1.18 Hz), so 0.25 half-widths (30 mHz) keep it within ~1 %."""
SHOCK_DC_TOLERANCE = 0.1
"""A change of the drive pick-off's mean from one rate period to the next beyond this part of
its amplitude is a shock (V1; ``core.gyro.channel.SenseChain``): ten times the drive's own
oscillation left in the mean (1 %)."""

REASONS = ('', 'PLL out of lock', 'rebalance loop off (drive not qualified)',
           'drive pick-off off its operating point', 'settling after a disturbance',
           'shock on the pick-offs', 'drive detuned from the sense mode', 'saturated',
           'rebalance force at its limit')
"""Why a sample is not a measurement, by code (0: it is one)."""
SATURATED = REASONS.index('saturated')
"""The code of a sample that reads the output word's full scale (V1b)."""


@dataclass(frozen=True)
class ValidityState:
    """The latest sample's standing: variance ((rad/s)^2), validity, reason (V5)."""

    variance: float = 0.0
    sigma_nominal: float = 0.0
    valid: bool = True
    reason: str = ''

    @property
    def sigma(self) -> float:
        """Return the standard deviation, rad/s."""
        return math.sqrt(self.variance)

    @property
    def band(self) -> float:
        """Return the stated band of the error, rad/s (:data:`BAND_SIGMAS` sigma)."""
        return BAND_SIGMAS * self.sigma


class RateValidity:
    """
    The variance and validity of each rate sample (module docstring, V1-V6).

    Parameters
    ----------
    noise_variance : float
        Variance of the white rate noise through the path, (rad/s)^2 (E10-E12).
    bias_sigma : float
        Standard deviation of the flicker (bias instability), rad/s.
    bandwidth_hz : float
        The rate path's bandwidth, Hz (E9): its time constant sets V2 and V4.
    sample_rate_hz : float
        Rate of the samples, Hz (``gyro.output_rate``).
    quadrature_per_rate : float
        The quadrature a rate causes, per unit rate (E6b; 0 with rebalance).
    resolution : float
        The output word's LSB, rad/s (``gyro.resolution``; 0: none): its rounding's
        variance ``L^2 / 12`` is part of a measurement's (V3).

    """

    def __init__(self, noise_variance: float, bias_sigma: float, bandwidth_hz: float,
                 sample_rate_hz: float, quadrature_per_rate: float,
                 resolution: float = 0.0) -> None:
        self.noise_variance = (float(noise_variance) + float(bias_sigma) ** 2
                               + float(resolution) ** 2 / 12.0)
        tau = 1.0 / (2.0 * math.pi * float(bandwidth_hz))
        self.settle_s = SETTLE_TIME_CONSTANTS * tau
        dt = 1.0 / float(sample_rate_hz)
        self._decay = math.exp(-dt / max(tau, ENVELOPE_MIN_S))
        self._track = dt / QUADRATURE_REFERENCE_S
        self.tracking = self._track
        """Part of a deviation a tracked steady reference takes per sample (V4)."""
        self.quadrature_per_rate = float(quadrature_per_rate)
        self._offset: Optional[float] = None
        self._envelope = 0.0
        self._measured_since = -math.inf  # time the latest not-a-measurement state ended, s
        self.state = ValidityState()

    def continue_from(self, previous: 'RateValidity') -> None:
        """Take over the running state of the monitor this one replaces."""
        self._offset = previous._offset
        self._envelope = previous._envelope
        self._measured_since = previous._measured_since
        self.state = previous.state

    def samples(self, t: np.ndarray, rate: np.ndarray, quadrature: np.ndarray,
                reasons: np.ndarray, saturated: Optional[np.ndarray] = None) -> np.ndarray:
        """
        Return the variance of each rate sample, (rad/s)^2, and update the state.

        Parameters
        ----------
        t, rate, quadrature : ndarray, shape (M,)
            Sample times (s), the rate output and its quadrature channel (rad/s).
        reasons : ndarray of int, shape (M,)
            Per sample, the index in :data:`REASONS` of why it is not a measurement (0: the
            loops hold their operating point, V1).
        saturated : ndarray of bool, shape (M,), optional
            Per sample, whether it reads the full scale (``RateSamples.saturated``, V1b);
            None: none did.

        """
        out = np.empty(rate.size)
        state = self.state
        clipped = (np.zeros(rate.size, dtype=bool) if saturated is None
                   else np.asarray(saturated, dtype=bool))
        for k in range(rate.size):
            r, q, code = float(rate[k]), float(quadrature[k]), int(reasons[k])
            nominal = self.noise_variance + (SCALE_FACTOR_SIGMA * r) ** 2
            if self._offset is None:
                self._offset = q - self.quadrature_per_rate * r  # the chain starts settled
            deviation = abs(q - self.quadrature_per_rate * r - self._offset)
            if clipped[k]:  # the reading is not the rate: the quadrature is not judged by it
                self._envelope *= self._decay
            else:
                self._envelope = max(deviation, self._envelope * self._decay)
            if code:
                self._measured_since = math.inf
            elif self._measured_since == math.inf:
                self._measured_since = float(t[k])  # the disturbance is over: settle (V2)
            settling = not code and float(t[k]) - self._measured_since < self.settle_s
            if code or settling or clipped[k]:
                variance = NOT_MEASURED_VARIANCE
                reason = REASONS[code or (SATURATED if clipped[k] else 4)]
            else:
                variance = min(nominal + self._envelope ** 2, NOT_MEASURED_VARIANCE)
                reason = ''
                if deviation * deviation <= nominal:  # quiet: follow the steady offset
                    self._offset += self._track * (q - self.quadrature_per_rate * r
                                                   - self._offset)
            out[k] = variance
            state = ValidityState(
                variance=variance, sigma_nominal=math.sqrt(nominal),
                valid=not reason and variance <= VALID_SIGMA_RATIO ** 2 * nominal,
                reason=reason)
        self.state = state
        return out
