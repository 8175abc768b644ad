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
Random base vibration: a test profile (PSD in g^2/Hz) made a seeded periodic multisine.

The profile
-----------
A one-sided acceleration PSD given at points ``(f_i, S_i)``, log-log between them (straight
lines in dB over octaves, as MIL-STD-810 and IEC 60068-2-64 write profiles), zero outside
``[f_0, f_last]`` (:func:`psd_at`). Its integral is the mean square (:func:`psd_mean_square`:
per segment ``S_i f_i / (b + 1) ((f_(i+1) / f_i)^(b + 1) - 1)``, ``b`` the segment's slope,
``S_i f_i ln(f_(i+1) / f_i)`` at ``b = -1``): the rms in g a datasheet states.

The generator
-------------
A random-phase multisine of period ``T_p = N / output.rate`` (:func:`period_samples`: the
power of two of at least :data:`PERIOD_TARGET_S` of samples, within
[:data:`MIN_PERIOD_SAMPLES`, :data:`MAX_PERIOD_SAMPLES`]; 2^20 = 5.24 s at 200 kHz)::

    a(n) = sum_k A_k cos(2 pi k n / N + phi_k),   A_k = sqrt(2 S(f_k) df),  df = 1 / T_p,

over the lines ``f_k = k df`` inside the profile's band, built once by an inverse real FFT
into a table of N samples; the base acceleration at output sample ``n`` is
``table[n mod N]``. So

* it is a function of the sample index: independent of how the run is cut, and a recording
  (which holds the parameters and ``gyro.noise_seed``) re-simulates it bit for bit;
