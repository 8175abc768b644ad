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
The gyroscope's figures over a run: the rate output and the closed-loop drive.

:class:`RateStats` keeps the figures ``ring_gyro run --json`` reports:

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

With the closed-loop drive (a closed ``control.mode``) :class:`DriveStats` adds:

``pll_lost_lock`` / ``pll_lock_lost_at_s`` / ``pll_relocked_at_s``
    Whether the PLL was ever out of lock (``core.gyro.control``, C4), when first, and when it
    last came back (None: never).
``drive_amplitude_recovery_s``
    After the first shock: from the shock's start to the last sample whose measured drive
    amplitude was outside 1 % of the AGC's set-point (0.0: never outside; None: still
    outside in the last :data:`RECOVERY_HOLD_S` of the run).
``drive_amplitude_final_ratio``
    The measured drive amplitude at the end over the set-point.
"""

from collections import deque
import math
from typing import Any, Deque, Dict, Optional, Tuple

import numpy as np
from ring_gyro_sim.core.gyro.control import CONTROL_CHANNELS
from ring_gyro_sim.core.gyro.electronics import RateSamples

__all__ = ['describe', 'DriveStats', 'MEAN_WINDOW_S', 'RateStats', 'RECOVERY_BAND',
           'RECOVERY_HOLD_S', 'RECOVERY_NOISE_SIGMAS']

RECOVERY_BAND = 0.01
"""Relative band of the recovery time: within 1 % of the applied rate."""
RECOVERY_NOISE_SIGMAS = 4.0
"""The band is at least this many standard deviations of the error before the shock."""
RECOVERY_HOLD_S = 0.1
"""A recovery counts when the output stayed in the band for at least this long at the end."""
MEAN_WINDOW_S = 1.0
"""Window of ``rate_mean_rad_s``, s."""


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
        setpoint = self.loop.setpoint_m
        # A set-point of 0 (the drive off from the start) has no ratio: 0, never inf.
        ratio = (control[:, self._column] / setpoint if setpoint > 0.0
                 else np.zeros(t.size))
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


def describe(figures: Dict[str, Any]) -> str:
    """
    Say in one line what a run's rate output and drive did (``Run.gyro_figures``).

    The rate read at the end against the applied rate; after a shock the error's peak and when
    the output came back within its band; whether the drive left its operating point (the
    closed loop's lock and amplitude, or the open loop's pick-off against its operating
    point: a drive that fell to its lower branch leaves ``~/rate`` without a scale factor).
    """
    deg = 180.0 / math.pi
    parts = []
    if 'rate_mean_rad_s' in figures:
        parts.append(f'~/rate {figures["rate_mean_rad_s"] * deg:.4f} deg/s over the last '
                     f'{MEAN_WINDOW_S:g} s (applied {figures["rate_true_mean_rad_s"] * deg:.4f})')
    if 'rate_error_peak_rad_s' in figures:
        peak = figures['rate_error_peak_rad_s'] * deg
        if figures.get('rate_recovered'):
            back = f'back within its band {figures["rate_recovery_s"]:.3f} s after the shock'
        else:
            back = 'not back within its band by the end'
        parts.append(f'after the first shock its error peaked at {peak:.4g} deg/s, {back}')
    if 'pll_lost_lock' in figures:
        if not figures['pll_lost_lock']:
            drive = 'the drive held its operating point (the PLL never lost lock)'
        else:
            relocked = figures.get('pll_relocked_at_s')
            drive = (f'the drive left its operating point: PLL out of lock from '
                     f'{figures["pll_lock_lost_at_s"]:.3f} s, '
                     + (f'locked again at {relocked:.3f} s' if relocked is not None
                        else 'not locked again'))
        recovery = figures.get('drive_amplitude_recovery_s')
        if 'drive_amplitude_recovery_s' in figures:
            drive += (f', amplitude within 1 % of its set-point {recovery:.3f} s after the '
                      f'shock' if recovery is not None else ', amplitude not back by the end')
        parts.append(drive)
    elif 'rate_drive_amplitude_ratio' in figures:
        ratio = figures['rate_drive_amplitude_ratio']
        if figures.get('rate_scale_factor_valid', True):
            parts.append(f'the drive on its operating point (pick-off at {ratio:.3g} of it)')
        else:
            parts.append(f'the drive left its branch (pick-off at {ratio:.3g} of its operating '
                         f'point): ~/rate is not a measurement')
    return '; '.join(parts)
