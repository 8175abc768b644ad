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
The recordings of the shipped configurations did not change: their digests against stored ones.

``test/data/recording_digests.json`` holds, per case of ``test/data/make_recording_digests.py``
(every run configuration of ``config/``, two of them with a drawn device, a temperature
profile or a vibration laid over), the SHA-256 of every topic's messages of a short
``ring_gyro run`` recording and of its ``--from`` re-simulation, made with the library versions
and on the CPU it names. A change that means to keep the behaviour keeps every digest; one
that means to change it regenerates the file and says why in CHANGELOG.md.

On the machine and versions it was made with, every digest must be equal. Elsewhere the last
bits of the start state and of the compiled kernels may move (``test/test_reference_outputs.py``
says why), so there the test checks what does not depend on them: the same topics with the same
numbers of messages, and a re-simulation equal to its recording byte for byte, topic by topic.
"""

import importlib.util
import json
import pathlib

import pytest

HERE = pathlib.Path(__file__).resolve().parent
_SPEC = importlib.util.spec_from_file_location('make_recording_digests',
                                               HERE / 'data' / 'make_recording_digests.py')
make_recording_digests = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(make_recording_digests)
STORED = json.loads((HERE / 'data' / 'recording_digests.json').read_text(encoding='utf-8'))


def _counts(topics):
    return {topic: value.split(':')[0] for topic, value in topics.items()}


@pytest.mark.ci
@pytest.mark.parametrize('case', sorted(STORED['cases']))
def test_a_recording_of_a_shipped_configuration_keeps_its_digests(case):
    got = make_recording_digests.compute([case])[case]
    stored = STORED['cases'][case]
    for kind in ('run', 'from'):
        assert _counts(got[kind]['topics']) == _counts(stored[kind]['topics']), kind
        assert sorted(got[kind]['metadata']) == sorted(stored[kind]['metadata']), kind
    # the re-simulation reproduces its recording byte for byte (all but the file's own name
    # in rosbag2's metadata)
    assert got['from']['topics'] == got['run']['topics']
    assert {k: v for k, v in got['from']['metadata'].items() if not k.startswith('rosbag2')} \
        == {k: v for k, v in got['run']['metadata'].items() if not k.startswith('rosbag2')}
    if make_recording_digests.versions_and_machine() != STORED['made_with']:
        return   # elsewhere: the structure and the re-simulation only (module docstring)
    for kind in ('run', 'from'):
        changed = sorted(topic for topic, value in got[kind]['topics'].items()
                         if stored[kind]['topics'][topic] != value)
        assert not changed, f'{case} {kind}: these topics changed: {changed}'
        assert got[kind]['metadata'] == stored[kind]['metadata'], f'{case} {kind}: metadata'


def _tiny_recording(path, values, temperature_k):
    from ring_gyro_sim.recording.writer import BagWriter
    from ring_gyro_sim.ros import conversions
    with BagWriter(str(path)) as writer:
        writer.add_topic('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray')
        writer.add_topic('/ring_gyro/die_temperature', 'sensor_msgs/msg/Temperature')
        writer.write('/diagnostics', conversions.diagnostics_message(
            1_000, 'ring_gyro: simulator', 'ring_gyro_sim:/ring_gyro', 'OK', 'running',
            values), 1_000)
        writer.write('/ring_gyro/die_temperature',
                     conversions.temperature_message(2_000, temperature_k, 'ring_gyro'), 2_000)


def test_a_digest_sees_a_changed_value_and_not_the_wall_clock(tmp_path):
    # The control of the test above: one value of one message changes its topic's digest;
    # the wall-clock values of /diagnostics do not.
    base = {'sim_time_s': 1.0, 'lag_s': 0.0, 'real_time_factor_achieved': 12.5}
    digests = {}
    for name, values, kelvin in (('a', base, 300.0), ('b', {**base, 'lag_s': 0.7}, 300.0),
                                 ('c', {**base, 'sim_time_s': 1.01}, 300.0),
                                 ('d', base, 300.0 + 1e-9)):
        _tiny_recording(tmp_path / f'{name}.mcap', values, kelvin)
        digests[name] = make_recording_digests.digest_recording(tmp_path / f'{name}.mcap')
    a, b, c, d = (digests[k]['topics'] for k in 'abcd')
    assert a == b
    assert a['/diagnostics'] != c['/diagnostics']
    assert a['/ring_gyro/die_temperature'] == c['/ring_gyro/die_temperature']
    assert a['/ring_gyro/die_temperature'] != d['/ring_gyro/die_temperature']
