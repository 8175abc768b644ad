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

"""Tests of core/rate_profile.py: the knots of the angular rate and their values."""

import numpy as np
from ring_gyro_sim.core.rate_profile import RateProfile


def test_a_step_keeps_the_value_before_it_as_at_computes_it():
    # step() reads the rate before its time by a bisection (its cost must not grow with the
    # knots ahead): the value must be that of the whole-profile evaluation, bit for bit, or a
    # re-simulation of an older recording would drift.
    rng = np.random.default_rng(7)
    times = np.sort(rng.integers(0, 10**9, 40)) * 1e-9
    profile = RateProfile(times, rng.normal(size=40))
    for at_ns in rng.integers(0, 12 * 10**8, 60):
        at_ns = int(at_ns)
        assert profile._value_at(at_ns) == float(profile.at(np.array([at_ns]))[0])
    for at_ns in sorted(int(t) for t in rng.integers(0, 12 * 10**8, 20))[::-1]:
        before = float(profile.at(np.array([at_ns]))[0])
        profile.step(at_ns, float(rng.normal()))
        assert profile._t[-2:] == [at_ns, at_ns] and profile._w[-2] == before
