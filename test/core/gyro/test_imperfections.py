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
The imperfect gyroscope against the closed forms of its imperfections (doc/imperfections.md).

Open loop, matched drive, linear regime (config/gyro.yaml's operating point: q2 = 0.04 um at
15 800 Hz), noise off: the zero-rate output of a damping mismatch, the quadrature of a
frequency split, the same device described from the other principal axis, and the
electronics' errors (the demodulation phase, the sense electrodes' misalignment). The runs
start in the pair's steady response (``operating_point.with_rate_response``), so 0.3 s of
rate samples are read, the last 0.1 s kept.
"""

import math

import numpy as np
import pytest
from ring_gyro_sim.core.params import build_config, paper_config
from ring_gyro_sim.run import Run

TEN_DEG_S = math.radians(10.0)
KAPPA = 0.8  # 2 n / (n^2 + 1) of the 2theta pair
W2 = 2.0 * math.pi * 15800.0
Q2 = 64700.0
OPEN_LOOP = {'modes.companions': True, 'gyro.enabled': True, 'drive.amplitude': 0.0065,
             'drive.frequency': 15800.0, 'control.mode': 'open_loop',
             'gyro.temperature': 0.0,
             'gyro.input_noise_density': 0.0, 'gyro.calibration.source': 'ideal'}


def readout(values, rate, seconds=0.3, base=OPEN_LOOP):
    """Return (rate, quadrature) of ~/rate over the last 0.1 s of a run at ``rate`` rad/s."""
    config = (paper_config if base is OPEN_LOOP else build_config)(
        {**base, **values, 'scenario.rate_times': [0.0], 'scenario.rate_values': [rate]})
    run = Run(config)
    blocks = [run.advance(config.run.block_samples) for _ in range(int(round(seconds / 0.01)))]
    r = np.concatenate([b.rate.rate for b in blocks])[-100:]
    q = np.concatenate([b.rate.quadrature for b in blocks])[-100:]
    return float(np.mean(r)), float(np.mean(q))


def zero_rate_output(values):
    """Return the zero-rate reading over the response to 10 deg/s, times 10 deg/s: rad/s."""
    at_zero, _ = readout(values, 0.0)
    turning, _ = readout(values, TEN_DEG_S)
    return at_zero / (turning - at_zero) * TEN_DEG_S


def test_a_damping_mismatch_off_the_axes_gives_a_zero_rate_output():
    # Q_y = 0.9 Q_x with its axis at 22.5 deg: |c_x - c_y| sin(4 theta_t) / (4 kappa)
    values = {'modes.companion_quality_factors': [120000.0, 0.9 * Q2, 170000.0],
              'modes.damping_axes': [0.0, 22.5, 0.0]}
    zro = zero_rate_output(values)
    c_x, c_y = W2 / Q2, W2 / (0.9 * Q2)
    expected = abs(c_x - c_y) * math.sin(4.0 * math.radians(22.5)) / (4.0 * KAPPA)
    print(f'zero-rate output {zro:.6e} rad/s, closed form {expected:.6e} '
          f'({math.degrees(expected):.3f} deg/s)')
    assert abs(zro) == pytest.approx(expected, rel=0.02)
    # on the axes it is gone
    assert abs(zero_rate_output({**values, 'modes.damping_axes': [0.0, 0.0, 0.0]})) \
        < 1e-3 * expected


def test_a_frequency_split_off_the_axes_gives_a_quadrature():
    # a 5 mHz split (well inside the 0.12 Hz half-width: matched) with its axis at 10 deg:
    # (w_x^2 - w_y^2) sin(4 theta_w) / (4 kappa w) in rate units
    f_y = 15800.005
    _, quadrature = readout({'modes.companion_frequencies': [11200.0, f_y, 22000.0],
                             'modes.frequency_axes': [0.0, 10.0, 0.0]}, 0.0)
    w_y = 2.0 * math.pi * f_y
    expected = (W2 * W2 - w_y * w_y) * math.sin(4.0 * math.radians(10.0)) / (4.0 * KAPPA * W2)
    print(f'quadrature {quadrature:.6e} rad/s, closed form {expected:.6e}')
    assert abs(quadrature) == pytest.approx(abs(expected), rel=0.02)


def test_the_other_principal_axis_describes_the_same_device():
    # axes turned by 90/n = 45 deg with the principal values swapped: the same ring
    one = {'modes.companion_frequencies': [11200.0, 15800.005, 22000.0],
           'modes.companion_quality_factors': [120000.0, 0.9 * Q2, 170000.0],
           'modes.frequency_axes': [0.0, 10.0, 0.0], 'modes.damping_axes': [0.0, 22.5, 0.0]}
    other = {'modes.frequencies': [11200.0, 15800.005, 22000.0],
             'modes.companion_frequencies': [11200.0, 15800.0, 22000.0],
             'modes.quality_factors': [120000.0, 0.9 * Q2, 170000.0],
             'modes.companion_quality_factors': [120000.0, Q2, 170000.0],
             'modes.frequency_axes': [0.0, 55.0, 0.0], 'modes.damping_axes': [0.0, 67.5, 0.0]}
    a = paper_config({**OPEN_LOOP, **one}).modes.pair_matrices(2)
    b = paper_config({**OPEN_LOOP, **other}).modes.pair_matrices(2)
    for x, y in zip(a, b):  # to round-off of the diagonal
        np.testing.assert_allclose(x, y, rtol=0, atol=1e-13 * x[0, 0])
    ra, qa = readout(one, TEN_DEG_S, seconds=0.1)
    rb, qb = readout(other, TEN_DEG_S, seconds=0.1)
    assert rb == pytest.approx(ra, rel=1e-6) and qb == pytest.approx(qa, rel=1e-6)


def test_a_demodulation_phase_error_turns_quadrature_into_bias():
    # (E3b) the reading is Omega cos(eps) - Q sin(eps): with a split's quadrature Q, a
    # phase error eps adds -Q sin(eps) to the zero-rate output
    split = {'modes.companion_frequencies': [11200.0, 15800.005, 22000.0],
             'modes.frequency_axes': [0.0, 10.0, 0.0]}
    r0, q0 = readout(split, 0.0)
    eps = 0.02
    r1, q1 = readout({**split, 'gyro.phase_error': eps}, 0.0)
    print(f'bias {r0:.3e} -> {r1:.3e} rad/s with a {eps} rad phase error; quadrature {q0:.3e}')
    assert r1 - r0 == pytest.approx(-q0 * math.sin(eps), rel=0.02)


def test_misaligned_sense_electrodes_read_the_drive_as_a_bias():
    # (E1b) the sense amplifier reads -tan(2 delta) of the drive's displacement, in phase
    # with the Coriolis response at match: a bias of tan(2 delta) w / (2 kappa Q) in rate
    # units (the sense mode's response per rate is 2 kappa Q A / w)
    delta = 0.1
    at_zero, _ = readout({'gyro.sense_misalignment': delta}, 0.0)
    expected = math.tan(2.0 * math.radians(delta)) * W2 / (2.0 * KAPPA * Q2)
    print(f'bias {at_zero:.4e} rad/s, closed form {expected:.4e}')
    assert abs(at_zero) == pytest.approx(expected, rel=0.02)


def test_a_pickoff_gain_mismatch_scales_the_sense_amplifier_only():
    # (E1c) the sense column of (E1) times 1 + g: its gain, and only its, moves by 1 + g
    g = 0.01
    perfect = Run(paper_config(OPEN_LOOP)).full_model().pickoff
    mismatched = Run(paper_config({**OPEN_LOOP, 'gyro.pickoff_gain_mismatch': g}))
    mismatched = mismatched.full_model().pickoff
    assert mismatched.sense_gain == pytest.approx((1.0 + g) * perfect.sense_gain, rel=1e-12)
    assert mismatched.drive_gain == perfect.drive_gain


def test_force_to_rebalance_reads_through_a_phase_error_as_a_rotation():
    # (E3b) with the rebalance loop: its demodulation and its modulation share the sense
    # reference, so the loop still cancels the Coriolis force, and the force it reads is
    # turned by eps: rate Omega cos(eps), quadrature Omega sin(eps) in magnitude; the PLL is
    # untouched
    eps = 0.02
    ftr = {'gyro.enabled': True, 'control.mode': 'rebalance',
           'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0,
           'gyro.calibration.source': 'ideal'}
    rate, quadrature = readout({**ftr, 'gyro.phase_error': eps}, TEN_DEG_S, seconds=0.2,
                               base={})
    print(f'rate {rate:.6e}, quadrature {quadrature:.6e} rad/s')
    assert rate == pytest.approx(TEN_DEG_S * math.cos(eps), rel=2e-3)
    assert abs(quadrature) == pytest.approx(TEN_DEG_S * math.sin(eps), rel=2e-2)


def test_force_to_rebalance_holds_a_misaligned_sense_mode_where_its_amplifier_reads_0():
    # (E1b) the rebalance loop nulls what the misaligned amplifier reads, cos(2 delta) q2s -
    # sin(2 delta) q2: it holds q2s = tan(2 delta) q2, in phase with the drive, with a force
    # tan(2 delta) C_ss w X in phase with the Coriolis force's: a bias of
    # tan(2 delta) w_s / (2 kappa Q_s), as open loop. The run starts there (no transient).
    delta = 0.1
    ftr = {'gyro.enabled': True, 'control.mode': 'rebalance',
           'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0,
           'gyro.calibration.source': 'ideal', 'gyro.sense_misalignment': delta,
           'scenario.rate_times': [0.0], 'scenario.rate_values': [0.0],
           'integrator.fidelity': 'full'}   # E1b of the full model's pick-off
    config = build_config(ftr)
    run = Run(config)
    first = run.advance(config.run.block_samples).rate.rate
    for _ in range(29):
        last = run.advance(config.run.block_samples).rate.rate
    w_s = 2.0 * math.pi * config.modes.coordinate_frequencies()[4]
    q_s = config.modes.coordinate_quality_factors()[4]
    expected = math.tan(2.0 * math.radians(delta)) * w_s / (2.0 * KAPPA * q_s)
    print(f'bias {np.mean(last):.5e} rad/s (first 10 ms {np.mean(first):.5e}), '
          f'closed form {expected:.5e}')
    assert abs(np.mean(last)) == pytest.approx(expected, rel=0.02)
    assert np.mean(first) == pytest.approx(np.mean(last), rel=1e-3)
