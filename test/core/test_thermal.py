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
Temperature (core.thermal): the die, the device's laws, the drift they give.

The die's lag against its closed form, the device's laws, and a factory-calibrated imperfect
gyroscope whose bias and scale factor move with a 20 K ramp of its die as the laws predict,
and less with the compensation.
"""

import math

import numpy as np
import pytest
from ring_gyro_sim.core import thermal
from ring_gyro_sim.core.errors import InputError
from ring_gyro_sim.core.gyro.control import KAPPA_2
from ring_gyro_sim.core.params import build_config
from ring_gyro_sim.run import AmbientTemperature, Run

T_REF = 298.15
TEN_DEG_S = math.radians(10.0)
IMPERFECT = {'modes.companion_frequencies': [11200.0, 15800.02, 22000.0],
             'modes.companion_quality_factors': [120000.0, 0.95 * 64700.0, 170000.0],
             'modes.frequency_axes': [0.0, 10.0, 0.0], 'modes.damping_axes': [0.0, 22.5, 0.0],
             'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0}


def test_the_die_lags_a_ramp_and_a_step_as_a_first_order_system():
    # (T2) tau T' = T_a - T: behind a ramp of slope s by s tau (1 - e^{-t/tau}), after a
    # step by dT e^{-t/tau}; advanced in any chunks, the same temperature
    tau, slope = 2.0, 0.5
    config = build_config({'thermal.time_constant': tau,
                           'scenario.temperature_times': [1.0, 11.0, 11.0],
                           'scenario.temperature_values': [300.0, 305.0, 290.0]})
    die = thermal.DieTemperature(config)
    assert die.kelvin == 300.0
    for t in (0.5, 1.0, 3.0, 7.5, 11.0):
        lag = slope * tau * (1.0 - math.exp(-(t - 1.0) / tau)) if t > 1.0 else 0.0
        assert die.advance_to(t) == pytest.approx(300.0 + slope * (max(t, 1.0) - 1.0) - lag,
                                                  abs=1e-12)
    at_step = die.kelvin
    for t in (11.5, 14.0):
        expected = 290.0 + (at_step - 290.0) * math.exp(-(t - 11.0) / tau)
        assert die.advance_to(t) == pytest.approx(expected, abs=1e-12)
    coarse = thermal.DieTemperature(config)
    assert coarse.advance_to(14.0) == pytest.approx(die.kelvin, abs=1e-12)
    streamed = thermal.DieTemperature(config)
    at_4 = streamed.advance_to(4.0)
    streamed.ambient.step(4.0, 310.0)  # a ~/temperature step holds, over the knots
    assert streamed.advance_to(20.0) == pytest.approx(
        310.0 + (at_4 - 310.0) * math.exp(-16.0 / tau), abs=1e-12)


def test_the_device_follows_its_laws_and_is_itself_at_the_reference():
    config = build_config({})
    assert thermal.device_at(config, T_REF) is config
    d = 20.0
    hot = thermal.device_at(config, T_REF + d)
    th = config.thermal
    for cold_f, hot_f in zip(config.modes.coordinate_frequencies(),
                             hot.modes.coordinate_frequencies()):
        assert hot_f == pytest.approx(cold_f * (1.0 + th.frequency_coefficient * d), rel=1e-15)
    for cold_q, hot_q in zip(config.modes.coordinate_quality_factors(),
                             hot.modes.coordinate_quality_factors()):
        assert hot_q == pytest.approx(
            cold_q * ((T_REF + d) / T_REF) ** -th.quality_factor_exponent, rel=1e-14)
    assert hot.gyro.temperature == pytest.approx(config.gyro.temperature * (T_REF + d) / T_REF)
    assert hot.gyro.feedback_capacitance == pytest.approx(
        config.gyro.feedback_capacitance / (1.0 + th.gain_coefficient * d))


def test_an_ambient_out_of_range_is_refused_and_counted():
    run = Run(build_config({'gyro.enabled': False, 'modes.companions': False,
                            'control.mode': 'open_loop',
                            'drive.start_on': 'rest'}))
    for bad in (float('nan'), 20.0, 1e4):
        with pytest.raises(InputError, match='temperature'):
            run.apply(AmbientTemperature(bad))
    assert run.rejected['temperature'] == 3
    run.apply(AmbientTemperature(310.0))
    run.advance(run.config.run.block_samples)
    assert run.diagnostics().values['ambient_temperature_k'] == 310.0


def _after_ramp(values, rate, hold=0.6):
    """Return the mean rate over 0.2 s after a 20 K ramp of the ambient over 2 s, held."""
    config = build_config({**IMPERFECT, **values, 'thermal.time_constant': 0.0,
                           'scenario.temperature_times': [0.0, 2.0],
                           'scenario.temperature_values': [T_REF, T_REF + 20.0],
                           'scenario.rate_times': [0.0], 'scenario.rate_values': [rate]})
    run = Run(config)
    blocks = [run.advance(config.run.block_samples)
              for _ in range(int(round((2.0 + hold) / config.run.block_duration)))]
    assert blocks[-1].samples.die_temperature == pytest.approx(T_REF + 20.0, abs=1e-9)
    r = np.concatenate([b.rate.rate for b in blocks])
    return float(np.mean(r[-200:])), run


def test_a_20_k_ramp_moves_bias_and_scale_factor_as_the_laws_predict():
    # Force-to-rebalance reads S_c = (2 kappa Omega + C_sc) omega X through the factory's
    # S = 2 kappa omega_0 X_0 and b = C_sc0 / (2 kappa). Warmer by dT: omega and every
    # principal frequency by 1 + alpha dT (T3), the damping c = omega / Q by
    # (1 + alpha dT) (T / T_ref)^gamma (T4), and the true amplitude that the AGC holds through
    # amplifiers whose gain rose by 1 + beta dT falls by it (T6). With
    # k = (1 + alpha dT) / (1 + beta dT):
    #   scale factor  S(T) / S = k
    #   bias          b(T) - b = b [k (1 + alpha dT) (T / T_ref)^gamma - 1]
    zero, run = _after_ramp({}, 0.0)
    turning, _ = _after_ramp({}, TEN_DEG_S)
    th = run.config.thermal
    d = 20.0
    k = (1.0 + th.frequency_coefficient * d) / (1.0 + th.gain_coefficient * d)
    b = run.calibration.bias
    w = 2.0 * math.pi * 15800.0
    assert b == pytest.approx((w / 64700.0 - w / (0.95 * 64700.0)) / (4.0 * KAPPA_2), rel=0.02)
    bias_change = b * (k * (1.0 + th.frequency_coefficient * d)
                       * ((T_REF + d) / T_REF) ** th.quality_factor_exponent - 1.0)
    scale_change = (turning - zero) / TEN_DEG_S - 1.0
    print(f'20 K: bias {zero:.5e} rad/s (laws {bias_change:.5e}), scale factor '
          f'{scale_change * 1e6:.1f} ppm (laws {(k - 1.0) * 1e6:.1f} ppm)')
    assert zero == pytest.approx(bias_change, rel=0.05)
    assert scale_change == pytest.approx(k - 1.0, rel=0.05)
    # The compensation fitted to a series at 308.15 and 318.15 K takes most of it out
    compensated, comp_run = _after_ramp(
        {'gyro.calibration.temperature_points': [T_REF + 10.0, T_REF + 20.0]}, 0.0)
    print(f'compensated: bias {compensated:.3e} rad/s, {abs(zero / compensated):.0f} x '
          f'less; coefficients {comp_run.calibration.temperature_coefficients}')
    assert abs(compensated) < abs(zero) / 20.0
