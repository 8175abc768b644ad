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
Tests of characterize.py (``ring_gyro characterize``): one ``--quick`` run shared by the module.

The datasheet of ``config/gyro.yaml`` against the model's predictions (the electronics of a
run at zero rate), with tolerances from the quick records' statistics; the analysis functions
against closed forms; and the refusals (non-gyro file, missing file, bad ``--loops``).
"""

import contextlib
from dataclasses import replace
import io
import json
import math
from pathlib import Path
import subprocess
import sys
import time

import numpy as np
import pytest
from ring_gyro_sim import characterize as ch
from ring_gyro_sim import cli
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.gyro import operating_point
from ring_gyro_sim.core.params import build_config, paper_config, STANDARD_GRAVITY
from ring_gyro_sim.run import Run
from scipy import signal

REPO_ROOT = Path(__file__).resolve().parents[1]
GYRO = REPO_ROOT / 'config' / 'gyro.yaml'
PNG_SIGNATURE = b'\x89PNG\r\n\x1a\n'
QUICK_STDERR = []
"""What the quick characterization wrote on stderr."""
SETTLE_PPM_FS = 150.0
"""Settling of the quick table's points (noise off, 0 - 0.5 s means: -207 / -387 ppm of the
reading at 300 / 100 deg/s, i.e. 69 / 129 ppm of full scale; doc/datasheet.md)."""


@pytest.fixture(scope='module')
def quick(tmp_path_factory):
    """
    One ``ring_gyro characterize config/gyro.yaml --quick --workers 2``: (exit code, stdout, DIR).

    On two worker processes, the default on a 2-core machine: their notes reach this
    process's stderr through the farm.
    """
    out = tmp_path_factory.mktemp('datasheet')
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        code = cli.main(['characterize', str(GYRO), '--out', str(out), '--quick',
                         '--no-progress', '--workers', '2'])
    QUICK_STDERR.append(stderr.getvalue())
    return code, stdout.getvalue(), out


@pytest.fixture(scope='module')
def sheet(quick):
    return json.loads((quick[2] / 'datasheet.json').read_text(encoding='utf-8'))


@pytest.fixture(scope='module')
def electronics():
    """Return the device's electronics at rest (zero rate): the model's predictions."""
    values = ch.load_device(str(GYRO))
    values = {k: v for k, v in values.items() if not k.startswith('scenario.')}
    config = paper_config(values)
    return Run(config).full_model().sense.electronics


def test_the_run_succeeds_and_prints_its_summary_last(quick, sheet):
    code, stdout, out = quick
    assert code == 0
    summary = json.loads(stdout.strip().splitlines()[-1])
    assert summary['quick'] is True
    assert summary['scale_factor_v_per_rad_s'] == sheet['scale_factor']
    assert summary['arw_deg_per_sqrt_h'] == sheet['arw_deg_per_sqrt_h']
    assert summary['shock_entries'] == len(sheet['shock'])
    # config/gyro.yaml is open loop: everything on the full model, no long record
    assert summary['drift_model'] == 'full' and summary['long_record_tau_max_s'] is None
    assert set(summary['files']) == {str(out / n) for n in (
        'datasheet.json', 'datasheet.md', 'allan.png', 'scale_factor.png', 'step.png',
        'shock_recovery.png', 'temperature.png')}


def test_it_says_when_it_computes_a_start_state(quick):
    # The start state takes seconds (~30 s for a new device): the user is told before
    notes = [line for line in QUICK_STDERR[0].splitlines()
             if line.startswith('characterize: computing the start state (upper_branch')]
    assert notes, QUICK_STDERR[0]


def test_the_datasheet_has_the_figures_and_the_predictions(sheet):
    for key in ('scale_factor', 'scale_factor_nonlinearity_ppm', 'bias_deg_per_h',
                'arw_deg_per_sqrt_h', 'bias_instability_deg_per_h', 'bandwidth_hz'):
        assert isinstance(sheet[key], float) and math.isfinite(sheet[key]), key
    assert sheet['scale_factor_unit'] == 'V/(rad/s)'
    assert isinstance(sheet['shock'], list) and sheet['shock']
    for key in ('scale_factor', 'arw_deg_per_sqrt_h', 'bandwidth_hz'):
        assert math.isfinite(sheet['predicted'][key]), key
    assert sheet['predicted']['scale_factor_unit'] == 'V/(rad/s)'
    assert sheet['arw_fit']['tau_s'][0] == pytest.approx(0.01)


def test_the_predictions_are_the_electronics_at_rest(sheet, electronics):
    p = sheet['predicted']
    assert p['scale_factor'] == pytest.approx(electronics.scale_factor, rel=1e-12)
    assert p['arw_deg_per_sqrt_h'] == pytest.approx(electronics.predicted_arw_deg_per_sqrt_h(),
                                                    rel=1e-12)
    assert p['bandwidth_hz'] == pytest.approx(electronics.bandwidth_hz, rel=1e-12)


def test_the_scale_factor_is_the_predicted_one_within_1_percent(sheet):
    # The table slope is 0.6 % above the small-signal value: at 100-300 deg/s the drive
    # amplitude has fallen (open loop), and with it the electrostatic softening of the sense
    # mode (E6b); the model's own table predicts that slope to 0.01 % (doc/datasheet.md).
    assert sheet['scale_factor'] == pytest.approx(sheet['predicted']['scale_factor'],
                                                  rel=0.01)
    assert sheet['agreement']['scale_factor_table'] == pytest.approx(0.0, abs=1e-3)
    assert sheet['scale_factor_relative'] == pytest.approx(
        sheet['scale_factor'] / sheet['predicted']['scale_factor'], rel=1e-12)


def surrogate_arw_ratios(n_th, n_el, time_constant_s, rate_hz, record_s, skip_s, count,
                         seed=7):
    """
    ARW estimates / truth of :func:`characterize.allan_fit` on simulated noise records.

    The rate noise of the device (doc/gyroscope.md): white thermomechanical rate noise of
    ARW ``n_th`` through the sense pole (first-order, ``time_constant_s``, started at 0 as
    the ring starts at rest) plus the pick-off's white ``n_el``; the record from ``skip_s``
    on, as the characterization takes it.
    """
    rng = np.random.default_rng(seed)
    rho = math.exp(-1.0 / (rate_hz * time_constant_s))
    n = int(round(record_s * rate_hz))
    skip = int(round(skip_s * rate_hz))
    sigma = n_th / math.sqrt(2.0 * time_constant_s) * math.sqrt(1.0 - rho * rho)
    truth = math.hypot(n_th, n_el)
    out = []
    for _ in range(count):
        x = signal.lfilter([1.0], [1.0, -rho], rng.standard_normal(n) * sigma)[skip:]
        x = x + rng.standard_normal(n - skip) * n_el * math.sqrt(rate_hz)
        fit = ch.allan_fit(x, rate_hz, time_constant_s, ('correlated', 'white'), 0.01)
        out.append(fit['arw_rad_sqrt_s'] / truth)
    return np.array(out)


def test_the_arw_is_the_predicted_one_within_the_quick_records_noise(sheet, electronics):
    # The tolerance is the spread of the same estimator on 300 records of the predicted
    # noise with the quick record's length and start (6 s after 2 s): ~6 % (1 sigma) with
    # a bias of ~-2 %; 3 sigma around that bias. With FULL's 300 s the spread is ~1 %.
    _, n_th, n_el = electronics.predicted_arw()
    tc = 1.0 / (2.0 * math.pi * electronics.bandwidth_hz)
    plan = ch.QUICK
    ratios = surrogate_arw_ratios(n_th, n_el, tc, electronics.config.gyro.output_rate,
                                  plan.zero_rate_s, plan.zero_rate_skip_s, 300)
    bias, spread = float(np.mean(ratios)) - 1.0, float(np.std(ratios, ddof=1))
    got = sheet['arw_deg_per_sqrt_h'] / sheet['predicted']['arw_deg_per_sqrt_h'] - 1.0
    print(f'ARW measured / predicted - 1 = {got:+.4f}; the quick estimator: bias '
          f'{bias:+.4f}, spread {spread:.4f} (bootstrap of the datasheet: '
          f'{sheet["arw_relative_standard_error"]:.4f})')
    assert 0.02 < spread < 0.15  # the tolerance is the quick record's, not a loose one
    assert abs(got - bias) <= 3.0 * spread
    # The datasheet's own standard error (a bootstrap of its fitted model) agrees with it.
    assert sheet['arw_relative_standard_error'] == pytest.approx(spread, rel=0.3)


def test_the_bandwidth_is_the_sense_pole(sheet):
    # A 10 deg/s step: the rate splits the pair by 2 kappa Omega = 0.28 rad/s against its
    # 0.77 rad/s half-width, which bends the first-order curve by up to 2 % (test_gyro.py);
    # the noise (0.004 deg/s) is 4e-4 of the step.
    assert sheet['bandwidth_hz'] == pytest.approx(sheet['predicted']['bandwidth_hz'], rel=0.03)
    assert sheet['step']['gain'] == pytest.approx(1.0, abs=0.03)


def test_the_nonlinearity_is_small_at_the_default_drive(sheet):
    # The model: 6 ppm of full scale over this table. Measured on 0.4 s means: the points'
    # settling (SETTLE_PPM_FS) and their noise, which grows as the drive amplitude falls
    # with the rate (x 30 at 300 deg/s: hundreds of ppm); 3 standard errors of the worst.
    worst = max(r['standard_error_ppm_fs'] for r in sheet['rate_table'])
    bound = sheet['predicted']['scale_factor_nonlinearity_ppm'] + SETTLE_PPM_FS + 3.0 * worst
    print(f'nonlinearity {sheet["scale_factor_nonlinearity_ppm"]:.0f} ppm FS, bound '
          f'{bound:.0f} (worst standard error {worst:.0f})')
    assert sheet['scale_factor_nonlinearity_ppm'] <= bound
    assert bound < 5000.0  # "small": below 0.5 % of full scale even with the quick's noise
    assert [r['rate_deg_per_s'] for r in sheet['rate_table']] == list(
        ch.QUICK.rate_points_dps)
    for r in sheet['rate_table']:
        assert r['output_deg_per_s'] == pytest.approx(r['rate_deg_per_s'], abs=0.02 * 300.0)


def test_one_shock_entry_per_amplitude_and_loop_mode(sheet):
    loops = ch.available_loops()
    assert sheet['loops'] == list(loops)
    assert sorted((s['peak_g'], s['loop']) for s in sheet['shock']) == sorted(
        (g, loop) for g in ch.QUICK.shock_peaks_g for loop in loops)
    for s in sheet['shock']:
        assert isinstance(s['peak_rate_error_deg_per_s'], float)
        assert s['recovery_s'] is None or s['recovery_s'] >= 0.0
        assert isinstance(s['jumped'], bool)
        assert isinstance(s['contact'], bool) and not s['contact']  # 10 000 g: 3.4 um gap
        assert s['min_gap_um'] > 0.0
        if s['loop'] == 'open':
            assert s['lost_lock'] is None  # no loop to lose
        else:
            assert isinstance(s['lost_lock'], bool)
    for loop in loops:
        by_g = {s['peak_g']: s for s in sheet['shock'] if s['loop'] == loop}
        # A larger shock detunes the drive more (q1 is 10 times larger): a larger error.
        assert (by_g[10000.0]['peak_rate_error_deg_per_s']
                > by_g[1000.0]['peak_rate_error_deg_per_s'])
        assert by_g[10000.0]['peak_rate_error_deg_per_s'] > 1.0  # the shock is seen


def test_the_pngs_are_written_and_embedded(quick):
    out = quick[2]
    text = (out / 'datasheet.md').read_text(encoding='utf-8')
    for name in ('allan.png', 'scale_factor.png', 'step.png', 'shock_recovery.png'):
        data = (out / name).read_bytes()
        assert data[:8] == PNG_SIGNATURE and len(data) > 10_000, name
        assert f']({name})' in text
    assert '| scale factor |' in text and '| angle random walk |' in text


@pytest.mark.ci
def test_the_datasheet_is_the_same_on_one_process_as_on_two(sheet, tmp_path):
    # Every piece the farm runs depends on no other and seeds from the file: in this process,
    # one after the other, the tests give the same datasheet, number for number.
    assert sheet['workers'] == 2
    operating_point._MEMO.clear()  # as a fresh process: the start states are computed here
    ch.characterize(str(GYRO), str(tmp_path), quick=True, progress=False, workers=1)
    one = json.loads((tmp_path / 'datasheet.json').read_text(encoding='utf-8'))
    assert one['workers'] == 1
    timing = ('wall_time_s', 'cpu_time_s', 'workers')
    assert ({k: v for k, v in one.items() if k not in timing}
            == {k: v for k, v in sheet.items() if k not in timing})
    # the workers' CPU time is counted: as much work as in one process (20.8 s there, 23.3 s
    # on two; the parent alone does a few seconds of it), whatever the host's load
    assert sheet['cpu_time_s'] > 0.5 * one['cpu_time_s']


def _fails_on_purpose(bar):
    """Report as a piece of a characterization does, then fail."""
    bar.note('a note from a worker')
    bar.update(0.5, 'halfway')
    bar.finish_run(1.0)
    raise ParameterError('scenario.shock_peaks: refused on purpose')


def _interrupted(bar):
    raise KeyboardInterrupt


def test_a_piece_interrupted_in_this_process_stops_the_characterization():
    # one worker: the pieces run in order here, and Ctrl-C in one ends them all
    farm = ch._Farm(ch._Bar(1.0, False), 1)
    with pytest.raises(KeyboardInterrupt):
        farm.submit(_interrupted)


@pytest.mark.parametrize('workers', [1, 2])
def test_a_piece_that_fails_raises_its_error_here(capsys, workers):
    bar = ch._Bar(2.0, False)
    farm = ch._Farm(bar, workers)
    try:
        with pytest.raises(ParameterError, match='scenario.shock_peaks: refused on purpose'):
            farm.result(farm.submit(_fails_on_purpose))
    finally:
        farm.close()
    # what the piece reported reached this process's bar (from a worker by the end: the
    # queue's order against the result's is not kept)
    assert bar.runs == 1 and bar.done_s == 1.0 and not bar.running
    assert 'characterize: a note from a worker' in capsys.readouterr().err


def _sleeps(bar):
    time.sleep(120.0)


def test_a_failed_characterization_ends_its_workers_at_once():
    # a piece fails while another has minutes to go: the workers end now, not after it
    farm = ch._Farm(ch._Bar(1.0, False), 2)
    try:
        farm.submit(_sleeps)
        with pytest.raises(ParameterError, match='refused on purpose'):
            farm.result(farm.submit(_fails_on_purpose))
    finally:
        start = time.monotonic()
        farm.close(abort=True)
    assert time.monotonic() - start < 30.0  # (the sleeping piece had 120 s left)


@pytest.mark.parametrize('workers', ['0', '-1'])
def test_a_bad_worker_count_is_refused_naming_the_option(tmp_path, capsys, workers):
    code = cli.main(['characterize', str(GYRO), '--out', str(tmp_path / 'x'), '--workers',
                     workers, '--no-progress'])
    assert code == 1
    assert '--workers: give a whole number of processes >= 1' in capsys.readouterr().err
    assert not (tmp_path / 'x').exists()


def test_a_resonator_file_is_refused_naming_gyro_enabled(tmp_path, capsys):
    code = cli.main(['characterize', str(REPO_ROOT / 'config' / 'paper.yaml'), '--out',
                     str(tmp_path / 'x'), '--quick', '--no-progress'])
    assert code == 1
    err = capsys.readouterr().err
    assert 'ring_gyro characterize: error:' in err and 'gyro.enabled' in err
    assert not (tmp_path / 'x').exists()


def test_a_missing_file_is_refused_naming_it(tmp_path, capsys):
    missing = tmp_path / 'nope.yaml'
    code = cli.main(['characterize', str(missing), '--out', str(tmp_path / 'x')])
    assert code == 1
    err = capsys.readouterr().err
    assert str(missing) in err and 'No such file' in err


def test_a_bad_loop_mode_is_refused_naming_the_option(tmp_path, capsys):
    code = cli.main(['characterize', str(GYRO), '--out', str(tmp_path / 'x'), '--loops',
                     'open,sideways'])
    assert code == 1
    assert "--loops: unknown loop mode 'sideways'" in capsys.readouterr().err


def test_the_exit_status_of_the_command_is_1_on_a_bad_file(tmp_path):
    result = subprocess.run([sys.executable, '-m', 'ring_gyro_sim.cli', 'characterize',
                             str(REPO_ROOT / 'config' / 'paper.yaml'), '--out',
                             str(tmp_path / 'x')], capture_output=True, text=True,
                            timeout=120, check=False, cwd=REPO_ROOT)
    assert result.returncode == 1
    assert 'gyro.enabled' in result.stderr and result.stdout == ''


# ----------------------------------------------------------------------------- the analyses
def test_the_first_order_allan_variance_has_its_limits():
    tc = 1.3
    long = np.array([1e3, 1e4]) * tc
    assert np.allclose(ch.lp1_allan_variance(long, tc) * long, 1.0 - 1.5 * tc / long,
                       rtol=1e-9)
    short = np.array([1e-4, 1e-3]) * tc
    assert np.allclose(ch.lp1_allan_variance(short, tc), short / (3.0 * tc * tc), rtol=2e-3)


def test_the_line_fit_reads_a_known_nonlinearity():
    # A cubic bow e x^3 on x = -5 .. 5: its line has the slope e sum x^4 / sum x^2 =
    # e 1958 / 110, the largest residual is at the ends, e (125 - 5 x 1958 / 110).
    x = np.linspace(-5.0, 5.0, 11)
    e = 4e-5
    fit = ch.scale_factor_fit(x, 2.0 * x + 0.1 + e * x ** 3)
    slope = 2.0 + e * 1958.0 / 110.0
    assert fit['slope'] == pytest.approx(slope, rel=1e-12)
    assert fit['offset_rad_s'] == pytest.approx(0.1, abs=1e-12)
    assert fit['full_scale_rad_s'] == pytest.approx(5.0 * slope, rel=1e-12)
    assert fit['nonlinearity_ppm'] == pytest.approx(
        e * (125.0 - 5.0 * 1958.0 / 110.0) / (5.0 * slope) * 1e6, rel=1e-9)


def test_the_step_fit_reads_a_first_order_response():
    t = np.arange(-1.0, 6.0, 1e-3)
    y = np.where(t > 0.0, 0.17 * 0.98 * (1.0 - np.exp(-np.maximum(t, 0.0) / 1.3)), 0.0)
    fit = ch.step_fit(t, y + 1e-3, 0.0, 0.17)
    assert fit['time_constant_s'] == pytest.approx(1.3, rel=1e-6)
    assert fit['gain'] == pytest.approx(0.98, rel=1e-6)
    assert fit['bandwidth_hz'] == pytest.approx(1.0 / (2.0 * math.pi * 1.3), rel=1e-6)
    assert fit['t63_s'] == pytest.approx(1.3, abs=2e-3)


def test_closed_needs_the_loop_parameter():
    loops = ch.available_loops()
    assert 'open' in loops
    assert ch.parse_loops(None) == loops
    assert ch.parse_loops('open') == ('open',)
    with pytest.raises(ValueError, match='--loops: give one or more'):
        ch.parse_loops(' , ')


def test_closed_is_refused_without_the_loop_parameter(monkeypatch):
    specs = {k: v for k, v in ch.SPECS.items() if k != ch.LOOP_PARAMETER}
    monkeypatch.setattr(ch, 'SPECS', specs)
    assert ch.available_loops() == ('open',)
    with pytest.raises(ValueError, match="--loops: 'closed' needs "
                                         'control.mode: closed_loop'):
        ch.parse_loops('open,closed')


def test_the_drive_figures_tell_a_drive_that_stays_down_from_one_that_returns():
    t = np.arange(1, 5001) * 1e-3  # 5 s at 1 kHz, a shock at 1 s
    back = np.where(t <= 1.0, 2.0, np.where(t < 3.0, 0.2, 2.0))
    down = np.where(t <= 1.0, 2.0, 0.2)
    common = dict(t=t, rate=np.zeros_like(t), applied=np.zeros_like(t),
                  quadrature=np.zeros_like(t), scale_factor=1.0,
                  drive_amplitude_m=1.0, electronics=None, summary=None, config=None)
    returns = ch._drive_figures(ch._Record(drive=back, **common), 1.0)
    assert returns['drive_ratio_end'] == pytest.approx(1.0)
    assert returns['drive_recovery_s'] == pytest.approx(3.0 - 1.0 - 1e-3, abs=1.5e-3)
    stays = ch._drive_figures(ch._Record(drive=down, **common), 1.0)
    assert stays['drive_ratio_end'] == pytest.approx(0.1)
    assert stays['drive_ratio_end'] < ch.JUMP_RATIO and stays['drive_recovery_s'] is None


def test_whole_numbers_are_written_in_full(quick):
    # 10 000 g, not "1e+04"
    text = (quick[2] / 'datasheet.md').read_text(encoding='utf-8')
    rows = [line for line in text.splitlines() if line.startswith('| 10 000 | ')]
    assert rows and '1e+04' not in text, text
    assert ch._fmt(10000.0) == '10 000' and ch._fmt(-300.0) == '-300'
    assert ch._fmt(3104.2, 3) == '3 104' and ch._fmt(5318.7, 3) == '5 319'
    assert ch._fmt(0.0123456) == '0.01235' and ch._fmt(15798.6, 6) == '15798.6'


def test_the_owned_device_s_temperature_series_follows_the_laws():
    # The default gyroscope (closed loops, force-to-rebalance, a perfect ring): its factory
    # calibration removes no bias and reads no quadrature (the ring's symmetry), and warmer
    # by dT its scale factor is k = (1 + alpha dT) / (1 + beta dT) of the held one (T3, T6:
    # the NCO's omega follows the mode, the AGC holds the amplitude through amplifiers whose
    # gain rose; test/core/test_thermal.py derives it). The compensation fitted at 0 and
    # 50 deg C with the reference takes nearly all of it out at 10 and 40 deg C.
    from ring_gyro_sim.core.params import build_config, to_flat
    flat = to_flat(build_config({}))
    plan = replace(ch.QUICK, temperature_points_k=(283.15, 313.15),
                   compensation_points_k=(273.15, 323.15))
    owned = ch._owned_device(flat, plan, ch._Bar(1.0, False))
    c, th = owned['calibration'], owned['temperature']
    assert abs(c['bias_deg_per_h']) < 1e-6 and abs(c['quadrature_deg_per_s']) < 1e-9
    alpha, beta = -30e-6, 50e-6  # thermal.frequency_coefficient, .gain_coefficient
    for row in th['points']:
        d = row['temperature_k'] - 298.15
        k = (1.0 + alpha * d) / (1.0 + beta * d)
        print(f'{d:+.0f} K: scale factor {row["scale_factor_error_ppm"]:.1f} ppm (laws '
              f'{(k - 1) * 1e6:.1f}), compensated {row["scale_factor_error_compensated_ppm"]:.3g}'
              f' ppm; bias {row["bias_deg_per_h"]:.3g} deg/h')
        assert row['scale_factor_error_ppm'] == pytest.approx((k - 1.0) * 1e6, rel=0.01)
        assert (abs(row['scale_factor_error_compensated_ppm'])
                < abs(row['scale_factor_error_ppm']) / 20.0)
        assert abs(row['bias_deg_per_h']) < 1e-6
    assert th['scale_factor_coefficient_ppm_per_k'] == pytest.approx(
        (alpha - beta) * 1e6, rel=0.01)


def test_the_sheet_has_the_owned_device_and_the_white_noise_convention(quick, sheet):
    # config/gyro.yaml drives open loop at a fixed 15 800 Hz: 15 K away the mode has moved
    # 30 ppm/K x 15 K = 7 Hz, 60 half-widths of the 0.12 Hz sense and drive resonances, and
    # the scale factor is nearly gone (an open-loop drive does not survive temperature; the
    # PLL of the default gyroscope follows the mode).
    c, th, w = sheet['calibration'], sheet['temperature'], sheet['white_noise']
    assert c['source'] == 'factory' and c['scale_factor_unit'] == 'V/(rad/s)'
    assert [r['temperature_k'] for r in th['points']] == [283.15, 313.15]
    assert all(r['scale_factor_error_ppm'] < -0.9e6 for r in th['points'])
    assert w['density_one_sided_deg_per_s_per_sqrt_hz'] == pytest.approx(
        math.sqrt(2.0) * w['density_two_sided_deg_per_s_per_sqrt_hz'], rel=1e-12)
    assert w['density_two_sided_deg_per_s_per_sqrt_hz'] * 60.0 == pytest.approx(
        sheet['arw_deg_per_sqrt_h'], rel=1e-12)
    text = (quick[2] / 'datasheet.md').read_text(encoding='utf-8')
    assert '## The device as owned' in text and 'one-sided' in text
    assert (quick[2] / 'temperature.png').stat().st_size > 10_000


# ----------------------------------------------------------------------------- every run
def test_the_plan_s_total_is_the_sum_of_the_runs_simulated(sheet):
    # One place (Plan.runs) gives the progress bar's total and the documented figures; the
    # sheet counts what _simulate and the environment runs actually ran.
    loops = len(sheet['loops'])
    assert sheet['simulated_s'] == pytest.approx(ch.QUICK.simulated_s(loops), rel=1e-12)
    assert sheet['runs'] == len(ch.QUICK.runs(loops))
    assert ch.QUICK.simulated_s(3) == pytest.approx(22.896, abs=1e-9)  # the docstring's
    assert ch.FULL.simulated_s(3) == pytest.approx(1121.189, abs=1e-9)
    sections = {name for name, _ in ch.QUICK.runs(loops)}
    assert sections == {'drift and step', 'rate table', 'shock', 'device as owned',
                        'environment'}


# ----------------------------------------------------------------------------- environment
def unit_keys(entry):
    """Yield the numeric keys of a sheet entry (nested), to check each names its unit."""
    if isinstance(entry, dict):
        for k, v in entry.items():
            if isinstance(v, (int, float)) and not isinstance(v, bool):
                yield k, v
            else:
                yield from unit_keys(v)
    elif isinstance(entry, list):
        for v in entry:
            yield from unit_keys(v)


UNITS = ('_g', '_hz', '_deg', '_s', '_deg_per_s', '_deg_per_h', '_per_g', '_per_m_s2',
         '_per_g2', '_m', '_at_1_g', '_slope', '_error', '_slopes', '_count', '_ratio',
         '_n_per_m2')


def test_the_environment_entries_are_finite_with_units(sheet):
    # The datasheet's JSON has the g-sensitivity and rectification
    # entries, finite, with their units in the key names (as the sheet's other entries).
    e = sheet['environment']
    g = {r['axis']: r for r in e['g_sensitivity']['axes']}
    assert set(g) == {'x', 'y'}
    for r in g.values():
        for key in ('linear_deg_per_s_per_g', 'linear_deg_per_s_per_m_s2', 'even_deg_per_s',
                    'quadratic_deg_per_s_per_g2'):
            assert isinstance(r[key], float) and math.isfinite(r[key]), key
    assert [p['frequency_hz'] for p in e['vibration']['points']] == list(
        ch.QUICK.vibration_frequencies_hz)
    for p in e['vibration']['points'] + e['vibration_angle']['points']:
        for key in ('rectified_bias_deg_per_s', 'rectified_bias_deg_per_h',
                    'rectified_bias_deg_per_s_per_g2', 'rectified_quadrature_deg_per_s'):
            assert isinstance(p[key], float) and math.isfinite(p[key]), key
    for key, value in unit_keys(e):
        assert key.endswith(UNITS), key
        assert math.isfinite(value), key
    assert e['record_s'] == ch.QUICK.environment_s and not e['settled']


def test_a_perfect_ring_reads_nothing_along_its_axes(sheet, quick):
    # config/gyro.yaml is a perfect ring. Mirrored about x (theta -> -theta) the ring, its
    # drive (cos 2theta) and a vibration or acceleration along x are unchanged while the
    # sense mode (sin 2theta), hence the rate, changes sign: the shift is exactly zero, to the
    # runs' rounding. Along y the mirror about y does the same. A steady +a and -a are also
    # the same ring turned by 180 deg (the 2theta pair does not change): no odd part.
    e = sheet['environment']
    zero = e['zero_floor_deg_per_s']
    for r in e['g_sensitivity']['axes']:
        assert abs(r['bias_shift_plus_deg_per_s']) < zero
        assert abs(r['bias_shift_minus_deg_per_s']) < zero
    for p in e['vibration']['points'] + [e['random']]:  # along x
        assert abs(p['rectified_bias_deg_per_s']) < zero, p
    rect = e['rectification']
    assert rect['zero_by_symmetry'] and rect['log_log_slope'] is None
    assert all(abs(b) < zero for b in rect['rectified_bias_deg_per_s'])
    text = (quick[2] / 'datasheet.md').read_text(encoding='utf-8')
    assert '## Environment: g-sensitivity and vibration rectification' in text
    assert 'mirror symmetry' in text


@pytest.fixture(scope='module')
def imperfect():
    """Return the quick environment tests of config/gyro.yaml drawn as device 1."""
    flat = ch.load_device(str(GYRO))
    flat['device.seed'] = 1
    return ch._environment(flat, replace(ch.QUICK, stop_test=False), ch._Bar(1.0, False))


def test_an_imperfect_ring_rectifies_with_the_square_of_the_amplitude(imperfect, tmp_path):
    # The shift is even in the amplitude: turning the ring by 180 deg maps a vibration A to
    # -A, a half-period delay of the sine that the mean does not see. So it is
    # b A^2 (1 + c A^2 + ...): the lowest power that survives is 2, and the local slopes
    # between neighbouring amplitudes tend to 2 as A -> 0 with a departure ~ c A^2 (the next
    # term of the series: the detuning's Lorentzian, the A^4 electrostatic terms).
    rect = imperfect['rectification']
    local = rect['local_slopes']
    a = rect['amplitudes_g']
    print(f'slope {rect["log_log_slope"]:.5f} +- {rect["log_log_slope_standard_error"]:.1e}, '
          f'local {local}')
    assert all(b < 0.0 for b in rect['rectified_bias_deg_per_s'])
    # the departure shrinks towards small A at least as A^2 does (a factor 2 to spare)
    top, bottom = abs(local[-1] - 2.0), abs(local[0] - 2.0)
    assert bottom <= 2.0 * top * (a[0] * a[1]) / (a[-2] * a[-1])
    # the fit over the decade lies within the top's departure: 2, not 1 nor 4 (a perfect
    # ring's lowest anisotropic power, sin 4 phi A^4)
    assert abs(rect['log_log_slope'] - 2.0) <= top
    assert top < 0.02
    # the labelled PNG
    from ring_gyro_sim.analysis import plotting
    assert plotting.plot_rectification(a, [b * 3600.0 for b in rect['rectified_bias_deg_per_s']],
                                       tmp_path / 'r.png', rect['log_log_slope'],
                                       rect['coefficient_deg_per_s_at_1_g'] * 3600.0)
    assert (tmp_path / 'r.png').read_bytes()[:8] == PNG_SIGNATURE


def test_an_imperfect_ring_rectifies_the_same_along_every_angle(imperfect):
    # What rectifies at A^2 is the mean square of the 1theta answer, q1^2 + q1s^2, which does
    # not depend on the direction: the 2theta pair's stiffness can only change with angle
    # through 4 phi (its anisotropy turns twice as fast as the pattern), which needs A^4. So
    # at 0, 22.5 and 45 deg the shift is the same to the A^4 share (< 1e-3 at 10 g).
    points = imperfect['vibration_angle']['points']
    assert [p['angle_deg'] for p in points] == [0.0, 22.5, 45.0]
    ref = points[0]['rectified_bias_deg_per_s']
    for p in points[1:]:
        assert p['rectified_bias_deg_per_s'] == pytest.approx(ref, rel=1e-3)


def test_the_g_sensitivity_is_even_and_twice_the_vibration_s_per_g2(imperfect):
    # No linear g-sensitivity: the ring turned by 180 deg maps +a to -a and leaves the 2theta
    # pair (and every imperfection of the model, all in that pair) unchanged, so the shifts at
    # +a and -a are equal to rounding. The even part is that of the mean square of the
    # 1theta answer: d^2 = (a / w1^2)^2 static against A1^2 / 2 for a sine of peak A, A1 its
    # amplitude: per g^2 and per square amplitude the static shift is twice the sine's,
    # within the 0.4 % by which the path through the 1theta and 3theta modes at the drive's
    # sidebands makes 1 kHz differ from static (doc/environments.md).
    e = imperfect
    for r in e['g_sensitivity']['axes']:
        assert abs(r['linear_deg_per_s_per_g']) < 1e-9 * abs(r['even_deg_per_s'])
    sine = next(p for p in e['vibration_angle']['points'] if p['angle_deg'] == 0.0)
    one_g = next(p for p in e['vibration']['points'] if p['frequency_hz'] == 100.0)
    w1 = 2.0 * math.pi * 11200.0
    static_q1 = STANDARD_GRAVITY / w1 ** 2
    for r in e['g_sensitivity']['axes']:
        per_square = r['even_deg_per_s'] / static_q1 ** 2
        mean_square = one_g['q1_amplitude_m'] ** 2 / 2.0
        sine_per_square = one_g['rectified_bias_deg_per_s'] / mean_square
        assert per_square == pytest.approx(sine_per_square, rel=0.01)
    assert sine['rectified_bias_deg_per_s'] < 0.0


def test_a_random_profile_rectifies_as_the_mean_square_of_its_answer(imperfect):
    # The same physics: the shift is that of the 1theta answer's mean square, so the random
    # profile's is the sine's per mean square times the multisine's (its lines through H).
    # Over the quick run (0.3 s) the mean square of a 20-2 000 Hz answer is a sample: its
    # relative spread is ~1 / sqrt(B T) = 1 / sqrt(1 980 Hz x 0.3 s) = 4 %; 3 of those.
    r = imperfect['random']
    assert r['rms_g'] == pytest.approx(math.sqrt(0.01 * 1980.0), rel=1e-9)
    assert r['rectified_bias_deg_per_s'] < 0.0
    assert r['rectified_bias_deg_per_s'] == pytest.approx(r['predicted_from_sine_deg_per_s'],
                                                          rel=0.12)


# ----------------------------------------------------------------------------- stops
def test_the_shock_survival_entries_are_finite_with_units(sheet, quick):
    # The largest shock without impact and, per level, the impacts, the
    # survival, the time ~/rate is not a measurement and the recovery. config/gyro.yaml has
    # no stops: the test says it put them at the plan's 0.6 d_g.
    s = sheet['environment']['stops']
    assert s['gap_m'] == pytest.approx(0.6 * s['electrode_gap_m'], rel=1e-12)
    assert s['gap_source'].startswith('default: 0.6 d_g')
    assert [r['peak_g'] for r in s['levels']] == list(ch.QUICK.stop_shock_peaks_g)
    for r in s['levels']:  # quick's levels lie below the threshold: no impact, survived
        assert r['impact_count'] == 0 and r['survived'] and not r['contact']
        assert [x['tolerance_deg_per_s'] for x in r['recovery']] == list(
            ch.QUICK.stop_tolerances_dps)
        assert math.isfinite(r['peak_error_deg_per_s'])
    for key, value in unit_keys(s):
        assert key.endswith(UNITS), key
        assert math.isfinite(value), key
    text = (quick[2] / 'datasheet.md').read_text(encoding='utf-8')
    assert '**Shock survival with stops**' in text and '0.6 d_g' in text


def test_the_half_sine_closed_form_is_the_oscillator_s_peak():
    # x'' + omega^2 x = -sin(pi t / T) on [0, T], from rest: the residual amplitude after the
    # pulse, 2 omega_p |cos(omega T / 2)| / (omega |omega_p^2 - omega^2|), or the pulse's own
    # maximum, whichever is larger; integrated here with an adaptive Runge-Kutta.
    from scipy.integrate import solve_ivp
    from ring_gyro_sim.analysis.environment import half_sine_residual
    omega = 2.0 * math.pi * 11200.0
    for duration in (6.329e-6, 30e-6, 200e-6):  # short (impulsive), mid, long (quasi-static)
        wp = math.pi / duration

        def f(t, y):
            a = math.sin(wp * t) if t <= duration else 0.0
            return [y[1], -omega * omega * y[0] - a]
        end = duration + 4.0 * math.pi / omega
        sol = solve_ivp(f, (0.0, end), [0.0, 0.0], max_step=duration / 200.0, rtol=1e-10,
                        atol=1e-20, dense_output=True)
        peak = np.max(np.abs(sol.sol(np.linspace(0.0, end, 200001))[0]))
        assert half_sine_residual(omega, duration) == pytest.approx(peak, rel=1e-4)
    # the impulsive limit: delta_v / omega = 2 T / (pi omega)
    assert half_sine_residual(omega, 1e-8) == pytest.approx(2e-8 / (math.pi * omega), rel=1e-6)


def test_the_no_impact_threshold_is_where_the_ring_reaches_the_stop(sheet):
    # The closed form gives the 1theta mode's peak: the half-sine's residual response
    # (eq. 27, 32) with the electrostatic softening of the mode (eq. 28: the energy the pulse
    # gives equals the softened potential at the peak). The run's q1 peak at the largest
    # level without impact agrees with it, closer than the linear form (2 % there).
    # The ring touches where its whole |w| reaches g_s: the electrostatic terms also drive
    # the 2theta and 3theta modes (q1^2, q1 q2), whose deflections add to q1 at the shock's
    # angle, so the runs' threshold lies below the 1theta mode's own. Checked without stops:
    # the largest outward |w| (d_g less the least gap) is below g_s at the level without
    # impact and beyond it at the level with.
    from ring_gyro_sim.analysis import environment as env
    s = sheet['environment']['stops']
    th = s['threshold']
    assert th['bracketed'] and th['no_impact_g'] < th['first_impact_g']
    span = (ch.STOP_BRACKET[1] - ch.STOP_BRACKET[0]) * th['closed_form_electrostatic_g']
    assert th['first_impact_g'] - th['no_impact_g'] <= span / 2 ** ch.QUICK.stop_bisections \
        * (1.0 + 1e-12)
    runs = {r['peak_g']: r for r in th['runs']}
    assert runs[th['no_impact_g']]['impact_count'] == 0
    assert runs[th['first_impact_g']]['impact_count'] > 0
    measured, closed = th['q1_peak_at_no_impact_m'], th['q1_peak_closed_form_at_no_impact_m']
    linear = th['no_impact_g'] * th['q1_per_g_m']
    assert measured == pytest.approx(closed, rel=0.01)
    assert abs(measured - closed) < abs(measured - linear) / 3.0
    assert th['first_impact_g'] < th['closed_form_electrostatic_g'] < th[
        'closed_form_linear_g']
    flat = ch.load_device(str(GYRO))
    reach = {}
    length = ch.STOP_THRESHOLD_AT_S + ch.QUICK.stop_threshold_after_s  # the same window
    for level in (th['no_impact_g'], th['first_impact_g']):
        config = env.quiet(build_config(ch._test_parameters(flat, length, **{
            'scenario.shock_times': [ch.STOP_THRESHOLD_AT_S],
            'scenario.shock_peaks': [level * STANDARD_GRAVITY]})))
        out = env.shock_record(config, length)
        reach[level] = s['electrode_gap_m'] - out['min_gap_m']
        assert reach[level] > out['q1_peak_m']  # the other modes add to q1
    assert reach[th['no_impact_g']] < s['gap_m'] < reach[th['first_impact_g']]


# ----------------------------------------------------------------------------- the long record
DEFAULT = REPO_ROOT / 'config' / 'default.yaml'


def with_fidelity(tmp_path, source, fidelity):
    """Write ``source`` with ``integrator.fidelity`` set; return its path."""
    import yaml
    data = yaml.safe_load(source.read_text(encoding='utf-8'))
    params = next(iter(data.values()))['ros__parameters']
    params.setdefault('integrator', {})['fidelity'] = fidelity
    path = tmp_path / f'{fidelity}.yaml'
    path.write_text(yaml.safe_dump(data), encoding='utf-8')
    return path


def test_the_plans_long_records_reach_their_tau():
    # The datasheet's goal: Allan to tau = 1 000 s from a record of at least 3 h.
    assert ch.FULL.long_record_s >= 3 * 3600.0
    for plan in (ch.FULL, ch.QUICK):
        top = (plan.long_record_s - plan.zero_rate_skip_s) / ch.TAU_FRACTION
        assert top >= (1000.0 if plan is ch.FULL else 20.0)


@pytest.fixture(scope='module')
def long_default():
    """Run the QUICK plan's long record of ``config/default.yaml`` (auto); analyse it."""
    flat = ch.load_device(str(DEFAULT))
    bar = ch._Bar(0.0, False, ch.QUICK.long_record_s)
    rec = ch._long_record(flat, ch.QUICK, bar, ch.averaged_refusal(flat))
    el = Run(rec['config']).full_model().sense.electronics
    # the step's time constant as the model predicts it (the fit's shortest tau, 10 Tc)
    drift = {'step': {'time_constant_s': 1.0 / (2.0 * math.pi * el.bandwidth_hz)}}
    return rec, ch._long_allan(rec, drift), el, bar


