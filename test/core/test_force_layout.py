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
The force kernel's layout for speed changes no value: bit for bit against a plain loop.

``core/kernels.py`` evaluates Horner's rule several degrees per pass over the angles, forms
the parity combinations of the general path once per representative and sums the
projections per coordinate in registers (issue 11). Each value must get the same floating
point operations in the same order as the plain definition, written out here one angle and
one coordinate at a time (:func:`plain_force`), for every series degree (the passes of
three degrees have a remainder of 0, 1 or 2) and on both paths (states with and without
sine content).
"""

import numpy as np
import pytest
from ring_gyro_sim.core import forces, kernels
from ring_gyro_sim.core.params import build_config

FREQUENCIES = [11200.0, 15800.0, 22000.0, 36300.0, 59200.0]  # Table 1 of the paper


def plain_force(x, kernel):
    """nl_accel's definition, one angle and one coordinate at a time (module docstring)."""
    kb, proj, signs, poly = kernel.kbasis, kernel.projection, kernel.signs, kernel.poly
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
        value = 0.0  # Horner from 0: 0 u + top is top
        for d in range(poly.size - 1, -1, -1):
            value = value * u + poly[d]
        p[k] = value
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


@pytest.mark.parametrize('taylor_terms', [3, 4, 5, 6, 7, 10, 40])
@pytest.mark.parametrize('n_modes, companions', [(3, False), (3, True), (5, True)])
def test_kernel_force_is_the_plain_loop_bit_for_bit(taylor_terms, n_modes, companions):
    config = build_config({'modes.frequencies': FREQUENCIES[:n_modes],
                           'modes.quality_factors': [1e5] * n_modes,
                           'modes.companions': companions, 'drive.amplitude': 0.0,
                           'electrodes.taylor_terms': taylor_terms})
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
