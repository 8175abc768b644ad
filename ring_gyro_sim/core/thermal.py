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
Temperature: the ambient, the die that follows it, and the device at the die's temperature.

Ambient (T1)
    ``T_a(t)``, K: the knots ``scenario.temperature_times`` / ``scenario.temperature_values``,
    linear between knots, the first value before the first knot and the last after the last
    (a repeated time is a step); no knots: ``thermal.reference_temperature``. A streamed
    ambient (``~/temperature``, :class:`~ring_gyro_sim.run.AmbientTemperature`) is a step at
    its time, held, and replaces the knots after it.

Die (T2)
    A first-order lag, the die's heat capacity against its conductance to the package::

        tau dT/dt = T_a - T,   T(0) = T_a(0)                                          (T2)

    ``tau`` = ``thermal.time_constant`` (0: the die is at the ambient). Over a stretch where
    the ambient is linear, ``T_a = A + s t``, the solution is exact:
    ``T(h) = T_a(h) - s tau + (T(0) - T_a(0) + s tau) e^{-h / tau}``; :class:`DieTemperature`
    advances it between the ambient's knots and steps.

The device at die temperature T (T3-T6), ``dT = T - T_ref`` (``thermal.reference_temperature``,
where the configuration's values hold)
    * (T3) every principal frequency ``f (1 + alpha dT)``, ``alpha`` =
      ``thermal.frequency_coefficient`` (silicon: about -30 ppm/K, half the temperature
      coefficient of its Young's modulus; the ring's expansion is second order);
    * (T4) every principal Q ``Q (T / T_ref)^(-gamma)``, ``gamma`` =
      ``thermal.quality_factor_exponent`` (a power law: the damping ``omega / Q`` of each
      principal axis grows by ``(T / T_ref)^gamma``, so a damping mismatch, and the zero-rate
      output it gives, grow with it);
    * (T5) the Brownian force noise at ``gyro.temperature * T / T_ref`` (``gyro.temperature``
      is the noise temperature at the reference, 0 keeps it off);
    * (T6) the charge amplifiers' gain ``(1 + beta dT)`` (their feedback capacitance
      ``C_f / (1 + beta dT)``), ``beta`` = ``thermal.gain_coefficient``.

    The electrostatic force, the electrodes' geometry and the loops' constants do not change.
    :func:`device_at` returns the configuration of the device at T; the simulator builds its
    linear coefficients and its amplifiers from it and keeps everything else (the loops'
    conversions, the sense chain's model values, the calibration): a real sensor's
    electronics do not know the die moved.

Validity: linear laws about the reference; silicon's TCF is itself linear to about 1 % over
100 K, and a power law of Q fits a narrow range only (Q of thermoelastic damping has its own
temperature peak). The model has no thermal stress: a package that warps the ring would add
a temperature-dependent split, which ``modes.*`` set as a constant.
"""

from dataclasses import replace
import math
from typing import List, Sequence, Tuple

from ring_gyro_sim.core.gyro import modes
from ring_gyro_sim.core.params import SimConfig

__all__ = ['AmbientProfile', 'DieTemperature', 'device_at', 'frequency_scale',
           'KELVIN_AT_0_CELSIUS', 'start_state_device']

KELVIN_AT_0_CELSIUS = 273.15
"""0 degC in K: sensor_msgs/msg/Temperature carries degrees Celsius."""


def device_at(config: SimConfig, temperature_k: float) -> SimConfig:
    """Return the configuration of the device at die temperature ``temperature_k`` (T3-T6)."""
    th = config.thermal
    d = temperature_k - th.reference_temperature
    if d == 0.0:
        return config
    f_scale = 1.0 + th.frequency_coefficient * d
    q_scale = (temperature_k / th.reference_temperature) ** (-th.quality_factor_exponent)
    m = config.modes

    def scaled(values: Sequence[float], k: float) -> Tuple[float, ...]:
        return tuple(float(v) * k for v in values)
    modes = replace(m, frequencies=scaled(m.frequencies, f_scale),
                    companion_frequencies=scaled(m.companion_frequencies, f_scale),
                    quality_factors=scaled(m.quality_factors, q_scale),
                    companion_quality_factors=scaled(m.companion_quality_factors, q_scale))
    g = config.gyro
    gyro = replace(g, temperature=g.temperature * temperature_k / th.reference_temperature,
                   feedback_capacitance=g.feedback_capacitance / (
                       1.0 + th.gain_coefficient * d))
    return replace(config, modes=modes, gyro=gyro)


def frequency_scale(config: SimConfig, temperature_k: float) -> float:
    """Return the frequencies' factor at die temperature ``temperature_k`` (T3)."""
    th = config.thermal
    return 1.0 + th.frequency_coefficient * (temperature_k - th.reference_temperature)


def start_state_device(config: SimConfig) -> SimConfig:
    """
    Return the device whose drive orbit a run starts on (T2: the die at the ambient at t = 0).

    Open loop, the device at that temperature under the fixed drive (an input). Closed loop,
    the device as configured: the loops hold their set-point (a constant of the electronics,
    the reference device's orbit amplitude) and the NCO starts moved with the frequencies
    (``frequency_scale``), so the start is the orbit the loops hold, up to the small
    difference of the device's frequencies.
    """
    if modes.of(config).closed:
        return config
    return device_at(config, AmbientProfile(config).at(0.0))


class AmbientProfile:
    """
    The ambient temperature (T1): the scheduled knots, then the streamed steps.

    :meth:`at` is the ambient at a time (its limit from the left with ``left=True``: the
    value the linear piece ending there reaches); :meth:`breaks` lists where it may bend.
    """

    def __init__(self, config: SimConfig) -> None:
        self.reference = float(config.thermal.reference_temperature)
        self.times = [float(t) for t in config.run.temperature_times]
        self.values = [float(v) for v in config.run.temperature_values]
        self.steps: List[Tuple[float, float]] = []  # (t s, K) streamed, in time order

    def step(self, t_s: float, kelvin: float) -> None:
        """Set the ambient to ``kelvin`` from ``t_s`` on (a streamed ``~/temperature``)."""
        self.steps = [s for s in self.steps if s[0] < t_s] + [(float(t_s), float(kelvin))]

    def at(self, t_s: float, left: bool = False) -> float:
        """Return the ambient at ``t_s`` (its limit from the left with ``left``), K."""
        held = [k for t, k in self.steps if (t < t_s if left else t <= t_s)]
        if held:
            return held[-1]
        times, values = self.times, self.values
        if not times:
            return self.reference
        for k in range(len(times) - 1):
            t0, t1 = times[k], times[k + 1]
            if t0 < t1 and ((t0 < t_s <= t1) if left else (t0 <= t_s < t1)):
                return values[k] + (values[k + 1] - values[k]) * (t_s - t0) / (t1 - t0)
        before = t_s <= times[0] if left else t_s < times[0]
        return values[0] if before else values[-1]

    def breaks(self, t0: float, t1: float) -> List[float]:
        """Return the times in ``(t0, t1)`` where the ambient's slope or value may change."""
        return sorted({t for t in self.times if t0 < t < t1}
                      | {t for t, _ in self.steps if t0 < t < t1})


class DieTemperature:
    """
    The die temperature (T2), advanced exactly over a piecewise-linear ambient.

    Parameters
    ----------
    config : SimConfig
        ``thermal.time_constant`` and the ambient's knots.

    Attributes
    ----------
    ambient : AmbientProfile
        The ambient it follows (streamed steps go there).
    kelvin : float
        The die temperature at :attr:`t_s`, K.

    """

    def __init__(self, config: SimConfig) -> None:
        self.ambient = AmbientProfile(config)
        self.tau = float(config.thermal.time_constant)
        self.t_s = 0.0
        self.kelvin = self.ambient.at(0.0)

    def advance_to(self, t_s: float) -> float:
        """Advance the die to ``t_s`` (s, not before its current time); return its K."""
        if t_s <= self.t_s:
            if t_s < self.t_s:
                raise ValueError(f"t_s: {t_s} is before the die temperature's time "
                                 f'{self.t_s}')
            return self.kelvin
        temp = self.kelvin
        if self.tau == 0.0:
            temp = self.ambient.at(t_s)
        else:
            edges = [self.t_s] + self.ambient.breaks(self.t_s, t_s) + [t_s]
            for a, b in zip(edges[:-1], edges[1:]):
                if b <= a:
                    continue
                start, end = self.ambient.at(a), self.ambient.at(b, left=True)
                slope_tau = (end - start) / (b - a) * self.tau
                temp = end - slope_tau + (temp - start + slope_tau) * math.exp(
                    -(b - a) / self.tau)
        self.t_s = t_s
        self.kelvin = temp
        return temp
