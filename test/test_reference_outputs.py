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
The physics did not change: a short run of the paper's resonator against a stored reference.

``test/data/demo_reference.npz`` was written by ``test/data/make_demo_reference.py`` with the
tree before the run-path redesign, and regenerated with an unchanged tree when the
numerical libraries or the machine changed (CHANGELOG.md says when and why). Under the library
versions and on the CPU it records, every output channel must come out bit for bit the same
(the SHA-256 of each complete channel, and the stored samples for a readable diff). Under other
versions or on another CPU the last bits may move (the start state is a scipy shooting solve
through OpenBLAS, which picks its kernels by the CPU; the kernel is compiled by LLVM for the
host): then each stored sample must agree within :data:`OTHER_VERSIONS_TOLERANCE` of its
channel's peak, ten times the largest drift measured between two library generations (8.6e-11,
numpy 2.4 / scipy 1.17 / numba 0.68 against the earlier ones; two CPUs: 4.3e-11).
"""

import importlib.util
import pathlib

import numpy as np

HERE = pathlib.Path(__file__).resolve().parent
_SPEC = importlib.util.spec_from_file_location('make_demo_reference',
                                               HERE / 'data' / 'make_demo_reference.py')
make_demo_reference = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(make_demo_reference)


OTHER_VERSIONS_TOLERANCE = 1e-9
"""Largest difference from a stored sample, over its channel's peak, elsewhere."""


def test_demo_outputs_are_bit_identical_to_the_stored_reference():
    stored = np.load(HERE / 'data' / 'demo_reference.npz')
    channels = make_demo_reference.compute()
    here = f'{make_demo_reference.versions()};{make_demo_reference.machine()}'
    made = f'{stored["versions"]};{stored["machine"]}'
    same_versions = here == made
    for name in make_demo_reference.CHANNELS:
        got = channels[name][::make_demo_reference.DECIMATION]
        assert got.shape == stored[name].shape, name
        if not same_versions:
            peak = float(np.max(np.abs(stored[name])))
            worst = float(np.max(np.abs(got - stored[name])))
            assert worst <= OTHER_VERSIONS_TOLERANCE * peak, (
                f'{name}: max |delta| = {worst!r} is {worst / peak:.3g} of the peak (here '
                f'{here}, reference {made})')
            continue
        diff = np.flatnonzero((got != stored[name]).reshape(len(got), -1).any(axis=1))
        assert diff.size == 0, (
            f'{name}: {diff.size} stored samples differ, first at row {diff[:1]}: '
            f'max |delta| = {np.max(np.abs(got - stored[name]))!r}')
        assert make_demo_reference.digest(channels[name]) == str(stored[f'sha256_{name}']), \
            f'{name}: the complete channel differs from the reference (samples in between)'
