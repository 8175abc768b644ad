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
The output channels' kernel (core/kernels/channels.py) on its own.

The grid maximum's first index, found in independent lanes, is the one a plain scan finds (ties,
every length around the lane width); a sample's channels do not depend on the other samples of
the call (the node's blocks and the closed loop's 1 ms stretches cut a run differently). Their
accuracy against brute force is test/core/test_outputs.py's.
"""

import numpy as np
import pytest
from ring_gyro_sim.core import kernels
from ring_gyro_sim.core.engine.full import Simulator
from ring_gyro_sim.core.kernels.channels import _first_argmax, _LANES
from ring_gyro_sim.core.params import paper_config


@pytest.mark.parametrize('m', [1, 2, _LANES - 1, _LANES, _LANES + 1, 3 * _LANES, 3 * _LANES + 5])
def test_first_argmax_is_the_first_index_of_the_largest(m):
    rng = np.random.default_rng(m)
    lanes = np.empty(_LANES)
    for _ in range(50):
        w = rng.integers(0, 4, m + 3).astype(float)  # many ties; a tail past m never counts
        assert _first_argmax(w, m, lanes) == int(np.argmax(w[:m]))


def test_a_samples_channels_do_not_depend_on_the_rest_of_the_call():
    sim = Simulator(paper_config({'modes.companions': True, 'drive.amplitude': 0.0,
                                  'drive.start_on': 'rest'}))
    geometry = sim._output_geometry
    rng = np.random.default_rng(2)
    n = sim.model.n_coordinates
    q = rng.uniform(-1.0, 1.0, (300, n))
    # |w| from 20 % of the gap to contact, so that some electrodes are refined
    q *= geometry.gap * rng.uniform(0.2, 1.1, (300, 1)) / np.abs(q).sum(axis=1, keepdims=True)
    k = geometry.centre_shapes.shape[1]

    def channels(rows):
        out = kernels.Channels(gap=np.empty((len(rows), k)), min_gap=np.empty(len(rows)),
                               capacitance=np.empty((len(rows), k)))
        kernels.output_channels(np.ascontiguousarray(rows), geometry, out)
        return out

    many = channels(q)
    for s in (0, 1, 150, 299):
        one = channels(q[s:s + 1])
        for name in kernels.Channels._fields:
            assert np.array_equal(getattr(one, name)[0], getattr(many, name)[s]), name
