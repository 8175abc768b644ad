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
The gyroscope's rate channel inside a :class:`~ring_gyro_sim.run.Run`: electronics and figures.

:class:`GyroChannel` builds the sense electronics (``core/electronics.py``) at the drive's
operating point and turns each block's samples into the demodulator's channels and the rate
output. :class:`RateStats` keeps the figures ``ring_gyro run --json`` reports (issue 12):

``rate_mean_rad_s``
    Mean of the rate output over the last second of the run (all of it if shorter).
``rate_true_mean_rad_s``
    Mean of the applied rate over the same samples (what ``rate_mean_rad_s`` should be).
``rate_error_peak_rad_s``
    After the first shock: the largest ``|rate output - applied rate|`` from the shock on.
``rate_recovery_s``
    After the first shock: the time from the shock's start to the last rate sample outside
    the band ``max(1 % of |applied rate|, RECOVERY_NOISE_SIGMAS x the standard deviation of
    the output's error before the shock)``; None when the output is still outside the band in
    the last :data:`RECOVERY_HOLD_S` of the run (not recovered, or too short a run to tell:
    ``rate_recovered`` says which it is not).
``rate_scale_factor_valid`` / ``drive_amplitude_ratio``
    At the end of the run: the drive pick-off against its value at the operating point. When
    the drive has jumped to its lower branch (the paper's Case 3) the ratio falls to ~0.1:
    the scale factor has collapsed and the rate output is not a measurement.

With the closed-loop drive (``control.drive_loop: closed``) :class:`DriveStats` adds:

``pll_lost_lock`` / ``pll_lock_lost_at_s`` / ``pll_relocked_at_s``
    Whether the PLL was ever out of lock (``core.control``, C4), when first, and when it
    last came back (None: never).
``drive_amplitude_recovery_s``
    After the first shock: from the shock's start to the last sample whose measured drive
    amplitude was outside 1 % of the AGC's set-point (0.0: never outside; None: still
    outside in the last :data:`RECOVERY_HOLD_S` of the run).
``drive_amplitude_final_ratio``
    The measured drive amplitude at the end over the set-point.
"""

from collections import deque
from dataclasses import replace
import math
from typing import Any, Deque, Dict, Optional, Tuple

import numpy as np

from ring_gyro_sim.core.control import CONTROL_CHANNELS
from ring_gyro_sim.core.electronics import DemodSamples, RateSamples, SenseElectronics
from ring_gyro_sim.core.params import SimConfig
from ring_gyro_sim.core.simulator import Samples, Simulator

__all__ = ['DriveStats', 'GyroChannel', 'RateStats', 'drive_operating_point', 'RECOVERY_BAND',
           'RECOVERY_HOLD_S', 'RECOVERY_NOISE_SIGMAS']

RECOVERY_BAND = 0.01
"""Relative band of the recovery time: within 1 % of the applied rate (issue 12)."""
RECOVERY_NOISE_SIGMAS = 4.0
"""The band is at least this many standard deviations of the error before the shock."""
RECOVERY_HOLD_S = 0.1
"""A recovery counts when the output stayed in the band for at least this long at the end."""
MEAN_WINDOW_S = 1.0
"""Window of ``rate_mean_rad_s``, s."""


def drive_operating_point(config: SimConfig, start_state) -> Tuple[float, float]:
    """
    Return ``(A, p)``: q2 = A cos(phi_drive(t) + p) at the start (m, rad).

    From the start state when q2 moves (the ``drive.start_on`` orbit: its softening
    included; the drive's phase is 0 at t = 0), else the linear response of the 2theta mode
    ``F / (omega_2^2 - omega^2 + i omega omega_2 / Q_2)`` it will settle to from rest.
    """
    w = 2.0 * math.pi * config.drive.frequency
    if start_state is not None and w > 0.0:
        q, v = start_state
        c = complex(float(q[1]), -float(v[1]) / w)
        if abs(c) > 0.0:
            return abs(c), math.atan2(c.imag, c.real)
    f2 = 2.0 * math.pi * config.modes.frequencies[1]
    q2 = config.modes.quality_factors[1]
    c = config.drive.amplitude / complex(f2 * f2 - w * w, w * f2 / q2)
    return abs(c), math.atan2(c.imag, c.real)


class GyroChannel:
    """The sense electronics of a run at its operating point (``gyro.enabled``)."""

    def __init__(self, config: SimConfig, sim: Simulator, start_state) -> None:
        amp, phase = drive_operating_point(config, start_state)
        self.lock_frequency_hz: Optional[float] = None
        electronics_config = config
        if sim.loop is not None:
            # Closed loop the drive sits at the PLL's lock point, q2 = X sin(phi), at the
            # AGC's set-point (core.control, C3, C5), on the backbone: the scale factor is
            # that of the sense mode driven there (config/gyro.yaml: 0.017 Hz below
            # drive.frequency, a seventh of the sense mode's half-width, which moves the
            # scale factor by 0.55 %).
            amp, phase = sim.loop.setpoint_m, -0.5 * math.pi
            from ring_gyro_sim.analysis.nnm import lock_frequency  # the analysis layer
            self.lock_frequency_hz = lock_frequency(config, amp)
            electronics_config = replace(config, drive=replace(
                config.drive, frequency=self.lock_frequency_hz))
        self.drive_amplitude_m = amp
        self.drive_phase_rad = phase
        start_rate = float(sim.rates_at(np.zeros(1, np.int64))[0])
        self.electronics = SenseElectronics(electronics_config, sim, amp, phase,
                                            start_rate=start_rate)
        self._rebalance_columns = [CONTROL_CHANNELS.index('rebalance_rate_rad_s'),
                                   CONTROL_CHANNELS.index('rebalance_quadrature_rad_s')]
        w = 2.0 * math.pi * config.drive.frequency
        # A start state without drive motion (rest, given or not) keeps the default: the
        # filters at the linear operating point the drive will build up to.
        moving = start_state is not None and w > 0.0 and (
            float(start_state[0][1]) != 0.0 or float(start_state[1][1]) != 0.0)
        if moving:
            # The demodulator's outputs of the start state (q = Re(c e^{i psi}), psi = p at
            # t = 0: I = G Re(c), Q = -G Im(c)), so that the filters start settled.
            el = self.electronics
            q, v = start_state
            turn = complex(math.cos(phase), -math.sin(phase))
            out = []
            for index, gain in ((el.sense_index, el.electronic_gain),
                                (el.drive_index, el.drive_gain)):
                c = complex(float(q[index]), -float(v[index]) / w) * turn
                out += [gain * c.real, -gain * c.imag]
            el.start_outputs(np.array(out))

    def process(self, first_index: int, samples: Samples) -> Tuple[DemodSamples, RateSamples]:
        """Return the demodulator's channels and the rate output of one block."""
        rebalance = None
        if self.electronics.rebalance:
            rebalance = samples.control[:, self._rebalance_columns]
        return self.electronics.process(first_index, samples.t, samples.capacitance,
                                        samples.drive_phase, rebalance)

    def diagnostics_values(self) -> Dict[str, Any]:
        """Return the rate channel's state for ``/diagnostics``."""
        return self.electronics.diagnostics_values()


class _Recovery:
    """The first shock, the last sample outside a band after it, and the recovery time."""

    def __init__(self) -> None:
        self.shock_s: Optional[float] = None
        self.last_outside_s: Optional[float] = None
        self.last_t = math.nan

    def shock_at(self, t_s: float) -> None:
        """Note the first shock's start time, s."""
        if self.shock_s is None or t_s < self.shock_s:
            self.shock_s = float(t_s)

    def recovery(self) -> Tuple[bool, Optional[float]]:
        """
        Return ``(recovered, seconds)`` after the first shock (module docstring).

        Recovered when nothing was outside the band or the last :data:`RECOVERY_HOLD_S` were
        inside it; the time from the shock's start to the last sample outside (0.0: none).
        """
        last = self.last_outside_s
        recovered = last is None or self.last_t - last >= RECOVERY_HOLD_S
        if not recovered:
            return False, None
        return True, 0.0 if last is None else last - self.shock_s


class RateStats(_Recovery):
    """Figures of the rate output over a run (module docstring)."""

    def __init__(self, output_rate_hz: float) -> None:
        super().__init__()
        self.keep = max(1, int(round(MEAN_WINDOW_S * output_rate_hz)))
        self.recent: Deque[Tuple[float, float]] = deque(maxlen=self.keep)
        self._pre = [0, 0.0, 0.0]  # count, sum and sum of squares of the error before a shock
        self.error_peak = 0.0
        self.samples = 0

    def add(self, rate: RateSamples, applied: np.ndarray) -> None:
        """Add a block's rate samples and the applied rate at the same times (rad/s)."""
        if len(rate) == 0:
            return
        self.samples += len(rate)
        for pair in zip(rate.rate.tolist(), applied.tolist()):
            self.recent.append(pair)
        self.last_t = float(rate.t[-1])
        before = rate.t < self.shock_s if self.shock_s is not None else np.ones(len(rate), bool)
        if np.any(before):
            e = rate.rate[before] - applied[before]
            self._pre[0] += int(e.size)
            self._pre[1] += float(np.sum(e))
            self._pre[2] += float(np.sum(e * e))
        if self.shock_s is None:
            return
        after = ~before
        if not np.any(after):
            return
        err = np.abs(rate.rate[after] - applied[after])
        self.error_peak = max(self.error_peak, float(np.max(err)))
        band = np.maximum(RECOVERY_BAND * np.abs(applied[after]),
                          RECOVERY_NOISE_SIGMAS * self.noise_sigma)
        outside = np.nonzero(err > band)[0]
        if outside.size:
            self.last_outside_s = float(rate.t[after][outside[-1]])

    @property
    def noise_sigma(self) -> float:
        """Return the standard deviation of the output's error before the first shock, rad/s."""
        n, total, squares = self._pre
        if n < 2:
            return 0.0
        mean = total / n
        return math.sqrt(max(0.0, squares / n - mean * mean))

    def figures(self) -> Dict[str, Any]:
        """Return the rate output's figures, ``rate_*`` (see the module docstring)."""
        out: Dict[str, Any] = {}
        if self.recent:
            arr = np.array(self.recent)
            out['rate_mean_rad_s'] = float(np.mean(arr[:, 0]))
            out['rate_true_mean_rad_s'] = float(np.mean(arr[:, 1]))
        if self.shock_s is not None and self.samples:
            out['rate_error_peak_rad_s'] = self.error_peak
            recovered, seconds = self.recovery()
            out['rate_recovered'] = recovered
            out['rate_recovery_s'] = seconds
        return out


class DriveStats(_Recovery):
    """Figures of the closed-loop drive over a run (module docstring)."""

    def __init__(self, loop) -> None:
        super().__init__()
        self.loop = loop
        self._column = CONTROL_CHANNELS.index('amplitude_m')
        self.last_ratio = 1.0

    def add(self, t: np.ndarray, control: np.ndarray) -> None:
        """Add a block's sample times (s) and ``Samples.control`` rows."""
        if t.size == 0:
            return
        ratio = control[:, self._column] / self.loop.setpoint_m
        self.last_t = float(t[-1])
        self.last_ratio = float(ratio[-1])
        if self.shock_s is None:
            return
        outside = np.nonzero((t >= self.shock_s)
                             & (np.abs(ratio - 1.0) > RECOVERY_BAND))[0]
        if outside.size:
            self.last_outside_s = float(t[outside[-1]])

    def figures(self) -> Dict[str, Any]:
        """Return the drive loop's figures, ``pll_*`` and ``drive_amplitude_*`` (module doc)."""
        loop = self.loop
        out: Dict[str, Any] = {
            'pll_lost_lock': loop.lost_lock_at_s is not None,
            'pll_lock_lost_at_s': loop.lost_lock_at_s,
            'pll_relocked_at_s': loop.relocked_at_s,
            'drive_amplitude_final_ratio': self.last_ratio,
        }
        if self.shock_s is not None:
            out['drive_amplitude_recovery_s'] = self.recovery()[1]
        return out
