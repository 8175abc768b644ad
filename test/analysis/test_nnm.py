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
Tests of analysis/nnm.py: backbone (Fig. 4), V_o calibration, forced orbits (Fig. 9).

Every reference is either a number of the paper (section 3.1-3.4) or an identity that holds
whatever the implementation: periodicity of the returned orbits checked by an independent
integration, Liouville's formula for the product of the Floquet multipliers.
"""

from dataclasses import replace
import math

import numpy as np
import pytest
from ring_gyro_sim.analysis import nnm
from ring_gyro_sim.core import forces
from ring_gyro_sim.core.params import build_config
from ring_gyro_sim.core.simulator import Simulator
from scipy.integrate import solve_ivp

PAPER_BACKBONE_HZ = 10.6e3
"""Fig. 4: the 1theta mode at about 6 um (60 % of the gap), N_T = 10."""
TABLE1_F1_HZ = 11.2e3
DRIVE_HZ = 15798.3
"""Section 3.4: drive frequency of the drive + shock cases."""


@pytest.fixture(scope='module')
def config():
    """Return the default configuration (N_R = 3, N_T = 10, calibrated V_o, drive on)."""
    return build_config({})


@pytest.fixture(scope='module')
def backbone_6um(config):
    """Backbone frequency (Hz) of the 1theta mode at 6 um (max |q1| over the orbit)."""
    return nnm.frequency_at_amplitude(config, 6e-6)


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


def test_backbone_at_6um_matches_fig4(backbone_6um):
    """
    The 1theta backbone at 6 um is within 0.15 kHz of Fig. 4's 10.6 kHz.

    Method (nnm.py): shooting for a periodic orbit of the conservative system (eq. 33, no
    damping, no drive). The orbit starts at rest at a turning point with q1 given; the other
    coordinates at the start and the half period are the unknowns of ``v(T/2) = 0``, solved by
    continuation in amplitude from the linear mode. The frequency is 1 / period; the amplitude
    is max |q1| over the orbit (the start is adjusted until it is 6 um).
    """
    print(f'backbone at 6 um: {backbone_6um:.1f} Hz (Fig. 4: ~{PAPER_BACKBONE_HZ:.0f} Hz)')
    assert abs(backbone_6um - PAPER_BACKBONE_HZ) < 150.0
    # Softening (eq. 23 puts the electrostatic force on the right-hand side).
    assert backbone_6um < TABLE1_F1_HZ - 300.0


def test_small_amplitude_limit_is_table1_frequency(config):
    # fold_linear_stiffness = True: the Table 1 frequency already holds K_c (eq. 26).
    assert config.electrodes.fold_linear_stiffness
    point, = nnm.nonlinear_mode(config, [1e-9])
    print(f'backbone at 1 nm: {point.frequency_hz:.3f} Hz')
    assert point.frequency_hz == pytest.approx(TABLE1_F1_HZ, abs=1.0)
    assert point.residual < 1e-8
    assert point.amplitude_m == pytest.approx(1e-9, rel=1e-6)


def test_small_amplitude_limit_moves_when_kc_is_kept_explicit(config):
    # physics.md, known traps: keeping K_c explicit shifts f1 by several hundred Hz (down:
    # the k = 2 term softens).
    explicit = build_config({'electrodes.fold_linear_stiffness': False})
    point, = nnm.nonlinear_mode(explicit, [1e-9])
    print(f'backbone at 1 nm, K_c explicit: {point.frequency_hz:.1f} Hz')
    assert point.frequency_hz < TABLE1_F1_HZ - 100.0


def test_backbone_orbit_is_periodic_in_an_independent_integration(config):
    """Integrate a returned 5 um orbit over a full period: it comes back to its start."""
    amplitudes = np.linspace(1e-6, 5e-6, 5)
    points = nnm.nonlinear_mode(config, amplitudes)
    freqs = [p.frequency_hz for p in points]
    assert all(np.diff(freqs) < 0), f'not softening monotonically: {freqs}'
    p = points[-1]
    n, rhs = equations(config)
    y0 = np.concatenate([p.initial_state_m, np.zeros(n)])
    period = 1.0 / p.frequency_hz
    sol = solve_ivp(rhs, (0.0, period), y0, method='DOP853', rtol=1e-11, atol=1e-18,
                    dense_output=True)
    x_end = sol.y[:n, -1]
    err = np.max(np.abs(x_end - p.initial_state_m)) / p.amplitude_m
    print(f'5 um orbit at {p.frequency_hz:.2f} Hz: return error / amplitude = {err:.2e}')
    assert err < 1e-6
    tt = np.linspace(0.0, period, 4001)
    assert np.max(np.abs(sol.sol(tt)[0])) == pytest.approx(p.amplitude_m, rel=1e-5)
    # Half a period earlier it is not back (the period is not a multiple of the true one).
    half = sol.sol(0.5 * period)[:n]
    assert np.max(np.abs(half - p.initial_state_m)) > p.amplitude_m


def test_taylor_order_changes_the_backbone(config, backbone_6um):
    # Fig. 4: N_T = 4 is visibly off at 6 um; N_T >= 10 is converged. The truncated series
    # has only positive terms (outer electrode), so fewer terms soften less.
    f4 = nnm.frequency_at_amplitude(build_config({'electrodes.taylor_terms': 4}), 6e-6)
    f12 = nnm.frequency_at_amplitude(build_config({'electrodes.taylor_terms': 12}), 6e-6)
    print(f'backbone at 6 um: N_T = 4 {f4:.1f} Hz, 10 {backbone_6um:.1f} Hz, 12 {f12:.1f} Hz')
    assert f4 - backbone_6um > 100.0
    assert abs(f12 - backbone_6um) < 0.25 * (f4 - backbone_6um)


def test_calibrated_voltage_puts_backbone_through_target(config):
    volts = nnm.calibrate_outer_voltage(config, PAPER_BACKBONE_HZ, 6e-6, bracket_v=(82.0, 85.0))
    tuned = replace(config, electrodes=replace(config.electrodes, outer_voltage=volts))
    f = nnm.frequency_at_amplitude(tuned, 6e-6)
    print(f'V_o for 10.6 kHz at 6 um: {volts:.3f} V (backbone there {f:.2f} Hz)')
    assert f == pytest.approx(PAPER_BACKBONE_HZ, abs=1.0)
    # More voltage, more softening: the exact fit needs more than the default voltage, whose
    # backbone sits above 10.6 kHz.
    assert volts > config.electrodes.outer_voltage


def test_calibrate_with_default_bracket(config):
    volts = nnm.calibrate_outer_voltage(config)
    assert 70.0 < volts < 100.0


@pytest.fixture(scope='module')
def branches(config):
    """Upper and lower forced orbits at 15.7983 kHz with the default drive amplitude."""
    a_e = config.drive.amplitude
    upper = nnm.forced_orbit(config, DRIVE_HZ, 0.4e-6, a_e)
    lower = nnm.forced_orbit(config, DRIVE_HZ, 0.04e-6, a_e)
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
    inside = nnm.ForcedOrbit(DRIVE_HZ, np.zeros(2), np.zeros(4), np.array([0.5, 0.99999j]))
    outside = nnm.ForcedOrbit(DRIVE_HZ, np.zeros(2), np.zeros(4), np.array([0.5, 1.0001]))
    assert inside.stable
    assert not outside.stable


def test_drive_initial_state_rest_or_drive_off_is_none():
    assert nnm.drive_initial_state(build_config({'drive.start_on': 'rest'})) is None
    assert nnm.drive_initial_state(build_config({'drive.amplitude': 0.0})) is None


def test_upper_branch_start_is_periodic(config):
    assert config.drive.start_on == 'upper_branch'
    upper = nnm.forced_orbit(config, config.drive.frequency, 0.4e-6, config.drive.amplitude)
    assert upper.stable
    x0, v0 = nnm.drive_initial_state(config)
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
    lower = nnm.forced_orbit(config, config.drive.frequency, 0.04e-6, config.drive.amplitude)
    assert lower.stable and lower.amplitude_m[1] < 0.1e-6
    x0, v0 = nnm.drive_initial_state(replace(config, drive=replace(config.drive,
                                                                   start_on='lower_branch')))
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
    upper = nnm.forced_orbit(config, config.drive.frequency, 0.4e-6, config.drive.amplitude)
    both = replace(config, modes=replace(config.modes, companions=True))
    with pytest.warns(RuntimeWarning, match='unstable to the sine companions'):
        x0, v0 = nnm.drive_initial_state(both)
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
    upper = nnm.forced_orbit(both, f, 0.4e-6, config.drive.amplitude)
    lower = nnm.forced_orbit(both, f, 0.04e-6, config.drive.amplitude)
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
