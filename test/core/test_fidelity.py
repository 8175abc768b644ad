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
The gyroscope handed between the averaged and the full model (``core.engine.handoff``).

Against a full-only run of the same gyroscope: the must-show through a 10 000 g shock.
"""

import math

import numpy as np
import pytest
from ring_gyro_sim.core.params import build_config, STANDARD_GRAVITY
from ring_gyro_sim.run import Run

HUNDRED_DEG_S = math.radians(100.0)
QUIET = {'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0,
         'scenario.rate_times': [0.0], 'scenario.rate_values': [HUNDRED_DEG_S]}


def rate_of(config, seconds):
    """Run ``config`` for ``seconds`` through ``Run``; return the run and its ~/rate."""
    run = Run(config, calibration=None)
    n = config.run.block_samples
    blocks = int(round(seconds / (n * run.period_ns * 1e-9)))
    parts = [run.advance(n).rate for _ in range(blocks)]
    return run, (np.concatenate([r.t for r in parts]), np.concatenate([r.rate for r in parts]))


def test_auto_goes_through_a_10000_g_shock_on_the_full_model_and_back():
    # The must-show: a 10 000 g half-sine along x at 1.05 s (scenario.shock_*), 100 deg/s,
    # noise off, 25 s. auto: the full model's first check, averaged, the full model from
    # the loop update at the shock's start (1.05 s) until the other modes have rung down
    # below HAND_BACK_THRESHOLD, averaged after. Against the full model throughout: within
    # 0.1 % of the reading at every sample before the shock and after the hand-back. In
    # between the full models differ (up to 5e-3 in the shock's recovery): the shock meets
    # states 1e-5 apart, which its response amplifies; "identical until the hand-back"
    # holds only from a common state.
    values = {**QUIET, 'scenario.shock_times': [1.05],
              'scenario.shock_peaks': [10000.0 * STANDARD_GRAVITY]}
    auto, (t, rate) = rate_of(build_config({**values, 'integrator.fidelity': 'auto'}), 25.0)
    full, (t_full, reference) = rate_of(
        build_config({**values, 'integrator.fidelity': 'full'}), 25.0)
    assert full.handoffs == [(0.0, 'full')]
    assert np.allclose(t, t_full, rtol=0.0, atol=1e-9)
    models = [model for _, model in auto.handoffs]
    assert models == ['full', 'averaged', 'full', 'averaged']
    assert auto.handoffs[2][0] == pytest.approx(1.05, abs=1e-9)
    back = auto.handoffs[3][0]
    assert 10.0 < back < 25.0
    error = np.abs(rate - reference)
    quiet = (t < 1.05) | (t > back)
    assert np.max(error[quiet]) < 1e-3 * HUNDRED_DEG_S


def test_the_next_scheduled_input_is_what_the_averaged_model_must_hand_over_before():
    # Simulator.next_scheduled_s: a pulse from its start until it ends, a scheduled input at
    # its sample, a base-acceleration profile from its first sample in use while it is not
    # over (its last value holds: a last value not zero never ends it); not a rate.
    from ring_gyro_sim.core.engine.full import Simulator
    sim = Simulator(build_config({}), calibration=None)
    assert sim.next_scheduled_s() == math.inf
    sim.set_rate(2_000_000, 0.1)
    assert sim.next_scheduled_s() == math.inf
    sim.shock(1000.0, at_ns=3_000_000)
    sim.set_ambient(300.0, at_ns=2_500_000)
    assert sim.next_scheduled_s() == pytest.approx(2.5e-3)
    sim.advance_samples(520)   # 2.6 ms: the temperature step acted
    assert sim.next_scheduled_s() == pytest.approx(3e-3)
    sim.advance_samples(620)   # 5.7 ms: the pulse (1/10 of the 2theta period) is over
    assert sim.next_scheduled_s() == math.inf
    sim.add_base_acceleration(6_000_000, 1.0)
    assert sim.next_scheduled_s() == pytest.approx(6e-3)
    sim.advance_samples(100)   # past the only sample: its 1 m/s^2 holds
    assert sim.next_scheduled_s() == pytest.approx(sim.time_s)
    sim.add_base_acceleration(7_000_000, 0.0)
    sim.advance_samples(400)   # past the last sample, which is 0: over
    assert sim.next_scheduled_s() == math.inf