def test_the_long_record_runs_on_the_averaged_model_to_its_tau(long_default):
    rec, g, _, bar = long_default
    plan = ch.QUICK
    assert rec['run'] and g['run'] and g['fidelity'] == 'auto'
    assert g['simulated_s'] == plan.long_record_s
    assert g['record_s'] == pytest.approx(plan.long_record_s - plan.zero_rate_skip_s)
    # oadev to T / TAU_FRACTION, its last m a whole number of samples at 1 kHz
    assert g['tau_max_s'] == pytest.approx(g['record_s'] / ch.TAU_FRACTION, abs=1e-3)
    assert g['allan']['tau_s'][-1] == g['tau_max_s']
    # the bar counted it at the averaged model's weight, the sheet's simulated_s does not
    assert bar.work == pytest.approx(plan.long_record_s * ch.AVERAGED_COST)
    assert bar.done_s == 0.0 and bar.runs == 0
    # the intervals hold the deviation and widen with tau (fewer clusters)
    lo, hi = np.transpose(g['allan']['adev_interval_deg_per_h'])
    dev = np.asarray(g['allan']['adev_deg_per_h'])
    assert np.all(lo < dev) and np.all(dev < hi)
    assert (hi / lo)[-1] > (hi / lo)[0]
    lo_b, hi_b = g['bias_instability_interval_deg_per_h']
    assert lo_b < g['bias_instability_deg_per_h'] < hi_b


