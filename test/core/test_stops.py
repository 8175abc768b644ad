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

"""The mechanical stops: restitution, a 30 000 g shock, the refusals."""

import math
import warnings

import numpy as np
import pytest

from ring_gyro_sim.core import forces
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.params import build_config

G = 9.80665
F1 = 11200.0
GAP_S = 6e-6


def _one_mode(restitution):
    """Return the rigid 1theta mode alone (N_R = 1), undamped in effect, no voltage."""
    return build_config({'modes.frequencies': [F1], 'modes.quality_factors': [1e12],
                         'modes.companions': False, 'gyro.enabled': False,
                         'control.mode': 'open_loop',
                         'drive.amplitude': 0.0, 'drive.start_on': 'rest',
                         'electrodes.outer_voltage': 0.0, 'stops.gap': GAP_S,
                         'stops.restitution': restitution})


def _stop_energy(q1, config):
    """Energy per unit modal mass stored in the stop at q1 (loading branch, S1-S2)."""
    stops = forces.build_stops(config, 1, 0)
    m = stops.basis.shape[1]
    unit = 2.0 * math.pi * config.ring.radius * config.stops.stiffness / (
        m * config.modal_masses()[0])
    # both stops: the rigid translation q1 > 0 presses the outer stop at theta = 0 and the
    # inner one at theta = pi (w = -q1 there)
    delta = np.maximum(np.abs(stops.basis[0] * q1) - GAP_S, 0.0)
    return float(unit * np.sum(0.5 * delta ** 2))


@pytest.mark.parametrize('restitution', [0.5, 0.8])
def test_one_impact_of_one_mode_keeps_e_squared_of_the_normal_kinetic_energy(restitution):
    # 1-DOF q'' + omega^2 q = a_stop(q, q'), started at q = 0 with v0 towards the stop at
    # theta = 0. Outside contact E = v^2 / 2 + omega^2 q^2 / 2 is constant, so the normal
    # kinetic energy at the stop is E - omega^2 g_s^2 / 2 before and after the impact. Every
    # angle of the arc is loaded with k_s and unloaded with e^2 k_s once (kernels/stops.py,
    # S3): the stop keeps (1 - e^2) of the energy U it held at the deepest point, where
    # v = 0 and E = omega^2 q_max^2 / 2 + U(q_max). The mode's own spring holds the rest of
    # the incoming kinetic energy K_in there and gives it back, so
    #     K_out / K_in = 1 - (1 - e^2) U(q_max) / K_in    -> e^2 as k_s -> infinity.
    config = _one_mode(restitution)
    omega = 2.0 * math.pi * F1
    v0 = 1.1  # m/s: what a 30 000 g, 6.33 us half-sine gives the free 1theta mode
    sim = Simulator(config, calibration=None)
    sim.set_state(np.array([0.0]), np.array([v0]))
    energy_in = 0.5 * v0 ** 2
    k_in = energy_in - 0.5 * (omega * GAP_S) ** 2
    while sim.impacts == 0 or sim.in_stop_contact:
        s = sim.advance_samples(1)
        assert sim.time_s < 20e-6
    k_out = 0.5 * s.v[-1, 0] ** 2 + 0.5 * (omega * s.q[-1, 0]) ** 2 - 0.5 * (omega * GAP_S) ** 2
    assert sim.impacts == 1 and abs(s.q[-1, 0]) < GAP_S
    # q_max from the energy at the deepest point, by bisection on the loading branch
    lo, hi = GAP_S, GAP_S * 1.5
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if 0.5 * (omega * mid) ** 2 + _stop_energy(mid, config) < energy_in:
            lo = mid
        else:
            hi = mid
    u_max = _stop_energy(lo, config)
    expected = 1.0 - (1.0 - restitution ** 2) * u_max / k_in
    ratio = k_out / k_in
    # the criterion: (1 - e^2) of the normal kinetic energy dissipated within 5 %
    assert ratio == pytest.approx(restitution ** 2, rel=0.05)
    # and the closed form with the spring's share, to the integrator's accuracy
    assert ratio == pytest.approx(expected, rel=1e-3)
    assert lo - GAP_S < 0.05 * GAP_S  # the penetration stays small


