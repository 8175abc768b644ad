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
The force kernel's layout for speed: each value's operations against a plain loop, bit for bit.

``core/kernels/force.py`` evaluates the series by Estrin's scheme in blocks of four coefficients
(or Horner's rule beyond 16), sums the angle values several coordinates per pass, forms the
parity combinations of the general path once per representative and sums the projections per
coordinate in registers. Each value must get the floating-point operations written
out here one angle and one coordinate at a time (:func:`plain_force`), for every series length
(4, 8, 12 and 16 slots, with and without the ``u^2`` factor of the folded model, and Horner's
rule) and on both paths (states with and without sine content). That the order is a good one
is checked against the polynomial's value in exact rational arithmetic.
"""

from fractions import Fraction

import numpy as np
import pytest
from ring_gyro_sim.core import forces, kernels
from ring_gyro_sim.core.params import paper_config

FREQUENCIES = [11200.0, 15800.0, 22000.0, 36300.0, 59200.0]  # Table 1 of the paper


def plain_series(u, kernel):
    """P(u) as kernels.force._series_values forms it, one value at a time."""
    c = [float(value) for value in kernel.series]
    if not c:
        value = 0.0  # Horner from 0: 0 u + top is top
        for d in range(kernel.poly.size - 1, -1, -1):
            value = value * u + kernel.poly[d]
        return value
    u2 = u * u
    u4 = u2 * u2
    scale = u2 if kernel.series_u2 else 1.0
    b = [(c[j] + c[j + 1] * u) + u2 * (c[j + 2] + c[j + 3] * u) for j in range(0, len(c), 4)]
    if len(b) == 1:
        value = b[0]
    elif len(b) == 2:
        value = b[0] + u4 * b[1]
    elif len(b) == 3:
        value = (b[0] + u4 * b[1]) + (u4 * u4) * b[2]
    else:
        value = (b[0] + u4 * b[1]) + (u4 * u4) * (b[2] + u4 * b[3])
    return value * scale


def plain_force(x, kernel):
    """nl_accel's definition, one angle and one coordinate at a time (module docstring)."""
    kb, proj, signs = kernel.kbasis, kernel.projection, kernel.signs
    n = x.size
    r = kb.shape[1] // 4
    even = not any(signs[1, i] < 0.0 and x[i] != 0.0 for i in range(n))
    m = 2 * r if even else 4 * r  # the half-circle rule without sine content
    p = np.empty(4 * r)
    for k in range(m):
        u = kb[0, k] * x[0]
        for i in range(1, n):
            if x[i] != 0.0:
                u += kb[i, k] * x[i]
        p[k] = plain_series(u, kernel)
    out = np.zeros(n)
    for i in range(n):
        s1, s2 = signs[0, i], signs[1, i]
        acc = 0.0
        for j in range(r):
            if even:
                if s2 > 0.0:
                    half = p[j] + s1 * p[r + j]
                    acc += proj[i, j] * (half + half)
            else:
                acc += proj[i, j] * ((p[j] + s1 * p[r + j])
                                     + s2 * (p[2 * r + j] + s1 * p[3 * r + j]))
        out[i] = acc
    return out


# Folded: Q = P / u^2 has N_T - 2 coefficients (3-6: 4 slots, 7-10: 8, 11-14: 12, 15-18:
# 16, 19 on: Horner); unfolded: P has N_T (3-4: 4, 5-8: 8, 9-12: 12, 13-16: 16, 17 on).
@pytest.mark.parametrize('taylor_terms, fold', [
    (3, True), (4, True), (5, True), (6, True), (7, True), (10, True), (11, True), (14, True),
    (15, True), (18, True), (19, True), (40, True),
    (3, False), (4, False), (5, False), (9, False), (10, False), (13, False), (17, False)])
@pytest.mark.parametrize('n_modes, companions', [(3, False), (3, True), (5, True)])
def test_kernel_force_is_the_plain_loop_bit_for_bit(taylor_terms, fold, n_modes, companions):
    config = paper_config({'modes.frequencies': FREQUENCIES[:n_modes],
                           'modes.quality_factors': [1e5] * n_modes,
                           'modes.companions': companions, 'drive.amplitude': 0.0,
                           'electrodes.taylor_terms': taylor_terms,
                           'electrodes.fold_linear_stiffness': fold})
    model = forces.build_force_model(config)
    n = model.n_coordinates
    rng = np.random.default_rng(11)
    work = np.empty(forces.scratch_size(model))
    info = np.zeros(2, dtype=np.int64)
    states = [rng.uniform(-1.0, 1.0, n) * 0.2 * config.electrodes.gap / n for _ in range(20)]
    if companions:  # without sine content: the common path (half circle)
        states += [np.concatenate([s[:n_modes], np.zeros(n_modes)]) for s in states[:10]]
    for x in states:
        out = np.full(n, np.nan)
        kernels.nl_accel(x, model.kernel, work, out, info)
        assert info[0] == 0
        expected = plain_force(x, model.kernel)
        assert np.array_equal(out, expected), (x, out - expected)


@pytest.mark.parametrize('taylor_terms, fold, slots',
                         [(6, True, 4), (10, True, 8), (14, True, 12), (18, True, 16),
                          (19, True, 0), (10, False, 12), (16, False, 16)])
def test_series_layout_and_its_values_against_exact_arithmetic(taylor_terms, fold, slots):
    config = paper_config({'modes.frequencies': FREQUENCIES[:3],
                           'modes.quality_factors': [1e5] * 3, 'drive.amplitude': 0.0,
                           'electrodes.taylor_terms': taylor_terms,
                           'electrodes.fold_linear_stiffness': fold})
    kernel = forces.build_force_model(config).kernel
    assert kernel.series.size == slots
    assert kernel.series_u2 == fold
    poly = [Fraction(float(c)) for c in kernel.poly]
    scale = float(sum(abs(c) for c in poly))
    for u in np.linspace(-0.97, 0.97, 41):
        exact = sum(c * Fraction(float(u)) ** d for d, c in enumerate(poly))
        # Estrin's scheme and Horner's rule are both backward stable here: a few ulps of the
        # sum of |c_d| (positive coefficients, |u| < 1).
        assert abs(plain_series(float(u), kernel) - float(exact)) <= 8e-16 * scale
