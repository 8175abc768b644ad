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
The angular rate of the sensor frame over time: the motion of the case about z.

Knots ``(t_k ns, Omega_k rad/s)``, non-decreasing in time, linear between them, 0 before the
first and held after the last; two knots at one time make a step (the value after the step
holds from that time on). ``scenario.rate_times`` / ``scenario.rate_values`` give the
scheduled knots; a streamed rate (:meth:`RateProfile.step`) replaces the knots after its
time. The simulator integrates each step with the rate at its middle (``core.kernels``) and
reports the rate at the sample times (``Samples.applied_rate``); ``ring_gyro rate`` rebuilds
the same values from a recording with this class alone.
"""

import bisect
from typing import List, Tuple

import numpy as np

from ring_gyro_sim.core.params import SimConfig

__all__ = ['RateProfile']

_EMPTY = np.empty(0)
COMPACT_KNOTS = 64
"""Knots over before a stretch that :meth:`RateProfile.stretch` lets pile up before dropping."""


class RateProfile:
    """The knots of an angular-rate profile (module docstring)."""

    def __init__(self, times_s=(), rates=()) -> None:
        self._t: List[int] = [int(round(t_s * 1e9)) for t_s in times_s]
        self._w: List[float] = [float(w) for w in rates]
        self._cache = None
        self.version = 0
        """Counts the changes of the knots (a caller's cache of :meth:`at` may key on it)."""

    @classmethod
    def of(cls, config: SimConfig) -> 'RateProfile':
        """Return the scheduled profile of ``config`` (``scenario.rate_*``)."""
        return cls(config.run.rate_times, config.run.rate_values)

    def __bool__(self) -> bool:
        """Tell whether there is any knot (no knot: the frame does not turn)."""
        return bool(self._t)

    def step(self, at_ns: int, rate: float) -> None:
        """
        Step the rate to ``rate`` (rad/s) at ``at_ns``; the knots after it are dropped.

        Its cost does not grow with the knots ahead: a bisection and the knots dropped (each
        knot is dropped once), never a pass over them all.
        """
        at_ns = int(at_ns)
        before = self._value_at(at_ns)
        keep = bisect.bisect_right(self._t, at_ns)
        del self._t[keep:]
        del self._w[keep:]
        self._t += [at_ns, at_ns]
        self._w += [before, float(rate)]
        self.version += 1

    def _value_at(self, t_ns: int) -> float:
        """Return the rate (rad/s) at one time ``t_ns`` (ns), as :meth:`at` computes it."""
        times, rates = self._t, self._w
        k = bisect.bisect_right(times, t_ns) - 1  # the value after a step at t
        if k < 0:
            return 0.0
        if k >= len(times) - 1:
            return rates[-1]
        dt = float(times[k + 1] - times[k])
        frac = (t_ns - times[k]) / dt if dt > 0 else 0.0
        return rates[k] + (rates[k + 1] - rates[k]) * frac

    def stretch(self, t_start: float, t_end: float) -> Tuple[np.ndarray, np.ndarray]:
        """
        Return the knots (s, rad/s) that a stretch ``[t_start, t_end]`` (s) needs.

        From the last knot at or before ``t_start`` to the first one after ``t_end``: the
        kernel interpolates between neighbours only. Knots before those are over; more than
        :data:`COMPACT_KNOTS` of them are dropped (the values stay the same).
        """
        if not self._t:
            return _EMPTY, _EMPTY
        times = self._t
        keep = max(0, bisect.bisect_right(times, int(round(t_start * 1e9))) - 1)
        if keep > COMPACT_KNOTS:
            del self._t[:keep]
            del self._w[:keep]
            self.version += 1
            keep = 0
        end = min(len(times), bisect.bisect_right(times, int(round(t_end * 1e9))) + 1)
        return (np.array(times[keep:end], dtype=np.float64) * 1e-9,
                np.array(self._w[keep:end], dtype=np.float64))

    def knots_from(self, t_s: float) -> Tuple[np.ndarray, np.ndarray]:
        """Return the knots (s, rad/s) from the last one at or before ``t_s`` (s) on."""
        if not self._t:
            return _EMPTY, _EMPTY
        keep = max(0, bisect.bisect_right(self._t, int(round(t_s * 1e9))) - 1)
        return (np.array(self._t[keep:], dtype=np.float64) * 1e-9,
                np.array(self._w[keep:], dtype=np.float64))

    def at(self, t_ns: np.ndarray) -> np.ndarray:
        """Return the rate (rad/s) at the times ``t_ns`` (ns; after a step there)."""
        t_ns = np.asarray(t_ns, dtype=np.int64)
        if not self._t:
            return np.zeros(t_ns.shape)
        if self._cache is None or self._cache[0] != self.version:
            # The knots change rarely (a streamed rate, a compaction); a loop asks per period.
            self._cache = (self.version, np.asarray(self._t, dtype=np.int64),
                           np.asarray(self._w, dtype=np.float64))
        times, rates = self._cache[1], self._cache[2]
        k = np.searchsorted(times, t_ns, side='right') - 1  # the value after a step at t
        inside = (k >= 0) & (k < times.size - 1)
        kk = np.clip(k, 0, max(0, times.size - 2))
        if times.size > 1:
            dt = (times[kk + 1] - times[kk]).astype(np.float64)
            frac = np.where(inside, (t_ns - times[kk]) / np.where(dt > 0, dt, 1.0), 0.0)
            value = rates[kk] + (rates[np.minimum(kk + 1, times.size - 1)] - rates[kk]) * frac
        else:
            value = np.full(t_ns.shape, rates[0])
        return np.where(k < 0, 0.0, np.where(k >= times.size - 1, rates[-1], value))
