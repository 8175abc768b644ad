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
The calibration of the rate output: a bias and a scale factor held for the whole run.

A real gyroscope does not know its own scale factor: it is measured once, on a rate table
at the factory, and the sensor then applies that number whatever happens to the device.
``~/rate`` is (K1)::

    rate = r / S - b,   quadrature = r_q / S                                       (K1)

``r, r_q`` the readout (the sense demodulator's in-phase and quadrature outputs over the
drive pick-off's amplitude relative to its amplitude at zero rate, V, open loop; the in-phase and
quadrature rebalance forces, m/s^2, with ``control.mode: rebalance``; both through the output
low-pass), ``S`` the scale factor (readout per rad/s), ``b`` the bias (rad/s).

``gyro.calibration.source``
    ``factory`` (default): ``S`` and ``b`` measured on this device as a factory does (K2),
    at the start of the run, then held. ``given``: ``gyro.calibration.scale_factor`` and
    ``gyro.calibration.bias`` as set. ``ideal``: no calibration: the rate is the readout
    over the model's own scale factor of the device in force (the mechanics alone, without
    bias; ``core.gyro.electronics`` E4, E7, and ``core.gyro.control`` C7).

Nothing recomputes a held calibration during the run: a parameter change, a shock that moves
the operating point or (with ``scenario.temperature_*``) the die temperature show up in the
rate as the errors they are.

