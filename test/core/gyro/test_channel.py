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
The sense chain the simulator owns (core/gyro/channel.py): rebuilt on parameter changes.

A physical charge amplifier's output is ``-(V_b / C_f) dC`` (E1): when the bias voltage
changes at run time, the volts it gives for the same motion change in proportion. The
simulator rebuilds the chain (and the amplifiers the loops read) whenever a parameter change
acts, keeping the filters' state.
"""

import math

import numpy as np
import pytest
from ring_gyro_sim.core.gyro.electronics import DEMOD_CHANNELS
from ring_gyro_sim.core.params import paper_config
from ring_gyro_sim.run import ParameterChange, Run

TEN_DEG_S = math.radians(10.0)
DRIVE_I = DEMOD_CHANNELS.index('drive_i')
DRIVE_Q = DEMOD_CHANNELS.index('drive_q')

GYROSCOPE = {
    'modes.companions': True, 'gyro.enabled': True, 'gyro.temperature': 0.0,
    'gyro.input_noise_density': 0.0, 'drive.amplitude': 0.0065, 'drive.frequency': 15800.0,
    'drive.start_on': 'upper_branch', 'control.mode': 'open_loop',
    'scenario.rate_times': [0.0],
    'scenario.rate_values': [TEN_DEG_S]}
"""config/gyro.yaml's operating point (q2 = 0.04 um, linear), noise-free, 10 deg/s."""


def drive_pickoff_and_q2(run, seconds, window_s=0.01):
    """Advance ``run``; return the drive pick-off's amplitude (V) and q2's (m) at the end."""
    block = run.config.run.block_samples
    blocks = [run.advance(block) for _ in range(int(round(seconds / 0.01)))]
    last = blocks[-1]
    keep = int(round(window_s / run.full_model().period_s))
    volts = np.hypot(last.demod.values[-keep:, DRIVE_I], last.demod.values[-keep:, DRIVE_Q])
    return float(np.mean(volts)), float(np.max(np.abs(last.samples.q[-keep:, 1])))


@pytest.mark.parametrize('loop', ['open_loop', 'closed_loop'])
def test_the_pickoff_follows_a_bias_voltage_changed_at_run_time(loop):
    config = paper_config(dict(GYROSCOPE, **{'control.mode': loop}))
    run = Run(config)
    volts_0, q2_0 = drive_pickoff_and_q2(run, 0.05)
    run.apply(ParameterChange({'electrodes.outer_voltage': 70.0}))
    sim = run.full_model()
    # One set of amplifiers, read by the loops and the sense chain alike, built anew.
    assert sim.pickoff.bias_voltage == 70.0
    assert sim.sense.electronics.pickoff is sim.pickoff
    if loop == 'closed':
        assert sim.loop.pickoff is sim.pickoff
    volts_1, q2_1 = drive_pickoff_and_q2(run, 0.05)
    # The amplifier's volts per metre scale with V_b (E1); the motion itself barely moves
    # (the voltage changes only the nonlinear terms: q2 within 1e-4 of itself here), so
    # the volts per motion must be 70 / 78 of what they were. A chain that kept the old
    # amplifier reads 1.0 (what the tree before this test gave).
    ratio = (volts_1 / q2_1) / (volts_0 / q2_0)
    print(f'{loop} loop: pick-off {volts_0:.6g} -> {volts_1:.6g} V, q2 {q2_0:.6g} -> '
          f'{q2_1:.6g} m, volts per motion x{ratio:.6f} (expected x{70 / 78:.6f})')
    assert ratio == pytest.approx(70.0 / 78.0, rel=2e-3)
    assert sim.sense.diagnostics_values()['drive_pickoff_nominal_v'] == pytest.approx(
        abs(sim.sense.electronics.drive_gain * sim.sense.drive_amplitude_m), rel=1e-12)


def test_a_rebuilt_chain_continues_the_filters_and_the_sample_count():
    # A Q change at 20 ms: the chain is rebuilt, but its filters carry on (no restart
    # transient on the drive pick-off) and the rate samples continue without a gap.
    config = paper_config(GYROSCOPE)
    run = Run(config)
    first = [run.advance(2000) for _ in range(2)]
    old = run.full_model().sense
    q = list(config.modes.quality_factors)
    q[2] = 150000.0  # the 3theta mode: the drive pair and the sense chain's gains unchanged
    run.apply(ParameterChange({'modes.quality_factors': q}))
    after = run.advance(2000)
    assert run.full_model().sense is not old
    demod = np.concatenate([b.demod.values for b in first] + [after.demod.values])
    steps = np.abs(np.diff(demod, axis=0))   # (sample to sample, per channel)
    # Across the rebuild (samples 3999 -> 4000) each channel moves as it did just before;
    # a restarted filter would jump to its start value (the sense channel: to 0 from its
    # response to 10 deg/s).
    assert np.all(steps[3999] <= 3.0 * np.max(steps[3799:3999], axis=0))
    assert np.all(np.abs(demod[4000, :2]) > 0.5 * np.abs(demod[3999, :2]))
    t = np.concatenate([b.rate.t for b in first] + [after.rate.t])
    assert np.allclose(np.diff(t), 1e-3, rtol=0, atol=1e-12) and t.size == 30


def test_the_closed_loops_sense_readout_starts_settled():
    # Closed loop the demodulator's reference at t = 0 is the NCO's phase, not the drive's 0:
    # the filters must start in the steady state of that reference. Started in the open
    # loop's, the first 10 deg/s samples read 7.7 % low and rang for ~10 ms.
    config = paper_config(dict(GYROSCOPE, **{'control.mode': 'closed_loop',
                                             'drive.amplitude': 0.065,
                                             'drive.frequency': 15798.6}))
    first = Run(config).advance(2000).rate
    assert np.max(np.abs(first.rate / TEN_DEG_S - 1.0)) < 0.005
