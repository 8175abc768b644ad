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
The drift (core/kernels/drift.py): the exact flow of the damped linear oscillators.

The propagators against the matrix exponential of the oscillator's first-order system (forward
and backward in time, light and heavy damping), the in-kernel propagators against the ones
built at set-up, and the drift and the fused kick and drift against the flow applied by hand.
"""

import math

import numpy as np
import pytest
from ring_gyro_sim.core.kernels.drift import (_drift, _fill_propagators, _kick_drift,
                                              linear_propagators)
from scipy.linalg import expm

OMEGA = 2.0 * math.pi * np.array([11200.0, 15800.0, 22000.0, 36300.0])
ZETA = 1.0 / (2.0 * np.array([120000.0, 64700.0, 50.0, 0.8]))  # the last two: heavy damping
TAUS = np.array([5e-6, -1.3e-6, 0.0, 2e-4])  # splitting drifts may go backwards


def scaled(flow, omega):
    """[xx, xv omega, vx / omega, vv]: the four entries in comparable (dimensionless) units."""
    return np.array([flow[0], flow[1] * omega, flow[2] / omega, flow[3]])


def test_linear_propagators_are_the_exact_flow():
    prop = linear_propagators(OMEGA, ZETA, TAUS)
    assert prop.shape == (TAUS.size, OMEGA.size, 4)
    for k, tau in enumerate(TAUS):
        for c, (w, z) in enumerate(zip(OMEGA, ZETA)):
            exact = expm(np.array([[0.0, 1.0], [-w * w, -2.0 * z * w]]) * tau).ravel()
            np.testing.assert_allclose(scaled(prop[k, c], w), scaled(exact, w), rtol=0.0,
                                       atol=1e-11)
    assert np.array_equal(prop[2], np.tile([1.0, 0.0, -0.0, 1.0], (OMEGA.size, 1)))


def test_the_in_kernel_propagators_are_those_of_the_set_up():
    a = np.array([0.3, -0.1, 0.8])
    tau = 4e-6
    prop = np.empty((a.size, OMEGA.size, 4))
    _fill_propagators(OMEGA, ZETA, a, tau, prop, np.zeros(OMEGA.size, dtype=np.bool_))
    expected = linear_propagators(OMEGA, ZETA, a * tau)
    for i in range(a.size):
        for c, w in enumerate(OMEGA):
            np.testing.assert_allclose(scaled(prop[i, c], w), scaled(expected[i, c], w),
                                       rtol=0.0, atol=1e-15)


@pytest.mark.parametrize('i', [0, 1])
def test_drift_and_fused_kick_drift_apply_the_flow(i):
    rng = np.random.default_rng(7)
    prop = linear_propagators(OMEGA, ZETA, np.array([3e-6, -1e-6]))
    q0 = rng.normal(0.0, 1e-7, OMEGA.size)
    v0 = rng.normal(0.0, 1e-2, OMEGA.size)
    acc = rng.normal(0.0, 1e3, OMEGA.size)
    fe = rng.normal(0.0, 1e3, OMEGA.size)
    kick = 2e-6
    xx, xv, vx, vv = prop[i].T
    q, v = q0.copy(), v0.copy()
    _drift(q, v, prop, i)
    assert np.array_equal(q, xx * q0 + xv * v0) and np.array_equal(v, vx * q0 + vv * v0)
    # The fused form is the kick then the drift, to rounding (it groups the force's term).
    q, v = q0.copy(), v0.copy()
    _kick_drift(q, v, acc, fe, kick, prop, i)
    kicked = v0 + kick * (acc + fe)
    np.testing.assert_allclose(q, xx * q0 + xv * kicked, rtol=1e-13, atol=0.0)
    np.testing.assert_allclose(v, vx * q0 + vv * kicked, rtol=1e-13, atol=0.0)


def test_a_coupled_pairs_flow_is_the_exponential_of_its_system():
    from scipy.linalg import expm
    from ring_gyro_sim.core.kernels.drift import (_expm4, _fill_pair_propagators,
                                                  _pair_drift, pair_propagators, pair_system)
    w = 2 * np.pi * 15800.0
    stiffness = np.array([[w * w, 3e5], [3e5, w * w * 1.0001]])
    damping = np.array([[w / 6e4, 0.02], [0.02, w / 5e4]])
    system = pair_system(stiffness, damping)
    taus = np.array([4e-6, -1.3e-6, 7.7e-6])
    flows = pair_propagators(system[None, :], taus)
    for k, tau in enumerate(taus):
        exact = expm(system.reshape(4, 4) * tau)
        out, work = np.empty(16), np.empty(32)
        _expm4(system, tau, out, work)  # the kernel's own, for sub-steps
        np.testing.assert_allclose(out.reshape(4, 4), exact, rtol=1e-12, atol=1e-12 * abs(tau))
        np.testing.assert_allclose(flows[k, 0].reshape(4, 4), exact, rtol=1e-14)
    inside = np.empty((taus.size, 1, 16))
    _fill_pair_propagators(system[None, :], np.array([1.0, -0.325, 1.925]), 4e-6, inside,
                           np.empty(32))
    np.testing.assert_allclose(inside, flows, rtol=1e-12, atol=1e-18)
    # applied to (q_c, q_s, v_c, v_s) of coordinates 1 and 4 of five, the others untouched
    q = np.arange(5.0) * 1e-7
    v = np.arange(5.0) * 1e-3
    before_q, before_v = q.copy(), v.copy()
    _pair_drift(q, v, flows, np.array([[1, 4]]), 0)
    state = flows[0, 0].reshape(4, 4) @ np.array([before_q[1], before_q[4], before_v[1],
                                                  before_v[4]])
    np.testing.assert_allclose([q[1], q[4], v[1], v[4]], state, rtol=1e-15)
    assert np.array_equal(q[[0, 2, 3]], before_q[[0, 2, 3]])