The factory procedure (K2)
    Run by ``core.bench.factory`` (the constants ``FACTORY_*`` named here are its own).
    A rate transfer test (IEEE Std 1431's scale-factor test, reduced to three rates) on the
    device as configured, simulated without noise (``gyro.temperature``,
    ``gyro.input_noise_density`` and ``gyro.bias_instability`` at 0), without the scenario
    (no shock, no rate profile), at the rates ``0`` and ``+-FACTORY_RATE``::

        S = (r(+W) - r(-W)) / (2 W),   b = r(0) / S                                  (K2)

    Each rate is a run that starts on its drive orbit with the sense mode's steady response
    to it (``operating_point.start_state``), settles for
    ``FACTORY_SETTLE_TIME_CONSTANTS`` time constants ``1 / (2 pi f)`` of the slowest of
    the output filter, the rebalance loop and, closed loop, the AGC and the PLL (at least
    ``FACTORY_MIN_SETTLE_S``), and is then averaged over windows of
    ``FACTORY_AVERAGE_S`` until two in a row agree within ``FACTORY_TOLERANCE`` of
    the reading: the loops together are slower than each one's bandwidth says (on the
    default gyroscope the reading's transient decays tenfold per 0.2 s, a 87 ms time
    constant against the AGC's 32 ms), and the open-loop drive and sense modes ring down
    with their own 1.3 s. 3.0 simulated s for the default gyroscope, 28.6 s for the open
    loops of ``config/gyro.yaml`` (doc/performance.md has their CPU time); at 313.15 K the table
    then reads the scale factor the temperature laws give within 0.13 % (10 time
    constants alone leave it 3.5 % off). A device is calibrated at
    ``thermal.reference_temperature`` whatever the run's ambient, once: ``factory``
    keeps its tables (``factory_tables``, from which the calibration is derived) in this
    process and, as a part keeps its calibration in its memory, in a file
    (``$RING_GYRO_SIM_CACHE``, default ``~/.cache/ring_gyro_sim``, ``calibration-<key>.json``;
    an empty variable keeps none), keyed by the SHA-256 of the configuration that matters
    and of the source of ``ring_gyro_sim.core``, so that a changed model measures again. A
    file that cannot be read or written is ignored.

Temperature compensation (K3)
    ``b(T) = b + sum_i b_i dT^i``, ``S(T) = S (1 + sum_i s_i dT^i)``, ``dT = T - T_ref``,
    ``T`` the die temperature sensor's reading (the die's temperature, every 10 ms: core.thermal)
    and ``[b_1 .. b_k, s_1 .. s_k]`` = ``gyro.calibration.temperature_coefficients``
    (``given``) or, ``factory``, fitted to a temperature series: the table (K2) again at each
    die temperature of ``gyro.calibration.temperature_points`` (the device at a steady die
    temperature, core.thermal T3-T6), and the least-squares polynomial through the
    reference of the biases' and the relative scale factors' changes, of degree 1 for one
    point and 2 for more (IEEE Std 1431's temperature tests fit a polynomial likewise).
    What a parabola leaves is the compensation's residual.

What the factory reads (:class:`TableReading`, ``factory_tables``)
    Each table's ``S(T)``, ``r(0)`` and the quadrature reading at zero rate ``r_q(0)``
    (K1's quadrature channel, the same window as ``r(0)``): the device's bias ``r(0) / S`` and
    quadrature ``r_q(0) / S`` in rate units, at the reference and at each temperature point.
    The calibration holds ``S``, ``b``, the fit and the reference table's ``V_ref`` (the
    open-loop readout's trim, with which the series' tables read too); a datasheet (a device
    population, ``sweep.point``) reads the rest from the same tables, which are run once.
"""

from dataclasses import dataclass
from typing import Any, Dict, Optional, Sequence, Tuple

import numpy as np
from ring_gyro_sim.core.gyro import modes
from ring_gyro_sim.core.params import SimConfig

__all__ = ['Calibration', 'TableReading', 'fit_temperature_series', 'given', 'readout_unit']


def readout_unit(config: SimConfig) -> str:
    """Return the unit of the readout ``r`` of (K1) and of ``S`` per rad/s."""
    return modes.of(config).readout_unit


@dataclass(frozen=True)
class Calibration:
    """
    A held calibration (K1).

    Attributes
    ----------
    source : str
        ``factory`` or ``given``.
    bias : float
        ``b``, rad/s.
    scale_factor : float
        ``S``, readout per rad/s (``unit``).
    unit : str
        Unit of the readout (``readout_unit``).
    reference_temperature : float
        K, the die temperature of ``bias`` and ``scale_factor``.
    temperature_coefficients : tuple of float
        ``[b_1 .. b_k, s_1 .. s_k]`` of the compensation (K3; empty: none).
    readout_reference_v : float
        The open-loop readout's drive pick-off amplitude at zero rate, V, trimmed with the
        calibration (K1); 0: the run's operating point's, taken back to zero rate.

    """

    source: str
    bias: float
    scale_factor: float
    unit: str
    reference_temperature: float = 298.15
    temperature_coefficients: Tuple[float, ...] = ()
    readout_reference_v: float = 0.0

    def at(self, die_temperature: Optional[float]) -> Tuple[float, float]:
        """
        Return ``(b, S)`` compensated at a die temperature, K (K3; None: the reference).

        ``b + sum b_i dT^i`` and ``S (1 + sum s_i dT^i)``, ``dT = T - T_ref``, of the
        coefficients ``[b_1 .. b_k, s_1 .. s_k]``.
        """
        coefficients = self.temperature_coefficients
        if not coefficients or die_temperature is None:
            return self.bias, self.scale_factor
        d = die_temperature - self.reference_temperature
        k = len(coefficients) // 2
        powers = [d ** (i + 1) for i in range(k)]
        bias = self.bias + sum(c * p for c, p in zip(coefficients[:k], powers))
        scale = self.scale_factor * (1.0 + sum(c * p for c, p in zip(coefficients[k:], powers)))
        return bias, scale

    def apply(self, readout: np.ndarray, quadrature: np.ndarray,
              die_temperature: Optional[float] = None):
        """Return ``(rate, quadrature)`` in rad/s of readouts (K1, K3)."""
        bias, scale = self.at(die_temperature)
        return readout / scale - bias, quadrature / scale

    @classmethod
    def from_dict(cls, values: Dict[str, Any]) -> 'Calibration':
        """Return the calibration of :meth:`to_dict`'s values (a recording's)."""
        unit = str(values['scale_factor_unit'])
        return cls(str(values['source']), float(values['bias_rad_s']),
                   float(values['scale_factor']), unit[:unit.index('/(rad/s)')],
                   float(values.get('reference_temperature_k', 298.15)),
                   tuple(float(c) for c in values.get('temperature_coefficients', ())),
                   float(values.get('readout_reference_v', 0.0)))

    def to_dict(self) -> Dict[str, Any]:
        """Return the calibration as plain values (for a recording and the diagnostics)."""
        return {'source': self.source, 'bias_rad_s': float(self.bias),
                'scale_factor': float(self.scale_factor),
                'scale_factor_unit': f'{self.unit}/(rad/s)',
                'reference_temperature_k': float(self.reference_temperature),
                'temperature_coefficients': [float(c) for c in self.temperature_coefficients],
                'readout_reference_v': float(self.readout_reference_v)}


@dataclass(frozen=True)
class TableReading:
    """
    One rate table (K2) at one steady die temperature: what the factory reads.

    Attributes
    ----------
    temperature_k : float
        The die temperature, K.
    scale_factor : float
        ``S(T)``, readout per rad/s.
    zero_rate, zero_quadrature : float
        ``r(0)`` and ``r_q(0)``: the readout and the quadrature readout at zero rate.
    readout_reference_v : float
        The open-loop readout's drive pick-off amplitude the table read with, V (K1): the
        reference table's at zero rate, held over the temperature series (0 with rebalance).

    """

    temperature_k: float
    scale_factor: float
    zero_rate: float
    zero_quadrature: float
    readout_reference_v: float = 0.0

    @property
    def bias(self) -> float:
        """``r(0) / S(T)``, rad/s: the zero-rate output at this temperature."""
        return self.zero_rate / self.scale_factor

    @property
    def quadrature(self) -> float:
        """``r_q(0) / S(T)``, rad/s: the quadrature at zero rate in rate units (K1)."""
        return self.zero_quadrature / self.scale_factor


def fit_temperature_series(reference_k: float, temperatures_k: Sequence[float],
                           changes: Sequence[float]) -> Tuple[float, ...]:
    """
    Return the coefficients of the least-squares polynomial through the reference (K3).

    ``changes[i]`` is a figure's change from the reference at ``temperatures_k[i]``; the
    polynomial ``sum_i c_i dT^i`` has degree 1 for one temperature and 2 for more.
    """
    order = min(2, len(temperatures_k))
    rows = [[(t - reference_k) ** (i + 1) for i in range(order)] for t in temperatures_k]
    fit = np.linalg.lstsq(np.array(rows), np.array(changes, dtype=float), rcond=None)[0]
    return tuple(float(c) for c in fit)


def given(config: SimConfig) -> Calibration:
    """Return the calibration of ``gyro.calibration.bias`` and ``.scale_factor`` as set."""
    g = config.gyro
    return Calibration('given', float(g.calibration_bias), float(g.calibration_scale_factor),
                       readout_unit(config), float(config.thermal.reference_temperature),
                       tuple(g.calibration_temperature_coefficients))