def test_the_long_record_s_arw_is_the_model_s(long_default):
    # E10-E12's ARW of the rebalance loop against the averaged record's Allan fit (from
    # 10 Tc, ~0.1 s): 4 x the relative error of the deviation at the fit's shortest tau,
    # 1 / sqrt(2 (T / tau - 1)) = 1.6 %, plus 3 % (the closed form's loop is continuous-time;
    # doc/averaged.md, the same margin).
    _, g, el, _ = long_default
    tau0 = g['arw_fit_tau_s'][0]
    margin = 4.0 / math.sqrt(2.0 * (g['record_s'] / tau0 - 1.0)) + 0.03
    assert g['arw_deg_per_sqrt_h'] == pytest.approx(el.predicted_arw_deg_per_sqrt_h(),
                                                    rel=margin)
    # white rate noise to the end of the record (no flicker on the default device): the
    # last decade's slope is -1/2, within the deviations' 68 % intervals at its ends
    lo, hi = g['allan']['adev_interval_deg_per_h'][-1]
    dev = g['adev_at_tau_max_deg_per_h']
    spread = math.log(hi / lo) / 2.0 / math.log(10.0)  # over one decade of tau
    assert g['long_tau_slope'] == pytest.approx(-0.5, abs=2.0 * spread)
    assert lo < dev < hi
    assert g['rate_random_walk_deg_per_h_per_sqrt_h'] is None


