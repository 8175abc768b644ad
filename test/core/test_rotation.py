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
The rotating sensor frame: Coriolis coupling, precession, sense response, force noise.

The physics (``structure.gyroscopic_coefficient``, eqs. G1-G6): kappa_n = 2 n / (n^2 + 1),
a free standing n-theta wave turns in the sensor frame by -2 / (n^2 + 1) times the sensor's
rotation angle (Bryan's factor: 0.4 for 2theta, 1 for the rigid 1theta translation), and the
thermomechanical force noise gives each coordinate k_B T / (m omega^2) (equipartition).
"""

import math

import numpy as np
import pytest
from ring_gyro_sim.core import forces, structure
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.errors import InputError
from ring_gyro_sim.core.params import BOLTZMANN, paper_config, STANDARD_GRAVITY
from scipy.integrate import solve_ivp

GYRO = {'gyro.enabled': True, 'modes.companions': True, 'gyro.temperature': 0.0}


def gyro_config(**extra):
    values = dict(GYRO)
    values.update(extra)
    return paper_config(values)


def test_kappa_and_bryan_factor_closed_forms():
    assert structure.gyroscopic_coefficient(1) == 1.0
    assert structure.gyroscopic_coefficient(2) == pytest.approx(0.8, rel=1e-15)
    assert structure.bryan_factor(2) == pytest.approx(0.4, rel=1e-15)
    assert structure.bryan_factor(3) == pytest.approx(0.2, rel=1e-15)


def pattern_angle(q_c, q_s, n):
    """Antinode angle (rad) of a standing wave q_c cos n theta + q_s sin n theta at its peak."""
    k = int(np.argmax(q_c ** 2 + q_s ** 2))
    sign = 1.0 if q_c[k] >= 0.0 else -1.0
    return math.atan2(sign * q_s[k], sign * q_c[k]) / n


@pytest.mark.parametrize('n', [1, 2, 3])
def test_free_standing_wave_precesses_by_bryans_factor(n):
    # Drive off, a free n-theta vibration (10 nm, far below the nonlinear range), a constant
    # rate of 20 rad/s: after 50 ms the sensor has turned by 1 rad, the pattern by
    # -2/(n^2+1) rad in the sensor frame. The 1 % budget is checked at 1e-3.
    rate = 20.0
    config = gyro_config(**{'drive.amplitude': 0.0, 'drive.start_on': 'rest',
                            'scenario.rate_times': [0.0], 'scenario.rate_values': [rate]})
    sim = Simulator(config)
    q = np.zeros(sim.model.n_coordinates)
    ic, js = sim.coordinates.index(f'q{n}'), sim.coordinates.index(f'q{n}s')
    q[ic] = 1e-8
    sim.set_state(q, np.zeros_like(q))
    out = sim.advance(0.05)
    period = int(round(1.0 / (config.modes.frequencies[n - 1] * sim.period_s)))
    last = slice(-period, None)
    psi = pattern_angle(out.q[last, ic], out.q[last, js], n)
    k = int(np.argmax(out.q[last, ic] ** 2 + out.q[last, js] ** 2))
    turned = rate * out.t[last][k]
    gain = -psi / turned
    print(f'n = {n}: pattern turned {psi:.6f} rad for {turned:.6f} rad: gain {gain:.6f}')
    assert gain == pytest.approx(structure.bryan_factor(n), rel=1e-3)


def test_no_rate_leaves_companions_exactly_zero_and_matches_the_resonator():
    # gyro.enabled with zero rate and no noise is the resonator with companions, bit for bit.
    base = {'modes.companions': True, 'drive.start_on': 'rest',
            'scenario.shock_times': [0.001], 'scenario.shock_peaks': [5000 * STANDARD_GRAVITY]}
    a = Simulator(paper_config(base)).advance(0.005)
    b = Simulator(gyro_config(**base)).advance(0.005)
    assert np.array_equal(a.q, b.q)
    assert np.all(b.q[:, 3:] == 0.0)


def rotating_reference(config, t_end, t_eval, rate_of):
    """DOP853 (rtol 1e-10) of eq. 28 plus G5-G6 written out here, shock at t = 0."""
    model = forces.build_force_model(config)
    omega = 2 * np.pi * np.asarray(config.modes.coordinate_frequencies())
    zeta = 1 / (2 * np.asarray(config.modes.coordinate_quality_factors()))
    t_s = config.shock_duration_s
    (at_ns, peak_x, peak_y), = config.run.scheduled_shocks()
    n = model.n_coordinates
    m = config.modes.count
    kap = np.array([2.0 * k / (k * k + 1.0) for k in range(1, m + 1)])

    def rhs(t, y):
        x, v = y[:n], y[n:]
        w, wdot = rate_of(t)
        a = -2 * zeta * omega * v - omega ** 2 * x + forces.nonlinear_acceleration(x, model)
        c, s = x[:m], x[m:]
        vc, vs = v[:m], v[m:]
        a[:m] += 2 * kap * w * vs + kap * wdot * s + w * w * c
        a[m:] += -2 * kap * w * vc - kap * wdot * c + w * w * s
        if t <= t_s:
            a[0] -= peak_x * math.sin(math.pi * t / t_s)
            a[m] -= peak_y * math.sin(math.pi * t / t_s)
        return np.concatenate([v, a])

    first = solve_ivp(rhs, (0, t_s), np.zeros(2 * n), method='DOP853', rtol=1e-10, atol=1e-16)
    second = solve_ivp(rhs, (t_s, t_end), first.y[:, -1], method='DOP853', rtol=1e-10,
                       atol=1e-16, dense_output=True)
    return second.sol(t_eval)[:n].T


def test_accuracy_against_dop853_with_a_fast_rate_ramp():
    # The step's error budget (largest error in any q below 1e-4 of the peak q1, 20 ms after a
    # 10 000 g shock, here at 30 deg so both members of every pair move) with the sensor
    # spinning up from 0 to 50 rad/s (2 900 deg/s) over the window: Coriolis, centrifugal and
    # angular-acceleration terms all act, far beyond any rate table.
    t_end = 0.02
    slope = 50.0 / t_end
    config = gyro_config(**{'drive.amplitude': 0.0, 'drive.start_on': 'rest',
                            'scenario.shock_times': [0.0],
                            'scenario.shock_peaks': [10_000 * STANDARD_GRAVITY],
                            'scenario.shock_angles': [30.0],
                            'scenario.rate_times': [0.0, t_end],
                            'scenario.rate_values': [0.0, 50.0]})
    sim = Simulator(config)
    out = sim.advance(t_end)
    after = out.t > config.shock_duration_s
    ref = rotating_reference(config, t_end, out.t[after], lambda t: (slope * t, slope))
    peak_q1 = np.max(np.abs(ref[:, 0]))
    err = np.max(np.abs(out.q[after] - ref)) / peak_q1
    # Control: the same reference without rotation differs from it by far more than 1e-4.
    still = rotating_reference(config, t_end, out.t[after], lambda t: (0.0, 0.0))
    effect = np.max(np.abs(still - ref)) / peak_q1
    print(f'error / peak q1 = {err:.2e}; rotation effect {effect:.2e}')
    assert effect > 1e-2
    assert err < 1e-4
    assert np.allclose(out.applied_rate[after], slope * out.t[after], rtol=0, atol=1e-12)


def sense_ratio_closed_form(config, rate):
    """|q2s / q2| of the linear, matched-or-not sense mode driven by -2 kappa Omega q2'."""
    w = 2 * math.pi * config.drive.frequency
    f = config.modes.coordinate_frequencies()
    qf = config.modes.coordinate_quality_factors()
    m = config.modes.count
    ws, qs = 2 * math.pi * f[m + 1], qf[m + 1]
    h = 1.0 / (ws * ws - w * w + 1j * w * ws / qs)
    return abs(-2j * structure.gyroscopic_coefficient(2) * rate * w * h)


def test_linear_sense_response_matches_the_closed_form():
    # A small drive (a hundredth of the paper's: linear) at 15 800 Hz, Q = 2 000 for the
    # 2theta pair so that it settles with the time constant tau = 2 Q / omega = 40 ms. The
    # drive starts from rest, so the sense mode, resonant and forced by a decaying resonant
    # term, keeps a transient (t / tau) e^(-t / tau): 5e-3 at 0.3 s, 5e-5 at 0.5 s.
    rate = math.radians(10.0)
    config = gyro_config(**{'drive.amplitude': 0.00065, 'drive.frequency': 15800.0,
                            'drive.start_on': 'rest',
                            'modes.quality_factors': [120000.0, 2000.0, 170000.0],
                            'scenario.rate_times': [0.0], 'scenario.rate_values': [rate]})
    sim = Simulator(config)
    out = sim.advance(0.5)
    last = out.t > 0.49
    i2, i2s = sim.coordinates.index('q2'), sim.coordinates.index('q2s')
    ratio = np.sqrt(np.mean(out.q[last, i2s] ** 2) / np.mean(out.q[last, i2] ** 2))
    expected = sense_ratio_closed_form(config, rate)
    print(f'q2s/q2 = {ratio:.6f}, closed form {expected:.6f}')
    assert ratio == pytest.approx(expected, rel=2e-3)
    # The opposite rate gives the opposite sense response.
    config_neg = paper_config({**{k: v for k, v in GYRO.items()},
                               'drive.amplitude': 0.00065, 'drive.frequency': 15800.0,
                               'drive.start_on': 'rest',
                               'modes.quality_factors': [120000.0, 2000.0, 170000.0],
                               'scenario.rate_times': [0.0], 'scenario.rate_values': [-rate]})
    neg = Simulator(config_neg).advance(0.5)
    assert np.allclose(neg.q[:, i2s], -out.q[:, i2s], rtol=1e-9, atol=1e-22)


def test_thermomechanical_noise_gives_equipartition():
    # No drive, no rate, Q = 100 for every coordinate (energy correlation time Q / (pi f),
    # 1.4-2.8 ms, so 2 s hold ~6 000 independent values over the six coordinates: the pooled
    # estimate of <q^2> / (k_B T / (m omega^2)) has a relative standard error of ~2 %;
    # tolerance 8 %). The first 50 ms (> 10 decay times) are dropped.
    config = gyro_config(**{'drive.amplitude': 0.0, 'drive.start_on': 'rest',
                            'gyro.temperature': 300.0, 'gyro.noise_seed': 7,
                            'modes.quality_factors': [100.0, 100.0, 100.0]})
    sim = Simulator(config)
    out = sim.advance(2.0)
    keep = out.t > 0.05
    omega = 2 * np.pi * np.asarray(config.modes.coordinate_frequencies())
    masses = np.asarray(config.modal_masses())
    expected = BOLTZMANN * 300.0 / (masses * omega ** 2)
    ratios = np.mean(out.q[keep] ** 2, axis=0) / expected
    print('<q^2> / (kT / m w^2):', np.round(ratios, 3))
    assert np.mean(ratios) == pytest.approx(1.0, abs=0.08)
    assert np.all(np.abs(ratios - 1.0) < 0.25)  # each coordinate: ~5 % standard error


def test_noise_and_rate_are_chunk_invariant_and_seeded():
    values = {'drive.amplitude': 0.0065, 'drive.frequency': 15800.0,
              'gyro.temperature': 300.0, 'gyro.noise_seed': 3,
              'scenario.rate_times': [0.0, 0.004, 0.004], 'scenario.rate_values': [0.0, 1.0, 2.0]}
    whole = Simulator(gyro_config(**values)).advance(0.01).q
    sim = Simulator(gyro_config(**values))
    parts = np.concatenate([sim.advance_samples(k).q for k in (1, 333, 7, 1659)])
    assert np.array_equal(whole, parts)
    other = Simulator(gyro_config(**{**values, 'gyro.noise_seed': 4})).advance(0.01).q
    assert not np.array_equal(whole, other)


def test_streamed_rate_steps_at_its_time_and_replaces_later_knots():
    config = gyro_config(**{'drive.amplitude': 0.0, 'scenario.rate_times': [0.0, 1.0],
                            'scenario.rate_values': [0.0, 10.0]})
    sim = Simulator(config)
    sim.advance_samples(100)
    sim.set_rate(sim.time_ns + 12_345, -1.5)  # between samples
    out = sim.advance_samples(10)
    # Before the step the ramp (10 rad/s per s), after it -1.5 held (the ramp is replaced).
    assert out.applied_rate[0] == pytest.approx(10.0 * out.t[0], rel=1e-12)
    assert np.all(out.applied_rate[3:] == -1.5)
    with pytest.raises(InputError, match='past'):
        sim.set_rate(0, 1.0)
    with pytest.raises(InputError, match='finite'):
        sim.set_rate(sim.time_ns, math.nan)
    plain = Simulator(paper_config({}))
    with pytest.raises(InputError, match='gyro.enabled'):
        plain.set_rate(0, 1.0)
