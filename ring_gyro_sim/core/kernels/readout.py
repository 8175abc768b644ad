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
Kernels of the read-out electronics: the pick-off amplifiers' volts and the I/Q fit.

:func:`pickoff_volts` (E1, ``core/electronics.py``) and :func:`iq_fit` (the synchronous
demodulator of the closed loop, C2, ``core/control.py``) sum in a fixed order, so that a
sample's value does not depend on how many samples a call holds.
"""

import math

from numba import njit

__all__ = ['pickoff_volts', 'iq_fit']


@njit(cache=True, nogil=True)
def pickoff_volts(capacitance, rest, volts_per_farad, out):
    """
    ``out[s, j] = sum_e (C[s, e] - C0[e]) G[e, j]``: the pick-off amplifiers' outputs (E1), V.

    Summed over the electrodes in their order, row by row, so that a sample's value does not
    depend on how many samples a call holds: ``numpy.matmul`` goes through BLAS, whose kernels
    for one row and for many round differently (a run cut into calls of 1 sample and one of
    12 000 samples differed in the last bits of the demodulator's output).

    Parameters
    ----------
    capacitance : ndarray, shape (S, K)
        Electrode capacitances, F.
    rest : ndarray, shape (K,)
        Their rest values, F.
    volts_per_farad : ndarray, shape (K, J)
        Gains, V/F.
    out : ndarray, shape (S, J)
        The outputs, V.

    """
    n_s, n_k = capacitance.shape
    n_j = volts_per_farad.shape[1]
    for s in range(n_s):
        for j in range(n_j):
            acc = 0.0
            for e in range(n_k):
                acc += (capacitance[s, e] - rest[e]) * volts_per_farad[e, j]
            out[s, j] = acc


@njit(cache=True, nogil=True)
def iq_fit(phase, volts, coef):
    """
    Least squares of each column of ``volts`` on ``cos(phase), sin(phase), 1``, into ``coef``.

    The closed loop's synchronous demodulator (``core/control.py``, C2): the normal equations
    (3 x 3, summed over the samples in their order) solved by Cramer's rule, for every column
    at once: one compiled loop, not ``np.linalg.solve`` on numpy's products, whose Python and
    BLAS call overhead would dominate a 1 ms loop period.

    Parameters
    ----------
    phase : ndarray, shape (N,)
        NCO phase at each sample, rad.
    volts : ndarray, shape (N, J)
        The signals, V.
    coef : ndarray, shape (3, J)
        ``(a, b, c)`` of ``a cos(phase) + b sin(phase) + c`` per column, V.

    """
    n = phase.size
    n_j = volts.shape[1]
    scc = 0.0
    scs = 0.0
    sc = 0.0
    sss = 0.0
    ss = 0.0
    for j in range(n_j):
        coef[0, j] = 0.0
        coef[1, j] = 0.0
        coef[2, j] = 0.0
    for k in range(n):
        c = math.cos(phase[k])
        s = math.sin(phase[k])
        scc += c * c
        scs += c * s
        sc += c
        sss += s * s
        ss += s
        for j in range(n_j):
            value = volts[k, j]
            coef[0, j] += c * value
            coef[1, j] += s * value
            coef[2, j] += value
    m = float(n)
    # the cofactors of the symmetric matrix [[scc, scs, sc], [scs, sss, ss], [sc, ss, m]]
    c00 = sss * m - ss * ss
    c01 = sc * ss - scs * m
    c02 = scs * ss - sss * sc
    c11 = scc * m - sc * sc
    c12 = scs * sc - scc * ss
    c22 = scc * sss - scs * scs
    det = scc * c00 + scs * c01 + sc * c02
    for j in range(n_j):
        r0 = coef[0, j]
        r1 = coef[1, j]
        r2 = coef[2, j]
        coef[0, j] = (c00 * r0 + c01 * r1 + c02 * r2) / det
        coef[1, j] = (c01 * r0 + c11 * r1 + c12 * r2) / det
        coef[2, j] = (c02 * r0 + c12 * r1 + c22 * r2) / det