def test_the_long_record_section_is_in_the_markdown(long_default):
    _, g, _, _ = long_default
    text = '\n'.join(ch._long_markdown(g, 0.05))
    assert '## Long zero-rate record (averaged model)' in text
    assert f'to tau = {ch._fmt(g["tau_max_s"], 4)} s' in text
    assert '| bias instability |' in text and '| rate random walk |' in text


def test_fidelity_full_leaves_the_long_record_out_and_says_why():
    flat = dict(ch.load_device(str(DEFAULT)), **{'integrator.fidelity': 'full'})
    bar = ch._Bar(0.0, False)
    assert ch.averaged_refusal(flat) == 'integrator.fidelity: full'
    g = ch._long_allan(ch._long_record(flat, ch.QUICK, bar, ch.averaged_refusal(flat)), None)
    assert g['run'] is False and 'integrator.fidelity: full' in g['reason']
    assert bar.work == 0.0
    text = '\n'.join(ch._long_markdown(g, 0.05))
    assert 'Not run: integrator.fidelity: full' in text


def test_auto_on_a_device_the_averaged_model_cannot_run_says_why(sheet, quick):
    # config/gyro.yaml is open loop: AveragedGyro needs force-to-rebalance
    g = sheet['long_record']
    assert g['run'] is False and g['fidelity'] == 'auto'
    assert 'control.mode' in g['reason'] and 'falls back' in g['reason']
    text = (quick[2] / 'datasheet.md').read_text(encoding='utf-8')
    assert '## Long zero-rate record (averaged model)\n\nNot run: the averaged model' in text


