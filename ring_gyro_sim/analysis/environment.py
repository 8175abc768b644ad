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

__all__ = ['ZERO_RAD_S', 'half_sine_residual', 'loglog_slope', 'mean_output',
           'one_theta_peak', 'quiet', 'recovery_time', 'shock_record', 'stop_threshold',
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
    try:
        run.advance_for(duration_s, progress)
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


def half_sine_residual(omega: float, duration_s: float) -> float:
    """
    Return the largest displacement of an undamped oscillator per m/s^2 of a half-sine, s^2.

    ``x'' + omega^2 x = -A sin(omega_p t)`` on ``0 <= t <= T`` (eq. 27, 32; ``omega_p = pi /
    T``), from rest: during the pulse ``x = -A (sin omega_p t - (omega_p / omega) sin omega t)
    / (omega^2 - omega_p^2)``; after it the free oscillation of amplitude
    ``2 A omega_p |cos(omega T / 2)| / (omega |omega_p^2 - omega^2|)`` (the residual shock
    response spectrum). The larger of the residual and the pulse's own maximum (on a grid of
    2 001 instants of the pulse) per unit A; ``~ 2 T / (pi omega)`` = ``delta_v / omega`` for
    a pulse much shorter than the period. ``omega = omega_p`` is taken as its limit.
    """
    wp = math.pi / duration_s
    if abs(omega - wp) < 1e-9 * wp:
        omega = wp * (1.0 + 1e-6)
    d = omega * omega - wp * wp
    residual = 2.0 * wp * abs(math.cos(omega * duration_s / 2.0)) / (omega * abs(d))
    t = np.linspace(0.0, duration_s, 2001)
    primary = float(np.max(np.abs(np.sin(wp * t) - wp / omega * np.sin(omega * t)))) / abs(d)
    return max(residual, primary)


def stop_threshold(config: SimConfig) -> Dict[str, float]:
    """
    Return the largest half-sine shock (m/s^2) whose 1theta answer stays inside the stops.

    ``linear``: the stop clearance ``g_s`` over :func:`half_sine_residual` at ``omega_1``
    (eq. 28 without ``F_nl``). ``electrostatic``: the same with the electrostatic softening of
    the 1theta mode alone, ``R(q) = omega_1^2 q - a_nl,1(q)`` (eq. 28, the other coordinates
    at 0): the pulse (much shorter than the period) gives the mode the energy
    ``A^2 S^2 omega_1^2 / 2`` of the linear answer, which reaches ``g_s`` where it equals
    ``U(g_s) = int_0^g_s R dq``: ``A = A_linear sqrt(U(g_s) / (omega_1^2 g_s^2 / 2))``.
    This is the 1theta mode alone: the ring touches where its whole radial displacement
    ``|w|`` reaches ``g_s``, and the electrostatic terms (eq. 21) also drive the 2theta and
    3theta modes with ``q1^2`` and ``q1 q2``, which add to ``|w|`` at the shock's angle (the
    datasheet's runs measure where). ``gap_m``, ``omega_1``, ``response_s2`` (per m/s^2),
    ``energy_ratio`` (``U(g_s)`` over its linear part) and the potential on its grid
    (``q_m``, ``potential``, J/kg), which :func:`one_theta_peak` inverts.
    """
    from ring_gyro_sim.core import forces
    gap = config.stops.gap
    omega = 2.0 * math.pi * config.modes.coordinate_frequencies()[0]
    s = half_sine_residual(omega, config.shock_duration_s)
    model = forces.build_force_model(config)
    x = np.zeros(model.n_coordinates)
    q = np.linspace(0.0, gap, 2001)
    r = np.empty_like(q)
    for k, qk in enumerate(q):
        x[0] = qk
        r[k] = omega * omega * qk - forces.nonlinear_acceleration(x, model)[0]
    potential = np.concatenate(([0.0], np.cumsum((r[1:] + r[:-1]) / 2.0 * np.diff(q))))
    energy = float(potential[-1])
    linear = gap / s
    return {'gap_m': gap, 'omega_1': omega, 'response_s2': s, 'linear': linear,
            'electrostatic': linear * math.sqrt(energy / (0.5 * omega * omega * gap * gap)),
            'energy_ratio': energy / (0.5 * omega * omega * gap * gap), 'q_m': q,
            'potential': potential}


def one_theta_peak(threshold: Dict[str, Any], peak: float) -> Optional[float]:
    """
    Return the 1theta mode's peak (m) under a half-sine of ``peak`` m/s^2, softened.

    The energy the pulse gives, ``(peak S omega_1)^2 / 2`` (:func:`stop_threshold`), equals
    the potential ``U(q)`` at the peak; None beyond the stop (``q > g_s``).
    """
    energy = 0.5 * (peak * threshold['response_s2'] * threshold['omega_1']) ** 2
    if energy > threshold['potential'][-1]:
        return None
    return float(np.interp(energy, threshold['potential'], threshold['q_m']))


class _Trace(Sink):
    """The rate output and whether each sample is a measurement."""

    def __init__(self) -> None:
        self.t, self.rate, self.variance = [], [], []

    def block(self, block) -> None:
        r = block.rate
        if r is None or len(r) == 0:
            return
        self.t.append(np.asarray(r.t))
        self.rate.append(np.asarray(r.rate))
        v = r.variance if r.variance is not None else np.zeros(len(r))
        self.variance.append(np.asarray(v))


def shock_record(config: SimConfig, duration_s: float,
                 log: Optional[Callable[[str], None]] = None,
                 progress: Optional[Callable[[float], None]] = None) -> Dict[str, Any]:
    """
    Run ``config`` (its shocks and stops) and return its rate record.

    Returns
    -------
    dict
        ``t``, ``rate`` (rad/s), ``variance`` ((rad/s)^2, ``NOT_MEASURED_VARIANCE`` where
        ``~/rate`` is not a measurement) arrays, ``impacts`` (``Simulator.impacts``),
        ``status`` (the summary's), ``contact`` (with an electrode), ``survived`` (the run
        reached ``duration_s`` free of the electrodes), ``finite`` (no NaN in the rate) and
        ``q1_peak_m`` (the largest ``|q1|`` of the run), ``min_gap_m`` (the least gap to
        an electrode, the summary's).

    """
    trace = _Trace()
    run = Run(config, sink=trace, log=log)
    try:
        complete = run.advance_for(duration_s, progress)
        summary = run.summary()
        impacts = run.full_model().impacts
    finally:
        run.close()
    t, rate, var = (np.concatenate(x) if x else np.zeros(0)
                    for x in (trace.t, trace.rate, trace.variance))
    contact = bool(summary.contact)
    return {'t': t, 'rate': rate, 'variance': var, 'impacts': int(impacts),
            'q1_peak_m': float(summary.peak_abs_m.get('q1', math.nan)),
            'min_gap_m': float(summary.min_gap_m),
            'status': summary.status, 'contact': contact,
            'survived': bool(complete and not contact),
            'finite': bool(np.all(np.isfinite(rate)))}


def recovery_time(t: np.ndarray, error: np.ndarray, at_s: float,
                  tolerance: float) -> Optional[float]:
    """
    Return the time from ``at_s`` to the last sample with ``|error| > tolerance`` (s).

    0 when no sample after ``at_s`` is off; None when the last one is (not back by the end).
    """
    after = t > at_s
    off = np.flatnonzero(~(np.abs(error[after]) <= tolerance))
    if not off.size:
        return 0.0
    if off[-1] == int(np.count_nonzero(after)) - 1:
        return None
    return float(t[after][off[-1]] - at_s)
