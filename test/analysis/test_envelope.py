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
Tests of analysis/envelope.py against analytic signals.

References: an amplitude-modulated carrier (envelope known in closed form), a linear chirp
(instantaneous frequency known in closed form) and a sampled sinusoid (peak known).
"""

import math

import numpy as np
import pytest
from ring_gyro_sim.analysis import envelope as env

RATE = 50000.0
CARRIER = 1003.7
"""Not a whole number of periods in the record: the FFT edges are not periodic."""


def am_signal(duration=0.5, depth=0.5, mod_hz=3.3):
    t = np.arange(int(duration * RATE)) / RATE
    a = 1.0 + depth * np.cos(2.0 * math.pi * mod_hz * t + 0.4)
    return t, a, a * np.cos(2.0 * math.pi * CARRIER * t + 0.3)


def test_analytic_envelope_of_am_signal():
    t, a, x = am_signal()
    e = env.analytic_envelope(x)
    inner = slice(int(0.02 * RATE), -int(0.02 * RATE))
    assert np.max(np.abs(e[inner] - a[inner])) < 2e-3
    # the mirror padding keeps the edges usable too
    assert np.max(np.abs(e - a)) < 3e-2


def test_mirror_padding_beats_plain_fft_at_the_edges():
    t, a, x = am_signal()
    edge = slice(0, int(0.005 * RATE))
    err_padded = np.max(np.abs(env.analytic_envelope(x)[edge] - a[edge]))
    err_plain = np.max(np.abs(env.analytic_envelope(x, pad=0)[edge] - a[edge]))
    assert err_padded < 0.5 * err_plain


def test_peak_envelope_of_am_signal_matches_the_modulation():
    t, a, x = am_signal()
    e = env.peak_envelope(t, x, window_s=5e-3)
    # |x| peaks where the carrier phase is a multiple of pi (to O((a' / (a omega))^2))
    m = np.arange(1, int(2 * CARRIER * t[-1]) + 3)
    t_peak = (m * math.pi - 0.3) / (2.0 * math.pi * CARRIER)
    a_peak = 1.0 + 0.5 * np.cos(2.0 * math.pi * 3.3 * t_peak + 0.4)
    ours = e.channel('x0')
    assert e.values.shape == (e.t.size, 1)
    for w in range(e.t.size):
        # crests inside the window, and those within a quarter period outside (their flank
        # can hold the window's largest sample, and the sine fit then finds their crest)
        t0, t1 = e.t[w] - 0.5 * e.window_s, e.t[w] + 0.5 * e.window_s
        inside = a_peak[(t_peak >= t0) & (t_peak < t1)].max()
        margin = 0.25 / CARRIER
        touching = a_peak[(t_peak >= t0 - margin) & (t_peak < t1 + margin)].max()
        assert inside * (1.0 - 1e-4) <= ours[w] <= touching * (1.0 + 1e-4), w
    assert e.window_s == pytest.approx(5e-3)


def test_sine_refinement_recovers_a_coarsely_sampled_peak():
    # 4.37 samples per period (about the 1theta mode at 50 kHz), three periods per window:
    # the raw largest sample misses the crest by up to a few %
    f = RATE / 4.37
    t = np.arange(20000) / RATE
    x = 2.0 * np.sin(2.0 * math.pi * f * t + 0.1)
    refined = env.peak_envelope(t, x, window_s=3.0 / f).channel('x0')
    n = int(round(3.0 / f * RATE))
    raw = np.max(np.abs(x[:refined.size * n].reshape(-1, n)), axis=1)
    assert np.max(np.abs(raw - 2.0)) > 0.01
    # exact wherever the crest sample has a usable neighbour triple (not at a window edge
    # next to a zero crossing, where the raw sample is kept); never worse than raw
    assert np.mean(np.abs(refined - 2.0) < 1e-9) > 0.9
    assert np.all(np.abs(refined - 2.0) <= np.abs(raw - 2.0) + 1e-12)


def test_streaming_envelope_does_not_depend_on_chunking():
    t, a, x = am_signal()
    data = np.column_stack([x, 2.0 * x])
    whole = env.StreamingEnvelope(RATE, ['a', 'b'], 1e-3)
    whole.add(data)
    pieces = env.StreamingEnvelope(RATE, ['a', 'b'], 1e-3)
    rng = np.random.default_rng(1)
    cuts = np.sort(rng.integers(0, data.shape[0], 40))
    for chunk in np.split(data, cuts):
        pieces.add(chunk)
    r1, r2 = whole.result(), pieces.result()
    np.testing.assert_array_equal(r1.values, r2.values)
    np.testing.assert_array_equal(r1.t, r2.t)
    np.testing.assert_allclose(r1.channel('b'), 2.0 * r1.channel('a'))


def test_instantaneous_frequency_of_a_linear_chirp():
    f0, k = 10.6e3, 1200.0   # Hz, Hz/s: the 1theta drift of Fig. 7, compressed
    t = np.arange(int(0.5 * RATE)) / RATE
    x = np.cos(2.0 * math.pi * (f0 * t + 0.5 * k * t ** 2))
    f = env.instantaneous_frequency(x, RATE)
    inner = slice(int(0.02 * RATE), -int(0.02 * RATE))
    assert np.max(np.abs(f[inner] - (f0 + k * t[inner]))) < 0.5


def test_bandpass_isolates_the_fundamental_before_the_frequency():
    rate = 200000.0   # 3 omega_1 must not alias
    t = np.arange(int(0.2 * rate)) / rate
    x = np.cos(2.0 * math.pi * 11e3 * t) + 0.3 * np.cos(2.0 * math.pi * 33e3 * t + 1.0)
    raw = env.instantaneous_frequency(x, rate)
    filtered = env.instantaneous_frequency(x, rate, band_hz=(9.5e3, 12.5e3))
    inner = slice(4000, -4000)   # past the filter's edge transients (20 ms)
    assert np.max(np.abs(raw[inner] - 11e3)) > 1e3    # the harmonic makes the phase wobble
    # what is left is the 33 kHz line attenuated ~80 dB: a wobble of ~2 Hz
    assert np.max(np.abs(filtered[inner] - 11e3)) < 5.0


def test_spectrogram_ridge_follows_a_chirp():
    f0, k = 10.6e3, 600.0
    t = np.arange(int(1.0 * RATE)) / RATE
    x = np.cos(2.0 * math.pi * (f0 * t + 0.5 * k * t ** 2))
    spec = env.spectrogram(x, RATE, segment_s=10e-3, overlap=0.5)
    ridge = spec.ridge((9.5e3, 12e3))
    assert spec.power.shape == (spec.f.size, spec.t.size)
    assert np.max(np.abs(ridge - (f0 + k * spec.t))) < 10.0   # bins are 100 Hz wide


def test_invalid_inputs_raise_value_errors_naming_the_argument():
    with pytest.raises(ValueError, match='sample_rate_hz'):
        env.instantaneous_frequency(np.ones(10), 0.0)
    with pytest.raises(ValueError, match='band_hz'):
        env.bandpass(np.ones(100), 1000.0, (100.0, 600.0))
    with pytest.raises(ValueError, match='x'):
        env.analytic_envelope([1.0, np.nan, 2.0, 3.0])
    with pytest.raises(ValueError, match='chunk'):
        env.StreamingEnvelope(RATE, ['a', 'b']).add(np.ones((5, 3)))
    with pytest.raises(KeyError):
        env.peak_envelope(np.arange(10.0), np.ones(10), window_s=3.0).channel('nope')
