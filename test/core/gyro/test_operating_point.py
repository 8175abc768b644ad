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
Tests of core/gyro/operating_point.py: the drive's forced orbits (Fig. 9), the start state.

Every reference is either a number of the paper (section 3.4) or an identity that holds
whatever the implementation: periodicity of the returned orbits checked by an independent
integration, Liouville's formula for the product of the Floquet multipliers.
"""

from dataclasses import replace
import math

import numpy as np
import pytest
from ring_gyro_sim.core import forces
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.gyro.operating_point import (drive_orbit, forced_orbit, ForcedOrbit,
                                                     start_state)
from ring_gyro_sim.core.params import paper_config
from scipy.integrate import solve_ivp

DRIVE_HZ = 15798.3
"""Section 3.4: drive frequency of the drive + shock cases."""


@pytest.fixture(scope='module')
def config():
    """Return the paper's resonator (N_R = 3, N_T = 10, calibrated V_o, drive on)."""
    return paper_config({})


def equations(config, drive_hz=0.0, drive_amplitude=0.0, damped=False):
    """Return (n, rhs) of eq. (28) written here, independently of nnm's own right-hand side."""
    model = forces.build_force_model(config)
    omega = 2 * np.pi * np.asarray(config.modes.coordinate_frequencies())
    zeta = 1 / (2 * np.asarray(config.modes.coordinate_quality_factors()))
    if not damped:
        zeta = np.zeros_like(zeta)
    w = 2 * math.pi * drive_hz
    n = model.n_coordinates

    def rhs(t, y):
        x, v = y[:n], y[n:]
        a = -omega ** 2 * x - 2 * zeta * omega * v + forces.nonlinear_acceleration(x, model)
        a[1] += drive_amplitude * math.cos(w * t)
        return np.concatenate([v, a])
    return n, rhs


@pytest.fixture(scope='module')
def branches(config):
    """Upper and lower forced orbits at 15.7983 kHz with the default drive amplitude."""
    a_e = config.drive.amplitude
    upper = forced_orbit(config, DRIVE_HZ, 0.4e-6, a_e)
    lower = forced_orbit(config, DRIVE_HZ, 0.04e-6, a_e)
    return upper, lower


def test_forced_response_has_two_stable_branches(config, branches):
    upper, lower = branches
    assert config.drive.amplitude == pytest.approx(0.065)
    print(f'A_e = {config.drive.amplitude} m/s^2 at {DRIVE_HZ} Hz: '
          f'upper q2 = {upper.amplitude_m[1] * 1e6:.4f} um, '
          f'lower q2 = {lower.amplitude_m[1] * 1e6:.4f} um (paper: 0.39 / 0.03 um)')
    print(f'max |mu|: upper {np.max(np.abs(upper.floquet_multipliers)):.8f}, '
          f'lower {np.max(np.abs(lower.floquet_multipliers)):.8f}')
    # Paper (section 3.4) at 15 798.3 Hz: ~0.39 um and ~0.03 um. Measured here 0.4265 and
    # 0.0307 um: this drive sits 9 mHz above our fold, where the upper branch is at its
    # highest (doc/calibration.md); within 10 % of the paper's values.
    assert upper.amplitude_m[1] == pytest.approx(0.39e-6, rel=0.10)
    assert lower.amplitude_m[1] == pytest.approx(0.03e-6, rel=0.10)
    assert upper.stable and lower.stable
    assert np.all(np.abs(upper.floquet_multipliers) < 1.0)
    assert np.all(np.abs(lower.floquet_multipliers) < 1.0)
    # From rest with only q2 driven, q1 and q3 stay zero (no q2-only forcing term reaches them).
    for orbit in branches:
        assert np.max(np.abs(orbit.amplitude_m[[0, 2]])) < 1e-12 * orbit.amplitude_m[1]


def test_floquet_multipliers_obey_liouville(config, branches):
    """
    The product of the multipliers is exp(-T sum omega_i / Q_i).

    The nonlinear force depends on positions only, so the trace of the Jacobian is the damping
    alone: det(monodromy) = exp(-T sum 2 zeta_i omega_i), whatever the orbit.
    """
    omega = 2 * np.pi * np.asarray(config.modes.coordinate_frequencies())
    q = np.asarray(config.modes.coordinate_quality_factors())
    expected = math.exp(-np.sum(omega / q) / DRIVE_HZ)
    for orbit in branches:
        product = float(np.prod(np.abs(orbit.floquet_multipliers)))
        assert product == pytest.approx(expected, rel=1e-6)