@pytest.mark.parametrize('device, fidelity, said', [
    (GYRO, 'averaged', ('integrator.fidelity: averaged', 'control.mode: rebalance')),  # open
    (DEFAULT, 'fast', ('integrator.fidelity', 'auto, full, averaged'))])        # no such value
def test_a_fidelity_that_cannot_be_kept_is_refused_before_any_run(tmp_path, capsys,
                                                                  device, fidelity, said):
    path = with_fidelity(tmp_path, device, fidelity)
    code = cli.main(['characterize', str(path), '--out', str(tmp_path / 'x'), '--quick',
                     '--no-progress'])
    assert code == 1
    err = capsys.readouterr().err
    assert all(part in err for part in said), err
    assert not (tmp_path / 'x').exists()


def test_the_averaged_record_of_the_step_is_the_full_one():
    # Noise off, the drift-and-step run's scenario (10 deg/s at 1 s here, 1.5 s after): the
    # first-order fit's time constant and gain of the averaged model's record against the
    # full model's, within 1e-3 (the required agreement of the reading after the first time
    # constant; the readings agree to 5.4e-4 just after it, 3e-6 from 0.1 s on:
    # doc/averaged.md).
    flat = dict(ch.load_device(str(DEFAULT)))
    flat.update({'gyro.temperature': 0.0, 'gyro.input_noise_density': 0.0})
    assert ch.averaged_refusal(flat) is None
    step, t0, length = 10.0 * ch.DEG, 1.0, 2.5
    values = ch._test_parameters(flat, length, **{'scenario.rate_times': [t0, t0],
                                                  'scenario.rate_values': [0.0, step]})
    bar = ch._Bar(0.0, False)
    averaged = ch._simulate_averaged(values, length, bar, 'step')
    full = ch._simulate(values, length, bar, 'step')
    assert averaged.model == 'averaged' and full.model == 'full'
    assert bar.averaged_s == bar.done_s == length and bar.runs == 1
    assert np.allclose(averaged.t, full.t, rtol=0.0, atol=1e-9)
    fit_a, fit_f = (ch.step_fit(r.t, r.rate, t0, step) for r in (averaged, full))
    for key in ('time_constant_s', 'gain'):
        assert fit_a[key] == pytest.approx(fit_f[key], rel=1e-3), key
    # the applied rate is the step, from its time on, as the full model applies it
    assert np.array_equal(averaged.applied, full.applied)
    assert averaged.scale_factor == full.scale_factor
    assert averaged.electronics.predicted_arw() == full.electronics.predicted_arw()


