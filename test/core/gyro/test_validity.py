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
The rate output says what it is worth (core/gyro/validity.py), from the sensor's own signals.

Never from the true rate. A 10 000 g shock at 1 s on a gyroscope turning at 10 deg/s, 6 s
(doc/gyroscope.md): open loop (config/gyro.yaml's operating point), the drive closed loop
with the open-loop sense readout, and the defaults (force-to-rebalance). The normalized error
``|rate - truth| / sqrt(cov_zz)`` of every ``~/rate`` sample must stay below 6 for at least
99.9 % of them, and whenever the channel says valid its error is within its stated band.
"""

import math

import numpy as np
import pytest
from ring_gyro_sim.core.gyro.control import CONTROL_CHANNELS
from ring_gyro_sim.core.gyro.validity import (NOT_MEASURED_VARIANCE, RateValidity,
                                              REASONS, SETTLE_TIME_CONSTANTS)
from ring_gyro_sim.core.params import build_config, STANDARD_GRAVITY
from ring_gyro_sim.run import Run

TEN_DEG_S = math.radians(10.0)
SHOCK = {'scenario.rate_times': [0.0], 'scenario.rate_values': [TEN_DEG_S],
         'scenario.shock_times': [1.0], 'scenario.shock_peaks': [10_000 * STANDARD_GRAVITY]}
MODES = {
    'open': {'control.mode': 'open_loop',
             'drive.amplitude': 0.0065, 'drive.frequency': 15800.0},
    'closed': {'control.mode': 'closed_loop'},
    'rebalance': {},
}


def shock_run(mode, seconds=6.0):
    """Run ``mode`` through the shock; return the rate samples, their truth and more."""
    config = build_config({**SHOCK, **MODES[mode]})
    run = Run(config)
    block = config.run.block_samples
    parts, rebalance_on, beyond_band, valid_snapshots = [], [], 0, 0
    on = CONTROL_CHANNELS.index('rebalance_on')
    for _ in range(int(round(seconds / 0.01))):
        b = run.advance(block)
        at = np.searchsorted(b.samples.t, b.rate.t)
        truth = b.samples.applied_rate[at]
        parts.append(np.column_stack([b.rate.t, b.rate.rate, truth, b.rate.variance]))
        if b.samples.control is not None:
            rebalance_on.append(b.samples.control[at, on])
        diag = run.diagnostics()
        if diag.values['rate_valid']:
            valid_snapshots += 1
            beyond_band += abs(b.rate.rate[-1] - truth[-1]) > diag.values['rate_band_rad_s']
    t, rate, truth, variance = np.concatenate(parts).T
    return {'t': t, 'error': rate - truth, 'variance': variance, 'beyond_band': beyond_band,
            'valid_snapshots': valid_snapshots,
            'rebalance_on': np.concatenate(rebalance_on) if rebalance_on else None}


@pytest.fixture(scope='module', params=sorted(MODES))
def shocked(request):
    return request.param, shock_run(request.param)


def test_the_covariance_is_honest_through_a_10000g_shock(shocked):
    mode, r = shocked
    z = np.abs(r['error']) / np.sqrt(r['variance'])
    within = float(np.mean(z < 6.0))
    measured = r['variance'] < NOT_MEASURED_VARIANCE
    print(f'{mode}: {100 * within:.3f} % of {z.size} samples within 6 sigma (worst '
          f'{z.max():.3g} at {r["t"][np.argmax(z)]:.3f} s); a measurement: '
          f'{100 * np.mean(measured):.1f} % (before the shock: '
          f'{100 * np.mean(measured[r["t"] < 1.0]):.1f} %); worst error while valid '
          f'{np.max(np.abs(r["error"][measured])):.3g} rad/s')
    assert within >= 0.999
    # Before the shock the output is a measurement, with a variance of its noise and scale
    # factor (the pre-shock error's spread within a few of its sigmas).
    assert np.all(measured[r['t'] < 0.999])
    # the channel never says valid while its error is beyond the band it states
    assert r['valid_snapshots'] > 50 and r['beyond_band'] == 0


def test_the_rebalance_loop_comes_back_once_and_says_when_it_is_off(shocked):
    # With hysteresis the rebalance loop is switched on again once after the shock (it
    # switched on and off with +-5 300 deg/s spikes 2-4 s after it without), and while it is
    # off ~/rate is not a measurement: its variance says so, whatever it reads.
    mode, r = shocked
    if mode != 'rebalance':
        pytest.skip('force-to-rebalance only')
    on = r['rebalance_on']
    after = r['t'] >= 1.0
    switched_on = np.count_nonzero(np.diff(on[after]) > 0.0)
    assert on[~after].all() and not on[after].all()
    assert switched_on == 1
    assert np.all(r['variance'][on == 0.0] == NOT_MEASURED_VARIANCE)


def test_a_disturbance_ends_in_a_settling_time_then_a_measurement():
    v = RateValidity(noise_variance=1e-8, bias_sigma=0.0, bandwidth_hz=20.0,
                     sample_rate_hz=1000.0, quadrature_per_rate=0.0)
    settle = SETTLE_TIME_CONSTANTS / (2.0 * math.pi * 20.0)
    t = np.arange(1, 201) * 1e-3
    codes = np.zeros(t.size, dtype=np.int64)
    codes[20:50] = REASONS.index('PLL out of lock')
    var = v.samples(t, np.full(t.size, 0.1), np.zeros(t.size), codes)
    assert np.all(var[:20] < 1e-6) and np.all(var[20:50] == NOT_MEASURED_VARIANCE)
    end = 50 + int(math.ceil(settle * 1000.0))
    assert np.all(var[50:end - 1] == NOT_MEASURED_VARIANCE) and np.all(var[end + 1:] < 1e-6)
    assert v.state.valid and v.state.reason == ''
    # the nominal variance: the noise and the scale factor's uncertainty at the reading
    assert var[-1] == pytest.approx(1e-8 + (0.0025 * 0.1) ** 2)


def test_a_saturated_sample_is_no_measurement_and_starts_no_settling():
    # (V1b) The output word's clip is memoryless: the samples at full scale say only that
    # the rate is at least the range, the first one back within it is a measurement again.
    # A loop's own reason (V1) says more than the clip and is kept.
    v = RateValidity(noise_variance=1e-8, bias_sigma=0.0, bandwidth_hz=20.0,
                     sample_rate_hz=1000.0, quadrature_per_rate=0.0, resolution=1e-3)
    t = np.arange(1, 101) * 1e-3
    codes = np.zeros(t.size, dtype=np.int64)
    saturated = np.zeros(t.size, dtype=bool)
    saturated[20:40] = True
    codes[30] = REASONS.index('PLL out of lock')
    var = v.samples(t[:35], np.full(35, 0.1), np.zeros(35), codes[:35], saturated[:35])
    assert np.all(var[20:] == NOT_MEASURED_VARIANCE)
    assert v.state.reason == 'saturated' and not v.state.valid
    var = np.concatenate([var, v.samples(t[35:], np.full(65, 0.1), np.zeros(65), codes[35:],
                                         saturated[35:])])
    nominal = 1e-8 + 1e-6 / 12.0 + (0.0025 * 0.1) ** 2  # the LSB's rounding: L^2 / 12
    # the PLL's sample at 30 starts a settling of 5 time constants (40 ms) from 31 on
    end = 31 + int(math.ceil(SETTLE_TIME_CONSTANTS / (2.0 * math.pi * 20.0) * 1000.0))
    assert np.all(var[:20] == pytest.approx(nominal, rel=1e-12))
    assert np.all(var[20:end - 1] == NOT_MEASURED_VARIANCE)
    assert np.all(var[end + 1:] == pytest.approx(nominal, rel=1e-12))
    w = RateValidity(noise_variance=1e-8, bias_sigma=0.0, bandwidth_hz=20.0,
                     sample_rate_hz=1000.0, quadrature_per_rate=0.0)
    var = w.samples(t, np.full(t.size, 0.1), np.zeros(t.size),
                    np.zeros(t.size, dtype=np.int64), saturated)
    assert np.all(var[20:40] == NOT_MEASURED_VARIANCE)
    assert np.all(var[40:] == pytest.approx(1e-8 + (0.0025 * 0.1) ** 2, rel=1e-12))
    assert w.state.valid and w.state.reason == ''


def test_a_quadrature_transient_inflates_the_variance_by_its_envelope():
    v = RateValidity(noise_variance=1e-8, bias_sigma=0.0, bandwidth_hz=20.0,
                     sample_rate_hz=1000.0, quadrature_per_rate=0.0)
    t = np.arange(1, 401) * 1e-3
    q = np.zeros(t.size)
    q[100] = 0.5  # one sample's departure of the quadrature: the envelope decays over 0.1 s
    var = v.samples(t, np.zeros(t.size), q, np.zeros(t.size, dtype=np.int64))
    assert var[99] == pytest.approx(1e-8)
    assert var[100] == pytest.approx(1e-8 + 0.25)
    assert math.sqrt(var[200] - 1e-8) == pytest.approx(0.5 * math.exp(-1.0), rel=1e-9)
    assert not v.state.valid  # 0.5 e^-3 rad/s against a 1e-4 rad/s noise, 0.3 s later
