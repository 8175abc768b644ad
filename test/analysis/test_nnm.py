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
Tests of analysis/nnm.py: backbone (Fig. 4) and V_o calibration.

Every reference is either a number of the paper (section 3.1-3.4) or an identity that holds
whatever the implementation: periodicity of the returned orbits checked by an independent
integration. The forced orbits (Fig. 9) are the gyroscope's operating point:
test/core/gyro/test_operating_point.py.
"""

from dataclasses import replace
import math

import numpy as np
import pytest
from ring_gyro_sim.analysis import nnm
from ring_gyro_sim.core import forces
from ring_gyro_sim.core.params import paper_config
from scipy.integrate import solve_ivp

PAPER_BACKBONE_HZ = 10.6e3
"""Fig. 4: the 1theta mode at about 6 um (60 % of the gap), N_T = 10."""
TABLE1_F1_HZ = 11.2e3
DRIVE_HZ = 15798.3
"""Section 3.4: drive frequency of the drive + shock cases."""


@pytest.fixture(scope='module')
def config():
    """Return the default configuration (N_R = 3, N_T = 10, calibrated V_o, drive on)."""
    return paper_config({})


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
    # doc/physics.md, "Known traps": keeping K_c explicit shifts f1 by several hundred Hz (down:
    # the k = 2 term softens).
    explicit = paper_config({'electrodes.fold_linear_stiffness': False})
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
    f4 = nnm.frequency_at_amplitude(paper_config({'electrodes.taylor_terms': 4}), 6e-6)
    f12 = nnm.frequency_at_amplitude(paper_config({'electrodes.taylor_terms': 12}), 6e-6)
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