def test_a_stop_at_or_beyond_the_electrodes_is_refused():
    with pytest.raises(ParameterError, match=r'^stops\.gap: must be below electrodes\.gap'):
        build_config({'stops.gap': 10e-6})
    with pytest.raises(ParameterError, match=r'^stops\.restitution'):
        build_config({'stops.gap': 6e-6, 'stops.restitution': 1.5})


def test_without_stops_a_shock_beyond_the_gap_is_contact_as_before():
    config = build_config({'modes.frequencies': [F1], 'modes.quality_factors': [1e12],
                           'modes.companions': False, 'gyro.enabled': False,
                           'control.mode': 'open_loop',
                           'drive.amplitude': 0.0, 'drive.start_on': 'rest',
                           'electrodes.outer_voltage': 0.0})
    sim = Simulator(config, calibration=None)
    sim.set_state(np.array([0.0]), np.array([1.1]))
    sim.advance(50e-6)
    assert str(sim.status) == 'contact' and sim.impacts == 0


def test_30000_g_into_stops_at_0p6_dg_bounces_saturates_and_runs_on():
    # The must-show on the default gyroscope with a 300 deg/s output word, turning at
    # 100 deg/s: the stops at 0.6 d_g, 30 000 g along x at 50 ms, 1 s in all. The run goes on
    # (no contact), the impacts are counted, nothing is NaN, |w| stays below 0.7 d_g (the
    # Taylor series within its range), the rate output is flagged (not a measurement,
    # variance 1e6) from the shock on and saturates at the range, flagged, while the loops
    # catch the drive again (measured: 0.52-0.79 s), then is a measurement again (from
    # 0.82 s). Its return to the unshocked reading takes seconds (doc/environments.md).
    full_scale = math.radians(300.0)
    config = build_config({'stops.gap': 0.6 * 10e-6, 'gyro.range': full_scale,
                           'gyro.calibration.source': 'ideal', 'scenario.shock_times': [0.05],
                           'scenario.shock_peaks': [30000.0 * G],
                           'scenario.rate_times': [0.0],
                           'scenario.rate_values': [math.radians(100.0)]})
    sim = Simulator(config)
    grid = forces.build_stops(config, 1, 0).basis
    w_max = 0.0
    rates = []
    for _ in range(100):
        s = sim.advance(0.01)
        assert np.all(np.isfinite(s.q)) and np.all(np.isfinite(s.rate_output.rate))
        assert np.all(np.isfinite(s.rate_output.variance))
        w_max = max(w_max, float(np.max(np.abs(s.q @ grid))))
        rates.append(s.rate_output)
    assert str(sim.status) == 'running'
    assert sim.impacts > 0
    assert 0.6 * 10e-6 < w_max < 0.7 * 10e-6
    t = np.concatenate([r.t for r in rates])
    rate = np.concatenate([r.rate for r in rates])
    variance = np.concatenate([r.variance for r in rates])
    saturated = np.concatenate([r.saturated for r in rates])
    assert np.all(variance[(t > 0.0501) & (t < 0.5)] >= 1e6)  # flagged from the shock on
    assert saturated.sum() > 0 and np.all(t[saturated] > 0.05)
    assert np.all(np.abs(rate[saturated]) == full_scale)  # reads the full scale, flagged
    assert np.all(variance[saturated] >= 1e6)
    assert np.all(variance[t > 0.9] < 1e6)  # a measurement again


def test_stops_beyond_the_static_pull_in_are_said_at_start():
    # The 1theta mode's static pull-in displacement on the default device (78 V, N_T = 10) is
    # where omega_1^2 q - a_nl,1(q) peaks: 0.702 d_g. Stops at 0.6 d_g lie inside it; at
    # 0.75 d_g the electrodes would pull a ring pushed past 0.702 d_g onto the stop.
    base = {'gyro.enabled': False, 'control.mode': 'open_loop',
            'drive.start_on': 'rest', 'modes.companions': False}
    with pytest.warns(RuntimeWarning, match=r'^stops\.gap: .* beyond the static pull-in'):
        sim = Simulator(build_config({**base, 'stops.gap': 7.5e-6}), calibration=None)
    assert sim.pull_in_displacement == pytest.approx(0.702e-5, abs=1e-8)
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        Simulator(build_config({**base, 'stops.gap': 6e-6}), calibration=None)
