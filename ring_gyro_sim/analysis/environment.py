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
What the environment does to the rate: a device's mean output with and without it.

The environment tests of ``ring_gyro characterize`` and the sweep points of ``kind:
environment`` measure one thing, the **rectified bias**: the mean of ``~/rate`` over the end
of a run of the device in its scenario's environment (``scenario.vibration_*``, the sine and
the random profile, ``scenario.acceleration``) less the same mean of the same device
without it. Both runs are :func:`quiet`: noise off and the model's own readout
(``gyro.calibration.source: ideal``), so the difference is the deterministic shift the
environment causes, exact in a short record (with noise a mean needs minutes to resolve a
shift of deg/h), and whatever the device reads at zero rate without the environment (an
imperfect ring's zero-rate output) cancels. Both
start as every run does (:func:`~ring_gyro_sim.core.gyro.operating_point.start_state`): the
drive's orbit (``drive.start_on``) with the 1theta pair on its linear answer to the
environment (:func:`~ring_gyro_sim.core.gyro.operating_point.with_environment_response`), so
the 1theta mode does not ring for its 3.4 s. What still settles is
the rate path itself: open loop the drive and the sense mode follow a change of their
frequencies with their own ``2 Q / omega`` (1.3 s), so a run of 10 s averaged over its last
2 s reads the settled shift within 0.5 % and a shorter one reads it low (doc/environments.md).
"""

from dataclasses import replace
import math
from typing import Any, Callable, Dict, Optional, Sequence

import numpy as np
from ring_gyro_sim.core.params import SimConfig
from ring_gyro_sim.run import Run, Sink

__all__ = ['ZERO_RAD_S', 'loglog_slope', 'mean_output', 'quiet',
           'without_environment']

ZERO_RAD_S = 1e-12
"""A rectified bias below this (rad/s, 2e-4 deg/h) is zero to the runs' rounding: a perfect
ring's mirror symmetry gives ~1e-17 rad/s there, the smallest shift measured on an
imperfect one (1 g, doc/environments.md) is 1e-5 rad/s."""


def quiet(config: SimConfig) -> SimConfig:
    """Return ``config`` with its noise off and the model's own readout (module docstring)."""
    gyro = replace(config.gyro, temperature=0.0, input_noise_density=0.0,
                   bias_instability=0.0, calibration_source='ideal')
    return replace(config, gyro=gyro)


def without_environment(config: SimConfig) -> SimConfig:
    """Return ``config`` without its sine and random vibrations and steady acceleration."""
    run = replace(config.run, vibration_frequency=0.0, vibration_amplitude=0.0,
                  vibration_angle=0.0, vibration_psd_frequencies=(),
                  vibration_psd_values=(), acceleration=())
    return replace(config, run=run)


class _Means(Sink):
    """Sums of the rate and quadrature samples from a time on."""

    def __init__(self, from_s: float) -> None:
        self.from_s = from_s
        self.rate = 0.0
        self.quadrature = 0.0
        self.count = 0

    def block(self, block) -> None:
        r = block.rate
        if r is None or len(r) == 0:
            return
        keep = r.t > self.from_s
        self.rate += float(np.sum(r.rate[keep]))
        self.quadrature += float(np.sum(r.quadrature[keep]))
        self.count += int(np.count_nonzero(keep))


def mean_output(config: SimConfig, duration_s: float, average_s: float,
                log: Optional[Callable[[str], None]] = None,
                progress: Optional[Callable[[float], None]] = None) -> Dict[str, Any]:
    """
    Run ``config`` (as given: :func:`quiet` it first) and return its means.

    Parameters
    ----------
    config : SimConfig
        The device and its scenario (``gyro.enabled``).
    duration_s, average_s : float
        The run's length and its final part averaged, s.
    log : callable, optional
        Told when a start state is computed.
    progress : callable, optional
        Called with the simulated time after each block, s.

    Returns
    -------
    dict
        ``rate_rad_s`` and ``quadrature_rad_s`` (means of ``~/rate`` over the window),
        ``samples`` (in it), ``contact`` (the run stopped on the electrodes: no means, nan).

    """
    means = _Means(duration_s - average_s)
    run = Run(config, sink=means, log=log)
    total = int(round(duration_s / (config.run.output_period_ns * 1e-9)))
    block = config.run.block_samples
    done = 0
    try:
        while done < total and run.running:
            count = min(block, total - done)
            run.advance(count)
            done += count
            if progress is not None:
                progress(run.sim.time_s)
        contact = not run.running
    finally:
        run.close()
    if contact or not means.count:
        return {'rate_rad_s': math.nan, 'quadrature_rad_s': math.nan, 'samples': 0,
                'contact': contact}
    return {'rate_rad_s': means.rate / means.count,
            'quadrature_rad_s': means.quadrature / means.count, 'samples': means.count,
            'contact': False}


def loglog_slope(amplitudes: Sequence[float], values: Sequence[float]) -> Optional[Dict]:
    """
    Least-squares line of ``ln |value|`` against ``ln amplitude``: the power of a power law.

    Returns
    -------
    dict or None
        ``slope``, its ``standard_error`` (from the residuals, n - 2 degrees of freedom; 0
        with two points), ``coefficient`` (``|value| = coefficient amplitude^slope``, the sign
        of the values kept) and ``local_slopes`` (between neighbours); None when a value is
        below :data:`ZERO_RAD_S` or not finite, or the values change sign (no power law).

    """
    a = np.asarray(amplitudes, dtype=float)
    y = np.asarray(values, dtype=float)
    if a.size < 2 or not np.all(np.isfinite(y)) or np.any(np.abs(y) < ZERO_RAD_S) or \
            not (np.all(y > 0) or np.all(y < 0)):
        return None
    x, z = np.log(a), np.log(np.abs(y))
    (slope, intercept), residual = np.polyfit(x, z, 1, full=True)[:2]
    error = 0.0
    if a.size > 2:
        s2 = float(residual[0]) / (a.size - 2) if residual.size else 0.0
        error = math.sqrt(s2 / float(np.sum((x - x.mean()) ** 2)))
    return {'slope': float(slope), 'standard_error': error,
            'coefficient': float(np.sign(y[0]) * math.exp(intercept)),
            'local_slopes': [float(v) for v in np.diff(z) / np.diff(x)]}