def test_the_long_record_reads_a_known_rate_random_walk():
    # White rate noise N and a rate random walk K (the rate a Wiener process of K per
    # sqrt(s)): sigma^2 = N^2 / tau + K^2 tau / 3 (IEEE Std 952, C.1), minimum at
    # tau_m = sqrt(3) N / K = 0.2 s. 1 000 s at 100 Hz, seeded. K read from 3 tau_m on:
    # 5.4 % high at most from the white part (RRW_START), plus 3 x the relative error of the
    # deviation at 3 tau_m, 1 / sqrt(2 (T / tau - 1)) = 1.7 %.
    rate_hz, length, n_white, k_rrw = 100.0, 1000.0, 1e-3, math.sqrt(3.0) * 1e-3 / 0.2
    rng = np.random.default_rng(25)
    size = int(length * rate_hz)
    x = n_white * math.sqrt(rate_hz) * rng.standard_normal(size) + k_rrw * np.cumsum(
        rng.standard_normal(size)) / math.sqrt(rate_hz)
    config = build_config({})
    long = {'run': True, 'fidelity': 'auto', 'model': 'synthetic', 'planned_s': length,
            'rate': x, 'rate_hz': rate_hz, 'config': config, 'simulated_s': length,
            'skip_s': 0.0, 'wall_s': 0.0}
    g = ch._long_allan(long, {'step': {'time_constant_s': 1e-3}})
    assert g['bias_instability_floor_reached']
    assert g['bias_instability_tau_s'] == pytest.approx(0.2, rel=0.5)
    lo = g['rate_random_walk_tau_s'][0]
    margin = 0.054 + 3.0 / math.sqrt(2.0 * (length / lo - 1.0))
    expected = k_rrw * ch.RAD_S_TO_DEG_H * 60.0  # deg/h/sqrt(h)
    assert g['rate_random_walk_deg_per_h_per_sqrt_h'] == pytest.approx(expected, rel=margin)
    # the last decade's slope +1/2 within the deviation's 68 % interval at its end
    lo_d, hi_d = g['adev_interval_at_tau_max_deg_per_h']
    spread = math.log(hi_d / lo_d) / 2.0 / math.log(10.0)
    assert g['long_tau_slope'] == pytest.approx(0.5, abs=2.0 * spread)
    text = '\n'.join(ch._long_markdown(g, 0.05))
    assert 'K sqrt(tau / 3)' in text
