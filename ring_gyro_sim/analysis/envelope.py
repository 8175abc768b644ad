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
Envelopes, instantaneous frequency and spectrograms of modal time histories.

Two envelope methods, both documented and tested against analytic signals:

* **Analytic signal** (:func:`analytic_envelope`): ``|x + i H[x]|`` with the Hilbert
  transform computed by FFT (``scipy.signal.hilbert``). The FFT assumes a periodic signal, so
  the record is continued at both ends by a linear predictor (and faded out) before the FFT;
  the padding is cut off afterwards (:func:`analytic_signal`). Exact for a narrow-band
  signal; a multi-frequency signal gives a beating envelope.
* **Windowed peaks** (:func:`peak_envelope`, :class:`StreamingEnvelope`): the largest ``|x|``
  in consecutive windows, each refined by the sinusoid through the peak sample and its two
  neighbours (exact for a sinusoid sampled at least 4 times per period). This is the
  "positive envelope" of the paper (section 3.3: local maxima in short windows) and it is
  also the decimation used for runs of many seconds: the streaming version keeps one value
  per window and per channel, never the full record.

:func:`instantaneous_frequency` differentiates the unwrapped phase of the analytic signal
(optionally after a band-pass around the component of interest) and :func:`spectrogram`
wraps ``scipy.signal.spectrogram`` with the settings used for Fig. 7. Times in s, frequencies
in Hz, amplitudes in the unit of the input (m for modal coordinates).
"""

from dataclasses import dataclass
import math
from typing import Optional, Sequence, Tuple

import numpy as np
from scipy import signal

DEFAULT_WINDOW_S = 1e-3
"""Envelope window, s: 11 periods of the 1theta mode, 16 of the drive."""


def _check_rate(sample_rate_hz: float) -> float:
    rate = float(sample_rate_hz)
    if not (math.isfinite(rate) and rate > 0.0):
        raise ValueError(f'sample_rate_hz: must be > 0, got {sample_rate_hz!r}')
    return rate


def _as_signal(x, name: str = 'x') -> np.ndarray:
    arr = np.asarray(x, dtype=np.float64)
    if arr.ndim != 1 or arr.size < 3:
        raise ValueError(f'{name}: expected a 1-D array of at least 3 samples, '
                         f'got shape {arr.shape}')
    if not np.all(np.isfinite(arr)):
        raise ValueError(f'{name}: contains non-finite values')
    return arr


def _extrapolate(x: np.ndarray, n: int, order: int, fit: int) -> np.ndarray:
    """
    Continue ``x`` by ``n`` samples with a least-squares linear predictor of ``order``.

    The predictor ``x[k] = sum_j a_j x[k - j]`` is fitted on the last ``fit`` samples; a
    sum of ``order / 2`` sinusoids is continued exactly. Values are clipped to twice the
    largest ``|x|`` of the fit window, so an unstable predictor cannot blow up.
    """
    seg = x[-fit:]
    rows = np.column_stack([seg[order - j - 1:fit - j - 1] for j in range(order)])
    coef = np.linalg.lstsq(rows, seg[order:], rcond=None)[0]
    lim = 2.0 * float(np.max(np.abs(seg)))
    out = np.empty(n)
    hist = list(seg[-order:][::-1])
    for i in range(n):
        v = min(lim, max(-lim, float(np.dot(coef, hist[:order]))))
        out[i] = v
        hist.insert(0, v)
    return out


def analytic_signal(x, pad: Optional[int] = None, order: int = 8) -> np.ndarray:
    """
    Analytic signal ``x + i H[x]`` with predicted (not mirrored) padding at both edges.

    Parameters
    ----------
    x : array_like, shape (K,)
        Real signal sampled uniformly.
    pad : int, optional
        Samples added at each end (default ``min(K, 1024)``; 0 = plain FFT).
    order : int
        Order of the linear predictor that continues the signal (4 sinusoids for 8).

    Returns
    -------
    ndarray of complex, shape (K,)
        The analytic signal on the original samples.

    Notes
    -----
    The FFT treats the record as periodic, so a plain Hilbert transform is wrong by up to
    tens of percent over the first and last few periods. Mirroring the record does not cure
    it (the kink at the mirror leaks as much). The record is instead continued at each end
    by a least-squares linear predictor fitted on its last ``64 order`` samples, and the
    outer half of each continuation is faded out with a cosine taper; for a narrow-band
    signal the edge error falls to the level of the interior (``test_envelope.py``).

    """
    x = _as_signal(x)
    k = x.size
    pad = min(k, 1024) if pad is None else int(pad)
    if pad < 0:
        raise ValueError(f'pad: must be >= 0, got {pad!r}')
    fit = min(k, 64 * order)
    if pad == 0 or fit < 4 * order:
        return signal.hilbert(x)
    tail = _extrapolate(x, pad, order, fit)
    head = _extrapolate(x[::-1], pad, order, fit)[::-1]
    xp = np.concatenate([head, x, tail])
    half = max(1, pad // 2)
    ramp = 0.5 * (1.0 - np.cos(math.pi * np.arange(half) / half))
    xp[:half] *= ramp
    xp[-half:] *= ramp[::-1]
    return signal.hilbert(xp)[pad:pad + k]


def analytic_envelope(x, pad: Optional[int] = None) -> np.ndarray:
    """
    Envelope ``|x + i H[x]|`` of a zero-mean oscillating signal (same unit as ``x``).

    See :func:`analytic_signal` for the edge handling. ``x`` is not de-meaned: remove a
    static offset first if there is one.
    """
    return np.abs(analytic_signal(x, pad))


def bandpass(x, sample_rate_hz: float, band_hz: Tuple[float, float], order: int = 4
             ) -> np.ndarray:
    """
    Zero-phase Butterworth band-pass (``sosfiltfilt``), to isolate one spectral line.

    Parameters
    ----------
    x : array_like, shape (K,)
        Signal.
    sample_rate_hz : float
        Sampling rate, Hz.
    band_hz : (float, float)
        Pass band, Hz (``0 < low < high < rate / 2``).
    order : int
        Filter order (doubled by the forward-backward pass).

    """
    x = _as_signal(x)
    rate = _check_rate(sample_rate_hz)
    low, high = (float(b) for b in band_hz)
    if not 0.0 < low < high < 0.5 * rate:
        raise ValueError(f'band_hz: need 0 < low < high < {0.5 * rate} Hz, got {band_hz!r}')
    sos = signal.butter(order, [low, high], btype='bandpass', fs=rate, output='sos')
    return signal.sosfiltfilt(sos, x)


def instantaneous_frequency(x, sample_rate_hz: float,
                            band_hz: Optional[Tuple[float, float]] = None,
                            pad: Optional[int] = None) -> np.ndarray:
    """
    Instantaneous frequency, Hz: derivative of the unwrapped analytic-signal phase.

    Parameters
    ----------
    x : array_like, shape (K,)
        Signal.
    sample_rate_hz : float
        Sampling rate, Hz.
    band_hz : (float, float), optional
        Band-pass first (:func:`bandpass`), e.g. around the 1theta line to remove its
        harmonics and the combination tones.
    pad : int, optional
        Mirror padding of :func:`analytic_signal`.

    Returns
    -------
    ndarray, shape (K,)
        Frequency at each sample, Hz (centred differences, one-sided at the ends).

    """
    rate = _check_rate(sample_rate_hz)
    x = _as_signal(x)
    if band_hz is not None:
        x = bandpass(x, rate, band_hz)
    phase = np.unwrap(np.angle(analytic_signal(x, pad)))
    return np.gradient(phase) * rate / (2.0 * math.pi)


@dataclass(frozen=True)
class Envelope:
    """
    Windowed positive envelope of one or several channels.

    Attributes
    ----------
    t : ndarray, shape (W,)
        Time of each window's peak, s (per channel the peaks differ; this is the window
        centre).
    values : ndarray, shape (W, C)
        Largest ``|x|`` in each window (sine-fit refined), in the unit of the input.
    names : tuple of str
        Channel names.
    window_s : float
        Window length, s.

    """

    t: np.ndarray
    values: np.ndarray
    names: Tuple[str, ...]
    window_s: float

    def channel(self, name: str) -> np.ndarray:
        """Envelope of channel ``name``, shape (W,)."""
        try:
            return self.values[:, self.names.index(name)]
        except ValueError:
            raise KeyError(f'no channel {name!r} (have {self.names})') from None

    def mean_over(self, name: str, t0_s: float, t1_s: float) -> float:
        """Mean envelope of ``name`` over windows with centre in ``[t0_s, t1_s]``."""
        sel = (self.t >= t0_s) & (self.t <= t1_s)
        if not np.any(sel):
            return math.nan
        return float(np.mean(self.channel(name)[sel]))


def _refined_peaks(block: np.ndarray) -> np.ndarray:
    """
    Largest ``|x|`` of each window of ``block`` (shape (W, L, C)), refined by a sine fit.

    Three consecutive samples ``y_-1, y_0, y_1`` of ``A cos(delta k + phi)`` satisfy
    ``y_-1 + y_1 = 2 y_0 cos(delta)``; the phase step ``delta`` is taken from the triple
    centred on the largest interior sample. The crest sample ``y_i`` and a neighbour
    ``y_n`` then give ``A = sqrt(y_i^2 + ((y_i cos(delta) - y_n) / sin(delta))^2)``: exact
    for a sinusoid at any rate above 4 samples per period, also when the crest sample sits
    on the window edge. Where the samples are not those of a sinusoid (``cos delta >= 1``)
    or hold fewer than 4 samples per period (``cos delta < 0``, where a multi-frequency
    signal fools the fit) the raw peak is kept; the result is bounded by
    ``peak / cos(delta / 2)`` (the true crest lies within half a sample of the largest
    sample). A crest just outside the window whose flank holds the window's largest sample
    is attributed to the window.
    """
    a = np.abs(block)
    length = a.shape[1]
    rows = np.arange(a.shape[0])[:, None]
    cols = np.arange(a.shape[2])[None, :]
    i = np.argmax(a, axis=1)  # (W, C)
    peak = a[rows, i, cols]
    j = 1 + np.argmax(a[:, 1:-1, :], axis=1)
    y0, ym, yp = block[rows, j, cols], block[rows, j - 1, cols], block[rows, j + 1, cols]
    yi = block[rows, i, cols]
    yn = block[rows, np.where(i < length - 1, i + 1, i - 1), cols]
    with np.errstate(divide='ignore', invalid='ignore'):
        c = (ym + yp) / (2.0 * y0)
        ok = (np.abs(y0) >= 0.5 * peak) & (c >= 0.0) & (c < 1.0 - 1e-12)
        c = np.where(ok, c, 0.0)
        sin_d = np.sqrt(1.0 - c * c)
        other = (yi * c - yn) / sin_d
        amp = np.sqrt(yi * yi + other * other)  # invariant under x -> -x
        bound = peak / np.sqrt(0.5 * (1.0 + c))  # peak / cos(delta / 2)
    return np.where(ok, np.clip(amp, peak, bound), peak)


class StreamingEnvelope:
    """
    Windowed positive envelope fed chunk by chunk (decimation of long runs).

    Parameters
    ----------
    sample_rate_hz : float
        Sampling rate of the chunks, Hz.
    names : sequence of str
        Channel names (columns of the chunks).
    window_s : float
        Window length, s (rounded to whole samples, at least 3).
    t0_s : float
        Time of the first sample fed, s.

    Notes
    -----
    Samples that do not fill a window are kept until the next chunk, so the result does not
    depend on how the record is cut. Each window's peak is refined by a three-point sine fit
    (see ``_refined_peaks``), exact for a single sinusoid.

    """

    def __init__(self, sample_rate_hz: float, names: Sequence[str],
                 window_s: float = DEFAULT_WINDOW_S, t0_s: float = 0.0) -> None:
        self.rate = _check_rate(sample_rate_hz)
        self.names = tuple(names)
        self.length = max(3, int(round(window_s * self.rate)))
        self.window_s = self.length / self.rate
        self.t0 = float(t0_s)
        self._pending = np.zeros((0, len(self.names)))
        self._values = []
        self._count = 0

    def add(self, chunk) -> None:
        """Feed samples, shape (K, C) (or (K,) for one channel)."""
        chunk = np.asarray(chunk, dtype=np.float64)
        if chunk.ndim == 1:
            chunk = chunk[:, None]
        if chunk.ndim != 2 or chunk.shape[1] != len(self.names):
            raise ValueError(f'chunk: expected shape (K, {len(self.names)}), got {chunk.shape}')
        data = np.concatenate([self._pending, chunk]) if self._pending.size else chunk
        full = data.shape[0] // self.length
        if full:
            block = data[:full * self.length].reshape(full, self.length, -1)
            self._values.append(_refined_peaks(block))
            self._count += full
        self._pending = data[full * self.length:].copy()

    def result(self) -> Envelope:
        """Return the envelope of the full windows fed so far (not a partial last one)."""
        values = (np.concatenate(self._values) if self._values
                  else np.zeros((0, len(self.names))))
        t = self.t0 + (np.arange(self._count) + 0.5) * self.window_s
        return Envelope(t=t, values=values, names=self.names, window_s=self.window_s)


def peak_envelope(t, x, window_s: float = DEFAULT_WINDOW_S,
                  names: Optional[Sequence[str]] = None) -> Envelope:
    """
    Windowed positive envelope of a uniformly sampled record.

    Parameters
    ----------
    t : array_like, shape (K,)
        Sample times, s (uniform).
    x : array_like, shape (K,) or (K, C)
        Channels.
    window_s : float
        Window, s: a few periods of the slowest oscillation.
    names : sequence of str, optional
        Channel names (default ``x0, x1, ...``).

    """
    t = np.asarray(t, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    if x.ndim == 1:
        x = x[:, None]
    if t.ndim != 1 or t.size < 3 or x.shape[0] != t.size:
        raise ValueError(f't, x: need K >= 3 samples in both, got {t.shape} and {x.shape}')
    dt = (t[-1] - t[0]) / (t.size - 1)
    names = tuple(names) if names is not None else tuple(f'x{i}' for i in range(x.shape[1]))
    acc = StreamingEnvelope(1.0 / dt, names, window_s, t0_s=t[0] - 0.5 * dt)
    acc.add(x)
    return acc.result()


@dataclass(frozen=True)
class Spectrogram:
    """
    Power spectral density against time (Fig. 7).

    Attributes
    ----------
    t : ndarray, shape (S,)
        Segment centres, s.
    f : ndarray, shape (F,)
        Frequencies, Hz.
    power : ndarray, shape (F, S)
        PSD, unit^2/Hz.

    """

    t: np.ndarray
    f: np.ndarray
    power: np.ndarray

    def ridge(self, band_hz: Tuple[float, float]) -> np.ndarray:
        """
        Frequency of the strongest line in ``band_hz`` for each segment, Hz.

        Refined by a parabola through the log-power of the peak bin and its neighbours.
        """
        low, high = band_hz
        sel = np.flatnonzero((self.f >= low) & (self.f <= high))
        if sel.size < 3:
            raise ValueError(f'band_hz: {band_hz!r} holds fewer than 3 frequency bins')
        p = np.log(np.maximum(self.power[sel], 1e-300))
        i = np.clip(np.argmax(p, axis=0), 1, sel.size - 2)
        cols = np.arange(p.shape[1])
        ym, y0, yp = p[i - 1, cols], p[i, cols], p[i + 1, cols]
        denom = ym - 2.0 * y0 + yp
        with np.errstate(divide='ignore', invalid='ignore'):
            shift = np.where(denom < 0.0, 0.5 * (ym - yp) / denom, 0.0)
        df = self.f[1] - self.f[0]
        return self.f[sel][i] + np.clip(shift, -0.5, 0.5) * df


def spectrogram(x, sample_rate_hz: float, segment_s: float = 5e-3,
                overlap: float = 0.5, t0_s: float = 0.0) -> Spectrogram:
    """
    Compute a sliding-window FFT spectrogram: Hann windows, PSD scaling.

    Parameters
    ----------
    x : array_like, shape (K,)
        Signal.
    sample_rate_hz : float
        Sampling rate, Hz.
    segment_s : float
        Segment length, s (frequency resolution ``1 / segment_s`` Hz before refinement).
    overlap : float
        Fraction of overlap between segments, in [0, 1).
    t0_s : float
        Time of the first sample, s.

    """
    x = _as_signal(x)
    rate = _check_rate(sample_rate_hz)
    if not 0.0 <= overlap < 1.0:
        raise ValueError(f'overlap: must be in [0, 1), got {overlap!r}')
    nper = min(x.size, max(8, int(round(segment_s * rate))))
    f, t, p = signal.spectrogram(x, fs=rate, window='hann', nperseg=nper,
                                 noverlap=int(overlap * nper), scaling='density')
    return Spectrogram(t=t + t0_s, f=f, power=p)