* over one period its mean square is ``sum_k S(f_k) df`` exactly, and its periodogram at
  resolution ``df`` is the profile in every line: the amplitudes are deterministic (the
  "periodic random" or pseudo-random excitation of vibration controllers), only the phases are
  random (Gaussian amplitudes would scatter each line's power by 100 % and the mean square of
  a finite record with them). With thousands of lines the values are nearly Gaussian all the
  same: the expected kurtosis is ``3 - 3 / (2 M)`` for M equal lines (a Gaussian's: 3);
* the phases ``phi_k = atan2(z_2, z_1)`` come from row ``k`` of the counter-based normals
  (``core.noise``, :data:`~ring_gyro_sim.core.noise.STREAM_VIBRATION`, width 2: uniform
  angles), so each line's phase depends on ``(gyro.noise_seed, k)`` only: a change of the
  profile's levels or band at run time keeps the phases of the lines that stay, and the
  stream is independent of the thermomechanical noise's;
* it repeats after ``T_p``: records longer than that are not independent realisations (a
  PSD estimate finer than ``df`` sees lines, not a continuum; a bias averaged over whole
  periods is exact, not a sample).

The kernel interpolates the samples linearly (as it does the sine's): a line's amplitude is
``sinc^2(f_k / output.rate)`` of ``A_k``, so the profile is limited to ``output.rate / 40``
(0.2 % of amplitude at the top) like the sine.
"""

from functools import lru_cache
import math
from typing import Sequence, Tuple

import numpy as np

__all__ = ['PERIOD_TARGET_S', 'MIN_PERIOD_SAMPLES', 'MAX_PERIOD_SAMPLES', 'MIN_LINES',
           'psd_at', 'psd_mean_square', 'period_samples', 'RandomVibration',
           'random_vibration']

PERIOD_TARGET_S = 5.0
"""The multisine's period is the power of two of at least this many seconds of samples."""
MIN_PERIOD_SAMPLES = 2 ** 16
MAX_PERIOD_SAMPLES = 2 ** 23
"""At most 2^23 samples (a 64 MB table): 0.84 s at the 10 MHz top output rate."""
MIN_LINES = 10
"""A profile's band must hold at least this many lines ``k df`` (else it is refused)."""


def psd_at(freqs: Sequence[float], values: Sequence[float], f: np.ndarray) -> np.ndarray:
    """Return the profile's PSD (units of ``values``) at ``f``: log-log, 0 outside its band."""
    lf = np.log(np.asarray(freqs, dtype=np.float64))
    lv = np.log(np.asarray(values, dtype=np.float64))
    f = np.asarray(f, dtype=np.float64)
    inside = (f >= freqs[0]) & (f <= freqs[-1])
    out = np.zeros(f.shape)
    out[inside] = np.exp(np.interp(np.log(f[inside]), lf, lv))
    return out


def psd_mean_square(freqs: Sequence[float], values: Sequence[float]) -> float:
    """Return the integral of the log-log profile over its band (g^2 for values in g^2/Hz)."""
    total = 0.0
    for f1, f2, s1, s2 in zip(freqs, freqs[1:], values, values[1:]):
        ratio = f2 / f1
        b = math.log(s2 / s1) / math.log(ratio)
        if abs(b + 1.0) < 1e-12:
            total += s1 * f1 * math.log(ratio)
        else:
            total += s1 * f1 / (b + 1.0) * (ratio ** (b + 1.0) - 1.0)
    return total


def period_samples(output_rate: float) -> int:
    """Return N, the multisine's period in output samples at ``output_rate`` (Hz)."""
    want = max(1.0, PERIOD_TARGET_S * output_rate)
    n = 1 << int(math.ceil(math.log2(want) - 1e-12))
    return int(min(MAX_PERIOD_SAMPLES, max(MIN_PERIOD_SAMPLES, n)))


class RandomVibration:
    """
    The multisine of one profile (module doc): its lines and its table of one period.

    Attributes
    ----------
    n : int
        Period, output samples.
    df : float
        Line spacing 1 / T_p, Hz.
    lines : ndarray of int
        Line numbers k (frequency ``k df``) inside the band.
    amplitudes : ndarray
        Peak ``A_k`` of each line, m/s^2 (``sqrt(2 S(f_k) df)``).
    phases : ndarray
        ``phi_k``, rad.
    table : ndarray, read-only
        ``a(n)`` over one period, m/s^2 (along the vibration's direction).
    rms_g : float
        The profile's rms, g (the integral of the PSD, :func:`psd_mean_square`).

    """

    def __init__(self, freqs: Tuple[float, ...], values: Tuple[float, ...],
                 output_rate: float, seed: int, g: float) -> None:
        self.n = period_samples(output_rate)
        self.df = output_rate / self.n
        k_lo = max(1, int(math.ceil(freqs[0] / self.df - 1e-9)))
        k_hi = min(self.n // 2 - 1, int(math.floor(freqs[-1] / self.df + 1e-9)))
        self.lines = np.arange(k_lo, k_hi + 1, dtype=np.int64)
        psd = psd_at(freqs, values, self.lines * self.df) * (g * g)  # (m/s^2)^2 / Hz
        self.amplitudes = np.sqrt(2.0 * psd * self.df)
        # (imported here: core.params checks profiles with this module without loading numba)
        from ring_gyro_sim.core import noise
        z = noise.normals(seed, noise.STREAM_VIBRATION, k_lo, self.lines.size, 2)
        self.phases = np.arctan2(z[:, 1], z[:, 0])
        spectrum = np.zeros(self.n // 2 + 1, dtype=np.complex128)
        spectrum[self.lines] = 0.5 * self.n * self.amplitudes * np.exp(1j * self.phases)
        self.table = np.fft.irfft(spectrum, n=self.n)
        self.table.flags.writeable = False
        self.rms_g = math.sqrt(psd_mean_square(freqs, values))

    def at(self, indices: np.ndarray) -> np.ndarray:
        """Return ``a`` (m/s^2) at output sample indices (any integers: periodic)."""
        return self.table[np.mod(indices, self.n)]


@lru_cache(maxsize=2)
def random_vibration(freqs: Tuple[float, ...], values: Tuple[float, ...],
                     output_rate: float, seed: int, g: float) -> RandomVibration:
    """Return the :class:`RandomVibration` of these arguments (memoised: built once)."""
    return RandomVibration(tuple(freqs), tuple(values), float(output_rate), int(seed),
                           float(g))