def test_stable_flag_discriminates():
    inside = ForcedOrbit(DRIVE_HZ, np.zeros(2), np.zeros(4), np.array([0.5, 0.99999j]))
    outside = ForcedOrbit(DRIVE_HZ, np.zeros(2), np.zeros(4), np.array([0.5, 1.0001]))
    assert inside.stable
    assert not outside.stable


def test_start_state_rest_or_drive_off_is_none():
    assert start_state(paper_config({'drive.start_on': 'rest'})) is None
    assert start_state(paper_config({'drive.amplitude': 0.0})) is None


def test_upper_branch_start_is_periodic(config):
    assert config.drive.start_on == 'upper_branch'
    upper = forced_orbit(config, config.drive.frequency, 0.4e-6, config.drive.amplitude)
    assert upper.stable
    x0, v0 = start_state(config)
    amp = upper.amplitude_m[1]
    w = 2 * math.pi * config.drive.frequency
    # One drive period of an independent scipy integration returns to the start.
    n, rhs = equations(config, config.drive.frequency, config.drive.amplitude, damped=True)
    period = 1.0 / config.drive.frequency
    sol = solve_ivp(rhs, (0.0, 2e-3), np.concatenate([x0, v0]), method='DOP853', rtol=1e-12,
                    atol=1e-20, dense_output=True)
    y_t = sol.sol(period)
    err_x = np.max(np.abs(y_t[:n] - x0)) / amp
    err_v = np.max(np.abs(y_t[n:] - v0)) / (amp * w)
    print(f'upper-branch start: q2(0) = {x0[1] * 1e6:.4f} um, one-period return error / '
          f'amplitude: x {err_x:.1e}, v {err_v:.1e}')
    assert err_x < 1e-6 and err_v < 1e-6
    # The Simulator (split-step kernels, drive phase 0 at t = 0) follows the same orbit ...
    sim = Simulator(config)
    sim.set_state(x0, v0)
    out = sim.advance(0.1)
    early = out.t <= 2e-3
    dev = np.max(np.abs(out.q[early, 1] - sol.sol(out.t[early])[1])) / amp
    # ... and stays on it: the 5 ms envelope of q2 is flat (a start off the orbit beats at the
    # detuning, several % in 0.1 s).
    window = int(round(5e-3 / sim.period_s))
    q2 = out.q[:, 1]
    envelope = np.array([np.max(np.abs(q2[i:i + window]))
                         for i in range(0, len(q2) - window + 1, window)])
    spread = (envelope.max() - envelope.min()) / amp
    print(f'Simulator vs scipy over 2 ms: {dev:.1e}; 0.1 s envelope spread / amplitude: '
          f'{spread:.1e}, envelope {envelope.mean() * 1e6:.4f} um')
    assert dev < 1e-6
    assert spread < 1e-3
    assert envelope.mean() == pytest.approx(amp, rel=1e-3)


def test_lower_branch_start(config):
    lower = forced_orbit(config, config.drive.frequency, 0.04e-6, config.drive.amplitude)
    assert lower.stable and lower.amplitude_m[1] < 0.1e-6
    x0, v0 = start_state(replace(config, drive=replace(config.drive, start_on='lower_branch')))
    np.testing.assert_allclose(np.concatenate([x0, v0]), lower.initial_state,
                               rtol=1e-6, atol=1e-6 * lower.amplitude_m[1])


def test_upper_branch_with_companions_is_the_cos_orbit(config):
    """
    With the sine companions the orbit is the same: their force is exactly zero.

    The drive has no sine content, so neither has the orbit, and the symmetric quadrature
    gives exactly 0.0 on every companion; the cos part must equal the orbit of the model
    without companions. (With the companions in the shooting unknowns, the degenerate cos/sin
    pairs made the solve stall on the integrator's round-off.)
    """
    upper = forced_orbit(config, config.drive.frequency, 0.4e-6, config.drive.amplitude)
    both = replace(config, modes=replace(config.modes, companions=True))
    with pytest.warns(RuntimeWarning, match='unstable to the sine companions'):
        x0, v0 = drive_orbit(both)  # not memoised: warns every time
    n = config.modes.count
    assert x0.shape == (2 * n,)
    assert np.all(x0[n:] == 0.0) and np.all(v0[n:] == 0.0)
    np.testing.assert_allclose(np.concatenate([x0[:n], v0[:n]]), upper.initial_state,
                               rtol=1e-8, atol=1e-8 * upper.amplitude_m[1])
    assert np.all(forces.nonlinear_acceleration(x0, forces.build_force_model(both))[n:] == 0.0)


