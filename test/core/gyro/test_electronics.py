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
The sense electronics (core/gyro/electronics.py) on synthesized trajectories.

The operating point is ``config/gyro.yaml``'s: a tenth of the paper's drive at 15 800 Hz,
linear response ``A = drive.amplitude Q_2 / omega^2 = 42.7 nm``. The trajectories are
``q2 = A cos(phi)``, ``q2s = a cos(phi) + b sin(phi)`` with ``phi`` the drive phase, and
their capacitances come from ``Simulator.outputs_for`` (those the node publishes), so the
chain is tested on exactly what it will be fed, without the Coriolis kernel.
"""

import math

import allantools
import numpy as np
import pytest
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.errors import InputError
from ring_gyro_sim.core.gyro import electronics
from ring_gyro_sim.core.gyro.electronics import (FlickerNoise, orbit_sense_response,
                                                 SenseElectronics)
from ring_gyro_sim.core.params import BOLTZMANN, EPSILON_0, paper_config
from scipy import signal

GYRO = {'gyro.enabled': True, 'modes.companions': True, 'drive.amplitude': 0.0065,
        'drive.frequency': 15800.0}
RATE = math.radians(10.0)  # 10 deg/s, the gyroscope's test rate
BLOCK = 2000  # samples per 10 ms block at the default 200 kHz


def make(**overrides):
    config = paper_config({**GYRO, **overrides})
    sim = Simulator(config)
    w = 2.0 * math.pi * config.drive.frequency
    amplitude = config.drive.amplitude * config.modes.quality_factors[1] / w ** 2
    return config, sim, amplitude


def trajectory(sim, el, amplitude, first, count, a=0.0, b=0.0, phase0=0.3):
    """
    Return times, capacitances and drive-force phases of q2 = A cos(psi), q2s = a cos + b sin.

    ``psi = phi_drive + drive_phase_rad`` with the electronics' drive phase.
    """
    k = np.arange(first, first + count)
    t = (k + 1) * sim.period_s
    phi = 2.0 * math.pi * el.config.drive.frequency * t + phase0
    psi = phi + el.drive_phase_rad
    q = np.zeros((count, sim.model.n_coordinates))
    q[:, el.drive_index] = amplitude * np.cos(psi)
    q[:, el.sense_index] = a * np.cos(psi) + b * np.sin(psi)
    return t, sim.outputs_for(q).capacitance, phi


def run(el, sim, amplitude, cuts, **traj):
    demod, rate_t, rate, quad = [], [], [], []
    at = 0
    for c in cuts:
        t, cap, phi = trajectory(sim, el, amplitude, at, c, **traj)
        d, r = el.process(at, t, cap, phi)
        demod.append(d.values)
        rate_t.append(r.t)
        rate.append(r.rate)
        quad.append(r.quadrature)
        at += c
    return (np.concatenate(demod), np.concatenate(rate_t), np.concatenate(rate),
            np.concatenate(quad))


def test_electronic_gain_against_the_closed_form():
    config, sim, amplitude = make()
    el = SenseElectronics(config, sim, amplitude, 0.0)
    # dC_e/dq2s = eps eps0 l r_o / d_g^2 * int_e sin(2 theta) dtheta (first order of
    # 1 / (d_g - w)), weighted by -(V_b / C_f) sin(2 theta_e)
    e = config.electrodes
    k = e.count
    half = math.pi / k
    scale = EPSILON_0 * e.relative_permittivity * config.ring.length * config.outer_radius
    gain = 0.0
    for i in range(k):
        c = 2.0 * math.pi * i / k
        weight = math.sin(2.0 * c)
        if abs(weight) < 1e-12:
            continue
        integral = 0.5 * (math.cos(2.0 * (c - half)) - math.cos(2.0 * (c + half)))
        gain += weight * scale / e.gap ** 2 * integral
    gain *= -e.outer_voltage / config.gyro.feedback_capacitance
    # module docstring (E7): truncation 1e-10 + round-off 1e-11
    assert el.electronic_gain == pytest.approx(gain, rel=1e-9, abs=0)
    assert el.bias_voltage == e.outer_voltage


def test_scale_factor_closed_form_at_match():
    config, sim, amplitude = make()
    el = SenseElectronics(config, sim, amplitude, 0.0)
    w = 2.0 * math.pi * 15800.0
    q_s = config.modes.quality_factors[1]
    # folded linear stiffness: jacobian(0) = 0, w_s = the table's 15 800 Hz (E5)
    assert el.sense_omega == pytest.approx(w, rel=1e-15, abs=0)
    assert el.linear_mechanical_scale_factor == pytest.approx(-2.0 * 0.8 * q_s * amplitude / w,
                                                              rel=1e-12, abs=0)
    # (E6b) about the drive orbit: the force's cubic term detunes the sense mode by
    # delta ~ A^2, which turns the response by ~delta / (w_s / 2 Q_s) into quadrature (first
    # order: ~A^2) and lowers the in-phase part by its square (~A^4); and (E6) itself for a
    # small drive.
    change = 1.0 - el.mechanical_scale_factor / el.linear_mechanical_scale_factor
    half = orbit_sense_response(config, sim.model, 0.5 * amplitude)
    change_half = 1.0 - half.real / (0.5 * el.linear_mechanical_scale_factor)
    assert 1e-3 < change < 2e-2
    assert change / change_half == pytest.approx(16.0, rel=0.05)
    quadrature_half = -half.imag / half.real
    assert el.rate_quadrature_per_rate / quadrature_half == pytest.approx(4.0, rel=0.05)
    small = orbit_sense_response(config, sim.model, 0.01 * amplitude)
    linear = -2.0 * 0.8 * q_s * 0.01 * amplitude / w
    assert small.real == pytest.approx(linear, rel=1e-6, abs=0)
    assert abs(small.imag / small.real) < 2e-5
    assert el.scale_factor == el.electronic_gain * el.mechanical_scale_factor
    # the closed form: q2s / q2 = 0.182 at 10 deg/s
    assert abs(el.linear_mechanical_scale_factor * RATE / amplitude) == pytest.approx(
        0.182, abs=5e-4)


def test_unfolded_stiffness_enters_the_sense_frequency():
    config, sim, amplitude = make(**{'electrodes.fold_linear_stiffness': False})
    el = SenseElectronics(config, sim, amplitude, 0.0)
    m = config.modal_masses()[el.sense_index]
    expect = (2.0 * math.pi * 15800.0) ** 2 - config.electrostatic_stiffness() / m  # eq. 26
    assert el.sense_omega ** 2 == pytest.approx(expect, rel=1e-12, abs=0)


@pytest.mark.parametrize('a_rate, b_rate', [(RATE, 0.0), (-RATE, 0.0), (0.0, RATE),
                                            (0.3 * RATE, -0.7 * RATE)])
def test_rate_and_quadrature_are_measured(a_rate, b_rate):
    config, sim, amplitude = make(**{'gyro.input_noise_density': 0.0})
    el = SenseElectronics(config, sim, amplitude, 0.3)
    s_m = el.mechanical_scale_factor
    a, b = a_rate * s_m, b_rate * s_m
    n = 30 * BLOCK  # 0.3 s: the Butterworth (slowest pole 240 /s) settles to 1e-20
    _, _, rate, quad = run(el, sim, amplitude, [n], a=a, b=b)
    settled = slice(len(rate) // 2, None)
    # Linearity: the capacitances' quadratic terms cancel in the sense pair (symmetric
    # electrodes, weights +-1); the first correction is cubic, (9/16) (A^2 + a^2 + b^2) /
    # d_g^2 with electrode averages <= 1: bound it by (A^2 + a^2 + b^2) / d_g^2 (2e-5 here).
    d = config.electrodes.gap
    tol = (amplitude ** 2 + a ** 2 + b ** 2) / d ** 2
    scale = max(abs(a_rate), abs(b_rate))
    np.testing.assert_allclose(rate[settled], a_rate, rtol=0, atol=tol * scale)
    np.testing.assert_allclose(quad[settled], b_rate, rtol=0, atol=tol * scale)
    # and the chain is exact against the Fourier coefficients of the published V(phi)
    # (64 phases: exact for the harmonics the capacitance has above round-off)
    phases = 2.0 * math.pi * np.arange(64) / 64
    q = np.zeros((64, sim.model.n_coordinates))
    q[:, el.drive_index] = amplitude * np.cos(phases)
    q[:, el.sense_index] = a * np.cos(phases) + b * np.sin(phases)
    both = (sim.outputs_for(q).capacitance - el.rest_capacitance) @ el._volts
    volts = both[:, 0]
    # the ratiometric readout (E4): divided by the drive pick-off's amplitude over nominal
    rho = math.hypot(2.0 * np.mean(both[:, 1] * np.cos(phases)),
                     2.0 * np.mean(both[:, 1] * np.sin(phases))) / el.drive_pickoff_nominal_v
    i_true = 2.0 * np.mean(volts * np.cos(phases)) / (el.scale_factor * rho)
    q_true = 2.0 * np.mean(volts * np.sin(phases)) / (el.scale_factor * rho)
    # left: the 2 omega ripple through the filter, (100 / 31 600)^4 = 1e-10 of the signal
    np.testing.assert_allclose(rate[settled], i_true, rtol=0, atol=1e-9 * scale)
    np.testing.assert_allclose(quad[settled], q_true, rtol=0, atol=1e-9 * scale)


def test_chunk_invariance_bit_for_bit_with_every_noise():
    config, sim, amplitude = make(**{'gyro.bias_instability': 3.0, 'gyro.noise_seed': 11})
    cuts_list = [[12000], [7, 1993, 2000, 8000], [1, 1, 11998], [199, 3001, 800, 8000]]
    results = []
    for cuts in cuts_list:
        el = SenseElectronics(config, sim, amplitude, 0.2)
        results.append(run(el, sim, amplitude, cuts, a=1e-9))
    for other in results[1:]:
        for x, y in zip(results[0], other):
            assert np.array_equal(x, y)
    demod, rate_t, rate, _ = results[0]
    assert demod.shape == (12000, len(electronics.DEMOD_CHANNELS))
    d = el.decimation
    assert d == 200
    # rate samples at the global indices k with (k + 1) % D == 0, at (k + 1) P
    np.testing.assert_array_equal(rate_t, (np.arange(d - 1, 12000, d) + 1) * sim.period_s)


def test_the_same_seed_gives_the_same_noise_another_seed_another():
    config, sim, amplitude = make(**{'gyro.noise_seed': 5})
    out = [run(SenseElectronics(config, sim, amplitude, 0.0), sim, amplitude, [4000])[2]
           for _ in range(2)]
    config2, sim2, _ = make(**{'gyro.noise_seed': 6})
    other = run(SenseElectronics(config2, sim2, amplitude, 0.0), sim2, amplitude, [4000])[2]
    assert np.array_equal(out[0], out[1])
    assert not np.any(out[0] == other)


def test_noise_free_when_the_densities_are_zero():
    config, sim, amplitude = make(**{'gyro.input_noise_density': 0.0})
    el = SenseElectronics(config, sim, amplitude, 0.0)
    demod, _, rate, quad = run(el, sim, 0.0, [5000])
    assert not np.any(demod[:, :2]) and not np.any(rate) and not np.any(quad)
    config, sim, amplitude = make()  # the default 10 nV/sqrt(Hz): the mutation check
    demod = run(SenseElectronics(config, sim, amplitude, 0.0), sim, 0.0, [5000])[0]
    assert np.all(demod[100:, :2] != 0.0)


def test_electronic_noise_gives_the_predicted_angle_random_walk():
    config, sim, amplitude = make(**{'gyro.temperature': 0.0, 'gyro.noise_seed': 3})
    el = SenseElectronics(config, sim, amplitude, 0.0)
    total, thermo, n_el = el.predicted_arw()
    assert thermo == 0.0 and total == n_el
    # (E2), (E11) by hand: C_in = 4 C_e0 + C_p
    c_in = 4.0 * el.rest_capacitance[1] + config.gyro.parasitic_capacitance
    e_o = config.gyro.input_noise_density * (1.0 + c_in / config.gyro.feedback_capacitance)
    assert n_el == pytest.approx(e_o / abs(el.scale_factor), rel=1e-12, abs=0)
    seconds = 30.0
    n = int(seconds * config.run.output_rate)
    rate = []
    for first in range(0, n, BLOCK):
        # the drive at its operating point (the ratiometric readout divides by its pick-off),
        # the sense mode at rest: the rate is noise only
        t, cap, phi = trajectory(sim, el, amplitude, first, BLOCK)
        rate.append(el.process(first, t, cap, phi)[1].rate)
    rate = np.concatenate(rate)[100:]  # 0.1 s: the filter's start
    fs_rate = config.gyro.output_rate
    # 1) variance = one-sided density 2 N^2 times the filter's noise bandwidth. 30 000
    # samples correlated over ~1 / (2 ENBW) = 5 samples: ~6000 independent, standard error
    # sqrt(2 / 6000) = 1.8 % of the variance; 3 standard errors = 5.5 %.
    f, h = signal.sosfreqz(el._sos, worN=200_000, fs=config.run.output_rate)
    enbw = np.trapezoid(np.abs(h) ** 2, f)
    assert np.var(rate) == pytest.approx(2.0 * n_el ** 2 * enbw, rel=0.055, abs=0)
    # 2) Allan deviation (allantools) N / sqrt(tau), within 10 %: at 0.05 s and
    # 0.1 s the low-pass removes 3 % and 1.5 % of the white-noise Allan variance (the part
    # of the Allan kernel above 100 Hz), and the overlapping estimator's standard error is
    # 2.3 % and 3.3 % (edf ~ 1.5 N / m): both inside the 10 %.
    taus, adev, _, _ = allantools.oadev(rate, rate=fs_rate, data_type='freq',
                                        taus=np.array([0.05, 0.1]))
    np.testing.assert_allclose(adev, n_el / np.sqrt(taus), rtol=0.1)


def _ar1_allan_variance(variance, rho, m):
    """Exact Allan variance of m-sample averages of a stationary AR(1) process."""
    k = np.arange(2 * m)
    r = variance * rho ** k
    var = (m * r[0] + 2.0 * np.sum((m - k[1:m]) * r[1:m])) / m ** 2
    cov = np.sum((m - np.abs(k[1:] - m)) * r[1:]) / m ** 2
    return var - cov


def test_flicker_bank_has_the_ieee_952_floor_exactly():
    f_r = 1000.0
    b = 1.0
    bank = FlickerNoise(b, f_r, 0)
    assert electronics.FLICKER_FLOOR_RATIO == pytest.approx(0.6643, abs=5e-5)  # IEEE 952
    for tau in (10.0 / f_r, 0.1, 1.0, 10.0, 100.0, 0.01 / electronics.FLICKER_LOWEST_HZ):
        m = int(round(tau * f_r))
        avar = sum(_ar1_allan_variance(bank.sigma ** 2, rho, m) for rho in bank.rho)
        # the module docstring's 1.5 % (discrete corners, the band's edges)
        assert math.sqrt(avar) == pytest.approx(electronics.FLICKER_FLOOR_RATIO * b,
                                                rel=0.015, abs=0)


def test_flicker_samples_have_the_floor():
    f_r = 1000.0
    b = 2.0e-5
    bank = FlickerNoise(b, f_r, 9)
    x = np.concatenate([bank.samples(i, 100_000) for i in range(0, 1_000_000, 100_000)])
    taus, adev, err, _ = allantools.oadev(x, rate=f_r, data_type='freq',
                                          taus=np.array([0.1, 1.0]))
    # Allan deviation of flicker rate noise at tau = 0.1 s and 1 s from 1000 s: 10 000 and
    # 1 000 averaging times, estimator error ~1/sqrt(those) -> 1 % and 3 %; within 10 %.
    np.testing.assert_allclose(adev, electronics.FLICKER_FLOOR_RATIO * b, rtol=0.1)


def test_flicker_reaches_the_rate_output():
    config, sim, amplitude = make(**{'gyro.input_noise_density': 0.0,
                                     'gyro.bias_instability': 10.0})
    el = SenseElectronics(config, sim, amplitude, 0.0)
    bank = FlickerNoise(electronics.deg_per_h_to_rad_per_s(10.0), 1000.0,
                        config.gyro.noise_seed)
    _, _, rate, _ = run(el, sim, 0.0, [BLOCK] * 3)
    assert np.array_equal(rate, bank.samples(0, rate.size))


def test_bandwidth_is_the_sense_pole_with_the_filter():
    config, sim, amplitude = make()
    el = SenseElectronics(config, sim, amplitude, 0.0)
    # f_s / (2 Q_s) (E9); the 100 Hz Butterworth changes it by ~(0.12 / 100)^8
    assert el.bandwidth_hz == pytest.approx(15800.0 / (2.0 * 64700.0), rel=1e-9, abs=0)
    # with a low Q the filter counts: then solve the product again here
    config, sim, amplitude = make(**{'modes.quality_factors': [120000.0, 300.0, 170000.0],
                                     'gyro.filter_bandwidth': 30.0})
    el = SenseElectronics(config, sim, amplitude, 0.0)
    f_m = 15800.0 / 600.0
    f = np.linspace(1.0, 30.0, 300_001)
    _, h = signal.sosfreqz(el._sos, worN=f, fs=config.run.output_rate)
    power = np.abs(h) ** 2 / (1.0 + (f / f_m) ** 2)
    expect = f[np.argmin(np.abs(power - 0.5))]
    assert el.bandwidth_hz == pytest.approx(expect, abs=2e-4)
    assert el.bandwidth_hz < min(f_m, 30.0)


def test_thermomechanical_arw_formula():
    config, sim, amplitude = make(**{'gyro.input_noise_density': 0.0})
    el = SenseElectronics(config, sim, amplitude, 0.0)
    total, thermo, n_el = el.predicted_arw()
    m = config.modal_masses()[el.sense_index]
    w = 2.0 * math.pi * 15800.0
    # (E10) at match
    expect = math.sqrt(BOLTZMANN * 300.0 / (m * w * 64700.0)) / (0.8 * amplitude)
    assert thermo == pytest.approx(expect, rel=1e-12, abs=0)
    assert n_el == 0.0 and total == thermo
    assert el.predicted_arw_deg_per_sqrt_h() == pytest.approx(
        math.degrees(thermo) * 60.0, rel=1e-12, abs=0)


def test_diagnostics_and_the_collapsed_drive():
    config, sim, amplitude = make(**{'gyro.input_noise_density': 0.0})
    el = SenseElectronics(config, sim, amplitude, 0.0)
    values = el.diagnostics_values()
    assert values['scale_factor_valid'] is True
    assert values['drive_amplitude_ratio'] == pytest.approx(1.0, abs=1e-12)
    expected_keys = {'rate_scale_factor_v_per_rad_s', 'rate_quadrature_rad_s', 'drive_pickoff_v',
                     'drive_pickoff_nominal_v', 'drive_amplitude_ratio', 'scale_factor_valid',
                     'noise_seed', 'input_noise_density_v_per_sqrt_hz', 'temperature_k',
                     'bias_instability_deg_per_h', 'predicted_arw_deg_per_sqrt_h',
                     'bandwidth_hz', 'drive_amplitude_ratio_expected', 'rate_range_rad_s',
                     'rate_resolution_rad_s', 'rate_saturated_samples'}
    assert set(values) == expected_keys
    assert values['drive_amplitude_ratio_expected'] == pytest.approx(1.0, abs=1e-12)
    run(el, sim, amplitude, [20 * BLOCK], b=0.5 * RATE * el.mechanical_scale_factor)
    values = el.diagnostics_values()
    assert values['scale_factor_valid'] is True
    assert values['rate_quadrature_rad_s'] == pytest.approx(0.5 * RATE, rel=1e-4, abs=0)
    # the drive falls to a tenth (the paper's Case 3 lower branch): the scale factor is void
    el = SenseElectronics(config, sim, amplitude, 0.0)
    run(el, sim, 0.1 * amplitude, [20 * BLOCK])
    values = el.diagnostics_values()
    assert values['drive_amplitude_ratio'] == pytest.approx(0.1, rel=1e-4, abs=0)
    assert values['scale_factor_valid'] is False


def test_no_drive_no_scale_factor():
    config, sim, _ = make()
    el = SenseElectronics(config, sim, 0.0, 0.0)
    assert el.scale_factor == 0.0 and not el.has_scale_factor
    _, _, rate, quad = run(el, sim, 0.0, [BLOCK])
    assert not np.any(rate) and not np.any(quad)
    assert el.diagnostics_values()['scale_factor_valid'] is False
    assert math.isinf(el.predicted_arw()[0])


def test_bad_inputs_name_the_argument():
    config, sim, amplitude = make()
    el = SenseElectronics(config, sim, amplitude, 0.0)
    t, cap, phi = trajectory(sim, el, amplitude, 0, 10)
    bad_cap = cap.copy()
    bad_cap[3, 2] = math.nan
    cases = [
        ((-1, t, cap, phi), 'first_index'), ((1.0, t, cap, phi), 'first_index'),
        ((0, t[:, None], cap, phi), 't'), ((0, t, cap[:, :4], phi), 'capacitance'),
        ((0, t, bad_cap, phi), 'capacitance'), ((0, t, cap, phi[:5]), 'drive_phase'),
        ((0, t, cap, np.full(10, math.inf)), 'drive_phase'),
        ((0, t, cap, 'abc'), 'drive_phase'),
    ]
    for args, name in cases:
        with pytest.raises(InputError, match=f'^{name}: '):
            el.process(*args)
    el.process(0, t, cap, phi)
    with pytest.raises(InputError, match='^first_index: .* continue at sample 10'):
        el.process(20, t, cap, phi)
    with pytest.raises(InputError, match='^drive_amplitude_m: '):
        SenseElectronics(config, sim, math.nan, 0.0)
    plain = paper_config({'modes.companions': False})
    with pytest.raises(InputError, match='^config: '):
        SenseElectronics(plain, Simulator(plain), amplitude, 0.0)


def test_the_periodic_state_of_the_low_pass_is_where_sosfilt_settles():
    # (S14's restart of the demodulator) the state of the E3 Butterworth under a constant
    # plus a 2 omega product, in closed form, against sosfilt run from rest until its
    # transient has died (~250 time constants of its slowest pole): each section's state to
    # 1e-10 of its size (measured 3e-12). The 2 omega product's part is 2.3e-5 of the first
    # section's state, which the filter's near-unit poles turn into a 1.2e-3 transient of
    # its output if it is left out.
    from ring_gyro_sim.core.gyro.electronics import _periodic_state
    from scipy import signal
    sos = signal.butter(4, 100.0, fs=200000.0, output='sos')
    theta = 2.0 * 2.0 * np.pi * 15800.0 / 200000.0
    n = np.arange(200000)
    dc, ripple = 0.3, 0.7 * np.exp(0.4j)
    x = dc + (ripple * np.exp(1j * theta * n)).real
    _, zf = signal.sosfilt(sos, x, zi=np.zeros((sos.shape[0], 2)))
    expected = (_periodic_state(sos, dc, 0.0).real
                + _periodic_state(sos, ripple * np.exp(1j * theta * n.size), theta).real)
    size = np.max(np.abs(zf), axis=1, keepdims=True)
    assert np.all(np.abs(zf - expected) < 1e-10 * size)
    constant_only = _periodic_state(sos, dc, 0.0).real
    assert np.max(np.abs(zf - constant_only)[0]) > 1e-6 * size[0, 0]
    # at theta = 0 it is sosfilt_zi's steady state (a linear solve: to 1e-9)
    assert np.allclose(_periodic_state(sos, 2.0, 0.0).real, 2.0 * signal.sosfilt_zi(sos),
                       rtol=1e-9, atol=0.0)
