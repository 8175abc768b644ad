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

"""The run's rate and drive figures (core/gyro/stats.py) and the line that says them."""

import math

import numpy as np
from ring_gyro_sim.core.gyro.control import CONTROL_CHANNELS
from ring_gyro_sim.core.gyro.stats import describe, DriveStats

DEG = math.pi / 180.0


def test_the_closing_line_says_the_rate_error_its_recovery_and_the_drive():
    closed = {'rate_mean_rad_s': 9.9 * DEG, 'rate_true_mean_rad_s': 10.0 * DEG,
              'rate_error_peak_rad_s': 691.0 * DEG, 'rate_recovered': True,
              'rate_recovery_s': 6.996, 'pll_lost_lock': True, 'pll_lock_lost_at_s': 0.501,
              'pll_relocked_at_s': 2.85, 'drive_amplitude_recovery_s': 3.779}
    text = describe(closed)
    for part in ('9.9000 deg/s', 'applied 10.0000', 'peaked at 691 deg/s',
                 'back within its band 6.996 s after the shock', 'out of lock from 0.501 s',
                 'locked again at 2.850 s', 'set-point 3.779 s after the shock'):
        assert part in text, (part, text)
    lost = dict(closed, rate_recovered=False, rate_recovery_s=None, pll_relocked_at_s=None,
                drive_amplitude_recovery_s=None)
    text = describe(lost)
    assert 'not back within its band' in text and 'not locked again' in text
    assert 'amplitude not back by the end' in text
    # Open loop: a drive fallen to its lower branch leaves no scale factor.
    fell = {'rate_drive_amplitude_ratio': 0.0995, 'rate_scale_factor_valid': False}
    assert 'left its branch (pick-off at 0.0995' in describe(fell)
    assert 'on its operating point' in describe(dict(fell, rate_scale_factor_valid=True,
                                                     rate_drive_amplitude_ratio=0.97))
    assert describe({}) == ''


def test_drive_stats_of_a_drive_that_never_ran_are_finite():
    # A closed loop started with the drive off has a set-point of 0: no ratio, never inf.
    class Loop:
        setpoint_m = 0.0
        lost_lock_at_s = relocked_at_s = None
    stats = DriveStats(Loop())
    rows = np.zeros((3, len(CONTROL_CHANNELS)))
    stats.add(np.array([1e-3, 2e-3, 3e-3]), rows)
    assert stats.figures()['drive_amplitude_final_ratio'] == 0.0
