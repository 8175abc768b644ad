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

"""The splitting's coefficients (core/kernels/splitting.py): consistent and symmetric."""

import numpy as np
import pytest
from ring_gyro_sim.core.kernels.splitting import splitting_coefficients


@pytest.mark.parametrize('method, drifts', [('strang', 1), ('bm4', 6), ('bm6', 11)])
def test_coefficients_are_consistent_and_symmetric(method, drifts):
    a, b = splitting_coefficients(method)
    assert a.size == drifts and b.size == drifts + 1  # BAB: one kick more than drifts
    assert abs(a.sum() - 1.0) < 1e-15 and abs(b.sum() - 1.0) < 1e-15
    assert np.array_equal(a, a[::-1]) and np.array_equal(b, b[::-1])  # symmetric: time-reversible


def test_an_unknown_method_is_refused():
    with pytest.raises(ValueError, match='integrator.method'):
        splitting_coefficients('rk4')
