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
The read-out electronics' kernels (``core/kernels/readout.py``) on their own.

``iq_fit`` (the closed loop's synchronous demodulator, C2) against numpy's least squares, and
``pickoff_volts`` (E1) summed row by row, so that a sample's volts do not depend on the rows of
the call. Their callers are tested in ``test/core/gyro/test_control.py`` and
``test/core/gyro/test_electronics.py``.
"""

import math

import numpy as np
from ring_gyro_sim.core import kernels
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.gyro import electronics
from ring_gyro_sim.core.params import paper_config

GYRO = {'gyro.enabled': True, 'modes.companions': True, 'drive.amplitude': 0.0065,
        'drive.frequency': 15800.0}
"""The gyroscope's operating point (as ``test/core/gyro/test_electronics.py``)."""


def test_iq_fit_is_the_least_squares_fit_of_cos_sin_and_offset():
    # kernels.iq_fit (C2) against numpy's least squares on the same basis, and exact on a
    # noise-free signal: one 1 ms period at 200 kHz of a 15.8 kHz NCO phase (15.8 cycles,
    # not a whole number: a boxcar would leak), with the fit's three parameters known.
    rng = np.random.default_rng(5)
    phase = 2.0 * math.pi * 15800.0 * np.arange(200) / 200000.0 + 0.7
    clean = np.stack([0.3 * np.cos(phase) - 1.2 * np.sin(phase) + 0.05,
                      -2.0 * np.cos(phase) + 0.4 * np.sin(phase) - 0.1], axis=1)
    coef = np.empty((3, 2))
    kernels.iq_fit(phase, np.ascontiguousarray(clean), coef)
    np.testing.assert_allclose(coef, [[0.3, -2.0], [-1.2, 0.4], [0.05, -0.1]],
                               rtol=0.0, atol=1e-13)
    noisy = np.ascontiguousarray(clean + rng.normal(0.0, 0.5, clean.shape))
    kernels.iq_fit(phase, noisy, coef)
    basis = np.stack([np.cos(phase), np.sin(phase), np.ones_like(phase)], axis=1)
    expected, *_ = np.linalg.lstsq(basis, noisy, rcond=None)
    np.testing.assert_allclose(coef, expected, rtol=0.0, atol=1e-13)


def test_pickoff_volts_of_a_sample_do_not_depend_on_the_rows_of_the_call():
    # kernels.pickoff_volts (E1) sums the electrodes in order, row by row: one row alone and
    # the same row among 2 000 give the same bits (numpy.matmul's BLAS did not), and the
    # value is the matrix product to rounding.
    config = paper_config(GYRO)
    pick = electronics.PickOff(config, Simulator(config))  # as SenseElectronics builds it
    rng = np.random.default_rng(3)
    shape = (2000, pick.rest_capacitance.size)
    cap = pick.rest_capacitance * (1.0 + 1e-3 * rng.standard_normal(shape))
    many = pick.clean_volts(cap)
    for s in (0, 1, 999, 1999):
        one = np.empty((1, many.shape[1]))
        kernels.pickoff_volts(np.ascontiguousarray(cap[s:s + 1]), pick.rest_capacitance,
                              pick.volts_per_farad, one)
        assert np.array_equal(one[0], many[s])
    reference = (cap - pick.rest_capacitance) @ pick.volts_per_farad
    np.testing.assert_allclose(many, reference, rtol=0.0, atol=1e-12 * np.abs(reference).max())
