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
The scenario's environment: sine, random vibration, steady acceleration.

The resonator without its drive, at rest: linear, so the 1theta coordinate answers a base
acceleration ``a(t)`` along x as ``q1'' + c q1' + omega_1^2 q1 = -a(t)`` (eq. 32's forcing,
unit participation): a sine ``A sin(omega t)`` far below omega_1 gives the steady amplitude
``A / (omega_1^2 - omega^2)`` in antiphase (damping shifts it by 1e-10 here), a steady
``a`` the deflection ``-a / omega_1^2``, a random one of PSD ``S_a`` the variance
``integral S_a |H|^2 df`` with ``H = 1 / (omega_1^2 - omega^2 + i omega omega_1 / Q_1)``.
"""

import math

import numpy as np
import pytest
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.errors import ParameterError
from ring_gyro_sim.core.params import paper_config, STANDARD_GRAVITY
from ring_gyro_sim.run import ParameterChange, Run
from scipy import signal

QUIET = {'drive.amplitude': 0.0, 'drive.start_on': 'rest'}
# A profile written as test profiles are: +3 dB/octave from 20 to 200 Hz (S proportional to
# f), flat to 1 kHz, -3 dB/octave to 5 kHz (S proportional to 1 / f), g^2/Hz; 5.01 g rms.
PSD_F = [20.0, 200.0, 1000.0, 5000.0]
PSD_S = [0.001, 0.01, 0.01, 0.002]
RANDOM = {**QUIET, 'scenario.vibration_psd_frequencies': PSD_F,
          'scenario.vibration_psd_values': PSD_S}


def profile(f):
    """Return the profile above at ``f`` (Hz), g^2/Hz, from its three straight segments."""
    f = np.asarray(f, dtype=np.float64)
    inside = (f >= PSD_F[0]) & (f <= PSD_F[-1])
    f = np.clip(f, PSD_F[0], PSD_F[-1])
    return inside * np.where(f < 200.0, 0.01 * f / 200.0,
                             np.where(f <= 1000.0, 0.01, 0.01 * 1000.0 / f))


def lock_in(t, x, f_hz):
    """Return (in-phase with sin, with cos) amplitudes of ``x`` at ``f_hz`` (whole periods)."""
    phase = 2.0 * math.pi * f_hz * t
    return 2.0 * np.mean(x * np.sin(phase)), 2.0 * np.mean(x * np.cos(phase))


def test_a_sine_vibration_drives_q1_with_its_closed_form_amplitude():
    f, peak = 1000.0, 10.0 * STANDARD_GRAVITY
    config = paper_config({**QUIET, 'scenario.vibration_frequency': f,
                           'scenario.vibration_amplitude': peak})
    sim = Simulator(config)
    s = sim.advance_samples(int(round(0.3 * config.run.output_rate)))
    late = s.t > 0.2  # 100 periods, after the start's transient at omega
    in_phase, quadrature = lock_in(s.t[late], s.q[late, 0], f)
    w1, w = 2.0 * math.pi * config.modes.frequencies[0], 2.0 * math.pi * f
    closed = peak / (w1 * w1 - w * w)
    print(f'q1 at 1 kHz: {-in_phase:.6e} m, closed form {closed:.6e} m '
          f'({-in_phase / closed - 1:+.2e}); out of phase {quadrature:.1e} m')
    assert -in_phase == pytest.approx(closed, rel=5e-3)
    assert abs(quadrature) < 1e-4 * closed


def test_the_vibration_s_angle_sets_its_direction_and_a_cut_run_is_the_same():
    # Along y (90 deg) the sine coordinate q1s answers and q1 does not; the result does not
    # depend on how the run is cut (the vibration is a function of the time).
    values = {**QUIET, 'modes.companions': True, 'scenario.vibration_frequency': 2000.0,
              'scenario.vibration_amplitude': 50.0, 'scenario.vibration_angle': 90.0}
    config = paper_config(values)
    whole = Simulator(config).advance_samples(4000)
    cut = Simulator(config)
    parts = [cut.advance_samples(n) for n in (1, 999, 1234, 1766)]
    assert np.array_equal(whole.q, np.concatenate([p.q for p in parts]))
    names = Simulator(config).coordinates
    q1, q1s = whole.q[:, names.index('q1')], whole.q[:, names.index('q1s')]
    assert np.max(np.abs(q1s)) > 1e-9 and np.max(np.abs(q1)) < 1e-6 * np.max(np.abs(q1s))


def test_a_steady_acceleration_deflects_q1_statically():
    a = 100.0 * STANDARD_GRAVITY
    config = paper_config({**QUIET, 'scenario.acceleration': [a, 0.0]})
    s = Simulator(config).advance_samples(int(round(0.2 * config.run.output_rate)))
    w1 = 2.0 * math.pi * config.modes.frequencies[0]
    period = int(round(config.run.output_rate / config.modes.frequencies[0] * 1120))
    mean = float(np.mean(s.q[-period:, 0]))  # 1120 periods of the ringing at omega_1
    print(f'q1 mean {mean:.6e} m, closed form {-a / w1 ** 2:.6e} m')
    assert mean == pytest.approx(-a / (w1 * w1), rel=5e-3)


@pytest.mark.parametrize('values, field', [
    ({'scenario.acceleration': [1.0, 2.0, 3.0]}, 'scenario.acceleration'),
    ({'scenario.vibration_frequency': 6000.0, 'output.rate': 200000.0},
     'scenario.vibration_frequency'),
    ({'scenario.vibration_amplitude': -1.0}, 'scenario.vibration_amplitude'),
])
def test_a_bad_environment_is_refused_naming_the_field(values, field):
    with pytest.raises(ParameterError, match=field.replace('.', r'\.')):
        paper_config(values)


def steady_state_start(config, rv):
    """
    Return the start state on the periodic answer of q1 to the multisine ``rv``.

    Each line ``C_k = A_k exp(i phi_k)`` reaches the ring as the linear interpolant of its
    samples, ``sinc^2(f_k / output.rate) C_k``; q1's periodic answer is ``-H C`` per line.
    Starting on it leaves no free ringing (which Q_1 = 120 000 would keep for seconds).
    """
    f = rv.lines * rv.df
    w, w1 = 2.0 * math.pi * f, 2.0 * math.pi * config.modes.frequencies[0]
    h = 1.0 / (w1 * w1 - w * w + 1j * w * w1 / config.modes.quality_factors[0])
    c = rv.amplitudes * np.exp(1j * rv.phases) * np.sinc(f / config.run.output_rate) ** 2
    q, v = np.zeros(config.modes.count), np.zeros(config.modes.count)
    q[0], v[0] = -np.real(np.sum(h * c)), -np.real(np.sum(1j * w * h * c))
    return q, v


def test_a_random_profile_drives_q1_with_the_variance_of_its_psd_through_the_mode():
    """
    Must show: var(q1) = integral S_a(f) |H(f)|^2 df within 5 %.

    One period of the multisine (2^20 samples, 5.24 s at 200 kHz): its amplitudes are
    deterministic, so q1's variance over a whole period has no statistical error; what is
    left is the line sum against the integral (0.19 Hz lines), the interpolation's
    ``sinc^4`` (-9e-4 here) and the integrator. The quasi-static answer ``S_a / omega_1^4``
    is 9 % off: the test sees the transfer function, not just the static compliance.
    """
    config = paper_config(RANDOM)
    rv = Simulator(config).random_vibration
    assert rv.n == 2 ** 20 and rv.df == pytest.approx(200000.0 / 2 ** 20)
    sim = Simulator(config, start_state=steady_state_start(config, rv))
    q1 = sim.advance_samples(rv.n).q[:, 0]
    w1, q_1 = 2.0 * math.pi * config.modes.frequencies[0], config.modes.quality_factors[0]
    f = np.linspace(PSD_F[0], PSD_F[-1], 2_000_001)
    s_a = profile(f) * STANDARD_GRAVITY ** 2
    w = 2.0 * math.pi * f
    h2 = 1.0 / np.abs(w1 * w1 - w * w + 1j * w * w1 / q_1) ** 2
    integral = np.trapezoid(s_a * h2, f)
    interpolated = np.trapezoid(s_a * h2 * np.sinc(f / config.run.output_rate) ** 4, f)
    quasi_static = np.trapezoid(s_a, f) / w1 ** 4
    var = float(np.var(q1))
    print(f'var(q1) {var:.6e} m^2 over {rv.n} samples ({rv.n / 2e5:.3f} s), integral '
          f'{integral:.6e} ({var / integral - 1:+.2e}), with sinc^4 {interpolated:.6e} '
          f'({var / interpolated - 1:+.2e}), quasi-static {var / quasi_static - 1:+.2e}')
    assert var == pytest.approx(integral, rel=0.05)  # the must-show
    assert var == pytest.approx(interpolated, rel=1e-4)
    assert abs(var / quasi_static - 1.0) > 0.05  # control: the quasi-static answer fails


def test_the_random_acceleration_has_the_profile_s_psd_and_rms():
    """
    The generated acceleration: rms and Welch PSD against the profile.

    Over one period its mean square is the line sum of the PSD (exact). Welch (Hann, 50 %
    overlap, K segments of one period) estimates a Gaussian process's PSD with a relative
    spread of ``sqrt(1.056 / K)`` per bin: 9.1 % with 16384 samples (12.2 Hz bins, K = 127)
    below 200 Hz, 4.5 % with 4096 (48.8 Hz, K = 511) above; the mean of three bins is
    compared within 3 of that, at points on both log-log slopes (where S is linear in f or
    in 1 / f, so the window's average is unbiased) and on the flat part, away from the
    band's edges (where the window averages across the step to zero).
    """
    config = paper_config(RANDOM)
    sim = Simulator(config)
    rv = sim.random_vibration
    x, y = sim.environment_at(np.arange(rv.n))
    assert np.all(y == 0.0)
    rms_g = math.sqrt(float(np.mean(x * x))) / STANDARD_GRAVITY
    print(f'rms {rms_g:.6f} g, profile {config.run.random_vibration_rms_g:.6f} g')
    assert rms_g == pytest.approx(config.run.random_vibration_rms_g, rel=1e-4)
    # the integral of the three segments by hand: 0.99 + 8 + 16.094 g^2
    assert config.run.random_vibration_rms_g ** 2 == pytest.approx(
        0.01 / 400.0 * (200.0 ** 2 - 20.0 ** 2) + 8.0 + 10.0 * math.log(5.0), rel=1e-12)
    fs = config.run.output_rate
    for nperseg, centres in ((16384, (60.0, 120.0)), (4096, (500.0, 2500.0, 4000.0))):
        f, p = signal.welch(x, fs=fs, window='hann', nperseg=nperseg)
        spread = math.sqrt(1.056 / (2 * rv.n // nperseg - 1))
        for centre in centres:
            j = int(np.argmin(np.abs(f - centre)))
            estimate = float(np.mean(p[j - 1:j + 2]))
            expected = float(np.mean(profile(f[j - 1:j + 2]))) * STANDARD_GRAVITY ** 2
            print(f'{f[j]:7.1f} Hz: Welch / profile - 1 = {estimate / expected - 1:+.4f} '
                  f'(spread {spread:.3f})')
            assert estimate == pytest.approx(expected, rel=3.0 * spread)
    # At the resolution of the period (one line per 0.19 Hz) the periodogram is the
    # profile in every line, log-log between the points, and zero outside the band.
    lines = np.abs(np.fft.rfft(x)) ** 2 * 2.0 / (rv.n * rv.n)  # A_k^2 / 2 per line
    f_k = np.arange(lines.size) * rv.df
    expected = profile(f_k) * STANDARD_GRAVITY ** 2 * rv.df
    inside = (f_k >= PSD_F[0]) & (f_k <= PSD_F[-1])
    assert np.allclose(lines[inside], expected[inside], rtol=1e-9, atol=0.0)
    assert np.max(lines[~inside]) < 1e-20 * np.max(lines)


def test_a_random_run_cut_in_pieces_is_the_same_and_the_seed_sets_the_phases():
    values = {**RANDOM, 'modes.companions': True, 'scenario.vibration_angle': 30.0}
    config = paper_config(values)
    whole = Simulator(config).advance_samples(4000)
    cut = Simulator(config)
    parts = [cut.advance_samples(n) for n in (1, 999, 1234, 1766)]
    assert np.array_equal(whole.q, np.concatenate([p.q for p in parts]))
    names = Simulator(config).coordinates
    q1, q1s = whole.q[:, names.index('q1')], whole.q[:, names.index('q1s')]
    assert np.std(q1s) == pytest.approx(math.tan(math.radians(30.0)) * np.std(q1), rel=1e-6)
    other = Simulator(paper_config({**values, 'gyro.noise_seed': 7}))
    a, _ = Simulator(config).environment_at(np.arange(1000))
    b, _ = other.environment_at(np.arange(1000))
    assert np.std(a) == pytest.approx(np.std(b), rel=0.2) and abs(np.corrcoef(a, b)[0, 1]) < 0.2


def test_a_level_change_keeps_the_phases_of_the_lines():
    sim = Simulator(paper_config(RANDOM))
    before, _ = sim.environment_at(np.arange(5000))
    sim.update_parameters({'scenario.vibration_psd_values': [4.0 * s for s in PSD_S]})
    after, _ = sim.environment_at(np.arange(5000))
    assert np.allclose(after, 2.0 * before, rtol=1e-12, atol=1e-12 * np.max(np.abs(before)))


def test_a_live_frequency_change_acts_at_its_sample_with_the_phase_continuous():
    f1, f2, peak = 1000.0, 1300.0, 10.0 * STANDARD_GRAVITY
    config = paper_config({**QUIET, 'scenario.vibration_frequency': f1,
                           'scenario.vibration_amplitude': peak})
    run = Run(config)
    run.advance(777)
    at_ns = run.apply(ParameterChange({'scenario.vibration_frequency': f2}))
    assert at_ns == 777 * 5000
    sim = run.full_model()
    n = np.arange(777, 2000)
    a, _ = sim.environment_at(n)
    t, t_c = n / 2e5, 777 / 2e5
    expected = peak * np.sin(2.0 * math.pi * f2 * (t - t_c) + 2.0 * math.pi * f1 * t_c)
    assert np.allclose(a, expected, rtol=0.0, atol=1e-9 * peak)
    # Continuous: at the change the new sine takes up the old one's value and phase.
    old = peak * math.sin(2.0 * math.pi * f1 * t_c)
    assert a[0] == pytest.approx(old, abs=1e-9 * peak)
    # The same change scheduled ahead, and the run cut elsewhere: the same samples, bit
    # for bit (a re-simulation applies a recorded change so).
    ahead = Run(config)
    ahead.apply(ParameterChange({'scenario.vibration_frequency': f2}, at_ns=at_ns))
    ahead_q = np.concatenate([ahead.advance(k).samples.q for k in (500, 1500)])
    assert np.array_equal(ahead_q, _live(config, f2))


def _live(config, f2):
    run = Run(config)
    first = run.advance(777).samples.q
    run.apply(ParameterChange({'scenario.vibration_frequency': f2}))
    return np.concatenate([first, run.advance(1223).samples.q])


def test_a_step_of_the_steady_acceleration_acts_from_its_sample_and_the_mode_rings():
    a = 100.0 * STANDARD_GRAVITY
    config = paper_config(QUIET)
    sim = Simulator(config)
    assert np.all(sim.advance_samples(1000).q == 0.0)
    sim.update_parameters({'scenario.acceleration': [a, 0.0]})
    q1 = sim.advance_samples(4000).q[:, 0]
    assert q1[0] != 0.0  # the sample after the change moves
    w1 = 2.0 * math.pi * config.modes.frequencies[0]
    # From rest, q1 = -(a / omega_1^2) (1 - cos omega_1 t): it rings between 0 and twice
    # the static deflection about it, for 2 Q_1 / omega_1 = 3.4 s.
    assert np.max(q1) <= 1e-3 * a / w1 ** 2
    assert np.min(q1) == pytest.approx(-2.0 * a / w1 ** 2, rel=1e-3)


@pytest.mark.parametrize('values, field', [
    ({'scenario.vibration_psd_frequencies': [20.0, 2000.0]}, 'scenario.vibration_psd_values'),
    ({'scenario.vibration_psd_frequencies': [20.0], 'scenario.vibration_psd_values': [0.01]},
     'scenario.vibration_psd_frequencies'),
    ({'scenario.vibration_psd_frequencies': [200.0, 20.0],
      'scenario.vibration_psd_values': [0.01, 0.01]}, 'scenario.vibration_psd_frequencies'),
    ({'scenario.vibration_psd_frequencies': [20.0, 6000.0],
      'scenario.vibration_psd_values': [0.01, 0.01]}, 'scenario.vibration_psd_frequencies'),
    ({'scenario.vibration_psd_frequencies': [20.0, 21.0],
      'scenario.vibration_psd_values': [0.01, 0.01]}, 'scenario.vibration_psd_frequencies'),
    ({'scenario.vibration_psd_frequencies': [20.0, 2000.0],
      'scenario.vibration_psd_values': [0.01, 0.0]}, 'scenario.vibration_psd_values'),
    ({'scenario.vibration_psd_frequencies': [20.0, 2000.0],
      'scenario.vibration_psd_values': [0.01, math.inf]}, 'scenario.vibration_psd_values'),
    ({'scenario.vibration_psd_frequencies': [20.0, 2000.0],
      'scenario.vibration_psd_values': [1e8, 1e8]}, 'scenario.vibration_psd_values'),
])
def test_a_bad_random_profile_is_refused_naming_the_field(values, field):
    with pytest.raises(ParameterError, match=field.replace('.', r'\.')):
        paper_config(values)


def test_the_start_on_the_environment_s_answer_does_not_ring():
    # with_environment_response puts the 1theta pair on its linear steady answer at t = 0:
    # started from rest a 3 kHz sine leaves a free ringing at omega_1 of (w / omega_1) = 0.27
    # of the forced amplitude for 3.4 s; from the answer (the interpolant's sinc^2 included)
    # 8e-7 of it is left: the electrostatic terms the linear answer leaves out. The forced
    # amplitude is the closed form times sinc^2(f / output.rate) = 1 - 7.4e-4 at 3 kHz. A
    # steady acceleration is held at -a / omega_1^2 from the first sample. A random profile's
    # start is the periodic answer of each line, steady_state_start's.
    from ring_gyro_sim.core.gyro.operating_point import with_environment_response
    f, peak = 3000.0, 10.0 * STANDARD_GRAVITY
    config = paper_config({**QUIET, 'scenario.vibration_frequency': f,
                           'scenario.vibration_amplitude': peak,
                           'scenario.acceleration': [STANDARD_GRAVITY, 0.0]})
    w1, w = 2.0 * math.pi * config.modes.frequencies[0], 2.0 * math.pi * f
    forced = peak / (w1 * w1 - w * w)
    periods = int(round(0.01 * config.run.output_rate))  # 10 ms: 30 and 112 whole periods
    for start, ringing_bound in ((None, 0.2), (with_environment_response(config, None), 1e-5)):
        s = Simulator(config, start).advance_samples(periods)
        q1 = s.q[:, 0] + STANDARD_GRAVITY / w1 ** 2
        in_phase, _ = lock_in(s.t, q1, f)
        ring = math.hypot(*lock_in(s.t, q1, config.modes.frequencies[0]))
        print(f'start {"settled" if start is not None else "at rest"}: forced '
              f'{-in_phase / forced - 1:+.2e}, ringing at omega_1 {ring / forced:.2e}')
        if start is None:
            assert ring > ringing_bound * forced  # the step's ringing, (w / omega_1) = 0.27
        else:
            assert ring < ringing_bound * forced
            assert -in_phase == pytest.approx(forced, rel=1e-3)
    random = paper_config(RANDOM)
    q, v = with_environment_response(random, None)
    expected = steady_state_start(random, Simulator(random).random_vibration)
    assert q[0] == pytest.approx(expected[0][0], rel=1e-9)
    assert v[0] == pytest.approx(expected[1][0], rel=1e-9)


def test_a_run_starts_on_the_environment_s_answer_and_holds_it():
    # A run (the node, ring_gyro run, characterize, sweeps: operating_point.start_state)
    # starts where a sensor switched on in its environment has been: q1 at the static
    # deflection -a / k of 100 g (k = omega_1^2 less the electrostatic softening at rest, so
    # within 1e-2 of -a / omega_1^2), and stays there: from rest it would swing to -2 a / k
    # (test_a_step_of_the_steady_acceleration_acts_from_its_sample_and_the_mode_rings).
    from ring_gyro_sim.core.gyro.operating_point import with_environment_response
    a = 100.0 * STANDARD_GRAVITY
    config = paper_config({**QUIET, 'scenario.acceleration': [a, 0.0]})
    run = Run(config)
    q0 = run.start_state[0][0]
    assert q0 == with_environment_response(config, None)[0][0]
    w1 = 2.0 * math.pi * config.modes.frequencies[0]
    assert q0 == pytest.approx(-a / w1 ** 2, rel=1e-2)
    q1 = run.full_model().advance_samples(2000).q[:, 0]  # 10 ms: 112 periods of omega_1
    assert np.max(np.abs(q1 / q0 - 1.0)) < 1e-3
    quiet = Run(paper_config(QUIET))  # without an environment the start is unchanged: rest
    assert not np.any(quiet.start_state[0])