def test_upper_branch_standing_wave_is_unstable_to_its_companion(config):
    """
    The driven standing 2theta wave is parametrically unstable to sin(2 theta) (whirling).

    With companions, the full monodromy matrix has one multiplier outside the unit circle on
    the upper branch (q2 ~ 0.39 um) and none on the lower branch (~5 nm), where the coupling,
    quadratic in the amplitude, is ~6000 times weaker than the damping. The cos multipliers
    are those of the model without companions; the companions' own are ~exp(-pi omega / (Q w))
    at small amplitude. The check of the instability itself: a tiny sin(2 theta) seed grows
    in the Simulator at the rate the multiplier gives.
    """
    both = replace(config, modes=replace(config.modes, companions=True))
    f = config.drive.frequency
    upper = forced_orbit(both, f, 0.4e-6, config.drive.amplitude)
    lower = forced_orbit(both, f, 0.04e-6, config.drive.amplitude)
    mu = np.sort(np.abs(upper.companion_multipliers))[::-1]
    print(f'upper branch with companions: largest companion multipliers {mu[:3]}, branch '
          f'{np.max(np.abs(upper.floquet_multipliers)):.8f}; lower: '
          f'{np.max(np.abs(lower.companion_multipliers)):.8f}')
    # One companion direction grows (measured 1.0000376: 40x the distance to 1 of the
    # finite-difference error, which the decaying pairs at exp(-pi omega / (Q w)) = 0.99998
    # bound), the others decay; the branch itself is stable.
    assert mu[0] > 1.00001 and mu[1] < 1.0
    assert upper.branch_stable and not upper.stable
    assert lower.stable and lower.companion_multipliers.size == 2 * config.modes.count
    growth = math.log(mu[0]) * f  # 1/s
    # The Simulator from the orbit with a 1 pm seed on q2s: the seed's envelope grows as
    # exp(growth t) (after its transient onto the unstable direction).
    sim = Simulator(both)
    n = config.modes.count
    x0, v0 = upper.initial_state[:2 * n].copy(), upper.initial_state[2 * n:].copy()
    x0[n + 1] = 1e-12
    sim.set_state(x0, v0)
    out = sim.advance(4.0)
    q2s = np.abs(out.q[:, n + 1])
    window = int(round(0.05 / sim.period_s))
    env = np.array([q2s[i:i + window].max() for i in range(0, len(q2s) - window + 1, window)])
    t_env = (np.arange(env.size) + 0.5) * 0.05
    late = t_env > 2.0  # the decaying direction (~0.29 /s) has faded below 5 %
    rate = np.polyfit(t_env[late], np.log(env[late]), 1)[0]
    print(f'growth of q2s: Floquet {growth:.3f} /s, Simulator {rate:.3f} /s')
    # Measured 0.594 vs 0.595 /s; 5 % allows for the log-linear fit of 40 window maxima.
    assert rate == pytest.approx(growth, rel=0.05)


def test_start_state_shoots_once_per_device_and_drive(monkeypatch):
    # Run(config) starts itself: the resting sensor's orbit is memoised per device and drive,
    # so runs that differ in their scenario, their rate or their noise shoot once.
    from ring_gyro_sim.core.gyro import operating_point
    calls = []
    real = operating_point.drive_orbit
    monkeypatch.setattr(operating_point, 'drive_orbit',
                        lambda config: calls.append(config) or real(config))
    base = {'modes.companions': True, 'gyro.enabled': True, 'drive.amplitude': 0.0065,
            'drive.frequency': 15800.0, 'modes.quality_factors': [120001.0, 64700.0, 170000.0]}
    logs = []
    rest = start_state(paper_config(base), logs.append)
    turning = start_state(paper_config({**base, 'scenario.rate_times': [0.0],
                                        'scenario.rate_values': [0.2],
                                        'gyro.noise_seed': 7, 'duration': 3.0}), logs.append)
    assert len(calls) == 1 and len(logs) == 1 and 'computing the start state' in logs[0]
    n = 3
    # The same orbit; the turning sensor has its 2theta pair in its response to the rate
    # (q2 and q2s), the other coordinates are the orbit's.
    assert rest[0][0] == turning[0][0] and rest[0][2] == turning[0][2]
    assert np.all(rest[0][n:] == 0.0) and turning[0][n + 1] != 0.0
    start_state(paper_config({**base, 'drive.amplitude': 0.006}))
    assert len(calls) == 2
