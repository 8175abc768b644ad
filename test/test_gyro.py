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
The gyroscope end to end: ``Run``, ``ring_gyro run`` and ``ring_gyro rate``.

The rate output against the applied rate, its bandwidth, its noise against the prediction
from the noise sources, the shock figures and the collapse of the scale factor (the node:
``test/ros/test_node_gyro.py``).
"""

import json
import math
from pathlib import Path
import warnings

import allantools
import numpy as np
import pytest
from ring_gyro_sim import cli
from ring_gyro_sim.core.gyro.validity import NOT_MEASURED_VARIANCE
from ring_gyro_sim.core.params import build_config, paper_config, STANDARD_GRAVITY
from ring_gyro_sim.paramfile import check_params_file
from ring_gyro_sim.rate_record import applied_rate
from ring_gyro_sim.ros.conversions import rate_messages
from ring_gyro_sim.run import AngularRate, Run
from scipy import signal
import yaml

REPO = Path(__file__).resolve().parents[1]
TEN_DEG_S = math.radians(10.0)  # 0.174533 rad/s, the gyroscope's test rate


def gyro_values(**extra):
    """config/gyro.yaml (the gyroscope's operating point) with changes."""
    values = check_params_file(str(REPO / 'config' / 'gyro.yaml'))
    values.update(extra)
    return values


def run_blocks(config, seconds, state='orbit', inputs=()):
    """Run ``config`` in its blocks; return (t, rate, applied, run)."""
    assert state == 'orbit' or config.drive.start_on == 'rest'
    run = Run(config)
    for event in inputs:
        run.apply(event)
    t, rate, applied = [], [], []
    block = config.run.block_samples
    for _ in range(int(round(seconds / (block * config.run.output_period_ns * 1e-9)))):
        b = run.advance(block)
        t.append(b.rate.t)
        rate.append(b.rate.rate)
        at = np.searchsorted(b.samples.t, b.rate.t)
        applied.append(b.samples.applied_rate[at])
    return np.concatenate(t), np.concatenate(rate), np.concatenate(applied), run


def write_params(path, values):
    nested = {}
    for name, value in values.items():
        node = nested
        parts = name.split('.')
        for part in parts[:-1]:
            node = node.setdefault(part, {})
        node[parts[-1]] = value
    path.write_text(yaml.safe_dump({'ring_gyro': {'ros__parameters': nested}}))
    return path


def test_ring_gyro_run_measures_10_deg_s_within_1_percent(tmp_path, capsys):
    # The 1 % check through the command line users run, the recording and `ring_gyro
    # rate` (which rebuilds the applied rate from the recording alone).
    rec = tmp_path / 'gyro.mcap'
    assert cli.main(['run', str(REPO / 'config' / 'gyro.yaml'), '--duration', '1.5', '--json',
                     '--no-progress', '-o', str(rec)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary['rate_true_mean_rad_s'] == pytest.approx(TEN_DEG_S, rel=1e-12)
    assert summary['rate_mean_rad_s'] == pytest.approx(TEN_DEG_S, rel=0.01)
    assert summary['rate_scale_factor_valid'] is True
    assert 'rate_error_peak_rad_s' not in summary  # no shock
    assert cli.main(['rate', str(rec), '--out', str(tmp_path / 'plot')]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report['samples'] == 1500
    assert report['rate_mean_rad_s'] == pytest.approx(summary['rate_mean_rad_s'], rel=1e-12)
    assert (tmp_path / 'plot' / 'rate.csv').exists()
    if any(f.endswith('.png') for f in report['files']):
        assert (tmp_path / 'plot' / 'rate.png').stat().st_size > 10_000


def test_minus_10_deg_s_reads_the_opposite_sign():
    config = paper_config(gyro_values(**{'scenario.rate_values': [-TEN_DEG_S],
                                         'gyro.temperature': 0.0}))
    t, rate, applied, _ = run_blocks(config, 0.5)
    assert np.all(applied == -TEN_DEG_S)
    assert np.mean(rate[t > 0.1]) == pytest.approx(-TEN_DEG_S, rel=0.01)


def test_a_rate_step_shows_the_documented_bandwidth():
    # A step from 0 to 10 deg/s at 0.2 s streamed on ~/angular_rate, no noise: the output
    # rises as the first-order low-pass of the sense mode's half-power pole f_s / (2 Q_s)
    # (electronics E9: bandwidth_hz, the Butterworth adds 1e-6). After one time constant
    # 1 - 1/e of the step, after two 1 - 1/e^2, within 2 % of the step (the 2theta pair
    # split by 2 kappa Omega = 0.28 rad/s against its 0.77 rad/s half-width bends the curve
    # a little).
    config = paper_config(gyro_values(**{'scenario.rate_times': [], 'scenario.rate_values': [],
                                         'gyro.temperature': 0.0,
                                         'gyro.input_noise_density': 0.0}))
    t_step = 0.2
    bandwidth_hz = Run(config).full_model().sense.electronics.bandwidth_hz
    tau = 1.0 / (2.0 * math.pi * bandwidth_hz)
    assert bandwidth_hz == pytest.approx(15800.0 / (2 * 64700.0), rel=1e-4)
    t, rate, applied, run = run_blocks(
        config, t_step + 2.2 * tau,
        inputs=[AngularRate(z=TEN_DEG_S, at_ns=int(t_step * 1e9))])
    assert np.all(applied[t < t_step] == 0.0) and np.all(applied[t > t_step] == TEN_DEG_S)
    for k in (1.0, 2.0):
        at = np.searchsorted(t, t_step + k * tau)
        rise = rate[at] / TEN_DEG_S
        print(f'after {k:g} tau = {k * tau:.3f} s: {rise:.4f} of the step '
              f'(first order: {1 - math.exp(-k):.4f})')
        assert rise == pytest.approx(1.0 - math.exp(-k), abs=0.02)


def predicted_allan_deviation(el, taus):
    """
    Allan deviation of the rate output predicted from the noise sources, rad/s.

    White rate-equivalent noise of one-sided density 2 N^2 (the electronics' predicted_arw:
    the thermomechanical part through the sense mode's first-order pole f_s / (2 Q_s), the
    pick-off's through the Butterworth only; both through the Butterworth), and
    sigma^2(tau) = 2 int S(f) |H(f)|^2 sin^4(pi f tau) / (pi f tau)^2 df (IEEE 952).
    """
    _, n_th, n_el = el.predicted_arw()
    f = np.geomspace(1e-4, 0.5 * el.config.gyro.output_rate, 200_000)
    _, hb = signal.sosfreqz(el._sos, worN=f, fs=el.sample_rate_hz)
    pole = el.sense_omega / (2.0 * el.sense_quality_factor) / (2.0 * math.pi)
    path = np.abs(hb) ** 2 * (2.0 * n_th ** 2 / (1.0 + (f / pole) ** 2) + 2.0 * n_el ** 2)
    out = []
    for tau in taus:
        x = np.pi * f * tau
        out.append(math.sqrt(2.0 * np.trapezoid(path * np.sin(x) ** 4 / x ** 2, f)))
    return np.array(out)


def test_angle_random_walk_matches_the_noise_sources():
    # Zero rate, every noise on, the 2theta pair at Q = 500 so that the sense mode's pole
    # (2 Q / omega = 10 ms) is short against the Allan times used; N_R = 2 (the 3theta mode
    # does not enter the rate). 30 s of record: the overlapping estimator's standard error
    # is ~2.4 / 3.3 / 4.7 % of the deviation at 0.05 / 0.1 / 0.2 s (edf ~ 3 N / (2 m)), so
    # the 10 % check is made where it is >= 3 standard errors: 0.05 and 0.1 s
    # (at 0.2 s this seed gives -10.7 %, 2.3 standard errors; 60 s of seed 6 gave 0.99,
    # 0.976, 1.011, 1.053, 1.071 of the prediction at 0.05, 0.1, 0.2, 0.5, 1 s). The filters'
    # share is in the prediction (30 % of the variance at 0.05 s); at 5 s it is N / sqrt(tau).
    values = gyro_values(**{'modes.frequencies': [11200.0, 15800.0],
                            'modes.quality_factors': [120000.0, 500.0],
                            'scenario.rate_times': [], 'scenario.rate_values': [],
                            'drive.start_on': 'rest', 'gyro.noise_seed': 5})
    config = paper_config(values)
    # Start on the drive's linear response (rest would need ~10 time constants to build up).
    w = 2 * math.pi * config.drive.frequency
    w2 = 2 * math.pi * config.modes.frequencies[1]
    c = config.drive.amplitude / complex(w2 * w2 - w * w, w * w2 / 500.0)
    q = np.zeros(4)
    v = np.zeros(4)
    q[1], v[1] = c.real, (1j * w * c).real
    run = Run(config, start_state=(q, v))
    el = run.full_model().sense.electronics
    n_total, n_thermo, n_el = el.predicted_arw()
    rate = []
    for _ in range(3000):
        rate.append(run.advance(config.run.block_samples).rate.rate)
    rate = np.concatenate(rate)[100:]  # after 0.1 s (10 time constants of the pole)
    taus = np.array([0.05, 0.1])
    expected = predicted_allan_deviation(el, taus)
    long = predicted_allan_deviation(el, [5.0])[0]
    assert long * math.sqrt(5.0) == pytest.approx(n_total, rel=2e-3)
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')
        got_taus, adev, _, _ = allantools.oadev(rate, rate=config.gyro.output_rate,
                                                data_type='freq', taus=taus)
    assert np.allclose(got_taus, taus)
    print(f'ARW predicted {n_total:.4e} rad/sqrt(s) (thermomechanical {n_thermo:.4e}, '
          f'pick-off {n_el:.2e}); Allan deviation / predicted at {taus} s: '
          f'{np.round(adev / expected, 4)}')
    np.testing.assert_allclose(adev, expected, rtol=0.1)


def test_same_seed_same_record_other_seed_other_record_bit_for_bit():
    base = gyro_values(**{'gyro.bias_instability': 1.0})
    a = run_blocks(paper_config(base), 0.05)[1]
    b = run_blocks(paper_config(base), 0.05)[1]
    c = run_blocks(paper_config({**base, 'gyro.noise_seed': 2}), 0.05)[1]
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    # and the record does not depend on how it is cut into blocks
    cut = paper_config({**base, 'output.block_duration': 0.003})
    d = run_blocks(cut, 0.051)[1][:a.size]
    assert np.array_equal(a, d)


def test_shock_figures_and_recovery():
    # Fast modes (Q = 2 000 for 1theta and 2theta: the rigid mode rings for Q / (pi f) =
    # 57 ms, the sense mode's time constant is 40 ms; the drive raised by 64 700 / 2 000 to
    # keep q2 = 0.04 um) so that the recovery fits in a short run: a 10 000 g shock along x
    # at 0.1 s during 10 deg/s. The error has a peak and returns within 1 % of the rate; the
    # figures say when. (With the default Q the rigid mode rings for seconds and detunes the
    # drive through the electrostatic coupling: doc/gyroscope.md.)
    values = gyro_values(**{'modes.quality_factors': [2000.0, 2000.0, 170000.0],
                            'drive.amplitude': 0.0065 * 64700.0 / 2000.0,
                            'scenario.shock_times': [0.1],
                            'scenario.shock_peaks': [10_000 * STANDARD_GRAVITY]})
    config = paper_config(values)
    t, rate, applied, run = run_blocks(config, 0.8)
    figures = run.gyro_figures()
    err = np.abs(rate - applied)
    assert figures['rate_error_peak_rad_s'] == pytest.approx(np.max(err[t >= 0.1]), rel=1e-12)
    assert figures['rate_error_peak_rad_s'] > 0.01 * TEN_DEG_S  # the shock is seen
    assert figures['rate_recovered'] is True
    rec = figures['rate_recovery_s']
    band = np.maximum(0.01 * TEN_DEG_S, 4.0 * run.rate_stats.noise_sigma)
    # the last sample outside the band is at 0.1 + rec (to round-off: half a rate period)
    half = 0.5 / config.gyro.output_rate
    last = np.searchsorted(t, 0.1 + rec - half)
    assert abs(t[last] - (0.1 + rec)) < 1e-9 and err[last] > band
    after = t > t[last]
    assert 0.0 < rec < 0.6
    assert np.all(err[after] <= band)  # inside the band from then on


def test_the_paper_case_3_collapses_the_scale_factor_and_says_so():
    # The paper's Case 3 settings (drive 0.065 m/s^2 at 15 798.6 Hz on its upper branch,
    # Q_1 = 40 000, 10 000 g) with the gyroscope: the drive falls, the pick-off drops far
    # below its operating point, and the diagnostics and the figures say the rate output is
    # not a measurement.
    values = {'modes.companions': True, 'gyro.enabled': True,
              'modes.quality_factors': [40000.0, 64700.0, 170000.0],
              'scenario.shock_times': [0.05], 'scenario.shock_peaks': [10_000 * STANDARD_GRAVITY],
              'scenario.rate_times': [0.0], 'scenario.rate_values': [TEN_DEG_S]}
    config = paper_config(values)
    with warnings.catch_warnings():
        warnings.simplefilter('ignore')  # the upper branch's companion instability
        run = Run(config)
    for _ in range(5):
        run.advance(config.run.block_samples)
    assert run.diagnostics().level == 'OK'
    for _ in range(25):
        run.advance(config.run.block_samples)
    diag = run.diagnostics()
    assert diag.level == 'WARN' and '~/rate is not a measurement' in diag.message
    assert diag.values['scale_factor_valid'] is False
    assert diag.values['drive_amplitude_ratio'] < 0.2
    figures = run.gyro_figures()
    assert figures['rate_scale_factor_valid'] is False


def test_applied_rate_rebuilt_from_inputs_matches_the_simulator():
    config = paper_config(gyro_values(**{'scenario.rate_times': [0.0, 0.02, 0.02, 0.03],
                                         'scenario.rate_values': [0.0, 1.0, -1.0, 2.0],
                                         'gyro.temperature': 0.0}))
    step = AngularRate(z=0.5, at_ns=25_000_123)
    t, _, applied, run = run_blocks(config, 0.04, inputs=[step])
    # the knots come with the configuration, the streamed step as an input (load_recording)
    rebuilt = applied_rate(config, [step], np.round(t * 1e9).astype(np.int64))
    assert np.array_equal(rebuilt, applied)
    assert applied[np.searchsorted(t, 0.0251)] == 0.5 and applied[0] == pytest.approx(0.05)


def test_a_constant_rate_from_the_start_keeps_a_valid_scale_factor():
    # 100 deg/s from t = 0, open loop: the start state already holds the drive's drop under
    # the rate (the pair splits), so the drive pick-off's expected ratio is 1 at that rate.
    # Counting the drop twice gave (1 + x^2) / (1 + 2 x^2) = 0.566 and a false "scale factor
    # collapsed" while the reading was within 0.2 %. The model's readout (ideal) reads at
    # the operating point's own scale factor.
    rate = math.radians(100.0)
    values = gyro_values(**{'scenario.rate_values': [rate], 'gyro.temperature': 0.0,
                            'gyro.input_noise_density': 0.0})
    config = paper_config({**values, 'gyro.calibration.source': 'ideal'})
    t, out, applied, run = run_blocks(config, 0.3)
    diag = run.diagnostics().values
    assert diag['drive_amplitude_ratio_expected'] == pytest.approx(1.0, abs=1e-3)
    assert diag['drive_amplitude_ratio'] == pytest.approx(1.0, abs=0.01)
    assert diag['scale_factor_valid'] is True and diag['rate_valid'] is True
    assert np.mean(out[t > 0.1]) == pytest.approx(rate, rel=0.005)
    # The factory's calibration, made at +-10 deg/s on the undropped drive and relative to
    # its pick-off amplitude at zero rate (K1), reads the ratio as one: the drive 4.3 times
    # lower softens the sense mode less (E6b), 0.5 % of scale-factor nonlinearity.
    t, out, applied, run = run_blocks(paper_config(values), 0.3)
    diag = run.diagnostics().values
    assert diag['scale_factor_valid'] is True and diag['rate_valid'] is True
    assert np.mean(out[t > 0.1]) == pytest.approx(rate, rel=0.01)
    assert np.mean(out[t > 0.1]) != pytest.approx(rate, rel=0.002)


def test_the_rebalance_variance_is_the_loops_noise():
    # The published variance of ~/rate with force-to-rebalance integrates the noise through
    # the loop's closed-loop response (E14, control.rebalance_response). At a 50 Hz loop the
    # loop's delay shapes it most: one period (C1) predicts within 3.5 % of 10 s measured;
    # the 1.5 periods it used to count over-predicted by 28 %. 6 s here: about 720
    # independent samples over the band, 5 % standard error of the variance.
    config = paper_config(gyro_values(**{'control.mode': 'rebalance',
                                         'control.rebalance_bandwidth': 50.0,
                                         'scenario.rate_values': [0.0], 'gyro.noise_seed': 3,
                                         'drive.amplitude': 0.065,
                                         'drive.frequency': 15798.6}))
    t, out, _, run = run_blocks(config, 6.0)
    measured = float(np.var(out[t > 0.5]))
    predicted = run.full_model().sense.electronics.rate_variance()
    print(f'rebalance at 50 Hz: measured {measured:.4e}, predicted {predicted:.4e} (rad/s)^2, '
          f'ratio {predicted / measured:.3f}')
    assert predicted == pytest.approx(measured, rel=0.15)


THOUSAND_DEG_S = math.radians(1000.0)


def thousand_deg_s(seconds=0.5, **extra):
    """
    Run the defaults under a constant rate from t = 0, the rebalance force allowed 2 m/s^2.

    Return the rate output's times, rates, variances and saturation flags, and the run.
    1 000 deg/s asks the rebalance loop for 2 kappa omega X Omega = 1.09 m/s^2: at the default
    limit (``control.drive_limit``, 1 m/s^2) the loop itself tops out at 917 deg/s, with 2 it
    holds the rate and the output reads it (checked below), so what cuts it is the range.
    """
    values = {'scenario.rate_times': [0.0], 'scenario.rate_values': [THOUSAND_DEG_S],
              'control.drive_limit': 2.0, **extra}
    run = Run(build_config(values))
    parts = [run.advance(run.config.run.block_samples).rate
             for _ in range(int(round(seconds / run.config.run.block_duration)))]
    out = {name: np.concatenate([getattr(p, name) for p in parts])
           for name in ('t', 'rate', 'variance')}
    out['saturated'] = (np.concatenate([p.saturated for p in parts])
                        if parts[0].saturated is not None else None)
    return out, run


@pytest.fixture(scope='module')
def unlimited():
    return thousand_deg_s()


def test_1000_deg_s_into_a_300_deg_s_range_reads_300_deg_s_flagged(unlimited):
    # The output word saturates at gyro.range (E15), reads the full scale exactly,
    # and says that it is not a measurement (V1b): the covariance and /diagnostics.
    free, _ = unlimited
    assert free['saturated'] is None  # no range: nothing to saturate
    assert np.mean(free['rate'][free['t'] > 0.1]) == pytest.approx(THOUSAND_DEG_S, rel=1e-3)
    assert np.all(free['variance'] < 0.01)  # a measurement: sigma below 0.1 rad/s
    full_scale = math.radians(300.0)
    cut, run = thousand_deg_s(**{'gyro.range': full_scale})
    assert len(cut['rate']) == 500
    assert np.all(cut['rate'] == full_scale)
    assert np.all(cut['saturated'])
    assert np.all(cut['variance'] == NOT_MEASURED_VARIANCE)
    diag = run.diagnostics()
    assert diag.level == 'WARN' and 'saturated' in diag.message
    assert diag.values['rate_valid'] is False
    assert diag.values['rate_invalid_reason'] == 'saturated'
    assert diag.values['rate_saturated_samples'] == 500
    assert diag.values['rate_range_rad_s'] == full_scale
    # ~/rate: angular_velocity.z at the full scale, covariance zz that of no measurement
    block = run.advance(run.config.run.block_samples).rate
    messages = rate_messages(block, 'ring_gyro')
    assert len(messages) == 10
    for _, imu in messages:
        assert imu.angular_velocity.z == full_scale
        assert list(imu.angular_velocity_covariance) == [
            1e6, 0.0, 0.0, 0.0, 1e6, 0.0, 0.0, 0.0, NOT_MEASURED_VARIANCE]
    # the other sense: -1 000 deg/s reads -300 deg/s
    cut, run = thousand_deg_s(0.1, **{'scenario.rate_values': [-THOUSAND_DEG_S],
                                      'gyro.range': full_scale})
    assert np.all(cut['rate'] == -full_scale) and np.all(cut['saturated'])
    assert run.diagnostics().values['rate_saturated_samples'] == 100


def test_a_rebalance_force_at_its_limit_says_the_reading_is_not_the_rate(unlimited):
    # At the default control.drive_limit (1 m/s^2) the loop tops out at
    # 1 / (2 kappa omega X) = 917 deg/s (C8): 1 000 deg/s reads about 917 deg/s, which is not
    # the rate, and every sample says so; with the limit at 2 m/s^2 the same rate is a
    # measurement (the fixture), and so is 800 deg/s at the default limit.
    free, _ = unlimited
    assert np.all(free['variance'] < 0.01)
    held, run = thousand_deg_s(0.3, **{'control.drive_limit': 1.0})
    late = held['t'] > 0.1
    print(f'1 000 deg/s at the default limit reads {math.degrees(np.mean(held["rate"][late])):.1f}'
          f' deg/s')
    assert math.degrees(np.mean(held['rate'][late])) == pytest.approx(917.0, rel=0.01)
    assert np.all(held['variance'][late] == NOT_MEASURED_VARIANCE)
    assert run.diagnostics().values['rate_invalid_reason'] == 'rebalance force at its limit'
    below, run = thousand_deg_s(0.3, **{'control.drive_limit': 1.0,
                                        'scenario.rate_values': [math.radians(800.0)]})
    assert np.all(below['variance'][below['t'] > 0.1] < 0.01)
    assert math.degrees(np.mean(below['rate'][below['t'] > 0.1])) == pytest.approx(
        800.0, rel=1e-3)


def test_a_rate_within_the_range_is_read_bit_for_bit_as_without_it(unlimited):
    free, _ = unlimited
    within, run = thousand_deg_s(**{'gyro.range': math.radians(2000.0)})
    assert not within['saturated'].any()
    assert np.array_equal(within['rate'], free['rate'])
    assert np.array_equal(within['variance'], free['variance'])
    diag = run.diagnostics().values
    assert diag['rate_valid'] is True and diag['rate_saturated_samples'] == 0


def test_the_resolution_rounds_the_output_to_whole_lsb(unlimited):
    # 80 LSB per deg/s (ADXRS453's word): the output is a whole number of LSB (numpy.round,
    # half to even), its error against the unrounded output within +-LSB/2 and uniform
    # (standard deviation LSB / sqrt(12); the noise, 0.044 rad/s per sample, spans 200 LSB),
    # and the stated variance grows by LSB^2 / 12.
    free, free_run = unlimited
    lsb = math.radians(1.0 / 80.0)
    word, run = thousand_deg_s(**{'gyro.resolution': lsb})
    codes = word['rate'] / lsb
    assert np.max(np.abs(codes - np.round(codes))) < 1e-9
    assert np.array_equal(word['rate'], np.round(free['rate'] / lsb) * lsb)
    error = word['rate'] - free['rate']
    assert np.max(np.abs(error)) <= 0.5 * lsb * (1.0 + 1e-9)
    assert np.std(error) == pytest.approx(lsb / math.sqrt(12.0), rel=0.1)
    assert abs(np.mean(error)) < 0.1 * lsb
    added = (run.full_model().sense.validity.noise_variance
             - free_run.full_model().sense.validity.noise_variance)
    assert added == pytest.approx(lsb ** 2 / 12.0, rel=1e-9)
    diag = run.diagnostics().values
    assert diag['rate_resolution_rad_s'] == lsb and diag['rate_valid'] is True
